"""The catalogue of unmodelled effects: each a plug-in the diagnosis fits to a log.

An :class:`Effect` declares its name, its parameters (unit, bounds, the value that means
"absent", a typical size), how it changes the model, and how its signature scales with the
manoeuvres that can tell it from other effects. How it changes the model is expressed with
the primitives of :class:`Perturbation`, which the compiled free-run and equation-error
kernels (:mod:`auv_gap.kernel`) understand:

* ``current`` (3): a water current in NED [m/s], with ``shear`` (2, north and east change per
  metre of depth [1/s]) and ``drift`` (2, change per second from the start of the first log
  [m/s^2]): the model's own environment vector;
* ``C`` (NB x 6): an extra body-FRD wrench ``sum_j phi_j(x) C[j]`` [N, N m] over the basis
  functions of :data:`auv_gap.kernel.BASIS_NAMES` (gravity direction, depth times
  gravity direction, quadratic speeds, ...);
* ``factors``: factors on vehicle-file parameters (the mass matrix rebuilt with them);
* ``delay``, ``tau``, ``rate`` (3 each, channels bar, helm, thrust): the actuator model
  driven by the logged commands (transport delay [s], first-order lag [s], rate limit
  [rad/s or N/s]);
* ``bias``, ``scale``, ``latency`` (12 each): the sensors read ``scale x(t - latency) + bias``
  of the true state (eta, nu), SI units.

The same perturbation drives the equation error (the model's wrench at the logged states)
and the free run (the model integrated from a logged state), so an effect written once is
fitted both ways. A new effect is declared in the one registry of effects
(:func:`auv_sim.environment.declare_effect`: name, fields, units) and a subclass registered
with :func:`register`, which checks it against the declaration; nothing else changes. An
effect that needs a primitive the kernels lack is a change of the kernels, not of the
diagnosis.

The effects are declared once, in :data:`auv_sim.environment.EFFECT_FIELDS`; their
implementations here are separate from the simulator's (:mod:`auv_sim.environment`), which
makes the synthetic logs: a test that makes the data with one and explains it with the other
compares two implementations of one declared effect.
"""
from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

import numpy as np

from auv_gap.errors import GapError
from auv_gap.kernel import (
    B_G,
    B_QQ,
    B_RR,
    B_THRUST,
    B_UQ,
    B_UU,
    B_UUBAR,
    B_UW,
    B_VV,
    B_WW,
    B_XDRAG,
    B_ZG,
    NB,
)
from auv_gap.manoeuvres import MANOEUVRE_TEXT, Envelope, manoeuvre
from auv_sim.environment import EFFECT_FIELDS
from auv_sim.model import E_DRIFT, E_SHEAR, E_VC, ENV_SIZE
from auv_sim.params import VehicleParams


@dataclasses.dataclass(frozen=True)
class Parameter:
    """One parameter of an effect: name, unit, search bounds ``lo``/``hi``, the value meaning
    "absent", its typical size ``scale`` (the optimiser's unit and finite-difference scale),
    and two ranges in the same unit:

    * ``plausible``: the *typical* range of a well-ballasted, well-rigged vehicle, with its
      ``source`` (default: the search bounds). A fit beyond it is *atypical*: a finding to
      check (``check`` says what), never an unchecked explanation;
    * ``possible``: what physics allows at all (a delay or lag is positive, a drag
      dissipates, a coefficient keeps the hull's sign; default: the search bounds). A fit
      beyond it is *impossible*: never an explanation.

    The search bounds are wider than the typical range on purpose: a fit that runs past it
    is evidence, and the diagnosis says which (atypical: named with "check ..."; impossible:
    listed as no explanation). The ranges of :data:`auv_gap.ranges` (a user-editable
    file) replace the built-in ones.
    """

    name: str
    unit: str
    lo: float
    hi: float
    absent: float
    scale: float
    plausible: tuple[float, float] | None = None
    source: str = ''
    possible: tuple[float, float] | None = None
    check: str = ''

    @property
    def plausible_range(self) -> tuple[float, float]:
        """``(lo, hi)`` typical of a well-ballasted, well-rigged vehicle [unit]."""
        return self.plausible if self.plausible is not None else (self.lo, self.hi)

    @property
    def possible_range(self) -> tuple[float, float]:
        """``(lo, hi)`` physics allows at all [unit]."""
        return self.possible if self.possible is not None else (self.lo, self.hi)

    def is_plausible(self, value: float) -> bool:
        """True when ``value`` lies strictly inside the typical range, or exactly at an
        end that is the "absent" value (a sign bound: zero is no effect, not an excess)."""
        return _inside(value, self.plausible_range, self.absent)

    def is_possible(self, value: float) -> bool:
        """True when ``value`` lies inside the range physics allows (as
        :meth:`is_plausible`)."""
        return _inside(value, self.possible_range, self.absent)


