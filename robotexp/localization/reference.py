"""Plain-numpy references of the scan-matcher kernels (`robotexp.localization.kernels`), for the tests
and the benchmark only: the same results computed with whole-array numpy operations."""

from __future__ import annotations

from collections.abc import Callable, Sequence
import math

import numpy as np
import numpy.typing as npt

from robotexp.localization.kernels import DAMPING, LINE_RATIO, OPEN_REACH, OVERLAP, RETRIES, HitSegments
from robotexp.localization.posegraph import Edge, _wrap, check_edges

__all__ = ["splat_field_ref", "pool_max_ref", "search_ref", "bilinear_ref", "refine_ref", "hit_points_ref",
           "wall_offset_ref", "refine_hits_ref", "optimize_ref", "add_hits_ref"]


def splat_field_ref(occ: npt.NDArray[np.bool_], off_x: npt.NDArray[np.float32], off_y: npt.NDArray[np.float32],
                    cell: float, sigma: float, reach: int) -> npt.NDArray[np.float64]:
    """Per offset (dr, dc) of the neighbourhood, the Gaussian of every occupied cell shifted there, max."""
    rows, cols = occ.shape
    out = np.zeros((rows, cols))
    rr, cc = np.nonzero(occ)
    hx, hy = cc + off_x[rr, cc].astype(np.float64), rr + off_y[rr, cc].astype(np.float64)
    for dr in range(-reach, reach + 1):
        for dc in range(-reach, reach + 1):
            tr, tc = rr + dr, cc + dc
            ok = (tr >= 0) & (tr < rows) & (tc >= 0) & (tc < cols)
            q = (tc - hx) ** 2 + (tr - hy) ** 2
            v = np.where(q <= (reach + 0.5) ** 2, np.exp(-q * cell * cell / (2.0 * sigma * sigma)), 0.0)
            np.maximum.at(out, (tr[ok], tc[ok]), v[ok])
    return out


