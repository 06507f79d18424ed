"""A stepping simulator around the pure model: commands, delays, sensors, records.

:class:`Simulator` owns the state of one vehicle and advances it with fixed-step RK4
(:func:`auv_sim.model.rk4_steps`, step ``dt`` from the vehicle file, default 0.01 s). Commands
are held between updates (zero-order hold) and take effect at the first integration step at or
after their time plus any transport delay of the environment. The simulator node and offline
runs (``auv run``) both drive this class, so the same inputs give the same trajectory.
"""
from __future__ import annotations

import collections
import dataclasses
import math

import numpy as np

from auv_contract import CHANNELS
from auv_sim.environment import Environment
from auv_sim.errors import CommandError, DivergenceError, ParameterError
from auv_sim.model import NX, STATE_NAMES, rk4_batch, rk4_batch_parallel, rk4_steps, wrenches
from auv_sim.params import VehicleParams


@dataclasses.dataclass
class Record:
    """Samples of a run: time [s] (N), true state (N x 15), measured state (N x 15),
    commands as applied (N x 3: bar [rad], helm [rad], thrust [N]), wrenches (N x 4 x 6)."""

    t: np.ndarray
    x: np.ndarray
    measured: np.ndarray
    cmd: np.ndarray
    wrench: np.ndarray

    def column(self, name: str, measured: bool = True) -> np.ndarray:
        """One state column by name (see :data:`auv_sim.model.STATE_NAMES`)."""
        return (self.measured if measured else self.x)[:, STATE_NAMES.index(name)]


def initial_state(z: float = 0.0, u: float = 0.0, theta: float = 0.0, psi: float = 0.0,
                  bar: float = 0.0, thrust: float = 0.0) -> np.ndarray:
    """A 15-state vector: depth z [m], surge u [m/s], pitch/yaw [rad], actuator positions."""
    x = np.zeros(NX)
    x[2], x[4], x[5], x[6], x[12], x[14] = z, theta, psi, u, bar, thrust
    return x


