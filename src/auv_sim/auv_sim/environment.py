"""The water and the departures of a real vehicle from its model: currents and effects.

An :class:`Environment` is what the simulator adds to the vehicle file: ocean current
(constant, a depth profile, an oscillation in time) and any effect of the sim-to-real
catalogue (buoyancy error, buoyancy changing with depth, actuator delay, lag, rate limit,
plane bias, cross-flow drag, centre-of-gravity offset, sensor biases). It is loaded from a
YAML file (``effects:`` mapping, see ``config/effects/*.yaml``) so that "real" logs can be made
whose effect a diagnosis is not told. Units: SI, radians; currents in NED [m/s].
"""
from __future__ import annotations

import dataclasses
import itertools
import math
import pathlib
from typing import Any

import numpy as np
import yaml

from auv_sim.errors import ParameterError
from auv_sim.model import (
    E_BARBIAS,
    E_BCOMP,
    E_MQQ,
    E_NRR,
    E_VAMP,
    E_VC,
    E_VPER,
    E_YVV,
    E_ZWW,
    ENV_SIZE,
)
from auv_sim.params import VehicleParams

# effect name -> {field: (unit, default)}
EFFECT_FIELDS: dict[str, dict[str, tuple[str, float]]] = {
    'current': {'north': ('m/s', 0.0), 'east': ('m/s', 0.0), 'down': ('m/s', 0.0)},
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
    'depth_sensor_bias': {'bias': ('m', 0.0)},
    'pitch_sensor_bias': {'bias': ('rad', 0.0)},
}


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
        """The vehicle as it really is: parameters changed by buoyancy, lag, rate and CG
        effects."""
        changes: dict[str, float] = {}
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
        if name == 'actuator_delay' and any(v < 0 for v in parsed.values()):
            raise ParameterError(f'{where}: actuator_delay values must be >= 0')
        if name == 'current_oscillation' and parsed.get('period', 0.0) < 0:
            raise ParameterError(f'{where}: current_oscillation.period must be >= 0')
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
    try:
        doc = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise ParameterError(f'cannot read effects file {path}: {exc.strerror}') from None
    except yaml.YAMLError:
        raise ParameterError(f'{path}: malformed YAML') from None
    return parse_environment(doc, str(path))
