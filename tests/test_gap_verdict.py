"""The verdict rule of the gap diagnosis on hand-made candidates (no fit): how the explained
share, the residual tests and rivals the held-out windows cannot tell apart combine.

A candidate here carries only what the rule reads: its effect names, plausibility, whether it
identifies something, the held-out cost (total and per window) and the explained share of the
gap above the floor. The numbers are chosen by hand so that the t statistic of the per-window
cost differences is known: differences (0.1, 0.3, 0.2, 0.2) have mean 0.2 and standard error
0.0408, t = 4.9 (told apart); (0.3, -0.1, 0.2, -0.2) have mean 0.05, t = 0.44 (not told apart).
"""
from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from auv_ident.gap.diagnose import decide_verdict, window_t_stat

BEST_WINDOWS = np.array([1.0, 1.0, 1.0, 1.0])


def _cand(names: tuple[str, ...], explained: float, windows: np.ndarray) -> Any:
    return SimpleNamespace(names=names, plausible=True, identifies=True, score=1.0,
                           explained=explained, cost=float(windows.sum()),
                           window_cost=windows)


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
