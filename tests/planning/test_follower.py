"""robotexp.planning.follower: the laser safety corridor and the path follower.

Commands are checked against hand-computed values; following is checked by driving the real
SimRobot with them.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotexp.errors import ConfigError
from robotexp.planning.follower import (FollowerConfig, PathFollower, _sweep_blocked, blocked_ahead, free_heading,
                                        roomy_cells, scan_clearance, sweep_blocked_reference)
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
# The disc of radius R swept along the command's arc for the stopping distance v^2 / (2 a_max) plus
# REACTION (0.2 s) at v plus the clearance; a return blocks when the disc comes within R + clearance
# of it and nearer than it is now. With v 0.3 m/s, a_max 0.5 and clearance 0.01: the centre moves
# 0.09 + 0.06 + 0.01 = 0.16 m and a return blocks within 0.26 m of that path.

def test_a_return_straight_ahead_blocks_within_the_stopping_distance() -> None:
    assert blocked_ahead(scan_at((0.41, 0.0)), R, 0.01, 0.3)          # 0.41 - 0.16 = 0.25 < 0.26
    assert not blocked_ahead(scan_at((0.43, 0.0)), R, 0.01, 0.3)      # 0.27


def test_the_swept_disc_by_hand_at_the_side() -> None:
    assert blocked_ahead(scan_at((0.1, 0.25)), R, 0.01, 0.3)          # the disc passes 0.25 from it
    assert not blocked_ahead(scan_at((0.1, 0.27)), R, 0.01, 0.3)      # 0.27: the robot slides past
    assert not blocked_ahead(scan_at((0.5, 0.265)), R, 0.01, 0.3)     # a wall 1.5 cm off the robot's side


def test_a_return_the_robot_moves_away_from_does_not_block() -> None:
    # 0.255 m from the centre (within R + 0.01) but behind it: driving on takes the disc away
    assert not blocked_ahead(scan_at((-0.05, 0.25)), R, 0.01, 0.3)
    assert not blocked_ahead(scan_at((-0.3, 0.0)), R, 0.01, 0.3)


def side(deg: float, r: float) -> tuple[float, float]:
    return r * math.cos(math.radians(deg)), r * math.sin(math.radians(deg))


def test_a_return_a_few_degrees_ahead_of_the_side_is_slid_past() -> None:
    """A return at 85 deg, 0.26 m off (within R + clearance already): driving straight on brings the disc's
    centre 0.26 (1 - sin 85 deg) = 1.0 mm nearer, then away. That does not block (it left a robot standing
    in laser noise for good); 75 deg (8.9 mm nearer) does, and so does coming within 2 mm of touching."""
    for v in (0.05, 0.3):
        assert not blocked_ahead(scan_at(side(85.0, 0.26)), R, 0.01, v)
    assert blocked_ahead(scan_at(side(75.0, 0.26)), R, 0.01, 0.3)       # the sweep (0.16 m) passes 0.067 m
    assert blocked_ahead(scan_at(side(88.0, 0.251)), R, 0.01, 0.05)     # 0.2509 m at best: 0.9 mm to spare
    f = PathFollower(LIM, R)
    f.set_path(np.array([[0.0, 0.0], [2.0, 0.0]]))
    twist = f.twist(Pose(0.0, 0.0, 0.0), scan_at(side(85.0, 0.26), side(86.0, 0.262), side(90.0, 0.28)))
    assert not f.blocked and twist.v > 0.1


def test_the_arc_of_a_turning_command_is_swept() -> None:
    # w 1 rad/s at 0.3 m/s: a circle of 0.3 m radius to the left; after 0.16 m the centre is at
    # (0.3 sin(0.533), 0.3 (1 - cos(0.533))) = (0.1525, 0.0417)
    assert blocked_ahead(scan_at((0.2, 0.27)), R, 0.01, 0.3, 1.0)     # 0.233 m from there
    assert not blocked_ahead(scan_at((0.2, 0.27)), R, 0.01, 0.3)      # straight on: 0.273 m at best
    assert blocked_ahead(scan_at((0.2, -0.25)), R, 0.01, 0.3)         # straight on: 0.253 m
    assert not blocked_ahead(scan_at((0.2, -0.25)), R, 0.01, 0.3, 1.0)


def test_nothing_blocks_when_not_moving_forward() -> None:
    assert not blocked_ahead(scan_at((0.3, 0.0)), R, 0.01, 0.0)
    assert not blocked_ahead(scan_at((0.3, 0.0)), R, 0.01, -0.2)
    assert not blocked_ahead(None, R, 0.01, 0.3)


def test_the_swept_length_grows_with_the_speed() -> None:
    # 0.6 m/s: 0.36 + 0.12 + 0.01 = 0.49 m, a return straight ahead blocks within 0.75 m
    assert blocked_ahead(scan_at((0.7, 0.0)), R, 0.01, 0.6)
    assert not blocked_ahead(scan_at((0.7, 0.0)), R, 0.01, 0.3)
    assert not blocked_ahead(scan_at((0.76, 0.0)), R, 0.01, 0.6)
    # crawling at 1 mm/s: 0.0102 m, within 0.2702 m
    assert blocked_ahead(scan_at((0.265, 0.0)), R, 0.01, 0.001)
    assert not blocked_ahead(scan_at((0.275, 0.0)), R, 0.01, 0.001)


def test_infinite_ranges_and_sensor_offset() -> None:
    far = LaserScan(np.array([-0.1, 0.0, 0.1]), np.full(3, math.inf), 3.0)
    assert not blocked_ahead(far, R, 0.01, 0.5)
    # a sensor 0.2 m ahead of the centre: a return 0.3 m from it is 0.5 m from the centre
    assert not blocked_ahead(scan_at((0.3, 0.0), offset_x=0.2), R, 0.01, 0.3)
    assert blocked_ahead(scan_at((0.2, 0.0), offset_x=0.2), R, 0.01, 0.3)


def test_the_sweep_kernel_agrees_with_its_numpy_reference() -> None:
    """The swept-disc guard's kernel against the numpy sweep it replaces, on returns scattered round the robot
    at the blocking distances (both outcomes occur), straight, turning either way and crawling."""
    rng = np.random.default_rng(11)
    outcomes = []
    for _ in range(400):
        n = int(rng.integers(0, 30))
        pts = rng.uniform(-0.2, 0.8, size=(n, 2)) * [1.0, 0.6] + [0.0, rng.uniform(-0.2, 0.2)]
        norms = np.hypot(pts[:, 0], pts[:, 1])
        speed, turn = float(rng.choice([0.001, 0.05, 0.3, 0.6])), float(rng.choice([0.0, 1e-10, 0.8, -1.5]))
        want = sweep_blocked_reference(pts, norms, R, 0.01, speed, turn, 0.5)
        assert _sweep_blocked(pts, norms, R, 0.01, speed, turn, 0.5) == want
        outcomes.append(want)
    assert 50 < sum(outcomes) < 350


def test_free_heading_slides_along_a_wall_ahead() -> None:
    # a wall across at x = 0.27 m (2 cm off the disc), at 0.08 m/s: the centre moves 0.0064 + 0.016 + 0.01
    # = 0.0324 m, so heading a brings it within 0.26 of the wall when 0.27 - 0.0324 cos a < 0.26, i.e.
    # a < 72 deg: the nearest free direction in 10 deg steps is 80 deg, to the left first
    wall = scan_at(*[(0.27, y) for y in np.linspace(-1.0, 1.0, 2001)])
    assert blocked_ahead(wall, R, 0.01, 0.08)
    assert free_heading(wall, R, 0.01, 0.08, 0.0) == pytest.approx(math.radians(80))
    assert free_heading(wall, R, 0.01, 0.08, math.radians(-30)) == pytest.approx(math.radians(-80))
    assert free_heading(wall, R, 0.01, 0.08, 0.0, widest=math.radians(60)) is None
    assert free_heading(scan_at((2.0, 0.0)), R, 0.01, 0.08, 0.3) == pytest.approx(0.3)     # free: as asked


def test_scan_clearance_by_hand() -> None:
    assert scan_clearance(scan_at((0.3, 0.4), (0.0, -0.6)), R) == pytest.approx(0.5 - R)
    assert scan_clearance(None, R) == math.inf


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


# -- the robot's own motion (drift_blocked) ------------------------------------------------------
# A robot moving at 0.3 m/s (a_max 0.3 m/s^2, alpha_max 1.75 rad/s^2, the P3-DX's) straight on, told to
# go on: 0.2 s at 0.3 m/s, then braking 0.3^2 / (2 * 0.3) = 0.15 m, 0.21 m in all (the trapezoid rule is exact
# on these ramps).

def test_the_drift_straight_on_by_hand() -> None:
    from robotexp.planning.follower import drift_poses

    poses = drift_poses(0.3, 0.0, 0.3, 0.0, 0.3, 1.75)
    assert poses[-1] == pytest.approx([0.21, 0.0, 0.0], abs=1e-9)
    assert (np.diff(poses[:, 0]) >= 0).all()


def test_a_robot_swinging_left_is_stopped_by_a_return_its_swing_reaches() -> None:
    """Swinging left at 1.5 rad/s and told to turn right at 1.1 rad/s, the robot still swings left for most
    of a second (its turn rate falls at 1.75 rad/s^2): in the 0.2 s told and the 1 s braking from 0.3 m/s it
    turns 1.5 * 1.2 - 1.75 * 1.2^2 / 2 = 0.54 rad left and ends 8 cm left of its heading.
    A return at (0.25, 0.30) lies 0.22 m from that end, inside the disc; the command's arc curves right,
    0.39 m from it, and sees nothing. The same return does not block a robot already turning right."""
    from robotexp.planning.follower import drift_blocked, drift_poses
    from robotexp.robot import Footprint

    end = drift_poses(0.3, 1.5, 0.3, -1.1, 0.3, 1.75)[-1]
    assert end == pytest.approx([0.19, 0.08, 0.54], abs=0.005)
    scan = scan_at((0.25, 0.30))
    pts = np.array([[0.25, 0.30]])
    disc = Footprint.disc(R)
    assert not blocked_ahead(scan, R, 0.01, 0.3, -1.1, a_max=0.3)
    assert drift_blocked(pts, disc, 0.01, 0.3, 1.5, 0.3, -1.1, 0.3, 1.75)
    assert not drift_blocked(pts, disc, 0.01, 0.3, -1.1, 0.3, -1.1, 0.3, 1.75)
    assert not drift_blocked(pts, disc, 0.01, 0.04, 1.5, 0.3, -1.1, 0.3, 1.75)    # slower than DRIFT_SPEED
    # the follower told the robot's velocity stops its translation; not told, it drives on
    lim = Limits(v_max=0.3, w_max=5.2, a_max=0.3, alpha_max=1.75)
    path = np.array([[0.0, 0.0], [0.5, -0.1], [1.0, -0.3]])
    for velocity, stops in ((Twist(0.3, 1.5), True), (None, False), (Twist(0.3, -0.4), False)):
        f = PathFollower(lim, R)
        f.set_path(path)
        twist = f.twist(Pose(0.0, 0.0, 0.0), scan, velocity)
        assert (twist.v == 0.0) == stops and f.blocked == stops, velocity


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
    assert f.remaining(Pose(1.0, 1.0)) == pytest.approx(math.hypot(2.0, 1.0) + 4.0)  # to the end of the segment, on
    f.twist(Pose(0.1, 0.0, 0.0))                                   # on the first segment
    assert f.remaining(Pose(0.1, 0.0)) == pytest.approx(2.9 + 4.0)
    f.twist(Pose(2.9, 0.0, 0.0))                                   # still on the first segment
    assert f.remaining(Pose(2.9, 0.0)) == pytest.approx(0.1 + 4.0)
    f.twist(Pose(3.05, 0.1, math.pi / 2))                          # on the second: projected at (3, 0.1)
    assert f.remaining(Pose(3.05, 0.1)) == pytest.approx(math.hypot(0.05, 3.9))
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


def test_roomy_cells_by_hand() -> None:
    passable = np.ones((5, 6), dtype=bool)
    passable[2, 3] = False
    roomy = roomy_cells(passable)
    want = np.zeros((5, 6), dtype=bool)
    want[1:4, 1:5] = True                 # off the border ...
    want[1:4, 2:5] = False                # ... and not beside the blocked cell (2, 3)
    assert np.array_equal(roomy, want)


def door_wall(gap: float) -> World:
    """The open room with a wall across it at x = 0 (0.1 m thick), a door `gap` [m] wide centred on y = 0."""
    half = gap / 2
    return World("door", np.array([segment_box(0, -5, 0, -half - 0.05, 0.1), segment_box(0, half + 0.05, 0, 5, 0.1)]),
                 bounds=(-5.0, -5.0, 5.0, 5.0))


@pytest.mark.parametrize("radius_name", ["p3dx", "kobuki"])
def test_drives_through_a_door_3_cm_wider_than_the_robot_on_each_side(radius_name: str) -> None:
    # approached at 45 degrees, the path's corner a cell before the door: the follower slows, turns at
    # the corner rather than cut it, and its guard lets it through (the jambs pass 3 cm from its disc)
    from robotexp.sim.presets import preset
    radius = preset(radius_name).radius
    world = door_wall(2 * radius + 0.06)
    with SimRobot(world, robot=radius_name, pose=Pose(-0.9, -0.8, 0.0), max_speed=0.5, sonar=False) as robot:
        f = PathFollower(robot.limits, robot.radius)
        f.set_path(np.array([[-0.9, -0.8], [-0.4, -0.3], [-0.3, 0.0], [1.0, 0.0]]))
        steps, poses = follow(robot, f, 600)
        assert f.done and steps < 600
        assert robot.collisions == 0
        assert poses[-1].x > 0.8
        inside = [p for p in poses if abs(p.x) < 0.1]
        assert inside and max(abs(p.y) for p in inside) < 0.03     # within the door's 3 cm of play
