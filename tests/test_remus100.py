"""The REMUS 100 of config/remus100.yaml (Prestero 2001) on the toolkit: file, trims, pilot, ident.

Oracles are Prestero's published dimensional coefficients (MIT/WHOI MS thesis, 2001, tables
2.3-2.6, B.1, B.2, C.1, C.5, C.10), typed in here independently of the file's nondimensional
values, and equilibria solved here from his equations with scipy.

What was measured (the figures the tests assert, with the margins stated there):

* The model's forces equal Prestero's linear terms to 7e-16 relative at 1.5 and 2.0 m/s
  (the scaling is exact at every speed); the axial drag equals his Xuu u|u| at u_ref =
  1.5 m/s and follows the ITTC line elsewhere (-5.7 % at 2.0 m/s).
* The file carries Prestero's quadratic cross-flow drag (Yvv, Yrr, Zww, Zqq, Mww, Mqq, Nvv,
  Nrr, tables B.1 and B.2). Trims at 1.5 and 2.0 m/s agree with the equilibrium of his
  dimensional equations (Zww w|w| and Mww w|w| included) to 1e-9 relative (BAR -9.13 and
  -5.47 deg, pitch -2.60 and -1.49 deg). At 1.0 m/s there is none within the 13.6 deg fins:
  with B - W = +7 N it needs BAR -17.0 deg (the lowest trimmable speed is 1.17 m/s). The trim
  thrust holds u0: from u0 +- 0.1 m/s, with the pitch held by the pilot's own LQR gain, u
  returns to u0 in 120 s.
* The vertical-plane linearisation equals Prestero's linearised equations typed in here, and
  is open-loop unstable in pitch/heave at 1.5 and 2.0 m/s (Munk moment Muw = +24 kg; the
  quadratic drag adds damping only away from w = q = 0).
* The depth pilot (default settings and speed grid, the vehicle's speed loop)
  flies 20 -> 10, 10 -> 30 and 5 -> 40 m at 1.5 m/s within 1.5x the time-optimal bound of
  the model, pitch within 25 deg (test_depth_change_settles; numbers there and in
  docs/vehicles.md).
* Identification from the force topic with the REMUS missions (config/missions/remus100_*:
  thrust, BAR and helm doublets flown on top of the depth pilot, tools/closed_loop_mission.py,
  20-24 s each, replayed open loop) recovers every coefficient to 3e-15 relative (the
  regression is exact on clean forces); Nelder-Mead agrees to 3e-15.
"""
from __future__ import annotations

import argparse
import json
import math
import pathlib
import subprocess
import sys
from typing import Any

import numpy as np
import pytest
from scipy.optimize import brentq, fsolve

from auv_depth_lqr.bound import settling_bound
from auv_depth_lqr.closed_loop import ClosedLoopRun, run_closed_loop
from auv_depth_lqr.metrics import StepMetrics, step_metrics
from auv_depth_lqr.pilot import PilotSettings, build_controller
from auv_ident import cli
from auv_logs.simlog import write_record
from auv_sim.environment import Environment
from auv_sim.errors import TrimError
from auv_sim.missions import load_mission, run_mission
from auv_sim.model import NX, dynamics, wrenches
from auv_sim.params import VehicleParams, load_vehicle
from auv_sim.simulator import Simulator
from auv_sim.trim import VerticalPlane

ROOT = pathlib.Path(__file__).resolve().parents[1]
REMUS = ROOT / 'config' / 'remus100.yaml'
MISSIONS = {name: ROOT / 'config' / 'missions' / f'remus100_{name}.yaml'
            for name in ('surge', 'pitch', 'yaw')}
#: Gain-scheduling grid [m/s]: the vehicle trims from 1.27 m/s up (13.6 deg fins).
SPEEDS = (1.3, 1.5, 2.0, 2.5)
_H = 1e-30  # complex step

