"""The mapping file: how a real vehicle's log becomes the contract's signals.

A map (YAML, ``format: auv-log-map/1``) says, for every contract signal, where it is in the
log and how to convert it. The contract signals are the state of ``auv_msgs/VehicleState``
(``x y z`` NED [m], ``phi theta psi`` ZYX Euler angles [rad], ``u v w`` body FRD [m/s],
``p q r`` body FRD [rad/s]) and the actuator signals ``bar``, ``helm`` [rad] (commanded;
``bar_measured``, ``helm_measured`` where the log has the fin positions) and ``thrust`` [N]
(or a propeller speed with a thrust law). See ``docs/real-logs.md`` for the full format and a
worked example per kind of log. Outline::

    format: auv-log-map/1
    kind: bag                 # or text
    time: {stamp: header, base: /odom, max_age: 0.1}
    sources:                  # presets for standard message types
      - {preset: odometry, topic: /odom, frame: ENU/FLU}
      - {preset: fluid_pressure, topic: /pressure, density: 1025, surface_pressure: 101325}
    signals:                  # one entry per contract signal (override presets)
      bar: {sum: [{topic: /fins, field: port, gain: 0.5},
                  {topic: /fins, field: starboard, gain: 0.5}], unit: deg}
      thrust: {topic: /thruster, field: data, unit: N}
    segments: {max_gap: 1.0, surface_depth: 0.5, thrust_off: 1.0, min_duration: 20}

Conversion of a scalar signal (``unit`` factor ``k_u``, map ``scale``, ``sign``, term
``gain``; ``offset`` in the contract's SI unit and frame, added last)::

    value = frame(sum_i sign * scale * gain_i * k_u * raw_i) + offset

``frame`` is the identity for NED/FRD and, for a number logged in the ENU/FLU convention
(REP-103), the change to NED/FRD: ``z, theta, v, w, q, r`` change sign, ``psi -> pi/2 - psi``,
``phi, u, p`` are unchanged. ``z`` follows the world frame, ``u v w p q r`` the body frame
(``w`` in ``ENU/FRD`` is unchanged); Euler angles need both in one convention (a mixed pair
is refused). ``x``/``y`` in ENU are not single numbers of the same axis (east is ENU x, NED
y): map them through a position vector. Vectors (presets, ``vectors:``) are converted whole
with :mod:`auv_sim.frames`.

Every error names the map key and its line (:class:`MapError`).
"""
from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import pathlib
from collections.abc import Mapping, Sequence
from typing import Any

from auv_contract import STATE_FIELDS
from auv_contract.files import YamlError, parse_yaml_with_lines
from auv_logs.errors import MapError
from auv_logs.units import SIGNAL_DIMENSION, unit

FORMAT = 'auv-log-map/1'
STATE = STATE_FIELDS
ACTUATORS = ('bar', 'helm', 'thrust', 'bar_measured', 'helm_measured')
SIGNALS = STATE + ACTUATORS
#: Vector kinds and the state signals each gives.
VECTOR_KINDS: dict[str, tuple[str, ...]] = {
    'position': ('x', 'y', 'z'),
    'orientation': ('phi', 'theta', 'psi'),
    'euler': ('phi', 'theta', 'psi'),
    'linear_velocity': ('u', 'v', 'w'),
    'angular_velocity': ('p', 'q', 'r'),
}
_VECTOR_DIMENSION = {'position': 'length', 'orientation': None, 'euler': 'angle',
                     'linear_velocity': 'speed', 'angular_velocity': 'angular_rate'}
#: Scalar frame changes ENU/FLU -> NED/FRD: (sign, offset) with value_ned = offset + sign * v.
SCALAR_ENU: dict[str, tuple[float, float]] = {
    'z': (-1.0, 0.0), 'phi': (1.0, 0.0), 'theta': (-1.0, 0.0), 'psi': (-1.0, math.pi / 2),
    'u': (1.0, 0.0), 'v': (-1.0, 0.0), 'w': (-1.0, 0.0),
    'p': (1.0, 0.0), 'q': (-1.0, 0.0), 'r': (-1.0, 0.0)}
_FRAME_ALIASES = {'NED': ('NED', 'FRD'), 'FRD': ('NED', 'FRD'), 'NED/FRD': ('NED', 'FRD'),
                  'ENU': ('ENU', 'FLU'), 'FLU': ('ENU', 'FLU'), 'ENU/FLU': ('ENU', 'FLU'),
                  'ENU/FRD': ('ENU', 'FRD'), 'NED/FLU': ('NED', 'FLU')}
