"""``auv ident BAG... --out DIR``: identify the hydrodynamic coefficients from bags.

Reads ``/auv/state`` and either ``/auv/hydrodynamic_forces`` (simulator bags) or the actuator
command topics (real logs: forces reconstructed from the motion), fits the report's section 2
regressions (:mod:`auv_ident.identify`) and writes the identified vehicle file, ``report.json``,
the fit figures and ``report.md`` (:mod:`auv_ident.report`). Progress goes to stderr; bad input
(damaged bag, missing topic, stamps out of order, too little excitation) is one line
``error: ...`` and exit status 1.
"""
from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from auv_contract import config_path
from auv_contract.jsonout import dumps
from auv_ident.errors import IdentError
from auv_ident.identify import EQUATIONS, ERROR_METHODS
from auv_ident.job import OUTPUT_ERROR_MODES, STRUCTURES, IdentOptions, run_ident
from auv_ident.motion import SOURCES, WINDOW_S
from auv_sim.cli_options import add_vehicle_option

#: Exit status when the identified model is not written (it predicts held-out data worse
#: than the base file, or diverges): not an error of the input.
NOT_WRITTEN = 3


def stderr_progress(text: str) -> None:
    """Progress line on stderr (overwritten in place on a terminal)."""
    end = '\r' if text.endswith('%') and sys.stderr.isatty() else '\n'
    print(text, file=sys.stderr, end=end, flush=True)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``auv ident``."""
    parser.add_argument('bags', nargs='+', metavar='BAG',
                        help='bag directories or .mcap files (with --map: the original logs)')
    parser.add_argument('--map', default=None, metavar='MAP',
                        help='read the original logs through this mapping file (as `auv '
                             'import` does, without writing a bag); forces from motion')
    add_vehicle_option(parser, default=str(config_path('a18m.yaml')), old_names=('--base',),
                       help_text='vehicle file the identified values replace')
    parser.add_argument('--out', required=True, help='output directory')
    parser.add_argument('--fit-c0', action='store_true',
                        help='fit CZ0 and CM0 too (default: fixed at the base values)')
    parser.add_argument('--fit-planes', action='store_true',
                        help='fit the dive plane\'s CZbar and CMbar too, from the plane\'s '
                             'part of the heave force and pitch moment (forces from motion; '
                             'default: fixed at the base values)')
    parser.add_argument('--bounds', action='store_true',
                        help='physical bounds (the default; kept for old scripts)')
    parser.add_argument('--unbounded', action='store_true',
                        help='no physical bounds (default: each coefficient within the sign '
                             'and range physics allows it, see docs/identification.md)')
    parser.add_argument('--no-priors', action='store_true',
                        help='the data alone (default: the posterior of the file\'s values, '
                             'each with a width set by its source, and the data)')
    parser.add_argument('--no-validation', action='store_true',
                        help='fit every sample and write without the held-out comparison '
                             'with the base file')
    parser.add_argument('--structure', choices=STRUCTURES, default='chosen',
                        help='the quadratic cross-flow structure of each equation: chosen by '
                             'held-out prediction (default), or the file\'s as it is')
    parser.add_argument('--output-error', choices=OUTPUT_ERROR_MODES, default='auto',
                        help='refine heave and pitch by output error (multiple shooting): '
                             'auto when the derivatives are poor (slow, quantised or '
                             'differenced logs; default), always, never')
    parser.add_argument('--source', choices=SOURCES, default='auto',
                        help='forces from the force topic, from the motion, or auto (the '
                             'topic when every bag has it)')
    parser.add_argument('--equations', nargs='+', choices=list(EQUATIONS), default=None,
                        help='equations to fit (default: all)')
    parser.add_argument('--errors', choices=ERROR_METHODS, default='hac',
                        help='covariance estimator of the standard errors (default: %(default)s; '
                             'see docs/identification.md)')
    parser.add_argument('--window', type=float, default=WINDOW_S,
                        help='derivative window for forces from motion [s] (default 1)')
    parser.add_argument('--no-nelder-mead', action='store_true',
                        help='skip the Nelder-Mead comparison in the report')
    parser.add_argument('--partial', action='store_true',
                        help='fit the equations the data identify and list the others under '
                             'not_identifiable (why, and what would fix it) instead of '
                             'stopping; the default with --map when --equations is not given')
    parser.add_argument('--strict', action='store_true',
                        help='with --map: refuse a row that does not parse or a log without a '
                             'usable segment (default: leave it out and say so)')


def options_from_args(args: argparse.Namespace) -> IdentOptions:
    """The :class:`auv_ident.job.IdentOptions` of parsed ``auv ident`` arguments.

    Raises
    ------
    IdentificationError
        An option out of its range (see :class:`auv_ident.job.IdentOptions`).
    """
    return IdentOptions(
        logs=tuple(str(b) for b in args.bags), out=str(args.out), vehicle=str(args.vehicle),
        map=args.map, fit_c0=args.fit_c0, fit_planes=args.fit_planes, bounds=not args.unbounded,
        priors=not args.no_priors, validation=not args.no_validation, structure=args.structure,
        output_error=args.output_error, source=args.source,
        equations=None if args.equations is None else tuple(args.equations),
        errors=args.errors, window=args.window, nelder_mead=not args.no_nelder_mead,
        partial=args.partial, strict=args.strict)


def run(args: argparse.Namespace) -> int:
    """Identify from the bags of ``args``; prints the coefficients as JSON on stdout. 0 when
    the vehicle file was written, :data:`NOT_WRITTEN` when it predicts worse than the base.

    Raises
    ------
    IdentError, ParameterError, OSError
        Bad input (:func:`auv_ident.job.run_ident`).
    """
    done = run_ident(options_from_args(args), stderr_progress)
    out = {name: {'value': c.value, 'std_error': c.std_error, 'ci95': list(c.ci95)}
           for name, c in done.result.coefficients.items()}
    print(dumps({'source': done.source, 'coefficients': out, 'files': done.files,
                      'validation': done.outcome.validation.verdict,
                      'written': done.written}, indent=2))
    return 0 if done.written else NOT_WRITTEN


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``auv ident`` on its own (errors as one line, exit 1)."""
    parser = argparse.ArgumentParser(prog='auv ident', description=__doc__.splitlines()[0])
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return run(args)
    except (IdentError, ValueError, OSError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1


if __name__ == '__main__':
    sys.exit(main())
