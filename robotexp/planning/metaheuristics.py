"""Target search on an objective surface: steady-state GA, firefly algorithm, exhaustive optimum.

Santos 2016 (sections 2.4, 4.3.2, 5.2). Both metaheuristics are real-coded over points (x, y) in
cells (see `robotexp.planning.objective`), evaluate a whole population at once by looking the
points up in the surface (decoded by floor, eq. 3.8; INFEASIBLE outside the feasible cells) and
return the best point they evaluated. All randomness comes from the `numpy.random.Generator` given.

Initial populations are drawn uniformly over the feasible cells (uniform within each cell): Santos
spreads them "uniformly over the environment", and early in a run most of a uniform sample would
land in unknown space, where every point is worth M and a 20-firefly swarm could not move at all.

Stopping rules: Santos stops both at "the maximum number of generations / iterations" without
giving the numbers (Tables 6-7 give only P_crossover 1, P_mutation 0.1, P_size 1024 for the GA and
beta_0 1, alpha_t 0.3, gamma 0.4, P_size 20 for the firefly). Ours, chosen by
`benchmarks/studies/bench_metaheuristics.py` (distance to the exhaustive optimum against time): the GA
runs 60 generations of 64 children each (6 % of the population per generation, steady state); the
firefly runs 100 iterations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.mapping.kernels import kernel
from robotexp.planning.objective import INFEASIBLE, lookup

__all__ = ["FireflyConfig", "GAConfig", "SearchResult", "blx_crossover", "exhaustive", "firefly_move",
           "firefly_search", "genetic_search", "initial_population", "nonuniform_mutation", "roulette"]

Points = npt.NDArray[np.float64]


@dataclass(frozen=True)
class SearchResult:
    """The best point a search found.

    Attributes:
        point: (x, y) [cells], continuous.
        cell: (row, col) the point decodes to.
        value: its objective value (INFEASIBLE when no feasible point was found).
        evaluations: objective evaluations made.
    """

    point: tuple[float, float]
    cell: tuple[int, int]
    value: float
    evaluations: int


@dataclass(frozen=True)
class GAConfig:
    """Genetic algorithm (Santos Table 6; generations and children are ours, see the module).

    Attributes:
        population: P_size.
        p_crossover: probability that a pair of parents is crossed (else the children are copies).
        p_mutation: probability that one gene (x or y) of a child is mutated.
        blx_alpha: BLX-alpha extension of the parents' interval on each side (0.25).
        generations: T, the number of generations (also the horizon of the non-uniform mutation).
        children: children per generation (even); they replace the worse members of the population.
        mutation_b: shape b of the non-uniform mutation (Michalewicz 1992: 5).
    """

    population: int = 1024
    p_crossover: float = 1.0
    p_mutation: float = 0.1
    blx_alpha: float = 0.25
    generations: int = 60
    children: int = 64
    mutation_b: float = 5.0

    def __post_init__(self) -> None:
        if self.population < 2 or self.generations < 1 or self.children < 2 or self.children % 2:
            raise ConfigError(f"GA: need population >= 2, generations >= 1 and an even children >= 2, got {self}")
        if not (0 <= self.p_crossover <= 1 and 0 <= self.p_mutation <= 1):
            raise ConfigError(f"GA: probabilities must be within [0, 1], got {self}")
        if not (self.blx_alpha >= 0 and self.mutation_b > 0):
            raise ConfigError(f"GA: need blx_alpha >= 0 and mutation_b > 0, got {self}")


@dataclass(frozen=True)
class FireflyConfig:
    """Firefly algorithm (Santos Table 7; iterations and decay are ours, see the module).

    Distances are measured in units of the map's longer side L (points / L lie in [0, 1]), as Yang
    recommends scaling gamma and alpha to the problem: with gamma = 0.4 per cell two fireflies 5
    cells apart would not see each other at all.

    Attributes:
        population: P_size.
        beta0: attractiveness at distance 0.
        alpha: alpha_0, the random step [L]; alpha_t = alpha * decay^t.
        gamma: light absorption [1/L^2].
        iterations: number of sweeps over all pairs.
        decay: factor of alpha per iteration (Yang 2010: 0.95..0.97).
    """

    population: int = 20
    beta0: float = 1.0
    alpha: float = 0.3
    gamma: float = 0.4
    iterations: int = 100
    decay: float = 0.95

    def __post_init__(self) -> None:
        if self.population < 2 or self.iterations < 1:
            raise ConfigError(f"firefly: need population >= 2 and iterations >= 1, got {self}")
        if not (self.beta0 >= 0 and self.alpha >= 0 and self.gamma >= 0 and 0 < self.decay <= 1):
            raise ConfigError(f"firefly: need beta0, alpha, gamma >= 0 and 0 < decay <= 1, got {self}")


def _result(point: npt.NDArray[np.float64], value: float, evaluations: int) -> SearchResult:
    x, y = float(point[0]), float(point[1])
    return SearchResult((x, y), (int(math.floor(y)), int(math.floor(x))), float(value), int(evaluations))


def initial_population(surface: npt.NDArray[np.float64], n: int, rng: np.random.Generator,
                       origin: tuple[int, int] = (0, 0), shape: tuple[int, int] | None = None) -> Points:
    """n points drawn uniformly over the feasible cells of `surface` (uniformly within each cell).

    Without feasible cells, uniformly over the whole grid. Returns (n, 2) float64 (x, y) [cells].
    `surface` may be a window of a larger grid of `shape` (None: the surface's own) whose cell (0, 0) is
    `origin` there, every cell outside it infeasible: the points, in the larger grid's cells, are then
    the ones drawn on the whole grid, bit for bit (the feasible cells keep their order).
    """
    rows, cols = shape if shape is not None else surface.shape
    wcols = surface.shape[1]
    cells = np.flatnonzero(surface.ravel() < INFEASIBLE)
    if cells.size:
        k = rng.choice(cells, size=n)
        col, row = k % wcols + origin[1], k // wcols + origin[0]
    else:
        k = rng.integers(0, rows * cols, size=n)
        col, row = k % cols, k // cols
    jitter = rng.random((n, 2))
    return np.column_stack([col + jitter[:, 0], row + jitter[:, 1]])


def exhaustive(surface: npt.NDArray[np.float64]) -> SearchResult:
    """The optimum over every cell: the centre of the cell of least value."""
    k = int(np.argmin(surface))
    r, c = divmod(k, surface.shape[1])
    return _result(np.array([c + 0.5, r + 0.5]), float(surface[r, c]), surface.size)


# -- GA operators -------------------------------------------------------------------------------

def roulette(values: npt.NDArray[np.float64], k: int, rng: np.random.Generator) -> npt.NDArray[np.intp]:
    """Roulette-wheel selection of k indices for a minimisation.

    Fitness is linearly scaled from the objective (Goldberg's windowing): fitness_i =
    max_feasible(f) - f_i, 0 for infeasible members (f >= INFEASIBLE); member i is drawn with
    probability fitness_i / sum(fitness). When all fitnesses are 0 the draw is uniform over the
    feasible members (over all when none is feasible).
    """
    v = np.asarray(values, dtype=np.float64)
    ok = v < INFEASIBLE
    fit = np.zeros(len(v))
    if ok.any():
        fit[ok] = v[ok].max() - v[ok]
    total = fit.sum()
    if not total > 0:
        fit = ok.astype(np.float64) if ok.any() else np.ones(len(v))
        total = fit.sum()
    return np.asarray(rng.choice(len(v), size=k, p=fit / total), dtype=np.intp)


def blx_crossover(p1: Points, p2: Points, alpha: float, rng: np.random.Generator,
                  lo: npt.NDArray[np.float64], hi: npt.NDArray[np.float64]) -> tuple[Points, Points]:
    """BLX-alpha: per gene, children uniform in [min - alpha d, max + alpha d], d = |p1 - p2|.

    Args:
        p1: (n, 2) first parents.
        p2: (n, 2) second parents.
        alpha: extension on each side (0.25 for BLX-0.25).
        rng: draws (n, 2) uniforms for the first children, then (n, 2) for the second.
        lo: (2,) lower bounds of the genes.
        hi: (2,) upper bounds; children are clipped to [lo, hi].

    Returns:
        The two (n, 2) arrays of children.
    """
    a = np.minimum(p1, p2)
    b = np.maximum(p1, p2)
    d = b - a
    low, span = a - alpha * d, (1 + 2 * alpha) * d
    c1 = np.clip(low + rng.random(a.shape) * span, lo, hi)
    c2 = np.clip(low + rng.random(a.shape) * span, lo, hi)
    return c1, c2


def nonuniform_mutation(x: Points, t: int, horizon: int, lo: npt.NDArray[np.float64], hi: npt.NDArray[np.float64],
                        p: float, b: float, rng: np.random.Generator) -> Points:
    """Michalewicz's non-uniform mutation: steps shrink as generation t approaches `horizon`.

    Each gene mutates with probability p: x + D(t, hi - x) or x - D(t, x - lo) (equally likely),
    D(t, y) = y (1 - u^((1 - t/T)^b)), u uniform in [0, 1): at t = 0 the mean step is y/2, at
    t = T it is 0. Draws, in order: (n, 2) uniforms for "mutate", (n, 2) for the direction (up when
    < 0.5), (n, 2) for u.

    Returns:
        (n, 2) mutated copy of x.
    """
    mutate = rng.random(x.shape) < p
    up = rng.random(x.shape) < 0.5
    u = rng.random(x.shape)
    shrink = 1.0 - u ** ((1.0 - min(t, horizon) / horizon) ** b)
    step = np.where(up, (hi - x) * shrink, -(x - lo) * shrink)
    return np.where(mutate, x + step, x)


def genetic_search(surface: npt.NDArray[np.float64], rng: np.random.Generator,
                   config: GAConfig | None = None, origin: tuple[int, int] = (0, 0),
                   shape: tuple[int, int] | None = None) -> SearchResult:
    """Steady-state real-coded GA (roulette, BLX-alpha, non-uniform mutation) on `surface`.

    Each generation draws `children` / 2 pairs of parents by roulette, crosses each pair with
    probability p_crossover (BLX), mutates the children, evaluates them and lets them replace the
    members of the population that are worse than them (the best `population` of the union stay).
    Genes range over the grid of `shape` (None: the surface's); `surface` may be its window at
    `origin` (see `initial_population`): the same search as on the whole grid, at the window's cost.
    """
    cfg = config or GAConfig()
    rows, cols = shape if shape is not None else surface.shape
    lo = np.zeros(2)
    hi = np.array([np.nextafter(cols, 0), np.nextafter(rows, 0)])
    pop = initial_population(surface, cfg.population, rng, origin, (rows, cols))
    val = lookup(surface, pop, origin)
    evaluations = len(pop)
    half = cfg.children // 2
    for t in range(cfg.generations):
        parents = roulette(val, cfg.children, rng)
        p1, p2 = pop[parents[:half]], pop[parents[half:]]
        c1, c2 = blx_crossover(p1, p2, cfg.blx_alpha, rng, lo, hi)
        keep = rng.random(half) >= cfg.p_crossover           # pairs not crossed: copies of the parents
        c1[keep], c2[keep] = p1[keep], p2[keep]
        kids = nonuniform_mutation(np.vstack([c1, c2]), t, cfg.generations, lo, hi, cfg.p_mutation,
                                   cfg.mutation_b, rng)
        kval = lookup(surface, kids, origin)
        evaluations += len(kids)
        allp = np.vstack([pop, kids])
        allv = np.concatenate([val, kval])
        best = np.argpartition(allv, cfg.population - 1)[:cfg.population]
        pop, val = allp[best], allv[best]
    i = int(np.argmin(val))
    return _result(pop[i], float(val[i]), evaluations)


# -- firefly ------------------------------------------------------------------------------------

def firefly_move(xi: Points, xj: Points, beta0: float, gamma: float, alpha: float, eps: Points) -> Points:
    """One move of firefly i towards a brighter j: x_i + beta0 e^(-gamma r^2) (x_j - x_i) + alpha eps.

    Santos eq. 2.20; r = |x_j - x_i|; eps is the random vector (uniform in [-0.5, 0.5] per axis in
    `firefly_search`). Works on (2,) points or (n, 2) arrays of them.
    """
    d = np.asarray(xj, dtype=np.float64) - np.asarray(xi, dtype=np.float64)
    r2 = np.sum(d * d, axis=-1, keepdims=True)
    return np.asarray(xi + beta0 * np.exp(-gamma * r2) * d + alpha * np.asarray(eps), dtype=np.float64)


@kernel
def _window_value(surface: npt.NDArray[np.float64], r: int, c: int) -> float:
    """surface[r, c], INFEASIBLE outside it."""
    if 0 <= r < surface.shape[0] and 0 <= c < surface.shape[1]:
        return float(surface[r, c])
    return INFEASIBLE


@kernel
def _firefly_kernel(surface: npt.NDArray[np.float64], pos: npt.NDArray[np.float64],  # noqa: PLR0913
                    eps: npt.NDArray[np.float64], alphas: npt.NDArray[np.float64], beta0: float, gamma: float,
                    best: npt.NDArray[np.float64], r0: int, c0: int, rows: int, cols: int) -> int:
    """Run the firefly sweeps in place on `pos` (n, 2) [units of L]; write (x, y, f) of the best to `best`.

    eps (iterations, n, n, 2) holds the random vectors, alphas (iterations,) the step sizes. The grid
    has rows x cols cells; `surface` is its window from cell (r0, c0), every cell outside infeasible.
    Returns the number of evaluations.
    """
    scale = float(max(rows, cols))
    xmax = np.nextafter(cols / scale, 0.0)
    ymax = np.nextafter(rows / scale, 0.0)
    n = pos.shape[0]
    val = np.empty(n)
    for i in range(n):
        val[i] = _window_value(surface, min(int(pos[i, 1] * scale), rows - 1) - r0,
                               min(int(pos[i, 0] * scale), cols - 1) - c0)
    evals = n
    k = int(np.argmin(val))
    best[0], best[1], best[2] = pos[k, 0], pos[k, 1], val[k]
    for t in range(alphas.size):
        a = alphas[t]
        for i in range(n):
            for j in range(n):
                if val[j] < val[i]:
                    dx = pos[j, 0] - pos[i, 0]
                    dy = pos[j, 1] - pos[i, 1]
                    b = beta0 * math.exp(-gamma * (dx * dx + dy * dy))
                    x = min(max(pos[i, 0] + b * dx + a * eps[t, i, j, 0], 0.0), xmax)
                    y = min(max(pos[i, 1] + b * dy + a * eps[t, i, j, 1], 0.0), ymax)
                    pos[i, 0] = x
                    pos[i, 1] = y
                    val[i] = _window_value(surface, min(int(y * scale), rows - 1) - r0,
                                           min(int(x * scale), cols - 1) - c0)
                    evals += 1
                    if val[i] < best[2]:
                        best[0], best[1], best[2] = x, y, val[i]
    return evals


def firefly_search(surface: npt.NDArray[np.float64], rng: np.random.Generator,
                   config: FireflyConfig | None = None, origin: tuple[int, int] = (0, 0),
                   shape: tuple[int, int] | None = None) -> SearchResult:
    """Firefly algorithm (Yang 2009; Santos Algorithm 2) on `surface`; returns the best point seen.

    Each iteration, every firefly i moves towards every brighter firefly j in turn (`firefly_move`
    in units of L, clipped to the map) and is re-evaluated; the brightest one stays put. Random
    vectors eps are uniform in [-0.5, 0.5]^2, drawn all at once after the initial population.
    The map is the grid of `shape` (None: the surface's), L its longer side; `surface` may be its
    window at `origin` (see `initial_population`): the same search as on the whole grid.
    """
    cfg = config or FireflyConfig()
    rows, cols = shape if shape is not None else surface.shape
    scale = float(max(rows, cols))
    pos = initial_population(surface, cfg.population, rng, origin, (rows, cols)) / scale
    eps = rng.random((cfg.iterations, cfg.population, cfg.population, 2)) - 0.5
    alphas = cfg.alpha * cfg.decay ** np.arange(cfg.iterations, dtype=np.float64)
    best = np.empty(3)
    evals = _firefly_kernel(np.ascontiguousarray(surface, dtype=np.float64), pos, eps, alphas,
                            float(cfg.beta0), float(cfg.gamma), best, int(origin[0]), int(origin[1]),
                            int(rows), int(cols))
    return _result(best[:2] * scale, float(best[2]), int(evals))