DELIMITERS = {'whitespace': None, 'comma': ',', 'semicolon': ';', 'tab': '\t'}
#: Defaults of the segment rules (see :mod:`auv_logs.segments`).
SEGMENT_DEFAULTS = {'max_gap': None, 'surface_depth': None, 'thrust_off': None,
                    'min_duration': 10.0}


@dataclasses.dataclass(frozen=True)
class Where:
    """A place in the map: the key path (``signals.theta``) and its line (1-based)."""

    key: str
    line: int

    def __str__(self) -> str:
        return f'map {self.key} (line {self.line})'


@dataclasses.dataclass(frozen=True)
class Term:
    """One logged number: ``topic`` and field ``path`` (bags; ``data[2]`` indexes an array)
    or ``column`` (text logs, ``topic`` None), times ``gain`` (unit factor, scale, sign and
    the term's own gain and sign)."""

    topic: str | None
    path: str
    gain: float
    where: Where


@dataclasses.dataclass(frozen=True)
class ThrustLaw:
    """Propeller thrust from shaft speed ``n`` [rev/s]: ``T = k n |n|`` [N], ``k`` in
    N/(rev/s)^2 (given, or ``rho D^4 K_T`` from a thrust coefficient)."""

    k: float


@dataclasses.dataclass(frozen=True)
class Pressure:
    """Depth from an absolute pressure ``P`` [Pa]: ``z = (P - surface) / (density g)`` [m]."""

    density: float
    surface: float
    g: float


@dataclasses.dataclass(frozen=True)
class Scalar:
    """A contract signal from one or several logged numbers (see the module docstring)."""

    name: str
    terms: tuple[Term, ...]
    unit: str
    dimension: str
    offset: float
    enu: bool
    where: Where
    law: ThrustLaw | None = None
    pressure: Pressure | None = None
    full_scale: float | None = None
    origin: str = 'signals'
    #: the sensor's own update rate [Hz] when the log repeats its value on several rows or
    #: messages (a 1 Hz DVL on 2 Hz rows); None: a new value at every stamp
    rate: float | None = None
    #: the step of the logged values in the contract's SI unit (0.1 m: depth printed in
    #: 0.1 m steps); None: full precision
    resolution: float | None = None


@dataclasses.dataclass(frozen=True)
class Vector:
    """Several state signals from one vector of a message: ``kind`` (see
    :data:`VECTOR_KINDS`), ``fields`` (3, or 4 for a quaternion x y z w), frames, and the
    unit factor to SI."""

    kind: str
    topic: str | None
    fields: tuple[str, ...]
    world: str
    body: str
    factor: float
    where: Where
    origin: str
    skip: tuple[str, ...] = ()
    #: linear velocity of a sensor mounted rotated: ZYX Euler angles (roll, pitch, yaw) [rad]
    #: of the sensor's axes relative to the body axes (both FRD, after the frame change):
    #: ``v_body = R(mounting) v_sensor``
    mounting: tuple[float, float, float] | None = None
    #: linear velocity of a sensor away from the body origin: its position [m], body FRD;
    #: the origin's velocity is ``v_sensor - omega x lever_arm``
    lever_arm: tuple[float, float, float] | None = None
    #: field path of the covariance element set to -1 where a message carries no estimate of
    #: this vector (sensor_msgs/Imu: ``orientation_covariance[0]``,
    #: ``angular_velocity_covariance[0]``); such samples are not usable, and a topic with no
    #: estimate in any message is an error
    unset: str | None = None
    #: update rate [Hz] and resolution [SI unit of its signals] as for :class:`Scalar`
    rate: float | None = None
    resolution: float | None = None
    #: the unit its fields are logged in (length, speed, rate vectors; '' for quaternions)
    unit: str = ''

    @property
    def gives(self) -> tuple[str, ...]:
        """The state signals this vector gives (its kind's, less those skipped)."""
        return tuple(n for n in VECTOR_KINDS[self.kind] if n not in self.skip)

    @property
    def components(self) -> tuple[str, ...]:
        """All the state signals of the vector's kind, in field order."""
        return VECTOR_KINDS[self.kind]


@dataclasses.dataclass(frozen=True)
class TextFormat:
    """How a text log is laid out."""

    delimiter: str | None
    header: bool
    columns: tuple[str, ...]
    comment: str


