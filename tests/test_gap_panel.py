"""The effect panel of the gap diagnosis, a few of its cases: a clean log (no gap), two
effects at once, an effect the dynamics cannot see and one of a form the catalogue lacks (a
current oscillating in time), each a 15-minute closed-loop log flown on the simulator with
realistic sensor noise; the diagnosis, told nothing, is judged by the benchmark's rules
(:func:`bench_gap_panel.judge`: name the effect or say it cannot tell it from another, bracket
its size with the 95 % interval, shrink the held-out depth RMS). The whole panel, one case per
file of ``config/effects``, is ``bench/bench_gap_panel.py``. Also: the report files, the
command line with a held-out bag, and ambiguity without the separating manoeuvre."""
from __future__ import annotations

import json
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from conftest import A18M, load_bench

from auv_gap import synth
from auv_gap.diagnose import diagnose
from auv_gap.report import REPORT_KEYS, write_report
from auv_gap.verdict import Diagnosis
from auv_sim.params import load_vehicle

PANEL = load_bench('gap_panel')
EFFECT_FILES = PANEL.EFFECT_FILES
#: the cases flown here (each special rule once; the others in the benchmark)
CASES = ('clean', 'two_effects', 'depth_sensor_bias', 'current_oscillation')


@pytest.fixture(scope='module')
def vehicle():  # type: ignore[no-untyped-def]
    return load_vehicle(A18M)


@pytest.fixture(scope='module')
def panel():  # type: ignore[no-untyped-def]
    """Diagnoses of the panel's logs, made once per module and case, on demand."""
    cache: dict[str, Diagnosis] = {}

    def get(case: str) -> Diagnosis:
        if case not in cache:
            cache[case] = PANEL.diagnose_case(case)
        return cache[case]
    return get


@pytest.mark.parametrize('case', CASES)
def test_panel(panel, case: str) -> None:  # type: ignore[no-untyped-def]
    r = panel(case).report
    assert tuple(r) == REPORT_KEYS
    why = PANEL.judge(r, PANEL.CASES[case])
    assert why is None, why


def test_report_files(panel, tmp_path: pathlib.Path) -> None:  # type: ignore[no-untyped-def]
    diag = panel('two_effects')
    path = write_report(diag, tmp_path / 'gap')
    report = json.loads(path.read_text())
    assert tuple(report) == REPORT_KEYS
    # the contract's keys, and what the report adds: the time origin of its times
    assert set(report['gap']) == {'free_run_rms', 'equation_rms', 'dominant_equation',
                                  'segments', 'regimes', 'band_hz', 'time_origin'}
    assert report['gap']['time_origin']['times'] == 'seconds since the start of each log'
    assert set(report['gap']['free_run_rms']) == {'z', 'theta', 'w', 'q', 'u'}
    assert set(report['gap']['equation_rms']) == {'surge', 'heave', 'pitch', 'sway', 'yaw'}
    assert {'rms_before', 'rms_after', 'shrink'} <= set(report['held_out'])
    for c in report['candidates']:
        assert {'effect', 'params', 'ci95', 'score', 'explained'} <= set(c)
        assert 0.0 <= c['explained'] <= 1.0
    assert report['candidates'][0]['effect'] == report['best']
    viable = [c['score'] for c in report['candidates'] if c['plausible'] and c['identifies']]
    assert viable[1:] == sorted(viable[1:], reverse=True)
    text = (tmp_path / 'gap' / 'report.md').read_text()
    assert 'Verdict: explained' in text and 'free_run_held_out.png' in text
    assert (tmp_path / 'gap' / 'free_run_held_out.png').stat().st_size > 1000


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, '-m', 'auv_gap.cli', *args],
                          capture_output=True, text=True, timeout=300)


def test_cli_bags_with_a_held_out_bag(vehicle, tmp_path: pathlib.Path) -> None:  # type: ignore
    """Two bags of the same vehicle; the second is held out whole."""
    bags = []
    for k, scenario in enumerate((synth.panel_scenario(), synth.Scenario(
            duration=360.0, z0=60.0, u0=2.0, depth=((0.0, 60.0), (120.0, 80.0)),
            thrust=((0.0, 55.0), (200.0, 100.0)),
            doublets=((40.0, 0.08, 3.0), (250.0, 0.1, 2.0))))):
        log = synth.simulate(vehicle, {'effects': EFFECT_FILES['buoyancy_offset']}, scenario,
                             seed=20 + k)
        bags.append(tmp_path / f'run{k}')
        synth.write_bag(bags[-1], log)
    out = tmp_path / 'out'
    res = _cli('--vehicle', str(A18M), str(bags[0]), str(bags[1]), '--holdout', str(bags[1]),
               '--out', str(out), '--no-plots', '--quiet')
    assert res.returncode == 0, res.stderr
    report = json.loads((out / 'report.json').read_text())
    assert report['verdict'] == 'explained' and report['best'] == 'buoyancy_offset'
    lo, hi = report['candidates'][0]['ci95']['dB']
    assert lo <= 30.0 <= hi
    details = json.loads((out / 'details.json').read_text())
    held = {w['log'] for w in details['windows'] if w['held_out']}
    assert held == {1}


def test_cli_errors(tmp_path: pathlib.Path) -> None:
    res = _cli('--vehicle', str(A18M), str(tmp_path / 'nope'), '--out', str(tmp_path / 'o'),
               '--quiet')
    assert res.returncode == 1
    assert res.stderr.startswith('error: ') and len(res.stderr.strip().splitlines()) == 1
    res = _cli('--vehicle', str(tmp_path / 'missing.yaml'), str(tmp_path / 'nope'),
               '--out', str(tmp_path / 'o'))
    assert res.returncode == 1 and 'missing.yaml' in res.stderr
    res = _cli('--vehicle', str(A18M), str(tmp_path / 'a'), '--holdout', str(tmp_path / 'b'),
               '--out', str(tmp_path / 'o'))
    assert res.returncode == 1 and 'not one of the bags' in res.stderr


def test_unknown_effect_is_an_error(vehicle) -> None:  # type: ignore[no-untyped-def]
    from auv_gap.errors import GapError
    log = synth.simulate(vehicle, None, synth.panel_scenario(), seed=1, noise=np.zeros(12))
    with pytest.raises(GapError, match="unknown effect 'waves'"):
        diagnose(vehicle, log.gap_logs(), effects=['waves'])


def test_ambiguous_without_the_separating_manoeuvre(vehicle) -> None:  # type: ignore
    """At one depth a buoyancy error and a depth-dependent buoyancy look alike: the diagnosis
    must say so and ask for a depth excursion."""
    flat = synth.Scenario(duration=600.0, z0=60.0, u0=2.0, depth=((0.0, 60.0),),
                          thrust=((0.0, 55.0), (200.0, 100.0), (400.0, 30.0)),
                          doublets=((40.0, 0.08, 3.0), (120.0, 0.1, 2.0), (250.0, 0.06, 4.0),
                                    (330.0, 0.1, 3.0), (450.0, 0.08, 3.0), (520.0, 0.1, 2.0)))
    log = synth.simulate(vehicle, {'effects': EFFECT_FILES['buoyancy_offset']}, flat, seed=2)
    r = diagnose(vehicle, log.gap_logs()).report
    assert r['verdict'] == 'ambiguous'
    assert {r['best'], *r['ambiguous_with']} == {'buoyancy_offset', 'buoyancy_depth'}
    assert r['suggested_manoeuvre'].startswith('depth excursion')
    assert r['held_out']['shrink'] >= 0.8
