"""Plain-numpy references of the scan-matcher kernels (`robotexp.localization.kernels`), for the tests
and the benchmark only: the same results computed with whole-array numpy operations."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from robotexp.localization.kernels import DAMPING, RETRIES

__all__ = ["splat_field_ref", "pool_max_ref", "search_ref", "bilinear_ref", "refine_ref"]


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


def refine_ref(field: npt.NDArray[np.float64], ox: float, oy: float, cell: float, px: npt.NDArray[np.float64],
               py: npt.NDArray[np.float64], x: float, y: float, th: float, iterations: int, cx: float,
               cy: float, cth: float, wxy: float, wth: float
               ) -> tuple[float, float, float, float, npt.NDArray[np.float64]]:
    """Gauss-Newton with the kernel's acceptance and stopping rules, Jacobians as arrays."""
    w = np.array([wxy, wxy, wth])
    centre = np.array([cx, cy, cth])

    def prior(v: npt.NDArray[np.float64]) -> float:
        return float(np.sum(w * (v - centre) ** 2))

    cost = _cost_ref(field, ox, oy, cell, px, py, x, y, th)[0] + prior(np.array([x, y, th]))
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
        step = None
        for _retry in range(RETRIES):
            trial = np.linalg.solve(hp + lam * trace * np.eye(3), g)
            v = np.array([x, y, th]) + trial
            new_cost = _cost_ref(field, ox, oy, cell, px, py, *v)[0] + prior(v)
            if new_cost < cost:
                step = trial
                break
            lam *= 10.0
        if step is None:
            break
        x, y, th, cost = x + step[0], y + step[1], th + step[2], new_cost
        lam = max(lam / 10.0, DAMPING)
        if np.all(np.abs(step) < 1e-5):
            break
    _, mean = _cost_ref(field, ox, oy, cell, px, py, x, y, th)
    return x, y, th, mean, h
