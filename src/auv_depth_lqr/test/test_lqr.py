"""Tests of auv_depth_lqr.lqr: lqrd against analytic oracles and the report, controllability."""
from __future__ import annotations

import math

import control
import numpy as np
import pytest

from auv_depth_lqr.errors import AuvLqrError, DesignError, NotControllableError
from auv_depth_lqr.lqr import (
    check_controllable,
    controllability,
    lqrd,
    uncontrollable_modes,
)

# Report, section 4.4: Jacobians of the "z_dot = w" model at its own trim (theta_e = -0.19917).
A_4_4 = np.array([
    [-0.4375, -0.6383, 0.0, 0.0001, 0.0],
    [0.2385, -1.1326, 0.0, -0.0383, 0.0],
    [1.0, 0.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0, 0.0],
])
# Report, section 4.2: same model, printed with A[0, 3] = 0.0000 and A[1, 3] = -0.0391.
A_4_2 = A_4_4.copy()
A_4_2[0, 3], A_4_2[1, 3] = 0.0, -0.0391
# Report, section 4.3: "z_dot = -u0 sin(theta) + w cos(theta)" at u0 = 2 m/s.
A_4_3 = A_4_2.copy()
A_4_3[2, 3] = -2.0
B_REPORT = np.array([[-0.1136], [-0.0888], [0.0], [0.0], [0.0]])

Q_4_4, R_4_4 = np.diag([1e-6, 1.0, 100.0, 10.0, 0.1]), np.array([[1e9]])
Q_5, R_5 = np.diag([1e8, 1e8, 350.0, 450.0, 1e-5]), np.array([[1e8]])
K_TABLE_4_4 = np.array([-0.0204, 0.0005, -0.0090, -0.0125, -0.0000])
K_TABLE_5 = np.array([-0.0889, -0.0170, -0.0025, -0.0061, -0.0000])
TS_REPORT = 0.1  # s


# -- lqrd: analytic oracle ----------------------------------------------------------------------
@pytest.mark.parametrize('ts', [0.01, 0.1, 0.5, 2.0])
def test_scalar_integrator_weights_match_closed_form(ts: float) -> None:
    """x_dot = u: x(t) = x0 + u t, so int_0^Ts (q x^2 + r u^2 + 2 n x u) dt is a polynomial."""
    q, r, n = 2.0, 3.0, 0.5
    res = lqrd([[0.0]], [[1.0]], [[q]], [[r]], ts, N=[[n]])
    assert res.Phi[0, 0] == pytest.approx(1.0, rel=1e-12)
    assert res.Gamma[0, 0] == pytest.approx(ts, rel=1e-12)
    assert res.Qd[0, 0] == pytest.approx(q * ts, rel=1e-10)
    assert res.Nd[0, 0] == pytest.approx(q * ts**2 / 2 + n * ts, rel=1e-10)
    assert res.Rd[0, 0] == pytest.approx(r * ts + q * ts**3 / 3 + n * ts**2, rel=1e-10)


def test_scalar_integrator_without_cross_term() -> None:
    """The brief's oracle: Qd = q Ts, Nd = q Ts^2 / 2, Rd = r Ts + q Ts^3 / 3."""
    q, r, ts = 4.0, 0.25, 0.3
    res = lqrd(0.0, 1.0, q, r, ts)
    assert (res.Qd[0, 0], res.Nd[0, 0], res.Rd[0, 0]) == pytest.approx(
        (q * ts, q * ts**2 / 2, r * ts + q * ts**3 / 3), rel=1e-10)


