"""Helpers shared by the benchmarks: timing (wall clock, medians; machines here are noisy) and
the results file each benchmark writes."""
from __future__ import annotations

import json
import pathlib
import statistics
import time
from collections.abc import Callable
from typing import Any


def median_time(fn: Callable[[], Any], repeats: int) -> tuple[float, Any]:
    """Median wall time [s] of ``repeats`` calls of ``fn`` and the last call's result."""
    times = []
    out = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def save_figures(name: str, figures: dict[str, Any]) -> pathlib.Path:
    """Write ``figures`` to ``bench/results/<name>.json`` and return the path."""
    out = pathlib.Path(__file__).resolve().parent / 'results' / f'{name}.json'
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(figures, indent=2) + '\n')
    return out
