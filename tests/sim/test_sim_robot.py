"""SimRobot against hand-computed geometry on small custom worlds."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pybullet as pb
import pytest

from robotexp.errors import RobotError, WorldError
from robotexp.run.spec import RunSpec
from robotexp.experiment import run_experiment
from robotexp.robot import Limits, Pose, Twist
from robotexp.sim import LaserConfig, OdometryError, RobotPreset, SimRobot, preset
from robotexp.world.model import Mover, World, segment_box

DT = 0.1
WALL_X = 2.0        # [m] the inner face of the wall in `wall_world`


def wall_world() -> World:
    """One long wall whose near face is the line x = 2 m; the robot starts at the origin."""
    return World("wall", np.array([[WALL_X + 0.05, 0.0, 0.05, 5.0, 0.0]]), bounds=(-3.0, -5.0, 2.1, 5.0))


def square_room(half: float) -> World:
    """A closed square room whose inner faces are x, y = +-half [m]."""
    t = 0.1
    h = half + t / 2
    boxes = [segment_box(-h, -h, h, -h, t), segment_box(-h, h, h, h, t),
             segment_box(-h, -h, -h, h, t), segment_box(h, -h, h, h, t)]
    return World("room", np.array(boxes))


def drive(robot: SimRobot, twist: Twist, seconds: float) -> None:
    """Command `twist` every tick for `seconds` of robot time."""
    for _ in range(round(seconds / DT)):
        robot.command(twist)
        robot.advance(DT)


def beam(scan_angles: np.ndarray, deg: float) -> int:
    i = int(np.argmin(np.abs(scan_angles - math.radians(deg))))
    assert abs(scan_angles[i] - math.radians(deg)) < 1e-9
    return i


# -- laser ---------------------------------------------------------------------------------

def test_laser_ranges_to_a_wall_are_exact() -> None:
    with SimRobot(wall_world(), pose=Pose(0.0, 0.0, 0.0)) as robot:
        scan = robot.read().laser
        assert scan is not None
        assert scan.ranges.shape == (181,) and scan.range_max == 3.0
        for deg in (0.0, 30.0, -30.0, 45.0):
            assert scan.ranges[beam(scan.angles, deg)] == pytest.approx(WALL_X / math.cos(math.radians(deg)),
                                                                        abs=1e-6)
        # beyond 48.19 deg the wall is farther than 3 m: 2 / cos(60 deg) = 4 m reads inf
        for deg in (60.0, -60.0, 90.0, -90.0):
            assert math.isinf(scan.ranges[beam(scan.angles, deg)])
        expect_hit = 2.0 / np.abs(np.cos(scan.angles)) < 3.0
        assert np.array_equal(np.isfinite(scan.ranges), expect_hit)


def test_laser_follows_heading_and_offset() -> None:
    # turned by 30 deg, the laser 0.1 m ahead: beam -30 deg is perpendicular to the wall
    laser = LaserConfig(offset_x=0.1)
    th = math.radians(30)
    with SimRobot(wall_world(), pose=Pose(0.0, 0.0, th), laser=laser) as robot:
        scan = robot.scan()
        sx = 0.1 * math.cos(th)
        assert scan.ranges[beam(scan.angles, -30.0)] == pytest.approx(WALL_X - sx, abs=1e-6)
        assert scan.ranges[beam(scan.angles, 0.0)] == pytest.approx((WALL_X - sx) / math.cos(th), abs=1e-6)


def _room_truth(angles: np.ndarray, half: float) -> np.ndarray:
    return half / np.maximum(np.abs(np.cos(angles)), np.abs(np.sin(angles)))


def _noise_samples(laser: LaserConfig, seed: int, scans: int = 20) -> np.ndarray:
    with SimRobot(square_room(1.5), pose=Pose(0.0, 0.0, 0.0), laser=laser, seed=seed) as robot:
        out = []
        for _ in range(scans):
            s = robot.scan()
            out.append(s.ranges - _room_truth(s.angles, 1.5))
            robot.advance(DT)          # a new instant: a new scan
        return np.concatenate(out)


FULL = {"beams": 360, "fov": 2 * math.pi, "range_max": 3.0}


def test_laser_noise_free_is_exact_in_a_room() -> None:
    err = _noise_samples(LaserConfig(**FULL), seed=1, scans=1)
    assert np.all(np.isfinite(err)) and np.abs(err).max() < 1e-6


def test_gaussian_laser_noise_statistics() -> None:
    sigma = 0.02
    err = _noise_samples(LaserConfig(**FULL, sigma=sigma), seed=3)
    n = err.size
    assert n == 7200
    assert abs(err.mean()) < 4 * sigma / math.sqrt(n)
    assert err.std() == pytest.approx(sigma, rel=0.05)
    assert np.abs(err).max() < 6 * sigma


def test_uniform_laser_noise_statistics() -> None:
    u = 0.1
    err = _noise_samples(LaserConfig(**FULL, uniform=u), seed=3)
    assert err.min() >= -u - 1e-6 and err.max() <= u + 1e-6
    assert err.min() < -0.95 * u and err.max() > 0.95 * u
    assert abs(err.mean()) < 4 * (u / math.sqrt(3)) / math.sqrt(err.size)
    assert err.std() == pytest.approx(u / math.sqrt(3), rel=0.05)


def test_laser_noise_is_seeded() -> None:
    laser = LaserConfig(**FULL, sigma=0.01, uniform=0.05)
    a = _noise_samples(laser, seed=7, scans=3)
    b = _noise_samples(laser, seed=7, scans=3)
    c = _noise_samples(laser, seed=8, scans=3)
    assert np.array_equal(a, b)
    assert not np.allclose(a, c)


def test_scan_is_cast_once_per_instant() -> None:
    with SimRobot(square_room(1.5), pose=Pose(0.0, 0.0, 0.0), laser=LaserConfig(sigma=0.05)) as robot:
        first = robot.scan()
        assert robot.scan() is first and robot.read().laser is first
        robot.advance(DT)
        assert not np.array_equal(robot.scan().ranges, first.ranges)


# -- motion --------------------------------------------------------------------------------

def test_acceleration_limit() -> None:
    with SimRobot(wall_world(), pose=Pose(0.0, 0.0, 0.0)) as robot:
        lim = robot.limits
        robot.command(Twist(1.0, 1.0))
        robot.advance(DT)
        state = robot.read()
        assert state.velocity.v == pytest.approx(lim.a_max * DT, abs=1e-12)
        assert state.velocity.w == pytest.approx(lim.alpha_max * DT, abs=1e-12)
        robot.advance(DT)
        assert robot.read().velocity.v == pytest.approx(2 * lim.a_max * DT, abs=1e-12)
        # commands are clamped to the limits, so v settles at min(command, v_max)
        robot.set_max_speed(0.08)
        robot.command(Twist(1.0, 0.0))
        robot.advance(DT)
        assert robot.read().velocity.v == pytest.approx(0.08, abs=1e-12)   # 0.06 + 0.03 would pass it


def _snappy() -> RobotPreset:
    base = preset("p3dx")
    return replace(base, limits=Limits(v_max=2.0, w_max=5.0, a_max=1e6, alpha_max=1e6))


def test_unicycle_circle_returns_to_start() -> None:
    v, w = 0.5, 1.0            # a circle of radius 0.5 m, centred 0.5 m left of the start
    n = 100
    dt = 2 * math.pi / w / n
    start = Pose(0.3, -0.2, math.radians(20))
    with SimRobot(square_room(3.0), robot=_snappy(), pose=start) as robot:
        robot.command(Twist(v, w))
        quarter = None
        for k in range(n):
            robot.advance(dt)
            if k + 1 == n // 4:
                quarter = robot.read().true_pose
        end = robot.read().true_pose
        assert end is not None and quarter is not None
        assert end.x == pytest.approx(start.x, abs=1e-6) and end.y == pytest.approx(start.y, abs=1e-6)
        assert abs(math.remainder(end.theta - start.theta, 2 * math.pi)) < 1e-6
        # a quarter turn: centre c = start + r * (-sin th, cos th); pose = c + r * (sin(th+90), -cos(th+90))
        r, th = v / w, start.theta
        cx, cy = start.x - r * math.sin(th), start.y + r * math.cos(th)
        assert quarter.x == pytest.approx(cx + r * math.sin(th + math.pi / 2), abs=1e-6)
        assert quarter.y == pytest.approx(cy - r * math.cos(th + math.pi / 2), abs=1e-6)
        # odometry sums the chord of each step: within (1 - sin(x)/x), x = w dt / 2, of the arc
        assert robot.read().distance == pytest.approx(2 * math.pi * r, rel=1e-3)
        odom = robot.read().pose
        assert (odom.x, odom.y) == pytest.approx((end.x, end.y), abs=1e-9)
        assert robot.collisions == 0


def test_driving_into_a_wall_stalls_once() -> None:
    with SimRobot(wall_world(), pose=Pose(0.0, 0.0, 0.0)) as robot:
        drive(robot, Twist(0.5, 0.0), 12.0)          # reaches the wall after ~5 s, then pushes
        state = robot.read()
        assert state.true_pose is not None
        assert state.true_pose.x == pytest.approx(WALL_X - robot.radius, abs=0.002)
        assert state.true_pose.x <= WALL_X - robot.radius + 1e-9
        assert state.stalled and state.bumpers == (True,)
        assert state.velocity.v == 0.0
        assert robot.collisions == 1 and state.extra["collisions"] == 1.0
        drive(robot, Twist(0.5, 0.0), 10.0)          # keeps pushing: still one collision
        assert robot.collisions == 1 and robot.read().stalled
        assert robot.read().true_pose.x == pytest.approx(WALL_X - robot.radius, abs=0.002)


def test_rotation_in_place_when_stalled() -> None:
    with SimRobot(wall_world(), pose=Pose(0.0, 0.0, 0.0)) as robot:
        drive(robot, Twist(0.5, 0.0), 8.0)
        before = robot.read()
        assert before.stalled and before.velocity.w == 0.0
        drive(robot, Twist(0.0, 1.0), 1.0)
        after = robot.read()
        # w ramps by alpha_max * dt per tick up to the command, theta integrates it
        step = robot.limits.alpha_max * DT
        w, theta = 0.0, 0.0
        for _ in range(10):
            w = min(1.0, w + step)
            theta += w * DT
        assert after.true_pose.theta == pytest.approx(theta, abs=1e-9)
        assert after.true_pose.x == before.true_pose.x and after.true_pose.y == before.true_pose.y
        assert not after.stalled
        # now facing away from the wall (heading > 90 deg), it can drive off
        drive(robot, Twist(0.0, 1.0), 1.0)
        assert robot.read().true_pose.theta > math.pi / 2
        drive(robot, Twist(0.3, 0.0), 2.0)
        assert robot.read().true_pose.x < before.true_pose.x - 0.1 and robot.collisions == 1


def test_new_contact_after_leaving_counts_again() -> None:
    with SimRobot(wall_world(), pose=Pose(0.0, 0.0, 0.0)) as robot:
        drive(robot, Twist(0.5, 0.0), 8.0)
        drive(robot, Twist(-0.3, 0.0), 3.0)           # back off well clear
        assert not robot.read().stalled
        drive(robot, Twist(0.3, 0.0), 6.0)
        assert robot.collisions == 2


# -- odometry ------------------------------------------------------------------------------

def test_odometry_equals_truth_without_error_model() -> None:
    with SimRobot(wall_world(), pose=Pose(-1.0, 0.5, math.radians(-10))) as robot:
        drive(robot, Twist(0.3, 0.0), 4.0)
        drive(robot, Twist(0.0, 0.0), 2.0)          # stop fully, then turn in place
        drive(robot, Twist(0.0, -0.8), 2.0)
        drive(robot, Twist(0.0, 0.0), 2.0)
        s = robot.read()
        assert s.true_pose is not None
        assert s.pose.x == pytest.approx(s.true_pose.x, abs=1e-9)
        assert s.pose.y == pytest.approx(s.true_pose.y, abs=1e-9)
        assert s.pose.theta == pytest.approx(s.true_pose.theta, abs=1e-9)
        assert s.distance == pytest.approx(math.hypot(s.true_pose.x + 1.0, s.true_pose.y - 0.5), abs=1e-9)


def test_wheel_mismatch_drifts_odometry_as_predicted() -> None:
    # (right - left) / nominal = +m: the right wheel is larger. On a truly straight line each wheel
    # covers ds on the ground; odometry, assuming nominal wheels, reads ds / (1 - m/2) on the left
    # and ds / (1 + m/2) on the right, so it believes the robot turns right (clockwise) by
    # -m ds / ((1 - m^2/4) b) and moved ds / (1 - m^2/4).
    m = 0.02
    b = preset("p3dx").wheel_base
    with SimRobot(wall_world(), pose=Pose(-2.0, 0.0, 0.0), odometry=OdometryError(wheel_mismatch=m)) as robot:
        drive(robot, Twist(0.3, 0.0), 10.0)
        s = robot.read()
        assert s.true_pose is not None
        assert s.true_pose.y == 0.0 and s.true_pose.theta == 0.0      # truth goes straight
        d = s.true_pose.x + 2.0
        assert d > 2.5
        k = 1.0 / (1.0 - m * m / 4)
        heading = -m * d * k / b
        assert s.pose.theta == pytest.approx(heading, rel=1e-9)
        assert s.distance == pytest.approx(d * k, rel=1e-9)
        # the believed path is (close to) an arc of that curvature: end point of the arc
        radius = d * k / heading
        assert s.pose.x == pytest.approx(-2.0 + radius * math.sin(heading), abs=2e-3)
        assert s.pose.y == pytest.approx(radius * (1 - math.cos(heading)), abs=2e-3)
        assert s.pose.y < -0.1


def test_wheel_slip_is_seeded() -> None:
    def run(seed: int) -> Pose:
        with SimRobot(wall_world(), pose=Pose(-2.0, 0.0, 0.0), seed=seed,
                      odometry=OdometryError(slip_sigma=0.05)) as robot:
            drive(robot, Twist(0.3, 0.0), 3.0)
            return robot.read().pose
    a, b, c = run(1), run(1), run(2)
    assert a == b and a != c and a.theta != 0.0


# -- sonar ---------------------------------------------------------------------------------

def test_sonar_ring_sees_the_wall() -> None:
    p3dx = preset("p3dx")
    cfg = p3dx.sonar
    assert cfg is not None
    with SimRobot(wall_world(), pose=Pose(0.0, 0.0, 0.0)) as robot:
        sonar = robot.read().sonar
        assert sonar is not None and sonar.ranges.shape == (16,) and sonar.angles.shape == (16,)
        assert sonar.range_max == cfg.range_max
        # each transducer at a on a ring of radius rr casts rays at a - 7.5, a, a + 7.5 deg;
        # it reads the nearest: (2 - rr cos a) / cos(ray) for the rays that reach x = 2 in range
        expected = []
        for a in cfg.angles_deg:
            x0 = cfg.ring_radius * math.cos(math.radians(a))
            best = math.inf
            for ray in (a - cfg.cone_deg / 2, a, a + cfg.cone_deg / 2):
                c = math.cos(math.radians(ray))
                if c > 1e-9 and (WALL_X - x0) / c < cfg.range_max:
                    best = min(best, (WALL_X - x0) / c)
            expected.append(best)
        np.testing.assert_allclose(sonar.ranges, expected, atol=1e-6)
        front = cfg.angles_deg.index(10)
        assert sonar.ranges[front] == pytest.approx((WALL_X - cfg.ring_radius * math.cos(math.radians(10)))
                                                    / math.cos(math.radians(2.5)), abs=1e-6)
        assert sum(np.isfinite(sonar.ranges)) == 6       # +-10, +-30, +-50 deg
        assert robot.capabilities >= {"sonar", "move_to", "ground_truth"}


def test_kobuki_has_no_sonar() -> None:
    with SimRobot(wall_world(), robot="kobuki", pose=Pose(0.0, 0.0, 0.0)) as robot:
        assert robot.read().sonar is None
        with pytest.raises(NotImplementedError):
            robot.sonar()


# -- movers --------------------------------------------------------------------------------

def test_mover_position_back_and_forth() -> None:
    m = Mover(radius=0.2, speed=1.0, path=np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0]]))
    cases = {0.0: (0.0, 0.0), 0.5: (0.5, 0.0), 2.0: (2.0, 0.0), 2.5: (2.0, 0.5), 3.0: (2.0, 1.0),
             3.5: (2.0, 0.5), 5.0: (1.0, 0.0), 6.0: (0.0, 0.0), 6.5: (0.5, 0.0)}
    for t, xy in cases.items():
        assert m.position(t) == pytest.approx(xy, abs=1e-12), t
    loop = Mover(radius=0.2, speed=1.0, path=np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0]]), loop=True)
    back = 3.0 + math.sqrt(5.0) / 2          # halfway along the closing segment (2, 1) -> (0, 0)
    assert loop.position(back) == pytest.approx((1.0, 0.5), abs=1e-12)
    assert loop.position(3.0 + math.sqrt(5.0) + 0.5) == pytest.approx((0.5, 0.0), abs=1e-12)


def _crossing_world() -> World:
    mover = Mover(radius=0.25, speed=0.5, path=np.array([[1.5, -2.0], [1.5, 2.0]]), height=1.7)
    return World("crossing", np.array([[-2.9, 0.0, 0.05, 2.9, 0.0]]), bounds=(-3.0, -3.0, 3.0, 3.0),
                 movers=[mover])


def _mover_xy(robot: SimRobot, i: int) -> tuple[float, float]:
    pos, _ = pb.getBasePositionAndOrientation(robot.engine.movers[i], physicsClientId=robot.engine.client)
    return pos[0], pos[1]


def test_sim_places_mover_and_laser_sees_it() -> None:
    world = _crossing_world()
    with SimRobot(world, pose=Pose(0.0, 0.0, 0.0)) as robot:
        assert _mover_xy(robot, 0) == pytest.approx((1.5, -2.0), abs=1e-9)
        ahead = beam(robot.scan().angles, 0.0)
        assert math.isinf(robot.scan().ranges[ahead])
        for _ in range(40):                       # 4 s at 0.5 m/s: the mover is at (1.5, 0)
            robot.advance(DT)
        assert robot.mover_positions()[0] == pytest.approx((1.5, 0.0), abs=1e-9)
        assert _mover_xy(robot, 0) == pytest.approx((1.5, 0.0), abs=1e-9)
        scan = robot.scan()
        assert scan.ranges[ahead] == pytest.approx(1.5 - 0.25, abs=1e-3)
        assert scan.nearest() == pytest.approx(1.25, abs=1e-3)
        for _ in range(40):                       # 8 s: at the far end (1.5, 2)
            robot.advance(DT)
        assert _mover_xy(robot, 0) == pytest.approx((1.5, 2.0), abs=1e-9)
        for _ in range(20):                       # 10 s: coming back, at (1.5, 1)
            robot.advance(DT)
        assert _mover_xy(robot, 0) == pytest.approx((1.5, 1.0), abs=1e-9)


def test_mover_blocked_by_robot_waits() -> None:
    world = _crossing_world()
    with SimRobot(world, pose=Pose(1.5, 0.5, 0.0)) as robot:   # standing on the mover's path
        for _ in range(60):
            robot.advance(DT)
        x, y = robot.mover_positions()[0]
        assert x == 1.5
        # it stops before coming within its 0.05 m margin: centres 0.55 m apart, give or take one step
        gap = 0.5 - y
        assert 0.55 - 1e-3 < gap <= 0.55 + 0.5 * DT + 1e-3
        assert _mover_xy(robot, 0) == pytest.approx((x, y), abs=1e-12)
        for _ in range(30):
            robot.advance(DT)
        assert robot.mover_positions()[0] == (x, y)
        robot.move_to(Pose(0.0, 0.0, 0.0))               # step aside: it walks on
        robot.advance(DT)
        assert robot.mover_positions()[0][1] == pytest.approx(y + 0.5 * DT, abs=1e-9)
        assert robot.collisions == 0


# -- lifecycle and errors ------------------------------------------------------------------

def test_move_to_teleports_and_refuses_obstacles() -> None:
    with SimRobot(wall_world(), pose=Pose(0.0, 0.0, 0.0)) as robot:
        robot.move_to(Pose(1.0, 1.0, 1.0))
        s = robot.read()
        assert s.pose == s.true_pose == Pose(1.0, 1.0, 1.0)
        with pytest.raises(WorldError, match="touches an obstacle"):
            robot.move_to(Pose(1.9, 0.0, 0.0))
        with pytest.raises(WorldError, match="outside"):
            robot.move_to(Pose(5.0, 0.0, 0.0))
        assert robot.read().true_pose == Pose(1.0, 1.0, 1.0)


def test_start_pose_errors() -> None:
    with pytest.raises(WorldError, match="touches an obstacle"):
        SimRobot(wall_world(), pose=Pose(1.8, 0.0, 0.0))
    with pytest.raises(WorldError, match="outside"):
        SimRobot(wall_world(), pose=Pose(-4.0, 0.0, 0.0))


def test_close_twice_and_read_after_close() -> None:
    robot = SimRobot(wall_world(), pose=Pose(0.0, 0.0, 0.0))
    robot.close()
    robot.close()
    assert robot.closed
    with pytest.raises(RobotError, match="closed"):
        robot.read()
    with pytest.raises(RobotError):
        robot.command(Twist(0.1, 0.0))
    with pytest.raises(RobotError):
        robot.advance(DT)


def test_exploration_is_deterministic() -> None:
    a = run_experiment(RunSpec(world="ufmg-static", max_time=60.0, seed=5), None, image=False).record
    b = run_experiment(RunSpec(world="ufmg-static", max_time=60.0, seed=5), None, image=False).record
    assert a["path_length_m"] > 1.0
    for key in ("path_length_m", "coverage", "collisions", "visited_cells", "robot_time_s", "map_iou"):
        assert a[key] == b[key], key


def test_leaked_robot_fails_the_test(pytester: pytest.Pytester) -> None:
    pytester.makeconftest(Path(__file__).parents[1].joinpath("conftest.py").read_text())
    pytester.makepyfile(test_leak="""
        import numpy as np
        from robotexp.robot import Pose
        from robotexp.sim import SimRobot
        from robotexp.world.model import World

        def world():
            return World("w", np.array([[2.05, 0.0, 0.05, 5.0, 0.0]]), bounds=(-3.0, -5.0, 2.1, 5.0))

        def test_leaks():
            SimRobot(world(), pose=Pose(0.0, 0.0, 0.0))

        def test_closes():
            with SimRobot(world(), pose=Pose(0.0, 0.0, 0.0)):
                pass

        def test_fails_to_open():
            try:
                SimRobot(world(), pose=Pose(1.9, 0.0, 0.0))
            except Exception:
                pass
    """)
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    result.assert_outcomes(passed=3, errors=1)
    result.stdout.fnmatch_lines(["*ERROR at teardown of test_leaks*", "*left 1 robot(s) open: SimRobot(sim)*"])