def test_gain_solves_discrete_riccati_with_cross_term() -> None:
    """K = (Rd + G'SG)^-1 (G'S Phi + Nd') and S solves the DARE with the cross term."""
    res = lqrd(A_4_3, B_REPORT, np.diag([1.0, 10.0, 1.0, 10.0, 0.01]), [[100.0]], 0.2)
    S, P, G = res.S, res.Phi, res.Gamma
    K = np.linalg.solve(res.Rd + G.T @ S @ G, G.T @ S @ P + res.Nd.T)
    np.testing.assert_allclose(res.K, K, rtol=1e-8, atol=1e-12)
    dare = P.T @ S @ P - S - (P.T @ S @ G + res.Nd) @ K + res.Qd
    assert np.max(np.abs(dare)) < 1e-8 * np.max(np.abs(S))
    assert np.all(np.abs(res.E) < 1.0)
    np.testing.assert_allclose(np.sort_complex(res.E),
                               np.sort_complex(np.linalg.eigvals(P - G @ res.K)), atol=1e-10)


@pytest.mark.parametrize('A', [A_4_4, A_4_2, A_4_3])
def test_gain_equals_python_controls_dlqr(A: np.ndarray) -> None:
    """The same discrete weights through python-control's ``dlqr`` (a second implementation)
    give the same gain, Riccati solution and closed-loop eigenvalues."""
    res = lqrd(A, B_REPORT, np.diag([1.0, 10.0, 1.0, 10.0, 0.01]), [[100.0]], 0.1)
    K, S, E = control.dlqr(res.Phi, res.Gamma, res.Qd, res.Rd, res.Nd)
    np.testing.assert_allclose(res.K, K, rtol=1e-9, atol=0.0)
    np.testing.assert_allclose(res.S, S, rtol=1e-9, atol=1e-12 * np.max(np.abs(S)))
    np.testing.assert_allclose(np.sort_complex(res.E), np.sort_complex(E), atol=1e-10)


