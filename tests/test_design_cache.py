"""The start-up cache: the pilot's design and the simulator's initial trim kept on disk.

Oracles: a design and a trim computed afresh with the cache off (never stored numbers); keys
compared between inputs that differ in one item.
"""
from __future__ import annotations

import dataclasses
import json
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from conftest import A18M

from auv_depth_lqr import pilot as pilot_module
from auv_depth_lqr.controller import PlaneState
from auv_depth_lqr.design_cache import DESIGN_KIND, DESIGN_PACKAGES, design_inputs
from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.pilot import PilotSettings, build_controller
from auv_sim import disk_cache
from auv_sim.disk_cache import CACHE_ENV, entry_key, source_digest
from auv_sim.params import load_vehicle
from auv_sim.sim_settings import SimSettings, build_setup
from auv_sim.trim import TRIM_KIND, VerticalPlane, cached_trim

FIELDS = ('speeds', 'K', 'w_e', 'theta_e', 'bar_e', 'F', 'P', 'D', 'Q', 'R')


@pytest.fixture(scope='module')
def params():  # type: ignore[no-untyped-def]
    return load_vehicle(A18M)


@pytest.fixture(scope='module')
def fresh(params):  # type: ignore[no-untyped-def]
    """The A18M pilot's controller designed with the cache off."""
    return build_fresh(params)


def _entries(root: pathlib.Path) -> list[pathlib.Path]:
    return sorted(root.glob(f'{DESIGN_KIND}-*.json'))


def _assert_same_design(a, b) -> None:  # type: ignore[no-untyped-def]
    for name in FIELDS:
        assert np.array_equal(getattr(a.design, name), getattr(b.design, name)), name
    assert a.design.Ts == b.design.Ts
    assert a.governor == b.governor  # surge length included


def _inputs(params, settings: PilotSettings | None = None,  # type: ignore[no-untyped-def]
            q_scale: float = 1.0):
    s = settings or PilotSettings()
    return design_inputs(params, s.speeds, q_scale * np.eye(5), np.eye(1), s.Ts)


def test_the_key_changes_with_every_input(params) -> None:
    key = entry_key(DESIGN_KIND, _inputs(params), DESIGN_PACKAGES)
    assert key == entry_key(DESIGN_KIND, _inputs(params), DESIGN_PACKAGES)
    changed = params.replace(CM0=params.CM0 * 1.01)
    assert entry_key(DESIGN_KIND, _inputs(changed), DESIGN_PACKAGES) != key
    faster = PilotSettings(rate_hz=20.0)
    assert entry_key(DESIGN_KIND, _inputs(params, faster), DESIGN_PACKAGES) != key
    grid = PilotSettings(speeds=(1.0, 2.0))
    assert entry_key(DESIGN_KIND, _inputs(params, grid), DESIGN_PACKAGES) != key
    heavier = _inputs(params, q_scale=2.0)
    assert entry_key(DESIGN_KIND, heavier, DESIGN_PACKAGES) != key
    assert entry_key('trim', _inputs(params), DESIGN_PACKAGES) != key


def test_the_key_changes_with_the_code(tmp_path, monkeypatch) -> None:
    package = tmp_path / 'cache_probe_pkg'
    package.mkdir()
    (package / '__init__.py').write_text('')
    (package / 'design.py').write_text('GAIN = 1.0\n')
    monkeypatch.syspath_prepend(str(tmp_path))
    before = source_digest(('cache_probe_pkg',))
    (package / 'design.py').write_text('GAIN = 2.0\n')
    source_digest.cache_clear()
    try:
        assert source_digest(('cache_probe_pkg',)) != before
    finally:
        source_digest.cache_clear()
        sys.modules.pop('cache_probe_pkg', None)


def test_a_cached_design_equals_a_fresh_one(params, fresh, tmp_path, monkeypatch) -> None:
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    first = build_controller(params, PilotSettings())  # computed, stored
    assert len(_entries(tmp_path)) == 1
    _assert_same_design(first, fresh)

    again = build_fresh(params)

    def no_trim(*_args: object) -> None:
        raise AssertionError('the design was computed again')

    monkeypatch.setattr(pilot_module, 'trimmable_speeds', no_trim)
    second = build_controller(params, PilotSettings())  # read from the cache
    _assert_same_design(second, fresh)
    # and the controllers fly alike: the same commands on the same states
    state = PlaneState(z=12.0, theta=0.02, w=0.05, q=0.0, u=1.9)
    assert [second.step(state, 20.0) for _ in range(5)] == \
        [again.step(state, 20.0) for _ in range(5)]


