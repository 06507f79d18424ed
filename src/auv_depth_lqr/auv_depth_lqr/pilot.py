"""The depth pilot's logic, clock- and ROS-free: commands, state freshness, safe fallback.

:class:`DepthPilot` wraps a :class:`~auv_depth_lqr.controller.DepthController` with what a
pilot on a vehicle must also do:

* a depth command that is NaN or infinite is rejected, and one outside the depth envelope
  ``[depth_min, depth_max]`` [m] (the vehicle file's, or a narrower one: surface margin,
  bottom, rated depth) is rejected or, when asked, clamped to it
  (:class:`~auv_depth_lqr.errors.InvalidInputError` naming the value; the last valid one is
  kept): a depth outside the envelope is never flown; before any command the pilot holds the
  first depth it measured, brought inside the envelope;
* when no state has arrived for longer than ``state_timeout`` [s] it commands the documented
  safe BAR (a gentle nose-up climb; by default 0.275 ``bar_max`` to the nose-up side,
  :func:`auv_depth_lqr.tuning.derive_tuning`: -0.12 rad = -6.9 deg, about +7 deg pitch and
  0.25 m/s climb for the A18M at 2 m/s) and says so; when state returns it resumes, with the
  controller reset so that no stale integrator or reference acts;
* any failure of the controller on a sample gives the safe BAR, never an exception;
* a pitch-sensor offset (misalignment, AHRS bias) is estimated from the depth kinematics
  (:mod:`auv_depth_lqr.attitude`, model-free) and removed from the measured pitch before the
  controller sees it, so the pilot does not hold a depth offset of ``b K_theta / K_z``
  (0.2 m per degree on the A18M) that only its slow integrator would remove;
* when the vehicle leaves the envelope its design model describes (pitch beyond the limit
  plus a margin, a depth rate the model cannot explain) it flies the conservative recovery
  law of :mod:`auv_depth_lqr.recovery` until the vehicle is back inside, then resumes with
  the controller reset;
* it measures how much of the plane holding depth takes (:mod:`auv_depth_lqr.authority`,
  model-free) and says when that leaves little to manoeuvre with (:attr:`DepthPilot.authority`).

The depth-pilot node and offline closed-loop runs both drive this class, so a lockstep graph
run and an offline run give the same commands. Times are in seconds on any one clock.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from auv_depth_lqr.attitude import PitchOffset, PitchOffsetEstimator
from auv_depth_lqr.authority import Authority, AuthorityMonitor
from auv_depth_lqr.controller import DepthController, PlaneState
from auv_depth_lqr.design_cache import cached_design
from auv_depth_lqr.errors import AuvLqrError, DesignError, InvalidInputError
from auv_depth_lqr.learning import PARAMETERS, PlantEstimator
from auv_depth_lqr.limits import Limits
from auv_depth_lqr.recovery import (
    RECOVERY,
    EnvelopeMonitor,
    RecoverySettings,
    Verdict,
    recovery_bar,
)
from auv_depth_lqr.runaway import RunawayMonitor
from auv_depth_lqr.schedule import GainSchedule
from auv_depth_lqr.surge import surge_length
from auv_depth_lqr.tuning import derive_tuning
from auv_depth_lqr.weights import Weights, preset
from auv_sim.errors import TrimError
from auv_sim.params import VehicleParams

SAFE_BAR_DEFAULT = -0.12
"""Safe dive-plane angle [rad] without state of the A18M (a gentle nose-up climb), for
reference: every pilot, the node's included (its ``safe_bar`` parameter is NaN by default),
derives its vehicle's own (:func:`auv_depth_lqr.tuning.derive_tuning`) when
``PilotSettings.safe_bar`` is ``None``."""

CURRENT_TIME = 30.0
"""Time constant [s] over which a pilot told its water speed follows the current along its
heading (see :meth:`DepthPilot.on_state`): long against a depth change, short against the
tides."""

LEVEL_SHARE = 0.1
"""A vehicle whose pitch is within this share of ``theta_max`` of its trim pitch is level:
a pilot told its water speed then takes the difference of its measured surge from that speed
as current [-]."""

PITCH_OFFSET_TIME = 20.0
"""Forgetting time [s] of the pitch-offset estimate of a pilot built without its vehicle file
(the A18M's derived value, :func:`auv_depth_lqr.tuning.derive_tuning`)."""

AUTHORITY_WINDOW = 20.0
"""Window [s] of the plane-authority measure of a pilot built without its vehicle file (the
A18M's derived value, :func:`auv_depth_lqr.tuning.derive_tuning`)."""

DEFAULT_SPEEDS = tuple(round(0.5 + 0.1 * k, 1) for k in range(36))
"""Gain-scheduling grid [m/s]: 0.5 to 4.0 m/s every 0.1 m/s, less the speeds the vehicle
cannot trim at (:func:`trimmable_speeds`). The stop of the reference governor is planned on
the model series interpolated linearly between grid speeds; on a 0.5 m/s grid that error
misplans the stop between grid points (A18M, 40 -> 10 m at 1.83 m/s: RMS pitch rate after
settling 0.20 deg/s, against 0.03 deg/s on this grid). The design takes ~2 ms per speed."""


LIMITED_SHARE = 0.9
"""A climb or dive whose steady vertical speed the plane allows is below this share of the
kinematic one (the pitch limit's) is limited by the plane at the present speed [-]."""

HELD_THRUST_PERIOD = 10.0
"""How long [s of state time] the steadiest climb and dive with the thrust held
(:meth:`DepthPilot.climb_limits`) are kept before they are solved again [s]."""

PLANE_RATE_SHARE = 1.0
"""The plane-rate design's rate weight (``plane_rate_design``) is Bryson's rule on a rate
excursion of this share of the plane's rate limit, ``R_rate = 1 / (share bar_rate)^2``
[-]: at 1 the acceptable rate is the limit itself (the vehicle's default weights take
0.2292 ``bar_max`` as the plane's acceptable angle, :func:`~auv_depth_lqr.tuning.derive_tuning`;
a rate weight in that proportion, ``share`` 0.2292, slowed the REMUS 100's plane-rate loop
and left more of its porpoise in the head-current case of ``tests/test_model_error.py``)."""

ENVELOPE_REPORT_TIME = 2.0
"""How long [s] after the pitch envelope selector last held a limit the pilot still says so
(:meth:`DepthPilot.envelope_state`, :meth:`DepthPilot.envelope_warning`): one line, not one
per sample."""


class ClimbLimits(NamedTuple):
    """The steadiest climb and dive the pilot can fly within its limits at the present
    speed (its learned model), and whether the plane, not the pitch limit, sets them."""

    climb: float
    """Largest steady climb rate [m/s, up positive] (nan before the first command)."""
    dive: float
    """Largest steady dive rate [m/s, down positive]."""
    kinematic: float
    """What the pitch limit alone allows, ``margin u sin(theta_max)`` [m/s]."""
    limited: bool
    """Whether a climb or dive is held below ``LIMITED_SHARE`` of ``kinematic`` by the
    plane (a weak or trimmed-out plane, a speed too low): depth changes take longer than
    the pitch limit would allow."""
    held_climb: float = math.nan
    """Steadiest climb [m/s, up positive] with the present thrust held, the speed settled
    where the thrust balances the drag and the weight less the buoyancy along the axis, the
    plane within its trim share (:mod:`auv_depth_lqr.glide`); ``inf``: the pitch limit,
    not the plane, bounds it; nan: not known (no learner, thrust not measured yet)."""
    held_dive: float = math.nan
    """The same for a dive [m/s, down positive]."""

    def message(self) -> str:
        """One line for an operator."""
        if not math.isfinite(self.kinematic):
            return 'not known yet'
        text = (f'climb at most {self.climb:.2f} m/s, dive at most {self.dive:.2f} m/s '
                f'(pitch limit alone: {self.kinematic:.2f} m/s)')
        if self.limited:
            text += ': the plane cannot hold the pitch limit at this speed, depth changes are ' \
                    'flown slower, within the limits'
        held = [f'{name} at most {value:.2f} m/s' for name, value in
                (('climb', self.held_climb), ('dive', self.held_dive)) if math.isfinite(value)]
        if held:
            text += '; with the thrust held, once the speed has settled: ' + ', '.join(held)
        return text


@dataclasses.dataclass(frozen=True)
class PilotSettings:
    """Design and run-time settings of the depth pilot (SI units, radians).

    ``weights``: a preset name or a :class:`Weights`; ``'default'`` is Bryson's rule on
    the vehicle's scales (:func:`auv_depth_lqr.tuning.derive_tuning`), ``report_4_4`` and
    ``report_5`` the report's fixed weights; ``safe_bar`` [rad] is the plane without state,
    ``None`` for the vehicle's derived one; the reference governor's settings are derived
    from the vehicle (:func:`~auv_depth_lqr.tuning.derive_tuning`); ``bar_max`` /
    ``bar_rate`` default to the vehicle file's actuator limits;
    ``speeds`` is the gain-scheduling grid [m/s]; ``water_speed`` [m/s], when given, is the
    surge speed through the water (from the propeller setting or a water-track log) that the
    pilot schedules on and flies its model at, instead of the measured surge over ground
    (see :func:`water_relative`). ``publish_delay`` [s, 0 <= d < Ts/2] is the fixed output
    phase of a pilot on the wall clock: the command of the tick due at ``t_k`` is published at
    ``t_k + publish_delay``, so the time its step took (and a late wake-up) does not move the
    publish instant (logical-execution-time output); 0 publishes as soon as it is computed.
    ``recovery``: when the envelope fallback acts and how (:class:`RecoverySettings`).
    ``pitch_offset``: estimate a pitch-sensor offset from the depth kinematics and fly the
    corrected pitch (:class:`~auv_depth_lqr.attitude.PitchOffsetEstimator`), with the
    forgetting time ``pitch_offset_time`` [s] (``None``: derived from the vehicle by
    :meth:`DepthPilot.for_vehicle`, :func:`~auv_depth_lqr.tuning.derive_tuning`; a pilot
    built directly takes :data:`PITCH_OFFSET_TIME`) and ``pitch_offset_max`` [rad], the
    largest offset taken as physical (default 3 deg, assumed: a sensor mounted within a few
    degrees; a larger fit is not applied). ``authority_window`` [s]: window of the
    plane-authority measure (:class:`~auv_depth_lqr.authority.AuthorityMonitor`; ``None``:
    derived from the vehicle by :meth:`DepthPilot.for_vehicle`; a pilot built directly takes
    :data:`AUTHORITY_WINDOW`). ``learn``: estimate what the vehicle file gets wrong while
    flying (:mod:`auv_depth_lqr.learning`) and, once the reference has come within
    ``landing_distance`` of a command (its stop flown), fly the learned model: on the
    landing the latest estimate, at rest the mean of the estimates since the reference came
    to rest (``docs/pilot-design.md``); off (the default), the vehicle file's model with its
    disturbance estimate throughout. ``pitch_envelope``: the pitch envelope
    selector (:mod:`auv_depth_lqr.envelope`) keeps the BAR within the commands of a
    pitch-hold law towards the pitch limits (default); off, only the pitch guard of the depth
    loop limits the pitch (to look at the depth loop alone, or to let excitation added to the
    pilot's command reach the pitch it is meant to). ``plane_rate_design``: design the LQR
    with the plane as a state and its rate as the input (:data:`PLANE_RATE_SHARE`,
    :meth:`~auv_depth_lqr.controller.DepthController.step`); off (the default), the LQR
    commands the plane's angle and its rate limit acts after it as a slew.
    """

    rate_hz: float = 10.0
    weights: str | Weights = 'default'
    theta_max: float = math.radians(25.0)
    bar_max: float | None = None
    bar_rate: float | None = None
    speeds: Sequence[float] = DEFAULT_SPEEDS
    state_timeout: float = 0.5
    safe_bar: float | None = None
    water_speed: float | None = None
    publish_delay: float = 0.01
    recovery: RecoverySettings = dataclasses.field(default_factory=RecoverySettings)
    pitch_offset: bool = True
    pitch_offset_time: float | None = None
    pitch_offset_max: float = math.radians(3.0)
    authority_window: float | None = None
    learn: bool = False
    pitch_envelope: bool = True
    plane_rate_design: bool = False

    def __post_init__(self) -> None:
        for name in ('rate_hz', 'theta_max', 'state_timeout'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise DesignError(f'pilot setting {name} = {value!r} must be finite and > 0')
        if not (isinstance(self.publish_delay, (int, float))
                and 0.0 <= self.publish_delay < 0.5 / self.rate_hz):
            raise DesignError(f'pilot setting publish_delay = {self.publish_delay!r} s must be '
                              f'>= 0 and below half the sample period ({0.5 / self.rate_hz:g} s)')
        for name in ('pitch_offset_time', 'pitch_offset_max', 'authority_window'):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, (int, float))
                                          and math.isfinite(value) and value > 0):
                raise DesignError(f'pilot setting {name} = {value!r} must be finite and > 0')
        if self.safe_bar is not None and not math.isfinite(self.safe_bar):
            raise DesignError(f'pilot setting safe_bar = {self.safe_bar!r} must be finite')
        if self.water_speed is not None and not (
                isinstance(self.water_speed, (int, float)) and math.isfinite(self.water_speed)
                and self.water_speed > 0):
            raise DesignError(f'pilot setting water_speed = {self.water_speed!r} must be '
                              'finite and > 0 [m/s] (or None: use the measured surge)')

    @property
    def Ts(self) -> float:
        """Sample period [s]."""
        return 1.0 / self.rate_hz


