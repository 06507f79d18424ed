"""Shared fixtures of the cross-package tests.

Every test that opens DDS participants runs its processes with a DDS domain id that no other
test, in this run or in any other process on the machine, holds at the same time, and with
localhost-only discovery, so parallel runs never cross-talk.

Domain ids are reserved with an exclusive ``flock`` on ``<tmp>/auv-ros-domains/<id>.lock``:
the lock is held for as long as the test (or, for :func:`ros_domain_id`, the test process)
runs, and the kernel releases it when the holder exits, however it exits. Among the free ids
the one released longest ago is taken, so a domain is not reused while processes of its last
test may still be shutting down.
"""
from __future__ import annotations

import fcntl
import importlib.util
import os
import pathlib
import sys
import tempfile
import time
from collections.abc import Iterator
from types import ModuleType
from typing import IO

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
A18M = ROOT / 'config' / 'a18m.yaml'

#: DDS domain ids handed out: 1..101, the range whose Fast DDS ports (7400 + 250 id + ...)
#: stay below Linux's ephemeral ports; 0, the default domain, is left to other ROS users.
DOMAIN_IDS = range(1, 102)
LOCK_DIR = pathlib.Path(tempfile.gettempdir()) / 'auv-ros-domains'
#: how long to wait for a free id when every id is held (s)
RESERVE_TIMEOUT = 120.0


def load_bench(name: str) -> ModuleType:
    """The benchmark module ``bench/bench_<name>.py`` (its cases and judges, for a test that
    flies a few of a benchmark's cases)."""
    path = ROOT / 'bench' / f'bench_{name}.py'
    spec = importlib.util.spec_from_file_location(f'bench_{name}', path)
    assert spec is not None and spec.loader is not None, path
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(path.parent))  # the benchmarks import their own ``timing``
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(path.parent))
    return module

class DomainReservation:
    """An exclusive hold on one DDS domain id, across processes, until :meth:`release`."""

    def __init__(self, domain_id: int, handle: IO[str]) -> None:
        self.domain_id = domain_id
        self._handle: IO[str] | None = handle

    def release(self) -> None:
        """Let go of the id; its lock file's time records when (for least-recently-used)."""
        if self._handle is None:
            return
        os.utime(self._handle.fileno())
        self._handle.close()    # closing the descriptor drops the flock
        self._handle = None


def reserve_domain_id(timeout: float = RESERVE_TIMEOUT) -> DomainReservation:
    """Reserve a DDS domain id no other process holds, the one released longest ago first.

    Raises
    ------
    TimeoutError
        every id in :data:`DOMAIN_IDS` stayed held for ``timeout`` seconds.
    """
    LOCK_DIR.mkdir(parents=True, exist_ok=True)
    deadline = time.monotonic() + timeout
    while True:
        paths = [LOCK_DIR / f'{i}.lock' for i in DOMAIN_IDS]
        for path in paths:
            path.open('a').close()      # creates a missing lock file; leaves its time alone
        for path in sorted(paths, key=lambda p: p.stat().st_mtime):
            handle = path.open('a')
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                handle.close()
                continue
            os.utime(handle.fileno())   # taken now: last in line, even if its holder dies
            return DomainReservation(int(path.stem), handle)
        if time.monotonic() > deadline:
            raise TimeoutError(f'no free DDS domain id in {DOMAIN_IDS} for {timeout} s '
                               f'(locks in {LOCK_DIR})')
        time.sleep(0.2)


_process_reservations: list[DomainReservation] = []


def ros_domain_id() -> int:
    """A DDS domain id reserved for the rest of this test process (for module-scoped
    fixtures); the kernel releases it when the process exits."""
    reservation = reserve_domain_id()
    _process_reservations.append(reservation)
    return reservation.domain_id


@pytest.fixture
def ros_env(_isolate_this_process: None) -> dict[str, str]:
    """Environment for a test's ROS processes: the test's own domain id (the same as the
    test process's participants), localhost discovery."""
    env = dict(os.environ)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env['RMW_IMPLEMENTATION'] = 'rmw_fastrtps_cpp'
    env['PYTHONUNBUFFERED'] = '1'
    return env


@pytest.fixture(autouse=True)
def _isolate_this_process(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Participants opened inside the test process itself are isolated too: the test holds
    its domain id from set-up to tear-down."""
    reservation = reserve_domain_id()
    monkeypatch.setenv('ROS_DOMAIN_ID', str(reservation.domain_id))
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    try:
        yield
    finally:
        reservation.release()
