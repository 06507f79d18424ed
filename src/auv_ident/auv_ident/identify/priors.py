"""What is known of a coefficient before the logs: its prior, from the base file's value and
the source the file gives for it.

Every fitted coefficient starts from its file value ``mean`` with a standard deviation set by
how that value was obtained (the ``source`` text of the vehicle file):

| source says | kind | standard deviation |
| --- | --- | --- |
| ``identified ... +-X (95 %)`` (an earlier ``auv ident``) | ``identified`` | ``X / 1.96`` |
| ``measured`` (a tank or sea test of this vehicle) | ``measured`` | 10 % of the value |
| ``calibrated``, ``derived``, a publication's table, ``axial symmetry`` | ``published`` | 30 % |
| ``estimated``, ``assumed``, nothing | ``estimated`` | 100 % |

The quadratic cross-flow terms are ``estimated``-class (100 %) unless measured or
identified: a published value is seldom better (Prestero's ``Mqq`` of the REMUS 100 is 25
times the strip theory of its hull, his ``Zww`` within 2 % of it), and a prior narrower than
the spread of published values would hold the fit at a wrong file value.
And never below a physical scale of the coefficient (:func:`physical_scale`), so that no
prior is of zero width, not even for a file value of 0: for the quadratic cross-flow terms the
strip-theory value of the file's hull (:func:`auv_sim.hull.crossflow_coefficients`); for the
dimensionless lift and damping coefficients 0.1 (0.01 for the offsets ``CZ0``, ``CM0``),
assumed, about 3-20 % of the coefficients of the vehicles in ``config/``; for the plane, 5 %
of its file value; for a ``measured`` or ``identified`` value 1 % of these (its own width
counts).

The fit is the posterior of these priors and the data (:mod:`auv_ident.identify.posterior`):
a coefficient the data do not inform stays at its prior, and the report says so.
"""
from __future__ import annotations

import math
import re
from typing import NamedTuple

from auv_sim.hull import CD_CROSSFLOW, crossflow_coefficients
from auv_sim.params import VehicleParams


class Prior(NamedTuple):
    """Gaussian prior of one coefficient (the file's units)."""

    mean: float
    sd: float
    kind: str      # 'identified', 'measured', 'published' or 'estimated'
    why: str       # how the width was set


#: Relative standard deviation by kind of source.
RELATIVE_SD = {'measured': 0.10, 'published': 0.30, 'estimated': 1.00}
#: Floor of the standard deviation of the dimensionless coefficients (assumed, see module).
DIMENSIONLESS_FLOOR = 0.1
OFFSET_FLOOR = 0.01
PLANE_FLOOR = 0.05
#: The floor's share for a measured or identified value (its own width counts; the floor
#: only keeps it above zero).
MEASURED_FLOOR = 0.01
CROSSFLOW = ('Yvv', 'Yrr', 'Zww', 'Zqq', 'Mww', 'Mqq', 'Nvv', 'Nrr')
_INTERVAL = re.compile(r'\+-\s*([0-9.eE+-]+)\s*\(95 %\)')


def source_kind(source: str) -> tuple[str, float | None]:
    """The kind of a vehicle-file source text and, for an identified value, the half-width
    of its 95 % interval (None otherwise)."""
    text = source.strip().lower()
    if text.startswith('identified'):
        m = _INTERVAL.search(source)
        if m:
            try:
                half = float(m.group(1))
            except ValueError:
                half = math.nan
            if math.isfinite(half) and half > 0:
                return 'identified', half
        return 'published', None
    if text.startswith('measured') or ' measured' in text[:40]:
        return 'measured', None
    if not text or text.startswith(('estimated', 'assumed', 'set to 0', 'scaled')):
        return 'estimated', None
    return 'published', None


def physical_scale(name: str, base: VehicleParams) -> float:
    """The floor of a coefficient's prior standard deviation (module docstring), > 0."""
    if name in CROSSFLOW:
        strip = crossflow_coefficients(base.L_ref, base.diameter, base.rho, CD_CROSSFLOW)
        return max(abs(strip[name]), 1e-6 * abs(strip['Zww']) * base.L_ref ** 2, 1e-9)
    if name in ('CZ0', 'CM0'):
        return OFFSET_FLOOR
    if name in ('CZbar', 'CMbar'):
        return max(PLANE_FLOOR * abs(base.values[name]), 1e-6)
    if name == 'Ksh':
        return 0.05 * max(abs(base.values['Ksh']), 1.0)
    return DIMENSIONLESS_FLOOR


def prior(name: str, base: VehicleParams) -> Prior:
    """The prior of coefficient ``name`` from ``base`` (see the module docstring)."""
    mean = float(base.values[name])
    source = base.sources.get(name, '')
    kind, half = source_kind(source)
    floor = physical_scale(name, base)
    if kind in ('measured', 'identified'):
        floor *= MEASURED_FLOOR
    if kind == 'identified' and half is not None:
        sd = half / 1.96
        why = f'identified earlier: +-{half:.3g} (95 %) in the file'
    else:
        rel = RELATIVE_SD[kind]
        if name in CROSSFLOW and kind == 'published':
            rel = RELATIVE_SD['estimated']
        sd = rel * abs(mean)
        why = f'{kind} ({source[:60] or "no source"}): {rel:.0%} of the file value'
    if sd < floor:
        what = ('strip theory of the file\'s hull' if name in CROSSFLOW
                else 'the coefficient\'s physical scale')
        why += f'; at least {floor:.3g} ({what})'
        sd = floor
    return Prior(mean=mean, sd=float(sd), kind=kind, why=why)


def priors(names: tuple[str, ...] | list[str], base: VehicleParams) -> dict[str, Prior]:
    """:func:`prior` of every name."""
    return {n: prior(n, base) for n in names}
