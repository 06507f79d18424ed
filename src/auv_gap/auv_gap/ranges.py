"""The typical and possible ranges of the catalogue's parameters, from a user-editable file.

A fitted effect parameter is judged against two ranges (see
:class:`auv_gap.catalogue.Parameter`): *typical* (a well-ballasted, well-rigged survey
AUV; beyond it the value is *atypical*: a finding named with "beyond the typical range:
check ...", never an unchecked explanation) and *possible* (what physics allows; beyond it
the fit is no explanation at all). The defaults live in ``config/plausible_ranges.yaml``; a
user who knows the vehicle better edits a copy and gives it to ``auv gap --ranges FILE``.

File format (``format: auv-plausible-ranges/1``)::

    effects:
      buoyancy_offset:
        dB: {typical: [-0.02, 0.02], possible: [-0.15, 0.15], per: W, check: '...',
             source: '...'}

``typical`` and ``possible`` are ``[lo, hi]`` in the parameter's unit times ``per``: ``W``
(the vehicle's weight [N]), ``L`` (hull length [m]), ``D`` (diameter [m]), ``crossflow_z``
(``1/2 rho D L`` [kg/m]: a cross-flow drag coefficient of 1), ``crossflow_m`` (``1/2 rho D
L^4 / 32`` [kg m^2]), or nothing (the unit itself). ``check`` says what to check when a fit
is atypical; ``source`` where the range comes from. An effect or parameter the file does not
name keeps the catalogue's built-in ranges.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import pathlib
from collections.abc import Mapping, Sequence
from typing import Any

from auv_contract import config_path, read_yaml_file
from auv_gap.catalogue import CATALOGUE, Parameter, crossflow_unit
from auv_gap.errors import GapError
from auv_sim.environment import EFFECT_FIELDS
from auv_sim.params import VehicleParams

FORMAT = 'auv-plausible-ranges/1'
DEFAULT_PATH = config_path('plausible_ranges.yaml')
PER = ('W', 'L', 'D', 'crossflow_z', 'crossflow_m', '')


@dataclasses.dataclass(frozen=True)
class Entry:
    """One parameter's ranges as the file gives them (in units of ``per``)."""

    typical: tuple[float, float] | None
    possible: tuple[float, float] | None
    per: str
    check: str
    source: str


@dataclasses.dataclass(frozen=True)
class Ranges:
    """The ranges of a file: effect -> parameter -> :class:`Entry`."""

    path: str
    entries: Mapping[str, Mapping[str, Entry]]

    def apply(self, effect: str, params: Sequence[Parameter], vehicle: VehicleParams
              ) -> tuple[Parameter, ...]:
        """``params`` of ``effect`` with the file's ranges for ``vehicle`` (scaled by
        ``per``); parameters the file does not name are returned as they are."""
        given = self.entries.get(effect, {})
        out = []
        for p in params:
            e = given.get(p.name)
            if e is None:
                out.append(p)
                continue
            k = _per(e.per, vehicle)
            change: dict[str, Any] = {}
            if e.typical is not None:
                change['plausible'] = (e.typical[0] * k, e.typical[1] * k)
            if e.possible is not None:
                change['possible'] = (e.possible[0] * k, e.possible[1] * k)
            if e.check:
                change['check'] = e.check
            if e.source:
                change['source'] = e.source
            out.append(dataclasses.replace(p, **change))
        return tuple(out)


def _per(per: str, vehicle: VehicleParams) -> float:
    """The scale [SI] a range given ``per`` a vehicle quantity is multiplied by."""
    if per == 'W':
        return float(vehicle.W)
    if per == 'L':
        return float(vehicle.L_ref)
    if per == 'D':
        return float(vehicle.diameter)
    if per == 'crossflow_z':
        return crossflow_unit(vehicle)[0]
    if per == 'crossflow_m':
        return crossflow_unit(vehicle)[1]
    return 1.0


