"""Student's t tail, Welch's test, Mann-Whitney U and the bootstrap interval against printed tables,
closed forms, hand computations and scipy."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scipy import stats as st

from robotexp.campaign.statistics import (
    NoVariance, bootstrap_mean_difference, mann_whitney_u, student_t_sf, t_two_sided_p, welch_t_test)


# -- t distribution: printed critical values and closed forms -------------------------------------

@pytest.mark.parametrize("t, df, p", [
    (12.706, 1, 0.05), (4.303, 2, 0.05), (2.228, 10, 0.05), (2.042, 30, 0.05),   # two-sided 5 % column
    (63.657, 1, 0.01), (3.169, 10, 0.01), (2.750, 30, 0.01),                      # two-sided 1 % column
    (1.812, 10, 0.10), (1.960, 1e6, 0.05), (2.576, 1e6, 0.01),
])
def test_two_sided_p_at_printed_critical_values(t: float, df: float, p: float) -> None:
    # The tables print t to 3 decimals: p is then right to a few parts in 1e4 of itself.
    assert t_two_sided_p(t, df) == pytest.approx(p, rel=2e-3)
    assert t_two_sided_p(-t, df) == t_two_sided_p(t, df)


@pytest.mark.parametrize("t", [0.0, 0.3, 1.0, 2.5, 12.706, 300.0])
def test_two_sided_p_closed_forms_for_one_and_two_df(t: float) -> None:
    # df = 1 is the Cauchy distribution: P(|T| > t) = 1 - (2/pi) atan t;
    # df = 2: P(|T| > t) = 1 - t / sqrt(2 + t^2).
    assert t_two_sided_p(t, 1) == pytest.approx(1 - 2 / math.pi * math.atan(t), rel=1e-12, abs=1e-15)
    assert t_two_sided_p(t, 2) == pytest.approx(1 - t / math.sqrt(2 + t * t), rel=1e-10, abs=1e-15)


def test_large_df_tends_to_the_normal() -> None:
    # First-order expansion in 1/df of the t tail (Abramowitz & Stegun 26.7.5):
    # P(|T| > t) = erfc(t / sqrt 2) + phi(t) (t^3 + t) / (2 df) + O(1/df^2).
    for t in (0.5, 1.96, 3.0):
        normal = math.erfc(t / math.sqrt(2))
        assert t_two_sided_p(t, math.inf) == pytest.approx(normal, rel=1e-14)
        phi = math.exp(-t * t / 2) / math.sqrt(2 * math.pi)
        for df in (1e5, 1e6):           # the 1/df^2 term is below 1e-7 of p here
            assert t_two_sided_p(t, df) == pytest.approx(normal + phi * (t ** 3 + t) / (2 * df), rel=1e-7)


def test_upper_tail_is_half_the_two_sided_p() -> None:
    assert student_t_sf(2.228, 10) == pytest.approx(0.025, rel=2e-3)
    assert student_t_sf(-2.228, 10) == pytest.approx(0.975, rel=1e-4)
    assert student_t_sf(0.0, 4) == 0.5
    assert student_t_sf(math.inf, 3) == 0.0
    with pytest.raises(ValueError, match="degrees of freedom"):
        t_two_sided_p(1.0, 0.0)


def _p_by_quadrature(t: float, df: float) -> float:
    """1 - 2 * integral_0^|t| of the t density, by Simpson's rule on 20000 intervals."""
    x = np.linspace(0.0, abs(t), 20001)
    c = math.exp(math.lgamma((df + 1) / 2) - math.lgamma(df / 2)) / math.sqrt(df * math.pi)
    f = c * (1 + x * x / df) ** (-(df + 1) / 2)
    h = x[1] - x[0]
    integral = h / 3 * (f[0] + f[-1] + 4 * f[1:-1:2].sum() + 2 * f[2:-1:2].sum())
    return 1 - 2 * float(integral)


# -- Welch ------------------------------------------------------------------------------------------

