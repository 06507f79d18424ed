"""``auv vehicle-init``: a starting vehicle file scaled from a reference by geometric
similarity. Oracles: the reference's own dimensions and mass give the reference back; a
vehicle twice as long and wide and eight times as heavy scales each quantity by the power
worked out by hand (inertia m L^2: 8 x 4; Mqdot rho D^2 L^3: 4 x 8; Yvdot rho D^2 L: 8;
Ix m D^2: 32; thrust ~ D^2: 4); every value not given says how it was estimated."""
from __future__ import annotations

import pathlib
import subprocess
import sys

import pytest

from auv_ident.vehicle_init import VehicleInitError, estimate
from auv_sim.params import PARAM_NAMES, load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]
REMUS = ROOT / 'config' / 'remus100.yaml'


def test_reference_dimensions_give_the_reference_back() -> None:
    ref = load_vehicle(REMUS)
    v = ref.values
    params, _ = estimate(v['L_ref'], v['diameter'], v['m'], ref)
    for key in PARAM_NAMES:
        assert params.values[key] == pytest.approx(v[key], rel=1e-12, abs=1e-15), key


def test_twice_the_size_scales_as_worked_by_hand() -> None:
    ref = load_vehicle(REMUS)
    v = ref.values
    params, notes = estimate(2 * v['L_ref'], 2 * v['diameter'], 8 * v['m'], ref)
    p = params.values
    for key, factor in (('Iy', 32), ('Iz', 32), ('Ix', 32), ('Mqdot', 32), ('Nrdot', 32),
                        ('Yvdot', 8), ('Zwdot', 8), ('Xudot', 8), ('Kpdot', 32), ('Yrdot', 16),
                        ('B', 8), ('zg', 2), ('thrust_max', 4), ('S_ref', 4), ('CZuw', 1),
                        ('CMbar', 1), ('bar_max', 1)):
        assert p[key] == pytest.approx(factor * v[key], rel=1e-12), key
    for key in PARAM_NAMES:
        src = params.sources[key]
        assert src.startswith(('estimated: ', 'given: ', 'derived: ')), (key, src)
    assert notes[0].startswith('fineness ratio L/D = 6.96 (reference')


def test_cli_writes_a_loadable_file_and_refuses_bad_input(tmp_path: pathlib.Path) -> None:
    out = tmp_path / 'mine.yaml'
    cmd = [sys.executable, '-m', 'auv_bringup.cli', 'vehicle-init', '--length', '1.6',
           '--diameter', '0.15', '--mass', '20', '--out', str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    mine = load_vehicle(out)
    assert mine.values['m'] == 20.0 and mine.values['L_ref'] == 1.6
    assert mine.sources['CZuw'].startswith('estimated: dimensionless')
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 1
    assert proc.stderr == f'error: {out} exists already\n'
    with pytest.raises(VehicleInitError, match='less than 3 diameters'):
        estimate(0.4, 0.15, 20.0, load_vehicle(REMUS))