def water_relative(u: float, w: float, theta: float, water_speed: float) -> tuple[float, float]:
    """Body surge and heave through the water ``(u_r, w_r)`` [m/s] from the measured ones.

    ``u``, ``w`` [m/s] are the body FRD velocities over ground (a DVL's bottom track),
    ``theta`` [rad] the pitch and ``water_speed`` [m/s] the known surge through the water.
    In a horizontal current ``c`` along the heading the body current is
    ``(c cos theta, c sin theta)``, so ``c = (u - u_r) / cos theta`` and
    ``w_r = w - (u - u_r) tan theta``; a current across the heading leaves both unchanged.
    The vertical speed over ground is then the vertical speed through the water.
    """
    return water_speed, w - (u - water_speed) * math.tan(theta)


def vehicle_linearization(params: VehicleParams):  # type: ignore[no-untyped-def]
    """``linearize(u0) -> (x_e, BAR_e, A, B)`` of the vehicle's vertical plane (exact
    kinematics)."""
    from auv_sim.trim import VerticalPlane  # the compiled model, only when a design is solved

    plane = VerticalPlane(params)

    def linearize(u0: float):  # type: ignore[no-untyped-def]
        trim = plane.trim(u0)
        A, B = plane.linearize(trim)
        return [trim.w, 0.0, trim.z, trim.theta, 0.0], trim.bar, A, B

    return linearize


