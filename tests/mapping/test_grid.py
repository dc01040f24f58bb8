"""OccupancyGrid: updates, states, probabilities, frontiers, marks and validation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotexp.errors import ConfigError
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.robot import LaserScan, Pose

GEO = GridGeometry(0.0, 0.0, 1.0, 5, 5)
L9 = math.log(9.0)


def _scan(angles, ranges, range_max=10.0, offset_x=0.0):
    return LaserScan(np.asarray(angles, float), np.asarray(ranges, float), range_max, offset_x)


def test_update_uses_sensor_offset_and_relative_angles():
    # Robot at (0.5, 0.3) heading +y; the sensor is 0.2 m ahead at (0.5, 0.5); the beam at -90 deg
    # relative points along +x and ends at x = 3.1 (col 3; without the offset it would be 2.9, col 2).
    grid = OccupancyGrid(GEO)
    n = grid.update(Pose(0.5, 0.3, math.pi / 2), _scan([-math.pi / 2], [2.6], offset_x=0.2))
    assert n == 4 and grid.cells_updated == 4
    states = grid.states()
    assert states.dtype == np.int8
    assert states[0].tolist() == [0, 0, 0, 100, -1]
    assert (states[1:] == -1).all()
    assert grid.free()[0].tolist() == [True, True, True, False, False]
    assert grid.occupied()[0].tolist() == [False, False, False, True, False]
    assert grid.unknown().sum() == 21
    np.testing.assert_allclose(grid.probability()[0], [0.1, 0.1, 0.1, 0.9, 0.5], atol=1e-6)
    assert grid.probability().dtype == np.float32
    assert grid.values[0, 0] == np.float32(-L9)


def test_hit_then_pass_cancels_to_unknown():
    grid = OccupancyGrid(GEO)
    grid.update(Pose(0.5, 0.5), _scan([0.0], [3.2]))           # (0, 3) hit
    grid.update(Pose(0.5, 0.5), _scan([0.0], [math.inf]))      # (0, 3) crossed
    assert grid.values[0, 3] == 0 and grid.unknown()[0, 3] and grid.states()[0, 3] == -1


def test_one_scan_updates_each_cell_once_and_a_hit_wins():
    # Two beams along +x from (0.5, 0.5): 1.2 m hits (0,1), 3.2 m crosses (0,0) (0,1) (0,2) and hits
    # (0,3). (0,1) keeps +l_occ (not cancelled by the pass), (0,0) gets l_free once.
    grid = OccupancyGrid(GEO)
    assert grid.update(Pose(0.5, 0.5), _scan([0.0, 0.0], [1.2, 3.2])) == 4
    l9 = float(np.float32(L9))
    assert grid.values[0].tolist() == [-l9, l9, -l9, l9, 0.0]
    assert grid.states()[0].tolist() == [0, 100, 0, 100, -1]
    assert grid.cells_updated == 4 and grid.scans == 1
    himm = OccupancyGrid(GEO, model="himm")
    himm.update(Pose(0.5, 0.5), _scan([0.0, 0.0], [1.2, 3.2]))    # hit first: +3, not +3 - 1
    assert himm.values[0].tolist() == [0, 3, 0, 3, 0] and himm.states()[0].tolist() == [0, 100, 0, 100, -1]


def test_stamp_scans_and_seen():
    grid = OccupancyGrid(GEO, model="himm")
    assert grid.stamp.dtype == np.int32 and grid.scans == 0 and not grid.seen.any()
    grid.update(Pose(0.5, 0.5), _scan([0.0], [3.2]))                # scan 1: row 0, cols 0..3
    occ = np.zeros((5, 5), bool)
    occ[0, 2] = occ[3, 3] = True
    grid.mark_occupied(occ)                                         # a mark counts as scan 2
    free = np.zeros((5, 5), bool)
    free[4, 4] = True
    grid.mark_free(free)                                            # scan 3
    assert grid.scans == 3
    expected = np.zeros((5, 5), np.int32)
    expected[0, 0:4] = [1, 1, 2, 1]
    expected[3, 3] = 2
    expected[4, 4] = 3
    np.testing.assert_array_equal(grid.stamp, expected)
    np.testing.assert_array_equal(grid.seen, expected > 0)
    assert grid.free()[4, 4] and grid.states()[4, 4] == 0           # HIMM free needs `seen`
    assert grid.values[0].tolist() == [0, 0, 15, 3, 0]
    # The next scan has id 4, so the cells the marks stamped are updated again: (0,2) 15 -> 14.
    grid.update(Pose(0.5, 0.5), _scan([0.0], [math.inf]))
    assert grid.scans == 4 and grid.stamp[0].tolist() == [4] * 5
    assert grid.values[0].tolist() == [0, 0, 14, 2, 0]
    with pytest.raises(AttributeError):
        grid.seen = np.zeros((5, 5), bool)


def test_range_max_cap_and_clamp():
    grid = OccupancyGrid(GEO, range_max=1.4, l_clamp=3.0)
    for _ in range(3):
        grid.update(Pose(0.5, 0.5), _scan([0.0], [3.2]))       # beyond 1.4 m: no hit, 2 cells free
    assert grid.values[0].tolist() == [-3.0, -3.0, 0.0, 0.0, 0.0]
    assert grid.cells_updated == 6


def test_himm_states_and_probability():
    grid = OccupancyGrid(GEO, model="himm")
    assert grid.values.dtype == np.uint8
    grid.update(Pose(0.5, 0.5), _scan([0.0], [3.2]))
    assert grid.values[0].tolist() == [0, 0, 0, 3, 0]
    assert grid.states()[0].tolist() == [0, 0, 0, 100, -1]
    for _ in range(5):
        grid.update(Pose(0.5, 0.5), _scan([0.0], [3.2]))
    assert grid.values[0, 3] == 15
    grid.update(Pose(0.5, 4.5), _scan([0.0], [math.inf]))     # row 4 all seen, certainty 0
    p = grid.probability()
    np.testing.assert_allclose(p[0], [0.0, 0.0, 0.0, 1.0, 0.5], atol=1e-6)
    assert (p[4] == 0).all() and (grid.states()[4] == 0).all()
    # The ROS thresholds reproduce the states.
    ros = np.where(p > 0.65, 100, np.where(p < 0.196, 0, -1))
    np.testing.assert_array_equal(ros, grid.states())


def test_frontier_and_groups():
    grid = OccupancyGrid(GridGeometry(0.0, 0.0, 1.0, 6, 7))
    free = np.zeros((6, 7), bool)
    free[0:2, 0:3] = True          # group A: touches unknown at col 3 and row 2
    free[5, 6] = True              # group B: one cell
    grid.mark_free(free)
    occ = np.zeros((6, 7), bool)
    occ[0:2, 3] = True             # wall right of A
    grid.mark_occupied(occ)
    front = grid.frontier()
    expected = np.zeros((6, 7), bool)
    expected[1, 0:3] = True        # unknown above
    expected[5, 6] = True
    np.testing.assert_array_equal(front, expected)
    groups = grid.frontier_groups()
    assert [g.tolist() for g in groups] == [[[1, 0], [1, 1], [1, 2]], [[5, 6]]]
    assert [g.tolist() for g in grid.frontier_groups(min_cells=2)] == [[[1, 0], [1, 1], [1, 2]]]
    assert grid.values[0, 0] == np.float32(-3.5) and grid.values[0, 3] == np.float32(3.5)
    assert grid.cells_updated == 9
    np.testing.assert_array_equal(grid.seen, free | occ)


def test_frontier_groups_are_8_connected():
    grid = OccupancyGrid(GridGeometry(0.0, 0.0, 1.0, 4, 4), model="himm")
    free = np.eye(4, dtype=bool)
    grid.mark_free(free)
    assert len(grid.frontier_groups()) == 1 and len(grid.frontier_groups()[0]) == 4
    assert (grid.values == 0).all() and grid.states().tolist()[0] == [0, -1, -1, -1]


def test_copy_is_independent():
    grid = OccupancyGrid(GEO)
    grid.update(Pose(0.5, 0.5), _scan([0.0], [3.2]))
    other = grid.copy()
    other.update(Pose(0.5, 4.5), _scan([0.0], [3.2]))
    assert grid.unknown()[4].all() and not other.unknown()[4].all()
    assert other.cells_updated == 8 and grid.cells_updated == 4
    assert other.scans == 2 and grid.scans == 1
    assert (other.stamp[4, 0:4] == 2).all() and not grid.stamp[4].any()


@pytest.mark.parametrize("kwargs", [
    {"model": "bayes"}, {"p_occ": 0.5}, {"p_occ": 1.0}, {"p_free": 0.0}, {"p_free": 0.6},
    {"l_clamp": 0.0}, {"range_max": -1.0},
])
def test_bad_parameters_raise_config_error(kwargs):
    with pytest.raises(ConfigError):
        OccupancyGrid(GEO, **kwargs)


def test_bad_inputs_raise_config_error():
    with pytest.raises(ConfigError, match="cell > 0"):
        OccupancyGrid(GridGeometry(0.0, 0.0, 0.0, 5, 5))
    grid = OccupancyGrid(GEO)
    with pytest.raises(ConfigError, match="angles"):
        grid.update(Pose(0.5, 0.5), _scan([0.0, 1.0], [1.0]))
    with pytest.raises(ConfigError, match="mask"):
        grid.mark_free(np.zeros((4, 5), bool))
    with pytest.raises(ConfigError, match="min_cells"):
        grid.frontier_groups(0)


def test_near_occupied_is_the_occupied_cells_and_their_8_neighbours() -> None:
    grid = OccupancyGrid(GridGeometry(0.0, 0.0, 1.0, 5, 6))
    grid.values[1, 1] = 1.0            # interior: a 3 x 3 block
    grid.values[4, 5] = 2.0            # corner: clipped to 2 x 2
    expected = np.zeros((5, 6), bool)
    expected[0:3, 0:3] = True
    expected[3:5, 4:6] = True
    assert np.array_equal(grid.near_occupied(), expected)


def test_geometry_array_helpers_agree_with_the_scalar_ones() -> None:
    geo = GridGeometry(-1.25, 2.0, 0.1, 30, 40)
    pts = np.array([[-1.25, 2.0], [-1.2500001, 2.05], [2.74, 4.99], [2.75, 5.0], [0.0, 3.333], [-9.0, 9.0]])
    cells = geo.cells_of(pts)
    assert cells.tolist() == [list(geo.cell_of(x, y)) for x, y in pts]
    assert cells.tolist()[:2] == [[0, 0], [0, -1]]
    assert geo.contains_cells(cells).tolist() == [geo.contains(int(r), int(c)) for r, c in cells]
    assert geo.contains_cells(cells).tolist() == [True, False, True, False, True, False]
    assert geo.centers_of(cells[:3]).tolist() == [list(geo.center_of(int(r), int(c))) for r, c in cells[:3]]
    assert geo.cells_of(np.zeros((0, 2))).shape == (0, 2) and geo.centers_of(np.zeros((0, 2))).shape == (0, 2)


def test_replace_box_sets_the_box_and_counts_one_mark():
    grid = OccupancyGrid(GEO)
    grid.update(Pose(0.5, 0.5), _scan([0.0, math.pi / 2], [4.2, 4.2]))     # scan 1: row 0 and col 0
    before = grid.values.copy()
    sub = OccupancyGrid(GridGeometry(2.0, 1.0, 1.0, 2, 3))                   # rows 1..2, cols 2..4
    sub.update(Pose(2.5, 1.5), _scan([0.0], [1.2]))                          # its row 0: cols 0, 1 free, none hit
    grid.replace_box(1, 2, sub)
    assert grid.scans == 2
    np.testing.assert_array_equal(grid.values[1:3, 2:5], sub.values)
    outside = np.ones((5, 5), bool)
    outside[1:3, 2:5] = False
    np.testing.assert_array_equal(grid.values[outside], before[outside])
    assert grid.stamp[1, 2:5].tolist() == [2, 2, 0] and grid.stamp[2, 2:5].tolist() == [0, 0, 0]
    assert grid.stamp[0].tolist() == [1] * 5                                   # outside: as it was
    assert grid.changed_box(1) == (1, 3, 2, 5)
    with pytest.raises(ConfigError, match="does not fit"):
        grid.replace_box(4, 4, sub)
    with pytest.raises(ConfigError, match="does not fit"):
        grid.replace_box(0, 0, OccupancyGrid(GridGeometry(0.0, 0.0, 1.0, 2, 2), model="himm"))


def test_reach_box_part_and_blank_by_hand():
    geo = GridGeometry(0.0, 0.0, 1.0, 10, 10)
    # points (2.5, 3.5) and (4.2, 3.9), reach 1 m: x 1.5..5.2 -> cols floor(1.5) - 1 = 0 .. ceil(5.2) + 1 = 7;
    # y 2.5..4.9 -> rows 1 .. 6
    assert geo.reach_box([[2.5, 3.5], [4.2, 3.9]], 1.0) == (1, 6, 0, 7)
    assert geo.reach_box([[9.5, 9.5]], 3.0) == (5, 10, 5, 10)            # cut to the grid
    assert geo.reach_box([[30.0, 30.0]], 1.0) is None                     # nothing of the grid left
    assert geo.part((1, 6, 0, 7)) == GridGeometry(0.0, 1.0, 1.0, 5, 7)
    grid = OccupancyGrid(geo, model="logodds", p_free=0.3, range_max=4.0)
    sub = grid.blank(geo.part((1, 6, 0, 7)))
    assert (sub.model, sub.range_max, sub.l_occ, sub.l_free, sub.l_clamp) == \
        (grid.model, grid.range_max, grid.l_occ, grid.l_free, grid.l_clamp)
    assert sub.shape == (5, 7) and not sub.values.any() and sub.scans == 0
