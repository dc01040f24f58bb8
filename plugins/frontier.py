"""Frontier-based exploration (Yamauchi 1997) as a robotexp explorer plugin."""

from __future__ import annotations

import math
import weakref
from typing import TYPE_CHECKING, ClassVar

import numpy as np
import numpy.typing as npt

from robotexp import ConfigError, Done, Explorer, ExplorerContext, Pose, RobotState, Twist
from robotexp.mapping.grid import OccupancyGrid
from robotexp.planning.follower import PathFollower
from robotexp.planning.grid_planner import Cell, Path, astar, nearest_goal
from robotexp.planning.reach import near_cells
from robotexp.planning.targets import (PlanCosts, WallMemory, discs_blocked, forget_firm_cells, frontier_targets,
                                      known_window, passable_cell, shared_wall_memory, wall_face_cells)

if TYPE_CHECKING:
    from robotexp.localization import FrameCorrection

__all__ = ["FrontierExplorer"]

GIVE_UP_REACH = 2.0     # [m] frontier given up around the goal and the robot when the run's stall watch strikes
WINDOW_MARGIN = 2       # [cells] kept around the scanned part of the map, where every plan is made
# the plan costs of each map, by (id of the map, robot radius, clearance), as long as an explorer plans with them:
# the explorers of a team on one map keep them once
_SHARED_COSTS: weakref.WeakValueDictionary[tuple[int, float, float], PlanCosts] = weakref.WeakValueDictionary()
GOAL_BOX_MARGIN = 3     # [cells] beyond the smallest group kept around a goal's cells, where `_goal_open` looks
Offset = tuple[int, int]

