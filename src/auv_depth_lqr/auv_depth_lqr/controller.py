"""The discrete depth controller as a pure object: gain-scheduled LQR with integral action.

Frames and units (Fossen): world frame NED, z positive down (z is depth) [m]; body frame FRD;
pitch ``theta`` positive nose up [rad]; heave ``w`` [m/s] and pitch rate ``q`` [rad/s] in the
body frame; surge ``u`` [m/s]; dive-plane (BAR) angle [rad]. The vertical speed
``v = z_dot`` is positive downwards, so a climb has ``v < 0`` and needs ``theta > 0``.

Design state (as in the report, section 3.4) ``X = (w, q, z, theta, xi)`` with
``xi = int (z - z_ref) dt`` [m s], input ``BAR`` [rad]. The vehicle model supplies
``linearize(u0) -> (x_e, u_e, A, B)``: trim state ``x_e = (w_e, 0, z_any, theta_e, 0)``,
trim input ``u_e = BAR_e`` and the Jacobians ``A`` (5, 5), ``B`` (5, 1) at that trim.

Beyond the report, :class:`DepthController` adds

* gain scheduling on the surge speed (:class:`~auv_depth_lqr.schedule.GainSchedule`: one
  discrete LQR per speed, gains and trim interpolated linearly in ``u``, clamped at the ends
  of the grid);
* integral action on the depth error with anti-windup (conditional integration plus a clamp
  of the integrator's share of the command);
* BAR angle and rate limits on the output command;
* a reference governor (:mod:`auv_depth_lqr.governor`) that turns a depth change into a
  near time-optimal vertical-speed profile (continuous jerk) whose steady climb/dive needs
  at most ``margin * theta_max`` pitch, whose feed-forward BAR stays within the plane's
  angle and rate, whose stop holds the plane at its braking end, and which ends on a short
  exponential landing, so the attitude is quiet once settled;
* model-based feed-forward of the whole manoeuvre: the linear model's exact trajectory for
  the profile (a series in the derivatives of the vertical speed,
  :class:`~auv_depth_lqr.schedule.OperatingPoint`),
  with the exact depth kinematics ``z_dot = -u sin(theta) + w cos(theta)``;
* pitch envelope protection: the depth feedback may not ask for more than
  ``pitch_guard * theta_max`` (a current or a wrong speed can make the vehicle lag the plan),
  less the pitch rate times the plane's reaction time while the vehicle rotates towards the
  limit (``pitch_anticipation``);
* a pitch envelope selector (:mod:`auv_depth_lqr.envelope`): the BAR is kept between the
  commands of an incremental pitch-hold law aiming at ``+-theta_max``, which counts the
  plane's reaction and braking on a rotation towards a limit; while it holds, the integrator
  is frozen. It aims at the limit itself, not at the guard's share of it, so that a flight
  of the design model, which the guard keeps below the limit, is not touched by it. The
  guard above shapes the depth loop's pitch demand on the model; the selector holds the
  limit on the measured pitch acceleration, whatever the model gets wrong (buoyancy, a trim
  moment, weak planes, a speed that falls with the thrust held);
* a stop planned at the surge speed the vehicle is heading for when that is lower than the
  measured one (``surge_length``, :class:`~auv_depth_lqr.surge.SurgeTrend`): with its
  propeller held, a positively buoyant vehicle slows down in a dive, and its plane with it;
* for a vehicle that is open-loop unstable in pitch/heave (its BAR -> vertical-speed series is
  not stable, e.g. the REMUS 100), a kinematic stop of the reference (``kinematic_stop``,
  :func:`~auv_depth_lqr.stop.kinematic_map`) instead of the held-plane stop, which would
  diverge;
* with a plane-rate design (``GainSchedule.K_rate``, ``PilotSettings.plane_rate_design``),
  the LQR on the state augmented by the plane with the plane's rate as its input: the rate
  command is integrated from the last commanded BAR, against the feed-forward BAR and its
  rate, before the selector and the limits (``docs/pilot-design.md``, 4b).

Modules: weights (:mod:`~auv_depth_lqr.weights`), limits (:mod:`~auv_depth_lqr.limits`), gain
schedule (:mod:`~auv_depth_lqr.schedule`), reference governor
(:mod:`~auv_depth_lqr.governor`), stop planner (:mod:`~auv_depth_lqr.stop`), root finder
(:mod:`~auv_depth_lqr.roots`); this one holds the sampled control law.

No ROS import here: the depth-pilot node converts messages and calls :meth:`DepthController.step`.
"""
from __future__ import annotations

