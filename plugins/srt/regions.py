"""Local safe regions of the Sensor-based Random Tree (SRT) and their geometry (thesis §3.2, §4.1.1).

A local safe region S(q) is star-shaped around the pose q where it was perceived: a point p is in
S when its distance to q is below RADIUS(S, theta), theta the world bearing of p from q. Three
perceptions (thesis Fig. 3.7):

- `BallRegion` (SRT-Ball): a disc whose radius is the smallest range read around the robot.
- `StarRegion` (SRT-Star): cones between adjacent sonar axes, each with the smallest reading of
  the two transducers bounding it (the sensors that take part in the cone).
- `PolygonRegion` (SRT-Laser): the polygon of the laser end points, its boundary split into
  frontier vertices (beams at maximum range) and obstacle vertices (Freda & Oriolo 2005).

Angles are world angles [rad]; positions world coordinates [m].
"""

from __future__ import annotations

import copy
import math
from abc import ABC, abstractmethod
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from robotexp import ConfigError
from robotexp.mapping.geometry import GridGeometry

__all__ = ["SafeRegion", "BallRegion", "StarRegion", "PolygonRegion", "SweepBuffer", "frontier_arcs",
           "segment_clearance", "ray_reach", "reachable_points", "clearance_map", "in_sight", "sector_intervals",
           "star_from_sonar", "star_from_sweep"]

TAU = 2.0 * math.pi
Array = npt.NDArray[np.float64]


