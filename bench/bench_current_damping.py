"""Why the plane-rate design (``plane_rate_design``) loses time on the REMUS 100 in a head
current: the over-ground heave takes pitch stiffness from the loop.

A pilot on its speed over ground (a DVL's bottom track) in a horizontal current ``c`` along
its heading (``c > 0`` against it) measures the body heave ``w_g = w_r - c sin(theta)`` (the
current's component on the body z axis; ``w_r`` through the water, ``theta`` nose up) and
the surge ``u_g = u_r - c cos(theta)``: with its speed loop holding ``u_g`` at ``u0`` the
vehicle flies through the water at ``u0 + c``. Linearised, the heave feedback
``-K_w w_g`` is ``-K_w w_r + c K_w theta``: the loop's pitch gain ``K_theta`` is reduced by
``c K_w`` (both negative). How much of it is left depends on the design's heave-to-pitch
ratio; the law that relies more on heave loses more.

For the REMUS 100 at ``u0`` = 1.5 m/s, the closed loop of the linear model through the
water at ``u0 + c`` with the gains scheduled at ``u0`` and the heave measured over ground,
the depth integrator frozen (it runs only at rest): the dominant (slowest oscillatory)
mode and its damping, for the angle design ``K``, the plane-rate design ``K_rate`` (its
quasi-static gain ``K_rate[:5] / K_rate[5]`` is what the heave-to-pitch ratio is read
from), and the plane-rate design with other rate weights (``1 / (share bar_rate)^2``, as
``pilot.PLANE_RATE_SHARE``) or plane-angle weights (times ``R``); and the head current at
which the dominant mode becomes unstable (the plant then through the water at
``u0 + c``). Then the closed-loop flights of ``tests/test_model_error.py``'s head-current
case (0.3 m/s, 20 -> 10 m, speed loop 2 s) with each design, as flown and with the pilot
given the heave through the water (``w_g + c sin(theta)``). Run as a script to write
``bench/results/current_damping.json``.
"""
from __future__ import annotations

import json
import math
import pathlib
from typing import Any

import numpy as np
import scipy.linalg
from timing import save_figures

from auv_depth_lqr.closed_loop import model_error_plant, run_closed_loop
from auv_depth_lqr.controller import DepthState, PlaneState
from auv_depth_lqr.lqr import input_rate_system, lqrd
from auv_depth_lqr.metrics import step_metrics
from auv_depth_lqr.pilot import PLANE_RATE_SHARE, DepthPilot, PilotSettings, vehicle_linearization
from auv_depth_lqr.tuning import derive_tuning
from auv_sim.params import load_vehicle

VEHICLE = pathlib.Path(__file__).resolve().parents[1] / 'config' / 'remus100.yaml'
U0 = 1.5                          # m/s, scheduled (over ground)
CURRENT = 0.3                     # m/s against the heading
THETA_MAX = math.radians(25.0)    # rad
TS = 0.1                          # s
#: name -> (rate weight share of the plane's rate limit, plane-angle weight times R);
#: None: the angle design
DESIGNS: dict[str, tuple[float, float] | None] = {
    'angle': None,
    'rate': (PLANE_RATE_SHARE, 1.0),
    'rate_share_2': (2.0, 1.0),
    'rate_share_4': (4.0, 1.0),
    'rate_share_0.5': (0.5, 1.0),
    'rate_angle_0.1R': (PLANE_RATE_SHARE, 0.1),
    'rate_angle_0.3R': (PLANE_RATE_SHARE, 0.3),
    'rate_angle_3R': (PLANE_RATE_SHARE, 3.0),
}


