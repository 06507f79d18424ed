"""Benchmark: timing of the node graph (simulator, depth pilot, recorder as processes).

* ``lockstep``: 300 s of the 40 m -> 10 m manoeuvre in lockstep, as fast as the processes
  allow; real-time factor = simulated time / wall time between the first and the last state
  the recorder received (start-up excluded), and with start-up included. Target >= 20.
The two real-time runs fly 20 m -> 10 m, so that their 30 s hold the whole manoeuvre: the
pitch-up, the climb and the stop, whose planning is the pilot's heaviest computation.

* ``timer``: 30 s in real time on the wall clock (as on a vehicle: no /clock, no lockstep):
  the pilot publishes from its 10 Hz timer. Its publish period (median, p99 of the deviation
  from 0.1 s) from the DDS source stamps the recorder writes as MCAP publish times: when the
  pilot called ``publish``. Target: p99 jitter < 2 ms. Reported beside it, the same period as
  received by the recorder (DDS receive stamps), which adds the delivery delay's jitter.
* ``timer_realtime``: the same with the pilot on ``SCHED_FIFO`` (``realtime_priority`` 50, as
  on a vehicle), measured after the ``timer`` run; ``null`` figures with the reason when the
  machine does not allow it.
* ``latency``: 30 s in real time with lockstep: for each control instant, the time from the
  recorder's receipt of the state stamped t_k to its receipt of the pilot's BAR command
  stamped t_k (state -> pilot -> BAR, both legs over DDS, measured at one process clock).
  Target: p99 < 5 ms.

Run: ``. .venv/bin/auv-env && python bench/bench_graph.py`` (writes bench/results/graph.json).
"""
from __future__ import annotations

import json
import os
import pathlib
import tempfile
import time
from typing import Any

import numpy as np
from timing import save_figures

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _fly(tmp: pathlib.Path, name: str, lockstep: bool, rtf: float, stop_time: float,
         env: dict[str, str], sim_clock: bool = True, z0: float = 40.0, priority: int = 0,
         ) -> tuple[dict[str, np.ndarray], float]:
    from auv_bag import read_arrays
    from auv_bringup.launch import GraphConfig, run_graph

    bag = tmp / name
    cfg = GraphConfig(vehicle=str(ROOT / 'config' / 'a18m.yaml'), lockstep=lockstep,
                      real_time_factor=rtf, initial_depth=z0, stop_time=stop_time,
                      record=str(bag), log_dir=str(tmp / f'{name}_logs'), depth_command=10.0,
                      sim_clock=sim_clock, realtime_priority=priority)
    wall = time.monotonic()
    codes = run_graph(cfg, duration=stop_time / max(rtf, 1.0) + 300.0, env=env)
    wall = time.monotonic() - wall
    if codes.get('simulator') not in (0, -2, 130):
        raise RuntimeError(f'graph run {name} failed: {codes}')
    return read_arrays(bag, ['/auv/state', '/auv/bar_command']), wall


def _publish_times(bag: pathlib.Path, topic: str) -> np.ndarray:
    """MCAP publish times (s) of ``topic`` in ``bag``: the DDS source stamps the recorder wrote."""
    from mcap.reader import make_reader

    times = []
    for file in sorted(bag.glob('*.mcap')):
        with open(file, 'rb') as fh:
            times += [m.publish_time for _, _, m in make_reader(fh).iter_messages(topics=[topic])]
    return np.array(times, dtype=np.int64) / 1e9


def _period_figures(times: np.ndarray, period: float = 0.1) -> dict[str, float]:
    """Median period and the median, p99 and largest deviation from ``period`` (ms), after
    the first ten periods (start-up)."""
    periods = np.diff(np.asarray(times))[10:]
    dev = np.abs(periods - period)
    return {'period_median_ms': float(1e3 * np.median(periods)),
            'jitter_median_ms': float(1e3 * np.median(dev)),
            'jitter_p99_ms': float(1e3 * np.percentile(dev, 99)),
            'jitter_max_ms': float(1e3 * dev.max())}


def run(lockstep_time: float = 300.0, real_time: float = 30.0) -> dict[str, Any]:
    """Run the three graph measurements; returns the figures."""
    env = dict(os.environ)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.setdefault('ROS_DOMAIN_ID', '87')
    out: dict[str, Any] = {'targets': {'lockstep_real_time_factor_min': 20.0,
                                       'timer_p99_jitter_ms_max': 2.0,
                                       'latency_p99_ms_max': 5.0}}
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = pathlib.Path(tmp_name)
        arrays, wall = _fly(tmp, 'lockstep', True, 0.0, lockstep_time, env)
        st = arrays['/auv/state']
        span = (st['t_log'][-1] - st['t_log'][0])
        sim_span = st['t'][-1] - st['t'][0]
        out['lockstep'] = {'simulated_s': float(sim_span), 'wall_s_running': float(span),
                           'real_time_factor': float(sim_span / span),
                           'wall_s_with_startup': wall,
                           'real_time_factor_with_startup': float(sim_span / wall)}

        def timer_figures(name: str, priority: int) -> dict[str, Any]:
            arrays, _ = _fly(tmp, name, False, 1.0, real_time, env, sim_clock=False, z0=20.0,
                             priority=priority)
            log = (tmp / f'{name}_logs' / 'pilot.log').read_text()
            if priority and 'threads on SCHED_FIFO' not in log:
                return {'jitter_p99_ms': None, 'reason': log.strip()[-300:]}
            bar = arrays['/auv/bar_command']
            return {'commands': int(len(bar)),
                    **_period_figures(_publish_times(tmp / name, '/auv/bar_command')),
                    'as_received': _period_figures(bar['t_log'])}

        out['timer'] = timer_figures('timer', 0)
        out['timer_realtime'] = timer_figures('timer_rt', 50)

        arrays, _ = _fly(tmp, 'latency', True, 1.0, real_time, env, z0=20.0)
        st, bar = arrays['/auv/state'], arrays['/auv/bar_command']
        state_at = dict(zip(np.round(st['t'], 6), st['t_log']))
        lat = np.array([tl - state_at[t] for t, tl in zip(np.round(bar['t'], 6), bar['t_log'])
                        if t in state_at])[5:]
        out['latency'] = {'samples': int(len(lat)), 'median_ms': float(1e3 * np.median(lat)),
                          'p99_ms': float(1e3 * np.percentile(lat, 99)),
                          'max_ms': float(1e3 * lat.max())}
    t = out['targets']
    out['targets_met'] = {
        'lockstep_real_time_factor': out['lockstep']['real_time_factor']
        >= t['lockstep_real_time_factor_min'],
        'timer_jitter': out['timer']['jitter_p99_ms'] <= t['timer_p99_jitter_ms_max'],
        'latency': out['latency']['p99_ms'] <= t['latency_p99_ms_max']}
    out['load_average_1min'] = os.getloadavg()[0]
    return out


if __name__ == '__main__':
    figures = run()
    save_figures('graph', figures)
    print(json.dumps(figures, indent=2))