class Simulator:
    """One vehicle in one environment, advanced on a fixed step grid ``t = t0 + k dt``."""

    def __init__(self, params: VehicleParams, environment: Environment | None = None,
                 x0: np.ndarray | None = None, t0: float = 0.0, dt: float | None = None) -> None:
        self.environment = environment or Environment()
        self.model_params = params
        self.params = self.environment.apply_to(params)
        self._p = self.params.as_array()
        self._env = self.environment.env_vector()
        self._prof = self.environment.profile()
        self.dt = float(dt if dt is not None else params.dt)
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ParameterError(f'integration step dt = {dt} s must be finite and > 0')
        self.t0 = float(t0)
        self.k = 0
        self.x = np.array(x0 if x0 is not None else initial_state(), dtype=np.float64)
        if self.x.shape != (NX,) or not np.all(np.isfinite(self.x)):
            raise ParameterError(f'initial state must be {NX} finite numbers')
        self.cmd = self.x[12:15].copy()
        self._delays = self.environment.delays()
        self._pending: list[collections.deque[tuple[int, float]]] = [
            collections.deque() for _ in CHANNELS]
        self._sensors = self.environment.sensors()

    @property
    def t(self) -> float:
        """Simulated time [s]."""
        return self.t0 + self.k * self.dt

    def limits(self, channel: str) -> tuple[float, float]:
        """Accepted command range of a channel (rad for planes, N for thrust)."""
        p = self.model_params
        if channel == 'bar':
            return -p.bar_max, p.bar_max
        if channel == 'helm':
            return -p.helm_max, p.helm_max
        if channel == 'thrust':
            return p.thrust_min, p.thrust_max
        raise CommandError(f'unknown actuator channel {channel!r} (known: {CHANNELS})')

    def check_command(self, channel: str, value: float) -> float:
        """``value`` as float when it is a valid command of ``channel``, else CommandError."""
        lo, hi = self.limits(channel)
        try:
            value = float(value)
        except (TypeError, ValueError):
            raise CommandError(f'{channel} command {value!r} is not a number') from None
        if not math.isfinite(value):
            raise CommandError(f'{channel} command {value} is not finite; last valid '
                               f'command kept')
        if not lo <= value <= hi:
            raise CommandError(f'{channel} command {value:.6g} outside [{lo:.6g}, {hi:.6g}]; '
                               f'last valid command kept')
        return value

    def command(self, channel: str, value: float) -> None:
        """Set a command now; it acts after the channel's transport delay (if any)."""
        value = self.check_command(channel, value)
        i = CHANNELS.index(channel)
        delay_steps = int(math.ceil(self._delays[i] / self.dt - 1e-9))
        if delay_steps == 0:
            self.cmd[i] = value
        else:
            self._pending[i].append((self.k + delay_steps, value))

    def _apply_due(self) -> None:
        for i, queue in enumerate(self._pending):
            while queue and queue[0][0] <= self.k:
                self.cmd[i] = queue.popleft()[1]

    def _next_due(self) -> int | None:
        due = [q[0][0] for q in self._pending if q]
        return min(due) if due else None

    def advance(self, duration: float) -> None:
        """Integrate ``duration`` [s] (rounded to whole steps) with the held commands."""
        nsteps = int(round(duration / self.dt))
        if nsteps < 0:
            raise ParameterError(f'cannot advance by a negative duration {duration} s')
        self.step(nsteps)

    def step(self, nsteps: int) -> None:
        """Integrate ``nsteps`` RK4 steps; DivergenceError if the state turns non-finite."""
        end = self.k + nsteps
        while self.k < end:
            self._apply_due()
            due = self._next_due()
            n = end - self.k if due is None else min(end, due) - self.k
            status = rk4_steps(self.t, self.x, self.cmd, self._p, self._env, self._prof,
                               self.dt, n)
            if status >= 0:
                self.k += status
                state = ', '.join(f'{k}={v:.4g}' for k, v in zip(STATE_NAMES, self.x))
                raise DivergenceError(
                    f'state turned non-finite at t = {self.t + self.dt:.3f} s '
                    f'(last finite state at t = {self.t:.3f} s: {state})')
            self.k += n
        self._apply_due()

    def warm_up(self) -> None:
        """Load the compiled step and force kernels now, leaving the simulator as it was.

        A process's first call of a compiled function initialises numba's target and loads
        the function from its cache (~0.3-0.5 s of CPU); one step is integrated and the forces
        evaluated on copies of the state and the commands, so that this happens here (in a
        node: once the state at ``t = 0`` went out, while the controller answers it) and not
        in the first step, whose lateness would count as lag.
        """
        x, cmd = self.x.copy(), self.cmd.copy()
        rk4_steps(self.t, x, cmd, self._p, self._env, self._prof, self.dt, 1)
        wrenches(self.t, x, self._p, self._env, self._prof, np.empty((4, 6)))

    def measured_state(self) -> np.ndarray:
        """The state as the vehicle's sensors report it: depth and pitch with the
        environment's sensor scale, latency and bias (:class:`auv_sim.environment.Sensors`;
        call once per sample, time non-decreasing)."""
        return self._sensors.measure(self.t, self.x)

    def wrenches(self) -> np.ndarray:
        """Force breakdown (4 x 6) at the current state, rows as model.WRENCH_NAMES."""
        out = np.empty((4, 6))
        wrenches(self.t, self.x, self._p, self._env, self._prof, out)
        return out

    def sample(self) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(t, true state, measured state, applied command, wrenches) now."""
        return self.t, self.x.copy(), self.measured_state(), self.cmd.copy(), self.wrenches()


def record(samples: list[tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]) -> Record:
    """Stack :meth:`Simulator.sample` tuples into a :class:`Record`."""
    return Record(t=np.array([s[0] for s in samples]), x=np.array([s[1] for s in samples]),
                  measured=np.array([s[2] for s in samples]),
                  cmd=np.array([s[3] for s in samples]), wrench=np.array([s[4] for s in samples]))


def step_batch(params: VehicleParams, X: np.ndarray, CMD: np.ndarray, nsteps: int,
               environment: Environment | None = None, t0: float = 0.0,
               dt: float | None = None, parallel: bool = True) -> np.ndarray:
    """Advance N vehicles in place (rows of X, N x 15) ``nsteps`` RK4 steps (Monte Carlo).

    All share one vehicle file and environment; each has its own state and held command
    (rows of CMD, N x 3). Returns the per-vehicle status (-1 ok, else first bad step).
    With ``parallel`` the vehicles are spread over the CPU's cores (same numbers).
    """
    env = environment or Environment()
    p = env.apply_to(params)
    kernel = rk4_batch_parallel if parallel else rk4_batch
    out: np.ndarray = kernel(t0, X, CMD, p.as_array(), env.env_vector(), env.profile(),
                             float(dt if dt is not None else params.dt), nsteps)
    return out
