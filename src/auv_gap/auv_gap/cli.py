"""``auv gap --vehicle VEHICLE.yaml BAG... --out DIR``: sim-to-real gap diagnosis from bags.

Reads ``/auv/state`` and the actuator command topics of each bag (no force topic needed),
diagnoses the gap between the vehicle file and the logs, and writes ``report.json`` (the
contract of the architecture document), ``details.json``, ``report.md`` and PNG plots.
Exit status 0 on success; on bad input one line ``error: ...`` and status 1.
"""
from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time

from auv_gap.errors import GapError
from auv_logs.errors import LogError
from auv_sim.cli_options import add_vehicle_option


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``auv gap``."""
    parser.add_argument('bags', nargs='+', metavar='BAG',
                        help='bag directories or .mcap files of the real vehicle')
    parser.add_argument('--map', default=None, metavar='MAP',
                        help='read the original logs (BAG...) through this mapping file, as '
                             '`auv import` does, without writing a bag')
    add_vehicle_option(parser, required=True, old_names=('--model',),
                       help_text='the nominal vehicle file (e.g. config/a18m.yaml)')
    parser.add_argument('--out', required=True, metavar='DIR', help='output directory')
    parser.add_argument('--holdout', nargs='+', default=[], metavar='BAG',
                        help='bags (among BAG...) held out whole to score the effects; '
                             'default: every third window of every bag')
    parser.add_argument('--window', type=float, default=None, metavar='S',
                        help='free-run window [s]; runs restart from the log (default: 60, '
                             'shorter for a vehicle unstable without feedback: 4 e-folding '
                             'times of its fastest vertical-plane mode, at least 10)')
    parser.add_argument('--effects', nargs='+', default=None, metavar='NAME',
                        help='catalogue effects to try (default: all)')
    parser.add_argument('--top', type=int, default=3,
                        help='effects refined by free run and combined (default 3)')
    parser.add_argument('--no-plots', action='store_true', help='skip the PNG plots')
    parser.add_argument('--quiet', action='store_true', help='no progress lines')


def run(args: argparse.Namespace) -> int:
    """Run the diagnosis; 0 on success, 1 with ``error: ...`` on stderr on bad input."""
    from auv_gap.diagnose import diagnose
    from auv_gap.logs import GapLog, from_contract_arrays, load_bag, measured_fins_vehicle
    from auv_gap.report import write_report
    from auv_logs.limits import as_logged, describe
    from auv_sim.errors import ParameterError
    from auv_sim.params import load_vehicle

    start = time.monotonic()

    def say(msg: str) -> None:
        if not args.quiet:
            print(f'[{time.monotonic() - start:6.1f} s] {msg}', file=sys.stderr, flush=True)

    try:
        if args.window is not None and not args.window > 0:
            raise ValueError(f'--window must be > 0 s, got {args.window}')
        vehicle = load_vehicle(args.vehicle)
        bags = [str(b) for b in args.bags]
        norm = {str(pathlib.Path(b).resolve()): i for i, b in enumerate(bags)}
        held_bags = []
        for h in args.holdout:
            key = str(pathlib.Path(h).resolve())
            if key not in norm:
                raise ValueError(f'--holdout {h} is not one of the bags given')
            held_bags.append(norm[key])
        if held_bags and len(set(held_bags)) == len(bags):
            raise ValueError('--holdout cannot hold out every bag')
        logs: list[GapLog] = []
        held_logs: list[int] = []
        imports = []
        for i, b in enumerate(bags):
            say(f'reading {b}')
            if args.map is not None:
                from auv_logs.importer import contract_arrays, import_log
                from auv_logs.mapping import load_map

                imported = import_log(load_map(args.map), b)
                imports.append(dict(imported.report))
                pieces = from_contract_arrays(imported.name, contract_arrays(imported),
                                              [imported.report])
            else:
                pieces = load_bag(b)
            for piece in pieces:
                if i in held_bags:
                    held_logs.append(len(logs))
                logs.append(piece)
        unique = {id(lg.commands): lg.commands for lg in logs}
        vehicle, limits = as_logged(vehicle, list(unique.values()))
        for line in describe(limits):
            say(line)
        vehicle = measured_fins_vehicle(vehicle, logs)
        diag = diagnose(vehicle, logs, window=args.window, held_out_logs=held_logs,
                        effects=args.effects, top=args.top, progress=say)
        path = write_report(diag, args.out, plots=not args.no_plots)
        (path.parent / 'inputs.json').write_text(json.dumps(
            {'logged_outside_limits': limits, 'imports': imports}, indent=2) + '\n')
    except (GapError, LogError, ParameterError, ValueError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1
    r = diag.report
    say(f'verdict {r["verdict"]}' + (f', best {r["best"]}' if r['best'] else '')
        + f'; held-out depth RMS {r["held_out"]["rms_before"]["z"]:.3g} -> '
          f'{r["held_out"]["rms_after"]["z"]:.3g} m; wrote {path}')
    if not args.quiet:
        print(r['statement'], file=sys.stderr)
    return 0


def main(argv: list[str] | None = None) -> int:
    """Stand-alone entry point (the umbrella ``auv`` command maps ``gap`` here)."""
    parser = argparse.ArgumentParser(prog='auv gap', description=__doc__.split('\n')[0])
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())
