"""The statistics module against independent computations (scipy's own routines, closed forms)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from tavc_agents.analysis.stats import bootstrap_ratio_ci, mean_ci, mean_sd, ratio_ci, welch


def test_mean_ci_is_scipys_t_interval() -> None:
    x = np.random.default_rng(3).normal(2.0, 1.5, size=12)
    m, lo, hi, n = mean_ci(x)
    want = stats.t.interval(0.95, len(x) - 1, loc=x.mean(), scale=stats.sem(x))
    assert n == 12
    assert m == pytest.approx(x.mean())
    assert (lo, hi) == pytest.approx(want, rel=1e-12)


def test_mean_ci_drops_non_finite_values_and_handles_tiny_samples() -> None:
    assert mean_ci([1.0, math.nan, None, 3.0])[::3] == (2.0, 2)
    m, lo, hi, n = mean_ci([5.0])
    assert (m, n) == (5.0, 1) and math.isnan(lo) and math.isnan(hi)
    assert all(math.isnan(v) for v in mean_ci([])[:3]) and mean_ci([])[3] == 0


def test_mean_ci_covers_the_true_mean_about_95_percent_of_the_time() -> None:
    rng = np.random.default_rng(0)
    hits = sum(
        lo <= 1.0 <= hi for lo, hi in (mean_ci(rng.normal(1, 2, 8))[1:3] for _ in range(2000))
    )
    assert 0.93 < hits / 2000 < 0.97


def test_mean_sd() -> None:
    assert mean_sd([1.0, 2.0, 3.0]) == (2.0, 1.0)
    assert math.isnan(mean_sd([4.0])[1])


def test_ratio_ci_brackets_the_ratio_and_is_exact_without_spread() -> None:
    r, lo, hi = ratio_ci([2.0, 2.2, 1.8, 2.1], [1.0, 1.1, 0.9, 1.0])
    assert r == pytest.approx(8.1 / 4.0)
    assert lo < r < hi and lo > 0
    assert ratio_ci([2.0, 2.0], [1.0, 1.0]) == (2.0, 2.0, 2.0)
    assert math.isnan(ratio_ci([], [1.0])[0])


def test_ratio_ci_covers_the_true_ratio_about_95_percent_of_the_time() -> None:
    rng = np.random.default_rng(1)
    hits = 0
    for _ in range(1000):
        _, lo, hi = ratio_ci(rng.normal(1.1, 0.05, 15), rng.normal(1.0, 0.05, 15))
        hits += lo <= 1.1 <= hi
    assert 0.92 < hits / 1000 < 0.98


def test_bootstrap_ratio_ci_is_near_the_delta_method_for_large_samples() -> None:
    rng = np.random.default_rng(2)
    a, b = rng.normal(1.2, 0.1, 200), rng.normal(1.0, 0.1, 200)
    _, lo, hi = ratio_ci(a, b)
    blo, bhi = bootstrap_ratio_ci(a, b, np.random.default_rng(0), reps=4000)
    assert blo == pytest.approx(lo, abs=0.01) and bhi == pytest.approx(hi, abs=0.01)


def test_welch_is_scipys_and_undefined_without_spread() -> None:
    a, b = [1.0, 2.0, 3.0, 4.0], [2.0, 4.0, 6.0]
    t, p = welch(a, b)
    want = stats.ttest_ind(a, b, equal_var=False)
    assert (t, p) == pytest.approx((want.statistic, want.pvalue))
    assert all(math.isnan(v) for v in welch([1.0, 1.0], [2.0, 2.0]))
    assert all(math.isnan(v) for v in welch([1.0], [2.0, 3.0]))
