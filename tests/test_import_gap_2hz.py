"""The gap diagnosis on an imported 2 Hz vendor text log: what was derived or assumed is
carried into the diagnosis and its report, and an effect present gives the right answer or
an honest one, never a confident wrong ``explained``.

Oracles: the rules of :func:`auv_gap.logs.measurement_weighting` worked by hand (which
free-run channels and equations a derived or assumed signal removes), and a plant whose
effect is known (a buoyancy offset of 20 N, the diagnosis is not told). The panel over
effects and log rates is in ``bench/bench_poor_data.py``.
"""
from __future__ import annotations

import pathlib

import numpy as np
import pytest

from auv_gap.logs import from_arrays, import_origins, measurement_weighting

ROOT = pathlib.Path(__file__).resolve().parents[1]
MAP = ROOT / 'config' / 'maps' / 'text_2hz_deg_cm.yaml'


def dive():  # type: ignore[no-untyped-def]
    """A 5-minute closed-loop flight: depth changes of 20 and 15 m, three thrust levels and
    five BAR doublets."""
    from auv_gap import synth
    return synth.Scenario(duration=300.0, z0=60.0, u0=2.0,
                          depth=((0.0, 60.0), (60.0, 80.0), (200.0, 65.0)),
                          thrust=((0.0, 55.0), (150.0, 100.0), (280.0, 40.0)),
                          doublets=((30.0, 0.08, 3.0), (110.0, 0.1, 2.0), (170.0, 0.06, 5.0),
                                    (240.0, 0.1, 3.0), (270.0, 0.08, 4.0)))


def _piece(origins: dict[str, str], period: float = 0.5) -> list:  # type: ignore[type-arg]
    t = np.arange(0.0, 120.0, period)
    state = np.zeros((t.size, 12))
    state[:, 2] = 10.0
    state[:, 6] = 2.0
    cmds = {'bar': (t, np.zeros(t.size)), 'thrust': (np.array([0.0]), np.array([50.0]))}
    return from_arrays('log', t, state, cmds, origins=origins)


def test_derived_and_assumed_signals_leave_out_what_they_would_count_twice() -> None:
    # the text log's import: q, w, p, r derived; v assumed; phi logged
    report = {'derived': ['q: derived from the attitude', 'w: derived from the depth rate',
                          'v: not logged and no position to derive it from: assumed 0 m/s'],
              'origins': {'q': 'derived', 'w': 'derived', 'v': 'assumed', 'z': 'measured'}}
    origins = import_origins([report])
    assert origins == {'q': 'derived: derived from the attitude',
                       'w': 'derived: derived from the depth rate',
                       'v': 'assumed: not logged and no position to derive it from: assumed '
                            '0 m/s'}
    wt = measurement_weighting(_piece(origins))
    assert set(wt.channels) == {'w', 'q', 'v', 'r'}
    assert set(wt.equations) == {'depth_kinematics', 'sway', 'yaw'}
    assert wt.report['assumed'] == {'v': origins['v'].split(': ', 1)[1]}
    assert 'Left out so that no measurement counts twice' in wt.statement
    # every state measured (a contract bag): nothing left out, nothing said
    plain = measurement_weighting(_piece({}))
    assert plain.channels == () and plain.equations == () and plain.statement == ''
    # u and v from position fixes are kept (over ground), w from the depth rate is not
    fixes = measurement_weighting(_piece({'u': 'derived: position', 'v': 'derived: position',
                                          'w': 'derived: depth'}))
    assert fixes.channels == ('w',) and fixes.equations == ('depth_kinematics',)
    # a slow log whose commands sit on the rows: the timing limit is said
    assert any('logged only at the state rows' in x for x in
               measurement_weighting(_piece({'q': 'derived: x'})).report['limits'])


def test_a_10hz_log_is_slow_whatever_the_rounding_of_its_stamps() -> None:
    """Hand-worked: rows every 0.1 s from 0.7 s differ by 0.09999999999999998 s in binary,
    from 1000 s by 0.10000000000002274 s, from an epoch of 1.7e9 s by 0.09999990463256836 s;
    all these logs, commands at every row, have them taken as linear between rows; a 20 Hz
    log's are held."""
    from auv_gap.logs import first_order_hold, sampled_commands
    for t0, period, slow in ((0.7, 0.1, True), (1000.0, 0.1, True), (1.7e9, 0.1, True),
                             (0.7, 0.05, False)):
        t = t0 + np.arange(200) * period
        state = np.zeros((t.size, 12))
        cmds = {'bar': (t, np.sin(t)), 'thrust': (t, np.full(t.size, 50.0))}
        piece = from_arrays('log', t, state, cmds)[0]
        assert (sampled_commands([piece]) == ['bar', 'thrust']) is slow, (t0, period)
        assert first_order_hold(piece).linear_between_rows == (('bar', 'thrust') if slow
                                                               else ())


def test_unknown_origin_is_an_error() -> None:
    from auv_gap.errors import GapError
    with pytest.raises(GapError, match='origins given for unknown state signals'):
        _piece({'depth': 'derived: z'})


def test_2hz_text_log_with_a_buoyancy_offset(tmp_path: pathlib.Path) -> None:
    """A 5-minute closed-loop flight of a plant 20 N heavy, logged as the vendor's 2 Hz text
    log (q, w derived; v assumed): the import's marks reach the report, and the verdict names
    the buoyancy offset with 20 N inside its interval, or makes no confident claim."""
    from auv_gap import synth
    from auv_gap.diagnose import diagnose
    from auv_gap.logs import from_contract_arrays
    from auv_gap.report import write_report
    from auv_logs import synth as realsynth
    from auv_logs.contract_bag import contract_arrays
    from auv_logs.importer import import_log
    from auv_logs.mapping import load_map
    from auv_sim.params import load_vehicle

    vehicle = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    log = synth.simulate(vehicle, {'effects': {'buoyancy_offset': {'dB': 20.0}}}, dive(),
                         seed=41)
    path = tmp_path / 'dive.txt'
    realsynth.write_text(path, realsynth.record_of(log.t, log.state, log.commands), every=25)
    imported = import_log(load_map(MAP), path)
    pieces = from_contract_arrays('dive', contract_arrays(imported), [imported.report])
    diag = diagnose(vehicle, pieces, window=60.0)
    r = diag.report
    md = (write_report(diag, tmp_path / 'gap', plots=False).parent / 'report.md').read_text()
    assert '## Signals not measured' in md
    assert '| v | assumed | not logged and no position to derive it from: assumed 0 m/s |' in md
    assert set(r['signals']['left_out']['free_run']) == {'w', 'q', 'v', 'r'}
    assert r['signals']['assumed'].keys() == {'v'}
    assert 'Not measured:' in r['statement']
    named = set(r['best'].split('+')) if r['best'] else set()
    if r['verdict'] == 'explained':
        assert named == {'buoyancy_offset'}, r['statement']
        lo, hi = next(c for c in r['candidates'] if c['effect'] == r['best'])['ci95']['dB']
        assert lo <= 20.0 <= hi
    else:
        assert r['verdict'] in ('partly_explained', 'unexplained', 'ambiguous'), r['verdict']
