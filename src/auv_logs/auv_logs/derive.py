"""State signals a log lacks, derived from the ones it has (each marked as derived).

All on one continuous segment (stamps ``t`` [s], increasing; never across a gap), in
NED/FRD with ZYX Euler angles; time derivatives by second-order central differences on the
stamps as they are (``numpy.gradient``, one-sided at the ends; no filtering: the
identification's own derivative filter comes later). Kinematics (Fossen 2021, eq. 2.29):

* body rates from the Euler-angle rates (the inverse of ``Theta_dot = T(Theta) omega``)::

      p = phi_dot - psi_dot sin(theta)
      q = theta_dot cos(phi) + psi_dot cos(theta) sin(phi)
      r = -theta_dot sin(phi) + psi_dot cos(theta) cos(phi)

* body velocities from the NED position rates, ``nu_1 = R(Theta)^T p_dot`` (over ground);
* heave from the depth rate, ``z_dot = -u sin(theta) + v cos(theta) sin(phi)
  + w cos(theta) cos(phi)`` solved for ``w``;
* north and east positions dead-reckoned from ``R(Theta) nu_1`` (trapezoidal rule, starting
  at 0 m): only the depth loop's models use them, and they are marked so.

What cannot be derived is said so: a log with neither surge speed (DVL, odometry) nor
horizontal position has no ``u``.
"""
from __future__ import annotations

from collections.abc import MutableMapping

import numpy as np

from auv_logs.errors import RealLogError
from auv_sim.frames import euler_to_quaternion, rotate


def _rate(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    out: np.ndarray = np.gradient(x, t) if len(t) > 2 else np.zeros_like(x)
    return out


def body_rates(t: np.ndarray, phi: np.ndarray, theta: np.ndarray,
               psi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(p, q, r) [rad/s] from ZYX Euler angles [rad] (yaw unwrapped first)."""
    dphi = _rate(t, np.unwrap(phi))
    dth = _rate(t, theta)
    dpsi = _rate(t, np.unwrap(psi))
    p = dphi - dpsi * np.sin(theta)
    q = dth * np.cos(phi) + dpsi * np.cos(theta) * np.sin(phi)
    r = -dth * np.sin(phi) + dpsi * np.cos(theta) * np.cos(phi)
    return p, q, r


def derive_missing(t: np.ndarray, s: MutableMapping[str, np.ndarray],
                   missing: set[str]) -> list[str]:
    """Fill the ``missing`` state signals of segment ``s`` (name -> array) in place.

    Returns one line per derived signal saying how. Raises :class:`RealLogError` for a
    signal that cannot be derived (``z``, ``theta``, ``psi``; ``u`` without position).
    """
    notes: list[str] = []
    for name in ('z', 'theta', 'psi'):
        if name in missing:
            raise RealLogError(f'{name} is not mapped and cannot be derived: map it')
    if 'phi' in missing:
        s['phi'] = np.zeros_like(t)
        notes.append('phi: not logged, assumed 0 rad (wings level)')
    rates = body_rates(t, s['phi'], s['theta'], s['psi'])
    for k, name in enumerate(('p', 'q', 'r')):
        if name in missing:
            s[name] = rates[k]
            notes.append(f'{name}: derived from the attitude (Euler-angle rates by central '
                         'differences, kinematic inverse)')
    q_nb = euler_to_quaternion(s['phi'], s['theta'], s['psi'])
    have_xy = 'x' not in missing and 'y' not in missing
    if have_xy:
        pdot = np.column_stack([_rate(t, s['x']), _rate(t, s['y']), _rate(t, s['z'])])
        conj = q_nb * np.array([-1.0, -1.0, -1.0, 1.0])
        nu = rotate(conj, pdot)
        for k, name in enumerate(('u', 'v')):
            if name in missing:
                s[name] = nu[:, k]
                notes.append(f'{name}: derived from the NED position rate rotated into the '
                             'body (velocity over ground)')
    if 'u' in missing and 'u' not in s:
        raise RealLogError('u is missing: the log has no surge speed (map a DVL, odometry '
                           'twist or a speed column) and no north/east position to derive it '
                           'from')
    if 'v' in missing and 'v' not in s:
        s['v'] = np.zeros_like(t)
        notes.append('v: not logged and no position to derive it from: assumed 0 m/s')
    if 'w' in missing:
        th, ph = s['theta'], s['phi']
        zdot = _rate(t, s['z'])
        s['w'] = (zdot + s['u'] * np.sin(th) - s['v'] * np.cos(th) * np.sin(ph)) / (
            np.cos(th) * np.cos(ph))
        notes.append('w: derived from the depth rate (central differences), pitch, roll, u '
                     'and v')
    if not have_xy:
        nu1 = np.column_stack([s['u'], s['v'], s['w']])
        vel = rotate(q_nb, nu1)
        dt = np.diff(t)[:, None]
        pos = np.vstack([np.zeros((1, 2)),
                         np.cumsum(0.5 * dt * (vel[1:, :2] + vel[:-1, :2]), axis=0)])
        for k, name in enumerate(('x', 'y')):
            if name in missing:
                s[name] = pos[:, k]
                notes.append(f'{name}: dead-reckoned from u, v, w and the attitude '
                             '(trapezoidal rule, from 0 m at the segment start)')
    return notes
