"""What a user should fly to identify an effect of the catalogue or tell two apart, stated
in the terms of the vehicle's flight envelope (:class:`Envelope`: surge speed [m/s], depth
[m], rated depth [m], plane limit [rad]; the texts give speeds in m/s, depths in m and plane
angles in deg).

The keys of :data:`MANOEUVRE_TEXT` are the manoeuvres an effect's signature and
``identify_by`` name (:class:`auv_gap.catalogue.Effect`); which one separates two effects is
:func:`auv_gap.catalogue.separating_manoeuvre`.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable


@dataclasses.dataclass(frozen=True)
class Envelope:
    """Where a vehicle flies, for manoeuvres stated in its own terms: the logs' median surge
    speed ``u0`` [m/s] and depth ``z0`` [m], the file's rated depth ``depth_max`` [m] and
    plane limit ``bar_max`` [rad]. The default is a 2 m/s survey vehicle at 60 m."""

    u0: float = 2.0
    z0: float = 60.0
    depth_max: float = 300.0
    bar_max: float = 0.4363

    def speeds(self) -> tuple[float, float]:
        """A speed change around ``u0``: 0.7 and 1.3 times it [m/s]."""
        return 0.7 * self.u0, 1.3 * self.u0

    def excursion(self) -> tuple[float, float]:
        """A depth excursion from ``z0`` [m]: by half the depth flown (at least 2 m) and no
        deeper than half the rated depth: ``(z0, z1)``."""
        dz = max(2.0, 0.5 * self.z0)
        z1 = min(self.z0 + dz, max(self.z0 + 1.0, 0.5 * self.depth_max))
        return self.z0, z1


def _deg(a: float) -> str:
    return f'{math.degrees(a):.0f}'


#: Manoeuvres that separate or identify effects, with what a user should fly, in the terms of
#: the vehicle's :class:`Envelope`. An effect's signature gives, per manoeuvre, the exponent
#: with which its depth/pitch signature scales (see Effect).
MANOEUVRE_TEXT: dict[str, Callable[[Envelope], str]] = {
    'speed change': lambda e: (
        'a speed change at constant plane angle (thrust steps giving about '
        f'{e.speeds()[0]:.2g} -> {e.speeds()[1]:.2g} m/s; the logs fly at {e.u0:.2g} m/s), '
        'holding each speed for a minute or more'),
    'depth excursion': lambda e: (
        f'a depth excursion from about {e.excursion()[0]:.2g} to {e.excursion()[1]:.2g} m '
        '(dive and climb at constant speed), holding each depth for a minute'),
    'heading change': lambda e: 'a heading change of 90 to 180 deg at constant depth and speed',
    'plane steps of several sizes': lambda e: (
        f'BAR steps of several sizes ({_deg(0.1 * e.bar_max)} to {_deg(0.6 * e.bar_max)} '
        'deg) at one speed'),
    'plane doublets of several periods': lambda e: (
        'BAR doublets of several periods (2 to 20 s) at one speed'),
    'short plane doublets': lambda e: (
        f'short BAR doublets (1 to 3 s half period, {_deg(0.2 * e.bar_max)} deg) at one '
        'speed: a delay shifts the response by the same time whatever the period'),
    'large fast plane steps': lambda e: (
        f'large, fast BAR steps ({_deg(0.5 * e.bar_max)} deg and more, both ways) at one '
        'speed: a rate limit shows only in fast, large moves'),
    'surface reference': lambda e: (
        'a pass at the surface (the depth sensor reads its zero there) or a fix against a '
        'known depth (the dynamics alone cannot see a constant depth offset)'),
    'thruster-off coast': lambda e: (
        f'a thruster-off coast at depth (about {max(e.z0, 2.0):.2g} m: stop the propeller '
        'for 30 to 60 s with the planes at zero): the vehicle slows, then rises or sinks at '
        'its net buoyancy and hangs at the pitch its centre of gravity gives'),
    'repeated leg': lambda e: (
        'the same straight leg at constant depth and speed flown at the start and at the end '
        'of the mission (an hour or more apart), in both directions'),
}
#: The manoeuvres in the terms of the default :class:`Envelope`.
MANOEUVRES: dict[str, str] = {k: f(Envelope()) for k, f in MANOEUVRE_TEXT.items()}


def manoeuvre(key: str, envelope: Envelope | None = None) -> str:
    """What to fly for manoeuvre ``key``, in the terms of ``envelope``."""
    return MANOEUVRE_TEXT[key](envelope or Envelope())
