"""Units of logged quantities and their conversion to SI (metres, radians, seconds, newtons,
pascals, revolutions per second).

Every unit belongs to one *dimension*; a contract signal accepts only units of its own
dimension (a pitch in ``cm`` is an error, not a silent mistake). Conversion is a pure factor:
``si = factor * raw`` (no unit here has an offset).
"""
from __future__ import annotations

import math
from typing import NamedTuple

from auv_logs.errors import MapError


class Unit(NamedTuple):
    """A unit: its dimension and the factor to the SI unit of that dimension."""

    dimension: str
    factor: float


_DEG = math.pi / 180.0
#: Known units: name -> (dimension, factor to SI). Sources: SI brochure (BIPM, 9th ed.) and
#: NIST SP 811 for knot (1852/3600 m/s), kgf (9.80665 N), lbf (4.448222 N), psi (6894.757 Pa).
UNITS: dict[str, Unit] = {
    # length (m)
    'm': Unit('length', 1.0), 'cm': Unit('length', 0.01), 'mm': Unit('length', 1e-3),
    'km': Unit('length', 1e3), 'ft': Unit('length', 0.3048),
    # angle (rad)
    'rad': Unit('angle', 1.0), 'deg': Unit('angle', _DEG), 'mrad': Unit('angle', 1e-3),
    # linear speed (m/s)
    'm/s': Unit('speed', 1.0), 'cm/s': Unit('speed', 0.01), 'mm/s': Unit('speed', 1e-3),
    'knot': Unit('speed', 1852.0 / 3600.0), 'km/h': Unit('speed', 1.0 / 3.6),
    # angular rate (rad/s)
    'rad/s': Unit('angular_rate', 1.0), 'deg/s': Unit('angular_rate', _DEG),
    # shaft speed (rev/s)
    'rpm': Unit('shaft_speed', 1.0 / 60.0), 'rev/s': Unit('shaft_speed', 1.0),
    # force (N)
    'N': Unit('force', 1.0), 'kgf': Unit('force', 9.80665), 'lbf': Unit('force', 4.4482216),
    # pressure (Pa)
    'Pa': Unit('pressure', 1.0), 'hPa': Unit('pressure', 100.0), 'kPa': Unit('pressure', 1e3),
    'bar': Unit('pressure', 1e5), 'mbar': Unit('pressure', 100.0),
    'dbar': Unit('pressure', 1e4), 'psi': Unit('pressure', 6894.757),
    # fraction of a full scale (the map gives the full scale)
    'percent': Unit('fraction', 0.01), 'fraction': Unit('fraction', 1.0),
    # time (s)
    's': Unit('time', 1.0), 'ms': Unit('time', 1e-3), 'us': Unit('time', 1e-6),
    'ns': Unit('time', 1e-9),
}

#: The dimension each contract signal must have (before any thrust law or full scale).
SIGNAL_DIMENSION: dict[str, tuple[str, ...]] = {
    **{k: ('length',) for k in ('x', 'y', 'z')},
    **{k: ('angle',) for k in ('phi', 'theta', 'psi')},
    **{k: ('speed',) for k in ('u', 'v', 'w')},
    **{k: ('angular_rate',) for k in ('p', 'q', 'r')},
    **{k: ('angle', 'fraction') for k in ('bar', 'helm', 'bar_measured', 'helm_measured')},
    'thrust': ('force', 'shaft_speed', 'fraction'),
}


def unit(name: str, where: str) -> Unit:
    """The unit called ``name``; ``where`` (map key and line) goes into the error.

    Raises
    ------
    MapError
        the unit is not known (the message lists the known ones).
    """
    found = UNITS.get(str(name))
    if found is None:
        raise MapError(f'{where}: unknown unit {name!r} (known: {", ".join(UNITS)})')
    return found
