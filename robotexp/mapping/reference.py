"""Slow plain-numpy references of the mapping kernels, for the tests and the benchmark only.

They compute the same results as `robotexp.mapping.kernels` by another method: a beam's cells
are found from the sorted parameters where it crosses grid lines (the cell of the midpoint of
each piece), not by stepping cell to cell. Do not use them in product code.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.kernels import LogOddsModel

__all__ = ["beam_cells", "integrate_scan_himm_ref", "integrate_scan_logodds_ref"]


def _forward(g: float, d: float) -> int:
    """Index of the cell just after grid coordinate `g` [cells] moving with direction sign `d`."""
    return math.ceil(g) - 1 if d < 0 else math.floor(g)


def beam_cells(geo: GridGeometry, x0: float, y0: float, angle: float,
               length: float) -> tuple[npt.NDArray[np.int64], bool]:
    """The cells a beam from (x0, y0) [m] at `angle` [rad] crosses within `length` [m], clipped.

    Returns:
        (cells, ended): int64 (n, 2) (row, col) in order from the origin, and whether the last
        cell holds the beam end (the cell just past the end point along the beam).
    """
    dx, dy = math.cos(angle), math.sin(angle)
    x_hi = geo.origin_x + geo.cols * geo.cell
    y_hi = geo.origin_y + geo.rows * geo.cell
    t_lo, t_box = 0.0, math.inf
    empty = np.zeros((0, 2), np.int64)
    for p, d, lo, hi in ((x0, dx, geo.origin_x, x_hi), (y0, dy, geo.origin_y, y_hi)):
        if d == 0.0:
            if not lo <= p < hi:
                return empty, False
        else:
            ta, tb = (lo - p) / d, (hi - p) / d
            t_lo, t_box = max(t_lo, min(ta, tb)), min(t_box, max(ta, tb))
    if t_lo >= t_box or t_lo > length:
        return empty, False
    t_hi = min(length, t_box)
    ts = [np.array([t_lo, t_hi])]
    for p, d, lo in ((x0, dx, geo.origin_x), (y0, dy, geo.origin_y)):
        if d != 0.0:
            ka = (p + t_lo * d - lo) / geo.cell
            kb = (p + t_hi * d - lo) / geo.cell
            k = np.arange(math.floor(min(ka, kb)), math.ceil(max(ka, kb)) + 1)
            t = (lo + k * geo.cell - p) / d
            ts.append(t[(t > t_lo) & (t < t_hi)])
    t_all = np.unique(np.concatenate(ts))
    mid = 0.5 * (t_all[:-1] + t_all[1:])
    cols = np.floor((x0 + mid * dx - geo.origin_x) / geo.cell).astype(np.int64)
    rows = np.floor((y0 + mid * dy - geo.origin_y) / geo.cell).astype(np.int64)
    cells = np.stack([rows, cols], axis=1)
    ended = length < t_box
    if ended:
        end = (_forward((y0 + length * dy - geo.origin_y) / geo.cell, dy),
               _forward((x0 + length * dx - geo.origin_x) / geo.cell, dx))
        if len(cells) == 0 or tuple(cells[-1]) != end:
            cells = np.vstack([cells, np.array([end], np.int64)])
    return cells, ended


def _scan_ref(values: npt.NDArray[np.generic], stamp: npt.NDArray[np.int32], scan_id: int, geo: GridGeometry,
              pose: npt.NDArray[np.float64], angles: npt.NDArray[np.float64], ranges: npt.NDArray[np.float64],
              range_max: float, occ: float, free: float, lo: float, hi: float) -> int:
    """Once-per-scan, hit-wins update: collect the cells first, then add in one vectorised step."""
    hits: dict[tuple[int, int], None] = {}
    frees: dict[tuple[int, int], None] = {}
    for a, rng in zip(angles, ranges, strict=True):
        if math.isnan(rng) or rng < 0:
            continue
        hit = rng < range_max
        cells, ended = beam_cells(geo, pose[0], pose[1], pose[2] + a, rng if hit else range_max)
        n_free = len(cells) - 1 if (hit and ended and len(cells)) else len(cells)
        for k, (r, c) in enumerate(cells.tolist()):
            (frees if k < n_free else hits)[(r, c)] = None
    free_only = [rc for rc in frees if rc not in hits]
    touched = 0
    for group, delta in ((list(hits), occ), (free_only, free)):
        if not group:
            continue
        idx = np.array(group, dtype=np.int64)
        r, c = idx[:, 0], idx[:, 1]
        values[r, c] = np.clip(values[r, c].astype(np.float64) + delta, lo, hi).astype(values.dtype)
        stamp[r, c] = scan_id
        touched += len(group)
    return touched


def integrate_scan_logodds_ref(logodds: npt.NDArray[np.float32], stamp: npt.NDArray[np.int32], scan_id: int,
                               geo: GridGeometry, pose: npt.NDArray[np.float64],
                               angles: npt.NDArray[np.float64], ranges: npt.NDArray[np.float64],
                               model: LogOddsModel) -> int:
    """Reference of `kernels.integrate_scan_logodds` (same arguments, same result)."""
    return _scan_ref(logodds, stamp, scan_id, geo, pose, angles, ranges, model.range_max,
                     model.l_occ, model.l_free, model.l_min, model.l_max)


def integrate_scan_himm_ref(cert: npt.NDArray[np.uint8], stamp: npt.NDArray[np.int32], scan_id: int,
                            geo: GridGeometry, pose: npt.NDArray[np.float64], angles: npt.NDArray[np.float64],
                            ranges: npt.NDArray[np.float64], range_max: float) -> int:
    """Reference of `kernels.integrate_scan_himm` (same arguments, same result)."""
    return _scan_ref(cert, stamp, scan_id, geo, pose, angles, ranges, range_max, 3.0, -1.0, 0.0, 15.0)