class SafeRegion(ABC):
    """A star-shaped region around (x, y) [m], defined by its radius function RADIUS(S, theta)."""

    x: float
    y: float

    @abstractmethod
    def radius(self, theta: Array) -> Array:
        """RADIUS(S, theta): distance [m] from the centre to the boundary along world angles `theta`
        [rad], any shape; returns the same shape."""

    @abstractmethod
    def boundary(self) -> Array:
        """The boundary as a closed polygon, (k, 2) float64 world points [m] in angular order."""

    @abstractmethod
    def obstacle_points(self) -> Array:
        """World points [m] (k, 2) known to lie on obstacles (may be empty)."""

    @property
    @abstractmethod
    def reach(self) -> float:
        """The largest radius [m] of the region."""

    def contains(self, points: Array, margin: float = 0.0) -> npt.NDArray[np.bool_]:
        """Bool (k,): which of the (k, 2) world points [m] lie strictly inside the region, its radius
        grown by `margin` [m]."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        dx, dy = p[:, 0] - self.x, p[:, 1] - self.y
        d = np.hypot(dx, dy)
        return d < self.radius(np.arctan2(dy, dx)) + margin

    def moved(self, dx: float, dy: float, dtheta: float) -> SafeRegion:
        """A copy moved rigidly, as loop closure moves the poses it was perceived from: every point p of it
        goes to R(dtheta) p + (dx, dy) [m] (its centre, boundary and obstacle points; its directions turn by
        `dtheta` [rad])."""
        out = copy.copy(self)
        c, s = math.cos(dtheta), math.sin(dtheta)
        out.x, out.y = c * self.x - s * self.y + dx, s * self.x + c * self.y + dy
        out._turn(dtheta, lambda p: np.column_stack([c * p[:, 0] - s * p[:, 1] + dx, s * p[:, 0] + c * p[:, 1] + dy]))
        return out

    @abstractmethod
    def _turn(self, dtheta: float, move: Callable[[Array], Array]) -> None:
        """`moved`'s part for the subclass's own angles [rad] and points [m] (`move` maps (k, 2) points)."""

    def mask(self, geo: GridGeometry) -> npt.NDArray[np.bool_]:
        """Bool (rows, cols): the cells of `geo` whose centre lies inside the region."""
        out = np.zeros((geo.rows, geo.cols), dtype=bool)
        r = self.reach
        c0 = max(int(math.floor((self.x - r - geo.origin_x) / geo.cell)), 0)
        c1 = min(int(math.ceil((self.x + r - geo.origin_x) / geo.cell)) + 1, geo.cols)
        r0 = max(int(math.floor((self.y - r - geo.origin_y) / geo.cell)), 0)
        r1 = min(int(math.ceil((self.y + r - geo.origin_y) / geo.cell)) + 1, geo.rows)
        if c1 <= c0 or r1 <= r0:
            return out
        cx = geo.origin_x + (np.arange(c0, c1) + 0.5) * geo.cell
        cy = geo.origin_y + (np.arange(r0, r1) + 0.5) * geo.cell
        gx, gy = np.meshgrid(cx, cy)
        inside = self.contains(np.column_stack([gx.ravel(), gy.ravel()]))
        out[r0:r1, c0:c1] = inside.reshape(r1 - r0, c1 - c0)
        return out


class BallRegion(SafeRegion):
    """SRT-Ball: the disc of radius `r` [m] around (x, y) [m]; `obstacle` is the nearest hit, if any."""

    def __init__(self, x: float, y: float, r: float, obstacle: tuple[float, float] | None = None) -> None:
        if not r >= 0:
            raise ConfigError(f"srt ball region: radius must be >= 0 m, got {r}")
        self.x, self.y, self.r = float(x), float(y), float(r)
        self._obstacle = np.zeros((0, 2)) if obstacle is None else np.array([obstacle], dtype=np.float64)

    def radius(self, theta: Array) -> Array:
        """The constant radius [m], shaped like `theta`."""
        return np.full(np.shape(theta), self.r)

    def _turn(self, dtheta: float, move: Callable[[Array], Array]) -> None:
        self._obstacle = move(self._obstacle)

    def boundary(self) -> Array:
        """The circle as a 360-gon (k, 2) [m]."""
        a = np.linspace(-math.pi, math.pi, 360, endpoint=False)
        return np.column_stack([self.x + self.r * np.cos(a), self.y + self.r * np.sin(a)])

    def obstacle_points(self) -> Array:
        """The nearest obstacle point (0 or 1 rows)."""
        return self._obstacle

    @property
    def reach(self) -> float:
        """The radius [m]."""
        return self.r


class StarRegion(SafeRegion):
    """SRT-Star: cones around (x, y) [m]; cone i spans world angles [edges[i], edges[i+1]) (cyclic)
    with radius `radii[i]` [m].

    Args:
        x, y: centre [m].
        edges: (k,) strictly increasing world angles [rad] within one turn (edges[-1] - edges[0] < 2 pi);
            the last cone wraps from edges[-1] round to edges[0].
        radii: (k,) cone radii [m], >= 0.
        echoes: (j, 2) world points [m] where the sonar heard an obstacle.
        walls: (k,) bool, True where the cone ends at the arc of a reading that heard an echo (an
            obstacle lies about there), False where it ends at a sector's side, at the range
            maximum or at the robot's disc (unknown space beyond). None: all False.
    """

    def __init__(self, x: float, y: float, edges: Array, radii: Array, echoes: Array | None = None,
                 walls: npt.NDArray[np.bool_] | None = None) -> None:
        e = np.asarray(edges, dtype=np.float64).ravel()
        r = np.asarray(radii, dtype=np.float64).ravel()
        if e.shape != r.shape or e.size < 1 or np.any(np.diff(e) <= 0) or e[-1] - e[0] >= TAU or np.any(r < 0):
            raise ConfigError("srt star region: edges must be strictly increasing within one turn and "
                              f"radii >= 0 of the same length, got {e.size} edges and {r.size} radii")
        self.x, self.y = float(x), float(y)
        self.edges, self.radii = e, r
        self._echoes = np.zeros((0, 2)) if echoes is None else np.asarray(echoes, dtype=np.float64).reshape(-1, 2)
        self._boundary: Array | None = None
        self.walls = np.zeros(e.size, dtype=bool) if walls is None else np.asarray(walls, dtype=bool).ravel()
        if self.walls.shape != e.shape:
            raise ConfigError(f"srt star region: need one wall flag per cone, got {self.walls.size} for {e.size}")

    def cone_of(self, theta: Array) -> npt.NDArray[np.intp]:
        """Index of the cone holding each world angle of `theta` [rad]."""
        rel = np.mod(np.asarray(theta, dtype=np.float64) - self.edges[0], TAU)
        return np.searchsorted(self.edges - self.edges[0], rel, side="right") - 1

    def radius(self, theta: Array) -> Array:
        """The radius [m] of the cone each angle falls in."""
        return self.radii[self.cone_of(theta)]

    def _turn(self, dtheta: float, move: Callable[[Array], Array]) -> None:
        self.edges = self.edges + dtheta
        self._echoes = move(self._echoes)
        self._boundary = None

    def boundary(self) -> Array:
        """Arcs sampled every <= 2 deg, joined by the radial steps between cones (k, 2) [m]; computed
        once (read-only: the way checks of a node ask for it at every try)."""
        if self._boundary is None:
            ends = np.append(self.edges[1:], self.edges[0] + TAU)
            n = np.maximum(2, np.ceil((ends - self.edges) / math.radians(2)).astype(np.intp) + 1)
            cone = np.repeat(np.arange(n.size), n)
            last = np.cumsum(n) - 1
            i = np.arange(int(n.sum())) - np.repeat(last - n + 1, n)
            # np.linspace(a0, a1, n) of each cone: i * step + a0, the last point exactly a1
            a = i * ((ends - self.edges) / (n - 1))[cone] + self.edges[cone]
            a[last] = ends
            r = self.radii[cone]
            self._boundary = np.column_stack([self.x + r * np.cos(a), self.y + r * np.sin(a)])
            self._boundary.flags.writeable = False
        return self._boundary

    def obstacle_points(self) -> Array:
        """The sonar echoes (j, 2) [m]."""
        return self._echoes

    @property
    def reach(self) -> float:
        """The largest cone radius [m]."""
        return float(self.radii.max())


class PolygonRegion(SafeRegion):
    """SRT-Laser: the star-shaped polygon of laser end points around (x, y) [m].

    Args:
        x, y: centre [m] (where the scans were taken).
        angles: (n,) strictly increasing world angles [rad] of the vertices within one turn, n >= 3,
            consecutive vertices less than pi apart (also across the wrap).
        ranges: (n,) finite vertex distances [m] from the centre, > 0.
        frontier: (n,) bool, True where the beam reached the maximum range (no obstacle seen).
    """

    def __init__(self, x: float, y: float, angles: Array, ranges: Array, frontier: npt.NDArray[np.bool_]) -> None:
        a = np.asarray(angles, dtype=np.float64).ravel()
        r = np.asarray(ranges, dtype=np.float64).ravel()
        f = np.asarray(frontier, dtype=bool).ravel()
        if not (a.shape == r.shape == f.shape) or a.size < 3:
            raise ConfigError(f"srt polygon region: need >= 3 vertices with as many ranges and frontier "
                              f"flags, got {a.size}, {r.size}, {f.size}")
        gaps = np.diff(np.append(a, a[0] + TAU))
        if np.any(gaps <= 0) or np.any(gaps >= math.pi) or not np.all(np.isfinite(r)) or np.any(r <= 0):
            raise ConfigError("srt polygon region: vertex angles must increase within one turn by steps "
                              "< pi and ranges must be finite and > 0")
        self.x, self.y = float(x), float(y)
        self.angles, self.ranges, self.frontier = a, r, f

    def radius(self, theta: Array) -> Array:
        """Distance [m] along `theta` to the polygon edge between the two vertices bracketing it.

        For vertices (phi_i, r_i), (phi_j, r_j) and a ray at theta between them, the ray meets the
        edge at r_i r_j sin(phi_j - phi_i) / (r_i sin(theta - phi_i) + r_j sin(phi_j - theta)).
        """
        th = np.asarray(theta, dtype=np.float64)
        rel = np.mod(th - self.angles[0], TAU)
        i = np.searchsorted(self.angles - self.angles[0], rel, side="right") - 1
        j = (i + 1) % self.angles.size
        pi_, pj = self.angles[i], self.angles[j] + np.where(j == 0, TAU, 0.0)
        t = self.angles[0] + rel
        ri, rj = self.ranges[i], self.ranges[j]
        return np.asarray(ri * rj * np.sin(pj - pi_) / (ri * np.sin(t - pi_) + rj * np.sin(pj - t)))

    def _turn(self, dtheta: float, move: Callable[[Array], Array]) -> None:
        self.angles = self.angles + dtheta

    def vertices(self) -> Array:
        """The vertices (n, 2) [m]."""
        return np.column_stack([self.x + self.ranges * np.cos(self.angles),
                                self.y + self.ranges * np.sin(self.angles)])

    def boundary(self) -> Array:
        """The vertices (n, 2) [m]."""
        return self.vertices()

    def obstacle_points(self) -> Array:
        """The vertices where a beam hit something (k, 2) [m]."""
        return self.vertices()[~self.frontier]

    @property
    def reach(self) -> float:
        """The largest vertex range [m]."""
        return float(self.ranges.max())


def frontier_arcs(flags: npt.NDArray[np.bool_]) -> list[tuple[int, int]]:
    """Maximal runs of True in the cyclic sequence `flags` (n,), as (first, last) indices inclusive.

    A run crossing the end of the sequence has first > last; all True gives [(0, n - 1)].
    """
    f = np.asarray(flags, dtype=bool).ravel()
    n = f.size
    if n == 0 or not f.any():
        return []
    if f.all():
        return [(0, n - 1)]
    shift = int(np.argmin(f))                   # start scanning at a False: no run is cut
    runs: list[tuple[int, int]] = []
    start = -1
    for k in range(1, n + 1):
        idx = (shift + k) % n
        if f[idx] and start < 0:
            start = idx
        elif not f[idx] and start >= 0:
            runs.append((start, (idx - 1) % n))
            start = -1
    return runs


def segment_clearance(points: Array, polygon: Array) -> Array:
    """Distance [m] from each of the (m, 2) points to the closed polygon (k, 2) boundary: (m,)."""
    a = np.asarray(polygon, dtype=np.float64).reshape(-1, 2)
    return _to_segments(np.asarray(points, dtype=np.float64).reshape(-1, 2), a, np.roll(a, -1, axis=0))


def _to_segments(p: Array, a: Array, b: Array) -> Array:
    """Distance [m] from each of the (m, 2) points `p` to the nearest of the segments a[i]-b[i]: (m,)
    (inf without segments)."""
    if len(a) == 0:
        return np.full(len(p), np.inf)
    ab = b - a
    len2 = np.maximum((ab ** 2).sum(axis=1), 1e-18)
    ap = p[:, None, :] - a[None, :, :]
    t = np.clip((ap * ab[None]).sum(axis=2) / len2[None], 0.0, 1.0)
    near = a[None] + t[..., None] * ab[None]
    return np.asarray(np.sqrt(((p[:, None, :] - near) ** 2).sum(axis=2)).min(axis=1))


def _floor(clear0: Array, s: Array, offset: float, escape: float | None) -> Array:
    """The least clearance [m] allowed at distance `s` [m] along a way that starts with clearance
    `clear0` [m] (see `ray_reach`)."""
    if escape is None:
        return np.minimum(offset, clear0) - 1e-9
    return np.minimum(offset, clear0 + escape * s) - 1e-9


def ray_reach(region: SafeRegion, theta: float, offset: float, *, length: float | None = None,
              min_step: float = 0.0, step: float = 0.02, escape: float | None = None) -> float | None:
    """The farthest distance [m] the robot can go from the region's centre along `theta` [rad]
    and stay `offset` [m] inside the region (the point mapped onto the region shrunk by `offset`).

    A robot that starts closer to the boundary than `offset` must not get closer still: along
    the way the clearance to the boundary never drops below min(offset, clearance at the centre)
    (`escape` None), or, stricter, below min(offset, clearance at the centre + `escape` s) at
    distance s (it must also move away from the boundary, at least `escape` m per m: a way along
    a wall at the starting clearance is refused). At the returned distance the clearance is >=
    offset. The search runs up to `length` [m] (default RADIUS(S, theta)) in steps of `step` [m].
    Returns None when no distance >= `min_step` qualifies: the region is narrower there than
    2 `offset` (a passage too narrow).
    """
    if length is None:
        length = float(region.radius(np.array(theta)))
    s = np.arange(0.0, max(length, 0.0) + 1e-12, step)
    pts = np.column_stack([region.x + s * math.cos(theta), region.y + s * math.sin(theta)])
    # only the boundary segments that may come within `offset` of the way decide (the rule compares
    # clearances with values <= offset): the others are left out, which changes no decision
    a = region.boundary()
    b = np.roll(a, -1, axis=0)
    mid, half = (a + b) / 2, np.hypot(*(b - a).T) / 2
    along = np.clip((mid[:, 0] - region.x) * math.cos(theta) + (mid[:, 1] - region.y) * math.sin(theta), 0.0,
                    max(float(s[-1]), 0.0))
    gap = np.hypot(mid[:, 0] - region.x - along * math.cos(theta), mid[:, 1] - region.y - along * math.sin(theta))
    keep = gap <= offset + half + 1e-6
    clear = _to_segments(pts, a[keep], b[keep])
    prefix = np.logical_and.accumulate(clear >= _floor(clear[0], s, offset, escape))
    good = prefix & (clear >= offset - 1e-9) & (s >= min_step)
    if not good.any():
        return None
    return float(s[np.flatnonzero(good)[-1]])


def clearance_map(region: SafeRegion, cell: float) -> tuple[Array, float, float]:
    """Clearance [m] to the region's boundary on a local raster of `cell` [m] around its centre.

    Returns (clear, x0, y0): clear (n, n) float64, row r and column c for the point
    (x0 + (c + 0.5) cell, y0 + (r + 0.5) cell); 0 outside the region. The distance to the nearest
    cell centre outside the region less half a cell diagonal: never more than the true clearance.
    """
    from robotexp.planning.grid_planner import distance_transform

    half = region.reach + 2 * cell
    n = int(math.ceil(2 * half / cell))
    x0, y0 = region.x - half, region.y - half
    c = (np.arange(n) + 0.5) * cell
    gx, gy = np.meshgrid(x0 + c, y0 + c)
    inside = region.contains(np.column_stack([gx.ravel(), gy.ravel()])).reshape(n, n)
    dist = distance_transform(~inside).astype(np.float64) * cell - cell * math.sqrt(0.5)
    return np.maximum(dist, 0.0), x0, y0


def reachable_points(region: SafeRegion, angles: Array, offset: float, *, step: float = 0.05,
                     min_step: float = 0.0, cell: float = 0.025, escape: float | None = None) -> Array:
    """The points (k, 2) [m] the robot reaches from the region's centre in a straight line along the
    world `angles` [rad] keeping `offset` [m] inside the region (the rule of `ray_reach`, with
    `escape`), sampled every `step` [m] from `min_step` [m] to each ray's reach: the region shrunk
    by `offset` as seen from its centre. Clearances come from `clearance_map` with `cell` [m]
    (conservative)."""
    clear_map, x0, y0 = clearance_map(region, cell)
    n = clear_map.shape[0]
    theta = np.asarray(angles, dtype=np.float64).ravel()
    s = np.arange(0.0, region.reach + 1e-12, step)
    px = region.x + s[None, :] * np.cos(theta)[:, None]
    py = region.y + s[None, :] * np.sin(theta)[:, None]
    cols = np.clip(np.floor((px - x0) / cell).astype(np.intp), 0, n - 1)
    rows = np.clip(np.floor((py - y0) / cell).astype(np.intp), 0, n - 1)
    clear = clear_map[rows, cols]
    ok = np.logical_and.accumulate(clear >= _floor(clear[:, :1], s[None, :], offset, escape), axis=1)
    ok &= (clear >= offset - 1e-9) & (s[None, :] >= min_step)
    return np.column_stack([px[ok], py[ok]])


def in_sight(region: SafeRegion, a: Array, b: Array, step: float = 0.05) -> bool:
    """True when the segment from `a` to `b` (world points [m]) lies inside the region; `b` itself
    may lie on the boundary (a frontier vertex)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    n = max(2, int(math.ceil(float(np.hypot(*(b - a))) / step)) + 1)
    t = np.linspace(0.0, 1.0, n)[:-1]
    return bool(region.contains(a[None, :] + t[:, None] * (b - a)[None, :]).all())


