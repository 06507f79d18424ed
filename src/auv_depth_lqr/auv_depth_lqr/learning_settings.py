"""Settings of the plant estimate of :mod:`auv_depth_lqr.learning` (its prior, its noise,
what it learns from and when what it learned is flown), each with the reason for its value.

Units: dimensionless shares unless stated; times [s].
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ['LearningSettings']


@dataclass(frozen=True)
class LearningSettings:
    """Prior and noise of the plant estimate (dimensionless unless stated).

    The prior standard deviations say how far the vehicle may be from its file before the
    data says so; they also set how the estimate splits a residual among terms that the
    data cannot tell apart (at rest a buoyancy and a plane offset look alike).
    """

    buoyancy: float = 0.05
    """Prior of ``p1``: a heave force offset of 5 % of the weight (a vehicle ballasted with
    ~1 % of its weight is typical) [-]."""
    moment: float = 1.0
    """Prior of ``p4``: a pitch moment offset as large as the plane's moment at full travel
    ``|M_bar(u)| bar_max`` at the speed ``u`` of the first sample learned from, in shares of
    that moment [-] (a larger offset is one the plane cannot trim out). The estimate ``p4``
    itself stays in shares of ``W L``; a prior in shares of ``W L`` would be ~7 full planes
    on the A18M and one on the REMUS 100, and so wide a prior lets the offset explain what
    is the plane's effectiveness."""
    plane: float = 0.5
    """Prior of ``p2``, ``p5``: the plane's force and moment within about +-50 % of the
    file's [-]."""
    hull: float = 0.5
    """Prior of ``p3``, ``p6``, ``p7``, as a share of the coefficient's size on the model
    (for ``p6`` the hull's ``CMuw`` plus the Munk moment the model computes) [-]."""
    noise: float = 0.2
    """Smallest standard deviation of the unexplained heave force and pitch moment per
    sample, in shares of the plane's force and moment at full travel at the sample's speed
    (``|Z_bar(u)| bar_max``, ``|M_bar(u)| bar_max``) [-]. Above it, the filter takes the
    scatter it measures (:attr:`noise_time`): the sample-to-sample error of finite
    differences, sensor noise, unmodelled fast dynamics."""
    noise_time: float = 10.0
    """Time [s] over which the measured scatter of the residual is averaged: half the mean
    square of its change from one sample to the next (the successive-difference estimate
    of a variance, which a slowly varying model error does not inflate), weighted
    exponentially and normalised by its weights (so it is a mean from the second sample
    on)."""
    drift_time: float = 60.0
    """Time [s] over which a parameter may drift by one prior standard deviation: the
    random walk of the Kalman filter (a vehicle changes its ballast or speed, the estimate
    follows)."""
    plausible: float = 3.0
    """An estimate is flown only while every parameter is within this many prior standard
    deviations of the vehicle file [-] (:attr:`PlantEstimator.implausible`): further off,
    the error is not of the model's form (a plane delay or lag is explained by a hull lift
    several times the file's and a weaker plane, whose model flown drove an A18M with a
    0.18 s plane delay and a 0.33 s lag 30 m past its command), and the pilot keeps the
    file's model."""
    delays: float = 0.3
    """Longest plane delay [s] the estimator considers: one filter per whole number of
    samples from 0 to it, each fed the commands that much later through the vehicle file's
    actuator; the filter whose predictions fit the data best gives the estimate
    (:attr:`delay_time`, :attr:`delay_margin`). A plane that acts later than its model says
    is otherwise explained by the model's own terms, and the estimate is biased."""
    delay_time: float = 120.0
    """Time [s] over which the filters' fits are compared: the log-likelihoods of their
    predictions of each sample, forgotten exponentially."""
    delay_margin: float = 3.0
    """Log-likelihood [-] by which another filter must fit the data better than the one
    giving the estimate before it takes over (no switching on noise)."""
    evidence: float = 10.0
    """Log-likelihood [-] by which the learned model's predictions of the samples learned
    from (each made before the sample was learned from, forgotten over :attr:`delay_time`)
    must beat the vehicle file's predictions of the same samples before the learned model is
    flown (:attr:`PlantEstimator.evidence`): an estimate that has fitted the sensors' noise
    predicts no better than the file and is not flown. The evidence is the log-likelihood
    ratio for Gaussian noise of the measured variance, without the estimate's own
    uncertainty, forgotten over ``delay_time``; the bar is set well above what the sensors'
    noise gives on a file that is right. Measured: at
    most 4.2 on the REMUS 100 and A18M files' own models with realistic sensor noise (12
    flights of 120 s), 10 within 0.4 s of learning on the foreign plants of
    :func:`auv_depth_lqr.closed_loop.foreign_plant` (0.1-49 s with that noise)."""
    gain_range: tuple[float, float] = (0.25, 4.0)
    """Range of the plane effectiveness ``1 + p`` used to scale the LQR gain [-]."""
    excitation_change: float = 1.0
    """Shortest depth change [m] that excites the plant: the estimate learns while the
    reference of a change at least this long moves and for :attr:`excitation_time` after;
    in a hold, before the first such change and in a shorter one (a reference started at a
    noisy depth reading moves a few millimetres) it learns nothing (the scatter of its
    residual and the thrust are still measured)."""
    excitation_time: float = 10.0
    """Time [s] after the depth reference of a change came to rest during which the
    estimate still learns (the vehicle's landing on it). At a hold nothing but the
    sensors' noise, fed back through the pilot, moves the plane and the state, so it is in
    the regressors and in the measured accelerations at once, and a regression on it is
    biased, not merely noisy (errors in variables; the closed loop ties the plane to the
    noise): a small AUV on its own model holding 2 m on realistic sensor noise
    (``SensorNoise.realistic``) learned a Munk moment of -1.1 and a plane 1.77 times as
    strong in 60 s, and its pitch swung to 5.2 deg. The commanded depth change is the
    excitation the noise is not part of. Learning the offsets alone at a hold is no
    answer: they then take up what the other terms' errors leave as the vehicle moves and,
    flown at once, drove the REMUS 100 foreign plant
    (:func:`auv_depth_lqr.closed_loop.foreign_plant`) into a growing oscillation about its
    held depth (+-0.2 m and 6 deg within 40 s)."""
    thrust_time: float = 2.0
    """Time constant [s] of the exponentially weighted mean of the thrust the vehicle flies
    with (the surge force the model's drag and the measured surge acceleration need,
    :attr:`PlantEstimator.thrust`), normalised by its weights: from the first samples on the
    mean of those samples."""
