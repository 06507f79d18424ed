"""``auv vehicle-init``: a starting vehicle file scaled from a reference by geometric
similarity. Oracles: the reference's own dimensions and mass give the reference back; a
vehicle twice as long and wide and eight times as heavy scales each quantity by the power
worked out by hand (inertia m L^2: 8 x 4; Mqdot rho D^2 L^3: 4 x 8; Yvdot rho D^2 L: 8;
Ix m D^2: 32; thrust ~ D^2: 4); every value not given says how it was estimated."""
from __future__ import annotations

import math
import pathlib
import subprocess
import sys

import pytest

from auv_ident.identify.priors import CROSSFLOW
from auv_ident.vehicle_init import VehicleInitError, estimate
from auv_sim.params import PARAM_NAMES, load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]
REMUS = ROOT / 'config' / 'remus100.yaml'


def test_reference_dimensions_give_the_reference_back() -> None:
    ref = load_vehicle(REMUS)
    v = ref.values
    params, _ = estimate(v['L_ref'], v['diameter'], v['m'], ref)
    for key in PARAM_NAMES:
        if key in CROSSFLOW:    # strip theory over the hull, not the reference's values
            continue
        assert params.values[key] == pytest.approx(v[key], rel=1e-12, abs=1e-15), key


def test_cross_flow_drag_is_strip_theory_over_the_hull() -> None:
    """Oracles: Prestero's hull cross-flow drag of the REMUS 100, Zww = -131 kg/m (2001,
    table B.1, strip theory with c_dc = 1.1 on his Myring hull), and a cylinder worked by
    hand: Zww = -1/2 rho c_dc D L, Mqq = -1/2 rho c_dc D (L/2)^4 / 2 about its middle."""
    ref = load_vehicle(REMUS)
    v = ref.values
    params, _ = estimate(v['L_ref'], v['diameter'], v['m'], ref)
    assert params.values['Zww'] == pytest.approx(-131.0, rel=0.03)
    assert params.values['Yvv'] == params.values['Zww']
    assert params.values['Mqq'] == params.values['Nrr'] < 0.0
    assert params.sources['Mqq'].startswith('estimated: cross-flow strip theory')
    assert 'c_dc = 1.1' in params.sources['Zww']
    # a 1.6 m, 0.15 m hull: Prestero's Mqq scaled by D L^4 would be -309 kg m^2; the hull's
    # own strip theory is less than a cylinder's of its length and diameter (its radius is
    # nowhere larger), -17.3 kg m^2, and more than half of it (the tapered ends)
    small, _ = estimate(1.6, 0.15, 20.0, ref, water='salt')
    cylinder_mqq = -0.5 * 1025.0 * 1.1 * 0.15 * 0.8 ** 4 / 2
    assert cylinder_mqq < small.values['Mqq'] < 0.5 * cylinder_mqq
    assert -0.5 * 1025.0 * 1.1 * 0.15 * 1.6 < small.values['Zww'] < 0.0
    # fresh water scales the drag with the density
    fresh, _ = estimate(1.6, 0.15, 20.0, ref, water='fresh')
    assert fresh.values['Zww'] / small.values['Zww'] == pytest.approx(999.1 / 1025.0,
                                                                      rel=1e-12)
    assert fresh.values['rho'] == 999.1 and fresh.sources['rho'].startswith('given: fresh')


def test_fins_give_the_plane_derivatives() -> None:
    """Two fins of 0.004 m^2 at a lift slope of 3/rad on a 0.15 m hull: CZbar = 2 x 3 x
    0.004 / (pi 0.15^2 / 4) in the reference's sign; CMbar keeps the reference's lever arm."""
    ref = load_vehicle(REMUS)
    params, _ = estimate(1.6, 0.15, 20.0, ref, fin_count=2, fin_area=0.004)
    expected = 2 * 3.0 * 0.004 / (math.pi * 0.15 ** 2 / 4)
    assert params.values['CZbar'] == pytest.approx(-expected, rel=1e-12)
    assert params.values['CMbar'] / params.values['CZbar'] == pytest.approx(
        ref.values['CMbar'] / ref.values['CZbar'], rel=1e-12)
    with pytest.raises(VehicleInitError, match='give --fin-count and --fin-area together'):
        estimate(1.6, 0.15, 20.0, ref, fin_count=2)
    with pytest.raises(VehicleInitError, match='--water must be one of'):
        estimate(1.6, 0.15, 20.0, ref, water='brackish')


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
