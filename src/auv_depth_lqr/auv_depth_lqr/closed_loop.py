"""Offline closed loop: the simulator and the depth pilot, with no ROS graph.

The sequence is the lockstep protocol of the node graph (see :mod:`auv_sim.node`): at each
control instant ``t_k = k Ts`` the measured state goes to the pilot, its BAR command is
applied at ``t_k`` and held while the simulator advances ``Ts``. A lockstep graph run and this
function therefore produce the same trajectory.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from auv_depth_lqr.errors import InvalidInputError
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_sim.environment import Environment
from auv_sim.params import VehicleParams
from auv_sim.simulator import Record, Simulator, record
from auv_sim.trim import VerticalPlane


@dataclasses.dataclass
class ClosedLoopRun:
    """A closed-loop run: the simulator record (every ``sample_period``), the pilot's BAR
    commands at the control instants (``bar_t`` [s], ``bar`` [rad]) and the depth commands
    (``z_ref_t`` [s], ``z_ref`` [m])."""

    record: Record
    bar_t: np.ndarray
    bar: np.ndarray
    z_ref_t: np.ndarray
    z_ref: np.ndarray


def run_closed_loop(params: VehicleParams, depth_commands: Sequence[tuple[float, float]],
                    duration: float, z0: float = 40.0, u0: float = 2.0,
                    environment: Environment | None = None,
                    settings: PilotSettings | None = None, sample_period: float = 0.02,
                    pilot: DepthPilot | None = None,
                    speed_time_constant: float | None = None) -> ClosedLoopRun:
    """Fly depth commands ``[(t [s], z [m]), ...]`` from a trim at ``z0`` [m], ``u0`` [m/s].

    The vehicle starts trimmed for the nominal model in the water it is in (its trim
    velocities through the water plus the current, see :meth:`auv_sim.trim.Trim.state`);
    ``environment`` makes the "real" vehicle differ. The speed loop is the vehicle's, outside
    this toolkit: by default the thrust is held at its trim value; with
    ``speed_time_constant`` [s] a proportional surge-speed hold stands for it, thrust
    ``T_trim + (m - Xudot) (u0 - u) / speed_time_constant`` [N] within the propeller's
    limits (``u`` the measured surge), as on a vehicle that holds its speed in a climb or
    dive (a positively buoyant vehicle with its thrust held slows down in a dive).
    """
    settings = settings or PilotSettings()
    pilot = pilot or DepthPilot.for_vehicle(params, settings)
    trim = VerticalPlane(params).trim(u0, z=z0)
    sim = Simulator(params, environment, x0=trim.state(environment))
    ts = settings.Ts
    steps_per_control = int(round(ts / sim.dt))
    steps_per_sample = int(round(sample_period / sim.dt))
    if steps_per_control * sim.dt - ts > 1e-9 or steps_per_control % steps_per_sample:
        raise ValueError(f'control period {ts} s must be a multiple of the sample period '
                         f'{sample_period} s, itself a multiple of dt = {sim.dt} s')
    if speed_time_constant is not None and not speed_time_constant > 0.0:
        raise ValueError(f'speed_time_constant must be > 0 s, got {speed_time_constant!r}')
    speed_gain = 0.0 if speed_time_constant is None else \
        (params.m - params.Xudot) / speed_time_constant
    n_control = int(math.floor(duration / ts + 1e-9))
    commands = sorted(depth_commands)
    samples, bar_t, bars, zr_t, zr = [], [], [], [], []
    for _k in range(n_control):
        t = sim.t
        while commands and commands[0][0] <= t + 1e-9:
            _, z_cmd = commands.pop(0)
            try:
                pilot.set_depth_command(z_cmd)
                zr_t.append(t)
                zr.append(z_cmd)
            except InvalidInputError:
                pass
        x = sim.measured_state()
        pilot.on_state(t, z=x[2], theta=x[4], w=x[8], q=x[10], u=x[6])
        bar, _ = pilot.command(t)
        sim.command('bar', bar)
        if speed_gain:
            thrust = trim.thrust + speed_gain * (u0 - x[6])
            sim.command('thrust', min(max(thrust, params.thrust_min), params.thrust_max))
        bar_t.append(t)
        bars.append(bar)
        for _ in range(steps_per_control // steps_per_sample):
            samples.append(sim.sample())
            sim.step(steps_per_sample)
    samples.append(sim.sample())
    return ClosedLoopRun(record=record(samples), bar_t=np.array(bar_t), bar=np.array(bars),
                         z_ref_t=np.array(zr_t), z_ref=np.array(zr))
