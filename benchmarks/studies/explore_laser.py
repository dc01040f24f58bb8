"""Frontier exploration with a real laser protocol: a robot emulator plus a laser emulator, each on
its own pseudo-terminal, against the embedded simulator.

The laser emulator (any of `robotexp.laser_emulators`) measures from the robot emulator's simulated
robot (`robotexp.sim.mounted_source`, the sensor at the robot centre facing forward), its driver
reads it through the pseudo-terminal, and `robotexp.run.laser_mount.LaserMountedRobot` pairs each scan
with the robot's pose at the scan's stamp (`--unpaired`, Kobuki only: the Kobuki backend takes the
newest scan as it is, as if taken at the present pose). Both runs explore `--world` from `--pose` at 0.3 m/s; the script
prints each run's coverage, completion, path and the coverage difference in points.

Run: python benchmarks/studies/explore_laser.py [--robot kobuki] [--laser rplidar] [--world ufmg-static] [--pose path1]
     [--speedup 10] [--laser-speedup S] [--max-time 300] [--unpaired]
(--laser-speedup above --speedup makes scans fresher in robot time: a way to see what the missing
pose pairing costs.)
Exit status 1 when the coverages differ by more than 2 points.

`--direct BEAMS,FOV` (Kobuki only) takes no laser protocol at all: each state read gets a scan of
BEAMS beams over FOV degrees cast at that moment from the emulated robot's true pose (3 m, as the
run's map) - exact pairing, nothing late - to tell what the sensor's field of view does from what
the protocol and the pairing do (`--direct 181,180` is the embedded Kobuki's laser, `360,360` an
RPLidar's).

The pairing line measures what the pairing gets wrong: for each scan the run used, the robot pose it
was paired with (`LaserMountedRobot.last_pair`) against the emulated robot's true pose when that scan
ended (logged by the laser emulator's source at each measurement; a scan is found among them by its
ranges in whole mm: an LMS2xx or Hokuyo scan is measured at once; an RPLidar turn is measured in 18
pieces, found by its first piece, and ends when the next turn's first piece is measured), as the
median and 95th percentile of the position [mm] and heading [deg] errors, and the stamp's lateness
[ms]. It includes the odometry's own error (small on these emulators); scans not found (a piece lost
on a full pseudo-terminal) are left out.

The embedded simulator's run uses the robot preset's own laser (the Kobuki's: 181 beams over 180 deg),
not the laser emulated here (an RPLidar turns 360 deg): the two runs differ in the sensor too, not only
in the protocol. The P3-DX is connected as with a laser device mounted (`laser_mount.robot_options`:
no simulated-laser packets); the line counts the simulated-laser requests it sent (0 expected).
"""

from __future__ import annotations

import argparse
import math
import threading
import time
from typing import Any

import numpy as np
import numpy.typing as npt

from robotexp.run.spec import RunSpec
from robotexp.experiment import run_experiment, run_on_robot
from robotexp.laser import LASER_EMULATORS, LASERS, Laser, StampedScan
from robotexp.run.laser_mount import LaserMountedRobot, robot_options
from robotexp.registry import available, connect_robot, load, make_emulator
from robotexp.robot import LaserScan, Pose, Robot, RobotState, wrap_angle
from robotexp.sim import mounted_source
from robotexp.world.builtin import builtin_world
from robotexp_drivers.kobuki.robot import KobukiRobot
from robotexp_drivers.lasers.rplidar.codec import beam_index, node_angles_cw
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


class DirectScan:
    """The laser source `KobukiRobot` takes for `--direct`: a scan cast now from the simulator's true
    pose (exact, no protocol)."""

    def __init__(self, sim: Any, lock: Any, beams: int, fov_deg: float, reach: float) -> None:
        self.source = mounted_source(sim, lock=lock)
        full = fov_deg >= 360.0
        fov = math.radians(fov_deg)
        self.angles = (-math.pi + np.arange(beams) * 2 * math.pi / beams if full
                       else np.linspace(-fov / 2, fov / 2, beams))
        self.reach = reach

    def read(self) -> LaserScan:
        return LaserScan(self.angles, np.asarray(self.source(self.angles, self.reach)), self.reach)


