"""How an emulator's speed-up lengthens a run's route: frontier on ufmg-static from path1 at 0.3 m/s, once
on the stepped simulator and `--runs` times through the Kobuki emulator (TCP, its simulated laser) at each
`--speedups` value, `--localize none` (the emulator's exact odometry).

Through an emulator paced by wall time, the client's planning time costs the speed-up times its wall time in
robot time: commands land later, turns are overshot and corrected, and the route grows. The test that compares
the two (tests/drivers/test_kobuki_explore.py) picks its speed-up from this.

    python benchmarks/studies/emulator_lag.py [--speedups 5,12,30] [--runs 5]

Prints one row per run: speed-up, path [m], coverage, completed, wall time [s]; then each speed-up's range.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

from robotexp.experiment import run_experiment, run_on_robot
from robotexp.run.spec import RunSpec
from robotexp.world.builtin import builtin_world
from robotexp.world.poses import resolve_pose
from robotexp_drivers.kobuki.emulator import EmulatorLaser, KobukiEmulator
from robotexp_drivers.kobuki.robot import KOBUKI_RADIUS, KobukiRobot


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--speedups", default="5,12,30", help="emulator speed-ups, comma-separated")
    ap.add_argument("--runs", type=int, default=5, help="runs through the emulator at each speed-up")
    args = ap.parse_args()
    world = builtin_world("ufmg-static")
    spec = RunSpec(world="ufmg-static", robot="kobuki", method="frontier", pose="path1", speed=0.3, max_time=300.0)
    ref = run_experiment(spec, None, image=False).record
    print(f"stepped simulator: path {ref['path_length_m']:.2f} m, coverage {ref['coverage']:.4f}")
    start = resolve_pose(world, "path1", KOBUKI_RADIUS)[0]
    ranges: dict[float, list[float]] = {}
    for speedup in (float(x) for x in args.speedups.split(",")):
        for i in range(args.runs):
            t0 = time.perf_counter()
            with KobukiEmulator(world, pose=start, speedup=speedup) as emu:
                with KobukiRobot(emu.address, laser=EmulatorLaser(emu)) as robot:
                    rec = run_on_robot(replace(spec, localize="none"), robot, None, world).record
            ranges.setdefault(speedup, []).append(rec["path_length_m"])
            print(f"{speedup:5g}x run {i}: path {rec['path_length_m']:.2f} m, coverage {rec['coverage']:.4f}, "
                  f"completed {rec['completed']}, {time.perf_counter() - t0:.1f} s wall", flush=True)
    for speedup, paths in ranges.items():
        print(f"{speedup:5g}x: path {min(paths):.1f}-{max(paths):.1f} m over {len(paths)} runs "
              f"({max(paths) / ref['path_length_m']:.2f} x the stepped simulator's at most)")


if __name__ == "__main__":
    main()