def test_large_weights_do_not_degrade_the_exponential() -> None:
    """Weights are scaled out of the matrix exponential: Qd, Rd scale exactly with them."""
    small = lqrd(A_4_4, B_REPORT, Q_5 / 1e8, R_5 / 1e8, TS_REPORT)
    large = lqrd(A_4_4, B_REPORT, Q_5, R_5, TS_REPORT)
    np.testing.assert_allclose(large.Qd, small.Qd * 1e8, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(large.Rd, small.Rd * 1e8, rtol=1e-10)
    np.testing.assert_allclose(large.K, small.K, rtol=1e-7)


@pytest.mark.parametrize(('Q', 'R', 'ts'), [(Q_4_4, R_4_4, 1e-3), (Q_5, R_5, 1e-4)])
def test_discrete_gain_tends_to_continuous_gain(Q: np.ndarray, R: np.ndarray, ts: float) -> None:
    """As Ts -> 0 the lqrd gain approaches control.lqr.

    (With R = 1e9 the discrete Riccati equation gets ill-conditioned below Ts ~ 1e-3 s, as
    Phi -> I; the continuous gain is then the better tool anyway.)
    """
    k_cont, _, _ = control.lqr(A_4_4, B_REPORT, Q, R)
    k_disc = lqrd(A_4_4, B_REPORT, Q, R, ts).K
    np.testing.assert_allclose(k_disc, k_cont, rtol=0.0, atol=2e-4 * np.max(np.abs(k_cont)))


def test_discrete_gain_error_is_first_order_in_ts() -> None:
    """With the report-5 weights (Ts-sensitive), the gap to control.lqr shrinks like Ts."""
    k_cont, _, _ = control.lqr(A_4_4, B_REPORT, Q_5, R_5)
    gaps = [float(np.max(np.abs(lqrd(A_4_4, B_REPORT, Q_5, R_5, ts).K - k_cont)))
            for ts in (0.1, 0.01, 0.001)]
    assert 5.0 < gaps[0] / gaps[1] < 20.0
    assert 5.0 < gaps[1] / gaps[2] < 20.0


# -- lqrd: the report's table ------------------------------------------------------------------
@pytest.mark.parametrize(('A', 'label'), [(A_4_4, '4.4'), (A_4_2, '4.2')])
@pytest.mark.parametrize(('Q', 'R', 'k_table'), [(Q_4_4, R_4_4, K_TABLE_4_4),
                                                 (Q_5, R_5, K_TABLE_5)])
def test_report_table_reproduces_within_2e_4(
    A: np.ndarray, label: str, Q: np.ndarray, R: np.ndarray, k_table: np.ndarray
) -> None:
    """Report 4.4 / 5 gains (MATLAB's u = -K x, same as here) from lqrd at Ts = 0.1 s.

    Both printed A matrices (4.4 and 4.2) reproduce every entry within 2e-4. Not to the
    printed 4 decimals: the q gain of 4.4 (0.00033 vs 0.0005) and the theta gain of 5
    (-0.00624 vs -0.0061) differ by ~1.5e-4; no rounding of A and B (+-5e-5), no Ts in
    [0.05, 1] s and neither A closes that gap (see test_report_residual_is_not_rounding).
    """
    k = lqrd(A, B_REPORT, Q, R, TS_REPORT).K[0]
    np.testing.assert_allclose(k, k_table, rtol=0.0, atol=2e-4, err_msg=f'A of {label}')
    assert np.array_equal(np.sign(np.round(k, 4)[:4]), np.sign(k_table[:4]))


def test_report_table_5_needs_the_sampled_design() -> None:
    """Table 5 is a discrete design at Ts ~ 0.1 s: the continuous lqr gain is 1.7e-3 off."""
    k_cont, _, _ = control.lqr(A_4_4, B_REPORT, Q_5, R_5)
    assert abs(k_cont[0, 0] - K_TABLE_5[0]) > 1e-3
    assert abs(lqrd(A_4_4, B_REPORT, Q_5, R_5, TS_REPORT).K[0, 0] - K_TABLE_5[0]) < 1e-4
    # The w gain pins Ts: 0.05 s and 0.2 s are off by > 4e-4.
    for ts in (0.05, 0.2):
        assert abs(lqrd(A_4_4, B_REPORT, Q_5, R_5, ts).K[0, 0] - K_TABLE_5[0]) > 4e-4


def test_report_residual_is_not_rounding() -> None:
    """Perturbing A and B within their printed rounding (+-5e-5) never gives 0.0005."""
    rng = np.random.default_rng(1)
    q_gains = []
    for _ in range(200):
        A = A_4_4.copy()
        A[:2, [0, 1, 3]] += rng.uniform(-5e-5, 5e-5, (2, 3))
        B = B_REPORT.copy()
        B[:2, 0] += rng.uniform(-5e-5, 5e-5, 2)
        q_gains.append(lqrd(A, B, Q_4_4, R_4_4, TS_REPORT).K[0, 1])
    assert max(q_gains) < 0.00045  # would round to 0.0005 at >= 0.00045


def test_report_sections_4_2_and_4_3_were_computed_with_r_1e8() -> None:
    """The K printed in 4.2 and 4.3 come from R = 1e8, not the R = 1e9 printed beside them."""
    k_4_3 = np.array([-0.0710, -0.1506, 0.0041, -0.2175, 0.0000])
    k_4_2 = np.array([-0.0366, 0.0013, -0.0164, -0.0219, -0.0000])
    np.testing.assert_allclose(lqrd(A_4_3, B_REPORT, Q_4_4, [[1e8]], 0.1).K[0], k_4_3,
                               atol=6e-5)
    np.testing.assert_allclose(lqrd(A_4_2, B_REPORT, Q_4_4, [[1e8]], 0.1).K[0], k_4_2,
                               atol=2e-4)
    assert abs(lqrd(A_4_3, B_REPORT, Q_4_4, R_4_4, 0.1).K[0, 3] - k_4_3[3]) > 0.09


# -- lqrd: input checks ------------------------------------------------------------------------
@pytest.mark.parametrize(('kwargs', 'match'), [
    ({'Q': np.eye(4)}, r'Q must have shape \(n, n\) = \(5, 5\), got shape \(4, 4\)'),
    ({'B': np.ones((4, 1))}, r'B must have shape \(n, m\) with n = 5, got shape \(4, 1\)'),
    ({'A': np.ones((5, 4))}, r'A must be square'),
    ({'R': np.eye(2)}, r'R must have shape \(m, m\) = \(1, 1\), got shape \(2, 2\)'),
    ({'N': np.ones((5, 2))}, r'N must have shape \(n, m\) = \(5, 1\)'),
    ({'Q': np.diag([1.0, 1.0, -1.0, 1.0, 1.0])}, r'Q must be positive semi-definite'),
    ({'Q': np.triu(np.ones((5, 5)))}, r'Q must be symmetric'),
    ({'R': [[0.0]]}, r'R must be positive definite'),
    ({'R': [[-1.0]]}, r'R must be positive definite'),
    ({'Ts': 0.0}, r'Ts must be finite and > 0 s, got 0.0'),
    ({'Ts': -0.1}, r'Ts must be finite and > 0 s'),
    ({'Ts': math.inf}, r'Ts must be finite and > 0 s, got inf'),
    ({'Ts': 'fast'}, r"Ts must be a number of seconds, got 'fast'"),
    ({'A': np.full((5, 5), np.nan)}, r'A has non-finite entries'),
])
def test_lqrd_rejects_bad_input(kwargs: dict[str, object], match: str) -> None:
    args: dict[str, object] = {'A': A_4_4, 'B': B_REPORT, 'Q': Q_4_4, 'R': R_4_4,
                               'Ts': TS_REPORT}
    args.update(kwargs)
    with pytest.raises(DesignError, match=match):
        lqrd(**args)  # type: ignore[arg-type]


def test_lqrd_errors_are_value_errors_of_the_family() -> None:
    with pytest.raises(ValueError):
        lqrd(A_4_4, B_REPORT, Q_4_4, R_4_4, -1.0)
    assert issubclass(DesignError, AuvLqrError)


def test_lqrd_unstabilisable_pair_is_a_design_error() -> None:
    """An unstable mode the input cannot reach leaves the Riccati equation without solution."""
    with pytest.raises(DesignError, match='no stabilising discrete LQR solution'):
        lqrd(np.diag([1.0, 2.0]), [[1.0], [0.0]], np.eye(2), [[1.0]], 0.1)


# -- controllability ---------------------------------------------------------------------------
@pytest.mark.parametrize('A', [A_4_4, A_4_2, A_4_3])
def test_report_models_are_controllable_rank_5(A: np.ndarray) -> None:
    ctrb = controllability(A, B_REPORT)
    assert ctrb.rank == 5
    assert 1.0 < ctrb.condition < 1e6
    assert check_controllable(A, B_REPORT) == ctrb
    assert uncontrollable_modes(A, B_REPORT).size == 0


def test_uncontrollable_mode_is_named() -> None:
    """Decoupled mode at -2 that the input cannot move: rank 1 of 2 and the eigenvalue."""
    with pytest.raises(NotControllableError,
                       match=r'rank 1 of 2; uncontrollable mode\(s\) at eigenvalue\(s\) -2$'):
        check_controllable(np.diag([-1.0, -2.0]), [[1.0], [0.0]])


def test_uncontrollable_complex_pair_is_named() -> None:
    """An oscillator (eigenvalues +-1j) that no input reaches, beside a driven integrator."""
    A = np.zeros((3, 3))
    A[1, 2], A[2, 1] = 1.0, -1.0
    modes = uncontrollable_modes(A, [[1.0], [0.0], [0.0]])
    np.testing.assert_allclose(np.sort_complex(modes), [-1j, 1j], atol=1e-12)
    with pytest.raises(NotControllableError, match=r'rank 1 of 3.*0\+1j'):
        check_controllable(A, [[1.0], [0.0], [0.0]])


def test_controllability_of_the_scalar_integrator() -> None:
    assert controllability([[0.0]], [[1.0]]) == (1, 1.0)
    assert controllability([[0.0]], [[0.0]]).condition == math.inf