# Prestero 2001, dimensional (his signs; rudder delta_r = -helm, see the vehicle file).
W, B, ZG = 299.0, 306.0, 0.0196                  # N, N, m (tables 2.3, 2.5)
XUU = -1.62                                      # kg/m (table C.1)
ZUW, ZUQ, ZUUDS = -28.6, -5.22, -9.64            # kg/m, kg/rad, kg/(m rad) (table B.1)
MUW, MUQ, MUUDS = 24.0, -2.00, -6.15             # kg, kg m/rad, kg/rad (table B.2)
YUV, YUR, YUUDR = -28.6, 5.22, 9.64              # (table B.1)
NUV, NUR, NUUDR = -24.0, -2.00, -6.15            # (table B.2)
ZWW, ZQQ, MWW, MQQ = -131.0, -0.632, 3.18, -188.0  # kg/m, kg m, kg, kg m^2 (tables B.1, B.2)
YVV, YRR, NVV, NRR = -1310.0, 0.632, -3.18, -94.0  # (tables B.1, B.2, as printed)
U_REF = 1.5                                      # m/s, where the axial drag is matched


@pytest.fixture(scope='module')
def remus() -> VehicleParams:
    return load_vehicle(REMUS)


# ----- the file and its forces ----------------------------------------------------------------

def test_file_loads_with_prestero_mass_properties(remus: VehicleParams) -> None:
    assert remus.name == 'REMUS100'
    weight = remus.m * remus.g
    assert weight == pytest.approx(W, rel=1e-12)
    assert remus.B == B
    assert (remus.zg, remus.Ix, remus.Iy, remus.Iz) == (ZG, 0.177, 3.45, 3.45)
    assert (remus.L_ref, remus.diameter, remus.depth_max) == (1.33, 0.191, 100.0)
    assert math.degrees(remus.bar_max) == pytest.approx(13.6, abs=1e-9)
    for name, source in remus.sources.items():
        assert source.startswith(('Prestero', 'derived', 'assumed', 'body origin', 'standard',
                                  'surface', 'RK4', 'REMUS', '20 deg/s')), (name, source)


def wrench_derivatives(p: VehicleParams, u: float) -> dict[str, float]:
    """d(wrench)/d(state) at straight flight at ``u`` [m/s], by complex step, split like
    Prestero's coefficients: hydrodynamic + added-mass (Coriolis row minus the rigid-body
    part, which he keeps on the left-hand side: m (w_dot - u q), m (v_dot + u r)) and fins."""
    P = p.as_array()
    env = Environment()
    e, prof = env.env_vector(), env.profile()
    x0 = np.zeros(NX, dtype=complex)
    x0[2], x0[6] = 20.0, u

    def d(index: int, rows: slice) -> np.ndarray:
        x = x0.copy()
        x[index] += 1j * _H
        out = np.zeros((4, 6), dtype=complex)
        wrenches(0.0, x, P, e, prof, out)
        return out[rows].sum(axis=0).imag / _H

    hydro = slice(0, 2)
    m = p.m
    return {
        'Zuw': d(8, hydro)[2] / u, 'Muw': d(8, hydro)[4] / u,
        'Zuq': (d(10, hydro)[2] - m * u) / u, 'Muq': d(10, hydro)[4] / u,
        'Yuv': d(7, hydro)[1] / u, 'Nuv': d(7, hydro)[5] / u,
        'Yur': (d(11, hydro)[1] + m * u) / u, 'Nur': d(11, hydro)[5] / u,
        'Zuuds': d(12, slice(3, 4))[2] / u**2, 'Muuds': d(12, slice(3, 4))[4] / u**2,
        'Yuudr': -d(13, slice(3, 4))[1] / u**2, 'Nuudr': -d(13, slice(3, 4))[5] / u**2,
    }


@pytest.mark.parametrize('u', [1.5, 2.0])
def test_forces_equal_prestero_linear_coefficients(remus: VehicleParams, u: float) -> None:
    got = wrench_derivatives(remus, u)
    expected = {'Zuw': ZUW, 'Muw': MUW, 'Zuq': ZUQ, 'Muq': MUQ, 'Yuv': YUV, 'Nuv': NUV,
                'Yur': YUR, 'Nur': NUR, 'Zuuds': ZUUDS, 'Muuds': MUUDS, 'Yuudr': YUUDR,
                'Nuudr': NUUDR}
    for name, value in expected.items():
        assert got[name] == pytest.approx(value, rel=1e-9), name


