"""The time-optimal settling bound: its value, how much it moves with the last digits, its cost.

For each case (the REMUS 100 and NPS AUV II changes of ``bench_vehicles.py`` at 1.5 m/s, the
A18M's 40 -> 10 m climb and 10 -> 40 m dive at 2 m/s), :func:`auv_depth_lqr.bound.
settling_bound` with a 25 deg pitch limit and its defaults (0.2 s grid, 0.1 m band, 20 s
hold). Reported per case:

* ``bound_s``, ``grid_time_s``, ``earlier_band_m``, ``band_reached_m``, ``solver_starts``,
  ``wall_s`` of the nominal bound;
* ``perturbed_s``: the bound with ``u0`` and with every hydrodynamic coefficient and mass
  property (``C*``, ``*dot``, ``Mqq``, ``Mww``, ``Zqq``, ``Zww``, ``m``, ``Iy``, ``zg``, ``B``)
  times ``1 + 1e-12`` and ``1 - 1e-12``: the digits a machine's compiler, BLAS or thread
  count change; ``spread_s``, the largest difference among them and the nominal bound
  (target < 0.1 s);
* with ``--previous FILE`` (a ``bound.py`` of an earlier commit, e.g. ``git show
  62c936d:src/auv_depth_lqr/auv_depth_lqr/bound.py > /tmp/bound_previous.py``), that module's
  ``settling_bound`` of the nominal case and its wall time, run in the same process just
  before (``previous_bound_s``, ``previous_wall_s``).

Every bound is computed afresh (the per-process cache is cleared). Run as a script to write
``bench/results/bound.json``; ``--cases remus100`` keeps the cases whose name contains it.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import pathlib
import platform
import sys
import time
from typing import Any

from timing import save_figures

from auv_depth_lqr import bound as bound_module
from auv_sim.params import VehicleParams, load_vehicle

CONFIG = pathlib.Path(__file__).resolve().parents[1] / 'config'
THETA_MAX = math.radians(25.0)
#: name -> (vehicle, z0 [m], z1 [m], u0 [m/s])
CASES = {
    'remus100 20->10m at 1.5 m/s': ('remus100', 20.0, 10.0, 1.5),
    'remus100 10->30m at 1.5 m/s': ('remus100', 10.0, 30.0, 1.5),
    'remus100 5->40m at 1.5 m/s': ('remus100', 5.0, 40.0, 1.5),
    'a18m 40->10m at 2 m/s': ('a18m', 40.0, 10.0, 2.0),
    'a18m 10->40m at 2 m/s': ('a18m', 10.0, 40.0, 2.0),
    'npsauv2 20->10m at 1.5 m/s': ('npsauv2', 20.0, 10.0, 1.5),
    'npsauv2 10->30m at 1.5 m/s': ('npsauv2', 10.0, 30.0, 1.5),
    'npsauv2 5->40m at 1.5 m/s': ('npsauv2', 5.0, 40.0, 1.5),
}
RELATIVE = 1e-12
_QUADRATIC = ('Mqq', 'Mww', 'Zqq', 'Zww', 'm', 'Iy', 'zg', 'B')


def perturbed(params: VehicleParams, factor: float) -> VehicleParams:
    """``params`` with every hydrodynamic coefficient and mass property times ``factor``."""
    names = [k for k in params.values
             if k.startswith('C') or k.endswith('dot') or k in _QUADRATIC]
    return params.replace(**{k: params.values[k] * factor for k in names})


def timed(fn: Any, *args: Any) -> tuple[Any, float]:
    """``fn(*args)`` and its wall time [s]."""
    t0 = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - t0


def case_figures(vehicle: str, z0: float, z1: float, u0: float, previous: Any | None
                 ) -> dict[str, Any]:
    """The figures of one case (see the module docstring)."""
    params = load_vehicle(CONFIG / f'{vehicle}.yaml')
    out: dict[str, Any] = {}
    if previous is not None:
        old, wall = timed(previous.settling_bound, params, z0, z1, u0, THETA_MAX)
        out.update(previous_bound_s=round(old.settling_time, 3),
                   previous_wall_s=round(wall, 1))
    bound_module.clear_cache()
    nominal, wall = timed(bound_module.settling_bound, params, z0, z1, u0, THETA_MAX)
    out.update(bound_s=round(nominal.settling_time, 4), grid_time_s=round(nominal.grid_time, 3),
               earlier_band_m=round(nominal.earlier_band, 4),
               band_reached_m=round(nominal.band_reached, 4), solver_starts=nominal.solves,
               wall_s=round(wall, 1))
    variants = {'u0 x (1 + 1e-12)': (params, u0 * (1 + RELATIVE)),
                'coefficients x (1 + 1e-12)': (perturbed(params, 1 + RELATIVE), u0),
                'coefficients x (1 - 1e-12)': (perturbed(params, 1 - RELATIVE), u0)}
    times = [nominal.settling_time]
    out['perturbed_s'] = {}
    for name, (p, speed) in variants.items():
        value = bound_module.settling_bound(p, z0, z1, speed, THETA_MAX).settling_time
        out['perturbed_s'][name] = round(value, 4)
        times.append(value)
    out['spread_s'] = round(max(times) - min(times), 4)
    return out


def load_previous(path: str) -> Any:
    """The ``bound.py`` module at ``path`` (an earlier version)."""
    spec = importlib.util.spec_from_file_location('bound_previous', path)
    if spec is None or spec.loader is None:
        raise ImportError(f'cannot load {path}')
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def run(previous: str | None = None, only: str = '') -> dict[str, Any]:
    """Every case (those whose name contains ``only``); returns the figures."""
    load_start = os.getloadavg()[0]
    module = None if previous is None else load_previous(previous)
    cases = {name: case_figures(*case, module) for name, case in CASES.items() if only in name}
    spreads = [c['spread_s'] for c in cases.values()]
    return {'theta_max_deg': 25.0, 'grid_s': 0.2, 'band_m': 0.1, 'hold_s': 20.0,
            'cases': cases, 'largest_spread_s': max(spreads), 'target_spread_s': 0.1,
            'machine': {'python': platform.python_version(), 'cpus': os.cpu_count(),
                        'load_average_1min_start': round(load_start, 2),
                        'load_average_1min_end': round(os.getloadavg()[0], 2)}}


if __name__ == '__main__':
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--previous', help='a bound.py of an earlier commit, timed beside')
    parser.add_argument('--cases', default='', help='keep the cases whose name contains this')
    args = parser.parse_args()
    figures = run(args.previous, args.cases)
    save_figures('bound', figures)
    print(json.dumps(figures, indent=2))