class SweepBuffer:
    """Collects laser beams over a turn on the spot into `bins` world-angle bins around the robot centre.

    Each beam's end point (at `range_max` for a beam that hit nothing) is taken relative to the
    robot centre, so a laser mounted ahead of the centre is handled. Each bin keeps the smallest
    distance it received (conservative) and whether any beam ending in it hit an obstacle.
    """

    def __init__(self, bins: int = 360) -> None:
        if bins < 3:
            raise ConfigError(f"srt sweep: bins must be >= 3, got {bins}")
        self.bins = bins
        self.best = np.full(bins, np.inf)
        self.seen = np.zeros(bins, dtype=bool)
        self.hit = np.zeros(bins, dtype=bool)
        self.range_max = 0.0

    def add(self, theta: float, angles: Array, ranges: Array, range_max: float, offset_x: float = 0.0) -> None:
        """Add one scan taken at heading `theta` [rad]: beam `angles` [rad] relative to the heading,
        `ranges` [m] (inf: nothing hit; NaN: skipped) up to `range_max` [m], from a sensor
        `offset_x` [m] ahead of the robot centre."""
        r = np.asarray(ranges, dtype=np.float64)
        a = theta + np.asarray(angles, dtype=np.float64)
        ok = ~np.isnan(r)
        hit = ok & (r < range_max)
        d = np.where(hit, r, range_max)[ok]
        px = offset_x * math.cos(theta) + d * np.cos(a[ok])
        py = offset_x * math.sin(theta) + d * np.sin(a[ok])
        # bin k is centred on -pi + k 2pi/bins: beams at whole degrees fall mid-bin, not on an edge
        world = np.mod(np.arctan2(py, px) + math.pi, TAU)
        idx = np.floor(world / TAU * self.bins + 0.5).astype(np.intp) % self.bins
        np.minimum.at(self.best, idx, np.hypot(px, py))
        self.seen[idx] = True
        self.hit[idx[hit[ok]]] = True
        self.range_max = max(self.range_max, float(range_max))

    def bin_angles(self) -> Array:
        """World angle [rad] of each bin's centre, (bins,) increasing from about -pi."""
        return -math.pi + np.arange(self.bins) * TAU / self.bins

    def complete(self) -> bool:
        """True when every bin received a beam."""
        return bool(self.seen.all())

    def _filled(self) -> tuple[Array, npt.NDArray[np.bool_]]:
        """Distances and hit flags per bin; a bin no beam reached takes the smaller distance of its
        nearest reached neighbours and counts as an obstacle (nothing is known there)."""
        best, hit = self.best.copy(), self.hit.copy()
        if not self.seen.any():
            return np.full(self.bins, 1e-3), np.ones(self.bins, dtype=bool)
        if not self.seen.all():
            seen = np.flatnonzero(self.seen)
            for k in np.flatnonzero(~self.seen):
                after = seen[np.searchsorted(seen, k) % seen.size]
                before = seen[np.searchsorted(seen, k) - 1]
                best[k] = min(best[before], best[after])
                hit[k] = True
        return best, hit

    def polygon(self, x: float, y: float) -> PolygonRegion:
        """The SRT-Laser region at (x, y) [m]: bins where no beam hit are frontier vertices, the
        others obstacle vertices at their smallest distance."""
        best, hit = self._filled()
        return PolygonRegion(x, y, self.bin_angles(), np.maximum(best, 1e-3), ~hit)

    def ball(self, x: float, y: float) -> BallRegion:
        """The SRT-Ball region at (x, y) [m]: the disc of the smallest distance, with its hit point
        (radius `range_max` when nothing was hit)."""
        best, hit = self._filled()
        if not hit.any():
            return BallRegion(x, y, float(min(best.min(), self.range_max)))
        k = int(np.argmin(best))
        r, a = float(best[k]), float(self.bin_angles()[k])
        return BallRegion(x, y, r, (x + r * math.cos(a), y + r * math.sin(a)) if hit[k] else None)


