"""The catalogue of unmodelled effects: each a plug-in the diagnosis fits to a log.

An :class:`Effect` declares its name, its parameters (unit, bounds, the value that means
"absent", a typical size), how it changes the model, and how its signature scales with the
manoeuvres that can tell it from other effects. How it changes the model is expressed with
the primitives of :class:`Perturbation`, which the compiled free-run and equation-error
kernels (:mod:`auv_ident.gap.kernel`) understand:

* ``current`` (3): a constant water current in NED [m/s];
* ``C`` (NB x 6): an extra body-FRD wrench ``sum_j phi_j(x) C[j]`` [N, N m] over the basis
  functions of :data:`auv_ident.gap.kernel.BASIS_NAMES` (gravity direction, depth times
  gravity direction, quadratic speeds, ...);
* ``delay``, ``tau``, ``rate`` (3 each, channels bar, helm, thrust): the actuator model
  driven by the logged commands (transport delay [s], first-order lag [s], rate limit
  [rad/s or N/s]);
* ``bias`` (12): what the sensors add to the true state (eta, nu), SI units.

The same perturbation drives the equation error (the model's wrench at the logged states)
and the free run (the model integrated from a logged state), so an effect written once is
fitted both ways. A new effect is a subclass registered with :func:`register`; nothing else
changes. An effect that needs a primitive the kernels lack (a wrench that varies in time,
say) is a change of the kernels, not of the diagnosis.

These implementations are separate from the simulator's effect code
(:mod:`auv_sim.environment`), which makes the synthetic logs: a test that makes the data
with one and explains it with the other checks both.
"""
from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

import numpy as np

from auv_ident.errors import GapError
from auv_ident.gap.kernel import B_G, B_QQ, B_RR, B_UU, B_VV, B_WW, B_ZG, NB
from auv_sim.params import VehicleParams

#: Manoeuvres that separate effects, with what a user should fly. An effect's signature gives,
#: per manoeuvre, the exponent with which its depth/pitch signature scales (see Effect).
MANOEUVRES: dict[str, str] = {
    'speed change': 'a speed change at constant plane angle (e.g. thrust steps giving '
                    '1.5 -> 2.5 m/s), holding each speed for a minute or more',
    'depth excursion': 'a depth excursion of several tens of metres (dive and climb at '
                       'constant speed), holding each depth for a minute',
    'heading change': 'a heading change of 90 to 180 deg at constant depth and speed',
    'plane steps of several sizes': 'BAR steps of several sizes (2 to 15 deg) at one speed',
    'plane doublets of several periods': 'BAR doublets of several periods (2 to 20 s) at '
                                         'one speed',
    'surface reference': 'a pass at the surface or a fix against a known depth (the '
                         'dynamics alone cannot see a constant depth offset)',
}


@dataclasses.dataclass(frozen=True)
class Parameter:
    """One parameter of an effect: name, unit, bounds, the value meaning "absent", and its
    typical size ``scale`` (the optimiser's unit and finite-difference scale)."""

    name: str
    unit: str
    lo: float
    hi: float
    absent: float
    scale: float


@dataclasses.dataclass
class Perturbation:
    """What a set of effects changes in the model (see module docstring); SI units."""

    current: np.ndarray
    C: np.ndarray
    delay: np.ndarray
    tau: np.ndarray
    rate: np.ndarray
    bias: np.ndarray

    @classmethod
    def nominal(cls, vehicle: VehicleParams) -> Perturbation:
        """The vehicle as its file describes it: calm water, nominal actuators, exact sensors."""
        return cls(current=np.zeros(3), C=np.zeros((NB, 6)), delay=np.zeros(3),
                   tau=np.array([vehicle.bar_tau, vehicle.helm_tau, vehicle.thrust_tau]),
                   rate=np.array([vehicle.bar_rate, vehicle.helm_rate, math.inf]),
                   bias=np.zeros(12))


class Effect:
    """An unmodelled effect (plug-in). Subclasses set the class attributes and implement
    :meth:`parameters` and :meth:`apply`.

    ``signature`` maps manoeuvres of :data:`MANOEUVRES` to how the effect's contribution to
    the vertical-plane gap scales with them (an exponent: -1 for 1/u with speed, 1 for
    proportional, 0 for insensitive); two effects are told apart best by the manoeuvre where
    their exponents differ most.
    """

    name: ClassVar[str] = ''
    description: ClassVar[str] = ''
    equations: ClassVar[tuple[str, ...]] = ()
    signature: ClassVar[dict[str, float]] = {}

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
    unknown = set(effect.signature) - set(MANOEUVRES)
    if unknown:
        raise GapError(f'effect {effect.name}: unknown manoeuvre(s) {sorted(unknown)}')
    CATALOGUE[effect.name] = effect
    return effect


def get_effect(name: str) -> Effect:
    """The registered effect ``name``; GapError naming the known ones otherwise."""
    try:
        return CATALOGUE[name]
    except KeyError:
        raise GapError(f'unknown effect {name!r} (known: {", ".join(CATALOGUE)})') from None


