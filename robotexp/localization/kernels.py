"""Numba kernels of the scan matcher: likelihood field, correlative search, Gauss-Newton refinement.

A likelihood field is a float64 (rows, cols) array over a `GridGeometry`: at each cell centre, a
Gaussian of the distance to the nearest laser hit of the map (`splat_field`). Scan points are
given in the robot frame as two float64 arrays `px`, `py` [m]; a pose (x, y, theta) maps point i to
(x + c px - s py, y + s px + c py). Points outside the field score 0.

`search` is the correlative matcher (Olson 2009): it scores every pose of a window of x, y offsets
(multiples of a step of whole cells) and headings by the sum of the field under the points, looked
up in the cell that holds each point, less a quadratic prior around the prediction (Olson's motion
model: in a corridor or a symmetric room the nearest of the good poses wins). Run on a max-pooled
field (`pool_max`) the scores bound the fine ones from above, which is what makes coarse-to-fine
search sound. `refine` is Gauss-Newton on
the bilinearly interpolated field (Kohlbrecher et al. 2011, Hector SLAM): it minimises
sum_i (1 - M(S_i(pose)))^2 and returns the normal matrix, whose conditioning tells a corridor.

`refine_hits` is Gauss-Newton on the field evaluated exactly at each point (`hit_value`: the Gaussian
of the distance to the nearest wall segment through the cells' hit points), not interpolated between
samples, with Welsch's robust cost sum_i (1 - M) instead of (1 - M)^2. Interpolated, the field is
biased at sub-cell scale: a wall whose hit points lie on a border between two cells has two equal
samples, one either side, and between them the bilinear field is flat, so the pose slides up to half
a cell across it at no cost; and (1 - M)^2 is quartic near its optimum, so the motion prior keeps a
part of every small correction. (A scan matched against a map made of itself, from its true pose,
ended 0.5-2.5 cm and 0.1-0.5 deg off with `refine`; see docs/localization.)

Every kernel has a plain-numpy reference in `robotexp.localization.reference` (tested equal).
"""

from __future__ import annotations

import math

import numba
import numpy as np
import numpy.typing as npt

__all__ = ["kernel", "mean_field", "objective", "splat_field", "pool_max", "search", "refine", "bilinear",
           "hit_points", "wall_offset", "hit_value", "refine_hits", "objective_hits", "mean_hits", "add_hits", "warm"]

kernel = numba.njit(cache=True, nogil=True)

# `hit_points`: (index of the occupied cells (rows, cols) int32, their wall segments (n, 8) float64, how far [cells]
# the open ends carry a segment on: OPEN_REACH when some end is open, else 0)
HitSegments = tuple[npt.NDArray[np.int32], npt.NDArray[np.float64], float]

DAMPING = 1e-4     # added to the normal matrix's diagonal, times its trace (the least Levenberg-Marquardt damping)
RETRIES = 4        # tries of a step with ten times more damping each before Gauss-Newton stops


@kernel
def splat_field(occ: npt.NDArray[np.bool_], off_x: npt.NDArray[np.float32], off_y: npt.NDArray[np.float32],
                cell: float, sigma: float, reach: int) -> npt.NDArray[np.float64]:
    """The likelihood field of hit points: at each cell centre, exp(-d^2 / (2 sigma^2)) with d [m] the least
    distance to the mean hit point of an occupied cell within `reach` cells (rows and columns) when
    d <= reach + 0.5 cells, else 0; a cell's mean hit point lies (off_x, off_y) [cells] from its
    centre (0, 0 when only the cell is known).

    Matching against cell centres would pull a scan by up to half a cell towards the walls it faces
    (a forward-looking laser sees most walls ahead); the hit points do not."""
    rows, cols = occ.shape
    d2 = np.full((rows, cols), np.inf)          # the least squared distance [cells^2], then its Gaussian
    r2 = (reach + 0.5) * (reach + 0.5)          # nothing beyond the reach (the Gaussian is ~0 there anyway)
    for r in range(rows):
        for c in range(cols):
            if not occ[r, c]:
                continue
            hx = c + float(off_x[r, c])      # in float64, as compiled
            hy = r + float(off_y[r, c])
            for rr in range(max(r - reach, 0), min(r + reach + 1, rows)):
                dy = rr - hy
                for cc in range(max(c - reach, 0), min(c + reach + 1, cols)):
                    dx = cc - hx
                    q = dx * dx + dy * dy
                    if q < d2[rr, cc]:
                        d2[rr, cc] = q
    out = np.zeros((rows, cols), np.float64)
    k = -cell * cell / (2.0 * sigma * sigma)
    for r in range(rows):
        for c in range(cols):
            if d2[r, c] <= r2:
                out[r, c] = math.exp(k * d2[r, c])
    return out


