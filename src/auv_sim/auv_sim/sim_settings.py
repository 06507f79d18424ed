"""Settings and simulated-time grid of the simulator node, as pure code (no rclpy).

The node (:mod:`auv_sim.node`) declares one ROS parameter per field of :class:`SimSettings`;
this module validates them, resolves the vehicle and effects files, builds the initial state
and the :class:`~auv_sim.simulator.Simulator`, and does the integer arithmetic of the time
grid: simulated time is ``t_k = k dt`` with ``k`` the integration-step counter, and a stamp is
``k * dt_ns`` integer nanoseconds, never a float product, so stamps never drift and two
parties compare them exactly.
"""
from __future__ import annotations

import dataclasses
import math
import os
import pathlib
from collections.abc import Mapping
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np

from auv_contract import CHANNELS, config_dir
from auv_contract.lockstep import NS_PER_S
from auv_contract.parameters import NON_NEGATIVE, POSITIVE, ParameterSpec, Range
from auv_sim.errors import ParameterError, TrimError
from auv_sim.params import VehicleParams, load_vehicle

if TYPE_CHECKING:
    from auv_sim.environment import Environment
    from auv_sim.simulator import Simulator

_GRID_TOL = 1e-6  # relative tolerance for "a whole number of steps" checks


@dataclasses.dataclass(frozen=True)
class SimSettings:
    """The simulator node's parameters (SI units; angles in rad; NED/FRD conventions).

    ``dt = 0`` takes the vehicle file's step; ``real_time_factor = 0`` runs as fast as
    possible; the initial state is trimmed (:meth:`VerticalPlane.trim`) at ``initial_speed``
    and ``initial_depth`` when ``initial_trim`` (``initial_pitch`` must then stay 0: the trim
    sets it), else it is ``z, u, theta, psi`` as given with planes at 0 and no thrust.
    Wall-clock durations (``lockstep_timeout``, ``lockstep_startup_timeout``) are in wall
    seconds; everything else is simulated time.
    """

    vehicle_file: str = 'config/a18m.yaml'
    effects_file: str = ''
    publish_rate: float = 50.0          # Hz of simulated time
    dt: float = 0.0                     # s, RK4 step; 0: the vehicle file's
    real_time_factor: float = 1.0       # simulated s per wall s; 0: as fast as possible
    use_sim_clock: bool = True          # publish /clock and stamp on simulated time
    initial_trim: bool = True
    initial_depth: float = 40.0         # m, NED z (positive down)
    initial_speed: float = 2.0          # m/s, body FRD surge
    initial_pitch: float = 0.0          # rad, positive nose up (only without initial_trim)
    initial_heading: float = 0.0        # rad, NED yaw (0 north, pi/2 east)
    lockstep: bool = False
    control_period: float = 0.1         # s of simulated time between control instants
    lockstep_timeout: float = 1.0       # wall s to wait for a control instant's command
    lockstep_startup_timeout: float = 30.0  # wall s to wait for the pilot to connect
    lockstep_channels: str = 'bar'      # comma-separated channels answered at each instant
    start_subscribers: float = 0.0      # state subscribers to wait for before t = 0
    start_stream_subscribers: float = 0.0  # the same for odom, forces and /clock (recorders)
    start_odom_subscribers: float = 0.0  # odom alone, when more (a controller on odom too)
    await_recorder: bool = False        # before t = 0, wait for a recorder's progress
    recorder_timeout: float = 5.0       # wall s without recorder progress before giving up
    stop_time: float = 0.0              # s of simulated time at which the node ends; 0: never
    report_file: str = ''               # JSON of what the node published, written at exit

    def replace(self, **changes: Any) -> SimSettings:
        """A copy with some fields changed (not validated; see :func:`check_settings`)."""
        return dataclasses.replace(self, **changes)


FLOAT_FIELDS = tuple(f.name for f in dataclasses.fields(SimSettings) if f.type == 'float')
BOOL_FIELDS = tuple(f.name for f in dataclasses.fields(SimSettings) if f.type == 'bool')
STR_FIELDS = tuple(f.name for f in dataclasses.fields(SimSettings) if f.type == 'str')
#: Fields the running node accepts changes of; the others need a restart.
RUNTIME_FIELDS = ('publish_rate', 'real_time_factor', 'lockstep_timeout')


