"""Frame conversions between Fossen's NED/FRD state and ROS's ENU/FLU odometry (REP-103/105).

Conventions:

* NED world: x north, y east, z down; FRD body: x forward, y right (starboard), z down.
  Attitude as ZYX Euler angles ``(phi, theta, psi)``: roll, pitch (positive nose up), yaw
  (positive from north towards east).
* ENU world: x east, y north, z up; FLU body: x forward, y left (port), z up. This is what
  ``nav_msgs/Odometry`` carries for RViz and Foxglove: pose in the world frame (``odom``),
  twist in the body frame (``base_link``).
* Quaternions are stored scalar-last, ``(x, y, z, w)``, as ``geometry_msgs/Quaternion`` and
  SciPy do; ``q_a_b`` rotates vectors from frame b to frame a (``v_a = q_a_b v_b q_a_b*``).

The world change ``P`` (NED -> ENU, swap x and y, negate z) and the body change ``F``
(FRD -> FLU, negate y and z) are both proper rotations by pi, about ``(1, 1, 0)/sqrt(2)``
and about x. So::

    R_enu_flu = P R_ned_frd F        q_enu_flu = q_P * q_ned_frd * q_F

Both changes are their own inverses, so every conversion here is an involution: the same
formula maps back (up to the sign of the quaternion, canonicalised to ``w >= 0``).

All functions take arrays with the components on the last axis and broadcast over any
leading axes (one sample or N samples).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

#: NED -> ENU change of world axes (a rotation by pi about (1, 1, 0)/sqrt(2)).
NED_TO_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
#: FRD -> FLU change of body axes (a rotation by pi about the body x axis).
FRD_TO_FLU = np.diag([1.0, -1.0, -1.0])
#: Quaternion (x, y, z, w) of NED_TO_ENU.
Q_NED_TO_ENU = np.array([math.sqrt(0.5), math.sqrt(0.5), 0.0, 0.0])
#: Quaternion (x, y, z, w) of FRD_TO_FLU.
Q_FRD_TO_FLU = np.array([1.0, 0.0, 0.0, 0.0])


class Odometry(NamedTuple):
    """The REP-103/105 pose and twist of the vehicle (arrays, components on the last axis).

    ``position`` ENU [m] (3), ``orientation`` quaternion q_enu_flu (x, y, z, w) (4),
    ``linear`` FLU body velocity [m/s] (3), ``angular`` FLU body rate [rad/s] (3).
    """

    position: np.ndarray
    orientation: np.ndarray
    linear: np.ndarray
    angular: np.ndarray


def quaternion_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` of (x, y, z, w) quaternions (broadcast over leading axes)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def quaternion_conjugate(q: np.ndarray) -> np.ndarray:
    """Conjugate (the inverse of a unit quaternion), (x, y, z, w)."""
    q = np.asarray(q, dtype=np.float64)
    out: np.ndarray = q * np.array([-1.0, -1.0, -1.0, 1.0])
    return out


def canonical(q: np.ndarray) -> np.ndarray:
    """The same rotation with ``w >= 0`` (q and -q rotate alike)."""
    q = np.asarray(q, dtype=np.float64)
    return np.where(q[..., 3:4] < 0.0, -q, q)


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v`` (3) by unit quaternions ``q`` (x, y, z, w): ``q v q*``."""
    q = np.asarray(q, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    qv = np.concatenate([v, np.zeros((*v.shape[:-1], 1))], axis=-1)
    return quaternion_multiply(quaternion_multiply(q, qv), quaternion_conjugate(q))[..., :3]


def euler_to_quaternion(phi: np.ndarray | float, theta: np.ndarray | float,
                        psi: np.ndarray | float) -> np.ndarray:
    """ZYX Euler angles [rad] -> quaternion (x, y, z, w): ``q = q_z(psi) q_y(theta) q_x(phi)``.

    With NED/FRD angles it is ``q_ned_frd``; with ENU/FLU angles ``q_enu_flu``.
    """
    hr = 0.5 * np.asarray(phi, dtype=np.float64)
    hp = 0.5 * np.asarray(theta, dtype=np.float64)
    hy = 0.5 * np.asarray(psi, dtype=np.float64)
    cr, sr = np.cos(hr), np.sin(hr)
    cp, sp = np.cos(hp), np.sin(hp)
    cy, sy = np.cos(hy), np.sin(hy)
    return np.stack([sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy,
                     cr * cp * sy - sr * sp * cy,
                     cr * cp * cy + sr * sp * sy], axis=-1)


def quaternion_to_euler(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quaternion (x, y, z, w) -> ZYX Euler angles ``(phi, theta, psi)`` [rad].

    ``theta`` in [-pi/2, pi/2], ``phi`` and ``psi`` in (-pi, pi]; the quaternion is normalised
    first. At ``|theta| = pi/2`` (gimbal lock) roll and yaw are not separable.
    """
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    x, y, z, w = np.moveaxis(q, -1, 0)
    phi = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    theta = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    psi = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return phi, theta, psi


def position_ned_to_enu(p_ned: np.ndarray) -> np.ndarray:
    """World position NED [m] -> ENU [m]: ``(y, x, -z)``. Its own inverse."""
    p = np.asarray(p_ned, dtype=np.float64)
    return np.stack([p[..., 1], p[..., 0], -p[..., 2]], axis=-1)


position_enu_to_ned = position_ned_to_enu


def body_frd_to_flu(v_frd: np.ndarray) -> np.ndarray:
    """A body vector (velocity, rate, force, moment) FRD -> FLU: ``(x, -y, -z)``. Involution."""
    v = np.asarray(v_frd, dtype=np.float64)
    return np.stack([v[..., 0], -v[..., 1], -v[..., 2]], axis=-1)


body_flu_to_frd = body_frd_to_flu


def orientation_ned_to_enu(q_ned_frd: np.ndarray) -> np.ndarray:
    """Attitude ``q_ned_frd`` -> ``q_enu_flu = q_P * q_ned_frd * q_F`` (canonical, w >= 0)."""
    q = quaternion_multiply(Q_NED_TO_ENU, quaternion_multiply(q_ned_frd, Q_FRD_TO_FLU))
    return canonical(q)


def orientation_enu_to_ned(q_enu_flu: np.ndarray) -> np.ndarray:
    """Attitude ``q_enu_flu`` -> ``q_ned_frd = q_P* * q_enu_flu * q_F*`` (canonical, w >= 0)."""
    q = quaternion_multiply(quaternion_conjugate(Q_NED_TO_ENU),
                            quaternion_multiply(q_enu_flu, quaternion_conjugate(Q_FRD_TO_FLU)))
    return canonical(q)


def state_to_odometry(x: np.ndarray) -> Odometry:
    """Fossen state (first 12 entries: eta NED, Euler ZYX, nu FRD) -> REP-103/105 odometry.

    Accepts a 12- or 15-state vector, or an N x 12/15 array.
    """
    x = np.asarray(x, dtype=np.float64)
    q_ned_frd = euler_to_quaternion(x[..., 3], x[..., 4], x[..., 5])
    return Odometry(position=position_ned_to_enu(x[..., 0:3]),
                    orientation=orientation_ned_to_enu(q_ned_frd),
                    linear=body_frd_to_flu(x[..., 6:9]),
                    angular=body_frd_to_flu(x[..., 9:12]))


def odometry_to_state(odom: Odometry) -> np.ndarray:
    """REP-103/105 odometry -> the 12 Fossen states ``(x, y, z, phi, theta, psi, u, v, w,
    p, q, r)`` (NED [m], ZYX Euler angles [rad], FRD body velocities [m/s, rad/s])."""
    pos = position_enu_to_ned(odom.position)
    phi, theta, psi = quaternion_to_euler(orientation_enu_to_ned(odom.orientation))
    return np.concatenate([pos, np.stack([phi, theta, psi], axis=-1),
                           body_flu_to_frd(odom.linear), body_flu_to_frd(odom.angular)],
                          axis=-1)
