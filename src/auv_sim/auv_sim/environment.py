"""The water and the departures of a real vehicle from its model: currents and effects.

An :class:`Environment` is what the simulator adds to the vehicle file: ocean current
(constant, a linear shear with depth, a linear drift in time, a depth profile, an oscillation
in time) and any effect of the sim-to-real catalogue (buoyancy error, buoyancy changing with
depth, actuator delay, lag, rate limit, plane bias, cross-flow drag, centre-of-gravity offset,
added-mass error, the model's own coefficients off, plane effectiveness, thrust error, depth
and pitch sensor bias, scale and latency) and forms outside that catalogue, for testing how
honest the diagnosis is about what it cannot name (the oscillating current, a thrust line off
the body origin, a plane whose lift saturates, buoyancy changing in time, a depth sensor's
zero drifting in time). It is loaded from a YAML file (``effects:``
mapping, see ``config/effects/*.yaml``) so that "real" logs can be made whose effect a
diagnosis is not told. Units: SI, radians; currents in NED [m/s].

:data:`EFFECT_FIELDS` is the one registry of effects: names, fields, units and the value
meaning "absent". The simulator implements them here; the gap diagnosis's catalogue
(:mod:`auv_gap.catalogue`) declares its effects against the same registry and
implements them apart, so a test that makes a log with one and explains it with the other
compares two implementations of one declared effect.
"""
from __future__ import annotations

import dataclasses
import itertools
import math
import pathlib
from typing import Any

import numpy as np

from auv_contract import read_yaml_file
from auv_sim.errors import ParameterError
from auv_sim.hull import strip_stations
from auv_sim.model import (
    E_BARBIAS,
    E_BCOMP,
    E_BDRIFT,
    E_DRIFT,
    E_HULL_CD,
    E_HULL_W,
    E_HULL_XI,
    E_MQQ,
    E_NRR,
    E_SHEAR,
    E_STALL,
    E_TGAIN,
    E_TZ,
    E_VAMP,
    E_VC,
    E_VPER,
    E_YVV,
    E_ZWW,
    ENV_SIZE,
    HULL_STRIPS,
)
from auv_sim.params import VehicleParams

#: The model's own coefficients an effect can scale (factor on the vehicle file's value).
COEFFICIENT_FIELDS = ('CZuw', 'CMuw', 'CZuq', 'CMuq', 'CZbar', 'CMbar', 'Ksh', 'CZ0', 'CM0')
_FACTOR = 'x file value'

#: The registry: effect name -> {field: (unit, value meaning "absent")}.
EFFECT_FIELDS: dict[str, dict[str, tuple[str, float]]] = {
    'current': {'north': ('m/s', 0.0), 'east': ('m/s', 0.0), 'down': ('m/s', 0.0)},
    'current_shear': {'north': ('1/s', 0.0), 'east': ('1/s', 0.0)},
    'current_drift': {'north': ('m/s^2', 0.0), 'east': ('m/s^2', 0.0)},
    'current_oscillation': {'north': ('m/s', 0.0), 'east': ('m/s', 0.0),
                            'down': ('m/s', 0.0), 'period': ('s', 0.0)},
    'buoyancy_offset': {'dB': ('N', 0.0)},
    'buoyancy_depth': {'k': ('1/m', 0.0)},
    'actuator_delay': {'bar': ('s', 0.0), 'helm': ('s', 0.0), 'thrust': ('s', 0.0)},
    'actuator_lag': {'bar_tau': ('s', 0.0), 'helm_tau': ('s', 0.0)},
    'actuator_rate_limit': {'bar_rate': ('rad/s', 0.0), 'helm_rate': ('rad/s', 0.0)},
    'bar_bias': {'bias': ('rad', 0.0)},
    'crossflow_drag': {'Zww': ('kg/m', 0.0), 'Mqq': ('kg m^2', 0.0),
                       'Yvv': ('kg/m', 0.0), 'Nrr': ('kg m^2', 0.0)},
    'cg_offset': {'dxg': ('m', 0.0), 'dzg': ('m', 0.0)},
    'added_mass': {'Zwdot': (_FACTOR, 1.0), 'Mqdot': (_FACTOR, 1.0)},
    'coefficients': {k: (_FACTOR, 1.0) for k in COEFFICIENT_FIELDS},
    'plane_effectiveness': {'gain': ('-', 1.0)},
    'thrust_error': {'gain': ('-', 1.0)},
    'depth_sensor_bias': {'bias': ('m', 0.0)},
    'depth_sensor_scale': {'scale': ('-', 1.0)},
    'depth_sensor_latency': {'latency': ('s', 0.0)},
    'pitch_sensor_bias': {'bias': ('rad', 0.0)},
    'pitch_sensor_scale': {'scale': ('-', 1.0)},
    'pitch_sensor_latency': {'latency': ('s', 0.0)},
    # simulated, outside the gap catalogue (forms a real vehicle shows that it cannot name)
    'thrust_moment': {'zt': ('m', 0.0)},
    'plane_stall': {'angle': ('rad', 0.0)},
    'buoyancy_drift': {'rate': ('N/s', 0.0)},
    'depth_sensor_drift': {'rate': ('m/s', 0.0)},
    # a plant whose cross-flow drag is strip theory over a Myring hull (auv_sim.hull), not the
    # model's separate quadratic terms: the identification's panel of non-model plants
    'hull_crossflow': {'cd': ('-', 0.0), 'length': ('m', 0.0), 'diameter': ('m', 0.0)},
}
#: Effects the simulator implements (an effect declared later with :func:`declare_effect`
#: is known to the registry but not simulated).
SIMULATED: frozenset[str] = frozenset(EFFECT_FIELDS)


