"""Vehicle parameter files: load, validate, pack for the model, write back.

A vehicle file (``config/*.yaml``) holds, section by section, every parameter as a mapping
``{value, unit, source}``. Frames and conventions: body frame FRD with its origin at the
centre of buoyancy, world frame NED, Fossen's signs for added mass (``Zwdot < 0``).
Hydrodynamic coefficients are dimensionless, scaled by ``1/2 rho S_ref`` (forces) and
``1/2 rho S_ref L_ref`` (moments), as in the report's section 2; the optional quadratic
cross-flow drag (section ``crossflow``, see :data:`OPTIONAL`) is dimensional, as Prestero's.
"""
from __future__ import annotations

import dataclasses
import math
import pathlib
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import yaml

from auv_contract import YamlError, parse_yaml
from auv_sim.errors import ParameterError

if TYPE_CHECKING:
    import numpy as np

# name -> (section, unit, check). The order is the packing order of the model vector.
POSITIVE: Callable[[float], bool] = lambda v: v > 0.0  # noqa: E731
NON_NEGATIVE: Callable[[float], bool] = lambda v: v >= 0.0  # noqa: E731
NON_POSITIVE: Callable[[float], bool] = lambda v: v <= 0.0  # noqa: E731
ANY: Callable[[float], bool] = lambda v: True  # noqa: E731
_CHECK_TEXT = {POSITIVE: 'must be > 0', NON_NEGATIVE: 'must be >= 0',
               NON_POSITIVE: 'must be <= 0', ANY: ''}

SCHEMA: dict[str, tuple[str, str, Callable[[float], bool]]] = {
    # environment
    'rho': ('environment', 'kg/m^3', POSITIVE),
    'nu_water': ('environment', 'm^2/s', POSITIVE),
    'g': ('environment', 'm/s^2', POSITIVE),
    # geometry
    'L_ref': ('geometry', 'm', POSITIVE),
    'S_ref': ('geometry', 'm^2', POSITIVE),
    'diameter': ('geometry', 'm', POSITIVE),
    # mass and inertia (inertia about the body origin = centre of buoyancy)
    'm': ('mass', 'kg', POSITIVE),
    'B': ('mass', 'N', POSITIVE),
    'xg': ('mass', 'm', ANY),
    'yg': ('mass', 'm', ANY),
    'zg': ('mass', 'm', ANY),
    'xb': ('mass', 'm', ANY),
    'yb': ('mass', 'm', ANY),
    'zb': ('mass', 'm', ANY),
    'Ix': ('mass', 'kg m^2', POSITIVE),
    'Iy': ('mass', 'kg m^2', POSITIVE),
    'Iz': ('mass', 'kg m^2', POSITIVE),
    'Ixz': ('mass', 'kg m^2', ANY),
    # added mass (Fossen's signs)
    'Xudot': ('added_mass', 'kg', NON_POSITIVE),
    'Yvdot': ('added_mass', 'kg', NON_POSITIVE),
    'Zwdot': ('added_mass', 'kg', NON_POSITIVE),
    'Kpdot': ('added_mass', 'kg m^2', NON_POSITIVE),
    'Mqdot': ('added_mass', 'kg m^2', NON_POSITIVE),
    'Nrdot': ('added_mass', 'kg m^2', NON_POSITIVE),
    'Yrdot': ('added_mass', 'kg m', ANY),
    'Zqdot': ('added_mass', 'kg m', ANY),
    # hydrodynamic damping, lift and drag (report section 2)
    'Ksh': ('hydrodynamics', '-', POSITIVE),
    'CZ0': ('hydrodynamics', '-', ANY),
    'CZuw': ('hydrodynamics', '-', ANY),
    'CZuq': ('hydrodynamics', '-', ANY),
    'CM0': ('hydrodynamics', '-', ANY),
    'CMuw': ('hydrodynamics', '-', ANY),
    'CMuq': ('hydrodynamics', '-', ANY),
    'CYuv': ('hydrodynamics', '-', ANY),
    'CYur': ('hydrodynamics', '-', ANY),
    'CNuv': ('hydrodynamics', '-', ANY),
    'CNur': ('hydrodynamics', '-', ANY),
    'CLup': ('hydrodynamics', '-', NON_POSITIVE),
    # quadratic cross-flow drag, dimensional as Prestero (2001) gives them (optional, 0)
    'Yvv': ('crossflow', 'kg/m', NON_POSITIVE),
    'Yrr': ('crossflow', 'kg m', ANY),
    'Zww': ('crossflow', 'kg/m', NON_POSITIVE),
    'Zqq': ('crossflow', 'kg m', ANY),
    'Mww': ('crossflow', 'kg', ANY),
    'Mqq': ('crossflow', 'kg m^2', NON_POSITIVE),
    'Nvv': ('crossflow', 'kg', ANY),
    'Nrr': ('crossflow', 'kg m^2', NON_POSITIVE),
    # control surfaces: dive plane (BAR) and helm (rudder)
    'CZbar': ('control_surfaces', '1/rad', ANY),
    'CMbar': ('control_surfaces', '1/rad', ANY),
    'CYhelm': ('control_surfaces', '1/rad', ANY),
    'CNhelm': ('control_surfaces', '1/rad', ANY),
    # actuators
    'bar_max': ('actuators', 'rad', POSITIVE),
    'bar_rate': ('actuators', 'rad/s', POSITIVE),
    'bar_tau': ('actuators', 's', POSITIVE),
    'helm_max': ('actuators', 'rad', POSITIVE),
    'helm_rate': ('actuators', 'rad/s', POSITIVE),
    'helm_tau': ('actuators', 's', POSITIVE),
    'thrust_max': ('actuators', 'N', POSITIVE),
    'thrust_min': ('actuators', 'N', NON_POSITIVE),
    'thrust_tau': ('actuators', 's', POSITIVE),
    # operating envelope
    'depth_min': ('envelope', 'm', NON_NEGATIVE),
    'depth_max': ('envelope', 'm', POSITIVE),
    # simulation
    'dt': ('simulation', 's', POSITIVE),
}
PARAM_NAMES: tuple[str, ...] = tuple(SCHEMA)
#: Parameters a vehicle file may leave out, with the value they then take. The quadratic
#: cross-flow drag (body FRD, about the body origin; velocities through the water)::
#:
#:     Y += Yvv v|v| + Yrr r|r|      Z += Zww w|w| + Zqq q|q|
#:     M += Mww w|w| + Mqq q|q|      N += Nvv v|v| + Nrr r|r|
#:
#: is Prestero's (2001, section 3.3, tables B.1 and B.2) with his signs; a vehicle without it
#: (a fit of linear terms only) simply has none.
OPTIONAL: dict[str, float] = {name: 0.0 for name, (sec, _, _) in SCHEMA.items()
                              if sec == 'crossflow'}