@dataclasses.dataclass(frozen=True)
class TimeSpec:
    """Time stamps: ``stamp`` ``header`` or ``log`` (bags), ``column`` and its unit factor
    (text), the state's time ``base`` topic, the zero-order-hold ``max_age`` [s], per-topic
    clock ``offsets`` [s], the optional uniform ``grid`` period [s] onto which each
    segment's state is resampled (linear interpolation; said in the report), and per-topic
    ``stamps`` (``header`` or ``log``) overriding ``stamp`` for that topic."""

    stamp: str
    column: str | None
    factor: float
    base: str | None
    max_age: float
    offsets: Mapping[str, float]
    grid: float | None = None
    stamps: Mapping[str, str] = dataclasses.field(default_factory=dict)

    def stamp_of(self, topic: str | None) -> str:
        """``header`` or ``log`` for a bag topic (its ``stamps`` entry, else ``stamp``)."""
        return self.stamps.get(str(topic), self.stamp)


@dataclasses.dataclass(frozen=True)
class LogMap:
    """A validated map. ``scalars`` and ``vectors`` together give each signal at most once."""

    kind: str
    time: TimeSpec
    scalars: Mapping[str, Scalar]
    vectors: tuple[Vector, ...]
    text: TextFormat | None
    segments: Mapping[str, float | None]
    text_source: str
    path: str
    description: str = ''

    def topics(self) -> list[str]:
        """Topics the map reads (bags), in first-use order."""
        seen: dict[str, None] = {}
        for s in self.scalars.values():
            for term in s.terms:
                if term.topic is not None:
                    seen[term.topic] = None
        for vec in self.vectors:
            if vec.topic is not None:
                seen[vec.topic] = None
        return list(seen)


# --------------------------------------------------------------------------------------------
# presets

def _preset_fields(preset: str, where: Where) -> dict[str, tuple[str, ...]]:
    """Vector kind -> field paths of a preset message type."""
    if preset == 'odometry':   # nav_msgs/Odometry: pose in the world frame, twist in the body
        return {'position': tuple(f'pose.pose.position.{a}' for a in 'xyz'),
                'orientation': tuple(f'pose.pose.orientation.{a}' for a in 'xyzw'),
                'linear_velocity': tuple(f'twist.twist.linear.{a}' for a in 'xyz'),
                'angular_velocity': tuple(f'twist.twist.angular.{a}' for a in 'xyz')}
    if preset == 'imu':        # sensor_msgs/Imu
        return {'orientation': tuple(f'orientation.{a}' for a in 'xyzw'),
                'angular_velocity': tuple(f'angular_velocity.{a}' for a in 'xyz')}
    if preset == 'dvl':        # geometry_msgs/TwistWithCovarianceStamped
        return {'linear_velocity': tuple(f'twist.twist.linear.{a}' for a in 'xyz')}
    if preset == 'dvl_twist_stamped':   # geometry_msgs/TwistStamped
        return {'linear_velocity': tuple(f'twist.linear.{a}' for a in 'xyz')}
    if preset == 'pose':       # geometry_msgs/PoseStamped
        return {'position': tuple(f'pose.position.{a}' for a in 'xyz'),
                'orientation': tuple(f'pose.orientation.{a}' for a in 'xyzw')}
    raise MapError(f'{where}: unknown preset {preset!r} (known: {", ".join(PRESETS)})')


#: Presets: name -> the message type they read.
PRESETS = {
    'odometry': 'nav_msgs/msg/Odometry',
    'imu': 'sensor_msgs/msg/Imu',
    'dvl': 'geometry_msgs/msg/TwistWithCovarianceStamped',
    'dvl_twist_stamped': 'geometry_msgs/msg/TwistStamped',
    'pose': 'geometry_msgs/msg/PoseStamped',
    'fluid_pressure': 'sensor_msgs/msg/FluidPressure',
    'float64': 'std_msgs/msg/Float64',
    'float64_array': 'std_msgs/msg/Float64MultiArray',
}


# --------------------------------------------------------------------------------------------
# parsing helpers

