"""``auv vehicle-init``: a starting vehicle file from main dimensions and mass.

For a user's own torpedo-shaped vehicle ("1.6 m long, 0.15 m diameter, 20 kg") with no
tank tests: every parameter is a class-typical first estimate, scaled from a reference
vehicle file with published values (default ``config/remus100.yaml``: Prestero 2001) by
geometric similarity, and marked ``estimated: ...`` in its source with the scaling used.
``auv ident --vehicle NEW.yaml`` then replaces what the logs identify (the hydrodynamic
coefficients); the rest stays estimated until measured (weigh, swing-test, trim).

Scaling (reference quantities with subscript r; ``r = D/2``; SI, body FRD at the CB):

* geometry: ``L_ref = L``, ``diameter = D``, ``S_ref = pi D^2 / 4``;
* mass: ``m`` given; ``B = m g (B_r / (m_r g_r))`` (the reference's buoyancy margin);
  ``zg = zg_r D / D_r``; ``Ix = Ix_r (m r^2) / (m_r r_r^2)``;
  ``Iy = Iz = Iy_r (m L^2) / (m_r L_r^2)``;
* added mass (slender body, proportional to the displaced fluid): ``Xudot, Yvdot, Zwdot``
  ``~ rho D^2 L``; ``Kpdot ~ rho D^4 L``; ``Yrdot, Zqdot ~ rho D^2 L^2``;
  ``Mqdot, Nrdot ~ rho D^2 L^3``;
* hydrodynamic and control-surface coefficients: dimensionless (scaled by ``1/2 rho S_ref``
  and ``1/2 rho S_ref L_ref``), so kept as the reference's (same hull and fin proportions
  assumed; the fineness ratio ``L/D`` is reported beside the reference's);
* actuators: angles, rates and lags as the reference's; thrust limits scaled with the drag
  at the same speed, ``~ S_ref``;
* environment, envelope and the simulation step: the reference's.
"""
from __future__ import annotations

import argparse
import math
import pathlib
import sys
from collections.abc import Sequence

from auv_contract import config_path
from auv_ident.errors import IdentError
from auv_sim.params import (
    VehicleParams,
    load_vehicle,
    parse_vehicle,
    save_vehicle,
    vehicle_document,
)


class VehicleInitError(IdentError, ValueError):
    """Bad dimensions or mass, or an output that exists already."""


