"""Frontier targets for a team (`team_candidates`): the frontier of a map cut into targets about a metre
wide, with the path cost from each robot to each, for a coordinator (`robotexp.coordinator`) to share out."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import numpy.typing as npt

from robotexp.coordinator import Candidates
from robotexp.mapping.grid import OccupancyGrid
from robotexp.planning.grid_planner import dijkstra
from robotexp.planning.targets import PlanCosts, frontier_targets, known_window, passable_cell

__all__ = ["team_candidates", "with_costs", "SPACING", "label_cells"]

SPACING = 1.0           # [m] side of the squares the frontier is cut into, one target each
STAND_REACH = 1.0       # [m] how far from its target a robot may stand to look at it
WINDOW_MARGIN = 2       # [cells] kept around the scanned part of the map


def team_candidates(grid: OccupancyGrid, costs: PlanCosts | None, poses: Sequence[tuple[float, float]],  # noqa: PLR0913
                    radius: float, spacing: float = SPACING,
                    frontier: tuple[npt.NDArray[np.bool_], tuple[int, int]] | None = None) -> Candidates:
    """The frontier targets of `grid` and the path cost [m] from each robot at `poses` [m] to each.

    The frontier cells worth going to (`frontier_targets`: groups at least a robot wide, wall faces left
    out) are cut into squares of `spacing` [m]; each square's cells are one target, placed at the cell
    nearest their mean. A robot's cost to a target is its shortest path (Dijkstra on `costs`, the same
    costs as the explorers' plans, times the cell size) to the nearest cell it can stand on within
    `radius` + STAND_REACH of that point; inf when there is none.

    Args:
        grid: the team's map.
        costs: the plan costs kept for `grid` (updated here); None: no costs yet (all nan: `with_costs`
            adds them).
        poses: (x, y) [m] of each robot.
        radius: [m] the largest footprint radius of the team.
        spacing: [m] side of the squares.
        frontier: the frontier cells to cut, a bool mask of a window of `grid` and the window's (row, col)
            offset (an explorer's `target_frontier`); None: `frontier_targets` of the map.
    """
    geo = grid.geo
    if frontier is None:
        view, off = known_window(grid, WINDOW_MARGIN)
        mask = frontier_targets(view, max(1, int(math.ceil(2 * radius / geo.cell))))
    else:
        mask, off = frontier
    cols = mask.shape[1]
    cells = np.argwhere(mask)
    side = max(1, int(round(spacing / geo.cell)))
    groups: list[npt.NDArray[np.int64]] = []
    points: list[tuple[float, float]] = []
    if len(cells):
        bins = (cells[:, 0] // side) * (cols // side + 1) + cells[:, 1] // side
        order = np.argsort(bins, kind="stable")
        cells, bins = cells[order], bins[order]
        starts = np.flatnonzero(np.r_[True, bins[1:] != bins[:-1]])
        for lo, hi in zip(starts, np.r_[starts[1:], len(cells)], strict=True):
            members = cells[lo:hi]
            mean = members.mean(axis=0)
            rep = members[int(np.argmin(((members - mean) ** 2).sum(axis=1)))]
            groups.append(members + off)
            points.append(geo.center_of(int(rep[0] + off[0]), int(rep[1] + off[1])))
    cand = Candidates(points=np.asarray(points, np.float64).reshape(-1, 2), cells=tuple(groups),
                      cost=np.full((len(poses), len(groups)), np.nan),
                      positions=np.asarray(poses, np.float64).reshape(-1, 2))
    return cand if costs is None else with_costs(cand, grid, costs, radius)


def with_costs(cand: Candidates, grid: OccupancyGrid, costs: PlanCosts, radius: float) -> Candidates:
    """`cand` with the path cost [m] from each robot to each target (see `team_candidates`): one Dijkstra
    per robot on the part of `grid` the scans touched."""
    geo = grid.geo
    view, off = known_window(grid, WINDOW_MARGIN)
    rows, cols = view.shape
    cost = np.full((cand.robots, len(cand)), np.inf)
    if len(cand):
        c = costs.update(grid)[off[0]:off[0] + rows, off[1]:off[1] + cols]
        passable = np.isfinite(c)
        reach = int(math.ceil((radius + STAND_REACH) / geo.cell))
        reps = [geo.cell_of(x, y) for x, y in cand.points]
        for i, (x, y) in enumerate(cand.positions):
            start = passable_cell(geo, passable, float(x), float(y), offset=off)
            if start is None:
                continue
            dist, _ = dijkstra(c, start)
            for k, (r, q) in enumerate(reps):
                r, q = r - off[0], q - off[1]
                box = dist[max(r - reach, 0):r + reach + 1, max(q - reach, 0):q + reach + 1]
                if box.size:
                    cost[i, k] = float(box.min()) * geo.cell
    return replace(cand, cost=cost)


def label_cells(candidates: Candidates, cells: npt.NDArray[np.int64]) -> int | None:
    """The candidate that holds most of `cells` ((m, 2) grid cells, a robot's earlier target), None when
    none holds any."""
    if len(cells) == 0 or len(candidates) == 0:
        return None
    wanted = {(int(r), int(c)) for r, c in cells}
    best, count = None, 0
    for k, members in enumerate(candidates.cells):
        n = sum((int(r), int(c)) in wanted for r, c in members)
        if n > count:
            best, count = k, n
    return best