def test_welch_by_hand() -> None:
    # a = 1..5: mean 3, s^2 = (4+1+0+1+4)/4 = 2.5, s^2/n = 0.5
    # b = 2,4,6: mean 4, s^2 = (4+0+4)/2 = 4, s^2/n = 4/3
    # t = (3 - 4) / sqrt(0.5 + 4/3) = -1 / sqrt(11/6) = -0.7385489...
    # df = (11/6)^2 / (0.5^2 / 4 + (4/3)^2 / 2) = (121/36) / (1/16 + 8/9) = (121/36) / (137/144)
    #    = 484/137 = 3.5328467...
    w = welch_t_test([1, 2, 3, 4, 5], [2, 4, 6])
    assert w.t == pytest.approx(-1 / math.sqrt(11 / 6), rel=1e-13)
    assert w.df == pytest.approx(484 / 137, rel=1e-13)
    assert w.p == pytest.approx(_p_by_quadrature(w.t, w.df), abs=1e-9)
    assert 0.50 < w.p < 0.51


def test_welch_santos_table_8_shape() -> None:
    # Two samples of five like Santos's env 2 (FA 1426 +- 237 vs GA 1923 +- 262):
    # a: mean 1426, deviations -300, -150, 0, 150, 300 -> s^2 = 2 * (90000 + 22500) / 4 = 56250
    # b: mean 1923, deviations -200, -100, 0, 100, 200 -> s^2 = 2 * (40000 + 10000) / 4 = 25000
    # se^2 = 56250/5 + 25000/5 = 16250, t = -497 / sqrt(16250) = -3.8988...
    # df = 16250^2 / (11250^2 / 4 + 5000^2 / 4) = 264062500 / 37890625 = 6.9691...
    a = [1126, 1276, 1426, 1576, 1726]
    b = [1723, 1823, 1923, 2023, 2123]
    w = welch_t_test(a, b)
    assert w.t == pytest.approx(-497 / math.sqrt(16250), rel=1e-13)
    assert w.df == pytest.approx(16250 ** 2 / (11250 ** 2 / 4 + 5000 ** 2 / 4), rel=1e-13)
    assert w.p == pytest.approx(_p_by_quadrature(w.t, w.df), abs=1e-9)
    assert 0.005 < w.p < 0.01
    swapped = welch_t_test(b, a)
    assert (swapped.t, swapped.df, swapped.p) == pytest.approx((-w.t, w.df, w.p))


def test_welch_one_constant_sample_has_df_n_minus_one() -> None:
    # b constant: df = (s_a^2/n_a)^2 / ((s_a^2/n_a)^2 / (n_a - 1)) = n_a - 1 = 3
    w = welch_t_test([1.0, 2.0, 3.0, 4.0], [5.0, 5.0, 5.0])
    assert w.df == pytest.approx(3.0)
    # t = (2.5 - 5) / sqrt((5/3) / 4) = -2.5 / sqrt(5/12)
    assert w.t == pytest.approx(-2.5 / math.sqrt(5 / 12))


def test_welch_zero_variances_say_no_variance() -> None:
    # a deterministic method repeated over seeds: no variance, no test (never p = 0, t = -inf)
    for a, b in (([3, 3, 3], [3, 3]), ([3, 3, 3], [4, 4])):
        with pytest.raises(NoVariance, match="neither sample varies"):
            welch_t_test(a, b)
        with pytest.raises(NoVariance):
            bootstrap_mean_difference(a, b)
    with pytest.raises(NoVariance, match="every value is the same"):
        mann_whitney_u([3, 3, 3], [3, 3])
    # the ranks still tell 3, 3, 3 from 4, 4 apart: U = 0; with ties, the normal approximation:
    # mean n_a n_b / 2 = 3, tie-corrected sd^2 = n_a n_b / 12 * (n + 1 - sum(t^3 - t) / (n (n - 1)))
    # = 6 / 12 * (6 - (24 + 6) / 20) = 2.25, z = (|0 - 3| - 0.5) / 1.5 = 5/3, p = erfc(z / sqrt 2)
    u = mann_whitney_u([3, 3, 3], [4, 4])
    assert u.u == 0.0 and u.p == pytest.approx(math.erfc(5 / 3 / math.sqrt(2)), rel=1e-12)