class FrontierExplorer(Explorer):
    """Drive to the nearest reachable frontier group (Yamauchi 1997); done when none is left.

    Frontier cells are free cells next to unknown ones, grouped by 8-connectivity; groups smaller
    than the robot (`min_group_cells`, default the robot's diameter in cells) are ignored, and so
    are frontier cells touching an occupied cell (the face of a wall whose far side is never seen
    is not an opening) and those whose unknown neighbours all lie within `face_reach` of an occupied
    cell: beams grazing a wall clear stretches of its face, and the unknown behind them is the wall's
    inside (a robot that drove to them looked, saw nothing new and dithered on warehouse rack faces).
    Both tests ask the cells the map has ever shown occupied (`WallMemory`), not the map's walls of
    the moment: in a log-odds map a beam passing through a wall cell cancels a hit, so grazing beams
    wear faces down to unknown or free cells, and a shelf's face worn over a metre looked like an
    opening into its unseen inside (generated warehouses: a long tail of trips to worn rack faces).
    Paths are planned on known-free cells where the robot's disc fits 2 cm clear of the walls' surface
    (`plan_costs`: the laser endpoints in the occupied cells, finer than the cell) and a costly zone of
    `clearance` beyond that keeps them centred (Dijkstra for the
    nearest goal, A* to refresh the path). The goal is the nearest cell the robot can stand on
    within a robot radius of a frontier cell - inside the room rather than in its door - or, for
    frontiers in pockets too narrow to enter, within a metre of one; on arrival the robot turns to
    look at the frontier's unknown neighbours. The goal is kept while its frontier lasts (switching
    at every plan makes robots oscillate); the path to it is refreshed every `replan_period` [s].
    Frontier cells are given up on (blacklisted) when the robot stood by them and looked their way
    yet they stayed frontier, or when their goal brought no progress for `goal_timeout` [s]: a run
    neither ends early nor loops on an unreachable goal. Every plan is made on the part of the map the
    scans have touched (`known_window`; beyond it every cell is unknown, so never passable nor frontier),
    on costs updated only near the cells the scans changed (`PlanCosts`): the same plans as on the whole
    map, at a cost that does not grow with the map's size.

    Args:
        min_group_cells: smallest frontier group considered (None: the robot's diameter in cells).
        replan_period: [s] robot time between plans.
        goal_timeout: [s] without progress before a goal is blacklisted.
        clearance: [m] width of the costly zone beyond the robot radius.
        return_home: drive back to the start pose when exploration is done.
        face_reach: [m] a frontier cell needs an unknown 4-neighbour farther than this from every
            cell ever firmly occupied (hit twice more than crossed: `WallMemory`), and no such cell
            as 8-neighbour (0: neither test, nor the memory of walls).
    """

    takes_targets = True
    parameter_bounds: ClassVar[dict[str, tuple[float | None, float | None]]] = {
        "min_group_cells": (1, 1_000_000), "replan_period": (None, 3600.0), "goal_timeout": (None, 86400.0),
        "clearance": (0.0, 10.0), "face_reach": (0.0, 10.0)}

    def __init__(self, *, min_group_cells: int | None = None, replan_period: float = 2.0,
                 goal_timeout: float = 20.0, clearance: float = 0.3, return_home: bool = False,
                 face_reach: float = 0.25) -> None:
        if min_group_cells is not None and min_group_cells < 1:
            raise ConfigError(f"frontier: min_group_cells must be >= 1, got {min_group_cells}")
        for name, value in (("replan_period", replan_period), ("goal_timeout", goal_timeout)):
            if not value > 0:
                raise ConfigError(f"frontier: {name} must be > 0, got {value}")
        if clearance < 0:
            raise ConfigError(f"frontier: clearance must be >= 0 m, got {clearance}")
        self.min_group_cells = min_group_cells
        self.replan_period = replan_period
        self.goal_timeout = goal_timeout
        self.clearance = clearance
        self.return_home = return_home
        if not (math.isfinite(face_reach) and face_reach >= 0):
            raise ConfigError(f"frontier: face_reach must be >= 0 m, got {face_reach}")
        self.face_reach = face_reach

    def reset(self, ctx: ExplorerContext) -> None:
        """Start a new run."""
        super().reset(ctx)
        self.follower = PathFollower(ctx.limits, ctx.radius, footprint=ctx.footprint)
        self.blacklist = np.zeros((0, 0), dtype=bool)     # frontier cells given up on
        self.blacklist_events = 0
        self.goal_cells = np.zeros((0, 2), dtype=np.int64)
        self.goal: tuple[float, float] | None = None
        self.face: tuple[float, float] | None = None      # the frontier cell to look at on arrival
        self.next_plan = -math.inf
        self.best_remaining = math.inf
        self.last_progress = 0.0
        self.homing = False
        self.plans = 0
        self.reach = 0.0            # [cells] from the goal to the frontier cells it serves
        self._now = 0.0
        self._pose_xy = (ctx.start.x, ctx.start.y)
        self._targets: tuple[object, npt.NDArray[np.bool_]] | None = None   # the last _frontier_targets
        self.walls_seen: WallMemory | None = None     # cells ever firmly occupied (with face_reach > 0)
        self.costs: PlanCosts | None = None           # plan_costs, updated where the scans changed the map
        self.assigned: npt.NDArray[np.int64] | None = None    # a team coordinator's target cells
        self.around: npt.NDArray[np.float64] | None = None     # teammates' discs to plan around (plan_around)

    def map_rebuilt(self, grid: OccupancyGrid, moved: FrameCorrection) -> None:
        """Loop closure rebuilt the map: forget the walls seen, the costs and the targets, and plan anew (the
        goal is kept only while its frontier cells are still frontier in the rebuilt map)."""
        self.walls_seen = None
        forget_firm_cells(grid)
        self._targets = None
        _SHARED_COSTS.pop((id(grid), self.ctx.radius, self.clearance), None)
        self.next_plan = -math.inf

    def assign_targets(self, cells: npt.NDArray[np.int64] | None) -> None:
        """A team coordinator's target: the next goal is chosen among these frontier cells (None: alone);
        a new target drops the goal at once."""
        self.assigned = None if cells is None else np.asarray(cells, np.int64).reshape(-1, 2)
        if self.goal is not None and not self.homing:
            self.follower.clear()
            self.goal = self.face = None
        self.next_plan = -math.inf

    def plan_around(self, discs: npt.NDArray[np.float64] | None) -> None:
        """Plan with the discs (k, 3) (x, y, radius) [m] impassable (None: as usual); discs drop the goal."""
        if discs is None:
            self.around = None
            return
        self.around = np.asarray(discs, np.float64).reshape(-1, 3)
        if not self.homing:
            self.follower.clear()
            self.goal = self.face = None
        self.next_plan = -math.inf

    # -- the decision ----------------------------------------------------------------
    def markers(self) -> dict[str, dict[str, object]]:
        """What the live view draws (robotexp.view): the goal [m] the robot drives to, when it has one."""
        if self.goal is None:
            return {}
        return {"points": {"frontier target": [round(float(v), 3) for v in self.goal]}}

    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        """Follow the current plan, re-planning when due; Done when no reachable frontier is left."""
        pose, now = state.pose, state.time
        self._now = now
        if self.face_reach > 0:
            self._memory(grid).note(grid)
        self._pose_xy = (pose.x, pose.y)
        self.follower.memory.see_map(grid)
        if self.homing:
            if self.follower.done:
                return Done("explored; back at the start")
            return self.follower.twist(pose, state.laser, state.velocity)
        if self.follower.done and self.face is not None:
            twist, facing = self.follower.turn_to(pose, math.atan2(self.face[1] - pose.y, self.face[0] - pose.x),
                                                  state.laser)
            if not facing:
                return twist
            # we stand by these frontier cells and look their way: those still frontier cannot be
            # resolved (seen from here, they stay next to unknown cells the laser cannot reach)
            self._blacklist_unresolved(grid)
            self.face = None
            self.next_plan = -math.inf
        if self.goal is not None and not self.follower.done:
            self._watch_progress(pose, now)
        if now >= self.next_plan or self.follower.done:
            # keep the goal while its frontier is still there (switching goals at every plan makes
            # a robot oscillate between two frontiers); only the path to it is refreshed
            if not (self._goal_open(grid) and self._replan_path(pose, grid)) and not self._plan(pose, grid):
                if self.around is None:
                    return self._finish(pose, grid)
                self.around = None          # no goal around the teammates: plan as usual
                if not self._plan(pose, grid):
                    return self._finish(pose, grid)
            self.next_plan = now + self.replan_period
        return self.follower.twist(pose, state.laser, state.velocity)

    def give_up(self, grid: OccupancyGrid) -> bool:
        """The run saw no progress for a while (its stall watch): blacklist the current goal's frontier
        cells and plan anew. False when there is no goal to give up."""
        if self.goal is None or len(self.goal_cells) == 0:
            return False
        if self.blacklist.shape != grid.shape:
            self.blacklist = np.zeros(grid.shape, dtype=bool)
        self.blacklist[self.goal_cells[:, 0], self.goal_cells[:, 1]] = True
        self._targets = None
        # the goals it switched between are around it: give up the frontier within GIVE_UP_REACH too
        view, off = known_window(grid, WINDOW_MARGIN)
        targets = np.argwhere(self._frontier_targets(grid, view, off)) + off
        if len(targets):
            xy = grid.geo.centers_of(targets)
            for px, py in (self.goal, self._pose_xy):
                near = np.hypot(xy[:, 0] - px, xy[:, 1] - py) <= GIVE_UP_REACH
                self.blacklist[targets[near, 0], targets[near, 1]] = True
        self.blacklist_events += 1
        self.follower.clear()
        self.goal = self.face = None
        self.next_plan = -math.inf
        return True

    def _goal_open(self, grid: OccupancyGrid) -> bool:
        """True while the robot is on its way to a goal whose frontier cells are not all resolved.

        Asked at every refresh of the path, so it looks only near the goal's cells: `_frontier_targets` of the
        box around them grown by the smallest group kept and a few cells, within the scanned window. A group
        holding a goal cell that reaches that box's edge has more cells than the smallest group kept, and
        every other cell of the box is classed as on the whole window (its neighbours lie in the box): the
        same answer as the whole window's targets, at a cost that follows the goal, not the map."""
        if self.goal is None or self.follower.done or len(self.goal_cells) == 0:
            return False
        view, off = known_window(grid, WINDOW_MARGIN)
        view_box = (off[0], off[0] + view.shape[0], off[1], off[1] + view.shape[1])
        grow = self._min_cells(grid) + GOAL_BOX_MARGIN
        r0 = max(int(self.goal_cells[:, 0].min()) - grow, view_box[0])
        r1 = min(int(self.goal_cells[:, 0].max()) + grow + 1, view_box[1])
        c0 = max(int(self.goal_cells[:, 1].min()) - grow, view_box[2])
        c1 = min(int(self.goal_cells[:, 1].max()) + grow + 1, view_box[3])
        local = self.goal_cells - (r0, c0)
        targets = self._targets_of(grid, grid.window(r0, r1, c0, c1), (r0, c0))
        return bool(targets[local[:, 0], local[:, 1]].any())

    def _replan_path(self, pose: Pose, grid: OccupancyGrid) -> bool:
        """A fresh path to the current goal on the current map; False when it cannot be reached."""
        assert self.goal is not None
        view, off = known_window(grid, WINDOW_MARGIN)
        cost = self._costs(grid, view, off)
        passable = np.isfinite(cost)
        start = self._start_cell(pose, grid, passable, off)
        gr, gc = grid.geo.cell_of(*self.goal)
        goal_rc = (gr - off[0], gc - off[1])
        if start is None or not (0 <= goal_rc[0] < passable.shape[0] and 0 <= goal_rc[1] < passable.shape[1]
                                 and passable[goal_rc]):
            return False
        path = astar(cost, start, goal_rc)
        if path is None:
            return False
        self._follow(path, passable, pose, grid, off)
        return True

    def _watch_progress(self, pose: Pose, now: float) -> None:
        remaining = self.follower.remaining(pose)
        if remaining < self.best_remaining - 0.1:
            self.best_remaining = remaining
            self.last_progress = now
        elif now - self.last_progress > self.goal_timeout and self.goal is not None:
            self.blacklist[self.goal_cells[:, 0], self.goal_cells[:, 1]] = True
            self.blacklist_events += 1
            self.follower.clear()
            self.goal = self.face = None
            self.next_plan = -math.inf

    def _blacklist_unresolved(self, grid: OccupancyGrid) -> None:
        view, off = known_window(grid, WINDOW_MARGIN)
        local = self.goal_cells - off
        still = self._frontier_targets(grid, view, off)[local[:, 0], local[:, 1]]
        if still.any():
            stuck = self.goal_cells[still]
            self.blacklist[stuck[:, 0], stuck[:, 1]] = True
            self.blacklist_events += 1

    def _plan(self, pose: Pose, grid: OccupancyGrid) -> bool:
        """Choose the nearest reachable frontier goal; False when there is none."""
        geo = grid.geo
        self.plans += 1
        view, off = known_window(grid, WINDOW_MARGIN)
        cost = self._costs(grid, view, off)
        passable = np.isfinite(cost)
        start = self._start_cell(pose, grid, passable, off)
        if start is None:
            return False
        frontier = self._frontier_targets(grid, view, off)
        if not frontier.any():
            return False
        targets = self._assigned_part(frontier, off)
        found = self._nearest(cost, passable, start, targets, geo.cell)
        if found is None and targets is not frontier:
            # the coordinator's target has no cell this robot can stand by: it chooses alone (a team run
            # must not end a robot's exploration on a target only the team's path costs thought reachable)
            targets = frontier
            found = self._nearest(cost, passable, start, targets, geo.cell)
        if found is None:
            return False
        goal_rc, path, _ = found
        gx, gy = geo.center_of(goal_rc[0] + off[0], goal_rc[1] + off[1])
        if self.goal is None or math.hypot(gx - self.goal[0], gy - self.goal[1]) > geo.cell * 1.5:
            self.best_remaining = math.inf
            self.last_progress = self._now
        self.goal = (gx, gy)
        self._aim(targets, goal_rc, view, grid, off)
        self._follow(path, passable, pose, grid, off)
        return True

    def _nearest(self, cost: npt.NDArray[np.float32], passable: npt.NDArray[np.bool_], start: tuple[int, int],
                 targets: npt.NDArray[np.bool_], cell: float) -> tuple[Cell, Path, float] | None:
        """The nearest cell (`nearest_goal`: the cell, the path, its cost) where the robot stands by one of
        `targets`: on or right by a frontier cell where possible (within a robot radius plus 1.5 cells: inside
        the room, not in its door), else within a metre of one (frontier cells in pockets too narrow for the
        robot); None when there is none. `reach` [cells] is set to the distance used."""
        # the cells within reach of a target: a disc around each target, not a distance transform of the window
        for reach in (self.ctx.radius / cell + 1.5, (self.ctx.radius + 1.0) / cell):
            found = nearest_goal(cost, start, near_cells(targets, reach) & passable)
            if found is not None:
                self.reach = reach
                return found
        return None

    def target_frontier(self, grid: OccupancyGrid) -> tuple[npt.NDArray[np.bool_], Offset]:
        """The frontier cells the next plan would choose among (walls' faces and cells given up on left out),
        on the window of the scanned part of `grid`, with the window's offset."""
        view, off = known_window(grid, WINDOW_MARGIN)
        return self._frontier_targets(grid, view, off), off

    def _assigned_part(self, targets: npt.NDArray[np.bool_], off: Offset) -> npt.NDArray[np.bool_]:
        """The targets among the coordinator's cells, when some are; else all of them."""
        if self.assigned is None or len(self.assigned) == 0:
            return targets
        local = self.assigned - off
        rows, cols = targets.shape
        inside = (local[:, 0] >= 0) & (local[:, 0] < rows) & (local[:, 1] >= 0) & (local[:, 1] < cols)
        local = local[inside]
        keep = np.zeros_like(targets)
        keep[local[:, 0], local[:, 1]] = targets[local[:, 0], local[:, 1]]
        return keep if keep.any() else targets

    def _frontier_targets(self, grid: OccupancyGrid, view: OccupancyGrid, off: Offset) -> npt.NDArray[np.bool_]:
        """`frontier_targets` of the groups large enough to matter, blacklisted cells left out, on the
        window `view` of `grid` whose cell (0, 0) is `off`."""
        # the same map (no scan since), window and blacklist give the same targets: computed once a step
        key = (id(grid), grid.scans, self.blacklist_events, off, view.shape)
        if self._targets is not None and self._targets[0] == key:
            return self._targets[1]
        targets = self._targets_of(grid, view, off)
        targets.flags.writeable = False
        self._targets = (key, targets)
        return targets

    def _min_cells(self, grid: OccupancyGrid) -> int:
        """The smallest frontier group kept [cells]."""
        return self.min_group_cells or max(1, int(math.ceil(2 * self.ctx.radius / grid.geo.cell)))

    def _targets_of(self, grid: OccupancyGrid, view: OccupancyGrid, off: Offset) -> npt.NDArray[np.bool_]:
        """`_frontier_targets` computed afresh on the window `view` of `grid` whose cell (0, 0) is `off`."""
        if self.blacklist.shape != grid.shape:
            self.blacklist = np.zeros(grid.shape, dtype=bool)
        rows, cols = view.shape
        skip = self.blacklist[off[0]:off[0] + rows, off[1]:off[1] + cols]
        if self.face_reach <= 0:
            return frontier_targets(view, self._min_cells(grid), skip)
        face, opening = wall_face_cells(self._memory(grid), grid, view, off, self.face_reach)
        return frontier_targets(view, self._min_cells(grid), skip | face) & opening

    def _costs(self, grid: OccupancyGrid, view: OccupancyGrid, off: Offset) -> npt.NDArray[np.float32]:
        """`plan_costs` of the window `view` of `grid` (a view of the cache's costs: not to be written), with the
        teammates' discs it plans around impassable (then a copy)."""
        rows, cols = view.shape
        cost = self._plan_costs(grid).update(grid)[off[0]:off[0] + rows, off[1]:off[1] + cols]
        return cost if self.around is None else discs_blocked(cost, grid.geo, off, self.around)

    def _plan_costs(self, grid: OccupancyGrid) -> PlanCosts:
        """The `PlanCosts` of `grid` for this robot's radius and clearance, one for every explorer that plans on
        that grid with them (a team sharing one map: the costs are a function of the map alone, bit for bit)."""
        key = (id(grid), self.ctx.radius, self.clearance)
        costs = _SHARED_COSTS.get(key)
        if costs is None:
            costs = _SHARED_COSTS[key] = PlanCosts(self.ctx.radius, self.clearance)
        self.costs = costs          # kept while this explorer plans with it
        return costs

    def _memory(self, grid: OccupancyGrid) -> WallMemory:
        """The cells ever firmly occupied (`WallMemory`), with distances exact to `face_reach` and the 8-neighbours."""
        if self.walls_seen is None:
            self.walls_seen = shared_wall_memory(grid, max(self.face_reach / grid.geo.cell, 1.5))
        return self.walls_seen

    def _start_cell(self, pose: Pose, grid: OccupancyGrid, passable: npt.NDArray[np.bool_],
                    off: Offset) -> tuple[int, int] | None:
        return passable_cell(grid.geo, passable, pose.x, pose.y, offset=off)

    def _aim(self, targets: npt.NDArray[np.bool_], goal_rc: tuple[int, int], view: OccupancyGrid,
             grid: OccupancyGrid, off: Offset) -> None:
        """Remember the frontier cells this goal is for (in `grid`'s cells), and where to look on arrival:
        the centre of their unknown neighbours. `targets` and `goal_rc` are the window `view`'s."""
        geo = grid.geo
        k = int(math.ceil(self.reach)) + 1
        r0, c0 = max(goal_rc[0] - k, 0), max(goal_rc[1] - k, 0)
        window = targets[r0:goal_rc[0] + k + 1, c0:goal_rc[1] + k + 1]
        local = np.argwhere(window) + (r0, c0)
        self.goal_cells = local + off
        if len(self.goal_cells) == 0:
            self.face = None
            return
        # look at the unknown 4-neighbours of those frontier cells: they are what must be seen (the window's
        # unknown cells asked only around them)
        rows, cols = view.shape
        b0, d0 = max(r0 - 1, 0), max(c0 - 1, 0)
        unknown = view.window(b0, goal_rc[0] + k + 2, d0, goal_rc[1] + k + 2).unknown()
        seen_from: list[tuple[int, int]] = []
        for r, c in local:
            for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                rr, cc = r + dr, c + dc
                if 0 <= rr < rows and 0 <= cc < cols and unknown[rr - b0, cc - d0]:
                    seen_from.append((rr + off[0], cc + off[1]))
        centre = np.mean(seen_from, axis=0) if seen_from else self.goal_cells.mean(axis=0)
        self.face = (geo.origin_x + (centre[1] + 0.5) * geo.cell, geo.origin_y + (centre[0] + 0.5) * geo.cell)

    def _follow(self, path: npt.NDArray[np.int32], passable: npt.NDArray[np.bool_], pose: Pose,
                grid: OccupancyGrid, off: Offset) -> None:
        """Follow `path` (cells of the window `passable` whose cell (0, 0) is `off`) through the points of
        its cells the costs planned with (`PlanCosts.points`)."""
        rows, cols = passable.shape
        points = None if self.costs is None else self.costs.points[off[0]:off[0] + rows, off[1]:off[1] + cols]
        self.follower.follow_cells(path, passable, grid.geo, (pose.x, pose.y), off, points)

    def _finish(self, pose: Pose, grid: OccupancyGrid) -> Twist | Done:
        """No frontier left: done, or drive home first."""
        self.follower.clear()
        if not self.return_home:
            return Done("no reachable frontier left")
        start = self.ctx.start
        view, off = known_window(grid, WINDOW_MARGIN)
        cost = self._costs(grid, view, off)
        passable = np.isfinite(cost)
        here = self._start_cell(pose, grid, passable, off)
        hr, hc = grid.geo.cell_of(start.x, start.y)
        home = (hr - off[0], hc - off[1])
        path = astar(cost, here, home) if here is not None and view.geo.contains(*home) else None
        self.homing = True
        if path is None:
            return Done("no reachable frontier left; the start is unreachable")
        self._follow(path, passable, pose, grid, off)
        self.follower.path[-1] = (start.x, start.y)
        return Twist.ZERO
