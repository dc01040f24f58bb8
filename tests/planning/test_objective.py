"""Santos's objective against direct double loops over the cell lists (no convolution)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotexp.errors import ConfigError
from robotexp.planning.grid_planner import distance_transform
from robotexp.planning.objective import (
    INFEASIBLE,
    PRESETS,
    TRUNCATION,
    Objective,
    ObjectiveParams,
    gaussian_sum,
    separable_sum_reference,
    gaussian_taps,
    params_for,
)


def direct(params: ObjectiveParams, fr: np.ndarray, oc: np.ndarray, vi: np.ndarray, robot: tuple[float, float],
           x: float, y: float, unit: float = 1.0) -> float:
    """The objective at (x, y) [cells] by a plain double loop over the lists (Santos eqs. 3.1-3.7)."""
    comps = []
    for mask, sigma in ((fr, params.sigma_f), (oc, params.sigma_o), (vi, params.sigma_v)):
        total = 0.0
        for r in range(mask.shape[0]):
            for c in range(mask.shape[1]):
                if mask[r, c]:
                    d2 = ((x - (c + 0.5)) ** 2 + (y - (r + 0.5)) ** 2) * unit ** 2   # squared distance
                    total += math.exp(-d2 / (2 * sigma ** 2))
        comps.append(total)
    cf, co, cv = -comps[0], comps[1], comps[2]
    delta = math.hypot(x - robot[0], y - robot[1]) * unit
    alpha = params.alpha
    if params.form == "conditional" and delta <= params.radius:
        alpha = params.alpha_near
    f = alpha * cf + params.beta * co + params.gamma * cv
    if params.form == "linear":
        f += params.rho * delta
    if params.form == "proportional":
        f /= params.rho * max(delta, 1.0)
    return f


@pytest.fixture
def lists() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    shape = (23, 31)
    return rng.random(shape) < 0.08, rng.random(shape) < 0.15, rng.random(shape) < 0.05


def test_presets_are_santos_tables() -> None:
    p = PRESETS
    assert (p["basic"].alpha, p["basic"].beta, p["basic"].gamma) == (50, 100, 3)
    assert (p["basic"].sigma_f, p["basic"].sigma_o, p["basic"].sigma_v) == (1.5, 4, 3.45)
    assert (p["conditional"].alpha, p["conditional"].alpha_near, p["conditional"].beta,
            p["conditional"].gamma, p["conditional"].radius) == (500, 1500, 10, 30, 30)
    assert (p["linear"].alpha, p["linear"].beta, p["linear"].gamma, p["linear"].rho) == (5000, 1000, 2000, 10)
    assert (p["proportional"].alpha, p["proportional"].beta, p["proportional"].gamma,
            p["proportional"].rho) == (500, 150, 3, 0.1)


def test_gaussian_sum_matches_double_loop_within_truncation() -> None:
    rng = np.random.default_rng(0)
    mask = rng.random((40, 50)) < 0.1
    sigma = 2.3
    got = gaussian_sum(mask, sigma)
    pts = np.argwhere(mask)
    ref = np.zeros(mask.shape)
    for r in range(mask.shape[0]):
        for c in range(mask.shape[1]):
            ref[r, c] = np.exp(-((pts[:, 0] - r) ** 2 + (pts[:, 1] - c) ** 2) / (2 * sigma ** 2)).sum()
    assert np.abs(got - ref).max() <= TRUNCATION * len(pts)
    assert np.abs(got - ref).max() > 0          # the truncation does drop far terms (window < grid)
    taps = gaussian_taps(sigma)
    half = (len(taps) - 1) // 2
    assert math.exp(-(half + 1) ** 2 / (2 * sigma ** 2)) < TRUNCATION <= math.exp(-(half - 1) ** 2 / (2 * sigma ** 2))


def test_single_cell_is_a_gaussian_of_the_squared_distance() -> None:
    mask = np.zeros((9, 9), dtype=bool)
    mask[4, 4] = True
    g = gaussian_sum(mask, 1.5)
    assert g[4, 4] == pytest.approx(1.0)
    assert g[4, 7] == pytest.approx(math.exp(-9 / 4.5))
    assert g[6, 6] == pytest.approx(math.exp(-8 / 4.5))


@pytest.mark.parametrize("form", ["basic", "conditional", "linear", "proportional"])
def test_surface_matches_double_loop(form: str, lists: tuple[np.ndarray, ...]) -> None:
    fr, oc, vi = lists
    robot = (12.3, 9.7)
    params = params_for(form, radius=6.0) if form == "conditional" else PRESETS[form]
    obj = Objective(params, fr, oc, vi, robot)
    # the documented truncation bound: each list's error <= TRUNCATION x its cells, times its weight
    tol = TRUNCATION * (max(params.alpha, params.alpha_near) * fr.sum() + params.beta * oc.sum()
                        + params.gamma * vi.sum())
    if form == "proportional":
        tol /= params.rho
    for r, c in [(0, 0), (5, 17), (11, 12), (9, 12), (22, 30), (14, 3)]:
        ref = direct(params, fr, oc, vi, robot, c + 0.5, r + 0.5)
        assert obj.surface[r, c] == pytest.approx(ref, rel=1e-12, abs=tol)
        assert abs(obj.surface[r, c] - ref) < 1e-7 * abs(ref) + tol


def test_exact_off_grid_and_feasibility(lists: tuple[np.ndarray, ...]) -> None:
    fr, oc, vi = lists
    feasible = np.ones(fr.shape, dtype=bool)
    feasible[:, :10] = False
    robot = (20.0, 11.0)
    params = PRESETS["linear"]
    obj = Objective(params, fr, oc, vi, robot, feasible)
    pts = np.array([[12.25, 3.8], [25.9, 20.1], [4.0, 4.0], [31.5, 2.0]])
    got = obj.exact(pts)
    assert got[0] == pytest.approx(direct(params, fr, oc, vi, robot, 12.25, 3.8), rel=1e-12)
    assert got[1] == pytest.approx(direct(params, fr, oc, vi, robot, 25.9, 20.1), rel=1e-12)
    assert got[2] == INFEASIBLE and got[3] == INFEASIBLE          # infeasible cell, outside the grid
    # the surface lookup decodes a point to its cell (floor): same value as the cell centre
    assert obj(pts[:1])[0] == obj.surface[3, 12]
    assert (obj.surface[:, :10] == INFEASIBLE).all()
    (r, c), v = obj.optimum()
    assert v == obj.surface[feasible].min() and feasible[r, c]


def test_cell_size_converts_lengths(lists: tuple[np.ndarray, ...]) -> None:
    fr, oc, vi = lists
    params = PRESETS["proportional"]
    obj = Objective(params, fr, oc, vi, (3.0, 4.0), cell=0.1)       # one cell = two Santos units
    tol = TRUNCATION * (params.alpha * fr.sum() + params.beta * oc.sum() + params.gamma * vi.sum()) / params.rho
    assert obj.surface[7, 20] == pytest.approx(direct(params, fr, oc, vi, (3.0, 4.0), 20.5, 7.5, unit=2.0),
                                               rel=1e-12, abs=tol)
    # and differs from the same lists read as 5 cm cells
    assert abs(obj.surface[7, 20] - direct(params, fr, oc, vi, (3.0, 4.0), 20.5, 7.5)) > 100 * tol


def test_frontier_attracts_and_walls_repel() -> None:
    shape = (30, 30)
    fr = np.zeros(shape, dtype=bool)
    oc = np.zeros(shape, dtype=bool)
    fr[20, 5:10] = True
    oc[5:25, 25] = True
    obj = Objective(PRESETS["basic"], fr, oc, np.zeros(shape, dtype=bool), (15.0, 15.0))
    (r, c), v = obj.optimum()
    assert r == 20 and 5 <= c < 10 and v < 0
    assert obj.surface[15, 25] > 0


def test_bad_input() -> None:
    with pytest.raises(ConfigError, match="form"):
        ObjectiveParams("quadratic")      # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="sigma_f"):
        ObjectiveParams(sigma_f=0.0)
    with pytest.raises(ConfigError, match="shape"):
        Objective(PRESETS["basic"], np.zeros((3, 3), bool), np.zeros((3, 4), bool), np.zeros((3, 3), bool),
                  (0.0, 0.0))
    with pytest.raises(ConfigError, match="unknown form"):
        params_for("cubic")


def test_a_window_gives_the_whole_grids_surface_bit_for_bit() -> None:
    # The plugins build the objective on the window of the explored cells (outside it no list cell and
    # nothing feasible); with `origin` the surface, lists and exact values are the whole grid's.
    rng = np.random.default_rng(5)
    shape, (r0, r1, c0, c1) = (90, 120), (20, 70, 30, 100)
    masks = []
    for p in (0.02, 0.05, 0.03, 0.6):
        m = np.zeros(shape, dtype=bool)
        m[r0 + 2:r1 - 2, c0 + 2:c1 - 2] = rng.random((r1 - r0 - 4, c1 - c0 - 4)) < p
        masks.append(m)
    fr, oc, vi, feasible = masks
    robot = (61.37, 44.81)
    for form in ("proportional", "conditional", "linear"):
        whole = Objective(PRESETS[form], fr, oc, vi, robot, feasible, cell=0.1)
        win = (slice(r0, r1), slice(c0, c1))
        part = Objective(PRESETS[form], fr[win], oc[win], vi[win], robot, feasible[win], cell=0.1, origin=(r0, c0))
        assert np.array_equal(part.surface, whole.surface[win])
        assert (whole.surface[~np.pad(np.ones((r1 - r0, c1 - c0), bool), ((r0, 90 - r1), (c0, 120 - c1)))]
                == INFEASIBLE).all()
        assert part.optimum() == whole.optimum()
        pts = rng.random((40, 2)) * (c1 - c0, r1 - r0) + (c0, r0)
        assert np.array_equal(part(pts), whole(pts))
        assert np.array_equal(part.exact(pts), whole.exact(pts))
        for a, b in zip(part.lists, whole.lists, strict=True):
            assert np.array_equal(a, b)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_separable_sum_kernel_equals_its_numpy_reference_bit_for_bit(seed: int) -> None:
    """The column pass visits only the blocks of columns a source wrote: the sums are the dense pass's,
    bit for bit, on sources clustered in a corner, spread over a wide grid and on its edges."""
    rng = np.random.default_rng(seed)
    shape = (70, 600)
    mask = np.zeros(shape, bool)
    mask[5:20, 10:40] = rng.random((15, 30)) < 0.3          # a cluster: most blocks stay empty
    mask[:, :300] |= rng.random((70, 300)) < 0.002            # scattered sources
    mask[0, 0] = mask[-1, -1] = mask[35, 63] = mask[36, 64] = True    # corners and a block boundary
    for sigma in (1.5, 4.0):
        taps = gaussian_taps(sigma)
        rr, cc = np.nonzero(mask)
        ref = separable_sum_reference(rr.astype(np.int64), cc.astype(np.int64), taps, shape)
        got = gaussian_sum(mask, sigma)
        np.testing.assert_array_equal(got, ref)
        half = (len(taps) - 1) // 2
        far = distance_transform(mask) > math.sqrt(2) * half + 1      # beyond every source's square of taps
        assert far.any() and (got[far] == 0).all() and (got[mask] >= 1).all()
