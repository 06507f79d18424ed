"""Learning the plant while flying: what the pilot's model gets wrong, estimated every sample.

Frames and units (Fossen): world NED, depth ``z`` positive down [m]; body FRD; pitch
``theta`` nose up [rad]; surge ``u``, heave ``w`` [m/s], pitch rate ``q`` [rad/s]; BAR [rad];
heave force ``Z`` [N] and pitch moment ``M`` [N m] about the body origin.

The pilot's model is the vehicle file's nonlinear vertical plane
(:class:`auv_sim.trim.VerticalPlane`: ``M_wq (w_dot, q_dot) = (Z, M)`` at the measured surge).
Over each control sample the measured change of ``(w, q)`` gives the wrench the vehicle
really felt, ``M_wq (dw, dq) / Ts``; less the model's wrench at the sample's mean state and the
BAR commanded over it, it is what the model does not explain. :class:`PlantEstimator`
explains it by seven parameters, a linear regression on the model's own terms::

    dZ = p1 W cos(theta) + p2 Z_bar(u) BAR + p3 qs u w
    dM = p4 W L          + p5 M_bar(u) BAR + p6 qs L u w + p7 qs L^2 u q

``W`` the weight [N], ``L`` the reference length [m], ``qs = 1/2 rho S_ref`` [kg/m];
``Z_bar``, ``M_bar`` the model's plane force and moment per radian at the measured speed
[N/rad, N m/rad]. So ``p1``, ``p4`` are a buoyancy or a trim offset (``p1 W`` a vertical
force, as a buoyancy is: along the body's axis it is ``-p1 W sin(theta)``, which slows a
buoyant vehicle's dive with its thrust held; a level trim needing
another plane angle, a plane bias, a pitch moment the hull has and the file does not), in
shares of ``W`` and ``W L``; ``p2``, ``p5`` the plane's effectiveness less one (a plane half
as strong: -0.5); ``p3``, ``p6``, ``p7`` errors of the hull's lift, Munk and damping
coefficients ``CZuw``, ``CMuw``, ``CMuq`` (a Munk moment the vehicle does not have). The
regression is a Kalman filter on random-walk parameters: it learns in every phase of flight
(a climb excites the plane terms, a hold the offsets), from a prior about the vehicle file
(:class:`LearningSettings`), never forgets faster than ``drift_time`` and keeps what it
cannot see (a direction the data does not excite keeps its estimate; its uncertainty grows).
Its noise per sample is the scatter it measures in the residual (half the mean square of
its change from one sample to the next), at least a share of the plane's own force and
moment; the prior of the moment offset is the plane's moment at full travel. Both are
sized by the plane, not by ``W`` and ``W L``: what tells the plane's effectiveness from an
offset is the difference between the plane's two ends, a climb and a stop, and a noise or
an offset prior many planes wide drowns it (on the A18M, 1 % of ``W L`` is 7 full planes).
Because the residual is taken against the nonlinear model, neither the unstable modes nor
the quadratic cross-flow drag of a steep climb are mistaken for a plant error, and an
open-loop-unstable vehicle (the REMUS 100) learns like any other.

:class:`~auv_depth_lqr.learned_model.LearnedModel` turns the estimate into the pilot's
linear model at a speed (:meth:`PlantEstimator.correct`): everything the pilot plans, the
reference's climb rate, its plane budget and its stop, then rests on the plane the plant has.

A plane that acts later than the file's actuator says is learned too, to a sample: one
filter runs per plane delay from 0 to ``LearningSettings.delays`` (0.3 s: 0, 1, 2, 3 samples
at 10 Hz), each fed the commands that much later; each sample adds the log-likelihood of each
filter's prediction of it to that filter's fit (forgotten over ``delay_time``, 120 s), and the
filter giving the estimate hands over to one that fits better by ``delay_margin`` (3). On
an A18M whose plane answers 0, 0.1, 0.2 or 0.3 s late, one 30 m dive picks that delay.

The regressors' heave velocity and pitch rate are an instrument, not the sample's own: the
mean of the state one sample before the sample's start and one sample after its end. The
model's wrench is taken at the sample's own mean state, so a sensor's noise is in the
residual through the model's own ``w`` and ``q`` terms; at that same state in the
regressors it would be in both, and the regression takes a share of the model's terms for
errors (errors in variables: on the REMUS 100's own model flown 10 -> 20 m with the
simulator's realistic sensor noise, 1 cm/s on the velocities, the hull lift was learned
+1.56 and the Munk moment -1.21). The instrument's noise is other samples' (white noise:
independent), and the estimate learns one sample late.

The plane's angle needs an instrument of another kind. The pilot's feedback moves the plane
with the noise of the state it answers, and that noise is in the measured acceleration of
the same sample (closed-loop identification): regressed on its own angle, the plane takes
the noise's share for its effectiveness (the REMUS 100's own model, 10 -> 20 and 20 -> 10 m
on the realistic sensor noise, three seeds each: a plane moment of +0.29 to +0.56, a plane
30-56 % stronger than it is). The regression is an instrumental-variable one: its gain is
``cov Z^T (H cov Z^T + R)^-1`` with ``H`` the rows above and ``Z`` the same rows at the
plane's mean angle over the sample before, which no noise of this sample has moved (white
noise; the plane is rate-limited, so the two angles are close). On the same flights the
plane moment is learned at -0.23 to +0.09 (mean -0.06): scatter about the truth, not a bias.

What is learned is flown only while it predicts better than the vehicle file: each filter
sums, forgotten over ``delay_time``, half the difference of the file's and its own squared
errors predicting each sample (made before the sample is learned from), over the noise's
variance (:attr:`PlantEstimator.evidence`); below ``LearningSettings.evidence`` (10) the
pilot flies the file. Fitted to the sensors' noise, an estimate predicts new samples worse
than the file: on the REMUS 100's and the A18M's own models with realistic sensor noise
(10 m changes, 120 s) the evidence ends at -13 to -63, and the pilot flies exactly as
without learning. The foreign plants' errors pass it within 0.4 s of learning.

Limits: the estimate is a regression on the model's own terms. A plant error of another form
(a plane lag other than the file's, a delay beyond ``delays`` or between two samples) is
explained by them as well as they can (behind a 0.3 s plane delay the REMUS 100 learned a
hull lift seven times its own before the delay filters), so on such a plant the learned
model is not the plant; where that puts it past what physics allows
(:attr:`PlantEstimator.implausible`), it is not flown; in a steady climb the data hold one
operating point and cannot split the error between an offset, the plane's effectiveness and
the Munk term.
"""
from __future__ import annotations