def _pair(raw: Any, where: str) -> tuple[float, float] | None:
    if raw is None:
        return None
    if not (isinstance(raw, Sequence) and not isinstance(raw, str) and len(raw) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                    for v in raw) and raw[0] < raw[1]):
        raise GapError(f'{where}: expected [lo, hi] with lo < hi, got {raw!r}')
    return float(raw[0]), float(raw[1])


def parse_ranges(doc: Any, path: str) -> Ranges:
    """Validate a loaded ranges document.

    Raises
    ------
    GapError
        one line naming the file and the key (unknown effect, parameter or key,
        a range that is not [lo, hi], a typical range outside the possible one).
    """
    if not isinstance(doc, Mapping) or doc.get('format') != FORMAT:
        raise GapError(f'{path}: not a ranges file (format: {FORMAT} expected)')
    unknown = set(doc) - {'format', 'description', 'effects'}
    if unknown:
        raise GapError(f'{path}: unknown key(s) {sorted(unknown)} (known: format, description, '
                       'effects)')
    effects = doc.get('effects') or {}
    if not isinstance(effects, Mapping):
        raise GapError(f'{path}: effects: expected a mapping of effect names')
    out: dict[str, dict[str, Entry]] = {}
    for name, params in effects.items():
        if name not in CATALOGUE:
            raise GapError(f'{path}: effects.{name}: unknown effect (known: '
                           f'{", ".join(CATALOGUE)})')
        if not isinstance(params, Mapping):
            raise GapError(f'{path}: effects.{name}: expected parameter: {{typical: ...}}')
        out[str(name)] = {}
        fields = EFFECT_FIELDS.get(str(name), {})
        for pname, spec in params.items():
            where = f'{path}: effects.{name}.{pname}'
            if pname not in fields:
                raise GapError(f'{where}: unknown parameter (known: {", ".join(fields)})')
            if not isinstance(spec, Mapping):
                raise GapError(f'{where}: expected {{typical: [lo, hi], ...}}')
            bad = set(spec) - {'typical', 'possible', 'per', 'unit', 'check', 'source'}
            if bad:
                raise GapError(f'{where}: unknown key(s) {sorted(bad)} (known: typical, '
                               'possible, per, unit, check, source)')
            unit = spec.get('unit')
            if unit is not None and str(unit) != fields[pname][0]:
                raise GapError(f'{where}.unit: {unit!r}, but {name}.{pname} is in '
                               f'{fields[pname][0]!r}')
            per = str(spec.get('per') or '')
            if per not in PER:
                raise GapError(f'{where}.per: unknown {per!r} (known: W, L, D, crossflow_z, '
                               'crossflow_m, or none)')
            typ = _pair(spec.get('typical'), f'{where}.typical')
            pos = _pair(spec.get('possible'), f'{where}.possible')
            if typ is not None and pos is not None and not (pos[0] <= typ[0] and typ[1] <= pos[1]):
                raise GapError(f'{where}: the typical range {list(typ)} is not inside the '
                               f'possible range {list(pos)}')
            out[str(name)][str(pname)] = Entry(typ, pos, per, str(spec.get('check') or ''),
                                               str(spec.get('source') or ''))
    return Ranges(path, out)


def load_ranges(path: str | pathlib.Path) -> Ranges:
    """Read a ranges file (see the module docstring).

    Raises
    ------
    GapError
        a missing or invalid file, one line.
    """
    p = pathlib.Path(path)
    return parse_ranges(read_yaml_file(p, 'ranges file', GapError), str(p))


@functools.lru_cache(maxsize=1)
def default_ranges() -> Ranges:
    """The ranges of ``config/plausible_ranges.yaml`` (the catalogue's built-in ones when the
    file is not there, e.g. an installed package without the repository's config)."""
    if not DEFAULT_PATH.is_file():
        return Ranges('(built in)', {})
    return load_ranges(DEFAULT_PATH)
