"""Gauss-Seidel kernels of the BVP potential (thesis eqs. 3.1, 3.2, 3.6, 3.7), gradient, region growing."""

from __future__ import annotations

import numpy as np
import pytest

from robotexp.errors import ConfigError
from robotexp.planning.harmonic import (
    descent,
    descent_field,
    flood4,
    free_box,
    gauss_seidel,
    gauss_seidel_perturbed,
    gauss_seidel_perturbed_ref,
    gauss_seidel_ref,
    relax,
    touches,
)


def _box(top: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """A 3x3 interior (padded 5x5): top boundary row at `top`, the other boundaries 0, interior 0."""
    p = np.zeros((5, 5))
    p[4, :] = top
    fixed = np.zeros((5, 5), bool)
    return p, fixed


@pytest.mark.parametrize("fn", [gauss_seidel, gauss_seidel_ref])
def test_one_and_two_sweeps_by_hand(fn) -> None:
    p, fixed = _box()
    fn(p, fixed, 1)
    # row-major: rows 1 and 2 see only zeros; row 3 reads the new left neighbour
    expect1 = np.array([[0, 0, 0], [0, 0, 0], [0.25, 0.3125, 0.328125]])
    np.testing.assert_array_equal(p[1:4, 1:4], expect1)
    fn(p, fixed, 1)
    expect2 = np.array([[0, 0, 0], [0.0625, 0.09375, 0.10546875], [0.34375, 0.44140625, 0.38671875]])
    np.testing.assert_array_equal(p[1:4, 1:4], expect2)
    # the boundary ring is never written
    assert (p[4, :] == 1).all() and (p[0, :] == 0).all() and (p[:4, 0] == 0).all() and (p[:4, 4] == 0).all()


def test_converges_to_exact_discrete_harmonic_solution() -> None:
    # solved by hand with the left-right symmetry: top corners 3/7, top middle 59/112, middle row
    # 3/16, 1/4, 3/16, bottom corners 1/14, bottom middle 11/112 (each satisfies the 5-point mean)
    p, fixed = _box()
    gauss_seidel(p, fixed, 200)
    exact = np.array([[1 / 14, 11 / 112, 1 / 14], [3 / 16, 1 / 4, 3 / 16], [3 / 7, 59 / 112, 3 / 7]])
    np.testing.assert_allclose(p[1:4, 1:4], exact, atol=1e-13, rtol=0)


def test_linear_field_is_a_fixed_point_and_fixed_cells_stay() -> None:
    # a linear function is discrete-harmonic: from zeros, GS must reach p = col / (cols - 1)
    rows, cols = 8, 12
    lin = np.tile(np.arange(cols) / (cols - 1), (rows, 1))
    p = np.zeros((rows, cols))
    p[0, :], p[-1, :], p[:, 0], p[:, -1] = lin[0], lin[-1], lin[:, 0], lin[:, -1]
    fixed = np.zeros((rows, cols), bool)
    fixed[3, 5] = True
    p[3, 5] = lin[3, 5]
    gauss_seidel(p, fixed, 2000)
    np.testing.assert_allclose(p, lin, atol=1e-12, rtol=0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_kernel_matches_reference_on_random_grids(seed: int) -> None:
    rng = np.random.default_rng(seed)
    shape = (int(rng.integers(5, 30)), int(rng.integers(5, 30)))
    p = rng.random(shape)
    fixed = rng.random(shape) < 0.2
    a, b = p.copy(), p.copy()
    gauss_seidel(a, fixed, 7)
    gauss_seidel_ref(b, fixed, 7)
    np.testing.assert_allclose(a, b, atol=1e-12, rtol=0)
    assert not np.array_equal(a, p)


def test_free_box_bounds_the_updated_cells() -> None:
    fixed = np.ones((8, 10), bool)
    assert free_box(fixed)[1] < free_box(fixed)[0]            # nothing to update
    fixed[2, 3] = fixed[5, 7] = False
    fixed[0, 0] = fixed[7, 9] = False                          # the outer ring is never updated
    assert free_box(fixed) == (2, 5, 3, 7)


def test_skewed_four_row_sweep_is_the_row_major_sweep_bit_for_bit() -> None:
    # Narrow and wide boxes, band counts with 0-3 rows left over, fixed cells anywhere.
    rng = np.random.default_rng(5)
    for rows, cols in [(3, 3), (4, 9), (5, 5), (6, 4), (7, 13), (9, 3), (11, 17), (12, 6), (23, 31)]:
        p = rng.random((rows, cols))
        fixed = rng.random((rows, cols)) < 0.25
        a, b = p.copy(), p.copy()
        gauss_seidel(a, fixed, 5)
        gauss_seidel_ref(b, fixed, 5)
        assert np.array_equal(a, b), (rows, cols)


@pytest.mark.parametrize("kernel_fn", ["laplace", "perturbed"])
def test_kernels_match_reference_on_a_small_free_island(kernel_fn: str) -> None:
    # Most of the map fixed (unknown or wall), a free island in one corner: the kernels sweep only its box,
    # the references sweep everything; the results must be identical.
    rng = np.random.default_rng(11)
    p = rng.random((40, 50))
    fixed = np.ones((40, 50), bool)
    fixed[30:37, 3:12] = rng.random((7, 9)) < 0.8
    fixed[31:36, 4:11] = rng.random((5, 7)) < 0.2
    a, b = p.copy(), p.copy()
    if kernel_fn == "laplace":
        gauss_seidel(a, fixed, 9)
        gauss_seidel_ref(b, fixed, 9)
    else:
        eps = rng.uniform(-1, 1, p.shape)
        gauss_seidel_perturbed(a, fixed, 9, 0.3, -0.2, eps)
        gauss_seidel_perturbed_ref(b, fixed, 9, 0.3, -0.2, eps)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, p)


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_perturbed_kernel_matches_reference_on_random_grids(seed: int) -> None:
    rng = np.random.default_rng(seed)
    shape = (int(rng.integers(5, 25)), int(rng.integers(5, 25)))
    p = rng.random(shape)
    fixed = rng.random(shape) < 0.2
    eps = rng.uniform(-1, 1, shape)
    ex, ey = rng.uniform(-1, 1, 2)
    a, b = p.copy(), p.copy()
    gauss_seidel_perturbed(a, fixed, 6, ex, ey, eps)
    gauss_seidel_perturbed_ref(b, fixed, 6, ex, ey, eps)
    np.testing.assert_allclose(a, b, atol=1e-12, rtol=0)
    # maximum principle: every update is a convex combination of neighbours
    assert a.min() >= p.min() - 1e-15 and a.max() <= p.max() + 1e-15


def test_perturbed_with_zero_terms_equals_laplace() -> None:
    rng = np.random.default_rng(9)
    p = rng.random((9, 11))
    fixed = rng.random((9, 11)) < 0.1
    a, b = p.copy(), p.copy()
    gauss_seidel(a, fixed, 5)
    gauss_seidel_perturbed(b, fixed, 5, 0.0, 0.0, np.zeros_like(p))
    np.testing.assert_allclose(a, b, atol=1e-15, rtol=0)


def _strip_solution(e: float, n: int) -> np.ndarray:
    """1-D discrete solution of p'' = e p' (central differences) with p(0) = 0, p(n) = 1:
    p[c+1] - 2 p[c] + p[c-1] = e (p[c+1] - p[c-1]) / 2  =>  p = (lam^c - 1) / (lam^n - 1),
    lam = (1 + e/2) / (1 - e/2)."""
    lam = (1 + e / 2) / (1 - e / 2)
    return (lam ** np.arange(n + 1) - 1) / (lam ** n - 1)


@pytest.mark.parametrize("e", [0.6, -0.4])
def test_eq_3_6_converges_to_the_1d_solution(e: float) -> None:
    n = 16
    exact = _strip_solution(e, n)
    p = np.tile(exact, (6, 1))        # top and bottom rows hold the profile: the field is 1-D
    p[1:-1, 1:-1] = 0.5
    fixed = np.zeros(p.shape, bool)
    relax(p, fixed, 3000, preferred=(e, 0.0))
    np.testing.assert_allclose(p[3], exact, atol=1e-10, rtol=0)


def test_eq_3_7_on_a_monotone_field_is_eq_3_6_along_the_gradient() -> None:
    # p increases with x, so |grad p| = d p/dx and eq. 3.7 with eps reads as eq. 3.6 with e = (eps, 0)
    n, eps = 16, 0.5
    exact = _strip_solution(eps, n)
    p = np.tile(exact, (6, 1))
    p[1:-1, 1:-1] = 0.0
    relax(p, np.zeros(p.shape, bool), 3000, eps_abs=eps)
    np.testing.assert_allclose(p[3], exact, atol=1e-10, rtol=0)


def test_eq_3_6_breaks_the_symmetry_of_a_corridor() -> None:
    # a corridor with walls (1) above and below and goals (0) at both ends: harmonic, the middle
    # is a saddle; with e = eps v, v = +x, eps > 0, the descent at the middle points to -x
    p = np.ones((9, 41))
    fixed = np.ones(p.shape, bool)
    fixed[1:-1, 2:-2] = False
    p[:, 1] = p[:, -2] = 0.0
    p[0, :] = p[-1, :] = 1.0
    p[1:-1, 2:-2] = 0.5
    q = p.copy()
    relax(p, fixed, 4000)
    relax(q, fixed, 4000, preferred=(0.5, 0.0))
    assert abs(descent(p, 4, 20)[0]) < 1e-12
    assert descent(q, 4, 20)[0] < -1e-4


def test_descent_by_hand() -> None:
    p = np.zeros((3, 3))
    p[1, 0], p[1, 2] = 0.2, 0.6           # west, east
    p[0, 1], p[2, 1] = 0.9, 0.1           # south (row 0 = smaller y), north
    p[1, 1] = 123.0                       # the cell's own value is not used
    vx, vy = descent(p, 1, 1)
    assert vx == pytest.approx(-0.2) and vy == pytest.approx(0.4)
    field = descent_field(p)
    assert field.shape == (1, 1, 2)
    np.testing.assert_allclose(field[0, 0], np.array([-0.2, 0.4]) / np.hypot(0.2, 0.4))
    assert (descent_field(np.ones((4, 5))) == 0).all()


def test_flood4_is_4_connected_and_touches() -> None:
    m = np.zeros((5, 5), bool)
    m[0:2, 0:2] = True
    m[2, 2] = True                      # touches the block only diagonally
    m[3:5, 2] = True
    region = flood4(m, 0, 0)
    assert region.sum() == 4 and not region[2, 2]
    assert flood4(m, 4, 2).sum() == 3
    assert not flood4(m, 0, 4).any() and not flood4(m, -1, 0).any()
    target = np.zeros_like(m)
    target[1, 3] = True                 # 4-neighbour of nothing in the block ((1, 2) is not in it)
    assert not touches(region, target)
    target[1, 2] = True                 # right of (1, 1)
    assert touches(region, target)
    target[:] = False
    target[2, 1] = True                 # above (1, 1)
    assert touches(region, target)


def test_relax_checks_its_inputs() -> None:
    p = np.zeros((4, 4))
    fixed = np.zeros((4, 4), bool)
    with pytest.raises(ConfigError, match="float64"):
        relax(p.astype(np.float32), fixed, 1)
    with pytest.raises(ConfigError, match="bool"):
        relax(p, fixed.astype(np.uint8), 1)
    with pytest.raises(ConfigError, match="sweeps"):
        relax(p, fixed, -1)
    with pytest.raises(ConfigError, match="preferred"):
        relax(p, fixed, 1, preferred=(1.5, 0.0))
    with pytest.raises(ConfigError, match="eps_abs"):
        relax(p, fixed, 1, eps_abs=2.0)
