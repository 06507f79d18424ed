"""Integral action removes a steady offset: a vertical current the design model does not know.

A vertical current of +-0.1 m/s (down / up, auv_sim.environment ``current``) needs the
vehicle to climb or dive through the water at 0.1 m/s to hold its depth: a steady pitch
offset of a few degrees that only the integrator can supply. Goal (issue: worst steady-state
depth error < 0.1 m): the depth over the last 20 s of a 200 s run within 0.01 m of the
command, pitch within the limit + 2 deg. Independent oracle: the command itself.
"""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest

from auv_depth_lqr.closed_loop import run_closed_loop
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_sim.environment import Environment
from auv_sim.params import load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]
THETA_MAX = math.radians(25.0)
#: vehicle -> (u0 [m/s], z0, z1 [m])
CASES = {'a18m': (2.0, 40.0, 10.0), 'remus100': (1.5, 20.0, 10.0),
         'npsauv2': (1.5, 20.0, 10.0)}


@pytest.mark.parametrize('down', [0.1, -0.1])
@pytest.mark.parametrize('name', sorted(CASES))
def test_vertical_current_leaves_no_offset(name: str, down: float) -> None:
    params = load_vehicle(ROOT / 'config' / f'{name}.yaml')
    u0, z0, z1 = CASES[name]
    settings = PilotSettings()
    run = run_closed_loop(params, [(0.0, z1)], 200.0, z0=z0, u0=u0,
                          environment=Environment(effects={'current': {'down': down}}),
                          settings=settings, pilot=DepthPilot.for_vehicle(params, settings),
                          speed_time_constant=2.0)
    rec = run.record
    last = rec.t > rec.t[-1] - 20.0
    assert np.max(np.abs(rec.x[last, 2] - z1)) < 0.01
    assert np.max(np.abs(rec.x[:, 4])) <= THETA_MAX + math.radians(2.0)


def _integrator_on(depth, seconds: float) -> list[tuple[float, float]]:  # type: ignore[no-untyped-def]
    """The A18M pilot's integrator [m s] at each sample of a measured depth ``depth(t)`` [m]
    with the pitch, heave and surge at the 2 m/s trim and the command 10 m (the first
    sample is at 10 m, so the reference is at rest there); the disturbance estimate is off,
    so that the integrator's own rule is what acts."""
    import dataclasses

    from auv_depth_lqr.controller import DepthController, PlaneState

    base = DepthPilot.for_vehicle(load_vehicle(ROOT / 'config' / 'a18m.yaml')).controller
    ctl = DepthController(base.design, base.limits, base.Ts,
                          dataclasses.replace(base.governor, disturbance_estimate=False))
    op = ctl.design.at(2.0)
    out = []
    for k in range(int(round(seconds / ctl.Ts)) + 1):
        t = k * ctl.Ts
        ctl.step(PlaneState(depth(t), op.theta_e, op.w_e, 0.0, 2.0), 10.0)
        out.append((t, ctl.integrator))
    return out


def test_the_integrator_takes_a_stalled_offset_but_not_a_turn_round() -> None:
    """Outside ``integrate_within`` (0.2 m) the integrator runs only on a stalled vehicle:
    one whose low-passed depth rate has stayed within ``stall_speed`` (0.01 m/s) for
    ``stall_time`` (5 s). Held 0.25 m below the command, the 2.5 m/s step of the rate at
    the jump decays below 0.01 m/s after ~8 s (time constant 5.1 s), so integration starts
    ~5 s later and runs at 0.25 m s per s: 4.0-4.5 m s at 30 s (from 8 s without the
    dwell: 5.5). A vehicle swinging 0.25-1.05 m below the command (period 30 s) passes
    through a zero depth rate at each turn; it has not stalled and nothing is integrated."""
    held = dict(_integrator_on(lambda t: 10.0 if t == 0.0 else 10.25, 30.0))
    assert held[12.0] == 0.0
    assert 4.0 <= held[30.0] <= 4.5
    swing = _integrator_on(lambda t: 10.0 if t == 0.0 else
                           10.65 + 0.4 * math.cos(2.0 * math.pi * t / 30.0), 60.0)
    assert max(abs(xi) for _, xi in swing) == 0.0
