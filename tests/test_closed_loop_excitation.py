"""Closed-loop identification flights (`run_closed_loop(excitation=...)`): the excitation is
flown on top of the pilot, and the BAR it records replays open loop to the same trajectory
(the two are different code paths: the closed loop and the mission runner)."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import A18M

from auv_depth_lqr.closed_loop import run_closed_loop
from auv_sim.missions import parse_mission, run_mission
from auv_sim.params import load_vehicle


def test_excitation_replays_open_loop_to_the_same_flight() -> None:
    params = load_vehicle(A18M)
    excitation = [(2.0, 'bar', 0.05), (4.0, 'bar', -0.05), (6.0, 'bar', 0.0),
                  (3.0, 'thrust', 60.0), (5.0, 'helm', 0.02), (7.0, 'helm', 0.0)]
    run = run_closed_loop(params, [(0.0, 20.0)], 10.0, z0=20.0, u0=2.0,
                          excitation=excitation)
    plain = run_closed_loop(params, [(0.0, 20.0)], 10.0, z0=20.0, u0=2.0)
    # before the first event the flights are the same; the offset shows in the BAR at 2 s
    k = int(np.searchsorted(run.bar_t, 2.0))
    assert np.array_equal(run.bar[:k], plain.bar[:k])
    assert run.bar[k] == pytest.approx(plain.bar[k] + 0.05, abs=1e-12)
    events = [[float(t), 'bar', float(b)] for t, b in zip(run.bar_t, run.bar)]
    events += [[t, c, v] for t, c, v in excitation if c != 'bar']
    mission = parse_mission({'duration': 10.0, 'initial': {'z': 20.0, 'u': 2.0},
                             'events': events})
    replay = run_mission(params, mission)
    assert np.max(np.abs(replay.x - run.record.x)) == pytest.approx(0.0, abs=1e-9)
    assert np.ptp(replay.x[:, 11]) > 0.0  # the helm pulse turned it
    assert np.ptp(replay.x[:, 6]) > 0.01  # the thrust step changed the speed


@pytest.mark.parametrize(('excitation', 'speed_tau', 'needle'), [
    ([(1.0, 'rudder', 0.1)], None, "channel 'rudder'"),
    ([(1.0, 'thrust', 50.0)], 2.0, 'both command the thrust'),
])
def test_bad_excitation_is_refused(excitation, speed_tau, needle: str) -> None:  # type: ignore
    with pytest.raises(ValueError, match=needle):
        run_closed_loop(load_vehicle(A18M), [(0.0, 20.0)], 1.0, z0=20.0, u0=2.0,
                        excitation=excitation, speed_time_constant=speed_tau)


@pytest.mark.parametrize('noise', [[0.01] * 11, [0.01] * 11 + [float('nan')],
                                   [0.01] * 11 + [-0.01]])
def test_bad_sensor_noise_is_refused(noise: list[float]) -> None:
    with pytest.raises(ValueError, match='sensor_noise must be 12 finite'):
        run_closed_loop(load_vehicle(A18M), [(0.0, 10.0)], 1.0, z0=10.0,
                        sensor_noise=noise)


def test_sensor_noise_reaches_the_pilot_alone() -> None:
    """Noise on the depth only (2 cm): the pilot's commands move with it, the same seed
    gives the same flight, and the record keeps the simulator's own (noise-free) depth:
    holding its trim, the vehicle's recorded depth stays within a few centimetres while the
    commands differ from the noise-free flight's."""
    params = load_vehicle(A18M)
    sigmas = [0.0] * 12
    sigmas[2] = 0.02  # z [m]
    runs = [run_closed_loop(params, [(0.0, 10.0)], 10.0, z0=10.0, u0=1.5,
                            sensor_noise=noise, seed=3)
            for noise in (None, sigmas, sigmas)]
    assert np.array_equal(runs[1].bar, runs[2].bar)
    assert np.max(np.abs(runs[1].bar - runs[0].bar)) > 1e-4  # [rad]
    assert np.max(np.abs(runs[1].record.x[:, 2] - 10.0)) < 0.05
