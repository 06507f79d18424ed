"""``auv gap --vehicle VEHICLE.yaml BAG... --out DIR``: sim-to-real gap diagnosis from bags.

Reads ``/auv/state`` and the actuator command topics of each bag (no force topic needed),
diagnoses the gap between the vehicle file and the logs, and writes ``report.json`` (the
contract of the architecture document), ``details.json``, ``report.md`` and PNG plots.
Exit status 0 on success; on bad input one line ``error: ...`` and status 1.
"""
from __future__ import annotations

import argparse
import sys
import time

from auv_gap.errors import GapError
from auv_gap.job import GapOptions, run_gap
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
                        help='window [s] the logs are cut into and held out by; free runs '
                             'restart from the log at each (default: chosen from the data, '
                             'the longest up to 60 s that gives 4 windows; on a vehicle '
                             'unstable without feedback the runs restart within it every 4 '
                             'e-folding times of its fastest vertical-plane mode)')
    parser.add_argument('--ranges', default=None, metavar='FILE',
                        help='typical and possible ranges of the effect parameters (default '
                             'config/plausible_ranges.yaml; see docs/gap-diagnosis.md)')
    parser.add_argument('--strict', action='store_true',
                        help='with --map: refuse a row that does not parse or a log without a '
                             'usable segment (default: leave it out and say so)')
    parser.add_argument('--effects', nargs='+', default=None, metavar='NAME',
                        help='catalogue effects to try (default: all)')
    parser.add_argument('--top', type=int, default=3,
                        help='effects refined by free run and combined (default 3)')
    parser.add_argument('--no-plots', action='store_true', help='skip the PNG plots')
    parser.add_argument('--quiet', action='store_true', help='no progress lines')


def options_from_args(args: argparse.Namespace) -> GapOptions:
    """The :class:`auv_gap.job.GapOptions` of parsed ``auv gap`` arguments.

    Raises
    ------
    GapError
        An option out of its range (see :class:`auv_gap.job.GapOptions`).
    """
    return GapOptions(
        logs=tuple(str(b) for b in args.bags), vehicle=str(args.vehicle), out=str(args.out),
        map=args.map, holdout=tuple(str(h) for h in args.holdout), window=args.window,
        ranges=args.ranges, strict=args.strict,
        effects=None if args.effects is None else tuple(args.effects), top=args.top,
        plots=not args.no_plots)


def run(args: argparse.Namespace) -> int:
    """Run the diagnosis; 0 on success, 1 with ``error: ...`` on stderr on bad input."""
    from auv_sim.errors import ParameterError

    start = time.monotonic()

    def say(msg: str) -> None:
        if not args.quiet:
            print(f'[{time.monotonic() - start:6.1f} s] {msg}', file=sys.stderr, flush=True)

    try:
        done = run_gap(options_from_args(args), say)
    except (GapError, LogError, ParameterError, ValueError, OSError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1
    r = done.diagnosis.report
    say(f'verdict {r["verdict"]}' + (f', best {r["best"]}' if r['best'] else '')
        + f'; held-out depth RMS {r["held_out"]["rms_before"]["z"]:.3g} -> '
          f'{r["held_out"]["rms_after"]["z"]:.3g} m; wrote {done.path}')
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