def declare_effect(name: str, fields: dict[str, tuple[str, float]]) -> None:
    """Declare a new effect (a plug-in of the gap catalogue) in the registry: its fields with
    ``(unit, value meaning "absent")``. The simulator does not implement it (an effects file
    naming it is an error); ParameterError if the name is taken or a field is malformed."""
    if not name or name in EFFECT_FIELDS:
        raise ParameterError(f'effect {name!r} is empty or declared already')
    for key, spec in fields.items():
        if not (isinstance(spec, tuple) and len(spec) == 2 and isinstance(spec[0], str)
                and isinstance(spec[1], float)):
            raise ParameterError(f'effect {name!r}: field {key!r} must be (unit, absent)')
    EFFECT_FIELDS[name] = dict(fields)


def undeclare_effect(name: str) -> None:
    """Remove an effect declared with :func:`declare_effect` (the simulated ones stay)."""
    if name not in SIMULATED:
        EFFECT_FIELDS.pop(name, None)


@dataclasses.dataclass(frozen=True)
class Environment:
    """Current and effects. ``effects`` maps an effect name to its fields (see EFFECT_FIELDS);
    ``current_profile`` is a K x 4 table ``z [m], v_n, v_e, v_d [m/s]`` (NED), depth ascending.
    """

    effects: dict[str, dict[str, float]] = dataclasses.field(default_factory=dict)
    current_profile: tuple[tuple[float, float, float, float], ...] = ()

    def field(self, effect: str, name: str) -> float:
        """Value of one field of an effect, its default when the effect is off."""
        return self.effects.get(effect, {}).get(name, EFFECT_FIELDS[effect][name][1])

    def apply_to(self, params: VehicleParams) -> VehicleParams:
        """The vehicle as it really is: parameters changed by buoyancy, lag, rate, CG,
        added-mass, coefficient and plane-effectiveness effects (factors multiply the file's
        value)."""
        changes: dict[str, float] = {}
        for effect, fields in (('added_mass', ('Zwdot', 'Mqdot')),
                               ('coefficients', COEFFICIENT_FIELDS)):
            for key in fields:
                factor = self.field(effect, key)
                if factor != 1.0:
                    changes[key] = factor * float(getattr(params, key))
        gain = self.field('plane_effectiveness', 'gain')
        if gain != 1.0:
            for key in ('CZbar', 'CMbar'):
                changes[key] = gain * changes.get(key, float(getattr(params, key)))
        if 'buoyancy_offset' in self.effects:
            changes['B'] = params.B + self.field('buoyancy_offset', 'dB')
        if 'cg_offset' in self.effects:
            changes['xg'] = params.xg + self.field('cg_offset', 'dxg')
            changes['zg'] = params.zg + self.field('cg_offset', 'dzg')
        for key in ('bar_tau', 'helm_tau'):
            value = self.field('actuator_lag', key)
            if value > 0.0:
                changes[key] = value
        for key in ('bar_rate', 'helm_rate'):
            value = self.field('actuator_rate_limit', key)
            if value > 0.0:
                changes[key] = value
        return params.replace(**changes) if changes else params

    def env_vector(self) -> np.ndarray:
        """The model's environment vector (see :mod:`auv_sim.model`)."""
        env = np.zeros(ENV_SIZE)
        env[E_VC:E_VC + 3] = [self.field('current', k) for k in ('north', 'east', 'down')]
        env[E_VAMP:E_VAMP + 3] = [self.field('current_oscillation', k)
                                  for k in ('north', 'east', 'down')]
        env[E_VPER] = self.field('current_oscillation', 'period')
        env[E_BCOMP] = self.field('buoyancy_depth', 'k')
        env[E_BARBIAS] = self.field('bar_bias', 'bias')
        env[E_ZWW] = self.field('crossflow_drag', 'Zww')
        env[E_MQQ] = self.field('crossflow_drag', 'Mqq')
        env[E_YVV] = self.field('crossflow_drag', 'Yvv')
        env[E_NRR] = self.field('crossflow_drag', 'Nrr')
        env[E_SHEAR:E_SHEAR + 2] = [self.field('current_shear', k) for k in ('north', 'east')]
        env[E_DRIFT:E_DRIFT + 2] = [self.field('current_drift', k) for k in ('north', 'east')]
        env[E_TGAIN] = self.field('thrust_error', 'gain') - 1.0
        env[E_TZ] = self.field('thrust_moment', 'zt')
        env[E_STALL] = self.field('plane_stall', 'angle')
        env[E_BDRIFT] = self.field('buoyancy_drift', 'rate')
        cd = self.field('hull_crossflow', 'cd')
        if cd > 0.0:
            xi, w = strip_stations(self.field('hull_crossflow', 'length'),
                                   self.field('hull_crossflow', 'diameter'), HULL_STRIPS)
            env[E_HULL_CD] = cd
            env[E_HULL_XI:E_HULL_XI + HULL_STRIPS] = xi
            env[E_HULL_W:E_HULL_W + HULL_STRIPS] = w
        return env

    def profile(self) -> np.ndarray:
        """The current profile table (K x 4), K = 0 when there is none."""
        return np.array(self.current_profile, dtype=np.float64).reshape(-1, 4)

    def delays(self) -> tuple[float, float, float]:
        """Command transport delays (bar, helm, thrust) [s]."""
        return (self.field('actuator_delay', 'bar'), self.field('actuator_delay', 'helm'),
                self.field('actuator_delay', 'thrust'))

    def sensor_bias(self) -> tuple[float, float]:
        """Biases added to the measured depth [m] and pitch [rad]."""
        return (self.field('depth_sensor_bias', 'bias'), self.field('pitch_sensor_bias', 'bias'))

    def sensors(self) -> Sensors:
        """A fresh depth and pitch sensor model of this environment (see :class:`Sensors`)."""
        return Sensors(
            scale=(self.field('depth_sensor_scale', 'scale'),
                   self.field('pitch_sensor_scale', 'scale')),
            latency=(self.field('depth_sensor_latency', 'latency'),
                     self.field('pitch_sensor_latency', 'latency')),
            bias=self.sensor_bias(),
            drift=(self.field('depth_sensor_drift', 'rate'), 0.0))