def estimate(length: float, diameter: float, mass: float, reference: VehicleParams,
             name: str = 'my_auv') -> tuple[VehicleParams, list[str]]:
    """A vehicle from ``length`` [m], ``diameter`` [m], ``mass`` [kg] scaled from
    ``reference`` (see the module docstring); returns it and notes on the estimate."""
    for what, v in (('length', length), ('diameter', diameter), ('mass', mass)):
        if not (math.isfinite(v) and v > 0):
            raise VehicleInitError(f'--{what} must be a finite positive number, got {v}')
    if length < 3 * diameter:
        raise VehicleInitError(f'length {length} m is less than 3 diameters ({diameter} m): '
                               'not a torpedo-shaped hull')
    ref = reference.values
    sl = length / ref['L_ref']
    sd = diameter / ref['diameter']
    sm = mass / ref['m']
    rho_ratio = 1.0     # same water as the reference
    values = dict(ref)
    how: dict[str, str] = {}
    tag = f'{reference.name} ({pathlib.Path(reference.path).name})'

    def put(key: str, value: float, rule: str) -> None:
        values[key] = value
        how[key] = f'estimated: {rule} from {tag}'

    values['L_ref'], values['diameter'] = length, diameter
    values['S_ref'] = math.pi * diameter ** 2 / 4.0
    how['L_ref'] = 'given: hull length'
    how['diameter'] = 'given: hull diameter'
    how['S_ref'] = 'derived: frontal area pi D^2 / 4'
    values['m'] = mass
    how['m'] = 'given: mass in air'
    put('B', mass * ref['g'] * ref['B'] / (ref['m'] * ref['g']),
        'm g times the reference buoyancy margin B/W')
    put('zg', ref['zg'] * sd, 'zg scaled with D')
    for key in ('xg', 'yg', 'xb', 'yb', 'zb', 'Ixz', 'Yrdot', 'Zqdot', 'CZ0', 'CM0'):
        if ref[key] == 0.0:
            put(key, 0.0, 'symmetric hull, as')
    put('Ix', ref['Ix'] * sm * sd ** 2, 'Ix scaled with m D^2')
    for key in ('Iy', 'Iz'):
        put(key, ref[key] * sm * sl ** 2, f'{key} scaled with m L^2')
    vol = rho_ratio * sd ** 2 * sl
    for key in ('Xudot', 'Yvdot', 'Zwdot'):
        put(key, ref[key] * vol, f'{key} scaled with rho D^2 L (slender body)')
    put('Kpdot', ref['Kpdot'] * vol * sd ** 2, 'Kpdot scaled with rho D^4 L')
    for key in ('Yrdot', 'Zqdot'):
        if ref[key] != 0.0:
            put(key, ref[key] * vol * sl, f'{key} scaled with rho D^2 L^2')
    for key in ('Mqdot', 'Nrdot'):
        put(key, ref[key] * vol * sl ** 2, f'{key} scaled with rho D^2 L^3 (slender body)')
    for key in ('Ksh', 'CZ0', 'CM0', 'CZuw', 'CZuq', 'CMuw', 'CMuq', 'CYuv', 'CYur', 'CNuv',
                'CNur', 'CLup', 'CZbar', 'CMbar', 'CYhelm', 'CNhelm'):
        if key not in how:
            put(key, ref[key], 'dimensionless, kept as the reference\'s (similar hull and fins'
                               '; identify it with auv ident)')
    # quadratic cross-flow drag (dimensional): 0.5 rho Cd D times the strip integral of x^k
    # over the length, so D L^(k+1) with k = 0 (Yvv, Zww), 1 (Mww, Nvv), 2 (Yrr, Zqq) and
    # 3 (Mqq, Nrr)
    for key, k in (('Yvv', 0), ('Zww', 0), ('Mww', 1), ('Nvv', 1), ('Yrr', 2), ('Zqq', 2),
                   ('Mqq', 3), ('Nrr', 3)):
        if key in values:
            put(key, ref[key] * sd * sl ** (k + 1),
                f'{key} scaled with rho D L^{k + 1} (cross-flow strip theory)')
    for key in ('thrust_max', 'thrust_min'):
        put(key, ref[key] * sd ** 2, f'{key} scaled with the drag at equal speed (~ D^2)')
    for key in ('bar_max', 'bar_rate', 'bar_tau', 'helm_max', 'helm_rate', 'helm_tau',
                'thrust_tau', 'rho', 'nu_water', 'g', 'depth_min', 'depth_max', 'dt'):
        put(key, ref[key], 'as')
    displaced = ref['B'] / ref['g'] * sd ** 2 * sl
    missing = [k for k in values if k not in how]
    assert not missing, missing
    notes = [f'fineness ratio L/D = {length / diameter:.2f} (reference {tag}: '
             f'{ref["L_ref"] / ref["diameter"]:.2f}); the further apart, the rougher the '
             'dimensionless coefficients',
             f'the hull at the reference\'s fullness displaces about {displaced:.3g} kg; the '
             f'given mass is {mass:.3g} kg (trim the ballast, or correct B after a trim test)']
    params = VehicleParams(name=name, values=values, sources=how, path='<estimated>',
                           description=f'Starting file for {name}: L = {length} m, D = '
                                       f'{diameter} m, m = {mass} kg; every value not given '
                                       f'is estimated from {tag} (auv vehicle-init)')
    # validated like any vehicle file (signs, positivity)
    parse_vehicle(vehicle_document(params), '<estimated>')
    return params, notes


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``auv vehicle-init``."""
    parser.add_argument('--length', type=float, required=True, help='hull length [m]')
    parser.add_argument('--diameter', type=float, required=True, help='hull diameter [m]')
    parser.add_argument('--mass', type=float, required=True, help='mass in air [kg]')
    parser.add_argument('--name', default='my_auv', help='vehicle name')
    parser.add_argument('--reference', default=str(config_path('remus100.yaml')),
                        help='vehicle file scaled from (default: config/remus100.yaml)')
    parser.add_argument('--out', required=True, help='vehicle file to write')


def run(args: argparse.Namespace) -> int:
    """Write the starting vehicle file; notes on stderr."""
    out = pathlib.Path(args.out)
    try:
        if out.exists():
            raise VehicleInitError(f'{out} exists already')
        params, notes = estimate(args.length, args.diameter, args.mass,
                                 load_vehicle(args.reference), args.name)
        save_vehicle(params, out)
    except (IdentError, ValueError, OSError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1
    for line in notes:
        print(line, file=sys.stderr)
    print(str(out))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``auv vehicle-init`` on its own."""
    parser = argparse.ArgumentParser(prog='auv vehicle-init',
                                     description=__doc__.splitlines()[0])
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())