def star_from_sonar(x: float, y: float, theta: float, axes: Array, ranges: Array, range_max: float,
                    ring_radius: float = 0.0) -> StarRegion:
    """The SRT-Star region of one sonar ring reading at pose (x, y, theta) [m, m, rad].

    Transducers sharing an axis are merged (smallest reading). The cone between two adjacent axes
    takes the smaller reading of the two (the sensors that take part in it). Distances are from
    the robot centre: `ring_radius` [m] plus the reading; no echo (inf) counts as `range_max` [m].
    """
    ax = np.mod(theta + np.asarray(axes, dtype=np.float64) + math.pi, TAU) - math.pi
    r = np.where(np.isfinite(ranges), np.asarray(ranges, dtype=np.float64), range_max) + ring_radius
    key = np.round(ax, 6)
    uniq = np.unique(key)
    dist = np.array([r[key == u].min() for u in uniq])
    hit = np.isfinite(ranges)
    echoes = np.column_stack([x + r[hit] * np.cos(ax[hit]), y + r[hit] * np.sin(ax[hit])])
    radii = np.minimum(dist, np.roll(dist, -1))      # cone [uniq[i], uniq[i+1])
    return StarRegion(x, y, uniq, radii, echoes)


def sector_intervals(x: float, y: float, directions: Array, apexes: Array, axes: Array, ranges: Array,
                     cone: float) -> tuple[Array, Array]:
    """Where rays from (x, y) [m] run inside the sonar sectors: (lo, hi) [m], each (n, k).

    Ray i leaves (x, y) along world angle `directions[i]` [rad]; sector j has its apex at
    `apexes[j]` (world point [m], the transducer), its axis along world angle `axes[j]` [rad], half
    opening `cone` / 2 (< pi / 2) and radius `ranges[j]` [m] from the apex. A sector is convex (a
    disc cut by two half-planes through the apex), so a ray meets it in one interval of distances
    from (x, y): [lo, hi], empty when lo > hi.
    """
    u = np.column_stack([np.cos(directions), np.sin(directions)])[:, None, :]        # (n, 1, 2)
    d = np.column_stack([x - apexes[:, 0], y - apexes[:, 1]])[None, :, :]            # (1, k, 2): apex -> centre
    du = (d * u).sum(axis=2)
    disc = du ** 2 - (d ** 2).sum(axis=2) + ranges[None, :] ** 2
    root = np.sqrt(np.maximum(disc, 0.0))
    lo = np.maximum(-du - root, 0.0)
    hi = np.where(disc >= 0.0, -du + root, -np.inf)
    half = cone / 2.0
    for edge, sign in ((axes - half, 1.0), (axes + half, -1.0)):
        # inside the half-plane: sign * cross(edge direction, q) >= 0 with q = d + t u
        ex, ey = np.cos(edge)[None, :], np.sin(edge)[None, :]
        c0 = sign * (ex * d[..., 1] - ey * d[..., 0])
        c1 = sign * (ex * u[..., 1] - ey * u[..., 0])
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -c0 / c1
        lo = np.where(c1 > 0, np.maximum(lo, t), lo)
        hi = np.where(c1 < 0, np.minimum(hi, t), hi)
        hi = np.where((c1 == 0) & (c0 < 0), -np.inf, hi)
    return lo, hi


