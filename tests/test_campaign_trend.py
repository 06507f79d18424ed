"""Drift and step tests of the campaign report (auv_campaign.trend): hand-worked cases,
a second method for the weighted slope (numpy.polyfit), and the false-alarm rate of the
permutation tests on series with no change, also when the intervals are wrong by a factor."""
from __future__ import annotations

import math

import numpy as np
import pytest

from auv_campaign import trend


def test_hand_worked_line_and_step() -> None:
    x = np.arange(6.0)
    r = trend.analyse(x, 2.0 + 0.5 * x, np.ones(6), permutations=99)
    assert r['slope'] == pytest.approx(0.5, abs=1e-12)
    assert r['intercept'] == pytest.approx(2.0, abs=1e-12)
    assert r['chi2_drift'] == pytest.approx(0.0, abs=1e-9)
    # constant model: mean 3.25, chi2 = sum (0.5 x - 1.25)^2 = 4.375 (by hand)
    assert r['chi2_constant'] == pytest.approx(4.375)
    r = trend.analyse(x, [1.0, 1.0, 1.0, 3.0, 3.0, 3.0], np.ones(6), permutations=99)
    assert r['step_index'] == 3
    assert r['before']['mean'] == pytest.approx(1.0)
    assert r['after']['mean'] == pytest.approx(3.0)
    assert r['chi2_step'] == pytest.approx(0.0, abs=1e-9)
    # a mean of three points with unit errors: se 1/sqrt(3) (dispersion floor 1)
    assert r['before']['std_error'] == pytest.approx(1 / math.sqrt(3))


def test_weighted_slope_matches_polyfit() -> None:
    rng = np.random.default_rng(4)
    x = np.sort(rng.uniform(0, 30, 25))
    s = rng.uniform(0.5, 3.0, 25)
    y = 4.0 - 0.3 * x + rng.standard_normal(25) * s
    r = trend.analyse(x, y, s, permutations=99)
    b, a = np.polyfit(x, y, 1, w=1 / s)   # polyfit weights multiply the residuals
    assert r['slope'] == pytest.approx(b, rel=1e-9)
    assert r['intercept'] == pytest.approx(a, rel=1e-9)


def test_drift_found_with_its_slope() -> None:
    rng = np.random.default_rng(1)
    x = np.arange(30.0)
    s = np.full(30, 1.0)
    y = 10.0 + 0.4 * x + rng.standard_normal(30) * s
    r = trend.analyse(x, y, s)
    assert r['verdict'] == 'drift'
    assert r['p_trend'] < 0.01
    lo, hi = r['slope_ci95']
    assert lo < 0.4 < hi


@pytest.mark.parametrize('k', [5, 20, 33])
def test_step_found_where_it_is(k: int) -> None:
    rng = np.random.default_rng(k)
    n = 40
    s = rng.uniform(0.002, 0.004, n)
    y = np.where(np.arange(n) >= k, 0.04, 0.0) + rng.standard_normal(n) * s
    r = trend.analyse(np.arange(n, dtype=float), y, s)
    assert r['verdict'] == 'step'
    assert r['step_index'] == k
    assert r['after']['mean'] - r['before']['mean'] == pytest.approx(0.04, abs=0.004)


def test_wide_interval_outlier_does_not_make_a_step() -> None:
    rng = np.random.default_rng(7)
    n = 30
    s = np.full(n, 1.0)
    y = 5.0 + rng.standard_normal(n)
    y[12], s[12] = 60.0, 100.0   # a mission that barely identified the quantity
    r = trend.analyse(np.arange(n, dtype=float), y, s)
    assert r['verdict'] == 'stable'


@pytest.mark.parametrize('interval_factor', [1.0, 0.1])
def test_false_alarm_rate_near_alpha(interval_factor: float) -> None:
    """200 series without change (intervals right, or 10 times too narrow): the share flagged
    stays near alpha = 0.05 (binomial: above 0.10 has probability < 1e-3)."""
    rng = np.random.default_rng(11)
    n, runs, alpha = 20, 200, 0.05
    flagged_t = flagged_s = 0
    for _ in range(runs):
        s = rng.uniform(0.5, 2.0, n)
        y = rng.standard_normal(n) * s
        r = trend.analyse(np.arange(n, dtype=float), y, s * interval_factor,
                          permutations=199, alpha=alpha, seed=int(rng.integers(1 << 30)))
        flagged_t += r['p_trend'] < alpha
        flagged_s += r['p_step'] < alpha
    assert flagged_t / runs < 0.10
    assert flagged_s / runs < 0.10


def test_too_few_and_unsorted() -> None:
    assert trend.analyse([0.0, 1.0, 2.0], [1.0, 2.0, 3.0], [1.0] * 3)['verdict'] == 'too_few'
    # missing intervals are left out, not guessed
    r = trend.analyse(np.arange(5.0), [1, 2, 3, 4, 5], [1, math.nan, 1, 1, 0.0])
    assert r['verdict'] == 'too_few' and r['used'] == [0, 2, 3]
    with pytest.raises(ValueError, match='sorted'):
        trend.analyse([3.0, 1.0, 2.0, 4.0], [1, 2, 3, 4], [1.0] * 4)


def test_standard_error_of_interval() -> None:
    assert trend.standard_error((-1.959963984540054, 1.959963984540054)) == pytest.approx(1.0)
