"""Write simulated runs as bags, the way the node graph records them (pure, no rclpy).

A :class:`auv_sim.simulator.Record` becomes ``/auv/state`` (the *measured* state, NED/FRD),
optionally ``/auv/hydrodynamic_forces`` (body FRD, same stamps) and the actuator command
topics (``/auv/bar_command``, ``/auv/helm_command``, ``/auv/thrust_command``: one message
each time the applied command changes, and at the first sample), plus ``/auv/depth_command``
when depth commands are given. Log times equal the stamps (simulated time, offset by
``t0_ns``). Sensor noise can be added to the state, seeded, to make realistic "real vehicle"
logs; :class:`SensorNoise` is the one definition of the sensor noise levels of simulated logs.
"""
from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from auv_bag import BagWriter, typestore
from auv_contract import CHANNELS, STATE_FIELDS
from auv_logs.errors import LogError
from auv_sim.simulator import Record

if TYPE_CHECKING:
    from rosbags.typesys.store import MsgType

NS_PER_S = 1_000_000_000


@dataclasses.dataclass(frozen=True)
class SensorNoise:
    """Standard deviations of white sensor noise: position/depth [m], angles [rad],
    velocities [m/s], rates [rad/s]. :meth:`realistic` gives the levels of a navigation-grade
    AUV (depth 0.02 m, angles 0.1 deg, velocities 0.01 m/s, rates 0.1 deg/s)."""

    position: float = 0.0
    angle: float = 0.0
    velocity: float = 0.0
    rate: float = 0.0

    @classmethod
    def realistic(cls) -> SensorNoise:
        return cls(position=0.02, angle=math.radians(0.1), velocity=0.01,
                   rate=math.radians(0.1))

    def sigmas(self) -> np.ndarray:
        """Per-state sigma (12) in STATE_FIELDS order."""
        return np.array([self.position] * 3 + [self.angle] * 3 + [self.velocity] * 3
                        + [self.rate] * 3)

    def draw(self, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
        """White noise on the 12 logged states (STATE_FIELDS order, units as the fields):
        one sample (12,) or ``n`` samples (n, 12), from ``rng``'s standard normals."""
        shape = (12,) if n is None else (n, 12)
        noise: np.ndarray = rng.standard_normal(shape) * self.sigmas()
        return noise


def stamp_ns(t: float, t0_ns: int = 0) -> int:
    """Simulated time [s] as integer nanoseconds after ``t0_ns`` (rounded, exact for step
    multiples)."""
    return t0_ns + int(round(t * NS_PER_S))


def measured_state(rec: Record, noise: SensorNoise | None = None, seed: int = 0) -> np.ndarray:
    """The state (N x 12, STATE_FIELDS order) a bag of ``rec`` carries: the record's measured
    state plus, with ``noise``, white noise drawn from ``numpy.random.default_rng(seed)``."""
    meas: np.ndarray = rec.measured[:, :12].copy()
    if noise is not None:
        meas += noise.draw(np.random.default_rng(seed), len(meas))
    return meas


def applied_commands(rec: Record) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per channel, the record's applied commands where they change (and at the first
    sample): ``(times [s], values [rad or N])``."""
    out = {}
    for j, ch in enumerate(CHANNELS):
        change = np.flatnonzero(np.diff(rec.cmd[:, j], prepend=np.nan) != 0)
        out[ch] = (rec.t[change], rec.cmd[change, j])
    return out


def write_record(path: str | os.PathLike[str], rec: Record, *, forces: bool = True,
                 commands: bool = True, noise: SensorNoise | None = None, seed: int = 0,
                 depth_commands: Sequence[tuple[float, float]] = (),
                 bar_commands: tuple[np.ndarray, np.ndarray] | None = None,
                 sent_commands: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None,
                 t0_ns: int = 0) -> int:
    """Write ``rec`` as a bag at ``path`` (directory or ``.mcap``); returns messages written.

    The commands written are, per channel, the changes of the record's *applied* commands,
    unless ``sent_commands`` maps the channel to ``(times [s], values [rad or N])``: the
    commands as they were sent, one message each (what a vehicle logs; they differ from the
    applied ones under an actuator transport delay). ``bar_commands`` is the same for the BAR
    alone (e.g. the pilot's commands of a closed-loop run, one per control instant). All
    stamps and log times are ``t0_ns`` [ns] plus the simulated time.
    """
    sent = applied_commands(rec) | dict(sent_commands or {})
    if bar_commands is not None:
        sent['bar'] = bar_commands
    unknown = sorted(set(sent_commands or {}) - set(CHANNELS))
    if unknown:
        raise LogError(f'sent_commands: unknown channel {unknown[0]!r} (known: {CHANNELS})')
    store = typestore()
    T = store.types
    Header, Time = T['std_msgs/msg/Header'], T['builtin_interfaces/msg/Time']
    State = T['auv_msgs/msg/VehicleState']
    Setpoint = T['auv_msgs/msg/ActuatorSetpoint']
    Forces = T['auv_msgs/msg/HydrodynamicForces']
    Wrench, Vector3 = T['geometry_msgs/msg/Wrench'], T['geometry_msgs/msg/Vector3']
    Float64 = T['std_msgs/msg/Float64']
    meas = measured_state(rec, noise, seed)

    def header(t: float, frame: str) -> MsgType:
        ns = stamp_ns(t, t0_ns)
        return Header(stamp=Time(sec=ns // NS_PER_S, nanosec=ns % NS_PER_S), frame_id=frame)

    def wrench(row: np.ndarray) -> MsgType:
        return Wrench(force=Vector3(x=row[0], y=row[1], z=row[2]),
                      torque=Vector3(x=row[3], y=row[4], z=row[5]))

    n = 0
    with BagWriter(path) as bag:
        bag.add_topic('/auv/state', 'auv_msgs/msg/VehicleState')
        if forces:
            bag.add_topic('/auv/hydrodynamic_forces', 'auv_msgs/msg/HydrodynamicForces')
        if commands:
            for ch in CHANNELS:
                bag.add_topic(f'/auv/{ch}_command', 'auv_msgs/msg/ActuatorSetpoint')
        if depth_commands:
            bag.add_topic('/auv/depth_command', 'std_msgs/msg/Float64')
        events: list[tuple[float, int, str, object]] = []
        for i, t in enumerate(rec.t):
            fields = {k: float(v) for k, v in zip(STATE_FIELDS, meas[i])}
            events.append((t, 1, '/auv/state', State(header=header(t, 'ned'), **fields)))
            if forces:
                w = rec.wrench[i]
                events.append((t, 2, '/auv/hydrodynamic_forces', Forces(
                    header=header(t, 'base_link_frd'), hydrodynamic=wrench(w[0]),
                    coriolis=wrench(w[1]), restoring=wrench(w[2]), actuators=wrench(w[3]))))
        if commands:
            for ch in CHANNELS:
                for t, v in zip(*sent[ch]):
                    events.append((float(t), 0, f'/auv/{ch}_command',
                                   Setpoint(header=header(float(t), ch), value=float(v))))
        for t, z in depth_commands:
            events.append((float(t), 0, '/auv/depth_command', Float64(data=float(z))))
        events.sort(key=lambda e: (e[0], e[1]))
        for t, _, topic, msg in events:
            bag.write(topic, msg, log_time_ns=stamp_ns(t, t0_ns))
            n += 1
    return n