def _zoh(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold ``(Phi, Gamma)`` of ``x_dot = A x + B u`` over :data:`TS`."""
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n:] = A, B
    E = scipy.linalg.expm(M * TS)
    return E[:n, :n], E[:n, n:]


def closed_loop(gain: np.ndarray, A: np.ndarray, B: np.ndarray, c: float) -> np.ndarray:
    """One-sample map of the loop on the manoeuvre's states ``(w, q, z, theta)`` (the
    integrator frozen), plus the last command for a plane-rate gain (6 entries): the plant
    ``(A, B)`` through the water, the heave fed back over ground ``w - c theta``."""
    phi, gam = _zoh(A[:4, :4], B[:4])
    measured = np.eye(4)
    measured[0, 3] = -c
    if gain.size == 5:
        return np.asarray(phi - gam @ (gain[:4] @ measured).reshape(1, 4))
    # BAR_k = BAR_{k-1} + Ts (-K_x x_k - K_bar BAR_{k-1}); x_{k+1} = Phi x_k + Gamma BAR_k
    row = np.concatenate([-TS * (gain[:4] @ measured), [1.0 - TS * gain[5]]])
    M = np.zeros((5, 5))
    M[4] = row
    M[:4, :4] = phi
    M[:4] += gam @ row.reshape(1, 5)
    return M


def dominant(M: np.ndarray) -> tuple[complex, float]:
    """The slowest oscillatory mode ``s`` [1/s] of a one-sample map and its damping [-]."""
    s = np.log(np.linalg.eigvals(M).astype(complex)) / TS
    pairs = [x for x in s if abs(x.imag) > 1e-9]
    mode = complex(min(pairs, key=abs))
    return mode, -mode.real / abs(mode)


def gains() -> dict[str, np.ndarray]:
    """Each design's gain at :data:`U0` on the vehicle's default weights."""
    params = load_vehicle(VEHICLE)
    _, _, A, B = vehicle_linearization(params)(U0)
    A, B = np.asarray(A, float), np.asarray(B, float).reshape(-1, 1)
    Q, R = derive_tuning(params, THETA_MAX, params.bar_max).weights.matrices()
    out = {}
    for name, design in DESIGNS.items():
        if design is None:
            out[name] = lqrd(A, B, Q, R, TS).K[0]
            continue
        share, angle = design
        q_aug = np.zeros((6, 6))
        q_aug[:5, :5], q_aug[5, 5] = Q, angle * R[0, 0]
        r_rate = np.array([[1.0 / (share * params.bar_rate) ** 2]])
        out[name] = lqrd(*input_rate_system(A, B), q_aug, r_rate, TS).K[0]
    return out


def linear() -> dict[str, Any]:
    """Dominant mode without and with the current, heave-to-pitch ratio, critical current."""
    params = load_vehicle(VEHICLE)
    plant = vehicle_linearization(params)

    def model(u: float) -> tuple[np.ndarray, np.ndarray]:
        _, _, A, B = plant(u)
        return np.asarray(A, float), np.asarray(B, float).reshape(-1, 1)

    nominal, head = model(U0), model(U0 + CURRENT)
    out: dict[str, Any] = {}
    for name, gain in gains().items():
        static = gain[:5] / gain[5] if gain.size == 6 else gain
        row: dict[str, Any] = {
            'heave_to_pitch_ratio_s_per_m': round(float(static[0] / static[3]), 3),
            'depth_gain_rad_per_m': round(float(static[2]), 4),
            'pitch_gain_rad_per_rad': round(float(static[3]), 4),
        }
        for label, (A, B), c in (('no_current', nominal, 0.0),
                                 ('head_current', head, CURRENT),
                                 ('head_heave_only', nominal, CURRENT)):
            mode, zeta = dominant(closed_loop(gain, A, B, c))
            row[label] = {'s_1_per_s': [round(mode.real, 3), round(abs(mode.imag), 3)],
                          'damping': round(zeta, 3)}
        critical = None
        for step in range(1, 101):
            c = 0.01 * step
            if dominant(closed_loop(gain, *model(U0 + c), c))[1] <= 0.0:
                critical = round(c, 2)
                break
        row['unstable_from_head_current_m_s'] = critical
        out[name] = row
    return out


def fly(rate: bool, through_water: bool) -> dict[str, Any]:
    """The head-current case of ``tests/test_model_error.py``; with ``through_water`` the
    pilot is given the heave through the water instead of over ground."""
    params = load_vehicle(VEHICLE)
    real, environment = model_error_plant(params, f'current_head_{CURRENT:g}')
    settings = PilotSettings(plane_rate_design=rate)
    pilot = DepthPilot.for_vehicle(params, settings)
    if through_water:
        controller = pilot.controller
        step = controller.step

        def corrected(state: DepthState, z_ref: float) -> float:
            heave = state.w + CURRENT * math.sin(state.theta)
            return step(PlaneState(state.z, state.theta, heave, state.q, state.u), z_ref)

        controller.step = corrected  # type: ignore[method-assign]
    run = run_closed_loop(real, [(0.0, 10.0)], 200.0, z0=20.0, u0=U0,
                          environment=environment, settings=settings, pilot=pilot,
                          speed_time_constant=2.0)
    rec = run.record
    m = step_metrics(rec.t, rec.x[:, 2], rec.x[:, 4], rec.x[:, 10], rec.x[:, 12], 10.0,
                     bar_max=params.bar_max, u0=U0, theta_max=THETA_MAX)
    return {'settling_time_s': round(m.settling_time, 2), 'overshoot_m': round(m.overshoot, 3),
            'peak_pitch_deg': round(math.degrees(m.peak_pitch), 2)}


def run() -> dict[str, Any]:
    """All figures."""
    return {
        'vehicle': VEHICLE.name, 'u0_m_s': U0, 'head_current_m_s': CURRENT,
        'linear': linear(),
        'flights': {f'{"rate" if rate else "angle"}_{"through_water" if water else "over_ground"}':
                    fly(rate, water) for rate in (False, True) for water in (False, True)},
    }


if __name__ == '__main__':
    figures = run()
    save_figures('current_damping', figures)
    print(json.dumps(figures, indent=2))
