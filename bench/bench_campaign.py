"""Benchmark: campaigns on the Dask engine (``auv campaign``).

1. A synthetic gap campaign written by the simulator: ``MISSIONS`` missions of ``DURATION_S``
   at 50 Hz, 8 h apart, with realistic sensor noise; the buoyancy error drifts linearly from
   10 N to 40 N over the campaign and a 0.04 rad (2.3 deg) dive-plane bias appears at mission
   ``BIAS_FROM`` (0-based) and stays. The report must call ``buoyancy_offset.dB`` a drift
   (its slope interval holding the true slope) and ``bar_bias.bias`` a step at that mission.
   Run with 1 and with 2 workers (no cache): wall times, speed-up, engine overhead per task
   (wall time of the 1-worker run less the time spent inside the tasks, per task, cluster
   start excluded), peak memory per worker; a no-op round trip per task on the engine.
2. Monte Carlo: ``MC_RUNS`` closed-loop runs of ``MC_DURATION_S`` (coefficient spreads, a
   buoyancy error, depth steps) in chunks through the engine with 1 and 2 workers (in this
   process, and as a fresh ``auv campaign montecarlo`` command), against the same runs
   without the engine (the bare closed-loop runner, one core: warm in this process, and in a
   fresh process), alternating: vehicle-steps per second (wall clock, with and without the
   cluster start) and per CPU-second, and their ratios (goal: engine on 1 worker >= 80 % of
   bare).

The scale is set so that the whole benchmark takes a few minutes on a 2-core machine.

Run: ``. .venv/bin/auv-env && python bench/bench_campaign.py`` (writes
bench/results/campaign.json).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import platform
import resource
import statistics
import tempfile
import time
from typing import Any

from timing import save_figures

ROOT = pathlib.Path(__file__).resolve().parents[1]
A18M = ROOT / 'config' / 'a18m.yaml'
MISSIONS = 40
DURATION_S = 300.0
SPACING_H = 8.0
BIAS_FROM = 20
BIAS = 0.04
DB_FIRST, DB_LAST = 10.0, 40.0
MC_RUNS = 96
MC_CHUNK = 12
MC_REPEATS = 2
MC_DURATION_S = 120.0


def _effects(i: int) -> dict[str, dict[str, float]]:
    eff = {'buoyancy_offset': {'dB': DB_FIRST + (DB_LAST - DB_FIRST) * i / (MISSIONS - 1)}}
    if i >= BIAS_FROM:
        eff['bar_bias'] = {'bias': BIAS}
    return eff


def _campaign(argv: list[str]) -> dict[str, Any]:
    from auv_campaign import cli

    parser = argparse.ArgumentParser()
    cli.add_arguments(parser)
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    assert cli.run(args) == 0
    wall = time.perf_counter() - t0
    out = pathlib.Path(args.out)
    name = 'montecarlo.json' if args.mode == 'montecarlo' else 'campaign.json'
    doc: dict[str, Any] = json.loads((out / name).read_text())
    doc['command_wall_s'] = wall
    return doc


def _cluster_start_and_noop(workers: int, tasks: int = 200) -> tuple[float, float]:
    """Seconds to start the embedded cluster, and seconds per no-op task round trip."""
    from auv_campaign import engine

    t0 = time.perf_counter()
    with engine.client(workers) as c:
        start = time.perf_counter() - t0
        t1 = time.perf_counter()
        futures = [c.submit(abs, -i, pure=False) for i in range(tasks)]
        c.gather(futures)
        per = (time.perf_counter() - t1) / tasks
    return start, per


def run_gap(tmp: pathlib.Path) -> dict[str, Any]:
    from auv_campaign.synthetic import write_campaign
    from auv_sim.params import load_vehicle

    t0 = time.perf_counter()
    missions = write_campaign(tmp / 'logs', load_vehicle(A18M), MISSIONS, _effects,
                              duration=DURATION_S, spacing_h=SPACING_H, seed=1)
    write_s = time.perf_counter() - t0
    start_s, noop_s = _cluster_start_and_noop(2)
    runs = {}
    for workers in (1, 2):
        runs[workers] = _campaign(['gap', str(tmp / 'logs'), '--vehicle', str(A18M),
                                   '--out', str(tmp / f'out{workers}'), '--no-cache',
                                   '--workers', str(workers), '--quiet',
                                   '--options=--no-plots'])
    doc = runs[2]
    tr = doc['trends']
    db, bias = tr.get('buoyancy_offset.dB', {}), tr.get('bar_bias.bias', {})
    true_slope = (DB_LAST - DB_FIRST) / ((MISSIONS - 1) * SPACING_H / 24.0)   # N/day
    one = runs[1]
    records = one['missions'] + one.get('refit', [])
    in_tasks = sum(r.get('elapsed_s', 0.0) for r in records)
    n_tasks = len(records)
    return {
        'scale': {'missions': MISSIONS, 'duration_s': DURATION_S, 'rate_hz': 50,
                  'spacing_h': SPACING_H, 'states_per_mission': int(DURATION_S * 50) + 1},
        'truth': {'buoyancy_offset.dB': f'{DB_FIRST} -> {DB_LAST} N linear, '
                                        f'{true_slope:.4g} N/day',
                  'bar_bias.bias': f'0 -> {BIAS} rad from mission_{BIAS_FROM:03d}'},
        'write_logs_s': write_s,
        'found': {
            'buoyancy_offset.dB': {'verdict': db.get('verdict'), 'slope_per_day': db.get('slope'),
                                   'slope_ci95': db.get('slope_ci95'),
                                   'p_trend': db.get('p_trend')},
            'bar_bias.bias': {'verdict': bias.get('verdict'),
                              'step_mission': bias.get('step_mission'),
                              'before': bias.get('before'), 'after': bias.get('after'),
                              'p_step': bias.get('p_step')},
            'other_quantities': {k: v['verdict'] for k, v in tr.items()
                                 if k not in ('buoyancy_offset.dB', 'bar_bias.bias')},
            'effect_set': doc['effect_set'],
        },
        'finds_drift': bool(db.get('verdict') == 'drift'
                            and db['slope_ci95'][0] <= true_slope <= db['slope_ci95'][1]),
        'finds_step_at_right_mission': bool(bias.get('verdict') == 'step'
                                            and bias.get('step_mission')
                                            == f'mission_{BIAS_FROM:03d}'),
        'failed_missions': doc['counts']['failed'],
        'first_pass_verdicts': _count([m.get('verdict') for m in doc['missions']]),
        'tasks': n_tasks,
        'wall_s': {'1_worker': one['wall_s'], '2_workers': doc['wall_s']},
        'speed_up_2_workers': one['wall_s'] / doc['wall_s'],
        'cluster_start_s': start_s,
        'mean_task_s': in_tasks / n_tasks,
        'overhead_per_task_s': (one['wall_s'] - start_s - in_tasks) / n_tasks,
        'noop_round_trip_per_task_s': noop_s,
        'worker_peak_rss_mb': doc['worker_peak_rss_mb'],
        'missions_written': len(missions),
    }


def _count(values: list[Any]) -> dict[str, int]:
    out: dict[str, int] = {}
    for v in values:
        out[str(v)] = out.get(str(v), 0) + 1
    return out


def _cpu_s() -> float:
    """CPU seconds of this process and of its finished children (the cluster's processes,
    once it is shut down)."""
    a = resource.getrusage(resource.RUSAGE_SELF)
    b = resource.getrusage(resource.RUSAGE_CHILDREN)
    return a.ru_utime + a.ru_stime + b.ru_utime + b.ru_stime


_BARE_CHILD = """
import json, resource, sys, time
t0 = time.perf_counter()
from auv_campaign.montecarlo import Draw, run_chunk
d = json.loads(sys.argv[1])
draw = Draw(d['vehicle'], runs=d['runs'], seed=d['seed'], duration=d['duration'],
            spreads=d['spreads'], effects={e: {f: tuple(v) for f, v in fs.items()}
                                           for e, fs in d['effects'].items()},
            step=tuple(d['step']))
