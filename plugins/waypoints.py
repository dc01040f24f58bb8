"""Waypoint potential-field navigation (the UFMG practical work) as a robotexp explorer plugin.

The robot visits a list of goals in order. At each step the command follows the sum of an
attractive force towards the current goal and repulsive forces from the laser returns nearby
(Khatib 1986; Siegwart, Nourbakhsh & Scaramuzza, *Autonomous Mobile Robots*, section 6.2.1.3):

    F_att = k_att * (g - p) / max(|g - p|, 1)                (unit pull beyond 1 m, linear inside)
    F_rep = sum over returns within `influence` of the robot's edge:
            k_rep * (1 / c - 1 / influence) / c**2 * u        (c: clearance [m], u: unit vector away)

The non-holonomic robot turns towards the force and drives forward at a speed that falls with the
heading error and with the clearance ahead. The map is whatever the run builds (log-odds, UFMG).

A pure potential field has local minima (a box straight between the robot and its goal). When the
distance to the goal has not shrunk by `progress` [m] for `stuck_time` [s], the attractor becomes
a point `lookahead` [m] along the shortest path to the goal on the current map (unknown cells
passable, occupied ones inflated by the robot radius), until the robot is closer to the goal than
it was when it got stuck minus `progress`: the field still steers, the map only picks the side.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import ClassVar

import numpy as np
import numpy.typing as npt

from robotexp import ConfigError, Done, Explorer, ExplorerContext, LaserScan, Pose, RobotState, Twist, wrap_angle
from robotexp.mapping.grid import OccupancyGrid
from robotexp.planning.grid_planner import astar, cost_grid
from robotexp.planning.targets import cell_points, passable_radius, wall_distance

__all__ = ["WaypointsExplorer", "attractive_force", "repulsive_force", "scan_points", "SECTORS"]

SECTORS = 16    # bearing sectors around the robot; the nearest return of each one repels


def attractive_force(pose: Pose, goal: tuple[float, float], k_att: float) -> npt.NDArray[np.float64]:
    """The pull [1] towards `goal` [m]: `k_att` times the offset, saturated at `k_att` beyond 1 m.

    Returns:
        (2,) float64 force in the world frame.
    """
    d = np.array([goal[0] - pose.x, goal[1] - pose.y], dtype=np.float64)
    return k_att * d / max(float(np.hypot(d[0], d[1])), 1.0)


def scan_points(pose: Pose, scan: LaserScan | None, reach: float) -> npt.NDArray[np.float64]:
    """The laser returns within `reach` [m] of the robot centre, in the world frame.

    Beams past `range_max` (no hit) and NaN ranges are left out.

    Returns:
        (k, 2) float64 world points [m].
    """
    if scan is None:
        return np.zeros((0, 2))
    ok = np.isfinite(scan.ranges) & (scan.ranges < scan.range_max)
    x = scan.offset_x + scan.ranges[ok] * np.cos(scan.angles[ok])
    y = scan.ranges[ok] * np.sin(scan.angles[ok])
    near = np.hypot(x, y) < reach
    x, y = x[near], y[near]
    ct, st = math.cos(pose.theta), math.sin(pose.theta)
    return np.column_stack([pose.x + ct * x - st * y, pose.y + st * x + ct * y])


def repulsive_force(x: float, y: float, points: npt.NDArray[np.float64], radius: float, influence: float,
                    k_rep: float) -> tuple[npt.NDArray[np.float64], float]:
    """The push [1] on a robot of `radius` [m] at (x, y) [m] away from obstacle `points` (k, 2) [m].

    The points are split into `SECTORS` equal bearing sectors around the robot centre and the
    nearest point of each sector counts (a wall pushes as hard seen by 10 beams as by 100). Each
    such point at clearance c = distance from the robot centre - `radius` [m], floored at 1 cm,
    within `influence` [m] adds k_rep * (1/c - 1/influence) / c**2 along the unit vector from the
    point to the robot centre.

    Returns:
        ((2,) float64 force in the world frame, the smallest clearance [m], inf without points).
    """
    force = np.zeros(2, dtype=np.float64)
    if len(points) == 0:
        return force, math.inf
    dx, dy = x - points[:, 0], y - points[:, 1]          # from the point towards the robot
    dist = np.maximum(np.hypot(dx, dy), 1e-9)
    clear = np.maximum(dist - radius, 0.01)
    c_min = float(clear.min())
    sector = np.minimum(((np.arctan2(-dy, -dx) + math.pi) / (2 * math.pi) * SECTORS).astype(np.int64), SECTORS - 1)
    order = np.lexsort((clear, sector))
    first = np.ones(len(order), dtype=bool)
    first[1:] = sector[order][1:] != sector[order][:-1]
    pick = order[first]
    pick = pick[clear[pick] < influence]
    if len(pick) == 0:
        return force, c_min
    c = clear[pick]
    mag = k_rep * (1.0 / c - 1.0 / influence) / c**2
    force[0] = float(np.sum(mag * dx[pick] / dist[pick]))
    force[1] = float(np.sum(mag * dy[pick] / dist[pick]))
    return force, c_min


class WaypointsExplorer(Explorer):
    """Visit a list of goals with a potential field (UFMG); done after the last one.

    The goals are `goals` when given, else the world's goal list named `path`, else the list named
    like the start pose (ufmg-static and ufmg-dynamic: `path1`, `path2`), else the world's only list.

    Args:
        goals: [m] the goals as (x, y) pairs, in visiting order; None: from the world.
        path: name of one of the world's goal lists; None: the one named like the start pose.
        k_att: attractive gain [1].
        k_rep: repulsive gain [m^2].
        influence: [m] clearance from the robot's edge within which obstacles repel.
        tolerance: [m] a goal is reached within this distance of the robot centre.
        k_turn: [1/s] turn rate per radian of heading error.
        stuck_time: [s] without `progress` towards the goal before the map picks the way around.
        progress: [m] what counts as getting closer to the goal.
        lookahead: [m] how far along the map's path the attractor is put when stuck.
        goal_timeout: [s] a goal not reached in this time is given up (the run goes on to the next).
        memory: [s] how long laser returns keep repelling after they were seen: what the laser saw
            before the robot turned still pushes (the Kobuki's laser is blind behind it).
    """

    parameter_bounds: ClassVar[dict[str, tuple[float | None, float | None]]] = {
        "k_att": (None, 1000.0), "k_rep": (None, 1000.0), "influence": (None, 10.0), "tolerance": (None, 10.0),
        "k_turn": (None, 100.0), "stuck_time": (None, 86400.0), "progress": (None, 100.0), "lookahead": (None, 100.0),
        "goal_timeout": (None, 86400.0), "memory": (None, 3600.0)}

    preferred_cell = 0.05       # [m] the UFMG study's choice (0.01 too slow, 0.1 too coarse)
    needs_range = False         # a route: laser returns, when there are any, only push it clear of obstacles

    def __init__(self, *, goals: Sequence[Sequence[float]] | None = None, path: str | None = None,  # noqa: PLR0913
                 k_att: float = 1.0, k_rep: float = 0.02, influence: float = 0.5, tolerance: float = 0.25,
                 k_turn: float = 2.0, stuck_time: float = 8.0, progress: float = 0.3, lookahead: float = 0.8,
                 goal_timeout: float = 240.0, memory: float = 3.0) -> None:
        for name, value in (("k_att", k_att), ("k_rep", k_rep), ("influence", influence), ("tolerance", tolerance),
                            ("k_turn", k_turn), ("stuck_time", stuck_time), ("progress", progress),
                            ("lookahead", lookahead), ("goal_timeout", goal_timeout), ("memory", memory)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ConfigError(f"waypoints: {name} must be a finite number > 0, got {value!r}")
        self.goals_param: list[tuple[float, float]] | None = None
        if goals is not None:
            try:
                pts = np.asarray(goals, dtype=np.float64)
            except (TypeError, ValueError):
                pts = np.zeros((0, 3))
            if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) == 0 or not np.isfinite(pts).all():
                raise ConfigError(f"waypoints: goals must be a non-empty list of finite [x, y] pairs [m], "
                                  f"got {goals!r}")
            self.goals_param = [(float(x), float(y)) for x, y in pts]
        if path is not None and goals is not None:
            raise ConfigError("waypoints: give either goals or path, not both")
        self.path = path
        self.k_att, self.k_rep, self.influence = float(k_att), float(k_rep), float(influence)
        self.tolerance, self.k_turn = float(tolerance), float(k_turn)
        self.stuck_time, self.progress, self.lookahead = float(stuck_time), float(progress), float(lookahead)
        self.goal_timeout = float(goal_timeout)
        self.memory = float(memory)

    # -- setup ---------------------------------------------------------------------------------
    def reset(self, ctx: ExplorerContext) -> None:
        """Start a new run: choose the goal list.

        Raises:
            ConfigError: no goals given and the world has no suitable goal list.
        """
        super().reset(ctx)
        self.goals = self._choose_goals(ctx)
        self.index = 0
        self.reached: list[float] = []          # [s] robot time at which each goal was reached
        self.skipped: list[int] = []            # goals given up
        self.detours = 0                        # times the map had to pick the way round
        self._new_goal(-math.inf)
        self._last_force = np.zeros(2)
        self._seen: list[tuple[float, npt.NDArray[np.float64]]] = []     # (robot time, world points)

    def _choose_goals(self, ctx: ExplorerContext) -> list[tuple[float, float]]:
        if self.goals_param is not None:
            self.path_name = "given"
            return list(self.goals_param)
        lists = ctx.goals
        name = self.path
        if name is None:
            if ctx.start_name is not None and ctx.start_name in lists:
                name = ctx.start_name
            elif len(lists) == 1:
                name = next(iter(lists))
        if name is None or name not in lists:
            have = ", ".join(lists) or "none"
            want = f"no goal list named {name!r}" if name is not None else \
                f"no goal list named like the start pose ({ctx.start_name or 'unnamed'})"
            raise ConfigError(f"waypoints: the world has {want} (it has: {have}); give the goals in metres "
                              "with the parameter goals (-p 'goals=[[1.0, 2.0], [3.5, 2.0]]'), or name one of "
                              "the world's goal lists with the parameter path (-p path=NAME)")
        pts = [(float(x), float(y)) for x, y in lists[name]]
        if not pts:
            raise ConfigError(f"waypoints: the world's goal list {name!r} is empty; give goals as [[x, y], ...]")
        self.path_name = name
        return pts

    def _new_goal(self, now: float) -> None:
        self.best = math.inf
        self.best_time = now
        self.goal_start = now
        self.detour_until: float | None = None     # distance to the goal that ends the detour
        self.detour_point: tuple[float, float] | None = None

    # -- the decision --------------------------------------------------------------------------
    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        """Steer along the potential field towards the current goal; Done after the last goal."""
        pose, now = state.pose, state.time
        if self.goal_start == -math.inf:
            self.goal_start = self.best_time = now
        while self.index < len(self.goals):
            gx, gy = self.goals[self.index]
            dist = math.hypot(gx - pose.x, gy - pose.y)
            if dist <= self.tolerance:
                self.reached.append(now)
                self.index += 1
                self._new_goal(now)
                continue
            if now - self.goal_start > self.goal_timeout:
                self.skipped.append(self.index)
                self.index += 1
                self._new_goal(now)
                continue
            break
        else:
            if self.skipped:
                return Done(f"goals {', '.join(str(i + 1) for i in self.skipped)} of path {self.path_name!r} "
                            "not reached", explored=False)
            # following goals is no claim that the place is explored: the run loop does not check it
            return Done(f"all {len(self.goals)} goals of path {self.path_name!r} reached", explored=False)
        target = self._target(pose, (gx, gy), dist, now, grid)
        reach = self.ctx.radius + self.influence + self.ctx.limits.v_max * self.memory
        self._seen = [(t, p) for t, p in self._seen if now - t < self.memory]
        self._seen.append((now, scan_points(pose, state.laser, reach)))
        points = np.concatenate([p for _, p in self._seen])
        f_rep, _ = repulsive_force(pose.x, pose.y, points, self.ctx.radius, self.influence, self.k_rep)
        force = attractive_force(pose, target, self.k_att) + f_rep
        self._last_force = force
        return self._twist(pose, force, state.laser)

    def _target(self, pose: Pose, goal: tuple[float, float], dist: float, now: float,
                grid: OccupancyGrid) -> tuple[float, float]:
        """The attractor: the goal, or a point on the map's path to it while stuck."""
        if dist < self.best - self.progress:
            self.best, self.best_time = dist, now
        if self.detour_until is not None:
            if dist < self.detour_until:
                self.detour_until = self.detour_point = None
                self.best, self.best_time = dist, now
            elif now - self.best_time > self.stuck_time:      # refresh the detour on the new map
                self.best_time = now
                self.detour_point = self._detour(pose, goal, grid)
        elif now - self.best_time > self.stuck_time:
            self.detours += 1
            self.best_time = now
            self.detour_until = self.best - self.progress
            self.detour_point = self._detour(pose, goal, grid)
        return self.detour_point or goal

    def _detour(self, pose: Pose, goal: tuple[float, float], grid: OccupancyGrid) -> tuple[float, float] | None:
        """The point `lookahead` [m] along the shortest map path to `goal`, or None when there is none."""
        geo = grid.geo
        occ = grid.occupied()
        if not occ.any():
            return None
        radius = passable_radius(geo.cell, self.ctx.radius)       # the planners' passability (the walls' surface)
        points = np.zeros(grid.shape, np.uint8)        # the point of each cell a plan passes through
        dist = wall_distance(grid, radius + self.influence / geo.cell, points=points, below=radius)
        cost = cost_grid(dist, robot_radius_cells=radius, danger_radius_cells=self.influence / geo.cell,
                         danger_cost=4.0)
        start, end = geo.cell_of(pose.x, pose.y), geo.cell_of(*goal)
        if not (geo.contains(*start) and geo.contains(*end)):
            return None
        cost[start] = min(float(cost[start]), 1.0)
        cost[end] = min(float(cost[end]), 1.0)
        cells = astar(cost, start, end)
        if cells is None or len(cells) < 2:
            return None
        pts = cell_points(geo, cells, points)
        along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
        i = min(int(np.searchsorted(along, self.lookahead)), len(pts) - 1)
        return float(pts[i, 0]), float(pts[i, 1])

    def _twist(self, pose: Pose, force: npt.NDArray[np.float64], scan: LaserScan | None) -> Twist:
        """Unicycle command: turn towards the force, drive forward when roughly facing it."""
        lim = self.ctx.limits
        err = wrap_angle(math.atan2(force[1], force[0]) - pose.theta)
        w = max(-lim.w_max, min(lim.w_max, self.k_turn * err))
        v = lim.v_max * max(math.cos(err), 0.0) ** 2
        ahead = _clearance_ahead(scan, self.ctx.radius)
        # slow down in the last 3 influence-lengths ahead; stop 3 cm short of contact
        v *= min(1.0, max(0.0, (ahead - 0.03) / (3 * self.influence)))
        if abs(err) > math.radians(60):
            v = 0.0
        return Twist(v, w)

    def result_fields(self) -> dict[str, object]:
        """Goals reached and given up, and the map detours taken."""
        return {"goals": len(self.goals), "goals_reached": len(self.reached), "goals_skipped": len(self.skipped),
                "detours": self.detours, "goal_path": self.path_name}

    def overlays(self) -> dict[str, npt.NDArray[np.float64]]:
        """No overlays: the field lives in the laser's frame, not on the grid."""
        return {}


def _clearance_ahead(scan: LaserScan | None, radius: float) -> float:
    """[m] free length in front of the robot's edge within its width (inf when nothing is there)."""
    if scan is None:
        return math.inf
    ok = np.isfinite(scan.ranges) & (scan.ranges < scan.range_max)
    x = scan.offset_x + scan.ranges[ok] * np.cos(scan.angles[ok])
    y = scan.ranges[ok] * np.sin(scan.angles[ok])
    front = (x > 0) & (np.abs(y) < radius + 0.03)
    if not front.any():
        return math.inf
    return float(x[front].min() - radius)
