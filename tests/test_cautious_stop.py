"""The first stop planned on a cautious plane once the vehicle has fallen behind its plan.

Oracles: the scaled model's series against the series solved afresh on its own matrices
(:func:`auv_depth_lqr.schedule.feedforward_series`, a second method); on the vehicle files'
own flights, where the reference never waits long enough, the same pilot with the caution
switched off (``caution_wait`` infinite) flies bitwise the same; on a plant with a plane
0.6 times as strong, the same pilot without the caution.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from conftest import ROOT

from auv_depth_lqr.closed_loop import foreign_plant, run_closed_loop
from auv_depth_lqr.metrics import step_metrics
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_depth_lqr.schedule import feedforward_series
from auv_sim.params import VehicleParams, load_vehicle

THETA_MAX = math.radians(25.0)


def _plane_matrices(P: np.ndarray, u0: float, w_e: float, theta_e: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` over ``(w, q, z, theta, xi)`` from the heave and pitch rows ``P``, written
    out by hand from the depth kinematics ``z_dot = -u sin(theta) + w cos(theta)``."""
    A = np.zeros((5, 5))
    B = np.zeros((5, 1))
    A[0, [0, 1, 3]] = P[0, :3]
    A[1, [0, 1, 3]] = P[1, :3]
    B[:2, 0] = P[:, 3]
    A[2, 0] = math.cos(theta_e)
    A[2, 3] = -u0 * math.cos(theta_e) - w_e * math.sin(theta_e)
    A[3, 1] = 1.0
    A[4, 2] = 1.0
    return A, B


@pytest.mark.parametrize('name', ['a18m', 'npsauv2'])
def test_the_cautious_plane_is_the_estimate_less_its_deviation(name: str) -> None:
    """Hand-worked: an estimate of a plane moment 0.6 of the file's (``p5 = -0.4``) with the
    prior's deviation 0.5 untouched is taken as ``0.6 - 0.5 = 0.1``, floored at the gain
    range's 0.25: the rows' plane column is ``0.25 / k`` of the estimate's, the series'
    plane column ``k / 0.25`` of it, and that series is the one solved afresh on the scaled
    rows; the trim and the other columns are the estimate's."""
    params = load_vehicle(ROOT / 'config' / f'{name}.yaml')
    pilot = DepthPilot.for_vehicle(params, PilotSettings(learn=True))
    learner = pilot.controller.learner
    assert learner is not None
    nominal = pilot.controller.design.at(1.5)
    learner.assume([0.0, 0.0, 0.0, 0.0, -0.4, 0.0, 0.0])
    assert learner.estimate.sigma[4] == pytest.approx(0.5, rel=1e-12)
    latest = learner.correct(nominal, latest=True)
    k = float(latest.P[1, 3]) / float(nominal.P[1, 3])
    # the plane-moment parameter alone: the pitch row's plane entry is 0.6 of the file's
    # to within the heave coupling of the mass matrix (a few per cent)
    assert k == pytest.approx(0.6, abs=0.06)
    cautious = learner.cautious(latest, nominal)
    s = 0.25 / k
    np.testing.assert_allclose(cautious.P[:, 3], s * latest.P[:, 3], rtol=1e-12)
    np.testing.assert_allclose(cautious.P[:, :3], latest.P[:, :3], rtol=0, atol=0)
    np.testing.assert_allclose(cautious.F[:, 3], latest.F[:, 3] / s, rtol=1e-12)
    np.testing.assert_allclose(cautious.F[:, :3], latest.F[:, :3], rtol=0, atol=0)
    assert (cautious.w_e, cautious.theta_e, cautious.bar_e) == \
        (latest.w_e, latest.theta_e, latest.bar_e)
    assert cautious.learned and cautious.dbar_dv == float(cautious.F[0, 3])
    # the rows are linearised at the design's trim (PlantEstimator.correct)
    A, B = _plane_matrices(cautious.P, nominal.u0, nominal.w_e, nominal.theta_e)
    np.testing.assert_allclose(feedforward_series(A, B, cautious.u0), cautious.F,
                               rtol=1e-8, atol=1e-12)
    # the stop planned on it brakes less than on the estimate
    braking = pilot.controller.reference.braking
    assert braking(cautious, -1.0) < braking(latest, -1.0)


