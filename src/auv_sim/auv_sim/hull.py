"""The hull as a body of revolution, and its quadratic cross-flow drag by strip theory.

The profile is Myring's (Myring 1976, as Prestero 2001, section 2.2 and table 2.1 give it for
the REMUS 100): an elliptic-power nose, a cylinder and a cubic tail,

    nose  r(x) = D/2 (1 - ((x + a_off - a) / a)^2)^(1/n),       0 <= x <= a - a_off
    mid   r(x) = D/2,                                            ... <= x <= l_f
    tail  r(x) = D/2 - (3 D / (2 c^2) - tan(t) / c) (x - l_f)^2
                 + (D / c^3 - tan(t) / c^2) (x - l_f)^3,         l_f <= x <= L

with ``x`` [m] from the nose tip aft, ``l_f = a - a_off + b`` and the REMUS 100's proportions
of the length (``a = 0.1436 L``, ``a_off = 0.0124 L``, ``b = 0.4917 L``, ``c = 0.4068 L``,
``c_off = 0.0277 L``, ``n = 2``, tail half-angle ``t = 0.436 rad``; Prestero 2001 table 2.1
divided by his 1.33 m), any diameter. The body origin is the centre of buoyancy of the hull
(the centroid of its volume), ``xi = x_cb - x`` positive forward (body FRD).

Cross-flow strip theory (Prestero 2001, 3.3; Fossen 2021, 6.6): a strip of length ``d xi`` at
``xi`` meets the cross-flow ``(v + xi r, w - xi q)`` [m/s] and takes the drag
``-1/2 rho c_dc 2 r(xi) |V| V d xi`` [N] against it. Split per velocity as Prestero does,
the integrals give the model's quadratic terms (dimensional, body FRD, about the origin):

    Zww = Yvv = -1/2 rho c_dc int 2r dxi              [kg/m]
    Mww = -Nvv = 1/2 rho c_dc int 2r xi dxi           [kg]
    Zqq = -Yrr = 1/2 rho c_dc int 2r xi|xi| dxi       [kg m]
    Mqq = Nrr = -1/2 rho c_dc int 2r |xi|^3 dxi       [kg m^2]

The hull only: fins, sail and appendages add drag this leaves out. :func:`strip_stations`
gives the quadrature the simulator's strip-theory plant (``hull_crossflow`` effect) integrates
the coupled drag with, the same profile.
"""
from __future__ import annotations

import itertools
import math

import numpy as np

#: Myring parameters as fractions of the length (Prestero 2001 table 2.1 over 1.33 m) and
#: the nose exponent and tail half-angle [rad].
MYRING = {'a': 0.191 / 1.33, 'a_off': 0.0165 / 1.33, 'b': 0.654 / 1.33, 'c': 0.541 / 1.33,
          'c_off': 0.0368 / 1.33, 'n': 2.0, 'tail_angle': 0.436}
#: Cross-flow drag coefficient of a circular cylinder below the critical Reynolds number
#: (Hoerner 1965, chapter 3; the value Prestero 2001, 3.3 uses for the REMUS hull).
CD_CROSSFLOW = 1.1
CD_SOURCE = ('c_dc = 1.1, a circular cylinder\'s cross-flow drag below the critical Reynolds '
             'number (Hoerner 1965, ch. 3; as Prestero 2001, 3.3)')
#: Strips of the quadrature (Gauss-Legendre on each part of the profile).
STRIPS = 24


def hull_radius(x: np.ndarray, length: float, diameter: float) -> np.ndarray:
    """Radius [m] of the Myring hull at ``x`` [m] from the nose tip (0 outside the hull)."""
    x = np.asarray(x, float)
    L, d = float(length), float(diameter)
    a, a_off = MYRING['a'] * L, MYRING['a_off'] * L
    b, c = MYRING['b'] * L, MYRING['c'] * L
    n, tt = MYRING['n'], math.tan(MYRING['tail_angle'])
    lf = a - a_off + b
    nose = 0.5 * d * np.clip(1.0 - ((x + a_off - a) / a) ** 2, 0.0, None) ** (1.0 / n)
    s = x - lf
    tail = (0.5 * d - (3.0 * d / (2.0 * c * c) - tt / c) * s * s
            + (d / c ** 3 - tt / (c * c)) * s ** 3)
    r = np.where(x < a - a_off, nose, np.where(x <= lf, 0.5 * d, tail))
    out: np.ndarray = np.where((x < 0.0) | (x > L), 0.0, np.maximum(r, 0.0))
    return out


def strip_stations(length: float, diameter: float, strips: int = STRIPS
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Quadrature of the hull: stations ``xi`` [m] (forward of the centre of buoyancy) and
    weights ``2 r(xi) d xi`` [m^2] (Gauss-Legendre on the nose, the cylinder and the tail,
    ``strips`` points in all)."""
    L = float(length)
    a, a_off, b = MYRING['a'] * L, MYRING['a_off'] * L, MYRING['b'] * L
    edges = (0.0, a - a_off, a - a_off + b, L)
    lengths = np.diff(edges)
    counts = np.maximum(2, np.round(strips * lengths / L).astype(int))
    xs, ws = [], []
    for (lo, hi), k in zip(itertools.pairwise(edges), counts):
        g, gw = np.polynomial.legendre.leggauss(int(k))
        xs.append(lo + 0.5 * (hi - lo) * (g + 1.0))
        ws.append(0.5 * (hi - lo) * gw)
    x = np.concatenate(xs)
    w = np.concatenate(ws)
    r = hull_radius(x, L, diameter)
    x_cb = float(np.sum(w * r * r * x) / np.sum(w * r * r))
    return x_cb - x, 2.0 * r * w


def crossflow_coefficients(length: float, diameter: float, rho: float,
                           cd: float = CD_CROSSFLOW) -> dict[str, float]:
    """The quadratic cross-flow coefficients of the hull by strip theory (module docstring):
    ``Yvv, Zww`` [kg/m], ``Mww, Nvv`` [kg], ``Yrr, Zqq`` [kg m], ``Mqq, Nrr`` [kg m^2]."""
    xi, w = strip_stations(length, diameter, 200)
    k = 0.5 * float(rho) * float(cd)
    zww = -k * float(np.sum(w))
    mww = k * float(np.sum(w * xi))
    zqq = k * float(np.sum(w * xi * np.abs(xi)))
    mqq = -k * float(np.sum(w * np.abs(xi) ** 3))
    return {'Yvv': zww, 'Zww': zww, 'Mww': mww, 'Nvv': -mww, 'Yrr': -zqq, 'Zqq': zqq,
            'Mqq': mqq, 'Nrr': mqq}
