"""What physics allows an identified coefficient to be: its sign and range, with the source.

A fitted value outside these is not an answer, so the fit is constrained to them (bounded
least squares, :mod:`auv_ident.identify.posterior`), and a coefficient that ends on a bound
is reported with what that suggests (:func:`at_bound_note`): the data push it past what the
physics allows, so something the model does not contain is being absorbed.

Coefficients (body FRD about the centre of buoyancy, velocities through the water; the
model's terms in :func:`auv_sim.model.hydro_basis`):

* ``Ksh`` > 0: the axial drag opposes the motion (ITTC-1957 friction line times a positive
  form factor);
* ``CZuw``, ``CYuv`` <= 0: the normal force of the hull and fins opposes the cross-flow
  (slender-body and fin lift; Prestero 2001, section 3.4-3.6, Zuw and Yuv < 0);
* ``CMuq``, ``CNur`` <= 0: pitch and yaw damping, the fins aft and the hull resist a rotation
  (Prestero 2001, Muq and Nur < 0 once the added-mass part, which the model computes, is
  taken out);
* ``Zww``, ``Yvv``, ``Mqq``, ``Nrr`` <= 0: quadratic cross-flow drag opposes the cross-flow
  or the rotation (drag coefficient > 0 at every strip of the hull; Prestero 2001, 3.3);
* ``CZbar``, ``CMbar``: the sign of the base file's ``CZbar`` (the sign convention of the
  BAR angle); ``CMbar`` has the sign the plane's lever arm gives it,
  ``CMbar = -(x_plane / L) CZbar``: the same as ``CZbar`` for planes aft of the centre of
  buoyancy (``x_plane < 0``), the opposite for bow planes, read off the base file's pair;
* ``CZuq``, ``CMuw``, ``CYur``, ``CNuv``, ``CZ0``, ``CM0``: either sign (the hull's lift
  moment against the fins', the fins' lever arm, a hull's asymmetry); no bound.

Ranges are the sign bounds; the magnitude is held by the coefficient's prior
(:mod:`auv_ident.identify.priors`), not by a bound.
"""
from __future__ import annotations

import math
from typing import NamedTuple

from auv_sim.params import VehicleParams


class Constraint(NamedTuple):
    """The range physics allows a coefficient and why."""

    lo: float                # lower bound (-inf: none)
    hi: float                # upper bound (+inf: none)
    source: str              # why (the physics and its reference)


_NEG = (-math.inf, 0.0)
_POS = (0.0, math.inf)
_FREE = (-math.inf, math.inf)
_DAMPING = ('pitch and yaw damping: the fins aft and the hull resist a rotation '
            '(Prestero 2001, Muq, Nur < 0 without the added-mass part)')
_LIFT = ('the normal force of hull and fins opposes the cross-flow (slender-body and fin '
         'lift; Prestero 2001, 3.4-3.6: Zuw, Yuv < 0)')
_CROSSFLOW = ('quadratic cross-flow drag opposes the cross-flow (drag coefficient > 0 on '
              'every strip of the hull; Prestero 2001, 3.3)')
_EITHER = 'either sign (hull lift moment against the fins\', a lever arm, an asymmetry)'

_FIXED_SIGN: dict[str, tuple[tuple[float, float], str]] = {
    'Ksh': (_POS, 'axial drag opposes the motion (ITTC-1957 friction line times a form '
                  'factor > 0)'),
    'CZuw': (_NEG, _LIFT), 'CYuv': (_NEG, _LIFT),
    'CMuq': (_NEG, _DAMPING), 'CNur': (_NEG, _DAMPING),
    'Zww': (_NEG, _CROSSFLOW), 'Yvv': (_NEG, _CROSSFLOW),
    'Mqq': (_NEG, _CROSSFLOW), 'Nrr': (_NEG, _CROSSFLOW),
}
#: Coefficients whose sign physics leaves open.
EITHER_SIGN = ('CZuq', 'CMuw', 'CYur', 'CNuv', 'CZ0', 'CM0')
#: The term each quadratic cross-flow coefficient competes with in its equation.
QUADRATIC_PARTNER = {'Zww': 'CZuw', 'Mqq': 'CMuq', 'Yvv': 'CYuv', 'Nrr': 'CNur'}


def constraint(name: str, base: VehicleParams) -> Constraint:
    """The physical range of coefficient ``name`` (see the module docstring); the plane's
    signs are read off ``base``."""
    if name in _FIXED_SIGN:
        (lo, hi), why = _FIXED_SIGN[name]
        return Constraint(lo, hi, why)
    if name in ('CZbar', 'CMbar'):
        zb, mb = base.values['CZbar'], base.values['CMbar']
        if name == 'CZbar':
            lo, hi = _POS if zb > 0 else _NEG
            return Constraint(lo, hi, f'the sign of the base file\'s CZbar ({zb:+.3g} 1/rad): '
                                      'the BAR angle\'s sign convention')
        if zb == 0.0 or mb == 0.0:
            return Constraint(-math.inf, math.inf, 'no plane lever arm in the base file')
        arm = -mb / zb * base.values['L_ref']
        where = 'aft of' if arm < 0 else 'forward of'
        lo, hi = _POS if mb > 0 else _NEG
        return Constraint(lo, hi, f'the plane sits {where} the centre of buoyancy (lever arm '
                                  f'{arm:+.3g} m from the base file\'s CMbar / CZbar): '
                                  'CMbar = -(x_plane / L) CZbar')
    return Constraint(-math.inf, math.inf, _EITHER)


def constraints(names: tuple[str, ...] | list[str], base: VehicleParams
                ) -> dict[str, Constraint]:
    """:func:`constraint` of every name."""
    return {n: constraint(n, base) for n in names}


def at_bound_note(name: str, value: float, con: Constraint) -> str:
    """What a coefficient stopped on its bound suggests, in one sentence."""
    side = 'past 0' if value == 0.0 else f'past {value:g}'
    if name in QUADRATIC_PARTNER.values() or name in ('CZuw', 'CYuv'):
        hint = ('see: the quadratic cross-flow terms (their file values may be far off; '
                'the structure chosen), an unmodelled current, a plane weaker than the file')
    elif name in QUADRATIC_PARTNER:
        hint = (f'see: the linear term {QUADRATIC_PARTNER[name]} it competes with; a '
                'cross-flow drag of this sign needs no quadratic term here')
    elif name == 'Ksh':
        hint = 'see: the thrust (logged values, the thrust map), a current along the track'
    elif name in ('CZbar', 'CMbar'):
        hint = 'see: the BAR sign convention of the logs, the plane\'s position'
    else:
        hint = 'see: the other coefficients of its equation'
    return (f'the data push {name} {side}: the model\'s structure cannot express what the '
            f'vehicle does ({hint}); {con.source}')
