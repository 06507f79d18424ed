"""Synthetic vehicle logs for tests and benchmarks of the gap diagnosis.

The "real" vehicle is the simulator of :mod:`auv_sim` with effects from an effects file
(:mod:`auv_sim.environment`), flown by the project's own depth pilot
(:class:`auv_depth_lqr.pilot.DepthPilot`, the LQR pilot of the node graph) on the noisy
measured state, with excitation added to its commands (the pilot without its pitch envelope
selector, :mod:`auv_depth_lqr.envelope`, and without learning its plant,
:mod:`auv_depth_lqr.learning`: the excitation is added outside the pilot, where a selector
would take it for a disturbance and cancel part of it near the pitch limit, and a learner,
which takes the plane to be where the pilot commanded it, for an error of the plane); the
log is written by the one simulated-log writer (:func:`auv_logs.simlog.write_record`) with
the sensor noise levels of :class:`auv_logs.simlog.SensorNoise`. The diagnosis never sees
the effects: it gets the log, as from a vehicle (state and commands as sent; no force
topic).

Frames and units: NED world, FRD body; SI units, radians.
"""
from __future__ import annotations

import copy
import dataclasses
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from auv_contract import CHANNELS
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_gap.logs import GapLog, from_arrays
from auv_logs.simlog import SensorNoise, write_record
from auv_sim.environment import Environment, parse_environment
from auv_sim.params import VehicleParams
from auv_sim.simulator import Record, Simulator, record
from auv_sim.trim import VerticalPlane


@dataclasses.dataclass(frozen=True)
class SyntheticLog:
    """A simulated log: the simulator's record (time [s], true state, measured state with
    sensor noise, applied commands, wrenches) and the commands as sent, per channel
    ``(stamps [s], values [rad or N])``."""

    record: Record
    commands: dict[str, tuple[np.ndarray, np.ndarray]]

    @property
    def t(self) -> np.ndarray:
        """Sample times (N) [s]."""
        return self.record.t

    @property
    def state(self) -> np.ndarray:
        """Measured state (N x 12) as logged: biases and sensor noise included."""
        return self.record.measured[:, :12]

    @property
    def true_state(self) -> np.ndarray:
        """True state (N x 12)."""
        return self.record.x[:, :12]

    def gap_logs(self, name: str = 'synthetic') -> list[GapLog]:
        """As the diagnosis would read it from a bag."""
        return from_arrays(name, self.t, self.state, self.commands)


@dataclasses.dataclass(frozen=True)
class Scenario:
    """A test flight: the project's depth pilot flies depth set-points while thrust steps
    change the speed and BAR doublets are added to the pilot's command to excite heave and
    pitch.

    ``depth`` rows ``(t [s], z_ref [m])``; ``thrust`` rows ``(t [s], N)``; ``doublets``
    rows ``(t [s], amplitude [rad], half period [s])``; commands at ``command_rate`` [Hz]
    (the pilot's rate). With ``pilot`` False the flight is open loop: the BAR command is the
    trim angle plus the ``bar_steps`` rows ``(t [s], offset [rad])`` (held) plus the
    doublets; ``depth`` is unused.
    """

    duration: float
    z0: float
    u0: float
    depth: tuple[tuple[float, float], ...]
    thrust: tuple[tuple[float, float], ...]
    doublets: tuple[tuple[float, float, float], ...]
    command_rate: float = 10.0
    pilot: bool = True
    bar_steps: tuple[tuple[float, float], ...] = ((0.0, 0.0),)
    #: thruster-off stretches ``(t0, t1)`` [s]: thrust 0 N and the plane held at
    #: ``coast_bar`` [rad] (no pilot, no doublets): the vehicle coasts, then rises or sinks
    #: and hangs at the pitch its restoring moments give
    coasts: tuple[tuple[float, float], ...] = ()
    coast_bar: float = 0.0