class _Node:
    """A mapping of the YAML document with its key path, for errors that name the line."""

    def __init__(self, data: Any, key: str, line: int) -> None:
        if not isinstance(data, Mapping):
            raise MapError(f'map {key} (line {line}): expected a mapping, got {data!r}')
        self.data = data
        self.key = key
        self.line = line
        self.used: set[str] = set()

    def where(self, name: str | None = None) -> Where:
        if name is None:
            return Where(self.key, self.line)
        lc = getattr(self.data, 'lc', None)
        line = self.line
        if lc is not None and name in self.data:
            with contextlib.suppress(KeyError, TypeError, IndexError):
                line = int(lc.key(name)[0]) + 1
        return Where(f'{self.key}.{name}' if self.key else name, line)

    def has(self, name: str) -> bool:
        return name in self.data

    def get(self, name: str, default: Any = None) -> Any:
        self.used.add(name)
        return self.data.get(name, default)

    def child(self, name: str) -> _Node:
        self.used.add(name)
        w = self.where(name)
        return _Node(self.data[name], w.key, w.line)

    def number(self, name: str, default: float | None = None, positive: bool = False) -> float:
        raw = self.get(name, default)
        w = self.where(name)
        if raw is None:
            raise MapError(f'{w}: missing (a number)')
        if isinstance(raw, bool) or not isinstance(raw, (int, float)):
            raise MapError(f'{w}: expected a number, got {raw!r}')
        val = float(raw)
        if not math.isfinite(val) or (positive and val <= 0):
            raise MapError(f'{w}: must be a finite{" positive" if positive else ""} number, '
                           f'got {raw!r}')
        return val

    def text(self, name: str, default: str | None = None) -> str:
        raw = self.get(name, default)
        if raw is None:
            raise MapError(f'{self.where(name)}: missing')
        if not isinstance(raw, str) or not raw:
            raise MapError(f'{self.where(name)}: expected a non-empty string, got {raw!r}')
        return raw

    def sign(self, name: str = 'sign') -> float:
        raw = self.get(name, 1)
        if raw not in (1, -1) or isinstance(raw, bool):
            raise MapError(f'{self.where(name)}: sign must be 1 or -1, got {raw!r}')
        return float(raw)

    def finish(self, allowed: Sequence[str]) -> None:
        """Reject keys not in ``allowed``."""
        for name in self.data:
            if name not in allowed:
                raise MapError(f'{self.where(str(name))}: unknown key {name!r} '
                               f'(known here: {", ".join(allowed)})')

    def items(self, name: str) -> list[_Node]:
        """The list ``name`` as nodes (empty if absent)."""
        self.used.add(name)
        raw = self.data.get(name)
        if raw is None:
            return []
        w = self.where(name)
        if isinstance(raw, (str, bytes)) or not isinstance(raw, Sequence):
            raise MapError(f'{w}: expected a list')
        out = []
        lc = getattr(raw, 'lc', None)
        for i, item in enumerate(raw):
            line = w.line
            if lc is not None:
                with contextlib.suppress(KeyError, TypeError, IndexError):
                    line = int(lc.item(i)[0]) + 1
            out.append(_Node(item, f'{w.key}[{i}]', line))
        return out


def _frame(node: _Node, name: str = 'frame') -> tuple[str, str]:
    raw = node.get(name)
    w = node.where(name) if node.has(name) else node.where()
    if raw is None:
        raise MapError(f'{w}: no frame declared (say NED/FRD or ENU/FLU)')
    pair = _FRAME_ALIASES.get(str(raw).upper())
    if pair is None:
        raise MapError(f'{w}: unknown frame {raw!r} (known: {", ".join(_FRAME_ALIASES)})')
    return pair


def _source_of(node: _Node, kind: str) -> tuple[str | None, str]:
    """(topic, field path) of a bag entry, or (None, column) of a text entry."""
    if kind == 'text':
        if node.has('topic') or node.has('field'):
            raise MapError(f'{node.where()}: a text log is read by column: use column:')
        col = node.get('column')
        if col is None:
            raise MapError(f'{node.where()}: no column given')
        return None, str(col)
    if node.has('column'):
        raise MapError(f'{node.where("column")}: a bag is read by topic and field, not column')
    return node.text('topic'), node.text('field')


def _law(node: _Node) -> ThrustLaw:
    kind = node.text('kind', 'quadratic')
    if kind == 'quadratic':
        node.finish(('kind', 'coefficient'))
        return ThrustLaw(node.number('coefficient', positive=True))
    if kind == 'kt':
        node.finish(('kind', 'kt', 'diameter', 'density'))
        return ThrustLaw(node.number('density', positive=True)
                         * node.number('diameter', positive=True) ** 4
                         * node.number('kt', positive=True))
    raise MapError(f'{node.where("kind")}: unknown thrust law {kind!r} (known: quadratic, kt)')


_SCALAR_KEYS = ('topic', 'field', 'column', 'unit', 'scale', 'offset', 'sign', 'frame', 'sum',
                'law', 'full_scale', 'pressure', 'rate', 'resolution')


def _rate_resolution(node: _Node, name: str, factor: float) -> tuple[float | None, float | None]:
    """``rate`` [Hz] and ``resolution`` (in the logged unit, returned times ``factor``: SI) of
    a state signal or vector, or None."""
    rate = node.number('rate', positive=True) if node.has('rate') else None
    res = node.number('resolution', positive=True) if node.has('resolution') else None
    if (rate is not None or res is not None) and name not in STATE and \
            name not in VECTOR_KINDS:
        key = 'rate' if rate is not None else 'resolution'
        raise MapError(f'{node.where(key)}: {key}: is for state signals ({name} is a command, '
                       'an event stream at its own stamps)')
    return rate, None if res is None else res * abs(factor)


