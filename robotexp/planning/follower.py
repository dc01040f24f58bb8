"""`PathFollower`: drives a differential robot along a polyline of world points.

Shared by every goal-seeking explorer (frontier, SRT, metaheuristic targets). It steers at a carrot on
the path a short way ahead of the robot's projection on it (pure pursuit that follows the polyline, not
its corners cut), turning in place when the heading error is large. Where the laser shows little room
around the robot (a door the plan says it fits) it slows down, steers at a nearer carrot and turns in
place at a smaller heading error, so that it passes where the plan passes. A guard stops forward motion
only when the robot's disc, swept along the command's arc for its stopping distance, would come within
`FollowerConfig.clearance` of a laser return it is approaching: the same geometry as the planners' (a
disc and the walls' surface), so it trips on an imminent collision, not on a wall it slides along.
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

__all__ = ["PathFollower", "FollowerConfig", "blocked_ahead", "free_heading", "path_points", "roomy_cells",
           "scan_clearance"]

REACTION = 0.2          # [s] of motion at the commanded speed added to the stopping distance the guard checks
SWEEP_STEP = 0.02       # [m] between the disc positions the guard checks along the arc


@dataclass(frozen=True)
class FollowerConfig:
    """Tuning of the path follower (SI units)."""

    lookahead: float = 0.2          # [m] carrot ahead of the robot's projection on the path where there is room
    goal_tolerance: float = 0.15    # [m] the path is done within this distance of its end
    turn_in_place: float = math.radians(50)   # [rad] heading error above which the robot only turns
    k_turn: float = 2.0             # [1/s] turn rate per radian of heading error
    clearance: float = 0.01         # [m] the guard's margin between the swept disc and a laser return
    tight: float = 0.15             # [m] room (laser clearance beyond the radius) below which the robot slows
    tight_turn: float = math.radians(15)      # [rad] heading error above which it only turns where room is tight
    tight_speed: float = 0.08       # [m/s] its speed with no room to spare

    def __post_init__(self) -> None:
        if (self.lookahead <= 0 or self.goal_tolerance <= 0 or self.k_turn <= 0 or self.clearance < 0
                or self.tight < 0 or not 0 < self.tight_turn <= self.turn_in_place or self.tight_speed <= 0):
            raise ConfigError(f"path follower: lookahead, goal_tolerance, k_turn and tight_speed must be > 0, "
                              f"clearance and tight >= 0, 0 < tight_turn <= turn_in_place, got {self}")


_POINTS: list[object] = [None, np.zeros((0, 2)), np.zeros(0)]     # the last scan, its points, their norms
_TRIG: list[object] = [None, np.zeros(0), np.zeros(0)]             # the last beam angles, their cos and sin


def _points_norms(scan: LaserScan | None) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """(k, 2) robot-frame points [m] of the returns of `scan` (ranges below its maximum) and (k,) their
    distances [m] from the robot's centre; the last scan's are kept (a control step asks more than once)."""
    if scan is None:
        return np.zeros((0, 2)), np.zeros(0)
    if _POINTS[0] is not scan:
        if _TRIG[0] is not scan.angles:          # a robot's scans share one array of beam angles
            _TRIG[:] = [scan.angles, np.cos(scan.angles), np.sin(scan.angles)]
        r = scan.ranges
        ok = r < scan.range_max                  # False for NaN and inf too
        rr = r[ok]
        pts = np.empty((len(rr), 2))
        pts[:, 0] = scan.offset_x + rr * _TRIG[1][ok]      # type: ignore[index]
        pts[:, 1] = rr * _TRIG[2][ok]                      # type: ignore[index]
        _POINTS[:] = [scan, pts, rr if scan.offset_x == 0 else np.hypot(pts[:, 0], pts[:, 1])]
    return _POINTS[1], _POINTS[2]          # type: ignore[return-value]


def scan_clearance(scan: LaserScan | None, radius: float) -> float:
    """[m] from the robot's disc of `radius` to the nearest laser return (inf without one)."""
    norms = _points_norms(scan)[1]
    if len(norms) == 0:
        return math.inf
    return float(norms.min()) - radius


def blocked_ahead(scan: LaserScan | None, radius: float, clearance: float, speed: float, turn: float = 0.0,
                  a_max: float = 0.5) -> bool:
    """True when driving at (`speed` [m/s], `turn` [rad/s]) would bring the robot's disc of `radius` [m]
    within `clearance` [m] of a laser return it is approaching, before it could stop.

    The disc is swept along the command's arc for the stopping distance speed^2 / (2 `a_max`) plus
    `REACTION` s at `speed` plus `clearance`; a return counts when some position on that arc is nearer
    than radius + clearance and nearer than the disc's centre is now (a wall the robot slides along, or
    moves away from, does not stop it). Not moving forward never blocks.
    """
    if scan is None or speed <= 0:
        return False
    pts, norms = _points_norms(scan)
    return _sweep_blocked(pts, norms, radius, clearance, speed, turn, a_max)


