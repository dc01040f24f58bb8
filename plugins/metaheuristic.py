"""Metaheuristic exploration targets (Santos 2016): plugins `meta-ga`, `meta-firefly`, `meta-exhaustive`.

At each decision the map gives three cell lists, FRONTIER, OCCUPIED and VISITED (cells the robot
centre passed, kept here from the state poses); they define Santos's objective surface
(`robotexp.planning.objective`), whose minimum is the next target. The GA or the firefly algorithm
(`robotexp.planning.metaheuristics`) searches it, seeded from the run's generator; `meta-exhaustive`
takes the exact optimum over every cell, the reference the thesis compares them with. A* on the
grid with danger zones near obstacles (Santos 4.3.3; `robotexp.planning.targets.plan_costs`) gives the
path and the shared `PathFollower` drives it. Exploration ends when fewer than `min_frontier`
usable frontier cells remain (Santos's |FRONTIER| < c).

Beyond the thesis, so that runs end and never loop (the same measures as the frontier plugin):
targets are restricted to cells the robot can stand on and reach (Santos's feasibility h is "the
cell is known"; a known cell inside a wall's inflation or behind a gap is no target either);
frontier cells with an occupied 8-neighbour (wall faces) are not FRONTIER; frontier cells farther
than 3 sigma_f from every reachable cell (their attraction cannot reach a target) are left out of
FRONTIER and of the count; a target is kept while frontier cells remain near it; and frontier
cells still there after the robot stood at their target and looked at them, or after
`goal_timeout` without progress, are given up on. A search that ends where no frontier cell is
within reach (a GA or firefly run caught far from every frontier: found in our dense runs, where a
meta-ga run then wandered for the whole 4 hours) is replaced by the optimum over the cells near the
frontier; results count these as `fallbacks`.

Cost: every plan works on the window of the cells the scans have touched (`known_window`; beyond it
every cell is unknown), with wall distances and costs updated only near what the scans changed
(`PlanCosts`) and the reachable cells from a flood fill; the searches run in the whole map's cells on
that window (`origin`, `shape` of `robotexp.planning.metaheuristics`), so targets, paths and records
are those of the whole map, bit for bit, at a cost that follows the explored part.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, ClassVar

import numpy as np
import numpy.typing as npt

from robotexp import ConfigError, Done, Explorer, ExplorerContext, Pose, RobotState, Twist
from robotexp.mapping.grid import OccupancyGrid
from robotexp.mapping.kernels import flood, label8
from robotexp.planning.follower import PathFollower
from robotexp.planning.grid_planner import astar, nearest_goal
from robotexp.planning.metaheuristics import (
    FireflyConfig,
    GAConfig,
    SearchResult,
    exhaustive,
    firefly_search,
    genetic_search,
)
from robotexp.planning.objective import FORMS, INFEASIBLE, SANTOS_CELL, Objective, params_for
from robotexp.planning.reach import near_cells
from robotexp.planning.targets import (PlanCosts, WallMemory, away_from, beside_large_unknown, discs_blocked,
                                      forget_firm_cells, known_window, passable_cell, shared_wall_memory,
                                      usable_frontier, wall_face_cells)

if TYPE_CHECKING:
    from robotexp.localization import FrameCorrection

__all__ = ["ExhaustiveExplorer", "FireflyExplorer", "GAExplorer", "MetaheuristicExplorer", "search_domain"]

WINDOW_MARGIN = 2       # [cells] kept around the scanned part of the map, where every plan is made
LOOK_REACH = 1.5        # [m] frontier this near the robot's path was looked at from close by (`last_look`)
LOOK_AREA = 2.0         # [m2] the least piece of unknown space behind frontier a last look is for
Offset = tuple[int, int]


class MetaheuristicExplorer(Explorer):
    """Drive to the minimum of Santos's objective found by a target search (subclasses choose it).

    Args:
        objective: form of the objective: "proportional" (Santos's best, default), "linear",
            "conditional" or "basic", with the parameters of Tables 2-5.
        min_frontier: c, the exploration ends with fewer usable frontier cells [cells]. Default 20:
            a metre of frontier at 5 cm (Santos's cell), two robot diameters of a P3-DX; smaller
            leftovers are the isolated cells from grazing beams Santos's c is meant to ignore.
        min_opening: [cells] (an extension) the run goes on below `min_frontier` while one
            8-connected group of usable frontier cells has at least this many cells: an opening as
            wide as the robot, such as a 0.9 m door into an unseen room (14-16 usable cells at 5 cm,
            the cells beside the frame being wall faces) or the corridor behind a robot whose laser
            never looked back; the targets are then chosen among such groups' cells alone. None: the robot's
            diameter in the run's cells; 0: Santos's rule alone.
        replan_period: [s] robot time between path refreshes.
        goal_timeout: [s] without progress before a target's frontier is given up on.
        clearance: [m] width of the danger zone beyond the robot radius (A* costs).
        near_frontier: (an extension; False: Santos's domain, every reachable cell) the searches run
            over the reachable cells with a usable frontier cell within reach, and of those over the
            ones where the objective is negative (the frontier's pull outweighs the walls' and the
            trail's push) when there are any: the only cells where the minimum can lie, and the only
            targets that resolve frontier (elsewhere a target was replaced by the `fallbacks` anyway).
            Over every reachable cell the searches spent most of their population where the surface is
            flat, and sometimes ended on a weak frontier across the map: see `FireflyExplorer`.
        face_reach: [m] (an extension, as in the frontier plugin) a FRONTIER cell needs an unknown
            4-neighbour farther than this from every cell the map has ever shown firmly occupied, and
            no such cell within 1.5 cells (`robotexp.planning.targets.wall_face_cells`): the worn faces
            of walls and the unknown inside thick or laser-built walls, seen through their gaps, are no
            frontier (no look resolves them; on a laser-built map dozens of such cells kept the count
            above `min_frontier` until the stall watch ended the run). 0: the map's walls of the moment.
        last_look: (an extension) below `min_frontier`, before the run ends the robot drives to look from
            close by (within `LOOK_REACH` of its path) at each usable frontier cell, faces and walls left
            out, that it never came that near and that borders a piece of unknown space of at least
            `LOOK_AREA`: a few cells beside a corner whose walls the laser never closed may lead into
            unknown space a robot fits in, and only a look tells. False: Santos's rule alone.
    """

    parameter_bounds: ClassVar[dict[str, tuple[float | None, float | None]]] = {
        "min_frontier": (1, 1_000_000), "min_opening": (0, 1_000_000), "replan_period": (None, 3600.0),
        "goal_timeout": (None, 86400.0), "clearance": (0.0, 10.0), "face_reach": (0.0, 10.0)}

    preferred_cell: ClassVar[float | None] = SANTOS_CELL
    takes_targets = True
    name: ClassVar[str] = "meta"

    def __init__(self, *, objective: str = "proportional", min_frontier: int = 20, min_opening: int | None = None,
                 replan_period: float = 2.0, goal_timeout: float = 20.0, clearance: float = 0.3,
                 near_frontier: bool = True, face_reach: float = 0.25, last_look: bool = True) -> None:
        if objective not in FORMS:
            raise ConfigError(f"{self.name}: objective must be one of {', '.join(FORMS)}, got {objective!r}")
        if min_frontier < 1:
            raise ConfigError(f"{self.name}: min_frontier must be >= 1 cell, got {min_frontier}")
        if min_opening is not None and min_opening < 0:
            raise ConfigError(f"{self.name}: min_opening must be >= 0 cells (0: off), got {min_opening}")
        for key, value in (("replan_period", replan_period), ("goal_timeout", goal_timeout)):
            if not value > 0:
                raise ConfigError(f"{self.name}: {key} must be > 0 s, got {value}")
        if clearance < 0:
            raise ConfigError(f"{self.name}: clearance must be >= 0 m, got {clearance}")
        if not (math.isfinite(face_reach) and face_reach >= 0):
            raise ConfigError(f"{self.name}: face_reach must be >= 0 m, got {face_reach}")
        self.params = params_for(objective)
        self.min_frontier = int(min_frontier)
        self.min_opening = min_opening
        self.replan_period = replan_period
        self.goal_timeout = goal_timeout
        self.clearance = clearance
        self.near_frontier = bool(near_frontier)
        self.face_reach = face_reach
        self.last_look = bool(last_look)

    def search(self, surface: npt.NDArray[np.float64], origin: Offset, shape: tuple[int, int]) -> SearchResult:
        """The target search on an objective surface (overridden by each plugin), in the cells of the
        map of `shape`; `surface` is its window from cell `origin`, every cell outside infeasible."""
        found = exhaustive(surface)
        return _shifted(found, origin)

    def reset(self, ctx: ExplorerContext) -> None:
        """Start a new run."""
        super().reset(ctx)
        self.follower = PathFollower(ctx.limits, ctx.radius, footprint=ctx.footprint)
        self.costs = PlanCosts(ctx.radius, self.clearance)     # plan_costs, updated where the scans changed the map
        self.visited = np.zeros((0, 0), dtype=bool)
        self.blacklist = np.zeros((0, 0), dtype=bool)
        self.walls_seen: WallMemory | None = None      # cells ever firmly occupied (with face_reach > 0)
        self.last_xy: tuple[float, float] | None = None
        self.target: tuple[int, int] | None = None
        self.target_cells = np.zeros((0, 2), dtype=np.int64)     # the frontier cells near the target
        self.face: tuple[float, float] | None = None
        self.next_plan = -math.inf
        self.best_remaining = math.inf
        self.last_progress = 0.0
        self.targets = 0
        self.gaps: list[float] = []         # [cells] from each target to the exhaustive optimum
        self.fallbacks = 0                  # searches that ended with no frontier within reach
        self.look_path = 0.0                # [m] driven on last looks (`last_look`)
        self._looking = False               # the target is a last look's
        self.frontier_left = 0
        self.assigned: npt.NDArray[np.int64] | None = None     # a team coordinator's target cells
        self.around: npt.NDArray[np.float64] | None = None      # teammates' discs to plan around (plan_around)

    @property
    def backtracking(self) -> bool:
        """True on a last look (`last_look`): the run's stall watch (`robotexp.run.endings.StallWatch`) does not
        count that time, which confirms what the map shows rather than map anything new. The looks are
        bounded: each brings the robot within `LOOK_REACH` of cells it never came near, or gives them up."""
        return self._looking and self.target is not None

    def map_rebuilt(self, grid: OccupancyGrid, moved: FrameCorrection) -> None:
        """Loop closure rebuilt the map: the memory of the walls seen is started anew from it."""
        self.walls_seen = None
        forget_firm_cells(grid)

    def assign_targets(self, cells: npt.NDArray[np.int64] | None) -> None:
        """A team coordinator's target: the search runs on the frontier among these cells (None: all of
        it); a new target drops the current one at once."""
        self.assigned = None if cells is None else np.asarray(cells, np.int64).reshape(-1, 2)
        self.target = self.face = None
        self.follower.clear()
        self.next_plan = -math.inf

    def plan_around(self, discs: npt.NDArray[np.float64] | None) -> None:
        """Search and plan with the discs (k, 3) (x, y, radius) [m] impassable (None: as usual); discs drop the
        target."""
        if discs is None:
            self.around = None
            return
        self.around = np.asarray(discs, np.float64).reshape(-1, 3)
        self.target = self.face = None
        self.follower.clear()
        self.next_plan = -math.inf

    def result_fields(self) -> dict[str, object]:
        """Targets chosen, their mean distance to the exhaustive optimum [cells], frontier left, and the
        searches that ended with no frontier within reach (`fallbacks`, see `_plan`)."""
        return {"targets": self.targets, "frontier_left": self.frontier_left, "fallbacks": self.fallbacks,
                "look_path_m": round(self.look_path, 3),
                "target_gap_cells": round(float(np.mean(self.gaps)), 2) if self.gaps else 0.0}

    # -- the decision --------------------------------------------------------------------
    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        """Follow the path to the target; choose a new target when it is reached or resolved."""
        pose, now = state.pose, state.time
        self._mark_visited(pose, grid)
        if self.face_reach > 0:
            self._memory(grid).note(grid)
        self.follower.memory.see_map(grid)
        if self.follower.done and self.face is not None:
            twist, facing = self.follower.turn_to(pose, math.atan2(self.face[1] - pose.y, self.face[0] - pose.x),
                                                  state.laser)
            if not facing:
                return twist
            self._give_up_open(grid)        # stood there and looked: what is left cannot be resolved
            self.face = None
            self.next_plan = -math.inf
        if self.target is not None and not self.follower.done:
            remaining = self.follower.remaining(pose)
            if remaining < self.best_remaining - 0.1:
                self.best_remaining, self.last_progress = remaining, now
            elif now - self.last_progress > self.goal_timeout:
                self._give_up_open(grid)
                self.follower.clear()
                self.target = self.face = None
        if now >= self.next_plan or self.follower.done:
            if not self._plan(pose, grid, now) and (self.around is None or not self._plan_as_usual(pose, grid, now)):
                self.follower.clear()
                opening = ", no opening as wide as the robot" if self.min_opening != 0 else ""
                return Done(f"fewer than {self.min_frontier} usable frontier cells left{opening}")
            self.next_plan = now + self.replan_period
        return self.follower.twist(pose, state.laser, state.velocity)

    def _plan_as_usual(self, pose: Pose, grid: OccupancyGrid, now: float) -> bool:
        """No target around the teammates' discs: forget them and plan again."""
        self.around = None
        return self._plan(pose, grid, now)

    def _mark_visited(self, pose: Pose, grid: OccupancyGrid) -> None:
        geo = grid.geo
        if self.visited.shape != grid.shape:
            self.visited = np.zeros(grid.shape, dtype=bool)
            self.blacklist = np.zeros(grid.shape, dtype=bool)
        x0, y0 = self.last_xy if self.last_xy is not None else (pose.x, pose.y)
        if self._looking:
            self.look_path += math.hypot(pose.x - x0, pose.y - y0)
        n = int(math.ceil(math.hypot(pose.x - x0, pose.y - y0) / (geo.cell / 2))) + 1
        for t in np.linspace(0.0, 1.0, n):
            r, c = geo.cell_of(x0 + t * (pose.x - x0), y0 + t * (pose.y - y0))
            if geo.contains(r, c):
                self.visited[r, c] = True
        self.last_xy = (pose.x, pose.y)

    def _openings(self, frontier: npt.NDArray[np.bool_], cell: float,
                  wide: npt.NDArray[np.bool_] | None = None) -> npt.NDArray[np.bool_]:
        """The cells of the usable `frontier` in an 8-connected group of at least `min_opening` cells (None:
        the robot's diameter in cells of `cell` [m]; 0: never, an empty mask). With `wide` (the frontier before
        the `face_reach` test of what lies beyond it, a superset of `frontier`), a group of `wide` that
        holds a cell of `frontier` is measured: a door's frontier spans its width, while the unknown
        beyond it lies far enough from the frame only in its middle."""
        need = self.min_opening if self.min_opening is not None else int(math.ceil(2 * self.ctx.radius / cell))
        if need <= 0 or not frontier.any():
            return np.zeros_like(frontier)
        labels, n = label8(np.ascontiguousarray(frontier if wide is None else wide))
        sizes = np.bincount(labels.ravel(), minlength=n + 1)
        if wide is not None:
            sizes[np.setdiff1d(np.arange(n + 1), labels[frontier])] = 0
        sizes[0] = 0
        return frontier & (sizes >= need)[labels]

    def _reach_cells(self, grid: OccupancyGrid) -> float:
        return 3.0 * self.params.sigma_f * SANTOS_CELL / grid.geo.cell + 1.0

    def _open_cells(self, frontier: npt.NDArray[np.bool_], off: Offset) -> npt.NDArray[np.int64]:
        """The target's frontier cells (the map's cells) still set in `frontier`, a window from `off`."""
        cells = self.target_cells
        if len(cells) == 0:
            return cells
        local = cells - off
        inside = ((local[:, 0] >= 0) & (local[:, 0] < frontier.shape[0])
                  & (local[:, 1] >= 0) & (local[:, 1] < frontier.shape[1]))
        keep = np.zeros(len(cells), dtype=bool)
        keep[inside] = frontier[local[inside, 0], local[inside, 1]]
        return cells[keep]

    def _frontier(self, grid: OccupancyGrid, view: OccupancyGrid, off: Offset, reachable: npt.NDArray[np.bool_],
                  reach: float) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
        """FRONTIER on the window `view` of `grid` from `off`: `usable_frontier` without the cells given up
        on and, with `face_reach`, without wall faces and the insides of walls (`wall_face_cells`); and
        the same before the test of the unknown beyond (`_openings` measures openings on it)."""
        if self.blacklist.shape != grid.shape:
            self.blacklist = np.zeros(grid.shape, dtype=bool)
        rows, cols = view.shape
        skip = self.blacklist[off[0]:off[0] + rows, off[1]:off[1] + cols]
        if self.face_reach <= 0:
            front = usable_frontier(view, reachable, reach, skip)
            return front, front
        face, opening = wall_face_cells(self._memory(grid), grid, view, off, self.face_reach)
        wide = usable_frontier(view, reachable, reach, skip | face)
        return wide & opening, wide

    def _memory(self, grid: OccupancyGrid) -> WallMemory:
        """The cells ever firmly occupied, with distances exact to `face_reach` and the 8-neighbours."""
        if self.walls_seen is None:
            self.walls_seen = shared_wall_memory(grid, max(self.face_reach / grid.geo.cell, 1.5))
        return self.walls_seen

    def give_up(self, grid: OccupancyGrid) -> bool:
        """The run saw no progress for a while (its stall watch): blacklist the target's frontier cells
        (all of them, open or not) and choose anew. False when there is no target to give up."""
        if self.target is None or len(self.target_cells) == 0:
            return False
        if self.blacklist.shape != grid.shape:
            self.blacklist = np.zeros(grid.shape, dtype=bool)
        self.blacklist[self.target_cells[:, 0], self.target_cells[:, 1]] = True
        self.follower.clear()
        self.target = self.face = None
        self.next_plan = -math.inf
        return True

    def _give_up_open(self, grid: OccupancyGrid) -> None:
        view, off = known_window(grid, WINDOW_MARGIN)
        cells = self._open_cells(view.frontier(), off)
        self.blacklist[cells[:, 0], cells[:, 1]] = True

    def _plan(self, pose: Pose, grid: OccupancyGrid, now: float) -> bool:
        """Refresh the path to the target while its frontier lasts, else choose a new target.

        Everything is computed on the window of the cells the scans have touched (`known_window`: every
        cell outside is unknown, so neither passable, frontier, occupied nor visited), which gives the
        targets and paths of the whole map at a cost that follows the explored part."""
        geo = grid.geo
        view, off = known_window(grid, WINDOW_MARGIN)
        wr, wc = view.shape
        cost = self.costs.update(grid)[off[0]:off[0] + wr, off[1]:off[1] + wc]
        if self.around is not None:
            cost = discs_blocked(cost, geo, off, self.around)
        passable = np.isfinite(cost)
        start = passable_cell(geo, passable, pose.x, pose.y, offset=off)
        if start is None:
            return False
        # the cells Dijkstra reaches: its diagonal steps need both side cells passable, so they connect
        # nothing 4-neighbour steps do not, and a 4-connected flood gives the same cells (at a tenth of the cost)
        reachable = flood(passable, start[0], start[1], False)
        reach = self._reach_cells(grid)
        window = (slice(off[0], off[0] + wr), slice(off[1], off[1] + wc))
        frontier, wide = self._frontier(grid, view, off, reachable, reach)
        self.frontier_left = int(np.count_nonzero(frontier))
        if self.frontier_left < self.min_frontier:
            # below c the run goes on for the openings alone: the search runs on them, not on the specks
            # beside them (each a trip that resolves a cell or two: on a large floor the trips from speck
            # to speck added no space for three stall windows while a door was left)
            openings = self._openings(frontier, geo.cell, wide)
            if not openings.any():
                return self.last_look and self._look_last(pose, grid, (view, off), wide, cost, start, now)
            frontier = openings
        frontier = self._assigned_part(frontier, off)
        target = None if self.target is None else (self.target[0] - off[0], self.target[1] - off[1])
        if (target is not None and not self.follower.done and 0 <= target[0] < wr and 0 <= target[1] < wc
                and reachable[target] and len(self._open_cells(frontier, off))):
            path = astar(cost, start, target)
            if path is not None:
                self._follow(path, passable, pose, grid, off)
                return True
        objective = Objective(self.params, frontier, view.occupied(), self.visited[window],
                              ((pose.x - geo.origin_x) / geo.cell, (pose.y - geo.origin_y) / geo.cell),
                              reachable, cell=geo.cell, origin=off)
        surface = search_domain(objective.surface, reachable, frontier, reach) if self.near_frontier \
            else objective.surface
        found = self.search(surface, off, grid.shape)
        if found.value >= INFEASIBLE:
            return False
        opt = _shifted(exhaustive(objective.surface), off)
        self.gaps.append(math.hypot(found.cell[0] - opt.cell[0], found.cell[1] - opt.cell[1]))
        k = int(math.ceil(reach))
        local = (found.cell[0] - off[0], found.cell[1] - off[1])
        self.target_cells = _cells_near(frontier, local, k) + off
        if len(self.target_cells) == 0:
            # The search stopped where no frontier cell is within reach (its C_f is ~0): driving there
            # resolves nothing, and with that frontier never looked at the run would not end. Take the
            # optimum over the cells that have a frontier cell within reach instead (counted).
            near = near_cells(frontier, reach)
            found = _shifted(exhaustive(np.where(near, objective.surface, INFEASIBLE)), off)
            if found.value >= INFEASIBLE:
                return False
            self.fallbacks += 1
            local = (found.cell[0] - off[0], found.cell[1] - off[1])
            self.target_cells = _cells_near(frontier, local, k) + off
        path = astar(cost, start, local)
        if path is None:
            return False
        self._looking = False
        self.targets += 1
        self.target = found.cell
        self.face = _face_point(grid, view, off, self.target_cells)
        self.best_remaining, self.last_progress = math.inf, now
        self._follow(path, passable, pose, grid, off)
        return True

    def _look_last(self, pose: Pose, grid: OccupancyGrid, window: tuple[OccupancyGrid, Offset],
                   frontier: npt.NDArray[np.bool_], cost: npt.NDArray[np.float32], start: tuple[int, int],
                   now: float) -> bool:
        """Drive to the nearest cell within a robot radius and a cell and a half of a cell of `frontier` (on
        the window `window`: (view, its cell (0, 0) in `grid`)) farther than `LOOK_REACH` from every cell the
        robot passed and beside a piece of unknown space of at least `LOOK_AREA`; False when there is none
        (or no way there)."""
        view, off = window
        rows, cols = frontier.shape
        cell = grid.geo.cell
        passed = self.visited[off[0]:off[0] + rows, off[1]:off[1] + cols]
        away = away_from(frontier, passed, LOOK_REACH / cell)
        if not away.any():
            return False
        # only beside a piece of unknown space of at least LOOK_AREA: the unknown inside a rack or a table's
        # outline seen through its gaps is less (looking at each such speck stalled a warehouse run); a piece
        # that reaches the window's edge inside the map goes on beyond it (all unknown there)
        gr, gc = grid.shape
        away &= beside_large_unknown(view.unknown(), LOOK_AREA, cell,
                                     (off[0] > 0, off[0] + rows < gr, off[1] > 0, off[1] + cols < gc))
        if not away.any():
            return False
        reach = self.ctx.radius / cell + 1.5
        passable = np.isfinite(cost)
        found = nearest_goal(cost, start, near_cells(away, reach) & passable)
        if found is None:
            return False
        goal, path, _ = found
        self._looking = True
        self.target = (goal[0] + off[0], goal[1] + off[1])
        self.target_cells = _cells_near(away, goal, int(math.ceil(reach))) + off
        self.face = _face_point(grid, view, off, self.target_cells)
        self.best_remaining, self.last_progress = math.inf, now
        self._follow(path, passable, pose, grid, off)
        return True

    def _assigned_part(self, frontier: npt.NDArray[np.bool_], off: Offset) -> npt.NDArray[np.bool_]:
        """The frontier among the coordinator's cells, when some is; else all of it."""
        if self.assigned is None or len(self.assigned) == 0:
            return frontier
        local = self.assigned - off
        rows, cols = frontier.shape
        local = local[(local[:, 0] >= 0) & (local[:, 0] < rows) & (local[:, 1] >= 0) & (local[:, 1] < cols)]
        keep = np.zeros_like(frontier)
        keep[local[:, 0], local[:, 1]] = frontier[local[:, 0], local[:, 1]]
        return keep if keep.any() else frontier

    def _follow(self, path: npt.NDArray[np.int32], passable: npt.NDArray[np.bool_], pose: Pose,
                grid: OccupancyGrid, off: Offset) -> None:
        """Follow `path` (cells of the window `passable` whose cell (0, 0) is `off`) through the points of
        its cells the costs planned with (`PlanCosts.points`)."""
        rows, cols = passable.shape
        points = None if self.costs is None else self.costs.points[off[0]:off[0] + rows, off[1]:off[1] + cols]
        self.follower.follow_cells(path, passable, grid.geo, (pose.x, pose.y), off, points)


def search_domain(surface: npt.NDArray[np.float64], reachable: npt.NDArray[np.bool_], frontier: npt.NDArray[np.bool_],
                  reach: float) -> npt.NDArray[np.float64]:
    """`surface` left only on the cells a target should be searched among (`near_frontier`): the reachable
    cells with a `frontier` cell within `reach` [cells] where the surface is negative, or all those near
    cells when none is negative; INFEASIBLE elsewhere. All arrays (rows, cols) of one grid or window."""
    near = reachable & near_cells(frontier, reach)
    pull = near & (surface < 0)
    return np.where(pull if pull.any() else near, surface, INFEASIBLE)


def _shifted(found: SearchResult, origin: Offset) -> SearchResult:
    """`found` on a window from cell `origin`, in the cells of the whole map."""
    if origin == (0, 0):
        return found
    return SearchResult((found.point[0] + origin[1], found.point[1] + origin[0]),
                        (found.cell[0] + origin[0], found.cell[1] + origin[1]), found.value, found.evaluations)


def _face_point(grid: OccupancyGrid, view: OccupancyGrid, off: Offset,
                cells: npt.NDArray[np.int64]) -> tuple[float, float] | None:
    """Where a robot at the target looks at frontier `cells` (int (k, 2)) [m]: 1 m beyond their centroid
    towards their unknown 4-neighbours (the side still to be seen), or the centroid when those balance.

    Facing the centroid alone failed when the robot stood on it: a start beside a corridor its
    180-degree laser had never seen (the frontier a line through the robot) "faced" its own position,
    turned nowhere, and gave the corridor up unseen (ActivMediaLab.map, coverage 0.69)."""
    if len(cells) == 0:
        return None
    geo = grid.geo
    unknown = view.unknown()            # the window `view` of `grid` from cell `off`; beyond it all unknown
    rows, cols = unknown.shape
    side = np.zeros(2)
    for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        r, c = cells[:, 0] - off[0] + dr, cells[:, 1] - off[1] + dc
        ok = (r >= 0) & (r < rows) & (c >= 0) & (c < cols)
        hit = np.zeros(len(cells), dtype=bool)
        hit[ok] = unknown[r[ok], c[ok]]
        side += np.count_nonzero(hit) * np.array([dr, dc], dtype=np.float64)
    cy, cx = cells.mean(axis=0)
    x, y = geo.origin_x + (float(cx) + 0.5) * geo.cell, geo.origin_y + (float(cy) + 0.5) * geo.cell
    norm = math.hypot(side[0], side[1])
    if norm < 1e-9:
        return x, y
    return x + float(side[1]) / norm, y + float(side[0]) / norm


def _cells_near(mask: npt.NDArray[np.bool_], cell: tuple[int, int], k: int) -> npt.NDArray[np.int64]:
    """(n, 2) (row, col) of the cells set in `mask` within the square of half-side `k` [cells] around `cell`."""
    r0, c0 = max(cell[0] - k, 0), max(cell[1] - k, 0)
    return np.argwhere(mask[r0:cell[0] + k + 1, c0:cell[1] + k + 1]) + (r0, c0)


class GAExplorer(MetaheuristicExplorer):
    """Targets from a steady-state real-coded GA (Santos Table 6) on the objective surface.

    Args:
        population: P_size (Santos: 1024).
        generations: generations of the steady-state GA.
        **kwargs: those of `MetaheuristicExplorer`.
    """

    parameter_bounds: ClassVar[dict[str, tuple[float | None, float | None]]] = {
        "population": (2, 100_000), "generations": (1, 10_000)}

    name: ClassVar[str] = "meta-ga"

    def __init__(self, *, population: int = 1024, generations: int = 60, **kwargs: object) -> None:
        super().__init__(**kwargs)  # type: ignore[arg-type]
        self.config = GAConfig(population=population, generations=generations)

    def search(self, surface: npt.NDArray[np.float64], origin: Offset, shape: tuple[int, int]) -> SearchResult:
        """GA target on `surface` (a window from `origin` of a map of `shape`), seeded from the run's generator."""
        return genetic_search(surface, self.ctx.rng, self.config, origin, shape)


class FireflyExplorer(MetaheuristicExplorer):
    """Targets from the firefly algorithm (Santos Table 7) on the objective surface.

    The swarm's size and sweeps are not Santos's 20 x 100 by default but 40 x 25 (about the same number of
    evaluations, fewer than the GA's): with gamma 0.4 per L^2 every firefly is drawn at least 0.67 of the
    way to each brighter one anywhere on the map, so the swarm gathers on its brightest member within a
    few sweeps and the target is decided by which frontier basins its first population landed in. Traced
    on generated warehouse 0 and cave 0 (900 s each, every search of the run repeated with 4 seeds): a
    target more than 2 m farther from the robot than the exhaustive optimum came from 13 % and 17 % of
    20 x 100 searches over every reachable cell (the GA: 2.3 %, 3.6 %), 9.9 % and 9.2 % over the cells
    near the frontier (`near_frontier`), 1.0 % and 1.5 % with 40 x 25 there (the GA there: 0 %): each
    such miss a trip across the map for a weak frontier, which made firefly's paths 1.5-2.7 times the
    GA's and left warehouse 0 at 0.776 coverage after 7200 s. `population=20, iterations=100,
    near_frontier=false` is Santos's firefly (campaigns/santos.toml).

    Args:
        population: P_size (Santos: 20).
        iterations: sweeps over all pairs of fireflies.
        **kwargs: those of `MetaheuristicExplorer`.
    """

    parameter_bounds: ClassVar[dict[str, tuple[float | None, float | None]]] = {
        # a sweep draws a random vector per pair: iterations x population^2 x 16 bytes (320 MB at the bounds)
        "population": (2, 200), "iterations": (1, 500)}

    name: ClassVar[str] = "meta-firefly"

    def __init__(self, *, population: int = 40, iterations: int = 25, **kwargs: object) -> None:
        super().__init__(**kwargs)  # type: ignore[arg-type]
        self.config = FireflyConfig(population=population, iterations=iterations)

    def search(self, surface: npt.NDArray[np.float64], origin: Offset, shape: tuple[int, int]) -> SearchResult:
        """Firefly target on `surface` (a window from `origin` of a map of `shape`), seeded from the run's
        generator."""
        return firefly_search(surface, self.ctx.rng, self.config, origin, shape)


class ExhaustiveExplorer(MetaheuristicExplorer):
    """Targets at the exact optimum of the objective over every cell (the reference of Santos 5.2)."""

    name: ClassVar[str] = "meta-exhaustive"
