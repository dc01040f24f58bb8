"""GA operators, the firefly move and search, and the exhaustive optimum, on fixed seeds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotexp.errors import ConfigError
from robotexp.planning.metaheuristics import (
    FireflyConfig,
    GAConfig,
    blx_crossover,
    exhaustive,
    firefly_move,
    firefly_search,
    genetic_search,
    initial_population,
    nonuniform_mutation,
    roulette,
)
from robotexp.planning.objective import INFEASIBLE

LO = np.array([0.0, 0.0])
HI = np.array([100.0, 50.0])


def bowl(rows: int = 60, cols: int = 80, at: tuple[int, int] = (41, 23)) -> np.ndarray:
    """A smooth surface with one minimum at cell `at` (row, col) and a ripple, left quarter infeasible."""
    y, x = np.mgrid[0:rows, 0:cols]
    s = ((y - at[0]) ** 2 + (x - at[1]) ** 2) / 100.0 + 0.3 * np.sin(x / 3.0) * np.cos(y / 4.0)
    s[:, : cols // 8] = INFEASIBLE
    return s


def test_blx_025_children_lie_in_the_extended_interval() -> None:
    rng = np.random.default_rng(1)
    p1 = np.array([[10.0, 20.0]] * 4000)
    p2 = np.array([[30.0, 25.0]] * 4000)
    c1, c2 = blx_crossover(p1, p2, 0.25, rng, LO, HI)
    kids = np.vstack([c1, c2])
    # d = (20, 5): children within [10 - 5, 30 + 5] x [20 - 1.25, 25 + 1.25], and they fill it
    assert kids[:, 0].min() >= 5.0 and kids[:, 0].max() <= 35.0
    assert kids[:, 1].min() >= 18.75 and kids[:, 1].max() <= 26.25
    assert kids[:, 0].min() < 5.1 and kids[:, 0].max() > 34.9
    assert kids[:, 0].mean() == pytest.approx(20.0, abs=0.3)
    # first children from the first block of uniforms: child = low + u * span
    u = np.random.default_rng(1).random(p1.shape)
    assert np.allclose(c1, np.array([5.0, 18.75]) + u * np.array([30.0, 7.5]))
    # clipped to the bounds near an edge
    c1, _ = blx_crossover(np.array([[1.0, 1.0]] * 1000), np.array([[90.0, 49.0]] * 1000), 0.25, rng, LO, HI)
    assert c1.min() >= 0.0 and c1[:, 0].max() <= 100.0 and c1[:, 1].max() <= 50.0


def test_nonuniform_mutation_steps_shrink_with_the_generation() -> None:
    x = np.full((20000, 2), 40.0)
    means = []
    for t in (0, 50, 90):
        out = nonuniform_mutation(x, t, 100, LO, HI, 1.0, 5.0, np.random.default_rng(t))
        means.append(np.abs(out - x)[:, 0].mean())
        assert out.min() >= 0 and out[:, 0].max() <= 100 and out[:, 1].max() <= 50
    # E[step] = y * s / (s + 1), s = (1 - t/T)^b; y = 60 up or 40 down with equal odds -> mean y 50
    for t, m in zip((0, 50, 90), means, strict=True):
        s = (1 - t / 100) ** 5
        assert m == pytest.approx(50 * s / (s + 1), rel=0.03)
    assert means[0] > means[1] > means[2]
    # hand-computed with the documented draws: mutate?, up?, u
    rng = np.random.default_rng(7)
    ref = np.random.default_rng(7)
    m, up, u = ref.random((1, 2)) < 0.5, ref.random((1, 2)) < 0.5, ref.random((1, 2))
    got = nonuniform_mutation(np.array([[40.0, 10.0]]), 30, 100, LO, HI, 0.5, 5.0, rng)
    shrink = 1 - u ** (0.7 ** 5)
    want = np.where(up, np.array([40.0, 10.0]) + (HI - [40.0, 10.0]) * shrink,
                    np.array([40.0, 10.0]) - np.array([40.0, 10.0]) * shrink)
    assert np.allclose(got, np.where(m, want, [[40.0, 10.0]]))
    # at the horizon nothing moves
    assert np.array_equal(nonuniform_mutation(x, 100, 100, LO, HI, 1.0, 5.0, np.random.default_rng(0)), x)


def test_roulette_frequencies() -> None:
    values = np.array([1.0, 2.0, 3.0, 4.0, INFEASIBLE])
    picks = roulette(values, 60000, np.random.default_rng(2))
    freq = np.bincount(picks, minlength=5) / len(picks)
    # fitness = worst feasible - f = 3, 2, 1, 0; infeasible 0 -> 1/2, 1/3, 1/6, 0, 0
    assert freq == pytest.approx([1 / 2, 1 / 3, 1 / 6, 0, 0], abs=0.006)
    same = roulette(np.array([5.0, 5.0, INFEASIBLE]), 30000, np.random.default_rng(3))
    assert np.bincount(same, minlength=3) / 30000 == pytest.approx([0.5, 0.5, 0.0], abs=0.01)


def test_firefly_move_hand_computed() -> None:
    # r^2 = 1 + 4 = 5, beta = e^(-0.4 * 5) = e^-2 = 0.1353352832
    got = firefly_move(np.array([0.0, 0.0]), np.array([1.0, 2.0]), 1.0, 0.4, 0.3, np.array([0.1, -0.2]))
    assert got == pytest.approx([0.1353352832 + 0.03, 0.2706705664 - 0.06], abs=1e-10)
    # gamma = 0: the whole way to j (plus noise); beta0 = 0: a random walk
    assert firefly_move(np.array([2.0, 3.0]), np.array([5.0, -1.0]), 1.0, 0.0, 0.0, np.zeros(2)) == \
        pytest.approx([5.0, -1.0])
    assert firefly_move(np.array([2.0, 3.0]), np.array([5.0, -1.0]), 0.0, 0.4, 0.5, np.array([0.2, 0.4])) == \
        pytest.approx([2.1, 3.2])


def firefly_reference(surface: np.ndarray, rng: np.random.Generator, cfg: FireflyConfig) -> tuple[float, ...]:
    """Plain-python firefly search with the same draws as `firefly_search` (slow reference)."""
    rows, cols = surface.shape
    scale = float(max(rows, cols))
    pos = initial_population(surface, cfg.population, rng) / scale
    eps = rng.random((cfg.iterations, cfg.population, cfg.population, 2)) - 0.5
    hi = np.array([np.nextafter(cols / scale, 0), np.nextafter(rows / scale, 0)])

    def f(p: np.ndarray) -> float:
        return float(surface[min(int(p[1] * scale), rows - 1), min(int(p[0] * scale), cols - 1)])

    val = [f(p) for p in pos]
    k = int(np.argmin(val))
    best = (pos[k, 0], pos[k, 1], val[k])
    for t in range(cfg.iterations):
        a = cfg.alpha * cfg.decay ** t
        for i in range(cfg.population):
            for j in range(cfg.population):
                if val[j] < val[i]:
                    pos[i] = np.clip(firefly_move(pos[i], pos[j], cfg.beta0, cfg.gamma, a, eps[t, i, j]), 0, hi)
                    val[i] = f(pos[i])
                    if val[i] < best[2]:
                        best = (pos[i, 0], pos[i, 1], val[i])
    return best[0] * scale, best[1] * scale, best[2]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_firefly_search_equals_reference(seed: int) -> None:
    surface = bowl()
    cfg = FireflyConfig(iterations=6, population=7)
    got = firefly_search(surface, np.random.default_rng(seed), cfg)
    want = firefly_reference(surface, np.random.default_rng(seed), cfg)
    assert got.point == pytest.approx(want[:2], abs=1e-9)
    assert got.value == want[2]


@pytest.mark.parametrize("seed", [0, 1])
def test_searches_find_the_optimum_of_a_bowl(seed: int) -> None:
    surface = bowl()
    opt = exhaustive(surface)
    r, c = np.unravel_index(np.argmin(surface), surface.shape)      # the ripple moves it off (41, 23)
    assert opt.cell == (r, c) and opt.point == (c + 0.5, r + 0.5) and opt.value == surface.min()
    fa = firefly_search(surface, np.random.default_rng(seed))
    ga = genetic_search(surface, np.random.default_rng(seed), GAConfig(population=256))
    for res in (fa, ga):
        assert math.dist(res.cell, opt.cell) <= 3.0
        assert res.value < INFEASIBLE and res.value == surface[res.cell]
    again = firefly_search(surface, np.random.default_rng(seed))
    assert again == fa                                  # seeded: reproducible


def test_initial_population_is_feasible() -> None:
    surface = bowl()
    pts = initial_population(surface, 500, np.random.default_rng(0))
    assert (surface[np.floor(pts[:, 1]).astype(int), np.floor(pts[:, 0]).astype(int)] < INFEASIBLE).all()


def test_bad_configs() -> None:
    with pytest.raises(ConfigError, match="GA"):
        GAConfig(children=3)
    with pytest.raises(ConfigError, match="firefly"):
        FireflyConfig(decay=0.0)


def _windowed(surface: np.ndarray, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
    """`surface` with every cell outside rows r0..r1, cols c0..c1 infeasible."""
    out = np.full_like(surface, INFEASIBLE)
    out[r0:r1, c0:c1] = surface[r0:r1, c0:c1]
    return out


@pytest.mark.parametrize("seed", [0, 3])
def test_searches_on_a_window_equal_the_whole_grid(seed: int) -> None:
    # The plugins search the window of the explored cells (every cell outside infeasible) in the whole
    # map's coordinates: the same points, values and draws as on the whole grid, bit for bit.
    whole = _windowed(bowl(120, 150), 30, 90, 20, 110)
    win, origin, shape = whole[27:93, 17:113].copy(), (27, 17), whole.shape
    a = initial_population(whole, 300, np.random.default_rng(seed))
    b = initial_population(win, 300, np.random.default_rng(seed), origin, shape)
    assert np.array_equal(a, b)
    cfg = GAConfig(population=128, generations=20)
    assert genetic_search(whole, np.random.default_rng(seed), cfg) == \
        genetic_search(win, np.random.default_rng(seed), cfg, origin, shape)
    fcfg = FireflyConfig(iterations=30)
    assert firefly_search(whole, np.random.default_rng(seed), fcfg) == \
        firefly_search(win, np.random.default_rng(seed), fcfg, origin, shape)
    # and without any feasible cell, the draw over the whole grid
    none = np.full((20, 30), INFEASIBLE)
    assert np.array_equal(initial_population(np.full((200, 300), INFEASIBLE), 50, np.random.default_rng(seed)),
                          initial_population(none, 50, np.random.default_rng(seed), (100, 100), (200, 300)))
