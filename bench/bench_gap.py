"""Benchmark: sim-to-real gap diagnosis of a 20-minute, 50 Hz log (target: under 60 s).

The log: the panel flight (closed-loop depth changes at three speeds with BAR doublets,
:func:`auv_gap.synth.panel_scenario`) for 1200 s with two hidden effects (a 0.3 m/s
current with a 2 cm/s vertical component and a 0.5 s plane delay) and realistic sensor noise,
written as a bag (60 001 states). Timed, median of ``repeats`` runs each:

* ``read_s``: the bag to log arrays (:func:`auv_gap.logs.load_bag`);
* ``diagnose_s``: the whole diagnosis (nominal free runs, equation error, every catalogue
  effect fitted and scored on held-out windows, combinations);
* ``report_s``: report.json, details.json, report.md and the PNG plots;
* ``total_s``: bag to report.

Run: ``. .venv/bin/auv-env && python bench/bench_gap.py`` (writes bench/results/gap.json).
"""
from __future__ import annotations

import dataclasses
import json
import os
import pathlib
import platform
import tempfile
from typing import Any

from timing import median_time, save_figures

ROOT = pathlib.Path(__file__).resolve().parents[1]
TARGET_S = 60.0
DURATION_S = 1200.0
EFFECTS = {'current': {'north': 0.3, 'east': 0.15, 'down': 0.02},
           'actuator_delay': {'bar': 0.5}}


def run(repeats: int = 3) -> dict[str, Any]:
    """Run the benchmark; returns the figures (seconds, counts, the verdict)."""
    import numba

    from auv_gap import synth
    from auv_gap.diagnose import diagnose
    from auv_gap.logs import load_bag
    from auv_gap.report import write_report
    from auv_sim.params import load_vehicle

    params = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    scenario = dataclasses.replace(synth.panel_scenario(repeat=2), duration=DURATION_S)
    log = synth.simulate(params, {'effects': EFFECTS}, scenario, seed=5)
    with tempfile.TemporaryDirectory() as tmp:
        bag = pathlib.Path(tmp) / 'log'
        synth.write_bag(bag, log)
        # warm-up on a 5-minute log: kernels compiled or loaded from cache, imports done
        short = dataclasses.replace(scenario, duration=300.0)
        diagnose(params, synth.simulate(params, None, short, seed=1).gap_logs())
        read_s, logs = median_time(lambda: load_bag(bag), repeats)
        diag_s, diag = median_time(lambda: diagnose(params, logs), repeats)
        rep_s, _ = median_time(lambda: write_report(diag, pathlib.Path(tmp) / 'out'), 1)
    r = diag.report
    return {
        'benchmark': 'gap diagnosis of a 20-minute 50 Hz log',
        'data': {'duration_s': float(log.t[-1] - log.t[0]), 'states': int(log.t.size),
                 'hidden_effects': EFFECTS},
        'repeats': repeats,
        'read_s': read_s, 'diagnose_s': diag_s, 'report_s': rep_s,
        'total_s': read_s + diag_s + rep_s,
        'target_s': TARGET_S,
        'meets_target': bool(read_s + diag_s + rep_s < TARGET_S),
        'verdict': r['verdict'], 'best': r['best'],
        'estimate': r['candidates'][0]['params'],
        'shrink': r['held_out']['shrink'],
        'machine': {'python': platform.python_version(), 'processor': platform.machine(),
                    'cpus': os.cpu_count(), 'numba_threads': numba.get_num_threads(),
                    'load_average_1min': os.getloadavg()[0]},
    }


if __name__ == '__main__':
    figures = run()
    save_figures('gap', figures)
    print(json.dumps(figures, indent=2))
