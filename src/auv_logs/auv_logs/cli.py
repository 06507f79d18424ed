"""``auv import --map MAP LOG... --out BAG``: real vehicles' logs -> a contract bag.

Reads each log (rosbag2 MCAP or sqlite3, ROS 1 bag, text log) through the mapping file
(:mod:`auv_logs.mapping`), converts it to the contract (``/auv/state`` NED/FRD and the
actuator command topics, SI units) and writes one bag whose ``metadata.yaml`` carries the
provenance (source files and their SHA-256, the map text, what was derived, held and left
out). The import report is printed as JSON on stdout; bad input is one line ``error: ...``
and exit status 1, with nothing written.

Logs as they come: a text row cut off mid-line (or any row that does not parse), a
non-finite value and a log with no usable segment (empty, surface data only) are left out,
each said in one line (stderr and the report's ``skipped`` and ``left_out``), and the batch
goes on; ``--strict`` refuses them instead. ``--vehicle`` bounds the plausibility checks by
the vehicle file's envelope (rated depth, top speed).
"""
from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

from auv_logs.errors import BagError, LogError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``auv import``."""
    parser.add_argument('logs', nargs='+', metavar='LOG',
                        help='bag directories, .mcap or ROS 1 .bag files, or text logs')
    parser.add_argument('--map', required=True, metavar='MAP',
                        help='mapping file (YAML, see docs/real-logs.md; examples in '
                             'config/maps/)')
    parser.add_argument('--out', required=True, metavar='BAG', help='contract bag to write')
    parser.add_argument('--strict', action='store_true',
                        help='refuse a row that does not parse, a non-finite value or a log '
                             'without a usable segment (default: leave it out and say so)')
    parser.add_argument('--vehicle', default=None, metavar='VEHICLE.yaml',
                        help='check depth and speed against this vehicle file\'s envelope '
                             '(default: physical limits only)')


def run(args: argparse.Namespace) -> int:
    """Import; 0 on success, 1 with ``error: ...`` on stderr on bad input."""
    from auv_logs.contract_bag import write_contract_bag
    from auv_logs.importer import import_logs
    from auv_logs.plausibility import envelope_of
    from auv_sim.errors import ParameterError
    from auv_sim.params import load_vehicle

    skipped: list[str] = []
    try:
        envelope = envelope_of(load_vehicle(args.vehicle)) if args.vehicle else None
        logmap, logs = import_logs(args.map, args.logs, strict=args.strict, envelope=envelope,
                                   skipped=skipped)
        prov = write_contract_bag(args.out, logmap, logs, skipped=skipped)
    except (LogError, BagError, OSError, ParameterError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1
    for line in skipped:
        print(line, file=sys.stderr)
    for lg in logs:
        r = lg.report
        print(f'{lg.name}: {len(lg.t)} state samples in {len(lg.segments)} segment(s)',
              file=sys.stderr)
        for line in [*r['derived'], *r['holds'], *r['left_out'], *r['notes']]:
            print(f'  {line}', file=sys.stderr)
    print(json.dumps({'out': str(args.out), 'imports': prov['imports'],
                      'skipped': prov['skipped'], 'sources': prov['sources']}, indent=2))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``auv import`` on its own."""
    parser = argparse.ArgumentParser(prog='auv import', description=__doc__.splitlines()[0])
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())