def _inside(value: float, bounds: tuple[float, float], absent: float) -> bool:
    """``value`` strictly inside ``bounds``, or exactly at an end that is ``absent``."""
    lo, hi = bounds
    if lo < value < hi:
        return True
    return value == absent and value in (lo, hi)


@dataclasses.dataclass
class Perturbation:
    """What a set of effects changes in the model (see module docstring); SI units.

    ``current`` (3) NED [m/s], ``shear`` (2) its north and east change per metre of depth
    [1/s] (zero at the surface), ``drift`` (2) their change per second [m/s^2] from the start
    of the first log; ``C`` (NB x 6) extra-wrench coefficients; ``delay``, ``tau``, ``rate``
    (3: bar, helm, thrust) the actuator model; ``factors`` multiply vehicle-file parameters
    (the mass matrix is rebuilt with them); the sensors read ``scale * x(t - latency) +
    bias`` for each of the 12 states (``bias``, ``scale``, ``latency`` 12 each).
    """

    current: np.ndarray
    C: np.ndarray
    delay: np.ndarray
    tau: np.ndarray
    rate: np.ndarray
    bias: np.ndarray
    shear: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(2))
    drift: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(2))
    scale: np.ndarray = dataclasses.field(default_factory=lambda: np.ones(12))
    latency: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(12))
    factors: dict[str, float] = dataclasses.field(default_factory=dict)

    @classmethod
    def nominal(cls, vehicle: VehicleParams) -> Perturbation:
        """The vehicle as its file describes it: calm water, nominal actuators, exact sensors."""
        return cls(current=np.zeros(3), C=np.zeros((NB, 6)), delay=np.zeros(3),
                   tau=np.array([vehicle.bar_tau, vehicle.helm_tau, vehicle.thrust_tau]),
                   rate=np.array([vehicle.bar_rate, vehicle.helm_rate, math.inf]),
                   bias=np.zeros(12))

    def env_vector(self) -> np.ndarray:
        """The water of this perturbation as the model's environment vector
        (:mod:`auv_sim.model`: constant current, shear, drift)."""
        env = np.zeros(ENV_SIZE)
        env[E_VC:E_VC + 3] = self.current
        env[E_SHEAR:E_SHEAR + 2] = self.shear
        env[E_DRIFT:E_DRIFT + 2] = self.drift
        return env

    def params_key(self) -> tuple[tuple[str, float], ...]:
        """The parameter factors as a hashable key."""
        return tuple(sorted(self.factors.items()))

    @property
    def sensors_exact(self) -> bool:
        """No sensor scale or latency (a bias alone is applied by subtraction)."""
        return bool(np.all(self.scale == 1.0) and np.all(self.latency == 0.0))


class Effect:
    """An unmodelled effect (plug-in). Subclasses set the class attributes and implement
    :meth:`parameters` and :meth:`apply`.

    ``signature`` maps manoeuvres of :data:`auv_gap.manoeuvres.MANOEUVRES` to how the
    effect's contribution to the vertical-plane gap scales with them (an exponent: -1 for 1/u
    with speed, 1 for proportional, 0 for insensitive); two effects are told apart best by
    the manoeuvre where their exponents differ most.
    """

    name: ClassVar[str] = ''
    description: ClassVar[str] = ''
    #: Effects of which this one is a special case (the same change of the model with fewer
    #: parameters): a tie between them is not an ambiguity.
    within: ClassVar[tuple[str, ...]] = ()
    equations: ClassVar[tuple[str, ...]] = ()
    signature: ClassVar[dict[str, float]] = {}
    #: the manoeuvre (a key of :data:`auv_gap.manoeuvres.MANOEUVRE_TEXT`) that identifies
    #: this effect best (default: its signature's largest exponent)
    identify_by: ClassVar[str] = ''

    def advice(self, envelope: Envelope | None = None) -> str:
        """What to fly to identify this effect, in the terms of ``envelope``."""
        key = self.identify_by or (max(self.signature, key=lambda k: abs(self.signature[k]))
                                   if self.signature else '')
        if not key:
            return 'a manoeuvre that excites it'
        return manoeuvre(key, envelope)

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        """The parameters, with bounds and sizes for this vehicle."""
        raise NotImplementedError

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        """Add the effect with parameter ``values`` (in :meth:`parameters` order) to ``pert``."""
        raise NotImplementedError


