"""team_candidates: the frontier cut into 1 m targets, with each robot's path cost; label_cells."""

from __future__ import annotations


import numpy as np

from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.planning.targets import PlanCosts, frontier_targets
from robotexp.planning.team import label_cells, team_candidates


def corridor() -> OccupancyGrid:
    """A known free strip 6 m x 1 m (x 1..7, y 1..2) in unknown space: its two ends and long sides are frontier."""
    grid = OccupancyGrid(GridGeometry(0.0, 0.0, 0.1, 30, 80))
    mask = np.zeros(grid.shape, bool)
    mask[10:20, 10:70] = True
    grid.mark_free(mask)
    return grid


def test_the_frontier_is_cut_into_metre_squares_each_cell_in_one():
    # squares on the grid of the scanned window: the 6 m x 1 m strip's frontier in 2 x 6 + 2 pieces at least
    grid = corridor()
    cand = team_candidates(grid, None, [(1.5, 1.5)], radius=0.25)
    frontier = np.argwhere(frontier_targets(grid, 5))
    cells = np.concatenate(cand.cells)
    assert sorted(map(tuple, cells)) == sorted(map(tuple, frontier))        # every frontier cell once
    for members, (x, y) in zip(cand.cells, cand.points, strict=True):
        rows, cols = members[:, 0], members[:, 1]
        assert rows.max() - rows.min() < 10 and cols.max() - cols.min() < 10      # within one 1 m square
        assert tuple(grid.geo.cell_of(x, y)) in set(map(tuple, members))     # placed on one of its cells
    assert len(cand) >= 14
    assert np.isnan(cand.cost).all()                # no costs asked for


def test_costs_are_path_lengths_to_where_a_robot_can_stand_and_label_cells_finds_a_target_again():
    grid = corridor()
    costs = PlanCosts(0.25, 0.3)
    cand = team_candidates(grid, costs, [(1.5, 1.5), (6.5, 1.5)], radius=0.25)
    assert np.isfinite(cand.cost).all()
    x = cand.points[:, 0]
    west, east = int(np.argmin(x)), int(np.argmax(x))
    # within reach of the robot (radius + 1 m) the cost is 0; across the strip it is about the distance
    # between the robot and the nearest place within reach, on cells that cost 1 per step away from walls
    assert cand.cost[0, west] == 0.0 and cand.cost[1, east] == 0.0
    far = cand.cost[0, east]
    straight = abs(cand.points[east, 0] - 1.5) - 1.25
    assert straight - 0.2 <= far <= straight * 1.3
    assert np.all(np.diff(cand.cost[0][np.argsort(x)]) >= -0.15)      # farther east, dearer from the west
    assert label_cells(cand, cand.cells[east][:3]) == east
    assert label_cells(cand, np.array([[0, 0]])) is None
    assert np.isinf(team_candidates(grid, costs, [(0.05, 0.05)], radius=0.25).cost).all()   # off the known map