SECTIONS: tuple[str, ...] = tuple(dict.fromkeys(s for s, _, _ in SCHEMA.values()))


@dataclasses.dataclass(frozen=True)
class VehicleParams:
    """Validated parameters of one vehicle (SI units, radians; FRD body, origin at the CB).

    ``values`` maps every name of :data:`SCHEMA` to its value; ``sources`` and ``units`` keep
    the file's provenance so that a written-back file loses nothing.
    """

    name: str
    values: dict[str, float]
    sources: dict[str, str]
    path: str = '<memory>'
    description: str = ''
    provenance: dict[str, Any] = dataclasses.field(default_factory=dict)

    def __getattr__(self, key: str) -> float:
        values = self.__dict__.get('values')
        if values is not None and key in values:
            return float(values[key])
        raise AttributeError(key)

    @property
    def W(self) -> float:
        """Weight m g [N]."""
        return self.values['m'] * self.values['g']

    def replace(self, **changes: float) -> VehicleParams:
        """A copy with some values changed (validated again)."""
        for key in changes:
            if key not in SCHEMA:
                raise ParameterError(f'unknown vehicle parameter {key!r}')
        values = {**self.values, **{k: float(v) for k, v in changes.items()}}
        _validate(values, self.path)
        return dataclasses.replace(self, values=values)

    def as_array(self) -> np.ndarray:
        """Parameter vector in :data:`PARAM_NAMES` order, then the inverse mass matrix (36)."""
        import numpy as np  # not for loading a file (``auv launch`` checks it, numpy-free)

        vec = np.array([self.values[k] for k in PARAM_NAMES], dtype=np.float64)
        minv = np.linalg.inv(mass_matrix(self))
        return np.concatenate([vec, minv.ravel()])


def mass_matrix(params: VehicleParams) -> np.ndarray:
    """Rigid-body plus added mass ``M = M_RB + M_A`` (6x6) about the body origin, FRD.

    ``M_RB = [[m I, -m S(r_g)], [m S(r_g), I_o]]`` with the inertia ``I_o`` about the origin
    (Fossen 2011, eq. 3.44); ``M_A = -[[Xudot..]]`` with the sway-yaw and heave-pitch cross
    terms ``Yrdot = Nvdot`` and ``Zqdot = Mwdot`` (symmetric M_A).
    """
    import numpy as np  # not for loading a file (``auv launch`` checks it, numpy-free)

    v = params.values
    m = v['m']
    rg = np.array([v['xg'], v['yg'], v['zg']])
    s_rg = np.array([[0.0, -rg[2], rg[1]], [rg[2], 0.0, -rg[0]], [-rg[1], rg[0], 0.0]])
    inertia = np.array([[v['Ix'], 0.0, -v['Ixz']], [0.0, v['Iy'], 0.0], [-v['Ixz'], 0.0, v['Iz']]])
    m_rb = np.zeros((6, 6))
    m_rb[:3, :3] = m * np.eye(3)
    m_rb[:3, 3:] = -m * s_rg
    m_rb[3:, :3] = m * s_rg
    m_rb[3:, 3:] = inertia
    m_a = -np.diag([v['Xudot'], v['Yvdot'], v['Zwdot'], v['Kpdot'], v['Mqdot'], v['Nrdot']])
    m_a[1, 5] = m_a[5, 1] = -v['Yrdot']
    m_a[2, 4] = m_a[4, 2] = -v['Zqdot']
    return m_rb + m_a


