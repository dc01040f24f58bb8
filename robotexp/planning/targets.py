"""Where goal-seeking explorers may go and at what cost: the planning helpers they share.

Frontier cells worth driving to (`frontier_targets`, `usable_frontier`), the traversal costs every plan
uses (`plan_costs`: known-free cells only, a cell passable where the robot's disc fits at one of its
points with a small hard `MARGIN` to the walls' surface, a costly zone beyond that keeps paths centred),
and the passable cell to plan from when the robot's own cell is not passable (`nearest_passable`,
`passable_cell`). The frontier, metaheuristic and SRT explorers all plan with these, and the run's check
of an explorer's "explored" asks the same passability; they lived in the frontier plugin before, and
plugins do not import each other.

The walls' surface is measured finer than the cell: each occupied cell keeps the box of the laser
endpoints that fell in it (`OccupancyGrid.hit_box`), and a cell's distance to the walls is the distance
from its centre to the nearest such box (`wall_distance`). A plan may pass through a cell at its centre
or, where the centre is too near a wall, at another of nine points a third of a cell apart
(`cell_points`): a gap is open to the planners wherever it lies on the grid when it is wider than the
robot plus twice the margin by a third of a cell and a little; judged at the centres only, it took a
whole cell more (a 0.6 m gap closed to a 0.5 m robot on 10 cm cells).
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from robotexp.mapping.geometry import GridGeometry
from robotexp.errors import ConfigError
from robotexp.mapping.grid import OccupancyGrid
from robotexp.mapping.kernels import label8
from robotexp.planning import kernels as _k
from robotexp.planning.grid_planner import cost_grid, distance_transform
from robotexp.planning.reach import probe_cells

__all__ = ["MARGIN", "START_REACH", "plan_costs", "nearest_passable", "passable_cell", "frontier_targets",
           "usable_frontier", "known_window", "PlanCosts", "WallDistance", "WallMemory", "wall_distance",
           "surface_distance", "passable_radius", "cell_points", "beside_large_unknown", "away_from",
           "discs_blocked", "FirmCells", "shared_firm_cells", "forget_firm_cells", "shared_wall_memory"]

MARGIN = 0.02       # [m] kept between the robot's disc and the walls' surface by every plan (a hard limit)
DANGER_COST = 4.0   # extra cost at the inner edge of the danger zone
START_REACH = 0.5   # [m] how far from the robot a plan may start when its own cell is not passable


def wall_distance(grid: OccupancyGrid, reach: float, exact: float | None = None,
                  need: npt.NDArray[np.bool_] | None = None, points: npt.NDArray[np.uint8] | None = None,
                  below: float | None = None) -> npt.NDArray[np.float32]:
    """(rows, cols) float32 distance [cells] from each cell's centre to the nearest box of laser endpoints
    of an occupied cell (`OccupancyGrid.hit_box`; an occupied cell with none counts whole), exact up to
    `exact` [cells] (None: `reach`), from there up to `reach` [cells] the distance to the nearest occupied
    cell's centre less half a cell (costs beyond the hard limit), beyond some larger value (inf without an
    occupied cell). `need` (rows, cols) bool: only these cells' distances are asked (None: all); the others
    get a lower bound (e.g. the cells not free, which no plan enters). `points`, `below`: as
    `surface_distance`."""
    return surface_distance(grid.occupied(), grid.hit_box, reach, exact, need, points, below)


def surface_distance(occupied: npt.NDArray[np.bool_], hit_box: npt.NDArray[np.uint8], reach: float,
                     exact: float | None = None, need: npt.NDArray[np.bool_] | None = None,
                     points: npt.NDArray[np.uint8] | None = None, below: float | None = None
                     ) -> npt.NDArray[np.float32]:
    """`wall_distance` from the cells of `occupied` (rows, cols) bool, e.g. a map's occupied cells and those
    it ever showed firmly occupied (`WallMemory`), with their boxes of endpoints `hit_box` (rows, cols, 4).

    `points` (rows, cols) uint8: filled with each cell's point (`cell_points`), and the distance is then
    that point's: a cell within `below` [cells] (None: `exact`; at most `exact`) of the surface at its centre
    but farther at another of its points (a third of a cell apart) takes that point (`best_point_kernel`)."""
    exact = reach if exact is None else min(exact, reach)
    below = exact if below is None else min(below, exact)
    occ = np.ascontiguousarray(occupied)
    centre = distance_transform(occ)
    out = np.empty(occ.shape, np.float32)
    need = np.ones(occ.shape, np.bool_) if need is None else np.ascontiguousarray(need)
    box = np.ascontiguousarray(hit_box)
    _k.box_distance_kernel(occ, box, centre, need, _k.box_offsets(exact), float(exact),
                           float(reach), 0, occ.shape[0], 0, occ.shape[1], out)
    if points is not None:
        _k.best_point_kernel(occ, box, need, _k.box_offsets(below + 1.0), float(below), 0, occ.shape[0],
                             0, occ.shape[1], out, points)
    return out


def passable_radius(cell: float, radius: float) -> float:
    """[cells] a cell whose `wall_distance` is at most this is blocked for a robot of `radius` [m]."""
    return (radius + MARGIN) / cell


def plan_costs(grid: OccupancyGrid, radius: float, clearance: float,
               points: npt.NDArray[np.uint8] | None = None) -> npt.NDArray[np.float32]:
    """Traversal costs on `grid` for a robot of `radius` [m]: only known-free cells are passable.

    A cell is blocked when each of its points (its centre and eight more a third of a cell apart:
    `cell_points`) lies within radius + MARGIN of the walls' surface (`wall_distance`: the boxes of the
    laser endpoints in the occupied cells); a plan passes through a cell at its centre, or at the point
    `points` names where the centre is too near. The next `clearance` [m] is a danger zone whose cost rises
    towards the obstacle, so paths keep off walls where there is room and run down the middle of a door.

    Args:
        grid: the map.
        radius: [m] the robot's footprint radius.
        clearance: [m] width of the danger zone beyond the blocked cells.
        points: (rows, cols) uint8 filled with each cell's point (`cell_points`), or None.

    Returns:
        (rows, cols) float32 costs, inf where blocked (as `cost_grid`).
    """
    rr, dr = _cost_radii(grid.geo.cell, radius, clearance)
    free = grid.free()
    code = np.zeros(grid.shape, np.uint8) if points is None else points
    dist = surface_distance(grid.occupied(), grid.hit_box, rr + dr, rr, free, code)
    return cost_grid(dist, robot_radius_cells=rr, danger_radius_cells=dr, danger_cost=DANGER_COST, blocked=~free)


def cell_points(geo: GridGeometry, cells: npt.ArrayLike, points: npt.NDArray[np.uint8] | None = None,
                offset: tuple[int, int] = (0, 0)) -> npt.NDArray[np.float64]:
    """(k, 2) world (x, y) [m] where a plan passes through the (k, 2) (row, col) `cells`: their centres, or
    the point of a cell that `points` (the window's uint8 codes from `plan_costs` / `PlanCosts.points`,
    indexed by `cells`) names, an index into `SUB_POINTS` (0 the centre). `offset`: (row, col) in `geo` of
    the window's cell (0, 0)."""
    rc = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    xy = geo.centers_of(rc + np.asarray(offset, dtype=np.int64))
    if points is not None and len(rc):
        shift = _k.SUB_POINTS[points[rc[:, 0], rc[:, 1]]] * geo.cell
        xy[:, 0] += shift[:, 1]
        xy[:, 1] += shift[:, 0]
    return xy


