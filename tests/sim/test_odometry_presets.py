"""Odometry error presets: the P3-DX curves when told to go straight, by the amount its wheels predict."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from robotexp.errors import ConfigError
from robotexp.robot import Pose, Twist
from robotexp.sim import ODOMETRY_PRESETS, OdometryError, SimRobot, odometry_error, preset
from robotexp.world.model import World

DT = 0.1


def open_floor() -> World:
    """A 20 m square with one far wall: room to drive 5 m in any direction from the origin."""
    return World("floor", np.array([[9.9, 0.0, 0.05, 9.0, 0.0]]), bounds=(-10.0, -10.0, 10.0, 10.0))


def drive_straight(robot: SimRobot, distance: float, v: float = 0.25) -> None:
    """Command straight at `v` until odometry has covered `distance` (accelerating, then cruising)."""
    while robot.read().distance < distance - 1e-9:
        left = distance - robot.read().distance
        robot.command(Twist(min(v, left / DT), 0.0))
        robot.advance(DT)
    robot.command(Twist(0.0, 0.0))


def test_p3dx_preset_curves_when_commanded_straight() -> None:
    # Wheels servoed on encoders: each wheel turns by the same count, the right one (1 + m/2) larger
    # covers s (1 + m/2) and the left s (1 - m/2); the true path is an arc of radius b/m and length s
    # while odometry reads a straight line of length s.
    err = replace(ODOMETRY_PRESETS["p3dx"], slip_sigma=0.0)
    m, b = err.wheel_mismatch, preset("p3dx").wheel_base
    with SimRobot(open_floor(), pose=Pose(0.0, 0.0, 0.0), odometry=err, sonar=False) as robot:
        drive_straight(robot, 5.0)
        s = robot.read()
        assert s.true_pose is not None
        assert s.pose.y == pytest.approx(0.0, abs=1e-6) and s.pose.theta == pytest.approx(0.0, abs=1e-6)
        travelled = s.pose.x                          # odometry straight: its x is the distance
        assert 5.0 <= travelled < 5.05                # (the last step decelerates within a_max)
        phi = travelled * m / b
        radius = b / m
        assert s.true_pose.theta == pytest.approx(phi, rel=1e-6)
        assert s.true_pose.x == pytest.approx(radius * math.sin(phi), abs=1e-6)
        assert s.true_pose.y == pytest.approx(radius * (1 - math.cos(phi)), abs=1e-6)
        assert 0.3 < s.true_pose.y < 0.45 and math.degrees(phi) == pytest.approx(8.68, abs=0.01)


def test_p3dx_preset_with_slip_still_curves_by_about_that_much() -> None:
    m, b = ODOMETRY_PRESETS["p3dx"].wheel_mismatch, preset("p3dx").wheel_base
    with SimRobot(open_floor(), pose=Pose(0.0, 0.0, 0.0), odometry=ODOMETRY_PRESETS["p3dx"], seed=3,
                  sonar=False) as robot:
        drive_straight(robot, 5.0)
        s = robot.read()
        assert s.true_pose is not None
        # the slip makes odometry wander a little around the command: truth relative to odometry
        # still turns by m s / b
        rel = s.true_pose.theta - s.pose.theta
        assert rel == pytest.approx(5.0 * m / b, abs=0.02)


def test_heading_drift_accrues_per_metre() -> None:
    err = OdometryError(heading_drift=math.radians(1.0))
    with SimRobot(open_floor(), pose=Pose(0.0, 0.0, 0.0), odometry=err, sonar=False) as robot:
        drive_straight(robot, 4.0)
        s = robot.read()
        assert s.true_pose is not None and s.true_pose.theta == 0.0
        assert math.degrees(s.pose.theta) == pytest.approx(s.distance, rel=1e-9) and s.distance >= 4.0


def test_without_servo_the_truth_follows_the_command() -> None:
    err = replace(ODOMETRY_PRESETS["p3dx"], slip_sigma=0.0, wheel_servo=False)
    with SimRobot(open_floor(), pose=Pose(0.0, 0.0, 0.0), odometry=err, sonar=False) as robot:
        for _ in range(30):
            robot.command(Twist(0.3, 0.0))
            robot.advance(DT)
        s = robot.read()
        assert s.true_pose is not None and s.true_pose.y == 0.0 and s.pose.theta < 0.0


def test_odometry_error_spec_parsing() -> None:
    assert odometry_error("none") == OdometryError() and not odometry_error("none").active
    assert odometry_error("p3dx") is ODOMETRY_PRESETS["p3dx"]
    e = odometry_error("p3dx:mismatch=0.02,slip=0")
    assert e.wheel_mismatch == 0.02 and e.slip_sigma == 0.0 and e.wheel_servo
    e = odometry_error("mismatch=0.005,drift=0.5,servo=1")
    assert e.wheel_mismatch == 0.005 and e.heading_drift == pytest.approx(math.radians(0.5)) and e.wheel_servo
    for bad in ("pioneer", "p3dx:speed=1", "mismatch=abc", "mismatch=0.7", "drift=nan", "p3dx:slip"):
        with pytest.raises(ConfigError, match="odometry"):
            odometry_error(bad)
