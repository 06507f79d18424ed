"""Offline closed loop: the simulator and the depth pilot, with no ROS graph.

The sequence is the lockstep protocol of the node graph (see :mod:`auv_sim.node`): at each
control instant ``t_k = k Ts`` the measured state goes to the pilot, its BAR command is
applied at ``t_k`` and held while the simulator advances ``Ts``. A lockstep graph run and this
function therefore produce the same trajectory.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from auv_depth_lqr.errors import InvalidInputError
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_sim.environment import Environment
from auv_sim.params import VehicleParams
from auv_sim.simulator import Record, Simulator, record
from auv_sim.trim import VerticalPlane

#: Model errors of :func:`model_error_plant`: effects of the sim-to-real catalogue at realistic
#: sizes, and the hull (CZuw, CZuq, CMuw, CMuq) or fin (CZbar, CMbar) lift off by +-30 %.
MODEL_ERRORS = ('buoyancy+1%', 'buoyancy-1%', 'delay_0.3s', 'lag_0.5s', 'bar_bias_1deg',
                'pitch_bias_0.5deg', 'hull*0.7', 'hull*1.3', 'fins*0.7', 'fins*1.3',
                'current_following_0.3', 'current_head_0.3', 'current_cross_0.3')
_HULL = ('CZuw', 'CZuq', 'CMuw', 'CMuq')
_FINS = ('CZbar', 'CMbar')


def model_error_plant(design: VehicleParams, error: str) -> tuple[VehicleParams, Environment]:
    """The "real" vehicle for one of :data:`MODEL_ERRORS`: parameters and environment.

    Buoyancy +-1 % of the weight [N], plane transport delay 0.3 s, plane lag 0.5 s, plane
    bias 1 deg, pitch-sensor bias 0.5 deg, a horizontal current of 0.3 m/s along (north: the
    runs head north), against or across the heading (auv_sim.environment effects), or the
    hull's or the fins' lift coefficients times 0.7 or 1.3. Raises ValueError for an unknown
    name.
    """
    weight = design.m * design.g
    effects: dict[str, dict[str, dict[str, float]]] = {
        'buoyancy+1%': {'buoyancy_offset': {'dB': 0.01 * weight}},
        'buoyancy-1%': {'buoyancy_offset': {'dB': -0.01 * weight}},
        'delay_0.3s': {'actuator_delay': {'bar': 0.3}},
        'lag_0.5s': {'actuator_lag': {'bar_tau': 0.5}},
        'bar_bias_1deg': {'bar_bias': {'bias': math.radians(1.0)}},
        'pitch_bias_0.5deg': {'pitch_sensor_bias': {'bias': math.radians(0.5)}},
        'current_following_0.3': {'current': {'north': 0.3}},
        'current_head_0.3': {'current': {'north': -0.3}},
        'current_cross_0.3': {'current': {'east': 0.3}},
    }
    if error in effects:
        return design, Environment(effects=effects[error])
    if error not in MODEL_ERRORS:
        raise ValueError(f'unknown model error {error!r} (known: {", ".join(MODEL_ERRORS)})')
    group, scale = error.split('*')
    names = _HULL if group == 'hull' else _FINS
    return design.replace(**{k: design.values[k] * float(scale) for k in names}), Environment()


def foreign_plant(design: VehicleParams, u0: float, trim_shift: float = math.radians(9.0),
                  plane_force: float = 0.5, plane_moment: float = 0.6) -> VehicleParams:
    """A vehicle that is not the pilot's model the way a third party's simulator is not.

    From the pilot's vehicle file ``design``: neutrally buoyant (``B = W``), the plane's
    force and moment times ``plane_force`` and ``plane_moment``, no moment in ``u w`` (the
    hull's ``CMuw`` set to cancel the Munk moment the model computes from its added masses),
    and a zero-incidence pitch moment ``CM0`` that puts its level trim at ``u0`` [m/s]
    ``trim_shift`` [rad] of plane away from the file's (on the REMUS 100, whose file is
    7 N buoyant, the neutral buoyancy alone moves it by 9.1 deg and ``CM0`` stays near 0).
    Raises TrimError if either has no level trim at ``u0``.
    """
    plant = design.replace(B=design.m * design.g, CZbar=plane_force * design.CZbar,
                           CMbar=plane_moment * design.CMbar, CMuw=0.0, CM0=0.0)
    plane = VerticalPlane(plant)
    # the model's d M / d w at u = 1 m/s, w = 0 with CMuw = 0 is the Munk moment per unit
    # u w [N m s^2/m^2] (complex step; the quadratic cross-flow terms have no slope there)
    h = 1e-30
    munk = plane.wrench(plane.full_state(1j * h, 0.0, 0.0, 0.0, 0.0, 1.0)).imag[4] / h
    plant = plant.replace(CMuw=-float(munk) / (0.5 * plant.rho * plant.S_ref * plant.L_ref))
    target = VerticalPlane(design).trim(u0).bar + trim_shift
    # CM0 by Newton's method on the trim BAR (the trim is smooth in CM0)
    cm0, step = 0.0, 1e-4
    for _ in range(8):
        bar = VerticalPlane(plant.replace(CM0=cm0)).trim(u0).bar
        if abs(bar - target) < 1e-7:
            break
        slope = (VerticalPlane(plant.replace(CM0=cm0 + step)).trim(u0).bar - bar) / step
        cm0 += (target - bar) / slope
    return plant.replace(CM0=cm0)


@dataclasses.dataclass
class ClosedLoopRun:
    """A closed-loop run: the simulator record (every ``sample_period``), the pilot's BAR
    commands at the control instants (``bar_t`` [s], ``bar`` [rad]) and the depth commands
    (``z_ref_t`` [s], ``z_ref`` [m])."""

    record: Record
    bar_t: np.ndarray
    bar: np.ndarray
    z_ref_t: np.ndarray
    z_ref: np.ndarray


def run_closed_loop(params: VehicleParams, depth_commands: Sequence[tuple[float, float]],
                    duration: float, z0: float = 40.0, u0: float = 2.0,
                    environment: Environment | None = None,
                    settings: PilotSettings | None = None, sample_period: float = 0.02,
                    pilot: DepthPilot | None = None,
                    speed_time_constant: float | None = None,
                    excitation: Sequence[tuple[float, str, float]] = (),
                    sensor_noise: Sequence[float] | None = None, seed: int = 0
                    ) -> ClosedLoopRun:
    """Fly depth commands ``[(t [s], z [m]), ...]`` from a trim at ``z0`` [m], ``u0`` [m/s].

    The vehicle starts trimmed for the nominal model in the water it is in (its trim
    velocities through the water plus the current, see :meth:`auv_sim.trim.Trim.state`);
    ``environment`` makes the "real" vehicle differ. The speed loop is the vehicle's, outside
    this toolkit: by default the thrust is held at its trim value; with
    ``speed_time_constant`` [s] a proportional surge-speed hold stands for it, thrust
    ``T_trim + (m - Xudot) (u0 - u) / speed_time_constant`` [N] within the propeller's
    limits (``u`` the measured surge), as on a vehicle that holds its speed in a climb or
    dive (a positively buoyant vehicle with its thrust held slows down in a dive).

    ``excitation`` flies an identification manoeuvre on top of the pilot (closed-loop
    identification, for a vehicle that open-loop manoeuvres would pitch over): events
    ``(t [s], channel, value)``, each from the first control instant at or after ``t``;
    ``thrust`` [N] and ``helm`` [rad] are commanded as given (no speed loop with thrust
    events), ``bar`` [rad] is an offset added to the pilot's BAR until the next ``bar`` event,
    the sum within ``+-bar_max``. ``ClosedLoopRun.bar`` holds the BAR commanded.

    ``sensor_noise``: standard deviations of white noise added to the 12 measured states the
    pilot gets (``x y z`` [m], ``phi theta psi`` [rad], ``u v w`` [m/s], ``p q r`` [rad/s],
    e.g. ``auv_logs.simlog.SensorNoise.realistic().sigmas()``), drawn at each control
    instant from ``numpy.random.default_rng(seed)``; the record keeps the simulator's own
    measured state.
    """
    settings = settings or PilotSettings()
    pilot = pilot or DepthPilot.for_vehicle(params, settings)
    sigmas = None if sensor_noise is None else np.asarray(sensor_noise, dtype=float)
    if sigmas is not None and (sigmas.shape != (12,) or not np.all(np.isfinite(sigmas))
                               or np.any(sigmas < 0.0)):
        raise ValueError(f'sensor_noise must be 12 finite standard deviations >= 0, got '
                         f'{sensor_noise!r}')
    rng = np.random.default_rng(seed)
    trim = VerticalPlane(params).trim(u0, z=z0)
    sim = Simulator(params, environment, x0=trim.state(environment))
    ts = settings.Ts
    steps_per_control = int(round(ts / sim.dt))
    steps_per_sample = int(round(sample_period / sim.dt))
    if steps_per_control * sim.dt - ts > 1e-9 or steps_per_control % steps_per_sample:
        raise ValueError(f'control period {ts} s must be a multiple of the sample period '
                         f'{sample_period} s, itself a multiple of dt = {sim.dt} s')
    if speed_time_constant is not None and not speed_time_constant > 0.0:
        raise ValueError(f'speed_time_constant must be > 0 s, got {speed_time_constant!r}')
    speed_gain = 0.0 if speed_time_constant is None else \
        (params.m - params.Xudot) / speed_time_constant
    events = sorted(excitation, key=lambda e: e[0])
    for _t, channel, _v in events:
        if channel not in ('bar', 'helm', 'thrust'):
            raise ValueError(f'excitation channel {channel!r} must be bar, helm or thrust')
        if channel == 'thrust' and speed_gain:
            raise ValueError('thrust excitation events and a speed loop '
                             '(speed_time_constant) both command the thrust: give one')
    bar_offset = 0.0
    n_control = int(math.floor(duration / ts + 1e-9))
    commands = sorted(depth_commands)
    samples, bar_t, bars, zr_t, zr = [], [], [], [], []
    for _k in range(n_control):
        t = sim.t
        while commands and commands[0][0] <= t + 1e-9:
            _, z_cmd = commands.pop(0)
            try:
                pilot.set_depth_command(z_cmd)
                zr_t.append(t)
                zr.append(z_cmd)
            except InvalidInputError:
                pass
        while events and events[0][0] <= t + 1e-9:
            _, channel, value = events.pop(0)
            if channel == 'bar':
                bar_offset = float(value)
            else:
                sim.command(channel, float(value))
        x = sim.measured_state()
        if sigmas is not None:
            x = x.copy()
            x[:12] += rng.standard_normal(12) * sigmas
        pilot.on_state(t, z=x[2], theta=x[4], w=x[8], q=x[10], u=x[6])
        bar, _ = pilot.command(t)
        if bar_offset:
            bar = min(max(bar + bar_offset, -params.bar_max), params.bar_max)
        sim.command('bar', bar)
        if speed_gain:
            thrust = trim.thrust + speed_gain * (u0 - x[6])
            sim.command('thrust', min(max(thrust, params.thrust_min), params.thrust_max))
        bar_t.append(t)
        bars.append(bar)
        for _ in range(steps_per_control // steps_per_sample):
            samples.append(sim.sample())
            sim.step(steps_per_sample)
    samples.append(sim.sample())
    return ClosedLoopRun(record=record(samples), bar_t=np.array(bar_t), bar=np.array(bars),
                         z_ref_t=np.array(zr_t), z_ref=np.array(zr))
