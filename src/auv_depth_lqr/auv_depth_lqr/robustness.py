"""The depth pilot on plants that are not its design model: plants, flights, figures (pure).

A :class:`Plant` is the "real" vehicle: the design vehicle file with some parameters scaled
(hydrodynamic derivatives, inertia, added mass: model error) plus the effects of the
sim-to-real catalogue that the simulator applies (:class:`auv_sim.environment.Environment`:
current, buoyancy offset, plane delay, lag, bias, pitch-sensor bias) and white noise on the
measured depth, which the simulator does not model and :class:`NoisyDepthPilot` adds at the
pilot's input. :func:`fly` designs the pilot on the *design* file and flies it on the plant
with the offline closed loop (:func:`auv_depth_lqr.closed_loop.run_closed_loop`: the 6-DOF
simulator at its RK4 step, the pilot at its rate, lockstep), and :func:`judge` scores the run
against :class:`Criteria`: settled within a multiple of the time-optimal bound of the design
model (:func:`auv_depth_lqr.bound.settling_bound`), no tumble, pitch limit kept to a margin,
steady-state depth error. :func:`draw_plant` draws random plants for a Monte Carlo.

Frames and units: world NED (depth ``z`` positive down) [m], body FRD, pitch ``theta``
positive nose up [rad], speeds [m/s], time [s]; currents are NED velocities of the water.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np

from auv_depth_lqr.closed_loop import ClosedLoopRun, run_closed_loop
from auv_depth_lqr.controller import DepthController
from auv_depth_lqr.errors import AuvLqrError, DesignError
from auv_depth_lqr.metrics import step_metrics
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_sim.environment import Environment
from auv_sim.errors import AuvSimError
from auv_sim.model import HYDRO_AXIS, HYDRO_TERMS, NX, hydro_basis, wrenches
from auv_sim.params import VehicleParams

DEG = math.pi / 180.0

#: Vertical-plane parameters of the model-error cases: hydrodynamic derivatives, plane
#: effectiveness, pitch inertia and the heave/pitch added masses.
MODEL_PARAMETERS = ('CZuw', 'CMuw', 'CZuq', 'CMuq', 'CZbar', 'CMbar', 'Iy', 'Mqdot', 'Zwdot')

#: The coefficients of :data:`MODEL_PARAMETERS` whose basis term (``surge x heave`` or
#: ``surge x pitch rate``, :func:`auv_sim.model.hydro_basis`) the added-mass Coriolis wrench
#: also has, with the state index of their second velocity (``w`` 8, ``q`` 10).
CORIOLIS_SHARED = {'CZuw': 8, 'CZuq': 10, 'CMuw': 8, 'CMuq': 10}


def coriolis_shift(design: VehicleParams, vehicle: VehicleParams, name: str) -> float:
    """How much more of coefficient ``name`` [-] an identification that reconstructs the
    hydrodynamic wrench with ``design``'s masses (``auv_ident.motion``) finds on ``vehicle``
    than it has: the Coriolis wrench of ``vehicle`` less that of ``design`` on ``name``'s
    axis, over ``name``'s basis term, both at 1 m/s surge and 1 m/s (or rad/s) of its second
    velocity (the terms are bilinear, so the ratio holds at any speed). With added masses
    that differ, this is Munk's moment ``(Xudot - Zwdot) u w`` on ``CMuw`` (Fossen 2011,
    eq. 6.43; -0.40 on the A18M for a heave added mass 25 % low) and ``Xudot u q`` on
    ``CZuq``; 0 for a coefficient outside :data:`CORIOLIS_SHARED`."""
    if name not in CORIOLIS_SHARED:
        return 0.0
    x = np.zeros(NX)
    x[6] = 1.0
    x[CORIOLIS_SHARED[name]] = 1.0
    term = HYDRO_TERMS.index(name)
    axis = int(HYDRO_AXIS[term])
    still = Environment()
    env, prof = still.env_vector(), still.profile()
    coriolis = []
    for params in (vehicle, design):
        out = np.zeros((4, 6))
        wrenches(0.0, x, params.as_array(), env, prof, out)
        coriolis.append(out[1, axis])
    basis = hydro_basis(x[6], x[7], x[8], x[9], x[10], x[11], design.as_array())[term]
    return float((coriolis[0] - coriolis[1]) / basis)


@dataclasses.dataclass(frozen=True)
class Plant:
    """A real vehicle that differs from the pilot's design model.

    ``factors`` scale vehicle-file parameters (``{'CMuq': 0.7}``: 30 % less pitch damping);
    ``effects`` are environment effects (:data:`auv_sim.environment.EFFECT_FIELDS`, SI
    units, radians); ``depth_noise`` [m] is the standard deviation of white noise on the
    measured depth, drawn with ``seed``; ``water_speed_told``: the pilot is told its surge
    speed through the water (``PilotSettings.water_speed``, as from its propeller setting)
    rather than scheduling on the measured surge over ground; ``base``: the plant's own
    vehicle file when it is not the design file (e.g. the true vehicle of an identified one).
    """

    name: str
    factors: Mapping[str, float] = dataclasses.field(default_factory=dict)
    effects: Mapping[str, Mapping[str, float]] = dataclasses.field(default_factory=dict)
    depth_noise: float = 0.0
    water_speed_told: bool = True
    seed: int = 0
    base: VehicleParams | None = None

    def vehicle(self, design: VehicleParams) -> VehicleParams:
        """The plant's vehicle parameters: its own file (``base``) or else ``design``, with
        the factors applied."""
        base = self.base or design
        try:
            return base.replace(**{k: base.values[k] * f for k, f in self.factors.items()})
        except (KeyError, AuvSimError) as exc:
            raise DesignError(f'plant {self.name}: bad parameter factor ({exc})') from None

    def environment(self) -> Environment:
        """The plant's water and effects."""
        return Environment(effects={k: dict(v) for k, v in self.effects.items()})