#: State indices the sensor model changes: depth z [m] and pitch theta [rad].
SENSED = (2, 4)


class Sensors:
    """The depth sensor and the attitude sensor's pitch, as the vehicle reads them::

        reading(t) = scale * true(t - latency) + bias + drift * t

    for depth z [m] and pitch theta [rad] (the other states are read exactly); ``drift``
    [m/s, rad/s] is a bias growing from t = 0 s (a pressure sensor's zero following the
    tide or the weather). A latency is
    served from the history of the states this model was asked to measure, linearly
    interpolated between them (exact for a state that varies linearly between two
    measurements); before the first measurement the state is taken as it was then. Call
    :meth:`measure` at every sample with a non-decreasing time.
    """

    def __init__(self, scale: tuple[float, float] = (1.0, 1.0),
                 latency: tuple[float, float] = (0.0, 0.0),
                 bias: tuple[float, float] = (0.0, 0.0),
                 drift: tuple[float, float] = (0.0, 0.0)) -> None:
        if any(v < 0.0 or not math.isfinite(v) for v in latency):
            raise ParameterError(f'sensor latencies must be finite and >= 0, got {latency}')
        self.scale = np.array(scale, dtype=np.float64)
        self.latency = np.array(latency, dtype=np.float64)
        self.bias = np.array(bias, dtype=np.float64)
        self.drift = np.array(drift, dtype=np.float64)
        self._keep = float(self.latency.max())
        self._t: list[float] = []
        self._v: list[np.ndarray] = []

    def measure(self, t: float, x: np.ndarray) -> np.ndarray:
        """The state ``x`` (12 or 15, true, at time ``t`` [s]) as the sensors read it."""
        out = np.array(x, dtype=np.float64)
        true = out[list(SENSED)].copy()
        if self._keep > 0.0:
            if self._t and t < self._t[-1]:
                raise ParameterError(f'sensor time went back from {self._t[-1]} to {t} s')
            if self._t and t == self._t[-1]:
                self._v[-1] = true.copy()
            else:
                self._t.append(float(t))
                self._v.append(true.copy())
            # drop what no later reading can need (keep one sample at or before t - latency)
            while len(self._t) > 2 and self._t[1] <= t - self._keep:
                del self._t[0]
                del self._v[0]
            times = np.array(self._t)
            values = np.array(self._v)
            for k in range(len(SENSED)):
                if self.latency[k] > 0.0:
                    true[k] = np.interp(t - self.latency[k], times, values[:, k])
        out[list(SENSED)] = self.scale * true + self.bias + self.drift * t
        return out


