"""Santos's exploration objective (Santos 2016, ch. 3): a surface over the map whose minima are targets.

Three cell lists come from the map: FRONTIER (free cells next to unknown ones), OCCUPIED and VISITED
(cells the robot centre passed). At a point p, with distances in Santos's unit of one 5 cm cell:

    C_f(p) = -sum_{k in FRONTIER} exp(-d(p, k) / (2 sigma_f^2))      (eq. 3.1, attracts)
    C_o(p) = +sum_{k in OCCUPIED} exp(-d(p, k) / (2 sigma_o^2))      (eq. 3.2, repels)
    C_v(p) = +sum_{k in VISITED}  exp(-d(p, k) / (2 sigma_v^2))      (eq. 3.3, repels)

**d is the squared Euclidean distance.** The thesis only calls d "the distance function", but it
writes each term as exp(-d / (2 sigma^2)) and calls sigma the width ("amplitude") of the behaviour,
which is the Gaussian of the distance, exp(-|p - k|^2 / (2 sigma^2)) (Julia et al. 2011, whom
Santos follows). The Gaussian also gives the sensible reach with the published widths: a frontier
cell attracts over ~3 sigma_f = 4.5 cells (22 cm), obstacles repel over ~60 cm; with a plain
distance an obstacle would still weigh 0.53 at 1 m. And it is separable, which makes the whole
surface a pair of 1-D convolutions.

Forms (delta = Euclidean distance from p to the robot, in the same unit):
basic f = alpha C_f + beta C_o + gamma C_v (3.4); conditional loss: alpha_near within `radius` of
the robot, alpha elsewhere (3.5); linear loss f + rho delta (3.6); proportional loss
f / (rho delta) (3.7), with delta floored at one unit so the robot's own cell stays finite.
Points the robot cannot use (unknown cells in Santos's Algorithm 3; here any cell outside the
`feasible` mask) are worth `INFEASIBLE` (Santos's M).

Speed: sums of Gaussians over thousands of cells are never evaluated point by point in Python.
`gaussian_sum` rasterises a list and convolves it with a Gaussian kernel truncated at
R = ceil(sigma sqrt(2 ln(1/TRUNCATION))) cells per axis (a row pass that scatters only the list's
cells, then a dense column pass, in numba). Every omitted term is below TRUNCATION = 1e-6 times the
weight of a cell at distance 0, so the absolute error of a component at any point is at most
1e-6 x (number of cells in its list): below 0.01 for 10,000 cells. `Objective.exact` evaluates the
sums directly (vectorised, untruncated) at off-grid points.

Coordinates: a point is (x, y) in cells, x = col + fraction, y = row + fraction (cell (r, c)
covers [c, c+1) x [r, r+1), its centre is (c + 0.5, r + 0.5)); decoding is floor (eq. 3.8).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.mapping.kernels import kernel

__all__ = ["FORMS", "INFEASIBLE", "PRESETS", "SANTOS_CELL", "TRUNCATION", "Objective", "ObjectiveParams",
           "gaussian_sum", "gaussian_taps", "lookup", "params_for"]

Form = Literal["basic", "conditional", "linear", "proportional"]
FORMS: tuple[str, ...] = ("basic", "conditional", "linear", "proportional")
SANTOS_CELL = 0.05      # [m] the unit of every length parameter (Santos's grid cell)
INFEASIBLE = 1e15       # Santos's M: far above any |f| a map can produce (|f| <= weights x cells)
TRUNCATION = 1e-6       # largest Gaussian term omitted by `gaussian_sum`


@dataclass(frozen=True)
class ObjectiveParams:
    """Weights and widths of the objective; lengths in cells of 5 cm (Santos's unit).

    Attributes:
        form: "basic", "conditional", "linear" or "proportional".
        alpha: weight of C_f (alpha_2, outside the radius, in the conditional form).
        beta: weight of C_o.
        gamma: weight of C_v.
        sigma_f: [5 cm] width of the frontier Gaussian.
        sigma_o: [5 cm] width of the obstacle Gaussian.
        sigma_v: [5 cm] width of the visited Gaussian.
        alpha_near: conditional form: weight of C_f within `radius` of the robot (alpha_1).
        radius: [5 cm] conditional form: the locality threshold k.
        rho: linear and proportional forms: weight of the distance to the robot [1/(5 cm)].
    """

    form: Form = "proportional"
    alpha: float = 500.0
    beta: float = 150.0
    gamma: float = 3.0
    sigma_f: float = 1.5
    sigma_o: float = 4.0
    sigma_v: float = 3.45
    alpha_near: float = 0.0
    radius: float = 0.0
    rho: float = 0.1

    def __post_init__(self) -> None:
        if self.form not in FORMS:
            raise ConfigError(f"objective: form must be one of {', '.join(FORMS)}, got {self.form!r}")
        for name in ("sigma_f", "sigma_o", "sigma_v"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) > 0):
                raise ConfigError(f"objective: {name} must be > 0 (cells of 5 cm), got {getattr(self, name)}")
        for name in ("alpha", "beta", "gamma", "alpha_near", "radius", "rho"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise ConfigError(f"objective: {name} must be finite and >= 0, got {getattr(self, name)}")
        if self.form == "proportional" and self.rho <= 0:
            raise ConfigError("objective: the proportional form divides by rho; rho must be > 0")


# Santos 2016, Tables 2-5 (alpha_1 = 3 alpha_2 in Table 3; Table 3 keeps Table 2's widths).
PRESETS: dict[str, ObjectiveParams] = {
    "basic": ObjectiveParams("basic", alpha=50, beta=100, gamma=3, rho=0.0),
    "conditional": ObjectiveParams("conditional", alpha=500, alpha_near=1500, beta=10, gamma=30, radius=30,
                                   rho=0.0),
    "linear": ObjectiveParams("linear", alpha=5000, beta=1000, gamma=2000, rho=10),
    "proportional": ObjectiveParams("proportional", alpha=500, beta=150, gamma=3, rho=0.1),
}


def gaussian_taps(sigma: float) -> npt.NDArray[np.float64]:
    """The 1-D kernel exp(-x^2 / (2 sigma^2)) for x = -R..R, R = ceil(sigma sqrt(2 ln(1/TRUNCATION))).

    Args:
        sigma: [cells] width, > 0.

    Returns:
        (2R + 1,) float64 taps; the omitted ones are below TRUNCATION.

    Raises:
        ConfigError: sigma not finite and > 0.
    """
    if not (math.isfinite(sigma) and sigma > 0):
        raise ConfigError(f"gaussian_taps: sigma must be > 0 cells, got {sigma}")
    half = int(math.ceil(sigma * math.sqrt(2.0 * math.log(1.0 / TRUNCATION))))
    x = np.arange(-half, half + 1, dtype=np.float64)
    return np.exp(-x * x / (2.0 * sigma * sigma))


@kernel
def _separable_sum(src_r: npt.NDArray[np.int64], src_c: npt.NDArray[np.int64], taps: npt.NDArray[np.float64],
                   tmp: npt.NDArray[np.float64], out: npt.NDArray[np.float64]) -> None:
    """out[r, c] = sum over sources k of taps[r - r_k + R] * taps[c - c_k + R] (|offsets| <= R).

    Row pass: scatter each source's taps along its row into `tmp` (only the sources are visited), noting
    the columns lo..hi of each row it wrote. Column pass: out = tmp convolved with the taps along the
    columns, over each row's written columns only: the others hold exact zeros, whose terms (+0.0) leave
    every sum as it is, so the result is that of the dense pass bit for bit (`separable_sum_reference`) at
    the cost of the rows and columns near a source.
    """
    rows, cols = out.shape
    half = (taps.size - 1) // 2
    tmp[:, :] = 0.0
    lo = np.full(rows, cols, dtype=np.int64)
    hi = np.zeros(rows, dtype=np.int64)
    for i in range(src_r.size):
        r = src_r[i]
        c = src_c[i]
        c0, c1 = max(c - half, 0), min(c + half + 1, cols)
        lo[r] = min(lo[r], c0)
        hi[r] = max(hi[r], c1)
        for cc in range(c0, c1):
            tmp[r, cc] += taps[cc - c + half]
    out[:, :] = 0.0
    for r in range(rows):
        for rr in range(max(r - half, 0), min(r + half + 1, rows)):
            a, b = lo[rr], hi[rr]
            if b > a:
                _axpy(out[r, a:b], taps[rr - r + half], tmp[rr, a:b])


@kernel
def _axpy(out: npt.NDArray[np.float64], w: float, x: npt.NDArray[np.float64]) -> None:
    """out += w x, element by element (1-D, one size)."""
    for i in range(out.size):
        out[i] += w * x[i]


def separable_sum_reference(src_r: npt.NDArray[np.int64], src_c: npt.NDArray[np.int64], taps: npt.NDArray[np.float64],
                            shape: tuple[int, int]) -> npt.NDArray[np.float64]:
    """`_separable_sum` in plain numpy, the dense passes in the kernel's order (each sum over the rows in
    ascending order): the reference the kernel is tested against, bit for bit."""
    rows, cols = shape
    half = (taps.size - 1) // 2
    tmp = np.zeros(shape, np.float64)
    for i in range(src_r.size):
        r, c = int(src_r[i]), int(src_c[i])
        lo, hi = max(c - half, 0), min(c + half + 1, cols)
        tmp[r, lo:hi] += taps[lo - c + half:hi - c + half]
    out = np.zeros(shape, np.float64)
    for k in range(-half, half + 1):        # out[r] += taps[k + half] * tmp[r + k], k ascending
        r0, r1 = max(-k, 0), min(rows - k, rows)
        if r1 > r0:
            out[r0:r1] += taps[k + half] * tmp[r0 + k:r1 + k]
    return out


def gaussian_sum(mask: npt.NDArray[np.bool_], sigma: float) -> npt.NDArray[np.float64]:
    """sum_{k: mask[k]} exp(-|p - k|^2 / (2 sigma^2)) at every cell centre p, truncated (see module).

    Args:
        mask: (rows, cols) bool, the cells of one list.
        sigma: [cells] width, > 0.

    Returns:
        (rows, cols) float64 sums.

    Raises:
        ConfigError: `mask` not a 2-D bool array, sigma <= 0.
    """
    m = np.asarray(mask)
    if m.ndim != 2 or m.dtype != np.bool_:
        raise ConfigError(f"gaussian_sum: mask must be a 2-D bool array, got {m.dtype} {m.shape}")
    taps = gaussian_taps(sigma)
    rr, cc = np.nonzero(m)
    out = np.empty(m.shape, dtype=np.float64)
    _separable_sum(rr.astype(np.int64), cc.astype(np.int64), taps, np.empty(m.shape, np.float64), out)
    return out


def lookup(surface: npt.NDArray[np.float64], points: npt.NDArray[np.float64],
           origin: tuple[int, int] = (0, 0)) -> npt.NDArray[np.float64]:
    """Values of `surface` at continuous points decoded to their cells (floor; eq. 3.8).

    Args:
        surface: (rows, cols) float64.
        points: (n, 2) float64 (x, y) in cells.
        origin: (row, col) of `surface`'s cell (0, 0) in the cells of the points, when `surface` is a
            window of a larger grid (every cell outside it worth INFEASIBLE).

    Returns:
        (n,) float64; INFEASIBLE for points outside `surface`.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    rows, cols = surface.shape
    c = np.floor(p[:, 0]) - origin[1]
    r = np.floor(p[:, 1]) - origin[0]
    inside = (c >= 0) & (c < cols) & (r >= 0) & (r < rows)
    out = np.full(len(p), INFEASIBLE)
    out[inside] = surface[r[inside].astype(np.intp), c[inside].astype(np.intp)]
    return out