@dataclasses.dataclass(frozen=True)
class Manoeuvre:
    """A depth change ``z0 -> z1`` [m] commanded at t = 0 from a trim at ``u0`` [m/s]."""

    z0: float
    z1: float
    u0: float = 2.0


@dataclasses.dataclass(frozen=True)
class Criteria:
    """Pass criteria of a flight.

    ``settle_ratio``: settled (true depth within ``band`` [m] of the target to the end)
    within this multiple of the time-optimal bound; ``tumble`` [rad]: largest ``|theta|``
    allowed at all; ``pitch_excess`` [rad]: largest excursion past the pilot's pitch limit;
    ``steady_error`` [m]: largest ``|mean(z - z1)|`` over the last ``steady_window`` [s].
    """

    settle_ratio: float = 2.0
    band: float = 0.1
    tumble: float = 35.0 * DEG
    pitch_excess: float = 2.0 * DEG
    steady_error: float = 0.1
    steady_window: float = 10.0


class NoisyDepthPilot(DepthPilot):
    """A :class:`DepthPilot` whose depth measurement carries white noise (a pressure
    sensor's, which the simulator does not model) and which keeps the status of every command
    (to measure how long its envelope fallback flew). Everything else is the pilot's own
    logic. Set the noise with :meth:`set_depth_noise` (none by default)."""

    def __init__(self, controller: DepthController, depth_min: float, depth_max: float,
                 settings: PilotSettings) -> None:
        super().__init__(controller, depth_min, depth_max, settings)
        self.depth_noise = 0.0
        self._rng = np.random.default_rng(0)
        self.statuses: list[str] = []

    def set_depth_noise(self, sigma: float, seed: int) -> None:
        """White noise of standard deviation ``sigma`` [m] on the depth, drawn with ``seed``."""
        if not (math.isfinite(sigma) and sigma >= 0.0):
            raise DesignError(f'depth noise sigma = {sigma!r} m must be finite and >= 0')
        self.depth_noise = float(sigma)
        self._rng = np.random.default_rng(seed)

    def on_state(self, t: float, z: float, theta: float, w: float, q: float, u: float,
                 stamp: float | None = None) -> None:
        """Record a measured state, the depth [m] with the sensor's noise added."""
        if self.depth_noise:
            z = z + float(self._rng.standard_normal()) * self.depth_noise
        super().on_state(t, z, theta, w, q, u, stamp)

    def command(self, t: float) -> tuple[float, str]:
        """The pilot's BAR command [rad] and status at ``t`` [s]; the status is kept."""
        bar, status = super().command(t)
        self.statuses.append(status)
        return bar, status