def ittc(p: VehicleParams, u: float) -> float:
    """ITTC-1957 friction line C_XF at speed u [m/s]."""
    return 0.075 / (math.log10(u * p.L_ref / p.nu_water) - 2.0) ** 2


def drag(p: VehicleParams, u: float) -> float:
    """The model's axial drag [N] at u (level flight), from its hydrodynamic row."""
    x = np.zeros(NX)
    x[2], x[6] = 20.0, u
    out = np.zeros((4, 6))
    env = Environment()
    wrenches(0.0, x, p.as_array(), env.env_vector(), env.profile(), out)
    return float(out[0, 0])


def test_axial_drag_is_prestero_xuu_at_the_reference_speed(remus: VehicleParams) -> None:
    assert drag(remus, U_REF) == pytest.approx(XUU * U_REF**2, rel=1e-12)
    # elsewhere it follows the ITTC line: 5.7 % less than Xuu u^2 at 2 m/s
    ratio = drag(remus, 2.0) / (XUU * 2.0**2)
    assert ratio == pytest.approx(ittc(remus, 2.0) / ittc(remus, U_REF), rel=1e-12)
    assert ratio == pytest.approx(0.9435, abs=5e-4)


# ----- trims --------------------------------------------------------------------------------

def prestero_trim(u: float) -> tuple[float, float, float]:
    """(theta, w, delta_s) of level flight at u from Prestero's dimensional equations:
    Z = (W - B) cos(theta) + Zuw u w + Zww w|w| + Zuuds u^2 ds = 0, M = -zg W sin(theta)
    + Muw u w + Mww w|w| + Muuds u^2 ds = 0 (q = 0: no other term), w = u tan(theta)
    (z_dot = 0)."""
    def residual(v: np.ndarray) -> list[float]:
        theta, ds = v
        w = u * math.tan(theta)
        return [(W - B) * math.cos(theta) + ZUW * u * w + ZWW * w * abs(w) + ZUUDS * u * u * ds,
                -ZG * W * math.sin(theta) + MUW * u * w + MWW * w * abs(w) + MUUDS * u * u * ds]
    theta, ds = fsolve(residual, [0.0, 0.0], xtol=1e-12)
    return float(theta), u * math.tan(theta), float(ds)


@pytest.mark.parametrize(('u0', 'bar_deg', 'theta_deg'), [(1.5, -9.129, -2.604),
                                                          (2.0, -5.465, -1.486)])
def test_trims_within_the_fin_limit_and_match_prestero(
        remus: VehicleParams, u0: float, bar_deg: float, theta_deg: float) -> None:
    trim = VerticalPlane(remus).trim(u0, z=30.0)
    theta, w, ds = prestero_trim(u0)
    assert abs(trim.bar) <= remus.bar_max
    assert trim.theta == pytest.approx(theta, rel=1e-9)
    assert trim.w == pytest.approx(w, rel=1e-9)
    assert trim.bar == pytest.approx(ds, rel=1e-9)
    assert math.degrees(trim.bar) == pytest.approx(bar_deg, abs=1e-3)
    assert math.degrees(trim.theta) == pytest.approx(theta_deg, abs=1e-3)
    # thrust = drag (Xuu, ITTC-scaled away from 1.5 m/s) + the buoyancy's surge component
    xuu = XUU * ittc(remus, u0) / ittc(remus, U_REF)
    assert trim.thrust == pytest.approx(-xuu * u0**2 + (W - B) * math.sin(theta), rel=1e-9)


def test_no_trim_at_1_m_s_within_the_13_6_deg_fins(remus: VehicleParams) -> None:
    _, _, ds = prestero_trim(1.0)
    assert math.degrees(ds) == pytest.approx(-17.01, abs=0.01)    # beyond 13.6 deg
    with pytest.raises(TrimError, match='beyond the plane limit'):
        VerticalPlane(remus).trim(1.0, z=30.0)
    # the lowest speed that trims within the fins (Prestero's equations)
    u_min = brentq(lambda u: prestero_trim(u)[2] + remus.bar_max, 1.0, 1.5, xtol=1e-10)
    assert u_min == pytest.approx(1.173, abs=1e-3)
    VerticalPlane(remus).trim(u_min + 0.01, z=30.0)