_PITCH = Range(-math.pi / 2, math.pi / 2, lower_open=True, upper_open=True)
_D = SimSettings()
_SPECS = (
    ParameterSpec('vehicle_file', _D.vehicle_file, 'vehicle parameter file (YAML)',
                  constraint='not empty'),
    ParameterSpec('effects_file', _D.effects_file,
                  "environment/effects file (YAML); '' for calm water"),
    ParameterSpec('publish_rate', _D.publish_rate, 'state publish rate [Hz of simulated time]',
                  'Hz', POSITIVE, constraint='1/publish_rate a whole number of steps'),
    ParameterSpec('dt', _D.dt, "RK4 step [s]; 0: the vehicle file's", 's', NON_NEGATIVE,
                  constraint='a whole number of nanoseconds'),
    ParameterSpec('real_time_factor', _D.real_time_factor,
                  'simulated seconds per wall second [s/s]; 0: as fast as possible', 's/s',
                  NON_NEGATIVE, constraint='0 needs use_sim_clock'),
    ParameterSpec('use_sim_clock', _D.use_sim_clock,
                  'publish /clock and stamp on simulated time'),
    ParameterSpec('initial_trim', _D.initial_trim,
                  'start trimmed (w, theta, BAR, thrust) at initial_speed and initial_depth'),
    ParameterSpec('initial_depth', _D.initial_depth, 'initial depth [m, NED z positive down]',
                  'm', NON_NEGATIVE, constraint="within the vehicle file's envelope"),
    ParameterSpec('initial_speed', _D.initial_speed, 'initial surge speed [m/s, body FRD]',
                  'm/s', constraint='> 0 with initial_trim'),
    ParameterSpec('initial_pitch', _D.initial_pitch, 'initial pitch [rad], positive nose up '
                  '(only with initial_trim false)', 'rad', _PITCH,
                  constraint='0 with initial_trim'),
    ParameterSpec('initial_heading', _D.initial_heading, 'initial heading [rad, NED yaw]',
                  'rad'),
    ParameterSpec('lockstep', _D.lockstep,
                  'wait at each control instant for the bar command stamped with it',
                  constraint='needs use_sim_clock'),
    ParameterSpec('control_period', _D.control_period,
                  'lockstep control period [s of simulated time]', 's', POSITIVE,
                  constraint='a whole number of steps dt'),
    ParameterSpec('lockstep_timeout', _D.lockstep_timeout,
                  'wait for a control instant command [wall s]', 's', POSITIVE),
    ParameterSpec('lockstep_startup_timeout', _D.lockstep_startup_timeout,
                  'wait for the pilot to connect [wall s]', 's', POSITIVE),
    ParameterSpec('lockstep_channels', _D.lockstep_channels,
                  'lockstep: the command channels answered at each control instant '
                  '(comma-separated: bar; bar,helm,thrust for a mission)',
                  constraint=f'channels among {", ".join(CHANNELS)}'),
    ParameterSpec('start_subscribers', _D.start_subscribers,
                  'before t = 0, wait (lockstep_startup_timeout) until /auv/state has this '
                  'many subscribers, e.g. pilot and recorder (0: do not wait)',
                  range=NON_NEGATIVE),
    ParameterSpec('start_stream_subscribers', _D.start_stream_subscribers,
                  'before t = 0, wait (lockstep_startup_timeout) until odom, '
                  'hydrodynamic_forces and /clock each have this many subscribers, e.g. '
                  'recorder and viewer (0: do not wait)', range=NON_NEGATIVE),
    ParameterSpec('start_odom_subscribers', _D.start_odom_subscribers,
                  'before t = 0, wait (lockstep_startup_timeout) until odom has this many '
                  'subscribers when that is more than start_stream_subscribers, e.g. a '
                  'controller on odom besides recorder and viewer (0: do not wait)',
                  range=NON_NEGATIVE),
    ParameterSpec('await_recorder', _D.await_recorder,
                  "before t = 0, wait (lockstep_startup_timeout) for a recorder's progress "
                  '(real_time_factor 0: the recorder paces the run from t = 0)'),
    ParameterSpec('recorder_timeout', _D.recorder_timeout,
                  'without recorder progress, the simulator stops waiting for the recorder '
                  'after this (said, and in report_file) [wall s]', 's', POSITIVE),
    ParameterSpec('stop_time', _D.stop_time, 'simulated time after which the node publishes '
                  'a last state and exits 0 [s]; 0: never', 's', NON_NEGATIVE),
    ParameterSpec('report_file', _D.report_file,
                  'JSON file written at exit: messages published per topic, missed lockstep '
                  "instants, recorder pacing given up ('' none)"),
)
#: Every parameter of the simulator node by name, in declaration order (the fields of
#: :class:`SimSettings`; the ones not in :data:`RUNTIME_FIELDS` apply at start only); the
#: ranges are the ones :func:`check_settings` enforces; every number must be finite.
PARAMETERS: Mapping[str, ParameterSpec] = MappingProxyType({
    s.name: dataclasses.replace(s, start_only=s.name not in RUNTIME_FIELDS) for s in _SPECS})