@dataclasses.dataclass(frozen=True)
class Outcome:
    """Figures of one flight and the verdict of each criterion.

    ``settling_time`` [s] (nan: never settled), ``bound`` [s] the time-optimal bound it is
    compared with, ``peak_pitch`` [rad] the largest true ``|theta|``, ``pitch_excess`` [rad]
    that beyond the pilot's limit (0 when within), ``steady_error`` [m] the mean true depth
    error over the last window, ``recovery_time`` [s] the time the envelope fallback flew,
    ``error``: why the flight could not be flown (design failure, divergence), else '';
    ``authority`` the pilot's plane-authority level at the end of the flight and
    ``hold_share`` [-] the share of the plane's travel its hold took then
    (:class:`~auv_depth_lqr.authority.Authority`; nan without hold samples).
    """

    plant: str
    z0: float
    z1: float
    u0: float
    settling_time: float
    bound: float
    peak_pitch: float
    pitch_excess: float
    steady_error: float
    recovery_time: float
    checks: dict[str, bool]
    error: str = ''
    authority: str = ''
    hold_share: float = math.nan

    @property
    def ratio(self) -> float:
        """Settling time over the bound (nan when never settled)."""
        return self.settling_time / self.bound

    @property
    def passed(self) -> bool:
        """All criteria met."""
        return not self.error and all(self.checks.values())

    def as_dict(self) -> dict[str, object]:
        """JSON-ready figures (degrees for angles, None for not-a-number)."""
        def num(v: float, digits: int) -> float | None:
            return round(v, digits) if math.isfinite(v) else None
        return {'plant': self.plant, 'z0_m': self.z0, 'z1_m': self.z1, 'u0_m_s': self.u0,
                'settling_time_s': num(self.settling_time, 2), 'bound_s': num(self.bound, 2),
                'settling_over_bound': num(self.ratio, 3),
                'peak_pitch_deg': num(math.degrees(self.peak_pitch), 2),
                'pitch_excess_deg': num(math.degrees(self.pitch_excess), 2),
                'steady_error_m': num(self.steady_error, 4),
                'recovery_time_s': round(self.recovery_time, 1),
                'checks': dict(self.checks), 'pass': self.passed, 'error': self.error,
                'authority': self.authority, 'hold_share': num(self.hold_share, 3)}


def flight_duration(bound: float, criteria: Criteria) -> float:
    """Simulated time [s] of a flight: the settling allowance plus 1.5 steady windows and
    5 s, so that a run settled at the allowance still has a full steady window."""
    return criteria.settle_ratio * bound + 1.5 * criteria.steady_window + 5.0


def fly(design: VehicleParams, plant: Plant, manoeuvre: Manoeuvre, bound: float,
        settings: PilotSettings | None = None, criteria: Criteria | None = None
        ) -> tuple[Outcome, ClosedLoopRun | None]:
    """Design the pilot on ``design``, fly ``manoeuvre`` on ``plant``, judge the run.

    ``bound`` [s] is the time-optimal settling bound of the manoeuvre (of the design model,
    :func:`auv_depth_lqr.bound.settling_bound`). The vehicle starts in the plant's own trim
    at ``z0`` in the water it is in; the command is given at t = 0. Returns the outcome and
    the run (``None`` when it could not be flown: the outcome's ``error`` says why).
    """
    criteria = criteria or Criteria()
    base = settings or PilotSettings()
    settings = dataclasses.replace(
        base, water_speed=manoeuvre.u0 if plant.water_speed_told else None)
    duration = flight_duration(bound, criteria)
    try:
        truth = plant.vehicle(design)
        pilot = NoisyDepthPilot.for_vehicle(design, settings)
        assert isinstance(pilot, NoisyDepthPilot)
        pilot.set_depth_noise(plant.depth_noise, plant.seed)
        run = run_closed_loop(truth, [(0.0, manoeuvre.z1)], duration, z0=manoeuvre.z0,
                              u0=manoeuvre.u0, environment=plant.environment(),
                              settings=settings, pilot=pilot)
    except (AuvLqrError, AuvSimError) as exc:
        nan = math.nan
        return Outcome(plant.name, manoeuvre.z0, manoeuvre.z1, manoeuvre.u0, nan, bound, nan,
                       nan, nan, 0.0, {}, error=str(exc)), None
    recovery = pilot.statuses.count('recovery') * settings.Ts
    outcome = judge(plant.name, manoeuvre, run, bound, settings, criteria, recovery)
    authority = pilot.authority
    return dataclasses.replace(outcome, authority=authority.level,
                               hold_share=authority.share), run


