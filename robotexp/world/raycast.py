"""Exact 2D ray casting against a world's obstacles, the simulator's laser and sonar.

The world's static obstacles are vertical prisms (boxes and cylinders WALL_HEIGHT tall standing on
the floor), so a horizontal ray at a sensor's height meets exactly their 2D outlines: oriented
rectangles and discs. `RayIndex` buckets those outlines in a uniform grid of square cells and
`cast_rays` walks each ray through the buckets (Amanatides & Woo) with an exact slab test per
rectangle and a quadratic per disc, stopping at the first bucket whose exit lies beyond the nearest
hit. Movers (kinematic cylinders) are few and tested directly.

Semantics follow pybullet's `rayTestBatch` on the same bodies, which the tests check ray by ray:
the hit fraction is the distance to the first entry along the ray over its length, 1.0 when
nothing is hit; a ray whose origin lies inside an obstacle does not hit that obstacle (it leaves
it); an obstacle of height h is seen by rays at heights 0 <= z < h.

Why not pybullet's ray test itself: Bullet casts a ray at a box or a cylinder by an iterative
convex cast, about 2.3 us per ray here, which was half of every simulated step; this kernel does
the same geometry in a few tens of nanoseconds. `Engine(..., rays="pybullet")` keeps Bullet's.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import numpy.typing as npt

from robotexp.mapping.kernels import kernel, strip_extent

__all__ = ["RayIndex", "box_distance", "box_extents", "bucket_window", "cast_rays", "parts", "shapes_near",
           "shapes_near_box"]

MAX_BUCKETS = 1 << 20       # a bucket grid never exceeds this many cells


class RayIndex:
    """Rectangles and discs of a world, bucketed in a uniform grid for `cast_rays`.

    Args:
        boxes: (n, 5) [cx, cy, half_x, half_y, yaw] [m, m, m, m, rad].
        discs: (m, 3) [cx, cy, r] [m].
        height: [m] height of every static obstacle (rays at 0 <= z < height meet them).
        bucket: [m] side of a bucket (default: about three times the median obstacle size,
            at least 0.25 m, and never more than MAX_BUCKETS buckets).
        max_bucket: [m] the default bucket is at most this (queries near a point: the clearance's).

    A rectangle is listed in the buckets it overlaps, row by row of buckets (not in every bucket of its
    bounding box: a long diagonal wall crosses about its length in buckets, not its length squared).
    """

    def __init__(self, boxes: npt.ArrayLike, discs: npt.ArrayLike, height: float,
                 bucket: float | None = None, *, max_bucket: float | None = None) -> None:
        b = np.asarray(boxes, dtype=np.float64).reshape(-1, 5)
        d = np.asarray(discs, dtype=np.float64).reshape(-1, 3)
        self.height = float(height)
        # One table of shapes: [kind, cx, cy, a, b, cos(yaw), sin(yaw)]; kind 0 rectangle (a, b half
        # sizes), kind 1 disc (a radius).
        shapes = np.zeros((len(b) + len(d), 7))
        shapes[:len(b), 1:5] = b[:, :4]
        shapes[:len(b), 5] = np.cos(b[:, 4])
        shapes[:len(b), 6] = np.sin(b[:, 4])
        shapes[len(b):, 0] = 1.0
        shapes[len(b):, 1:4] = d
        self.shapes = shapes
        # Axis-aligned bounds of every shape.
        ex, ey = box_extents(b)
        lo = np.vstack([np.column_stack([b[:, 0] - ex, b[:, 1] - ey]), d[:, :2] - d[:, 2:3]])
        hi = np.vstack([np.column_stack([b[:, 0] + ex, b[:, 1] + ey]), d[:, :2] + d[:, 2:3]])
        if len(shapes) == 0:
            lo, hi = np.zeros((1, 2)), np.ones((1, 2))
        x0, y0 = lo.min(axis=0) - 1e-6
        x1, y1 = hi.max(axis=0) + 1e-6
        if bucket is None:
            sizes = np.maximum(hi - lo, 0.0).max(axis=1) if len(shapes) else np.ones(1)
            bucket = max(0.25, 3.0 * float(np.median(sizes)))
            if max_bucket is not None:
                bucket = min(bucket, max_bucket)
        bucket = max(float(bucket), math.sqrt((x1 - x0) * (y1 - y0) / MAX_BUCKETS))
        cols = max(int(math.ceil((x1 - x0) / bucket)), 1)
        rows = max(int(math.ceil((y1 - y0) / bucket)), 1)
        self.origin = (float(x0), float(y0))
        self.bucket, self.rows, self.cols = bucket, rows, cols
        # CSR lists of the shapes overlapping each bucket: a run of buckets per shape and bucket row
        # (vectorised: maps of 10^5 boxes)
        n = len(shapes)          # lo and hi have one dummy row when there is no shape
        grid = (float(x0), float(y0), float(bucket), rows, cols)
        owner, row, c0, c1 = _bucket_runs(b, lo[:n], hi[:n], grid)
        count = c1 - c0 + 1
        owner = np.repeat(owner, count)
        local = np.arange(int(count.sum()), dtype=np.int64) - np.repeat(np.cumsum(count) - count, count)
        cell = np.repeat(row * cols + c0, count) + local
        order = np.lexsort((owner, cell))       # each bucket's shapes in the order of the shapes
        self.items = owner[order]
        self.starts = np.searchsorted(cell[order], np.arange(rows * cols + 1)).astype(np.int64)

    def near(self, x: float, y: float, reach: float) -> bool:
        """True when a shape lies within `reach` [m] of the point (x, y) [m] (touching counts)."""
        return bool(shapes_near(self.shapes, self.starts, self.items, self.origin[0], self.origin[1], self.bucket,
                                self.rows, self.cols, float(x), float(y), float(reach)))

    def near_box(self, x: float, y: float, theta: float, half_length: float, half_width: float,  # noqa: PLR0913
                 reach: float) -> bool:
        """True when a shape lies within `reach` [m] of the rectangle centred at (x, y) [m], its half
        length `half_length` [m] along `theta` [rad] and half width `half_width` [m] across (touching counts)."""
        return bool(shapes_near_box(self.shapes, self.starts, self.items, self.origin[0], self.origin[1], self.bucket,
                                    self.rows, self.cols, float(x), float(y), math.cos(theta), math.sin(theta),
                                    float(half_length), float(half_width), float(reach)))

    def cast(self, origins: npt.NDArray[np.float64], headings: npt.NDArray[np.float64], reach: float, z: float,
             movers: npt.NDArray[np.float64] | None = None) -> npt.NDArray[np.float64]:
        """Hit fractions (n,) of rays from `origins` (n, 2) [m] along `headings` (n,) [rad], `reach` [m] long,
        at height `z` [m]; `movers` (k, 4) [cx, cy, r, height] [m]. 1.0: no hit."""
        if movers is None:
            movers = np.zeros((0, 4))
        out = np.empty(len(headings))
        static = 0.0 <= z < self.height
        cast_rays(np.ascontiguousarray(origins, dtype=np.float64), np.ascontiguousarray(headings, dtype=np.float64),
                  float(reach), self.shapes if static else self.shapes[:0], self.starts, self.items,
                  self.origin[0], self.origin[1], self.bucket, self.rows, self.cols,
                  np.ascontiguousarray(movers[(movers[:, 3] > z) & (z >= 0.0)] if len(movers) else movers,
                                       dtype=np.float64), out)
        return out


_RUN_ROWS = 1 << 18         # shape-rows handled at once while listing a map's shapes in buckets
_EDGE = 1e-6                # [m] a rectangle is listed in a bucket it comes this near (rounding)


def box_extents(boxes: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """(ex, ey) [m]: the half sizes along x and y of the bounding boxes of the (n, 5) rectangles [cx, cy, hx, hy,
    yaw]."""
    c, s = np.cos(boxes[:, 4]), np.sin(boxes[:, 4])
    return np.abs(boxes[:, 2] * c) + np.abs(boxes[:, 3] * s), np.abs(boxes[:, 2] * s) + np.abs(boxes[:, 3] * c)


def parts(sizes: npt.ArrayLike, part: float) -> Iterator[tuple[int, int]]:
    """Consecutive ranges [first, last) of the items whose `sizes` are given, each holding about `part` in all
    (at least one item): work cut into pieces of bounded size (between which signals are handled)."""
    ends = np.cumsum(sizes)
    first = 0
    while first < len(ends):
        last = max(int(np.searchsorted(ends, (ends[first - 1] if first else 0) + part, "right")), first + 1)
        yield first, last
        first = last


def _bucket_runs(boxes: npt.NDArray[np.float64], lo: npt.NDArray[np.float64], hi: npt.NDArray[np.float64],
                 grid: tuple[float, float, float, int, int]) -> tuple[npt.NDArray[np.int64], ...]:
    """The buckets each shape overlaps, as runs (owner, row, c0, c1) of a bucket row from column c0 to c1
    (inclusive): a turned rectangle (of the first len(boxes) shapes) crossing several rows and columns by the
    columns of its part within each row, any other shape (discs, rectangles along the axes, those within
    one row or column) by its bounds `lo`..`hi` (n, 2) [m]. `grid` is (x0, y0, bucket, rows, cols)."""
    x0, y0, bucket, rows, cols = grid
    r0 = np.clip(((lo[:, 1] - _EDGE - y0) // bucket).astype(np.int64), 0, rows - 1)
    r1 = np.clip(((hi[:, 1] + _EDGE - y0) // bucket).astype(np.int64), 0, rows - 1)
    b0 = np.clip(((lo[:, 0] - _EDGE - x0) // bucket).astype(np.int64), 0, cols - 1)
    b1 = np.clip(((hi[:, 0] + _EDGE - x0) // bucket).astype(np.int64), 0, cols - 1)
    n_rows = r1 - r0 + 1
    turned = np.zeros(len(lo), np.bool_)
    turned[:len(boxes)] = (np.sin(2.0 * boxes[:, 4]) != 0.0) & (n_rows[:len(boxes)] > 1) & (b1 > b0)[:len(boxes)]
    runs: list[tuple[npt.NDArray[np.int64], ...]] = []
    plain = np.flatnonzero(~turned)
    owner = np.repeat(plain, n_rows[plain])
    row = r0[owner] + np.arange(len(owner)) - np.repeat(np.cumsum(n_rows[plain]) - n_rows[plain], n_rows[plain])
    runs.append((owner, row, b0[owner], b1[owner]))
    k_all = np.flatnonzero(turned)
    for first, last in parts(n_rows[k_all], _RUN_ROWS):
        k = k_all[first:last]
        # corners in order around each rectangle: centre +- the half axes
        c, s = np.cos(boxes[k, 4]), np.sin(boxes[k, 4])
        ux, uy, vx, vy = c * boxes[k, 2], s * boxes[k, 2], -s * boxes[k, 3], c * boxes[k, 3]
        px = np.repeat(boxes[k, 0:1] + np.column_stack([ux + vx, -ux + vx, -ux - vx, ux - vx]), n_rows[k], axis=0)
        py = np.repeat(boxes[k, 1:2] + np.column_stack([uy + vy, -uy + vy, -uy - vy, uy - vy]), n_rows[k], axis=0)
        owner = np.repeat(k, n_rows[k])
        row = r0[owner] + np.arange(len(owner)) - np.repeat(np.cumsum(n_rows[k]) - n_rows[k], n_rows[k])
        x_lo, x_hi = _strip_span(px, py, y0 + row * bucket - _EDGE, y0 + (row + 1) * bucket + _EDGE)
        c0 = np.maximum(np.floor((x_lo - _EDGE - x0) / bucket), b0[owner]).astype(np.int64)
        c1 = np.minimum(np.floor((x_hi + _EDGE - x0) / bucket), b1[owner]).astype(np.int64)
        keep = c0 <= c1
        runs.append((owner[keep], row[keep], c0[keep], c1[keep]))
    return tuple(np.concatenate([p[i] for p in runs]).astype(np.int64) for i in range(4))


@kernel
def _strip_span(px: npt.NDArray[np.float64], py: npt.NDArray[np.float64], y_lo: npt.NDArray[np.float64],
                y_hi: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """(x_lo, x_hi) (n,): the x range of the part of each convex polygon (corners px, py (n, 4) in order)
    between y_lo and y_hi (n,) (x_lo > x_hi when none; `strip_extent`)."""
    n = px.shape[0]
    x_lo, x_hi = np.empty(n), np.empty(n)
    corners = np.empty((px.shape[1], 2))
    for i in range(n):
        corners[:, 0] = px[i]
        corners[:, 1] = py[i]
        x_lo[i], x_hi[i] = strip_extent(corners, y_lo[i], y_hi[i])
    return x_lo, x_hi


@kernel
def _hit_shape(kind: float, cx: float, cy: float, a: float, b: float, c: float, s: float,
               ox: float, oy: float, dx: float, dy: float) -> float:
    """Distance along the unit ray (ox, oy) + t (dx, dy) to where it enters the shape; inf if it does not
    (or if the origin lies inside)."""
    px, py = ox - cx, oy - cy
    if kind == 0.0:
        # Rectangle: into its frame, then the slab test on |x| <= a, |y| <= b.
        lx, ly = c * px + s * py, -s * px + c * py
        ux, uy = c * dx + s * dy, -s * dx + c * dy
        t_in, t_out = -math.inf, math.inf
        if ux != 0.0:
            t1, t2 = (-a - lx) / ux, (a - lx) / ux
            t_in, t_out = max(t_in, min(t1, t2)), min(t_out, max(t1, t2))
        elif abs(lx) > a:
            return math.inf
        if uy != 0.0:
            t1, t2 = (-b - ly) / uy, (b - ly) / uy
            t_in, t_out = max(t_in, min(t1, t2)), min(t_out, max(t1, t2))
        elif abs(ly) > b:
            return math.inf
        if t_in > t_out or t_in < 0.0:
            return math.inf
        return t_in
    # Disc: |p + t d|^2 = a^2 with |d| = 1.
    half_b = px * dx + py * dy
    cc = px * px + py * py - a * a
    if cc <= 0.0:
        return math.inf              # the origin is inside
    disc = half_b * half_b - cc
    if disc < 0.0 or half_b >= 0.0:
        return math.inf
    return -half_b - math.sqrt(disc)


@kernel
def _slab(o: float, d: float, lo: float, hi: float, t0: float, t1: float) -> tuple[float, float]:
    """The part [t0, t1] of a ray (origin `o`, direction `d` along one axis) within lo..hi on that axis;
    t1 < t0 when none."""
    if d != 0.0:
        a1, a2 = (lo - o) / d, (hi - o) / d
        return max(t0, min(a1, a2)), min(t1, max(a1, a2))
    if o < lo or o > hi:
        return t0, -1.0
    return t0, t1


@kernel
def _next_border(o: float, d: float, g: float, k: int, bucket: float) -> float:
    """Ray parameter at which a ray (origin `o`, direction `d` along one axis) leaves bucket `k` of a grid
    starting at `g` with buckets of `bucket` [m]; inf when it never does."""
    if d > 0.0:
        return (g + (k + 1) * bucket - o) / d
    if d < 0.0:
        return (g + k * bucket - o) / d
    return math.inf


@kernel
def cast_rays(origins: npt.NDArray[np.float64], headings: npt.NDArray[np.float64], reach: float,
              shapes: npt.NDArray[np.float64], starts: npt.NDArray[np.int64], items: npt.NDArray[np.int64],
              gx: float, gy: float, bucket: float, rows: int, cols: int, movers: npt.NDArray[np.float64],
              out: npt.NDArray[np.float64]) -> None:
    """Write into `out` the hit fraction of each ray (see `RayIndex.cast`; the bucket grid has its corner
    at (gx, gy) [m], square buckets of `bucket` [m], `rows` x `cols`; movers (k, 4) are tested directly)."""
    for i in range(len(headings)):
        ox, oy = origins[i, 0], origins[i, 1]
        dx, dy = math.cos(headings[i]), math.sin(headings[i])
        best = reach
        for k in range(movers.shape[0]):
            t = _hit_shape(1.0, movers[k, 0], movers[k, 1], movers[k, 2], 0.0, 1.0, 0.0, ox, oy, dx, dy)
            if t < best:
                best = t
        if shapes.shape[0] > 0:
            # Clip the ray to the bucket grid's rectangle.
            t0, t1 = _slab(ox, dx, gx, gx + cols * bucket, 0.0, best)
            t0, t1 = _slab(oy, dy, gy, gy + rows * bucket, t0, t1)
            if t0 <= t1:
                fx, fy = (ox + t0 * dx - gx) / bucket, (oy + t0 * dy - gy) / bucket
                c = min(max(int(math.floor(fx)), 0), cols - 1)
                r = min(max(int(math.floor(fy)), 0), rows - 1)
                step_c = 1 if dx > 0.0 else -1
                step_r = 1 if dy > 0.0 else -1
                # Ray parameter at the next vertical / horizontal bucket border.
                next_x = _next_border(ox, dx, gx, c, bucket)
                next_y = _next_border(oy, dy, gy, r, bucket)
                dt_x = bucket / abs(dx) if dx != 0.0 else math.inf
                dt_y = bucket / abs(dy) if dy != 0.0 else math.inf
                while True:
                    cell = r * cols + c
                    for j in range(starts[cell], starts[cell + 1]):
                        k = items[j]
                        t = _hit_shape(shapes[k, 0], shapes[k, 1], shapes[k, 2], shapes[k, 3], shapes[k, 4],
                                       shapes[k, 5], shapes[k, 6], ox, oy, dx, dy)
                        if t < best:
                            best = t
                    exit_t = min(next_x, next_y)
                    if best <= exit_t or exit_t > t1:
                        break
                    if next_x < next_y:
                        c += step_c
                        next_x += dt_x
                        if c < 0 or c >= cols:
                            break
                    else:
                        r += step_r
                        next_y += dt_y
                        if r < 0 or r >= rows:
                            break
        out[i] = best / reach if best < reach else 1.0


@kernel
def shape_distance(kind: float, cx: float, cy: float, a: float, b: float, c: float, s: float,
                    x: float, y: float) -> float:
    """Distance [m] from the point (x, y) to the shape (0 inside it)."""
    px, py = x - cx, y - cy
    if kind == 0.0:
        lx, ly = abs(c * px + s * py), abs(-s * px + c * py)
        return math.hypot(max(lx - a, 0.0), max(ly - b, 0.0))
    return max(math.hypot(px, py) - a, 0.0)


@kernel
def bucket_window(gx: float, gy: float, bucket: float, rows: int, cols: int, x: float, y: float,
                  reach: float) -> tuple[int, int, int, int]:
    """(r0, r1, c0, c1): the buckets, inclusive and clipped to the grid, of every point within `reach` [m]
    of (x, y) [m]."""
    c0 = max(int(math.floor((x - reach - gx) / bucket)), 0)
    c1 = min(int(math.floor((x + reach - gx) / bucket)), cols - 1)
    r0 = max(int(math.floor((y - reach - gy) / bucket)), 0)
    r1 = min(int(math.floor((y + reach - gy) / bucket)), rows - 1)
    return r0, r1, c0, c1


@kernel
def shapes_near(shapes: npt.NDArray[np.float64], starts: npt.NDArray[np.int64], items: npt.NDArray[np.int64],
                gx: float, gy: float, bucket: float, rows: int, cols: int, x: float, y: float, reach: float) -> bool:
    """True when a shape of the bucket grid (see `cast_rays`) lies within `reach` [m] of (x, y) [m]."""
    r0, r1, c0, c1 = bucket_window(gx, gy, bucket, rows, cols, x, y, reach)
    for r in range(r0, r1 + 1):
        for cc in range(c0, c1 + 1):
            cell = r * cols + cc
            for j in range(starts[cell], starts[cell + 1]):
                k = items[j]
                if shape_distance(shapes[k, 0], shapes[k, 1], shapes[k, 2], shapes[k, 3], shapes[k, 4],
                                   shapes[k, 5], shapes[k, 6], x, y) <= reach:
                    return True
    return False


@kernel
def _separated(ax: float, ay: float, a1: float, b1: float, c1: float, s1: float,  # noqa: PLR0913
               bx: float, by: float, a2: float, b2: float, c2: float, s2: float) -> bool:
    """True when two rectangles (centre, half extents, cos and sin of their heading) do not overlap: one of
    their four edge directions separates their projections."""
    dx, dy = bx - ax, by - ay
    for k in range(4):
        if k == 0:
            ux, uy = c1, s1
        elif k == 1:
            ux, uy = -s1, c1
        elif k == 2:
            ux, uy = c2, s2
        else:
            ux, uy = -s2, c2
        ra = a1 * abs(ux * c1 + uy * s1) + b1 * abs(-ux * s1 + uy * c1)
        rb = a2 * abs(ux * c2 + uy * s2) + b2 * abs(-ux * s2 + uy * c2)
        if abs(ux * dx + uy * dy) > ra + rb:
            return True
    return False


@kernel
def box_distance(ax: float, ay: float, a1: float, b1: float, c1: float, s1: float,  # noqa: PLR0913
                 bx: float, by: float, a2: float, b2: float, c2: float, s2: float) -> float:
    """Distance [m] between two rectangles (centre, half extents, cos and sin of their heading), 0 when they
    overlap. Apart, the nearest points of two convex polygons include a corner of one of them."""
    if not _separated(ax, ay, a1, b1, c1, s1, bx, by, a2, b2, c2, s2):
        return 0.0
    best = math.inf
    for i in range(4):
        u = 1.0 if i < 2 else -1.0
        v = 1.0 if i % 2 == 0 else -1.0
        # a corner of the first against the second, then a corner of the second against the first
        d = shape_distance(0.0, bx, by, a2, b2, c2, s2, ax + c1 * u * a1 - s1 * v * b1, ay + s1 * u * a1 + c1 * v * b1)
        best = min(best, d)
        d = shape_distance(0.0, ax, ay, a1, b1, c1, s1, bx + c2 * u * a2 - s2 * v * b2, by + s2 * u * a2 + c2 * v * b2)
        best = min(best, d)
    return best


@kernel
def shapes_near_box(shapes: npt.NDArray[np.float64], starts: npt.NDArray[np.int64], items: npt.NDArray[np.int64],  # noqa: PLR0913
                    gx: float, gy: float, bucket: float, rows: int, cols: int, x: float, y: float, c: float, s: float,
                    half_length: float, half_width: float, reach: float) -> bool:
    """True when a shape of the bucket grid (see `cast_rays`) lies within `reach` [m] of the rectangle at
    (x, y) [m] with half extents (`half_length`, `half_width`) [m] along the heading (cos `c`, sin `s`)."""
    r0, r1, c0, c1 = bucket_window(gx, gy, bucket, rows, cols, x, y, reach + math.hypot(half_length, half_width))
    for r in range(r0, r1 + 1):
        for cc in range(c0, c1 + 1):
            cell = r * cols + cc
            for j in range(starts[cell], starts[cell + 1]):
                k = items[j]
                if shapes[k, 0] == 0.0:
                    d = box_distance(x, y, half_length, half_width, c, s, shapes[k, 1], shapes[k, 2], shapes[k, 3],
                                     shapes[k, 4], shapes[k, 5], shapes[k, 6])
                else:   # a disc: its centre against the rectangle, less its radius
                    d = shape_distance(0.0, x, y, half_length, half_width, c, s, shapes[k, 1], shapes[k, 2]) \
                        - shapes[k, 3]
                if d <= reach:
                    return True
    return False