def build_fresh(params):  # type: ignore[no-untyped-def]
    """A controller designed afresh (cache off)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(CACHE_ENV, '')
        return build_controller(params, PilotSettings())


@pytest.mark.parametrize('damage', ['garbage', 'truncated', 'payload', 'shape', 'nan'])
def test_a_damaged_entry_is_ignored_and_rewritten(params, fresh, tmp_path, monkeypatch,
                                                  damage: str) -> None:
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    build_controller(params, PilotSettings())
    (entry,) = _entries(tmp_path)
    text = entry.read_text()
    doc = json.loads(text)
    if damage == 'garbage':
        entry.write_bytes(b'\x00\xffnot json')
    elif damage == 'truncated':
        entry.write_text(text[:len(text) // 2])
    elif damage == 'payload':  # a number changed, the checksum not
        doc['payload']['K'][0][0] += 1.0
        entry.write_text(json.dumps(doc))
    else:  # checksum made to match: the decoder's checks refuse it
        if damage == 'shape':
            doc['payload']['K'] = doc['payload']['K'][:-1]
        else:
            doc['payload']['bar_e'][3] = float('nan')
        doc['payload_sha256'] = disk_cache.payload_digest(doc['payload'])
        entry.write_text(json.dumps(doc))
    again = build_controller(params, PilotSettings())
    _assert_same_design(again, fresh)
    assert json.loads(entry.read_text()) == json.loads(text)  # rewritten whole


def test_the_cache_off_or_unwritable(params, fresh, tmp_path, monkeypatch) -> None:
    monkeypatch.setenv(CACHE_ENV, '')
    _assert_same_design(build_controller(params, PilotSettings()), fresh)
    assert disk_cache.cache_dir() is None
    blocker = tmp_path / 'a_file'
    blocker.write_text('')
    monkeypatch.setenv(CACHE_ENV, str(blocker / 'cache'))  # below a file: cannot be made
    _assert_same_design(build_controller(params, PilotSettings()), fresh)


def test_default_directory(monkeypatch, tmp_path) -> None:
    monkeypatch.delenv(CACHE_ENV, raising=False)
    monkeypatch.setenv('XDG_CACHE_HOME', str(tmp_path))
    assert disk_cache.cache_dir() == tmp_path / 'auv'
    monkeypatch.delenv('XDG_CACHE_HOME')
    monkeypatch.setenv('HOME', str(tmp_path))
    assert disk_cache.cache_dir() == tmp_path / '.cache' / 'auv'


def test_a_failed_design_is_not_stored(params, tmp_path, monkeypatch) -> None:
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    with pytest.raises(DesignError, match='no trim'):
        build_controller(params, dataclasses.replace(PilotSettings(), speeds=(0.01, 0.02)))
    assert _entries(tmp_path) == []


def test_the_simulators_initial_trim(params, tmp_path, monkeypatch) -> None:
    monkeypatch.setenv(CACHE_ENV, '')
    fresh_trim = VerticalPlane(params).trim(1.7, z=25.0)
    settings = SimSettings(initial_speed=1.7, initial_depth=25.0)
    fresh_x0 = build_setup(settings).x0
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    assert cached_trim(params, 1.7, z=25.0) == fresh_trim  # computed, stored
    (entry,) = tmp_path.glob(f'{TRIM_KIND}-*.json')

    def no_solve(*_args: object, **_kwargs: object) -> None:
        raise AssertionError('the trim was solved again')

    with monkeypatch.context() as mp:
        mp.setattr(VerticalPlane, 'trim', no_solve)
        assert cached_trim(params, 1.7, z=25.0) == fresh_trim
        assert np.array_equal(build_setup(settings).x0, fresh_x0)
    assert cached_trim(params, 1.7, z=25.5) != fresh_trim  # another depth, another entry
    entry.write_text(entry.read_text().replace('"theta": ', '"theta": "x'))
    assert cached_trim(params, 1.7, z=25.0) == fresh_trim  # damaged: solved again


_PROBE = '''
import sys
from auv_sim.params import load_vehicle
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
pilot = DepthPilot.for_vehicle(load_vehicle(sys.argv[1]), PilotSettings(learn=sys.argv[2] == "1"))
loaded = [m for m in ("numba", "scipy.optimize") if m in sys.modules]
if loaded:
    from auv_sim.model import wrenches
    loaded.append(f"{len(wrenches.signatures)} signatures")
print(" ".join(loaded))
'''


def test_what_a_start_from_the_cache_loads(tmp_path) -> None:
    """From a warm cache a pilot loads neither numba nor scipy.optimize; one that learns
    loads both, and the compiled force kernel, at start (its control steps use them)."""
    env = dict(os.environ, **{CACHE_ENV: str(tmp_path)})

    def probe(learn: str) -> str:
        out = subprocess.run([sys.executable, '-c', _PROBE, A18M, learn], env=env, check=True,
                             capture_output=True, text=True, timeout=300)
        return out.stdout.strip()

    probe('0')  # the design computed and stored
    assert probe('0') == ''
    numba, optimize, compiled, _ = probe('1').split()
    assert (numba, optimize) == ('numba', 'scipy.optimize') and int(compiled) >= 1


def test_the_least_recently_used_entries_beyond_the_cap_are_removed(tmp_path,
                                                                     monkeypatch) -> None:
    """Five values of a kind with room for three: the three kept are the last two written
    and the first, read (used) after the second was written; another kind is not touched."""
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    monkeypatch.setattr(disk_cache, 'MAX_ENTRIES', 3)
    computed: list[int] = []

    def value(n: int, kind: str = 'test') -> int:
        def compute() -> int:
            computed.append(n)
            return n
        return disk_cache.cached(kind, {'n': n}, ('auv_sim',), compute, int, int)

    value(0, 'other')
    for n, stamp in ((1, 100.0), (2, 200.0)):
        value(n)
        path = disk_cache.entry_path('test', entry_key('test', {'n': n}, ('auv_sim',)))
        assert path is not None
        os.utime(path, (stamp, stamp))  # written long ago, one after the other
    assert value(1) == 1 and computed == [0, 1, 2]  # read from the cache: now the newest
    for n in (3, 4):
        value(n)
    assert len(list(tmp_path.glob('test-*.json'))) == 3
    assert len(list(tmp_path.glob('other-*.json'))) == 1
    assert [value(n) for n in (1, 3, 4)] == [1, 3, 4] and computed == [0, 1, 2, 3, 4]
    assert value(2) == 2 and computed[-1] == 2  # the one removed is computed again