@pytest.mark.parametrize('u0', [1.5, 2.0])
@pytest.mark.parametrize('du', [-0.1, 0.1])
def test_trim_thrust_brings_the_surge_speed_to_u0(remus: VehicleParams, u0: float,
                                                  du: float) -> None:
    """Open loop the vehicle pitches over (see the modes test), so the pitch is held by the
    pilot's own discrete LQR gain at u0 (depth 30 m, no reference governor) while the trim
    thrust alone sets the speed; measured |u - u0| <= 6.2e-7 m/s after 120 s, pitch within
    0.33 deg of the trim."""
    trim = VerticalPlane(remus).trim(u0, z=30.0)
    op = build_controller(remus, PilotSettings(speeds=SPEEDS)).design.at(u0)
    x0 = trim.state()
    x0[6] += du
    sim = Simulator(remus, x0=x0)
    ts, xi, bar, peak = 0.1, 0.0, trim.bar, 0.0
    for _ in range(1200):
        x = sim.x
        error = np.array([x[8] - trim.w, x[10], x[2] - 30.0, x[4] - trim.theta, xi])
        slew = remus.bar_rate * ts
        bar = float(np.clip(np.clip(trim.bar - op.K @ error, -remus.bar_max, remus.bar_max),
                            bar - slew, bar + slew))
        xi += (x[2] - 30.0) * ts
        sim.command('bar', bar)
        sim.step(10)
        peak = max(peak, abs(x[4] - trim.theta))
    assert sim.x[6] == pytest.approx(u0, abs=2e-6)
    assert abs(sim.x[2] - 30.0) < 1e-4 and math.degrees(peak) < 0.5


# ----- open-loop modes (why the pilot and the missions are as they are) -----------------------

def jacobian(p: VehicleParams, u0: float) -> np.ndarray:
    trim = VerticalPlane(p).trim(u0, z=30.0)
    env = Environment()
    x0 = trim.state().astype(complex)
    cmd = np.array([trim.bar, 0.0, trim.thrust], dtype=complex)
    J = np.empty((NX, NX))
    for j in range(NX):
        x = x0.copy()
        x[j] += 1j * _H
        xdot = np.zeros(NX, dtype=complex)
        dynamics(0.0, x, cmd, p.as_array(), env.env_vector(), env.profile(), xdot,
                 np.zeros((4, 6), dtype=complex))
        J[:, j] = xdot.imag / _H
    return J


def prestero_vertical_jacobian(u0: float, w_e: float, theta_e: float) -> np.ndarray:
    """(w, q, theta) Jacobian at the trim, surge held at u0, from Prestero's dimensional
    vertical-plane equations typed in here (his combined Zuq, Muw, Muq hold the added-mass
    parts; the quadratic cross-flow terms linearise to 2 Zww |w_e|, 2 Mww |w_e|)::

        (m - Zwd) w' - Zqd q' = (Zuw u + 2 Zww|w_e|) w + (Zuq + m) u q - (W - B) sin(th_e) th
        (Iy - Mqd) q' - Mwd w' = (Muw u + 2 Mww|w_e|) w + (Muq u - m zg w_e) q - zg W cos(th_e) th
    """
    m, zwd, zqd, mqd, iy = W / 9.81, -35.5, -1.93, -4.88, 3.45
    mass = np.array([[m - zwd, -zqd], [-zqd, iy - mqd]])
    forces = np.array([
        [ZUW * u0 + 2 * ZWW * abs(w_e), (ZUQ + m) * u0, -(W - B) * math.sin(theta_e)],
        [MUW * u0 + 2 * MWW * abs(w_e), MUQ * u0 - m * ZG * w_e, -ZG * W * math.cos(theta_e)]])
    J = np.zeros((3, 3))
    J[:2] = np.linalg.solve(mass, forces)
    J[2, 1] = 1.0
    return J