class TruthLog:
    """A `ScanSource` that measures with `source` and logs the host time and the simulated robot's true
    pose at each measurement of a scan (the first call, a warm-up of one beam, is not one)."""

    def __init__(self, source: Any, sim: Any, lock: Any) -> None:
        self.source, self.sim, self.lock = source, sim, lock or threading.Lock()
        self.times: list[float] = []
        self.poses: list[Pose] = []
        self.by_ranges: dict[bytes, list[int]] = {}     # whole-mm ranges -> the measurements that gave them
        self.ranges: list[npt.NDArray[np.float64]] = []

    def __call__(self, angles: npt.NDArray[np.float64], reach: float) -> npt.NDArray[np.float64]:
        ranges = self.source(angles, reach)
        if len(angles) > 1:
            with self.lock:
                pose = self.sim.true_pose
            self.times.append(time.monotonic())
            self.poses.append(pose)
            self.by_ranges.setdefault(mm_key(np.asarray(ranges)), []).append(len(self.times) - 1)
            self.ranges.append(np.asarray(ranges, np.float64))
        return np.asarray(ranges)


def mm_key(ranges: npt.NDArray[np.float64]) -> bytes:
    """A scan's ranges in whole mm (echoes under 7.9 m; others -1) as a dictionary key."""
    r = np.asarray(ranges, np.float64)
    ok = np.isfinite(r) & (r < 7.9)
    return np.where(ok, np.rint(np.where(ok, r, 0.0) * 1000), -1).astype(np.int64).tobytes()


class PairLog(LaserMountedRobot):
    """A `LaserMountedRobot` that keeps each pairing it made: (scan seq, stamp, paired robot pose)."""

    pairs: list[tuple[StampedScan, Pose]]

    def _read(self) -> RobotState:
        state = super()._read()
        if self.last_pair is not None:
            self.pairs.append(self.last_pair)
        return state