import collections
import math
from typing import NamedTuple, Protocol

import numpy as np

from auv_depth_lqr.envelope import Heave, PitchEnvelope
from auv_depth_lqr.errors import ControllerError, DesignError
from auv_depth_lqr.governor import GovernorSettings, Reference, ReferenceGovernor
from auv_depth_lqr.learning import PlantEstimator
from auv_depth_lqr.limits import Limits
from auv_depth_lqr.schedule import N_STATES, GainSchedule, Matrix, OperatingPoint, feedforward
from auv_depth_lqr.surge import SurgeTrend
from auv_depth_lqr.validate import finite, run_input

__all__ = ['DepthController', 'DepthState', 'PlaneState']


class DepthState(Protocol):
    """What the controller reads from a vehicle state (``auv_msgs/VehicleState`` fits)."""

    @property
    def z(self) -> float:
        """Depth, NED down [m]."""

    @property
    def theta(self) -> float:
        """Pitch, positive nose up [rad]."""

    @property
    def w(self) -> float:
        """Body FRD heave velocity [m/s]."""

    @property
    def q(self) -> float:
        """Body FRD pitch rate [rad/s]."""

    @property
    def u(self) -> float:
        """Body FRD surge velocity [m/s]."""


class PlaneState(NamedTuple):
    """A minimal vertical-plane state satisfying :class:`DepthState`."""

    z: float
    """Depth, NED down [m]."""
    theta: float
    """Pitch, positive nose up [rad]."""
    w: float
    """Heave velocity, body FRD [m/s]."""
    q: float
    """Pitch rate, body FRD [rad/s]."""
    u: float
    """Surge velocity, body FRD [m/s]."""


