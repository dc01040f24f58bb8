"""Grid path planning: distance transform, cost grid with danger zones, Dijkstra, A*, smoothing.

All grids are numpy arrays indexed [row, col] with row 0 at the bottom (see
`robotexp.mapping.geometry.GridGeometry`); distances are in cells, costs in cost units (a cost
of 1 per cell of length means cost units = cells). Moves are 8-connected: a step costs its length
(1 or sqrt 2) times the mean of the two cells' costs; a diagonal step is allowed only when both
orthogonal neighbours it passes between are passable (no corner cutting). A cost of ``inf``
marks a blocked cell.

Typical use::

    dist = distance_transform(occupied | unknown)
    cost = cost_grid(dist, robot_radius_cells=5, danger_radius_cells=4, danger_cost=10.0)
    path = astar(cost, start_rc, goal_rc)
    if path is not None:
        waypoints = simplify(path, np.isfinite(cost))

A start cell that is itself blocked reaches nothing: planners return None (or an all-``inf``
field); clear the start cell's cost first to plan out of an inflated obstacle.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TypeVar

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.planning import kernels as _k

__all__ = [
    "astar",
    "cost_grid",
    "dijkstra",
    "distance_transform",
    "line_of_sight",
    "nearest_goal",
    "path_cost",
    "path_from_parents",
    "simplify",
    "warm",
]

Cell = tuple[int, int]
Path = npt.NDArray[np.int32]
_T = TypeVar("_T", bound=np.generic)


def _grid(a: npt.ArrayLike, what: str, dtype: type[_T]) -> npt.NDArray[_T]:
    arr = np.asarray(a)
    if arr.ndim != 2 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise ConfigError(f"{what}: expected a non-empty 2-D (rows, cols) array, got shape {arr.shape}")
    return np.ascontiguousarray(arr, dtype=dtype)


def _costs(cost: npt.ArrayLike, where: str) -> npt.NDArray[np.float64]:
    return _costs_low(cost, where)[0]


def _costs_low(cost: npt.ArrayLike, where: str) -> tuple[npt.NDArray[np.float64], float]:
    """The checked costs (float64, C-contiguous) and their smallest value (NaN if any is NaN: one pass finds
    both a bad cost and the smallest one; inf when every cell is blocked)."""
    c = _grid(cost, f"{where}: cost", np.float64)
    low = float(c.min())
    if math.isnan(low) or low < 0:
        bad = np.argwhere(np.isnan(c) | (c < 0))[0]
        raise ConfigError(f"{where}: cost[{bad[0]}, {bad[1]}] = {c[bad[0], bad[1]]}; costs must be "
                          f">= 0 or inf (blocked), never NaN or negative")
    return c, low


def _mask(mask: npt.ArrayLike, shape: tuple[int, ...], what: str) -> npt.NDArray[np.bool_]:
    m = np.asarray(mask)
    if m.shape != shape:
        raise ConfigError(f"{what}: shape {m.shape} differs from the grid's {shape}; pass one value "
                          f"per cell")
    if m.dtype != np.bool_:
        raise ConfigError(f"{what}: expected a bool array, got dtype {m.dtype}; compare or cast it "
                          f"(e.g. mask > 0)")
    return np.ascontiguousarray(m)


def _cell(rc: Sequence[int] | npt.ArrayLike, shape: tuple[int, ...], what: str) -> Cell:
    vals = np.asarray(rc).ravel()
    if vals.shape != (2,) or not np.issubdtype(vals.dtype, np.integer):
        raise ConfigError(f"{what}: expected an integer (row, col) pair, got {rc!r}")
    r, c = int(vals[0]), int(vals[1])
    if not (0 <= r < shape[0] and 0 <= c < shape[1]):
        raise ConfigError(f"{what}: cell ({r}, {c}) is outside the {shape[0]} x {shape[1]} grid; "
                          f"need 0 <= row < {shape[0]} and 0 <= col < {shape[1]}")
    return r, c


def distance_transform(occ: npt.ArrayLike) -> npt.NDArray[np.float32]:
    """Exact Euclidean distance [cells] from each cell centre to the nearest occupied centre.

    Felzenszwalb-Huttenlocher lower envelope of parabolas, one 1-D pass per axis: O(rows*cols).

    Args:
        occ: (rows, cols) bool, True = occupied (pass ``occupied | unknown`` to keep clear of
            unexplored space too).

    Returns:
        (rows, cols) float32 distances [cells]: 0 on occupied cells, ``inf`` everywhere when no
        cell is occupied.

    Raises:
        ConfigError: `occ` is not a non-empty 2-D bool array.
    """
    o = np.asarray(occ)
    if o.dtype != np.bool_:
        raise ConfigError(f"distance_transform: occ must be a bool array, got dtype {o.dtype}; "
                          f"compare or cast it (e.g. logodds > 0)")
    o = _grid(o, "distance_transform: occ", np.bool_)
    out = np.empty(o.shape, dtype=np.float32)
    _k.distance_transform_kernel(o, out)
    return out


def cost_grid(dist_cells: npt.ArrayLike, *, robot_radius_cells: float,
              danger_radius_cells: float = 0.0, danger_cost: float = 0.0,
              blocked: npt.ArrayLike | None = None) -> npt.NDArray[np.float32]:
    """Per-cell traversal cost from the obstacle distance, with a "danger zone" (Santos 2016).

    With d the distance, R = robot_radius_cells and D = danger_radius_cells:
    ``inf`` where d <= R or `blocked`; ``1 + danger_cost * (1 - (d - R) / D)`` where
    R < d <= R + D (from 1 + danger_cost next to the inflated obstacle down to 1 at its edge);
    1 elsewhere.

    Args:
        dist_cells: (rows, cols) distance to the nearest obstacle [cells], e.g. from
            `distance_transform`.
        robot_radius_cells: [cells] robot radius; cells this close to an obstacle are blocked.
        danger_radius_cells: [cells] width of the danger zone beyond the robot radius (0: none).
        danger_cost: extra cost at the inner edge of the danger zone (>= 0).
        blocked: optional (rows, cols) bool, True = blocked regardless of distance.

    Returns:
        (rows, cols) float32 costs, >= 1 or ``inf``.

    Raises:
        ConfigError: a negative radius or danger cost, NaN distances, a `blocked` mask of another
            shape or dtype.
    """
    d = _grid(dist_cells, "cost_grid: dist_cells", np.float64)
    for name, value in (("robot_radius_cells", robot_radius_cells),
                        ("danger_radius_cells", danger_radius_cells), ("danger_cost", danger_cost)):
        if not (math.isfinite(value) and value >= 0):
            raise ConfigError(f"cost_grid: {name} must be finite and >= 0, got {value}")
    if np.isnan(d).any():
        raise ConfigError("cost_grid: dist_cells contains NaN; pass distances >= 0 or inf")
    rr = float(robot_radius_cells)
    dr = float(danger_radius_cells)
    cost = np.ones(d.shape, dtype=np.float64)
    if dr > 0 and danger_cost > 0:
        zone = (d > rr) & (d <= rr + dr)
        cost[zone] = 1.0 + danger_cost * (1.0 - (d[zone] - rr) / dr)
    cost[d <= rr] = np.inf
    if blocked is not None:
        cost[_mask(blocked, d.shape, "cost_grid: blocked")] = np.inf
    return cost.astype(np.float32)


def dijkstra(cost: npt.ArrayLike, start_rc: Sequence[int], goal_mask: npt.ArrayLike | None = None,
             max_dist: float = math.inf) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int32]]:
    """Shortest-path distances from `start_rc` (8-connected, no corner cutting).

    Without `goal_mask` the whole field within `max_dist` is filled. With it the search stops
    when the first goal cell is settled: that cell is then the only goal cell with a finite
    distance (use `nearest_goal` to get it directly).

    Args:
        cost: (rows, cols) cell costs >= 0, ``inf`` = blocked.
        start_rc: (row, col) start cell.
        goal_mask: optional (rows, cols) bool goal cells.
        max_dist: [cost units] cells farther than this stay unreached.

    Returns:
        ``(dist, parent)``: dist (rows, cols) float64 exact distances [cost units], ``inf`` for
        cells not reached (or not settled before the early exit); parent (rows*cols,) int32 flat
        index of the previous cell on a shortest path, -1 for the start and unreached cells (see
        `path_from_parents`).

    Raises:
        ConfigError: malformed cost or mask, start outside the grid, NaN `max_dist`.
    """
    c = _costs(cost, "dijkstra")
    r, col = _cell(start_rc, c.shape, "dijkstra: start_rc")
    if math.isnan(max_dist):
        raise ConfigError("dijkstra: max_dist is NaN; pass a distance [cost units] or inf")
    dist = np.empty(c.size, dtype=np.float64)
    parent = np.empty(c.size, dtype=np.int32)
    start = r * c.shape[1] + col
    if goal_mask is None:
        _k.dijkstra_fill(c, start, float(max_dist), dist, parent)
    else:
        g = _mask(goal_mask, c.shape, "dijkstra: goal_mask")
        _k.dijkstra_search(c, start, g, float(max_dist), dist, parent)
    return dist.reshape(c.shape), parent


def path_from_parents(parent: npt.NDArray[np.int32], cols: int, end_rc: Sequence[int]) -> Path:
    """The cells from the search root to `end_rc`, following a `dijkstra` parent array.

    Args:
        parent: (rows*cols,) int32 as returned by `dijkstra`.
        cols: number of grid columns.
        end_rc: (row, col) end cell; it should have a finite distance.

    Returns:
        (k, 2) int32 [row, col] cells, root first, `end_rc` last (k = 1 when `end_rc` has no
        parent).

    Raises:
        ConfigError: `end_rc` outside the grid, or `parent` is not a flat int32 array.
    """
    p = np.asarray(parent)
    if p.ndim != 1 or p.dtype != np.int32 or cols < 1 or p.size % cols:
        raise ConfigError(f"path_from_parents: parent must be the flat int32 array from dijkstra "
                          f"with a multiple of cols={cols} entries, got shape {p.shape} {p.dtype}")
    r, c = _cell(end_rc, (p.size // cols, cols), "path_from_parents: end_rc")
    return _k.trace_path(np.ascontiguousarray(p), int(cols), r * cols + c)


def astar(cost: npt.ArrayLike, start_rc: Sequence[int], goal_rc: Sequence[int]) -> Path | None:
    """Least-cost path by A* (octile heuristic times the smallest cell cost: optimal).

    Same moves and step costs as `dijkstra`, so ``path_cost(cost, path)`` equals Dijkstra's
    distance to the goal.

    Args:
        cost: (rows, cols) cell costs >= 0, ``inf`` = blocked.
        start_rc: (row, col) start cell.
        goal_rc: (row, col) goal cell.

    Returns:
        (k, 2) int32 [row, col] cells from start to goal, both included (k = 1 when they are the
        same cell), or None when the goal is unreachable or either end is blocked.

    Raises:
        ConfigError: malformed cost, start or goal outside the grid.
    """
    c, low = _costs_low(cost, "astar")
    sr, sc = _cell(start_rc, c.shape, "astar: start_rc")
    gr, gc = _cell(goal_rc, c.shape, "astar: goal_rc")
    min_cost = low if math.isfinite(low) else 0.0       # the smallest finite cost (inf only when none is)
    cols = c.shape[1]
    parent = np.empty(c.size, dtype=np.int32)
    length = _k.astar_kernel(c, sr * cols + sc, gr * cols + gc, min_cost, parent)
    if math.isinf(length):
        return None
    return _k.trace_path(parent, cols, gr * cols + gc)


def nearest_goal(cost: npt.ArrayLike, start_rc: Sequence[int],
                 goal_mask: npt.ArrayLike) -> tuple[Cell, Path, float] | None:
    """The goal cell with the least path cost from `start_rc` (Dijkstra with early exit).

    Args:
        cost: (rows, cols) cell costs >= 0, ``inf`` = blocked.
        start_rc: (row, col) start cell.
        goal_mask: (rows, cols) bool goal cells (e.g. frontier cells).

    Returns:
        ``(goal_rc, path, length)``: the goal (row, col), the (k, 2) int32 path from start to it
        and its cost [cost units]; None when no goal cell is reachable.

    Raises:
        ConfigError: malformed cost or mask, start outside the grid.
    """
    c = _costs(cost, "nearest_goal")
    r, col = _cell(start_rc, c.shape, "nearest_goal: start_rc")
    g = _mask(goal_mask, c.shape, "nearest_goal: goal_mask")
    dist = np.empty(c.size, dtype=np.float64)
    parent = np.empty(c.size, dtype=np.int32)
    cols = c.shape[1]
    found = _k.nearest_goal_kernel(c, r * cols + col, g, dist, parent)
    if found < 0:
        return None
    return (found // cols, found % cols), _k.trace_path(parent, cols, found), float(dist[found])


def path_cost(cost: npt.ArrayLike, path: npt.ArrayLike) -> float:
    """Cost [cost units] of a path under the planners' step rule (length x mean cell cost).

    Args:
        cost: (rows, cols) cell costs.
        path: (k, 2) int [row, col] cells, consecutive ones 8-neighbours.

    Returns:
        Sum of the step costs (0 for a single cell; ``inf`` through a blocked cell).

    Raises:
        ConfigError: malformed cost or path, a cell outside the grid, a jump longer than one cell.
    """
    c = _costs(cost, "path_cost")
    p = np.asarray(path)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] < 1 or not np.issubdtype(p.dtype, np.integer):
        raise ConfigError(f"path_cost: path must be a (k >= 1, 2) integer array, got shape {p.shape} "
                          f"{p.dtype}")
    p = p.astype(np.int64)
    if (p < 0).any() or (p[:, 0] >= c.shape[0]).any() or (p[:, 1] >= c.shape[1]).any():
        raise ConfigError(f"path_cost: path leaves the {c.shape[0]} x {c.shape[1]} grid")
    steps = np.abs(np.diff(p, axis=0))
    jump = steps.max(axis=1) > 1
    if jump.any():
        k = int(np.argmax(jump))
        raise ConfigError(f"path_cost: cells {k} and {k + 1} of the path are not 8-neighbours")
    vals = c[p[:, 0], p[:, 1]]
    lengths = np.where(steps.sum(axis=1) == 2, math.sqrt(2.0), 1.0)
    return float(np.sum(lengths * (0.5 * (vals[:-1] + vals[1:]))))


def line_of_sight(passable: npt.ArrayLike, a_rc: Sequence[int], b_rc: Sequence[int]) -> bool:
    """True when every cell the segment between the centres of `a_rc` and `b_rc` touches is passable.

    Supercover line: a segment through a grid corner touches all four cells around it, so a
    diagonal step is visible only when both cells beside it are passable (as in the planners).

    Args:
        passable: (rows, cols) bool, e.g. ``np.isfinite(cost)``.
        a_rc: (row, col) first cell.
        b_rc: (row, col) second cell.

    Returns:
        Whether b is visible from a (False when either is blocked).

    Raises:
        ConfigError: `passable` not a 2-D bool array, a cell outside the grid.
    """
    m = _passable(passable, "line_of_sight")
    ar, ac = _cell(a_rc, m.shape, "line_of_sight: a_rc")
    br, bc = _cell(b_rc, m.shape, "line_of_sight: b_rc")
    return bool(_k.line_of_sight_kernel(m, ar, ac, br, bc))


def _passable(passable: npt.ArrayLike, where: str) -> npt.NDArray[np.bool_]:
    m = np.asarray(passable)
    if m.dtype != np.bool_:
        raise ConfigError(f"{where}: passable must be a bool array, got dtype {m.dtype}; use e.g. "
                          f"np.isfinite(cost)")
    return _grid(m, f"{where}: passable", np.bool_)


def simplify(path: npt.ArrayLike, passable: npt.ArrayLike) -> Path:
    """Drop the path cells not needed for line of sight (string pulling); ends are kept.

    Greedy: from the last kept cell, follow the path while cells stay visible; keep the last
    visible one. Consecutive kept cells see each other (`line_of_sight`) when the input is a
    valid planner path.

    Args:
        path: (k, 2) int [row, col] cells, consecutive ones 8-neighbours (as from `astar`).
        passable: (rows, cols) bool, e.g. ``np.isfinite(cost)``.

    Returns:
        (m, 2) int32 kept cells in path order, m <= k (m = 2 for a visible straight run).

    Raises:
        ConfigError: malformed path or passable, a path cell outside the grid.
    """
    m = _passable(passable, "simplify")
    p = np.asarray(path)
    if p.ndim != 2 or p.shape[1] != 2 or not np.issubdtype(p.dtype, np.integer):
        raise ConfigError(f"simplify: path must be a (k, 2) integer array, got shape {p.shape} {p.dtype}")
    p = np.ascontiguousarray(p, dtype=np.int32)
    if (p < 0).any() or (p[:, 0] >= m.shape[0]).any() or (p[:, 1] >= m.shape[1]).any():
        raise ConfigError(f"simplify: path leaves the {m.shape[0]} x {m.shape[1]} grid")
    keep = np.empty(p.shape[0], dtype=np.bool_)
    _k.simplify_kernel(p, m, keep)
    return p[keep]


_warmed = False


def warm() -> None:
    """Call every planning kernel once, through the functions above, on an 8 x 8 grid: numba compiles
    (or loads from its cache) each at its first call, and a real robot's run must not wait for that
    mid-run, blind (`robotexp.experiment.warm_kernels` calls this; once per process). A short warm-up
    run may never need some of them: A* is only called once a target is chosen."""
    global _warmed
    if _warmed:
        return
    occ = np.zeros((8, 8), np.bool_)
    occ[4, 1:6] = True
    dist = distance_transform(occ)
    cost = cost_grid(dist, robot_radius_cells=0.5, danger_radius_cells=1.0, danger_cost=1.0).astype(np.float64)
    dijkstra(cost, (0, 0))
    dijkstra(cost, (0, 0), ~occ, max_dist=50.0)
    nearest_goal(cost, (0, 0), ~occ)
    path = astar(cost, (0, 0), (7, 7))
    if path is not None:
        simplify(path, ~occ)
    line_of_sight(~occ, (0, 0), (7, 7))
    boxes = np.zeros((8, 8, 4), np.uint8)
    out = np.empty((8, 8), np.float32)
    offsets = _k.box_offsets(3.0)
    _k.box_distance_kernel(occ, boxes, dist, ~occ, offsets, 3.0, 3.0, 0, 8, 0, 8, out)             # a whole grid
    _k.box_distance_kernel(occ, boxes, dist, ~occ, offsets, 3.0, 3.0, 2, 4, 2, 4, out[2:4, 2:4])   # a window
    _warmed = True
