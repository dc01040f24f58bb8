"""The data types of robotexp.robot, GridGeometry and the clocks, against hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robotexp.clock import SimClock, WallClock
from robotexp.errors import ConfigError, RobotError
from robotexp.mapping.geometry import GridGeometry
from robotexp.robot import LaserScan, Limits, Pose, Robot, RobotState, Twist, sensor_origin, wrap_angle

# -- Limits.clamp --------------------------------------------------------------------------

LIM = Limits(v_max=0.5, w_max=2.0)


@pytest.mark.parametrize(("given_twist", "expected"), [
    (Twist(0.3, -1.0), Twist(0.3, -1.0)),            # inside: unchanged
    (Twist(0.9, 5.0), Twist(0.5, 2.0)),              # above both maxima
    (Twist(-0.9, -5.0), Twist(-0.5, -2.0)),          # below both minima: clamped to -max, not 0
    (Twist(0.5, -2.0), Twist(0.5, -2.0)),            # exactly on the limits
    (Twist(math.inf, -math.inf), Twist(0.5, -2.0)),
    (Twist(math.nan, 1.0), Twist(0.0, 1.0)),          # NaN becomes 0, the other part is kept
    (Twist(-0.2, math.nan), Twist(-0.2, 0.0)),
])
def test_limits_clamp(given_twist: Twist, expected: Twist) -> None:
    assert LIM.clamp(given_twist) == expected


def test_limits_defaults() -> None:
    assert (LIM.a_max, LIM.alpha_max) == (0.5, 2.0)


# -- wrap_angle ----------------------------------------------------------------------------

@pytest.mark.parametrize(("angle", "expected"), [
    (0.0, 0.0),
    (math.pi, -math.pi),                  # +pi is outside [-pi, pi): it wraps to -pi
    (-math.pi, -math.pi),
    (3 * math.pi, -math.pi),
    (-3 * math.pi, -math.pi),
    (math.pi / 2, math.pi / 2),
    (2 * math.pi + 0.5, 0.5),
    (-2 * math.pi - 0.5, -0.5),
    (math.radians(270), math.radians(-90)),
    (math.radians(-190), math.radians(170)),
])
def test_wrap_angle_values(angle: float, expected: float) -> None:
    assert wrap_angle(angle) == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize("angle", [
    math.nextafter(math.pi, 0.0), math.nextafter(math.pi, 4.0),
    math.nextafter(-math.pi, 0.0),
    math.nextafter(-math.pi, -4.0),     # (angle + pi) % 2 pi rounds up to 2 pi here: +pi came out
    -1e-300, 1e-300, math.nextafter(3 * math.pi, 0.0), math.nextafter(-3 * math.pi, -10.0),
])
def test_wrap_angle_next_to_the_edges(angle: float) -> None:
    w = wrap_angle(angle)
    assert -math.pi <= w < math.pi
    assert math.cos(w) == pytest.approx(math.cos(angle), abs=1e-12)
    assert math.sin(w) == pytest.approx(math.sin(angle), abs=1e-12)


@given(st.floats(min_value=-1e6, max_value=1e6, allow_nan=False))
def test_wrap_angle_range_and_equivalence(angle: float) -> None:
    w = wrap_angle(angle)
    assert -math.pi <= w < math.pi
    # the same direction: sin and cos agree (tolerance grows with |angle| through the modulo)
    tol = 1e-9 * max(1.0, abs(angle))
    assert math.sin(w) == pytest.approx(math.sin(angle), abs=tol)
    assert math.cos(w) == pytest.approx(math.cos(angle), abs=tol)


# -- Pose, LaserScan -----------------------------------------------------------------------

def test_pose_distance_to() -> None:
    a, b = Pose(1.0, 2.0, 0.3), Pose(4.0, 6.0, -2.0)
    assert a.distance_to(b) == 5.0                    # 3-4-5, heading ignored
    assert b.distance_to(a) == 5.0
    assert a.distance_to(Pose(1.0, 2.0, 1.0)) == 0.0
    assert Pose(-1.5, 0.0).distance_to(Pose(0.0, 2.0)) == pytest.approx(2.5)


def test_pose_as_list_gives_plain_floats() -> None:
    values = Pose(np.float64(1.5), np.float32(-2.0), np.float64(0.25)).as_list()
    assert values == [1.5, -2.0, 0.25]
    assert all(type(v) is float for v in values)


def test_laser_scan_nearest() -> None:
    angles = np.array([-0.1, 0.0, 0.1])
    assert LaserScan(angles, np.array([2.0, math.inf, 0.7]), 3.0).nearest() == 0.7
    assert LaserScan(angles, np.full(3, math.inf), 3.0).nearest() == math.inf


def test_the_laser_stands_its_offset_ahead_along_the_heading() -> None:
    # a robot at (1, 2) facing +y (90 deg) with its laser 0.2 m ahead: the laser is at (1, 2.2)
    x, y = LaserScan(np.zeros(1), np.ones(1), 3.0, offset_x=0.2).origin(Pose(1.0, 2.0, math.pi / 2))
    assert x == pytest.approx(1.0, abs=1e-12) and y == pytest.approx(2.2, abs=1e-12)
    # facing 180 deg, 0.3 m ahead: 0.3 m towards -x
    assert sensor_origin(Pose(0.5, -1.0, math.pi), 0.3) == pytest.approx((0.2, -1.0), abs=1e-12)
    assert sensor_origin(Pose(0.5, -1.0, 0.7), 0.0) == (0.5, -1.0)


# -- GridGeometry --------------------------------------------------------------------------

def test_covering_aligns_on_cell_multiples() -> None:
    # cell 0.25 m (exact in binary): origin floor(-1.1 / 0.25) = -5 -> -1.25, floor(0.3 / 0.25) = 1 -> 0.25;
    # cols ceil((2.0 + 1.25) / 0.25) = 13, rows ceil((1.0 - 0.25) / 0.25) = 3
    assert GridGeometry.covering(-1.1, 0.3, 2.0, 1.0, cell=0.25) == GridGeometry(-1.25, 0.25, 0.25, 3, 13)


def test_covering_with_margin_and_exact_fit() -> None:
    # a box already on cell multiples gets no extra row or column
    assert GridGeometry.covering(0.0, 0.0, 1.0, 1.0, cell=0.25) == GridGeometry(0.0, 0.0, 0.25, 4, 4)
    # margin 0.5: x -0.5..1.5, y -0.5..1.5 -> 8 x 8
    assert GridGeometry.covering(0.0, 0.0, 1.0, 1.0, cell=0.25, margin=0.5) == GridGeometry(-0.5, -0.5, 0.25, 8, 8)
    # a degenerate box still has one cell
    assert GridGeometry.covering(0.1, 0.1, 0.1, 0.1, cell=0.25) == GridGeometry(0.0, 0.0, 0.25, 1, 1)


def test_cell_of_center_of_contains() -> None:
    geo = GridGeometry(-1.25, 0.25, 0.25, 3, 13)
    assert geo.cell_of(-1.25, 0.25) == (0, 0)                  # the lower-left corner is in cell (0, 0)
    assert geo.cell_of(-1.0, 0.5) == (1, 1)                    # a cell border belongs to the upper cell
    assert geo.cell_of(-1.01, 0.49) == (0, 0)
    assert geo.cell_of(1.9, 0.9) == (2, 12)
    assert geo.cell_of(-1.26, 0.2) == (-1, -1)                 # outside: floors, not truncates
    assert geo.cell_of(2.0, 1.0) == (3, 13)
    assert geo.center_of(0, 0) == (-1.125, 0.375)
    assert geo.center_of(2, 12) == (1.875, 0.875)
    assert geo.cell_of(*geo.center_of(1, 7)) == (1, 7)
    assert geo.contains(0, 0) and geo.contains(2, 12)
    assert not geo.contains(3, 0) and not geo.contains(0, 13) and not geo.contains(-1, 5)
    assert (geo.width, geo.height) == (3.25, 0.75)


# -- clocks --------------------------------------------------------------------------------

def test_sim_clock_advances_by_the_period() -> None:
    advanced: list[float] = []
    clock = SimClock(0.1, advanced.append)
    assert clock.now() == 0.0 and advanced == []
    for _ in range(3):
        clock.tick()
    assert advanced == [0.1, 0.1, 0.1]
    assert clock.now() == pytest.approx(0.3)
    assert clock.period == 0.1


def test_wall_clock_tick_waits_a_period() -> None:
    period = 0.03
    clock = WallClock(period)
    clock.tick()
    assert clock.now() >= period - 1e-3
    clock.tick()
    # each tick ends at the next multiple of the period after the clock started (lower bounds only)
    assert clock.now() >= 2 * period - 1e-3


# -- the Robot base class with a minimal in-memory backend ---------------------------------

class _MemoryRobot(Robot):
    """A backend whose link is a list: records every command and the close."""

    name = "memory"

    def __init__(self) -> None:
        self.limits = Limits(v_max=0.5, w_max=1.0)
        self.log: list[object] = []
        super().__init__()

    def _read(self) -> RobotState:
        return RobotState(time=0.0, pose=Pose(0.0, 0.0), velocity=Twist.ZERO)

    def _command(self, twist: Twist) -> None:
        self.log.append(twist)

    def _close(self) -> None:
        self.log.append("closed")


def test_robot_base_clamps_stops_on_close_and_refuses_when_closed() -> None:
    robot = _MemoryRobot()
    with robot:
        robot.command(Twist(2.0, -3.0))
        robot.stop()
        assert robot.read().pose == Pose(0.0, 0.0)
    assert robot.closed
    assert robot.log == [Twist(0.5, -1.0), Twist.ZERO, Twist.ZERO, "closed"]
    robot.close()                                              # twice: nothing more happens
    assert robot.log[-1] == "closed" and len(robot.log) == 4
    with pytest.raises(RobotError, match="memory: the robot is closed"):
        robot.read()
    with pytest.raises(RobotError, match="closed"):
        robot.command(Twist.ZERO)


def test_robot_set_max_speed() -> None:
    with _MemoryRobot() as robot:
        robot.set_max_speed(0.2)
        assert robot.limits == Limits(0.2, 1.0)
        robot.command(Twist(1.0, 0.0))
        assert robot.log[-1] == Twist(0.2, 0.0)
        for bad in (0.0, -1.0, math.nan):
            with pytest.raises(ConfigError, match="max speed must be > 0"):
                robot.set_max_speed(bad)
