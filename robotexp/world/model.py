"""`World`: the 2D ground truth of an environment (static obstacles, dynamic ones, start poses).

Static obstacles are oriented boxes and discs in metres; every loader (built-in worlds, MobileSim
`.map`, ROS map_server) produces these, and the simulator and ground-truth rasteriser consume them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from robotexp.errors import WorldError
from robotexp.robot import Pose

__all__ = ["World", "Mover", "segment_box", "BOX_COLUMNS"]

BOX_COLUMNS = ("cx", "cy", "half_x", "half_y", "yaw")   # [m, m, m, m, rad]


def segment_box(x0: float, y0: float, x1: float, y1: float, thickness: float) -> tuple[float, ...]:
    """The oriented box (cx, cy, half_x, half_y, yaw) of a wall from (x0, y0) to (x1, y1) [m].

    The box reaches `thickness`/2 past each end so walls meeting at a corner close it.
    """
    length = math.hypot(x1 - x0, y1 - y0)
    yaw = math.atan2(y1 - y0, x1 - x0) if length > 0 else 0.0
    return ((x0 + x1) / 2, (y0 + y1) / 2, length / 2 + thickness / 2, thickness / 2, yaw)


@dataclass(frozen=True)
class Mover:
    """A dynamic obstacle (a walking person): a disc of `radius` [m] moving at `speed` [m/s]
    along the polyline `path` (k, 2) [m], back and forth when `loop` is False, else round."""

    radius: float
    speed: float
    path: npt.NDArray[np.float64]
    loop: bool = False
    height: float = 1.7

    def position(self, t: float) -> tuple[float, float]:
        """Where the mover is at time `t` [s]."""
        pts = self.path if not self.loop else np.vstack([self.path, self.path[:1]])
        seg = np.hypot(*np.diff(pts, axis=0).T)
        total = float(seg.sum())
        if total == 0 or self.speed == 0:
            return float(pts[0, 0]), float(pts[0, 1])
        s = (self.speed * t) % (total if self.loop else 2 * total)
        if not self.loop and s > total:
            s = 2 * total - s
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        i = min(int(np.searchsorted(cum, s, side="right")) - 1, len(seg) - 1)
        f = (s - cum[i]) / seg[i] if seg[i] > 0 else 0.0
        p = pts[i] + f * (pts[i + 1] - pts[i])
        return float(p[0]), float(p[1])


@dataclass
class World:
    """The ground truth of an environment.

    `boxes` is (n, 5) float64 [cx, cy, half_x, half_y, yaw]; `discs` is (m, 3) [cx, cy, r];
    `bounds` is (xmin, ymin, xmax, ymax) [m] and encloses every obstacle; `poses` are named start
    poses in insertion order; `goals` are named waypoint lists for goal-following explorers.
    `declared` is the area a map file declares (a `.map`'s MinPos..MaxPos and LineMinPos..LineMaxPos,
    a ROS map's image extent), None when it declares none. `collision` says how the simulator tests
    the robot against the static obstacles: "bodies" (one pybullet body per obstacle, the built-in
    worlds) or "index" (an exact disc-to-shape test over the ray caster's buckets, no pybullet
    body: maps of tens of thousands of boxes load in seconds).
    """

    name: str
    boxes: npt.NDArray[np.float64]
    discs: npt.NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    bounds: tuple[float, float, float, float] | None = None
    poses: dict[str, Pose] = field(default_factory=dict)
    movers: list[Mover] = field(default_factory=list)
    goals: dict[str, list[tuple[float, float]]] = field(default_factory=dict)
    source: str = "builtin"
    description: str = ""
    home: Pose | None = None             # a .map file's RobotHome cairn
    declared: tuple[float, float, float, float] | None = None
    collision: str = "bodies"

    def __post_init__(self) -> None:
        self.boxes = np.asarray(self.boxes, dtype=np.float64).reshape(-1, 5)
        self.discs = np.asarray(self.discs, dtype=np.float64).reshape(-1, 3)
        if self.collision not in ("bodies", "index"):
            raise WorldError(f"world {self.name!r}: collision must be 'bodies' or 'index', got {self.collision!r}")
        if self.bounds is None:
            self.bounds = self.obstacle_bounds()

    def obstacle_bounds(self) -> tuple[float, float, float, float]:
        """The axis-aligned box [m] around every static obstacle."""
        xs: list[float] = []
        ys: list[float] = []
        for cx, cy, hx, hy, yaw in self.boxes:
            ex = abs(hx * math.cos(yaw)) + abs(hy * math.sin(yaw))
            ey = abs(hx * math.sin(yaw)) + abs(hy * math.cos(yaw))
            xs += [cx - ex, cx + ex]
            ys += [cy - ey, cy + ey]
        for cx, cy, r in self.discs:
            xs += [cx - r, cx + r]
            ys += [cy - r, cy + r]
        if not xs:
            raise WorldError(f"world {self.name!r} ({self.source}): it has no obstacles at all")
        return (float(min(xs)), float(min(ys)), float(max(xs)), float(max(ys)))

    @property
    def size(self) -> tuple[float, float]:
        """(width, height) [m] of the bounds."""
        assert self.bounds is not None
        return (self.bounds[2] - self.bounds[0], self.bounds[3] - self.bounds[1])

    def pose(self, name: str) -> Pose:
        """The named start pose. Raises WorldError listing the names this world has."""
        try:
            return self.poses[name]
        except KeyError:
            names = ", ".join(self.poses) or "none"
            raise WorldError(f"world {self.name!r} has no start pose {name!r} (it has: {names})") from None