runs = run_chunk(draw, range(draw.runs))
print(json.dumps({'steps': sum(r['steps'] for r in runs if r['status'] == 'ok'),
                  'wall_s': time.perf_counter() - t0}))
"""


def _bare_fresh_process(draw: Any) -> tuple[float, float, int]:
    """The same runs without the engine in a fresh Python process (paying, like a command,
    the interpreter, imports, compiled kernels and pilot design): wall [s], CPU [s], steps."""
    import dataclasses
    import subprocess
    import sys

    spec = {**dataclasses.asdict(draw), 'effects': {e: {f: list(v) for f, v in fs.items()}
                                                     for e, fs in draw.effects.items()}}
    c0, t0 = _cpu_s(), time.perf_counter()
    proc = subprocess.run([sys.executable, '-c', _BARE_CHILD, json.dumps(spec)],
                          capture_output=True, text=True, check=True, timeout=1800)
    wall, cpu = time.perf_counter() - t0, _cpu_s() - c0
    return wall, cpu, int(json.loads(proc.stdout.splitlines()[-1])['steps'])


def _engine_command(args: list[str]) -> tuple[float, float, dict[str, Any]]:
    """``auv campaign montecarlo`` as a user runs it (a fresh process): wall [s], CPU [s] of
    the command and its cluster's processes, and its montecarlo.json."""
    import subprocess
    import sys

    c0, t0 = _cpu_s(), time.perf_counter()
    subprocess.run([sys.executable, '-m', 'auv_bringup.cli', 'campaign', *args],
                   capture_output=True, text=True, check=True, timeout=1800)
    wall, cpu = time.perf_counter() - t0, _cpu_s() - c0
    out = pathlib.Path(args[args.index('--out') + 1])
    return wall, cpu, json.loads((out / 'montecarlo.json').read_text())


