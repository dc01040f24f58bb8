"""`PathFollower`: drives a differential robot along a polyline of world points.

Shared by every goal-seeking explorer (frontier, SRT, metaheuristic targets). It steers at a carrot on
the path a short way ahead of the robot's projection on it (pure pursuit that follows the polyline, not
its corners cut), turning in place when the heading error is large. Where the laser shows little room
around the robot (a door the plan says it fits) it slows down, steers at a nearer carrot and turns in
place at a smaller heading error, so that it passes where the plan passes. A guard stops forward motion
only when the robot's disc, swept along the command's arc for its stopping distance, would come within
`FollowerConfig.clearance` of a laser return it is approaching: the same geometry as the planners' (a
disc and the walls' surface), so it trips on an imminent collision, not on a wall it slides along.

A rectangular robot (`robotexp.robot.Footprint`) is guarded with its own outline, turning included: its
corners sweep a wider disc than its width, so where a turn in place would bring a corner onto a return
(a door it crosses straight) it turns while creeping forward along the path, or waits.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.planning.grid_planner import simplify
from robotexp.planning.kernels import scan_points_kernel, sweep_blocked_kernel
from robotexp.planning.targets import cell_points
from robotexp.robot import Footprint, LaserScan, Limits, Pose, Twist, wrap_angle

__all__ = ["GRAIN", "PathFollower", "FollowerConfig", "ScanMemory", "blocked_ahead", "drift_blocked", "drift_poses",
           "footprint_blocked", "free_heading",
           "path_points", "roomy_cells", "scan_clearance"]

REACTION = 0.2          # [s] of motion at the commanded speed added to the stopping distance the guard checks
SWEEP_STEP = 0.02       # [m] between the disc positions the guard checks along the arc
GRAZE = 0.005           # [m] a return within reach that the swept disc comes at most this much nearer to is one the
                        # robot slides along (beside it, not ahead): it does not block ...
MIN_GAP = 0.002         # [m] ... unless the disc would come within this of touching it
TIGHT_TURN_RATE = 1.0   # [rad/s] a rectangle's fastest turn where the laser shows little room
BACK_OUT = 0.1          # [m] a rectangle backs out of a tight place only over ground it just drove straight in on
GRAIN = 0.02            # [m] the recent returns a rectangle's guard checks are kept one per square this wide
TURN_STEP = math.radians(3)     # [rad] between the headings the guard checks as a rectangle turns


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
            angles = np.asarray(scan.angles, np.float64)
            _TRIG[:] = [scan.angles, np.cos(angles), np.sin(angles)]
        pts, norms = scan_points_kernel(np.ascontiguousarray(scan.ranges, np.float64), _TRIG[1], _TRIG[2],  # type: ignore[arg-type]
                                        float(scan.offset_x), float(scan.range_max))
        _POINTS[:] = [scan, pts, norms]
    return _POINTS[1], _POINTS[2]          # type: ignore[return-value]


def scan_clearance(scan: LaserScan | None, radius: float, footprint: Footprint | None = None) -> float:
    """[m] from the robot's disc of `radius` (or its rectangular `footprint`) to the nearest laser return
    (inf without one)."""
    pts, norms = _points_norms(scan)
    if len(norms) == 0:
        return math.inf
    if footprint is not None and not footprint.round:
        return float(footprint.distance(pts[:, 0], pts[:, 1]).min())
    return float(norms.min()) - radius


def blocked_ahead(scan: LaserScan | None, radius: float, clearance: float, speed: float, turn: float = 0.0,  # noqa: PLR0913
                  a_max: float = 0.5, footprint: Footprint | None = None, alpha_max: float = 2.0) -> bool:
    """True when driving at (`speed` [m/s], `turn` [rad/s]) would bring the robot's disc of `radius` [m]
    within `clearance` [m] of a laser return it is approaching, before it could stop.

    The disc is swept along the command's arc for the stopping distance speed^2 / (2 `a_max`) plus
    `REACTION` s at `speed` plus `clearance`; a return counts when some position on that arc is nearer
    than radius + clearance and more than `GRAZE` nearer than the disc's centre is now, or within `MIN_GAP`
    of the disc (a wall the robot slides along, or moves away from, does not stop it: a return a few
    degrees ahead of the robot's side, already within radius + clearance, comes a millimetre nearer as the
    robot drives on, and stopping for it left a robot standing for good). Not moving forward never blocks a
    disc. A rectangular `footprint` is swept instead, heading included, so turning in place (stopping angle
    turn^2 / (2 `alpha_max`) plus `REACTION` s of turn) can block too.
    """
    if scan is None:
        return False
    if footprint is not None and not footprint.round:
        if speed <= 0 and turn == 0:
            return False
        return footprint_blocked(_points_norms(scan)[0], footprint, clearance, speed, turn, a_max, alpha_max)
    if speed <= 0:
        return False
    pts, norms = _points_norms(scan)
    return _sweep_blocked(pts, norms, radius, clearance, speed, turn, a_max)


def _sweep_length(speed: float, a_max: float, clearance: float) -> float:
    """[m] how far the guard sweeps the robot along a command at `speed` [m/s]: its stopping distance
    speed^2 / (2 `a_max`), `REACTION` s at `speed`, and `clearance`."""
    return speed * speed / (2.0 * max(a_max, 1e-6)) + speed * REACTION + clearance


def footprint_blocked(pts: npt.NDArray[np.float64], foot: Footprint, clearance: float, speed: float,  # noqa: PLR0913
                      turn: float, a_max: float = 0.5, alpha_max: float = 2.0) -> bool:
    """`blocked_ahead` for a robot of outline `foot` against robot-frame points `pts` (k, 2) [m] (a scan's
    returns, or `ScanMemory.points`): its poses along the command's arc (or its turn in place) for the
    stopping distance (or angle), each checked against the points it is approaching."""
    speed = max(speed, 0.0)
    if len(pts) == 0 or (speed == 0 and turn == 0):
        return False
    reach = foot.swing + clearance
    if speed > 0:
        length = _sweep_length(speed, a_max, clearance)
        k = turn / speed
        steps = max(length / SWEEP_STEP, abs(k) * length / TURN_STEP)   # the corners move as it turns
        s = np.linspace(0.0, length, max(2, int(math.ceil(steps)) + 1))[1:]
        th = k * s
        if abs(k) < 1e-9:
            cx, cy = s, np.zeros_like(s)
        else:
            cx, cy = np.sin(th) / k, (1.0 - np.cos(th)) / k
    else:
        angle = turn * turn / (2.0 * max(alpha_max, 1e-6)) + abs(turn) * REACTION + math.radians(2)
        th = math.copysign(1.0, turn) * np.linspace(0.0, angle, max(2, int(math.ceil(angle / TURN_STEP)) + 1))[1:]
        cx = cy = np.zeros_like(th)
        length = 0.0
    near = np.hypot(pts[:, 0], pts[:, 1]) < length + reach
    if not near.any():
        return False
    return _poses_blocked(pts[near], foot, clearance, cx, cy, th)


def _poses_blocked(pts: npt.NDArray[np.float64], foot: Footprint, clearance: float, x: npt.NDArray[np.float64],
                   y: npt.NDArray[np.float64], th: npt.NDArray[np.float64]) -> bool:
    """True when the outline `foot` at one of the robot-frame poses (`x`, `y`, `th`) comes within `clearance`
    [m] of a point of `pts` (k, 2) that it is nearer to than the outline is now (the robot approaches it)."""
    d0 = foot.distance(pts[:, 0], pts[:, 1])
    c, sn = np.cos(th)[None, :], np.sin(th)[None, :]
    dx, dy = pts[:, None, 0] - x[None, :], pts[:, None, 1] - y[None, :]
    d = foot.distance(c * dx + sn * dy, -sn * dx + c * dy)
    return bool(((d < clearance) & (d < d0[:, None] - 1e-4)).any())


DRIFT_STEP = 0.04       # [s] between the poses `drift_blocked` predicts (1.2 cm at 0.3 m/s)
DRIFT_SPEED = 0.05      # [m/s] below this the robot's motion is the command's (the arc's guard alone)
DRIFT_TURN = 0.01       # [rad] heading the robot's turn rate may gain on the command's before it is swept apart


def _ramp(start: float, target: float, rate: float, t: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """A value going from `start` toward `target` at `rate` per second, at the times `t` [s]."""
    return start + np.clip(target - start, -rate * t, rate * t)


def drift_poses(v0: float, w0: float, v: float, w: float, a_max: float, alpha_max: float
                ) -> npt.NDArray[np.float64]:
    """(k, 3) robot-frame poses (x, y, heading) the robot passes through, one per `DRIFT_STEP`, when, moving
    at (`v0`, `w0`) now, it is told (`v`, `w`) for `REACTION` s and then to stop: speed and turn rate change
    at most at `a_max` and `alpha_max` (the turn rate keeps going toward `w` while the speed falls to 0).
    The robot's own motion, not the command's arc: a robot swinging left at 1.5 rad/s told to turn right
    still swings left for most of a second."""
    a, alpha = max(a_max, 1e-6), max(alpha_max, 1e-6)
    v0 = max(v0, 0.0)
    react = np.arange(1, int(round(REACTION / DRIFT_STEP)) + 1, dtype=np.float64) * DRIFT_STEP
    speed = _ramp(v0, max(v, 0.0), a, react)
    stop = np.arange(1, int(math.ceil(speed[-1] / (a * DRIFT_STEP))) + 1) * DRIFT_STEP
    speed = np.concatenate([speed, np.maximum(speed[-1] - a * stop, 0.0)])
    t = np.arange(len(speed) + 1, dtype=np.float64) * DRIFT_STEP
    turn = _ramp(w0, w, alpha, t)
    heading = np.cumsum(turn[1:] + turn[:-1]) * (DRIFT_STEP / 2.0)          # the trapezoid rule
    step = (speed + np.concatenate([[v0], speed[:-1]])) * (DRIFT_STEP / 2.0)
    mid = heading - (turn[:-1] + 3.0 * turn[1:]) * (DRIFT_STEP / 8.0)        # the heading half a step back
    return np.column_stack([np.cumsum(step * np.cos(mid)), np.cumsum(step * np.sin(mid)), heading])


def drift_blocked(pts: npt.NDArray[np.float64], foot: Footprint, clearance: float, v0: float, w0: float,  # noqa: PLR0913
                  v: float, w: float, a_max: float, alpha_max: float) -> bool:
    """True when the motion `drift_poses` predicts brings the outline `foot` within `clearance` [m] of a
    robot-frame point of `pts` (k, 2) it is approaching (nearer than the outline is now); False while the
    robot moves slower than `DRIFT_SPEED`, or when its turn rate meets the command's within `DRIFT_TURN`
    of heading ((w0 - w)^2 / 2 alpha_max) and it is not faster than told: its motion is then the arc's that
    `footprint_blocked` sweeps."""
    if len(pts) == 0 or v0 < DRIFT_SPEED:
        return False
    if (w0 - w) ** 2 < 2.0 * max(alpha_max, 1e-6) * DRIFT_TURN and v0 <= v + DRIFT_SPEED:
        return False        # the turn rate meets the command's within DRIFT_TURN of heading: the arc's motion
    # the farthest it can go: REACTION s at the faster speed, then its stopping distance
    top = max(v0, v)
    travel = top * REACTION + top * top / (2.0 * max(a_max, 1e-6)) + DRIFT_STEP * top
    near = np.hypot(pts[:, 0], pts[:, 1]) < travel + foot.swing + clearance
    if not near.any():
        return False
    poses = drift_poses(v0, w0, v, w, a_max, alpha_max)
    return _poses_blocked(pts[near], foot, clearance, poses[:, 0], poses[:, 1], poses[:, 2])


def _sweep_blocked(pts: npt.NDArray[np.float64], norms: npt.NDArray[np.float64], radius: float, clearance: float,
                   speed: float, turn: float, a_max: float) -> bool:
    """`blocked_ahead` on the robot-frame points `pts` (k, 2) [m] at distances `norms` (k,), for speed > 0."""
    length = _sweep_length(speed, a_max, clearance)
    steps = max(1, int(math.ceil(length / SWEEP_STEP)))
    return bool(sweep_blocked_kernel(pts, norms, radius, clearance, length, turn / speed, steps, GRAZE, MIN_GAP))


def sweep_blocked_reference(pts: npt.NDArray[np.float64], norms: npt.NDArray[np.float64], radius: float,
                            clearance: float, speed: float, turn: float, a_max: float) -> bool:
    """`_sweep_blocked` in numpy (the kernel's reference)."""
    length = _sweep_length(speed, a_max, clearance)
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
    return bool(((d < reach) & ((d < d0[:, None] - GRAZE) | (d < radius + MIN_GAP))).any())


def map_points(grid: OccupancyGrid, x: float, y: float, reach: float) -> npt.NDArray[np.float64]:
    """(k, 2) world points [m] of the obstacles `grid` holds within about `reach` [m] of (x, y): the corners
    of the box of laser endpoints in each occupied cell (`OccupancyGrid.hit_box`; a cell with none: its
    own corners). What the laser saw of the walls round the robot, however long ago."""
    geo = grid.geo
    r, c = geo.cell_of(x, y)
    k = int(math.ceil(reach / geo.cell)) + 1
    r0, c0, r1, c1 = max(r - k, 0), max(c - k, 0), min(r + k + 1, geo.rows), min(c + k + 1, geo.cols)
    if r1 <= r0 or c1 <= c0:
        return np.zeros((0, 2))
    win = grid.window(r0, r1, c0, c1)
    rr, cc = np.nonzero(win.occupied())
    if len(rr) == 0:
        return np.zeros((0, 2))
    box = win.hit_box[rr, cc].astype(np.float64) / 255.0
    none = box[:, 0] > box[:, 1]
    box[none] = (0.0, 1.0, 0.0, 1.0)
    x0 = geo.origin_x + (c0 + cc) * geo.cell
    y0 = geo.origin_y + (r0 + rr) * geo.cell
    xs = x0[:, None] + geo.cell * box[:, [0, 1, 0, 1]]
    ys = y0[:, None] + geo.cell * box[:, [2, 2, 3, 3]]
    return np.column_stack([xs.ravel(), ys.ravel()])


class ScanMemory:
    """The laser returns near the robot from its last `scans` scans, kept in the world frame: a forward
    laser does not see what a rectangle's rear corners swing into as it turns, but it saw it a moment ago.

    Args:
        reach: [m] returns farther than this from the robot are not kept.
        scans: how many scans are kept.
    """

    def __init__(self, reach: float = 1.0, scans: int = 150) -> None:
        self.reach = reach
        self.scans = scans
        self._kept: list[npt.NDArray[np.float64]] = []
        self._last: LaserScan | None = None
        self._merged: npt.NDArray[np.float64] | None = None
        self.grid: OccupancyGrid | None = None
        # ((x, y, id of the map, its scans), the map's wall points there): `_map_walls`
        self._walls: tuple[tuple[float, float, int, int], npt.NDArray[np.float64]] | None = None

    def _map_walls(self, pose: Pose) -> npt.NDArray[np.float64]:
        """`map_points` of the map near `pose`, gathered once per position and map update (the guard asks
        for several commands at one pose)."""
        if self.grid is None:
            return np.zeros((0, 2))
        key = (pose.x, pose.y, id(self.grid), self.grid.scans)
        if self._walls is None or self._walls[0] != key:
            self._walls = (key, map_points(self.grid, pose.x, pose.y, self.reach))
        return self._walls[1]

    def see_map(self, grid: OccupancyGrid | None) -> None:
        """Check against the obstacles of `grid` too (`map_points`): it remembers what the scans kept here
        have forgotten, behind the robot."""
        self.grid = grid

    def note(self, pose: Pose, scan: LaserScan | None) -> None:
        """Keep the returns of `scan`, read at `pose`, within `reach` (a scan noted twice is kept once)."""
        if scan is None or scan is self._last:
            return
        self._last = scan
        pts, norms = _points_norms(scan)
        near = pts[norms < self.reach]
        c, s = math.cos(pose.theta), math.sin(pose.theta)
        world = np.column_stack([pose.x + c * near[:, 0] - s * near[:, 1], pose.y + s * near[:, 0] + c * near[:, 1]])
        self._kept.append(world)
        del self._kept[:-self.scans]
        self._merged = None

    def points(self, pose: Pose) -> npt.NDArray[np.float64]:
        """(k, 2) [m] the kept returns within `reach` of `pose`, in the robot frame at `pose`."""
        fixed = self._map_walls(pose)
        if not self._kept and not len(fixed):
            return np.zeros((0, 2))
        if self._merged is None and self._kept:        # one point per GRAIN square: the same wall seen scan after scan
            world = np.concatenate(self._kept[::-1])
            keys = np.floor(world / GRAIN).astype(np.int64)
            _, first = np.unique(keys[:, 0] * (1 << 32) + keys[:, 1], return_index=True)
            self._merged = world[first]
        world = fixed if self._merged is None else np.concatenate([self._merged, fixed])
        dx, dy = world[:, 0] - pose.x, world[:, 1] - pose.y
        near = dx * dx + dy * dy < self.reach * self.reach
        c, s = math.cos(pose.theta), math.sin(pose.theta)
        dx, dy = dx[near], dy[near]
        return np.column_stack([c * dx + s * dy, -s * dx + c * dy])

    def clear(self) -> None:
        """Forget every return."""
        self._kept = []
        self._last = None
        self._merged = None
        self._walls = None


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
                geo: GridGeometry, offset: tuple[int, int] = (0, 0),
                points: npt.NDArray[np.uint8] | None = None) -> npt.NDArray[np.float64]:
    """The world points [m] (k, 2) of a planner path: the points of `cells` a plan passes through (their
    centres, or the points `points` names: `cell_points`), string-pulled across the `roomy_cells` of
    `passable` whose point is their centre (every cell kept where the path runs through tight places).

    Args:
        cells: (n, 2) int (row, col) cells of a path, consecutive ones 8-neighbours (as from `astar`).
        passable: (rows, cols) bool the path was planned on.
        geo: the grid's geometry.
        offset: (row, col) of `passable`'s cell (0, 0) in `geo` (a window of the grid, as
            `OccupancyGrid.window`); `cells` are the window's.
        points: (rows, cols) uint8 the point of each cell of the window (`plan_costs`' `points`), or None
            (the centres).

    Returns:
        (k, 2) float64, k <= n.
    """
    passable = np.asarray(passable, dtype=bool)
    if points is not None:
        passable = passable & (points == 0)
    kept = simplify(cells, roomy_cells(passable)) if len(cells) > 2 else cells
    return cell_points(geo, kept, points, offset)


