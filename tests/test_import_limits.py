"""Logged commands outside the vehicle file's limits are used as logged and reported, never
clipped: the surge mission of config/a18m.yaml logs thrust up to 200 N; identified against
a copy of the vehicle file whose ``thrust_max`` is 100 N, Ksh must be what the unmodified
file gives (the logged thrust reaches the reconstruction whole), and the report must count
the commands above 100 N and give their range."""
from __future__ import annotations

import pathlib

import numpy as np
import pytest

from auv_ident.identify import identify
from auv_ident.job import load_records
from auv_logs.limits import as_logged, describe
from auv_logs.simlog import write_record
from auv_sim.missions import load_mission, run_mission
from auv_sim.params import load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]
A18M = ROOT / 'config' / 'a18m.yaml'


def test_thrust_above_the_file_limit_is_used_as_logged_and_reported(
        tmp_path: pathlib.Path) -> None:
    base = load_vehicle(A18M)
    rec = run_mission(base, load_mission('surge'))
    write_record(tmp_path / 'surge', rec, forces=False)
    thrust = rec.cmd[:, 2]
    change = np.flatnonzero(np.diff(thrust, prepend=np.nan) != 0)
    above = int(np.count_nonzero(thrust[change] > 100.0))
    assert above > 0 and float(thrust.max()) == 200.0
    low = base.replace(thrust_max=100.0)
    limits: dict[str, dict[str, float]] = {}
    rec_low, _ = load_records([str(tmp_path / 'surge')], low, 'motion', limits=limits)
    rec_true, _ = load_records([str(tmp_path / 'surge')], base, 'motion')
    ksh_low = identify(rec_low, low, equations=['surge']).coefficients['Ksh']
    ksh_true = identify(rec_true, base, equations=['surge']).coefficients['Ksh']
    assert ksh_low.value == pytest.approx(ksh_true.value, rel=1e-12)
    assert ksh_low.value == pytest.approx(base.values['Ksh'], rel=1e-3)
    r = limits['thrust']
    assert (r['count'], r['total'], r['max'], r['limits']) == (above, len(change), 200.0,
                                                               [-60.0, 100.0])
    assert 'bar' not in limits and 'helm' not in limits
    assert describe(limits)[0].startswith(f'thrust: {above} of {len(change)} logged commands '
                                          "outside the vehicle file's limits [-60, 100] N "
                                          '(logged ')


def test_fin_limits_widen_symmetrically() -> None:
    base = load_vehicle(A18M)
    cmds = {'bar': (np.array([0.0, 1.0]), np.array([0.1, -0.6])),
            'thrust': (np.array([0.0]), np.array([20.0]))}
    widened, report = as_logged(base, [cmds])
    assert widened.values['bar_max'] == 0.6
    assert report['bar']['count'] == 1 and report['bar']['min'] == -0.6
    assert widened.values['thrust_max'] == base.values['thrust_max']
