"""Teams against one robot: coverage, time to 95 %, total path and overlap of 4 P3-DX robots per coordinator.

On `--world` (default dense) with the frontier explorer, for each start pose and seed: one P3-DX alone, then
a team of `--team` P3-DX robots (spread from the same start) with each coordinator of `--coordinators`. The
simulator and the frontier explorer are deterministic without noise, so start poses, not seeds, give the
runs their variety; with laser noise (`--noise-sigma`) each seed is another draw of it, and a run's course
with it. Prints a row per run and the medians per setting (time to 95 % also as a share of the single
robot's from the same start), then each coordinator against `none` run by run (same team size, start and
seed): in how many runs its overlap and time to 95 % are lower, the median difference and the two-sided
Wilcoxon signed-rank p-value. Writes every record to OUT/results.jsonl, the tables as OUT/team_study.md,
and the figures (the coverage curves of the first start, the map of its team run for each coordinator) to
`--figures`.

    python benchmarks/studies/team_study.py [--world dense] [--team 4 | 2,4,8]
        [--coordinators none,greedy,burgard,minpos,burgard:beta=4] [--poses 1] [--seeds 0] [--max-time 1800]
        [--noise-sigma 0] [--params replan_period=2.1] [--jobs 1] [--out out/team_study] [--figures docs/figures]

docs/how-to/teams.md: ``python benchmarks/studies/team_study.py --poses 1,2,3,4,5,6,7,8,9 --figures docs/figures``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any


def _slug(name: str) -> str:
    """A coordinator with its parameters as a file name: burgard:beta=4 -> burgard_beta4."""
    return name.replace(":", "_").replace("=", "")


def _case(world: str, pose: str, seed: int, sizes: list[int], coordinators: list[str], max_time: float,  # noqa: PLR0913
          sigma: float, params: dict[str, float], out: Path, keep: bool) -> list[tuple[str, str, dict[str, Any], Any]]:
    """One start and seed: the robot alone, then every team. (label, slug, row, output when `keep`) each."""
    from robotexp.experiment import run_experiment, run_team
    from robotexp.run.spec import RunSpec
    from robotexp.run.team import TeamSpec

    spec = RunSpec(world=world, method="frontier", pose=None if pose == "default" else pose, seed=seed,
                   max_time=max_time, laser_sigma=sigma, params=params)
    settings = [("1 robot", "", run_experiment(spec, out, image=False))]
    for size in sizes:
        for name in coordinators:
            coordinator, *given = name.split(":")
            team = TeamSpec(robots=("p3dx",) * size, coordinator=coordinator,
                            coordinator_params={k: float(v) for k, v in (p.split("=", 1) for p in given)})
            where = out / _slug(name) if given else out    # one results file per parameter set
            settings.append((f"{size} {name}", _slug(name), run_team(spec, team, where, image=False)))
    base = settings[0][2].record.time_to_coverage_95_s
    rows = []
    for label, slug, output in settings:
        r = output.record
        t95 = r.time_to_coverage_95_s
        rows.append((label, slug, {
            "pose": pose, "seed": seed, "coverage": r.coverage, "floor": r.coverage_inside, "t95": t95,
            "share": None if t95 is None or not base else t95 / base, "path": r.path_length_m,
            "max_path": r.max_path_m, "overlap": r.overlap_ratio, "idle": r.idle_time_s,
            "collisions": r.collisions, "robot_collisions": r.robot_collisions, "wall": r.wall_time_s,
            "end": r.end.value}, output if keep else None))
    return rows


def main() -> int:
    from robotexp.output.figures import curve_figure, run_map_figure, save_figure

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--world", default="dense")
    ap.add_argument("--team", default="4", help="robots in a team, comma-separated sizes (2,4,8: a scaling study)")
    ap.add_argument("--coordinators", default="none,greedy,burgard,minpos",
                    help="comma-separated; a coordinator's parameters after colons: burgard:beta=4:cost_scale=10")
    ap.add_argument("--seeds", default="0", help="comma-separated")
    ap.add_argument("--poses", default="1", help="start poses of the world, comma-separated ('default': the "
                                                  "default start, for a map that names none)")
    ap.add_argument("--max-time", type=float, default=1800.0, help="[s] robot time of each run")
    ap.add_argument("--noise-sigma", type=float, default=0.0, help="[mm] gaussian laser noise (each seed a draw)")
    ap.add_argument("--params", default="", help="the frontier explorer's parameters, name=value,... "
                                                  "(replan_period=2.1)")
    ap.add_argument("--jobs", type=int, default=1, help="starts and seeds run in this many processes")
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
    if not (0 <= args.noise_sigma <= 1000) or args.jobs < 1:
        print("team_study: --noise-sigma must be 0..1000 mm and --jobs at least 1", file=sys.stderr)
        return 2
    try:
        params = {k.strip(): float(v) for k, v in (p.split("=", 1) for p in args.params.split(",") if p.strip())}
        from robotexp.registry import make_explorer

        make_explorer("frontier", params)     # an unknown or out-of-range parameter: one line, before any run
    except RobotexpError as exc:
        print(f"team_study: --params: {exc}", file=sys.stderr)
        return 2
    except ValueError:
        print(f"team_study: --params {args.params!r}: give name=number pairs, comma-separated", file=sys.stderr)
        return 2
    stem = Path(args.world).stem if is_map_file(args.world) else args.world   # in file names
    seeds = [int(s) for s in args.seeds.split(",")]
    cases = [(pose, seed) for pose in args.poses.split(",") for seed in seeds]
    coordinators = args.coordinators.split(",")
    sizes = [int(n) for n in args.team.split(",")]
    figures = args.figures or args.out
    figures.mkdir(parents=True, exist_ok=True)
    header = f"{'setting':<16} {'pose':>4} {'seed':>4} {'coverage':>8} {'floor':>6} {'t95 s':>7} {'t95/1':>6} " \
             f"{'path m':>7} " \
             f"{'max m':>6} {'overlap':>7} {'idle s':>7} {'coll':>4} {'r-r':>3} {'wall s':>6}  end"
    print(header)
    t0 = time.perf_counter()
    common = (sizes, coordinators, args.max_time, args.noise_sigma / 1000.0, params, args.out)
    if args.jobs > 1 and len(cases) > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            later = [pool.submit(_case, args.world, pose, seed, *common, False) for pose, seed in cases[1:]]
            first = _case(args.world, *cases[0], *common, True)      # in this process: its runs draw the figures
            results = [first] + [f.result() for f in later]
    else:
        results = [_case(args.world, pose, seed, *common, i == 0) for i, (pose, seed) in enumerate(cases)]
    rows: dict[str, list[dict[str, Any]]] = {}
    curves = []
    for case in results:
        for label, slug, row, output in case:
            rows.setdefault(label, []).append(row)
            print(f"{label:<16} {row['pose']:>4} {row['seed']:>4} {_f(row['coverage'], 4):>8} "
                  f"{_f(row['floor'], 4):>6} {_f(row['t95'], 0):>7} "
                  f"{_f(row['share'], 2):>6} {row['path']:>7.1f} {_f(row['max_path'], 1):>6} "
                  f"{_f(row['overlap'], 3):>7} {_f(row['idle'], 0):>7} {row['collisions']:>4} "
                  f"{_f(row['robot_collisions'], 0):>3} {row['wall']:>6.1f}  {row['end']}")
            if output is not None:
                curve = output.run.metrics.curve
                curves.append((label, [c[0] for c in curve], [100 * c[2] for c in curve]))
                if output.record.team_size is not None:
                    fig = run_map_figure(output.run)
                    size = "" if sizes == [4] else f"{output.record.team_size}_"
                    save_figure(fig, figures / f"teams_{stem}_{size}{slug}", ("png",))
    table = ["| setting | runs | coverage | floor away from the walls | time to 95 % [s] | t95 / one robot | "
             "total path [m] | overlap | collisions |", "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for label, rs in rows.items():
        table.append(f"| {label} | {len(rs)} | {_med(rs, 'coverage', 4)} | {_med(rs, 'floor', 4)} | "
                     f"{_med(rs, 't95', 0)} | "
                     f"{_med(rs, 'share', 2)} | {_med(rs, 'path', 1)} | {_med(rs, 'overlap', 3)} | "
                     f"{_med(rs, 'collisions', 0)} |")
    paired = _against_none(rows, sizes, coordinators)
    print("\nmedians\n" + "\n".join(table))
    if paired:
        print("\nagainst none, run by run\n" + "\n".join(paired))
    (args.out / "team_study.md").write_text("\n".join(table + [""] + paired) + "\n", encoding="utf-8")
    fig = curve_figure(curves, xlabel="robot time [s]", ylabel="coverage [%]",
                       title=f"{stem}: one robot and teams of {args.team} (frontier, start {cases[0][0]})",
                       hlines=[95.0])
    save_figure(fig, figures / f"teams_{stem}_{'' if sizes == [4] else 'scaling_'}coverage", ("png",))
    print(f"\n{len(cases) * (1 + len(sizes) * len(coordinators))} runs in {time.perf_counter() - t0:.0f} s; records in "
          f"{args.out / 'results.jsonl'}, figures in {figures}")
    return 0


def _against_none(rows: dict[str, list[dict[str, Any]]], sizes: list[int], coordinators: list[str]) -> list[str]:
    """Each coordinator's overlap and time to 95 % against `none`'s of the same size, start and seed: runs
    lower, median difference, Wilcoxon signed-rank p (two-sided; "-" for fewer than 6 pairs)."""
    from scipy.stats import wilcoxon

    out = ["| setting | pairs | overlap lower | median overlap - none's | p | t95 lower | median t95 - none's [s] "
           "| p |",
           "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for size in sizes:
        base = {(r["pose"], r["seed"]): r for r in rows.get(f"{size} none", [])}
        for name in coordinators:
            if name == "none" or not base:
                continue
            cells = [f"{size} {name}"]
            pairs = [(r, base[(r["pose"], r["seed"])]) for r in rows[f"{size} {name}"]
                     if (r["pose"], r["seed"]) in base]
            cells.append(str(len(pairs)))
            for key, digits in (("overlap", 3), ("t95", 0)):
                diffs = [a[key] - b[key] for a, b in pairs if a[key] is not None and b[key] is not None]
                lower = sum(d < 0 for d in diffs)
                p = "-" if len(diffs) < 6 or not any(diffs) else _p(float(wilcoxon(diffs).pvalue))
                cells += [f"{lower} of {len(diffs)}", _f(statistics.median(diffs) if diffs else None, digits), p]
            out.append("| " + " | ".join(cells) + " |")
    return out if len(out) > 2 else []


def _p(value: float) -> str:
    """A p-value: two decimals, one significant digit below 0.01."""
    return f"{value:.2f}" if value >= 0.01 else f"{value:.1g}"


def _f(value: float | None, digits: int) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def _med(rows: list[dict[str, float | None]], key: str, digits: int) -> str:
    values = [r[key] for r in rows if r[key] is not None]
    missing = len(rows) - len(values)
    text = "-" if not values else f"{statistics.median(values):.{digits}f}"   # type: ignore[type-var]
    return text + (f" ({missing} never)" if missing and values else "")


if __name__ == "__main__":
    sys.exit(main())