def _scalar(name: str, node: _Node, kind: str, origin: str = 'signals') -> Scalar:
    node.finish(_SCALAR_KEYS)
    if name not in SIGNALS:
        raise MapError(f'{node.where()}: unknown signal {name!r} (known: {", ".join(SIGNALS)})')
    unit_name = node.get('unit')
    if unit_name is None:
        raise MapError(f'{node.where()}: no unit given for {name}')
    u = unit(str(unit_name), str(node.where('unit')))
    pressure = None
    if node.has('pressure'):
        if name != 'z':
            raise MapError(f'{node.where("pressure")}: a pressure gives z only')
        pn = node.child('pressure')
        pn.finish(('density', 'surface_pressure', 'g'))
        pressure = Pressure(pn.number('density', positive=True),
                            pn.number('surface_pressure', 101325.0),
                            pn.number('g', 9.80665, positive=True))
        if u.dimension != 'pressure':
            raise MapError(f'{node.where("unit")}: a pressure needs a pressure unit, '
                           f'got {unit_name}')
    elif u.dimension not in SIGNAL_DIMENSION[name]:
        raise MapError(f'{node.where("unit")}: unit {unit_name} ({u.dimension}) does not fit '
                       f'{name} (needs {" or ".join(SIGNAL_DIMENSION[name])})')
    law = None
    full_scale = None
    if u.dimension == 'shaft_speed':
        if not node.has('law'):
            raise MapError(f'{node.where()}: thrust in {unit_name} needs a thrust law (law:)')
        law = _law(node.child('law'))
    elif node.has('law'):
        raise MapError(f'{node.where("law")}: a thrust law needs a shaft speed unit (rpm, rev/s)')
    if u.dimension == 'fraction':
        full_scale = node.number('full_scale', positive=True)
    elif node.has('full_scale'):
        raise MapError(f'{node.where("full_scale")}: full_scale needs unit percent or fraction')
    common = node.sign() * node.number('scale', 1.0) * u.factor
    terms = []
    if node.has('sum'):
        if node.has('topic') or node.has('field') or node.has('column'):
            raise MapError(f'{node.where("sum")}: give either sum: or one source, not both')
        parts = node.items('sum')
        if not parts:
            raise MapError(f'{node.where("sum")}: empty')
        for part in parts:
            part.finish(('topic', 'field', 'column', 'gain', 'sign'))
            topic, path = _source_of(part, kind)
            terms.append(Term(topic, path, common * part.number('gain', 1.0) * part.sign(),
                              part.where()))
    else:
        topic, path = _source_of(node, kind)
        terms.append(Term(topic, path, common, node.where()))
    enu = False
    if name in STATE:
        world, body = _frame(node)
        # a world-frame number changes with the world frame, a body-frame number with the
        # body frame; an Euler angle with both (a mixed pair is no single-axis change)
        if name in ('x', 'y', 'z'):
            enu = world == 'ENU'
        elif name in ('phi', 'theta', 'psi'):
            if (world == 'ENU') != (body == 'FLU'):
                raise MapError(f'{node.where("frame")}: {name} in the mixed frame {world}/{body}'
                               ' is not a change of one axis: map the attitude as a vector '
                               '(kind euler or orientation) or give it in NED/FRD or ENU/FLU')
            enu = world == 'ENU'
        else:
            enu = body == 'FLU'
        if enu and name in ('x', 'y'):
            raise MapError(f'{node.where("frame")}: {name} in ENU is another axis than NED '
                           f'{name}: map the position as a vector (vectors: or a preset) or '
                           'give the NED component with frame NED')
    elif node.has('frame'):
        raise MapError(f'{node.where("frame")}: {name} has no frame (use sign: for its '
                       'convention)')
    si = common * (1.0 / (pressure.density * pressure.g) if pressure is not None else 1.0)
    rate, resolution = _rate_resolution(node, name, si)
    return Scalar(name, tuple(terms), str(unit_name), u.dimension, node.number('offset', 0.0),
                  enu, node.where(), law, pressure, full_scale, origin, rate, resolution)