CATALOGUE: dict[str, Effect] = {}


def register(effect: Effect) -> Effect:
    """Add an effect to the catalogue (its name must be new)."""
    if not effect.name or effect.name in CATALOGUE:
        raise GapError(f'effect name {effect.name!r} is empty or registered already')
    unknown = (set(effect.signature) | ({effect.identify_by} - {''})) - set(MANOEUVRE_TEXT)
    if unknown:
        raise GapError(f'effect {effect.name}: unknown manoeuvre(s) {sorted(unknown)}')
    check_declared(effect)
    CATALOGUE[effect.name] = effect
    return effect


def check_declared(effect: Effect, vehicle: VehicleParams | None = None) -> None:
    """GapError unless ``effect`` is declared in the one registry of effects
    (:data:`auv_sim.environment.EFFECT_FIELDS`) and, given the ``vehicle`` its parameters
    are sized for, each of its parameters is a declared field with the declared unit."""
    fields = EFFECT_FIELDS.get(effect.name)
    if fields is None:
        raise GapError(f'effect {effect.name!r} is not declared in the effect registry '
                       '(auv_sim.environment.EFFECT_FIELDS; declare_effect adds one)')
    if vehicle is None:
        return
    for prm in effect.parameters(vehicle):
        spec = fields.get(prm.name)
        if spec is None:
            raise GapError(f'effect {effect.name}: parameter {prm.name!r} is not a declared '
                           f'field (fields: {", ".join(fields)})')
        if spec[0] != prm.unit:
            raise GapError(f'effect {effect.name}: parameter {prm.name} in {prm.unit!r}, '
                           f'declared in {spec[0]!r}')


def get_effect(name: str) -> Effect:
    """The registered effect ``name``; GapError naming the known ones otherwise."""
    try:
        return CATALOGUE[name]
    except KeyError:
        raise GapError(f'unknown effect {name!r} (known: {", ".join(CATALOGUE)})') from None


def separating_manoeuvre(a: str, b: str, envelope: Envelope | None = None) -> str:
    """The manoeuvre that best tells effect ``a`` from effect ``b`` (text for the user, in
    the terms of the vehicle's ``envelope``)."""
    sa, sb = get_effect(a).signature, get_effect(b).signature
    best, gap = 'speed change', -1.0
    for key in MANOEUVRE_TEXT:
        d = abs(sa.get(key, 0.0) - sb.get(key, 0.0))
        if d > gap + 1e-12:
            best, gap = key, d
    return f'{best}: {manoeuvre(best, envelope)}'


#: Sources of the plausible ranges (the table of docs/gap-diagnosis.md repeats them).
SRC_CURRENT = ('horizontal currents: tidal streams in coastal straits reach 2-3 m/s; an AUV '
               'cannot make way against more than its own speed (~2.5 m/s)')
SRC_UPWELLING = ('vertical currents (internal waves, convection, upwelling) are mm/s to '
                 'cm/s, rarely 0.1 m/s (Thorpe 2005, The Turbulent Ocean)')
SRC_BALLAST = ('trim ballasting leaves |dB| within a few per mille of the weight; 2 % of it is '
               'a badly trimmed vehicle, 5 % (flooding, lost ballast) the most a flying '
               'vehicle survives (assumed)')
SRC_COMPRESS = ('sea water compressibility 4.4e-10 1/Pa (4.4e-6 1/m, UNESCO EOS-80); hulls and '
                'syntactic foam compress by the same order: |k| <= 1e-4 1/m (1 % per 100 m)')
SRC_DELAY = ('bus, servo-controller and sample-and-hold latencies: tens to hundreds of ms; '
             'a delay is positive, 1.5 s bounds a broken link (assumed)')
SRC_LAG = ('fin servos have time constants 0.05-0.5 s (bandwidth 0.3-3 Hz); a lag is '
           'positive; 2 s bounds a failing servo (assumed)')
