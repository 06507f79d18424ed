"""One BLAS thread for the nodes (auv_contract.blas), unless the user names a count."""
from __future__ import annotations

import json
import os
import subprocess
import sys

from auv_contract.blas import BLAS_THREADS_VARIABLE, use_one_blas_thread

_PROBE = """
import json, sys
import numpy, scipy.linalg
from threadpoolctl import threadpool_info
from auv_contract.blas import use_one_blas_thread
before = [p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas']
named = use_one_blas_thread()
after = [p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas']
print(json.dumps({'before': before, 'after': after, 'named': named}))
"""


def _probe(count: str | None) -> dict[str, object]:
    """Run :data:`_PROBE` in a new process with ``count`` in the variable (None: unset)."""
    env = {k: v for k, v in os.environ.items() if k != BLAS_THREADS_VARIABLE}
    if count is not None:
        env[BLAS_THREADS_VARIABLE] = count
    out = subprocess.run([sys.executable, '-c', _PROBE], env=env, capture_output=True,
                         text=True, timeout=120, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_environment_of_processes_to_start() -> None:
    env: dict[str, str] = {}
    assert use_one_blas_thread(env) == '1'
    assert env == {BLAS_THREADS_VARIABLE: '1'}
    user = {BLAS_THREADS_VARIABLE: '3'}
    assert use_one_blas_thread(user) == '3'
    assert user == {BLAS_THREADS_VARIABLE: '3'}


def test_process_limited_from_the_call_on() -> None:
    got = _probe(None)
    assert got['named'] == '1'
    assert got['after'] and all(n == 1 for n in got['after'])  # type: ignore[union-attr]


def test_process_keeps_the_users_count() -> None:
    got = _probe('2')
    assert got['named'] == '2'
    assert got['before'] == got['after']
    assert all(n == 2 for n in got['after'])  # type: ignore[union-attr]
