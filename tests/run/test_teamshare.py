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