@pytest.mark.parametrize('u0', [1.5, 2.0])
def test_open_loop_vertical_plane_is_prestero_and_unstable(remus: VehicleParams,
                                                           u0: float) -> None:
    """The linearisation (complex-step through the model's wrench, quadratic cross-flow drag
    included) equals Prestero's linearised equations at the trim; both are open-loop
    unstable in pitch/heave: the Munk moment (Muw = +24 kg) outweighs the restoring moment,
    and the quadratic drag adds damping only away from w = q = 0."""
    plane = VerticalPlane(remus)
    trim = plane.trim(u0, z=30.0)
    A, _ = plane.linearize(trim)
    got = A[np.ix_([0, 1, 3], [0, 1, 3])]
    expected = prestero_vertical_jacobian(u0, trim.w, trim.theta)
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12)
    assert max(np.linalg.eigvals(expected).real) > 0.05


# ----- the depth pilot ----------------------------------------------------------------------

THETA_MAX = PilotSettings().theta_max


#: The vehicle's own speed loop in the closed-loop runs (thrust from the surge error, 2 s time
#: constant): with the thrust held, the 7 N positively buoyant REMUS slows to 0.8 m/s in a
#: 24 deg dive, where the bound (surge held at u0) does not apply.
SPEED_TAU = 2.0


def fly(p: VehicleParams, z0: float, z1: float, u0: float,
        duration: float = 120.0) -> tuple[ClosedLoopRun, StepMetrics]:
    run = run_closed_loop(p, [(0.0, z1)], duration, z0=z0, u0=u0,
                          settings=PilotSettings(), speed_time_constant=SPEED_TAU)
    rec = run.record
    return run, step_metrics(rec.t, rec.x[:, 2], rec.x[:, 4], rec.x[:, 10], rec.x[:, 12], z1,
                             bar_max=p.bar_max, u0=u0, theta_max=THETA_MAX)


@pytest.mark.parametrize(('z0', 'z1'), [(20.0, 10.0), (10.0, 30.0), (5.0, 40.0)])
def test_depth_change_settles(remus: VehicleParams, z0: float, z1: float) -> None:
    """Settled within 1.5x the time-optimal bound of the vehicle's own model, pitch and plane
    within their limits, on the pilot's default speed grid (0.1 m/s). Measured: 22.5 / 18.95 s,
    49.6 / 38.44 s, 81.5 / 65.65 s (ratios 1.19, 1.29, 1.24: 14 % or more under the line),
    peak pitch 24.4 deg, overshoot 0.22 m (the A18M's 0.2 m target is not asked here: it is
    not met). On a coarse grid
    (1.3, 1.5, 2.0, 2.5 m/s) the linear interpolation of the trim between grid speeds makes the
    20 -> 10 m climb peak at 25.02 deg."""
    run, m = fly(remus, z0, z1, 1.5, duration=150.0)
    x = run.record.x
    assert np.max(np.abs(x[:, 4])) <= THETA_MAX + 1e-6, m
    assert np.max(np.abs(x[:, 12])) <= remus.bar_max + 1e-9
    assert abs(x[-1, 2] - z1) < 0.1 and m.overshoot < 0.5, m
    bound = settling_bound(remus, z0, z1, 1.5, THETA_MAX).settling_time
    assert m.settling_time <= 1.5 * bound, (m, bound)


def _auv_run(tmp: pathlib.Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, '-m', 'auv_bringup.cli', 'run', '--vehicle',
                           str(REMUS), '--depth', '30',
                           '--initial-depth', '10', '--speed', '1.5', '--duration', '150',
                           '--out', str(tmp / 'run'), *extra],
                          capture_output=True, text=True, timeout=300, check=False)


def test_auv_run_with_the_vehicle_speed_loop_flies_the_dive(remus: VehicleParams,
                                                            tmp_path: pathlib.Path) -> None:
    """`auv run --speed-hold 2` is the flight of the test above as a user runs it."""
    proc = _auv_run(tmp_path, '--speed-hold', '2')
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out['speed_hold_s'] == 2.0
    bound = settling_bound(remus, 10.0, 30.0, 1.5, THETA_MAX).settling_time
    assert out['metrics']['settling_time'] <= 1.5 * bound, (out['metrics'], bound)
    assert out['metrics']['peak_pitch_deg'] <= math.degrees(THETA_MAX) + 1e-6
    bad = _auv_run(tmp_path, '--speed-hold', '-1')
    assert bad.returncode != 0
    assert bad.stderr.strip().splitlines()[-1] == \
        'error: --speed-hold must be > 0 s, got -1'