def judge(name: str, manoeuvre: Manoeuvre, run: ClosedLoopRun, bound: float,
          settings: PilotSettings, criteria: Criteria, recovery_time: float = 0.0) -> Outcome:
    """Score a flight on the *true* state (not the measured one) against ``criteria``."""
    rec = run.record
    z, theta = rec.x[:, 2], rec.x[:, 4]
    m = step_metrics(rec.t, z, theta, rec.x[:, 10], rec.x[:, 12], manoeuvre.z1,
                     band=criteria.band, u0=manoeuvre.u0, theta_max=settings.theta_max)
    tail = rec.t >= rec.t[-1] - criteria.steady_window
    steady = abs(float(np.mean(z[tail] - manoeuvre.z1)))
    excess = max(0.0, m.peak_pitch - settings.theta_max)
    checks = {
        'settled': bool(math.isfinite(m.settling_time)
                        and m.settling_time <= criteria.settle_ratio * bound),
        'no_tumble': bool(m.peak_pitch < criteria.tumble),
        'pitch_limit': bool(excess <= criteria.pitch_excess),
        'steady_error': bool(steady < criteria.steady_error),
    }
    return Outcome(name, manoeuvre.z0, manoeuvre.z1, manoeuvre.u0, m.settling_time, bound,
                   m.peak_pitch, excess, steady, recovery_time, checks)


@dataclasses.dataclass(frozen=True)
class Distribution:
    """How :func:`draw_plant` draws a plant (uniform draws unless said).

    ``factor_spread``: each of :data:`MODEL_PARAMETERS` scaled by a factor uniform in
    ``[1 - s, 1 + s]``, independently; ``factor_spreads``: the spread of named parameters
    instead (e.g. the relative half-widths of an identification's intervals); ``current``
    [m/s] from a direction uniform in 0-360 deg (horizontal), the pilot told its water speed
    with probability ``told``; buoyancy offset uniform within ``+-buoyancy`` of the weight;
    plane delay uniform in ``[0, delay]`` [s]; plane lag time constant uniform between the
    file's and ``lag`` [s]; plane bias and pitch-sensor bias uniform within ``+-bar_bias``,
    ``+-pitch_bias`` [rad]; depth-sensor noise sigma uniform in ``[0, depth_noise]`` [m].

    ``apparent``: the coefficients ``factor_spreads`` names are an identification's, which
    reconstructs the hydrodynamic wrench with the design file's added masses: what it
    measures of a vehicle whose added masses differ is that vehicle's coefficient plus the
    Coriolis difference on the same basis term (:func:`coriolis_shift`: Munk's moment on
    ``CMuw``). A plant then takes the drawn value as the apparent one and its own
    coefficient is that less the shift of its drawn added masses, so that it would give the
    identification what the identification gave. Off, every factor scales the plant's own
    coefficient (a model error independent of any log).
    """

    factor_spread: float = 0.3
    factor_spreads: Mapping[str, float] = dataclasses.field(default_factory=dict)
    current: float = 0.3
    told: float = 0.5
    buoyancy: float = 0.01
    delay: float = 0.3
    lag: float = 0.5
    bar_bias: float = 1.0 * DEG
    pitch_bias: float = 0.5 * DEG
    depth_noise: float = 0.05
    apparent: bool = False

    def __post_init__(self) -> None:
        unknown = sorted(set(self.factor_spreads) - set(MODEL_PARAMETERS))
        if unknown:
            raise DesignError(f'Distribution.factor_spreads: unknown parameters {unknown}; '
                              f'known: {list(MODEL_PARAMETERS)}')
        for name, spread in {'factor_spread': self.factor_spread, **self.factor_spreads}.items():
            if isinstance(spread, bool) or not isinstance(spread, (int, float)) \
                    or not 0.0 <= spread < 1.0:
                raise DesignError(f'Distribution spread of {name} = {spread!r} must be in '
                                  f'[0, 1)')


