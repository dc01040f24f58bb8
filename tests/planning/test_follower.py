"""robotexp.planning.follower: the laser safety corridor and the path follower.

Commands are checked against hand-computed values; following is checked by driving the real
SimRobot with them.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotexp.errors import ConfigError
from robotexp.planning.follower import FollowerConfig, PathFollower, blocked_ahead
from robotexp.robot import LaserScan, Limits, Pose, Twist, wrap_angle
from robotexp.sim import SimRobot
from robotexp.world.model import World, segment_box

R = 0.25                # [m] robot radius
LIM = Limits(v_max=0.5, w_max=2.0, a_max=0.5)
DT = 0.1


def scan_at(*points: tuple[float, float], offset_x: float = 0.0) -> LaserScan:
    """A scan whose beams return exactly at the given robot-frame points (x, y) [m] of the sensor."""
    angles = np.array([math.atan2(y, x) for x, y in points], dtype=np.float64)
    ranges = np.array([math.hypot(x, y) for x, y in points], dtype=np.float64)
    return LaserScan(angles, ranges, range_max=3.0, offset_x=offset_x)


# -- blocked_ahead -------------------------------------------------------------------------
# corridor: 0 < x < R + clearance + max(speed, 0.05) / 2, |y| < R + 0.02.
# With clearance 0.08 and speed 0.3: x < 0.48 and |y| < 0.27.

def test_a_return_straight_ahead_blocks() -> None:
    assert blocked_ahead(scan_at((0.3, 0.0)), R, 0.08, 0.3)


def test_the_same_return_to_the_side_does_not_block() -> None:
    assert not blocked_ahead(scan_at((0.3, 0.4)), R, 0.08, 0.3)
    assert not blocked_ahead(scan_at((0.3, -0.4)), R, 0.08, 0.3)


def test_a_return_behind_does_not_block() -> None:
    assert not blocked_ahead(scan_at((-0.3, 0.0)), R, 0.08, 0.3)


def test_nothing_blocks_when_not_moving_forward() -> None:
    assert not blocked_ahead(scan_at((0.3, 0.0)), R, 0.08, 0.0)
    assert not blocked_ahead(scan_at((0.3, 0.0)), R, 0.08, -0.2)
    assert not blocked_ahead(None, R, 0.08, 0.3)


def test_corridor_edges_by_hand() -> None:
    assert blocked_ahead(scan_at((0.3, 0.26)), R, 0.08, 0.3)         # |y| 0.26 < 0.27
    assert not blocked_ahead(scan_at((0.3, 0.28)), R, 0.08, 0.3)
    assert blocked_ahead(scan_at((0.47, 0.0)), R, 0.08, 0.3)         # x 0.47 < 0.48
    assert not blocked_ahead(scan_at((0.49, 0.0)), R, 0.08, 0.3)
    # faster: the corridor grows with the stopping distance (speed / 2): at 0.6 m/s x < 0.63
    assert blocked_ahead(scan_at((0.6, 0.0)), R, 0.08, 0.6)
    assert not blocked_ahead(scan_at((0.6, 0.0)), R, 0.08, 0.3)
    # crawling: at least 0.05 m/s counts, x < 0.355
    assert blocked_ahead(scan_at((0.35, 0.0)), R, 0.08, 0.001)
    assert not blocked_ahead(scan_at((0.36, 0.0)), R, 0.08, 0.001)


def test_infinite_ranges_and_sensor_offset() -> None:
    far = LaserScan(np.array([-0.1, 0.0, 0.1]), np.full(3, math.inf), 3.0)
    assert not blocked_ahead(far, R, 0.08, 0.5)
    # a sensor 0.2 m ahead of the centre: a return 0.3 m from it is 0.5 m from the centre
    assert not blocked_ahead(scan_at((0.3, 0.0), offset_x=0.2), R, 0.08, 0.3)
    assert blocked_ahead(scan_at((0.2, 0.0), offset_x=0.2), R, 0.08, 0.3)


# -- commands by hand ----------------------------------------------------------------------

def test_turns_in_place_above_50_degrees() -> None:
    f = PathFollower(LIM, R)
    for deg, w in ((90, 2.0), (60, 2.0), (-55, -2 * math.radians(55))):   # k_turn 2, |w| <= 2
        a = math.radians(deg)
        f.set_path(np.array([[0.0, 0.0], [2 * math.cos(a), 2 * math.sin(a)]]))
        twist = f.twist(Pose(0.0, 0.0, 0.0))
        assert twist.v == 0.0
        assert twist.w == pytest.approx(w)
    # 45 deg: drives and turns, v = v_max cos(err) (the end is 2 m away: no ramp, no braking)
    f.set_path(np.array([[0.0, 0.0], [math.sqrt(2), math.sqrt(2)]]))
    twist = f.twist(Pose(0.0, 0.0, 0.0))
    assert twist.v == pytest.approx(0.5 * math.cos(math.pi / 4))
    assert twist.w == pytest.approx(2 * math.pi / 4)


def test_speed_ramps_down_and_brakes_near_the_end() -> None:
    f = PathFollower(LIM, R)
    f.set_path(np.array([[0.0, 0.0], [0.3, 0.0]]))
    # ramp: 0.5 * min(1, 0.3 / 0.5 + 0.2) = 0.4; braking sqrt(2 * 0.5 * 0.3) + 0.02 = 0.568
    assert f.twist(Pose(0.0, 0.0, 0.0)) == Twist(pytest.approx(0.4), 0.0)
    slow = PathFollower(Limits(0.5, 2.0, a_max=0.1), R)
    slow.set_path(np.array([[0.0, 0.0], [0.3, 0.0]]))
    # braking: sqrt(2 * 0.1 * 0.3) + 0.02 = 0.2649 < 0.4
    assert slow.twist(Pose(0.0, 0.0, 0.0)).v == pytest.approx(math.sqrt(0.06) + 0.02)


def test_an_obstacle_ahead_stops_forward_motion() -> None:
    f = PathFollower(LIM, R)
    f.set_path(np.array([[0.0, 0.0], [2.0, 0.2]]))
    pose = Pose(0.0, 0.0, 0.0)
    twist = f.twist(pose, scan_at((0.3, 0.0)))
    assert f.blocked
    assert twist == Twist(0.0, pytest.approx(2 * math.atan2(0.2, 2.0)))     # still turns
    twist = f.twist(pose, scan_at((0.3, 0.6)))                               # off to the side: go
    assert not f.blocked and twist.v > 0.4


def test_done_within_goal_tolerance_and_cleared() -> None:
    f = PathFollower(LIM, R)
    assert f.done and f.twist(Pose(0.0, 0.0)) == Twist.ZERO          # no path yet
    f.set_path(np.array([[0.8, 0.0], [1.0, 0.0]]))    # a path starts where the robot stands
    assert not f.done
    assert f.twist(Pose(0.84, 0.0, 0.0)).v > 0 and not f.done          # 0.16 m from the end: not yet
    assert f.twist(Pose(0.86, 0.0, 0.0)) == Twist.ZERO and f.done      # 0.14 m < 0.15 m: done
    assert f.twist(Pose(0.0, 0.0, 0.0)) == Twist.ZERO                  # stays done
    f.set_path(np.array([[0.0, 0.0], [1.0, 0.0]]))
    f.clear()
    assert f.done and f.path.shape == (0, 2)


def test_remaining_by_hand() -> None:
    f = PathFollower(LIM, R)
    assert f.remaining(Pose(5.0, 5.0)) == 0.0                      # no path
    f.set_path(np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 4.0]]))
    assert f.remaining(Pose(0.0, 0.0)) == pytest.approx(7.0)
    assert f.remaining(Pose(1.0, 1.0)) == pytest.approx(math.sqrt(2) + 7.0)  # to the first point, then along
    f.twist(Pose(0.1, 0.0, 0.0))                                   # passes (0, 0): within the 0.2 m look-ahead
    assert f.remaining(Pose(0.1, 0.0)) == pytest.approx(2.9 + 4.0)
    f.twist(Pose(2.9, 0.0, 0.0))                                   # passes (3, 0)
    assert f.remaining(Pose(2.9, 0.0)) == pytest.approx(math.hypot(0.1, 4.0))
    f.twist(Pose(3.0, 3.9, math.pi / 2))                           # within 0.15 m of the end: done
    assert f.done and f.remaining(Pose(3.0, 3.9)) == 0.0


def test_turn_to_by_hand() -> None:
    f = PathFollower(LIM, R)
    assert f.turn_to(Pose(0.0, 0.0, 0.0), math.radians(4.9)) == (Twist.ZERO, True)
    twist, reached = f.turn_to(Pose(0.0, 0.0, 3.0), -3.0)          # the short way: +0.283 rad across pi
    assert not reached and twist == Twist(0.0, pytest.approx(2 * (2 * math.pi - 6.0)))
    twist, reached = f.turn_to(Pose(0.0, 0.0, 0.0), -math.pi / 2)
    assert not reached and twist == Twist(0.0, -2.0)


def test_config_is_checked() -> None:
    for bad in ({"lookahead": 0.0}, {"goal_tolerance": -0.1}, {"k_turn": 0.0}, {"clearance": -0.01}):
        with pytest.raises(ConfigError, match="path follower"):
            FollowerConfig(**bad)  # type: ignore[arg-type]


# -- driving the simulator -----------------------------------------------------------------

def open_room() -> World:
    """An empty 10 x 10 m room centred on the origin."""
    t, h = 0.1, 5.0
    return World("open", np.array([segment_box(-h, -h, h, -h, t), segment_box(-h, h, h, h, t),
                                   segment_box(-h, -h, -h, h, t), segment_box(h, -h, h, h, t)]))


def follow(robot: SimRobot, follower: PathFollower, max_steps: int) -> tuple[int, list[Pose]]:
    """Drive `robot` with `follower` until done; return the steps taken and the true poses."""
    poses = []
    for step in range(max_steps):
        state = robot.read()
        assert state.true_pose is not None
        poses.append(state.true_pose)
        twist = follower.twist(state.pose, state.laser)
        if follower.done:
            return step, poses
        robot.command(twist)
        robot.advance(DT)
    return max_steps, poses


def test_follows_a_straight_path_to_its_end() -> None:
    with SimRobot(open_room(), pose=Pose(-2.0, 0.0, 0.0), max_speed=0.5, sonar=False) as robot:
        f = PathFollower(robot.limits, robot.radius)
        f.set_path(np.array([[-2.0, 0.0], [1.0, 0.0]]))
        steps, poses = follow(robot, f, 300)
        assert f.done
        # 3 m at up to 0.5 m/s with a 0.3 m/s^2 ramp: ~8 s; allow twice that
        assert steps < 160
        end = poses[-1]
        assert end.distance_to(Pose(1.0, 0.0)) < 0.15
        assert max(abs(p.y) for p in poses) < 1e-9                  # straight: never left the line
        assert robot.collisions == 0


def test_follows_a_corner_without_cutting_it() -> None:
    with SimRobot(open_room(), pose=Pose(0.0, 0.0, 0.0), max_speed=0.5, sonar=False) as robot:
        f = PathFollower(robot.limits, robot.radius)
        f.set_path(np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]]))
        steps, poses = follow(robot, f, 400)
        assert f.done and steps < 400
        assert poses[-1].distance_to(Pose(2.0, 2.0)) < 0.15
        # the robot passed within the look-ahead (plus the turn) of the corner
        assert min(p.distance_to(Pose(2.0, 0.0)) for p in poses) < 0.3


def test_turn_to_converges_on_the_simulator() -> None:
    with SimRobot(open_room(), pose=Pose(0.0, 0.0, 0.0), max_speed=0.5, sonar=False) as robot:
        f = PathFollower(robot.limits, robot.radius)
        target = 2.5
        for _ in range(200):
            pose = robot.read().pose
            twist, reached = f.turn_to(pose, target)
            if reached:
                break
            assert twist.v == 0.0
            robot.command(twist)
            robot.advance(DT)
        assert reached, f"not facing {target} rad after 200 steps"
        final = robot.read()
        assert abs(wrap_angle(final.pose.theta - target)) < math.radians(5)
        assert final.true_pose is not None and final.true_pose.distance_to(Pose(0.0, 0.0)) < 1e-9
