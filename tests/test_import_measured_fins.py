"""Measured fin positions replace the commands run through the actuator model.

A 10 Hz text log (navigation-grade sensor noise) of the pitch mission whose command column
is wrong (the plane commands logged 1.5 s late, as a bad clock would) but whose fin column
holds the plane's true position (the simulator's actuator state). Through a map with
``bar_measured``, the identification drives the model with the measured fin and its heave
and pitch intervals hold the vehicle file's values; through the commands alone (the same
log, no ``bar_measured``) the fit is worse and the intervals wider. The gap's log pieces
carry the measured fin.
"""
from __future__ import annotations

import argparse
import json
import math
import pathlib
from typing import Any

import numpy as np

from auv_gap.logs import from_contract_arrays, measured_fins_vehicle
from auv_ident import cli
from auv_logs.contract_bag import contract_arrays
from auv_logs.importer import import_log
from auv_logs.mapping import load_map
from auv_logs.simlog import SensorNoise
from auv_sim.missions import load_mission, run_mission
from auv_sim.params import load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]
A18M = ROOT / 'config' / 'a18m.yaml'
NOISE_SEED = 7       # navigation-grade noise, seed fixed as in the import round trips
MAP = """format: auv-log-map/1
kind: text
text: {delimiter: whitespace, header: true}
time: {column: time, unit: s}
signals:
  z: {column: depth, unit: m, frame: NED}
  phi: {column: roll, unit: rad, frame: NED/FRD}
  theta: {column: pitch, unit: rad, frame: NED/FRD}
  psi: {column: yaw, unit: rad, frame: NED}
  u: {column: u, unit: m/s, frame: FRD}
  w: {column: w, unit: m/s, frame: FRD}
  q: {column: q, unit: rad/s, frame: FRD}
  bar: {column: bar_cmd, unit: rad}
  helm: {column: helm, unit: rad}
MEASURED  thrust: {column: thrust, unit: N}
"""


def _ident(log: pathlib.Path, map_path: pathlib.Path, out: pathlib.Path,
           status: int = 0) -> dict[str, Any]:
    parser = argparse.ArgumentParser()
    cli.add_arguments(parser)
    ns = parser.parse_args([str(log), '--map', str(map_path), '--out', str(out),
                            '--equations', 'heave', 'pitch', '--no-nelder-mead'])
    assert cli.run(ns) == status
    report: dict[str, Any] = json.loads((out / 'report.json').read_text())
    return report


def test_measured_fin_positions_replace_late_commands(tmp_path: pathlib.Path) -> None:
    base = load_vehicle(A18M)
    rec = run_mission(base, load_mission('pitch'))
    noise = np.random.default_rng(NOISE_SEED).standard_normal((len(rec.t), 12)) * \
        SensorNoise.realistic().sigmas()
    idx = np.arange(0, len(rec.t), 5)                       # 10 Hz
    late = np.interp(rec.t - 1.5, rec.t, rec.cmd[:, 0])     # commands 1.5 s late
    lines = ['time depth roll pitch yaw u w q bar_cmd bar_fin helm thrust']
    for i in idx:
        x = rec.measured[i, :12] + noise[i]
        lines.append(' '.join(f'{v:.12g}' for v in (
            rec.t[i], x[2], x[3], x[4], x[5], x[6], x[8], x[10], late[i], rec.x[i, 12],
            rec.cmd[i, 1], rec.cmd[i, 2])))
    (tmp_path / 'dive.txt').write_text('\n'.join(lines) + '\n')
    (tmp_path / 'fins.yaml').write_text(MAP.replace(
        'MEASURED', '  bar_measured: {column: bar_fin, unit: rad}\n'))
    (tmp_path / 'cmds.yaml').write_text(MAP.replace('MEASURED', ''))
    fins = _ident(tmp_path / 'dive.txt', tmp_path / 'fins.yaml', tmp_path / 'a')
    # fitted on commands 1.5 s late, the model predicts the held-out flight worse than the
    # vehicle file (the simulated truth): not written (exit status 3)
    cmds = _ident(tmp_path / 'dive.txt', tmp_path / 'cmds.yaml', tmp_path / 'b',
                  status=cli.NOT_WRITTEN)
    assert fins['validation']['written'] and not cmds['validation']['written']
    assert cmds['validation']['verdict'] == 'worse'
    assert fins['actuators']['bar'].startswith('measured fin position (/auv/bar_measured')
    assert cmds['actuators']['bar'].startswith('command through the actuator model')
    for name, c in fins['coefficients'].items():
        lo, hi = c['ci95']
        assert lo <= base.values[name] <= hi, (name, c)
    # the late commands leave the plane's force in the residual: a worse fit, wider intervals
    for eq in ('heave', 'pitch'):
        assert fins['equations'][eq]['r2'] > cmds['equations'][eq]['r2'], eq
    for name, c in fins['coefficients'].items():
        assert c['std_error'] < cmds['coefficients'][name]['std_error'], name
    # the gap: the measured fin drives the model; its actuator passes it through
    imported = import_log(load_map(tmp_path / 'fins.yaml'), tmp_path / 'dive.txt')
    pieces = from_contract_arrays('dive', contract_arrays(imported), [imported.report])
    assert pieces[0].measured_fins == ('bar',)
    _, va = pieces[0].commands['bar']
    assert np.allclose(va, rec.x[idx, 12])
    assert any('measured fin positions (/auv/bar_measured) used' in n for n in pieces[0].notes)
    v = measured_fins_vehicle(base, pieces)
    assert v.bar_tau == base.dt and v.bar_rate == 1000.0 and v.helm_tau == base.helm_tau
    assert math.isfinite(v.bar_max)
