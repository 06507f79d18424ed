"""Free runs of the model against a log, the strip-theory plant, commands sampled at slow
rows, and output error where the equation error's derivatives are poor.

Oracles: the simulator's own record (a free run from its true states, with its commands,
must reproduce it); strip theory on a single velocity (the coupled strip integral reduces to
the split coefficients of :func:`auv_sim.hull.crossflow_coefficients`); a pilot's command
sampled at 2 Hz rows (its samples lie on a line between rows); the A18M's own coefficients
for a 2 Hz text log flown with them.
"""
from __future__ import annotations

import json
import math
import pathlib

import numpy as np
import pytest

from auv_ident.freerun import FreeRuns, parameter_vector, split_windows, window_length
from auv_ident.identify import LoggedRun
from auv_ident.motion import sampled_commands
from auv_ident.output_error import needs_output_error, quantisation_step
from auv_sim.environment import Environment
from auv_sim.hull import crossflow_coefficients
from auv_sim.missions import load_mission, run_mission
from auv_sim.model import wrench_series
from auv_sim.params import VehicleParams, load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]
A18M = ROOT / 'config' / 'a18m.yaml'
REMUS = ROOT / 'config' / 'remus100.yaml'


@pytest.fixture(scope='module')
def base() -> VehicleParams:
    return load_vehicle(A18M)


def mission_log(params: VehicleParams, name: str) -> tuple[object, LoggedRun]:
    rec = run_mission(params, load_mission(name))
    cmds = {}
    for j, ch in enumerate(('bar', 'helm', 'thrust')):
        change = np.flatnonzero(np.diff(rec.cmd[:, j], prepend=np.nan) != 0)
        cmds[ch] = (rec.t[change], rec.cmd[change, j])
    return rec, LoggedRun(rec.t, rec.x[:, :12], cmds)


def test_free_runs_from_true_states_reproduce_the_simulator(base: VehicleParams) -> None:
    rec, run = mission_log(base, 'pitch')
    length, _ = window_length(base, [run])
    windows = split_windows([run], length, hold=False)
    runs = FreeRuns([run], windows, base, step=base.dt)
    pred = runs.run(parameter_vector(base)[None], runs.initial_states()[None])
    err = max(float(np.max(np.abs(p[0][:, :12] - rec.x[w.i0:w.i1, :12])))
              for p, w in zip(pred, windows))
    assert len(windows) >= 6 and err < 1e-3
    # a coarser step (the identification's, up to 0.05 s) stays within 5 mm of depth
    coarse = FreeRuns([run], windows, base)
    assert coarse.dt > base.dt
    pred = coarse.run(parameter_vector(base)[None], coarse.initial_states()[None])
    assert max(float(np.max(np.abs(p[0][:, 2] - rec.x[w.i0:w.i1, 2])))
               for p, w in zip(pred, windows)) < 5e-3


def test_strip_theory_plant_is_not_the_models_form() -> None:
    v = load_vehicle(REMUS).replace(**{k: 0.0 for k in (
        'Yvv', 'Yrr', 'Zww', 'Zqq', 'Mww', 'Mqq', 'Nvv', 'Nrr')})
    env = Environment(effects={'hull_crossflow': {'cd': 1.1, 'length': v.L_ref,
                                                  'diameter': v.diameter}})
    split = crossflow_coefficients(v.L_ref, v.diameter, v.rho)
    X = np.zeros((3, 15))
    X[:, 6] = 1.5
    X[0, 8] = 0.2                      # heave alone
    X[1, 10] = 0.3                     # pitch rate alone
    X[2, 8], X[2, 10] = 0.2, 0.3       # both: the cross-flow couples them along the hull
    P = v.as_array()
    W = wrench_series(np.zeros(3), X, P, env.env_vector(), env.profile())[:, 0]
    W0 = wrench_series(np.zeros(3), X, P, Environment().env_vector(), env.profile())[:, 0]
    d = W - W0
    assert d[0, 2] == pytest.approx(split['Zww'] * 0.04, rel=2e-3)
    # (the plant's 24 strips against 200: Mww, a small difference of fore and aft, to 1 %)
    assert d[0, 4] == pytest.approx(split['Mww'] * 0.04, rel=1e-2)
    assert d[1, 4] == pytest.approx(split['Mqq'] * 0.09, rel=2e-3)
    separable = split['Zww'] * 0.04 + split['Zqq'] * 0.09
    assert abs(d[2, 2] - separable) > 0.1 * abs(separable)