def test_without_caution_or_with_a_sure_plane_the_estimate_is_kept() -> None:
    """``caution`` 0, or an estimate whose plane is already at the gain range's floor: the
    model is returned as it is."""
    params = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    pilot = DepthPilot.for_vehicle(params, PilotSettings(learn=True))
    learner = pilot.controller.learner
    assert learner is not None
    nominal = pilot.controller.design.at(1.5)
    learner.assume([0.0, 0.0, 0.0, 0.0, -0.4, 0.0, 0.0])
    latest = learner.correct(nominal, latest=True)
    learner.settings = dataclasses.replace(learner.settings, caution=0.0)
    assert learner.cautious(latest, nominal) is latest
    learner.settings = dataclasses.replace(learner.settings, caution=1.0)
    learner.assume([0.0, 0.0, 0.0, 0.0, -0.8, 0.0, 0.0])
    weak = learner.correct(nominal, latest=True)
    assert float(weak.P[1, 3]) / float(nominal.P[1, 3]) < 0.25
    assert learner.cautious(weak, nominal) is weak


def _fly(design: VehicleParams, plant: VehicleParams, z0: float, z1: float, caution: bool,
         duration: float) -> tuple[np.ndarray, object, tuple[float, float] | None]:
    pilot = DepthPilot.for_vehicle(design, PilotSettings(learn=True))
    learner = pilot.controller.learner
    assert learner is not None
    if not caution:
        learner.settings = dataclasses.replace(learner.settings, caution_wait=math.inf)
    run = run_closed_loop(plant, [(0.0, z1)], duration, z0=z0, u0=1.5, pilot=pilot)
    r = run.record
    metrics = step_metrics(r.t, r.x[:, 2], r.x[:, 4], r.x[:, 10], r.cmd[:, 0], z1, u0=1.5,
                           theta_max=THETA_MAX)
    return np.column_stack([r.x, r.cmd]), metrics, pilot.controller.waited


@pytest.mark.parametrize('name, z0, z1', [('a18m', 20.0, 10.0), ('a18m', 10.0, 30.0),
                                          ('remus100', 20.0, 10.0),
                                          ('npsauv2', 20.0, 10.0)])
def test_on_the_files_own_model_the_caution_changes_nothing(name: str, z0: float,
                                                           z1: float) -> None:
    """On the vehicle file's own model the reference waits less than ``caution_wait`` (the
    REMUS 100's climb the longest), so the flight is bitwise the one without the caution."""
    params = load_vehicle(ROOT / 'config' / f'{name}.yaml')
    duration = 60.0 if z1 < z0 else 80.0
    with_caution, _, waited = _fly(params, params, z0, z1, True, duration)
    assert waited is not None and waited[1] < 3.0
    without, _, _ = _fly(params, params, z0, z1, False, duration)
    np.testing.assert_array_equal(with_caution, without)


def test_a_plant_that_falls_behind_its_plan_is_stopped_on_a_cautious_plane() -> None:
    """The A18M's foreign plant (plane 0.6 as strong in moment, trim 9 deg off), first
    10 -> 30 m with learning: the reference waits for the dive for far longer than
    ``caution_wait`` (measured 30 s), and the stop planned on the cautious plane overshoots
    less and settles sooner than the same pilot's without the caution (measured 80.5 s and
    0.09 m, against 94.7 s and 0.38 m)."""
    design = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    plant = foreign_plant(design, 1.5)
    _, cautious, waited = _fly(design, plant, 10.0, 30.0, True, 160.0)
    _, plain, _ = _fly(design, plant, 10.0, 30.0, False, 160.0)
    assert waited is not None and waited[1] > 10.0
    assert plain.settling_time is not None and cautious.settling_time is not None
    assert cautious.settling_time < plain.settling_time - 5.0, (cautious, plain)
    assert cautious.overshoot < 0.5 * plain.overshoot, (cautious, plain)
    assert math.degrees(cautious.peak_pitch) <= 26.0, cautious
