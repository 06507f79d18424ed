"""``auv demo`` (``make demo``): the report's scenario end to end, through the node graph.

1. The graph (simulator, depth pilot, recorder; lockstep on simulated time, as fast as the
   processes allow) flies the A18M from 40 m to the commanded 10 m; the recorder writes the
   bag ``graph_bag/``.
2. From the bag: the report's plots (figures 10-15) and a summary of settling time,
   overshoot, peak pitch, RMS pitch rate after settling and BAR saturation time.
3. The same manoeuvre offline (``auv run``'s core) and with the report's own tuning, for the
   lockstep check (graph = offline) and the comparison with the report's ~379 s.
4. The sim-to-real step: a "real" vehicle with an effect the diagnosis is not told flies the
   missions; ``auv gap`` finds the effect and says how far the gap shrinks on held-out data.

Everything is written under ``--out`` (default ``out/demo``); ``summary.md`` links it all.
"""
from __future__ import annotations

import argparse
import math
import os
import pathlib
import shutil
import sys
import time
from typing import Any

import numpy as np

from auv_bag import read_arrays
from auv_bringup.errors import RunError
from auv_bringup.launch import GraphConfig, run_graph
from auv_bringup.options import check_number
from auv_bringup.plots import plot_depth_run
from auv_contract import STATE_FIELDS, config_path
from auv_contract.jsonout import dumps
from auv_depth_lqr.closed_loop import run_closed_loop
from auv_depth_lqr.metrics import step_metrics
from auv_depth_lqr.pilot import PilotSettings
from auv_sim.params import load_vehicle

STATE_KEYS = ('t', 'x', 'y', 'z', 'phi', 'theta', 'psi', 'u', 'v', 'w', 'p', 'q', 'r')


def say(text: str) -> None:
    print(f'demo: {text}', file=sys.stderr, flush=True)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('--out', default='out/demo', help='output directory')
    parser.add_argument('--vehicle', default=str(config_path('a18m.yaml')),
                        help='vehicle file (default: config/a18m.yaml)')
    parser.add_argument('--from-depth', type=float, default=40.0, help='[m]')
    parser.add_argument('--to-depth', type=float, default=10.0, help='[m]')
    parser.add_argument('--duration', type=float, default=150.0, help='simulated [s]')
    parser.add_argument('--skip-gap', action='store_true', help='leave out the gap step')


def graph_run(args: argparse.Namespace, out: pathlib.Path) -> dict[str, np.ndarray]:
    """Step 1: fly the manoeuvre through the node graph; returns the bag's arrays."""
    bag = out / 'graph_bag'
    cfg = GraphConfig(vehicle=args.vehicle, lockstep=True, real_time_factor=0.0,
                      initial_depth=args.from_depth, initial_speed=2.0,
                      stop_time=args.duration, record=str(bag), log_dir=str(out / 'logs'),
                      depth_command=args.to_depth)
    env = dict(os.environ)
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    wall = time.monotonic()
    codes = run_graph(cfg, duration=max(600.0, 10 * args.duration), env=env)
    wall = time.monotonic() - wall
    say(f'graph run: {args.duration:g} s simulated in {wall:.1f} s wall '
        f'(real-time factor {args.duration / wall:.1f}); exit codes {codes}')
    arrays = read_arrays(bag, ['/auv/state', '/auv/bar_command'])
    state = arrays['/auv/state']
    if len(state) < 10:
        raise RunError(f'the graph run recorded only {len(state)} states; see {out}/logs')
    return {'state': state, 'bar': arrays['/auv/bar_command'], 'wall': np.array(wall)}


