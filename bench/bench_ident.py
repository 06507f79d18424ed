"""Benchmark: identification from one hour of 50 Hz data (target: under 10 s).

One hour of manoeuvres: the surge, pitch and yaw missions of ``config/missions`` flown one
after another (surge, pitch, yaw, surge, pitch, yaw, pitch: 3741 s, 187 057 states) with the
A18M, written as bags twice: with the force topic, and as a "real" log (no force topic,
sensor noise as in the round-trip test). Timed, median of ``repeats`` runs each:

* ``read_s``: the bags to numpy arrays (:func:`auv_bag.read_arrays`), per source;
* ``identify_forces_s``: force records plus the identification from the force topic;
* ``identify_motion_s``: forces reconstructed from motion plus the identification;

The identification is ``auv ident``'s whole procedure (:func:`auv_ident.workflow.
run_identification`): the windows held out, the five regressions as the posterior of the
file's priors inside the physical bounds, the cross-flow structure chosen by held-out
prediction, and the free-run validation against the base file on the held-out windows (the
command topics are read with the force topic for it). Output error is not used on these
50 Hz logs with every state measured (their derivatives are good).

* ``nelder_mead_s``: the report's bounded Nelder-Mead on the same data (comparison only);
* ``total_*_s``: bags to coefficients (read + identify);
* ``coefficients_*``: the identified coefficients (the vehicle file's to rounding from the
  force topic).

Run: ``. .venv/bin/auv-env && python bench/bench_ident.py`` (writes bench/results/ident.json).
"""
from __future__ import annotations

import json
import os
import pathlib
import platform
import tempfile
from typing import Any

from timing import median_time, save_figures

ROOT = pathlib.Path(__file__).resolve().parents[1]
SEQUENCE = ('surge', 'pitch', 'yaw', 'surge', 'pitch', 'yaw', 'pitch')
TARGET_S = 10.0


def run(repeats: int = 3) -> dict[str, Any]:
    """Run the benchmark; returns the figures (seconds, counts)."""
    from auv_bag import read_arrays
    from auv_contract import COMMAND_TOPICS
    from auv_ident.identify import compare_nelder_mead
    from auv_ident.motion import needed_topics, records_from_topics
    from auv_ident.workflow import run_identification
    from auv_logs.simlog import SensorNoise, write_record
    from auv_sim.missions import load_mission, run_mission
    from auv_sim.params import load_vehicle

    params = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        root = pathlib.Path(tmp)
        recs = {name: run_mission(params, load_mission(name)) for name in set(SEQUENCE)}
        forces_bags, motion_bags = [], []
        samples = 0
        duration = 0.0
        for i, name in enumerate(SEQUENCE):
            rec = recs[name]
            samples += len(rec.t)
            duration += float(rec.t[-1] - rec.t[0])
            write_record(root / f'f{i}_{name}', rec, forces=True)
            write_record(root / f'm{i}_{name}', rec, forces=False,
                         noise=SensorNoise.realistic(), seed=i)
            forces_bags.append(root / f'f{i}_{name}')
            motion_bags.append(root / f'm{i}_{name}')

        def read(bags: list[pathlib.Path], source: str) -> list[Any]:
            topics = list(dict.fromkeys([*needed_topics(source), *COMMAND_TOPICS.values()]))
            return [read_arrays(b, topics) for b in bags]

        def fit(arrays: list[Any], source: str) -> Any:
            records = []
            for i, arr in enumerate(arrays):
                records += records_from_topics(arr, params, source, name=str(i))
            outcome = run_identification(records, params)
            return records, outcome.result, outcome.validation

        # warm-up: numba kernels compiled or loaded from cache, imports done
        fit(read(forces_bags[:3], 'forces'), 'forces')
        fit(read(motion_bags[:3], 'motion'), 'motion')
        read_f, arr_f = median_time(lambda: read(forces_bags, 'forces'), repeats)
        read_m, arr_m = median_time(lambda: read(motion_bags, 'motion'), repeats)
        fit_f, (records_f, result_f, val_f) = median_time(lambda: fit(arr_f, 'forces'),
                                                           repeats)
        fit_m, (_, result_m, val_m) = median_time(lambda: fit(arr_m, 'motion'), repeats)
        nm_s, _ = median_time(lambda: compare_nelder_mead(records_f, result_f), 1)
        messages_f = sum(len(a) for arrs in arr_f for a in arrs.values())
    return {
        'benchmark': 'identification from one hour of 50 Hz data',
        'data': {'missions': list(SEQUENCE), 'duration_s': duration, 'states': samples,
                 'messages_forces_bags': messages_f},
        'repeats': repeats,
        'read_forces_s': read_f, 'read_motion_s': read_m,
        'identify_forces_s': fit_f, 'identify_motion_s': fit_m,
        'total_forces_s': read_f + fit_f, 'total_motion_s': read_m + fit_m,
        'nelder_mead_s': nm_s,
        'target_s': TARGET_S,
        'meets_target': bool(read_f + fit_f < TARGET_S and read_m + fit_m < TARGET_S),
        'validation_forces': val_f.message, 'validation_motion': val_m.message,
        'structures_motion': {k: f.structure for k, f in result_m.fits.items()},
        'coefficients_forces': result_f.values(),
        'coefficients_motion': result_m.values(),
        'machine': {'python': platform.python_version(), 'processor': platform.machine(),
                    'cpus': os.cpu_count(),
                    # 1-minute load average at the start and at the end of the run: timings
                    # taken on a busy machine are longer than on an idle one
                    'load_average': [load_before, os.getloadavg()[0]]},
    }


if __name__ == '__main__':
    figures = run()
    save_figures('ident', figures)
    print(json.dumps({k: v for k, v in figures.items() if not k.startswith('coefficients')},
                     indent=2))
