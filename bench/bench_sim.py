"""Benchmark: simulation speed of the compiled 6-DOF model (targets: <= 7 us per single-vehicle
RK4 step, >= 1e6 vehicle-steps/s in batch).

* single vehicle: :func:`auv_sim.model.rk4_steps` advancing the A18M from its 2 m/s trim
  with a BAR step held, ``steps`` RK4 steps (four model evaluations each) per run; the median
  over ``repeats`` runs gives microseconds per step and the real-time factor ``dt / step``.
* batch (Monte Carlo): N vehicles with scattered initial states and commands, stepped together
  by :func:`auv_sim.model.rk4_batch` (one thread) and :func:`auv_sim.model.rk4_batch_parallel`
  (numba ``prange`` over vehicles, all cores), as vehicle-steps per second.
* ``simulator_us_per_step``: the :class:`~auv_sim.simulator.Simulator` wrapper stepping
  50 steps per call (how the node and ``auv run`` drive it), per step.

Compilation is excluded (kernels are warmed up first). Figures are medians; on a shared,
loaded machine they vary by tens of percent between runs.

Run: ``. .venv/bin/auv-env && python bench/bench_sim.py`` (writes bench/results/sim.json).
"""
from __future__ import annotations

import json
import os
import pathlib
import platform
from typing import Any

import numpy as np
from timing import median_time, save_figures

ROOT = pathlib.Path(__file__).resolve().parents[1]
TARGET_US_PER_STEP = 7.0
TARGET_BATCH_STEPS_PER_S = 1.0e6


def run(steps: int = 100_000, repeats: int = 7, batch_sizes: tuple[int, ...] = (1000, 10_000),
        batch_steps: int = 100) -> dict[str, Any]:
    """Run the benchmark; returns the figures (microseconds, steps per second, ratios)."""
    import numba

    from auv_sim.environment import Environment
    from auv_sim.model import rk4_batch, rk4_batch_parallel, rk4_steps
    from auv_sim.params import load_vehicle
    from auv_sim.simulator import Simulator
    from auv_sim.trim import VerticalPlane

    params = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    env = Environment()
    P, E, prof = params.as_array(), env.env_vector(), env.profile()
    dt = params.dt
    trim = VerticalPlane(params).trim(2.0, z=40.0)
    x0 = trim.state()
    cmd = x0[12:15].copy()
    cmd[0] += 0.05

    # single vehicle
    rk4_steps(0.0, x0.copy(), cmd, P, E, prof, dt, 10)      # warm-up (compiled/cached)

    def single() -> None:
        x = x0.copy()
        if rk4_steps(0.0, x, cmd, P, E, prof, dt, steps) != -1:
            raise RuntimeError('benchmark run diverged')
    t_single = median_time(single, repeats)[0]
    us_per_step = t_single / steps * 1e6

    sim_steps = 50

    def wrapped() -> None:
        sim = Simulator(params, env, x0=x0)
        sim.command('bar', cmd[0])
        for _ in range(steps // sim_steps):
            sim.step(sim_steps)
    sim_us = median_time(wrapped, max(3, repeats // 2))[0] / steps * 1e6

    # batch
    rng = np.random.default_rng(0)
    batch: dict[str, Any] = {}
    for n in batch_sizes:
        X0 = np.tile(x0, (n, 1))
        X0[:, 2] += rng.uniform(-10.0, 10.0, n)
        X0[:, 6] += rng.uniform(-0.3, 0.3, n)
        CMD = np.tile(cmd, (n, 1))
        CMD[:, 0] = rng.uniform(-0.3, 0.3, n)
        figures = {}
        for name, kernel in (('serial', rk4_batch), ('parallel', rk4_batch_parallel)):
            kernel(0.0, X0.copy(), CMD, P, E, prof, dt, 1)    # warm-up
            X = X0.copy()

            def go() -> None:
                kernel(0.0, X, CMD, P, E, prof, dt, batch_steps)  # noqa: B023
            t = median_time(go, repeats)[0]
            figures[f'{name}_vehicle_steps_per_s'] = round(n * batch_steps / t)
        batch[str(n)] = figures

    best_batch = max(v for f in batch.values() for v in f.values())
    return {
        'single_us_per_step': round(us_per_step, 3),
        'single_real_time_factor': round(dt / (us_per_step * 1e-6)),
        'single_steps': steps,
        'simulator_us_per_step': round(sim_us, 3),
        'dt_s': dt,
        'batch': batch,
        'batch_steps': batch_steps,
        'targets': {'us_per_step_max': TARGET_US_PER_STEP,
                    'batch_vehicle_steps_per_s_min': TARGET_BATCH_STEPS_PER_S},
        'single_target_met': us_per_step <= TARGET_US_PER_STEP,
        'batch_target_met': best_batch >= TARGET_BATCH_STEPS_PER_S,
        'repeats': repeats,
        'threads': numba.get_num_threads(),
        'cpus': os.cpu_count(),
        'load_average_1min': round(os.getloadavg()[0], 2),
        'python': platform.python_version(),
        'machine': platform.machine(),
    }


if __name__ == '__main__':
    figures = run()
    save_figures('sim', figures)
    print(json.dumps(figures, indent=2))
