"""The reference governor: a depth command becomes a flyable vertical-speed profile.

Units: depth [m] and vertical speed [m/s] NED (positive down), acceleration [m/s^2], jerk
[m/s^3], snap [m/s^4]; BAR [rad]; surge ``u`` [m/s]. :class:`GovernorSettings` are its
settings, :class:`ReferenceGovernor` the planner (re-planned every sample, stop planned by
:mod:`auv_depth_lqr.stop`, the latest braking found by :mod:`auv_depth_lqr.roots`).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.linalg

from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.limits import Limits
from auv_depth_lqr.roots import largest_root_below
from auv_depth_lqr.schedule import GainSchedule, OperatingPoint
from auv_depth_lqr.stop import Brake, kinematic_map, series_map, stable_series, stop_distance
from auv_depth_lqr.validate import finite

__all__ = ['GovernorSettings', 'Reference', 'ReferenceGovernor']


@dataclass(frozen=True)
class GovernorSettings:
    """Reference governor: how a depth step becomes a flyable vertical-speed profile.

    The governed reference ``(z_r, v_r, a_r, j_r, s_r)`` (depth [m], vertical speed [m/s],
    acceleration [m/s^2], jerk [m/s^3], snap [m/s^4], NED down) is a near time-optimal
    motion to the commanded depth, re-planned every sample (:meth:`ReferenceGovernor.advance`),
    that ends on a short exponential landing. Its feed-forward BAR is the vehicle's linear
    model series ``bar_e + b_0 v + b_1 a + b_2 j + b_3 s`` (:class:`OperatingPoint`), and
    the reference is built so that this BAR is one the plane can fly:

    * ``|v_r|``: steady climbs/dives whose pitch stays within ``margin * theta_max`` and BAR
      within ``margin * bar_max`` (:meth:`GainSchedule.vertical_speed_bounds`);
    * the feed-forward BAR within ``bar_margin * bar_max`` and moving at most at
      ``bar_rate_margin`` times the plane's rate: it bounds the pitch-up (the restoring
      moment of a steep climb eats the plane's authority) and shapes the stop;
    * a stop holds the feed-forward BAR at ``brake_bar_share`` of that budget on the
      braking side (the vehicle pitches back at the rate the plane allows), then releases
      it towards the landing's BAR (plus ``release_bar_share`` of the room beyond) so that
      the landing starts with the attitude at rest (see :func:`stop_distance`);
    * the speed-up: ``|a_r| <= accel_max``, ``|j_r| <= accel_max / jerk_time``;
    * a short change from rest (one the speed-up's jerk would fly in four of the short time
      constants ``short_swings`` ``t_swing``) follows a critically damped fourth-order
      filter of the command with that time constant instead.

    The reference never overshoots the commanded depth; it waits for a vehicle that falls
    more than ``max_lag`` behind it. The defaults were chosen on the A18M model at 1.5-3 m/s
    (``bench/bench_closed_loop.py``) against the settling, overshoot and quiet-attitude
    targets; the time-optimal bound of :mod:`auv_depth_lqr.bound` is about 10 % faster.
    """

    margin: float = 0.97
    """Fraction of ``theta_max`` and ``u sin(theta_max)`` that the steady climb or dive of the
    reference may use; the rest is left to the feedback [-]."""
    bar_margin: float = 0.98
    """Fraction of ``bar_max`` that the feed-forward BAR of the reference may use [-]."""
    accel_max: float = 0.2
    """Largest vertical acceleration of the reference [m/s^2]; it bounds the pitch rate of
    the transitions, ``~ accel_max / u`` [rad/s] (0.05 rad/s = 2.9 deg/s at 2 m/s)."""
    jerk_time: float = 1.0
    """Shortest time for the reference acceleration to go from 0 to ``accel_max`` [s]
    (jerk limit ``accel_max / jerk_time``); it bounds the pitch acceleration."""
    approach_length: float = 8.0
    """Distance run through the water during one time constant of the final exponential
    approach (the landing) [m]: the time constant is ``approach_length / u`` [s] (4 s at
    2 m/s), so it follows the vehicle's attitude dynamics, which scale with ``1 / u``. The
    pitch left to take out once the vehicle is within a +-0.1 m band, and the pitch rate
    that takes it out, shrink with it: this keeps the attitude quiet once the depth has
    settled."""
    landing_distance: float = 0.12
    """Length of the landing [m]: the stop ends on it at the speed
    ``landing_distance / approach time`` [m/s], i.e. with the same pitch above the trim
    at any speed."""
    integrate_within: float = 0.2
    """The depth integrator runs only while ``|z - z_r|`` is at most this [m]."""
    integrate_below_speed: float = 0.005
    """The depth integrator runs only while ``|v_r|`` is at most this [m/s]: the manoeuvre
    itself is flown on the feed-forward and the proportional feedback, so transient tracking
    errors of a climb or of its final approach do not wind the integrator up."""
    brake_bar_share: float = 0.9
    """Fraction of the feed-forward BAR budget (``bar_margin * bar_max``) that a planned stop
    may use; the rest is left to the feedback, which must absorb the tracking errors of the
    braking, where they become overshoot [-]."""
    release_bar_share: float = 0.1
    """How far beyond the landing's BAR (about the trim) the release of a stop moves the
    feed-forward BAR, as a fraction of the room to the other end of the budget [-]."""
    bar_rate_margin: float = 0.9
    """Fraction of the BAR rate limit that the feed-forward BAR of the reference may use
    [-]; the stop is planned with the BAR moving at that rate."""
    jerk_bar_share: float = 0.28
    """Fraction of ``bar_margin * bar_max`` that the jerk term ``b_2 j`` of the speed-up may
    use; it bounds the jerk (the pitch acceleration) of the speed-up [-]."""
    short_swings: float = 1.0
    """Time constant of a short depth change, in full swings of the plane from one stop to
    the other (``t_swing = 2 bar_max / bar_rate_max`` [s]) [-]. A change from rest whose
    length is at most what the speed-up's jerk ``J`` covers in four such time constants
    ``tau`` (``J (4 tau)^3 / 32`` [m], the four-phase profile of that jerk) follows the
    critically damped fourth-order filter ``(1 + tau s)^-4`` of the command: speed,
    acceleration, jerk and snap proportional to its length, no overshoot, a feed-forward
    plane that never reverses faster than the plane swings. Planned time-optimally instead,
    its jerk and snap are at their limits whatever its length: a 1 cm change moved the
    A18M's plane 15 deg, and 5-10 cm changes (a depth reading a few centimetres off the
    command) pitched the small AUV of ``auv vehicle-init`` past 40 deg, its loop running into
    the plane's 20 deg/s rate limit. At 1.5 m/s the short changes are those below 0.53 m on
    that AUV, 0.66 m on the REMUS 100, 0.19 m on the A18M, 0.28 m on the NPS AUV II. 0 turns
    it off (every change planned time-optimally)."""
    max_lag: float = 0.5
    """Largest distance [m] by which the governed reference may lead the vehicle in the
    direction of travel; when the vehicle falls further behind (a current, a speed lower
    than assumed) the reference waits for it instead of winding up the depth error."""
    stall_time: float = 5.0
    """Time constant [s] of the low-pass of the measured depth rate that tells a stalled
    vehicle (see ``stall_speed``)."""
    stall_speed: float = 0.01
    """A vehicle whose low-passed depth rate has stayed at most this [m/s] for
    ``stall_time`` has stalled: held off the reference by a steady disturbance (a rate that
    only passes through zero, as at the turn of an overshoot, is not a stall). The
    reference then no longer waits for it (``max_lag``) and the integrator runs at any
    distance from the reference at rest (``integrate_within`` no longer applies), so integral
    action removes steady offsets."""
    disturbance_estimate: bool = True
    """Whether the controller estimates the heave and pitch accelerations its linear model
    does not explain and moves its level trim to hold them (``disturbance_time``). Off, the
    integrator alone removes steady offsets (as on an open-loop-unstable vehicle)."""
    disturbance_time: float = 3.0
    """Time constant [s] of the disturbance estimate: the heave and pitch accelerations
    the linear model does not explain (a buoyancy or trim offset, a plane bias, coefficients
    off), low-passed; the level trim the pilot flies about is moved to hold them
    (:meth:`auv_depth_lqr.controller.DepthController.step`)."""
    trim_bar_share: float = 0.8
    """Largest share of ``bar_max`` the trim BAR moved by the disturbance estimate may
    use; the rest is the feedback's [-]."""
    trim_pitch_share: float = 0.5
    """Largest share of ``theta_max`` the trim pitch moved by the disturbance estimate
    may use [-]."""
    pitch_guard: float = 0.97
    """Fraction of ``theta_max`` beyond which the depth feedback may not ask for more pitch:
    the pitch command ``theta_ref + (depth and integral terms) / K_theta`` of the LQR is
    clipped there (pitch envelope protection; inactive in normal flight) [-]."""
    pitch_envelope: bool = True
    """Whether the pitch envelope selector (:mod:`auv_depth_lqr.envelope`) keeps the BAR
    within the commands of its pitch-hold law towards ``+-theta_max``; off
    leaves the guard alone (to look at the depth loop by itself)."""
    pitch_anticipation: float = 0.5
    """Lead of the pitch guard on a rotation towards the limit, in units of the plane's
    reaction time ``bar_max / bar_rate_max`` (the time it takes from one end to neutral)
    [-]: while the pitch rate ``q`` runs towards a limit, that side of the guard moves in by
    ``|q| * pitch_anticipation * bar_max / bar_rate_max`` [rad], so the attitude loop starts
    to take the rotation out before the limit, while the plane swings over. Inactive at rest
    and on a rotation away from the limit; 0 turns it off. Chosen on the Monte Carlo of
    ``bench/bench_robustness.py --family ident`` (0, 0.5, 1: see docs/robustness.md)."""
    surge_length: float = 0.0
    """Time constant of the surge speed with the thrust held, times the speed [m]: the
    vehicle's ``(m - Xudot) u / T'(u)``, ``(m - Xudot) / (2 k)`` for a surge drag ``k u |u|``
    (from the vehicle file's level trims, :func:`auv_depth_lqr.surge.surge_length`, set by
    :func:`auv_depth_lqr.pilot.build_controller`). A climb or dive changes
    the surge speed of a vehicle whose propeller is held (the weight less the buoyancy along
    its axis, the drag of the lift): the stop is planned at the speed the measured trend is
    heading for (:class:`auv_depth_lqr.surge.SurgeTrend`), where the plane's authority will
    be. 0 plans it at the measured speed (a vehicle whose speed loop holds it)."""
    surge_trend_time: float = 1.0
    """Time constant [s] of each of the two low-passes that give the measured surge speed's
    trend (:class:`auv_depth_lqr.surge.SurgeTrend`)."""
    surge_horizon: float = 10.0
    """How far ahead [s] the surge speed is predicted for the stop, and how long a
    prediction is kept (the stop is planned at the lowest of the last ``surge_horizon``, or
    at the measured speed if that is lower):
    about the length of a stop, after which the vehicle is level again and its speed no
    longer falls (the steady speed of the dive, reached only after several time constants,
    would plan it far too slowly)."""

    glide_bar_share: float = 0.9
    """Largest share of ``bar_max`` the plane may hold in the steadiest climb or dive with
    the thrust held (:mod:`~auv_depth_lqr.glide`); the rest is the feedback's, which must
    absorb the speed's changes [-]."""
    glide_period: float = 2.0
    """How often [s] the steadiest climb or dive with the thrust held (:mod:`~auv_depth_lqr.
    glide`, on the learned model and the thrust the vehicle flies with) is solved again
    during a depth change; it caps the reference's steady climb or dive."""

    def __post_init__(self) -> None:
        for name in ('margin', 'bar_margin', 'brake_bar_share', 'pitch_guard', 'glide_bar_share',
                     'jerk_bar_share', 'bar_rate_margin', 'trim_bar_share',
                     'trim_pitch_share'):
            value = finite(f'GovernorSettings.{name}', getattr(self, name), positive=True)
            if value > 1.0:
                raise DesignError(f'GovernorSettings.{name} must be in (0, 1], got {value!r}')
        share = finite('GovernorSettings.release_bar_share', self.release_bar_share)
        if not 0.0 <= share < 1.0:
            raise DesignError(f'GovernorSettings.release_bar_share must be in [0, 1), got '
                              f'{share!r}')
        for name in ('pitch_anticipation', 'surge_length', 'short_swings'):
            if finite(f'GovernorSettings.{name}', getattr(self, name)) < 0.0:
                raise DesignError(f'GovernorSettings.{name} must be >= 0, got '
                                  f'{getattr(self, name)!r}')
        for name in ('accel_max', 'approach_length', 'jerk_time', 'landing_distance',
                     'integrate_within',
                     'integrate_below_speed', 'max_lag', 'stall_time', 'stall_speed',
                     'surge_trend_time', 'surge_horizon',
                     'disturbance_time', 'glide_period'):
            finite(f'GovernorSettings.{name}', getattr(self, name), positive=True)



