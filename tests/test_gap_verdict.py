"""The verdict rule of the gap diagnosis on hand-made candidates (no fit): how the explained
share, the residual tests and rivals the held-out windows cannot tell apart combine.

A candidate here carries only what the rule reads: its effect names, plausibility (typical
range) and possibility (what physics allows), whether it identifies something, the held-out
cost (total and per window) and the explained share of the gap above the floor. The numbers
are chosen by hand so that the t statistic of the per-window cost differences is known:
differences (0.1, 0.3, 0.2, 0.2) have mean 0.2 and standard error 0.0408, t = 4.9 (told
apart); (0.3, -0.1, 0.2, -0.2) have mean 0.05, t = 0.44 (not told apart).
"""
from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from auv_gap.verdict import decide_verdict, window_t_stat

BEST_WINDOWS = np.array([1.0, 1.0, 1.0, 1.0])


def _cand(names: tuple[str, ...], explained: float, windows: np.ndarray,
          plausible: bool = True, possible: bool = True) -> Any:
    return SimpleNamespace(names=names, plausible=plausible, possible=possible,
                           identifies=True, score=1.0, explained=explained,
                           cost=float(windows.sum()), window_cost=windows)


def test_the_hand_worked_t_statistics() -> None:
    assert window_t_stat(np.array([0.1, 0.3, 0.2, 0.2])) == pytest.approx(0.2 / (0.08165 / 2),
                                                                    rel=1e-4)
    assert window_t_stat(np.array([0.3, -0.1, 0.2, -0.2])) == pytest.approx(
        0.05 / (np.std([0.3, -0.1, 0.2, -0.2], ddof=1) / 2), rel=1e-12)


@pytest.mark.parametrize(('explained', 'white', 'verdict'), [
    (0.95, True, 'ambiguous'),          # would be explained: the rival makes it ambiguous
    (0.80, True, 'partly_explained'),   # falls short of 90 %: rivals do not lift it
    (0.95, False, 'partly_explained'),  # structure left: rivals do not lift it
])
def test_rivals_make_an_answer_ambiguous_only_when_it_would_be_explained(
        explained: float, white: bool, verdict: str) -> None:
    best = _cand(('cg_offset',), explained, BEST_WINDOWS)
    rival = _cand(('bar_bias',), explained * 0.98,
                  BEST_WINDOWS + np.array([0.3, -0.1, 0.2, -0.2]))
    got, rivals, manoeuvre = decide_verdict(['z', 'theta'], best, [best, rival], white)
    assert got == verdict
    assert rivals == ['bar_bias']
    assert manoeuvre


def test_a_rival_the_windows_tell_apart_leaves_thedecide_verdict_alone() -> None:
    best = _cand(('cg_offset',), 0.95, BEST_WINDOWS)
    rival = _cand(('bar_bias',), 0.93, BEST_WINDOWS + np.array([0.1, 0.3, 0.2, 0.2]))
    assert decide_verdict(['z'], best, [best, rival], True) == ('explained', [], None)
    short = _cand(('cg_offset',), 0.8, BEST_WINDOWS)
    assert decide_verdict(['z'], short, [short, rival], True) == ('partly_explained', [], None)


def test_an_atypical_rival_the_windows_cannot_tell_apart_makes_it_ambiguous() -> None:
    """A 10 deg fin zero error (beyond the typical range, within what physics allows) that
    predicts the held-out windows a little better than a typical plane effectiveness: the
    data cannot choose, so not ``explained`` but ``ambiguous``, with the manoeuvre that
    separates a bias from a gain (plane steps of several sizes). A rival beyond what physics
    allows never counts."""
    from auv_gap.verdict import verdict_and_rivals

    best = _cand(('plane_effectiveness',), 0.93, BEST_WINDOWS)
    bias = _cand(('bar_bias',), 0.96, BEST_WINDOWS - np.array([0.3, -0.1, 0.2, -0.2]),
                 plausible=False)
    got, rivals, manoeuvre, cands = verdict_and_rivals(['z', 'theta'], best, [best, bias],
                                                       True)
    assert (got, rivals) == ('ambiguous', ['bar_bias'])
    assert cands == [bias]
    assert manoeuvre is not None and manoeuvre.startswith('plane steps of several sizes')
    impossible = _cand(('bar_bias',), 0.96, bias.window_cost, plausible=False,
                       possible=False)
    assert decide_verdict(['z'], best, [best, impossible], True) == ('explained', [], None)


def test_residuals_that_cannot_be_tested_are_not_called_white() -> None:
    from auv_gap.residuals import Group, residual_tests

    white, findings, left = residual_tests([Group({'heave': [np.zeros(3), np.zeros(3)]}, {},
                                                  1.0, white=True)])
    assert (white, findings) == (False, [])
    assert left == ['the residuals could not be tested (held-out windows too short)']


def test_short_held_out_windows_are_tested_over_fewer_lags() -> None:
    """Ten-sample pieces (the 10-s windows of a vehicle unstable without feedback): three
    lags. An alternating residual (+1, -1, ...) has autocorrelations -0.9, +0.8, -0.7 at lags
    1-3 over a 10-sample piece, so Ljung-Box flags it; white noise passes."""
    from auv_gap.residuals import Group, residual_tests

    alt = [np.array([(-1.0) ** k for k in range(10)]) for _ in range(6)]
    white, findings, left = residual_tests([Group({'pitch': alt}, {}, 1.0, white=True)])
    assert not white
    assert left[0].startswith('pitch: autocorrelated (Ljung-Box Q = ')
    assert left[0].endswith(' over 3 lags)')
    rng = np.random.default_rng(3)
    noise = [rng.standard_normal(10) for _ in range(6)]
    white, findings, _ = residual_tests([Group({'pitch': noise}, {}, 1.0, white=True)])
    assert white and len(findings) == 2


def test_the_campaign_joint_fit_gives_no_values_for_velocities_the_import_derived() -> None:
    """A 5-minute log of a 0.3 m/s north current: with every signal measured the campaign's
    joint fit finds the current (north within 0.03 m/s of 0.3); with the heave velocity marked
    derived by the import (as from a text log without a DVL) it gives no value and says why."""
    import dataclasses

    from conftest import A18M
    from test_gap_units import SHORT

    from auv_campaign.tasks import joint_fit
    from auv_gap.synth import simulate
    from auv_sim.params import load_vehicle

    vehicle = load_vehicle(A18M)
    logs = simulate(vehicle, {'effects': {'current': {'north': 0.3}}}, SHORT,
                    seed=4).gap_logs()
    _, measured = joint_fit(vehicle, logs, 30.0, ['current'])
    assert abs(measured['current.north']['value'] - 0.3) < 0.03, measured
    derived = [dataclasses.replace(lg, origins={'w': 'derived: from depth, pitch and u'})
               for lg in logs]
    label, q = joint_fit(vehicle, derived, 30.0, ['current'])
    assert label == 'current'
    assert all(v['value'] is None and v['ci95'] is None and not v['identified']
               for v in q.values()), q
    assert q['current.north']['why'].startswith('not fitted: w derived or assumed')
