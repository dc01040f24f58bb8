"""Which cells lie within a distance of a set of cells, without a distance transform of the whole grid.

`distance_transform(src) <= reach` answers it for every cell at the cost of the grid; the planners often
need it only for a few cells (the frontier: is a reachable cell within reach?) or only from a few
(the cells within reach of the frontier), and these kernels visit just those cells and a disc around
each. They give exactly the comparison's answer: `distance_transform` returns float32(sqrt(d2)) for an
integer squared distance d2, so "<= reach" holds for every d2 up to `max_d2(reach)` and for no other.
`within_reference` is that comparison itself, the plain numpy reference the kernels are tested against.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.mapping.kernels import kernel
from robotexp.planning.grid_planner import distance_transform

__all__ = ["max_d2", "near_cells", "probe_cells", "within_reference"]


def max_d2(reach: float) -> int:
    """The largest integer squared distance d2 with float32(sqrt(d2)) <= `reach` [cells] (-1: none)."""
    if math.isnan(reach):
        raise ConfigError("reach: the distance is NaN; give a number of cells")
    if reach < 0:
        return -1
    if math.isinf(reach):
        raise ConfigError("reach: the distance must be finite")
    d2 = int(math.floor(reach * reach)) + 2
    while d2 >= 0 and not float(np.float32(math.sqrt(d2))) <= reach:
        d2 -= 1
    return d2


def _offsets(d2: int) -> npt.NDArray[np.int64]:
    k = int(math.isqrt(max(d2, 0)))
    dr, dc = np.mgrid[-k:k + 1, -k:k + 1]
    keep = dr * dr + dc * dc <= d2
    # nearest first, so a probe stops early
    order = np.argsort((dr * dr + dc * dc)[keep], kind="stable")
    return np.ascontiguousarray(np.column_stack([dr[keep], dc[keep]])[order].astype(np.int64))


@kernel
def _paint(src: npt.NDArray[np.bool_], offsets: npt.NDArray[np.int64], out: npt.NDArray[np.bool_]) -> None:
    rows, cols = src.shape
    for r in range(rows):
        for c in range(cols):
            if src[r, c]:
                for i in range(offsets.shape[0]):
                    rr = r + offsets[i, 0]
                    cc = c + offsets[i, 1]
                    if 0 <= rr < rows and 0 <= cc < cols:
                        out[rr, cc] = True


@kernel
def _probe(src: npt.NDArray[np.bool_], cand: npt.NDArray[np.bool_], offsets: npt.NDArray[np.int64],
           out: npt.NDArray[np.bool_]) -> None:
    rows, cols = src.shape
    for r in range(rows):
        for c in range(cols):
            if cand[r, c]:
                for i in range(offsets.shape[0]):
                    rr = r + offsets[i, 0]
                    cc = c + offsets[i, 1]
                    if 0 <= rr < rows and 0 <= cc < cols and src[rr, cc]:
                        out[r, c] = True
                        break


def _check(name: str, *masks: npt.NDArray[np.bool_]) -> None:
    for m in masks:
        if m.ndim != 2 or m.dtype != np.bool_ or m.shape != masks[0].shape:
            raise ConfigError(f"{name}: masks must be 2-D bool arrays of one shape, got "
                              + ", ".join(f"{x.dtype} {x.shape}" for x in masks))


def near_cells(src: npt.NDArray[np.bool_], reach: float) -> npt.NDArray[np.bool_]:
    """Bool (rows, cols): the cells within `reach` [cells] of a `src` cell, as
    ``distance_transform(src) <= reach``, at the cost of the `src` cells times the disc (for few sources).

    Raises:
        ConfigError: `src` not a 2-D bool array, `reach` NaN or infinite.
    """
    s = np.ascontiguousarray(src)
    _check("near_cells", s)
    out = np.zeros(s.shape, dtype=bool)
    d2 = max_d2(reach)
    if d2 >= 0:
        _paint(s, _offsets(d2), out)
    return out


def probe_cells(src: npt.NDArray[np.bool_], cand: npt.NDArray[np.bool_], reach: float) -> npt.NDArray[np.bool_]:
    """Bool (rows, cols): the `cand` cells with a `src` cell within `reach` [cells], as
    ``cand & (distance_transform(src) <= reach)``, at the cost of the `cand` cells times the disc at most
    (for few candidates among many sources).

    Raises:
        ConfigError: masks not 2-D bool arrays of one shape, `reach` NaN or infinite.
    """
    s, c = np.ascontiguousarray(src), np.ascontiguousarray(cand)
    _check("probe_cells", s, c)
    out = np.zeros(s.shape, dtype=bool)
    d2 = max_d2(reach)
    if d2 >= 0:
        _probe(s, c, _offsets(d2), out)
    return out


def within_reference(src: npt.NDArray[np.bool_], reach: float) -> npt.NDArray[np.bool_]:
    """``distance_transform(src) <= reach`` (all False without a `src` cell): the reference of the kernels."""
    if not np.asarray(src).any():
        return np.zeros(np.shape(src), dtype=bool)
    return np.asarray(distance_transform(src) <= reach)
