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
import json
import pathlib
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

from auv_contract import COMMAND_TOPICS, MEASURED_TOPICS, config_path
from auv_ident.errors import IdentError, IdentificationError, NotIdentifiableError
from auv_ident.identify import (
    EQUATIONS,
    ERROR_METHODS,
    SIGN_BOUNDS,
    ForceRecord,
    Identification,
    compare_nelder_mead,
    identify,
)
from auv_ident.motion import SOURCES, WINDOW_S, choose_source, needed_topics, records_from_topics
from auv_ident.report import write_outputs
from auv_sim.cli_options import add_vehicle_option
from auv_sim.params import VehicleParams, load_vehicle

Progress = Callable[[str], None]


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
                        help='bounded solve with physical signs (Ksh >= 0; CZuw, CMuq, CYuv, '
                             'CNur <= 0)')
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


def load_records(bags: Sequence[str], base: VehicleParams, source: str = 'auto',
                 window_s: float = WINDOW_S, progress: Progress | None = None,
                 limits: dict[str, Any] | None = None) -> tuple[list[ForceRecord], str]:
    """Read the bags and build force records; returns them and the source used.

    ``auto`` uses the force topic when every bag has it, else the motion of every bag.
    Logged commands outside the vehicle file's limits are used as logged and counted into
    ``limits`` (see :mod:`auv_logs.limits`).
    """
    limits = {} if limits is None else limits
    from auv_bag import bag_topics, read_arrays

    present = [set(bag_topics(b)) for b in bags]
    if source == 'auto':
        source = 'forces' if all(choose_source(p) == 'forces' for p in present) else 'motion'
    topics = needed_topics(source)
    records: list[ForceRecord] = []
    for bag, have in zip(bags, present):
        name = pathlib.Path(bag).name
        if name.endswith('.mcap'):
            name = name[:-5]
        last = [-1]

        def report(done: int, total: int, bag: str = bag, last: list[int] = last) -> None:
            pct = int(100 * done / total) if total else 100
            if progress is not None and pct // 25 != last[0] // 25:
                last[0] = pct
                progress(f'reading {bag}: {pct}%')

        t0 = time.perf_counter()
        measured = [tp for tp in MEASURED_TOPICS.values() if tp in have] \
            if source == 'motion' else []
        arrays = read_arrays(bag, topics + measured, progress=report)
        if progress is not None:
            n = sum(len(a) for a in arrays.values())
            progress(f'read {bag}: {n} messages in {time.perf_counter() - t0:.2f} s')
        records += records_as_logged(arrays, base, source, name, window_s, limits)
    return records, source


def records_as_logged(arrays: Any, base: VehicleParams, source: str, name: str,
                       window_s: float, limits: dict[str, Any]) -> list[ForceRecord]:
    """Force records with the actuator limits widened to the logged commands
    (:mod:`auv_logs.limits`: used as logged, never clipped); what lay outside the vehicle
    file's limits is merged into ``limits`` (channel -> count, total, range)."""
    from auv_logs.limits import as_logged

    commands = {ch: (arrays[tp]['t'], arrays[tp]['value']) for ch, tp in COMMAND_TOPICS.items()
                if tp in arrays}
    params, found = as_logged(base, [commands])
    for ch, r in found.items():
        old = limits.get(ch)
        limits[ch] = r if old is None else {**r, 'count': old['count'] + r['count'],
                                            'total': old['total'] + r['total'],
                                            'min': min(old['min'], r['min']),
                                            'max': max(old['max'], r['max'])}
    return records_from_topics(arrays, params, source, name=name, window_s=window_s)


#: Equations whose regressors need a state signal: not identifiable when it was only assumed.
_REGRESSOR_NEEDS = {'sway': 'v', 'yaw': 'v'}
#: Equations whose reconstructed force needs a signal (Coriolis terms): biased in turns when
#: it was only assumed (the surge force holds (m - Yvdot) v r).
_FORCE_NEEDS = {'surge': 'v'}


def unsupported_equations(imports: Sequence[dict[str, Any]], requested: Sequence[str] | None
                           ) -> tuple[list[str], dict[str, str]]:
    """Equations to fit, and why others are left out, when the import only assumed a signal
    (``v`` = 0 with no DVL or position). Sway and yaw requested explicitly: an error; surge
    requested explicitly: fitted, with the warning in the returned reasons."""
    assumed = {line.split(':')[0] for imp in imports for line in imp['derived']
               if 'assumed' in line}
    out: dict[str, str] = {}
    keep = []
    for eq in requested or EQUATIONS:
        sig = _REGRESSOR_NEEDS.get(eq)
        if sig in assumed:
            why = (f'{sig} was not logged (assumed 0 in the import); log it (a DVL, odometry '
                   'twist or position fixes) to identify this equation')
            if requested is not None:
                raise NotIdentifiableError(f'{eq}: {why}')
            out[eq] = why
            continue
        sig = _FORCE_NEEDS.get(eq)
        if sig in assumed:
            why = (f'{sig} was not logged (assumed 0): its Coriolis term is missing from the '
                   'reconstructed force, which biases the fit wherever the vehicle turns')
            if requested is None:
                out[eq] = why + '; left out (ask for it with --equations on straight runs)'
                continue
            out[eq] = why + '; fitted as asked: use straight runs only'
        keep.append(eq)
    if not keep:
        raise NotIdentifiableError('no equation can be identified from these logs: '
                                   + '; '.join(f'{k}: {v}' for k, v in out.items()))
    return keep, out