def trimmable_speeds(params: VehicleParams, speeds: Sequence[float]) -> tuple[float, ...]:
    """The speeds [m/s] of a gain-scheduling grid at which the vehicle can trim (a slow
    speed may need more plane than the vehicle has); DesignError if there is none."""
    from auv_sim.trim import VerticalPlane  # the compiled model, only when a design is solved

    plane = VerticalPlane(params)
    usable = []
    for u in speeds:
        try:
            plane.trim(float(u))
        except TrimError:
            continue
        usable.append(float(u))
    if not usable:
        raise DesignError(f'{params.name}: no trim within the plane limit at any of the '
                          f'gain-scheduling speeds {list(speeds)} m/s')
    return tuple(usable)


def build_controller(params: VehicleParams, settings: PilotSettings) -> DepthController:
    """Gain-scheduled LQR depth controller of a vehicle (see :mod:`auv_depth_lqr.controller`),
    its weights (``'default'``) and governor derived from the vehicle file
    (:func:`auv_depth_lqr.tuning.derive_tuning`)."""
    bar_max = settings.bar_max if settings.bar_max is not None else params.bar_max
    bar_rate = settings.bar_rate if settings.bar_rate is not None else params.bar_rate
    if not (math.isfinite(bar_rate) and bar_rate > 0.0):
        raise DesignError(f'bar_rate = {bar_rate!r} rad/s must be finite and > 0')
    tuning = derive_tuning(params, settings.theta_max, bar_max)
    if isinstance(settings.weights, Weights):
        weights = settings.weights
    elif settings.weights == 'default':
        weights = tuning.weights
    else:
        weights = preset(settings.weights)
    Q, R = weights.matrices()
    R_rate = np.array([[1.0 / (PLANE_RATE_SHARE * bar_rate) ** 2]]) \
        if settings.plane_rate_design else None
    if settings.safe_bar is not None and not abs(settings.safe_bar) <= bar_max:
        raise DesignError(f'safe_bar = {settings.safe_bar} rad is beyond bar_max = {bar_max}')

    def design() -> tuple[GainSchedule, float]:
        speeds = trimmable_speeds(params, settings.speeds)
        schedule = GainSchedule.design(vehicle_linearization(params), speeds=speeds,
                                       Q=Q, R=R, Ts=settings.Ts, R_rate=R_rate)
        return schedule, surge_length(params, speeds)

    # the same design as computed afresh, from the disk cache when the vehicle, the settings
    # and the code are those it was made with (auv_depth_lqr.design_cache)
    schedule, surge = cached_design(params, settings.speeds, Q, R, settings.Ts, design, R_rate)
    limits = Limits(bar_max=bar_max, bar_rate_max=bar_rate, theta_max=settings.theta_max)
    governor = dataclasses.replace(tuning.governor, surge_length=surge,
                                   pitch_envelope=settings.pitch_envelope)
    learner = PlantEstimator(params, settings.Ts) if settings.learn else None
    return DepthController(schedule, limits, settings.Ts, governor, learner)