SRC_RATE = ('fin servos move 5-60 deg/s (0.09-1 rad/s); 0.01 rad/s (0.6 deg/s) bounds a '
            'failing one (assumed)')
SRC_BAR_BIAS = 'fin zeroing and mounting errors are a few degrees: |bias| <= 0.1 rad (assumed)'
SRC_CROSSFLOW = ('hull as a cylinder in cross-flow: Zww = -1/2 rho Cd D L, Mqq = -1/2 rho Cd '
                 'D L^4 / 32 (and Yvv, Nrr alike); Cd of a circular cylinder 0.6-1.2 '
                 '(Hoerner 1965, Fluid-Dynamic Drag), Prestero 2001 uses 1.1 for '
                 'REMUS; dissipative sign; plausible up to Cd = 1.2')
SRC_CG = ('ballasting places the centre of gravity to within 2 % of the length along the '
          'hull and 10 % of the diameter vertically (assumed)')
SRC_DEPTH_BIAS = ('atmospheric pressure (+-0.1 bar ~ 1 m) and density errors: |bias| <= 2 m '
                  '(assumed)')
SRC_PITCH_BIAS = 'AHRS mounting errors are a degree or two: |bias| <= 0.05 rad (assumed)'
SRC_COEF = ('semi-empirical derivatives (slender-body theory, DATCOM) are commonly off by '
            'tens of per cent, at worst a factor 2-3, against captive-model or flight data; '
            'the sign is fixed by the hull: factor 0.25-4 (assumed)')
SRC_PLANE = ('fouling, damage and hull interference lower a fin\'s lift; a lift-slope '
             'estimate may be low by a third: gain 0.3-1.5 (assumed)')
SRC_THRUST = ('propeller thrust against the command: wear, fouling, a mis-set thrust map; '
              'gain 0.7-1.3 (assumed)')

SRC_SHEAR = ('vertical shear of horizontal currents: 1e-3 to 1e-2 1/s in thermoclines and '
             'tidal bottom layers; a sheared flow stays stable while N^2/S^2 > 1/4 (Miles '
             '1961, Howard 1961), so S < 2N, and N reaches 0.02-0.03 1/s in strong '
             'thermoclines (Thorpe 2005): |S| <= 0.05 1/s')
SRC_DRIFT = ('a tidal stream changes at most by its amplitude times the tide\'s angular '
             'frequency: 2.5 m/s x 2 pi / 12.42 h = 3.5e-4 m/s^2 for the M2 tide: '
             '|dv/dt| <= 4e-4 m/s^2')
SRC_ADDED_MASS = ('slender-body and strip-theory added masses of torpedo hulls agree with '
                  'measurements to 10-30 % (Prestero 2001; Fossen 2011, ch. 6): factor '
                  '0.5-2 (assumed)')
SRC_DEPTH_SCALE = ('pressure to depth: sea-water density 1020-1030 kg/m^3 against the one '
                   'assumed (+-0.5 %), a fresh-water setting in the sea (2.5 %), transducer '
                   'gain 0.1-0.5 % of full scale: scale 0.95-1.05')
SRC_DEPTH_LATENCY = ('pressure sensors are low-pass filtered and polled: latencies of tens to '
                     'hundreds of ms; 1 s bounds a slow filter (assumed)')
SRC_PITCH_SCALE = ('attitude scale errors of a mis-calibrated AHRS are a few per cent: '
                   'scale 0.9-1.1 (assumed)')
SRC_PITCH_LATENCY = ('AHRS filter and bus latencies: 10-100 ms; 0.5 s bounds a slow filter '
                     '(assumed)')

#: The largest cross-flow drag coefficient of the hull that is physically plausible.
CROSSFLOW_CD_MAX = 1.2


def crossflow_unit(vehicle: VehicleParams) -> tuple[float, float]:
    """Magnitudes of Zww [kg/m] and Mqq [kg m^2] for a cross-flow drag coefficient of 1 on
    the hull taken as a cylinder of the vehicle's diameter and length."""
    length, diam = vehicle.L_ref, vehicle.diameter
    zww = 0.5 * vehicle.rho * diam * length
    return zww, zww * length ** 3 / 32.0


def _dynamic_pressure_area(vehicle: VehicleParams) -> float:
    """``1/2 rho S_ref`` [kg/m]."""
    qs: float = 0.5 * vehicle.rho * vehicle.S_ref
    return qs


