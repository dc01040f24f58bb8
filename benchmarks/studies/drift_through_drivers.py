"""Localization end to end through the real drivers: an emulated P3-DX whose encoders drift, its
laser served by the LMS2xx emulator, explored with and without scan matching.

The emulator runs the P3-DX odometry-error preset (`robotexp emulate p3dx --odometry-error p3dx
--laser lms2xx`); the explorer drives it through the ARIA driver and reads the laser through the
LMS2xx driver, as on a real robot. The simulator's true pose comes back through MobileSim's SIMSTAT
packet, so each record's ATE is the distance between the pose the explorer used and the truth.

Run: python benchmarks/studies/drift_through_drivers.py [--world dense] [--method frontier]
     [--modes none,scan-match] [--speedup 4] [--max-time 3600] [--seed 0]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from robotexp.run.spec import RunSpec
from robotexp.experiment import run_on_robot
from robotexp.run.laser_mount import connect_with_laser, emulate_devices

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # benchmarks/: perflog
from perflog import Figure, record  # noqa: E402


def one_run(world: str, method: str, localize: str, speedup: float, max_time: float, seed: int) -> dict:
    """One exploration through the drivers; its record as a dict."""
    devices = emulate_devices("p3dx", world, speedup=speedup, laser="lms2xx", odometry="p3dx", port=0)
    try:
        addresses = dict((label, dev.address) for label, dev in devices)
        spec = RunSpec(world=world, method=method, robot="p3dx", max_time=max_time, seed=seed, localize=localize,
                       odometry="none")
        with tempfile.TemporaryDirectory() as tmp, \
                connect_with_laser("p3dx", addresses["robot"], f"lms2xx:{addresses['laser']}", None) as bot:
            t0 = time.perf_counter()
            out = run_on_robot(spec, bot, Path(tmp), world, image=False)
            wall = time.perf_counter() - t0
        r = out.record.as_dict()
        r["study_wall_s"] = wall
        return r
    finally:
        for _, dev in reversed(devices):
            dev.close()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="dense")
    ap.add_argument("--method", default="frontier")
    ap.add_argument("--modes", default="none,scan-match")
    ap.add_argument("--speedup", type=float, default=4.0)
    ap.add_argument("--max-time", type=float, default=3600.0, help="[s] robot time per run")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    figures = []
    for mode in args.modes.split(","):
        r = one_run(args.world, args.method, mode, args.speedup, args.max_time, args.seed)
        ate = r.get("ate_m")
        print(f"{mode:10s} ATE {ate} m, coverage {r['coverage']:.3f}, map IoU {r.get('map_iou')}, "
              f"{r['reason']}, robot time {r['robot_time_s']:.0f} s, wall {r['study_wall_s']:.0f} s", flush=True)
        figures += [Figure(f"localize {mode}: ATE", float("nan") if ate is None else float(ate), "m",
                           "target <= 0.10 m with scan matching"),
                    Figure(f"localize {mode}: coverage", float(r["coverage"]), "", r["reason"])]
    record("drift-through-drivers", figures, section="studies",
           title="Localization through the drivers: P3-DX emulator with the P3-DX odometry error, LMS2xx emulator",
           parameters={"world": args.world, "method": args.method, "speedup": args.speedup, "seed": args.seed})
    return 0


if __name__ == "__main__":
    sys.exit(main())
