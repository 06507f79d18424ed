"""Synthetic gap logs (auv_gap.synth): flown by the project's pilot, written by simlog.

Oracles: the project's offline closed loop (:func:`auv_depth_lqr.closed_loop.run_closed_loop`)
flying the same depth change; a fresh pilot replayed on the logged states; the hand-written
open-loop schedule; the bag read back by the gap diagnosis's own reader.
"""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest

from auv_depth_lqr.closed_loop import run_closed_loop
from auv_gap import synth
from auv_gap.logs import load_bag
from auv_logs.simlog import SensorNoise
from auv_sim.params import VehicleParams, load_vehicle
from auv_sim.trim import VerticalPlane

A18M = pathlib.Path(__file__).resolve().parents[1] / 'config' / 'a18m.yaml'
Z0, Z1, U0 = 40.0, 44.0, 2.0  # m, m, m/s


@pytest.fixture(scope='module')
def vehicle() -> VehicleParams:
    return load_vehicle(A18M)


def _flight(vehicle: VehicleParams, duration: float,
            doublets: tuple[tuple[float, float, float], ...] = ()) -> synth.Scenario:
    thrust = VerticalPlane(vehicle).trim(U0, z=Z0).thrust
    return synth.Scenario(duration=duration, z0=Z0, u0=U0, depth=((0.0, Z0), (5.0, Z1)),
                          thrust=((0.0, thrust),), doublets=doublets)


def test_the_flight_is_the_projects_closed_loop(vehicle: VehicleParams) -> None:
    log = synth.simulate(vehicle, None, _flight(vehicle, 40.0), noise=np.zeros(12))
    run = run_closed_loop(vehicle, [(0.0, Z0), (5.0, Z1)], 40.0, z0=Z0, u0=U0,
                          pilot=synth.new_pilot(vehicle, 10.0))  # the design is done once
    np.testing.assert_array_equal(log.t, run.record.t)
    np.testing.assert_allclose(log.true_state, run.record.x[:, :12], rtol=0, atol=1e-12)
    times, bars = log.commands['bar']  # one command per control instant, and one at the end
    np.testing.assert_allclose(times[:-1], run.bar_t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(bars[:-1], run.bar, rtol=0, atol=1e-12)
    assert abs(log.true_state[-1, 2] - Z1) < 0.2  # the pilot brought it to the new depth


def test_doublets_are_added_to_the_pilots_command(vehicle: VehicleParams) -> None:
    doublets = ((10.0, 0.05, 2.0), (20.0, -0.08, 3.0))
    log = synth.simulate(vehicle, None, _flight(vehicle, 30.0, doublets), seed=4)
    pilot = synth.new_pilot(vehicle, 10.0)  # a fresh pilot of the same design
    times, bars = log.commands['bar']
    replayed = []
    for t in times:
        k = int(round(t / 0.02))
        x = log.state[k]
        assert log.t[k] == pytest.approx(t)
        pilot.set_depth_command(Z0 if t < 5.0 - 1e-9 else Z1)
        pilot.on_state(t, z=x[2], theta=x[4], w=x[8], q=x[10], u=x[6])
        replayed.append(pilot.command(t)[0])
    offset = bars - np.array(replayed)
    expected = np.zeros(len(times))
    expected[(times >= 10.0 - 1e-9) & (times < 12.0 - 1e-9)] = 0.05
    expected[(times >= 12.0 - 1e-9) & (times < 14.0 - 1e-9)] = -0.05
    expected[(times >= 20.0 - 1e-9) & (times < 23.0 - 1e-9)] = -0.08
    expected[(times >= 23.0 - 1e-9) & (times < 26.0 - 1e-9)] = 0.08
    inside = np.abs(bars) < vehicle.bar_max - 1e-9
    assert np.count_nonzero(inside) > 200  # of 301; the others are clipped to the limit
    np.testing.assert_allclose(offset[inside], expected[inside], rtol=0, atol=1e-12)


def test_open_loop_commands_follow_the_schedule(vehicle: VehicleParams) -> None:
    sc = synth.Scenario(duration=20.0, z0=Z0, u0=U0, depth=((0.0, Z0),),
                        thrust=((0.0, 50.0), (10.0, 70.0)), doublets=((4.0, 0.03, 1.0),),
                        pilot=False, bar_steps=((0.0, 0.0), (8.0, 0.02)))
    log = synth.simulate(vehicle, None, sc, seed=1)
    trim_bar = VerticalPlane(vehicle).trim(U0, z=Z0).bar
    times, bars = log.commands['bar']
    np.testing.assert_allclose(times, np.arange(201) * 0.1, atol=1e-9)
    by_hand = {0.0: 0.0, 4.0: 0.03, 4.5: 0.03, 5.0: -0.03, 6.0: 0.0, 8.0: 0.02, 19.9: 0.02}
    for t, offset in by_hand.items():
        k = int(round(t / 0.1))
        assert bars[k] == pytest.approx(trim_bar + offset, abs=1e-12), t
    np.testing.assert_allclose(log.commands['thrust'][0], [0.0, 10.0], atol=1e-9)
    np.testing.assert_allclose(log.commands['thrust'][1], [50.0, 70.0])


def test_sensor_noise_is_the_one_definition(vehicle: VehicleParams) -> None:
    log = synth.simulate(vehicle, None, _flight(vehicle, 60.0), seed=2)
    err = log.state - log.true_state
    sigma = np.std(err, axis=0)
    # 3001 samples: the sample standard deviation is within 5 % of the truth (over 2.7 sigma)
    np.testing.assert_allclose(sigma, SensorNoise.realistic().sigmas(), rtol=0.05)
    assert SensorNoise.realistic().sigmas()[2] == 0.02                 # depth [m]
    assert SensorNoise.realistic().sigmas()[4] == pytest.approx(math.radians(0.1))


def test_the_bag_reads_back_as_logged(vehicle: VehicleParams, tmp_path: pathlib.Path) -> None:
    sc = synth.Scenario(duration=30.0, z0=Z0, u0=U0, depth=((0.0, Z0),),
                        thrust=((0.0, 55.0),), doublets=((5.0, 0.05, 2.0),))
    log = synth.simulate(vehicle, {'effects': {'actuator_delay': {'bar': 0.3}}}, sc, seed=3)
    t0_ns = 1_000_123_000_000  # 1000.123 s: float seconds still resolve 1 ns
    n = synth.write_bag(tmp_path / 'log.mcap', log, t0_ns=t0_ns)
    assert n == log.t.size + sum(len(v[0]) for v in log.commands.values())
    (piece,) = load_bag(tmp_path / 'log.mcap')
    np.testing.assert_allclose(piece.t - t0_ns * 1e-9, log.t, atol=1e-6)
    np.testing.assert_allclose(piece.state, log.state, atol=1e-9)
    for ch, (times, values) in log.commands.items():  # as sent, not as applied after delay
        np.testing.assert_allclose(piece.commands[ch][0] - t0_ns * 1e-9, times, atol=1e-6)
        np.testing.assert_array_equal(piece.commands[ch][1], values)
