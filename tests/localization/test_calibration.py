"""Online odometry calibration, the localizer's turning rule, never-seen points, the cached likelihood field,
the 2x2 eigen-solver and `--localize auto`."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotexp.errors import ConfigError
from robotexp.run.spec import RunSpec
from robotexp.world.poses import resolve_pose
from robotexp.experiment import run_on_robot
from robotexp.localization.calibration import OdometryCalibration
from robotexp.localization.matcher import Localizer, MatcherConfig, ScanMatcher, _eig2, scan_points
from robotexp.run.localize import localized, release
from robotexp.localization.robot import LocalizedRobot
from robotexp.mapping.geometry import GridGeometry
from robotexp.robot import LaserScan, Pose, Twist
from robotexp.sim import SimRobot, odometry_error
from robotexp.world.builtin import builtin_world
from robotexp_drivers.kobuki.emulator import EmulatorLaser, KobukiEmulator
from robotexp_drivers.kobuki.robot import KOBUKI_RADIUS, KobukiRobot


def test_apply_turns_a_straight_increment_by_k_d_and_its_chord_by_half() -> None:
    cal = OdometryCalibration()
    cal.k, cal.e = 0.03, 0.0
    inc = cal.apply(Pose(0.5, 0.0, 0.0))
    # 0.5 m at 0.03 rad/m: the heading turns 0.015 rad, the chord of the arc by half of it
    assert inc.theta == pytest.approx(0.015)
    assert inc.x == pytest.approx(0.5 * math.cos(0.0075)) and inc.y == pytest.approx(0.5 * math.sin(0.0075))
    cal.k, cal.e = 0.0, 0.02
    assert cal.apply(Pose(0.0, 0.0, 1.0)).theta == pytest.approx(1.02)


@pytest.mark.parametrize("shrink", [1.0, 0.4])
def test_calibration_converges_to_the_true_bias_even_when_matches_correct_only_part_of_it(shrink: float) -> None:
    # A robot whose true turn is dth + k d + e dth (k = 0.0303 rad/m: the P3-DX preset's 1 % wheel
    # mismatch over its 0.33 m wheelbase; e = 0.01); matches every 0.1 m, with turns, and the matcher
    # corrects only `shrink` of the heading error the prediction made (a motion prior pulls towards
    # the prediction), plus 0.05 deg of noise.
    k_true, e_true = 0.01 / 0.33, 0.01
    rng = np.random.default_rng(0)
    cal = OdometryCalibration()
    for _ in range(3000):
        d = 0.1 * rng.uniform(0.5, 1.0)
        dth = rng.choice([0.0, 0.0, rng.uniform(-0.3, 0.3)])
        error = (k_true - cal.k) * d + (e_true - cal.e) * dth
        cal.observe(d, dth, shrink * error + rng.normal(0.0, math.radians(0.05)))
    assert cal.k == pytest.approx(k_true, rel=0.05)
    assert cal.e == pytest.approx(e_true, abs=0.003)
    assert cal.samples == 3000


def test_calibration_clamps_and_rejects_bad_settings() -> None:
    cal = OdometryCalibration(k_max=0.05)
    for _ in range(200):
        cal.observe(0.1, 0.0, 0.1)             # 1 rad/m: far beyond any wheel mismatch
    assert cal.k == 0.05
    with pytest.raises(ConfigError):
        OdometryCalibration(forget=0.0)
    with pytest.raises(ConfigError):
        OdometryCalibration(ridge=(0.0, 1.0))


def test_eig2_matches_numpy() -> None:
    rng = np.random.default_rng(1)
    for i in range(500):
        m = rng.normal(size=(2, 2))
        m = m @ m.T
        if i % 5 == 0:
            m[0, 1] = m[1, 0] = 0.0
        (lo, hi), v = _eig2(m[0, 0], m[0, 1], m[1, 1])
        w, _ = np.linalg.eigh(m)
        assert (lo, hi) == pytest.approx(tuple(w))
        assert np.allclose(m @ v, lo * v, atol=1e-9) and np.linalg.norm(v) == pytest.approx(1.0)


def _wall_scan() -> LaserScan:
    angles = np.radians(np.arange(-90.0, 91.0))
    ranges = np.where(np.abs(angles) < 1.2, 1.0 / np.cos(angles), np.inf)     # a wall 1 m ahead
    return LaserScan(angles, ranges, 3.0)


def test_a_scan_taken_while_turning_fast_is_neither_matched_nor_mapped() -> None:
    loc = Localizer(GridGeometry.covering(-2.0, -2.0, 2.0, 2.0, 0.05), max_turn_rate=0.5)
    loc.reset(Pose(0, 0, 0), Pose(0, 0, 0))
    loc.integrate(Pose(0, 0, 0), _wall_scan())
    before = loc.grid.values.copy()
    odom = Pose(0.0, 0.0, 0.2)
    p = loc.locate(odom, _wall_scan(), turn_rate=1.0)
    assert (p.x, p.y, p.theta) == pytest.approx((0.0, 0.0, 0.2))     # odometry's turn, kept
    assert loc.counts == {"turning": 1}
    assert np.array_equal(loc.grid.values, before)
    loc.locate(Pose(0.0, 0.0, 0.0), _wall_scan(), turn_rate=0.1)
    assert "turning" not in loc.counts or loc.counts["turning"] == 1
    assert sum(loc.counts.values()) == 2


def test_localize_auto_is_scan_matching_on_real_robots_and_on_the_simulator_only_with_odometry_error() -> None:
    world = builtin_world("dense")
    assert world.bounds is not None
    geo = GridGeometry.covering(*world.bounds, cell=0.1, margin=1.0)
    with SimRobot(world, pose=world.poses["1"], sonar=False) as exact, \
            SimRobot(world, pose=world.poses["1"], sonar=False, odometry=odometry_error("p3dx")) as curved:
        robot, tracker = localized(RunSpec(localize="auto"), exact, geo)
        assert robot is exact and tracker.localize == "none"
        robot, tracker = localized(RunSpec(localize="auto", odometry="p3dx"), curved, geo)
        assert isinstance(robot, LocalizedRobot) and tracker.localize == "scan-match"
        assert robot.localizer.max_turn_rate == math.inf      # the simulator's scans are taken at the state's instant
        release(robot)
        robot, tracker = localized(RunSpec(localize="none", odometry="p3dx"), curved, geo)
        assert robot is curved and tracker.localize == "none"


def test_a_real_robot_explores_with_scan_matching_by_default() -> None:
    # the Kobuki driver on its emulator's TCP link, the laser beside it: a real robot as far as the run
    # path can tell; --localize auto (the default) puts the localizer in, with the turning rule
    world = builtin_world("ufmg-static")
    start = resolve_pose(world, "path1", KOBUKI_RADIUS)[0]
    spec = RunSpec(world="ufmg-static", robot="kobuki", method="frontier", pose="path1", speed=0.3, max_time=20.0)
    assert spec.localize == "auto"
    with KobukiEmulator(world, pose=start, speedup=30.0) as emu, \
            KobukiRobot(emu.address, laser=EmulatorLaser(emu)) as robot:
        record = run_on_robot(spec, robot, None, world).record
    assert record["localize"] == "scan-match"
    assert record["matches"].get("matched", 0) > 5
    assert record["ate_m"] is None                         # a real robot: no ground truth to measure it
    assert record["collisions"] == 0


def _two_scans(turn: float) -> tuple[LaserScan, Pose, LaserScan, Pose]:
    """Two scans of `dense` from pose 1 (a corridor), the second after turning in place at `turn` rad/s for 1 s."""
    world = builtin_world("dense")
    with SimRobot(world, pose=world.poses["1"], seed=1, sonar=False) as sim:
        s1 = sim.read()
        sim.command(Twist(0.0, turn))
        sim.advance(1.0)
        sim.command(Twist(0.0, 0.0))
        sim.advance(0.1)
        s2 = sim.read()
    assert s1.laser is not None and s2.laser is not None and s1.true_pose is not None and s2.true_pose is not None
    return s1.laser, s1.true_pose, s2.laser, s2.true_pose


def test_never_seen_points_left_out_keep_a_turn_in_a_corridor_in_place() -> None:
    # the second scan, 75 deg further round, sees mostly corridor the first did not (fewer than half its
    # points on seen cells): with those points in, the match slid 16 cm along the corridor and turned
    # 1.5 deg; left out, it stays within 1 cm
    world = builtin_world("dense")
    assert world.bounds is not None
    geo = GridGeometry.covering(*world.bounds, cell=0.05, margin=1.0)
    scan1, pose1, scan2, pose2 = _two_scans(1.2)
    errors = {}
    for drop in (False, True):
        loc = Localizer(geo, ScanMatcher(MatcherConfig(drop_unseen=drop)))
        loc.reset(pose1, pose1)
        loc.integrate(pose1, scan1)
        px, py = scan_points(scan2)
        m = loc.matcher.match(loc.grid.values, geo, px, py, pose2, loc.hits, loc.grid.stamp)
        errors[drop] = math.hypot(m.pose.x - pose2.x, m.pose.y - pose2.y)
    assert errors[True] < 0.01 < 0.1 < errors[False]


def test_a_cached_field_matches_as_a_fresh_one() -> None:
    world = builtin_world("dense")
    assert world.bounds is not None
    geo = GridGeometry.covering(*world.bounds, cell=0.05, margin=1.0)
    scan1, pose1, scan2, pose2 = _two_scans(0.2)
    loc = Localizer(geo)
    loc.integrate(pose1, scan1)
    px, py = scan_points(scan2)
    matcher = loc.matcher
    off = Pose(pose2.x + 0.05, pose2.y - 0.04, pose2.theta + 0.02)
    fresh = matcher.match(loc.grid.values, geo, px, py, off, loc.hits)
    first = matcher.match(loc.grid.values, geo, px, py, off, loc.hits, version=1)     # computes and caches
    assert matcher._cache is not None and matcher._cache[0] == 1
    cached_field = matcher._cache[2]
    again = matcher.match(loc.grid.values, geo, px, py, off, loc.hits, version=1)     # reuses it
    assert matcher._cache[2] is cached_field
    for m in (first, again):
        assert (m.pose.x, m.pose.y, m.pose.theta) == pytest.approx((fresh.pose.x, fresh.pose.y, fresh.pose.theta),
                                                                     abs=1e-6)
        assert m.status == fresh.status
    matcher.match(loc.grid.values, geo, px, py, off, loc.hits, version=2)              # the map changed: recomputed
    assert matcher._cache[2] is not cached_field