def whole_steps(duration: float, dt: float, what: str) -> int:
    """``duration / dt`` as an integer >= 1, or ParameterError if it is not a whole number."""
    n = round(duration / dt)
    if n < 1 or abs(n * dt - duration) > _GRID_TOL * max(duration, dt):
        raise ParameterError(f'{what} = {duration:.9g} s must be a whole multiple of the '
                             f'integration step dt = {dt:.9g} s')
    return int(n)


def step_ns(dt: float) -> int:
    """The step ``dt`` [s] in integer nanoseconds; ParameterError if it is not a whole ns."""
    ns = round(dt * NS_PER_S)
    if ns < 1 or abs(ns - dt * NS_PER_S) > 1e-3:
        raise ParameterError(f'dt = {dt!r} s must be a whole number of nanoseconds')
    return int(ns)


def check_settings(s: SimSettings, vehicle_dt: float | None = None) -> None:
    """Range and consistency checks of ``s``; ParameterError naming the parameter.

    With ``vehicle_dt`` [s] (the vehicle file's step, used when ``s.dt == 0``) the time grid is
    checked too: whole-nanosecond step, publish and control periods whole numbers of steps.
    """
    for name in FLOAT_FIELDS:
        value = getattr(s, name)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParameterError(f'parameter {name} = {value!r} must be a number')
        if not math.isfinite(value):
            raise ParameterError(f'parameter {name} = {value} must be finite')
    for name in BOOL_FIELDS:
        if not isinstance(getattr(s, name), bool):
            raise ParameterError(f'parameter {name} = {getattr(s, name)!r} must be a bool')
    for name in STR_FIELDS:
        if not isinstance(getattr(s, name), str):
            raise ParameterError(f'parameter {name} = {getattr(s, name)!r} must be a string')
    for name, spec in PARAMETERS.items():
        if spec.range is not None and getattr(s, name) not in spec.range:
            unit = f' {spec.unit}' if spec.unit and spec.range.upper < math.inf else ''
            raise ParameterError(f'parameter {name} = {getattr(s, name)}{unit} must be '
                                 f'{spec.range.condition()}')
    lockstep_channels(s)
    if not s.vehicle_file:
        raise ParameterError('parameter vehicle_file must name a vehicle file')
    if s.initial_trim and s.initial_pitch != 0.0:
        raise ParameterError('parameter initial_pitch is set by the trim; give it only with '
                             'initial_trim:=false')
    if s.initial_trim and s.initial_speed <= 0.0:
        raise ParameterError(f'parameter initial_speed = {s.initial_speed} m/s: a trimmed start '
                             f'needs a forward speed > 0 (or initial_trim:=false)')
    if not s.use_sim_clock and s.real_time_factor == 0.0:
        raise ParameterError('real_time_factor = 0 (as fast as possible) needs '
                             'use_sim_clock:=true: wall-clock stamps would be meaningless')
    if not s.use_sim_clock and s.lockstep:
        raise ParameterError('lockstep needs use_sim_clock:=true (commands are matched to '
                             'simulated-time stamps)')
    if vehicle_dt is not None:
        dt = s.dt or vehicle_dt
        step_ns(dt)
        whole_steps(1.0 / s.publish_rate, dt, 'publish period 1/publish_rate')
        if s.lockstep:
            whole_steps(s.control_period, dt, 'control_period')


