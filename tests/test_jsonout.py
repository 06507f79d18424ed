"""Strict JSON out (``auv_contract.jsonout``): what no strict parser refuses.

Oracle: RFC 8259 (no NaN, no Infinity), checked with a strict parse that refuses the
constants Python's ``json`` would otherwise accept.
"""
from __future__ import annotations

import json
import math
import pathlib
import subprocess
import sys

import numpy as np
import pytest

from auv_contract.jsonout import dumps, plain


def _strict(text: str) -> object:
    def refuse(name: str) -> float:
        raise ValueError(f'not strict JSON: {name}')
    return json.loads(text, parse_constant=refuse)


def test_non_finite_numbers_become_null_numpy_becomes_python() -> None:
    doc = {'settling_time': math.nan, 'ratio': math.inf, 1: (np.float64(-math.inf), 2.5),
           'n': np.int64(7), 'ok': np.bool_(True), 'a': np.array([1.0, np.nan]),
           'name': 'x'}
    assert plain(doc) == {'settling_time': None, 'ratio': None, '1': [None, 2.5], 'n': 7,
                          'ok': True, 'a': [1.0, None], 'name': 'x'}
    assert _strict(dumps(doc)) == plain(doc)
    assert type(plain(np.int64(7))) is int and type(plain(np.float32(0.5))) is float


def test_python_json_would_write_nan() -> None:
    """The oracle itself: the default writer's text is refused by the strict parse."""
    with pytest.raises(ValueError, match='not strict JSON: NaN'):
        _strict(json.dumps({'x': math.nan}))


def test_auv_run_of_a_step_that_does_not_settle_prints_strict_json(
        ros_env: dict[str, str], tmp_path: pathlib.Path) -> None:
    """A 10 -> 30 m step flown for 5 s does not settle: its settling time is null."""
    res = subprocess.run([sys.executable, '-m', 'auv_bringup.cli', 'run', '--depth', '30',
                          '--initial-depth', '10', '--duration', '5', '--out',
                          str(tmp_path / 'r')], env=ros_env, capture_output=True, text=True,
                         timeout=240)
    assert res.returncode == 0, res.stderr
    summary = _strict(res.stdout)
    assert isinstance(summary, dict)
    assert summary['metrics']['settling_time'] is None
    assert summary['metrics']['settling_over_kinematic_bound'] is None
    assert summary['metrics']['peak_pitch_deg'] > 0.0
