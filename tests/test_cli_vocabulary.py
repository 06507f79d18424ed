"""One vocabulary at the surface: every option of every ``auv`` subcommand has help, the
vehicle file is ``--vehicle`` everywhere, and values are in SI units."""
from __future__ import annotations

import argparse
import importlib

import pytest

from auv_bringup.cli import SUBCOMMANDS

FORMER_VEHICLE_NAMES = ('--model', '--base', '--vehicle-file')


def _parsers(name: str) -> list[tuple[str, argparse.ArgumentParser]]:
    """The subcommand's parser and, for commands with sub-subcommands, theirs."""
    parser = argparse.ArgumentParser(prog=f'auv {name}')
    importlib.import_module(SUBCOMMANDS[name].module).add_arguments(parser)
    found = [(f'auv {name}', parser)]
    for action in parser._actions:  # argparse keeps no public list of its actions
        if isinstance(action, argparse._SubParsersAction):
            found += [(f'auv {name} {sub}', p) for sub, p in action.choices.items()]
    return found


@pytest.mark.parametrize('name', sorted(SUBCOMMANDS))
def test_every_option_has_help_and_one_name_for_the_vehicle(name: str) -> None:
    for prog, parser in _parsers(name):
        for action in parser._actions:
            if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
                continue
            label = '/'.join(action.option_strings) or action.dest
            if action.help == argparse.SUPPRESS:
                continue      # a former spelling, accepted but not shown
            assert action.help, f'{prog}: {label} has no help'
            for option in action.option_strings:
                assert option not in FORMER_VEHICLE_NAMES, \
                    f'{prog}: {option} shown; the vehicle file is --vehicle'
                assert not option.endswith('-deg'), f'{prog}: {option} is not in SI units'


def test_former_vehicle_option_names_still_work() -> None:
    parsers = dict(_parsers('ident'))
    args = parsers['auv ident'].parse_args(['bag', '--base', 'v.yaml', '--out', 'o'])
    assert args.vehicle == 'v.yaml'
    args = parsers['auv ident'].parse_args(['bag', '--out', 'o'])
    assert args.vehicle.endswith('a18m.yaml')
