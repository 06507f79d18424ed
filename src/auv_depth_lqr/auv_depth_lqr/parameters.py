"""The depth-pilot node's parameters as data: default, description, unit, range, choices and
whether each applies at start only; the checks of a set of values and the pilot they describe.

ROS-free: :mod:`auv_depth_lqr.node` turns each :class:`ParameterSpec` into a
``ParameterDescriptor`` and calls :func:`checked_values` and :func:`pilot_from_values` on
start and on every change.

The ranges are the ones the pure core already enforces (:class:`~auv_depth_lqr.pilot.
PilotSettings`, :class:`~auv_depth_lqr.recovery.RecoverySettings`, :class:`~auv_depth_lqr.
limits.Limits`, :meth:`~auv_depth_lqr.pilot.DepthPilot.for_vehicle`), written once here so
that the node can publish them in its descriptors and refuse a value outside them with a
message naming the parameter. Limits that depend on another parameter or on the vehicle file
(``publish_delay`` below half the sample period, ``depth_min`` / ``depth_max`` within the
vehicle's envelope, ``bar_max`` within the vehicle's plane) are said in
:attr:`ParameterSpec.constraint` and checked by :func:`pilot_from_values`.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

from auv_contract import config_path
from auv_contract.parameters import (
    INT64_MAX,
    NON_NEGATIVE,
    POSITIVE,
    SHARE,
    ParameterSpec,
    Range,
)
from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_depth_lqr.recovery import RecoverySettings
from auv_depth_lqr.state_input import ODOM_FRAMES
from auv_sim.params import load_vehicle

__all__ = ['COMMAND_MODES', 'INT64_MAX', 'PARAMETERS', 'RELIABILITIES', 'START_ONLY',
           'STATE_SOURCES', 'ParameterSpec', 'Range', 'checked_values', 'default_vehicle_file',
           'pilot_from_values']

COMMAND_MODES = ('refuse', 'clamp')
STATE_SOURCES = ('vehicle_state', 'odometry')
RELIABILITIES = ('reliable', 'best_effort')


def default_vehicle_file() -> str:
    """The shipped ``a18m.yaml``.

    Returns
    -------
    str
        Its path (:func:`auv_contract.config_path`).
    """
    return str(config_path('a18m.yaml'))


_RECOVERY = RecoverySettings()
_SPECS = (
    ParameterSpec('vehicle_file', default_vehicle_file(),
                  'vehicle parameter file (YAML); default the shipped a18m.yaml'),
    ParameterSpec('rate', 10.0, 'control rate, of bar_command [Hz]', 'Hz', POSITIVE,
                  setting='pilot setting rate_hz', constraint='finite'),
    ParameterSpec('theta_max', PilotSettings.theta_max, 'maximum pitch magnitude [rad]',
                  'rad', Range(0.0, math.pi / 2, lower_open=True, upper_open=True)),
    ParameterSpec('bar_max', 0.0, 'BAR plane travel limit [rad]; 0 = the vehicle file\'s',
                  'rad', NON_NEGATIVE, constraint='finite'),
    ParameterSpec('bar_rate', 0.0, 'BAR plane rate limit [rad/s]; 0 = the vehicle file\'s',
                  'rad/s', NON_NEGATIVE, constraint='finite'),
    ParameterSpec('state_timeout', 0.5, 'state age beyond which safe_bar is flown [s]', 's',
                  POSITIVE, constraint='finite'),
    ParameterSpec('safe_bar', math.nan, 'BAR plane without state [rad]; NaN = derived from '
                  'the vehicle file', 'rad', nan=True, constraint='finite or NaN'),
    ParameterSpec('water_speed', 0.0, 'known surge speed through the water [m/s, body FRD]; '
                  '0 = schedule on the measured surge over ground', 'm/s', NON_NEGATIVE,
                  constraint='finite'),
    ParameterSpec('publish_delay', 0.01, 'output phase after each control instant [s]', 's',
                  NON_NEGATIVE, constraint='below half the sample period, 0.5 / rate s'),
    ParameterSpec('depth_min', math.nan, 'shallowest depth command [m, NED down]; NaN = the '
                  'vehicle file\'s envelope', 'm', nan=True,
                  constraint="finite or NaN; within the vehicle file's envelope, "
                             'below depth_max'),
    ParameterSpec('depth_max', math.nan, 'deepest depth command [m, NED down]; NaN = the '
                  'vehicle file\'s envelope', 'm', nan=True,
                  constraint="finite or NaN; within the vehicle file's envelope, "
                             'above depth_min'),
    ParameterSpec('recovery_pitch_margin', _RECOVERY.pitch_margin,
                  'pitch beyond theta_max that starts recovery [rad]', 'rad', POSITIVE,
                  setting='recovery setting pitch_margin', constraint='finite'),
    ParameterSpec('recovery_rate_residual', _RECOVERY.rate_residual_max,
                  'unexplained depth rate that starts recovery [m/s, NED down]', 'm/s',
                  POSITIVE, setting='recovery setting rate_residual_max', constraint='finite'),
    ParameterSpec('recovery_rate_window', _RECOVERY.rate_window,
                  'window of the depth-rate residual mean [s]', 's', POSITIVE,
                  setting='recovery setting rate_window', constraint='finite'),
    ParameterSpec('recovery_resume_time', _RECOVERY.resume_time,
                  'time back inside the envelope before control resumes [s]', 's', POSITIVE,
                  setting='recovery setting resume_time', constraint='finite'),
    ParameterSpec('recovery_gain', _RECOVERY.gain,
                  "share of the LQR's heave/pitch feedback the recovery law uses", '', SHARE,
                  setting='recovery setting gain'),
    ParameterSpec('recovery_bar_fraction', _RECOVERY.bar_fraction,
                  'share of the plane travel the recovery law may use', '', SHARE,
                  setting='recovery setting bar_fraction'),
    ParameterSpec('diagnostics_period', 1.0, 'period of the /diagnostics statuses [s]', 's',
                  POSITIVE, start_only=True, constraint='finite'),
    ParameterSpec('startup_timeout', 10.0, 'longest wait for start_subscribers and '
                  'diagnostics_subscribers [s]', 's', POSITIVE, start_only=True,
                  constraint='finite'),
    ParameterSpec('weights', 'default', 'LQR weight preset (auv_depth_lqr.weights.PRESETS)'),
    ParameterSpec('depth_command_mode', COMMAND_MODES[0],
                  'a depth command outside the envelope: refused or clamped',
                  choices=COMMAND_MODES),
    ParameterSpec('state_source', STATE_SOURCES[0],
                  'state from VehicleState (state) or Odometry (odom)', choices=STATE_SOURCES,
                  start_only=True),
    ParameterSpec('odom_frame', ODOM_FRAMES[0],
                  'frames of the odom topic: enu_flu (REP-105) or ned_frd',
                  choices=ODOM_FRAMES),
    ParameterSpec('state_reliability', RELIABILITIES[0], 'QoS reliability of the state '
                  'subscription', choices=RELIABILITIES, start_only=True),
    ParameterSpec('lockstep', False, 'answer each state at a control instant instead of a '
                  'timer (docs/lockstep.md)'),
    ParameterSpec('recovery', True, 'envelope fallback to the recovery law'),
    ParameterSpec('pitch_envelope', True, 'keep the BAR within the commands of a pitch-hold '
                  'law towards the pitch limits (auv_depth_lqr.envelope)', start_only=True),
    ParameterSpec('plane_rate_design', False, 'design the LQR on the plane\'s rate, the plane a '
                  'state (docs/pilot-design.md, 4b; not the default)', start_only=True),
    ParameterSpec('learn', False, 'learn what the vehicle file gets wrong while flying and fly '
                  'the learned model (docs/pilot-design.md)', start_only=True),
    ParameterSpec('realtime_priority', 0, 'SCHED_FIFO priority of the node\'s threads; '
                  '0 = normal scheduling', '', Range(0, 99), start_only=True),
    ParameterSpec('start_subscribers', 0, 'bar_command subscriptions awaited before the first '
                  'command; 0 = do not wait', '', NON_NEGATIVE, start_only=True),
    ParameterSpec('diagnostics_subscribers', 0, '/diagnostics subscriptions awaited before '
                  'the first status; 0 = do not wait', '', NON_NEGATIVE, start_only=True),
    ParameterSpec('report_file', '', 'JSON report written at exit; \'\' = none',
                  start_only=True),
)
#: Every parameter of the node by name, in declaration order.
PARAMETERS: Mapping[str, ParameterSpec] = MappingProxyType({s.name: s for s in _SPECS})
#: Parameters applied at start only: a change while running is refused.
START_ONLY = tuple(s.name for s in _SPECS if s.start_only)


def _checked_number(spec: ParameterSpec, value: Any) -> float | int:
    """One numeric value checked against ``spec``.

    Parameters
    ----------
    spec : ParameterSpec
        A parameter with a float or integer default.
    value : Any
        The value given (a float parameter also takes an integer).

    Returns
    -------
    float or int
        ``value`` as a float for a float parameter, as it is for an integer one.

    Raises
    ------
    DesignError
        Wrong type, not finite (NaN where the parameter allows it), or outside its range; the
        message names the parameter and its unit.
    """
    unit = f' {spec.unit}' if spec.unit else ''
    where = f' ({spec.setting})' if spec.setting else ''
    if isinstance(spec.default, int):
        if isinstance(value, bool) or not isinstance(value, int):
            raise DesignError(f'parameter {spec.name} = {value!r} must be an integer')
        number: float | int = value
    else:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise DesignError(f'parameter {spec.name} = {value!r} must be a number')
        number = float(value)
        if math.isnan(number) and spec.nan:
            return number
        if not math.isfinite(number):
            nan = ' (or NaN)' if spec.nan else ''
            raise DesignError(f'parameter {spec.name} = {number!r}{unit} must be finite{nan}'
                              f'{where}')
    if spec.range is not None and number not in spec.range:
        raise DesignError(f'parameter {spec.name} = {number!r}{unit} must be in '
                          f'{spec.range.text()}{where}')
    return number


def checked_values(values: Mapping[str, Any]) -> dict[str, Any]:
    """The node's parameter values checked for type, range and choice.

    Parameters
    ----------
    values : mapping of str to Any
        A value for every name of :data:`PARAMETERS` (other names are passed through).

    Returns
    -------
    dict of str to Any
        The values, float parameters as float (an integer given for one is accepted).

    Raises
    ------
    DesignError
        The first value of the wrong type, outside its range or not one of its choices; the
        message names the parameter.
    """
    out = dict(values)
    for name, spec in PARAMETERS.items():
        value = values[name]
        if isinstance(spec.default, bool):
            if not isinstance(value, bool):
                raise DesignError(f'parameter {name} = {value!r} must be true or false')
        elif isinstance(spec.default, (int, float)):
            out[name] = _checked_number(spec, value)
        elif not isinstance(value, str):
            raise DesignError(f'parameter {name} = {value!r} must be a text')
        elif spec.choices and value not in spec.choices:
            raise DesignError(f'parameter {name} = {value!r} must be one of '
                              f'{list(spec.choices)}')
    return out


def pilot_from_values(v: Mapping[str, Any]) -> DepthPilot:
    """The pilot that checked parameter values describe.

    Parameters
    ----------
    v : mapping of str to Any
        Values passed through :func:`checked_values`.

    Returns
    -------
    DepthPilot
        Designed for the vehicle file, its envelope narrowed by ``depth_min`` /
        ``depth_max`` [m, NED down] when they are not NaN.

    Raises
    ------
    DesignError
        A setting the design refuses (``publish_delay`` not below half the sample period, a
        depth outside the vehicle's envelope, an unknown weight preset, ...).
    auv_sim.errors.ParameterError
        The vehicle file is missing or invalid.
    """
    params = load_vehicle(v['vehicle_file'])
    recovery = RecoverySettings(
        enabled=v['recovery'], pitch_margin=v['recovery_pitch_margin'],
        rate_residual_max=v['recovery_rate_residual'], rate_window=v['recovery_rate_window'],
        resume_time=v['recovery_resume_time'], gain=v['recovery_gain'],
        bar_fraction=v['recovery_bar_fraction'])
    settings = PilotSettings(
        rate_hz=v['rate'], weights=str(v['weights']),
        theta_max=v['theta_max'],
        bar_max=v['bar_max'] or None, bar_rate=v['bar_rate'] or None,
        state_timeout=v['state_timeout'],
        safe_bar=None if math.isnan(v['safe_bar']) else v['safe_bar'],
        water_speed=v['water_speed'] or None, publish_delay=v['publish_delay'],
        recovery=recovery, learn=bool(v['learn']),
        pitch_envelope=bool(v['pitch_envelope']),
        plane_rate_design=bool(v['plane_rate_design']))
    return DepthPilot.for_vehicle(
        params, settings,
        depth_min=None if math.isnan(v['depth_min']) else v['depth_min'],
        depth_max=None if math.isnan(v['depth_max']) else v['depth_max'])