@pytest.mark.xfail(strict=True, reason=(
    'measured: with the thrust held at its 1.5 m/s trim value (no speed loop), the 7 N '
    'positively buoyant REMUS slows to 0.87 m/s in the 22 deg dive, below the speed at which '
    'its fins can hold it level (no trim at 1 m/s within 13.6 deg): 10 -> 30 m settles after '
    '107 s (2.8x the 38.4 s bound, line 1.5x); its pitch peaks at 24.6 deg (line 27 deg; 31 '
    'deg before the pitch envelope selector); 5 -> 40 m does not settle in 150 s. '
    'The pilot does not yet limit a dive to what a held thrust sustains'))
def test_the_dive_with_the_thrust_held(remus: VehicleParams) -> None:
    run = run_closed_loop(remus, [(0.0, 30.0)], 150.0, z0=10.0, u0=1.5,
                          settings=PilotSettings())
    rec = run.record
    m = step_metrics(rec.t, rec.x[:, 2], rec.x[:, 4], rec.x[:, 10], rec.x[:, 12], 30.0,
                     bar_max=remus.bar_max, u0=1.5, theta_max=THETA_MAX)
    assert np.max(np.abs(rec.x[:, 4])) <= THETA_MAX + math.radians(2.0), m
    assert m.settling_time <= 1.5 * settling_bound(remus, 10.0, 30.0, 1.5,
                                                   THETA_MAX).settling_time, m


# ----- the gap diagnosis on a vehicle unstable without feedback -----------------------------

def test_free_run_window_spans_four_e_folding_times_of_the_unstable_pair(
        remus: VehicleParams) -> None:
    """Oracle: the eigenvalues of the full 6-DOF model's complex-step Jacobian (actuators
    held) restricted to w, q, theta, against the window chosen from the
    vertical plane's own linearisation; the A18M (stable) keeps 60 s."""
    from auv_gap.logs import GapLog
    from auv_gap.problem import free_run_window
    from auv_sim import model
    from auv_sim.trim import VerticalPlane

    trim = VerticalPlane(remus).trim(1.5, z=20.0)
    x0 = trim.state()
    env, prof = np.zeros(model.ENV_SIZE), np.zeros((0, 4))
    J = np.zeros((15, 15))
    for k in range(15):
        xc = x0.astype(complex)
        xc[k] += 1e-20j
        xd = np.zeros(15, dtype=complex)
        model.dynamics(0.0, xc, np.array([x0[12], 0.0, x0[14]], dtype=complex),
                       remus.as_array(), env, prof, xd, np.zeros((4, 6), dtype=complex))
        J[:, k] = xd.imag / 1e-20
    idx = [8, 10, 4]                                    # w, q, theta
    lam = float(np.max(np.linalg.eigvals(J[np.ix_(idx, idx)]).real))
    assert lam > 0.3                                    # measured: +0.385 1/s
    t = np.arange(0.0, 100.0, 0.1)
    state = np.tile(x0[:12], (t.size, 1))
    log = GapLog('level', t, state, {})
    window, why = free_run_window(remus, [log])
    # the vertical plane's own linearisation (surge held by its trim thrust) gives +0.385,
    # the restricted full Jacobian +0.381 1/s (measured): two linearisations within 2 %
    assert window == pytest.approx(4.0 / lam, rel=0.02), why
    a18m = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    level = np.tile(VerticalPlane(a18m).trim(2.0, z=20.0).state()[:12], (t.size, 1))
    assert free_run_window(a18m, [GapLog('level', t, level, {})])[0] == 60.0


