"""The umbrella ``auv`` command: one subcommand per tool, imported only when it runs.

A subcommand is a module exposing ``add_arguments(parser)`` and ``run(args) -> int`` (the exit
status). :data:`SUBCOMMANDS` maps each name to its module and a one-line summary; a package
plugs a new tool in by adding an entry. Errors of the project's own exception families (any
exception class defined in a module whose name starts with ``auv_``) print one line
``error: ...`` on stderr and exit 1; Ctrl-C exits 130.
"""
from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable, Sequence
from types import ModuleType
from typing import NamedTuple

from auv_contract.dds import use_dds_profile


class CliError(Exception):
    """Bad input to a command of auv_bringup (bad argument value, nothing to talk to)."""


class Subcommand(NamedTuple):
    module: str
    summary: str


#: name -> (module, summary). Modules are imported lazily, when their subcommand runs.
SUBCOMMANDS: dict[str, Subcommand] = {
    'sim': Subcommand('auv_sim.node', 'the simulator node'),
    'pilot': Subcommand('auv_depth_lqr.node', 'the LQR depth-pilot node'),
    'ident-node': Subcommand('auv_ident.node', 'identification node fitting from live topics'),
    'launch': Subcommand('auv_bringup.launch', 'start the node graph as processes'),
    'record': Subcommand('auv_bringup.record_node', 'record topics to an MCAP bag'),
    'foxglove': Subcommand('auv_bringup.foxglove_node', 'live topics on a Foxglove WebSocket'),
    'play': Subcommand('auv_bringup.play_node', 'replay a bag on its topics'),
    'bag': Subcommand('auv_bringup.bag_cli', 'look at a bag; repair a damaged one'),
    'depth': Subcommand('auv_bringup.depth', "command a depth (m, positive down), wait for "
                        "the pilot's answer"),
    'run': Subcommand('auv_bringup.run', 'offline batch run written as a bag'),
    'mission': Subcommand('auv_bringup.mission_node', 'fly a scripted mission through the graph'),
    'design': Subcommand('auv_depth_lqr.cli', 'trim, linearisation and LQR gains as JSON'),
    'ident': Subcommand('auv_ident.cli', 'identify coefficients from bags'),
    'gap': Subcommand('auv_gap.cli', 'sim-to-real gap diagnosis'),
    'import': Subcommand('auv_logs.cli', 'real logs through a map -> contract bag'),
    'vehicle-init': Subcommand('auv_ident.vehicle_init', 'starting vehicle file from L, D, m'),
    'campaign': Subcommand('auv_campaign.cli', 'ident/gap over many logs, Monte Carlo'),
    'demo': Subcommand('auv_bringup.demo', 'the end-to-end demonstration'),
}

EXIT_ERROR = 1
EXIT_INTERRUPTED = 130


def is_project_error(exc: BaseException) -> bool:
    """True if ``exc`` belongs to one of the project's exception families."""
    return any(cls.__module__.startswith('auv_') for cls in type(exc).__mro__)


def load(name: str) -> ModuleType:
    """Import the module of subcommand ``name``.

    Raises
    ------
    CliError
        unknown subcommand, or its module cannot be imported or lacks
        ``add_arguments``/``run``.
    """
    entry = SUBCOMMANDS.get(name)
    if entry is None:
        raise CliError(f'unknown subcommand {name!r} (try: auv --help)')
    try:
        module = importlib.import_module(entry.module)
    except ImportError as exc:
        raise CliError(f'subcommand {name} is not available: {exc}') from None
    for attr in ('add_arguments', 'run'):
        if not callable(getattr(module, attr, None)):
            raise CliError(f'subcommand {name} is not available: {entry.module} has no '
                           f'{attr}()')
    return module


def _top_parser() -> argparse.ArgumentParser:
    width = max(len(name) for name in SUBCOMMANDS)
    lines = [f'  {name:<{width}}  {entry.summary}' for name, entry in SUBCOMMANDS.items()]
    return argparse.ArgumentParser(
        prog='auv',
        description='Depth control of torpedo AUVs: simulate, control, record, identify.',
        epilog='subcommands:\n' + '\n'.join(lines) + '\n\nEach subcommand has --help.',
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )


def run_module(module: ModuleType, prog: str, argv: Sequence[str], description: str = '') -> int:
    """Parse ``argv`` with the module's arguments and run it, mapping errors to exit codes."""
    parser = argparse.ArgumentParser(prog=prog, description=description or (module.__doc__
                                     and module.__doc__.strip().splitlines()[0]))
    module.add_arguments(parser)
    args = parser.parse_args(list(argv))
    return _guarded(lambda: int(module.run(args) or 0))


def _guarded(call: Callable[[], int]) -> int:
    try:
        return call()
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
    except Exception as exc:
        if is_project_error(exc):
            print(f'error: {exc}', file=sys.stderr)
            return EXIT_ERROR
        raise


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``auv``: ``auv SUBCOMMAND [options]``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ('-h', '--help'):
        _top_parser().print_help()
        return 0 if argv else 2
    name, rest = argv[0], argv[1:]
    use_dds_profile()  # before this process's first participant (auv_contract.dds)
    try:
        module = load(name)
    except CliError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return EXIT_ERROR
    try:
        return run_module(module, f'auv {name}', rest, SUBCOMMANDS[name].summary)
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED


def standalone(module_name: str, prog: str) -> int:
    """Entry point for a subcommand run on its own (``ros2 run auv_bringup recorder``).

    ROS arguments (``--ros-args ...``) are left out of parsing.
    """
    argv = sys.argv[1:]
    if '--ros-args' in argv:
        argv = argv[:argv.index('--ros-args')]
    use_dds_profile()
    module = importlib.import_module(module_name)
    try:
        return run_module(module, prog, argv)
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED


if __name__ == '__main__':
    sys.exit(main())
