"""Round trips through the simulator: a run of config/a18m.yaml written as other vehicles log
it (ROS 2 MCAP and sqlite3 bags with Odometry ENU/FLU + Imu + FluidPressure, a ROS 1 bag, a
bag with a custom fin message, a 2 Hz text log in degrees and centimetres with two
elevators), written with rosbags' own writers, read back through the bundled maps.

Oracles: the simulator's measured state and applied commands (NED/FRD, SI). The bags carry
the state as float64 through exact conversions (quaternions, pressure with rho g), so the
contract arrays must equal it to rounding (1e-9); the text log prints 10 significant
digits. Identification: the coefficients from the converted logs (25 Hz and 10 Hz) must lie
inside the 95 % intervals of those from the simulator's own contract bag (50 Hz); and
``auv ident --map`` on the original log must give exactly what ``auv ident`` gives on the
bag ``auv import`` wrote.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import math
import pathlib
from typing import Any

import numpy as np
import pytest

from auv_bag import read_arrays
from auv_gap import cli as gap_cli
from auv_ident import cli
from auv_logs import cli as import_cli
from auv_logs import synth
from auv_logs.contract_bag import contract_arrays, read_provenance
from auv_logs.importer import ContractLog, import_log
from auv_logs.mapping import load_map
from auv_logs.simlog import SensorNoise, write_record
from auv_sim.missions import load_mission, run_mission
from auv_sim.params import load_vehicle
from auv_sim.simulator import Record

ROOT = pathlib.Path(__file__).resolve().parents[1]
A18M = ROOT / 'config' / 'a18m.yaml'
MAPS = ROOT / 'config' / 'maps'
T0 = 1.7e9           # the synthetic logs' clock [s]
NOISE_SEED = 7       # fixed once, not chosen for passing
KINDS = {            # log -> (map, writer options)
    'mcap': ('ros2_odometry_imu_pressure', {'storage': 'mcap', 'every': 2}),
    'db3': ('ros2_odometry_imu_pressure', {'storage': 'sqlite3', 'every': 2}),
    'ros1.bag': ('ros1_odometry_pressure', {'ros1': True, 'every': 2}),
    'custom': ('ros2_custom_fins', {'custom_fins': True, 'every': 2}),
}


@pytest.fixture(scope='module')
def run() -> tuple[Record, np.ndarray]:
    """The pitch mission (50 Hz samples) and seeded navigation-grade sensor noise."""
    rec = run_mission(load_vehicle(A18M), load_mission('pitch'))
    rng = np.random.default_rng(NOISE_SEED)
    noise = rng.standard_normal((len(rec.t), 12)) * SensorNoise.realistic().sigmas()
    return rec, noise


@pytest.fixture(scope='module')
def logs(run: tuple[Record, np.ndarray], tmp_path_factory: pytest.TempPathFactory
         ) -> dict[str, pathlib.Path]:
    rec, noise = run
    root = tmp_path_factory.mktemp('third_party')
    out = {}
    for name, (_, opts) in KINDS.items():
        synth.write_ros2(root / name, rec, noise=noise, t0=T0, **opts)
        out[name] = root / name
    synth.write_ros2(root / 'mcap10', rec, noise=noise, t0=T0, every=5)
    out['mcap10'] = root / 'mcap10'
    synth.write_text(root / 'log.txt', rec, noise=noise, every=25)
    out['text'] = root / 'log.txt'
    return out


def _truth_at(rec: Record, noise: np.ndarray, t: np.ndarray) -> np.ndarray:
    i = np.searchsorted(rec.t, t - 1e-6)
    assert np.allclose(rec.t[i], t, atol=1e-6)
    out: np.ndarray = (rec.measured[:, :12] + noise)[i]
    return out


def _angle_diff(a: np.ndarray) -> np.ndarray:
    out: np.ndarray = (a + math.pi) % (2 * math.pi) - math.pi
    return out


def _import(logs: dict[str, pathlib.Path], name: str) -> ContractLog:
    return import_log(load_map(MAPS / f'{KINDS[name][0]}.yaml'), logs[name])


@pytest.mark.parametrize('name', list(KINDS))
def test_bag_kinds_give_the_simulated_state_and_commands(
        name: str, logs: dict[str, pathlib.Path], run: tuple[Record, np.ndarray]) -> None:
    rec, noise = run
    log = _import(logs, name)
    # every second 50 Hz sample, less the surfaced start (z < 0.5 m: none in this mission)
    assert len(log.t) == len(rec.t[::2])
    truth = _truth_at(rec, noise, log.t - T0)
    err = log.state - truth
    err[:, 3:6] = _angle_diff(err[:, 3:6])
    assert np.max(np.abs(err)) < 1e-9
    assert log.report['derived'] == []
    # commands: every change of the applied commands, as logged, at its own stamp
    change = np.flatnonzero(np.any(np.diff(rec.cmd, axis=0, prepend=np.nan) != 0, axis=1))
    for c, ch in enumerate(('bar', 'helm', 'thrust')):
        st, va = log.commands[ch]
        assert np.allclose(st - T0, rec.t[change], atol=1e-6)
        assert np.allclose(va, rec.cmd[change, c], rtol=1e-12, atol=1e-12), ch


def test_text_log_2hz_degrees_centimetres_two_elevators(
        logs: dict[str, pathlib.Path], run: tuple[Record, np.ndarray]) -> None:
    rec, noise = run
    log = import_log(load_map(MAPS / 'text_2hz_deg_cm.yaml'), logs['text'])
    assert len(log.t) == len(rec.t[::25])
    truth = _truth_at(rec, noise, log.t)
    for k in (2, 3, 4, 5, 6):     # z, phi, theta, psi, u: logged (10 significant digits)
        d = log.state[:, k] - truth[:, k]
        if k == 5:
            d = _angle_diff(d)
        assert np.max(np.abs(d)) < 1e-8 * max(1.0, float(np.max(np.abs(truth[:, k])))), k
    derived = ' '.join(log.report['derived'])
    for sig in ('q:', 'w:', 'v:', 'x:', 'y:'):
        assert sig in derived
    assert log.report['signals']['q'] == 'derived'
    _, va = log.commands['bar']       # (port - starboard) / 2 of (bar, -bar) in degrees
    assert np.allclose(va, rec.cmd[::25, 0], atol=1e-10)
    _, va = log.commands['thrust']    # rpm through T = k n |n|
    assert np.allclose(va, rec.cmd[::25, 2], rtol=1e-8)


def _ident(args: list[str], out: pathlib.Path) -> dict[str, Any]:
    parser = argparse.ArgumentParser()
    cli.add_arguments(parser)
    ns = parser.parse_args([*args, '--out', str(out), '--equations', 'heave', 'pitch',
                            '--no-nelder-mead'])
    assert cli.run(ns) == 0
    report: dict[str, Any] = json.loads((out / 'report.json').read_text())
    return report


@pytest.fixture(scope='module')
def contract_ident(run: tuple[Record, np.ndarray], tmp_path_factory: pytest.TempPathFactory
                   ) -> dict[str, Any]:
    """Identification from the simulator's contract bag (50 Hz, same noisy state)."""
    rec, noise = run
    root = tmp_path_factory.mktemp('contract')
    rec_noisy = Record(rec.t, rec.x, rec.measured.copy(), rec.cmd, rec.wrench)
    rec_noisy.measured[:, :12] += noise
    write_record(root / 'bag', rec_noisy, forces=False)
    report = _ident([str(root / 'bag')], root / 'out')
    report['bag'] = str(root / 'bag')
    return report


