"""Command-line options every ``auv`` subcommand spells the same way.

The vehicle file is ``--vehicle VEHICLE.yaml`` in every command. Names it had in earlier
releases (``--model`` in ``auv gap``, ``--base`` in ``auv ident``) are still accepted, are not
shown in ``--help``, and set the same value.
"""
from __future__ import annotations

import argparse
from collections.abc import Sequence


def add_vehicle_option(parser: argparse.ArgumentParser, *, default: str | None = None,
                       required: bool = False, help_text: str = '',
                       old_names: Sequence[str] = ()) -> None:
    """Add ``--vehicle VEHICLE.yaml`` (the vehicle file, ``args.vehicle``) to ``parser``.

    Parameters
    ----------
    parser
        the subcommand's parser.
    default
        the file used when the option is not given (None: no default).
    required
        the option must be given.
    help_text
        what the file is for in this command.
    old_names
        former spellings (e.g. ``--model``), accepted silently.
    """
    what = help_text or 'the vehicle file'
    group = parser.add_mutually_exclusive_group(required=required)
    group.add_argument('--vehicle', default=default, metavar='VEHICLE.yaml',
                       help=what + (f' (default: {default})' if default else ''))
    for name in old_names:
        group.add_argument(name, dest='vehicle', default=argparse.SUPPRESS,
                           help=argparse.SUPPRESS)