def test_welch_needs_two_values_per_group() -> None:
    with pytest.raises(ValueError, match="sample b has 1 value"):
        welch_t_test([1, 2, 3], [4])
    with pytest.raises(ValueError, match="sample a has 1 value"):
        mann_whitney_u([1], [4, 5])
    with pytest.raises(ValueError, match="sample a has 0 value"):
        welch_t_test([], [1, 2])
    with pytest.raises(ValueError, match="NaN or infinite"):
        welch_t_test([1, math.nan], [1, 2])


def test_santos_table_8_p_values() -> None:
    # Santos 2016, Table 8 (visited cells, FA vs GA, five runs each) and the p-values he reports for
    # Welch's test: 0.635 (environment 1) and 0.0136 (environment 2). His 0.0136 is the p at the
    # Welch df rounded to a whole number (7.92 -> 8: 0.01370), cut to four decimals, as some statistics
    # packages report it; ours keeps the fractional df (0.01387).
    env1 = welch_t_test([1433, 1401, 1577, 1765, 1850], [928, 1730, 2094, 1675, 2207])
    env2 = welch_t_test([1257, 1324, 1192, 1713, 1646], [1960, 1709, 2112, 1608, 2227])
    assert env1.p == pytest.approx(0.635, abs=5e-4)
    assert env2.df == pytest.approx(7.92, abs=5e-3)
    assert env2.p == pytest.approx(0.0139, abs=5e-5)
    assert 0.0136 <= t_two_sided_p(env2.t, round(env2.df)) < 0.0137
    # and they are scipy's numbers
    for a, b, w in (([1433, 1401, 1577, 1765, 1850], [928, 1730, 2094, 1675, 2207], env1),
                    ([1257, 1324, 1192, 1713, 1646], [1960, 1709, 2112, 1608, 2227], env2)):
        ref = st.ttest_ind(a, b, equal_var=False)
        assert (w.t, w.df, w.p) == pytest.approx((ref.statistic, ref.df, ref.pvalue), rel=1e-12)


def test_mann_whitney_exact_by_hand() -> None:
    # a below every b: U_a = 0; without ties the exact two-sided p is 2 / C(8, 3) = 2 / 56
    r = mann_whitney_u([1, 2, 3, 4, 5], [6, 7, 8])
    assert r.u == 0.0 and r.p == pytest.approx(2 / 56, rel=1e-12)
    # a = 1, 3, 5 vs b = 2, 4: pairs with a > b: (3, 2), (5, 2), (5, 4) -> U = 3 = n_a n_b / 2: p = 1
    r = mann_whitney_u([1, 3, 5], [2, 4])
    assert r.u == 3.0 and r.p == pytest.approx(1.0)
    # Santos's Table 8, environment 2: every FA below every GA but 1713 > 1709 and 1713 > 1608,
    # 1646 > 1608: U = 3; exact p = 2 P(U <= 3) = 2 * 7 / C(10, 5) (counts of U = 0..3: 1, 1, 2, 3)
    r = mann_whitney_u([1257, 1324, 1192, 1713, 1646], [1960, 1709, 2112, 1608, 2227])
    assert r.u == 3.0 and r.p == pytest.approx(2 * 7 / 252, rel=1e-12)


def test_bootstrap_interval_agrees_with_plain_resampling() -> None:
    a = [1126, 1276, 1426, 1576, 1726]
    b = [1723, 1823, 1923, 2023, 2123]
    ci = bootstrap_mean_difference(a, b, resamples=20000, seed=3)
    assert ci.difference == pytest.approx(-497.0) and ci.level == 0.95
    # the percentile interval by hand: resample each sample with replacement, 2.5 % and 97.5 % points
    rng = np.random.default_rng(11)
    xa, xb = np.array(a, float), np.array(b, float)
    diffs = (xa[rng.integers(0, 5, (40000, 5))].mean(axis=1) - xb[rng.integers(0, 5, (40000, 5))].mean(axis=1))
    lo, hi = np.percentile(diffs, [2.5, 97.5])
    assert ci.low == pytest.approx(lo, abs=8.0) and ci.high == pytest.approx(hi, abs=8.0)
    assert ci.low < -497 < ci.high < 0          # GA's advantage holds in every likely resample
    assert bootstrap_mean_difference(a, b, resamples=2000, seed=1) == bootstrap_mean_difference(a, b, resamples=2000,
                                                                                               seed=1)
