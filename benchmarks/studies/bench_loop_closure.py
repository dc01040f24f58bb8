"""Online loop closure in whole runs: scan matching alone (`--localize scan-match`) against scan matching
with loop closure (`--localize slam`), under the P3-DX odometry preset.

    python benchmarks/studies/bench_loop_closure.py                       # dense and the ring corridor, frontier
    python benchmarks/studies/bench_loop_closure.py --worlds dense --max-time 600 --no-record

For each world and mode: ATE, `map_iou`, the tolerant IoU (`map_iou_tolerant`, one cell), coverage, robot time
/ wall time; with loop closure also the keyframes, loop edges, map rebuilds, their time and the iSAM2 update
time per keyframe (median). Writes `benchmarks/results/loop_closure.json` (`perflog.record`).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # benchmarks/: perflog
from perflog import Figure, record  # noqa: E402

from robotexp.run.spec import RunSpec  # noqa: E402
from robotexp.experiment import run_experiment
from robotexp.world.groundtruth import map_iou_tolerant  # noqa: E402

RING = "/work/shared/maps/eb_loop.yaml"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", default=f"dense,{RING}", help="comma-separated worlds (names or map files)")
    ap.add_argument("--method", default="frontier")
    ap.add_argument("--modes", default="scan-match,slam")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-time", type=float, default=3600.0, help="[s] robot time per run at most")
    ap.add_argument("--no-record", action="store_true", help="print only")
    args = ap.parse_args()
    run_experiment(RunSpec(world="dense", method=args.method, odometry="p3dx", localize="slam", max_time=5.0),
                   None, image=False)            # numba compiles outside the timing
    figures: list[Figure] = []
    for world in args.worlds.split(","):
        label = Path(world).stem if world.endswith(".yaml") else world
        for mode in args.modes.split(","):
            spec = RunSpec(world=world, method=args.method, odometry="p3dx", localize=mode, seed=args.seed,
                           max_time=args.max_time)
            t0 = time.perf_counter()
            out = run_experiment(spec, None, image=False)
            wall = time.perf_counter() - t0
            rec, run = out.record, out.run
            assert rec is not None and run.truth is not None
            tol = map_iou_tolerant(run.grid.states(), run.truth)[0]
            lc = rec.extra.get("loop_closure") or {}
            print(f"{label} {args.method} {mode}: ATE {rec.extra.get('ate_m')} m, map IoU {rec.map_iou}, tolerant "
                  f"{tol:.4f}, coverage {rec.coverage}, robot {rec.robot_time_s:.0f} s in {wall:.1f} s wall "
                  f"(x{rec.robot_time_s / wall:.0f}) {lc}", flush=True)
            name = f"{label}, {args.method}, {mode}"
            figures += [Figure(f"{name}: ATE", float(rec.extra.get("ate_m") or float("nan")), "m"),
                        Figure(f"{name}: map IoU", float(rec.map_iou or float("nan"))),
                        Figure(f"{name}: tolerant map IoU (1 cell)", round(tol, 4)),
                        Figure(f"{name}: coverage", float(rec.coverage or float("nan"))),
                        Figure(f"{name}: robot time / wall time", round(rec.robot_time_s / wall, 1), "x",
                               note=f"{rec.robot_time_s:.0f} s of robot time, {rec.reason}")]
            if lc:
                figures += [Figure(f"{name}: loop edges / keyframes", lc["loops"], "",
                                   note=f"{lc['keyframes']} keyframes, {lc['tried']} loop matches tried, "
                                        f"{lc['rebuilds']} map rebuilds in {lc['rebuild_s']} s"),
                            Figure(f"{name}: {lc['backend']} update per keyframe (median)",
                                   float(lc["update_ms"] or float("nan")), "ms")]
    if not args.no_record:
        record("loop_closure", figures, title="Online loop closure (P3-DX odometry error)", section="studies",
               parameters={"method": args.method, "seed": args.seed, "max robot time": f"{args.max_time:g} s"})


if __name__ == "__main__":
    main()