class DepthPilot:
    """Depth pilot around a controller (see module docstring)."""

    def __init__(self, controller: DepthController, depth_min: float, depth_max: float,
                 settings: PilotSettings) -> None:
        if not (math.isfinite(depth_min) and math.isfinite(depth_max)
                and 0.0 <= depth_min < depth_max):
            raise DesignError(f'depth envelope [{depth_min!r}, {depth_max!r}] m must be finite '
                              'with 0 <= depth_min < depth_max')
        if settings.safe_bar is None:
            raise DesignError('pilot setting safe_bar is None: give it, or build the pilot '
                              'with DepthPilot.for_vehicle, which derives it')
        self.controller = controller
        self.depth_min = float(depth_min)
        self.depth_max = float(depth_max)
        self.settings = settings
        self.monitor = EnvelopeMonitor(controller.limits.theta_max, settings.recovery)
        self.verdict: Verdict | None = None
        self._t_monitored: float | None = None
        self.z_ref: float | None = None
        self._state: PlaneState | None = None
        self._t_state: float | None = None
        self._stale = True
        self._last_bar: float | None = None
        self.status = 'no_state'
        self._current: float | None = None
        """Estimated current along the heading [m/s] (``water_speed`` given), see
        :meth:`on_state`."""
        offset_time = settings.pitch_offset_time if settings.pitch_offset_time is not None \
            else PITCH_OFFSET_TIME
        self._pitch_offset = PitchOffsetEstimator(offset_time, settings.pitch_offset_max,
                                                  settings.state_timeout)
        self._theta_measured = 0.0
        """Pitch [rad] of the latest state as measured (before the offset is removed)."""
        self._t_measured = 0.0
        """Measurement time [s] of the latest state (its stamp)."""
        self._held: tuple[float, float, float] | None = None
        """``(t [s], climb, dive [m/s])`` of the last held-thrust limits solved."""
        self._envelope_t: float | None = None
        """Time [s] the pitch envelope selector last held a limit in normal control."""
        self._envelope_given_t: float | None = None
        """Time [s] it last held a limit that had given way (below the pitch limit)."""
        self._t_offset: float | None = None
        """Measurement time [s] of the last state the pitch-offset estimate took."""
        self.pitch_offset = PitchOffset(0.0, False, math.nan)
        """The last pitch-sensor offset estimate (:class:`~auv_depth_lqr.attitude.PitchOffset`;
        its ``offset`` [rad] is subtracted from the measured pitch when ``pitch_offset``)."""
        self.authority_monitor = AuthorityMonitor(
            controller.limits.bar_max,
            AUTHORITY_WINDOW if settings.authority_window is None else settings.authority_window,
            controller.governor.trim_bar_share)
        self.runaway_monitor = RunawayMonitor(controller.limits.bar_max)
        """The vehicle away from its command and not coming back with the plane at the stop
        that would bring it back (:mod:`auv_depth_lqr.runaway`), in normal control."""

    @property
    def authority(self) -> Authority:
        """How much of the plane holding depth took over the last window
        (:class:`~auv_depth_lqr.authority.Authority`), from the commands of normal control."""
        return self.authority_monitor.authority

    def climb_limits(self) -> ClimbLimits:
        """The steadiest climb and dive at the present speed on the learned model
        (:class:`ClimbLimits`; from the last control step), and with the present thrust
        held (solved at most every ``HELD_THRUST_PERIOD`` seconds of state time)."""
        caps = self.controller.vertical_speed_caps
        if caps is None:
            return ClimbLimits(math.nan, math.nan, math.nan, False)
        v_lo, v_hi, v_kin = caps
        held_climb, held_dive = self._held_thrust_caps()
        limited = min(-v_lo, v_hi, held_climb, held_dive) < LIMITED_SHARE * v_kin
        return ClimbLimits(-v_lo, v_hi, v_kin, bool(limited), held_climb, held_dive)

    def _held_thrust_caps(self) -> tuple[float, float]:
        """``(climb, dive)`` [m/s] of :attr:`ClimbLimits.held_climb`, ``held_dive``."""
        learner, u = self.controller.learner, self.controller.state_speed
        t = self._t_state
        if learner is None or learner.thrust is None or u is None or t is None:
            return math.nan, math.nan
        if self._held is None or not 0.0 <= t - self._held[0] < HELD_THRUST_PERIOD:
            self._held = (t, self.controller.held_thrust_cap(-1.0, u),
                          self.controller.held_thrust_cap(1.0, u))
        return self._held[1], self._held[2]

    def envelope_state(self, t: float) -> str:
        """What the pitch envelope selector (:mod:`auv_depth_lqr.envelope`) did within
        ``ENVELOPE_REPORT_TIME`` of ``t`` [s]: ``'given way'`` it held a limit that had
        given way (the plane cannot hold the pitch limit at the speed the held thrust is
        heading for: the depth change cannot be flown within the limits), ``'at limit'`` it
        held the pitch limit itself (the change is flown at the limit, as a time-optimal
        climb or dive is), ``'clear'`` it held none."""
        def recent(held_at: float | None) -> bool:
            return held_at is not None and 0.0 <= t - held_at <= ENVELOPE_REPORT_TIME
        if recent(self._envelope_given_t):
            return 'given way'
        return 'at limit' if recent(self._envelope_t) else 'clear'

    def envelope_warning(self, t: float) -> str:
        """One line for an operator when :meth:`envelope_state` at ``t`` [s] is ``'given
        way'``: the depth change asked for cannot be flown within the limits at the present
        speed and thrust, and is flown the best it can within them; '' otherwise (a limit
        held at the pitch limit itself is the plan, not a warning)."""
        if self.envelope_state(t) != 'given way':
            return ''
        env = self.controller.envelope
        return (f'pitch limit held (nose up {math.degrees(env.up):.1f} deg, nose down '
                f'{math.degrees(env.down):.1f} deg): the depth change cannot be flown within '
                'the limits at the present speed and thrust; flying the best it can within '
                'them')

    def runaway_warning(self) -> str:
        """One line for an operator while the runaway monitor
        (:mod:`auv_depth_lqr.runaway`) holds one: how far off the command the vehicle is
        and that the plane cannot bring it back at its present speed; '' otherwise."""
        runaway = self.runaway_monitor.state
        if runaway is None or self.z_ref is None:
            return ''
        side, stop = ('below', 'nose-up') if runaway.below else ('above', 'nose-down')
        u = math.nan if self._state is None else self._state.u
        return (f'depth runaway: {runaway.off:.1f} m {side} the commanded {self.z_ref:g} m '
                f'and no nearer to it for {runaway.stop_time:.0f} s with the plane at its '
                f'{stop} stop: the plane cannot bring the vehicle back at {u:.2f} m/s (more '
                'speed, less buoyancy or a trim change is needed)')

    def speed_diagnostics(self) -> dict[str, str]:
        """The surge speed the pilot schedules its gains and plans its climbs on, as
        diagnostic key/values: ``speed_basis`` (``through the water`` when told its water
        speed, else ``over ground``), ``scheduled_speed_mps`` (the surge [m/s, body FRD] of
        the last state as flown from; ``none`` before the first) and
        ``current_along_heading_mps`` (the current along the heading [m/s, positive
        following] the pilot follows when told its water speed, :meth:`_through_water`;
        ``unknown`` when it is not told: a speed over ground cannot tell a current from the
        vehicle's own speed). Not told, ``speed_basis_note`` says what a current does."""
        state = self._state
        out = {'scheduled_speed_mps': 'none' if state is None else f'{state.u:.3f}'}
        if self.settings.water_speed is None:
            out['speed_basis'] = 'over ground'
            out['current_along_heading_mps'] = 'unknown'
            out['speed_basis_note'] = (
                'no water speed told (parameter water_speed): in a current along the heading '
                'the gains and the climb plan are those of the speed over ground, not of the '
                'speed through the water')
        else:
            out['speed_basis'] = (f'through the water (told '
                                  f'{self.settings.water_speed:.3f} m/s)')
            out['current_along_heading_mps'] = ('none' if self._current is None
                                                else f'{self._current:+.3f}')
        return out

    def learning_diagnostics(self) -> dict[str, str]:
        """What the pilot has learned of its plant and what it can fly, as diagnostic
        key/values (``learned_*`` the latest estimate's parameters and standard deviations
        (:mod:`auv_depth_lqr.learning`), ``learned_model`` whether the learned model is flown
        (at rest, the mean of how many estimates) or why not, ``learned_evidence`` by how
        much (log-likelihood) its predictions beat the vehicle file's
        (:attr:`~auv_depth_lqr.learning.PlantEstimator.evidence`), ``learning_noise`` the
        noise learned with, ``learned_plane_delay`` how much later than its model the plane
        acts, ``climb_limit_*``, ``depth_change_limited``)."""
        out: dict[str, str] = {}
        learner = self.controller.learner
        if learner is None:
            out['learning'] = 'off'
        else:
            est = learner.estimate
            out['learning'] = f'{est.samples} samples'
            reason = learner.implausible
            if learner.flying:
                count = learner.flown_estimates
                out['learned_model'] = 'flown' if count <= 1 else \
                    f'flown: the mean of {count} estimates since the reference came to rest'
            elif reason is not None:
                out['learned_model'] = f'the file\'s: the estimate is not physical ({reason})'
            elif est.samples and not learner.predicts_better:
                out['learned_model'] = ('the file\'s: the estimate predicts the samples no '
                                        'better than the file')
            else:
                out['learned_model'] = 'the file\'s: nothing learned at rest or on a landing yet'
            out['learned_evidence'] = f'{learner.evidence:+.1f}'
            noise = learner.noise
            out['learning_noise'] = f'{noise[0]:.3g} N, {noise[1]:.3g} N m per sample'
            out['learned_plane_delay'] = f'{learner.plane_delay:.1f} s'
            for name, value, sigma in zip(PARAMETERS, est.values, est.sigma):
                out[f'learned_{name}'] = f'{value:+.4f} +- {sigma:.4f}'
            if self.controller.state_speed is not None:
                op = self.controller.design.at(self.controller.state_speed)
                learned = self.controller.trimmed(op)
                out['learned_trim_bar_deg'] = f'{math.degrees(learned.bar_e):+.2f}'
                out['model_trim_bar_deg'] = f'{math.degrees(op.bar_e):+.2f}'
                out['learned_plane_gain'] = f'{learner.plane_gain(op):.3f}'
        limits = self.climb_limits()
        out['climb_limit_mps'] = f'{limits.climb:.3f}'
        out['dive_limit_mps'] = f'{limits.dive:.3f}'
        out['held_thrust_climb_limit_mps'] = f'{limits.held_climb:.3f}'
        out['held_thrust_dive_limit_mps'] = f'{limits.held_dive:.3f}'
        out['depth_change_limited'] = 'true' if limits.limited else 'false'
        out['depth_change_limits'] = limits.message()
        return out

    @property
    def state(self) -> PlaneState | None:
        """The vertical-plane state the pilot flies from, as its last :meth:`on_state` made
        it (z [m] down, theta [rad] nose up, w [m/s], q [rad/s] in body FRD; u [m/s] through
        the water when told its water speed), or None before the first state."""
        return self._state

    @classmethod
    def for_vehicle(cls, params: VehicleParams, settings: PilotSettings | None = None,
                    depth_min: float | None = None, depth_max: float | None = None,
                    ) -> DepthPilot:
        """A pilot for a vehicle file's parameters; its depth envelope [m] is the vehicle
        file's unless ``depth_min`` / ``depth_max`` narrow it (DesignError if they are
        outside the file's rated envelope)."""
        settings = settings or PilotSettings()
        bar_max = settings.bar_max if settings.bar_max is not None else params.bar_max
        tuning = derive_tuning(params, settings.theta_max, bar_max)
        if settings.safe_bar is None:
            settings = dataclasses.replace(settings, safe_bar=tuning.safe_bar)
        if settings.pitch_offset_time is None:
            settings = dataclasses.replace(settings, pitch_offset_time=tuning.pitch_offset_time)
        if settings.authority_window is None:
            settings = dataclasses.replace(settings, authority_window=tuning.authority_window)
        lo = params.depth_min if depth_min is None else depth_min
        hi = params.depth_max if depth_max is None else depth_max
        for name, value in (('depth_min', lo), ('depth_max', hi)):
            if not (math.isfinite(value) and params.depth_min <= value <= params.depth_max):
                raise DesignError(f'{name} = {value!r} m is outside the envelope '
                                  f'[{params.depth_min:g}, {params.depth_max:g}] m of '
                                  f'{params.name} (its vehicle file)')
        if not lo < hi:
            raise DesignError(f'depth_min = {lo:g} m must be below depth_max = {hi:g} m')
        return cls(build_controller(params, settings), lo, hi, settings)

    def set_depth_command(self, z: float, clamp: bool = False) -> float:
        """Accept a commanded depth [m, down] and return the depth that will be flown.

        A non-finite command is always refused; one outside ``[depth_min, depth_max]`` is
        refused, or with ``clamp`` replaced by the nearest envelope bound. Refused:
        InvalidInputError naming the value (the last valid command is kept).
        """
        try:
            value = float(z)
        except (TypeError, ValueError):
            raise InvalidInputError(f'depth command {z!r} is not a number; kept '
                                    f'{self.z_ref} m') from None
        if not math.isfinite(value):
            raise InvalidInputError(f'depth command {value} is not finite; kept {self.z_ref} m')
        if clamp:
            value = min(max(value, self.depth_min), self.depth_max)
        if not self.depth_min <= value <= self.depth_max:
            raise InvalidInputError(
                f'depth command {value:g} m is outside the depth envelope '
                f'[{self.depth_min:g}, {self.depth_max:g}] m; kept {self.z_ref} m')
        self.z_ref = value
        return value

    def on_state(self, t: float, z: float, theta: float, w: float, q: float, u: float,
                 stamp: float | None = None) -> None:
        """Record a measured state received at time ``t`` [s]; non-finite states are ignored
        (InvalidInputError). ``stamp`` [s] is when it was measured (its header stamp; default
        ``t``): the pitch-offset estimate integrates the kinematics over these times."""
        values = (z, theta, w, q, u)
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values):
            raise InvalidInputError(f'state with non-finite fields {values} ignored')
        if self.settings.water_speed is not None:
            u, w = self._through_water(t, u, w, theta)
        self._theta_measured = float(theta)
        self._t_measured = float(t if stamp is None else stamp)
        if self.settings.pitch_offset:
            theta -= self.pitch_offset.offset  # the latest estimate (see :meth:`command`)
        self._state = PlaneState(z=z, theta=theta, w=w, q=q, u=u)
        self._t_state = float(t)
        if self.z_ref is None:
            self.z_ref = min(max(float(z), self.depth_min), self.depth_max)

    def _through_water(self, t: float, u: float, w: float, theta: float
                       ) -> tuple[float, float]:
        """Surge and heave through the water [m/s] from those over ground (body FRD).

        ``water_speed`` is the surge through the water in steady level flight (the
        propeller's setting). What the measured surge differs from it there is the current
        along the heading, ``c = (u - water_speed) / cos(theta)`` (:func:`water_relative`);
        the pilot takes it from the first state and then follows it, low-passed over
        ``CURRENT_TIME``, only while the vehicle is level (pitch within ``LEVEL_SHARE *
        theta_max`` of its trim). In a climb or dive the vehicle slows down or speeds up
        (the thrust does not change with the pitch): the surge through the water is then
        ``u - c cos(theta)``, not the setting, and the plane's authority goes with its
        square."""
        along = (u - self.settings.water_speed) / math.cos(theta) \
            if self.settings.water_speed is not None else 0.0
        if self._current is None or self._t_state is None:
            self._current = along
        else:
            u_r = u - self._current * math.cos(theta)
            level = abs(theta - self.controller.design.at(u_r).theta_e) \
                <= LEVEL_SHARE * self.controller.limits.theta_max
            dt = t - self._t_state
            if level and dt > 0.0:
                self._current += dt / (CURRENT_TIME + dt) * (along - self._current)
        return (u - self._current * math.cos(theta), w - self._current * math.sin(theta))

    def command(self, t: float) -> tuple[float, str]:
        """BAR command [rad] at time ``t`` [s] and the status that produced it.

        Status: ``ok``; ``recovery`` (outside the envelope of the design model: recovery
        law, see :attr:`verdict`); ``stale`` (no state for longer than the timeout: safe
        BAR); ``no_state`` (none yet: safe BAR); ``error: ...`` (controller failed: safe BAR).
        """
        if self._state is None or self._t_state is None:
            self.status = 'no_state'
            return self._safe(), self.status
        if t - self._t_state > self.settings.state_timeout:
            self._stale = True
            self.monitor.reset()
            self.status = 'stale'
            return self._safe(), self.status
        if self.settings.pitch_offset and self._t_offset != self._t_measured:
            self._estimate_pitch_offset()
        if self._t_monitored != self._t_state:
            s = self._state
            self.verdict = self.monitor.update(self._t_state, s.z, s.theta, s.w, s.u)
            self._t_monitored = self._t_state
        if self.monitor.mode == RECOVERY:
            self._stale = True  # the controller restarts from scratch on resuming
            self.status = 'recovery'
            return self._recovery(), self.status
        if self._stale:
            self.controller.reset(bar_previous=self._last_bar)
            self.authority_monitor.reset()  # its window is of normal control only
            self.runaway_monitor.reset()
            self._stale = False
        assert self.z_ref is not None
        try:
            bar = self.controller.step(self._state, self.z_ref)
        except AuvLqrError as exc:
            self._stale = True
            self.status = f'error: {exc}'
            return self._safe(), self.status
        self._last_bar = bar
        env = self.controller.envelope
        if env.active:
            self._envelope_t = t
            if (env.up if env.active > 0 else env.down) < env.theta_lim:
                self._envelope_given_t = t
        self.status = 'ok'
        self.authority_monitor.update(
            t, bar, self.controller.governed_reference == (self.z_ref, 0.0))
        self.runaway_monitor.update(t, self._state.z, self.z_ref, bar)
        return bar, self.status

    def _estimate_pitch_offset(self) -> None:
        """Add the latest state to the pitch-offset estimate and correct its pitch.

        Called once per control step with a new state, so the estimate sees the states the
        controller sees, whatever rate they arrive at (the simulator's 50 Hz or a 10 Hz
        navigation solution give the same estimate). The kinematics hold for the velocities
        over ground, and through the water in a horizontal current, with the pitch they were
        converted with (the measured one)."""
        s = self._state
        assert s is not None
        self.pitch_offset = self._pitch_offset.update(self._t_measured, s.z,
                                                      self._theta_measured, s.w, s.u)
        self._t_offset = self._t_measured
        self._state = s._replace(theta=self._theta_measured - self.pitch_offset.offset)

    def _recovery(self) -> float:
        """The recovery law's BAR (see :func:`auv_depth_lqr.recovery.recovery_bar`) at the
        present speed, rate-limited like every command."""
        assert self._state is not None
        s, rec = self._state, self.settings.recovery
        op = self.controller.design.at(s.u)
        limits = self.controller.limits
        return self._slewed(recovery_bar(
            float(op.K[0]), float(op.K[1]), float(op.K[3]), op.w_e, op.theta_e, op.bar_e,
            s.w, s.q, s.theta, rec.gain, rec.bar_fraction * limits.bar_max))

    def _safe(self) -> float:
        """The safe BAR, reached no faster than the plane's rate limit allows."""
        assert self.settings.safe_bar is not None
        return self._slewed(self.settings.safe_bar)

    def _slewed(self, target: float) -> float:
        """``target`` [rad] moved toward from the last command at most the plane's rate
        limit times the sample period."""
        if self._last_bar is not None:
            slew = self.controller.limits.bar_rate_max * self.settings.Ts
            target = min(max(target, self._last_bar - slew), self._last_bar + slew)
        self._last_bar = target
        return target