def bag_imports(bags: Sequence[str]) -> list[dict[str, Any]]:
    """The import reports in the provenance of bags ``auv import`` wrote (none for others):
    the same knowledge of derived and assumed signals as ``--map`` gives."""
    from auv_logs.importer import read_provenance

    out: list[dict[str, Any]] = []
    for bag in bags:
        prov = read_provenance(bag) if pathlib.Path(bag).is_dir() else None
        out += [dict(rep) for rep in (prov or {}).get('imports', [])]
    return out


def load_records_from_map(map_path: str, logs: Sequence[str], base: VehicleParams,
                          window_s: float = WINDOW_S, progress: Progress | None = None,
                          limits: dict[str, Any] | None = None
                          ) -> tuple[list[ForceRecord], list[dict[str, Any]]]:
    """Import the original logs through a map (:mod:`auv_logs`) into the contract's
    arrays and build force records from motion exactly as from the imported bag; returns the
    records and each log's import report."""
    from auv_logs.importer import contract_arrays, import_logs

    _, imported = import_logs(map_path, logs)
    records: list[ForceRecord] = []
    for lg in imported:
        if progress is not None:
            progress(f'imported {lg.name}: {len(lg.t)} state samples, '
                     f'{len(lg.segments)} segment(s)')
        records += records_as_logged(contract_arrays(lg), base, 'motion', lg.name, window_s,
                                      {} if limits is None else limits)
    return records, [dict(lg.report) for lg in imported]


def identify_and_report(records: Sequence[ForceRecord], base: VehicleParams, out: str,
                        bags: Sequence[str], *, fit_c0: bool = False, bounds: bool = False,
                        errors: str = 'hac', equations: Sequence[str] | None = None,
                        nelder_mead: bool = True, progress: Progress | None = None,
                        extra: dict[str, Any] | None = None, partial: bool = False,
                        fit_planes: bool = False) -> tuple[Identification, dict[str, str]]:
    """Fit, compare with Nelder-Mead (optional) and write every output into ``out``
    (``partial``: see :func:`auv_ident.identify.identify`)."""
    if progress is not None:
        progress(f'fitting {", ".join(equations or EQUATIONS)} on {len(records)} record(s), '
                 f'{sum(len(r.t) for r in records)} samples')
    t0 = time.perf_counter()
    result = identify(records, base, equations=equations, fit_offsets=fit_c0,
                      bounds=SIGN_BOUNDS if bounds else None, errors=errors, partial=partial,
                      fit_planes=fit_planes)
    if progress is not None:
        progress(f'fitted in {time.perf_counter() - t0:.2f} s')
        for eq, why in result.not_identifiable.items():
            progress(f'{eq} left out: {why}')
    extra = dict(extra or {})
    if result.not_identifiable:
        extra['not_identifiable'] = {**result.not_identifiable,
                                     **extra.get('not_identifiable', {})}
    sources = {ch: src for r in records for ch, src in r.actuators.items()}
    if sources:
        extra['actuators'] = sources
    nm = None
    if nelder_mead:
        t0 = time.perf_counter()
        nm = compare_nelder_mead(records, result)
        if progress is not None:
            progress(f'Nelder-Mead comparison in {time.perf_counter() - t0:.2f} s')
    files = write_outputs(result, out, bags, nm, extra)
    return result, files


def run(args: argparse.Namespace) -> int:
    """Identify from the bags of ``args``; prints the coefficients as JSON on stdout."""
    base = load_vehicle(args.vehicle)
    if not (args.window > 0):
        raise IdentificationError(f'--window must be > 0 s, got {args.window}')
    limits: dict[str, Any] = {}
    extra: dict[str, Any] = {}
    partial = args.partial or (args.map is not None and args.equations is None)
    if args.map is not None:
        if args.source == 'forces':
            raise IdentificationError('--map logs have no force topic: use --source motion')
        records, extra['imports'] = load_records_from_map(
            args.map, args.bags, base, args.window, stderr_progress, limits)
        source = 'motion'
        args.equations, extra['not_identifiable'] = unsupported_equations(
            extra['imports'], args.equations)
        for eq, why in extra['not_identifiable'].items():
            stderr_progress(f'{eq}: {why}')
    else:
        records, source = load_records(args.bags, base, args.source, args.window,
                                       stderr_progress, limits)
        imports = bag_imports(args.bags)
        if imports:   # bags `auv import` wrote: what their imports derived or assumed
            partial = args.partial or args.equations is None
            extra['imports'] = imports
            args.equations, extra['not_identifiable'] = unsupported_equations(
                imports, args.equations)
            for eq, why in extra['not_identifiable'].items():
                stderr_progress(f'{eq}: {why}')
    stderr_progress(f'force source: {source}')
    from auv_logs.limits import describe
    for line in describe(limits):
        stderr_progress(line)
    extra['logged_outside_limits'] = limits
    result, files = identify_and_report(
        records, base, args.out, args.bags, fit_c0=args.fit_c0, bounds=args.bounds,
        errors=args.errors, equations=args.equations, nelder_mead=not args.no_nelder_mead,
        progress=stderr_progress, extra=extra, partial=partial, fit_planes=args.fit_planes)
    out = {name: {'value': c.value, 'std_error': c.std_error, 'ci95': list(c.ci95)}
           for name, c in result.coefficients.items()}
    print(json.dumps({'source': source, 'coefficients': out, 'files': files}, indent=2))
    return 0


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