def _add_force_at(pert: Perturbation, row: int, coef: float, r: tuple[float, float, float]
                  ) -> None:
    """Add a force ``coef * phi_{row..row+2}`` (a vector along the gravity basis) applied at
    body point ``r`` [m]: force rows and the moment ``r x F``."""
    rx, ry, rz = r
    for k in range(3):
        pert.C[row + k, k] += coef
    # moment r x F with F = coef (gx, gy, gz)
    pert.C[row + 2, 3] += coef * ry
    pert.C[row + 1, 3] -= coef * rz
    pert.C[row + 0, 4] += coef * rz
    pert.C[row + 2, 4] -= coef * rx
    pert.C[row + 1, 5] += coef * rx
    pert.C[row + 0, 5] -= coef * ry


class Current(Effect):
    name = 'current'
    description = ('constant water current (NED north, east, down): the vehicle moves through '
                   'the water at nu - R^T v_c while the logged velocities are over ground')
    equations = ('surge', 'heave', 'pitch', 'sway', 'yaw')
    signature = {'speed change': 0.0, 'heading change': 1.0}
    identify_by = 'heading change'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('north', 'm/s', -5.0, 5.0, 0.0, 0.1, (-2.5, 2.5), SRC_CURRENT),
                Parameter('east', 'm/s', -5.0, 5.0, 0.0, 0.1, (-2.5, 2.5), SRC_CURRENT),
                Parameter('down', 'm/s', -0.5, 0.5, 0.0, 0.01, (-0.2, 0.2), SRC_UPWELLING))

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.current += values[:3]