def test_gap_finds_a_current_on_the_remus(tmp_path: pathlib.Path) -> None:
    """`auv run` with the current of config/effects/current.yaml (0.3 north, 0.15 east,
    0.02 m/s down), noise, no force topic; `auv gap` as a user runs it: the current named
    with the truth inside its intervals (with 60-s free runs the open-loop unstable REMUS
    diverges in every window and the diagnosis says `unexplained`)."""
    run = subprocess.run([sys.executable, '-m', 'auv_bringup.cli', 'run', '--vehicle',
                          str(REMUS), '--effects', str(ROOT / 'config' / 'effects' /
                                                       'current.yaml'),
                          '--depth', '30', '--initial-depth', '10', '--speed', '1.5',
                          '--speed-hold', '2', '--duration', '300', '--noise',
                          '--no-forces', '--out', str(tmp_path / 'log')],
                         capture_output=True, text=True, timeout=300, check=False)
    assert run.returncode == 0, run.stderr
    gap = subprocess.run([sys.executable, '-m', 'auv_bringup.cli', 'gap', '--vehicle',
                          str(REMUS), str(tmp_path / 'log'), '--out', str(tmp_path / 'gap'),
                          '--no-plots'], capture_output=True, text=True, timeout=300,
                         check=False)
    assert gap.returncode == 0, gap.stderr
    # the window from the data; the free runs restart within it, every 4 e-folding times
    assert 'runs restart every ' in gap.stderr
    assert 'vertical plane unstable without feedback' in gap.stderr
    report = json.loads((tmp_path / 'gap' / 'report.json').read_text())
    assert report['best'] == 'current', report['statement']
    assert report['verdict'] in ('explained', 'partly_explained'), report['statement']
    cand = next(c for c in report['candidates'] if c['effect'] == 'current')
    for key, true in (('north', 0.3), ('east', 0.15), ('down', 0.02)):
        lo, hi = cand['ci95'][key]
        assert lo <= true <= hi, (key, lo, hi)


# ----- identification from the simulator's force topic -------------------------------------

@pytest.fixture(scope='module')
def mission_records(remus: VehicleParams) -> dict[str, Any]:
    return {name: run_mission(remus, load_mission(path)) for name, path in MISSIONS.items()}


def test_missions_stay_near_the_trim(remus: VehicleParams,
                                     mission_records: dict[str, Any]) -> None:
    """The identification missions (made by tools/closed_loop_mission.py: the depth pilot's
    BAR plus the excitation, replayed open loop) keep the vehicle, unstable in pitch/heave
    without feedback, near its 30 m, 1.5 m/s trim, where the linear force regression holds:
    pitch within 5 deg of the trim, pitch rate below 5 deg/s, depth within 0.5 m, surge above
    1.3 m/s; each mission excites its own channel (the surge mission u by 0.2 m/s, the pitch
    mission the plane by 6 deg, the yaw mission r by 5 deg/s)."""
    trim = VerticalPlane(remus).trim(1.5, z=30.0)
    for name, rec in mission_records.items():
        x = rec.x
        assert math.degrees(np.max(np.abs(x[:, 4] - trim.theta))) < 5.0, name
        assert math.degrees(np.max(np.abs(x[:, 10]))) < 5.0, name
        assert np.all(x[:, 6] > 1.3) and np.all(np.abs(x[:, 2] - 30.0) < 0.5), name
    records = mission_records
    assert np.ptp(records['surge'].x[:, 6]) > 0.2
    assert math.degrees(np.ptp(records['pitch'].x[:, 12])) > 6.0
    assert math.degrees(np.max(np.abs(records['yaw'].x[:, 11]))) > 5.0


def test_force_topic_identification_recovers_the_file(
        remus: VehicleParams, mission_records: dict[str, Any],
        tmp_path: pathlib.Path) -> None:
    bags = []
    for name, rec in mission_records.items():
        write_record(tmp_path / name, rec, forces=True)
        bags.append(str(tmp_path / name))
    parser = argparse.ArgumentParser()
    cli.add_arguments(parser)
    args = parser.parse_args([*bags, '--vehicle', str(REMUS), '--out', str(tmp_path / 'out')])
    assert cli.run(args) == 0
    report = json.loads((tmp_path / 'out' / 'report.json').read_text())
    assert report['source'] == 'forces'
    assert set(report['coefficients']) == {'Ksh', 'CZuw', 'CZuq', 'CMuw', 'CMuq', 'CYuv',
                                            'CYur', 'CNuv', 'CNur'}
    for name, c in report['coefficients'].items():
        assert c['value'] == pytest.approx(remus.values[name], rel=1e-9), name
    identified = load_vehicle(tmp_path / 'out' / 'vehicle.yaml')
    assert identified.name == 'REMUS100' and identified.m == remus.m
    for cmp in report['nelder_mead'].values():
        assert cmp['max_relative_difference'] < 1e-5
