"""Teams against one robot: coverage, time to 95 %, total path and overlap of 4 P3-DX robots per coordinator.

On `--world` (default dense) with the frontier explorer, for each start pose and seed: one P3-DX alone, then
a team of `--team` P3-DX robots (spread from the same start) with each coordinator of `--coordinators`. The
simulator and the frontier explorer are deterministic without noise, so start poses, not seeds, give the
runs their variety. Prints a row per run and the medians per setting (time to 95 % also as a share of the
single robot's from the same start), writes every record to OUT/results.jsonl, the table as
OUT/team_study.md, and the figures (the coverage curves of the first start, the map of its team run for each
coordinator) to `--figures`.

    python benchmarks/studies/team_study.py [--world dense] [--team 4 | 2,4,8]
        [--coordinators none,greedy,burgard,minpos,burgard:beta=4] [--poses 1] [--seeds 0] [--max-time 1800]
        [--out out/team_study] [--figures docs/figures]

docs/how-to/teams.md: ``python benchmarks/studies/team_study.py --poses 1,2,3,4,5,6,7,8,9 --figures docs/figures``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path


def _slug(name: str) -> str:
    """A coordinator with its parameters as a file name: burgard:beta=4 -> burgard_beta4."""
    return name.replace(":", "_").replace("=", "")


def main() -> int:
    from robotexp.experiment import run_experiment, run_team
    from robotexp.output.figures import curve_figure, run_map_figure, save_figure
    from robotexp.run.spec import RunSpec
    from robotexp.run.team import TeamSpec

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--world", default="dense")
    ap.add_argument("--team", default="4", help="robots in a team, comma-separated sizes (2,4,8: a scaling study)")
    ap.add_argument("--coordinators", default="none,greedy,burgard,minpos",
                    help="comma-separated; a coordinator's parameters after colons: burgard:beta=4:cost_scale=10")
    ap.add_argument("--seeds", default="0", help="comma-separated")
    ap.add_argument("--poses", default="1", help="start poses of the world, comma-separated ('default': the "
                                                  "default start, for a map that names none)")
    ap.add_argument("--max-time", type=float, default=1800.0, help="[s] robot time of each run")
    ap.add_argument("--out", type=Path, default=Path("out/team_study"))
    ap.add_argument("--figures", type=Path, default=None, help="folder of the figures (default: OUT)")
    args = ap.parse_args()
    from robotexp.errors import RobotexpError
    from robotexp.world.loader import is_map_file, load_world

    try:
        load_world(args.world)          # a map that is not there: one line, before any run
    except RobotexpError as exc:
        print(f"team_study: {exc}", file=sys.stderr)
        return 2
    stem = Path(args.world).stem if is_map_file(args.world) else args.world   # in file names
    seeds = [int(s) for s in args.seeds.split(",")]
    cases = [(pose, seed) for pose in args.poses.split(",") for seed in seeds]
    coordinators = args.coordinators.split(",")
    sizes = [int(n) for n in args.team.split(",")]
    figures = args.figures or args.out
    figures.mkdir(parents=True, exist_ok=True)
    rows: dict[str, list[dict[str, float | None]]] = {}
    curves = []
    header = f"{'setting':<16} {'pose':>4} {'seed':>4} {'coverage':>8} {'t95 s':>7} {'t95/1':>6} {'path m':>7} " \
             f"{'max m':>6} {'overlap':>7} {'idle s':>7} {'coll':>4} {'r-r':>3} {'wall s':>6}  end"
    print(header)
    t0 = time.perf_counter()
    for pose, seed in cases:
        spec = RunSpec(world=args.world, method="frontier", pose=None if pose == "default" else pose, seed=seed,
                       max_time=args.max_time)
        single = run_experiment(spec, args.out, image=False)
        settings = [("1 robot", "", single)]
        for size in sizes:
            for name in coordinators:
                coordinator, *params = name.split(":")
                team = TeamSpec(robots=("p3dx",) * size, coordinator=coordinator,
                                coordinator_params={k: float(v) for k, v in (p.split("=", 1) for p in params)})
                where = args.out / _slug(name) if params else args.out    # one results file per parameter set
                settings.append((f"{size} {name}", _slug(name), run_team(spec, team, where, image=False)))
        base = single.record.time_to_coverage_95_s
        for label, slug, output in settings:
            r = output.record
            t95 = r.time_to_coverage_95_s
            share = None if t95 is None or not base else t95 / base
            row = {"coverage": r.coverage, "t95": t95, "share": share, "path": r.path_length_m,
                   "overlap": r.overlap_ratio, "collisions": r.collisions}
            rows.setdefault(label, []).append(row)
            print(f"{label:<16} {pose:>4} {seed:>4} {_f(r.coverage, 4):>8} {_f(t95, 0):>7} {_f(share, 2):>6} "
                  f"{r.path_length_m:>7.1f} {_f(r.max_path_m, 1):>6} {_f(r.overlap_ratio, 3):>7} "
                  f"{_f(r.idle_time_s, 0):>7} {r.collisions:>4} {_f(r.robot_collisions, 0):>3} "
                  f"{r.wall_time_s:>6.1f}  {r.end.value}")
            if (pose, seed) == cases[0]:
                curve = output.run.metrics.curve
                curves.append((label, [c[0] for c in curve], [100 * c[2] for c in curve]))
                if r.team_size is not None:
                    fig = run_map_figure(output.run)
                    size = "" if sizes == [4] else f"{r.team_size}_"
                    save_figure(fig, figures / f"teams_{stem}_{size}{slug}", ("png",))
    table = ["| setting | runs | coverage | time to 95 % [s] | t95 / one robot | total path [m] | overlap | "
             "collisions |", "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for label, rs in rows.items():
        table.append(f"| {label} | {len(rs)} | {_med(rs, 'coverage', 4)} | {_med(rs, 't95', 0)} | "
                     f"{_med(rs, 'share', 2)} | {_med(rs, 'path', 1)} | {_med(rs, 'overlap', 3)} | "
                     f"{_med(rs, 'collisions', 0)} |")
    print("\nmedians\n" + "\n".join(table))
    (args.out / "team_study.md").write_text("\n".join(table) + "\n", encoding="utf-8")
    fig = curve_figure(curves, xlabel="robot time [s]", ylabel="coverage [%]",
                       title=f"{stem}: one robot and teams of {args.team} (frontier, start {cases[0][0]})",
                       hlines=[95.0])
    save_figure(fig, figures / f"teams_{stem}_{'' if sizes == [4] else 'scaling_'}coverage", ("png",))
    print(f"\n{len(cases) * (1 + len(sizes) * len(coordinators))} runs in {time.perf_counter() - t0:.0f} s; records in "
          f"{args.out / 'results.jsonl'}, figures in {figures}")
    return 0


def _f(value: float | None, digits: int) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def _med(rows: list[dict[str, float | None]], key: str, digits: int) -> str:
    values = [r[key] for r in rows if r[key] is not None]
    missing = len(rows) - len(values)
    text = "-" if not values else f"{statistics.median(values):.{digits}f}"   # type: ignore[type-var]
    return text + (f" ({missing} never)" if missing and values else "")


if __name__ == "__main__":
    sys.exit(main())
