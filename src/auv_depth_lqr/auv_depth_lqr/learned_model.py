"""The pilot's linear model with a learned estimate applied.

Frames and units (Fossen): world NED, depth ``z`` positive down [m]; body FRD; pitch
``theta`` nose up [rad]; heave ``w`` [m/s], pitch rate ``q`` [rad/s]; BAR [rad]. The
parameters ``p`` are :data:`auv_depth_lqr.learning.PARAMETERS`, in their units (the
regression of :mod:`auv_depth_lqr.learning`).

Here :meth:`LearnedModel.correct` turns the estimate into the pilot's linear model at a speed:
the heave and pitch rows of the design model plus the estimated corrections, its level trim
re-solved (the plane angle and pitch the vehicle really holds depth at), its feed-forward
series (the plane a climb really takes) and its LQR gain scaled by the plane's estimated
effectiveness ``k`` when that is below 1 (the LQR of a plane ``k`` times as strong with the
input weight ``k^2`` times as large is the design gain over ``k``; a stronger plane keeps the
design gain, within the LQR's gain margin). Everything the pilot plans, the reference's climb
rate, its plane budget and its stop, then rests on the plane the plant has.
"""
from __future__ import annotations

import math

import numpy as np

from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.schedule import Matrix, OperatingPoint, disturbance_map, feedforward_series

__all__ = ['LearnedModel']


class LearnedModel:
    """The corrections of :mod:`auv_depth_lqr.learning` applied to the pilot's linear model.

    Parameters
    ----------
    m_wq : Matrix
        The heave and pitch rows and columns of the vehicle's mass matrix (2 x 2) [kg,
        kg m, kg m^2].
    weight : float
        ``W`` [N].
    length : float
        Reference length ``L`` [m].
    qs : float
        ``1/2 rho S_ref`` [kg/m].
    gain_range : tuple of float
        Range of the plane effectiveness used to scale the LQR gain [-].
    """

    def __init__(self, m_wq: Matrix, weight: float, length: float, qs: float,
                 gain_range: tuple[float, float]) -> None:
        self.m_wq: Matrix = np.asarray(m_wq, dtype=np.float64)
        self.m_wq_inv: Matrix = np.asarray(np.linalg.inv(self.m_wq), dtype=np.float64)
        self.weight, self.length, self.qs = float(weight), float(length), float(qs)
        self.gain_range = gain_range

    def plane_gain(self, p: Matrix, op: OperatingPoint) -> float:
        """The plane's effectiveness on the pitch acceleration at ``op`` under the
        parameters ``p``, relative to the model's, within ``gain_range`` [-]."""
        corrected = self.plane_rows(p, op)
        nominal = float(op.P[1, 3])
        ratio = float(corrected[1]) / nominal if nominal != 0.0 else 1.0
        lo, hi = self.gain_range
        return min(max(ratio, lo), hi)

    def plane_rows(self, p: Matrix, op: OperatingPoint) -> Matrix:
        """The heave and pitch accelerations per radian of BAR of the learned model at
        ``op`` [m/s^2/rad, rad/s^2/rad]."""
        z_bar, m_bar = self.m_wq @ op.P[:, 3]
        out: Matrix = op.P[:, 3] + self.m_wq_inv @ np.array([p[1] * z_bar, p[4] * m_bar])
        return out

    def correct(self, p: Matrix, op: OperatingPoint) -> OperatingPoint:
        """The pilot's linear model at ``op`` with the parameters ``p`` applied (module
        docstring): heave and pitch rows ``P``, level trim ``(w_e, theta_e, BAR_e)``, series
        ``F``, disturbance map ``D`` and gain ``K`` (over the plane's learned effectiveness
        when that is below 1, :meth:`plane_gain`). ``op`` itself if the learned model has no
        steady climb (an estimate far off: the design model is kept)."""
        u = op.u0
        qs, ln, wt = self.qs, self.length, self.weight
        z_bar, m_bar = self.m_wq @ op.P[:, 3]
        # Wrench corrections: their derivatives over (w, q, theta, BAR) and their value at
        # the design trim.
        dwrench = np.array([[p[2] * qs * u, 0.0, 0.0, p[1] * z_bar],
                            [p[5] * qs * ln * u, p[6] * qs * ln * ln * u, 0.0, p[4] * m_bar]])
        offset = np.array([p[0] * wt, p[3] * wt * ln]) + dwrench @ np.array(
            [op.w_e, 0.0, op.theta_e, op.bar_e])
        P = op.P + self.m_wq_inv @ dwrench
        A, B = _plane_matrices(P, op)
        try:
            _, D = disturbance_map(A, B, u)
            F = feedforward_series(A, B, u)
        except (DesignError, np.linalg.LinAlgError):
            return op
        shift = D @ (self.m_wq_inv @ offset)
        # The LQR's gain margin is [1/2, inf): the design gain keeps a stronger plane stable,
        # not a much weaker one, so the gain is raised for a weaker plane and never lowered
        # (an unmodelled plane delay is learned as a stronger plane, and a lowered gain
        # widens the hold's limit cycle behind it)
        gain = min(self.plane_gain(p, op), 1.0)
        return op._replace(w_e=op.w_e + float(shift[0]), theta_e=op.theta_e + float(shift[2]),
                           bar_e=op.bar_e + float(shift[3]), F=F, P=P, D=D, K=op.K / gain,
                           K_rate=_rate_gain(op.K_rate, gain),
                           dw_dv=float(F[0, 0]), dtheta_dv=float(F[0, 2]),
                           dbar_dv=float(F[0, 3]), learned=True)

    def offset_acceleration(self, p: Matrix, op: OperatingPoint) -> tuple[float, float]:
        """The heave and pitch accelerations [m/s^2, rad/s^2] the corrections ``p`` give at
        the design trim of ``op``: what the design model leaves unexplained while the
        vehicle holds that trim."""
        u = op.u0
        z_bar, m_bar = self.m_wq @ op.P[:, 3]
        qs, ln = self.qs, self.length
        wrench = np.array([
            p[0] * self.weight + p[1] * z_bar * op.bar_e + p[2] * qs * u * op.w_e,
            p[3] * self.weight * ln + p[4] * m_bar * op.bar_e + p[5] * qs * ln * u * op.w_e])
        acc = self.m_wq_inv @ wrench
        return float(acc[0]), float(acc[1])




