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
* quadratic cross-flow drag (``Yvv, Zww, Mww, Nvv, Yrr, Zqq, Mqq, Nrr``): not scaled from
  another vehicle but estimated by cross-flow strip theory over this hull
  (:func:`auv_sim.hull.crossflow_coefficients`: a Myring profile of the given length and
  diameter, the cross-flow drag coefficient of a circular cylinder ``c_dc = 1.1``, Hoerner
  1965, as Prestero 2001, 3.3), in the water's density. (Scaling Prestero's ``Mqq`` by
  ``D L^4`` gives a 1.6 m, 0.15 m hull -309 kg m^2, 22 times the strip theory of its
  own hull: his ``Mqq`` is 25 times the strip theory of the REMUS hull, and his ``Zww`` agrees
  with it to 2 %.)
* the dive plane and the rudder, when the fin count and the area of one fin are given:
  ``CZbar = s n CL_alpha A / S_ref`` (the lift of ``n`` fins of area ``A`` per unit deflection,
  on this model's scaling), ``CL_alpha`` = :data:`FIN_LIFT_SLOPE` per rad (assumed, see
  there), the sign ``s`` of the reference's (the BAR convention), ``CMbar`` with the
  reference's lever arm as a fraction of the length (``CMbar / CZbar``); the rudder
  (``CYhelm``, ``CNhelm``) likewise with the same fins; else the reference's;
* water: ``--water salt`` (1025 kg/m^3, 1.19e-6 m^2/s: sea water of 35 g/kg at 15 degC) or
  ``fresh`` (999 kg/m^3, 1.14e-6 m^2/s at 15 degC), else the reference's;
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
from auv_sim.hull import CD_CROSSFLOW, CD_SOURCE, crossflow_coefficients
from auv_sim.params import (
    VehicleParams,
    load_vehicle,
    parse_vehicle,
    save_vehicle,
    vehicle_document,
)

#: Water by kind: density [kg/m^3], kinematic viscosity [m^2/s] and the source.
WATER = {'salt': (1025.0, 1.19e-6, 'sea water of 35 g/kg at 15 degC (UNESCO 1981; ITTC 2011 '
                                   'fresh and sea water properties)'),
         'fresh': (999.1, 1.14e-6, 'fresh water at 15 degC (ITTC 2011 fresh and sea water '
                                   'properties)')}
#: Lift slope of one control fin on its planform area [1/rad]: a low-aspect-ratio fin against
#: the hull (effective aspect ratio about twice its own from the hull's mirror image, 2-3:
#: 2.6-3.4 /rad by Whicker and Fehlner 1958); assumed, 3.0.
FIN_LIFT_SLOPE = 3.0


class VehicleInitError(IdentError, ValueError):
    """Bad dimensions or mass, or an output that exists already."""


def estimate(length: float, diameter: float, mass: float, reference: VehicleParams,
             name: str = 'my_auv', water: str | None = None, fin_count: int | None = None,
             fin_area: float | None = None) -> tuple[VehicleParams, list[str]]:
    """A vehicle from ``length`` [m], ``diameter`` [m], ``mass`` [kg] scaled from
    ``reference`` (see the module docstring), in ``water`` (``salt``, ``fresh`` or None: the
    reference's), with ``fin_count`` fins of ``fin_area`` [m^2] each per control plane when
    known; returns it and notes on the estimate."""
    for what, v in (('length', length), ('diameter', diameter), ('mass', mass)):
        if not (math.isfinite(v) and v > 0):
            raise VehicleInitError(f'--{what} must be a finite positive number, got {v}')
    if water is not None and water not in WATER:
        raise VehicleInitError(f'--water must be one of {", ".join(WATER)}, got {water!r}')
    if (fin_count is None) != (fin_area is None):
        raise VehicleInitError('give --fin-count and --fin-area together (the fins of one '
                               'control plane and the planform area of one fin)')
    if fin_count is not None and not (fin_count >= 1):
        raise VehicleInitError(f'--fin-count must be at least 1, got {fin_count}')
    if fin_area is not None and not (math.isfinite(fin_area) and fin_area > 0):
        raise VehicleInitError(f'--fin-area must be a finite positive area [m^2], got {fin_area}')
    if length < 3 * diameter:
        raise VehicleInitError(f'length {length} m is less than 3 diameters ({diameter} m): '
                               'not a torpedo-shaped hull')
    ref = reference.values
    sl = length / ref['L_ref']
    sd = diameter / ref['diameter']
    sm = mass / ref['m']
    rho = ref['rho'] if water is None else WATER[water][0]
    rho_ratio = rho / ref['rho']
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
    # quadratic cross-flow drag (dimensional): strip theory over this hull, not scaled
    strip = crossflow_coefficients(length, diameter, rho, CD_CROSSFLOW)
    for key, value in strip.items():
        values[key] = value
        how[key] = (f'estimated: cross-flow strip theory over a Myring hull of L = {length:g} '
                    f'm, D = {diameter:g} m (auv_sim.hull, Prestero 2001, 3.3), {CD_SOURCE}, '
                    f'rho = {rho:g} kg/m^3')
    if fin_count is not None and fin_area is not None:
        lift = fin_count * FIN_LIFT_SLOPE * fin_area / values['S_ref']
        fins = (f'{fin_count} fins of {fin_area:g} m^2 (given), lift slope '
                f'{FIN_LIFT_SLOPE:g}/rad each (assumed: low-aspect-ratio fin on the hull)')
        for zkey, mkey in (('CZbar', 'CMbar'), ('CYhelm', 'CNhelm')):
            sign = 1.0 if ref[zkey] > 0 else -1.0
            arm = ref[mkey] / ref[zkey] if ref[zkey] != 0.0 else 0.0
            put(zkey, sign * lift, f'{fins}, n CL_alpha A / S_ref with the sign convention')
            put(mkey, sign * lift * arm,
                f'{zkey} times the lever arm fraction {mkey}/{zkey} = {arm:.3g}')
    for key in ('thrust_max', 'thrust_min'):
        put(key, ref[key] * sd ** 2, f'{key} scaled with the drag at equal speed (~ D^2)')
    for key in ('bar_max', 'bar_rate', 'bar_tau', 'helm_max', 'helm_rate', 'helm_tau',
                'thrust_tau', 'g', 'depth_min', 'depth_max', 'dt'):
        put(key, ref[key], 'as')
    if water is None:
        put('rho', ref['rho'], 'as')
        put('nu_water', ref['nu_water'], 'as')
    else:
        values['rho'], values['nu_water'] = WATER[water][0], WATER[water][1]
        how['rho'] = how['nu_water'] = f'given: {water} water, {WATER[water][2]}'
    displaced = ref['B'] / ref['g'] * sd ** 2 * sl * rho_ratio
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
    parser.add_argument('--water', choices=sorted(WATER), default=None,
                        help='the water the vehicle dives in (density and viscosity; default: '
                             'the reference\'s)')
    parser.add_argument('--fin-count', type=int, default=None,
                        help='fins of one control plane (dive plane; the rudder assumed alike)')
    parser.add_argument('--fin-area', type=float, default=None,
                        help='planform area of one fin [m^2] (with --fin-count: the plane\'s '
                             'control derivatives from the fins instead of the reference\'s)')
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
                                 load_vehicle(args.reference), args.name, water=args.water,
                                 fin_count=args.fin_count, fin_area=args.fin_area)
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