def panel_scenario(repeat: int = 1) -> Scenario:
    """About ``900 repeat`` s: depth changes of 20-40 m at three speeds (1.3, 2, 2.9 m/s) and
    BAR doublets of 2-8 s half period and 3-7 deg: several distinct manoeuvres."""
    period = 900.0
    depth = [(0.0, 60.0), (150.0, 90.0), (330.0, 55.0), (480.0, 80.0), (640.0, 60.0),
             (780.0, 95.0)]
    thrust = [(0.0, 55.0), (300.0, 110.0), (560.0, 25.0), (760.0, 55.0)]
    doublets = [(40.0, 0.06, 3.0), (80.0, 0.10, 2.0), (110.0, 0.05, 6.0),
                (200.0, 0.08, 4.0), (260.0, 0.12, 2.0), (360.0, 0.06, 3.0),
                (420.0, 0.10, 6.0), (520.0, 0.05, 2.0), (600.0, 0.12, 4.0),
                (700.0, 0.08, 8.0), (820.0, 0.10, 3.0), (870.0, 0.06, 2.0)]
    rep = range(repeat)
    return Scenario(
        duration=period * repeat, z0=60.0, u0=2.0,
        depth=tuple((t + k * period, z) for k in rep for t, z in depth),
        thrust=tuple((t + k * period, f) for k in rep for t, f in thrust),
        doublets=tuple((t + k * period, a, h) for k in rep for t, a, h in doublets))


def open_loop_scenario() -> Scenario:
    """600 s open loop (no depth pilot): BAR steps of +-1 to 3 deg about trim, doublets of
    2-8 s half period, and thrust steps giving about 1.5, 2.4 and 2 m/s."""
    return Scenario(duration=600.0, z0=60.0, u0=2.0, depth=((0.0, 60.0),),
                    thrust=((0.0, 55.0), (200.0, 95.0), (420.0, 40.0)),
                    doublets=((30.0, 0.06, 3.0), (90.0, 0.08, 2.0), (160.0, 0.05, 6.0),
                              (250.0, 0.07, 4.0), (330.0, 0.1, 2.0), (470.0, 0.06, 8.0),
                              (540.0, 0.08, 3.0)),
                    pilot=False,
                    bar_steps=((0.0, 0.0), (60.0, 0.02), (120.0, -0.02), (220.0, 0.0),
                               (300.0, -0.025), (380.0, 0.03), (450.0, 0.0),
                               (520.0, -0.015)))


def held(rows: tuple[tuple[float, float], ...], t: float) -> float:
    """The value of schedule ``rows`` ``(t [s], value)`` at ``t`` [s]: the last row at or
    before it (before the first, the first)."""
    value = rows[0][1]
    for tr, v in rows:
        if tr <= t + 1e-9:
            value = v
    return value


def doublet(doublets: tuple[tuple[float, float, float], ...], t: float) -> float:
    """The sum of the doublets ``(t0 [s], amplitude [rad], half period [s])`` at ``t`` [s]:
    ``+amplitude`` over the first half period, ``-amplitude`` over the second."""
    value = 0.0
    for t_d, amp, half in doublets:
        if t_d <= t < t_d + half:
            value += amp
        elif t_d + half <= t < t_d + 2 * half:
            value -= amp
    return value


_DESIGNED: dict[tuple[str, float, bytes], DepthPilot] = {}


def new_pilot(params: VehicleParams, rate_hz: float) -> DepthPilot:
    """A fresh :class:`auv_depth_lqr.pilot.DepthPilot` for ``params`` at ``rate_hz`` [Hz]
    with the default settings but the pitch envelope selector and learning off (module
    docstring): a copy
    of one designed once per vehicle and rate (the gain schedule's design takes seconds; a
    panel flies many logs)."""
    key = (params.name, float(rate_hz), params.as_array().tobytes())
    if key not in _DESIGNED:
        if len(_DESIGNED) >= 8:
            _DESIGNED.pop(next(iter(_DESIGNED)))
        _DESIGNED[key] = DepthPilot.for_vehicle(params, PilotSettings(
            rate_hz=rate_hz, pitch_envelope=False, learn=False))
    return copy.deepcopy(_DESIGNED[key])


