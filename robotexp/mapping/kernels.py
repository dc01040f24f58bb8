"""Numba kernels of the occupancy grids.

Beam traversal, scan integration (log-odds, HIMM), rasterisation, frontiers, connected components,
distance transform, clearance, flood fill and laser visibility.

Every grid is a (rows, cols) array over a `GridGeometry` (row 0 at the bottom, smallest y). The
kernels are pure functions of arrays and scalars compiled by the one shared decorator `kernel`
(`cache=True`, no `fastmath`: max-range beams are `inf`). Their slow plain-numpy references live in
`robotexp.mapping.reference` and in the tests.

Beam convention (exact cell traversal, Amanatides & Woo 1987): a beam visits every cell its open
segment crosses with positive length, in order. Where a point lies exactly on a cell border, it
belongs to the cell the beam moves into (the "forward" cell), so a beam ending exactly on a face
ends in the cell behind that face, where the obstacle is. A beam passing through a corner (within
1e-9 cell) steps diagonally. Beams are clipped to the grid: cells outside are never touched.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numba
import numpy as np
import numpy.typing as npt

from robotexp.mapping.geometry import GridGeometry

__all__ = [
    "HIT_STEPS",
    "note_hits",
    "LogOddsModel",
    "clearance_mask",
    "edt_sq",
    "flood",
    "flood8",
    "frontier_mask",
    "integrate_scan_himm",
    "integrate_scan_logodds",
    "kernel",
    "label8",
    "rasterize",
    "strip_extent",
    "traverse",
    "view_free",
]

kernel = numba.njit(cache=True)

_TOL = 1e-9        # [m] or [cells]: contacts closer than this count as touching, not overlapping
_BIG = 1e20        # "infinite" squared distance inside the distance transform (inf - inf is NaN)


class LogOddsModel(NamedTuple):
    """The inverse sensor model of a log-odds grid (all values in log-odds, range in [m])."""

    l_free: float      # added to each cell a beam crosses before its end (< 0)
    l_occ: float       # added to the cell of a hit (> 0)
    l_min: float       # lower clamp
    l_max: float       # upper clamp
    range_max: float   # [m] beams at or beyond this range are free up to it and record no hit


@kernel
def _forward_index(g: float, d: float) -> int:
    """Index of the cell a ray with direction component `d` is in just after grid coordinate `g`."""
    if d < 0.0:
        return math.ceil(g) - 1
    return math.floor(g)


WRITE, LOGODDS, HIMM = 0, 1, 2     # what `_walk` does at each cell a beam crosses


@kernel
def _walk(geo: GridGeometry, x0: float, y0: float, dx: float, dy: float, length: float,  # noqa: PLR0913
          cells: npt.NDArray[np.int64], cap: int, mode: int, values: npt.NDArray[Any], stamp: npt.NDArray[np.int32],
          scan_id: int, hit: bool, l_free: float, l_min: float, l_max: float) -> tuple[int, bool, int]:
    """Visit the cells a beam crosses, in order from the sensor (at most `cap`): WRITE them into `cells`, or
    (LOGODDS, HIMM) lower each one this scan has not touched yet in `values` (log-odds: add `l_free` and clamp
    to [l_min, l_max]; HIMM certainty: less 1, floor 0) and stamp it `scan_id`, leaving out the end cell of a
    beam that ends in the grid with a `hit`. One walk serves the beam traversal (`traverse`) and the scan
    integration, which would otherwise write the cells out and read them back.

    Returns:
        (n, ended, lowered): the cells visited, whether the last holds the beam end (False when the beam
        left the grid, or never entered it, before its end), and the cells lowered.
    """
    cell = geo.cell
    rows = geo.rows
    cols = geo.cols
    gx = (x0 - geo.origin_x) / cell
    gy = (y0 - geo.origin_y) / cell
    glen = length / cell
    # Slab clipping of the ray (t >= 0, in cells) against the grid box.
    t_in = 0.0
    t_out = math.inf
    if dx != 0.0:
        ta = (0.0 - gx) / dx
        tb = (cols - gx) / dx
        t_in = max(t_in, min(ta, tb))
        t_out = min(t_out, max(ta, tb))
    elif gx < 0.0 or gx >= cols:
        return 0, False, 0
    if dy != 0.0:
        ta = (0.0 - gy) / dy
        tb = (rows - gy) / dy
        t_in = max(t_in, min(ta, tb))
        t_out = min(t_out, max(ta, tb))
    elif gy < 0.0 or gy >= rows:
        return 0, False, 0
    if t_in >= t_out or t_in > glen:
        return 0, False, 0
    c = min(max(_forward_index(gx + t_in * dx, dx), 0), cols - 1)
    r = min(max(_forward_index(gy + t_in * dy, dy), 0), rows - 1)
    sx = 1 if dx > 0.0 else -1
    sy = 1 if dy > 0.0 else -1
    # the next border's index offset per axis (1 ahead when moving up, 0 when moving down) and the
    # inverse direction (a multiplication per step instead of a division)
    bx = 1 if dx > 0.0 else 0
    by = 1 if dy > 0.0 else 0
    ix = 1.0 / dx if dx != 0.0 else 0.0
    iy = 1.0 / dy if dy != 0.0 else 0.0
    n = 0
    lowered = 0
    while n < cap:
        n += 1
        # Parameters of the next vertical / horizontal border, from the indices (no drift).
        tx = (c + bx - gx) * ix if dx != 0.0 else math.inf
        ty = (r + by - gy) * iy if dy != 0.0 else math.inf
        end = min(tx, ty) > glen
        if mode == WRITE:
            cells[n - 1, 0] = r
            cells[n - 1, 1] = c
        elif not (end and hit) and stamp[r, c] != scan_id:
            stamp[r, c] = scan_id
            if mode == LOGODDS:
                # Sum in float64 (explicitly: NumPy would keep float32), round once on the store.
                v = np.float64(values[r, c]) + l_free
                values[r, c] = min(max(v, l_min), l_max)
            else:
                values[r, c] = max(int(values[r, c]) - 1, 0)
            lowered += 1
        if end:
            return n, True, lowered
        if tx < ty - _TOL:
            c += sx
        elif ty < tx - _TOL:
            r += sy
        else:                 # through a corner (within 1e-9 cell): step diagonally
            c += sx
            r += sy
        if c < 0 or c >= cols or r < 0 or r >= rows:
            return n, False, lowered
    return n, False, lowered


@kernel
def traverse(geo: GridGeometry, x0: float, y0: float, dx: float, dy: float, length: float,
             cells: npt.NDArray[np.int64]) -> tuple[int, bool]:
    """Write the cells a beam crosses into `cells`, in order from the sensor.

    Args:
        geo: the grid.
        x0: [m] world x of the beam origin (may lie outside the grid).
        y0: [m] world y of the beam origin.
        dx: x component of the unit beam direction.
        dy: y component of the unit beam direction.
        length: [m] beam length (may be `inf`).
        cells: int64 (k, 2) output of (row, col) pairs; k >= rows + cols is always enough.

    Returns:
        (n, ended): the number of cells written and whether the last one holds the beam end
        (False when the beam left the grid, or never entered it, before its end).
    """
    n, ended, _ = _walk(geo, x0, y0, dx, dy, length, cells, cells.shape[0], WRITE, np.empty((0, 0), np.float32),
                        np.empty((0, 0), np.int32), 0, False, 0.0, 0.0, 0.0)
    return n, ended


@kernel
def _hit_cell(geo: GridGeometry, pose: npt.NDArray[np.float64], dx: float, dy: float, rng: float) -> tuple[int, int]:
    """(row, col) of the cell a hit at range `rng` [m] along the unit direction (`dx`, `dy`) from the sensor
    at `pose` ends in, as `traverse` ends; (-1, -1) off the grid."""
    r = _forward_index((pose[1] + rng * dy - geo.origin_y) / geo.cell, dy)
    c = _forward_index((pose[0] + rng * dx - geo.origin_x) / geo.cell, dx)
    if r < 0 or r >= geo.rows or c < 0 or c >= geo.cols:
        return -1, -1
    return r, c


@kernel
def nudged_ranges(ranges: npt.NDArray[np.float64], range_max: float, depth: float) -> npt.NDArray[np.float64]:
    """A copy of `ranges` [m] with each hit (a range below `range_max`) moved `depth` [m] further, but not to
    `range_max` or beyond; NaN, inf and the ranges at or beyond `range_max` are kept as they are."""
    out = ranges.copy()
    below = np.nextafter(range_max, 0.0)
    for i in range(out.shape[0]):
        if out[i] < range_max:
            out[i] = min(out[i] + depth, below)
    return out


BOX_LIMIT = 1e15    # [cells] `note_hits`' box beyond this (or not finite) is the whole grid
HIT_STEPS = 255     # a cell's hit box is kept in 1/HIT_STEPS of its side (uint8)


@kernel
def note_hits(hit_box: npt.NDArray[np.uint8], geo: GridGeometry, pose: npt.NDArray[np.float64],
              angles: npt.NDArray[np.float64], ranges: npt.NDArray[np.float64], nudged: npt.NDArray[np.float64],
              range_max: float) -> tuple[int, int, int, int]:
    """Grow each hit cell's box of laser endpoints by the endpoints of one scan; return the box of cells
    the scan's beams cross or end in.

    `hit_box` (rows, cols, 4) uint8 holds per cell x_lo, x_hi, y_lo, y_hi of the endpoints that fell in it,
    in 1/HIT_STEPS of the cell's side from its lower-left corner, rounded outwards (the box holds every
    endpoint); x_lo > x_hi: no endpoint yet. The cell of a hit is the cell the scan integration marks
    (`_hit_cell` at the `nudged` range); its endpoint is the measured one (`ranges`), clamped into that cell.

    The box returned, rows r0..r1 and columns c0..c1 (half-open, not clipped to the grid), holds every cell
    the integration (`integrate_scan_logodds`) may touch: the box of the sensor's cell and each beam's end
    (its `nudged` range, or `range_max` for a beam that records no hit; NaN and negative ranges are skipped,
    as the integration skips them), a cell of slack on each side for rounding. A beam is a segment, so its
    cells lie in the box of its ends. A pose or an end not finite (or beyond any index): the whole grid.

    Args:
        hit_box: (rows, cols, 4) uint8, updated in place.
        geo: the grid.
        pose: float64 (3,) sensor x [m], y [m], heading [rad].
        angles: float64 (n,) beam angles [rad] relative to the heading.
        ranges: float64 (n,) measured ranges [m].
        nudged: float64 (n,) the ranges the integration used (a hit nudged into its obstacle).
        range_max: [m] beams at or beyond this range record no hit.
    """
    x0 = (pose[0] - geo.origin_x) / geo.cell
    y0 = (pose[1] - geo.origin_y) / geo.cell
    if not (abs(x0) < BOX_LIMIT and abs(y0) < BOX_LIMIT and math.isfinite(pose[2])):
        return 0, geo.rows, 0, geo.cols         # a pose not finite, or beyond any index: no hit has a cell
    whole = False
    xl, xh, yl, yh = x0, x0, y0, y0
    for i in range(angles.shape[0]):
        rng = nudged[i]
        if math.isnan(rng) or rng < 0.0:
            continue
        a = pose[2] + angles[i]
        dx = math.cos(a)
        dy = math.sin(a)
        end = min(rng, range_max) / geo.cell
        if whole or not end < BOX_LIMIT:        # a reach not finite, or beyond any index: the whole grid
            whole = True
            end = 0.0
        xl, xh = min(xl, x0 + end * dx), max(xh, x0 + end * dx)
        yl, yh = min(yl, y0 + end * dy), max(yh, y0 + end * dy)
        if rng >= range_max:
            continue
        r, c = _hit_cell(geo, pose, dx, dy, rng)
        if r < 0:
            continue
        fx = (pose[0] + ranges[i] * dx - geo.origin_x) / geo.cell - c
        fy = (pose[1] + ranges[i] * dy - geo.origin_y) / geo.cell - r
        fx = min(max(fx, 0.0), 1.0) * HIT_STEPS
        fy = min(max(fy, 0.0), 1.0) * HIT_STEPS
        hxl, hxh = np.uint8(math.floor(fx)), np.uint8(math.ceil(fx))
        hyl, hyh = np.uint8(math.floor(fy)), np.uint8(math.ceil(fy))
        if hit_box[r, c, 0] > hit_box[r, c, 1]:
            hit_box[r, c, 0], hit_box[r, c, 1], hit_box[r, c, 2], hit_box[r, c, 3] = hxl, hxh, hyl, hyh
        else:
            hit_box[r, c, 0] = min(hit_box[r, c, 0], hxl)
            hit_box[r, c, 1] = max(hit_box[r, c, 1], hxh)
            hit_box[r, c, 2] = min(hit_box[r, c, 2], hyl)
            hit_box[r, c, 3] = max(hit_box[r, c, 3], hyh)
    if whole or not (abs(xl) < BOX_LIMIT and abs(xh) < BOX_LIMIT and abs(yl) < BOX_LIMIT and abs(yh) < BOX_LIMIT):
        return 0, geo.rows, 0, geo.cols
    return math.floor(yl) - 1, math.floor(yh) + 2, math.floor(xl) - 1, math.floor(xh) + 2


@kernel
def integrate_scan_logodds(logodds: npt.NDArray[np.float32], stamp: npt.NDArray[np.int32], scan_id: int,
                           geo: GridGeometry, pose: npt.NDArray[np.float64],
                           angles: npt.NDArray[np.float64], ranges: npt.NDArray[np.float64],
                           model: LogOddsModel) -> int:
    """Add one scan to `logodds` (rows, cols) float32 in place; return the number of cells updated.

    Each cell is updated at most once per scan, as in the cell-wise inverse sensor model of
    Thrun et al. (Probabilistic Robotics, table 9.2), and a hit wins: the end cell of a hit gets
    `l_occ` even when other beams of the same scan cross it. Without this rule, beams grazing a
    wall clear the cells its face lies in (those cells are partly free) as fast as the beams that
    hit it mark them. The cells a beam crosses before its end cell get `l_free`; a beam with
    range >= `model.range_max` (or `inf`) records no hit and frees every cell up to `range_max`.
    Values are clamped to [l_min, l_max]; NaN and negative ranges are skipped.

    Args:
        logodds: float32 (rows, cols) log-odds, updated in place.
        stamp: int32 (rows, cols): the id of the last scan that touched each cell (0: never);
            cells this scan touches are set to `scan_id`.
        scan_id: > 0 and different from every earlier scan's id.
        geo: the grid.
        pose: float64 (3,) sensor x [m], y [m], heading [rad].
        angles: float64 (n,) beam angles [rad] relative to the heading.
        ranges: float64 (n,) measured ranges [m].
        model: the inverse sensor model.

    Returns:
        The number of cells this scan updated.
    """
    touched = 0
    for i in range(angles.shape[0]):        # hits first: they need no traversal
        rng = ranges[i]
        if not (0.0 <= rng < model.range_max):
            continue
        a = pose[2] + angles[i]
        r, c = _hit_cell(geo, pose, math.cos(a), math.sin(a), rng)
        if r < 0 or stamp[r, c] == scan_id:
            continue
        stamp[r, c] = scan_id
        # Sum in float64 (explicitly: NumPy would keep float32), round once on the store.
        v = np.float64(logodds[r, c]) + model.l_occ
        logodds[r, c] = min(max(v, model.l_min), model.l_max)
        touched += 1
    cap = geo.rows + geo.cols + 1
    no_cells = np.empty((0, 2), np.int64)   # `_walk` lowers the cells, it does not write them out
    for i in range(angles.shape[0]):        # then the free cells no hit claimed
        rng = ranges[i]
        if math.isnan(rng) or rng < 0.0:
            continue
        a = pose[2] + angles[i]
        hit = rng < model.range_max
        touched += _walk(geo, pose[0], pose[1], math.cos(a), math.sin(a), rng if hit else model.range_max, no_cells,
                         cap, LOGODDS, logodds, stamp, scan_id, hit, model.l_free, model.l_min, model.l_max)[2]
    return touched


@kernel
def integrate_scan_himm(cert: npt.NDArray[np.uint8], stamp: npt.NDArray[np.int32], scan_id: int,
                        geo: GridGeometry, pose: npt.NDArray[np.float64], angles: npt.NDArray[np.float64],
                        ranges: npt.NDArray[np.float64], range_max: float) -> int:
    """Add one scan to the HIMM certainty grid `cert` (rows, cols) uint8 in place (Borenstein & Koren).

    The end cell of a hit gains 3 (cap 15); cells a beam crosses lose 1 (floor 0). Each cell is
    updated at most once per scan and a hit wins, as in `integrate_scan_logodds`, whose `stamp`,
    `scan_id`, clipping and return value this follows; `range_max` is in [m].
    """
    touched = 0
    for i in range(angles.shape[0]):        # hits first: they need no traversal
        rng = ranges[i]
        if not (0.0 <= rng < range_max):
            continue
        a = pose[2] + angles[i]
        r, c = _hit_cell(geo, pose, math.cos(a), math.sin(a), rng)
        if r < 0 or stamp[r, c] == scan_id:
            continue
        stamp[r, c] = scan_id
        cert[r, c] = min(int(cert[r, c]) + 3, 15)
        touched += 1
    cap = geo.rows + geo.cols + 1
    no_cells = np.empty((0, 2), np.int64)   # `_walk` lowers the cells, it does not write them out
    for i in range(angles.shape[0]):        # then the free cells no hit claimed
        rng = ranges[i]
        if math.isnan(rng) or rng < 0.0:
            continue
        a = pose[2] + angles[i]
        hit = rng < range_max
        touched += _walk(geo, pose[0], pose[1], math.cos(a), math.sin(a), rng if hit else range_max, no_cells,
                         cap, HIMM, cert, stamp, scan_id, hit, 0.0, 0.0, 0.0)[2]
    return touched


@kernel
def strip_extent(corners: npt.NDArray[np.float64], ya: float, yb: float) -> tuple[float, float]:
    """The x extent (lo, hi) of the convex polygon `corners` (n, 2), in order around it, within the strip
    ya <= y <= yb: the extremes of its edges clipped to the strip (lo > hi: the strip misses it)."""
    lo, hi = math.inf, -math.inf
    n = corners.shape[0]
    for j in range(n):
        px, py = corners[j, 0], corners[j, 1]
        qx, qy = corners[(j + 1) % n, 0], corners[(j + 1) % n, 1]
        if (py < ya and qy < ya) or (py > yb and qy > yb):
            continue
        if py == qy:
            lo, hi = min(lo, px, qx), max(hi, px, qx)
            continue
        for y in (min(max(py, ya), yb), min(max(qy, ya), yb)):     # the edge's ends within the strip
            t = min(max((y - py) / (qy - py), 0.0), 1.0)
            x = px + t * (qx - px)
            lo, hi = min(lo, x), max(hi, x)
    return lo, hi


@kernel
def rasterize(occ: npt.NDArray[np.bool_], geo: GridGeometry, boxes: npt.NDArray[np.float64],
              discs: npt.NDArray[np.float64]) -> None:
    """Set `occ` (rows, cols) where a cell's square overlaps an obstacle with positive area.

    Boxes (n, 5) are [cx, cy, half_x, half_y, yaw] [m, rad], tested exactly by separating axes;
    discs (m, 3) are [cx, cy, r] [m], overlapping when the square is nearer than r to the centre.
    Contacts within 1e-9 m (a face lying on a cell border) do not count.
    """
    h = 0.5 * geo.cell
    corners = np.empty((4, 2))
    for k in range(boxes.shape[0]):
        cx, cy, hx, hy, yaw = boxes[k, 0], boxes[k, 1], boxes[k, 2], boxes[k, 3], boxes[k, 4]
        ca = math.cos(yaw)
        sa = math.sin(yaw)
        ex = abs(hx * ca) + abs(hy * sa)
        ey = abs(hx * sa) + abs(hy * ca)
        cell_proj = h * (abs(ca) + abs(sa))    # half extent of a cell along the box axes
        c0 = max(math.floor((cx - ex - geo.origin_x) / geo.cell), 0)
        c1 = min(math.floor((cx + ex - geo.origin_x) / geo.cell), geo.cols - 1)
        r0 = max(math.floor((cy - ey - geo.origin_y) / geo.cell), 0)
        r1 = min(math.floor((cy + ey - geo.origin_y) / geo.cell), geo.rows - 1)
        for j in range(4):      # the corners, relative to the centre, in order around the box
            sx = 1.0 if j == 0 or j == 3 else -1.0
            sy = 1.0 if j < 2 else -1.0
            corners[j, 0] = sx * hx * ca - sy * hy * sa
            corners[j, 1] = sx * hx * sa + sy * hy * ca
        for r in range(r0, r1 + 1):
            qy = geo.origin_y + (r + 0.5) * geo.cell - cy
            if ey + h - abs(qy) <= _TOL:
                continue
            # the row's columns that can overlap the box: those meeting the x extent of the box within the
            # row's strip (its edges clipped to the strip), a cell of slack each side; the tests below decide
            lo, hi = strip_extent(corners, qy - h, qy + h)
            if lo > hi:
                continue
            ca0 = max(c0, math.floor((cx + lo - geo.origin_x) / geo.cell) - 1)
            ca1 = min(c1, math.floor((cx + hi - geo.origin_x) / geo.cell) + 1)
            for c in range(ca0, ca1 + 1):
                if occ[r, c]:           # set already (by another box, or before this call)
                    continue
                qx = geo.origin_x + (c + 0.5) * geo.cell - cx
                if ex + h - abs(qx) <= _TOL:
                    continue
                if hx + cell_proj - abs(qx * ca + qy * sa) <= _TOL:
                    continue
                if hy + cell_proj - abs(qy * ca - qx * sa) <= _TOL:
                    continue
                occ[r, c] = True
    for k in range(discs.shape[0]):
        cx, cy, rad = discs[k, 0], discs[k, 1], discs[k, 2]
        c0 = max(math.floor((cx - rad - geo.origin_x) / geo.cell), 0)
        c1 = min(math.floor((cx + rad - geo.origin_x) / geo.cell), geo.cols - 1)
        r0 = max(math.floor((cy - rad - geo.origin_y) / geo.cell), 0)
        r1 = min(math.floor((cy + rad - geo.origin_y) / geo.cell), geo.rows - 1)
        for r in range(r0, r1 + 1):
            qy = geo.origin_y + (r + 0.5) * geo.cell
            ny = min(max(cy, qy - h), qy + h)
            for c in range(c0, c1 + 1):
                qx = geo.origin_x + (c + 0.5) * geo.cell
                nx = min(max(cx, qx - h), qx + h)
                if math.sqrt((cx - nx) ** 2 + (cy - ny) ** 2) < rad - _TOL:
                    occ[r, c] = True


@kernel
def merge_boxes(boxes: npt.NDArray[np.int32], grow: int) -> npt.NDArray[np.int32]:
    """The non-empty boxes (n, 4) int32 rows r0..r1, cols c0..c1 (half-open), those whose boxes grown by `grow`
    cells overlap or touch replaced by their bounding box, repeatedly until no two of the result do: (m, 4)
    int32, in the order each merged box was last grown."""
    out = np.empty((len(boxes), 4), np.int32)
    m = 0
    for i in range(len(boxes)):
        r0, r1, c0, c1 = boxes[i, 0], boxes[i, 1], boxes[i, 2], boxes[i, 3]
        if r1 <= r0 or c1 <= c0:
            continue
        merged = True
        while merged:       # absorb every box the grown current one meets; again with the grown result
            merged = False
            j = 0
            while j < m:
                if (out[j, 0] - grow <= r1 + grow and r0 - grow <= out[j, 1] + grow
                        and out[j, 2] - grow <= c1 + grow and c0 - grow <= out[j, 3] + grow):
                    r0, r1 = min(r0, out[j, 0]), max(r1, out[j, 1])
                    c0, c1 = min(c0, out[j, 2]), max(c1, out[j, 3])
                    out[j] = out[m - 1]
                    m -= 1
                    merged = True
                else:
                    j += 1
        out[m, 0], out[m, 1], out[m, 2], out[m, 3] = r0, r1, c0, c1
        m += 1
    return out[:m].copy()


@kernel
def frontier_mask(free: npt.NDArray[np.bool_], unknown: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """Bool (rows, cols): free cells with an unknown 4-neighbour (outside the grid is not unknown)."""
    rows, cols = free.shape
    out = np.zeros((rows, cols), np.bool_)
    for r in range(rows):
        for c in range(cols):
            if free[r, c] and ((r > 0 and unknown[r - 1, c]) or (r + 1 < rows and unknown[r + 1, c])
                               or (c > 0 and unknown[r, c - 1]) or (c + 1 < cols and unknown[r, c + 1])):
                out[r, c] = True
    return out


@kernel
def label8(mask: npt.NDArray[np.bool_]) -> tuple[npt.NDArray[np.int32], int]:
    """8-connected components of `mask` (rows, cols).

    Returns:
        (labels, k): int32 (rows, cols) labels, 0 outside the mask and 1..k inside, numbered in
        row-major order of each component's first cell; and the number of components k.
    """
    rows, cols = mask.shape
    labels = np.zeros((rows, cols), np.int32)
    stack = np.empty(rows * cols, np.int64)
    k = 0
    for r0 in range(rows):
        for c0 in range(cols):
            if not mask[r0, c0] or labels[r0, c0] != 0:
                continue
            k += 1
            labels[r0, c0] = k
            top = 0
            stack[top] = r0 * cols + c0
            top += 1
            while top > 0:
                top -= 1
                r = stack[top] // cols
                c = stack[top] % cols
                for rr in range(max(r - 1, 0), min(r + 2, rows)):
                    for cc in range(max(c - 1, 0), min(c + 2, cols)):
                        if mask[rr, cc] and labels[rr, cc] == 0:
                            labels[rr, cc] = k
                            stack[top] = rr * cols + cc
                            top += 1
    return labels, k


@kernel
def flood(mask: npt.NDArray[np.bool_], row: int, col: int, diagonal: bool) -> npt.NDArray[np.bool_]:
    """Bool (rows, cols): the connected component of `mask` holding cell (row, col), 8-connected when
    `diagonal`, else 4-connected (empty when (row, col) is outside or unset)."""
    rows, cols = mask.shape
    out = np.zeros((rows, cols), np.bool_)
    if row < 0 or row >= rows or col < 0 or col >= cols or not mask[row, col]:
        return out
    stack = np.empty(rows * cols, np.int64)
    out[row, col] = True
    stack[0] = row * cols + col
    top = 1
    while top > 0:
        top -= 1
        r = stack[top] // cols
        c = stack[top] % cols
        if not diagonal:        # the 4 neighbours written out (a 3 x 3 loop skipping corners took twice as long)
            if r > 0:
                top = _push(mask, out, stack, top, r - 1, c, cols)
            if r + 1 < rows:
                top = _push(mask, out, stack, top, r + 1, c, cols)
            if c > 0:
                top = _push(mask, out, stack, top, r, c - 1, cols)
            if c + 1 < cols:
                top = _push(mask, out, stack, top, r, c + 1, cols)
            continue
        for rr in range(max(r - 1, 0), min(r + 2, rows)):
            for cc in range(max(c - 1, 0), min(c + 2, cols)):
                top = _push(mask, out, stack, top, rr, cc, cols)
    return out


@kernel
def _push(mask: npt.NDArray[np.bool_], out: npt.NDArray[np.bool_], stack: npt.NDArray[np.int64], top: int,
          r: int, c: int, cols: int) -> int:
    """Mark cell (r, c) and stack it when it is in `mask` and not marked yet; the new stack top."""
    if mask[r, c] and not out[r, c]:
        out[r, c] = True
        stack[top] = r * cols + c
        return top + 1
    return top


@kernel
def flood8(mask: npt.NDArray[np.bool_], row: int, col: int) -> npt.NDArray[np.bool_]:
    """Bool (rows, cols): the 8-connected component of `mask` holding cell (row, col) (empty if unset)."""
    return flood(mask, row, col, True)


@kernel
def _edt_1d(f: npt.NDArray[np.float64], d: npt.NDArray[np.float64], v: npt.NDArray[np.int64],
            z: npt.NDArray[np.float64]) -> None:
    """Lower envelope of parabolas (Felzenszwalb & Huttenlocher 2012): d[q] = min_p (q-p)^2 + f[p]."""
    n = f.shape[0]
    k = 0
    v[0] = 0
    z[0] = -math.inf
    z[1] = math.inf
    for q in range(1, n):
        s = ((f[q] + q * q) - (f[v[k]] + v[k] * v[k])) / (2 * q - 2 * v[k])
        while s <= z[k]:
            k -= 1
            s = ((f[q] + q * q) - (f[v[k]] + v[k] * v[k])) / (2 * q - 2 * v[k])
        k += 1
        v[k] = q
        z[k] = s
        z[k + 1] = math.inf
    k = 0
    for q in range(n):
        while z[k + 1] < q:
            k += 1
        d[q] = (q - v[k]) ** 2 + f[v[k]]


@kernel
def edt_sq(occ: npt.NDArray[np.bool_]) -> npt.NDArray[np.float64]:
    """Exact squared Euclidean distance [cells^2] from each cell centre to the nearest set cell centre.

    Returns float64 (rows, cols); `inf` everywhere when `occ` has no set cell.
    """
    rows, cols = occ.shape
    n = max(rows, cols)
    f = np.empty(n, np.float64)
    d = np.empty(n, np.float64)
    v = np.empty(n, np.int64)
    z = np.empty(n + 1, np.float64)
    out = np.empty((rows, cols), np.float64)
    for c in range(cols):
        for r in range(rows):
            f[r] = 0.0 if occ[r, c] else _BIG
        _edt_1d(f[:rows], d[:rows], v, z)
        for r in range(rows):
            out[r, c] = d[r]
    for r in range(rows):
        for c in range(cols):
            f[c] = out[r, c]
        _edt_1d(f[:cols], d[:cols], v, z)
        for c in range(cols):
            out[r, c] = d[c] if d[c] < 0.5 * _BIG else math.inf
    return out


@kernel
def clearance_mask(occ: npt.NDArray[np.bool_], radius: float) -> npt.NDArray[np.bool_]:
    """Bool (rows, cols): cells whose centre is farther than `radius` [cells] from every set square.

    Exact: the distance transform to set cell centres settles all but a band of cells, which are
    checked against each set square near them. A distance equal to `radius` (within 1e-9) blocks.
    """
    rows, cols = occ.shape
    d2 = edt_sq(occ)
    out = np.zeros((rows, cols), np.bool_)
    lim = radius + _TOL
    w = int(radius + 0.5) + 1
    for r in range(rows):
        for c in range(cols):
            d = math.sqrt(d2[r, c])
            if d - 0.5 <= lim:          # the nearest centre's square lies within d - 0.5
                continue
            if d - math.sqrt(0.5) > lim:  # every square lies beyond its centre distance - sqrt(1/2)
                out[r, c] = True
                continue
            best = math.inf
            for rr in range(max(r - w, 0), min(r + w + 1, rows)):
                ay = max(abs(rr - r) - 0.5, 0.0)
                for cc in range(max(c - w, 0), min(c + w + 1, cols)):
                    if occ[rr, cc]:
                        ax = max(abs(cc - c) - 0.5, 0.0)
                        best = min(best, ax * ax + ay * ay)
            out[r, c] = math.sqrt(best) > lim
    return out


@kernel
def view_free(occ: npt.NDArray[np.bool_], views: npt.NDArray[np.int64], offsets: npt.NDArray[np.int64],
              skip: npt.NDArray[np.int64]) -> npt.NDArray[np.bool_]:
    """Bool (rows, cols): free cells seen from the cells `views` (k, 2) through a tree of rays.

    The rays of a laser at a cell centre cross the same cell offsets wherever the cell is, so they
    are given once as a prefix tree in depth-first order: node j is the cell offset `offsets[j]`
    (drow, dcol), node 0 the viewpoint itself, and `skip[j]` the first node after j's subtree. A
    node is seen when it lies in the grid and neither it nor an ancestor is set in `occ`; a ray
    stopped by an occupied cell or by the grid edge stops all its descendants (rays are monotone
    along each axis, so a ray that left the grid never re-enters).
    """
    rows, cols = occ.shape
    seen = np.zeros((rows, cols), np.bool_)
    n = offsets.shape[0]
    for k in range(views.shape[0]):
        vr = views[k, 0]
        vc = views[k, 1]
        j = 0
        while j < n:
            r = vr + offsets[j, 0]
            c = vc + offsets[j, 1]
            if r < 0 or r >= rows or c < 0 or c >= cols or occ[r, c]:
                j = skip[j]
            else:
                seen[r, c] = True
                j += 1
    return seen
