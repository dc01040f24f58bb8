"""Frontier exploration through the MAVLink rover emulator (real UDP socket, OBSTACLE_DISTANCE), repeated,
against the embedded simulator: how far apart the final coverages are, run after run.

Through MAVLink the scan is OBSTACLE_DISTANCE (72 sectors of 5 degrees, whole cm) at 10 Hz while
poses come at 20 Hz, poses are float32 NED and commands land a packet later than on the stepped
simulator, so runs differ from each other (the order frontiers are visited in is chaotic) and from
the embedded run. tests/drivers/test_mavlink_explore.py asks one run's floor away from the walls (`coverage_inside`: the
cells next to an obstacle left out) to come within half a point of the embedded run's; this prints the
distribution behind that bound, and of `coverage` (the cells along the walls included).

Run: python benchmarks/studies/mavlink_explore.py [--runs 10] [--world ufmg-static] [--pose path1]
                                          [--speedup 30] [--max-time 300] [--busy N]
`--busy N` runs N busy-looping processes meanwhile (a loaded machine, as a CI run under pytest).
Prints each run's coverage (inside and whole), end and robot time, then min / median / max and the worst
differences in points; exit status 1 when a run's inside is more than half a point below the embedded one.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import statistics
import sys
import time

from robotexp.run.spec import RunSpec
from robotexp.world.poses import resolve_pose
from robotexp.experiment import run_experiment, run_on_robot
from robotexp.world.builtin import builtin_world
from robotexp.world.groundtruth import coverage_inside
from robotexp_drivers.mavlink.emulator import MavlinkEmulator
from robotexp_drivers.mavlink.robot import ROVER_RADIUS, MavlinkRobot


def _busy() -> None:
    while True:
        pass


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--world", default="ufmg-static")
    ap.add_argument("--pose", default="path1")
    ap.add_argument("--speedup", type=float, default=30.0)
    ap.add_argument("--max-time", type=float, default=300.0)
    ap.add_argument("--busy", type=int, default=0, help="busy-looping processes meanwhile")
    args = ap.parse_args()
    world = builtin_world(args.world)
    spec = RunSpec(world=args.world, robot="p3dx", method="frontier", pose=args.pose, speed=0.3,
                   max_time=args.max_time)
    out = run_experiment(spec, None)
    embedded = out.record
    assert out.run.truth is not None
    embedded_inside = coverage_inside(out.run.grid.free(), out.run.truth)
    print(f"embedded: inside {embedded_inside:.4f}, coverage {embedded['coverage']:.4f}, {embedded['reason']}, "
          f"{embedded['robot_time_s']:.0f} s of robot time")
    start = resolve_pose(world, args.pose, ROVER_RADIUS)[0]
    busy = [multiprocessing.Process(target=_busy, daemon=True) for _ in range(args.busy)]
    for p in busy:
        p.start()
    covs: list[float] = []
    insides: list[float] = []
    try:
        for i in range(args.runs):
            t0 = time.perf_counter()
            with MavlinkEmulator(world, pose=start, speedup=args.speedup, obstacle_distance=True) as emu:
                with MavlinkRobot(emu.address) as robot:
                    o = run_on_robot(spec, robot, None, world)
                collisions = emu.sim.collisions
            r = o.record
            assert o.run.truth is not None
            covs.append(r["coverage"])
            insides.append(coverage_inside(o.run.grid.free(), o.run.truth))
            print(f"run {i + 1}: inside {insides[-1]:.4f}, coverage {r['coverage']:.4f}, "
                  f"{r['robot_time_s']:.0f} s of robot time, "
                  f"{collisions} collisions, {time.perf_counter() - t0:.1f} s wall, {r['reason']}", flush=True)
    finally:
        for p in busy:
            p.terminate()
    worst = (embedded["coverage"] - min(covs)) * 100
    worst_inside = (embedded_inside - min(insides)) * 100
    print(f"through MAVLink, {len(covs)} runs: inside min {min(insides):.4f}, median "
          f"{statistics.median(insides):.4f}, max {max(insides):.4f}, worst {worst_inside:.2f} points below the "
          f"embedded run; coverage min {min(covs):.4f}, median {statistics.median(covs):.4f}, max {max(covs):.4f}, "
          f"worst {worst:.2f} points below; load average {os.getloadavg()[0]:.1f}")
    return 1 if worst_inside > 0.5 else 0


if __name__ == "__main__":
    sys.exit(main())
