"""NED/FRD <-> ENU/FLU odometry conversions (auv_sim.frames), checked by rotating vectors.

The oracle is geometry, not the conversion formula: a body axis is rotated into the world
frame by the quaternion and compared with where that axis must point (north, up, ...).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from auv_sim import frames

NORTH_ENU = np.array([0.0, 1.0, 0.0])
EAST_ENU = np.array([1.0, 0.0, 0.0])
UP_ENU = np.array([0.0, 0.0, 1.0])
FORWARD = np.array([1.0, 0.0, 0.0])
LEFT_FLU = np.array([0.0, 1.0, 0.0])


def state(phi: float = 0.0, theta: float = 0.0, psi: float = 0.0) -> np.ndarray:
    x = np.zeros(15)
    x[3:6] = phi, theta, psi
    return x


def test_heading_north_is_enu_yaw_plus_90_deg() -> None:
    odom = frames.state_to_odometry(state(psi=0.0))
    np.testing.assert_allclose(frames.rotate(odom.orientation, FORWARD), NORTH_ENU, atol=1e-15)
    _, _, yaw_enu = frames.quaternion_to_euler(odom.orientation)
    assert yaw_enu == pytest.approx(math.pi / 2, abs=1e-15)


def test_heading_east_is_enu_yaw_zero() -> None:
    odom = frames.state_to_odometry(state(psi=math.pi / 2))
    np.testing.assert_allclose(frames.rotate(odom.orientation, FORWARD), EAST_ENU, atol=1e-15)
    assert frames.quaternion_to_euler(odom.orientation)[2] == pytest.approx(0.0, abs=1e-15)


def test_nose_up_points_the_nose_up_and_is_negative_flu_pitch() -> None:
    theta = 0.3  # NED pitch, positive nose up
    odom = frames.state_to_odometry(state(theta=theta, psi=0.0))
    nose = frames.rotate(odom.orientation, FORWARD)
    np.testing.assert_allclose(nose, [0.0, math.cos(theta), math.sin(theta)], atol=1e-15)
    # REP-103: rotation about FLU y (to the left) by a positive angle pitches the nose down.
    _, pitch_enu, _ = frames.quaternion_to_euler(odom.orientation)
    assert pitch_enu == pytest.approx(-theta, abs=1e-14)


def test_roll_to_starboard_raises_the_port_side() -> None:
    phi = 0.2  # NED/FRD roll: positive = starboard side down, port side up
    odom = frames.state_to_odometry(state(phi=phi))
    left = frames.rotate(odom.orientation, LEFT_FLU)
    assert left[2] == pytest.approx(math.sin(phi), abs=1e-15)  # port (left) rises
    assert frames.quaternion_to_euler(odom.orientation)[0] == pytest.approx(phi, abs=1e-14)


def test_position_and_body_twist() -> None:
    x = np.zeros(15)
    x[0:3] = 10.0, -3.0, 40.0          # 10 m north, 3 m west, 40 m deep
    x[6:12] = 2.0, 0.1, -0.2, 0.01, 0.02, -0.03
    odom = frames.state_to_odometry(x)
    np.testing.assert_array_equal(odom.position, [-3.0, 10.0, -40.0])
    np.testing.assert_array_equal(odom.linear, [2.0, -0.1, 0.2])
    np.testing.assert_array_equal(odom.angular, [0.01, -0.02, 0.03])


def test_world_velocity_is_the_same_physical_vector_in_both_conventions() -> None:
    rng = np.random.default_rng(1)
    x = np.zeros(15)
    x[3:6] = rng.uniform(-1.0, 1.0, 3)
    x[6:9] = rng.uniform(-2.0, 2.0, 3)
    q_ned_frd = frames.euler_to_quaternion(*x[3:6])
    v_ned = frames.rotate(q_ned_frd, x[6:9])
    odom = frames.state_to_odometry(x)
    v_enu = frames.rotate(odom.orientation, odom.linear)
    np.testing.assert_allclose(v_enu, frames.NED_TO_ENU @ v_ned, atol=1e-14)


def test_round_trip_vectorised() -> None:
    rng = np.random.default_rng(7)
    n = 1000
    x = np.zeros((n, 15))
    x[:, 0:3] = rng.normal(0.0, 100.0, (n, 3))
    x[:, 3] = rng.uniform(-math.pi, math.pi, n)
    x[:, 4] = rng.uniform(-1.5, 1.5, n)            # away from gimbal lock
    x[:, 5] = rng.uniform(-math.pi, math.pi, n)
    x[:, 6:12] = rng.normal(0.0, 1.0, (n, 6))
    odom = frames.state_to_odometry(x)
    assert odom.orientation.shape == (n, 4)
    np.testing.assert_allclose(np.linalg.norm(odom.orientation, axis=1), 1.0, atol=1e-15)
    back = frames.odometry_to_state(odom)
    np.testing.assert_allclose(back, x[:, :12], atol=1e-9)
    np.testing.assert_array_equal(frames.position_enu_to_ned(odom.position), x[:, 0:3])


def test_quaternion_round_trip_and_sign() -> None:
    rng = np.random.default_rng(3)
    q = rng.normal(size=(200, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    back = frames.orientation_enu_to_ned(frames.orientation_ned_to_enu(q))
    np.testing.assert_allclose(back, frames.canonical(q), atol=1e-15)
    assert np.all(frames.orientation_ned_to_enu(q)[:, 3] >= 0.0)