def parse_environment(doc: Any, where: str = '<memory>') -> Environment:
    """Validate an environment document
    ``{effects: {...}, current_profile: [[z, vn, ve, vd]]}``."""
    if doc is None:
        return Environment()
    if not isinstance(doc, dict):
        raise ParameterError(f'{where}: an effects file must be a mapping')
    unknown = set(doc) - {'effects', 'current_profile', 'description'}
    if unknown:
        raise ParameterError(f'{where}: unknown key(s) {sorted(unknown)}')
    effects: dict[str, dict[str, float]] = {}
    for name, fields in (doc.get('effects') or {}).items():
        if name not in EFFECT_FIELDS:
            raise ParameterError(
                f'{where}: unknown effect {name!r} (known: {", ".join(EFFECT_FIELDS)})')
        if not isinstance(fields, dict):
            raise ParameterError(f'{where}: effect {name!r} must map fields to numbers')
        parsed: dict[str, float] = {}
        for key, value in fields.items():
            if key not in EFFECT_FIELDS[name]:
                raise ParameterError(f'{where}: effect {name!r} has no field {key!r} '
                                     f'(fields: {", ".join(EFFECT_FIELDS[name])})')
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value):
                raise ParameterError(f'{where}: {name}.{key} = {value!r} is not a finite number')
            parsed[key] = float(value)
        if name not in SIMULATED:
            raise ParameterError(f'{where}: effect {name!r} is declared but the simulator '
                                 'does not implement it')
        if name in ('actuator_delay', 'depth_sensor_latency', 'pitch_sensor_latency') \
                and any(v < 0 for v in parsed.values()):
            raise ParameterError(f'{where}: {name} values must be >= 0')
        if name == 'current_oscillation' and parsed.get('period', 0.0) < 0:
            raise ParameterError(f'{where}: current_oscillation.period must be >= 0')
        if name == 'hull_crossflow' and parsed.get('cd', 0.0) != 0.0 and not (
                parsed.get('cd', 0.0) > 0 and parsed.get('length', 0.0) > 0
                and parsed.get('diameter', 0.0) > 0):
            raise ParameterError(f'{where}: hull_crossflow needs cd, length and diameter > 0')
        if name == 'plane_stall' and parsed.get('angle', 0.0) < 0:
            raise ParameterError(f'{where}: plane_stall.angle must be >= 0 (0: no stall)')
        effects[name] = parsed
    rows = doc.get('current_profile') or []
    table = []
    for i, row in enumerate(rows):
        if not isinstance(row, (list, tuple)) or len(row) != 4 or not all(
                isinstance(v, (int, float)) and math.isfinite(v) for v in row):
            raise ParameterError(f'{where}: current_profile row {i} must be [z, v_n, v_e, v_d]')
        table.append(tuple(float(v) for v in row))
    if any(b[0] <= a[0] for a, b in itertools.pairwise(table)):
        raise ParameterError(f'{where}: current_profile depths must increase')
    return Environment(effects=effects, current_profile=tuple(table))  # type: ignore[arg-type]


def load_environment(path: str | pathlib.Path | None) -> Environment:
    """Load an effects file; ``None`` gives calm water and a vehicle exactly as its model."""
    if path is None:
        return Environment()
    path = pathlib.Path(path)
    return parse_environment(read_yaml_file(path, 'effects file', ParameterError), str(path))
