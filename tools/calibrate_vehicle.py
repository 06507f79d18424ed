"""Calibrate a vehicle file's heave/pitch coefficients to published trim and Jacobian figures.

Usage: python tools/calibrate_vehicle.py VEHICLE.yaml TARGETS.yaml [--write]

With the mass properties of VEHICLE.yaml held, solves (least squares on relative errors) for
CZ0, CZuw, CZuq, CM0, CMuw, CMuq, CZbar, CMbar, zg and B so that the vertical-plane trims and
Jacobian of the 6-DOF model match TARGETS.yaml; sway/yaw coefficients follow by axial symmetry
(CYuv = CZuw, CYur = -CZuq, CNuv = -CMuw, CNur = CMuq, CYhelm = CZbar, CNhelm = -CMbar).
Prints each figure against its target; --write stores the values in VEHICLE.yaml.
"""
from __future__ import annotations

import argparse
import sys

import numpy as np
import yaml
from scipy import optimize

from auv_sim.params import load_vehicle, save_vehicle
from auv_sim.trim import VerticalPlane

FREE = ('CZ0', 'CZuw', 'CZuq', 'CM0', 'CMuw', 'CMuq', 'CZbar', 'CMbar', 'zg', 'B')


def figures(params, targets):  # type: ignore[no-untyped-def]
    """(name, model value, target) for every calibration figure."""
    u0 = targets['u0']
    vp = VerticalPlane(params)
    full = vp.trim(u0, kinematics='full')
    w_trim = vp.trim(u0, kinematics='w')
    A, B = vp.linearize(full)
    rows = [(f'trim_full.{k}', getattr(full, k), v) for k, v in targets['trim_full'].items()]
    rows += [(f'trim_w.{k}', getattr(w_trim, k), v) for k, v in targets['trim_w'].items()]
    rows += [(f'A[{i},{j}]', A[i, j], v) for i, j, v in targets['jacobian']['A']]
    rows += [(f'B[{i}]', B[i, 0], v) for i, v in targets['jacobian']['B']]
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('vehicle')
    ap.add_argument('targets')
    ap.add_argument('--write', action='store_true')
    args = ap.parse_args()
    base = load_vehicle(args.vehicle)
    with open(args.targets) as f:
        targets = yaml.safe_load(f)

    def params_of(x: np.ndarray):  # type: ignore[no-untyped-def]
        return base.replace(**dict(zip(FREE, x)))

    def residual(x: np.ndarray) -> np.ndarray:
        try:
            rows = figures(params_of(x), targets)
        except Exception:
            return np.full(12, 1e3)
        return np.array([(v - t) / abs(t) for _, v, t in rows])

    x0 = np.array([base.values[k] for k in FREE])
    sol = optimize.least_squares(residual, x0, x_scale=np.abs(x0) + 1e-3, xtol=1e-14,
                                 ftol=1e-14, gtol=1e-14)
    params = params_of(sol.x)
    worst = 0.0
    for name, value, target in figures(params, targets):
        err = (value - target) / abs(target)
        worst = max(worst, abs(err))
        print(f'{name:14s} model {value: .6f}  report {target: .6f}  error {100 * err:+.2f} %')
    sym = {'CYuv': params.CZuw, 'CYur': -params.CZuq, 'CNuv': -params.CMuw,
           'CNur': params.CMuq, 'CYhelm': params.CZbar, 'CNhelm': -params.CMbar}
    params = params.replace(**sym)
    for k in FREE + tuple(sym):
        print(f'{k} = {params.values[k]:.6g}')
    print(f'worst relative error {100 * worst:.2f} %')
    if args.write:
        save_vehicle(params, args.vehicle)
        print(f'wrote {args.vehicle}')
    return 0 if worst < 0.02 else 1


if __name__ == '__main__':
    sys.exit(main())
