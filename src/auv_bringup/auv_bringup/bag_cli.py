"""``auv bag info|repair``: look at a bag, and make a damaged one readable again.

* ``auv bag info BAG``: topics, types, message counts and time span, read from the messages
  themselves (not from ``metadata.yaml``); a damaged bag is read up to the damage, which is
  said (exit 0: the command is for looking).
* ``auv bag repair BAG --out NEW``: every whole message of a damaged bag (a recorder killed,
  a copy cut short) written to the new bag ``NEW``, which every ``auv`` command, rosbags and
  the ``mcap`` tools read; the damaged bag is left as it is (:mod:`auv_bag.repair`). Prints
  what was recovered per topic and where the damage was.
"""
from __future__ import annotations

import argparse
import sys

from auv_bringup.cli import CliError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``auv bag``."""
    sub = parser.add_subparsers(dest='action', metavar='ACTION', required=True)
    info = sub.add_parser('info', help='topics, counts and time span of a bag (read to the '
                          'damage if it is damaged)')
    info.add_argument('bag', help='bag directory or .mcap file')
    repair = sub.add_parser('repair', help="a damaged bag's whole messages written to a new, "
                            'readable bag')
    repair.add_argument('bag', help='the damaged bag (directory or .mcap file)')
    repair.add_argument('--out', required=True, metavar='NEW',
                        help='the repaired bag to create (directory, or a .mcap file name)')
    repair.add_argument('--compression', choices=['zstd', 'lz4', 'none'], default='zstd',
                        help='chunk compression of the new bag (default: zstd)')


def run(args: argparse.Namespace) -> int:
    from auv_bag import BagError, bag_topics, read_messages, repair_bag

    if args.action == 'repair':
        report = repair_bag(args.bag, args.out, compression=args.compression)
        print(report.text(), file=sys.stderr)
        return 0
    topics = bag_topics(args.bag)
    if not topics:
        raise CliError(f'bag {args.bag} holds no topic')
    counts = dict.fromkeys(topics, 0)
    first: dict[str, int] = {}
    last: dict[str, int] = {}
    damage = None
    try:
        for m in read_messages(args.bag, decode=False):
            counts[m.topic] = counts.get(m.topic, 0) + 1
            first.setdefault(m.topic, m.log_time)
            last[m.topic] = m.log_time
    except BagError as exc:
        damage = str(exc)
        if 'whole messages before the damage' not in damage:
            raise
    for topic, n in sorted(counts.items()):
        span = (f'log time {first[topic] / 1e9:.3f} .. {last[topic] / 1e9:.3f} s'
                if topic in first else 'no message')
        print(f'{topic}  {topics.get(topic, "?")}  {n} messages  {span}')
    if damage:
        print(f'damaged: {damage}')
    return 0
