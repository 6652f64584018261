"""Statistics over independent replicates (trials, seeds): means with Student-t intervals, ratios
of means, Welch's test. Non-finite values are dropped before anything is computed."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np
from scipy import stats


def _finite(values: Iterable[float | None]) -> np.ndarray:
    return np.asarray([v for v in values if v is not None and math.isfinite(v)], dtype=float)


def mean_ci(
    values: Iterable[float | None], confidence: float = 0.95
) -> tuple[float, float, float, int]:
    """Mean and Student-t confidence interval over independent replicates (e.g. seeds).

    Returns (mean, low, high, n). With one value the interval is (nan, nan); with none everything
    is nan.
    """
    x = _finite(values)
    n = len(x)
    if n == 0:
        return (math.nan, math.nan, math.nan, 0)
    m = float(x.mean())
    if n == 1:
        return (m, math.nan, math.nan, 1)
    half = float(stats.t.ppf(0.5 + confidence / 2, n - 1) * x.std(ddof=1) / math.sqrt(n))
    return (m, m - half, m + half, n)


def mean_sd(values: Sequence[float]) -> tuple[float, float]:
    """Mean and sample standard deviation (nan for fewer than two values)."""
    x = np.asarray(values, dtype=float)
    return (float(x.mean()), float(x.std(ddof=1)) if len(x) > 1 else math.nan)


def ratio_ci(
    num: Sequence[float], den: Sequence[float], confidence: float = 0.95
) -> tuple[float, float, float]:
    """Ratio of means mean(num) / mean(den) of two independent samples (e.g. per-seed means of two
    separate sets of runs), with a delta-method interval on the log scale:

        log R = log mean(num) - log mean(den),
        SE(log R)^2 = (SE_num / mean_num)^2 + (SE_den / mean_den)^2,

    and a Student-t quantile with Welch-Satterthwaite degrees of freedom. The interval is
    exp(log R +- t * SE), asymmetric and positive. Returns (ratio, low, high).
    """
    a = _finite(num)
    b = _finite(den)
    if len(a) == 0 or len(b) == 0:
        return (math.nan, math.nan, math.nan)
    ma, mb = float(a.mean()), float(b.mean())
    ratio = ma / mb
    if len(a) < 2 or len(b) < 2:
        return (ratio, math.nan, math.nan)
    va = (a.var(ddof=1) / len(a)) / ma**2  # squared relative standard errors
    vb = (b.var(ddof=1) / len(b)) / mb**2
    se = math.sqrt(va + vb)
    if se == 0:
        return (ratio, ratio, ratio)
    df = (va + vb) ** 2 / (va**2 / (len(a) - 1) + vb**2 / (len(b) - 1))
    t = float(stats.t.ppf(0.5 + confidence / 2, df))
    return (ratio, ratio * math.exp(-t * se), ratio * math.exp(t * se))


def bootstrap_ratio_ci(
    num: Sequence[float],
    den: Sequence[float],
    rng: np.random.Generator,
    reps: int = 10_000,
    confidence: float = 0.95,
) -> tuple[float, float]:
    """Percentile bootstrap of mean(num) / mean(den), resampling each sample's seeds independently.
    With few seeds this interval is too narrow (it cannot see beyond the observed spread); it is
    reported next to the delta-method interval as a cross-check."""
    a = np.asarray(num, dtype=float)
    b = np.asarray(den, dtype=float)
    if len(a) < 2 or len(b) < 2:
        return (math.nan, math.nan)
    ra = a[rng.integers(0, len(a), size=(reps, len(a)))].mean(axis=1)
    rb = b[rng.integers(0, len(b), size=(reps, len(b)))].mean(axis=1)
    q = np.quantile(ra / rb, [0.5 - confidence / 2, 0.5 + confidence / 2])
    return (float(q[0]), float(q[1]))


def welch(a: Sequence[float], b: Sequence[float]) -> tuple[float, float]:
    """Welch's unequal-variance t-test: (t, two-sided p); nan where it is undefined."""
    if len(a) < 2 or len(b) < 2 or (np.var(a) == 0 and np.var(b) == 0):
        return (math.nan, math.nan)
    res = stats.ttest_ind(a, b, equal_var=False)
    return (float(res.statistic), float(res.pvalue))
