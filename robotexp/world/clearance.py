"""Exact clearance of a world and the regions a disc robot can reach in it.

Clearance is the Euclidean distance [m] from a point to the nearest static obstacle of a world, computed
from the exact shapes the simulator collides with and casts its rays at (oriented rectangles and discs,
bucketed by `robotexp.world.raycast.RayIndex`; a bitmap map's obstacles are its pixel squares, merged into
rectangles by the loader). A disc robot of radius r fits at a point whose clearance exceeds r.

`reach_regions` splits the places where the robot fits into connected regions without a fine raster of
the whole map. On a grid of cell h, clearance is 1-Lipschitz, so a cell whose centre has clearance
C > r + h/sqrt(2) lies wholly in the free space ("sure") and one with C + h/sqrt(2) <= r wholly outside
("blocked"). Only the remaining cells, a band along the free space's border, are sampled finely: k x k
points per cell (k = ceil(h / FINE_STEP), lowered to keep the band under MAX_SAMPLES samples), each free
when its own exact clearance exceeds r. The regions
are the 8-connected components of the fine lattice whose points are free when their cell is sure or
their own sample is free. A passage the robot fits through with d to spare on each side keeps a row of
fine points when 2 d exceeds the fine step: with FINE_STEP 1 cm, a door 2 cm wider than the robot is
open, one 2 cm narrower is closed (a narrower door has no point of clearance > r at all).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.kernels import edt_sq, kernel
from robotexp.world.raycast import RayIndex, bucket_window, shape_distance
from robotexp.world.model import World

__all__ = ["BUCKET", "FINE_STEP", "MAX_SAMPLES", "TOL", "Regions", "clearance", "clearance_points", "reach_regions",
           "world_index"]

FINE_STEP = 0.01        # [m] the finest spacing at which the border of the free space is sampled
MAX_SAMPLES = 16_000_000  # the border band holds at most this many fine samples (k is lowered to fit)
TOL = 1e-9              # [m] a clearance within this of the radius counts as touching: the robot does not fit
BUCKET = 0.5            # [m] largest bucket of the clearance's index (`world_index`)
CHUNK = 1 << 16         # points searched per kernel call: signals are handled between calls


def world_index(world: World) -> RayIndex:
    """The bucket index of `world`'s static obstacles for clearance queries: the ray caster's, with
    buckets of at most BUCKET (a query looks at the few buckets within its cap of the point, whatever
    the obstacles' size)."""
    return RayIndex(world.boxes, world.discs, 1.0, max_bucket=BUCKET)


@kernel
def _nearer(shapes: npt.NDArray[np.float64], starts: npt.NDArray[np.int64], items: npt.NDArray[np.int64],  # noqa: PLR0913
            cell: int, x: float, y: float, best: float) -> float:
    """The least of `best` and the distance [m] from (x, y) to the shapes of bucket `cell`."""
    for j in range(starts[cell], starts[cell + 1]):
        k = items[j]
        d = shape_distance(shapes[k, 0], shapes[k, 1], shapes[k, 2], shapes[k, 3], shapes[k, 4], shapes[k, 5],
                           shapes[k, 6], x, y)
        if d < best:
            best = d
    return best


@kernel
def clearance_points(shapes: npt.NDArray[np.float64], starts: npt.NDArray[np.int64], items: npt.NDArray[np.int64],  # noqa: PLR0913
                     gx: float, gy: float, bucket: float, rows: int, cols: int, xs: npt.NDArray[np.float64],
                     ys: npt.NDArray[np.float64], cap: float, out: npt.NDArray[np.float64]) -> None:
    """Write into `out` the exact distance [m] from each point (xs[i], ys[i]) to the nearest shape of the
    bucket grid (see `robotexp.world.raycast.cast_rays`), or `cap` when none lies nearer than `cap`.

    The point's own bucket is searched first; a bucket of the window wholly as far as the nearest shape
    found so far is skipped (a shape is listed in every bucket it overlaps, so a nearer point of it lies in
    a nearer bucket)."""
    for i in range(xs.shape[0]):
        x, y = xs[i], ys[i]
        best = cap
        r0, r1, c0, c1 = bucket_window(gx, gy, bucket, rows, cols, x, y, cap)
        ro = int(math.floor((y - gy) / bucket))
        co = int(math.floor((x - gx) / bucket))
        if r0 <= ro <= r1 and c0 <= co <= c1:
            best = _nearer(shapes, starts, items, ro * cols + co, x, y, best)
        for r in range(r0, r1 + 1):
            dy = max(gy + r * bucket - y, y - (gy + (r + 1) * bucket), 0.0)
            if dy >= best:
                continue
            for c in range(c0, c1 + 1):
                if r == ro and c == co:
                    continue
                dx = max(gx + c * bucket - x, x - (gx + (c + 1) * bucket), 0.0)
                if dx * dx + dy * dy < best * best:
                    best = _nearer(shapes, starts, items, r * cols + c, x, y, best)
        out[i] = best


def clearance(world: World, geo: GridGeometry, cap: float, *, index: RayIndex | None = None,  # noqa: PLR0913
              occupied: npt.NDArray[np.bool_] | None = None, floor: float | None = None) -> npt.NDArray[np.float64]:
    """Float64 (rows, cols): the exact clearance [m] of each cell centre of `geo`, at most `cap` [m].

    `occupied` (the cells overlapping an obstacle, `groundtruth.occupancy`) lets cells whose nearest
    occupied cell lies beyond `cap` skip the exact search; `index` is `world_index(world)`. With `floor`
    [m] (and `occupied`), a cell that an occupied cell proves to lie within `floor` of an obstacle (the
    farthest point of that cell's square is that near) gets that bound (<= `floor`, >= its clearance)
    instead of its exact clearance: for callers that only tell clearances above `floor` apart. The
    search runs in parts, so Ctrl-C and signals are handled between them.
    """
    if index is None:
        index = world_index(world)
    out = np.full((geo.rows, geo.cols), float(cap))
    if occupied is not None and occupied.any():
        # every obstacle point lies in an occupied cell's square: at least (centre distance - h/sqrt 2) away,
        # and the nearest occupied cell holds one at most (centre distance + h/sqrt 2) away
        centre = np.sqrt(edt_sq(occupied)) * geo.cell
        half_diag = geo.cell * math.sqrt(0.5)
        near = centre - half_diag < cap
        if floor is not None:
            proven = centre + half_diag < floor - TOL
            out[proven] = np.minimum(centre[proven] + half_diag, cap)
            near &= ~proven
    else:
        near = np.ones((geo.rows, geo.cols), np.bool_) if occupied is None else np.zeros((geo.rows, geo.cols),
                                                                                          np.bool_)
    rr, cc = np.nonzero(near)
    xs = (geo.origin_x + (cc + 0.5) * geo.cell).astype(np.float64)
    ys = (geo.origin_y + (rr + 0.5) * geo.cell).astype(np.float64)
    vals = np.empty(len(rr))
    for a in range(0, len(rr), CHUNK):
        b = a + CHUNK
        clearance_points(index.shapes, index.starts, index.items, index.origin[0], index.origin[1], index.bucket,
                         index.rows, index.cols, xs[a:b], ys[a:b], float(cap), vals[a:b])
    out[rr, cc] = vals
    return out


@kernel
def _fine_free(shapes: npt.NDArray[np.float64], starts: npt.NDArray[np.int64], items: npt.NDArray[np.int64],  # noqa: PLR0913
               gx: float, gy: float, bucket: float, rows: int, cols: int, ox: float, oy: float, h: float,
               k: int, radius: float, mr: npt.NDArray[np.int64], mc: npt.NDArray[np.int64],
               out: npt.NDArray[np.bool_]) -> None:
    """out[m, i, j]: True when the point (i, j) of the k x k lattice in cell (mr[m], mc[m]) lies farther than
    `radius` (+ TOL) from every shape (the shapes near the cell are gathered once per cell)."""
    cand = np.empty(shapes.shape[0], np.int64)
    seen = np.full(shapes.shape[0], -1, np.int64)     # the last cell that took each shape as a candidate
    s = h / k
    reach = radius + h
    for m in range(mr.shape[0]):
        x0 = ox + mc[m] * h
        y0 = oy + mr[m] * h
        c0 = max(int(math.floor((x0 - reach - gx) / bucket)), 0)
        c1 = min(int(math.floor((x0 + h + reach - gx) / bucket)), cols - 1)
        r0 = max(int(math.floor((y0 - reach - gy) / bucket)), 0)
        r1 = min(int(math.floor((y0 + h + reach - gy) / bucket)), rows - 1)
        n = 0
        xc, yc = x0 + 0.5 * h, y0 + 0.5 * h
        for r in range(r0, r1 + 1):
            for c in range(c0, c1 + 1):
                cell = r * cols + c
                for j in range(starts[cell], starts[cell + 1]):
                    q = items[j]
                    d = shape_distance(shapes[q, 0], shapes[q, 1], shapes[q, 2], shapes[q, 3], shapes[q, 4],
                                        shapes[q, 5], shapes[q, 6], xc, yc)
                    if d <= radius + h and seen[q] != m:   # within reach of some point of the cell (h > h / sqrt 2)
                        seen[q] = m
                        cand[n] = q
                        n += 1
        for i in range(k):
            y = y0 + (i + 0.5) * s
            for j in range(k):
                x = x0 + (j + 0.5) * s
                free = True
                for t in range(n):
                    q = cand[t]
                    if shape_distance(shapes[q, 0], shapes[q, 1], shapes[q, 2], shapes[q, 3], shapes[q, 4],
                                       shapes[q, 5], shapes[q, 6], x, y) <= radius + 1e-9:
                        free = False
                        break
                out[m, i, j] = free


@kernel
def _label(sure: npt.NDArray[np.bool_], mid: npt.NDArray[np.int64], mr: npt.NDArray[np.int64],  # noqa: C901
           mc: npt.NDArray[np.int64], fine: npt.NDArray[np.bool_], k: int
           ) -> tuple[npt.NDArray[np.int32], npt.NDArray[np.int32], int]:
    """Label the 8-connected components of the fine lattice (see the module): (coarse labels (rows, cols)
    of the sure cells, fine labels (m, k, k) of the free samples, count); 0 is no region."""
    rows, cols = sure.shape
    nm = mr.shape[0]
    lab_c = np.zeros((rows, cols), np.int32)
    lab_f = np.zeros((nm, k, k), np.int32)
    n_coarse = rows * cols
    queue = np.empty(n_coarse + nm * k * k, np.int64)
    count = 0
    for seed in range(n_coarse + nm * k * k):
        if seed < n_coarse:
            sr, sc = seed // cols, seed % cols
            if not sure[sr, sc] or lab_c[sr, sc] != 0:
                continue
            count += 1
            lab_c[sr, sc] = count
        else:
            f = seed - n_coarse
            fm, fi, fj = f // (k * k), (f // k) % k, f % k
            if not fine[fm, fi, fj] or lab_f[fm, fi, fj] != 0:
                continue
            count += 1
            lab_f[fm, fi, fj] = count
        head, tail = 0, 0
        queue[tail] = seed
        tail += 1
        while head < tail:
            node = queue[head]
            head += 1
            if node < n_coarse:
                r, c = node // cols, node % cols
                for dr in range(-1, 2):
                    for dc in range(-1, 2):
                        nr, nc = r + dr, c + dc
                        if (dr == 0 and dc == 0) or nr < 0 or nr >= rows or nc < 0 or nc >= cols:
                            continue
                        if sure[nr, nc]:
                            if lab_c[nr, nc] == 0:
                                lab_c[nr, nc] = count
                                queue[tail] = nr * cols + nc
                                tail += 1
                        elif mid[nr, nc] >= 0:
                            m = mid[nr, nc]
                            # the samples of the neighbour cell along the side (or at the corner) facing (r, c)
                            i0, i1 = (0, k) if dr == 0 else ((0, 1) if dr > 0 else (k - 1, k))
                            j0, j1 = (0, k) if dc == 0 else ((0, 1) if dc > 0 else (k - 1, k))
                            for i in range(i0, i1):
                                for j in range(j0, j1):
                                    if fine[m, i, j] and lab_f[m, i, j] == 0:
                                        lab_f[m, i, j] = count
                                        queue[tail] = n_coarse + (m * k + i) * k + j
                                        tail += 1
            else:
                f = node - n_coarse
                m, i, j = f // (k * k), (f // k) % k, f % k
                fr, fc = mr[m] * k + i, mc[m] * k + j
                for di in range(-1, 2):
                    for dj in range(-1, 2):
                        gr, gc = fr + di, fc + dj
                        if (di == 0 and dj == 0) or gr < 0 or gc < 0:
                            continue
                        nr, nc = gr // k, gc // k
                        if nr >= rows or nc >= cols:
                            continue
                        if sure[nr, nc]:
                            if lab_c[nr, nc] == 0:
                                lab_c[nr, nc] = count
                                queue[tail] = nr * cols + nc
                                tail += 1
                        elif mid[nr, nc] >= 0:
                            n2 = mid[nr, nc]
                            i2, j2 = gr - nr * k, gc - nc * k
                            if fine[n2, i2, j2] and lab_f[n2, i2, j2] == 0:
                                lab_f[n2, i2, j2] = count
                                queue[tail] = n_coarse + (n2 * k + i2) * k + j2
                                tail += 1
    return lab_c, lab_f, count


@dataclass(frozen=True)
class Regions:
    """The connected regions where a disc robot fits, on a grid (see the module).

    Attributes:
        geo: the grid.
        radius: [m] the robot's radius.
        k: fine samples per cell side in the border band.
        clear: float64 (rows, cols) exact clearance [m] of the cell centres, capped at radius + cell (a cell
            the occupied cells prove blocked holds a bound <= radius - cell / sqrt 2 instead: `clearance`).
        coarse: int32 (rows, cols) region of each sure cell (0: not sure).
        mid: int64 (rows, cols) index of each border-band cell in `fine` (-1: not in the band).
        fine: int32 (m, k, k) region of each fine sample of the band's cells (0: the robot does not fit).
        count: number of regions.
        area: float64 (count + 1,) [m2] area of each region (index 0 unused).
    """

    geo: GridGeometry
    radius: float
    k: int
    clear: npt.NDArray[np.float64]
    coarse: npt.NDArray[np.int32]
    mid: npt.NDArray[np.int64]
    fine: npt.NDArray[np.int32]
    count: int
    area: npt.NDArray[np.float64]

    def region_at(self, x: float, y: float) -> int:
        """The region holding the point (x, y) [m]: its cell's when sure, else that of the free sample of
        its cell nearest the point; 0 when the cell has none (or lies off the grid)."""
        row, col = self.geo.cell_of(x, y)
        if not self.geo.contains(row, col):
            return 0
        if self.coarse[row, col]:
            return int(self.coarse[row, col])
        m = int(self.mid[row, col])
        if m < 0:
            return 0
        labels = self.fine[m]
        ii, jj = np.nonzero(labels)
        if len(ii) == 0:
            return 0
        s = self.geo.cell / self.k
        x0 = self.geo.origin_x + col * self.geo.cell
        y0 = self.geo.origin_y + row * self.geo.cell
        d2 = (x0 + (jj + 0.5) * s - x) ** 2 + (y0 + (ii + 0.5) * s - y) ** 2
        best = int(np.argmin(d2))
        return int(labels[ii[best], jj[best]])

    def centre_labels(self) -> npt.NDArray[np.int32]:
        """Int32 (rows, cols): the region of each cell centre where the robot fits there (its clearance
        exceeds the radius): a sure cell's own, else that of the free sample nearest the centre; 0 where
        the robot does not fit at the centre."""
        out = self.coarse.copy()
        rr, cc = np.nonzero((self.mid >= 0) & (self.clear > self.radius + TOL))
        if len(rr):
            k = self.k
            ii, jj = np.divmod(np.arange(k * k), k)
            order = np.argsort((ii + 0.5 - k / 2) ** 2 + (jj + 0.5 - k / 2) ** 2, kind="stable")
            labels = self.fine[self.mid[rr, cc]].reshape(len(rr), k * k)[:, order]
            first = np.argmax(labels != 0, axis=1)
            out[rr, cc] = labels[np.arange(len(rr)), first]
        return out


def reach_regions(world: World, geo: GridGeometry, radius: float, *, occupied: npt.NDArray[np.bool_],
                  index: RayIndex | None = None, fine_step: float = FINE_STEP) -> Regions:
    """The connected regions of the places where a disc of `radius` [m] fits (clearance > radius) in
    `world`, on `geo` refined to `fine_step` [m] along the free space's border (see the module).

    Args:
        world: the world (its static boxes and discs).
        geo: the grid.
        radius: [m] the robot's radius (>= 0).
        occupied: bool (rows, cols) cells overlapping an obstacle (`groundtruth.occupancy`).
        index: `world_index(world)`, when already built.
        fine_step: [m] the border band's sample spacing (at most the cell; coarser when the band would
            hold more than MAX_SAMPLES samples, as on a very coarse grid).
    """
    if index is None:
        index = world_index(world)
    h = float(geo.cell)
    half_diag = h * math.sqrt(0.5)
    # a cell proven within radius - h/sqrt 2 of an obstacle is blocked whatever its exact clearance
    clear = clearance(world, geo, radius + h, index=index, occupied=occupied, floor=radius - half_diag)
    sure = clear > radius + half_diag + TOL
    band = ~sure & (clear + half_diag > radius + TOL)
    mr, mc = np.nonzero(band)
    mr, mc = mr.astype(np.int64), mc.astype(np.int64)
    k = max(1, min(math.ceil(h / fine_step - 1e-9), math.isqrt(MAX_SAMPLES // max(len(mr), 1))))
    mid = np.full((geo.rows, geo.cols), -1, np.int64)
    mid[mr, mc] = np.arange(len(mr), dtype=np.int64)
    fine = np.zeros((len(mr), k, k), np.bool_)
    step = max(1, CHUNK // (k * k))
    for a in range(0, len(mr), step):       # in parts: Ctrl-C and signals are handled between them
        b = a + step
        _fine_free(index.shapes, index.starts, index.items, index.origin[0], index.origin[1], index.bucket,
                   index.rows, index.cols, float(geo.origin_x), float(geo.origin_y), h, k, float(radius),
                   mr[a:b], mc[a:b], fine[a:b])
    lab_c, lab_f, count = _label(sure, mid, mr, mc, fine, k)
    area = np.bincount(lab_c.ravel(), minlength=count + 1).astype(np.float64) * h * h
    area += np.bincount(lab_f.ravel(), minlength=count + 1).astype(np.float64) * (h / k) ** 2
    area[0] = 0.0
    return Regions(geo, float(radius), k, clear, lab_c, mid, lab_f, int(count), area)
