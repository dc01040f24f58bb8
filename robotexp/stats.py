"""Small statistics for campaign reports: Student's t distribution and Welch's two-sample t-test.

Pure Python (math only; scipy is not a dependency). The t distribution's tail comes from the
regularized incomplete beta function I_x(a, b), evaluated by its continued fraction (DLMF 8.17.22)
with the modified Lentz method, the prefactor through `math.lgamma`:

    P(|T| > t) = I_{df / (df + t^2)}(df / 2, 1 / 2)          (T with df degrees of freedom)

Welch's test (Welch 1947) compares the means of two samples whose variances may differ:

    t  = (mean_a - mean_b) / sqrt(s_a^2 / n_a + s_b^2 / n_b)
    df = (s_a^2 / n_a + s_b^2 / n_b)^2 / ((s_a^2 / n_a)^2 / (n_a - 1) + (s_b^2 / n_b)^2 / (n_b - 1))

with s^2 the sample variances (divisor n - 1); df is the Welch-Satterthwaite approximation.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import NamedTuple

__all__ = ["WelchResult", "regularized_incomplete_beta", "student_t_sf", "t_two_sided_p", "welch_t_test"]

_EPS = 1e-15            # relative accuracy of the continued fraction
_TINY = 1e-300          # Lentz's guard against a zero denominator
_MAX_TERMS = 100_000    # the fraction needs O(sqrt(max(a, b))) terms; a safety bound only


class WelchResult(NamedTuple):
    """The outcome of `welch_t_test`."""

    t: float    # t statistic, positive when the first sample's mean is the larger
    df: float   # Welch-Satterthwaite degrees of freedom
    p: float    # two-sided p-value, P(|T| >= |t|) for T ~ Student t(df)


def _beta_fraction(a: float, b: float, x: float) -> float:
    """The continued fraction 1 / (1 + d1 / (1 + d2 / (1 + ...))) of DLMF 8.17.22 (modified Lentz).

    d_{2m+1} = -(a + m)(a + b + m) x / ((a + 2m)(a + 2m + 1)),
    d_{2m}   = m (b - m) x / ((a + 2m - 1)(a + 2m)).
    Converges fast for x < (a + 1) / (a + b + 2).
    """
    # Lentz on G = 1 + d1 / (1 + d2 / (1 + ...)) (b0 = 1, a_n = d_n, b_n = 1); the fraction is 1 / G.
    g = 1.0
    c = 1.0
    d = 0.0
    for n in range(1, _MAX_TERMS + 1):
        m = n // 2
        if n % 2:
            coef = -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1))
        else:
            coef = m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m))
        d = 1.0 + coef * d
        d = 1.0 / (d if abs(d) > _TINY else _TINY)
        c = 1.0 + coef / c
        c = c if abs(c) > _TINY else _TINY
        delta = c * d
        g *= delta
        if abs(delta - 1.0) < _EPS:
            return 1.0 / g
    raise ArithmeticError(f"incomplete beta: continued fraction did not converge for a={a}, b={b}, x={x}")


def regularized_incomplete_beta(a: float, b: float, x: float) -> float:
    """I_x(a, b) = B(x; a, b) / B(a, b), the CDF at x of a Beta(a, b) variable.

    Args:
        a: first shape parameter (> 0).
        b: second shape parameter (> 0).
        x: point in [0, 1].

    Returns:
        The value in [0, 1], to about 1e-13 absolute for shapes up to a few hundred (the
        log-gamma differences of the prefactor lose digits beyond: about 1e-10 at a = b = 5000).

    Raises:
        ValueError: a or b not a positive finite number, x outside [0, 1] or NaN.
    """
    if not (a > 0 and b > 0 and math.isfinite(a) and math.isfinite(b)):
        raise ValueError(f"incomplete beta: shapes must be positive and finite, got a={a}, b={b}")
    if not 0.0 <= x <= 1.0:
        raise ValueError(f"incomplete beta: x must lie in [0, 1], got {x}")
    if x == 0.0 or x == 1.0:
        return x
    # log of x^a (1-x)^b / B(a, b); the fraction is used on the side where it converges quickly,
    # the other side through I_x(a, b) = 1 - I_{1-x}(b, a).
    log_front = (math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b)
                 + a * math.log(x) + b * math.log1p(-x))
    front = math.exp(log_front)
    if x < (a + 1.0) / (a + b + 2.0):
        return min(1.0, front * _beta_fraction(a, b, x) / a)
    return max(0.0, 1.0 - front * _beta_fraction(b, a, 1.0 - x) / b)


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
    if math.isinf(t):
        return 0.0
    if math.isinf(df):
        return math.erfc(abs(t) / math.sqrt(2.0))
    # df / (df + t^2) computed as 1 / (1 + t^2/df) so that huge t gives a tiny x, not 0 by cancellation.
    return regularized_incomplete_beta(df / 2.0, 0.5, 1.0 / (1.0 + t * t / df))


def student_t_sf(t: float, df: float) -> float:
    """P(T > t), the upper tail of Student's t with `df` degrees of freedom.

    Raises:
        ValueError: df <= 0 or NaN, t NaN.
    """
    half = 0.5 * t_two_sided_p(t, df)
    return half if t >= 0 else 1.0 - half


def _sample(name: str, values: Iterable[float]) -> list[float]:
    xs = [float(v) for v in values]
    if len(xs) < 2:
        raise ValueError(f"welch_t_test: sample {name} has {len(xs)} value(s); the test needs at least 2 "
                         "per group to estimate a variance")
    if not all(math.isfinite(v) for v in xs):
        raise ValueError(f"welch_t_test: sample {name} holds a NaN or infinite value: {xs}")
    return xs


def _mean_var(xs: list[float]) -> tuple[float, float]:
    mean = math.fsum(xs) / len(xs)
    return mean, math.fsum((v - mean) ** 2 for v in xs) / (len(xs) - 1)


def welch_t_test(a: Iterable[float], b: Iterable[float]) -> WelchResult:
    """Welch's unequal-variance two-sample t-test of equal means, two-sided.

    When both samples have zero variance the statistic is undefined; then p = 1 when the means are
    equal (t = 0) and p = 0 otherwise (t = +-inf), with df = n_a + n_b - 2.

    Args:
        a: first sample (at least 2 finite values).
        b: second sample (at least 2 finite values).

    Returns:
        WelchResult(t, df, p).

    Raises:
        ValueError: a sample with fewer than 2 values, or a NaN / infinite value.
    """
    xa, xb = _sample("a", a), _sample("b", b)
    (ma, va), (mb, vb) = _mean_var(xa), _mean_var(xb)
    ua, ub = va / len(xa), vb / len(xb)     # squared standard errors of the means
    se2 = ua + ub
    if se2 == 0.0:
        df = float(len(xa) + len(xb) - 2)
        if ma == mb:
            return WelchResult(0.0, df, 1.0)
        return WelchResult(math.copysign(math.inf, ma - mb), df, 0.0)
    t = (ma - mb) / math.sqrt(se2)
    df = se2 * se2 / (ua * ua / (len(xa) - 1) + ub * ub / (len(xb) - 1))
    return WelchResult(t, df, t_two_sided_p(t, df))
