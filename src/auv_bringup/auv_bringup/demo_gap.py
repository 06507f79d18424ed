"""The demo's sim-to-real step: a "real" vehicle with hidden effects, then ``auv gap``.

The real vehicle is the simulator with ``config/effects/demo_hidden.yaml`` applied; it flies a
15-minute closed-loop log (depth changes, speed changes, plane doublets) measured with
realistic sensor noise, written as a bag with ``/auv/state`` and the command topics only, as a
vehicle logs. ``auv gap`` then diagnoses it against the nominal vehicle file, as a user would.
"""
from __future__ import annotations

import json
import pathlib
import subprocess
import sys
from typing import Any

from auv_bringup.errors import RunError
from auv_contract import config_path
from auv_gap.synth import simulate, write_bag
from auv_sim.environment import load_environment
from auv_sim.params import VehicleParams


def gap_step(params: VehicleParams, vehicle_file: str, out: pathlib.Path,
             hidden: pathlib.Path | None = None) -> dict[str, Any]:
    """Make the real log (``hidden``: its effects file, by default the shipped
    ``effects/demo_hidden.yaml``), run ``auv gap`` on it; returns the figures for the summary."""
    out.mkdir(parents=True, exist_ok=True)
    env = load_environment(hidden or config_path('effects', 'demo_hidden.yaml'))
    log = simulate(params, env, seed=7)
    bag = out / 'real_log'
    write_bag(bag, log)
    proc = subprocess.run([sys.executable, '-m', 'auv_bringup.cli', 'gap', '--vehicle',
                           vehicle_file, str(bag), '--out', str(out / 'report')],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise RunError(f'auv gap failed: {proc.stderr.strip().splitlines()[-1:]}')
    report = json.loads((out / 'report' / 'report.json').read_text())
    best = report['best']
    params_best: dict[str, float] = next(
        (c['params'] for c in report['candidates'] if c['effect'] == best), {})
    held = report['held_out']
    return {'hidden': ', '.join(f'{k} {v}' for k, v in env.effects.items()),
            'verdict': report['verdict'], 'best': best,
            'params': {k: round(v, 4) for k, v in params_best.items()},
            'rms_before_z': held['rms_before']['z'], 'rms_after_z': held['rms_after']['z'],
            'shrink': held['shrink'], 'report': str(out / 'report' / 'report.md')}
