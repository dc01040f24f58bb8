"""Matching maps with their walls filled in between neighbouring beams (`fill_walls`): a wall seen at range is
a line in the map, not a row of dots one beam apart, and a scan turned by a fraction of a beam against it
keeps its heading."""

from __future__ import annotations

import math

import numpy as np

from robotexp.localization import Localizer, ScanMatcher, fill_walls, scan_points
from robotexp.localization.robot import RUN_MATCHER
from robotexp.mapping.geometry import GridGeometry
from robotexp.robot import LaserScan, Pose
from robotexp.world.builtin import builtin_world
from robotexp.world.raycast import RayIndex

CELL = 0.05


def _points(scan: LaserScan) -> np.ndarray:
    ok = np.isfinite(scan.ranges)
    a, r = scan.angles[ok], scan.ranges[ok]
    return np.column_stack([scan.offset_x + r * np.cos(a), r * np.sin(a)])


def test_a_wall_seen_square_on_is_filled_along_the_chords() -> None:
    # three beams 1 deg apart on the wall x = 8 m: each chord is 8 (tan 1 deg - tan 0) = 0.1396 m, so two points
    # go in each (ceil(0.1396 / 0.05) - 1), every one on the wall, the beams in order of angle
    angles = np.radians([-1.0, 0.0, 1.0])
    scan = LaserScan(angles, 8.0 / np.cos(angles), 20.0, 0.0, stamp=4.0)
    out = fill_walls(scan, CELL)
    assert len(out.ranges) == 3 + 4 and out.stamp == 4.0 and out.range_max == 20.0
    assert np.all(np.diff(out.angles) > 0)
    xy = _points(out)
    np.testing.assert_allclose(xy[:, 0], 8.0, atol=1e-9)
    gaps = np.diff(xy[:, 1])
    assert gaps.max() <= CELL + 1e-9
    np.testing.assert_allclose(gaps[:3], 8.0 * math.tan(math.radians(1.0)) / 3)


def test_a_sensor_ahead_of_the_centre_fills_the_wall_it_sees() -> None:
    # the laser 0.2 m ahead of the robot's centre: ranges from the laser, points on the wall x = 5.2 m
    angles = np.radians([-0.5, 0.5])
    scan = LaserScan(angles, 5.0 / np.cos(angles), 20.0, 0.2)
    out = fill_walls(scan, CELL)
    assert len(out.ranges) == 2 + 1
    np.testing.assert_allclose(_points(out)[:, 0], 5.2, atol=1e-9)


def test_no_fill_across_a_depth_jump_a_missing_echo_or_a_grazing_wall() -> None:
    one = math.radians(1.0)
    jump = LaserScan(np.array([0.0, one]), np.array([2.0, 6.0]), 20.0)             # a door post and the room behind
    gap = LaserScan(np.array([0.0, one, 2 * one]), np.array([6.0, np.inf, 6.0]), 20.0)   # no echo between
    # the wall y = 1 m at 12 and 13 deg: a chord of 0.37 m, 4.8 times the arc between the beams (> 3)
    a = np.radians([12.0, 13.0])
    grazing = LaserScan(a, 1.0 / np.sin(a), 20.0)
    for scan in (jump, gap, grazing):
        assert len(fill_walls(scan, CELL).ranges) == len(scan.ranges)
    # the same wall at 30 and 31 deg: 1.8 arcs, filled
    a = np.radians([30.0, 31.0])
    assert len(fill_walls(LaserScan(a, 1.0 / np.sin(a), 20.0), CELL).ranges) == 3


def _cast(index: RayIndex, pose: Pose, angles: np.ndarray, reach: float = 8.0) -> LaserScan:
    frac = index.cast(np.tile([pose.x, pose.y], (len(angles), 1)), pose.theta + angles, reach, 0.5)
    return LaserScan(angles, np.where(frac >= 1.0, np.inf, frac * reach), reach, 0.0)


def test_a_scan_turned_by_a_fraction_of_a_beam_keeps_its_heading_against_a_filled_map() -> None:
    # the hall `sparse`, 8 m laser, 1 deg a beam: the matching map is one scan at the start; the same spot turned
    # by 4.6, 9.2, ... 36.8 deg (never a whole number of beams) is matched from the true pose. Against the
    # dotted map the scan's points are drawn to the old beams' and the heading comes out 0.2-0.4 deg off
    world = builtin_world("sparse")
    assert world.bounds is not None
    index = RayIndex(world.boxes, world.discs, 1.0)
    angles = np.radians(np.linspace(-90.0, 90.0, 181))
    geo = GridGeometry.covering(*world.bounds, cell=CELL, margin=1.0)
    start = Pose(-12.0, -4.0, 0.0)
    worst = {}
    for fill in (False, True):
        loc = Localizer(geo, ScanMatcher(RUN_MATCHER), range_max=8.0, fill=fill)
        loc.integrate(start, _cast(index, start, angles))
        errors = []
        for k in range(1, 9):
            pose = Pose(start.x, start.y, math.radians(4.6 * k))
            px, py = scan_points(_cast(index, pose, angles), 8.0)
            m = loc.matcher.match(loc.grid.values, geo, px, py, pose, loc.hits, loc.grid.stamp)
            if m.status == "matched":
                errors.append(abs(math.degrees(m.pose.theta - pose.theta)))
        assert len(errors) >= 5
        worst[fill] = max(errors)
    assert worst[True] < 0.1 < 0.2 < worst[False]