class Objective:
    """The objective of one map state, as a surface over every cell and as exact off-grid sums.

    Args:
        params: weights, widths and form.
        frontier: (rows, cols) bool FRONTIER cells.
        occupied: (rows, cols) bool OCCUPIED cells.
        visited: (rows, cols) bool VISITED cells.
        robot: (x, y) [cells] robot position (continuous, as points).
        feasible: (rows, cols) bool cells a target may lie in (Santos: the known cells; the
            plugins: cells the robot can reach and stand on); None: every cell.
        cell: [m] side of a grid cell; lengths are converted from Santos's 5 cm cells.
        origin: (row, col) of the masks' cell (0, 0) in a larger grid when they cover a window of it
            (every cell outside empty and infeasible: `OccupancyGrid.window`); `robot` and the points
            given to the objective are then in the larger grid's cells, and the surface equals the
            larger grid's over the window, bit for bit.

    Attributes:
        surface: (rows, cols) float64 objective at every cell centre, INFEASIBLE outside `feasible`.
        components: (C_f, C_o, C_v) at every cell centre, each (rows, cols) float64.

    Raises:
        ConfigError: masks of different shapes or not bool, cell <= 0.
    """

    def __init__(self, params: ObjectiveParams, frontier: npt.NDArray[np.bool_], occupied: npt.NDArray[np.bool_],
                 visited: npt.NDArray[np.bool_], robot: tuple[float, float],
                 feasible: npt.NDArray[np.bool_] | None = None, *, cell: float = SANTOS_CELL,
                 origin: tuple[int, int] = (0, 0)) -> None:
        shape = np.shape(frontier)
        for name, m in (("frontier", frontier), ("occupied", occupied), ("visited", visited),
                        ("feasible", feasible)):
            if m is not None and (np.shape(m) != shape or np.asarray(m).dtype != np.bool_ or len(shape) != 2):
                raise ConfigError(f"objective: {name} must be a bool array of the frontier's shape {shape}, "
                                  f"got {np.asarray(m).dtype} {np.shape(m)}")
        if not (math.isfinite(cell) and cell > 0):
            raise ConfigError(f"objective: cell must be > 0 m, got {cell}")
        self.params = params
        self.unit = cell / SANTOS_CELL          # [5 cm] per cell
        self.robot = (float(robot[0]), float(robot[1]))
        self.origin = (int(origin[0]), int(origin[1]))
        self._masks = tuple(np.array(m, dtype=bool) for m in (frontier, occupied, visited))   # for `lists`
        s = self._sigmas()
        cf = -gaussian_sum(np.asarray(frontier), s[0])
        co = gaussian_sum(np.asarray(occupied), s[1])
        cv = gaussian_sum(np.asarray(visited), s[2])
        self.components = (cf, co, cv)
        if feasible is None:
            rows, cols = shape
            y, x = np.mgrid[0:rows, 0:cols]
            self.surface = self._combine(cf, co, cv, (x + self.origin[1]) + 0.5, (y + self.origin[0]) + 0.5)
        else:       # the same values, computed at the feasible cells only
            r, c = np.nonzero(np.asarray(feasible))
            self.surface = np.full(shape, INFEASIBLE)
            x = np.asarray((c + self.origin[1]) + 0.5, dtype=np.float64)
            y = np.asarray((r + self.origin[0]) + 0.5, dtype=np.float64)
            self.surface[r, c] = self._combine(cf[r, c], co[r, c], cv[r, c], x, y)

    @functools.cached_property
    def lists(self) -> tuple[npt.NDArray[np.int64], ...]:
        """The (row, col) cells of FRONTIER, OCCUPIED and VISITED (in the larger grid's cells), each (k, 2),
        made when first asked for (`exact` needs them; the surface does not)."""
        return tuple(np.argwhere(m) + self.origin for m in self._masks)

    def _sigmas(self) -> tuple[float, float, float]:
        p = self.params
        return (p.sigma_f / self.unit, p.sigma_o / self.unit, p.sigma_v / self.unit)

    def _combine(self, cf: npt.NDArray[np.float64], co: npt.NDArray[np.float64], cv: npt.NDArray[np.float64],
                 x: npt.NDArray[np.float64], y: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        p = self.params
        delta = np.hypot(x - self.robot[0], y - self.robot[1]) * self.unit     # [5 cm]
        alpha = np.where(delta <= p.radius, p.alpha_near, p.alpha) if p.form == "conditional" else p.alpha
        f = alpha * cf + p.beta * co + p.gamma * cv
        if p.form == "linear":
            f = f + p.rho * delta
        elif p.form == "proportional":
            f = f / (p.rho * np.maximum(delta, 1.0))
        return np.asarray(f, dtype=np.float64)

    def __call__(self, points: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Objective at (n, 2) points [cells], read from the surface at their cells (fast)."""
        return lookup(self.surface, points, self.origin)

    def exact(self, points: npt.NDArray[np.float64], chunk: int = 256) -> npt.NDArray[np.float64]:
        """Objective at (n, 2) off-grid points [cells] by direct, untruncated vectorised sums.

        Feasibility is read from the cell each point decodes to, as in Santos's Algorithm 3.
        """
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        sig = self._sigmas()
        comps = []
        for cells, s in zip(self.lists, sig, strict=True):
            centres = cells[:, ::-1].astype(np.float64) + 0.5          # (x, y) of each list cell
            total = np.zeros(len(p))
            for i in range(0, len(p), chunk):
                d2 = ((p[i:i + chunk, None, :] - centres[None, :, :]) ** 2).sum(axis=2)
                total[i:i + chunk] = np.exp(-d2 / (2.0 * s * s)).sum(axis=1)
            comps.append(total)
        f = self._combine(-comps[0], comps[1], comps[2], p[:, 0], p[:, 1])
        f[lookup(self.surface, p, self.origin) >= INFEASIBLE] = INFEASIBLE
        return f

    def optimum(self) -> tuple[tuple[int, int], float]:
        """The exhaustive optimum: the (row, col) of the least surface value (in the larger grid's cells),
        and that value."""
        k = int(np.argmin(self.surface))
        r, c = divmod(k, self.surface.shape[1])
        return (r + self.origin[0], c + self.origin[1]), float(self.surface[r, c])


def params_for(form: str, **overrides: float) -> ObjectiveParams:
    """The preset of `form` (Tables 2-5) with some fields replaced.

    Raises:
        ConfigError: unknown form or field, or a value out of range.
    """
    if form not in PRESETS:
        raise ConfigError(f"objective: unknown form {form!r}; use one of {', '.join(FORMS)}")
    try:
        return replace(PRESETS[form], **overrides)     # type: ignore[arg-type]
    except TypeError as exc:
        raise ConfigError(f"objective: {exc}") from exc
