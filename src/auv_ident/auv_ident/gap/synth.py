"""Synthetic vehicle logs for tests and benchmarks of the gap diagnosis.

The "real" vehicle is the simulator of :mod:`auv_sim` with effects from an effects file
(:mod:`auv_sim.environment`); this module only runs it and adds sensor noise. The diagnosis
never sees the effects: it gets the log, as from a vehicle.
"""
from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from auv_ident.gap.logs import (
    CHANNELS,
    COMMAND_TOPICS,
    STATE_FIELDS,
    STATE_TOPIC,
    GapLog,
    from_arrays,
)
from auv_sim.environment import Environment, parse_environment
from auv_sim.params import VehicleParams
from auv_sim.simulator import Simulator
from auv_sim.trim import VerticalPlane

#: Sensor noise (1 sigma) per state: position/depth [m], angles [rad], velocities [m/s],
#: rates [rad/s]: a pressure sensor, an AHRS, a DVL, gyros of a survey AUV (assumed).
SENSOR_NOISE = np.array([0.02, 0.02, 0.02,
                         np.radians(0.1), np.radians(0.1), np.radians(0.1),
                         0.01, 0.01, 0.01,
                         np.radians(0.1), np.radians(0.1), np.radians(0.1)])


@dataclasses.dataclass(frozen=True)
class SyntheticLog:
    """A simulated log: time [s] (N), measured state (N x 12), true state (N x 12), and the
    commands as sent, per channel ``(stamps [s], values)``."""

    t: np.ndarray
    state: np.ndarray
    true_state: np.ndarray
    commands: dict[str, tuple[np.ndarray, np.ndarray]]

    def gap_logs(self, name: str = 'synthetic') -> list[GapLog]:
        """As the diagnosis would read it from a bag."""
        return from_arrays(name, self.t, self.state, self.commands)


@dataclasses.dataclass(frozen=True)
class Scenario:
    """A closed-loop test flight: a simple depth pilot (a test harness, not the project's
    LQR pilot) flies depth set-points while thrust steps change the speed and BAR doublets
    are added to the pilot's command to excite heave and pitch.

    ``depth`` rows ``(t [s], z_ref [m])``; ``thrust`` rows ``(t [s], N)``; ``doublets``
    rows ``(t [s], amplitude [rad], half period [s])``; commands at ``command_rate`` [Hz].
    With ``pilot`` False the flight is open loop: the BAR command is the trim angle plus the
    ``bar_steps`` rows ``(t [s], offset [rad])`` (held) plus the doublets; ``depth`` is unused.
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


def _held(rows: tuple[tuple[float, float], ...], t: float) -> float:
    value = rows[0][1]
    for tr, v in rows:
        if tr <= t + 1e-9:
            value = v
    return value


def simulate(params: VehicleParams, effects: Environment | Mapping[str, Any] | None,
             scenario: Scenario | None = None, seed: int = 0, noise: np.ndarray | None = None,
             sample_period: float = 0.02) -> SyntheticLog:
    """Fly ``scenario`` (default :func:`panel_scenario`) on the simulator with ``effects``
    (an Environment or an effects document ``{effects: {...}}``), measured with seeded sensor
    noise (default :data:`SENSOR_NOISE`, on top of the simulator's sensor biases).

    The pilot: ``theta_ref = clip(0.06 (z - z_ref) + 0.002 int(z - z_ref), +-0.35)``,
    ``bar = bar_trim + (2/u)^2 (1.2 (theta - theta_ref) + 3 q)`` from the measured state,
    plus the doublets, clipped to the plane limit.
    """
    env = effects if isinstance(effects, Environment) else parse_environment(effects)
    sc = scenario or panel_scenario()
    sigma = SENSOR_NOISE if noise is None else np.asarray(noise, dtype=np.float64)
    rng = np.random.default_rng(seed)
    trim = VerticalPlane(params).trim(sc.u0, z=sc.z0)
    sim = Simulator(params, env, x0=trim.state())
    every = int(round(sample_period / sim.dt))
    per_cmd = int(round(1.0 / (sc.command_rate * sample_period)))
    n = int(round(sc.duration / sample_period)) + 1
    t_out = np.empty(n)
    meas = np.empty((n, 12))
    true = np.empty((n, 12))
    cmds: dict[str, list[tuple[float, float]]] = {ch: [] for ch in CHANNELS}
    cmds['helm'].append((0.0, 0.0))
    integ = 0.0
    last_thrust = None
    bar_max = params.bar_max
    for i in range(n):
        t = sim.t
        x = sim.measured_state()[:12] + rng.standard_normal(12) * sigma
        t_out[i], meas[i], true[i] = t, x, sim.x[:12]
        if i % per_cmd == 0:
            thrust = _held(sc.thrust, t)
            if thrust != last_thrust:
                sim.command('thrust', thrust)
                cmds['thrust'].append((t, thrust))
                last_thrust = thrust
            dz = x[2] - _held(sc.depth, t)
            integ = float(np.clip(integ + dz / sc.command_rate, -100.0, 100.0))
            th_ref = float(np.clip(0.06 * dz + 0.002 * integ, -0.35, 0.35))
            gain = (2.0 / max(x[6], 0.8)) ** 2
            bar = trim.bar + gain * (1.2 * (x[4] - th_ref) + 3.0 * x[10]) if sc.pilot \
                else trim.bar + _held(sc.bar_steps, t)
            for t_d, amp, half in sc.doublets:
                if t_d <= t < t_d + half:
                    bar += amp
                elif t_d + half <= t < t_d + 2 * half:
                    bar -= amp
            bar = float(np.clip(bar, -bar_max, bar_max))
            sim.command('bar', bar)
            cmds['bar'].append((t, bar))
        if i < n - 1:
            sim.step(every)
    commands = {ch: (np.array([c[0] for c in v]), np.array([c[1] for c in v]))
                for ch, v in cmds.items()}
    return SyntheticLog(t_out, meas, true, commands)


def write_bag(path: str | os.PathLike[str], log: SyntheticLog, t0_ns: int = 0) -> None:
    """Write a log as a vehicle would: ``/auv/state`` and the three command topics."""
    from auv_bag import BagWriter, typestore

    store = typestore()
    state_t = store.types['auv_msgs/msg/VehicleState']
    set_t = store.types['auv_msgs/msg/ActuatorSetpoint']
    header_t = store.types['std_msgs/msg/Header']
    time_t = store.types['builtin_interfaces/msg/Time']

    def header(t: float) -> Any:
        ns = t0_ns + int(round(t * 1e9))
        return header_t(stamp=time_t(sec=ns // 10**9, nanosec=ns % 10**9), frame_id='ned')

    msgs: list[tuple[float, str, Any]] = []
    for k in range(log.t.size):
        vals = {f: float(log.state[k, i]) for i, f in enumerate(STATE_FIELDS)}
        msgs.append((float(log.t[k]), STATE_TOPIC, state_t(header=header(log.t[k]), **vals)))
    for ch, (stamps, values) in log.commands.items():
        for t, v in zip(stamps, values):
            msgs.append((float(t), COMMAND_TOPICS[ch], set_t(header=header(t), value=float(v))))
    msgs.sort(key=lambda m: m[0])
    with BagWriter(path, flush_interval=60.0) as bag:
        bag.add_topic(STATE_TOPIC, 'auv_msgs/msg/VehicleState')
        for tp in COMMAND_TOPICS.values():
            bag.add_topic(tp, 'auv_msgs/msg/ActuatorSetpoint')
        for t, topic, msg in msgs:
            bag.write(topic, msg, log_time_ns=t0_ns + int(round(t * 1e9)))