import collections
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.glide import Glide, glide_cap
from auv_depth_lqr.learned_model import LearnedModel
from auv_depth_lqr.learning_settings import LearningSettings
from auv_depth_lqr.mean import ExponentialMean
from auv_depth_lqr.schedule import Matrix, OperatingPoint
from auv_sim.errors import TrimError
from auv_sim.params import VehicleParams, mass_matrix

__all__ = ['N_PARAMS', 'PARAMETERS', 'LearningSettings', 'PlantEstimate', 'PlantEstimator']

PARAMETERS = ('buoyancy', 'plane_force', 'hull_lift', 'moment', 'plane_moment', 'munk',
              'pitch_damping')
"""Names of the estimated parameters ``p1..p7`` (module docstring), as on ``/diagnostics``."""
N_PARAMS = len(PARAMETERS)
_H = 1e-30
"""Complex step [-]."""
OPTIMISM = 1.0
"""Standard deviations by which :meth:`PlantEstimator.optimistic` moves a figure [-]."""
THRUST_KNOWN = 1.0 - math.exp(-1.0)
"""Weight the thrust's mean must have gathered before it is known (``thrust_time`` of
samples) [-]: one sample's surge force is the difference of two noisy speeds over a sample
(on the realistic sensor noise the REMUS 100's, 4 N of noise against 4 N of thrust, was
8.6 N off, and the held-thrust dive cap solved on it held a dive still for 5 s)."""


class PlantEstimate(NamedTuple):
    """The estimate at one sample (module docstring)."""

    values: tuple[float, ...]
    """``p1..p7`` [-] (:data:`PARAMETERS`)."""
    sigma: tuple[float, ...]
    """Their standard deviations [-]."""
    samples: int
    """Samples learned from since the pilot started."""


class _Sample(NamedTuple):
    """One sample as :meth:`PlantEstimator.update` takes it."""

    start: tuple[float, float, float]
    end: tuple[float, float, float]
    u: float
    bar: float
    du: float
    excited: bool


@dataclass
class _Filter:
    """One plane delay's Kalman filter: its commands, its plane's angle and its estimate."""

    delay: int
    """Samples by which the commands reach the plane later [-]."""
    p: Matrix
    """The parameters ``p1..p7`` (module docstring)."""
    cov: Matrix
    """Their covariance."""
    commands: collections.deque[float] = field(default_factory=collections.deque)
    """The last ``delay + 1`` commands [rad], oldest first."""
    plane_angle: float | None = None
    """The plane's angle at the end of the last sample [rad] (None: not known)."""
    plane_before: float | None = None
    """The plane's mean angle over the sample before the one being learned [rad] (None: not
    known): the plane regressor's instrument."""
    unsure: float = 0.0
    """Time [s] still to wait before learning (the plane's angle is not known)."""
    samples: int = 0
    thrust: ExponentialMean = field(default_factory=lambda: ExponentialMean(1))
    """Mean over ``thrust_time`` of the surge force the measured accelerations need beyond
    the model's [N] (:attr:`PlantEstimator.thrust`)."""
    residual: Matrix | None = None
    scatter: ExponentialMean = field(default_factory=lambda: ExponentialMean(2))
    """Mean over ``noise_time`` of half the squared change of the residual from one sample
    to the next [N^2, N^2 m^2] (its successive-difference variance)."""
    noise: Matrix = field(default_factory=lambda: np.full(2, math.nan))
    fit: float = 0.0
    """Log-likelihood of the filter's predictions, forgotten over ``delay_time`` [-]."""
    over_file: float = 0.0
    """How much better the estimate predicts the samples learned from than the vehicle file
    does: half the difference of their squared errors over the noise's variance, forgotten
    over ``delay_time`` [-]."""