class BuoyancyOffset(Effect):
    name = 'buoyancy_offset'
    description = 'buoyancy differs from the file by dB (N, positive: more buoyant)'
    equations = ('heave', 'surge')
    signature = {'speed change': -1.0, 'thruster-off coast': 1.0}
    identify_by = 'thruster-off coast'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        w = vehicle.W
        return (Parameter('dB', 'N', -0.15 * w, 0.15 * w, 0.0, 0.002 * w,
                          (-0.02 * w, 0.02 * w), SRC_BALLAST),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        # extra buoyancy acts upward (-gravity direction) at the centre of buoyancy
        _add_force_at(pert, B_G, -values[0], (vehicle.xb, vehicle.yb, vehicle.zb))


class BuoyancyDepth(Effect):
    name = 'buoyancy_depth'
    description = 'buoyancy changes with depth: B(z) = B (1 + k z), k in 1/m (hull compression)'
    equations = ('heave',)
    signature = {'speed change': -1.0, 'depth excursion': 1.0}
    identify_by = 'depth excursion'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('k', '1/m', -1e-3, 1e-3, 0.0, 1e-5, (-1e-4, 1e-4), SRC_COMPRESS),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        _add_force_at(pert, B_ZG, -vehicle.B * values[0], (vehicle.xb, vehicle.yb, vehicle.zb))


class ActuatorDelay(Effect):
    name = 'actuator_delay'
    description = 'transport delay between the logged BAR command and the plane'
    equations = ('heave', 'pitch')
    signature = {'speed change': 2.0, 'plane doublets of several periods': 1.0}
    identify_by = 'short plane doublets'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('bar', 's', 0.0, 3.0, 0.0, 0.1, (0.0, 1.5), SRC_DELAY),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.delay[0] += values[0]


class ActuatorLag(Effect):
    name = 'actuator_lag'
    description = 'the plane follows its command with a first-order lag bar_tau (s)'
    equations = ('heave', 'pitch')
    signature = {'speed change': 2.0, 'plane doublets of several periods': 0.5}
    identify_by = 'plane doublets of several periods'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('bar_tau', 's', vehicle.dt, 10.0, vehicle.bar_tau, 0.2, (0.0, 2.0),
                          SRC_LAG),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.tau[0] = values[0]


class ActuatorRateLimit(Effect):
    name = 'actuator_rate_limit'
    description = 'the plane moves at most bar_rate (rad/s)'
    equations = ('heave', 'pitch')
    signature = {'speed change': 2.0, 'plane steps of several sizes': 1.0,
                 'plane doublets of several periods': 0.5}
    identify_by = 'large fast plane steps'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('bar_rate', 'rad/s', 0.002, max(2.0, vehicle.bar_rate),
                          vehicle.bar_rate, 0.02, (0.01, max(1.5, vehicle.bar_rate)),
                          SRC_RATE),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.rate[0] = values[0]


class BarBias(Effect):
    name = 'bar_bias'
    #: a plane bias adds CZbar bias and CMbar bias to the zero-lift CZ0 and CM0
    within = ('coefficients',)
    description = 'the plane sits at its logged angle plus a bias (rad): force ~ u^2'
    equations = ('heave', 'pitch')
    signature = {'speed change': 2.0}
    identify_by = 'speed change'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('bias', 'rad', -0.35, 0.35, 0.0, 0.005, (-0.1, 0.1), SRC_BAR_BIAS),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        qs = _dynamic_pressure_area(vehicle)
        pert.C[B_UU, 2] += qs * vehicle.CZbar * values[0]
        pert.C[B_UU, 4] += qs * vehicle.L_ref * vehicle.CMbar * values[0]


class CrossflowDrag(Effect):
    name = 'crossflow_drag'
    description = ('quadratic cross-flow drag the model lacks: Zww w|w|, Mqq q|q|, Yvv v|v|, '
                   'Nrr r|r| (w, v through the water)')
    equations = ('heave', 'pitch', 'sway', 'yaw')
    signature = {'plane steps of several sizes': 1.0}
    identify_by = 'plane steps of several sizes'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        zww, mqq = crossflow_unit(vehicle)
        cd = CROSSFLOW_CD_MAX
        # a drag dissipates: a positive coefficient (anti-damping) is impossible
        return (Parameter('Zww', 'kg/m', -20 * zww, 5 * zww, 0.0, zww, (-cd * zww, 0.0),
                          SRC_CROSSFLOW, (-20 * zww, 0.0)),
                Parameter('Mqq', 'kg m^2', -20 * mqq, 5 * mqq, 0.0, mqq, (-cd * mqq, 0.0),
                          SRC_CROSSFLOW, (-20 * mqq, 0.0)),
                Parameter('Yvv', 'kg/m', -20 * zww, 5 * zww, 0.0, zww, (-cd * zww, 0.0),
                          SRC_CROSSFLOW, (-20 * zww, 0.0)),
                Parameter('Nrr', 'kg m^2', -20 * mqq, 5 * mqq, 0.0, mqq, (-cd * mqq, 0.0),
                          SRC_CROSSFLOW, (-20 * mqq, 0.0)))

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.C[B_WW, 2] += values[0]
        pert.C[B_QQ, 4] += values[1]
        pert.C[B_VV, 1] += values[2]
        pert.C[B_RR, 5] += values[3]


class CgOffset(Effect):
    name = 'cg_offset'
    description = ('centre of gravity displaced by (dxg, dzg) [m] from the file (restoring '
                   'moment only; the mass matrix change is second order)')
    equations = ('pitch', 'roll')
    signature = {'speed change': -2.0, 'thruster-off coast': 1.0}
    identify_by = 'thruster-off coast'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        lim = 0.05 * vehicle.L_ref
        px, pz = 0.02 * vehicle.L_ref, 0.1 * vehicle.diameter
        return (Parameter('dxg', 'm', -lim, lim, 0.0, 0.002, (-px, px), SRC_CG),
                Parameter('dzg', 'm', -lim, lim, 0.0, 0.002, (-pz, pz), SRC_CG))

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        w = vehicle.W
        dxg, dzg = values[0], values[1]
        # weight W (gx, gy, gz) at the displaced point: moment d x F, force unchanged
        pert.C[B_G + 1, 3] -= w * dzg
        pert.C[B_G + 0, 4] += w * dzg
        pert.C[B_G + 2, 4] -= w * dxg
        pert.C[B_G + 1, 5] += w * dxg


class DepthSensorBias(Effect):
    name = 'depth_sensor_bias'
    description = 'the depth sensor reads the true depth plus a bias (m)'
    equations = ()
    signature = {'surface reference': 1.0, 'depth excursion': 0.5}
    identify_by = 'surface reference'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('bias', 'm', -10.0, 10.0, 0.0, 0.1, (-2.0, 2.0), SRC_DEPTH_BIAS),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.bias[2] += values[0]


class PitchSensorBias(Effect):
    name = 'pitch_sensor_bias'
    description = 'the pitch sensor reads the true pitch plus a bias (rad)'
    equations = ('depth kinematics', 'pitch')
    signature = {'speed change': 1.0}
    identify_by = 'speed change'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('bias', 'rad', -0.2, 0.2, 0.0, 0.005, (-0.05, 0.05),
                          SRC_PITCH_BIAS),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.bias[4] += values[0]


#: The coefficients of the vertical plane and of surge that ``auv ident`` fits, as (name,
#: basis row, body row, power of L_ref in the wrench; None: the basis holds the whole term per
#: unit coefficient): ``Z = qs (CZ0 ur|ur| + CZuw ur wr + CZuq L ur q + CZbar ur|ur| bar)``,
#: ``M = qs L (CM0 ur|ur| + CMuw ur wr + CMuq L ur q + CMbar ur|ur| bar)``,
#: ``X = -Ksh qs C_XF(Re) ur|ur|``. CZ0 and CM0 (the zero-lift force and moment) are fitted by
#: ``auv ident --fit-c0``.
COEFFICIENTS = (('CZuw', B_UW, 2, 0), ('CMuw', B_UW, 4, 1), ('CZuq', B_UQ, 2, 1),
                ('CMuq', B_UQ, 4, 2), ('CZbar', B_UUBAR, 2, 0), ('CMbar', B_UUBAR, 4, 1),
                ('Ksh', B_XDRAG, 0, None), ('CZ0', B_UU, 2, 0), ('CM0', B_UU, 4, 1))


class Coefficients(Effect):
    name = 'coefficients'
    description = ("the model's own coefficients are off: each of CZuw, CMuw, CZuq, CMuq, "
                   'CZbar, CMbar, Ksh, CZ0 and CM0 is re-fitted as a factor on its file value')
    equations = ('heave', 'pitch', 'surge')
    signature = {'speed change': 1.0, 'plane doublets of several periods': 1.0,
                 'plane steps of several sizes': 0.0}
    identify_by = 'plane doublets of several periods'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        # a factor of zero or below turns the hull's coefficient off or its sign over
        return tuple(Parameter(n, 'x file value', -1.0, 6.0, 1.0, 0.05, (0.25, 4.0), SRC_COEF,
                               (0.0, 6.0))
                     for n, _, _, _ in COEFFICIENTS)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        qs = _dynamic_pressure_area(vehicle)
        for k, (n, row, col, power) in enumerate(COEFFICIENTS):
            unit = 1.0 if power is None else qs * vehicle.L_ref ** power
            pert.C[row, col] += (values[k] - 1.0) * unit * float(getattr(vehicle, n))


class PlaneEffectiveness(Effect):
    name = 'plane_effectiveness'
    within = ('coefficients',)
    description = ("the dive plane's lift and moment are a gain times the file's "
                   '(CZbar, CMbar scaled together)')
    equations = ('heave', 'pitch')
    signature = {'plane steps of several sizes': 1.0, 'speed change': 2.0,
                 'plane doublets of several periods': 1.0}
    identify_by = 'plane steps of several sizes'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('gain', '-', 0.0, 2.5, 1.0, 0.05, (0.3, 1.5), SRC_PLANE, (0.0, 2.5)),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        qs = _dynamic_pressure_area(vehicle)
        pert.C[B_UUBAR, 2] += (values[0] - 1.0) * qs * vehicle.CZbar
        pert.C[B_UUBAR, 4] += (values[0] - 1.0) * qs * vehicle.L_ref * vehicle.CMbar


class ThrustError(Effect):
    name = 'thrust_error'
    description = 'the propeller gives a gain times the commanded thrust'
    equations = ('surge',)
    signature = {'speed change': 1.0}
    identify_by = 'speed change'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('gain', '-', 0.2, 2.5, 1.0, 0.02, (0.7, 1.3), SRC_THRUST),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.C[B_THRUST, 0] += values[0] - 1.0


class CurrentShear(Effect):
    name = 'current_shear'
    description = ('a current that changes linearly with depth: north and east components '
                   'grow by S [1/s] per metre of depth (zero at the surface; with `current`, '
                   'v = v0 + S z)')
    equations = ('surge', 'heave', 'pitch', 'sway', 'yaw')
    signature = {'depth excursion': 1.0, 'heading change': 1.0, 'speed change': 0.0}
    identify_by = 'depth excursion'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('north', '1/s', -0.1, 0.1, 0.0, 1e-3, (-0.05, 0.05), SRC_SHEAR),
                Parameter('east', '1/s', -0.1, 0.1, 0.0, 1e-3, (-0.05, 0.05), SRC_SHEAR))

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.shear += values[:2]