@pytest.mark.parametrize('name', ['mcap', 'mcap10', 'ros1.bag', 'custom'])
def test_coefficients_from_converted_logs_within_contract_intervals(
        name: str, logs: dict[str, pathlib.Path], contract_ident: dict[str, Any],
        tmp_path: pathlib.Path) -> None:
    map_name = KINDS.get(name, KINDS['mcap'])[0]
    report = _ident([str(logs[name]), '--map', str(MAPS / f'{map_name}.yaml')], tmp_path)
    assert report['source'] == 'motion'
    assert report['imports'][0]['derived'] == []
    for coef, ref in contract_ident['coefficients'].items():
        lo, hi = ref['ci95']
        assert hi - lo > 0
        assert lo <= report['coefficients'][coef]['value'] <= hi, (coef, ref)


def test_import_writes_a_contract_bag_with_provenance_and_ident_map_equals_it(
        logs: dict[str, pathlib.Path], tmp_path: pathlib.Path) -> None:
    map_path = MAPS / 'ros2_custom_fins.yaml'
    bag = tmp_path / 'imported'
    parser = argparse.ArgumentParser()
    import_cli.add_arguments(parser)
    assert import_cli.run(parser.parse_args([str(logs['custom']), '--map', str(map_path),
                                             '--out', str(bag)])) == 0
    prov = read_provenance(bag)
    assert prov is not None
    assert prov['map'] == map_path.read_text()
    mcap = next(logs['custom'].glob('*.mcap'))
    assert prov['sources'][str(mcap)] == hashlib.sha256(mcap.read_bytes()).hexdigest()
    # the bag holds exactly the arrays the direct path feeds to the identification
    direct = contract_arrays(import_log(load_map(map_path), logs['custom']))
    read = read_arrays(bag, list(direct))
    for topic, arr in direct.items():
        for field in arr.dtype.names or ():
            assert np.array_equal(read[topic][field], arr[field]), (topic, field)
    a = _ident([str(bag)], tmp_path / 'a')
    b = _ident([str(logs['custom']), '--map', str(map_path)], tmp_path / 'b')
    for coef, c in a['coefficients'].items():
        assert b['coefficients'][coef]['value'] == c['value']
        assert b['coefficients'][coef]['ci95'] == c['ci95']


