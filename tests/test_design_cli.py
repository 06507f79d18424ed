"""``auv design`` as a user runs it: a subprocess printing JSON, or one error line."""
from __future__ import annotations

import json
import subprocess
import sys
from typing import Any

import numpy as np
import pytest
from conftest import A18M

TIMEOUT = 60.0  # s, deadline for one command


def auv_design(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, '-m', 'auv_bringup.cli', 'design', *args],
                          capture_output=True, text=True, timeout=TIMEOUT, check=False)


def design_json(*args: str) -> dict[str, Any]:
    proc = auv_design('--vehicle', str(A18M), *args)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)  # type: ignore[no-any-return]


def test_design_at_2_m_s_reproduces_the_report_trim() -> None:
    """Report 4.3/4.4 (full kinematics): theta_e = 0.00689 rad, BAR_e = -0.08367 rad."""
    d = design_json('--speed', '2.0')
    assert d['trim']['theta'] == pytest.approx(0.00689, rel=0.02)
    assert d['trim']['bar'] == pytest.approx(-0.08367, rel=0.02)
    assert d['states'] == ['w', 'q', 'z', 'theta', 'xi'] and d['kinematics'] == 'full'
    assert np.shape(d['A']) == (5, 5) and np.shape(d['B']) == (5, 1)
    assert np.shape(d['K']) == (1, 5)
    assert d['controllability']['rank'] == 5
    assert len(d['poles_continuous']) == len(d['poles_discrete']) == 5
    assert all(np.hypot(p['re'], p['im']) < 1.0 for p in d['poles_discrete'])
    assert d['min_damping'] >= 0.7


def test_design_with_the_reports_simplified_kinematics_and_weights() -> None:
    """Report 4.2 (z_dot = w): theta_e = -0.19917 rad, BAR_e = -0.03048 rad."""
    d = design_json('--speed', '2.0', '--kinematics', 'w', '--weights', 'report_5',
                    '--Ts', '0.1')
    assert d['trim']['theta'] == pytest.approx(-0.19917, rel=0.02)
    assert d['trim']['bar'] == pytest.approx(-0.03048, rel=0.02)
    assert d['weights'] == 'report_5'
    assert np.diag(d['Q']).tolist() == [1e8, 1e8, 350.0, 450.0, 1e-5] and d['R'] == [[1e8]]


@pytest.mark.parametrize(('args', 'message'), [
    (('--vehicle', 'no/such/vehicle.yaml'),
     'error: cannot read vehicle file no/such/vehicle.yaml'),
    (('--vehicle', str(A18M), '--speed', '0.2'), 'error: trim at u0 = 0.2 m/s needs BAR'),
    (('--vehicle', str(A18M), '--speed', '-1'), 'error: --speed must be a finite forward speed'),
    (('--vehicle', str(A18M), '--Ts', '0'), 'error: --Ts must be a finite sample period'),
])
def test_bad_input_gives_one_error_line_and_exit_1(args: tuple[str, ...], message: str) -> None:
    proc = auv_design(*args)
    assert proc.returncode == 1
    assert proc.stdout == ''
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(message), proc.stderr
