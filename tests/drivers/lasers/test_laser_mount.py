"""A laser attached to a robot (robotexp.run.laser_mount): poses interpolated at a scan's stamp, echoes
re-expressed in the robot frame (hand-computed cases), and a Kobuki emulator plus an RPLidar emulator
on two pseudo-terminals: scans paired during a run, and the laser unplugged mid-run ends the run
within a second with the robot stopped and the partial result kept."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robotexp.errors import ConfigError
from robotexp.run.spec import RunSpec
from robotexp.experiment import run_on_robot
from robotexp.run.laser_mount import LaserMountedRobot, parse_laser_pose, parse_laser_spec
from robotexp.laser import PoseHistory, scan_in_robot_frame
from robotexp.run.observers import RunObserver
from robotexp.robot import LaserScan, Pose
from robotexp.sim import mounted_source
from robotexp.world.model import World
from robotexp_drivers.kobuki.codec import BaseControl
from robotexp_drivers.kobuki.emulator import KobukiEmulator
from robotexp_drivers.kobuki.robot import KobukiRobot
from robotexp_drivers.lasers.rplidar import RPLidarLaser
from robotexp_drivers.lasers.rplidar.emulator import RPLidarEmulator
from scan_sources import BoxSource


@pytest.mark.untimed
def test_pose_history_interpolates_across_the_heading_wrap() -> None:
    h = PoseHistory()
    assert h.at(1.0) is None
    h.add(1.0, Pose(0.0, 0.0, math.radians(170)))
    h.add(2.0, Pose(1.0, -2.0, math.radians(-170)))     # 20 deg counter-clockwise, across +-180
    h.add(2.0, Pose(9.0, 9.0, 0.0))                      # not after the last: dropped
    p = h.at(1.25)
    assert p is not None
    assert (p.x, p.y) == pytest.approx((0.25, -0.5)) and math.degrees(p.theta) == pytest.approx(175.0)
    assert h.at(0.5) is None and h.at(3.0) == Pose(1.0, -2.0, math.radians(-170))


def test_scan_in_robot_frame_by_hand() -> None:
    # the sensor was at (1, 1) facing +y when the robot, now at (1, 0) facing +x, took the scan
    scan = LaserScan(np.array([0.0, math.pi / 2, 0.1, -0.1]), np.array([2.0, 1.0, math.inf, 4.0]), 4.0)
    out = scan_in_robot_frame(scan, Pose(1.0, 1.0, math.pi / 2), Pose(1.0, 0.0, 0.0))
    assert out.offset_x == pytest.approx(0.0)
    # echo 0 at world (1, 3): robot frame (0, 3); echo 1 at world (0, 1): robot frame (-1, 1)
    assert out.angles[0] == pytest.approx(math.pi / 2) and out.ranges[0] == pytest.approx(3.0)
    assert out.angles[1] == pytest.approx(3 * math.pi / 4) and out.ranges[1] == pytest.approx(math.sqrt(2))
    # no echo (inf, or at range_max) keeps its direction, turned by the heading difference
    assert out.angles[2] == pytest.approx(math.pi / 2 + 0.1) and out.ranges[2] == math.inf
    assert out.angles[3] == pytest.approx(math.pi / 2 - 0.1) and out.ranges[3] == math.inf
    # the robot drove 0.5 m on from where a forward sensor 0.1 m ahead saw a wall at x = 2
    ahead = scan_in_robot_frame(LaserScan(np.array([0.0, 0.5]), np.array([1.9, 1.9 / math.cos(0.5)]), 4.0),
                                Pose(0.1, 0.0, 0.0), Pose(0.5, 0.0, 0.0))
    assert ahead.offset_x == pytest.approx(-0.4) and list(ahead.ranges) == pytest.approx([1.9, 1.9 / math.cos(0.5)])


def test_parsers() -> None:
    assert parse_laser_pose("100, -50, 90") == Pose(0.1, -0.05, math.pi / 2)
    assert parse_laser_spec("hokuyo:192.168.0.10:10940") == ("hokuyo", "192.168.0.10:10940")
    for bad in ("1,2", "a,b,c", "1,2,nan"):
        with pytest.raises(ConfigError, match="X,Y,THETA"):
            parse_laser_pose(bad)
    with pytest.raises(ConfigError, match="NAME:ADDRESS"):
        parse_laser_spec("/dev/ttyUSB0")


class _Unplug(RunObserver):
    """Closes the laser emulator once the run passes `after` s of robot time."""

    def __init__(self, emulator: RPLidarEmulator, after: float, cpu_wait: Any) -> None:
        self.emulator, self.after, self.cpu_wait = emulator, after, cpu_wait
        self.unplugged: float | None = None
        self.ended: float | None = None
        self.mark = self.waited = 0.0       # CPU wait: the total when it unplugged, then until the run ended

    def on_sample(self, run, t, coverage):  # noqa: ANN001, ANN201 - RunObserver's signature
        if t >= self.after and self.unplugged is None:
            self.unplugged, self.mark = time.monotonic(), self.cpu_wait.total()
            self.emulator.close()

    def on_end(self, run, record):  # noqa: ANN001, ANN201
        self.ended = time.monotonic()
        self.waited = self.cpu_wait.since(self.mark)


def test_rplidar_on_a_kobuki_unplugged_mid_run(world: World, start: Pose, tmp_path: Path, cpu_wait: Any) -> None:
    with KobukiEmulator(world, pose=start, speedup=10.0, pty=True) as kobuki, \
            RPLidarEmulator(mounted_source(kobuki.sim, lock=kobuki.lock), pty=True, speedup=10.0) as lidar:
        robot = LaserMountedRobot(KobukiRobot(kobuki.address), RPLidarLaser(lidar.address), Pose(0.0, 0.0, 0.0))
        unplug = _Unplug(lidar, after=8.0, cpu_wait=cpu_wait)
        with robot:
            assert "A1 series" in robot.describe()["laser"]
            spec = RunSpec(world="ufmg-static", robot="kobuki", method="frontier", pose="path1", speed=0.3,
                           max_time=120.0)
            out = run_on_robot(spec, robot, tmp_path, world, observers=[unplug])
        record = out.record
        assert robot.paired > 20, record                 # scans went out with interpolated poses
        assert not record["completed"] and "rplidar" in record["reason"]
        assert unplug.unplugged is not None and unplug.ended is not None
        # within a second, plus what a loaded machine kept the threads waiting for a CPU meanwhile
        assert unplug.ended - unplug.unplugged < 1.0 + unplug.waited
        assert 0.05 < record["coverage"] < 0.9          # it mapped until the laser went away
        lines = (tmp_path / "results.jsonl").read_text().splitlines()
        assert len(lines) == 1 and json.loads(lines[0])["coverage"] == record["coverage"]
        assert kobuki.last_base_control == BaseControl(0, 0)


def test_each_beam_placed_from_the_pose_at_its_own_time() -> None:
    # two beams straight ahead of the sensor, measured while the robot turned from 0 to 90 deg in place
    scan = LaserScan(np.array([0.0, 0.0]), np.array([2.0, 3.0]), 4.0)
    beams = (np.array([0.0, 0.0]), np.array([0.0, 0.0]), np.array([0.0, math.pi / 2]))
    out = scan_in_robot_frame(scan, Pose(0.0, 0.0, math.pi / 2), Pose(0.0, 0.0, math.pi / 2), beams)
    # beam 0 (heading 0) hit world (2, 0): from the robot now facing +y that is 90 deg to its right
    assert out.angles[0] == pytest.approx(-math.pi / 2) and out.ranges[0] == pytest.approx(2.0)
    assert out.angles[1] == pytest.approx(0.0) and out.ranges[1] == pytest.approx(3.0)


def test_rplidar_beam_offsets_follow_its_clockwise_turn() -> None:
    with RPLidarEmulator(BoxSource(), pty=True) as lidar, RPLidarLaser(lidar.address) as laser:
        offsets = laser.beam_offsets()
        period = laser.geometry.period
        angles = np.degrees(laser.geometry.angles())
        # the front is measured first (a whole turn before the stamp), then the right, back, left
        assert offsets[np.argmin(np.abs(angles))] == pytest.approx(-period)
        assert offsets[np.argmin(np.abs(angles + 90))] == pytest.approx(-0.75 * period)
        assert offsets[np.argmin(np.abs(angles - 90))] == pytest.approx(-0.25 * period)
        assert np.all((offsets <= 0) & (offsets >= -period))
