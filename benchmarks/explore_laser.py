"""Frontier exploration with a real laser protocol: a robot emulator plus a laser emulator, each on
its own pseudo-terminal, against the embedded simulator.

The laser emulator (any of `robotexp.laser_emulators`) measures from the robot emulator's simulated
robot (`robotexp.sim.mounted_source`, the sensor at the robot centre facing forward), its driver
reads it through the pseudo-terminal, and `robotexp.laser_mount.LaserMountedRobot` pairs each scan
with the robot's pose at the scan's stamp (`--unpaired`, Kobuki only: the Kobuki backend takes the
newest scan as it is, as if taken at the present pose). Both runs explore `--world` from `--pose` at 0.3 m/s; the script
prints each run's coverage, completion, path and the coverage difference in points.

Run: python benchmarks/explore_laser.py [--robot kobuki] [--laser rplidar] [--world ufmg-static] [--pose path1]
     [--speedup 10] [--laser-speedup S] [--max-time 300] [--unpaired]
(--laser-speedup above --speedup makes scans fresher in robot time: a way to see what the missing
pose pairing costs.)
Exit status 1 when the coverages differ by more than 2 points.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

from robotexp.experiment import RunSpec, run_experiment, run_on_robot
from robotexp.laser import LASER_EMULATORS, LASERS, Laser
from robotexp.laser_mount import LaserMountedRobot, robot_options
from robotexp.registry import available, connect_robot, load, make_emulator
from robotexp.robot import LaserScan, Robot
from robotexp.sim import mounted_source
from robotexp.world.builtin import builtin_world
from robotexp_drivers.kobuki.robot import KobukiRobot
from robotexp_drivers.p3dx import constants as p3dx

_SIM_LASER = (p3dx.CMD_SIM_LRF_ENABLE, p3dx.CMD_OLD_SIM_LRF_ENABLE)


class NewestScan:
    """The laser source `KobukiRobot` takes: the newest scan of a laser mounted at the robot centre,
    facing forward (its sensor frame is the robot frame)."""

    def __init__(self, laser: Laser) -> None:
        self.laser = laser

    def read(self) -> LaserScan:
        s = self.laser.latest() or self.laser.wait_scan(-1, 2.0)
        return s.scan


def main() -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="kobuki", help="a robot backend with an emulator (kobuki, p3dx)")
    parser.add_argument("--laser", default="rplidar")
    parser.add_argument("--world", default="ufmg-static")
    parser.add_argument("--pose", default="path1")
    parser.add_argument("--speedup", type=float, default=10.0, help="robot and laser seconds per wall second")
    parser.add_argument("--laser-speedup", type=float, default=None,
                        help="the laser's own speed-up (default --speedup; higher: fresher scans in robot time)")
    parser.add_argument("--max-time", type=float, default=300.0, help="[s of robot time]")
    parser.add_argument("--unpaired", action="store_true", help="use the newest scan without pairing it")
    args = parser.parse_args()
    names = sorted(set(available(LASERS)) & set(available(LASER_EMULATORS)))
    if args.laser not in names:
        parser.error(f"--laser must be one of {', '.join(names)}, got {args.laser!r}")
    laser_speedup = args.speedup if args.laser_speedup is None else args.laser_speedup
    if not (args.speedup > 0 and args.max_time > 0 and laser_speedup > 0):
        parser.error("--speedup, --laser-speedup and --max-time must be > 0")
    driver = load(LASERS, args.laser, Laser)
    emulator_cls = load(LASER_EMULATORS, args.laser, object)
    if args.unpaired and args.robot != "kobuki":
        parser.error("--unpaired needs --robot kobuki (its backend takes a laser source)")
    world = builtin_world(args.world)

    def spec() -> RunSpec:
        return RunSpec(world=args.world, robot=args.robot, method="frontier", pose=args.pose, speed=0.3,
                       max_time=args.max_time)

    t0 = time.monotonic()
    embedded = run_experiment(spec(), None).record
    print(f"embedded simulator: coverage {embedded['coverage']:.4f}, completed {embedded['completed']}, "
          f"path {embedded['path_length_m']:.1f} m, {time.monotonic() - t0:.0f} s wall", flush=True)
    t0 = time.monotonic()
    emu: Any = make_emulator(args.robot, args.world, pose=args.pose, pty=True, speedup=args.speedup)
    source = mounted_source(emu.sim, lock=getattr(emu, "lock", None))     # the P3-DX emulator has no lock
    with emu.start(), emulator_cls(source, pty=True, speedup=laser_speedup) as lemu, \
            driver(lemu.address) as laser:
        if args.unpaired:
            robot: Robot = KobukiRobot(emu.address, laser=NewestScan(laser))
        else:
            # no simulated-laser packets: the robot is connected as with a laser device mounted
            robot = LaserMountedRobot(connect_robot(args.robot, emu.address, **robot_options(args.robot, True)), laser)
        with robot:
            record = run_on_robot(spec(), robot, None, world).record
            scans = (laser.latest().seq + 1) if laser.latest() else 0
        # commands that asked the robot emulator for its own simulated laser (P3-DX's SIM_LRF_ENABLE)
        asked = sum(1 for cmd in getattr(emu, "commands", ()) if getattr(cmd, "cmd", None) in _SIM_LASER)
    diff = 100 * (record["coverage"] - embedded["coverage"])
    print(f"{args.robot} + {args.laser} emulators on pseudo-terminals, {'un' if args.unpaired else ''}paired "
          f"(speed-up {args.speedup:g} / laser "
          f"{laser_speedup:g}): coverage {record['coverage']:.4f}, completed "
          f"{record['completed']} ({record['reason']}), path {record['path_length_m']:.1f} m, collisions "
          f"{record['collisions']}, {scans} scans, {asked} simulated-laser requests, "
          f"{time.monotonic() - t0:.0f} s wall; "
          f"{diff:+.2f} points against the embedded simulator")
    return 0 if abs(diff) <= 2.0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