def _plane_matrices(P: Matrix, op: OperatingPoint) -> tuple[Matrix, Matrix]:
    """``(A, B)`` (5 x 5, 5 x 1) of the vertical plane over ``(w, q, z, theta, xi)`` from its
    heave and pitch rows ``P`` (2 x 4 over ``(w, q, theta, BAR)``) and the exact depth
    kinematics ``z_dot = -u sin(theta) + w cos(theta)`` linearised at ``op``'s trim."""
    A = np.zeros((5, 5))
    B = np.zeros((5, 1))
    A[:2, 0], A[:2, 1], A[:2, 3] = P[:, 0], P[:, 1], P[:, 2]
    B[:2, 0] = P[:, 3]
    c, s = math.cos(op.theta_e), math.sin(op.theta_e)
    A[2, 0], A[2, 3] = c, -op.u0 * c - op.w_e * s
    A[3, 1] = 1.0
    A[4, 2] = 1.0
    return A, B


def _rate_gain(K_rate: Matrix, gain: float) -> Matrix:
    """The plane-rate gain (6,) for a plane ``gain`` times as effective as the design's: the
    plant's response to ``gain BAR`` is the design's to ``BAR``, so the gains on the design
    state (the first five) are divided by ``gain`` and the plane's own (the last) is kept.
    Empty stays empty (no plane-rate design)."""
    if K_rate.size == 0:
        return K_rate
    out: Matrix = np.concatenate([K_rate[:-1] / gain, K_rate[-1:]])
    return out