class Reference(NamedTuple):
    """The governed reference at one sample (NED, positive down)."""

    z: float
    """Depth [m]."""
    v: float
    """Vertical speed [m/s]."""
    a: float
    """Vertical acceleration [m/s^2]."""
    j: float
    """Vertical jerk [m/s^3]."""
    s: float
    """Vertical snap, held over the sample [m/s^4]."""


class ReferenceGovernor:
    """The governed reference of a :class:`GainSchedule` within :class:`Limits`.

    :meth:`start` it at the measured depth, :meth:`advance` it once per sample and
    :meth:`accept` the reference actually flown (the controller may hold it back for a
    vehicle that lags). An open-loop-unstable vehicle (no stable series at some grid speed)
    cannot stop by holding its plane: its stop is planned kinematically
    (:attr:`kinematic_stop`, :func:`~auv_depth_lqr.stop.kinematic_map`).
    """

    def __init__(self, design: GainSchedule, limits: Limits, settings: GovernorSettings,
                 ts: float) -> None:
        self.design, self.limits, self.settings, self.ts = design, limits, settings, ts
        # One-sample maps of the stop model at the grid speeds, interpolated like the gains.
        self.kinematic_stop = not all(stable_series([float(x) for x in design.F[k, :, 3]])
                                      for k in range(design.speeds.size))
        self.stop_tau = 0.5 * settings.jerk_time
        """Time constant of the kinematic stop [s]."""
        self.stop_maps = [
            kinematic_map(self.stop_tau, ts) if self.kinematic_stop
            else series_map([float(x) for x in design.F[k, :, 3]], ts)
            for k in range(design.speeds.size)]
        self._short_map: np.ndarray | None = None
        """The short change's transition matrix (:meth:`short_filter`), made on first use."""
        self._plane_only = dataclasses.replace(limits, theta_max=math.radians(89.0))
        """The limits without the pitch limit's (for the plane's bound alone)."""
        self.reset()

    def reset(self) -> None:
        """Forget the reference (the next :meth:`start` sets it)."""
        self._z_r: float | None = None
        self._v_r = 0.0
        self._a_r = 0.0
        self._j_r = 0.0
        self._s_r = 0.0
        self._landing: tuple[float, float] | None = None
        self._short: np.ndarray | None = None
        """One-sample transition matrix (4 x 4) of the short change's filter on ``(z - z_cmd,
        v, a, j)``, while the present change is a short one (``short_swings``)."""
        self._switch_hint = [0]
        self._s_root: float | None = None
        self._stopping = False

    @property
    def stopping(self) -> bool:
        """Whether the stop for the present command has begun: a sample of :meth:`advance`
        since the command was given braked for the target (the snap whose stop ends on the
        target, or the landing's exponential), and the reference has not come to rest."""
        return self._stopping

    @property
    def reference(self) -> Reference | None:
        """The last accepted reference, ``None`` before :meth:`start`."""
        if self._z_r is None:
            return None
        return Reference(self._z_r, self._v_r, self._a_r, self._j_r, self._s_r)

    def start(self, z: float) -> None:
        """Start the reference at rest at depth ``z`` [m] unless it is running."""
        if self._z_r is None:
            self._z_r, self._v_r, self._a_r, self._j_r, self._s_r = z, 0.0, 0.0, 0.0, 0.0

    def accept(self, ref: Reference) -> None:
        """Store ``ref`` as the reference flown this sample."""
        self._z_r, self._v_r, self._a_r, self._j_r, self._s_r = ref

    def short_tau(self) -> float:
        """Time constant of a short change [s]: ``short_swings`` full swings of the plane
        (``2 bar_max / bar_rate_max``)."""
        return self.settings.short_swings * 2.0 * self.limits.bar_max / self.limits.bar_rate_max

    def short_length(self, jerk: float) -> float:
        """Longest short change [m]: what the jerk ``jerk`` [m/s^3] of a four-phase profile
        covers in four :meth:`short_tau` (0 with ``short_swings`` 0)."""
        return jerk * (4.0 * self.short_tau()) ** 3 / 32.0

    def short_filter(self) -> np.ndarray:
        """One-sample transition matrix (4 x 4) of the critically damped filter
        ``(1 + tau s)^-4`` (``tau`` :meth:`short_tau`) on its state ``(z - z_cmd, v, a, j)``
        [m, m/s, m/s^2, m/s^3] (exact, the matrix exponential over the sample; made once)."""
        if self._short_map is None:
            tau = self.short_tau()
            F = np.zeros((4, 4))
            F[0, 1] = F[1, 2] = F[2, 3] = 1.0
            F[3] = [-1.0 / tau**4, -4.0 / tau**3, -6.0 / tau**2, -4.0 / tau]
            self._short_map = np.asarray(scipy.linalg.expm(F * self.ts))
        return self._short_map

    def speedup_jerk(self, op: OperatingPoint) -> float:
        """Jerk limit of the speed-up [m/s^3]: ``accel_max / jerk_time``, and ``b_2 jerk``
        (the series' jerk term at ``op``) within ``jerk_bar_share`` of the plane budget."""
        settings = self.settings
        jerk = settings.accel_max / settings.jerk_time
        b2 = float(op.F[2, 3])
        if b2 != 0.0:
            budget = settings.bar_margin * self.limits.bar_max
            jerk = min(jerk, settings.jerk_bar_share * budget / abs(b2))
        return jerk

    def limits_toward(self, op: OperatingPoint, u: float, travel: float, landing: float
                       ) -> tuple[float, float, Brake]:
        """Limits of the reference for a motion in ``travel`` (+1 down, -1 up).

        Returns ``(v_cap, jerk, brake)``: the steady vertical speed it may reach [m/s, > 0,
        along ``travel``], the jerk limit of its speed-up [m/s^3] and the model of its stop
        (:class:`Brake`, :func:`stop_distance`). In the travel frame (speed ``V``,
        acceleration ``A``, jerk ``J``, snap ``S``, all along ``travel``) the feed-forward
        input ``U = travel (BAR - bar_e)`` of the series is ``b_0 V + b_1 A + b_2 J + b_3 S``
        (linear kinematics). A stop moves that input at ``bar_rate_margin`` times the plane's
        rate to the braking end of ``brake_bar_share * bar_margin * bar_max`` and holds it,
        then releases it at the same rate towards the landing's input plus
        ``release_bar_share`` of the room beyond it, until the deceleration is down to that of
        the landing (time constant ``landing`` [s]). The speed-up jerk is at most
        ``accel_max / jerk_time`` and ``b_2 jerk`` at most ``jerk_bar_share`` of the budget.
        """
        settings, lim = self.settings, self.limits
        b = op.F[:, 3]
        budget = settings.bar_margin * lim.bar_max
        jerk = self.speedup_jerk(op)
        v_lo, v_hi = GainSchedule.vertical_speed_bounds(op, u, lim, settings.margin)
        v_cap = v_hi if travel > 0.0 else -v_lo
        v_land = settings.landing_distance / landing
        share = settings.brake_bar_share * budget
        sign = 1.0 if float(b[1]) >= 0.0 else -1.0
        u_brake = self._brake_input(op, travel)
        u_other = sign * share - travel * op.bar_e
        b0, b1 = float(b[0]), float(b[1])
        u_land = b0 * v_land - b1 * v_land / landing  # the landing's input at its start
        u_release = u_land + settings.release_bar_share * (u_other - u_land)
        du = settings.bar_rate_margin * lim.bar_rate_max * self.ts
        if self.kinematic_stop:
            # Input: the commanded acceleration along the travel [m/s^2], moved no faster than
            # the jerk limit. The stop brakes at the deceleration that the braking share of
            # the plane's room (about the trim, on the side where b_1 (-travel a) lies) holds,
            # at most accel_max.
            a_stop = self._stop_deceleration(op, travel)
            u_brake, u_other = -a_stop, a_stop
            u_land = -v_land / landing
            u_release = u_land + settings.release_bar_share * (u_other - u_land)
            du = jerk * self.ts
        # The stop's one-sample map is the design's, interpolated between grid speeds (the
        # map of a learned model's own series picks its stable truncation afresh at every
        # sample, and planned the A18M with twice its plane moment into 0.2 m of overshoot)
        _, i, j, w = self.design.weights(u)
        (phi_i, gam_i), (phi_j, gam_j) = self.stop_maps[i], self.stop_maps[j]
        phi = tuple((1.0 - w) * x + w * y for x, y in zip(phi_i, phi_j))
        gam = tuple((1.0 - w) * x + w * y for x, y in zip(gam_i, gam_j))
        if op.learned and not self.kinematic_stop:
            # the plane of a learned model moves the series k times as much per radian as
            # the design's (k its learned effectiveness on the pitch acceleration): the map's
            # input column is scaled by k (a weaker plane stops later)
            nominal = float(self.design.at(u).P[1, 3])
            k = float(op.P[1, 3]) / nominal if nominal != 0.0 else 1.0
            gam = tuple(k * g for g in gam)
        brake = Brake(phi, gam, u_brake, u_release, max(du, 1e-9), landing, v_land)
        return v_cap, jerk, brake


    def _brake_input(self, op: OperatingPoint, travel: float) -> float:
        """The stop's braking input ``U`` [rad] of :meth:`limits_toward` (dynamic stop): the
        braking end of ``brake_bar_share * bar_margin * bar_max``, in the travel frame about
        the trim ``op.bar_e``."""
        share = self.settings.brake_bar_share * self.settings.bar_margin * self.limits.bar_max
        sign = 1.0 if float(op.F[1, 3]) >= 0.0 else -1.0
        return -sign * share - travel * op.bar_e

    def _stop_deceleration(self, op: OperatingPoint, travel: float) -> float:
        """The deceleration [m/s^2] a kinematic stop of :meth:`limits_toward` brakes at: what
        the braking share of the plane's room about the trim holds, at most ``accel_max``."""
        settings = self.settings
        budget = settings.bar_margin * self.limits.bar_max
        b1 = float(op.F[1, 3])
        side = -travel * (1.0 if b1 >= 0.0 else -1.0)
        room = max(budget - side * op.bar_e, 0.0)
        return settings.accel_max if b1 == 0.0 else min(
            settings.accel_max, settings.brake_bar_share * room / abs(b1))

    def braking(self, op: OperatingPoint, travel: float) -> float:
        """How hard the stop of :meth:`limits_toward` planned on ``op`` brakes a motion in
        ``travel`` (+1 down, -1 up), to compare operating points at one speed: for a
        kinematic stop its deceleration [m/s^2]; else the braking input's distance from the
        trim times the plane's pitch acceleration per radian ``|P[1, 3]|`` [rad/s^2] (the
        stop's map takes its input column times the plane's effectiveness)."""
        if self.kinematic_stop:
            return self._stop_deceleration(op, travel)
        return abs(float(op.P[1, 3])) * abs(self._brake_input(op, travel))

    def advance(self, op: OperatingPoint, u: float, z_cmd: float,
                stop: tuple[OperatingPoint, float] | None = None,
                v_limit: float = math.inf, brake_on: OperatingPoint | None = None
                ) -> Reference:
        """The governed reference one sample on (:class:`Reference`); not stored (see
        :meth:`accept`). ``stop``, if given, is the operating point and surge speed [m/s] the
        stop is planned at (the speed the vehicle is heading for); else ``op`` and ``u``.
        ``v_limit`` [m/s, >= 0] caps the steady climb or dive further (the steadiest one the
        plane holds with the thrust held, :mod:`auv_depth_lqr.glide`); once the stop has
        begun (:attr:`stopping`), never below the reference's speed. ``brake_on``, if
        given, is an operating point at the stop's speed whose braking the stop is planned on
        instead (its steady climb or dive and its jerk stay those of ``op`` and ``stop``).

        A time-optimal point-to-point motion, re-planned at every sample (so it follows a
        new command, a new speed or a reference held back by the vehicle). The snap ``s_r``
        [m/s^4], constant over the sample, moves the jerk towards the speed-up profile: the
        acceleration goes towards ``sqrt(2 jerk dv + (jerk c)^2) - jerk c`` (``dv`` the speed
        still to gain up to ``v_cap``, ``c = jerk_time / 2``) at most at the jerk limit. The
        feed-forward BAR ``bar_e + b_0 v_lin + b_1 a + b_2 j + b_3 s`` stays inside
        ``bar_margin * bar_max`` and moves at most at ``bar_rate_margin`` times the plane's
        rate, so the reference is one the plane can fly. If the stop from the state after the
        sample (:func:`stop_distance`) would pass the target, the snap is instead the largest
        one whose stop ends on the target (regula falsi from the last sample's root; the rate
        limit gives way before the target does): the reference brakes as late as the plane
        allows and never overshoots.

        A short change from rest follows a critically damped filter of the command instead
        (:meth:`short_filter`, ``short_swings``).
        """
        settings, lim, ts = self.settings, self.limits, self.ts
        assert self._z_r is not None, 'start() the governor first'
        error = z_cmd - self._z_r
        travel = 1.0 if error > 0.0 or (error == 0.0 and self._v_r > 0.0) else -1.0
        E, V = travel * error, travel * self._v_r
        A, J = travel * self._a_r, travel * self._j_r
        if self._landing is None or self._landing[0] != z_cmd:
            # The landing's time constant is fixed per command (at the speed of its first
            # sample): a landing that changed with every wobble of the measured speed would
            # re-plan itself. Whether the change is a short one is decided there too.
            self._landing = (z_cmd, settings.approach_length / max(u, 0.1))
            self._stopping = False
            short = (settings.short_swings > 0.0 and V == 0.0 and A == 0.0 and J == 0.0
                     and self.short_length(self.speedup_jerk(op)) >= E)
            self._short = self.short_filter() if short else None
        if E < 1e-3 and abs(V) < 1e-3 and abs(A) < 2e-3 and abs(J) < 2e-3:
            self._stopping = False
            return Reference(z_cmd, 0.0, 0.0, 0.0, 0.0)
        if self._short is not None:
            tau = self.short_tau()
            e1, v1, a1, j1 = self._short @ np.array(
                [self._z_r - z_cmd, self._v_r, self._a_r, self._j_r])
            s1 = -(4.0 * j1 / tau + 6.0 * a1 / tau**2 + 4.0 * v1 / tau**3 + e1 / tau**4)
            return Reference(z_cmd + float(e1), float(v1), float(a1), float(j1), float(s1))
        v_cap, jerk, brake = self.limits_toward(op, u, travel, self._landing[1])
        if stop is not None:
            # the climb or dive is capped, and the stop planned, at the speed the vehicle is
            # heading for: with its thrust held it slows down in a dive (a buoyant one) or a
            # climb, and its plane's authority with it
            # (the plane's bound only: the pitch limit's follows the measured speed)
            plane_lo, plane_hi = GainSchedule.vertical_speed_bounds(
                stop[0], stop[1], self._plane_only, settings.margin)
            v_cap = min(v_cap, plane_hi if travel > 0.0 else -plane_lo)
        if stop is not None or brake_on is not None:
            stop_op, stop_u = (op, u) if stop is None else stop
            _, _, brake = self.limits_toward(stop_op if brake_on is None else brake_on,
                                             stop_u, travel, self._landing[1])
        # v_limit bounds the climb or dive, not the stop: once the stop has begun it cuts no
        # speed the reference has (a cap solved on an estimate the stop's own swing of the
        # plane has just moved would cut the braking reference's speed at once and turn it
        # back from the target)
        v_cap = min(v_cap, max(v_limit, V) if self._stopping else v_limit)
        landing, v_land = brake.landing, brake.v_land
        if 0.0 < V <= v_land * (1.0 + 1e-6) and V * landing * (1.0 + 1e-6) >= E:
            # Final approach: the exponential e(t) = E exp(-t / landing).
            self._stopping = True
            e1 = E * math.exp(-ts / landing)
            v1 = e1 / landing
            return Reference(z_cmd - travel * e1, travel * v1, -travel * v1 / landing,
                             travel * v1 / landing**2, -travel * v1 / landing**3)
        b = [float(x) for x in op.F[:, 3]]
        # Feed-forward input U = b0 V + b1 A + b2 J + b3 S at the end of the sample, linear
        # in the snap S held over it; BAR = bar_e + travel U (exact kinematics in b0's term).
        _, v0, a0, j0 = _constant_snap(V, A, J, 0.0, ts)
        lin0 = travel * GainSchedule.linear_speed(op, u, travel * v0)
        centre = b[0] * lin0 + b[1] * a0 + b[2] * j0
        slope = b[3] + b[2] * ts + b[1] * ts * ts / 2.0 + b[0] * ts ** 3 / 6.0
        budget = settings.bar_margin * lim.bar_max
        u_hi, u_lo = budget - travel * op.bar_e, -budget - travel * op.bar_e
        s_cap = settings.accel_max / ts ** 2
        if slope != 0.0 and not self.kinematic_stop:
            ends = sorted(((u_lo - centre) / slope, (u_hi - centre) / slope))
            s_lo, s_hi = ends
            s_floor = s_lo
            lin_prev = travel * GainSchedule.linear_speed(op, u, self._v_r)
            u_prev = b[0] * lin_prev + b[1] * A + b[2] * J + b[3] * travel * self._s_r
            rate = sorted(((u_prev - brake.du - centre) / slope,
                           (u_prev + brake.du - centre) / slope))
            if rate[0] <= s_hi and rate[1] >= s_lo:
                s_lo, s_hi = max(s_lo, rate[0]), min(s_hi, rate[1])
        else:
            s_lo = s_floor = -s_cap
            s_hi = s_cap
        if self.kinematic_stop:
            # The series of an unstable vehicle lets profiles that grow at its unstable rates
            # through the plane budget at no cost: bound the reference's jerk (twice the
            # speed-up's) and, beyond accel_max, turn its acceleration back.
            j_lim = 2.0 * jerk
            k_lo, k_hi = (-j_lim - J) / ts, (j_lim - J) / ts
            if settings.accel_max < A:
                k_hi = min(k_hi, (-j_lim - J) / ts + 1e-9)
            elif -settings.accel_max > A:
                k_lo = max(k_lo, (j_lim - J) / ts - 1e-9)
            s_lo, s_hi = max(s_lo, k_lo), min(s_hi, k_hi)
            if s_lo > s_hi:
                s_lo = s_hi = min(max(0.0, k_lo), k_hi)
            s_floor = max(s_floor, k_lo)
        # Speed-up: the jerk goes towards what brings the acceleration to a_goal.
        dv = v_cap - V - 0.5 * A * settings.jerk_time  # the jerk lags jerk_time behind
        lag = 0.5 * settings.jerk_time * jerk
        a_goal = math.copysign(math.sqrt(2.0 * jerk * abs(dv) + lag * lag) - lag, dv)
        a_goal = min(a_goal, settings.accel_max)
        j_goal = (a_goal - A) / settings.jerk_time
        j_goal = max(j_goal, -jerk) if A < 0.0 else min(max(j_goal, -jerk), jerk)
        s = min(max((j_goal - J) / ts, s_lo), s_hi)

        hint = self._switch_hint
        hint[0] = max(hint[0] - 1, 0)

        def overshoot(s_try: float) -> float:
            dz, v1, a1, j1 = _constant_snap(V, A, J, s_try, ts)
            u1 = (a1 + 2.0 * self.stop_tau * j1 + self.stop_tau ** 2 * s_try
                  if self.kinematic_stop else b[0] * v1 + b[1] * a1 + b[2] * j1 + b[3] * s_try)
            return dz + stop_distance(v1, a1, j1, u1, brake, hint) - E

        f_hi = overshoot(s)
        if f_hi > 0.0:
            self._stopping = True
            lo, hi = s_lo, s
            f_lo = overshoot(lo)
            if f_lo >= 0.0 and s_floor < s_lo:
                lo, hi = s_floor, s_lo  # the rate limit gives way before the target does
                f_lo, f_hi = overshoot(lo), f_lo
            s = lo if f_lo >= 0.0 else largest_root_below(overshoot, lo, hi, f_lo, f_hi,
                                                           self._s_root)
            self._s_root = s
        dz, v1, a1, j1 = _constant_snap(V, A, J, s, ts)
        if v1 > v_cap:  # the speed-up's momentum: never beyond the climb/dive bound
            v1, a1, j1 = v_cap, min(a1, 0.0), min(j1, 0.0)
        return Reference(self._z_r + travel * dz, travel * v1, travel * a1, travel * j1,
                         travel * s)



def _constant_snap(v: float, a: float, j: float, s: float, t: float
                   ) -> tuple[float, float, float, float]:
    """Distance [m], speed [m/s], acceleration [m/s^2] and jerk [m/s^3] after ``t`` [s] at
    constant snap ``s`` [m/s^4]."""
    t2 = t * t
    return (v * t + a * t2 / 2.0 + j * t2 * t / 6.0 + s * t2 * t2 / 24.0,
            v + a * t + j * t2 / 2.0 + s * t2 * t / 6.0, a + j * t + s * t2 / 2.0, j + s * t)

