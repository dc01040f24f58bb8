"""SeenCells (the overlap of a team record), groups_within and ScanExchange against grids built by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.robot import LaserScan, Pose
from robotexp.run.teamshare import ScanExchange, SeenCells, groups_within

GEO = GridGeometry(0.0, 0.0, 0.1, 60, 60)


def fan(ranges: float = 2.0) -> LaserScan:
    angles = np.linspace(-math.pi / 2, math.pi / 2, 91)
    return LaserScan(angles, np.full(91, ranges), 3.0, 0.0)


POSES = [Pose(1.0, 3.0, 0.0), Pose(2.0, 3.0, 0.0), Pose(5.0, 1.0, math.pi / 2)]


def test_seen_cells_count_what_each_robots_scans_touched_and_the_overlap():
    shared = OccupancyGrid(GEO)
    seen = SeenCells(shared.shape, 3)
    alone = [OccupancyGrid(GEO) for _ in POSES]
    for robot, pose in enumerate(POSES):
        shared.update(pose, fan())
        seen.note(robot, shared)
        alone[robot].update(pose, fan())
    masks = [g.seen for g in alone]
    union = masks[0] | masks[1] | masks[2]
    several = (masks[0] & masks[1]) | (masks[0] & masks[2]) | (masks[1] & masks[2])
    assert seen.counts() == (int(union.sum()), int(several.sum()))
    assert seen.overlap() == pytest.approx(several.sum() / union.sum())
    assert 0 < seen.overlap() < 1
    for robot in range(3):
        assert np.array_equal(seen.seen_by(robot), masks[robot])
    assert SeenCells((4, 4), 64).bits.dtype == np.uint64 and SeenCells((4, 4), 2).overlap() is None


def test_groups_within_chain_robots_that_can_talk():
    xy = np.array([[0.0, 0.0], [1.5, 0.0], [3.0, 0.0], [10.0, 0.0], [0.0, 1.9]])
    assert groups_within(xy, 2.0) == [[0, 1, 2, 4], [3]]
    assert groups_within(xy, 1.0) == [[0], [1], [2], [3], [4]]
    assert groups_within(xy, None) == [[0, 1, 2, 3, 4]]


def test_scans_pass_on_through_the_robots_that_met():
    grids = [OccupancyGrid(GEO) for _ in POSES]
    ex = ScanExchange(grids)
    for robot, pose in enumerate(POSES):
        grids[robot].update(pose, fan())
        ex.log(robot, pose, fan())
    assert ex.share([[0], [1], [2]]) == 0
    assert ex.share([[0, 1], [2]]) == 2               # robots 0 and 1 swap their one scan each
    assert ex.known.tolist() == [[1, 1, 0], [1, 1, 0], [0, 0, 1]]
    assert ex.share([[1, 2], [0]]) == 3               # robot 2 gets 0's scan from 1 (relayed), 1 gets 2's
    assert ex.known.tolist() == [[1, 1, 0], [1, 1, 1], [1, 1, 1]]
    assert ex.received.tolist() == [1, 2, 2]
    both = OccupancyGrid(GEO)
    for pose in POSES:
        both.update(pose, fan())
    np.testing.assert_allclose(grids[2].values, both.values, atol=1e-6)
    assert ex.share([[0, 1, 2]]) == 1 and ex.share([[0, 1, 2]]) == 0     # only what is new travels


def test_beams_ending_on_a_teammate_by_hand_and_against_the_numpy_reference() -> None:
    """A sensor at (1, 2) facing +x: the beam straight ahead ends 2 m away at (3, 2), 0.05 m from a teammate's
    centre at (3.05, 2) (reach 0.3 m); the beam to the left ends at (1, 3.5), 0.4 m from a teammate at
    (1, 3.9) (out of reach 0.3); a beam with no echo through that teammate ends nowhere. Then random scans and
    teammates against `beams_on_teammates_reference`."""
    from robotexp.run.teamshare import beams_on_teammates, beams_on_teammates_reference

    angles = np.array([0.0, np.pi / 2, np.pi / 2 + 1e-3, -np.pi / 2])
    ranges = np.array([2.0, 1.5, np.nan, 0.5])
    xy = np.array([[3.05, 2.0], [1.0, 3.9]])
    reach = np.array([0.3, 0.3])
    got = beams_on_teammates((1.0, 2.0, 0.0), angles, ranges, xy, reach)
    assert got.tolist() == [True, False, False, False]
    assert beams_on_teammates((1.0, 2.0, 0.0), angles, ranges, xy, np.array([0.3, 0.45])).tolist() == \
        [True, True, False, False]
    rng = np.random.default_rng(5)
    on = 0
    for _ in range(200):
        angles = np.linspace(-np.pi, np.pi, 181, endpoint=False)
        ranges = rng.uniform(0.05, 4.0, 181)
        ranges[rng.random(181) < 0.1] = np.nan
        sensor = (float(rng.uniform(-2, 2)), float(rng.uniform(-2, 2)), float(rng.uniform(-np.pi, np.pi)))
        xy = rng.uniform(-4, 4, (int(rng.integers(0, 8)), 2))
        reach = rng.uniform(0.2, 0.6, len(xy))
        got = beams_on_teammates(sensor, angles, ranges, xy, reach)
        np.testing.assert_array_equal(got, beams_on_teammates_reference(sensor, angles, ranges, xy, reach))
        on += int(got.sum())
    assert on > 100         # the random teammates were hit


def test_teammates_near_by_hand() -> None:
    """Robot 0 at (0, 0); robot 1 at (1, 0) (swing 0.3, 0.4 m/s, brake 2 m/s2) within 2 m of its disc; robot 2
    at (2.5, 0) (swing 0.3: its disc 2.2 m away, out of reach); robot 3 not placed yet (NaN)."""
    from robotexp.run.teamshare import teammates_near

    xy = np.array([[0.0, 0.0], [1.0, 0.0], [2.5, 0.0], [np.nan, np.nan]])
    swing = np.full(4, 0.3)
    speed = np.array([0.0, 0.4, 0.3, 0.0])
    brake = np.full(4, 2.0)
    near = np.ones(4, bool)
    found, closing, gap = teammates_near(0.0, 0.0, xy, swing, speed, brake, 0, 2.0, near)
    assert found and closing == pytest.approx(0.4 * 0.4 / 2.0 + 0.4 * 0.2) and gap == pytest.approx(0.7)
    assert near.tolist() == [False, True, False, False]
    found, closing, gap = teammates_near(0.0, 0.0, xy, swing, speed, brake, 0, 2.3, near)  # robot 2 within reach
    assert found and closing == pytest.approx(0.16) and gap == pytest.approx(0.7)
    assert near.tolist() == [False, True, True, False]
    found, closing, gap = teammates_near(-5.0, 0.0, xy, swing, speed, brake, 0, 2.0, near)  # nobody near
    assert not found and closing == 0.0 and gap == math.inf and not near.any()
