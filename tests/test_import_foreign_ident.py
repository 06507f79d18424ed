"""Vendor logs whose rows are irregular (jittered stamps, dropped rows) and whose command
columns are logged at those rows: the gap diagnosis must still see that the commands are
known only at the rows (``auv_gap.logs.sampled_commands``) and take them as linear
between rows, whether the state was resampled by ``from_arrays`` or by the map's
``time.grid``. Before the fix the rows were compared with the uniform grid the state was
interpolated onto, the commands were held at each row for a whole row (half a row late on
average) and a clean 15-minute 5 Hz log came out ``unexplained`` in ``auv gap --map``.

The logs are written here with plain Python; the truth is known by construction: the command
is a ramp ``c(t) = SLOPE (t - T0)``, so its value at any instant is known exactly.
"""

from __future__ import annotations

import pathlib

import numpy as np

from auv_gap.logs import (
    first_order_hold,
    from_arrays,
    from_contract_arrays,
    measurement_weighting,
    sampled_commands,
)
from auv_logs.contract_bag import contract_arrays
from auv_logs.importer import import_log
from auv_logs.mapping import load_map

T0 = 1.7e9
PERIOD = 0.2
SLOPE = 0.001  # rad/s: the logged BAR command is SLOPE (t - T0)


def _rows(n: int = 1500, seed: int = 3) -> np.ndarray:
    """Row stamps [s]: 5 Hz with +-10 % jitter and 2 % of the rows dropped."""
    rng = np.random.default_rng(seed)
    t = T0 + PERIOD * (np.arange(n) + rng.uniform(-0.1, 0.1, n))
    return t[rng.random(n) > 0.02]


def _held(st: np.ndarray, va: np.ndarray, t: np.ndarray) -> np.ndarray:
    return va[np.clip(np.searchsorted(st, t, side='right') - 1, 0, None)]


def _check_linear(pieces: list, rows: np.ndarray) -> None:
    for piece in pieces:
        if piece.linear_between_rows:  # from_contract_arrays has applied the hold already
            log = piece
        else:
            assert set(sampled_commands([piece])) == {'bar', 'thrust'}
            log = first_order_hold(piece)
        assert log.linear_between_rows == ('bar', 'thrust')
        assert any('logged only at the rows' in n for n in log.notes)
        # between rows the reconstruction follows the ramp: no mean lag (held: half a row)
        t = np.linspace(log.t[5], log.t[-5], 4000)
        err = _held(*log.commands['bar'], t) - SLOPE * (t - T0)
        held_err = _held(rows, SLOPE * (rows - T0), t) - SLOPE * (t - T0)
        assert abs(np.mean(held_err)) > 0.4 * SLOPE * PERIOD
        assert abs(np.mean(err)) < 0.1 * SLOPE * PERIOD


def test_jittered_rows_commands_taken_as_logged_at_rows() -> None:
    rows = _rows()
    state = np.zeros((rows.size, 12))
    state[:, 2] = 50.0
    state[:, 6] = 2.0
    cmds = {'bar': (rows, SLOPE * (rows - T0)), 'helm': (rows, 0.0 * rows),
            'thrust': (rows, 55.0 + 0.0 * rows)}
    _check_linear(from_arrays('jittered', rows, state, cmds), rows)
    # commands with their own stamps at another rate are no row samples
    own = T0 + np.arange(0.0, rows[-1] - T0, 1 / 7)
    other = dict(cmds, bar=(own, SLOPE * (own - T0)))
    assert 'bar' not in sampled_commands(from_arrays('own', rows, state, other))
    # a regular 10 Hz log at epoch stamps over 15 minutes (the median step of float stamps
    # at 1.7e9 s is 0.09999990 s: a grid from it drifts 0.9 ms from the rows): commands at
    # the rows are row samples; a 10 Hz controller's own stamps 3 ms off the rows are not
    reg = T0 + 0.1 * np.arange(9000)
    zeros = np.zeros((reg.size, 12))
    pieces = from_arrays('regular', reg, zeros,
                         {'bar': (reg, 0.0 * reg), 'thrust': (reg, 0.0 * reg)})
    assert not pieces[0].irregular_rows
    assert set(sampled_commands(pieces)) == {'bar', 'thrust'}
    ctl = reg - 0.003
    pieces = from_arrays('controller', reg, zeros,
                         {'bar': (ctl, 0.0 * ctl), 'thrust': (ctl, 0.0 * ctl)})
    assert sampled_commands(pieces, min_period=0.0) == []


def test_text_log_resampled_by_map_grid(tmp_path: pathlib.Path) -> None:
    rows = _rows()
    log = tmp_path / 'vendor.csv'
    with open(log, 'w') as f:
        f.write('time,depth_m,pitch_deg,heading_deg,speed_ms,elev_deg,rpm\n')
        for t in rows:
            f.write(f'{t:.4f},{50.0 + 0.01 * np.sin(t - T0):.4f},0.5,10.0,2.0,'
                    f'{np.degrees(SLOPE * (t - T0)):.8f},1990.0\n')
    mp = tmp_path / 'map.yaml'
    mp.write_text('format: auv-log-map/1\nkind: text\n'
                  'text: {delimiter: comma, header: true}\n'
                  f'time: {{column: time, unit: s, grid: {PERIOD}}}\n'
                  'signals:\n'
                  '  z: {column: depth_m, unit: m, frame: NED}\n'
                  '  theta: {column: pitch_deg, unit: deg, frame: NED/FRD}\n'
                  '  psi: {column: heading_deg, unit: deg, frame: NED}\n'
                  '  u: {column: speed_ms, unit: m/s, frame: FRD}\n'
                  '  bar: {column: elev_deg, unit: deg}\n'
                  '  thrust: {column: rpm, unit: rpm, law: {kind: quadratic, coefficient: 0.05}}\n'
                  'segments: {surface_depth: 0.5, min_duration: 20}\n')
    imported = import_log(load_map(mp), log)
    assert not imported.report['resampled'].startswith('no')
    pieces = from_contract_arrays(imported.name, contract_arrays(imported), [imported.report])
    assert all(p.irregular_rows for p in pieces)
    # the thrust column: 0.05 (1990 / 60)^2 N at every row
    assert np.allclose(pieces[0].commands['thrust'][1], 0.05 * (1990.0 / 60.0) ** 2)
    _check_linear(pieces, rows)


def test_limit_names_only_the_differenced_rates() -> None:
    """A vendor log with a gyro (p q r logged) and no DVL: only the heave velocity comes from
    differences; the report must not say the pitch rate does, nor ask to log it."""
    rows = T0 + PERIOD * np.arange(500)
    state = np.zeros((rows.size, 12))
    cmds = {'bar': (rows, 0.0 * rows), 'thrust': (rows, 0.0 * rows)}
    w_only = from_arrays('gyro', rows, state, cmds,
                         origins={'w': 'derived: from the depth rate'})
    text = ' '.join(measurement_weighting(w_only).report['limits'])
    assert 'heave velocity comes from depth differenced at the 0.2 s' in text
    assert 'pitch rate' not in text and 'log the heave velocity (DVL)' in text
    both = from_arrays('no gyro', rows, state, cmds,
                       origins={'w': 'derived: from the depth rate',
                                'q': 'derived: from the pitch rate'})
    text = ' '.join(measurement_weighting(both).report['limits'])
    assert 'heave velocity and pitch rate come from depth and pitch differenced' in text
    assert 'log the pitch rate (gyro) and the heave velocity (DVL)' in text