def _vector(kind_name: str, node: _Node, topic: str | None, fields: Sequence[str],
            origin: str, unit_default: str | None) -> Vector:
    world, body = _frame(node)
    dim = _VECTOR_DIMENSION[kind_name]
    factor = 1.0
    uname = None
    if dim is not None:
        uname = node.get('unit', unit_default)
        if uname is None:
            raise MapError(f'{node.where()}: no unit given for the {kind_name}')
        u = unit(str(uname), str(node.where('unit')))
        if u.dimension != dim:
            raise MapError(f'{node.where("unit")}: unit {uname} does not fit a {kind_name}')
        # scale: raw sensor counts per ... (a gyro logging counts: 1 / counts per unit)
        factor = u.factor * (node.number('scale', 1.0) if node.has('scale') else 1.0)
    elif node.has('scale'):
        raise MapError(f'{node.where("scale")}: a quaternion has no scale')
    need = 4 if kind_name == 'orientation' else 3
    if len(fields) != need:
        raise MapError(f'{node.where("fields")}: a {kind_name} needs {need} fields')
    rate, resolution = _rate_resolution(node, kind_name, factor)
    return Vector(kind_name, topic, tuple(str(f) for f in fields), world, body, factor,
                  node.where(), origin, rate=rate, resolution=resolution,
                  unit=str(uname) if uname is not None else '')


def _triple(node: _Node, name: str) -> tuple[float, float, float]:
    raw = node.get(name)
    if not isinstance(raw, Sequence) or isinstance(raw, str) or len(raw) != 3 or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            for v in raw):
        raise MapError(f'{node.where(name)}: expected three numbers, got {raw!r}')
    return float(raw[0]), float(raw[1]), float(raw[2])


def _mounting(node: _Node, kind_name: str
              ) -> tuple[tuple[float, float, float] | None, tuple[float, float, float] | None]:
    """``mounting: {rpy: [roll, pitch, yaw], unit: deg}`` and ``lever_arm: [x, y, z]`` [m]
    (body FRD) of a linear-velocity sensor (a DVL), or None."""
    if not (node.has('mounting') or node.has('lever_arm')):
        return None, None
    if kind_name != 'linear_velocity':
        key = 'mounting' if node.has('mounting') else 'lever_arm'
        raise MapError(f'{node.where(key)}: {key} is for a linear velocity (a DVL), not a '
                       f'{kind_name}')
    rpy = None
    if node.has('mounting'):
        mn = node.child('mounting')
        mn.finish(('rpy', 'unit'))
        u = unit(mn.text('unit', 'rad'), str(mn.where('unit')))
        if u.dimension != 'angle':
            raise MapError(f'{mn.where("unit")}: the mounting angles need an angle unit')
        r = _triple(mn, 'rpy')
        rpy = (r[0] * u.factor, r[1] * u.factor, r[2] * u.factor)
    lever = _triple(node, 'lever_arm') if node.has('lever_arm') else None
    return rpy, lever


def _preset(node: _Node, kind: str) -> tuple[list[Vector], list[Scalar]]:
    preset = node.text('preset')
    if preset not in PRESETS:
        raise MapError(f'{node.where("preset")}: unknown preset {preset!r} '
                       f'(known: {", ".join(PRESETS)})')
    if kind != 'bag':
        raise MapError(f'{node.where("preset")}: presets read bags; a text log maps columns '
                       'in signals:')
    topic = node.text('topic')
    origin = f'{preset} {topic}'
    if preset == 'fluid_pressure':
        node.finish(('preset', 'topic', 'density', 'surface_pressure', 'g', 'offset', 'rate',
                     'resolution'))
        press = Pressure(node.number('density', positive=True),
                         node.number('surface_pressure', 101325.0),
                         node.number('g', 9.80665, positive=True))
        rate, resolution = _rate_resolution(node, 'z', 1.0 / (press.density * press.g))
        return [], [Scalar('z', (Term(topic, 'fluid_pressure', 1.0, node.where()),), 'Pa',
                           'pressure', node.number('offset', 0.0), False, node.where(),
                           pressure=press, origin=origin, rate=rate, resolution=resolution)]
    if preset in ('float64', 'float64_array'):
        node.finish(('preset', 'topic', 'signal', 'index', 'unit', 'scale', 'offset', 'sign',
                     'frame', 'law', 'full_scale', 'rate', 'resolution'))
        signal = node.text('signal')
        path = 'data'
        if preset == 'float64_array':
            index = node.number('index')
            if index < 0 or index != int(index):
                raise MapError(f'{node.where("index")}: index must be an integer >= 0')
            path = f'data[{int(index)}]'
        body = {k: v for k, v in node.data.items() if k not in ('preset', 'signal', 'index')}
        body['field'] = path
        return [], [_scalar(signal, _Node(body, node.key, node.line), kind, origin)]
    node.finish(('preset', 'topic', 'frame', 'use', 'unit', 'skip', 'mounting', 'lever_arm',
                 'rate', 'resolution', 'scale'))
    fields = _preset_fields(preset, node.where('preset'))
    use = node.get('use') or list(fields)
    if isinstance(use, str):
        use = [use]
    skip = node.get('skip') or []
    skip = [skip] if isinstance(skip, str) else list(skip)
    for name in skip:
        if name not in STATE:
            raise MapError(f'{node.where("skip")}: {name!r} is not a state signal')
    vectors = []
    mounting, lever = _mounting(node, 'linear_velocity' if 'linear_velocity' in use
                                else str(use[0]))
    for k in use:
        if k not in fields:
            raise MapError(f'{node.where("use")}: {preset} gives {", ".join(fields)}, not {k!r}')
        default_unit = {'position': 'm', 'linear_velocity': 'm/s',
                        'angular_velocity': 'rad/s'}.get(k)
        vec = _vector(k, node, topic, fields[k], origin, default_unit)
        if k == 'linear_velocity':
            vec = dataclasses.replace(vec, mounting=mounting, lever_arm=lever)
        if preset == 'imu':     # covariance element 0 of -1: no estimate (sensor_msgs/Imu)
            vec = dataclasses.replace(vec, unset=f'{k}_covariance[0]')
        vectors.append(dataclasses.replace(vec, skip=tuple(str(n) for n in skip)))
    return vectors, []