def draw_plant(design: VehicleParams, rng: np.random.Generator, name: str,
               dist: Distribution | None = None) -> Plant:
    """One random plant around ``design`` with every error and effect at once (see
    :class:`Distribution`)."""
    d = dist or Distribution()
    spreads = {k: float(d.factor_spreads.get(k, d.factor_spread)) for k in MODEL_PARAMETERS}
    factors = {k: float(rng.uniform(1.0 - s, 1.0 + s)) for k, s in spreads.items()}
    if d.apparent:
        own = Plant(name, factors).vehicle(design)
        for k in sorted(set(d.factor_spreads) & set(CORIOLIS_SHARED)):
            factors[k] -= coriolis_shift(design, own, k) / float(design.values[k])
    heading = float(rng.uniform(0.0, 2.0 * math.pi))
    effects = {
        'current': {'north': d.current * math.cos(heading),
                    'east': d.current * math.sin(heading)},
        'buoyancy_offset': {'dB': float(rng.uniform(-d.buoyancy, d.buoyancy)) * design.W},
        'actuator_delay': {'bar': float(rng.uniform(0.0, d.delay))},
        'actuator_lag': {'bar_tau': float(rng.uniform(design.bar_tau,
                                                      max(d.lag, design.bar_tau)))},
        'bar_bias': {'bias': float(rng.uniform(-d.bar_bias, d.bar_bias))},
        'pitch_sensor_bias': {'bias': float(rng.uniform(-d.pitch_bias, d.pitch_bias))},
    }
    told = bool(rng.uniform() < d.told)
    noise = float(rng.uniform(0.0, d.depth_noise))
    seed = int(rng.integers(0, 2**31 - 1))
    return Plant(name, factors, effects, noise, told, seed)


def catalogue(design: VehicleParams, depth_noise: float = 0.05) -> dict[str, Plant]:
    """One plant per effect or model error, each alone at the size of a real vehicle's
    departure from its model: a 0.3 m/s current from ahead, behind, the side and 45 deg
    off the bow (the vehicle heads north), the pilot told its water speed and, from ahead and
    behind, not told; buoyancy +-1 % of the weight; a 0.3 s plane delay; a 0.5 s plane lag;
    a +-1 deg plane bias; a +-0.5 deg pitch-sensor bias; white depth-sensor noise of
    ``depth_noise`` [m]; each of :data:`MODEL_PARAMETERS` 30 % low and 30 % high."""
    plants = [Plant('nominal')]
    c, s = 0.3, 0.3 / math.sqrt(2.0)
    for label, cur in (('head', {'north': -c}), ('following', {'north': c}),
                       ('cross', {'east': c}), ('bow_45', {'north': -s, 'east': s})):
        plants.append(Plant(f'current_{label}_0.3_told', effects={'current': cur}))
        if label in ('head', 'following'):
            plants.append(Plant(f'current_{label}_0.3_not_told', effects={'current': cur},
                                water_speed_told=False))
    for sign, label in ((1.0, '+'), (-1.0, '-')):
        plants.append(Plant(f'buoyancy_{label}1pct',
                            effects={'buoyancy_offset': {'dB': sign * 0.01 * design.W}}))
    plants.append(Plant('plane_delay_0.3s', effects={'actuator_delay': {'bar': 0.3}}))
    plants.append(Plant('plane_lag_0.5s', effects={'actuator_lag': {'bar_tau': 0.5}}))
    for sign, label in ((1.0, '+'), (-1.0, '-')):
        plants.append(Plant(f'bar_bias_{label}1deg', effects={'bar_bias': {'bias': sign * DEG}}))
        plants.append(Plant(f'pitch_sensor_bias_{label}0.5deg',
                            effects={'pitch_sensor_bias': {'bias': sign * 0.5 * DEG}}))
    plants.append(Plant(f'depth_noise_{depth_noise:g}m', depth_noise=depth_noise, seed=7))
    for key in MODEL_PARAMETERS:
        for factor in (0.7, 1.3):
            plants.append(Plant(f'{key}_x{factor:g}', factors={key: factor}))
    return {p.name: p for p in plants}