def lockstep_channels(s: SimSettings) -> tuple[str, ...]:
    """The channels answered at each control instant in lockstep (``lockstep_channels``, e.g.
    ``'bar'`` for the depth pilot, ``'bar,helm,thrust'`` for a mission); ParameterError for an
    empty list or an unknown channel."""
    names = tuple(dict.fromkeys(c.strip() for c in s.lockstep_channels.split(',')
                                if c.strip()))
    unknown = [c for c in names if c not in CHANNELS]
    if not names or unknown:
        raise ParameterError(f'parameter lockstep_channels = {s.lockstep_channels!r} must list '
                             f'channels among {", ".join(CHANNELS)} (comma-separated)')
    return names


def resolve_file(name: str, what: str) -> pathlib.Path:
    """Find a file given absolute, or relative to the working directory, ``$AUV_ROOT``, the
    shipped configuration's parent (``config/a18m.yaml``) or the shipped configuration itself
    (``a18m.yaml``), in that order (:func:`auv_contract.config_dir`); ParameterError listing
    where it looked."""
    path = pathlib.Path(name).expanduser()
    if path.is_absolute():
        candidates = [path]
    else:
        roots = [pathlib.Path.cwd()]
        if os.environ.get('AUV_ROOT'):
            roots.append(pathlib.Path(os.environ['AUV_ROOT']))
        shipped = config_dir()
        roots += [shipped.parent, shipped]
        candidates = list(dict.fromkeys(root / path for root in roots))
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    raise ParameterError(f'{what} {name!r} not found (looked in: '
                         f'{", ".join(str(c) for c in candidates)})')


@dataclasses.dataclass(frozen=True)
class SimSetup:
    """What the node runs: parameters, environment, initial state and the time grid.

    ``dt_ns`` is the step in integer ns; ``steps_per_publish`` and ``steps_per_control``
    the publish and control periods in steps (``t_k = k dt``, stamp ``k dt_ns``).
    """

    settings: SimSettings
    params: VehicleParams
    environment: Environment
    x0: np.ndarray
    dt: float
    dt_ns: int
    steps_per_publish: int
    steps_per_control: int

    def simulator(self) -> Simulator:
        """A fresh :class:`Simulator` at the initial state (what the node drives)."""
        from auv_sim.simulator import Simulator

        return Simulator(self.params, self.environment, x0=self.x0, dt=self.dt)

    def stamp_ns(self, k: int) -> int:
        """Stamp of step ``k`` [ns]: ``k dt_ns`` (exact)."""
        return k * self.dt_ns


def build_setup(s: SimSettings) -> SimSetup:
    """Validate ``s``, load the files and trim: everything the node needs to start.

    Raises ParameterError (bad parameter or file) with one line naming what is wrong. The
    compiled model (numba) is imported here, not with this module: a node creates its
    publishers and subscriptions first, so that the graph's discovery goes on while it loads.
    """
    from auv_sim.environment import Environment, load_environment
    from auv_sim.simulator import initial_state
    from auv_sim.trim import cached_trim

    check_settings(s)
    params = load_vehicle(resolve_file(s.vehicle_file, 'vehicle_file'))
    environment = (load_environment(resolve_file(s.effects_file, 'effects_file'))
                   if s.effects_file else Environment())
    check_settings(s, vehicle_dt=params.dt)
    if not params.depth_min <= s.initial_depth <= params.depth_max:
        raise ParameterError(
            f'parameter initial_depth = {s.initial_depth} m outside the vehicle envelope '
            f'[{params.depth_min}, {params.depth_max}] m of {params.path}')
    if s.initial_trim:
        try:
            trim = cached_trim(params, s.initial_speed, z=s.initial_depth)
        except TrimError as exc:
            raise ParameterError(f'initial state: {exc}') from None
        x0 = trim.state(environment, psi=s.initial_heading)
    else:
        x0 = initial_state(z=s.initial_depth, u=s.initial_speed, theta=s.initial_pitch,
                           psi=s.initial_heading)
    dt = s.dt or params.dt
    return SimSetup(settings=s, params=params, environment=environment, x0=x0, dt=dt,
                    dt_ns=step_ns(dt),
                    steps_per_publish=whole_steps(1.0 / s.publish_rate, dt, 'publish period'),
                    steps_per_control=whole_steps(s.control_period, dt, 'control_period')
                    if s.lockstep else 0)


def next_multiple(k: int, n: int) -> int:
    """The smallest multiple of ``n`` strictly greater than ``k`` (steps)."""
    return (k // n + 1) * n
