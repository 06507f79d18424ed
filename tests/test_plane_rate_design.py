"""The plane-rate design of the depth pilot: the LQR on the state augmented by the plane,
its input the plane's rate (``PilotSettings.plane_rate_design``).

Oracles: the augmented matrices written out by hand; the continuous LQR of a double
integrator in closed form (the augmented integrator ``x_dot = u``, ``u_dot = r``), which the
sampled design approaches as the sample period goes to zero; python-control's ``dlqr`` on
the same sampled augmented matrices and weights (a second Riccati solver); the change of
variables ``BAR' = g BAR``, under which a plane ``g`` times as strong has the same optimum.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg

from auv_depth_lqr.design_cache import design_data, design_from_data
from auv_depth_lqr.lqr import input_rate_system, lqrd
from auv_depth_lqr.schedule import GainSchedule


def test_augmented_matrices_by_hand() -> None:
    A = [[-1.0, 2.0], [0.5, -3.0]]
    B = [[4.0], [-5.0]]
    a_aug, b_aug = input_rate_system(A, B)
    assert a_aug.tolist() == [[-1.0, 2.0, 4.0], [0.5, -3.0, -5.0], [0.0, 0.0, 0.0]]
    assert b_aug.tolist() == [[0.0], [0.0], [1.0]]


def test_augmented_integrator_tends_to_the_double_integrator_closed_form() -> None:
    """``x_dot = u`` augmented: ``(x, u)`` a double integrator driven by ``r = u_dot``. With
    ``Q = diag(q1, q2)`` and ``R = rho`` its continuous Riccati solution has
    ``p12 = sqrt(q1 rho)``, ``p22 = sqrt(rho (q2 + 2 p12))``, so ``K = (sqrt(q1 / rho),
    sqrt((q2 + 2 sqrt(q1 rho)) / rho))``: with q1 = 4, q2 = 1, rho = 1, K = (2, sqrt 5).
    The sampled gain differs by O(Ts)."""
    a_aug, b_aug = input_rate_system([[0.0]], [[1.0]])
    result = lqrd(a_aug, b_aug, np.diag([4.0, 1.0]), [[1.0]], 1e-3)
    assert result.K[0, 0] == pytest.approx(2.0, rel=5e-3)
    assert result.K[0, 1] == pytest.approx(math.sqrt(5.0), rel=5e-3)


def test_augmented_riccati_matches_python_control() -> None:
    """Sampled with Ts = 0.1 s the augmented integrator is ``Phi = [[1, Ts], [0, 1]]``,
    ``Gamma = (Ts^2 / 2, Ts)`` (by hand); python-control's ``dlqr`` on those matrices and the
    sampled weights gives the same Riccati solution and gain."""
    control = pytest.importorskip('control')
    ts = 0.1
    a_aug, b_aug = input_rate_system([[0.0]], [[1.0]])
    result = lqrd(a_aug, b_aug, np.diag([4.0, 1.0]), [[1.0]], ts)
    assert result.Phi == pytest.approx(np.array([[1.0, ts], [0.0, 1.0]]), abs=1e-12)
    assert result.Gamma == pytest.approx(np.array([[ts ** 2 / 2], [ts]]), abs=1e-12)
    K, S, _ = control.dlqr(result.Phi, result.Gamma, result.Qd, result.Rd, result.Nd)
    np.testing.assert_allclose(result.S, np.asarray(S), rtol=1e-8)
    np.testing.assert_allclose(result.K, np.asarray(K), rtol=1e-8)


def test_a_stronger_plane_divides_the_state_gains_and_keeps_the_plane_gain() -> None:
    """A plane ``g`` times as strong, ``(A, g B)``, weighted ``g^2 R`` on its angle ``c``
    and ``g^2 R_rate`` on its rate ``s`` is the design's problem in ``BAR = g c``, ``r = g s``:
    from ``r = -K_x x - K_b BAR``, ``s = -(K_x / g) x - K_b c``: the gain on the state
    divided by ``g``, the gain on the plane kept (as ``learning`` scales it)."""
    A = np.array([[-0.8, 0.3], [1.0, 0.0]])
    B = np.array([[-0.6], [0.0]])
    q, r, r_rate, g = np.diag([2.0, 5.0]), 3.0, 0.4, 0.6
    base = lqrd(*input_rate_system(A, B), np.diag([2.0, 5.0, r]), [[r_rate]], 0.1).K[0]
    q_g = np.zeros((3, 3))
    q_g[:2, :2], q_g[2, 2] = q, r * g ** 2
    scaled = lqrd(*input_rate_system(A, g * B), q_g, [[r_rate * g ** 2]], 0.1).K[0]
    assert scaled[:2] == pytest.approx(base[:2] / g, rel=1e-6)
    assert scaled[2] == pytest.approx(base[2], rel=1e-6)


def _pitch_plane(u0: float):  # type: ignore[no-untyped-def]
    """A stable vertical plane at ``u0`` [m/s] over ``(w, q, z, theta, xi)``, level trim."""
    A = np.zeros((5, 5))
    A[0, 0], A[0, 1] = -1.0 * u0, 0.8 * u0
    A[1, 0], A[1, 1], A[1, 3] = 0.5 * u0, -1.2 * u0, -0.6
    A[2, 0], A[2, 3] = 1.0, -u0
    A[3, 1] = 1.0
    A[4, 2] = 1.0
    B = np.array([[-0.3 * u0 ** 2], [-1.0 * u0 ** 2], [0.0], [0.0], [0.0]])
    return [0.0, 0.0, 0.0, 0.0, 0.0], 0.0, A, B


def test_schedule_designs_a_stabilising_plane_rate_gain_and_caches_it() -> None:
    schedule = GainSchedule.design(_pitch_plane, (1.0, 2.0), Ts=0.1, R_rate=[[10.0]])
    assert schedule.K_rate.shape == (2, 6)
    for row, u0 in zip(schedule.K_rate, schedule.speeds):
        _, _, A, B = _pitch_plane(float(u0))
        a_aug, b_aug = input_rate_system(A, B)
        block = np.zeros((7, 7))  # zero-order hold: expm([[A, B], [0, 0]] Ts)
        block[:6, :6], block[:6, 6:] = a_aug, b_aug
        hold = scipy.linalg.expm(block * 0.1)
        closed = hold[:6, :6] - hold[:6, 6:] @ row.reshape(1, 6)
        assert np.max(np.abs(np.linalg.eigvals(closed))) < 1.0
    op = schedule.at(1.5)
    assert op.K_rate == pytest.approx(0.5 * (schedule.K_rate[0] + schedule.K_rate[1]))
    back, surge = design_from_data(design_data((schedule, 3.0)), 0.1)
    assert np.array_equal(back.K_rate, schedule.K_rate) and surge == 3.0
    assert np.array_equal(back.R_rate, schedule.R_rate)
    plain = GainSchedule.design(_pitch_plane, (1.0, 2.0), Ts=0.1)
    assert plain.K_rate.shape == (0, 6) and plain.at(1.5).K_rate.size == 0
    assert design_from_data(design_data((plain, 3.0)), 0.1)[0].K_rate.shape == (0, 6)