def test_commands_sampled_at_slow_rows_are_taken_as_linear() -> None:
    t = 0.5 * np.arange(40)
    pilot = 0.05 * np.sin(0.7 * t)                      # changes at every row
    steps = np.where(t < 10.0, 0.0, 0.1)                 # a step, logged at every row
    commands = {'bar': (t, pilot), 'helm': (t, steps), 'thrust': (t[:1], np.array([50.0]))}
    out, changed = sampled_commands(t, commands, 0.01)
    assert changed == ['bar']
    st, va = out['bar']
    assert st[1] - st[0] == pytest.approx(0.01)
    mid = np.searchsorted(st, 0.25 + 1e-9) - 1       # half way between the first two rows
    assert va[mid] == pytest.approx(0.5 * (pilot[0] + pilot[1]), abs=2e-4)
    assert out['helm'] is commands['helm']


def test_output_error_where_a_2hz_quantised_log_makes_derivatives_poor(
        base: VehicleParams, tmp_path: pathlib.Path) -> None:
    """The A18M's pitch mission written as a vendor text log at 2 Hz (depth in 0.1 m steps),
    identified from a base 30 % off in its heave and pitch coefficients: output error is used
    and says why, and its coefficients hold the A18M's within their intervals; equation error
    on the same log misses them."""
    from auv_ident import cli
    from auv_logs import synth

    rec, _ = mission_log(base, 'pitch')
    meas = rec.measured.copy()
    meas[:, 2] = np.round(meas[:, 2] / 0.1) * 0.1
    import dataclasses
    synth.write_text(tmp_path / 'pitch.txt', dataclasses.replace(rec, measured=meas), every=25)
    assert quantisation_step(meas[::25, 2]) == pytest.approx(0.1, rel=1e-6)
    wrong = base.replace(CZuw=1.3 * base.CZuw, CZuq=0.7 * base.CZuq, CMuw=1.3 * base.CMuw,
                         CMuq=0.7 * base.CMuq)
    from auv_sim.params import save_vehicle
    save_vehicle(wrong, tmp_path / 'base.yaml')
    truth = ('CZuw', 'CZuq', 'CMuw', 'CMuq')
    reports = {}
    for label, extra in (('oe', []), ('ee', ['--output-error', 'never'])):
        status = cli.main([str(tmp_path / 'pitch.txt'), '--map',
                           str(ROOT / 'config' / 'maps' / 'text_2hz_deg_cm.yaml'),
                           '--vehicle', str(tmp_path / 'base.yaml'), '--out',
                           str(tmp_path / label), '--equations', 'heave', 'pitch',
                           '--no-nelder-mead', *extra])
        assert status in (0, 3)
        reports[label] = json.loads((tmp_path / label / 'report.json').read_text())
    oe = reports['oe']
    assert oe['derivatives'].startswith('output error (multiple shooting')
    assert 'rows at 2 Hz' in oe['output_error']['why']
    assert 'depth quantised or repeated (0.1 m steps)' in oe['output_error']['why']
    for name in truth:
        c = oe['coefficients'][name]
        assert c['method'] == 'output error'
        assert c['ci95'][0] <= base.values[name] <= c['ci95'][1], (name, c)
    ee_err = [abs(reports['ee']['coefficients'][n]['value'] / base.values[n] - 1)
              for n in truth if n in reports['ee']['coefficients']]
    oe_err = [abs(oe['coefficients'][n]['value'] / base.values[n] - 1) for n in truth]
    assert max(oe_err) < 0.1
    assert not ee_err or max(ee_err) > max(oe_err)
    assert oe['validation']['written'] and math.isfinite(oe['validation']['ratio']['z'])


def test_poor_derivatives_are_named() -> None:
    t = 0.5 * np.arange(100)
    state = np.zeros((100, 12))
    state[:, 2] = np.round(10.0 + np.sin(0.1 * t) / 0.1) * 0.1
    run = LoggedRun(t, state, {}, origins={'w': 'derived', 'q': 'derived'})
    why = needs_output_error([run])
    assert why.startswith('rows at 2 Hz')
    assert 'q and w derived by differencing (not measured)' in why
    assert needs_output_error([LoggedRun(0.02 * np.arange(100), np.random.default_rng(1)
                                         .standard_normal((100, 12)), {})]) == ''