def test_text_log_at_2hz_intervals_cover_the_vehicle_file(
        logs: dict[str, pathlib.Path], tmp_path: pathlib.Path) -> None:
    """At 2 Hz with q, w derived by central differences, the heave and pitch coefficients
    are still identified; their (wider) 95 % intervals hold the simulated vehicle's values
    (one noise realisation, seed fixed beforehand)."""
    report = _ident([str(logs['text']), '--map', str(MAPS / 'text_2hz_deg_cm.yaml')],
                    tmp_path)
    base = load_vehicle(A18M)
    for coef, c in report['coefficients'].items():
        lo, hi = c['ci95']
        assert lo <= base.values[coef] <= hi, (coef, c)
    assert any(line.startswith('q: derived') for line in report['imports'][0]['derived'])


def _gap(args: list[str], out: pathlib.Path) -> dict[str, Any]:
    parser = argparse.ArgumentParser()
    gap_cli.add_arguments(parser)
    assert gap_cli.run(parser.parse_args([*args, '--vehicle', str(A18M), '--out', str(out),
                                          '--no-plots', '--quiet'])) == 0
    report: dict[str, Any] = json.loads((out / 'report.json').read_text())
    return report


def test_gap_on_original_log_with_map_equals_gap_on_imported_bag(
        logs: dict[str, pathlib.Path], contract_ident: dict[str, Any],
        tmp_path: pathlib.Path) -> None:
    map_path = MAPS / 'ros2_odometry_imu_pressure.yaml'
    parser = argparse.ArgumentParser()
    import_cli.add_arguments(parser)
    assert import_cli.run(parser.parse_args([str(logs['mcap10']), '--map', str(map_path),
                                             '--out', str(tmp_path / 'bag')])) == 0
    direct = _gap([str(logs['mcap10']), '--map', str(map_path)], tmp_path / 'a')
    imported = _gap([str(tmp_path / 'bag')], tmp_path / 'b')
    # the same windows, named after the log each comes from (the original, the bag)
    for seg in direct['gap']['segments']:
        assert seg.pop('log') == 'mcap10'
    for seg in imported['gap']['segments']:
        assert seg.pop('log') == str(tmp_path / 'bag')
    for report, name in ((direct, 'mcap10'), (imported, str(tmp_path / 'bag'))):
        origins = report['gap']['time_origin']['logs']
        assert list(origins) == [name]
        report['gap']['time_origin']['logs'] = list(origins.values())
    assert direct == imported
    # the simulated vehicle is the model: no gap, as on the simulator's own 50 Hz bag
    contract = _gap([contract_ident['bag']], tmp_path / 'c')
    assert direct['verdict'] == contract['verdict'] == 'no_gap'


def test_columnar_and_per_message_readers_agree(logs: dict[str, pathlib.Path]) -> None:
    """MCAP storage is read by the columnar decoder; rosbags' per-message deserialisation
    (the second, independent path) must give the same stamps and values bit for bit."""
    from auv_logs.readers import read_bag

    req = {'/odom': ['pose.pose.orientation.w', 'twist.twist.linear.x'],
           '/fins': ['port_elevator', 'lower_rudder'], '/thruster/rpm': ['data']}
    fast = read_bag(logs['custom'], req, fast=True)
    slow = read_bag(logs['custom'], req, fast=False)
    for topic in req:
        assert fast[topic].stamp_kind == slow[topic].stamp_kind
        assert np.array_equal(fast[topic].stamps, slow[topic].stamps)
        for path in req[topic]:
            assert np.array_equal(fast[topic].columns[path], slow[topic].columns[path])
    assert slow['/thruster/rpm'].stamp_kind == 'log'     # Float64 has no header