def _sweep_blocked(pts: npt.NDArray[np.float64], norms: npt.NDArray[np.float64], radius: float, clearance: float,
                   speed: float, turn: float, a_max: float) -> bool:
    """`blocked_ahead` on the robot-frame points `pts` (k, 2) [m] at distances `norms` (k,), for speed > 0."""
    length = speed * speed / (2.0 * max(a_max, 1e-6)) + speed * REACTION + clearance
    reach = radius + clearance
    near = norms < length + reach        # the rest cannot be reached
    if not near.any():
        return False
    pts = pts[near]
    d0 = norms[near]
    s = np.linspace(0.0, length, max(2, int(math.ceil(length / SWEEP_STEP)) + 1))[1:]
    k = turn / speed                                             # curvature [1/m]
    if abs(k) < 1e-9:
        cx, cy = s, np.zeros_like(s)
    else:
        cx, cy = np.sin(k * s) / k, (1.0 - np.cos(k * s)) / k
    d = np.hypot(pts[:, None, 0] - cx[None, :], pts[:, None, 1] - cy[None, :])
    return bool(((d < reach) & (d < d0[:, None] - 1e-4)).any())


def free_heading(scan: LaserScan | None, radius: float, clearance: float, speed: float, heading: float,
                 a_max: float = 0.5, widest: float = math.pi / 2, step: float = math.radians(10)) -> float | None:
    """The direction [rad, robot frame] nearest `heading` (at most `widest` off it, tried every `step`, the
    left first on a tie) in which the robot could drive straight at `speed` [m/s] without `blocked_ahead`;
    None when there is none. A robot whose way is blocked turns to it and slides along the obstacle."""
    if scan is None or speed <= 0:
        return heading
    pts, norms = _points_norms(scan)
    k = int(widest / step)
    for off in [0.0] + [sign * i * step for i in range(1, k + 1) for sign in (1.0, -1.0)]:
        a = heading + off
        c, s = math.cos(a), math.sin(a)
        turned = np.column_stack([c * pts[:, 0] + s * pts[:, 1], -s * pts[:, 0] + c * pts[:, 1]])
        if not _sweep_blocked(turned, norms, radius, clearance, speed, 0.0, a_max):
            return wrap_angle(a)
    return None


