"""The simulator's actuator model and the gap diagnosis's agree.

The simulator integrates the plane with the vehicle (:func:`auv_sim.model.actuator_rates`
inside the model's RK4: angle limit, rate limit, first-order lag; a transport delay rounded up
to whole steps). The gap diagnosis drives the plane from logged commands apart from the
vehicle (:func:`auv_gap.kernel.actuator_series`: the lag integrated exactly, the rate limit as
a cap on each step's change, a continuous delay). Both are the same physics; what may differ,
worked out by hand for a step ``h`` and a lag ``tau``:

* in the lag alone, RK4's error per step is ``(h/tau)^5 / 120`` of the distance to the
  command (the Taylor remainder of ``exp(-h/tau)``): at ``h/tau = 0.2``, 2.7e-6 of it;
* where the rate limit takes over or lets go inside a step, the two place the switch
  differently within that step: at most one step's travel at the limit, ``rate h``;
* with commands on the step grid and a delay of whole steps, the delays are the same.
"""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest

from auv_gap.kernel import actuator_series
from auv_sim.environment import parse_environment
from auv_sim.params import load_vehicle
from auv_sim.simulator import Simulator, initial_state

ROOT = pathlib.Path(__file__).resolve().parents[1]

H = 0.02  # s, the simulator's step
TAU = 0.1  # s, plane lag
RATE = math.radians(10.0)  # rad/s, plane rate limit
DELAY = 0.2  # s, ten whole steps


def _commands() -> tuple[np.ndarray, np.ndarray]:
    """A BAR command every 0.5 s on the step grid: small steps (lag only) then large ones
    (rate limited), and the last ones beyond the angle limit."""
    t = np.arange(0.0, 20.0, 0.5)
    rng = np.random.default_rng(3)
    small = rng.uniform(-0.01, 0.01, t.size // 2)
    large = rng.choice([-0.3, 0.3], t.size - t.size // 2)
    values = np.r_[small, large]
    values[0] = 0.0  # the plane's initial position (before its first command both hold it)
    values[-6:] = 1.0  # beyond bar_max for the last 3 s: both stop at the limit
    return t, values


def _simulated(stamps: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    params = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    env = parse_environment({'effects': {
        'actuator_delay': {'bar': DELAY}, 'actuator_lag': {'bar_tau': TAU},
        'actuator_rate_limit': {'bar_rate': RATE}}}, 'test')
    x0 = initial_state()
    x0[12] = 0.0
    sim = Simulator(params, env, x0=x0, dt=H)
    out = np.empty(n)
    k_cmd = 0
    for j in range(n):
        while k_cmd < stamps.size and stamps[k_cmd] <= j * H + 1e-9:
            sim.command('bar', float(np.clip(values[k_cmd], *sim.limits('bar'))))
            k_cmd += 1
        out[j] = sim.x[12]
        sim.step(1)
    return out


def test_simulator_and_diagnosis_actuator_models_agree() -> None:
    params = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    stamps, values = _commands()
    n = int(21.0 / H)
    sim = _simulated(stamps, values, n)
    gap = actuator_series(0.0, H, n, stamps, values, DELAY, TAU, RATE, -params.bar_max,
                          params.bar_max, 0.0)
    diff = np.abs(sim - gap)
    lag_only = np.arange(n) * H < 10.0 + DELAY  # the small steps never reach the rate limit
    assert np.max(np.abs(np.diff(sim[lag_only]))) < RATE * H  # (they do not)
    assert np.max(diff[lag_only]) < 2.7e-6 * 0.02 * 10, np.max(diff[lag_only])
    assert np.max(diff) <= RATE * H * 1.0001, np.max(diff)
    assert np.max(np.abs(sim)) == pytest.approx(params.bar_max, abs=RATE * H)