def test_what_a_log_without_sway_cannot_identify_is_said(
        logs: dict[str, pathlib.Path], tmp_path: pathlib.Path) -> None:
    """The text log has no sway speed and no position: v is assumed 0, so sway and yaw are
    not identifiable and surge would be biased in turns; they are left out and said so, and
    asking for sway is one error naming the cause."""
    parser = argparse.ArgumentParser()
    cli.add_arguments(parser)
    ns = parser.parse_args([str(logs['text']), '--map', str(MAPS / 'text_2hz_deg_cm.yaml'),
                            '--out', str(tmp_path / 'a'), '--no-nelder-mead'])
    assert cli.run(ns) == 0
    report = json.loads((tmp_path / 'a' / 'report.json').read_text())
    assert sorted(report['not_identifiable']) == ['surge', 'sway', 'yaw']
    assert sorted(report['coefficients']) == ['CMuq', 'CMuw', 'CZuq', 'CZuw']
    ns = parser.parse_args([str(logs['text']), '--map', str(MAPS / 'text_2hz_deg_cm.yaml'),
                            '--out', str(tmp_path / 'b'), '--equations', 'sway'])
    from auv_ident.errors import NotIdentifiableError
    with pytest.raises(NotIdentifiableError, match=r'^sway: v was not logged \(assumed 0 in '
                                                   r'the import\); log it '):
        cli.run(ns)


def test_irregular_text_log_resampled_only_when_the_map_asks(
        run: tuple[Record, np.ndarray], tmp_path: pathlib.Path) -> None:
    """Rows at 2 Hz +- 0.1 s with 3 % dropped. With ``time: {grid: 0.5}`` the state is on a
    uniform 0.5 s grid, said so in the report; linear interpolation between noisy samples
    cannot raise white noise, so the resampled depth stays within the logged noise (0.02 m
    rms) of the simulator's noise-free depth at the grid times."""
    rec, noise = run
    rng = np.random.default_rng(11)
    rows = np.arange(5, len(rec.t) - 5, 25)
    rows = rows + rng.integers(-5, 6, len(rows))
    rows = rows[rng.random(len(rows)) > 0.03]
    synth.write_text(tmp_path / 'jitter.txt', rec, noise=noise, rows=rows)
    text = (MAPS / 'text_2hz_deg_cm.yaml').read_text()
    as_logged = import_log(load_map(MAPS / 'text_2hz_deg_cm.yaml'), tmp_path / 'jitter.txt')
    assert np.allclose(as_logged.t, rec.t[rows], rtol=0, atol=1e-9)
    assert as_logged.report['resampled'] == 'no: state at its own stamps'
    (tmp_path / 'grid.yaml').write_text(text.replace(
        'time: {column: time, unit: s}', 'time: {column: time, unit: s, grid: 0.5}'))
    log = import_log(load_map(tmp_path / 'grid.yaml'), tmp_path / 'jitter.txt')
    assert log.report['resampled'].startswith('state of each segment resampled onto a '
                                              'uniform 0.5 s grid by linear interpolation')
    assert np.allclose(np.diff(log.t), 0.5)
    i = np.searchsorted(rec.t, log.t - 1e-6)
    assert np.allclose(rec.t[i], log.t, atol=1e-9)
    assert float(np.sqrt(np.mean((log.state[:, 2] - rec.measured[i, 2]) ** 2))) < 0.02


def test_ident_on_an_imported_2hz_bag_knows_what_the_import_assumed(
        logs: dict[str, pathlib.Path], tmp_path: pathlib.Path) -> None:
    """The bag `auv import` wrote from the 2 Hz text log carries the import's marks in its
    provenance: `auv ident` on it leaves out what the assumed v cannot support, as `auv ident
    --map` does on the text log, with the same coefficients."""
    map_path = MAPS / 'text_2hz_deg_cm.yaml'
    parser = argparse.ArgumentParser()
    import_cli.add_arguments(parser)
    assert import_cli.run(parser.parse_args([str(logs['text']), '--map', str(map_path),
                                             '--out', str(tmp_path / 'bag')])) == 0
    parser = argparse.ArgumentParser()
    cli.add_arguments(parser)
    reports = []
    for args, out in (([str(tmp_path / 'bag')], 'a'),
                      ([str(logs['text']), '--map', str(map_path)], 'b')):
        assert cli.run(parser.parse_args([*args, '--out', str(tmp_path / out),
                                          '--no-nelder-mead'])) == 0
        reports.append(json.loads((tmp_path / out / 'report.json').read_text()))
    bag, direct = reports
    assert sorted(bag['not_identifiable']) == sorted(direct['not_identifiable']) == [
        'surge', 'sway', 'yaw']
    for name, c in direct['coefficients'].items():
        for key in ('value', 'std_error', 'ci95'):
            assert bag['coefficients'][name][key] == c[key], (name, key)