def run_montecarlo(tmp: pathlib.Path) -> dict[str, Any]:
    """Four arms per repeat, alternating, so that a change of the shared machine's load hits
    all (ratios are medians over the repeats):

    * bare, warm: the runs in this process, one after the other (pilot designed and kernels
      loaded beforehand, not counted);
    * engine, in this process: ``cli.run`` with 1 worker (cluster start counted; the pilot's
      design counted: its cache is cleared first; the kernels are already loaded in this
      process, which the forked worker inherits);
    * engine, command: ``auv campaign montecarlo --workers 1`` in a fresh process;
    * bare, fresh process: the same runs without Dask in a fresh Python process.

    Figures per wall second and per CPU second (this process and its children: the
    scheduler, the workers; CPU time is far less sensitive to the load than wall time)."""
    from auv_campaign.montecarlo import Draw, forget_pilots, run_chunk

    spreads = {'CZuw': 0.2, 'CMuq': 0.2, 'CMuw': 0.1}
    effects = {'buoyancy_offset': {'dB': (-30.0, 30.0)}}
    draw = Draw(str(A18M), runs=MC_RUNS, seed=7, duration=MC_DURATION_S, spreads=spreads,
                effects=effects, step=(5.0, 20.0))
    run_chunk(draw, [0])                      # warm-up: kernels loaded, pilot designed
    args = ['montecarlo', '--runs', str(MC_RUNS), '--chunk', str(MC_CHUNK), '--seed', '7',
            '--duration', str(MC_DURATION_S), '--spread', *[f'{k}={v}' for k, v in
                                                           spreads.items()],
            '--effect', 'buoyancy_offset.dB=-30:30', '--step', '5:20', '--quiet']
    pairs = []
    bare: list[dict[str, Any]] = []
    steps = 0
    for rep in range(MC_REPEATS):
        c0, t0 = _cpu_s(), time.perf_counter()
        bare = run_chunk(draw, range(MC_RUNS))
        bare_s, bare_cpu = time.perf_counter() - t0, _cpu_s() - c0
        steps = sum(r['steps'] for r in bare if r['status'] == 'ok')
        forget_pilots()
        c0 = _cpu_s()
        eng = _campaign([*args, '--out', str(tmp / f'mc1-{rep}'), '--workers', '1'])
        eng_cpu = _cpu_s() - c0
        cmd_s, cmd_cpu, cmd = _engine_command([*args, '--out', str(tmp / f'mcc-{rep}'),
                                               '--workers', '1'])
        fresh_s, fresh_cpu, fresh_steps = _bare_fresh_process(draw)
        assert cmd['summary']['vehicle_steps'] == steps == fresh_steps
        pairs.append({
            'bare_steps_per_s': steps / bare_s,
            'engine_steps_per_s': eng['vehicle_steps_per_s'],
            'engine_steps_per_s_after_start': eng['vehicle_steps_per_s_tasks'],
            'cluster_start_s': eng['wall_s'] - eng['tasks_wall_s'],
            'bare_steps_per_cpu_s': steps / bare_cpu,
            'engine_steps_per_cpu_s': steps / eng_cpu,
            'command_steps_per_s': steps / cmd_s,
            'command_steps_per_cpu_s': steps / cmd_cpu,
            'bare_fresh_steps_per_s': steps / fresh_s,
            'bare_fresh_steps_per_cpu_s': steps / fresh_cpu,
            'load_average_1min': os.getloadavg()[0]})
    two = _campaign([*args, '--out', str(tmp / 'mc2'), '--workers', '2'])
    same = all((a['settling_time'] is None and math.isnan(b['settling_time']))
               or a['settling_time'] == b['settling_time']
               for a, b in zip(two['runs'], bare))

    def med(key: str, base: str = 'bare_steps_per_s') -> float:
        return statistics.median(p[key] / p[base] for p in pairs)
    ratio = med('engine_steps_per_s')
    cpu_ratio = med('engine_steps_per_cpu_s', 'bare_steps_per_cpu_s')
    return {
        'runs': MC_RUNS, 'chunk': MC_CHUNK, 'duration_s': MC_DURATION_S,
        'vehicle_steps': steps, 'repeats': MC_REPEATS, 'pairs': pairs,
        'median_bare_steps_per_s': statistics.median(p['bare_steps_per_s'] for p in pairs),
        'median_bare_steps_per_cpu_s': statistics.median(p['bare_steps_per_cpu_s']
                                                         for p in pairs),
        'engine_1_worker_over_bare': ratio,
        'engine_1_worker_over_bare_after_start': med('engine_steps_per_s_after_start'),
        'engine_1_worker_over_bare_per_cpu_s': cpu_ratio,
        'command_over_bare': med('command_steps_per_s'),
        'command_over_bare_per_cpu_s': med('command_steps_per_cpu_s', 'bare_steps_per_cpu_s'),
        'command_over_bare_fresh_process': med('command_steps_per_s',
                                               'bare_fresh_steps_per_s'),
        'command_over_bare_fresh_process_per_cpu_s': med('command_steps_per_cpu_s',
                                                         'bare_fresh_steps_per_cpu_s'),
        'engine_2_workers_steps_per_s': two['vehicle_steps_per_s'],
        'engine_2_workers_steps_per_s_after_start': two['vehicle_steps_per_s_tasks'],
        'engine_2_workers_over_bare_1_core': two['vehicle_steps_per_s']
        / statistics.median(p['bare_steps_per_s'] for p in pairs),
        'engine_wall_includes': 'cluster start, task submission, gathering',
        'bare': 'the same runs in this process, one after the other (warm: pilot designed, '
                'kernels loaded, not counted)',
        'goal_engine_over_bare': 0.8,
        'meets_goal_wall_clock': bool(ratio >= 0.8),
        'meets_goal_per_cpu_s': bool(cpu_ratio >= 0.8),
        'engine_extra_cpu_s': statistics.median(
            steps / p['engine_steps_per_cpu_s'] - steps / p['bare_steps_per_cpu_s']
            for p in pairs),
        'command_extra_cpu_s': statistics.median(
            steps / p['command_steps_per_cpu_s'] - steps / p['bare_steps_per_cpu_s']
            for p in pairs),
        'bare_fresh_process_extra_cpu_s': statistics.median(
            steps / p['bare_fresh_steps_per_cpu_s'] - steps / p['bare_steps_per_cpu_s']
            for p in pairs),
        'same_results_as_bare': same,
        'summary': two['summary'],
    }


def run() -> dict[str, Any]:
    """Run both parts; returns the figures."""
    with tempfile.TemporaryDirectory() as tmp:
        gap = run_gap(pathlib.Path(tmp))
        mc = run_montecarlo(pathlib.Path(tmp))
    return {
        'benchmark': 'campaigns on the Dask engine',
        'gap_campaign': gap, 'montecarlo': mc,
        'machine': {'python': platform.python_version(), 'cpus': os.cpu_count(),
                    'load_average_1min': os.getloadavg()[0]},
    }


if __name__ == '__main__':
    import sys

    if sys.argv[1:] == ['--only', 'montecarlo']:   # re-measure one part, keep the other
        figures = json.loads((pathlib.Path(__file__).parent / 'results'
                              / 'campaign.json').read_text())
        with tempfile.TemporaryDirectory() as tmp:
            figures['montecarlo'] = run_montecarlo(pathlib.Path(tmp))
        figures['machine_montecarlo'] = {'load_average_1min': os.getloadavg()[0]}
    else:
        figures = run()
    save_figures('campaign', figures)
    print(json.dumps(figures, indent=2))
