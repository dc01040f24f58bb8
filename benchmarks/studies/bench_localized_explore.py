"""Exploration under odometry error (the P3-DX preset), with and without scan-matching localization.

Run: python benchmarks/studies/bench_localized_explore.py [--worlds dense,sparse] [--methods frontier,srt-laser]
         [--speeds 300] [--modes exact,odometry,scan-match] [--max-time 3600] [--seed 0 | --seeds 0-4]
         [--odometry p3dx] [--jobs 2] [--trace DIR] [--known-bias] [--jsonl FILE] [--no-record] [--result-name NAME]
     python benchmarks/studies/bench_localized_explore.py --table FILE      # the markdown table of a --jsonl FILE

The loop-closure study (scan matching + online loop closure, `--localize slam`, 45 runs and their exact runs):

    nice -n 5 python benchmarks/studies/bench_localized_explore.py --methods frontier,srt-laser,bvp \
        --worlds dense,sparse,/work/shared/maps/eb_loop.yaml --modes exact,slam --seeds 0-4 --jobs 2 \
        --jsonl out/slam-study.jsonl

For each world, method and speed [mm/s], runs from the same start and seed in each mode: "exact" (perfect
odometry), "odometry" (the error on, the map built on odometry: `--localize none`), "scan-match" (the error
on, corrected by scan matching: `--localize scan-match`, the mapper and the explorer get the corrected pose)
and "slam" (scan matching with online loop closure: `--localize slam`). A world is a built-in name or a map
file (named by its stem). With `--seeds` every run is repeated for each seed, against the exact run of its
seed. `--jsonl FILE` appends each run's figures as one JSON line as soon as it ends (a long study keeps what
it measured if stopped); at the end the share of the runs that meet the targets (ATE, tolerant IoU, coverage
>= 0.95) is printed. Printed per run: coverage, map IoU against the ground truth, the IoU drop against the
exact run of the same world, method and speed, the same with one cell of tolerance (`map_iou_tolerant`: a mark
counts as right, a target as found, within one cell), ATE [m] (the record's `ate_m`: RMSE of the pose the
explorer used against the true pose, sampled every second of robot time, no alignment), robot time, robot time
/ wall time (noisy with --jobs > 1 or a busy machine), the localizer's outcome counts. `--trace DIR` writes
each scan-match run's per-step errors (heading error against time, where the matcher fell back: few points,
corridors) as CSV.
The speed table:
`--worlds dense --methods bvp,srt-laser --speeds 40,100,300 --modes odometry,scan-match --max-time 7200`.
`--known-bias` is a diagnostic: the localizer's odometry calibration starts at the odometry error's
true heading bias (wheel mismatch / wheel base, less the heading drift; a robot calibrated before the
run) instead of 0, to tell what the bias learned online costs from what is left.
The laser reaches as far as the robot's would (`--laser-range auto`): 8 m in `sparse` and on map files (a
P3-DX's LMS200 reads 8 m; with 3 m the robot crosses the hall blind for a minute and the heading bias cannot be
observed, and in a real depot or lab it drives on odometry alone for metres at a time), 3 m in the other
built-in worlds (the thesis's setting). `--laser-range 3` gives every world 3 m.
Targets: with scan matching ATE <= 0.10 m and the tolerant map IoU within 0.03 of the exact run.
The figures are written to benchmarks/results/localized-explore.json (perflog).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from robotexp.run.spec import RunSpec
from robotexp.experiment import run_experiment
from robotexp.localization.robot import LocalizedRobot
from robotexp.world.groundtruth import map_iou_tolerant
from robotexp.world.loader import is_map_file

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # benchmarks/: perflog
from perflog import Figure, record  # noqa: E402

MODES = ("exact", "odometry", "scan-match", "slam")
LASER_RANGE = {"sparse": 8.0}     # [m] the built-in worlds whose robot has a longer laser than the thesis's 3 m
REAL_LASER = 8.0                  # [m] on map files: a real building, the robot's own laser (an LMS200)


def laser_reach(world: str, choice: str) -> float:
    """[m] the laser range of runs on `world` for `--laser-range` `choice` ("auto" or metres)."""
    if choice != "auto":
        return float(choice)
    if is_map_file(world):
        return REAL_LASER
    return LASER_RANGE.get(world, 3.0)


def run_one(job: tuple[str, str, float, str, int, argparse.Namespace]) -> dict[str, Any]:
    """One run through `run_experiment` (the `robotexp explore` path); returns its figures."""
    world, method, speed, mode, seed, args = job
    if args.known_bias:
        _known_bias(args.odometry)
    reach = laser_reach(world, args.laser_range)
    spec = RunSpec(world=world, method=method, speed=speed / 1000, laser_range=reach, seed=seed,
                   max_time=args.max_time, odometry="none" if mode == "exact" else args.odometry,
                   localize=mode if mode in ("scan-match", "slam") else "none")
    out = run_experiment(spec, None)
    r = out.record
    robot = out.run.robot
    truth = out.run.truth
    tol = None if truth is None else map_iou_tolerant(out.run.grid.states(), truth, 1)[0]
    if args.trace is not None and isinstance(robot, LocalizedRobot):
        _write_trace(args.trace / f"{_label(world)}_{method}_{speed:g}mms_seed{seed}.csv", robot)
    return {"world": _label(world), "method": method, "speed": speed, "mode": mode, "seed": seed, "laser_m": reach,
            "coverage": r["coverage"] or 0.0,
            "iou": r["map_iou"], "iou1": tol, "ate": r["ate_m"], "time": r["robot_time_s"],
            "ratio": r["robot_time_s"] / max(r["wall_time_s"], 1e-9), "reason": r["reason"],
            "counts": r.get("matches") or {}, "loop_closure": r.get("loop_closure")}


def _label(world: str) -> str:
    return Path(world).stem if is_map_file(world) else world


def _seeds(text: str) -> list[int]:
    """"0-4" or "0,2,3" -> the seeds."""
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b) + 1)) if b else [int(a)]
    return out


def _known_bias(odometry: str) -> None:
    """`--known-bias`: every `LocalizedRobot` made in this process starts its odometry calibration at the
    heading bias [rad/m] of the `odometry` error on the P3-DX (the runs' robot)."""
    from robotexp.localization import robot as localized_robot
    from robotexp.localization.calibration import OdometryCalibration
    from robotexp.sim import odometry_error
    from robotexp.sim.presets import preset

    err = odometry_error(odometry)
    bias = err.wheel_mismatch / preset("p3dx").wheel_base - err.heading_drift

    def calibrated() -> OdometryCalibration:
        cal = OdometryCalibration()
        cal.k = bias
        return cal

    localized_robot.OdometryCalibration = calibrated      # type: ignore[misc, assignment]


def _write_trace(path: Path, robot: LocalizedRobot) -> None:
    """One line per state: robot time, the localizer's status, the scan's echoes, calibration k
    [deg/m], the corrected and true pose (x, y [m], theta [deg]), position error [m], heading error [deg]."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t_s", "status", "echoes", "k_deg_per_m", "x_m", "y_m", "theta_deg", "true_x_m", "true_y_m",
                    "true_theta_deg", "error_m", "heading_error_deg"])
        for (t, status, echoes, k), (p, q) in zip(robot.steps, robot.track, strict=True):
            dth = math.degrees(math.remainder(p.theta - q.theta, 2 * math.pi))
            w.writerow([f"{t:.2f}", status, echoes, f"{math.degrees(k):.4f}", f"{p.x:.4f}", f"{p.y:.4f}",
                        f"{math.degrees(p.theta):.3f}", f"{q.x:.4f}", f"{q.y:.4f}", f"{math.degrees(q.theta):.3f}",
                        f"{math.hypot(p.x - q.x, p.y - q.y):.4f}", f"{dth:.3f}"])


def main() -> None:
    """Run the grid of runs (in --jobs processes) and print one line each, with the IoU drops."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", default="dense,sparse")
    ap.add_argument("--methods", default="frontier,srt-laser")
    ap.add_argument("--speeds", default="300", help="maximum speeds [mm/s], comma-separated")
    ap.add_argument("--modes", default=",".join(MODES), help="exact, odometry, scan-match (comma-separated)")
    ap.add_argument("--max-time", type=float, default=3600.0, help="[s] robot time")
    ap.add_argument("--laser-range", default="auto", help="[m], or auto: 8 in sparse and on map files, 3 elsewhere")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--seeds", default=None, help="seeds, e.g. 0-4 or 0,2 (instead of --seed)")
    ap.add_argument("--jsonl", type=Path, default=None, metavar="FILE", help="append each run's figures here")
    ap.add_argument("--no-record", action="store_true", help="print only (benchmarks/results is left alone)")
    ap.add_argument("--result-name", default="localized-explore",
                    help="the figures' file in benchmarks/results (NAME.json): one per study kept side by side")
    ap.add_argument("--odometry", default="p3dx", help="an --odometry-error spec (robotexp.sim.odometry_error)")
    ap.add_argument("--jobs", type=int, default=1, help="runs at once (processes)")
    ap.add_argument("--trace", type=Path, default=None, metavar="DIR",
                    help="write a per-step error trace of each scan-match run (CSV) in DIR")
    ap.add_argument("--known-bias", action="store_true",
                    help="diagnostic: the odometry calibration starts at the true heading bias, not 0")
    ap.add_argument("--table", type=Path, default=None, metavar="FILE",
                    help="run nothing: print the markdown table of the runs in a --jsonl FILE and the summary")
    args = ap.parse_args()
    if args.table is not None:
        try:
            rows = [json.loads(line) for line in args.table.read_text().splitlines() if line.strip()]
        except (OSError, ValueError) as exc:
            print(f"bench_localized_explore: --table {args.table}: {exc}; give a file written by --jsonl",
                  file=sys.stderr)
            sys.exit(2)
        table(rows)
        summary(rows)
        return
    modes = args.modes.split(",")
    if set(modes) - set(MODES) or args.jobs < 1:
        print(f"bench_localized_explore: --modes takes {', '.join(MODES)} and --jobs >= 1", file=sys.stderr)
        sys.exit(2)
    try:
        speeds = [float(s) for s in args.speeds.split(",")]
    except ValueError:
        print(f"bench_localized_explore: --speeds {args.speeds!r}: expected mm/s values like 40,100,300",
              file=sys.stderr)
        sys.exit(2)
    try:
        seeds = _seeds(args.seeds) if args.seeds else [args.seed]
    except ValueError:
        print(f"bench_localized_explore: --seeds {args.seeds!r}: expected seeds like 0-4 or 0,2", file=sys.stderr)
        sys.exit(2)
    jobs = [(w, m, s, mode, seed, args) for seed in seeds for w in args.worlds.split(",")
            for m in args.methods.split(",") for s in speeds for mode in modes]
    print(f"{'world':7s} {'method':10s} {'mm/s':>5s} {'mode':11s} {'seed':4s} "
          f"{'coverage':>8s} {'IoU':>7s} {'dIoU':>7s} "
          f"{'IoU+-1':>7s} {'dIoU+-1':>7s} {'ATE m':>7s} {'time s':>7s} {'x real':>6s}  reason / matches", flush=True)
    results = []
    with ProcessPoolExecutor(args.jobs) as pool:
        for r in pool.map(run_one, jobs):      # in order: each line as soon as its run (and those before) ended
            results.append(r)
            _line(r, results)
            if args.jsonl is not None:
                args.jsonl.parent.mkdir(parents=True, exist_ok=True)
                with args.jsonl.open("a") as fh:
                    fh.write(json.dumps(r) + "\n")
    print("IoU drops against the exact runs:")
    for r in results:
        _line(r, results)
    summary(results)
    exact = {(e["world"], e["method"], e["speed"], e["seed"]): e for e in results if e["mode"] == "exact"}
    figures = []
    for r in results:
        label = f"{r['world']} {r['method']} {r['speed']:g} mm/s, {r['mode']}"
        if len(seeds) > 1:
            label += f", seed {r['seed']}"
        base = exact.get((r["world"], r["method"], r["speed"], r["seed"]))
        figures.append(Figure(f"{label}: ATE", float("nan") if r["ate"] is None else r["ate"], "m", r["reason"]))
        figures.append(Figure(f"{label}: coverage", r["coverage"], ""))
        if base is not None and r is not base and r["iou1"] is not None and base["iou1"] is not None:
            figures.append(Figure(f"{label}: tolerant map IoU - the exact run's", r["iou1"] - base["iou1"], "",
                                  "target >= -0.03"))
    if args.no_record:
        return
    record(args.result_name, figures, section="studies",
           title="Exploration under the odometry error, with and without scan matching",
           parameters={"seeds": ",".join(map(str, seeds)), "odometry": args.odometry, "laser range": args.laser_range,
                       "robot time": f"{args.max_time:g} s"})