class PathFollower:
    """Follows one path at a time; `twist()` returns the command and `done` says when it arrived."""

    def __init__(self, limits: Limits, radius: float, config: FollowerConfig | None = None,
                 footprint: Footprint | None = None, memory: ScanMemory | None = None) -> None:
        self.limits = limits
        self.radius = radius
        self.footprint = footprint if footprint is not None and not footprint.round else None   # None: a disc
        self._disc = Footprint.disc(radius)
        # the returns a rectangle's guard checks (an explorer that sees every scan may share its own)
        self.memory = memory or ScanMemory(reach=(self.footprint.swing if self.footprint else radius) + 0.6)
        self._pose = Pose(0.0, 0.0, 0.0)
        self._trail: deque[Pose] = deque(maxlen=100)      # a rectangle's own recent poses (`_came_straight`)
        self.config = config or FollowerConfig()
        self.path: npt.NDArray[np.float64] = np.zeros((0, 2))
        self._xy: list[tuple[float, float]] = []
        self._after: list[float] = []
        self._index = 0
        self.done = True
        self.blocked = False
        self._velocity: Twist | None = None     # the robot's own velocity at the last `twist`, when told

    def set_path(self, points: npt.NDArray[np.float64]) -> None:
        """Follow `points` (k, 2) [m] from the first to the last."""
        self.path = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        self._xy = [(float(x), float(y)) for x, y in self.path]      # plain floats: the carrot's loop is Python
        steps = np.hypot(*np.diff(self.path, axis=0).T) if len(self.path) > 1 else np.zeros(0)
        self._after = np.concatenate([np.cumsum(steps[::-1])[::-1], [0.0]]).tolist()   # path left after point i
        self._index = 0
        self.done = len(self.path) == 0

    def follow_cells(self, cells: npt.NDArray[np.integer], passable: npt.NDArray[np.bool_], geo: GridGeometry,
                     start: tuple[float, float], offset: tuple[int, int] = (0, 0),
                     points: npt.NDArray[np.uint8] | None = None) -> None:
        """Follow a planner path of cells (`path_points`, with its `offset` and `points`), its first point
        moved to `start` (x, y) [m], the robot's exact position."""
        pts = path_points(cells, passable, geo, offset, points)
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

    def twist(self, pose: Pose, scan: LaserScan | None = None, velocity: Twist | None = None) -> Twist:
        """The command that follows the path from `pose`; zero once done. With the robot's `velocity` now
        (`RobotState.velocity`) the guard also sweeps the motion the robot will make from it (`drift_blocked`),
        not only the command's arc."""
        cfg = self.config
        self._velocity = velocity
        if self.done:
            return Twist.ZERO
        end = self.path[-1]
        to_end = math.hypot(end[0] - pose.x, end[1] - pose.y)
        if to_end < cfg.goal_tolerance:
            self.done = True
            return Twist.ZERO
        self._note(pose, scan)
        room = scan_clearance(scan, self.radius, self.footprint)
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
        if self.footprint is not None and tight < 1.0:
            # a rectangle turning where room is tight turns slowly: its guard sweeps the angle it needs to
            # stop (w^2 / 2 alpha), and a fast turn's sweeps a whole turn
            w = max(-TIGHT_TURN_RATE, min(TIGHT_TURN_RATE, w))
        if abs(err) > cfg.tight_turn + tight * (cfg.turn_in_place - cfg.tight_turn):
            if self.footprint is None or not self._blocked(scan, 0.0, w):
                self.blocked = False
                return Twist(0.0, w)
            return self._squeeze(scan, w, to_end)
        v = lim.v_max * math.cos(err) * min(1.0, to_end / 0.5 + 0.2)
        # braking distance v^2 / 2a must fit in what is left of the path
        v = min(v, math.sqrt(2 * lim.a_max * max(to_end, 0.0)) + 0.02)
        v = min(v, cfg.tight_speed + tight * lim.v_max)
        self.blocked = self._blocked(scan, v, w)
        if self.blocked:
            if self.footprint is None or not self._blocked(scan, 0.0, w):
                return Twist(0.0, w)
            return self._squeeze(scan, w, to_end)
        return Twist(max(0.0, v), w)

    def _squeeze(self, scan: LaserScan | None, w: float, to_end: float) -> Twist:
        """A rectangle whose corner would touch turning in place: turn while creeping forward, else turn
        the other way round, else creep straight out of the narrow place, else back out over the ground it
        came straight in on (a forward laser does not see behind), else wait (`blocked`)."""
        v = min(self.config.tight_speed, math.sqrt(2 * self.limits.a_max * max(to_end, 0.0)))
        back = Twist(-self.config.tight_speed, 0.0) if self._came_straight() else Twist.ZERO
        for command in (Twist(v, w), Twist(0.0, -w), Twist(v, 0.0), back):
            if command != Twist.ZERO and not self._blocked(scan, command.v, command.w):
                self.blocked = False
                return command
        self.blocked = True
        return Twist.ZERO

    def _came_straight(self) -> bool:
        """True when the ground it would back over is known: the map (`ScanMemory.see_map`) holds every cell
        under the body moved BACK_OUT m back as free, or the robot's own recent poses include one BACK_OUT m
        or more straight behind it, at its heading (the body stood there)."""
        p = self._pose
        grid = self.memory.grid
        if grid is not None and self.footprint is not None:
            f = self.footprint
            u, v = np.meshgrid(np.linspace(-f.length / 2 - BACK_OUT, f.length / 2, 12),
                               np.linspace(-f.width / 2, f.width / 2, 6))
            c, s = math.cos(p.theta), math.sin(p.theta)
            cells = np.column_stack([(p.x + c * u - s * v).ravel(), (p.y + s * u + c * v).ravel()])
            rc = np.floor((cells - [grid.geo.origin_x, grid.geo.origin_y]) / grid.geo.cell).astype(np.int64)
            lo, hi = rc.min(axis=0), rc.max(axis=0)
            if (lo >= 0).all() and hi[1] < grid.geo.rows and hi[0] < grid.geo.cols:
                free = grid.window(int(lo[1]), int(hi[1]) + 1, int(lo[0]), int(hi[0]) + 1).free()
                if free[rc[:, 1] - lo[1], rc[:, 0] - lo[0]].all():
                    return True
        c, s = math.cos(p.theta), math.sin(p.theta)
        for q in self._trail:
            dx, dy = q.x - p.x, q.y - p.y
            behind, aside = -(c * dx + s * dy), abs(-s * dx + c * dy)
            if behind >= BACK_OUT and aside < 0.02 and abs(wrap_angle(q.theta - p.theta)) < math.radians(5):
                return True
        return False

    def _note(self, pose: Pose, scan: LaserScan | None) -> None:
        self._pose = pose
        if self.footprint is not None:
            self.memory.note(pose, scan)
            self._trail.append(pose)

    def _blocked(self, scan: LaserScan | None, v: float, w: float) -> bool:
        """The guard (`blocked_ahead`) for the command (v, w) with this robot's outline; a rectangle's
        against the returns of its recent scans too (`ScanMemory`)."""
        lim = self.limits
        if self.footprint is None:
            if blocked_ahead(scan, self.radius, self.config.clearance, v, w, lim.a_max):
                return True
            return self._drifts(_points_norms(scan)[0] if scan is not None else np.zeros((0, 2)),
                                self._disc, self.config.clearance, v, w)
        pts = self.memory.points(self._pose)
        if v < 0:       # backing up is driving forward in the mirror image (x -> -x, turns reversed)
            return footprint_blocked(pts * np.array([-1.0, 1.0]), self.footprint, self.config.clearance + GRAIN,
                                     -v, -w, lim.a_max, lim.alpha_max)
        # the returns are kept one per GRAIN square: a corner may lie that much between them
        if footprint_blocked(pts, self.footprint, self.config.clearance + GRAIN, v, w, lim.a_max, lim.alpha_max):
            return True
        return self._drifts(pts, self.footprint, self.config.clearance + GRAIN, v, w)

    def _drifts(self, pts: npt.NDArray[np.float64], foot: Footprint, clearance: float, v: float, w: float) -> bool:
        """`drift_blocked` from the robot's velocity at this `twist` (False when it was not told)."""
        vel = self._velocity
        if vel is None:
            return False
        lim = self.limits
        return drift_blocked(pts, foot, clearance, vel.v, vel.w, v, w, lim.a_max, lim.alpha_max)

    def turn_to(self, pose: Pose, heading: float, scan: LaserScan | None = None) -> tuple[Twist, bool]:
        """Turn in place to `heading` [rad]; returns the command and whether it is over: reached (5 deg),
        or, for a rectangular robot with `scan`, as far as it can turn without a corner touching."""
        self._note(pose, scan)
        err = wrap_angle(heading - pose.theta)
        if abs(err) < math.radians(5):
            return Twist.ZERO, True
        w = max(-self.limits.w_max, min(self.limits.w_max, self.config.k_turn * err))
        if self.footprint is not None:
            w = max(-TIGHT_TURN_RATE, min(TIGHT_TURN_RATE, w))
        if self.footprint is not None and self._blocked(scan, 0.0, w):
            return Twist.ZERO, True
        return Twist(0.0, w), False