@kernel
def pool_max(field: npt.NDArray[np.float64], factor: int) -> npt.NDArray[np.float64]:
    """Max over blocks of factor x factor cells: coarse cell (R, C) covers fine rows R*f..R*f+f-1."""
    rows, cols = field.shape
    cr = (rows + factor - 1) // factor
    cc = (cols + factor - 1) // factor
    out = np.zeros((cr, cc), np.float64)
    for r in range(rows):
        for c in range(cols):
            v = field[r, c]
            if v > out[r // factor, c // factor]:
                out[r // factor, c // factor] = v
    return out


@kernel
def search(field: npt.NDArray[np.float64], ox: float, oy: float, cell: float,
           px: npt.NDArray[np.float64], py: npt.NDArray[np.float64],
           x0: float, y0: float, th0: float, nxy: int, step: int, nth: int, dth: float,
           cx: float, cy: float, cth: float, kxy: float, kth: float,
           ) -> tuple[float, float, float, float]:
    """Best pose of the window x0 + i*step*cell, y0 + j*step*cell (|i|, |j| <= nxy), th0 + k*dth (|k| <= nth).

    A pose scores the sum of the field under the points minus a prior penalty
    kxy ((x - cx)^2 + (y - cy)^2) + kth (theta - cth)^2 around the prediction (cx, cy, cth).

    Args:
        field: the (pooled) field; cell (r, c) covers [ox + c cell, ox + (c+1) cell) in x.
        ox, oy: [m] lower-left corner of the field.
        cell: [m] the field's cell size.
        px, py: [m] the scan points in the robot frame.
        x0, y0, th0: the window's centre pose [m, m, rad].
        nxy: half-width of the x and y window in steps.
        step: the x, y step in cells of this field.
        nth: half-width of the heading window in steps.
        dth: [rad] the heading step.
        cx, cy, cth: the prediction the prior is centred on.
        kxy: [1/m^2] weight of the prior on position.
        kth: [1/rad^2] weight of the prior on heading.

    Returns:
        (x, y, theta, score): the best pose and its score (penalised sum of the field). Ties
        go to the pose nearest the centre (offsets in steps, squared), then the first in scan order.
    """
    n = px.shape[0]
    rows, cols = field.shape
    rr = np.empty(n, np.int64)
    cc = np.empty(n, np.int64)
    best = -1.0
    best_d = 1 << 60
    bx, by, bth = x0, y0, th0
    span = nxy * step
    for k in range(-nth, nth + 1):
        th = th0 + k * dth
        pen_th = kth * (th - cth) * (th - cth)
        c, s = math.cos(th), math.sin(th)
        for i in range(n):
            cc[i] = math.floor((x0 + c * px[i] - s * py[i] - ox) / cell)
            rr[i] = math.floor((y0 + s * px[i] + c * py[i] - oy) / cell)
        for j in range(-span, span + 1, step):
            for i2 in range(-span, span + 1, step):
                ex = x0 + i2 * cell - cx
                ey = y0 + j * cell - cy
                total = -pen_th - kxy * (ex * ex + ey * ey)
                for i in range(n):
                    r = rr[i] + j
                    q = cc[i] + i2
                    if 0 <= r < rows and 0 <= q < cols:
                        total += field[r, q]
                d = (i2 // step) ** 2 + (j // step) ** 2 + k * k
                if total > best + 1e-9 or (total > best - 1e-9 and d < best_d):
                    best = total
                    best_d = d
                    bx = x0 + i2 * cell
                    by = y0 + j * cell
                    bth = th
    return bx, by, bth, best


@kernel
def bilinear(field: npt.NDArray[np.float64], gx: float, gy: float) -> tuple[float, float, float]:
    """Bilinear value and gradient [per cell] of `field` at grid coordinates (gx, gy) [cells].

    Sample (r, c) sits at the centre of its cell, grid coordinates (c + 0.5, r + 0.5); outside the
    samples the field is 0 (value and gradient)."""
    rows, cols = field.shape
    fx = gx - 0.5
    fy = gy - 0.5
    c0 = math.floor(fx)
    r0 = math.floor(fy)
    if c0 < 0 or r0 < 0 or c0 + 1 >= cols or r0 + 1 >= rows:
        return 0.0, 0.0, 0.0
    ax = fx - c0
    ay = fy - r0
    m00 = field[r0, c0]
    m01 = field[r0, c0 + 1]
    m10 = field[r0 + 1, c0]
    m11 = field[r0 + 1, c0 + 1]
    value = (1 - ay) * ((1 - ax) * m00 + ax * m01) + ay * ((1 - ax) * m10 + ax * m11)
    dx = (1 - ay) * (m01 - m00) + ay * (m11 - m10)
    dy = (1 - ax) * (m10 - m00) + ax * (m11 - m01)
    return value, dx, dy


LINE_RATIO = 0.1   # hit points of a 3 x 3 block this close to a line (eigenvalue ratio) make a wall segment
OVERLAP = 0.01     # [cells] a cell's wall segment reaches this far beyond the cell (no crack between neighbours)
OPEN_REACH = 1.5   # [cells] a wall segment goes on this far past an end beyond which the map has seen nothing


@kernel
def _clip(h: float, u: float, lo: float, hi: float) -> tuple[float, float]:
    """The range of t for which h + t u lies in [lo, hi] (all of it when u = 0)."""
    if u == 0.0:
        return -math.inf, math.inf
    a = (lo - h) / u
    b = (hi - h) / u
    return (a, b) if a <= b else (b, a)


@kernel
def hit_points(occ: npt.NDArray[np.bool_], off_x: npt.NDArray[np.float32], off_y: npt.NDArray[np.float32],  # noqa: C901
               known: npt.NDArray[np.bool_]) -> tuple[npt.NDArray[np.int32], npt.NDArray[np.float64], float]:
    """The hit point of every occupied cell in grid coordinates [cells] (cell (r, c) spans [c, c + 1) in x)
    and the wall segment through it, as (index, segments, reach): index (rows, cols) int32 numbers the occupied
    cells in row order (-1 elsewhere), segments (n, 8) holds each one's x, y, ux, uy, t0, t1, open0, open1, and
    reach is OPEN_REACH when some end is open, else 0 (`wall_offset`'s search stops the sooner).

    The segment is the points (x, y) + t (ux, uy), t0 <= t <= t1: the line through the hit point clipped
    to the cell (OVERLAP wider), so that the segments of a wall's cells join up with neither gap nor
    overhang. A cell's hit point lies (off_x, off_y) [cells] from its centre (as in `splat_field`); the
    direction is the principal axis of the hit points of the occupied cells of the 3 x 3 block around it
    when they lie along a line (smaller / larger eigenvalue of their scatter below LINE_RATIO, at least
    two of them), else (0, 0) and t0 = t1 = 0: a lone point.

    open0 (open1) is 1.0 where the wall may go on past the t0 (t1) end: a cell 0.5 or 1.5 cells beyond it
    along the line lies in the grid, is not occupied and the map has never seen it (`known` false). That
    end is where the map stopped seeing the wall (the laser's reach), not where the wall ends, and
    `wall_offset` carries the segment on by OPEN_REACH there: a scan point on the wall just past the
    mapped part is not pulled back to the end (in a corridor, such pulls took a few percent off every
    metre driven)."""
    rows, cols = occ.shape
    index = np.full((rows, cols), -1, np.int32)
    n = 0
    for r in range(rows):
        for c in range(cols):
            if occ[r, c]:
                index[r, c] = n
                n += 1
    seg = np.zeros((n, 8))
    ext = 0.0
    for r in range(rows):
        for c in range(cols):
            i = index[r, c]
            if i >= 0:
                seg[i, 0] = c + 0.5 + float(off_x[r, c])      # in float64, as compiled
                seg[i, 1] = r + 0.5 + float(off_y[r, c])
    for r in range(rows):
        for c in range(cols):
            i = index[r, c]
            if i < 0:
                continue
            m = 0
            sx = sy = 0.0
            for rr in range(max(r - 1, 0), min(r + 2, rows)):
                for cc in range(max(c - 1, 0), min(c + 2, cols)):
                    j = index[rr, cc]
                    if j >= 0:
                        m += 1
                        sx += seg[j, 0]
                        sy += seg[j, 1]
            ux = uy = t0 = t1 = 0.0
            if m >= 2:
                mx, my = sx / m, sy / m
                a = b = d = 0.0
                for rr in range(max(r - 1, 0), min(r + 2, rows)):
                    for cc in range(max(c - 1, 0), min(c + 2, cols)):
                        j = index[rr, cc]
                        if j >= 0:
                            ex = seg[j, 0] - mx
                            ey = seg[j, 1] - my
                            a += ex * ex
                            b += ex * ey
                            d += ey * ey
                half = (a + d) / 2.0
                q = math.sqrt((a - d) * (a - d) / 4.0 + b * b)
                if half + q > 0.0 and half - q < LINE_RATIO * (half + q):
                    # the larger eigenvalue's eigenvector: (b, big - a) or (big - d, b), the better conditioned
                    big = half + q
                    vx, vy = (b, big - a) if abs(big - a) >= abs(big - d) else (big - d, b)
                    norm = math.sqrt(vx * vx + vy * vy)
                    if norm > 0.0:
                        ux, uy = vx / norm, vy / norm
                    else:
                        ux, uy = (1.0, 0.0) if a >= d else (0.0, 1.0)
                    lx, hx = _clip(seg[i, 0], ux, c - OVERLAP, c + 1.0 + OVERLAP)
                    ly, hy = _clip(seg[i, 1], uy, r - OVERLAP, r + 1.0 + OVERLAP)
                    t0, t1 = max(lx, ly), min(hx, hy)
            seg[i, 2] = ux
            seg[i, 3] = uy
            seg[i, 4] = t0
            seg[i, 5] = t1
            if ux != 0.0 or uy != 0.0:
                for end in range(2):
                    t = t0 if end == 0 else t1
                    sign = -1.0 if end == 0 else 1.0
                    for beyond in (0.5, 1.5):
                        bx = seg[i, 0] + (t + sign * beyond) * ux
                        by = seg[i, 1] + (t + sign * beyond) * uy
                        bc = math.floor(bx)
                        br = math.floor(by)
                        if 0 <= br < rows and 0 <= bc < cols and not occ[br, bc] and not known[br, bc]:
                            seg[i, 6 + end] = 1.0
                            ext = OPEN_REACH
    return index, seg, ext


@kernel
def wall_offset(hits: HitSegments, gx: float, gy: float, reach: int
                ) -> tuple[float, float, float, float, float]:
    """The nearest wall segment of `hits` (`hit_points`: the line through a cell's hit point clipped to the cell,
    the point itself without a direction) to grid coordinates (gx, gy) [cells], among the cells within
    `reach` rows and columns of the one holding (gx, gy).

    Returns:
        (q, ex, ey, ux, uy): the squared distance [cells^2] (inf when none lies within reach + 0.5 cells,
        or outside the grid), the offset (ex, ey) [cells] from the segment's nearest point to (gx, gy), and
        the segment's direction where that point lies inside it ((0, 0) at an end or a lone point: the
        offset then moves with (gx, gy) in both directions). Ties go to the first cell in row order.
    """
    index, seg, ext = hits
    rows, cols = index.shape
    c0 = math.floor(gx)
    r0 = math.floor(gy)
    if c0 < 0 or r0 < 0 or c0 >= cols or r0 >= rows:
        return math.inf, 0.0, 0.0, 0.0, 0.0
    best = (reach + 0.5) * (reach + 0.5)
    bx = by = bux = buy = 0.0
    br = bc = -1
    # rings of cells around (r0, c0), nearest first: a cell k rings out is at least k - 1 - OVERLAP cells away,
    # less the open ends' reach `ext`, so once that exceeds the best distance no farther cell can win (the result
    # is the row-order scan's)
    for k in range(reach + 1):
        near = k - 1 - OVERLAP - ext     # the least distance of a segment of a cell k rings out
        if k >= 2 and near > 0 and near * near > best:
            break
        for r in range(max(r0 - k, 0), min(r0 + k + 1, rows)):
            edge = r == r0 - k or r == r0 + k
            step = 1 if edge else 2 * k
            for c in range(c0 - k, c0 + k + 1, max(step, 1)):
                if c < 0 or c >= cols:
                    continue
                i = index[r, c]
                if i < 0:
                    continue
                dx = gx - seg[i, 0]
                dy = gy - seg[i, 1]
                ux = seg[i, 2]
                uy = seg[i, 3]
                t = dx * ux + dy * uy
                lo = seg[i, 4] - OPEN_REACH * seg[i, 6]
                hi = seg[i, 5] + OPEN_REACH * seg[i, 7]
                inside = lo < t < hi
                t = min(max(t, lo), hi)
                dx -= t * ux
                dy -= t * uy
                q = dx * dx + dy * dy
                if q < best or (q == best and (br < 0 or r < br or (r == br and c < bc))):
                    best = q
                    bx, by = dx, dy
                    bux, buy = (ux, uy) if inside else (0.0, 0.0)
                    br, bc = r, c
    found = br >= 0
    if not found:
        return math.inf, 0.0, 0.0, 0.0, 0.0
    return best, bx, by, bux, buy


@kernel
def hit_value(hits: HitSegments, gx: float, gy: float, reach: int, k: float) -> float:
    """The likelihood field of `hits` at grid coordinates (gx, gy) [cells], evaluated there: exp(k q) with q
    [cells^2] the squared distance to the nearest wall segment (`wall_offset`), 0 when none is near.
    Unlike the nearest hit point's, the nearest segment's field has no ripple along a wall: the points
    of a scan lying on a wall the map has seen score 1 wherever they fall along it."""
    q = wall_offset(hits, gx, gy, reach)[0]
    return math.exp(k * q) if q < math.inf else 0.0


@kernel
def _hit_sums(hits: HitSegments, ox: float, oy: float, cell: float, reach: int, k: float,
              px: npt.NDArray[np.float64], py: npt.NDArray[np.float64], x: float, y: float, th: float) -> float:
    """Sum of `hit_value` under the points placed at (x, y, th)."""
    c, s = math.cos(th), math.sin(th)
    total = 0.0
    for i in range(px.shape[0]):
        total += hit_value(hits, (x + c * px[i] - s * py[i] - ox) / cell, (y + s * px[i] + c * py[i] - oy) / cell,
                           reach, k)
    return total


@kernel
def objective_hits(hits: HitSegments, ox: float, oy: float, cell: float, sigma: float, reach: int,
                   px: npt.NDArray[np.float64], py: npt.NDArray[np.float64], x: float, y: float, th: float,
                   cx: float, cy: float, cth: float, wxy: float, wth: float) -> float:
    """What `refine_hits` minimises: sum_i (1 - M(S_i)) with M = `hit_value`, plus the motion prior."""
    k = -cell * cell / (2.0 * sigma * sigma)
    return (px.shape[0] - _hit_sums(hits, ox, oy, cell, reach, k, px, py, x, y, th)
            + _prior(x, y, th, cx, cy, cth, wxy, wth))


@kernel
def mean_hits(hits: HitSegments, ox: float, oy: float, cell: float, sigma: float, reach: int,
              px: npt.NDArray[np.float64], py: npt.NDArray[np.float64], x: float, y: float, th: float) -> float:
    """The mean of `hit_value` under the points placed at (x, y, th)."""
    k = -cell * cell / (2.0 * sigma * sigma)
    return _hit_sums(hits, ox, oy, cell, reach, k, px, py, x, y, th) / max(px.shape[0], 1)


@kernel
def refine_hits(hits: HitSegments, ox: float, oy: float, cell: float, sigma: float, reach: int,
                px: npt.NDArray[np.float64], py: npt.NDArray[np.float64],
                x: float, y: float, th: float, iterations: int,
                cx: float, cy: float, cth: float, wxy: float, wth: float,
                ) -> tuple[float, float, float, float, npt.NDArray[np.float64]]:
    """Gauss-Newton on sum_i (1 - M(S_i)) + wxy ((x - cx)^2 + (y - cy)^2) + wth (th - cth)^2 from (x, y, th),
    with M the field of the hit points' wall segments evaluated exactly at each point (`hit_value`; `hits`
    from `hit_points`, cell (0, 0) with its lower-left corner at (ox, oy); sigma [m]; `reach` cells).

    1 - M = 1 - exp(-d^2 / (2 sigma^2)) is Welsch's robust cost of the point's distance d to the wall:
    quadratic near it, so a small offset is corrected in full (on sum (1 - M)^2, quartic there, the motion
    prior kept a part of every small correction), and bounded, so a point off the map costs at most 1.
    Each step is iteratively reweighted least squares on the offsets e_i to the walls (weight M_i,
    Jacobian (I - u u^T) dS_i/dpose across a wall of direction u): the steps, Levenberg-Marquardt damping
    and stopping rules of `refine`.

    Returns:
        (x, y, th, mean, H): the refined pose, the mean of M under the points there, and the 3x3 weighted
        normal matrix sum_i M_i J_i^T J_i of the scan alone [x, y in m, theta in rad] at the last pose.
    """
    n = px.shape[0]
    k = -cell * cell / (2.0 * sigma * sigma)
    half = 0.5 / (sigma * sigma)          # d(1 - M)/d(d^2) = M / (2 sigma^2)
    h = np.zeros((3, 3), np.float64)
    cost = n - _hit_sums(hits, ox, oy, cell, reach, k, px, py, x, y, th) + _prior(x, y, th, cx, cy, cth, wxy, wth)
    lam = DAMPING
    for _ in range(iterations):
        h[:, :] = 0.0
        g0 = 0.0
        g1 = 0.0
        g2 = 0.0
        c, s = math.cos(th), math.sin(th)
        for i in range(n):
            wx = x + c * px[i] - s * py[i]
            wy = y + s * px[i] + c * py[i]
            q, ex, ey, ux, uy = wall_offset(hits, (wx - ox) / cell, (wy - oy) / cell, reach)
            if q == math.inf:
                continue
            m = math.exp(k * q)
            ex *= cell
            ey *= cell
            # the offset's Jacobian: dS/dpose = [[1, 0, a], [0, 1, b]], projected across the wall
            a = -s * px[i] - c * py[i]
            b = c * px[i] - s * py[i]
            j00, j01, j11 = 1.0 - ux * ux, -ux * uy, 1.0 - uy * uy       # I - u u^T
            j02 = j00 * a + j01 * b
            j12 = j01 * a + j11 * b
            w = m * half
            h[0, 0] += m * (j00 * j00 + j01 * j01)
            h[0, 1] += m * (j00 * j01 + j01 * j11)
            h[0, 2] += m * (j00 * j02 + j01 * j12)
            h[1, 1] += m * (j01 * j01 + j11 * j11)
            h[1, 2] += m * (j01 * j02 + j11 * j12)
            h[2, 2] += m * (j02 * j02 + j12 * j12)
            g0 -= w * (j00 * ex + j01 * ey)
            g1 -= w * (j01 * ex + j11 * ey)
            g2 -= w * (j02 * ex + j12 * ey)
        h[1, 0] = h[0, 1]
        h[2, 0] = h[0, 2]
        h[2, 1] = h[1, 2]
        g0 -= wxy * (x - cx)
        g1 -= wxy * (y - cy)
        g2 -= wth * (th - cth)
        hp = h * half
        hp[0, 0] += wxy
        hp[1, 1] += wxy
        hp[2, 2] += wth
        trace = hp[0, 0] + hp[1, 1] + hp[2, 2]
        if trace == 0.0:
            break
        hd = hp.copy()
        accepted = False
        s0 = s1 = s2 = new_cost = 0.0
        for _retry in range(RETRIES):
            for d in range(3):
                hd[d, d] = hp[d, d] + lam * trace
            det = _det3(hd)
            if not abs(det) > 1e-300:
                break
            s0, s1, s2 = _solve3(hd, det, g0, g1, g2)
            new_cost = (n - _hit_sums(hits, ox, oy, cell, reach, k, px, py, x + s0, y + s1, th + s2)
                        + _prior(x + s0, y + s1, th + s2, cx, cy, cth, wxy, wth))
            if new_cost < cost:
                accepted = True
                break
            lam *= 10.0
        if not accepted:
            break
        x, y, th, cost = x + s0, y + s1, th + s2, new_cost
        lam = max(lam / 10.0, DAMPING)
        if abs(s0) < 1e-5 and abs(s1) < 1e-5 and abs(s2) < 1e-5:
            break
    mean = _hit_sums(hits, ox, oy, cell, reach, k, px, py, x, y, th) / max(n, 1)
    return x, y, th, mean, h


@kernel
def refine(field: npt.NDArray[np.float64], ox: float, oy: float, cell: float,
           px: npt.NDArray[np.float64], py: npt.NDArray[np.float64],
           x: float, y: float, th: float, iterations: int,
           cx: float, cy: float, cth: float, wxy: float, wth: float,
           ) -> tuple[float, float, float, float, npt.NDArray[np.float64]]:
    """Gauss-Newton on sum_i (1 - M(S_i))^2 + wxy ((x - cx)^2 + (y - cy)^2) + wth (th - cth)^2 from
    (x, y, th), at most `iterations` steps: the scan's fit plus a motion prior around the prediction
    (cx, cy, cth), which holds the directions the scan does not fix (along a corridor) near it.

    Levenberg-Marquardt: each step solves (H + lam trace(H) I) step = J^T r, lam starting at DAMPING; a
    step that does not lower the cost is retried with lam ten times larger (RETRIES tries in all, then
    the iterations end), an accepted one divides lam by ten (not below DAMPING). A step below 1e-5 m
    and 1e-5 rad, or a zero normal matrix, ends them too.

    Returns:
        (x, y, th, mean, H): the refined pose, the mean field value under the points there, and the
        3x3 normal matrix J^T J of the scan alone [x, y in m, theta in rad] at the last pose.
    """
    n = px.shape[0]
    h = np.zeros((3, 3), np.float64)
    cost = _cost(field, ox, oy, cell, px, py, x, y, th) + _prior(x, y, th, cx, cy, cth, wxy, wth)
    lam = DAMPING
    for _ in range(iterations):
        h[:, :] = 0.0
        g0 = 0.0
        g1 = 0.0
        g2 = 0.0
        c, s = math.cos(th), math.sin(th)
        for i in range(n):
            wx = x + c * px[i] - s * py[i]
            wy = y + s * px[i] + c * py[i]
            m, dx, dy = bilinear(field, (wx - ox) / cell, (wy - oy) / cell)
            dx /= cell
            dy /= cell
            dth = dx * (-s * px[i] - c * py[i]) + dy * (c * px[i] - s * py[i])
            res = 1.0 - m
            g0 += dx * res
            g1 += dy * res
            g2 += dth * res
            h[0, 0] += dx * dx
            h[0, 1] += dx * dy
            h[0, 2] += dx * dth
            h[1, 1] += dy * dy
            h[1, 2] += dy * dth
            h[2, 2] += dth * dth
        h[1, 0] = h[0, 1]
        h[2, 0] = h[0, 2]
        h[2, 1] = h[1, 2]
        g0 -= wxy * (x - cx)
        g1 -= wxy * (y - cy)
        g2 -= wth * (th - cth)
        # Levenberg-Marquardt: a little damping keeps a corridor's flat direction from blowing the step
        # up; a step that raises the cost is retried with ten times the damping, up to RETRIES times
        trace = h[0, 0] + h[1, 1] + h[2, 2] + 2.0 * wxy + wth
        if trace == 0.0:
            break
        hp = h.copy()
        hp[0, 0] += wxy
        hp[1, 1] += wxy
        hp[2, 2] += wth
        hd = hp.copy()
        accepted = False
        s0 = s1 = s2 = 0.0
        for _retry in range(RETRIES):
            for d in range(3):
                hd[d, d] = hp[d, d] + lam * trace
            det = _det3(hd)
            if not abs(det) > 1e-300:
                break
            s0, s1, s2 = _solve3(hd, det, g0, g1, g2)
            new_cost = (_cost(field, ox, oy, cell, px, py, x + s0, y + s1, th + s2)
                        + _prior(x + s0, y + s1, th + s2, cx, cy, cth, wxy, wth))
            if new_cost < cost:
                accepted = True
                break
            lam *= 10.0
        if not accepted:
            break
        x, y, th, cost = x + s0, y + s1, th + s2, new_cost
        lam = max(lam / 10.0, DAMPING)
        if abs(s0) < 1e-5 and abs(s1) < 1e-5 and abs(s2) < 1e-5:
            break
    mean = mean_field(field, ox, oy, cell, px, py, x, y, th)
    return x, y, th, mean, h


@kernel
def objective(field: npt.NDArray[np.float64], ox: float, oy: float, cell: float, px: npt.NDArray[np.float64],
              py: npt.NDArray[np.float64], x: float, y: float, th: float, cx: float, cy: float, cth: float,
              wxy: float, wth: float) -> float:
    """What `refine` minimises: sum_i (1 - M(S_i))^2 plus the motion prior."""
    return _cost(field, ox, oy, cell, px, py, x, y, th) + _prior(x, y, th, cx, cy, cth, wxy, wth)


@kernel
def _prior(x: float, y: float, th: float, cx: float, cy: float, cth: float, wxy: float, wth: float) -> float:
    return wxy * ((x - cx) * (x - cx) + (y - cy) * (y - cy)) + wth * (th - cth) * (th - cth)


@kernel
def _det3(h: npt.NDArray[np.float64]) -> float:
    return (h[0, 0] * (h[1, 1] * h[2, 2] - h[1, 2] * h[2, 1]) - h[0, 1] * (h[1, 0] * h[2, 2] - h[1, 2] * h[2, 0])
            + h[0, 2] * (h[1, 0] * h[2, 1] - h[1, 1] * h[2, 0]))


@kernel
def _solve3(h: npt.NDArray[np.float64], det: float, b0: float, b1: float, b2: float) -> tuple[float, float, float]:
    """h x = b for a symmetric 3x3 h of determinant `det` (Cramer's rule; no LAPACK in a kernel)."""
    x0 = (b0 * (h[1, 1] * h[2, 2] - h[1, 2] * h[2, 1]) - h[0, 1] * (b1 * h[2, 2] - h[1, 2] * b2)
          + h[0, 2] * (b1 * h[2, 1] - h[1, 1] * b2)) / det
    x1 = (h[0, 0] * (b1 * h[2, 2] - h[1, 2] * b2) - b0 * (h[1, 0] * h[2, 2] - h[1, 2] * h[2, 0])
          + h[0, 2] * (h[1, 0] * b2 - b1 * h[2, 0])) / det
    x2 = (h[0, 0] * (h[1, 1] * b2 - b1 * h[2, 1]) - h[0, 1] * (h[1, 0] * b2 - b1 * h[2, 0])
          + b0 * (h[1, 0] * h[2, 1] - h[1, 1] * h[2, 0])) / det
    return x0, x1, x2


@kernel
def _sums(field: npt.NDArray[np.float64], ox: float, oy: float, cell: float,
          px: npt.NDArray[np.float64], py: npt.NDArray[np.float64], x: float, y: float, th: float
          ) -> tuple[float, float]:
    """Sum of the bilinear field under the points placed at (x, y, th), and sum of (1 - field)^2."""
    c, s = math.cos(th), math.sin(th)
    total = 0.0
    squares = 0.0
    for i in range(px.shape[0]):
        m, _, _ = bilinear(field, (x + c * px[i] - s * py[i] - ox) / cell, (y + s * px[i] + c * py[i] - oy) / cell)
        total += m
        squares += (1.0 - m) * (1.0 - m)
    return total, squares


@kernel
def _cost(field: npt.NDArray[np.float64], ox: float, oy: float, cell: float,
          px: npt.NDArray[np.float64], py: npt.NDArray[np.float64], x: float, y: float, th: float) -> float:
    return _sums(field, ox, oy, cell, px, py, x, y, th)[1]


@kernel
def mean_field(field: npt.NDArray[np.float64], ox: float, oy: float, cell: float,
               px: npt.NDArray[np.float64], py: npt.NDArray[np.float64], x: float, y: float, th: float) -> float:
    """The mean bilinear field value under the points placed at (x, y, th)."""
    return _sums(field, ox, oy, cell, px, py, x, y, th)[0] / max(px.shape[0], 1)


@kernel
def add_hits(sum_x: npt.NDArray[np.float32], sum_y: npt.NDArray[np.float32], count: npt.NDArray[np.float32],
             ox: float, oy: float, cell: float, x: float, y: float, th: float, offset_x: float,
             ranges: npt.NDArray[np.float64], angles: npt.NDArray[np.float64], range_max: float, depth: float) -> None:
    """`HitMap.add` in place: each finite range in (0, range_max), `depth` [m] beyond the hit, in the cell a beam
    is in just after it (a point on a cell border in the cell the beam goes on into), adds its offset from the
    cell's centre [cells] to `sum_x`, `sum_y` and 1 to `count` (float32 sums, in beam order). The robot is at
    (x, y, th), the laser `offset_x` [m] ahead of it; the grid's lower-left corner at (ox, oy) [m]."""
    rows, cols = count.shape
    sx = x + offset_x * math.cos(th)
    sy = y + offset_x * math.sin(th)
    for i in range(ranges.shape[0]):
        r = ranges[i]
        if not (math.isfinite(r) and r > 0.0 and r < range_max):
            continue
        r += depth
        a = angles[i] + th
        dx = math.cos(a)
        dy = math.sin(a)
        gx = (sx + r * dx - ox) / cell
        gy = (sy + r * dy - oy) / cell
        c = math.ceil(gx) - 1 if dx < 0.0 else math.floor(gx)
        w = math.ceil(gy) - 1 if dy < 0.0 else math.floor(gy)
        if w < 0 or w >= rows or c < 0 or c >= cols:
            continue
        sum_x[w, c] += np.float32(gx - c - 0.5)
        sum_y[w, c] += np.float32(gy - w - 0.5)
        count[w, c] += np.float32(1.0)


_warmed = False


def warm() -> None:
    """Call every kernel of the scan matcher once, on a few cells, with the argument types `ScanMatcher.match`
    passes: numba compiles (or loads from its cache) each at its first call, and a real robot's run must
    not wait for that mid-run (`LocalizedRobot` calls this before the run starts; once per process).
    The correlative search, for one, runs only where Gauss-Newton from the prediction fits poorly,
    which a short warm-up run may never meet."""
    global _warmed
    if _warmed:
        return
    occ = np.zeros((8, 8), np.bool_)
    occ[2, 1:7] = True
    occ[2:7, 6] = True
    off = np.zeros((8, 8), np.float32)
    px = np.ascontiguousarray(np.linspace(0.05, 0.3, 6))
    py = np.ascontiguousarray(np.full(6, 0.1))
    f = splat_field(occ, off, off, 0.05, 0.05, 3)
    coarse = pool_max(f, 2)
    search(coarse, 0.0, 0.0, 0.1, px, py, 0.0, 0.0, 0.0, 1, 1, 1, 0.01, 0.0, 0.0, 0.0, 1.0, 1.0)
    refine(f, 0.0, 0.0, 0.05, px, py, 0.0, 0.0, 0.0, 2, 0.0, 0.0, 0.0, 1.0, 1.0)
    objective(f, 0.0, 0.0, 0.05, px, py, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0)
    mean_field(f, 0.0, 0.0, 0.05, px, py, 0.0, 0.0, 0.0)
    hits = hit_points(occ, off, off, np.ones((8, 8), np.bool_))
    refine_hits(hits, 0.0, 0.0, 0.05, 0.05, 3, px, py, 0.0, 0.0, 0.0, 2, 0.0, 0.0, 0.0, 1.0, 1.0)
    objective_hits(hits, 0.0, 0.0, 0.05, 0.05, 3, px, py, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0)
    mean_hits(hits, 0.0, 0.0, 0.05, 0.05, 3, px, py, 0.0, 0.0, 0.0)
    add_hits(off, off.copy(), off.copy(), 0.0, 0.0, 0.05, 0.1, 0.1, 0.0, 0.0, px, py, 3.0, 1e-4)
    _warmed = True