def _validate(values: dict[str, float], path: str) -> None:
    for key, (section, unit, check) in SCHEMA.items():
        if key not in values and key in OPTIONAL:
            values[key] = OPTIONAL[key]
        elif key not in values:
            raise ParameterError(f'{path}: missing parameter {section}.{key} [{unit}]')
        value = values[key]
        if not math.isfinite(value):
            raise ParameterError(f'{path}: {section}.{key} = {value} is not finite')
        if not check(value):
            raise ParameterError(
                f'{path}: {section}.{key} = {value} {_CHECK_TEXT[check]} [{unit}]')
    if values['depth_max'] <= values['depth_min']:
        raise ParameterError(f'{path}: envelope.depth_max must exceed envelope.depth_min')
    if values['bar_tau'] < values['dt'] or values['helm_tau'] < values['dt']:
        raise ParameterError(f'{path}: actuator time constants must be >= simulation.dt')


def _number(raw: Any, where: str) -> float:
    if isinstance(raw, dict):
        if 'value' not in raw:
            raise ParameterError(f'{where} has no "value"')
        raw = raw['value']
    if isinstance(raw, bool) or not isinstance(raw, (int, float)):
        raise ParameterError(f'{where} = {raw!r} is not a number')
    return float(raw)


def parse_vehicle(doc: Any, path: str = '<memory>') -> VehicleParams:
    """Build validated parameters from a parsed vehicle document (see module docstring)."""
    if not isinstance(doc, dict):
        raise ParameterError(f'{path}: a vehicle file must be a mapping of sections')
    values: dict[str, float] = {}
    sources: dict[str, str] = {}
    for section in SECTIONS:
        block = doc.get(section)
        if block is None and all(k in OPTIONAL for k, v in SCHEMA.items() if v[0] == section):
            continue
        if block is None:
            raise ParameterError(f'{path}: missing section {section!r}')
        if not isinstance(block, dict):
            raise ParameterError(f'{path}: section {section!r} must be a mapping')
        for key, raw in block.items():
            if key not in SCHEMA or SCHEMA[key][0] != section:
                raise ParameterError(f'{path}: unknown parameter {section}.{key}')
            values[key] = _number(raw, f'{path}: {section}.{key}')
            if isinstance(raw, dict):
                sources[key] = str(raw.get('source', ''))
                unit = raw.get('unit')
                if unit is not None and str(unit) != SCHEMA[key][1]:
                    raise ParameterError(
                        f'{path}: {section}.{key} is in {unit!r}, expected {SCHEMA[key][1]!r}')
    _validate(values, path)
    return VehicleParams(name=str(doc.get('vehicle', pathlib.Path(path).stem)), values=values,
                         sources=sources, path=path,
                         description=str(doc.get('description', '')),
                         provenance=dict(doc.get('provenance') or {}))


def load_vehicle(path: str | pathlib.Path) -> VehicleParams:
    """Load and validate a vehicle file; any defect raises ParameterError naming file and key."""
    path = pathlib.Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ParameterError(f'cannot read vehicle file {path}: {exc.strerror}') from None
    try:
        doc = parse_yaml(text, str(path))
    except YamlError as exc:
        raise ParameterError(str(exc)) from None
    return parse_vehicle(doc, str(path))


def vehicle_document(params: VehicleParams, *, sources: dict[str, str] | None = None,
                     provenance: dict[str, Any] | None = None) -> dict[str, Any]:
    """The vehicle file's document for ``params`` (same format as ``config/a18m.yaml``)."""
    doc: dict[str, Any] = {'vehicle': params.name}
    if params.description:
        doc['description'] = params.description
    merged_sources = {**params.sources, **(sources or {})}
    for section in SECTIONS:
        doc[section] = {
            key: {'value': params.values[key], 'unit': unit,
                  'source': merged_sources.get(key, '')}
            for key, (sec, unit, _) in SCHEMA.items() if sec == section}
    prov = {**params.provenance, **(provenance or {})}
    if prov:
        doc['provenance'] = prov
    return doc


def save_vehicle(params: VehicleParams, path: str | pathlib.Path, **kwargs: Any) -> None:
    """Write ``params`` as a vehicle file (see :func:`vehicle_document`)."""
    text = yaml.safe_dump(vehicle_document(params, **kwargs), sort_keys=False, width=120,
                          default_flow_style=None)
    pathlib.Path(path).write_text(text)
