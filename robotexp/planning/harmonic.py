"""Harmonic (and perturbed) potentials by Gauss-Seidel relaxation, their gradient and region growing.

Thesis (Ribacki 2011) section 3.1: obstacles are held at potential 1, goals (unknown cells) at 0,
and every other cell is relaxed in place by Gauss-Seidel, eq. 3.1,

    p[i, j] <- (p[i-1, j] + p[i+1, j] + p[i, j-1] + p[i, j+1]) / 4,

a fixed number of sweeps per update (never SOR: its unconverged states are unsafe). Arrays are
indexed [row, col] with row 0 at the bottom (see `robotexp.mapping.geometry`), so the thesis's i is
our column (x) and j our row (y). One sweep visits the cells in row-major order (row 0 first, each
row from column 0 up), reading the new values of the cells already visited in this sweep (below and
to the left) and the old values of the others, exactly as eq. 3.1 writes it.

The kernels work on a *padded* array: the outermost ring of cells is never updated and acts as the
Dirichlet boundary of the map (the plugin sets it to 1, a wall around the map). Inside, a cell is
updated unless its `fixed` flag is set.

The perturbed equations the thesis left out (eqs. 3.6 and 3.7, Prestes 2003; Prestes & Engel 2011)
use central differences with a cell side of 1:

    lap p = e . grad p + eps(r) |grad p|,   e = eps * v (eq. 3.6: a preferred direction v, |v| = 1),
    p <- (sum of the 4 neighbours - (e_x gx + e_y gy) - eps(r) |g|) / 4,
    gx = (p[i+1, j] - p[i-1, j]) / 2,  gy = (p[i, j+1] - p[i, j-1]) / 2.

With |e_x|, |e_y| <= 1 and |eps(r)| <= 1 every update is a convex combination of the neighbours, so
values stay within the boundary values and the field keeps the maximum principle (no local minima).

`gauss_seidel_ref` and `gauss_seidel_perturbed_ref` are slow plain-Python references that visit
the cells in the same order; the tests compare the kernels with them.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.mapping.kernels import flood, kernel

__all__ = [
    "descent",
    "descent_field",
    "flood4",
    "free_box",
    "free_box_in",
    "gauss_seidel",
    "gauss_seidel_box",
    "gauss_seidel_perturbed",
    "gauss_seidel_perturbed_box",
    "gauss_seidel_perturbed_ref",
    "gauss_seidel_ref",
    "relax",
    "touches",
]


@kernel
def free_box(fixed: npt.NDArray[np.bool_]) -> tuple[int, int, int, int]:
    """Rows r0..r1 and columns c0..c1 (inclusive) that hold every updated cell (not fixed, not on the outer
    ring); r1 < r0 when there is none. Sweeping only this box changes nothing in the result (every other
    cell keeps its value anyway) and skips the unknown and walled-off parts of the map."""
    return free_box_in(fixed, 0, fixed.shape[0], 0, fixed.shape[1])


@kernel
def free_box_in(fixed: npt.NDArray[np.bool_], wr0: int, wr1: int, wc0: int, wc1: int) -> tuple[int, int, int, int]:
    """`free_box` of the cells in rows wr0..wr1 and columns wc0..wc1 (half-open) only: the caller
    guarantees every updated cell lies there (see `relax`'s window)."""
    rows, cols = fixed.shape
    r0, r1, c0, c1 = rows, -1, cols, -1
    for r in range(max(wr0, 1), min(wr1, rows - 1)):
        for c in range(max(wc0, 1), min(wc1, cols - 1)):
            if not fixed[r, c]:
                r0 = min(r0, r)
                r1 = max(r1, r)
                c0 = min(c0, c)
                c1 = max(c1, c)
    return r0, r1, c0, c1


@kernel
def _gs_cell(p: npt.NDArray[np.float64], fixed: npt.NDArray[np.bool_], r: int, c: int) -> None:
    """One update of eq. 3.1 at (r, c) (kept when fixed)."""
    new = 0.25 * (((p[r - 1, c] + p[r + 1, c]) + p[r, c + 1]) + p[r, c - 1])
    p[r, c] = p[r, c] if fixed[r, c] else new


@kernel
def gauss_seidel(p: npt.NDArray[np.float64], fixed: npt.NDArray[np.bool_], sweeps: int) -> None:
    """Relax `p` (rows, cols) float64 in place by `sweeps` Gauss-Seidel sweeps of eq. 3.1.

    Cells with `fixed` (rows, cols) bool set and the outermost ring keep their values. Only the box of
    the updated cells (`free_box`) is swept. The result is that of the row-major sweep, bit for bit,
    computed four rows at a time on a skewed front: row r + k is at column c - k while row r is at
    column c, so each cell still reads the new values below and to its left and the old ones above
    and to its right, and the four updates of a step are independent (four dependency chains in
    flight instead of one: 4.9x the one-row sweep in `benchmarks/speed/bench_gauss_seidel.py`).
    """
    r0, r1, c0, c1 = free_box(fixed)
    gauss_seidel_box(p, fixed, sweeps, r0, r1, c0, c1)


@kernel
def gauss_seidel_box(p: npt.NDArray[np.float64], fixed: npt.NDArray[np.bool_], sweeps: int,
                     r0: int, r1: int, c0: int, c1: int) -> None:
    """`gauss_seidel` sweeping rows r0..r1 and columns c0..c1 (inclusive, inside the outer ring), which
    must hold every cell not fixed (`free_box`); nothing when r1 < r0."""
    if r1 < r0:
        return
    for _ in range(sweeps):
        r = r0
        while r + 3 <= r1:
            for c in range(c0, min(c0 + 3, c1 + 4)):            # the front enters the band
                for k in range(4):
                    if c0 <= c - k <= c1:
                        _gs_cell(p, fixed, r + k, c - k)
            # all four rows in the box; written out, every load before the stores: four `_gs_cell`
            # calls give the same numbers but measured 5x slower (each store then waits on the loads)
            for c in range(c0 + 3, c1 + 1):
                a = 0.25 * (((p[r - 1, c] + p[r + 1, c]) + p[r, c + 1]) + p[r, c - 1])
                b = 0.25 * (((p[r, c - 1] + p[r + 2, c - 1]) + p[r + 1, c]) + p[r + 1, c - 2])
                d = 0.25 * (((p[r + 1, c - 2] + p[r + 3, c - 2]) + p[r + 2, c - 1]) + p[r + 2, c - 3])
                e = 0.25 * (((p[r + 2, c - 3] + p[r + 4, c - 3]) + p[r + 3, c - 2]) + p[r + 3, c - 4])
                p[r, c] = p[r, c] if fixed[r, c] else a
                p[r + 1, c - 1] = p[r + 1, c - 1] if fixed[r + 1, c - 1] else b
                p[r + 2, c - 2] = p[r + 2, c - 2] if fixed[r + 2, c - 2] else d
                p[r + 3, c - 3] = p[r + 3, c - 3] if fixed[r + 3, c - 3] else e
            for c in range(max(c1 + 1, c0 + 3), c1 + 4):        # the front leaves it
                for k in range(4):
                    if c0 <= c - k <= c1:
                        _gs_cell(p, fixed, r + k, c - k)
            r += 4
        for rr in range(r, r1 + 1):                              # the last rows, one at a time
            for c in range(c0, c1 + 1):
                _gs_cell(p, fixed, rr, c)


@kernel
def gauss_seidel_perturbed(p: npt.NDArray[np.float64], fixed: npt.NDArray[np.bool_], sweeps: int,
                           ex: float, ey: float, eps_abs: npt.NDArray[np.float64]) -> None:
    """Relax `p` in place by `sweeps` Gauss-Seidel sweeps of lap p = e . grad p + eps(r) |grad p|.

    Args:
        p: (rows, cols) float64 potential, padded (the outer ring is the boundary).
        fixed: (rows, cols) bool, True = Dirichlet cell (kept).
        sweeps: number of sweeps.
        ex: eps * v_x of eq. 3.6 [1/cell].
        ey: eps * v_y of eq. 3.6 [1/cell].
        eps_abs: (rows, cols) float64 eps(r) of eq. 3.7 [1/cell].
    """
    r0, r1, c0, c1 = free_box(fixed)
    gauss_seidel_perturbed_box(p, fixed, sweeps, ex, ey, eps_abs, r0, r1, c0, c1)


@kernel
def gauss_seidel_perturbed_box(p: npt.NDArray[np.float64], fixed: npt.NDArray[np.bool_], sweeps: int,
                               ex: float, ey: float, eps_abs: npt.NDArray[np.float64],
                               r0: int, r1: int, c0: int, c1: int) -> None:
    """`gauss_seidel_perturbed` sweeping rows r0..r1 and columns c0..c1 (inclusive) only (`free_box`)."""
    for _ in range(sweeps):
        for r in range(r0, r1 + 1):
            for c in range(c0, c1 + 1):
                if not fixed[r, c]:
                    w = p[r, c - 1]
                    e = p[r, c + 1]
                    s = p[r - 1, c]
                    n = p[r + 1, c]
                    gx = 0.5 * (e - w)
                    gy = 0.5 * (n - s)
                    total = ((s + n) + e) + w
                    p[r, c] = 0.25 * (total - (ex * gx + ey * gy) - eps_abs[r, c] * math.sqrt(gx * gx + gy * gy))


def gauss_seidel_ref(p: npt.NDArray[np.float64], fixed: npt.NDArray[np.bool_], sweeps: int) -> None:
    """Plain-Python reference of `gauss_seidel` (same sweep order and arithmetic); slow."""
    rows, cols = p.shape
    for _ in range(sweeps):
        for r in range(1, rows - 1):
            for c in range(1, cols - 1):
                if not fixed[r, c]:
                    p[r, c] = 0.25 * (((p[r - 1, c] + p[r + 1, c]) + p[r, c + 1]) + p[r, c - 1])


def gauss_seidel_perturbed_ref(p: npt.NDArray[np.float64], fixed: npt.NDArray[np.bool_], sweeps: int,
                               ex: float, ey: float, eps_abs: npt.NDArray[np.float64]) -> None:
    """Plain-Python reference of `gauss_seidel_perturbed` (same sweep order and arithmetic); slow."""
    rows, cols = p.shape
    for _ in range(sweeps):
        for r in range(1, rows - 1):
            for c in range(1, cols - 1):
                if not fixed[r, c]:
                    w, e, s, n = p[r, c - 1], p[r, c + 1], p[r - 1, c], p[r + 1, c]
                    gx, gy = 0.5 * (e - w), 0.5 * (n - s)
                    total = ((s + n) + e) + w
                    p[r, c] = 0.25 * (total - (ex * gx + ey * gy) - eps_abs[r, c] * math.sqrt(gx * gx + gy * gy))


def relax(p: npt.NDArray[np.float64], fixed: npt.NDArray[np.bool_], sweeps: int, *,
          preferred: tuple[float, float] = (0.0, 0.0),
          eps_abs: npt.NDArray[np.float64] | float = 0.0,
          window: tuple[int, int, int, int] | None = None) -> None:
    """Checked entry point: `sweeps` in-place Gauss-Seidel sweeps of the (perturbed) potential.

    Uses the plain Laplace kernel when both perturbations are zero. With `window` only its rows and
    columns are read and swept (its outer ring is their boundary): the same result as the whole array
    when every cell outside the window's inner part is fixed, at a cost that follows the window.

    Args:
        p: (rows, cols) C-contiguous float64 potential, padded: the outer ring is the boundary.
        fixed: (rows, cols) bool, True = Dirichlet cell.
        sweeps: number of sweeps, >= 0.
        preferred: eps * v of eq. 3.6 as (x, y) [1/cell]; each component within [-1, 1].
        eps_abs: eps(r) of eq. 3.7 [1/cell], a scalar or a (rows, cols) array, within [-1, 1].
        window: rows r0..r1 and columns c0..c1 (half-open) of `p`, or None for all of it.

    Raises:
        ConfigError: wrong shapes or dtypes, a negative sweep count, a perturbation out of range.
    """
    if not (isinstance(p, np.ndarray) and p.dtype == np.float64 and p.ndim == 2 and p.flags.c_contiguous):
        raise ConfigError("relax: p must be a C-contiguous 2-D float64 array")
    if not (isinstance(fixed, np.ndarray) and fixed.dtype == np.bool_ and fixed.shape == p.shape):
        raise ConfigError(f"relax: fixed must be a bool array of shape {p.shape}")
    if sweeps < 0:
        raise ConfigError(f"relax: sweeps must be >= 0, got {sweeps}")
    ex, ey = float(preferred[0]), float(preferred[1])
    if not (abs(ex) <= 1.0 and abs(ey) <= 1.0):
        raise ConfigError(f"relax: preferred (eps * v) components must be within [-1, 1], got {preferred}")
    eps = np.asarray(eps_abs, np.float64)
    if eps.ndim and eps.shape != p.shape:
        raise ConfigError(f"relax: eps_abs must be a scalar or an array of shape {p.shape}, got {eps.shape}")
    if not (np.abs(eps) <= 1.0).all():
        raise ConfigError("relax: eps_abs must be within [-1, 1] everywhere")
    wr0, wr1, wc0, wc1 = (0, p.shape[0], 0, p.shape[1]) if window is None else (int(v) for v in window)
    if not (0 <= wr0 < wr1 <= p.shape[0] and 0 <= wc0 < wc1 <= p.shape[1]):
        raise ConfigError(f"relax: window rows {wr0}..{wr1}, cols {wc0}..{wc1} is not inside {p.shape}")
    # the window's outer ring is its boundary: only the cells inside it are updated
    r0, r1, c0, c1 = free_box_in(fixed, wr0 + 1, wr1 - 1, wc0 + 1, wc1 - 1)
    if ex == 0.0 and ey == 0.0 and not eps.any():
        gauss_seidel_box(p, fixed, int(sweeps), r0, r1, c0, c1)
    else:
        field = np.ascontiguousarray(np.broadcast_to(eps, p.shape)) if eps.ndim else np.full(p.shape, float(eps))
        gauss_seidel_perturbed_box(p, fixed, int(sweeps), ex, ey, field, r0, r1, c0, c1)


def descent(p: npt.NDArray[np.float64], row: int, col: int) -> tuple[float, float]:
    """The descent vector of eq. 3.2 at cell (row, col): ((p_W - p_E) / 2, (p_S - p_N) / 2).

    p_W is p[row, col - 1] (smaller x), p_S is p[row - 1, col] (smaller y). The cell's own value
    is not used. The cell must not be on the outer ring of `p`.
    """
    return (0.5 * float(p[row, col - 1] - p[row, col + 1]), 0.5 * float(p[row - 1, col] - p[row + 1, col]))


def descent_field(p: npt.NDArray[np.float64], tiny: float = 1e-14) -> npt.NDArray[np.float64]:
    """Unit descent directions of eq. 3.2 over the interior of the padded `p`.

    Returns:
        (rows - 2, cols - 2, 2) float64 (x, y) unit vectors; (0, 0) where |v| <= `tiny`.
    """
    vx = 0.5 * (p[1:-1, :-2] - p[1:-1, 2:])
    vy = 0.5 * (p[:-2, 1:-1] - p[2:, 1:-1])
    norm = np.hypot(vx, vy)
    ok = norm > tiny
    out = np.zeros(vx.shape + (2,), np.float64)
    out[ok, 0] = vx[ok] / norm[ok]
    out[ok, 1] = vy[ok] / norm[ok]
    return out


@kernel
def flood4(mask: npt.NDArray[np.bool_], row: int, col: int) -> npt.NDArray[np.bool_]:
    """Region growing: bool (rows, cols), the 4-connected component of `mask` holding (row, col).

    4-connected, like the 5-point stencil of eq. 3.1: a region joined to a goal only through a
    diagonal gets no potential gradient towards it. Empty when (row, col) is outside or unset.
    """
    return flood(mask, row, col, False)


def touches(region: npt.NDArray[np.bool_], target: npt.NDArray[np.bool_]) -> bool:
    """True when a cell of `region` has a 4-neighbour in `target` (both (rows, cols) bool)."""
    hit = np.zeros_like(region)
    hit[1:, :] |= target[:-1, :]
    hit[:-1, :] |= target[1:, :]
    hit[:, 1:] |= target[:, :-1]
    hit[:, :-1] |= target[:, 1:]
    return bool((hit & region).any())
