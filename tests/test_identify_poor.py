"""What cannot be identified from poor data is said so: which coefficient, why (too few
samples, too little excitation, a log rate whose derivative window removes it, two
coefficients alike, an actuator at its limit) and what would fix it; ``--partial`` fits the
rest. And the 2 Hz surge fit: the actuator wrench integrated inside each sample interval.

Oracles: hand-built records whose excitation is known (a pitch rate at 0.55 Hz that a
5-sample window at 2 Hz removes, read off the kernel's gain; a plane at its limit in a known
share of the samples), and the vehicle file's Ksh for a noise-free 2 Hz log.
"""
from __future__ import annotations

import argparse
import json
import math
import pathlib

import numpy as np
import pytest

from auv_ident.errors import NotIdentifiableError
from auv_ident.identify import EQUATIONS, ForceRecord, NoisePropagation, build_system, identify
from auv_ident.identify.regression import check_identifiable
from auv_ident.motion import consistent_kernel
from auv_sim.environment import Environment
from auv_sim.model import wrench_series
from auv_sim.params import VehicleParams, load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]
A18M = ROOT / 'config' / 'a18m.yaml'


@pytest.fixture(scope='module')
def base() -> VehicleParams:
    return load_vehicle(A18M)


def _record(base: VehicleParams, dt: float, q_hz: float, n: int, *,
            saturated_share: float = 0.0) -> ForceRecord:
    """u = 2 m/s, w slow (period 40 s), q = 0.02 rad/s at ``q_hz``; hydrodynamic forces of
    the model, filtered like forces from motion (5-sample kernel), tiny white noise."""
    t = dt * np.arange(n)
    nu = np.zeros((n, 6))
    nu[:, 0] = 2.0
    nu[:, 2] = 0.03 * np.sin(2 * np.pi * t / 40.0)
    nu[:, 4] = 0.02 * np.sin(2 * np.pi * q_hz * t)
    X = np.zeros((n, 15))
    X[:, 6:12] = nu
    env = Environment()
    tau = wrench_series(t, X, base.as_array(), env.env_vector(), env.profile())[:, 0, :].copy()
    kernel = consistent_kernel(5)
    for j in range(6):
        tau[:, j] = np.convolve(tau[:, j], kernel, mode='same')
    tau[:2] = tau[-2:] = np.nan
    noise = NoisePropagation(sigma=np.full(12, 1e-6), other_jacobian=np.zeros((n, 6, 12)),
                             mass=np.eye(6), derivative_kernel=np.zeros(5))
    sat = np.zeros((n, 3), bool)
    sat[:int(saturated_share * n), 0] = True
    return ForceRecord('poor', t, nu, tau, source='motion', kernel=kernel, noise=noise,
                       saturated=sat)


def test_pitch_rate_lost_to_the_2hz_derivative_window_is_named(base: VehicleParams) -> None:
    # the 5-tap consistent kernel's gain at 0.55 Hz and 2 Hz: |sum_k w_k e^{-i w k dt}|
    kernel = consistent_kernel(5)
    k = np.arange(-2, 3)
    gain = abs(np.sum(kernel * np.exp(-2j * np.pi * 0.55 * 0.5 * k)))
    assert 0.02 * gain < math.radians(0.2)     # below CZuq's threshold after the window
    rec = _record(base, 0.5, 0.55, 600)
    with pytest.raises(NotIdentifiableError,
                       match=r'^CZuq: pitch rate q never varies by more than .* \(as logged it '
                             r'varies by 1\.1[0-9] deg/s beyond the noise: the 2\.5 s '
                             r'derivative window of this 2 Hz log removes it; log at 5 Hz or '
                             r'faster, or fly slower manoeuvres\); fly the pitch mission'):
        check_identifiable(build_system([rec], EQUATIONS['heave'], base))


def test_a_plane_at_its_limit_is_named_with_the_collinearity(base: VehicleParams) -> None:
    rec = _record(base, 0.5, 0.55, 600, saturated_share=0.4)
    rec.nu[:, 4] = 0.5 * rec.nu[:, 2]          # q follows w: CZuw and CZuq alike
    with pytest.raises(NotIdentifiableError,
                       match=r'cannot be told apart .*; the plane was at its limit in 40% of '
                             r'the samples, where the motion follows the limit and not the '
                             r'commands'):
        check_identifiable(build_system([rec], EQUATIONS['heave'], base))


def test_partial_fits_what_is_identifiable_and_lists_the_rest(base: VehicleParams) -> None:
    rec = _record(base, 0.5, 0.05, 600)        # q at 0.05 Hz: passes the window
    rec_flat = _record(base, 0.5, 0.55, 600)   # q lost to the window
    with pytest.raises(NotIdentifiableError):
        identify([rec_flat], base, equations=['heave', 'surge'])
    result = identify([rec_flat], base, equations=['heave', 'surge'], partial=True)
    assert list(result.fits) == ['surge']
    assert result.not_identifiable['heave'].startswith('CZuq: pitch rate q never varies')
    ok = identify([rec], base, equations=['heave'], partial=True)
    assert ok.not_identifiable == {}
    assert ok.coefficients['CZuq'].value == pytest.approx(base.CZuq, rel=1e-3)
    with pytest.raises(NotIdentifiableError, match=r'^no equation can be identified'):
        identify([rec_flat], base, equations=['heave'], partial=True)


def test_surge_from_a_noise_free_2hz_text_log(tmp_path: pathlib.Path,
                                              base: VehicleParams) -> None:
    """The surge mission's 0.5 s thrust lag settles within one 2 Hz sample interval; the
    actuator wrench is integrated over sub-steps of each interval, so Ksh from a noise-free
    2 Hz log equals the file's 48.0 to 3e-5 (the trapezoid rule on the samples alone gave
    48.017, +1.4 of the noisy log's standard errors)."""
    from auv_ident import cli
    from auv_logs import synth
    from auv_sim.missions import load_mission, run_mission

    rec = run_mission(base, load_mission('surge'))
    synth.write_text(tmp_path / 'surge.txt', rec, every=25)
    parser = argparse.ArgumentParser()
    cli.add_arguments(parser)
    ns = parser.parse_args([str(tmp_path / 'surge.txt'), '--map',
                            str(ROOT / 'config' / 'maps' / 'text_2hz_deg_cm.yaml'), '--out',
                            str(tmp_path / 'o'), '--equations', 'surge', '--no-nelder-mead'])
    assert cli.run(ns) == 0
    report = json.loads((tmp_path / 'o' / 'report.json').read_text())
    assert report['coefficients']['Ksh']['value'] == pytest.approx(48.0, rel=3e-5)
    assert report['actuators']['bar'].startswith('command through the actuator model')