def _cost_radii(cell: float, radius: float, clearance: float) -> tuple[float, float]:
    """`plan_costs`' robot radius and danger zone width [cells]."""
    return passable_radius(cell, radius), clearance / cell


class WallDistance:
    """The distance [cells] from each cell of a growing map to its nearest occupied cell, kept up to date
    by recomputing only near what the scans changed.

    Exact up to `reach` cells (beyond, some value > `reach`, or inf): a cell's distance within `reach`
    depends only on the occupied cells within `reach` of it, so after some scans the cells within `reach`
    of the box they changed (`OccupancyGrid.changed_box`) are recomputed from the occupied cells in that
    box grown by twice `reach`. An update costs what the scans since the last one touched, not the map.

    Args:
        reach: [cells] how far the distance must be exact.
        occupied: the cells to measure from, as a function of a box of the grid (rows r0..r1, cols
            c0..c1, half-open) giving its bool mask; None: the grid's occupied cells. It must change
            only where the scans changed the map (e.g. `WallMemory`'s cells ever firmly occupied).
        surface: measure to the boxes of the laser endpoints in the occupied cells (`wall_distance`,
            the walls' surface) rather than to the occupied cells' centres.
        exact: with `surface`, how far [cells] the distance to the surface is exact (None: `reach`);
            beyond, up to `reach`, as `wall_distance`.
        free_only: with `surface`, only the free cells' distances are asked (the others get a lower
            bound: `wall_distance`'s `need`), for costs that block every other cell anyway.
        points: with `surface`, a cell within `exact` of the surface at its centre but farther at another
            of its points (`cell_points`) takes that point's distance, and `code` (rows, cols) uint8 names
            the point (`surface_distance`'s `points`).
    """

    def __init__(self, reach: float,
                 occupied: Callable[[int, int, int, int], npt.NDArray[np.bool_]] | None = None,
                 surface: bool = False, exact: float | None = None, free_only: bool = False,
                 points: bool = False) -> None:
        # a box lies within half a diagonal of its cell's centre: the cells that bear on a distance
        # within `reach` of the surface lie within `reach` + 2 half diagonals of the centres
        self.reach = reach
        self.exact = reach if exact is None else min(exact, reach)
        self.k = int(math.ceil(reach)) + (3 if surface else 1)
        self.surface = surface
        self.free_only = free_only
        self.points = points and surface
        self._offsets: npt.NDArray[np.float64] | None = None
        self._point_offsets = _k.box_offsets(self.exact + 1.0) if self.points else None
        self.dist = np.zeros((0, 0), np.float32)
        self.code = np.zeros((0, 0), np.uint8)
        self._grid: OccupancyGrid | None = None
        self._synced = 0
        self._occupied = occupied

    def update(self, grid: OccupancyGrid) -> list[tuple[int, int, int, int]]:
        """Bring `dist` up to `grid` (a grid other than the last one, or with fewer scans, is started
        afresh: no cell occupied yet, all inf); return the boxes (rows r0..r1, cols c0..c1, half-open) of
        the cells recomputed, [] when none was (one box near each part of the map the scans changed:
        `OccupancyGrid.changed_boxes`)."""
        if self._grid is not grid or self.dist.shape != grid.shape or grid.scans < self._synced:
            self.dist = np.full(grid.shape, np.inf, np.float32)
            self.code = np.zeros(grid.shape if self.points else (0, 0), np.uint8)
            self._grid, self._synced = grid, 0
        boxes = grid.changed_boxes(self._synced, self.k)
        self._synced = grid.scans
        return [self._recompute(grid, box) for box in boxes]

    def _recompute(self, grid: OccupancyGrid, box: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
        """Recompute the cells within `k` of `box` from the occupied cells within 2 `k`; return their box."""
        k, (rows, cols) = self.k, grid.shape
        r0, r1, c0, c1 = max(box[0] - k, 0), min(box[1] + k, rows), max(box[2] - k, 0), min(box[3] + k, cols)
        s0, s1, t0, t1 = max(r0 - k, 0), min(r1 + k, rows), max(c0 - k, 0), min(c1 + k, cols)
        occ = grid.window(s0, s1, t0, t1).occupied() if self._occupied is None else self._occupied(s0, s1, t0, t1)
        sub = distance_transform(occ)
        if self.surface:
            if self._offsets is None:
                self._offsets = _k.box_offsets(self.exact)
            need = (grid.window(s0, s1, t0, t1).free() if self.free_only else np.ones(occ.shape, np.bool_))
            hits = np.ascontiguousarray(grid.hit_box[s0:s1, t0:t1])
            _k.box_distance_kernel(occ, hits, sub, need, self._offsets, float(self.exact), float(self.reach),
                                   r0 - s0, r1 - s0, c0 - t0, c1 - t0, self.dist[r0:r1, c0:c1])
            if self._point_offsets is not None:
                _k.best_point_kernel(occ, hits, need, self._point_offsets, float(self.exact), r0 - s0, r1 - s0,
                                     c0 - t0, c1 - t0, self.dist[r0:r1, c0:c1], self.code[r0:r1, c0:c1])
        else:
            self.dist[r0:r1, c0:c1] = sub[r0 - s0:r1 - s0, c0 - t0:c1 - t0]
        return r0, r1, c0, c1


class FirmCells:
    """The cells of a growing log-odds map ever shown firmly occupied (`OccupancyGrid.firmly_occupied`: hit at
    least twice more than crossed), noted once for every memory of walls that shares it (`shared_firm_cells`:
    the explorers of a team planning on one map, and the run's check of "explored" on that map). Call `note`
    after every scan the map integrates: it reads only the box the scans since the last call changed, so no
    occupied state is missed."""

    def __init__(self) -> None:
        self.ever = np.zeros((0, 0), np.bool_)
        self._grid: OccupancyGrid | None = None
        self._synced = 0

    def note(self, grid: OccupancyGrid) -> None:
        """Remember the cells of `grid` firmly occupied now among those the scans since the last call
        changed (a grid other than the last one, or with fewer scans, is started afresh)."""
        if self._grid is not grid or self.ever.shape != grid.shape or grid.scans < self._synced:
            self.ever = np.zeros(grid.shape, np.bool_)
            self._grid, self._synced = grid, 0
        if grid.scans == self._synced:
            return
        boxes = grid.changed_boxes(self._synced)
        self._synced = grid.scans
        for r0, r1, c0, c1 in boxes:
            self.ever[r0:r1, c0:c1] |= grid.firmly_occupied((r0, r1, c0, c1))


_SHARED_FIRM: weakref.WeakKeyDictionary[OccupancyGrid, FirmCells] = weakref.WeakKeyDictionary()


def shared_firm_cells(grid: OccupancyGrid) -> FirmCells:
    """The `FirmCells` of `grid` that every caller on that grid shares (made at the first call): eight explorers
    on a team's map note each scan once between them, not each the scans of all eight."""
    cells = _SHARED_FIRM.get(grid)
    if cells is None:
        cells = _SHARED_FIRM[grid] = FirmCells()
    return cells


def forget_firm_cells(grid: OccupancyGrid) -> None:
    """Start the shared `FirmCells` of `grid` afresh at the next `shared_firm_cells` (a map rebuilt after a loop
    closure: walls where the old poses put them are no walls); memories that hold the old one keep it."""
    _SHARED_FIRM.pop(grid, None)


class WallMemory:
    """The cells a growing log-odds map has ever shown firmly occupied, and the distance to them.

    A wall stays a wall: beams that graze it (a full-circle scan, a robot driving along it) pass
    through its cells and wear their log-odds down to unknown or free, and the unknown inside of a
    shelf or a thick wall then borders free cells - frontier that no trip resolves (every look wears
    the face again). Explorers that ask what an opening is ask this memory instead of the map's
    current walls. Only cells hit at least twice more than crossed count (`firmly_occupied`): a scan
    taken from a slightly wrong pose (real odometry, a pose a packet old) puts single hits beside the
    walls, which the next beams undo, and a memory of those would hide openings for good. Call `note`
    after every scan the map integrates (`FirmCells`); `distance` brings the distance to the remembered
    cells up to date, recomputing only near what changed (`WallDistance`).

    Args:
        reach: [cells] how far the distance must be exact (beyond: some larger value, or inf).
        cells: the remembered cells, shared with other memories of the same map (`shared_firm_cells`);
            None: this memory's own.
    """

    def __init__(self, reach: float, cells: FirmCells | None = None) -> None:
        self.cells = FirmCells() if cells is None else cells
        self.walls = WallDistance(reach, lambda r0, r1, c0, c1: self.cells.ever[r0:r1, c0:c1])

    @property
    def ever(self) -> npt.NDArray[np.bool_]:
        """(rows, cols) bool: the cells ever firmly occupied (the array noting updates: do not write to it)."""
        return self.cells.ever

    def note(self, grid: OccupancyGrid) -> None:
        """Remember the cells of `grid` firmly occupied now among those the scans since the last note changed."""
        self.cells.note(grid)

    def distance(self, grid: OccupancyGrid) -> npt.NDArray[np.float32]:
        """(rows, cols) float32 distance [cells] of every cell of `grid` to the nearest cell ever firmly occupied
        (exact up to `reach`; the memory's own array: do not write to it)."""
        self.note(grid)
        self.walls.update(grid)
        return self.walls.dist


_SHARED_MEMORY: weakref.WeakKeyDictionary[OccupancyGrid, dict[float, WallMemory]] = weakref.WeakKeyDictionary()


def shared_wall_memory(grid: OccupancyGrid, reach: float) -> WallMemory:
    """The `WallMemory` of `grid` with `reach` [cells] that every caller on that grid shares, over its shared
    cells (`shared_firm_cells`): eight explorers of a team asking the distance to the walls of the map they
    share bring one distance up to date between them, not each their own. Its distances within `reach` are the
    same whoever asked before; a memory made before `forget_firm_cells` is not handed out after it."""
    cells = shared_firm_cells(grid)
    memories = _SHARED_MEMORY.setdefault(grid, {})
    memory = memories.get(reach)
    if memory is None or memory.cells is not cells:
        memory = memories[reach] = WallMemory(reach, cells)
    return memory


def wall_face_cells(memory: WallMemory, grid: OccupancyGrid, view: OccupancyGrid, off: tuple[int, int],
                    face_reach: float) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """What a wall's face is, asked of the walls the map has ever shown (`memory`), on the window `view` of
    `grid` whose cell (0, 0) is `off`: (face, opening), each bool of the window's shape.

    face: cells within 1.5 cells of a cell ever firmly occupied (a cell beside a wall that grazing beams
    wore away is still a wall face). opening: cells with an unknown 4-neighbour farther than `face_reach`
    [m] from every cell ever firmly occupied. Beams grazing a wall clear stretches of its face, whose
    unknown neighbours are the wall's inside, a cell or two from the hits on either face, and wear the
    face's cells down to unknown or free (log-odds); an opening leads into unknown space away from walls.
    """
    rows, cols = view.shape
    dist = memory.distance(grid)[off[0]:off[0] + rows, off[1]:off[1] + cols]
    deep = view.unknown() & (dist > face_reach / grid.geo.cell)
    opening = np.zeros_like(deep)
    opening[1:, :] |= deep[:-1, :]
    opening[:-1, :] |= deep[1:, :]
    opening[:, 1:] |= deep[:, :-1]
    opening[:, :-1] |= deep[:, 1:]
    return dist < 1.5, opening


class PlanCosts:
    """`plan_costs` of a growing map, kept up to date by recomputing only the cells near what changed.

    A cell's cost depends on whether it is free and on its distance to the walls' surface up to the
    robot radius plus the danger zone (beyond, the cost is 1): `WallDistance` keeps that distance
    (`wall_distance`) and the costs are recomputed in the box it recomputed. The costs equal `plan_costs` of the whole
    map, bit for bit; unknown cells (all of them at first) are blocked.

    Args:
        radius: [m] the robot's footprint radius.
        clearance: [m] width of the danger zone beyond the inflated walls.
    """

    def __init__(self, radius: float, clearance: float) -> None:
        self.radius, self.clearance = radius, clearance
        self.cost = np.zeros((0, 0), np.float32)
        self.walls: WallDistance | None = None

    @property
    def points(self) -> npt.NDArray[np.uint8]:
        """(rows, cols) uint8 each cell's point a plan passes through, as `plan_costs`' `points` (`cell_points`),
        as of the last `update` (the cache's own array: do not write to it)."""
        return self.walls.code if self.walls is not None else np.zeros((0, 0), np.uint8)

    def update(self, grid: OccupancyGrid) -> npt.NDArray[np.float32]:
        """The costs of `grid` now, (rows, cols) float32 as `plan_costs` (the cache's own array: do not
        write to it)."""
        rr, dr = _cost_radii(grid.geo.cell, self.radius, self.clearance)
        if self.walls is None or self.walls._grid is not grid:
            self.walls = WallDistance(rr + dr, surface=True, exact=rr, free_only=True, points=True)
        fresh = self.walls._grid is not grid or self.cost.shape != grid.shape or grid.scans < self.walls._synced
        boxes = self.walls.update(grid)
        if fresh:
            self.cost = np.full(grid.shape, np.inf, np.float32)     # unknown cells are blocked
        for r0, r1, c0, c1 in boxes:
            self.cost[r0:r1, c0:c1] = cost_grid(self.walls.dist[r0:r1, c0:c1], robot_radius_cells=rr,
                                                danger_radius_cells=dr, danger_cost=DANGER_COST,
                                                blocked=~grid.window(r0, r1, c0, c1).free())
        return self.cost


def discs_blocked(cost: npt.NDArray[np.float32], geo: GridGeometry, off: tuple[int, int],
                  discs: npt.NDArray[np.float64]) -> npt.NDArray[np.float32]:
    """A copy of the cost window `cost` (its cell (0, 0) is the grid's cell `off`) with every cell whose centre
    lies within one of `discs` (k, 3) (x, y, radius) [m] made impassable (inf): robots standing in the way,
    each disc the reach of the planning robot's centre (the two robots' turning radii and a margin)."""
    out = cost.copy()
    window = (off[0], off[0] + out.shape[0], off[1], off[1] + out.shape[1])
    for x, y, r in np.asarray(discs, np.float64).reshape(-1, 3):
        box = geo.disc_box(x, y, r, window)
        if box is not None:
            r0, r1, c0, c1 = box
            out[r0 - off[0]:r1 - off[0], c0 - off[1]:c1 - off[1]][geo.disc_mask(box, x, y, r)] = np.inf
    return out


def nearest_passable(passable: npt.NDArray[np.bool_], row: int, col: int, reach: int) -> tuple[int, int] | None:
    """The passable cell nearest (row, col) within the square of half-side `reach` cells, or None.

    Args:
        passable: (rows, cols) bool.
        row: row of the cell searched around.
        col: column of the cell searched around.
        reach: [cells] half-side of the square searched.

    Returns:
        (row, col) of the nearest passable cell (the first in row-major order on a tie; (row, col)
        itself when it is passable), or None when there is none.
    """
    rows, cols = passable.shape
    r0, r1 = max(row - reach, 0), min(row + reach + 1, rows)
    c0, c1 = max(col - reach, 0), min(col + reach + 1, cols)
    cand = np.argwhere(passable[r0:r1, c0:c1])
    if cand.size == 0:
        return None
    cand += (r0, c0)
    best = int(np.argmin((cand[:, 0] - row) ** 2 + (cand[:, 1] - col) ** 2))
    return int(cand[best, 0]), int(cand[best, 1])


def known_window(grid: OccupancyGrid, margin: int) -> tuple[OccupancyGrid, tuple[int, int]]:
    """The part of `grid` that holds every cell a scan has touched, grown by `margin` cells, as a window
    (`OccupancyGrid.window`, sharing the arrays) and the (row, col) of its cell (0, 0) in `grid`.

    Every cell outside it is unknown, so a plan (only known-free cells are passable), the frontier and
    the walls' inflation (within `margin` of a wall) are the same on the window as on the whole grid,
    at a cost that follows what has been explored rather than the map's size. Before the first scan
    the window is the whole grid.

    Args:
        grid: the map.
        margin: [cells] kept around the touched cells (>= 1 for the frontier's unknown neighbours).

    Returns:
        (window, (row0, col0)).
    """
    box = grid.touched_box()
    if box is None:
        return grid, (0, 0)
    r0, c0 = max(box[0] - margin, 0), max(box[2] - margin, 0)
    return grid.window(r0, box[1] + margin, c0, box[3] + margin), (r0, c0)


def passable_cell(geo: GridGeometry, passable: npt.NDArray[np.bool_], x: float, y: float,
                  reach: float = START_REACH, offset: tuple[int, int] = (0, 0)) -> tuple[int, int] | None:
    """The cell a plan from or to the world point (x, y) [m] uses: its own cell when passable, else the
    nearest passable one within `reach` [m]; None when the point is off the grid or none is near.

    Args:
        geo: the grid's geometry.
        passable: (rows, cols) bool, e.g. ``np.isfinite(plan_costs(...))``.
        x: [m] world x.
        y: [m] world y.
        reach: [m] how far to look for a passable cell.
        offset: (row, col) in `geo` of `passable`'s cell (0, 0) when `passable` covers a window of the
            grid (`known_window`); the cell returned is the window's.

    Returns:
        (row, col) or None.
    """
    r, c = geo.cell_of(x, y)
    r, c = r - offset[0], c - offset[1]
    if not (0 <= r < passable.shape[0] and 0 <= c < passable.shape[1]):
        return None
    if passable[r, c]:
        return r, c
    return nearest_passable(passable, r, c, int(math.ceil(reach / geo.cell)))


def frontier_targets(grid: OccupancyGrid, min_cells: int,
                     skip: npt.NDArray[np.bool_] | None = None) -> npt.NDArray[np.bool_]:
    """Bool (rows, cols): the frontier cells of `grid` worth going to.

    Frontier cells of the 8-connected groups of at least `min_cells` cells, leaving out wall faces
    and the `skip` cells (same shape as the grid). A free cell beside an occupied one, with unknown
    on its other side, is the face of a wall whose far half the sensor never sees (or a cell that
    grazing beams cleared): not an opening into unknown space. Openings are cells with no occupied
    8-neighbour.

    Args:
        grid: the map.
        min_cells: smallest frontier group kept [cells].
        skip: (rows, cols) bool cells left out (e.g. given up on), or None.

    Returns:
        (rows, cols) bool.
    """
    if min_cells < 1:
        raise ConfigError(f"frontier_targets: min_cells must be >= 1, got {min_cells}")
    # the cells of `grid.frontier_groups(min_cells)` as one mask: labels and group sizes, no loop over groups
    labels, k = label8(grid.frontier())
    if k == 0:
        return np.zeros(grid.shape, dtype=bool)
    large = np.bincount(labels.ravel(), minlength=k + 1) >= min_cells
    large[0] = False
    drop = grid.near_occupied()
    if skip is not None:
        drop |= skip
    mask: npt.NDArray[np.bool_] = large[labels]
    mask &= ~drop
    return mask


def beside_large_unknown(unknown: npt.NDArray[np.bool_], least: float, cell: float,
                         open_edges: tuple[bool, bool, bool, bool] = (False, False, False, False)
                         ) -> npt.NDArray[np.bool_]:
    """Bool, `unknown`'s shape: the cells within a cell and a half of an 8-connected piece of `unknown` of at
    least `least` [m^2] (cells of `cell` [m]): what a robot would still map from there, where smaller pieces
    (the inside of a rack or a table's outline seen through its gaps, a wall's unseen cells) are not worth a
    trip. `open_edges` (bottom, top, left, right rows/columns) says which edges of `unknown` are not the map's:
    a piece reaching such an edge goes on beyond it and counts as large."""
    labels, k = label8(np.ascontiguousarray(unknown))
    large = np.bincount(labels.ravel(), minlength=k + 1) * cell ** 2 >= least
    for edge, beyond in zip((labels[0, :], labels[-1, :], labels[:, 0], labels[:, -1]), open_edges, strict=True):
        if beyond:
            large[edge] = True
    large[0] = False
    return distance_transform(large[labels]) <= 1.5


def away_from(cells: npt.NDArray[np.bool_], been: npt.NDArray[np.bool_], reach: float) -> npt.NDArray[np.bool_]:
    """`cells` (bool) less those within `reach` [cells] of a cell of `been` (where the robot has been and
    looked: what is still unknown there no laser sees from anywhere near)."""
    return cells & (distance_transform(been) > reach) if been.any() else cells


def usable_frontier(grid: OccupancyGrid, reachable: npt.NDArray[np.bool_], reach_cells: float,
                    blacklist: npt.NDArray[np.bool_] | None = None) -> npt.NDArray[np.bool_]:
    """Frontier cells with no occupied 8-neighbour, within `reach_cells` of a reachable cell (Santos's FRONTIER).

    Args:
        grid: the map.
        reachable: (rows, cols) bool cells the robot can reach and stand on.
        reach_cells: [cells] how far a frontier cell may lie from the nearest reachable cell.
        blacklist: (rows, cols) bool frontier cells given up on, or None.

    Returns:
        (rows, cols) bool.
    """
    front = grid.frontier() & ~grid.near_occupied()
    if blacklist is not None:
        front &= ~blacklist
    if not front.any() or not reachable.any():
        return np.zeros_like(front)
    return probe_cells(reachable, front, reach_cells)      # front & (distance_transform(reachable) <= reach)
