"""Exploration under odometry error (the P3-DX preset), with and without scan-matching localization.

Run: python benchmarks/bench_localized_explore.py [--worlds dense,sparse] [--methods frontier,srt-laser]
         [--speeds 300] [--modes exact,odometry,scan-match] [--max-time 3600] [--seed 0]
         [--odometry p3dx] [--jobs 2]

For each world, method and speed [mm/s], runs from the same start and seed in each mode: "exact"
(perfect odometry), "odometry" (the error on, the map built on odometry: `--localize none`) and
"scan-match" (the error on, corrected by scan matching: `--localize scan-match`, the mapper and the
explorer get the corrected pose). Printed per run: coverage, map IoU against the ground truth, the IoU
drop against the exact run of the same world, method and speed, ATE [m] (the record's `ate_m`: RMSE of
the pose the explorer used against the true pose, sampled every second of robot time, no alignment),
robot time, robot time / wall time (noisy with --jobs > 1 or a busy machine), the localizer's outcome
counts. The issue 14 speed table (item 5): `--worlds dense --methods bvp,srt-laser --speeds 40,100,300`.
Targets (issue 14): with scan matching ATE <= 0.10 m and map IoU within 0.03 of the exact run.
"""

from __future__ import annotations

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor
from typing import Any

from robotexp.experiment import RunSpec, run_experiment

MODES = ("exact", "odometry", "scan-match")


def run_one(job: tuple[str, str, float, str, argparse.Namespace]) -> dict[str, Any]:
    """One run through `run_experiment` (the `robotexp explore` path); returns its figures."""
    world, method, speed, mode, args = job
    spec = RunSpec(world=world, method=method, speed=speed / 1000, laser_range=args.laser_range, seed=args.seed,
                   max_time=args.max_time, odometry="none" if mode == "exact" else args.odometry,
                   localize="scan-match" if mode == "scan-match" else "none")
    r = run_experiment(spec, None).record
    return {"world": world, "method": method, "speed": speed, "mode": mode, "coverage": r["coverage"] or 0.0,
            "iou": r["map_iou"], "ate": r["ate_m"], "time": r["robot_time_s"],
            "ratio": r["robot_time_s"] / max(r["wall_time_s"], 1e-9), "reason": r["reason"],
            "counts": r.get("matches") or {}}


def main() -> None:
    """Run the grid of runs (in --jobs processes) and print one line each, with the IoU drops."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", default="dense,sparse")
    ap.add_argument("--methods", default="frontier,srt-laser")
    ap.add_argument("--speeds", default="300", help="maximum speeds [mm/s], comma-separated")
    ap.add_argument("--modes", default=",".join(MODES), help="exact, odometry, scan-match (comma-separated)")
    ap.add_argument("--max-time", type=float, default=3600.0, help="[s] robot time")
    ap.add_argument("--laser-range", type=float, default=3.0, help="[m]")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--odometry", default="p3dx", help="an --odometry-error spec (robotexp.sim.odometry_error)")
    ap.add_argument("--jobs", type=int, default=1, help="runs at once (processes)")
    args = ap.parse_args()
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
    jobs = [(w, m, s, mode, args) for w in args.worlds.split(",") for m in args.methods.split(",")
            for s in speeds for mode in modes]
    print(f"{'world':7s} {'method':10s} {'mm/s':>5s} {'mode':11s} {'coverage':>8s} {'IoU':>7s} {'dIoU':>7s} "
          f"{'ATE m':>7s} {'time s':>7s} {'x real':>6s}  reason / matches", flush=True)
    results = []
    with ProcessPoolExecutor(args.jobs) as pool:
        for r in pool.map(run_one, jobs):      # in order: each line as soon as its run (and those before) ended
            results.append(r)
            _line(r, results)
    print("IoU drops against the exact runs:")
    for r in results:
        _line(r, results)


def _line(r: dict[str, Any], results: list[dict[str, Any]]) -> None:
    exact = {(e["world"], e["method"], e["speed"]): e["iou"] for e in results if e["mode"] == "exact"}
    base = exact.get((r["world"], r["method"], r["speed"]))
    drop = "" if base is None else f"{r['iou'] - base:+7.4f}"
    ate = "-" if r["ate"] is None else f"{r['ate']:.3f}"
    print(f"{r['world']:7s} {r['method']:10s} {r['speed']:5.0f} {r['mode']:11s} {r['coverage']:8.4f} "
          f"{r['iou']:7.4f} {drop:>7s} {ate:>7s} {r['time']:7.0f} {r['ratio']:6.0f}  {r['reason']} "
          f"{r['counts']}", flush=True)


if __name__ == "__main__":
    main()
