"""The fresh-clone series' verdict (``bench/bench_fresh_clone.py``), on hand-written series.

Oracle: the runs written out by hand, and the green runs in a row at the end counted by
hand; nothing is flown or cloned.
"""
from __future__ import annotations

from typing import Any

import pytest
from conftest import load_bench

BENCH = load_bench('fresh_clone')


def _series(greens: list[bool]) -> dict[str, Any]:
    return {'runs': [{'run': i, 'green': g, 'wall_s_with_setup': 100.0 + i}
                     for i, g in enumerate(greens)]}


@pytest.mark.parametrize(('greens', 'in_a_row', 'met'), [
    ([True] * 10, 10, True),
    ([True] * 9, 9, False),
    ([True] * 5 + [False] + [True] * 10, 10, True),   # a red run before the last ten
    ([True] * 5 + [False] + [True] * 9, 9, False),
    ([True] * 12 + [False], 0, False),                 # the last run red
])
def test_the_goal_is_the_last_ten_runs_green_in_a_row(greens: list[bool], in_a_row: int,
                                                      met: bool) -> None:
    figures = BENCH.score(_series(greens))
    assert BENCH.GOAL_RUNS == 10
    assert figures['green_in_a_row'] == in_a_row
    assert figures['goal_met'] is met
    assert figures['done'] == len(greens)
    assert figures['green'] == sum(greens)


def test_the_median_wall_time_is_the_middle_runs() -> None:
    """Walls 100..104 s: the median is 102 s."""
    assert BENCH.score(_series([True] * 5))['median_wall_s'] == 102.0