def roomy_cells(passable: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """Bool (rows, cols): the passable cells whose 8 neighbours are all passable. A segment through
    them stays nearly as clear of the walls as the passable cells' centres (it lies within the squares
    of passable centres around it), so a path is string-pulled across them only; elsewhere (a door the
    robot just fits) it keeps every cell."""
    p = passable
    out = p.copy()
    out[1:, :] &= p[:-1, :]
    out[:-1, :] &= p[1:, :]
    rows = out.copy()
    out[:, 1:] &= rows[:, :-1]
    out[:, :-1] &= rows[:, 1:]
    out[0, :] = out[-1, :] = False         # beyond the border nothing is known to be passable
    out[:, 0] = out[:, -1] = False
    return out


def path_points(cells: npt.NDArray[np.integer], passable: npt.NDArray[np.bool_],
                geo: GridGeometry, offset: tuple[int, int] = (0, 0)) -> npt.NDArray[np.float64]:
    """The world points [m] (k, 2) of a planner path: the cell centres of `cells`, string-pulled across
    the `roomy_cells` of `passable` (every cell kept where the path runs through tight places).

    Args:
        cells: (n, 2) int (row, col) cells of a path, consecutive ones 8-neighbours (as from `astar`).
        passable: (rows, cols) bool the path was planned on.
        geo: the grid's geometry.
        offset: (row, col) of `passable`'s cell (0, 0) in `geo` (a window of the grid, as
            `OccupancyGrid.window`); `cells` are the window's.

    Returns:
        (k, 2) float64, k <= n.
    """
    kept = simplify(cells, roomy_cells(np.asarray(passable, dtype=bool))) if len(cells) > 2 else cells
    return geo.centers_of(np.asarray(kept) + np.asarray(offset, dtype=np.int64))


class PathFollower:
    """Follows one path at a time; `twist()` returns the command and `done` says when it arrived."""

    def __init__(self, limits: Limits, radius: float, config: FollowerConfig | None = None) -> None:
        self.limits = limits
        self.radius = radius
        self.config = config or FollowerConfig()
        self.path: npt.NDArray[np.float64] = np.zeros((0, 2))
        self._xy: list[tuple[float, float]] = []
        self._after: list[float] = []
        self._index = 0
        self.done = True
        self.blocked = False

    def set_path(self, points: npt.NDArray[np.float64]) -> None:
        """Follow `points` (k, 2) [m] from the first to the last."""
        self.path = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        self._xy = [(float(x), float(y)) for x, y in self.path]      # plain floats: the carrot's loop is Python
        steps = np.hypot(*np.diff(self.path, axis=0).T) if len(self.path) > 1 else np.zeros(0)
        self._after = np.concatenate([np.cumsum(steps[::-1])[::-1], [0.0]]).tolist()   # path left after point i
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
        i = min(self._index + 1, len(self._xy) - 1)          # the end of the segment it is on, then along
        return math.hypot(self._xy[i][0] - pose.x, self._xy[i][1] - pose.y) + self._after[i]

    def twist(self, pose: Pose, scan: LaserScan | None = None) -> Twist:
        """The command that follows the path from `pose`; zero once done."""
        cfg = self.config
        if self.done:
            return Twist.ZERO
        end = self.path[-1]
        to_end = math.hypot(end[0] - pose.x, end[1] - pose.y)
        if to_end < cfg.goal_tolerance:
            self.done = True
            return Twist.ZERO
        room = scan_clearance(scan, self.radius)
        tight = min(1.0, max(0.0, room / cfg.tight)) if cfg.tight > 0 else 1.0   # 0: no room to spare, 1: plenty
        ahead = cfg.lookahead * (0.5 + 0.5 * tight)
        tx, ty = self._carrot(pose, ahead)
        return self.toward(pose, tx, ty, to_end, scan, tight)

    def _carrot(self, pose: Pose, ahead: float) -> tuple[float, float]:
        """The point `ahead` [m] along the path beyond the robot's projection on it (the projection searched
        on the segment it is on and the next ones within reach, never behind)."""
        pts = self._xy
        n = len(pts)
        if n == 1:
            return pts[0]
        px, py = pose.x, pose.y
        best, best_d, best_t = self._index, math.inf, 0.0
        for i in range(self._index, min(n - 1, self._index + 8)):
            ax, ay = pts[i]
            bx, by = pts[i + 1]
            dx, dy = bx - ax, by - ay
            seg2 = dx * dx + dy * dy
            t = 0.0 if seg2 == 0 else min(1.0, max(0.0, ((px - ax) * dx + (py - ay) * dy) / seg2))
            d = math.hypot(ax + t * dx - px, ay + t * dy - py)
            if d < best_d - 1e-9:
                best, best_d, best_t = i, d, t
            if d > best_d + 2 * ahead:
                break
        self._index = best
        i, t, left = best, best_t, ahead
        while i < n - 1:
            ax, ay = pts[i]
            bx, by = pts[i + 1]
            seg = math.hypot(bx - ax, by - ay)
            rest = seg * (1.0 - t)
            if rest >= left and seg > 0:
                f = t + left / seg
                return ax + f * (bx - ax), ay + f * (by - ay)
            left -= rest
            i, t = i + 1, 0.0
        return pts[-1]

    def toward(self, pose: Pose, tx: float, ty: float, to_end: float, scan: LaserScan | None,
               tight: float = 1.0) -> Twist:
        """Head for (tx, ty); `to_end` [m] sets the speed ramp at the end of the path, `tight` (0 no room to
        spare .. 1 plenty, from the laser) the speed and the heading error above which it only turns."""
        cfg, lim = self.config, self.limits
        err = wrap_angle(math.atan2(ty - pose.y, tx - pose.x) - pose.theta)
        w = max(-lim.w_max, min(lim.w_max, cfg.k_turn * err))
        if abs(err) > cfg.tight_turn + tight * (cfg.turn_in_place - cfg.tight_turn):
            self.blocked = False
            return Twist(0.0, w)
        v = lim.v_max * math.cos(err) * min(1.0, to_end / 0.5 + 0.2)
        # braking distance v^2 / 2a must fit in what is left of the path
        v = min(v, math.sqrt(2 * lim.a_max * max(to_end, 0.0)) + 0.02)
        v = min(v, cfg.tight_speed + tight * lim.v_max)
        self.blocked = blocked_ahead(scan, self.radius, cfg.clearance, v, w, lim.a_max)
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