class DepthController:
    """Sampled depth pilot: BAR command from the vertical-plane state and a depth reference.

    Call :meth:`step` once per sample period ``Ts`` with the latest state and the commanded
    depth; the returned BAR angle is to be held (zero-order hold) until the next call.

    Parameters
    ----------
    design : GainSchedule
        Gains and trims on a speed grid, designed for the same ``Ts``.
    limits : Limits
        BAR angle/rate limits, pitch limit, integrator bound.
    Ts : float
        Sample period [s]; must equal ``design.Ts``.
    governor : GovernorSettings, optional
        Reference-governor settings.
    learner : PlantEstimator, optional
        Learns what the design model gets wrong while flying (:mod:`auv_depth_lqr.learning`);
        every model-derived quantity (trim, feed-forward, the reference's climb and stop,
        the gain) then rests on the learned model. Without it (a controller built from a
        linear model only) the disturbance estimate of :meth:`trimmed` acts instead.

    Raises
    ------
    DesignError
        If ``Ts`` differs from the design's, or the trim BAR or pitch at a grid speed is
        already beyond the limits (the vehicle cannot hold depth there: shrink the grid).
    """

    def __init__(
        self,
        design: GainSchedule,
        limits: Limits | None = None,
        Ts: float | None = None,
        governor: GovernorSettings | None = None,
        learner: PlantEstimator | None = None,
    ) -> None:
        self.design = design
        self.learner = learner
        """The plant estimate (:class:`~auv_depth_lqr.learning.PlantEstimator`), or None.
        It is not forgotten on :meth:`reset`: what was learned of the vehicle stays true."""
        self.limits = limits if limits is not None else Limits()
        self.governor = governor if governor is not None else GovernorSettings()
        ts = design.Ts if Ts is None else finite('Ts', Ts, positive=True)
        if abs(ts - design.Ts) > 1e-9 * design.Ts:
            raise DesignError(
                f'Ts={ts:g} s differs from the sample period of the gain design '
                f'({design.Ts:g} s); redesign the schedule for this Ts')
        self.Ts = ts
        for u0, bar_e, theta_e in zip(design.speeds, design.bar_e, design.theta_e):
            if abs(bar_e) >= self.limits.bar_max or abs(theta_e) >= self.limits.theta_max:
                raise DesignError(
                    f'trim at u0={u0:g} m/s (BAR_e={bar_e:.4g} rad, theta_e={theta_e:.4g} rad)'
                    f' is beyond the limits (bar_max={self.limits.bar_max:.4g} rad, '
                    f'theta_max={self.limits.theta_max:.4g} rad); remove this speed from the '
                    'grid')
        self.reference = ReferenceGovernor(design, self.limits, self.governor, ts)
        """The reference governor (:class:`~auv_depth_lqr.governor.ReferenceGovernor`)."""
        self.envelope = PitchEnvelope(self.limits.theta_max,
                                      self.limits.bar_rate_max, ts)
        """The pitch envelope selector (:class:`~auv_depth_lqr.envelope.PitchEnvelope`)."""
        self.surge = SurgeTrend(self.governor.surge_length, self.governor.surge_trend_time, ts,
                                self.governor.surge_horizon)
        """The measured surge speed's trend (:class:`~auv_depth_lqr.surge.SurgeTrend`)."""
        self.reset()

    @property
    def kinematic_stop(self) -> bool:
        """Whether the stop is planned kinematically (open-loop-unstable vehicle)."""
        return self.reference.kinematic_stop

    # -- state -----------------------------------------------------------------------------
    def reset(self, bar_previous: float | None = None) -> None:
        """Forget the integrator, the governed reference and the previous command.

        Parameters
        ----------
        bar_previous : float, optional
            Current BAR angle [rad]. If given, the first command after the reset is
            rate-limited from it; if omitted, the first command is only angle-limited.
        """
        self._xi = 0.0
        self._taking = False
        """Whether the last sample took the learner's estimates with the reference at rest."""
        self._disturbance = np.zeros(2)
        self._observed: tuple[float, float, float] | None = None
        self._quiet = math.inf
        """Time [s] since the reference of a depth change at least the learner's
        ``excitation_change`` long last moved (inf: not since the reset)."""
        self._change: tuple[float, float] | None = None
        """The command [m] the reference goes to and the change's length [m] from where the
        reference was when it was given."""
        self._u_last: float | None = None
        self._caps: tuple[float, float, float] | None = None
        self._glide: tuple[float, float, float, float] | None = None
        self._z_prev: float | None = None
        self._z_rate = 0.0
        self._still = 0.0
        self._stop_speed: float | None = None
        self._headings: collections.deque[float] = collections.deque(
            maxlen=max(int(round(self.governor.surge_horizon / self.Ts)), 1))
        self.surge.reset()
        self.envelope.reset()
        self.reference.reset()
        self._bar_prev = None if bar_previous is None else finite('bar_previous', bar_previous)
        self._bar_at_limit = False
        if self.learner is not None:
            self.learner.forget_plane()

    @property
    def integrator(self) -> float:
        """Integrated depth error ``xi`` [m s]."""
        return self._xi

    @property
    def disturbance(self) -> tuple[float, float]:
        """Estimated heave and pitch accelerations the model does not explain
        ``(d_w [m/s^2], d_q [rad/s^2])`` (see :meth:`step`); with a :attr:`learner`, those
        of its estimate at the design trim of the last measured speed."""
        if self.learner is not None and self.learner.flying:
            if self._u_last is None:
                return 0.0, 0.0
            return self.learner.offset_acceleration(self.design.at(self._u_last))
        return float(self._disturbance[0]), float(self._disturbance[1])

    def trimmed(self, op: OperatingPoint, latest: bool = False) -> OperatingPoint:
        """``op`` with its level trim ``(w_e, theta_e, BAR_e)`` moved to hold the estimated
        disturbance (``OperatingPoint.D``), as far as ``trim_bar_share * bar_max`` and
        ``trim_pitch_share * theta_max`` allow (the shift is scaled down, not clipped per
        component, so the trim stays one of the model's). With a :attr:`learner`, the learned
        model (:meth:`~auv_depth_lqr.learning.PlantEstimator.correct`), its trim shift
        bounded the same way; with ``latest``, the learner's latest estimate rather than the
        one flown (``op`` itself before anything is learned)."""
        learner = self.learner
        if learner is not None and latest and learner.estimate.samples == 0:
            return op
        if learner is not None and (latest or learner.flying):
            learned = learner.correct(op, latest=latest)
            shift = np.array([learned.w_e - op.w_e, 0.0, learned.theta_e - op.theta_e,
                              learned.bar_e - op.bar_e])
            base = learned._replace(w_e=op.w_e, theta_e=op.theta_e, bar_e=op.bar_e)
        else:
            shift = op.D @ self._disturbance
            base = op
        scale = 1.0
        for centre, delta, bound in (
                (op.bar_e, float(shift[3]), self.governor.trim_bar_share * self.limits.bar_max),
                (op.theta_e, float(shift[2]),
                 self.governor.trim_pitch_share * self.limits.theta_max)):
            if abs(centre + delta) > bound and delta != 0.0:
                reach = math.copysign(bound, delta) - centre
                scale = min(scale, max(reach / delta, 0.0))
        shift = scale * shift
        return base._replace(w_e=op.w_e + float(shift[0]),
                             theta_e=op.theta_e + float(shift[2]),
                             bar_e=op.bar_e + float(shift[3]))

    def _observe(self, op: OperatingPoint, w: float, q: float, theta: float, u: float
                 ) -> None:
        """Update the disturbance estimate from the heave and pitch accelerations over the
        last sample against the model's (trapezoidal mean of the state, the BAR commanded
        over the sample), low-passed with ``disturbance_time`` (``disturbance_estimate`` on).
        Not for an open-loop-unstable
        vehicle (:attr:`kinematic_stop`, e.g. the REMUS 100): in its climbs the linear model's
        error (the unstable modes, the quadratic cross-flow drag) is taken for an offset and
        moves the trim (10 -> 30 m: 27.4 deg peak pitch, against 24.4 deg without), and at
        rest behind a 0.3 s plane delay it widens the hold's limit cycle (1.3 cm against
        0.8 cm); its estimate stays zero and its integrator removes offsets.
        With a :attr:`learner`, the sample goes to it instead (any vehicle), as excited by
        a depth change (``LearningSettings.excitation_change``) while the reference moved
        over it or came to rest less than ``excitation_time`` before (else nothing is learned
        from it).

        A sample over which the BAR was held at its angle limit (``|BAR| = bar_max``) leaves
        the estimate as it is: the estimate is an offset, and an error of the model's plane
        effectiveness ``k`` shows in the residual as ``(k - 1)`` times the plane's
        acceleration per radian times ``BAR - BAR_e`` [rad], largest at the limits and of
        either sign, which the offset cannot tell from a trim offset. A plane 0.6 times as
        strong held at -25 deg for a climb (the A18M's foreign plant of
        :func:`auv_depth_lqr.closed_loop.foreign_plant`, 20 -> 10 m) moved the trim BAR from
        the model's -5.0 deg to -13.6 deg, away from the plant's +4.0 deg, and the stop was
        planned on that much more braking room; held at +25 deg in the stop, it moved it to
        +14 deg. With the plane at its limit the feedback cannot act on what the estimate
        moves either; it learns again as soon as the plane leaves the limit."""
        if self.learner is not None and self._observed is not None \
                and self._bar_prev is not None and self._u_last is not None \
                and self.governor.disturbance_estimate:
            self.learner.update(self._observed, (w, q, theta), 0.5 * (u + self._u_last),
                                self._bar_prev, u - self._u_last, excited=self._quiet
                                < self.learner.settings.excitation_time)
        self._u_last = u
        if self._observed is not None and self._bar_prev is not None \
                and self.governor.disturbance_estimate and not self.kinematic_stop \
                and not self._bar_at_limit:
            w0, q0, theta0 = self._observed
            ts = self.Ts
            dx = np.array([0.5 * (w + w0) - op.w_e, 0.5 * (q + q0),
                           0.5 * (theta + theta0) - op.theta_e, self._bar_prev - op.bar_e])
            residual = np.array([(w - w0) / ts, (q - q0) / ts]) - op.P @ dx
            alpha = ts / (self.governor.disturbance_time + ts)
            self._disturbance = self._disturbance + alpha * (residual - self._disturbance)
        self._observed = (w, q, theta)

    @property
    def stop_speed(self) -> float | None:
        """Surge speed [m/s] the last sample's stop was planned at: the measured one or, if
        lower, the lowest the vehicle was heading for over the last ``surge_horizon``; None
        before the first :meth:`step`."""
        return self._stop_speed

    @property
    def state_speed(self) -> float | None:
        """Surge speed [m/s] of the last state stepped on, None before."""
        return self._u_last

    @property
    def vertical_speed_caps(self) -> tuple[float, float, float] | None:
        """``(v_lo, v_hi, v_kin)`` [m/s, NED down] of the last sample: the steadiest climb
        (``v_lo`` < 0) and dive (``v_hi`` > 0) the reference may fly on the (learned) model at
        the speed the vehicle is heading for, within ``margin`` of the pitch and plane limits
        (:meth:`GainSchedule.vertical_speed_bounds`), and the kinematic cap
        ``margin u sin(theta_max)`` they would be without the plane's limit; None before the
        first :meth:`step`."""
        return self._caps

    @property
    def governed_reference(self) -> tuple[float, float] | None:
        """Governed depth and vertical speed ``(z_r [m], v_r [m/s])`` seen by the LQR."""
        ref = self.reference.reference
        return None if ref is None else (ref.z, ref.v)

    # -- one sample ------------------------------------------------------------------------

    def feedforward(self, op: OperatingPoint, u: float, v: float, a: float, j: float,
                    snap: float = 0.0) -> tuple[Matrix, float]:
        """Reference ``(w, q, theta)`` [m/s, rad/s, rad] and BAR [rad] of a vertical motion
        (:func:`auv_depth_lqr.schedule.feedforward`)."""
        return feedforward(op, u, v, a, j, snap)

    def held_thrust_cap(self, travel: float, u: float) -> float:
        """The steadiest climb (``travel`` -1) or dive (+1) [m/s, >= 0] the learned model
        holds with the present thrust held, its BAR within ``glide_bar_share * bar_max`` and
        its pitch within ``margin * theta_max``, from the level trim at ``u`` [m/s]
        (:meth:`~auv_depth_lqr.learning.PlantEstimator.glide_cap`); ``inf`` when the pitch
        limit, not the plane, bounds it, without a learner or before the thrust is known.
        The thrust is a mean of noisy samples: the cap is taken one standard deviation of
        the thrust's uncertainty higher (:meth:`~auv_depth_lqr.learning.PlantEstimator.
        optimistic`). On the NPS AUV II's foreign plant read through the realistic sensor
        noise (5 -> 40 m, seed 0), one sample's surge force has some 850 N of noise, its 2 s
        mean ranged from -54 to 175 N about the plant's 125 N, and a cap solved on the mean
        alone stopped the reference several times within the dive, which did not settle in
        200 s (139.0 s now, 138.4 s without learning)."""
        if self.learner is None:
            return math.inf
        settings, lim = self.governor, self.limits
        learner = self.learner

        def cap() -> float:
            return learner.glide_cap(travel, settings.margin * lim.theta_max,
                                     settings.glide_bar_share * lim.bar_max, u)

        return learner.optimistic(cap)

    def _glide_cap(self, z_cmd: float, z: float, u: float) -> float:
        """:meth:`held_thrust_cap` towards ``z_cmd`` [m] from the governed reference (``z``
        [m] before it starts), solved on a new command and every ``glide_period`` seconds
        (``inf`` at rest on the command); the governor does not apply it to a stop that has
        begun (:attr:`ReferenceGovernor.stopping`)."""
        ref = self.reference.reference
        if self.learner is None or (ref is not None and ref.v == 0.0 and ref.z == z_cmd):
            self._glide = None
            return math.inf
        travel = 1.0 if z_cmd >= (z if ref is None else ref.z) else -1.0
        last = self._glide
        if last is not None and last[0] == z_cmd and last[1] == travel and last[2] > 0.0:
            self._glide = (z_cmd, travel, last[2] - self.Ts, last[3])
            return last[3]
        cap = self.held_thrust_cap(travel, u)
        self._glide = (z_cmd, travel, self.governor.glide_period - self.Ts, cap)
        return cap

    def weaker_brake(self, op: OperatingPoint, u: float,
                      stop: tuple[OperatingPoint, float] | None, z_cmd: float
                      ) -> OperatingPoint | None:
        """The operating point whose braking the stop is planned on, if not the model flown:
        with a learner, during a change, its latest estimate where that brakes less
        (:meth:`ReferenceGovernor.braking`) than the model flown (``stop`` or ``op`` at
        ``u`` [m/s]); else None.

        The model flown through a change is the one taken at its start; the latest estimate
        learns from the change itself (the climb at one plane angle, then the plane swung
        over). Neither is trusted to brake more than the other says: a stop planned on the
        file's braking that the plant does not have overshoots (the NPS AUV II's foreign
        plant of :func:`auv_depth_lqr.closed_loop.foreign_plant`, first 20 -> 10 m: 0.80 m,
        43.8 s; on the weaker of the two, 0.37 m, 40.3 s), while a latest estimate that
        brakes more (a climb's offset read as trim) leaves the stop where it was. Only the
        stop: capping the climb by an estimate a few samples old slowed the REMUS 100 with
        its fins 0.7 times as strong from 21.3 s to 35.1 s (what else was tried:
        docs/pilot-design.md, "What does not work")."""
        ref = self.reference.reference
        if self.learner is None or ref is None or abs(ref.z - z_cmd) <= \
                self.governor.landing_distance or self.learner.implausible \
                or not self.learner.predicts_better:
            return None
        s_op, s_u = (op, u) if stop is None else stop
        travel = 1.0 if z_cmd >= ref.z else -1.0
        braking = self.reference.braking
        latest = self.trimmed(self.design.at(s_u), latest=True)
        return latest if braking(latest, travel) < braking(s_op, travel) else None

    def step(self, state: DepthState, z_ref: float) -> float:
        """BAR command [rad] for this sample.

        Parameters
        ----------
        state : DepthState
            Measured ``z`` [m, NED down], ``theta`` [rad, nose up], ``w`` [m/s], ``q``
            [rad/s], ``u`` [m/s] (e.g. an ``auv_msgs/VehicleState``).
        z_ref : float
            Commanded depth [m, positive down].

        Returns
        -------
        float
            BAR angle [rad], within ``+-bar_max`` and within ``bar_rate_max * Ts`` of the
            previous command.

        Raises
        ------
        InvalidInputError
            If ``z_ref`` or a state field is missing or not finite; the controller's internal
            state is left unchanged.
        """
        z_cmd = run_input('depth reference z_ref [m]', z_ref)
        z = run_input('state.z [m]', getattr(state, 'z', None))
        theta = run_input('state.theta [rad]', getattr(state, 'theta', None))
        w = run_input('state.w [m/s]', getattr(state, 'w', None))
        q = run_input('state.q [rad/s]', getattr(state, 'q', None))
        u = run_input('state.u [m/s]', getattr(state, 'u', None))

        ts, lim, settings = self.Ts, self.limits, self.governor
        nominal = self.design.at(u)
        self._observe(nominal, w, q, theta, u)
        ref = self.reference.reference
        taking = False
        if self.learner is not None and (
                ref is None or abs(ref.z - z_cmd) <= settings.landing_distance
                or (self.learner.flying and self.learner.implausible)):
            # at rest or on the landing (the stop is flown): the latest estimate, at rest the
            # mean of the estimates since the reference came to rest; at any time, the
            # file's model once the estimate is past what physics allows
            taking = ref is not None and ref.v == 0.0 and ref.z == z_cmd
            self.learner.fly_latest(begin=not (taking and self._taking))
        self._taking = taking
        op = self.trimmed(nominal)

        self.reference.start(z)
        # The stop is planned at the surge speed the vehicle is heading for, if lower than the
        # measured one: the lowest prediction over the last surge_horizon of the manoeuvre (a
        # plan made on a speed that then falls would brake too late; a prediction older than
        # its horizon is about a moment already past).
        heading = self.surge.update(u)
        ref = self.reference.reference
        if ref is None or (ref.v == 0.0 and ref.z == z_cmd):
            self._headings.clear()
        self._headings.append(heading)
        u_heading = min(u, min(self._headings))
        self._stop_speed = u_heading
        stop = None if u_heading >= u else (self.trimmed(self.design.at(u_heading)), u_heading)
        brake_on = self.weaker_brake(op, u, stop, z_cmd)
        glide = self._glide_cap(z_cmd, z, u)
        z_r, v_r, a_r, j_r, s_r = self.reference.advance(op, u, z_cmd, stop, glide, brake_on)
        # the sample now flown is excited by a depth change while the reference moves and
        # for LearningSettings.excitation_time after (the learner, _observe)
        if self.learner is not None:
            if self._change is None or self._change[0] != z_cmd:
                self._change = (z_cmd, abs(z_cmd - (z if ref is None else ref.z)))
            moving = v_r != 0.0 and \
                self._change[1] >= self.learner.settings.excitation_change
            self._quiet = 0.0 if moving else self._quiet + ts
        slowest = op if stop is None else stop[0]
        self._caps = (*GainSchedule.vertical_speed_bounds(slowest, u_heading, lim,
                                                          settings.margin),
                      settings.margin * u_heading * math.sin(lim.theta_max))
        # Depth rate [m/s, down] from the measured depth, low-passed over stall_time: a vehicle
        # whose depth no longer moves is held off by a steady disturbance (a vertical current,
        # a buoyancy the model does not know), not by the transient of a manoeuvre.
        if self._z_prev is not None:
            alpha = ts / (settings.stall_time + ts)
            self._z_rate += alpha * ((z - self._z_prev) / ts - self._z_rate)
            self._still = self._still + ts if abs(self._z_rate) <= settings.stall_speed else 0.0
        # Stalled: the low-passed rate has stayed within stall_speed for stall_time, not just
        # passed through it (a vehicle turning round at the end of an overshoot).
        stalled = self._still >= settings.stall_time
        # The reference waits for a vehicle that falls behind it by more than max_lag, unless
        # the vehicle has stalled: then the reference goes on to the command, at rest, where
        # the integrator removes the offset.
        if v_r != 0.0:
            travel = math.copysign(1.0, v_r)
            if travel * (z_r - z) > settings.max_lag and not stalled:
                z_r = z + travel * settings.max_lag

        # Feed-forward of the reference manoeuvre and the LQR correction around it.
        wqt, bar_ff = feedforward(op, u, v_r, a_r, j_r, s_r)
        x = np.array([w, q, z, theta, self._xi])
        x_ref = np.array([wqt[0], wqt[1], z_r, wqt[2], 0.0])
        error = x - x_ref
        # With a plane-rate design (OperatingPoint.K_rate) the law commands the plane's rate
        # from the state augmented by the plane, the last command (where the plane is now,
        # within its rate), against the feed-forward plane, whose own rate is the series'
        # derivative (one order up the profile).
        rate_law = op.K_rate.size == N_STATES + 1 and self._bar_prev is not None
        K = op.K_rate if rate_law else op.K
        depth_terms = float(K[2] * error[2] + K[4] * error[4])
        # Pitch envelope protection: the depth and integral terms act like a pitch command
        # theta_ref - depth_terms / K_theta for the attitude loop; clip that command. While
        # the vehicle rotates towards a limit, that side of the clip leads by the rotation over
        # the plane's reaction time (the plane needs it to swing over and stop the rotation).
        k_theta = float(K[3])
        if k_theta != 0.0:
            theta_lim = settings.pitch_guard * lim.theta_max
            lead = settings.pitch_anticipation * lim.bar_max / lim.bar_rate_max
            theta_cmd = x_ref[3] - depth_terms / k_theta
            clipped = min(max(theta_cmd, -theta_lim + lead * max(-q, 0.0)),
                          theta_lim - lead * max(q, 0.0))
            depth_terms = k_theta * (x_ref[3] - clipped)
        attitude_terms = float(K[0] * error[0] + K[1] * error[1] + K[3] * error[3])
        if rate_law:
            assert self._bar_prev is not None
            rate_ff = float(np.array([a_r, j_r, s_r, 0.0]) @ op.F[:, 3])
            rate = rate_ff - attitude_terms - depth_terms \
                - float(K[5]) * (self._bar_prev - bar_ff)
            bar_linear = self._bar_prev + rate * ts
        else:
            bar_linear = bar_ff - attitude_terms - depth_terms
        if settings.pitch_envelope:
            # Pitch envelope selector: within the pitch-hold law's commands towards the
            # limits, on the model's rows at the measured speed (OperatingPoint.rows_at).
            rows = op.rows_at(u)
            m_bar = float(rows[1, 3])
            heave = Heave(w, float(rows[0, 0]), float(rows[0, 1]), float(rows[0, 3]),
                          float(rows[1, 0]))
            settles = self.surge.ahead(u)  # the speed the thrust held settles at
            # the hold law's attitude gains are the angle design's, whichever law flies
            bounds = self.envelope.bounds(theta, q, self._bar_prev, m_bar,
                                          float(rows[1, 1]), float(op.K[3]),
                                          float(op.K[1]),
                                          lim.bar_max, u / settles if settles > 0.0 else 0.0,
                                          settings.glide_bar_share * lim.bar_max, heave,
                                          float(x_ref[3]))
            bar_linear = self.envelope.select(bar_linear, bounds)

        if not (math.isfinite(bar_linear) and math.isfinite(z_r) and math.isfinite(v_r)):
            # min/max would turn a NaN into a limit: refuse instead; the state is left as is
            raise ControllerError(
                f'the controller produced a non-finite command (BAR {bar_linear}, reference '
                f'z {z_r} m, v {v_r} m/s) from z={z} m, theta={theta} rad, w={w} m/s, '
                f'q={q} rad/s, u={u} m/s, z_ref={z_cmd} m')
        # Angle limit, then rate limit.
        bar_cmd = min(max(bar_linear, -lim.bar_max), lim.bar_max)
        if self._bar_prev is not None:
            slew = lim.bar_rate_max * ts
            bar_cmd = min(max(bar_cmd, self._bar_prev - slew), self._bar_prev + slew)

        # Anti-windup (conditional integration): integrate only while the governed reference
        # is (nearly) at rest and the depth is near it, and not when the command is limited
        # and integrating would push it further into the limit; then clamp the integrator's
        # share of the command.
        k_xi = float(K[4])
        increment = (z - z_r) * ts
        pushes = -k_xi * increment  # effect of this increment on the command [rad]
        limited = bar_linear - bar_cmd
        winds_up = abs(limited) > 1e-12 and pushes * limited > 0.0
        near = (abs(v_r) <= settings.integrate_below_speed
                and (abs(z - z_r) <= settings.integrate_within or stalled))
        if near and not winds_up and not self.envelope.active:
            self._xi += increment
        if k_xi != 0.0:
            # The integral term as a pitch offset of the attitude loop, at most
            # integral_pitch_max (the plane's travel without an attitude gain).
            reach = lim.integral_pitch_max * abs(k_theta) if k_theta != 0.0 else lim.bar_max
            xi_max = reach / abs(k_xi)
            self._xi = min(max(self._xi, -xi_max), xi_max)

        self.reference.accept(Reference(z_r, v_r, a_r, j_r, s_r))
        self._bar_prev = bar_cmd
        self._bar_at_limit = abs(bar_cmd) >= lim.bar_max  # held over the next sample
        self._z_prev = z
        return bar_cmd

