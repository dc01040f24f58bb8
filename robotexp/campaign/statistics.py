"""Two-sample statistics for campaign reports, from scipy.stats: Welch's t-test, the Mann-Whitney U
test and a bootstrap confidence interval of the difference of the means.

Welch's test (Welch 1947) compares the means of two samples whose variances may differ:

    t  = (mean_a - mean_b) / sqrt(s_a^2 / n_a + s_b^2 / n_b)
    df = (s_a^2 / n_a + s_b^2 / n_b)^2 / ((s_a^2 / n_a)^2 / (n_a - 1) + (s_b^2 / n_b)^2 / (n_b - 1))

with s^2 the sample variances (divisor n - 1). When neither sample varies (a deterministic method
repeated over seeds) the statistic is undefined: the tests raise `NoVariance` and the report says
"no variance" instead of printing p = 0. Mann-Whitney U (a rank test: no normality assumed) is
undefined only when every value of both samples is the same.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable
from typing import NamedTuple

import numpy as np
from scipy import stats as _st  # type: ignore[import-untyped]  # no type information in scipy

__all__ = ["BootstrapCI", "MannWhitneyResult", "NoVariance", "WelchResult", "bootstrap_mean_difference",
           "mann_whitney_u", "student_t_sf", "t_two_sided_p", "welch_t_test"]


class NoVariance(ValueError):
    """A test that needs variance was given samples without any."""


class WelchResult(NamedTuple):
    """The outcome of `welch_t_test`."""

    t: float    # t statistic, positive when the first sample's mean is the larger
    df: float   # Welch-Satterthwaite degrees of freedom
    p: float    # two-sided p-value, P(|T| >= |t|) for T ~ Student t(df)


class MannWhitneyResult(NamedTuple):
    """The outcome of `mann_whitney_u`."""

    u: float    # U statistic of the first sample (pairs (x, y) with x > y, ties counting one half)
    p: float    # two-sided p-value


class BootstrapCI(NamedTuple):
    """The outcome of `bootstrap_mean_difference`."""

    difference: float   # mean_a - mean_b of the samples
    low: float          # lower end of the confidence interval
    high: float         # upper end
    level: float        # confidence level, e.g. 0.95


def _check_df(df: float) -> None:
    if not df > 0:     # also refuses NaN
        raise ValueError(f"t distribution: degrees of freedom must be > 0, got {df}")


def t_two_sided_p(t: float, df: float) -> float:
    """P(|T| >= |t|) for T ~ Student t with `df` degrees of freedom (df may be fractional or inf).

    Raises:
        ValueError: df <= 0 or NaN, t NaN.
    """
    _check_df(df)
    if math.isnan(t):
        raise ValueError("t distribution: t is NaN")
    if math.isinf(df):
        return float(2.0 * _st.norm.sf(abs(t)))
    return float(2.0 * _st.t.sf(abs(t), df))


def student_t_sf(t: float, df: float) -> float:
    """P(T > t), the upper tail of Student's t with `df` degrees of freedom.

    Raises:
        ValueError: df <= 0 or NaN, t NaN.
    """
    half = 0.5 * t_two_sided_p(t, df)
    return half if t >= 0 else 1.0 - half


def _sample(test: str, name: str, values: Iterable[float]) -> list[float]:
    xs = [float(v) for v in values]
    if len(xs) < 2:
        raise ValueError(f"{test}: sample {name} has {len(xs)} value(s); the test needs at least 2 "
                         "per group to estimate a variance")
    if not all(math.isfinite(v) for v in xs):
        raise ValueError(f"{test}: sample {name} holds a NaN or infinite value: {xs}")
    return xs


def welch_t_test(a: Iterable[float], b: Iterable[float]) -> WelchResult:
    """Welch's unequal-variance two-sample t-test of equal means, two-sided (scipy.stats.ttest_ind).

    Args:
        a: first sample (at least 2 finite values).
        b: second sample (at least 2 finite values).

    Returns:
        WelchResult(t, df, p).

    Raises:
        NoVariance: neither sample varies (the statistic is undefined).
        ValueError: a sample with fewer than 2 values, or a NaN / infinite value.
    """
    xa, xb = _sample("welch_t_test", "a", a), _sample("welch_t_test", "b", b)
    if min(xa) == max(xa) and min(xb) == max(xb):
        raise NoVariance("welch_t_test: neither sample varies; the t statistic is undefined")
    with warnings.catch_warnings():      # a constant sample makes scipy warn of precision loss in its variance
        warnings.simplefilter("ignore", RuntimeWarning)
        r = _st.ttest_ind(xa, xb, equal_var=False)
    return WelchResult(float(r.statistic), float(r.df), float(r.pvalue))


def mann_whitney_u(a: Iterable[float], b: Iterable[float]) -> MannWhitneyResult:
    """The Mann-Whitney U test (Wilcoxon rank-sum), two-sided (scipy.stats.mannwhitneyu: exact
    without ties on small samples, else the normal approximation with tie and continuity corrections).

    Raises:
        NoVariance: every value of both samples is the same.
        ValueError: a sample with fewer than 2 values, or a NaN / infinite value.
    """
    xa, xb = _sample("mann_whitney_u", "a", a), _sample("mann_whitney_u", "b", b)
    if min(xa + xb) == max(xa + xb):
        raise NoVariance("mann_whitney_u: every value is the same; ranks cannot tell the samples apart")
    r = _st.mannwhitneyu(xa, xb, alternative="two-sided")
    return MannWhitneyResult(float(r.statistic), float(r.pvalue))


def bootstrap_mean_difference(a: Iterable[float], b: Iterable[float], *, level: float = 0.95,
                              resamples: int = 9999, seed: int = 0) -> BootstrapCI:
    """Percentile bootstrap confidence interval of mean(a) - mean(b) (scipy.stats.bootstrap; each
    sample resampled on its own), reproducible through `seed`.

    Raises:
        NoVariance: neither sample varies (every resample gives the same difference).
        ValueError: a sample with fewer than 2 values, a NaN / infinite value, level outside (0, 1).
    """
    xa, xb = _sample("bootstrap", "a", a), _sample("bootstrap", "b", b)
    if not 0.0 < level < 1.0:
        raise ValueError(f"bootstrap: confidence level must lie in (0, 1), got {level}")
    diff = math.fsum(xa) / len(xa) - math.fsum(xb) / len(xb)
    if min(xa) == max(xa) and min(xb) == max(xb):
        raise NoVariance("bootstrap: neither sample varies; the interval would be the single point "
                         f"{diff:g}")

    def mean_diff(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
        return np.asarray(np.mean(x, axis=axis) - np.mean(y, axis=axis))

    r = _st.bootstrap((np.asarray(xa), np.asarray(xb)), mean_diff, n_resamples=resamples, confidence_level=level,
                      method="percentile", vectorized=True, rng=np.random.default_rng(seed))
    ci = r.confidence_interval
    return BootstrapCI(diff, float(ci.low), float(ci.high), level)