class PlantEstimator:
    """Online estimate of what the vehicle file gets wrong (module docstring).

    Parameters
    ----------
    params : VehicleParams
        The pilot's vehicle file.
    ts : float
        Control sample period [s].
    settings : LearningSettings, optional
        Prior and noise.
    """

    def __init__(self, params: VehicleParams, ts: float,
                 settings: LearningSettings | None = None) -> None:
        if not (math.isfinite(ts) and ts > 0.0):
            raise DesignError(f'plant estimator: ts = {ts!r} s must be finite and > 0')
        # the compiled model only for a pilot that learns (a node's start without it is quicker)
        from auv_sim.trim import VerticalPlane

        self.settings = settings if settings is not None else LearningSettings()
        s = self.settings
        for name, value in (('delays', s.delays), ('delay_margin', s.delay_margin),
                            ('excitation_change', s.excitation_change),
                            ('excitation_time', s.excitation_time)):
            if not (math.isfinite(value) and value >= 0.0):
                raise DesignError(f'plant estimator: {name} = {value!r} must be finite and >= 0')
        for name, value in (('delay_time', s.delay_time), ('thrust_time', s.thrust_time),
                            ('noise', s.noise)):
            if not (math.isfinite(value) and value > 0.0):
                raise DesignError(f'plant estimator: {name} = {value!r} must be finite and > 0')
        if not math.isfinite(s.evidence):
            raise DesignError(f'plant estimator: evidence = {s.evidence!r} must be finite')
        self.plane = VerticalPlane(params)
        self.plane.warm_up()  # at start, not in the first control step that learns or trims
        self.ts = float(ts)
        m = mass_matrix(params)
        self.m_wq: Matrix = np.asarray(m[np.ix_([2, 4], [2, 4])], dtype=np.float64)
        self.m_u: Matrix = np.asarray(m[0, [0, 2, 4]], dtype=np.float64)
        """The surge row of the mass matrix over ``(u_dot, w_dot, q_dot)`` [kg, kg, kg m]."""
        self.m_wq_u: Matrix = np.asarray(m[[2, 4], 0], dtype=np.float64)
        """The heave and pitch rows' surge column of the mass matrix [kg, kg m]: a surge
        acceleration ``u_dot`` takes ``m_wq_u u_dot`` of the wrench (``m z_g`` in pitch)."""
        self.bar_tau = max(float(params.bar_tau), 0.0)
        self.bar_rate = float(params.bar_rate)
        self.plane_settling = 2.0 * float(params.bar_max) / self.bar_rate + 5.0 * self.bar_tau
        """Time [s] the plane takes from anywhere to where it is commanded (across its travel at
        its rate, then five lags): until then after a start its angle is not known and
        nothing is learned."""
        self.weight = float(params.m * params.g)
        self.length = float(params.L_ref)
        self.qs = 0.5 * float(params.rho) * float(params.S_ref)
        self.model = LearnedModel(self.m_wq, self.weight, self.length, self.qs,
                                  s.gain_range)
        """The pilot's linear model with an estimate applied."""
        # The model's u w moment per unit u w [N m s^2/m^2]: the hull's CMuw and the Munk
        # moment of the added masses, read off the model's own wrench.
        munk = self._wrench(1.0, 1.0, 0.0, 0.0, 0.0)[0][1] - self._wrench(1.0, 0.0, 0.0, 0.0,
                                                                          0.0)[0][1]
        s = self.settings
        cmuw = max(abs(munk) / (self.qs * self.length), 1e-3)
        self._prior = np.array([s.buoyancy, s.plane, s.hull * max(abs(params.CZuw), 1e-3),
                                s.moment, s.plane, s.hull * cmuw,
                                s.hull * max(abs(params.CMuq), 1e-3)])
        self.bar_max = float(params.bar_max)
        self.czuw, self.cmuq = float(params.CZuw), float(params.CMuq)
        """The file's hull lift and pitch damping coefficients [-] (:attr:`implausible`)."""
        self._drift = self._prior ** 2 * self.ts / s.drift_time
        self.reset()

    def reset(self) -> None:
        """Forget everything learned (back to the vehicle file)."""
        self._flown: Matrix = np.zeros(N_PARAMS)
        self._flying = False
        self._assumed = False
        """Whether the estimate was taken by :meth:`assume` (flown before a sample is
        learned)."""
        self._mean: tuple[_Filter, int, Matrix, int] | None = None
        """The mean flown (:meth:`fly_latest`): its filter, that filter's sample count at
        the last estimate taken in, the mean [parameter units] and the number of estimates."""
        self._moment_prior_set = False
        delays = int(math.floor(self.settings.delays / self.ts + 1e-9))
        self._filters = [_Filter(k, np.zeros(N_PARAMS), np.diag(self._prior ** 2))
                         for k in range(max(delays, 0) + 1)]
        self._h = self._filters[0]
        """The filter giving the estimate."""
        self._thrust_shift = 0.0
        """A move of the thrust [N] while :meth:`optimistic` evaluates a figure at it."""
        self._file_y: Matrix = np.zeros(2)
        """The file's error predicting the sample being learned [N, N m]."""
        self.forget_plane()

    def forget_plane(self) -> None:
        """The plane's angle is not known (a start, a gap in the commands): the actuator
        model starts again from the next command, and nothing is learned for
        :attr:`plane_settling` seconds."""
        # every filter waits as long as the longest delay's: their fits are compared on the
        # same samples
        wait = self.plane_settling + self._filters[-1].delay * self.ts
        for h in self._filters:
            h.plane_angle = None
            h.plane_before = None
            h.unsure = wait
            h.residual = None
            h.commands.clear()
        self._before: _Sample | None = None
        """The last sample learned, whose start is the next one's instrument."""
        self._pending: _Sample | None = None
        """The sample waiting for the next one (its instrument's end)."""

    @property
    def noise(self) -> tuple[float, float]:
        """Standard deviation of the unexplained heave force [N] and pitch moment [N m] per
        sample the last sample was learned with (``LearningSettings.noise``, ``noise_time``);
        nan before the first."""
        return float(self._h.noise[0]), float(self._h.noise[1])

    @property
    def plane_delay(self) -> float:
        """The plane delay [s] of the filter giving the estimate (``LearningSettings.
        delays``): how much later than its model the plane acts, to a sample."""
        return self._h.delay * self.ts

    def _sample_noise(self, h: _Filter, y: Matrix, z_bar: float, m_bar: float) -> Matrix:
        """The noise standard deviations [N, N m] for a sample whose residual is ``y``:
        the measured scatter (``noise_time``), at least ``noise`` of the plane's force and
        moment at full travel (``z_bar``, ``m_bar`` [N/rad, N m/rad] at the sample's
        speed)."""
        s = self.settings
        if h.residual is not None:
            decay = math.exp(-self.ts / s.noise_time)
            h.scatter.add(0.5 * (y - h.residual) ** 2, decay)
        h.residual = y.copy()
        floor = s.noise * self.bar_max * np.array([abs(z_bar), abs(m_bar)])
        if h.scatter.weight > 0.0:
            return np.maximum(np.sqrt(h.scatter.mean), floor)
        return floor

    def _set_moment_prior(self, m_bar: float) -> None:
        """The prior of ``p4`` from the plane's moment per radian ``m_bar`` [N m/rad] at the
        first sample's speed (``LearningSettings.moment``), its drift with it."""
        prior = self.settings.moment * abs(m_bar) * self.bar_max / (self.weight * self.length)
        if not prior > 0.0:
            return
        self._prior[3] = prior
        self._drift[3] = prior ** 2 * self.ts / self.settings.drift_time
        for h in self._filters:
            h.cov[3, :] = 0.0
            h.cov[:, 3] = 0.0
            h.cov[3, 3] = prior ** 2

    def plane_over(self, bar: float) -> float:
        """The mean plane angle [rad] over a sample commanded ``bar`` [rad], on the vehicle
        file's actuator (``BAR_dot = clip((bar - BAR) / bar_tau, +-bar_rate)``, solved
        exactly: at the rate limit while ``|bar - BAR| > bar_rate bar_tau``, then the lag)
        reached by the command :attr:`plane_delay` later; the plane is then where it ends
        the sample."""
        return self._plane_over(self._h, bar)

    def _plane_over(self, h: _Filter, bar: float) -> float:
        """:meth:`plane_over` on the filter ``h``'s plane and delay."""
        h.commands.append(bar)
        # the command of `delay` samples ago (the oldest known, just after a start)
        bar = h.commands.popleft() if len(h.commands) > h.delay else h.commands[0]
        start = bar if h.plane_angle is None else h.plane_angle
        ts, tau, rate = self.ts, self.bar_tau, self.bar_rate
        gap = bar - start
        sign = 1.0 if gap >= 0.0 else -1.0
        # rate-limited phase: |gap| shrinks at `rate` down to rate * tau (all of it if tau = 0)
        t1 = min(max(abs(gap) - rate * tau, 0.0) / rate, ts) if rate > 0.0 else 0.0
        mid = start + sign * rate * t1
        area = 0.5 * (start + mid) * t1
        t2 = ts - t1
        if t2 > 0.0:
            if tau > 0.0:
                decay = math.exp(-t2 / tau)
                end = bar + (mid - bar) * decay
                area += bar * t2 + (mid - bar) * tau * (1.0 - decay)
            else:
                end = bar
                area += bar * t2
        else:
            end = mid
        h.plane_angle = end
        return area / ts

    @property
    def plane_angle(self) -> float | None:
        """The plane's angle [rad] at the end of the last sample on the vehicle file's
        actuator (:meth:`plane_over`), None while it is not known."""
        return self._h.plane_angle

    def assume(self, values: Sequence[float]) -> None:
        """Take ``values`` (one per :data:`PARAMETERS`, in their units) as the present
        estimate, its covariance kept (e.g. what an earlier mission learned). It starts with
        twice the evidence ``LearningSettings.evidence`` asks for (:attr:`evidence`): it is
        flown from the next :meth:`fly_latest` (the controller's first sample), before any
        sample is learned, until the samples learned from say that it predicts worse than
        the file.

        Raises
        ------
        DesignError
            Not one finite value per parameter.
        """
        p = np.asarray(values, dtype=float).reshape(-1)
        if p.size != N_PARAMS or not np.all(np.isfinite(p)):
            raise DesignError(f'plant estimator: {N_PARAMS} finite values needed, got '
                              f'{list(values)!r}')
        for h in self._filters:
            h.p = p.copy()
            h.over_file = 2.0 * self.settings.evidence
        self._assumed = True

    @property
    def estimate(self) -> PlantEstimate:
        """The present estimate (:class:`PlantEstimate`)."""
        h = self._h
        return PlantEstimate(tuple(float(x) for x in h.p),
                             tuple(float(math.sqrt(max(x, 0.0))) for x in np.diag(h.cov)),
                             h.samples)

    def _wrench(self, u: float, w: float, q: float, theta: float, bar: float
                ) -> tuple[tuple[float, float], tuple[float, float], float]:
        """The model's heave force and pitch moment ``(Z [N], M [N m])`` at a state, their
        derivatives by the BAR ``(Z_bar [N/rad], M_bar [N m/rad])`` (complex step) and its
        surge force without the thrust ``X`` [N]."""
        x = self.plane.full_state(w, q, 0.0, theta, bar + 1j * _H, u)
        f = self.plane.wrench(x)
        return ((float(f[2].real), float(f[4].real)),
                (float(f[2].imag) / _H, float(f[4].imag) / _H), float(f[0].real))

    @property
    def thrust(self) -> float | None:
        """The thrust the vehicle flies with [N], averaged over ``thrust_time``: the surge
        force that the measured surge, heave and pitch accelerations need beyond the
        model's (``m_u nu_dot - X``), the model being the one :meth:`force` takes (with a
        learned heave offset ``p1 W``, its share along the axis: a buoyancy slows a dive);
        None before it is known."""
        mean = self._h.thrust
        if mean.weight < THRUST_KNOWN:
            return None
        return float(mean.mean[0]) + self._thrust_shift

    @property
    def thrust_sigma(self) -> float:
        """Standard deviation of :attr:`thrust` [N] (nan while it is not known): the scatter
        of the samples' surge force about their mean, over the weighted mean's effective
        number of samples once its weights have settled, ``(1 + d) / (1 - d)``, ``d =
        exp(-Ts / thrust_time)``. It takes the samples as independent; each is the
        difference of two speeds, one shared with the next sample, so their noise largely
        cancels in the mean and this overstates its spread (NPS AUV II foreign plant, realistic
        sensor noise: a median of 134 N against the mean's measured scatter of 49 N; REMUS
        100: 0.70 N against 0.47 N)."""
        mean = self._h.thrust
        if mean.weight < THRUST_KNOWN:
            return math.nan
        decay = math.exp(-self.ts / self.settings.thrust_time)
        return math.sqrt(float(mean.spread[0]) * (1.0 - decay) / (1.0 + decay))

    def force(self, u: float, w: float, theta: float, bar: float
              ) -> tuple[float, float, float]:
        """The learned model's surge and heave force and pitch moment ``(X [N], Z [N],
        M [N m])`` without the thrust in a steady straight motion (``q = 0``) at surge ``u``,
        heave ``w`` [m/s], pitch ``theta`` and BAR ``bar`` [rad] (a
        :data:`auv_depth_lqr.glide.Force`)."""
        (z_m, m_m), (z_bar, m_bar), x_m = self._wrench(u, w, 0.0, theta, bar)
        p = self._latest
        dz, dm = self.regressors(u, w, 0.0, bar, z_bar, m_bar, theta) @ p
        x_m -= p[0] * self.weight * math.sin(theta)
        return x_m, z_m + float(dz), m_m + float(dm)

    def glide_cap(self, travel: float, theta_limit: float, bar_limit: float, u: float
                  ) -> float:
        """The fastest steady climb (``travel`` -1) or dive (+1) [m/s, >= 0] of the learned
        model with the present :attr:`thrust` held whose BAR stays within ``bar_limit``
        [rad], ``inf`` if the one at ``theta_limit`` [rad] does or the thrust is not known
        (:func:`auv_depth_lqr.glide.glide_cap`, from the level trim at ``u`` [m/s])."""
        thrust = self.thrust
        if thrust is None or not u > 0.0:
            return math.inf
        try:
            trim = self.plane.trim(u)
        except TrimError:
            return math.inf
        return glide_cap(self.force, thrust, travel, theta_limit, bar_limit,
                         Glide(trim.u0, trim.w, 0.0, trim.bar))

    def regressors(self, u: float, w: float, q: float, bar: float, z_bar: float,
                   m_bar: float, theta: float = 0.0) -> Matrix:
        """The regression's rows (2, 7) at a state: heave force and pitch moment [N, N m]
        per unit parameter (the heave offset ``p1 W`` acts along the vertical, as a
        buoyancy does: ``p1 W cos(theta)`` on the body's heave axis)."""
        qs, ln, wt = self.qs, self.length, self.weight
        H = np.zeros((2, N_PARAMS))
        H[0, :3] = (wt * math.cos(theta), z_bar * bar, qs * u * w)
        H[1, 3:] = (wt * ln, m_bar * bar, qs * ln * u * w, qs * ln * ln * u * q)
        return H

    def update(self, start: tuple[float, float, float], end: tuple[float, float, float],
               u: float, bar: float, du: float = 0.0, excited: bool = True) -> PlantEstimate:
        """Learn from one sample.

        Parameters
        ----------
        start, end : tuple of float
            ``(w [m/s], q [rad/s], theta [rad])`` measured at the start and the end of the
            sample.
        u : float
            Surge speed over the sample [m/s].
        bar : float
            BAR commanded over the sample [rad]; the plane's own angle over it is that of
            the vehicle file's actuator reached by the command each filter's delay later
            (:meth:`plane_over`).
        du : float, optional
            Change of the surge speed over the sample [m/s] (its share of the wrench through
            the mass matrix's surge column, :attr:`m_wq_u`).
        excited : bool, optional
            Whether a commanded depth change excited the sample (``LearningSettings.
            excitation_change``, ``excitation_time``); if not, nothing is learned from
            it (the scatter of its residual and the thrust are still measured).

        Returns
        -------
        PlantEstimate
            The estimate after the sample before it: a sample is learned when the next one
            comes, its regressors at the mean of the state one sample before its start and
            one sample after its end (the module docstring's instrument; at its own mean
            state when a gap, a non-finite sample or ``u <= 0``, leaves it without both
            neighbours). Unchanged while the plane's angle is not known
            (:meth:`forget_plane`).
        """
        values = (*start, *end, u, bar, du)
        if not all(math.isfinite(v) for v in values) or u <= 0.0:
            return self.estimate
        sample = _Sample(start, end, u, bar, du, excited)
        pending, before = self._pending, self._before
        if pending is not None:
            # the pending sample's regressors at its neighbours' state, when it has both
            instrument = None
            if before is not None and before.end == pending.start \
                    and pending.end == sample.start:
                instrument = (0.5 * (before.start[0] + sample.end[0]),
                              0.5 * (before.start[1] + sample.end[1]))
            self._learn_sample(pending, instrument)
            self._before = pending
        self._pending = sample
        return self.estimate

    def _learn_sample(self, sample: _Sample, instrument: tuple[float, float] | None) -> None:
        """:meth:`update`'s sample into every filter, the regressors' ``(w, q)`` [m/s,
        rad/s] the ``instrument`` (its own mean state if None)."""
        start, end = sample.start, sample.end
        w, q, theta = (0.5 * (a + b) for a, b in zip(start, end))
        accel = np.array([sample.du, end[0] - start[0], end[1] - start[1]]) / self.ts
        # what the measured accelerations take, the same for every filter: the heave and
        # pitch wrench, and the surge force
        felt = self.m_wq @ accel[1:] + self.m_wq_u * accel[0]
        surge = float(self.m_u @ accel)
        for h in self._filters:
            self._learn(h, (w, q, theta), felt, surge, sample.u, sample.bar, sample.excited,
                        (w, q) if instrument is None else instrument)
        best = max(self._filters, key=lambda h: h.fit)
        if best.fit > self._h.fit + self.settings.delay_margin:
            self._h = best

    def _learn(self, h: _Filter, mean: tuple[float, float, float], felt: Matrix,
               surge: float, u: float, bar: float, excited: bool,
               instrument: tuple[float, float]) -> None:
        """One sample into the filter ``h``: ``mean`` ``(w, q, theta)`` over it [m/s,
        rad/s, rad], the heave force and pitch moment ``felt`` [N, N m] and the surge force
        ``surge`` [N] the measured accelerations take, surge ``u`` [m/s], command ``bar``
        [rad] (``excited``: :meth:`update`), the regressors' ``(w, q)`` ``instrument``; its
        fit gains the log-likelihood of its prediction of the sample."""
        w, q, theta = mean
        plane = self._plane_over(h, bar)
        plane_before, h.plane_before = h.plane_before, plane
        if h.unsure > 0.0:
            h.unsure -= self.ts
            return
        (z_m, m_m), (z_bar, m_bar), x_m = self._wrench(u, w, q, theta, plane)
        # the thrust (:attr:`thrust`): the surge force the accelerations need beyond the
        # model's, a learned heave offset's share along the axis included (a buoyancy slows
        # a dive) while the estimate is the one flown; an exponentially weighted mean
        # normalised by its weights, so from the first samples on the mean of those samples
        if self.predicts_better:
            x_m -= h.p[0] * self.weight * math.sin(theta)
        decay = math.exp(-self.ts / self.settings.thrust_time)
        h.thrust.add(np.array([surge - x_m]), decay)
        y = felt - np.array([z_m, m_m])
        if not self._moment_prior_set:
            self._moment_prior_set = True
            self._set_moment_prior(m_bar)
        h.noise = self._sample_noise(h, y, z_bar, m_bar)
        if not excited:
            return
        H = self.regressors(u, instrument[0], instrument[1], plane, z_bar, m_bar, theta)
        cov = h.cov + np.diag(self._drift)
        R = np.diag(h.noise ** 2)
        S = H @ cov @ H.T + R
        innovation = y - H @ h.p
        solved = np.linalg.solve(S, innovation)
        _, logdet = np.linalg.slogdet(S)
        loglik = -0.5 * (float(innovation @ solved) + float(logdet))
        decay = math.exp(-self.ts / self.settings.delay_time)
        h.fit = decay * h.fit + loglik
        # the file's error predicting the sample (filter 0's residual: the file's own plane,
        # p = 0) against the estimate's, both in this filter's noise
        if h.delay == 0:
            self._file_y = y
        h.over_file = decay * h.over_file + 0.5 * float(
            np.sum((self._file_y ** 2 - innovation ** 2) / h.noise ** 2))
        # the gain of the instrumental-variable regression: the plane's rows at its angle
        # over the sample before (module docstring)
        Z = H if plane_before is None else \
            self.regressors(u, instrument[0], instrument[1], plane_before, z_bar, m_bar, theta)
        gain = np.linalg.solve((H @ cov @ Z.T + R).T, Z @ cov).T
        h.p = h.p + gain @ innovation
        # the recursive-IV update of the covariance: not symmetric, so symmetrised; it
        # stands for the estimate's uncertainty (sigma, the filters' likelihoods,
        # `optimistic`) and understates the IV estimate's error somewhat
        cov = cov - gain @ H @ cov
        h.cov = 0.5 * (cov + cov.T)
        h.samples += 1

    def fly_latest(self, begin: bool = True) -> None:
        """Fly the latest estimates from now on (:meth:`correct`, :meth:`plane_gain`,
        :meth:`force`, :meth:`offset_acceleration` use the model of the last call), or,
        while the latest is not plausible (:attr:`implausible`) or predicts no better than
        the file (:attr:`predicts_better`), the vehicle file's model.

        With ``begin`` false (the controller's samples at rest after the first) the model
        flown is the mean of the estimates after each sample learned since the last call
        with ``begin`` true, from the one taken then on; a switch of the filter giving the
        estimate (another plane delay) or a return to the file starts the mean again. With
        ``begin`` true (each sample of a landing, the first at rest) it is the latest
        estimate. At rest each sample moves the estimate by the sensors' noise more than by
        what it tells: a model that followed every sample there moved its trim by up to
        1 deg of pitch and 6 deg of plane from one second to the next on the realistic
        sensor noise (``auv_logs.simlog.SensorNoise.realistic``; the A18M's foreign plant
        of :func:`auv_depth_lqr.closed_loop.foreign_plant`, 10 -> 30 m), and its hold
        drifted 0.12 m from the last estimate's trim (settled in 159.6 s; with the mean,
        96.7 s; without learning, 104.7 s). The mean of the estimates along a recursive fit
        (Polyak averaging) scatters less than its last one. On a landing the estimate still
        learns what the stop shows (the plane swung over) and is taken as it comes: a mean
        over it lagged the trim the REMUS 100's foreign plant was learning there and slowed
        its noisy 10 -> 30 m dive from 1.23x to 1.40x its bound (an exponential mean of 2 s:
        1.35x)."""
        if self.implausible or not self.predicts_better:
            self._flown = np.zeros(N_PARAMS)
            self._flying = False
            self._mean = None
            return
        h = self._h
        mean = self._mean
        if begin or mean is None or mean[0] is not h:
            mean = (h, h.samples, h.p.copy(), 1)
        elif h.samples != mean[1]:
            count = mean[3] + 1
            mean = (h, h.samples, mean[2] + (h.p - mean[2]) / count, count)
        self._mean = mean
        self._flown = mean[2].copy()
        self._flying = self._flying or h.samples > 0 or self._assumed

    @property
    def implausible(self) -> str | None:
        """Why the latest estimate is not what physics allows, or None if it is: a plane
        that no longer gives force or moment (``1 + p2``, ``1 + p5`` <= 0), a hull lift
        ``CZuw + p3`` or a pitch damping ``CMuq + p7`` of the other sign than the file's (a
        hull that lifts against its incidence, a damping that feeds the rotation), or a
        parameter further than ``LearningSettings.plausible`` prior standard deviations from
        the file."""
        p = self._h.p
        for name, value in (('plane_force', 1.0 + p[1]), ('plane_moment', 1.0 + p[4])):
            if value <= 0.0:
                return f'{name}: the plane would give {value:+.2f} of the file\'s'
        for name, file_value, learned in (('hull_lift', self.czuw, self.czuw + p[2]),
                                          ('pitch_damping', self.cmuq, self.cmuq + p[6])):
            if file_value * learned <= 0.0:
                return (f'{name}: {learned:+.3g} against the file\'s {file_value:+.3g}, '
                        f'of the other sign')
        distance = np.abs(p) / self._prior
        worst = int(np.argmax(distance))
        if distance[worst] > self.settings.plausible:
            return (f'{PARAMETERS[worst]}: {distance[worst]:.1f} prior deviations from the '
                    f'file')
        return None

    @property
    def evidence(self) -> float:
        """Log-likelihood [-] by which the latest estimate's predictions of the samples
        learned from beat the vehicle file's (``LearningSettings.evidence``)."""
        return self._h.over_file

    @property
    def predicts_better(self) -> bool:
        """Whether the latest estimate predicts the samples learned from better than the
        vehicle file by ``LearningSettings.evidence``."""
        return self.evidence > self.settings.evidence

    @property
    def _latest(self) -> Matrix:
        """The latest estimate where it predicts better than the file, else zeros (the
        file's model)."""
        return self._h.p.copy() if self.predicts_better else np.zeros(N_PARAMS)

    def optimistic(self, value: Callable[[], float], deviations: float = OPTIMISM) -> float:
        """``value()``, a figure of the :attr:`thrust` (a held-thrust glide cap), plus
        ``deviations`` of its standard deviation over the thrust's uncertainty
        (:attr:`thrust_sigma`), linearised: ``value`` is taken again with the thrust one
        deviation higher, and the figure moves by ``deviations`` times the change, whichever
        its sign (towards the faster motion). ``value()`` itself while the thrust is not
        known; ``inf`` if either value is."""
        base = value()
        sigma = self.thrust_sigma
        if not math.isfinite(base) or not (math.isfinite(sigma) and sigma > 0.0):
            return base
        self._thrust_shift = sigma
        try:
            moved = value()
        finally:
            self._thrust_shift = 0.0
        if not math.isfinite(moved):
            return math.inf
        return base + deviations * abs(moved - base)

    @property
    def flown_estimates(self) -> int:
        """How many estimates the model flown is the mean of (:meth:`fly_latest`; 1: one
        estimate; 0: the file's model)."""
        return 0 if self._mean is None or not self._flying else self._mean[3]

    @property
    def flying(self) -> bool:
        """Whether a learned model is flown: one was taken by :meth:`fly_latest` (the
        controller takes it at rest and on a stop's landing) after at least one sample was
        learned, or after :meth:`assume`."""
        return self._flying

    def plane_gain(self, op: OperatingPoint, latest: bool = False) -> float:
        """The plane's estimated effectiveness on the pitch acceleration at ``op``, relative
        to the model's, within ``gain_range`` [-] (of the flown estimate, or with ``latest``
        of the latest one; :meth:`LearnedModel.plane_gain`)."""
        return self.model.plane_gain(self._latest if latest else self._flown, op)

    def correct(self, op: OperatingPoint, latest: bool = False) -> OperatingPoint:
        """The pilot's linear model at ``op`` with the flown estimate applied
        (:meth:`LearnedModel.correct`), or with ``latest`` the latest estimate instead of
        the one flown (:meth:`fly_latest`); ``op`` itself for the file's model."""
        p = self._latest if latest else self._flown
        return self.model.correct(p, op) if np.any(p) else op

    def offset_acceleration(self, op: OperatingPoint) -> tuple[float, float]:
        """The heave and pitch accelerations [m/s^2, rad/s^2] the flown corrections give at
        the design trim of ``op`` (:meth:`LearnedModel.offset_acceleration`)."""
        return self.model.offset_acceleration(self._flown, op)
