"""Scripted open-loop manoeuvres (report section 2) as data, and running them.

A mission file (``config/missions/*.yaml``) holds ``mission`` (name), ``duration`` [s],
``initial`` (``z`` [m], ``u`` [m/s]: the run starts trimmed at that depth and speed) and
``events``: rows ``[t, channel, value]`` with channel ``bar`` / ``helm`` [rad] or ``thrust``
[N]. A value may be the string ``trim``: the trim BAR or thrust of the initial speed.
"""
from __future__ import annotations

import dataclasses
import math
import pathlib
from collections.abc import Callable
from typing import Any

import numpy as np

from auv_contract import CHANNELS, config_path, read_yaml_file
from auv_sim.environment import Environment
from auv_sim.errors import ParameterError
from auv_sim.params import VehicleParams
from auv_sim.simulator import Record, Simulator, record
from auv_sim.trim import VerticalPlane


@dataclasses.dataclass(frozen=True)
class Mission:
    """A scripted manoeuvre: events ``(t [s], channel, value or 'trim')`` sorted by time."""

    name: str
    duration: float
    z0: float
    u0: float
    events: tuple[tuple[float, str, float | str], ...]


def parse_mission(doc: Any, where: str = '<memory>') -> Mission:
    """Validate a mission document (see module docstring)."""
    if not isinstance(doc, dict):
        raise ParameterError(f'{where}: a mission file must be a mapping')
    try:
        duration = float(doc['duration'])
        init = doc.get('initial', {})
        z0, u0 = float(init.get('z', 0.0)), float(init.get('u', 0.0))
        rows = doc['events']
    except (KeyError, TypeError, ValueError) as exc:
        raise ParameterError(f'{where}: missing or malformed mission field ({exc})') from None
    if not (math.isfinite(duration) and duration > 0):
        raise ParameterError(f'{where}: duration must be > 0 s')
    events = []
    for i, row in enumerate(rows):
        if not isinstance(row, (list, tuple)) or len(row) != 3 or row[1] not in CHANNELS:
            raise ParameterError(f'{where}: event {i} must be [t, bar|helm|thrust, value]')
        t, channel, value = row
        if not isinstance(t, (int, float)) or not math.isfinite(t) or t < 0:
            raise ParameterError(f'{where}: event {i} time {t!r} must be a number >= 0')
        if value != 'trim' and (isinstance(value, bool) or not isinstance(value, (int, float))
                                or not math.isfinite(value)):
            raise ParameterError(f'{where}: event {i} value {value!r} must be a number or trim')
        events.append((float(t), str(channel), value if value == 'trim' else float(value)))
    events.sort(key=lambda e: e[0])
    return Mission(name=str(doc.get('mission', where)), duration=duration, z0=z0, u0=u0,
                   events=tuple(events))


def load_mission(name_or_path: str | pathlib.Path) -> Mission:
    """Load a mission by file path or by name of a file in ``config/missions``."""
    path = pathlib.Path(name_or_path)
    shipped = config_path('missions', f'{name_or_path}.yaml')
    if not path.exists() and shipped.exists():
        path = shipped
    return parse_mission(read_yaml_file(path, 'mission', ParameterError), str(path))


def start_simulator(params: VehicleParams, mission: Mission,
                    environment: Environment | None = None) -> Simulator:
    """A simulator at the mission's initial depth and speed, trimmed for the nominal model."""
    trim = VerticalPlane(params).trim(mission.u0, z=mission.z0)
    return Simulator(params, environment, x0=trim.state())


def run_mission(params: VehicleParams, mission: Mission, environment: Environment | None = None,
                sample_period: float = 0.02,
                on_sample: Callable[[float, Simulator], None] | None = None) -> Record:
    """Run ``mission`` open loop; samples every ``sample_period`` [s] (a multiple of dt)."""
    sim = start_simulator(params, mission, environment)
    trim = VerticalPlane(params).trim(mission.u0, z=mission.z0)
    every = int(round(sample_period / sim.dt))
    if every < 1 or abs(every * sim.dt - sample_period) > 1e-9:
        raise ParameterError(f'sample period {sample_period} s must be a multiple of dt')
    nsamples = int(round(mission.duration / sample_period)) + 1
    events = list(mission.events)
    samples = []
    for i in range(nsamples):
        t = sim.t
        while events and events[0][0] <= t + 1e-9:
            _, channel, value = events.pop(0)
            if value == 'trim':
                value = trim.bar if channel == 'bar' else (trim.thrust if channel == 'thrust'
                                                           else 0.0)
            sim.command(channel, float(value))
        samples.append(sim.sample())
        if on_sample is not None:
            on_sample(t, sim)
        if i < nsamples - 1:
            sim.step(every)
    return record(samples)


def events_array(mission: Mission, params: VehicleParams) -> np.ndarray:
    """Events as an array (M x 3): t [s], channel index, value (``trim`` resolved)."""
    trim = VerticalPlane(params).trim(mission.u0, z=mission.z0)
    out = []
    for t, channel, value in mission.events:
        if value == 'trim':
            value = trim.bar if channel == 'bar' else (trim.thrust if channel == 'thrust' else 0.0)
        out.append((t, CHANNELS.index(channel), float(value)))
    return np.array(out).reshape(-1, 3)
