"""The regressions of the identification (report section 2): which wrench component each
fits, which coefficients it identifies, and what a coefficient needs to be identifiable.

Wrench components are body FRD about the body origin (the centre of buoyancy); velocities
``nu = (u, v, w, p, q, r)`` are body FRD through the water [m/s, rad/s].
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

#: Body-FRD wrench components (index into a 6-vector of forces/moments).
AXES = ('X', 'Y', 'Z', 'K', 'M', 'N')
#: Velocity components (index into ``nu``).
NU_NAMES = ('u', 'v', 'w', 'p', 'q', 'r')


class Equation(NamedTuple):
    """One regression: the wrench component it fits and the coefficients it identifies."""

    name: str                        # 'surge', 'heave', 'pitch', 'sway', 'yaw'
    axis: int                        # index of the fitted component in the body wrench
    unit: str                        # unit of that component
    coefficients: tuple[str, ...]    # always fitted
    offset: str | None               # CZ0 / CM0: fixed from the base, or fitted on request
    figure: int                      # the report's figure showing this fit
    plane: str | None = None         # CZbar / CMbar: fixed from the base, or fitted on request


EQUATIONS: dict[str, Equation] = {
    'surge': Equation('surge', 0, 'N', ('Ksh',), None, 2),
    'heave': Equation('heave', 2, 'N', ('CZuw', 'CZuq'), 'CZ0', 3, 'CZbar'),
    'pitch': Equation('pitch', 4, 'N m', ('CMuw', 'CMuq'), 'CM0', 4, 'CMbar'),
    'sway': Equation('sway', 1, 'N', ('CYuv', 'CYur'), None, 5),
    'yaw': Equation('yaw', 5, 'N m', ('CNuv', 'CNur'), None, 6),
}


class Excitation(NamedTuple):
    """What must vary for a coefficient to be identifiable, and which manoeuvre does it."""

    variable: int       # index into nu
    what: str           # e.g. 'pitch rate q'
    scale: float        # display factor (rad/s -> deg/s)
    unit: str           # display unit
    threshold: float    # minimum 99th percentile of |x - median(x)| (|x| for Ksh), SI
    manoeuvre: str


_DEG = 180.0 / math.pi
_MANOEUVRE_PITCH = 'fly the pitch mission (plane doublets)'
_MANOEUVRE_YAW = 'fly the yaw "Dieudonnee" mission (helm doublets)'
EXCITATION: dict[str, Excitation] = {
    'Ksh': Excitation(0, 'forward speed |u|', 1.0, 'm/s', 0.3,
                      'fly the surge mission (thrust steps)'),
    'CZ0': Excitation(0, 'forward speed u', 1.0, 'm/s', 0.2,
                      'fly at several speeds (thrust steps, as in the surge or pitch mission)'),
    'CM0': Excitation(0, 'forward speed u', 1.0, 'm/s', 0.2,
                      'fly at several speeds (thrust steps, as in the surge or pitch mission)'),
    'CZuw': Excitation(2, 'heave velocity w', 1.0, 'm/s', 0.005, _MANOEUVRE_PITCH),
    'CMuw': Excitation(2, 'heave velocity w', 1.0, 'm/s', 0.005, _MANOEUVRE_PITCH),
    'CZuq': Excitation(4, 'pitch rate q', _DEG, 'deg/s', math.radians(0.2), _MANOEUVRE_PITCH),
    'CMuq': Excitation(4, 'pitch rate q', _DEG, 'deg/s', math.radians(0.2), _MANOEUVRE_PITCH),
    # the plane's own angle is not in nu: its doublets show in the pitch rate they cause
    'CZbar': Excitation(4, 'pitch rate q', _DEG, 'deg/s', math.radians(0.2), _MANOEUVRE_PITCH),
    'CMbar': Excitation(4, 'pitch rate q', _DEG, 'deg/s', math.radians(0.2), _MANOEUVRE_PITCH),
    'CYuv': Excitation(1, 'sway velocity v', 1.0, 'm/s', 0.005, _MANOEUVRE_YAW),
    'CNuv': Excitation(1, 'sway velocity v', 1.0, 'm/s', 0.005, _MANOEUVRE_YAW),
    'CYur': Excitation(5, 'yaw rate r', _DEG, 'deg/s', math.radians(0.2), _MANOEUVRE_YAW),
    'CNur': Excitation(5, 'yaw rate r', _DEG, 'deg/s', math.radians(0.2), _MANOEUVRE_YAW),
    # the quadratic cross-flow terms (fitted with a structure that has them)
    'Zww': Excitation(2, 'heave velocity w', 1.0, 'm/s', 0.005, _MANOEUVRE_PITCH),
    'Mqq': Excitation(4, 'pitch rate q', _DEG, 'deg/s', math.radians(0.2), _MANOEUVRE_PITCH),
    'Yvv': Excitation(1, 'sway velocity v', 1.0, 'm/s', 0.005, _MANOEUVRE_YAW),
    'Nrr': Excitation(5, 'yaw rate r', _DEG, 'deg/s', math.radians(0.2), _MANOEUVRE_YAW),
    'Zqq': Excitation(4, 'pitch rate q', _DEG, 'deg/s', math.radians(0.2), _MANOEUVRE_PITCH),
    'Mww': Excitation(2, 'heave velocity w', 1.0, 'm/s', 0.005, _MANOEUVRE_PITCH),
    'Yrr': Excitation(5, 'yaw rate r', _DEG, 'deg/s', math.radians(0.2), _MANOEUVRE_YAW),
    'Nvv': Excitation(1, 'sway velocity v', 1.0, 'm/s', 0.005, _MANOEUVRE_YAW),
}

#: Physical sign bounds (``--bounds``): drag and the damping derivatives cannot change sign.
SIGN_BOUNDS: dict[str, tuple[float, float]] = {
    'Ksh': (0.0, math.inf),
    'CZuw': (-math.inf, 0.0),
    'CMuq': (-math.inf, 0.0),
    'CYuv': (-math.inf, 0.0),
    'CNur': (-math.inf, 0.0),
}



def excitation_amplitude(name: str, x: np.ndarray) -> float:
    """The excitation measure of coefficient ``name`` on its variable ``x`` (SI units):
    99th percentile of ``|x|`` for Ksh (speed must be non-zero), else of ``|x - median x|``."""
    if len(x) == 0:
        return 0.0
    if name == 'Ksh':
        return float(np.percentile(np.abs(x), 99.0))
    return float(np.percentile(np.abs(x - np.median(x)), 99.0))
