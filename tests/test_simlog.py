"""The one simulated-log writer (auv_logs.simlog.write_record): commands as sent or as
applied, a log-time offset, seeded sensor noise; read back with auv_bag's reader."""
from __future__ import annotations

import pathlib

import numpy as np
import pytest

from auv_bag import read_arrays
from auv_logs.errors import LogError
from auv_logs.simlog import SensorNoise, write_record
from auv_sim.environment import Environment
from auv_sim.params import VehicleParams, load_vehicle
from auv_sim.simulator import Record, Simulator, record
from auv_sim.trim import VerticalPlane

A18M = pathlib.Path(__file__).resolve().parents[1] / 'config' / 'a18m.yaml'
DELAY = 0.3  # s, plane transport delay of the "real" vehicle


@pytest.fixture(scope='module')
def vehicle() -> VehicleParams:
    return load_vehicle(A18M)


def _delayed_run(vehicle: VehicleParams) -> tuple[Record, tuple[np.ndarray, np.ndarray]]:
    """10 s at 50 Hz; BAR commands sent at 2 s and 5 s, acting 0.3 s later."""
    trim = VerticalPlane(vehicle).trim(2.0, z=20.0)
    sim = Simulator(vehicle, Environment(effects={'actuator_delay': {'bar': DELAY}}),
                    x0=trim.state())
    sent = (np.array([0.0, 2.0, 5.0]), np.array([trim.bar, trim.bar + 0.05, trim.bar - 0.05]))
    samples = []
    for k in range(501):
        t = sim.t
        for ts, value in zip(*sent):
            if abs(t - ts) < 1e-9:
                sim.command('bar', float(value))
        samples.append(sim.sample())
        if k < 500:
            sim.step(2)
    return record(samples), sent


def test_commands_as_sent_or_as_applied(vehicle: VehicleParams,
                                        tmp_path: pathlib.Path) -> None:
    rec, sent = _delayed_run(vehicle)
    t0_ns = 42 * 10**9 + 7
    write_record(tmp_path / 'sent.mcap', rec, forces=False, sent_commands={'bar': sent},
                 t0_ns=t0_ns)
    write_record(tmp_path / 'applied.mcap', rec, forces=False)
    topics = ['/auv/state', '/auv/bar_command']
    a = read_arrays(tmp_path / 'sent.mcap', topics)
    b = read_arrays(tmp_path / 'applied.mcap', topics)
    np.testing.assert_allclose(a['/auv/state']['t'], 42.0 + rec.t, atol=1e-8)
    np.testing.assert_allclose(a['/auv/bar_command']['t'], 42.0 + sent[0], atol=1e-8)
    np.testing.assert_array_equal(a['/auv/bar_command']['value'], sent[1])
    # as applied: the simulator's plane set-point changes DELAY later (first sample at 0 s)
    np.testing.assert_allclose(b['/auv/bar_command']['t'], [0.0, 2.0 + DELAY, 5.0 + DELAY],
                               atol=1e-8)
    np.testing.assert_array_equal(b['/auv/bar_command']['value'], sent[1])


def test_noise_is_seeded_with_the_declared_levels(vehicle: VehicleParams,
                                                  tmp_path: pathlib.Path) -> None:
    rec, _ = _delayed_run(vehicle)
    noise = SensorNoise(position=0.1, angle=0.01, velocity=0.05, rate=0.02)
    for name in ('a', 'b'):
        write_record(tmp_path / name, rec, forces=False, noise=noise, seed=5)
    write_record(tmp_path / 'c', rec, forces=False, noise=noise, seed=6)
    fields = ('z', 'theta', 'w', 'q')
    st = {k: read_arrays(tmp_path / k, ['/auv/state'])['/auv/state'] for k in 'abc'}
    err = np.column_stack([st['a'][f] - rec.measured[:, i]
                           for f, i in zip(fields, (2, 4, 8, 10))])
    np.testing.assert_array_equal(st['a']['z'], st['b']['z'])       # same seed, same log
    assert not np.array_equal(st['a']['z'], st['c']['z'])           # another seed
    # 501 samples: a sample standard deviation within 12 % of the truth (2.7 sigma)
    np.testing.assert_allclose(np.std(err, axis=0), [0.1, 0.01, 0.05, 0.02], rtol=0.12)


def test_unknown_command_channel_is_named(vehicle: VehicleParams,
                                         tmp_path: pathlib.Path) -> None:
    rec, sent = _delayed_run(vehicle)
    with pytest.raises(LogError, match="unknown channel 'rudder'"):
        write_record(tmp_path / 'x.mcap', rec, sent_commands={'rudder': sent})