def simulate(params: VehicleParams, effects: Environment | Mapping[str, Any] | None,
             scenario: Scenario | None = None, seed: int = 0,
             noise: SensorNoise | np.ndarray | None = None,
             sample_period: float = 0.02) -> SyntheticLog:
    """Fly ``scenario`` (default :func:`panel_scenario`) on the simulator with ``effects``
    (an Environment or an effects document ``{effects: {...}}``), measured with seeded sensor
    noise (default :meth:`SensorNoise.realistic`, or 12 standard deviations in the units of
    the state fields; on top of the simulator's sensor biases).

    At each command instant (``scenario.command_rate``) the thrust takes its scheduled value
    and the BAR command is the pilot's (:class:`auv_depth_lqr.pilot.DepthPilot` for the
    vehicle, at the command rate, fed the noisy measured state and the scheduled depth) or,
    open loop, the trim angle plus the scheduled offset; the doublets are added and the sum
    is clipped to the plane limit. The pilot's design model is ``params`` without the
    effects: the effects are what the real vehicle adds.
    """
    env = effects if isinstance(effects, Environment) else parse_environment(effects)
    sc = scenario or panel_scenario()
    sensors = SensorNoise.realistic() if noise is None else noise
    sigma = sensors.sigmas() if isinstance(sensors, SensorNoise) else np.asarray(sensors, float)
    rng = np.random.default_rng(seed)
    trim = VerticalPlane(params).trim(sc.u0, z=sc.z0)
    coasting = False
    sim = Simulator(params, env, x0=trim.state())
    pilot = new_pilot(params, sc.command_rate) if sc.pilot else None
    every = int(round(sample_period / sim.dt))
    per_cmd = int(round(1.0 / (sc.command_rate * sample_period)))
    n = int(round(sc.duration / sample_period)) + 1
    samples = []
    cmds: dict[str, list[tuple[float, float]]] = {ch: [] for ch in CHANNELS}
    cmds['helm'].append((0.0, 0.0))
    last_thrust = None
    last_depth = None
    for i in range(n):
        t, x_true, x, applied, wrench = sim.sample()
        x[:12] += rng.standard_normal(12) * sigma
        samples.append((t, x_true, x, applied, wrench))
        if i % per_cmd == 0:
            coast = any(a <= t + 1e-9 < b for a, b in sc.coasts)
            thrust = 0.0 if coast else held(sc.thrust, t)
            if thrust != last_thrust:
                sim.command('thrust', thrust)
                cmds['thrust'].append((t, thrust))
                last_thrust = thrust
            if pilot is not None:
                depth = held(sc.depth, t)
                if depth != last_depth:
                    pilot.set_depth_command(depth)
                    last_depth = depth
                pilot.on_state(t, z=x[2], theta=x[4], w=x[8], q=x[10], u=x[6])
                if coasting and not coast:      # the pilot takes over again from scratch
                    pilot = new_pilot(params, sc.command_rate)
                    pilot.set_depth_command(depth)
                    pilot.on_state(t, z=x[2], theta=x[4], w=x[8], q=x[10], u=x[6])
                bar = sc.coast_bar if coast else pilot.command(t)[0]
            else:
                bar = sc.coast_bar if coast else trim.bar + held(sc.bar_steps, t)
            coasting = coast
            if not coast:
                bar += doublet(sc.doublets, t)
            bar = float(np.clip(bar, -params.bar_max, params.bar_max))
            sim.command('bar', bar)
            cmds['bar'].append((t, bar))
        if i < n - 1:
            sim.step(every)
    commands = {ch: (np.array([c[0] for c in v]), np.array([c[1] for c in v]))
                for ch, v in cmds.items()}
    return SyntheticLog(record(samples), commands)


def write_bag(path: str | os.PathLike[str], log: SyntheticLog, t0_ns: int = 0) -> int:
    """Write a log as a vehicle would (:func:`auv_logs.simlog.write_record`): the measured
    state on ``/auv/state`` and the commands as sent, no force topic; stamps ``t0_ns`` [ns]
    plus the simulated time. Returns the number of messages written."""
    return write_record(path, log.record, forces=False, sent_commands=log.commands,
                        t0_ns=t0_ns)