def run(args: argparse.Namespace) -> int:
    check_number('--from-depth', args.from_depth, unit='m')
    check_number('--to-depth', args.to_depth, unit='m')
    check_number('--duration', args.duration, above=0.0, unit='s')
    out = pathlib.Path(args.out)
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    params = load_vehicle(args.vehicle)
    z1 = args.to_depth
    summary: dict[str, Any] = {'scenario': f'{args.from_depth:g} m -> {z1:g} m at 2 m/s, '
                                           f'A18M, {args.duration:g} s simulated'}

    say('step 1/4: closed loop through the node graph (simulator, pilot, recorder)')
    g = graph_run(args, out)
    st, bar = g['state'], g['bar']
    state = {k: st[k] for k in STATE_KEYS}
    say('step 2/4: plots and summary from the bag')
    plot_depth_run(state, bar['t'], bar['value'], out / 'plots',
                   z_ref_t=np.array([st['t'][0]]), z_ref=np.array([z1]), title='(graph run)')
    bar_on_state = np.interp(st['t'], bar['t'], bar['value'])
    m = step_metrics(st['t'], st['z'], st['theta'], st['q'], bar_on_state, z1,
                     t_command=float(st['t'][0]), bar_max=params.bar_max)
    expected = int(round(args.duration * 50.0)) + 1
    if len(st) != expected:
        say(f'warning: the bag holds {len(st)} of the {expected} states the simulator '
            f'published')
    summary['graph'] = {**m.as_dict(), 'states_recorded': int(len(st)),
                        'states_published': expected,
                        'bar_commands_recorded': int(len(bar)),
                        'wall_time_s': float(g['wall'])}

    say('step 3/4: the same offline, and with the report\'s tuning')
    offline = run_closed_loop(params, [(0.0, z1)], args.duration, z0=args.from_depth)
    rec = offline.record
    common, i_off, i_graph = np.intersect1d(np.round(rec.t, 6), np.round(st['t'], 6),
                                            return_indices=True)
    cols = STATE_FIELDS
    diff = max(float(np.max(np.abs(rec.measured[i_off, j] - st[c][i_graph])))
               for j, c in enumerate(cols)) if len(common) else math.nan
    summary['lockstep_vs_offline'] = {'samples_compared': int(len(common)),
                                      'max_abs_state_difference': diff}
    report = run_closed_loop(params, [(0.0, z1)], max(args.duration, 600.0),
                             z0=args.from_depth, settings=PilotSettings(weights='report_5'))
    r = report.record
    mr = step_metrics(r.t, r.x[:, 2], r.x[:, 4], r.x[:, 10], r.x[:, 12], z1,
                      bar_max=params.bar_max)
    summary['report_tuning_offline'] = mr.as_dict()

    if not args.skip_gap:
        say('step 4/4: sim-to-real gap diagnosis of a vehicle with a hidden effect')
        from auv_bringup.demo_gap import gap_step
        summary['gap'] = gap_step(params, args.vehicle, out / 'gap')

    (out / 'summary.json').write_text(dumps(summary, indent=2))
    (out / 'summary.md').write_text(summary_markdown(summary))
    print((out / 'summary.md').read_text())
    return 0


def summary_markdown(s: dict[str, Any]) -> str:
    """The human-readable summary of the demo."""
    g = s['graph']
    rep = s['report_tuning_offline']
    lines = [
        f'# Depth manoeuvre: {s["scenario"]}', '',
        '| figure | this pilot (graph run) | report tuning (offline) |', '| --- | --- | --- |',
        f'| settling time to +-0.1 m [s] | {g["settling_time"]:.1f} | '
        f'{rep["settling_time"]:.1f} |',
        f'| settling / kinematic bound | {g["settling_over_kinematic_bound"]:.2f} | '
        f'{rep["settling_over_kinematic_bound"]:.2f} |',
        f'| overshoot [m] | {g["overshoot"]:.3f} | {rep["overshoot"]:.3f} |',
        f'| peak pitch [deg] | {g["peak_pitch_deg"]:.1f} | {rep["peak_pitch_deg"]:.1f} |',
        f'| RMS pitch rate after settling [deg/s] | {g["rms_q_settled_deg_s"]:.4f} | '
        f'{rep["rms_q_settled_deg_s"]:.4f} |',
        f'| BAR saturation time [s] | {g["bar_saturation_time"]:.1f} | '
        f'{rep["bar_saturation_time"]:.1f} |', '',
        f'Kinematic bound |dz| / (u0 sin 25 deg) = {g["kinematic_bound"]:.1f} s. '
        f'Graph run: {g["states_recorded"]} states and {g["bar_commands_recorded"]} BAR '
        f'commands in `graph_bag/`, {g["wall_time_s"]:.1f} s wall.', '',
        f'Lockstep graph run against the offline run: max state difference '
        f'{s["lockstep_vs_offline"]["max_abs_state_difference"]:.2e} over '
        f'{s["lockstep_vs_offline"]["samples_compared"]} samples.', '',
        '## Plots (report figures 10-15)', '',
        *[f'![{p}](plots/{p})' for p in ('fig10_depth.png', 'fig11_xy.png', 'fig12_euler.png',
                                          'fig13_linear_speed.png', 'fig14_angular_speed.png',
                                          'fig15_bar.png')], '']
    if 'gap' in s:
        gap = s['gap']
        lines += ['## Sim-to-real gap', '',
                  f'Hidden effect: `{gap["hidden"]}`. Verdict: **{gap["verdict"]}**, best '
                  f'candidate `{gap["best"]}` with {gap["params"]}; held-out depth RMS '
                  f'{gap["rms_before_z"]:.3f} m -> {gap["rms_after_z"]:.3f} m '
                  f'(shrink {100 * gap["shrink"]:.0f} %). Report: `gap/report.md`.', '']
    return '\n'.join(lines)
