"""``auv run``: offline batch run (no ROS graph) written as a bag.

Either a scripted open-loop mission (``--mission surge|pitch|yaw|FILE``) or the closed loop of
the depth pilot (``--depth Z``: from a trim at ``--initial-depth``, fly to Z metres, the pilot
learning its plant with ``--learn``; the
thrust held at its trim value, or with ``--speed-hold TAU`` [s] the vehicle's own speed loop
holding ``--speed``). The bag
has the topics the graph records (``/auv/state`` measured, ``/auv/hydrodynamic_forces``, the
actuator and depth commands) stamped on simulated time; with ``--effects`` the simulated
vehicle differs from its model as the effects file says. Prints a JSON summary.
"""
from __future__ import annotations

import argparse

from auv_bringup.errors import RunError
from auv_bringup.options import check_number
from auv_contract import config_path
from auv_contract.jsonout import dumps
from auv_depth_lqr.closed_loop import run_closed_loop
from auv_depth_lqr.metrics import step_metrics
from auv_depth_lqr.pilot import PilotSettings
from auv_logs.simlog import SensorNoise, write_record
from auv_sim.environment import load_environment
from auv_sim.missions import load_mission, run_mission
from auv_sim.params import load_vehicle


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('--vehicle', default=str(config_path('a18m.yaml')),
                        help='vehicle file of the simulated vehicle and of the pilot '
                             '(default: config/a18m.yaml)')
    parser.add_argument('--effects', default=None, help='effects file of the "real" vehicle')
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument('--mission', help='open-loop mission: surge, pitch, yaw or a file')
    what.add_argument('--depth', type=float, help='closed loop: commanded depth [m]')
    parser.add_argument('--initial-depth', type=float, default=40.0, help='[m] (closed loop)')
    parser.add_argument('--speed', type=float, default=2.0, help='[m/s] (closed loop)')
    parser.add_argument('--duration', type=float, default=150.0, help='[s] (closed loop)')
    parser.add_argument('--weights', default='default', help='LQR weight preset')
    parser.add_argument('--water-speed', type=float, default=None,
                        help='[m/s] speed through the water the pilot is told (closed loop; '
                             'default: it schedules on the measured surge over ground)')
    parser.add_argument('--speed-hold', type=float, default=None, metavar='TAU',
                        help='[s] the vehicle\'s own speed loop holds --speed with this time '
                             'constant (closed loop; default: thrust held at its trim value, '
                             'so a buoyant vehicle slows down in a dive)')
    parser.add_argument('--learn', action='store_true',
                        help='the pilot learns what its vehicle file gets wrong while flying '
                             '(closed loop; the pilot node\'s parameter learn; off by default)')
    parser.add_argument('--noise', action='store_true',
                        help='add realistic sensor noise to the logged state')
    parser.add_argument('--seed', type=int, default=0,
                        help='seed of the sensor noise (with --noise; default: %(default)s)')
    parser.add_argument('--no-forces', action='store_true',
                        help='leave out /auv/hydrodynamic_forces, as a real vehicle log')
    parser.add_argument('--out', required=True, help='bag directory (or .mcap file) to write')


def check_options(args: argparse.Namespace) -> None:
    """Every number of ``auv run`` checked before anything runs (one-line CliError)."""
    check_number('--depth', args.depth, unit='m')
    check_number('--initial-depth', args.initial_depth, unit='m')
    check_number('--speed', args.speed, above=0.0, unit='m/s')
    check_number('--duration', args.duration, above=0.0, unit='s')
    check_number('--water-speed', args.water_speed, above=0.0, unit='m/s')
    check_number('--speed-hold', args.speed_hold, above=0.0, unit='s')
    check_number('--seed', args.seed, minimum=0)


def run(args: argparse.Namespace) -> int:
    check_options(args)
    params = load_vehicle(args.vehicle)
    env = load_environment(args.effects)
    noise = SensorNoise.realistic() if args.noise else None
    if args.mission:
        rec = run_mission(params, load_mission(args.mission), env)
        n = write_record(args.out, rec, forces=not args.no_forces, noise=noise, seed=args.seed)
        summary = {'bag': args.out, 'messages': n, 'mission': args.mission,
                   'duration_s': float(rec.t[-1] - rec.t[0])}
    else:
        for option, z in (('--depth', args.depth), ('--initial-depth', args.initial_depth)):
            if not params.depth_min <= z <= params.depth_max:
                raise RunError(f'{option} {z:g} m is outside the vehicle envelope '
                               f'[{params.depth_min:g}, {params.depth_max:g}] m')
        hold = args.speed_hold
        settings = PilotSettings(weights=args.weights, water_speed=args.water_speed,
                                 learn=args.learn)
        cl = run_closed_loop(params, [(0.0, args.depth)], args.duration,
                             z0=args.initial_depth, u0=args.speed, environment=env,
                             settings=settings, speed_time_constant=hold)
        rec = cl.record
        n = write_record(args.out, rec, forces=not args.no_forces, noise=noise, seed=args.seed,
                         depth_commands=[(0.0, args.depth)], bar_commands=(cl.bar_t, cl.bar))
        m = step_metrics(rec.t, rec.x[:, 2], rec.x[:, 4], rec.x[:, 10], rec.x[:, 12],
                         args.depth, bar_max=params.bar_max, u0=args.speed,
                         theta_max=settings.theta_max)
        summary = {'bag': args.out, 'messages': n, 'speed_hold_s': hold, 'learn': args.learn,
                   'metrics': m.as_dict()}
    print(dumps(summary, indent=2))
    return 0
