"""`PathFollower`: drives a differential robot along a polyline of world points.

Shared by every goal-seeking explorer (frontier, SRT, metaheuristic targets). Pure pursuit with a
look-ahead point, turning in place when the heading error is large, slowing near the end, and a
safety check on the laser: no forward motion towards an obstacle closer than the robot needs to stop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.mapping.geometry import GridGeometry
from robotexp.planning.grid_planner import simplify
from robotexp.robot import LaserScan, Limits, Pose, Twist, wrap_angle

__all__ = ["PathFollower", "FollowerConfig", "blocked_ahead", "path_points"]


@dataclass(frozen=True)
class FollowerConfig:
    """Tuning of the path follower (SI units)."""

    lookahead: float = 0.2          # [m] a waypoint this close counts as passed (small: no corner cutting)
    goal_tolerance: float = 0.15    # [m] the path is done within this distance of its end
    turn_in_place: float = math.radians(50)   # [rad] heading error above which the robot only turns
    k_turn: float = 2.0             # [1/s] turn rate per radian of heading error
    clearance: float = 0.08         # [m] kept between the robot's edge and an obstacle ahead

    def __post_init__(self) -> None:
        if self.lookahead <= 0 or self.goal_tolerance <= 0 or self.k_turn <= 0 or self.clearance < 0:
            raise ConfigError(f"path follower: lookahead, goal_tolerance and k_turn must be > 0 and "
                              f"clearance >= 0, got {self}")


def blocked_ahead(scan: LaserScan | None, radius: float, clearance: float, speed: float) -> bool:
    """True when a laser return lies in the corridor the robot would sweep in the next moment.

    The corridor is the robot's width (plus `clearance`) wide and as long as the stopping distance
    at `speed` plus `clearance`, measured from the robot's front.
    """
    if scan is None or speed <= 0:
        return False
    r = scan.ranges
    a = scan.angles
    ok = np.isfinite(r)
    x = scan.offset_x + r[ok] * np.cos(a[ok])
    y = r[ok] * np.sin(a[ok])
    reach = radius + clearance + max(speed, 0.05) * 0.5
    inside = (x > 0) & (x < reach) & (np.abs(y) < radius + 0.02)
    return bool(inside.any())


def path_points(cells: npt.NDArray[np.integer], passable: npt.NDArray[np.bool_],
                geo: GridGeometry, offset: tuple[int, int] = (0, 0)) -> npt.NDArray[np.float64]:
    """The world points [m] (k, 2) of a planner path: the cell centres of `cells` string-pulled on `passable`.

    Args:
        cells: (n, 2) int (row, col) cells of a path, consecutive ones 8-neighbours (as from `astar`).
        passable: (rows, cols) bool the path was planned on.
        geo: the grid's geometry.
        offset: (row, col) of `passable`'s cell (0, 0) in `geo` (a window of the grid, as
            `OccupancyGrid.window`); `cells` are the window's.

    Returns:
        (k, 2) float64, k <= n.
    """
    kept = simplify(cells, passable) if len(cells) > 2 else cells
    return geo.centers_of(np.asarray(kept) + np.asarray(offset, dtype=np.int64))


class PathFollower:
    """Follows one path at a time; `twist()` returns the command and `done` says when it arrived."""

    def __init__(self, limits: Limits, radius: float, config: FollowerConfig | None = None) -> None:
        self.limits = limits
        self.radius = radius
        self.config = config or FollowerConfig()
        self.path: npt.NDArray[np.float64] = np.zeros((0, 2))
        self._index = 0
        self.done = True
        self.blocked = False

    def set_path(self, points: npt.NDArray[np.float64]) -> None:
        """Follow `points` (k, 2) [m] from the first to the last."""
        self.path = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        self._index = 0
        self.done = len(self.path) == 0

    def follow_cells(self, cells: npt.NDArray[np.integer], passable: npt.NDArray[np.bool_], geo: GridGeometry,
                     start: tuple[float, float], offset: tuple[int, int] = (0, 0)) -> None:
        """Follow a planner path of cells (`path_points`, with its `offset`), its first point moved to
        `start` (x, y) [m], the robot's exact position."""
        pts = path_points(cells, passable, geo, offset)
        pts[0] = start
        self.set_path(pts if len(pts) > 1 else np.vstack([pts, pts]))

    def clear(self) -> None:
        """Forget the path."""
        self.set_path(np.zeros((0, 2)))

    def remaining(self, pose: Pose) -> float:
        """Distance [m] left along the path from `pose`."""
        if self.done or len(self.path) == 0:
            return 0.0
        pts = self.path[self._index:]
        first = math.hypot(pts[0, 0] - pose.x, pts[0, 1] - pose.y)
        return first + float(np.hypot(*np.diff(pts, axis=0).T).sum()) if len(pts) > 1 else first

    def twist(self, pose: Pose, scan: LaserScan | None = None) -> Twist:
        """The command that follows the path from `pose`; zero once done."""
        cfg = self.config
        if self.done:
            return Twist.ZERO
        end = self.path[-1]
        if math.hypot(end[0] - pose.x, end[1] - pose.y) < cfg.goal_tolerance:
            self.done = True
            return Twist.ZERO
        # advance along the path past points already within the look-ahead
        while (self._index < len(self.path) - 1
               and math.hypot(self.path[self._index, 0] - pose.x,
                              self.path[self._index, 1] - pose.y) < cfg.lookahead):
            self._index += 1
        tx, ty = self.path[self._index]
        return self.toward(pose, tx, ty, math.hypot(end[0] - pose.x, end[1] - pose.y), scan)

    def toward(self, pose: Pose, tx: float, ty: float, to_end: float, scan: LaserScan | None) -> Twist:
        """Head for (tx, ty); `to_end` [m] sets the speed ramp at the end of the path."""
        cfg, lim = self.config, self.limits
        err = wrap_angle(math.atan2(ty - pose.y, tx - pose.x) - pose.theta)
        w = max(-lim.w_max, min(lim.w_max, cfg.k_turn * err))
        if abs(err) > cfg.turn_in_place:
            self.blocked = False
            return Twist(0.0, w)
        v = lim.v_max * math.cos(err) * min(1.0, to_end / 0.5 + 0.2)
        # braking distance v^2 / 2a must fit in what is left of the path
        v = min(v, math.sqrt(2 * lim.a_max * max(to_end, 0.0)) + 0.02)
        self.blocked = blocked_ahead(scan, self.radius, cfg.clearance, v)
        if self.blocked:
            return Twist(0.0, w)
        return Twist(max(0.0, v), w)

    def turn_to(self, pose: Pose, heading: float) -> tuple[Twist, bool]:
        """Turn in place to `heading` [rad]; returns the command and whether it is reached (5 deg)."""
        err = wrap_angle(heading - pose.theta)
        if abs(err) < math.radians(5):
            return Twist.ZERO, True
        w = max(-self.limits.w_max, min(self.limits.w_max, self.config.k_turn * err))
        return Twist(0.0, w), False