def pool_max_ref(field: npt.NDArray[np.float64], factor: int) -> npt.NDArray[np.float64]:
    """Block maximum, the last blocks padded with zeros."""
    rows, cols = field.shape
    cr, cc = -(-rows // factor), -(-cols // factor)
    padded = np.zeros((cr * factor, cc * factor))
    padded[:rows, :cols] = field
    return padded.reshape(cr, factor, cc, factor).max(axis=(1, 3))


def search_ref(field: npt.NDArray[np.float64], ox: float, oy: float, cell: float,
               px: npt.NDArray[np.float64], py: npt.NDArray[np.float64], x0: float, y0: float, th0: float,
               nxy: int, step: int, nth: int, dth: float, cx: float, cy: float, cth: float, kxy: float,
               kth: float) -> tuple[float, float, float, float]:
    """All window scores at once (heading, y, x), then the best with the kernel's tie rule."""
    rows, cols = field.shape
    ks = np.arange(-nth, nth + 1)
    offs = np.arange(-nxy, nxy + 1) * step
    th = th0 + ks * dth
    c, s = np.cos(th)[:, None], np.sin(th)[:, None]
    cc = np.floor((x0 + c * px - s * py - ox) / cell).astype(np.int64)       # (K, n)
    rr = np.floor((y0 + s * px + c * py - oy) / cell).astype(np.int64)
    r = rr[:, None, None, :] + offs[None, :, None, None]                         # (K, J, I, n)
    q = cc[:, None, None, :] + offs[None, None, :, None]
    inside = (r >= 0) & (r < rows) & (q >= 0) & (q < cols)
    vals = np.where(inside, field[np.clip(r, 0, rows - 1), np.clip(q, 0, cols - 1)], 0.0)
    ex = (x0 + offs * cell - cx)[None, None, :]
    ey = (y0 + offs * cell - cy)[None, :, None]
    scores = vals.sum(axis=3) - kth * ((th - cth) ** 2)[:, None, None] - kxy * (ex ** 2 + ey ** 2)   # (K, J, I)
    kk, jj, ii = np.meshgrid(ks, offs // step, offs // step, indexing="ij")
    dist = kk ** 2 + jj ** 2 + ii ** 2
    best = scores.max()
    near = scores > best - 1e-9               # within the kernel's tie band of the maximum
    # the kernel keeps the first of the nearest among (almost) equal scores in (K, J, I) order
    cand = np.flatnonzero(near.ravel())
    d = dist.ravel()[cand]
    pick = cand[np.argmin(d)]
    k, j, i = np.unravel_index(pick, scores.shape)
    return (float(x0 + offs[i] * cell), float(y0 + offs[j] * cell), float(th[k]), float(scores[k, j, i]))


def bilinear_ref(field: npt.NDArray[np.float64], gx: npt.NDArray[np.float64], gy: npt.NDArray[np.float64]
                 ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Bilinear value and gradient [per cell] at arrays of grid coordinates; 0 outside the samples."""
    rows, cols = field.shape
    fx, fy = np.asarray(gx) - 0.5, np.asarray(gy) - 0.5
    c0, r0 = np.floor(fx).astype(np.int64), np.floor(fy).astype(np.int64)
    ok = (c0 >= 0) & (r0 >= 0) & (c0 + 1 < cols) & (r0 + 1 < rows)
    c0c, r0c = np.clip(c0, 0, cols - 2), np.clip(r0, 0, rows - 2)
    ax, ay = fx - c0, fy - r0
    m00, m01 = field[r0c, c0c], field[r0c, c0c + 1]
    m10, m11 = field[r0c + 1, c0c], field[r0c + 1, c0c + 1]
    value = (1 - ay) * ((1 - ax) * m00 + ax * m01) + ay * ((1 - ax) * m10 + ax * m11)
    dx = (1 - ay) * (m01 - m00) + ay * (m11 - m10)
    dy = (1 - ax) * (m10 - m00) + ax * (m11 - m01)
    return np.where(ok, value, 0.0), np.where(ok, dx, 0.0), np.where(ok, dy, 0.0)


def _cost_ref(field: npt.NDArray[np.float64], ox: float, oy: float, cell: float, px: npt.NDArray[np.float64],
              py: npt.NDArray[np.float64], x: float, y: float, th: float) -> tuple[float, float]:
    c, s = math.cos(th), math.sin(th)
    m, _, _ = bilinear_ref(field, (x + c * px - s * py - ox) / cell, (y + s * px + c * py - oy) / cell)
    return float(np.sum((1.0 - m) ** 2)), float(m.mean()) if len(m) else 0.0


def _damped_step(hp: npt.NDArray[np.float64], trace: float, g: npt.NDArray[np.float64], lam: float, cost: float,
                 v: npt.NDArray[np.float64], total: Callable[[npt.NDArray[np.float64]], float]
                 ) -> tuple[npt.NDArray[np.float64] | None, float, float]:
    """One Levenberg-Marquardt step from pose `v` as the kernels take it: solve (hp + lam trace I) s = g and
    multiply the damping by ten until `total(v + s)` falls below `cost`, at most RETRIES times. Returns
    (the step or None, its cost, the damping it was taken with)."""
    for _retry in range(RETRIES):
        trial = np.asarray(np.linalg.solve(hp + lam * trace * np.eye(3), g), dtype=np.float64)
        new_cost = total(v + trial)
        if new_cost < cost:
            return trial, new_cost, lam
        lam *= 10.0
    return None, cost, lam


def refine_ref(field: npt.NDArray[np.float64], ox: float, oy: float, cell: float, px: npt.NDArray[np.float64],
               py: npt.NDArray[np.float64], x: float, y: float, th: float, iterations: int, cx: float,
               cy: float, cth: float, wxy: float, wth: float
               ) -> tuple[float, float, float, float, npt.NDArray[np.float64]]:
    """Gauss-Newton with the kernel's acceptance and stopping rules, Jacobians as arrays."""
    w = np.array([wxy, wxy, wth])
    centre = np.array([cx, cy, cth])

    def total(v: npt.NDArray[np.float64]) -> float:
        return _cost_ref(field, ox, oy, cell, px, py, *v)[0] + float(np.sum(w * (v - centre) ** 2))

    cost = total(np.array([x, y, th]))
    h = np.zeros((3, 3))
    lam = DAMPING
    for _ in range(iterations):
        c, s = math.cos(th), math.sin(th)
        m, dx, dy = bilinear_ref(field, (x + c * px - s * py - ox) / cell, (y + s * px + c * py - oy) / cell)
        jac = np.column_stack([dx / cell, dy / cell,
                               dx / cell * (-s * px - c * py) + dy / cell * (c * px - s * py)])
        h = jac.T @ jac
        hp = h + np.diag(w)
        trace = np.trace(hp)
        if trace == 0.0:
            break
        g = jac.T @ (1.0 - m) - w * (np.array([x, y, th]) - centre)
        step, new_cost, lam = _damped_step(hp, trace, g, lam, cost, np.array([x, y, th]), total)
        if step is None:
            break
        x, y, th, cost = x + step[0], y + step[1], th + step[2], new_cost
        lam = max(lam / 10.0, DAMPING)
        if np.all(np.abs(step) < 1e-5):
            break
    _, mean = _cost_ref(field, ox, oy, cell, px, py, x, y, th)
    return x, y, th, mean, h


def hit_points_ref(occ: npt.NDArray[np.bool_], off_x: npt.NDArray[np.float32], off_y: npt.NDArray[np.float32],
                   known: npt.NDArray[np.bool_]) -> HitSegments:
    """Hit points as arrays; each cell's direction from np.linalg.eigh of its 3 x 3 block's scatter, its
    segment from the line's crossings of the cell's four sides, each end open where a cell 0.5 or 1.5 cells
    beyond it along the line is in the grid, free and never seen; then the occupied cells in row order."""
    rows, cols = occ.shape
    out = np.full((8, rows, cols), np.nan)
    rr, cc = np.nonzero(occ)
    out[0, rr, cc] = cc + 0.5 + off_x[rr, cc].astype(np.float64)
    out[1, rr, cc] = rr + 0.5 + off_y[rr, cc].astype(np.float64)
    for r, c in zip(rr, cc, strict=True):
        block = (slice(max(r - 1, 0), r + 2), slice(max(c - 1, 0), c + 2))
        sel = occ[block]
        u, span = np.zeros(2), np.zeros(2)
        if np.count_nonzero(sel) >= 2:
            pts = np.column_stack([out[0][block][sel], out[1][block][sel]])
            scatter = (pts - pts.mean(axis=0)).T @ (pts - pts.mean(axis=0))
            vals, vecs = np.linalg.eigh(scatter)
            if vals[1] > 0 and vals[0] < LINE_RATIO * vals[1]:
                u = vecs[:, 1]
                h = np.array([out[0, r, c], out[1, r, c]])
                lo, hi = np.array([c, r]) - OVERLAP, np.array([c, r]) + 1.0 + OVERLAP
                with np.errstate(divide="ignore"):
                    a, b = (lo - h) / u, (hi - h) / u
                a, b = np.where(u == 0, -np.inf, np.minimum(a, b)), np.where(u == 0, np.inf, np.maximum(a, b))
                span = np.array([a.max(), b.min()])
        out[2, r, c], out[3, r, c] = u
        out[4, r, c], out[5, r, c] = span
        for end, (t, sign) in enumerate(((span[0], -1.0), (span[1], 1.0))):
            beyond = [np.floor(np.array([out[0, r, c], out[1, r, c]]) + (t + sign * d) * u).astype(int)
                      for d in (0.5, 1.5)]
            out[6 + end, r, c] = float(u.any() and any(0 <= b[1] < rows and 0 <= b[0] < cols
                                                       and not occ[b[1], b[0]] and not known[b[1], b[0]]
                                                       for b in beyond))
    index = np.full((rows, cols), -1, np.int32)
    index[rr, cc] = np.arange(len(rr), dtype=np.int32)          # np.nonzero: row order
    seg = np.ascontiguousarray(out[:, rr, cc].T)
    return index, seg, OPEN_REACH if (seg[:, 6:] > 0).any() else 0.0


def wall_offset_ref(hits: HitSegments, gx: npt.NDArray[np.float64], gy: npt.NDArray[np.float64],
                    reach: int) -> tuple[npt.NDArray[np.float64], ...]:
    """`wall_offset` at arrays of grid coordinates: every cell of the neighbourhood at once, the first nearest."""
    gx, gy = np.asarray(gx, np.float64), np.asarray(gy, np.float64)
    index, seg, _ = hits
    rows, cols = index.shape
    c0, r0 = np.floor(gx).astype(np.int64), np.floor(gy).astype(np.int64)
    inside = (c0 >= 0) & (r0 >= 0) & (c0 < cols) & (r0 < rows)
    offs = np.arange(-reach, reach + 1)
    dr, dc = np.meshgrid(offs, offs, indexing="ij")                      # row order, as the kernel scans
    r = r0[:, None] + dr.ravel()[None, :]
    c = c0[:, None] + dc.ravel()[None, :]
    ok = inside[:, None] & (r >= 0) & (r < rows) & (c >= 0) & (c < cols)
    rc, cc = np.clip(r, 0, rows - 1), np.clip(c, 0, cols - 1)
    idx = index[rc, cc]
    ok &= idx >= 0
    hx, hy, ux, uy, t0, t1, open0, open1 = (seg[np.maximum(idx, 0), k] for k in range(8))
    t0, t1 = t0 - OPEN_REACH * open0, t1 + OPEN_REACH * open1
    dx, dy = gx[:, None] - hx, gy[:, None] - hy
    t = dx * ux + dy * uy
    interior = (t0 < t) & (t < t1)
    t = np.clip(t, t0, t1)
    dx, dy = dx - t * ux, dy - t * uy
    q = np.where(ok, dx * dx + dy * dy, np.inf)
    q = np.where(q <= (reach + 0.5) ** 2, q, np.inf)
    j = np.argmin(q, axis=1)
    i = np.arange(len(gx))
    qb = q[i, j]
    found = np.isfinite(qb)
    keep = found & interior[i, j]
    return (qb, np.where(found, dx[i, j], 0.0), np.where(found, dy[i, j], 0.0),
            np.where(keep, ux[i, j], 0.0), np.where(keep, uy[i, j], 0.0))


def _hits_cost_ref(hits: HitSegments, ox: float, oy: float, cell: float, sigma: float, reach: int,
                   px: npt.NDArray[np.float64], py: npt.NDArray[np.float64], x: float, y: float, th: float
                   ) -> tuple[float, float]:
    c, s = math.cos(th), math.sin(th)
    q = wall_offset_ref(hits, (x + c * px - s * py - ox) / cell, (y + s * px + c * py - oy) / cell, reach)[0]
    m = np.exp(-q * cell * cell / (2.0 * sigma * sigma))
    return float(np.sum(1.0 - m)), float(m.mean()) if len(m) else 0.0


def refine_hits_ref(hits: HitSegments, ox: float, oy: float, cell: float, sigma: float, reach: int,
                    px: npt.NDArray[np.float64], py: npt.NDArray[np.float64], x: float, y: float, th: float,
                    iterations: int, cx: float, cy: float, cth: float, wxy: float, wth: float
                    ) -> tuple[float, float, float, float, npt.NDArray[np.float64]]:
    """Reweighted Gauss-Newton with the kernel's acceptance and stopping rules, Jacobians as (n, 2, 3) arrays."""
    w = np.array([wxy, wxy, wth])
    centre = np.array([cx, cy, cth])
    half = 0.5 / (sigma * sigma)

    def total(v: npt.NDArray[np.float64]) -> float:
        return _hits_cost_ref(hits, ox, oy, cell, sigma, reach, px, py, *v)[0] + float(np.sum(w * (v - centre) ** 2))

    v = np.array([x, y, th])
    cost = total(v)
    h = np.zeros((3, 3))
    lam = DAMPING
    for _ in range(iterations):
        c, s = math.cos(v[2]), math.sin(v[2])
        q, ex, ey, ux, uy = wall_offset_ref(hits, (v[0] + c * px - s * py - ox) / cell,
                                            (v[1] + s * px + c * py - oy) / cell, reach)
        near = np.isfinite(q)
        m = np.where(near, np.exp(-np.where(near, q, 0.0) * cell * cell / (2.0 * sigma * sigma)), 0.0)
        dpose = np.zeros((len(px), 2, 3))
        dpose[:, 0, 0] = dpose[:, 1, 1] = 1.0
        dpose[:, 0, 2] = -s * px - c * py
        dpose[:, 1, 2] = c * px - s * py
        u = np.stack([ux, uy], axis=1)
        proj = np.eye(2)[None] - u[:, :, None] * u[:, None, :]              # I - u u^T
        jac = proj @ dpose                                                   # (n, 2, 3)
        e = np.stack([ex, ey], axis=1) * cell
        h = np.einsum("n,nki,nkj->ij", m, jac, jac)
        g = -half * np.einsum("n,nki,nk->i", m, jac, e) - w * (v - centre)
        hp = half * h + np.diag(w)
        trace = np.trace(hp)
        if trace == 0.0:
            break
        step, new_cost, lam = _damped_step(hp, trace, g, lam, cost, v, total)
        if step is None:
            break
        v, cost = v + step, new_cost
        lam = max(lam / 10.0, DAMPING)
        if np.all(np.abs(step) < 1e-5):
            break
    _, mean = _hits_cost_ref(hits, ox, oy, cell, sigma, reach, px, py, *v)
    return float(v[0]), float(v[1]), float(v[2]), mean, h


def optimize_ref(poses: npt.ArrayLike, edges: Sequence[Edge], *, iterations: int = 10, cauchy: float = 3.0
                 ) -> npt.NDArray[np.float64]:
    """`robotexp.localization.posegraph.optimize` edge by edge with a dense system: Gauss-Newton on the pose
    graph, node 0 held fixed; loop edges weighted by a Cauchy kernel of scale `cauchy` (in units of their
    standard deviation) by iterative reweighting.

    Args:
        poses: (n, 3) initial [x, y, theta].
        edges: the constraints.
        iterations: at most this many steps (stops when the step is below 1e-6).
        cauchy: the kernel's scale.

    Returns:
        (n, 3) optimised poses.

    Raises:
        ConfigError: an edge names a node outside 0..n-1.
    """
    x = np.array(poses, np.float64, copy=True)
    n = len(x)
    check_edges(edges, n)
    for _ in range(iterations):
        h = np.zeros((3 * n, 3 * n))
        b = np.zeros(3 * n)
        for e in edges:
            xi, xj = x[e.i], x[e.j]
            ci, si = math.cos(xi[2]), math.sin(xi[2])
            cz, sz = math.cos(e.z.theta), math.sin(e.z.theta)
            ri_t = np.array([[ci, si], [-si, ci]])
            rz_t = np.array([[cz, sz], [-sz, cz]])
            dt = xj[:2] - xi[:2]
            err = np.empty(3)
            err[:2] = rz_t @ (ri_t @ dt - np.array([e.z.x, e.z.y]))
            err[2] = _wrap(xj[2] - xi[2] - e.z.theta)
            dri_t = np.array([[-si, ci], [-ci, -si]])
            a = np.zeros((3, 3))
            a[:2, :2] = -rz_t @ ri_t
            a[:2, 2] = rz_t @ dri_t @ dt
            a[2, 2] = -1.0
            bj = np.zeros((3, 3))
            bj[:2, :2] = rz_t @ ri_t
            bj[2, 2] = 1.0
            omega = e.info
            if e.loop:
                chi2 = float(err @ omega @ err)
                omega = omega / (1.0 + chi2 / (cauchy * cauchy))
            si_, sj_ = slice(3 * e.i, 3 * e.i + 3), slice(3 * e.j, 3 * e.j + 3)
            h[si_, si_] += a.T @ omega @ a
            h[si_, sj_] += a.T @ omega @ bj
            h[sj_, si_] += bj.T @ omega @ a
            h[sj_, sj_] += bj.T @ omega @ bj
            b[si_] += a.T @ omega @ err
            b[sj_] += bj.T @ omega @ err
        h[:3, :3] += np.eye(3) * 1e12          # hold node 0
        h += np.eye(3 * n) * 1e-9
        step = np.linalg.solve(h, -b)
        x += step.reshape(n, 3)
        x[:, 2] = _wrap(x[:, 2])
        if np.abs(step).max() < 1e-6:
            break
    return x


def add_hits_ref(sum_x: npt.NDArray[np.float32], sum_y: npt.NDArray[np.float32], count: npt.NDArray[np.float32],
                 ox: float, oy: float, cell: float, x: float, y: float, th: float, offset_x: float,
                 ranges: npt.NDArray[np.float64], angles: npt.NDArray[np.float64], range_max: float,
                 depth: float) -> None:
    """Every beam at once, accumulated with `np.add.at`."""
    r, a = np.asarray(ranges, np.float64), np.asarray(angles, np.float64)
    ok = np.isfinite(r) & (r > 0.0) & (r < range_max)
    r, a = r[ok] + depth, a[ok] + th
    dx, dy = np.cos(a), np.sin(a)
    gx = (x + offset_x * math.cos(th) + r * dx - ox) / cell
    gy = (y + offset_x * math.sin(th) + r * dy - oy) / cell
    col = np.where(dx < 0.0, np.ceil(gx) - 1, np.floor(gx)).astype(np.intp)
    row = np.where(dy < 0.0, np.ceil(gy) - 1, np.floor(gy)).astype(np.intp)
    ok = (row >= 0) & (row < count.shape[0]) & (col >= 0) & (col < count.shape[1])
    row, col = row[ok], col[ok]
    np.add.at(sum_x, (row, col), (gx[ok] - col - 0.5).astype(np.float32))
    np.add.at(sum_y, (row, col), (gy[ok] - row - 0.5).astype(np.float32))
    np.add.at(count, (row, col), np.float32(1.0))
