"""The pilot's state from a navigation solution: ``nav_msgs/Odometry`` in either convention.

The pilot flies on the vertical-plane state ``(z, theta, w, q, u)`` in Fossen's convention
(NED world, FRD body, ZYX Euler angles; z [m] down, theta [rad] nose up, u, w [m/s] and
q [rad/s] in the body frame). A vehicle's navigation solution usually comes as
``nav_msgs/Odometry``: the pose of ``child_frame_id`` in ``header.frame_id`` (world) and the
twist in ``child_frame_id`` (body), in one of two conventions:

* ``enu_flu`` — REP-103/105, what ROS tools expect: ENU world (z up), FLU body (y to port,
  z up); converted with :func:`auv_sim.frames.odometry_to_state` (tested both ways there);
* ``ned_frd`` — the marine convention, as many INS/DVL drivers publish it: NED world, FRD
  body; the pose and twist are already Fossen's.

The twist must be in the body frame (``child_frame_id``), as ``nav_msgs/Odometry`` defines;
a driver that puts the world-frame velocity there feeds the pilot wrong ``u``, ``w``.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from auv_depth_lqr.controller import PlaneState
from auv_depth_lqr.errors import InvalidInputError
from auv_sim.frames import Odometry, odometry_to_state, quaternion_to_euler

ODOM_FRAMES = ('enu_flu', 'ned_frd')
"""Conventions of an Odometry input (see module docstring)."""


def plane_state_from_odometry(position: Sequence[float], orientation: Sequence[float],
                              linear: Sequence[float], angular: Sequence[float],
                              frame: str) -> PlaneState:
    """Vertical-plane state (NED/FRD) of an odometry sample.

    ``position`` [m] (x, y, z) in the world frame, ``orientation`` the quaternion
    (x, y, z, w) of the body in the world, ``linear`` [m/s] and ``angular`` [rad/s] the body
    twist, all in the convention ``frame`` (``enu_flu`` or ``ned_frd``).
    InvalidInputError for an unknown convention, a non-finite value or a zero quaternion.
    """
    if frame not in ODOM_FRAMES:
        raise InvalidInputError(f'odometry frame {frame!r} is not one of {list(ODOM_FRAMES)}')
    pos = np.asarray(position, dtype=np.float64)
    quat = np.asarray(orientation, dtype=np.float64)
    lin = np.asarray(linear, dtype=np.float64)
    ang = np.asarray(angular, dtype=np.float64)
    if not all(np.all(np.isfinite(a)) for a in (pos, quat, lin, ang)):
        raise InvalidInputError('odometry with non-finite fields ignored')
    if not np.linalg.norm(quat) > 1e-6:
        raise InvalidInputError(f'odometry orientation {quat.tolist()} is not a rotation '
                                '(zero quaternion) ignored')
    if frame == 'enu_flu':
        x = odometry_to_state(Odometry(position=pos, orientation=quat, linear=lin,
                                       angular=ang))
        return PlaneState(z=float(x[2]), theta=float(x[4]), w=float(x[8]), q=float(x[10]),
                          u=float(x[6]))
    _, theta, _ = quaternion_to_euler(quat)
    return PlaneState(z=float(pos[2]), theta=float(theta), w=float(lin[2]), q=float(ang[1]),
                      u=float(lin[0]))