def star_from_sweep(x: float, y: float, apexes: Array, axes: Array, ranges: Array, cone: float, bins: int = 360,
                    body: float = 0.0, echo: npt.NDArray[np.bool_] | None = None) -> StarRegion:
    """The SRT-Star region of sonar readings gathered while turning on the spot at (x, y) [m].

    Reading j is the nearest echo in its transducer's sector: apex `apexes[j]` (world point [m]),
    axis `axes[j]` (world angle [rad]), opening `cone` [rad], radius `ranges[j]` [m] measured from
    the apex; nothing lies closer anywhere in that sector, so it is free, and the region is the
    union of these sectors (thesis Fig. 3.7b: "a set of cones"), as seen from the robot centre
    (x, y): each of the `bins` equal world-angle cones of the region (the first starting at -pi)
    reaches as far as the union covers both its edge rays without a gap, starting from the
    robot's own disc of radius `body` [m] (free: the robot stands there). A sector whose apex is off
    the centre covers the rays from the centre only in part: near the robot a transducer 0.2 m out
    with a 15-degree cone holds the rays within about +-1.5 degrees of its axis, farther out more;
    the turn gives readings at many axes, and their union closes the star. A cone whose reach ends
    on the arc of a reading flagged in `echo` (bool per reading; None: none) is a wall cone
    (`StarRegion.walls`). Raises ConfigError on inconsistent input.
    """
    ap = np.asarray(apexes, dtype=np.float64).reshape(-1, 2)
    ax = np.asarray(axes, dtype=np.float64).ravel()
    r = np.asarray(ranges, dtype=np.float64).ravel()
    if not (len(ap) == ax.size == r.size) or bins < 3 or not 0 < cone < math.pi or body < 0:
        raise ConfigError(f"srt star sweep: need as many apexes, axes and ranges, bins >= 3, cone in (0, pi) rad "
                          f"and body >= 0 m, got {len(ap)}, {ax.size}, {r.size}, {bins} bins, cone {cone}, "
                          f"body {body}")
    edges = -math.pi + np.arange(bins) * TAU / bins
    reach = np.full(bins, float(body))
    walls = np.zeros(bins, dtype=bool)
    if r.size:
        lo1, hi1 = sector_intervals(x, y, edges, ap, ax, r, cone)
        lo2, hi2 = sector_intervals(x, y, edges + TAU / bins, ap, ax, r, cone)
        lo, hi = np.maximum(lo1, lo2), np.minimum(hi1, hi2)         # the whole bin, both edge rays
        for _ in range(r.size):                   # grow each bin through the intervals that touch it
            grown = np.where((lo <= reach[:, None] + 1e-9) & (hi > reach[:, None]), hi, -np.inf).max(axis=1)
            more = grown > reach
            if not more.any():
                break
            reach = np.where(more, grown, reach)
        if echo is not None:
            ends = (lo <= reach[:, None] + 1e-9) & (hi >= reach[:, None] - 1e-9) & (hi > -np.inf)
            src = np.argmax(ends, axis=1)
            mid = edges + math.pi / bins
            px, py = x + reach * np.cos(mid), y + reach * np.sin(mid)
            on_arc = np.hypot(px - ap[src, 0], py - ap[src, 1]) >= r[src] - 0.02
            walls = ends.any(axis=1) & on_arc & np.asarray(echo, dtype=bool).ravel()[src] & (reach > body)
    return StarRegion(x, y, edges, reach, walls=walls)