def parse_map(data: Any, kind_hint: str | None = None, path: str = '<map>',
              text: str = '') -> LogMap:
    """Validate a loaded map document (ruamel round-trip data keep line numbers).

    Raises
    ------
    MapError
        naming the key and line of the first problem.
    """
    root = _Node(data, '', 1)
    root.finish(('format', 'kind', 'description', 'text', 'time', 'sources', 'vectors',
                 'signals', 'segments'))
    fmt = root.get('format')
    if fmt != FORMAT:
        raise MapError(f'{root.where("format")}: format must be {FORMAT!r}, got {fmt!r}')
    kind = root.text('kind', kind_hint)
    if kind not in ('bag', 'text'):
        raise MapError(f'{root.where("kind")}: kind must be bag or text, got {kind!r}')
    fmt_text = None
    if kind == 'text':
        if not root.has('text'):
            raise MapError(f'{root.where()}: a text log needs text: (delimiter, header)')
        tn = root.child('text')
        tn.finish(('delimiter', 'header', 'columns', 'comment'))
        delim = tn.text('delimiter', 'whitespace')
        if delim not in DELIMITERS:
            raise MapError(f'{tn.where("delimiter")}: unknown delimiter {delim!r} '
                           f'(known: {", ".join(DELIMITERS)})')
        header = tn.get('header', True)
        cols = tn.get('columns') or []
        if not header and not cols:
            raise MapError(f'{tn.where()}: a text log without header needs columns:')
        fmt_text = TextFormat(DELIMITERS[delim], bool(header), tuple(str(c) for c in cols),
                              tn.text('comment', '#'))
    elif root.has('text'):
        raise MapError(f'{root.where("text")}: text: is for kind text')
    tm = root.child('time') if root.has('time') else _Node({}, 'time', root.line)
    tm.finish(('stamp', 'column', 'unit', 'base', 'max_age', 'offsets', 'grid', 'stamps'))
    stamp = tm.text('stamp', 'header' if kind == 'bag' else 'column')
    col = None
    factor = 1.0
    if kind == 'text':
        col = tm.text('column')
        tu = unit(tm.text('unit', 's'), str(tm.where('unit')))
        if tu.dimension != 'time':
            raise MapError(f'{tm.where("unit")}: not a time unit')
        factor = tu.factor
    elif stamp not in ('header', 'log'):
        raise MapError(f'{tm.where("stamp")}: stamp must be header or log, got {stamp!r}')
    offsets_raw = tm.get('offsets') or {}
    if not isinstance(offsets_raw, Mapping):
        raise MapError(f'{tm.where("offsets")}: expected topic: seconds')
    offsets = {}
    for k, v in offsets_raw.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise MapError(f'{tm.where("offsets")}: offset of {k} must be a number of seconds')
        offsets[str(k)] = float(v)
    stamps_raw = tm.get('stamps') or {}
    if stamps_raw and (not isinstance(stamps_raw, Mapping) or kind != 'bag'):
        raise MapError(f'{tm.where("stamps")}: stamps: is topic: header|log, for bags')
    per_topic: dict[str, str] = {}
    for k, v in stamps_raw.items():
        if v not in ('header', 'log'):
            raise MapError(f'{tm.where("stamps")}: stamps of {k} must be header or log, '
                           f'got {v!r}')
        per_topic[str(k)] = str(v)
    time_spec = TimeSpec(stamp, col, factor, tm.get('base'), tm.number('max_age', 0.0) if
                         tm.has('max_age') else 0.0, offsets,
                         tm.number('grid', positive=True) if tm.has('grid') else None,
                         per_topic)
    if time_spec.max_age < 0:
        raise MapError(f'{tm.where("max_age")}: must be >= 0 s')
    scalars: dict[str, Scalar] = {}
    vectors: list[Vector] = []
    given: dict[str, Where] = {}

    def claim(names: Sequence[str], where: Where) -> None:
        for name in names:
            if name in given:
                raise MapError(f'{where}: {name} is given twice (also {given[name]}); keep one '
                               '(a preset takes use: [...])')
            given[name] = where

    overrides = set()
    if root.has('signals'):
        sig = root.child('signals')
        overrides = {str(k) for k in sig.data}
    for node in root.items('sources'):
        vecs, scs = _preset(node, kind)
        for vec in vecs:
            claim([n for n in vec.gives if n not in overrides], vec.where)
            vectors.append(vec)
        for sc in scs:
            if sc.name not in overrides:
                claim([sc.name], sc.where)
                scalars[sc.name] = sc
    for node in root.items('vectors'):
        node.finish(('kind', 'topic', 'fields', 'columns', 'frame', 'unit', 'mounting',
                     'lever_arm', 'rate', 'resolution', 'scale'))
        kname = node.text('kind')
        if kname not in VECTOR_KINDS:
            raise MapError(f'{node.where("kind")}: unknown vector kind {kname!r} '
                           f'(known: {", ".join(VECTOR_KINDS)})')
        if kind == 'text':
            topic, fields = None, node.get('columns') or []
        else:
            topic, fields = node.text('topic'), node.get('fields') or []
        vec = _vector(kname, node, topic, list(fields), f'vector {node.key}', None)
        mounting, lever = _mounting(node, kname)
        vec = dataclasses.replace(vec, mounting=mounting, lever_arm=lever)
        claim([n for n in vec.gives if n not in overrides], vec.where)
        vectors.append(vec)
    if root.has('signals'):
        sig = root.child('signals')
        for name in sig.data:
            sc = _scalar(str(name), sig.child(str(name)), kind)
            claim([sc.name], sc.where)
            scalars[sc.name] = sc
    seg = root.child('segments') if root.has('segments') else _Node({}, 'segments', root.line)
    seg.finish(tuple(SEGMENT_DEFAULTS))
    segments: dict[str, float | None] = {}
    for k, default in SEGMENT_DEFAULTS.items():
        segments[k] = seg.number(k, positive=k != 'thrust_off') if seg.has(k) else default
    if kind == 'bag' and time_spec.base is None:
        topics = [v.topic for v in vectors if v.topic] + [
            t.topic for s in scalars.values() if s.name in STATE for t in s.terms if t.topic]
        if not topics:
            raise MapError(f'{root.where()}: no state signal mapped')
        time_spec = dataclasses.replace(time_spec, base=topics[0])
    read = {v.topic for v in vectors} | {t.topic for s in scalars.values() for t in s.terms}
    for key, names in (('offsets', time_spec.offsets), ('stamps', time_spec.stamps)):
        for name in names:      # a misspelt topic would leave its clock uncorrected
            if name not in read:
                known = ', '.join(sorted(str(t) for t in read if t)) or \
                    'a text log has no topics'
                raise MapError(f'{tm.where(key)}: {name} is not a topic the map reads '
                               f'({known})')
    if 'thrust' not in scalars:
        raise MapError(f'{root.where("signals")}: thrust is not mapped (a thrust, or a '
                       'propeller speed with law:)')
    if 'bar' not in scalars:
        raise MapError(f'{root.where("signals")}: bar is not mapped (the dive-plane command)')
    return LogMap(kind, time_spec, scalars, tuple(vectors), fmt_text,
                  segments, text, path, str(root.get('description', '') or ''))


def load_map(path: str | os.PathLike[str]) -> LogMap:
    """Read and validate a map file.

    Raises
    ------
    MapError
        the file is missing, is not YAML, or is not a valid map.
    """
    p = pathlib.Path(path)
    try:
        text = p.read_text()
    except OSError as exc:
        raise MapError(f'cannot read map {p}: {exc.strerror}') from None
    try:
        data = parse_yaml_with_lines(text, f'map {p}')
    except YamlError as exc:
        raise MapError(str(exc)) from None
    try:
        return parse_map(data, path=str(p), text=text)
    except MapError as exc:
        raise MapError(f'{p}: {exc}') from None