def separating_manoeuvre(a: str, b: str) -> str:
    """The manoeuvre that best tells effect ``a`` from effect ``b`` (text for the user)."""
    sa, sb = get_effect(a).signature, get_effect(b).signature
    best, gap = 'speed change', -1.0
    for key in MANOEUVRES:
        d = abs(sa.get(key, 0.0) - sb.get(key, 0.0))
        if d > gap + 1e-12:
            best, gap = key, d
    return f'{best}: {MANOEUVRES[best]}'


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

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('north', 'm/s', -2.5, 2.5, 0.0, 0.1),
                Parameter('east', 'm/s', -2.5, 2.5, 0.0, 0.1),
                Parameter('down', 'm/s', -0.5, 0.5, 0.0, 0.01))

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.current += values[:3]


class BuoyancyOffset(Effect):
    name = 'buoyancy_offset'
    description = 'buoyancy differs from the file by dB (N, positive: more buoyant)'
    equations = ('heave', 'surge')
    signature = {'speed change': -1.0}

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        w = vehicle.W
        return (Parameter('dB', 'N', -0.05 * w, 0.05 * w, 0.0, 0.002 * w),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        # extra buoyancy acts upward (-gravity direction) at the centre of buoyancy
        _add_force_at(pert, B_G, -values[0], (vehicle.xb, vehicle.yb, vehicle.zb))


class BuoyancyDepth(Effect):
    name = 'buoyancy_depth'
    description = 'buoyancy changes with depth: B(z) = B (1 + k z), k in 1/m (hull compression)'
    equations = ('heave',)
    signature = {'speed change': -1.0, 'depth excursion': 1.0}

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('k', '1/m', -1e-3, 1e-3, 0.0, 1e-5),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        _add_force_at(pert, B_ZG, -vehicle.B * values[0], (vehicle.xb, vehicle.yb, vehicle.zb))


class ActuatorDelay(Effect):
    name = 'actuator_delay'
    description = 'transport delay between the logged BAR command and the plane'
    equations = ('heave', 'pitch')
    signature = {'speed change': 2.0, 'plane doublets of several periods': 1.0}

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('bar', 's', 0.0, 3.0, 0.0, 0.1),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.delay[0] += values[0]


class ActuatorLag(Effect):
    name = 'actuator_lag'
    description = 'the plane follows its command with a first-order lag bar_tau (s)'
    equations = ('heave', 'pitch')
    signature = {'speed change': 2.0, 'plane doublets of several periods': 0.5}

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('bar_tau', 's', vehicle.dt, 10.0, vehicle.bar_tau, 0.2),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.tau[0] = values[0]


class ActuatorRateLimit(Effect):
    name = 'actuator_rate_limit'
    description = 'the plane moves at most bar_rate (rad/s)'
    equations = ('heave', 'pitch')
    signature = {'speed change': 2.0, 'plane steps of several sizes': 1.0,
                 'plane doublets of several periods': 0.5}

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('bar_rate', 'rad/s', 0.002, max(2.0, vehicle.bar_rate),
                          vehicle.bar_rate, 0.02),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.rate[0] = values[0]


class BarBias(Effect):
    name = 'bar_bias'
    description = 'the plane sits at its logged angle plus a bias (rad): force ~ u^2'
    equations = ('heave', 'pitch')
    signature = {'speed change': 2.0}

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('bias', 'rad', -0.2, 0.2, 0.0, 0.005),)

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

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        length, diam = vehicle.L_ref, vehicle.diameter
        zww = 0.5 * vehicle.rho * diam * length  # crossflow Cd = 1 scale [kg/m]
        mqq = zww * length ** 3 / 32.0           # the same over the length [kg m^2]
        return (Parameter('Zww', 'kg/m', -50 * zww, 50 * zww, 0.0, zww),
                Parameter('Mqq', 'kg m^2', -50 * mqq, 50 * mqq, 0.0, mqq),
                Parameter('Yvv', 'kg/m', -50 * zww, 50 * zww, 0.0, zww),
                Parameter('Nrr', 'kg m^2', -50 * mqq, 50 * mqq, 0.0, mqq))

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
    signature = {'speed change': -2.0}

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        lim = 0.05 * vehicle.L_ref
        return (Parameter('dxg', 'm', -lim, lim, 0.0, 0.002),
                Parameter('dzg', 'm', -lim, lim, 0.0, 0.002))

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

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('bias', 'm', -10.0, 10.0, 0.0, 0.1),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.bias[2] += values[0]


class PitchSensorBias(Effect):
    name = 'pitch_sensor_bias'
    description = 'the pitch sensor reads the true pitch plus a bias (rad)'
    equations = ('depth kinematics', 'pitch')
    signature = {'speed change': 1.0}

    def parameters(self, vehicle: VehicleParams) -> tuple[Parameter, ...]:
        return (Parameter('bias', 'rad', -0.2, 0.2, 0.0, 0.005),)

    def apply(self, pert: Perturbation, values: np.ndarray, vehicle: VehicleParams) -> None:
        pert.bias[4] += values[0]


for _effect in (Current(), BuoyancyOffset(), BuoyancyDepth(), ActuatorDelay(), ActuatorLag(),
                ActuatorRateLimit(), BarBias(), CrossflowDrag(), CgOffset(), DepthSensorBias(),
                PitchSensorBias()):
    register(_effect)