def table(results: list[dict[str, Any]]) -> None:
    """Print a markdown table: each run that is not exact beside the exact run of its world, method, speed, seed."""
    exact = {(e["world"], e["method"], e["speed"], e["seed"]): e for e in results if e["mode"] == "exact"}
    print("| world | method | seed | mode | ATE | coverage | tolerant IoU (exact run) | drop | met |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in results:
        if r["mode"] == "exact":
            continue
        base = exact.get((r["world"], r["method"], r["speed"], r["seed"]))
        drop = None if base is None or r["iou1"] is None or base["iou1"] is None else r["iou1"] - base["iou1"]
        met = (r["ate"] is not None and r["ate"] <= 0.10 and r["coverage"] >= 0.95 and drop is not None
               and drop >= -0.03)
        ate = "-" if r["ate"] is None else f"{r['ate']:.3f} m"
        ref = "-" if base is None or base["iou1"] is None else f"{base['iou1']:.3f}"
        print(f"| {r['world']} | {r['method']} | {r['seed']} | {r['mode']} | {ate} | {r['coverage']:.3f} | "
              f"{(r['iou1'] or 0.0):.3f} ({ref}) | {'-' if drop is None else f'{drop:+.3f}'} | "
              f"{'yes' if met else 'no'} |")


def summary(results: list[dict[str, Any]]) -> None:
    """Print, per mode other than exact, how many runs meet the targets: ATE <= 0.10 m, the tolerant IoU
    within 0.03 of the exact run of the same world, method, speed and seed, coverage >= 0.95."""
    exact = {(e["world"], e["method"], e["speed"], e["seed"]): e for e in results if e["mode"] == "exact"}
    for mode in sorted({r["mode"] for r in results} - {"exact"}):
        runs = [r for r in results if r["mode"] == mode]
        met = 0
        for r in runs:
            base = exact.get((r["world"], r["method"], r["speed"], r["seed"]))
            ok = (r["ate"] is not None and r["ate"] <= 0.10 and r["coverage"] >= 0.95 and base is not None
                  and r["iou1"] is not None and base["iou1"] is not None and r["iou1"] >= base["iou1"] - 0.03)
            met += ok
        print(f"{mode}: {met} of {len(runs)} runs meet ATE <= 0.10 m, tolerant IoU within 0.03 of the exact run "
              f"and coverage >= 0.95 ({met / max(len(runs), 1):.0%})")


def _line(r: dict[str, Any], results: list[dict[str, Any]]) -> None:
    exact = {(e["world"], e["method"], e["speed"], e["seed"]): e for e in results if e["mode"] == "exact"}
    base = exact.get((r["world"], r["method"], r["speed"], r["seed"]))
    drop = "" if base is None else f"{r['iou'] - base['iou']:+7.4f}"
    drop1 = "" if base is None or r["iou1"] is None else f"{r['iou1'] - base['iou1']:+7.4f}"
    ate = "-" if r["ate"] is None else f"{r['ate']:.3f}"
    print(f"{r['world']:7s} {r['method']:10s} {r['speed']:5.0f} {r['mode']:11s} {r['seed']:4d} {r['coverage']:8.4f} "
          f"{r['iou']:7.4f} {drop:>7s} {r['iou1'] or 0.0:7.4f} {drop1:>7s} {ate:>7s} {r['time']:7.0f} "
          f"{r['ratio']:6.0f}  {r['reason']} {r['counts']}", flush=True)


if __name__ == "__main__":
    main()
