"""Benchmark: coverage of the 95 % intervals of the identification from motion.

``runs`` replications of the surge, pitch and yaw missions of the A18M, each with its own
draw of navigation-grade sensor noise (depth 0.02 m, angles 0.1 deg, velocities 0.01 m/s,
rates 0.1 deg/s; seeds ``first + 3 k + (0, 1, 2)``), forces reconstructed from the noisy
motion and the coefficients identified (``tools/ident_coverage.py``). Reported per
coefficient: coverage of the 95 % interval (goal: about 0.95; the binomial standard error
for 100 runs is 0.022), misses, rms of error / standard error (calibrated: near 1), the ratio
of the mean standard error to the estimates' spread, bias in standard errors.

Run: ``. .venv/bin/auv-env && python bench/bench_ident_coverage.py [--runs 100]`` (writes
bench/results/ident_coverage.json; ~2 s per run on an idle core).
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import pathlib
import platform
import time
from typing import Any

from timing import save_figures

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _tool() -> Any:
    spec = importlib.util.spec_from_file_location('ident_coverage',
                                                  ROOT / 'tools' / 'ident_coverage.py')
    if spec is None or spec.loader is None:
        raise ImportError('cannot load tools/ident_coverage.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def run(runs: int = 100, first: int = 1000) -> dict[str, Any]:
    """Coverage figures over ``runs`` noise replications (see module doc)."""
    load_before = os.getloadavg()[0]
    t0 = time.perf_counter()
    table = _tool().run(runs, first, 'hac', ROOT / 'config' / 'a18m.yaml', 1.0, 1.0, False)
    wall = time.perf_counter() - t0
    coefficients = {k: v for k, v in table.items() if not k.startswith('equation ')}
    coverages = [v['coverage'] for v in coefficients.values()]
    return {
        'vehicle': 'a18m.yaml', 'runs': runs, 'first_seed': first,
        'noise': 'realistic (depth 0.02 m, angles 0.1 deg, velocities 0.01 m/s, rates 0.1 deg/s)',
        'min_coverage': min(coverages), 'max_coverage': max(coverages),
        'coefficients': coefficients,
        'equations': {k.removeprefix('equation '): v for k, v in table.items()
                      if k.startswith('equation ')},
        'wall_s': round(wall, 1), 'load_before': load_before, 'machine': platform.machine(),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--runs', type=int, default=100, help='replications (default 100)')
    args = parser.parse_args()
    figures = run(args.runs)
    print(save_figures('ident_coverage', figures))
    for name, row in figures['coefficients'].items():
        print(f'{name:6s} coverage {row["coverage"]:.2f} (misses {row["misses"]}), '
              f'rms z {row["rms_z"]:.2f}, se/spread {row["se_over_spread"]:.2f}')


if __name__ == '__main__':
    main()
