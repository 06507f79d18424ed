"""Shared fixtures of the cross-package tests.

Every test that opens DDS participants runs its processes with an own ``ROS_DOMAIN_ID`` and
localhost-only discovery, so parallel runs never cross-talk.
"""
from __future__ import annotations

import os
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
A18M = ROOT / 'config' / 'a18m.yaml'


@pytest.fixture
def ros_env(_isolate_this_process: None) -> dict[str, str]:
    """Environment for a test's ROS processes: the test's own domain id (the same as the
    test process's participants), localhost discovery."""
    env = dict(os.environ)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env['RMW_IMPLEMENTATION'] = 'rmw_fastrtps_cpp'
    env['PYTHONUNBUFFERED'] = '1'
    return env


_counter = [0]


def ros_domain_id() -> int:
    """A DDS domain id in 1..100 unique to this test process and call (ids 0 and >101 avoided)."""
    _counter[0] += 1
    return 1 + (os.getpid() * 7 + _counter[0]) % 100


@pytest.fixture(autouse=True)
def _isolate_this_process(monkeypatch: pytest.MonkeyPatch) -> None:
    """Participants opened inside the test process itself are isolated too."""
    monkeypatch.setenv('ROS_DOMAIN_ID', str(ros_domain_id()))
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