def pairing_line(pairs: list[tuple[StampedScan, Pose]], truth: TruthLog, first_piece: npt.NDArray[np.int64] | None
                 ) -> str:
    """The pairing errors (see the module docstring); `first_piece`: an RPLidar turn's first piece's beams."""
    pos, head, late = [], [], []
    found = 0
    starts = np.arange(0, len(truth.ranges), 18)        # an RPLidar turn's first pieces
    if first_piece is not None and len(starts):
        firsts = np.nan_to_num(np.stack([truth.ranges[j] for j in starts]), posinf=-1.0)
    for stamped, pose in {p[0].seq: p for p in pairs}.values():
        stamp = stamped.stamp
        # the measurement with these ranges nearest in time (a turn: its first piece, within 2 mm; it
        # ends 18 pieces on)
        if first_piece is None:
            seen = truth.by_ranges.get(mm_key(stamped.scan.ranges), [])
        elif len(starts):
            r = np.nan_to_num(np.asarray(stamped.scan.ranges)[first_piece], nan=-2.0, posinf=-1.0)
            seen = [int(j) + 18 for j in starts[np.max(np.abs(firsts - r), axis=1) <= 0.002]]
        else:
            seen = []
        i = min(seen, key=lambda j: abs(truth.times[j] - stamp) if j < len(truth.times) else math.inf,
                default=len(truth.times))
        if i >= len(truth.times):
            continue
        found += 1
        true = truth.poses[i]
        pos.append(1000 * math.hypot(pose.x - true.x, pose.y - true.y))
        head.append(abs(math.degrees(wrap_angle(pose.theta - true.theta))))
        late.append(1000 * (stamp - truth.times[i]))
    if not pos:
        return "pairing: no scan to compare"
    q = [50, 95]
    p50, p95 = np.percentile(pos, q)
    h50, h95 = np.percentile(head, q)
    l50, l95 = np.percentile(late, q)
    used = len({p[0].seq for p in pairs})
    return (f"pairing over {found} of the {used} scans used: position error median {p50:.0f} mm, 95% {p95:.0f} mm; "
            f"heading "
            f"median {h50:.2f} deg, 95% {h95:.2f} deg; stamp minus true end median {l50:.1f} ms, 95% {l95:.1f} ms")


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
    parser.add_argument("--direct", default=None, metavar="BEAMS,FOV",
                        help="no laser protocol: an exact scan of BEAMS beams over FOV deg at each read (kobuki)")
    args = parser.parse_args()
    names = sorted(set(available(LASERS)) & set(available(LASER_EMULATORS)))
    if args.laser not in names:
        parser.error(f"--laser must be one of {', '.join(names)}, got {args.laser!r}")
    laser_speedup = args.speedup if args.laser_speedup is None else args.laser_speedup
    if not (args.speedup > 0 and args.max_time > 0 and laser_speedup > 0):
        parser.error("--speedup, --laser-speedup and --max-time must be > 0")
    driver = load(LASERS, args.laser, Laser)
    emulator_cls = load(LASER_EMULATORS, args.laser, object)
    if (args.unpaired or args.direct) and args.robot != "kobuki":
        parser.error("--unpaired and --direct need --robot kobuki (its backend takes a laser source)")
    direct = None
    if args.direct:
        try:
            beams, fov = (float(v) for v in args.direct.split(","))
        except ValueError:
            parser.error(f"--direct: give BEAMS,FOV (e.g. 360,360), got {args.direct!r}")
        if not (beams >= 2 and 0 < fov <= 360):
            parser.error(f"--direct: BEAMS >= 2 and 0 < FOV <= 360, got {args.direct!r}")
        direct = (int(beams), fov)
    world = builtin_world(args.world)

    def spec() -> RunSpec:
        return RunSpec(world=args.world, robot=args.robot, method="frontier", pose=args.pose, speed=0.3,
                       max_time=args.max_time)

    t0 = time.monotonic()
    embedded = run_experiment(spec(), None).record
    print(f"embedded simulator: coverage {embedded['coverage']:.4f}, completed {embedded['completed']} "
          f"({embedded['reason']}), robot time {embedded['robot_time_s']:.0f} s, "
          f"path {embedded['path_length_m']:.1f} m, {time.monotonic() - t0:.0f} s wall", flush=True)
    t0 = time.monotonic()
    emu: Any = make_emulator(args.robot, args.world, pose=args.pose, pty=True, speedup=args.speedup)
    truth = TruthLog(mounted_source(emu.sim, lock=getattr(emu, "lock", None)), emu.sim,     # the P3-DX emulator
                     getattr(emu, "lock", None))                                             # has no lock
    source = truth
    with emu.start(), emulator_cls(source, pty=True, speedup=laser_speedup) as lemu, \
            driver(lemu.address) as laser:
        if direct is not None:
            robot: Robot = KobukiRobot(emu.address, laser=DirectScan(emu.sim, emu.lock, *direct, reach=3.0))
        elif args.unpaired:
            robot = KobukiRobot(emu.address, laser=NewestScan(laser))
        else:
            # no simulated-laser packets: the robot is connected as with a laser device mounted
            robot = PairLog(connect_robot(args.robot, emu.address, **robot_options(args.robot, True)), laser)
            robot.pairs = []
        with robot:
            record = run_on_robot(spec(), robot, None, world).record
            scans = (laser.latest().seq + 1) if laser.latest() else 0
        first_piece = None
        if args.laser == "rplidar":         # 18 pieces a turn, each measured on its own
            n = lemu.samples
            first_piece = beam_index(node_angles_cw(n)[:n // 18], n)
        sent = len(truth.times) // (1 if first_piece is None else 18)
        pairing = "" if args.unpaired or direct else (pairing_line(robot.pairs, truth, first_piece)  # type: ignore[attr-defined]
                                                      + f" (scans measured {sent}, read {scans})")
        # commands that asked the robot emulator for its own simulated laser (P3-DX's SIM_LRF_ENABLE)
        asked = sum(1 for cmd in getattr(emu, "commands", ()) if getattr(cmd, "cmd", None) in _SIM_LASER)
    diff = 100 * (record["coverage"] - embedded["coverage"])
    how = (f"an exact {direct[0]}-beam {direct[1]:g} deg scan at each read (no laser protocol)" if direct
           else f"{args.laser} emulator, {'un' if args.unpaired else ''}paired")
    print(f"{args.robot} emulator + {how}, on pseudo-terminals "
          f"(speed-up {args.speedup:g} / laser "
          f"{laser_speedup:g}): coverage {record['coverage']:.4f}, completed "
          f"{record['completed']} ({record['reason']}), robot time {record['robot_time_s']:.0f} s, path "
          f"{record['path_length_m']:.1f} m, collisions "
          f"{record['collisions']}, {scans} scans, {asked} simulated-laser requests, "
          f"{time.monotonic() - t0:.0f} s wall; "
          f"{diff:+.2f} points against the embedded simulator")
    if pairing:
        print(pairing)
    return 0 if abs(diff) <= 2.0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