class CurrentDrift(Effect):
    name = 'current_drift'
    description = ('a current that drifts linearly in time over the mission (a tide): north '
                   'and east components change by D [m/s^2], zero at the start of the first '
                   'log (with `current`, v = v0 + D t)')
    equations = ('surge', 'heave', 'pitch', 'sway', 'yaw')
    signature = {'repeated leg': 1.0, 'heading change': 1.0, 'speed change': 0.0}
    identify_by = 'repeated leg'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('north', 'm/s^2', -2e-3, 2e-3, 0.0, 1e-5, (-4e-4, 4e-4), SRC_DRIFT),
                Parameter('east', 'm/s^2', -2e-3, 2e-3, 0.0, 1e-5, (-4e-4, 4e-4), SRC_DRIFT))

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.drift += values[:2]


class AddedMass(Effect):
    name = 'added_mass'
    description = ("the heave and pitch added masses are a factor times the file's (Zwdot, "
                   'Mqdot): inertia and the added-mass Coriolis (Munk) terms change together')
    equations = ('heave', 'pitch')
    signature = {'plane doublets of several periods': 2.0, 'speed change': 1.0,
                 'plane steps of several sizes': 0.0}
    identify_by = 'plane doublets of several periods'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('Zwdot', 'x file value', 0.2, 4.0, 1.0, 0.05, (0.5, 2.0),
                          SRC_ADDED_MASS, (0.2, 4.0)),
                Parameter('Mqdot', 'x file value', 0.2, 4.0, 1.0, 0.05, (0.5, 2.0),
                          SRC_ADDED_MASS, (0.2, 4.0)))

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        for key, value in zip(('Zwdot', 'Mqdot'), values):
            if value != 1.0:
                pert.factors[key] = pert.factors.get(key, 1.0) * float(value)


class DepthSensorScale(Effect):
    name = 'depth_sensor_scale'
    description = 'the depth sensor reads a scale times the true depth'
    equations = ('depth kinematics',)
    signature = {'depth excursion': 1.0, 'surface reference': 1.0}
    identify_by = 'depth excursion'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('scale', '-', 0.8, 1.25, 1.0, 0.002, (0.95, 1.05), SRC_DEPTH_SCALE),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.scale[2] *= values[0]


class DepthSensorLatency(Effect):
    name = 'depth_sensor_latency'
    description = 'the depth sensor reads the depth of a latency (s) ago'
    equations = ('depth kinematics',)
    signature = {'plane doublets of several periods': 1.0, 'depth excursion': 0.0}
    identify_by = 'short plane doublets'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('latency', 's', 0.0, 3.0, 0.0, 0.05, (0.0, 1.0), SRC_DEPTH_LATENCY),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.latency[2] += values[0]


class PitchSensorScale(Effect):
    name = 'pitch_sensor_scale'
    description = 'the attitude sensor reads a scale times the true pitch'
    equations = ('depth kinematics', 'pitch')
    signature = {'plane steps of several sizes': 1.0, 'depth excursion': 1.0}
    identify_by = 'plane steps of several sizes'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('scale', '-', 0.5, 1.5, 1.0, 0.01, (0.9, 1.1), SRC_PITCH_SCALE),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.scale[4] *= values[0]


class PitchSensorLatency(Effect):
    name = 'pitch_sensor_latency'
    description = 'the attitude sensor reads the pitch of a latency (s) ago'
    equations = ('depth kinematics', 'pitch')
    signature = {'plane doublets of several periods': 1.0, 'plane steps of several sizes': 0.0}
    identify_by = 'short plane doublets'

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('latency', 's', 0.0, 2.0, 0.0, 0.02, (0.0, 0.5), SRC_PITCH_LATENCY),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.latency[4] += values[0]


for _effect in (Current(), CurrentShear(), CurrentDrift(), BuoyancyOffset(), BuoyancyDepth(),
                ActuatorDelay(), ActuatorLag(), ActuatorRateLimit(), BarBias(), CrossflowDrag(),
                CgOffset(), AddedMass(), DepthSensorBias(), DepthSensorScale(),
                DepthSensorLatency(), PitchSensorBias(), PitchSensorScale(),
                PitchSensorLatency(), Coefficients(), PlaneEffectiveness(), ThrustError()):
    register(_effect)
