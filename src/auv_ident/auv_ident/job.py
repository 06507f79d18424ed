"""The identification of ``auv ident`` as one library call: :class:`IdentOptions` in,
:class:`IdentRun` out (:func:`run_ident`).

The logs are read (contract bags, or original logs through a mapping file:
:mod:`auv_logs`), turned into force records (:mod:`auv_ident.motion`), identified, refined and
validated (:func:`auv_ident.workflow.run_identification`) and written into the output
directory (:mod:`auv_ident.report`). ``auv ident``, the identification node and campaigns
(:mod:`auv_campaign.tasks`) are adapters over these objects. Units: SI; the state in NED/FRD
(:data:`auv_contract.STATE_FIELDS`).
"""
from __future__ import annotations

import dataclasses
import math
import pathlib
import time
from collections.abc import Callable, Sequence
from typing import Any

from auv_contract import COMMAND_TOPICS, MEASURED_TOPICS, config_path
from auv_ident.errors import IdentificationError, NotIdentifiableError
from auv_ident.identify import (
    EQUATIONS,
    ERROR_METHODS,
    ForceRecord,
    Identification,
    compare_nelder_mead,
)
from auv_ident.motion import (
    SOURCES,
    WINDOW_S,
    choose_source,
    needed_topics,
    records_from_topics,
    shared_actuator_tracks,
)
from auv_ident.report import write_outputs
from auv_ident.workflow import Outcome, run_identification
from auv_sim.params import VehicleParams, load_vehicle

Progress = Callable[[str], None]
#: Ways the quadratic cross-flow structure of each equation is set: chosen by held-out
#: prediction, or the vehicle file's as it is.
STRUCTURES = ('chosen', 'file')
#: When the heave and pitch coefficients are refined by output error.
OUTPUT_ERROR_MODES = ('auto', 'always', 'never')


@dataclasses.dataclass(frozen=True)
class IdentOptions:
    """What to identify from which logs, and how (the options of ``auv ident``).

    Raises
    ------
    IdentificationError
        On construction: no log, a derivative window that is not a finite time > 0 s, an
        unknown source, structure, output-error mode, equation or covariance estimator, or
        ``--map`` logs asked for the force topic.
    """

    logs: tuple[str, ...]
    """Contract bags (directories or ``.mcap`` files), or original logs with :attr:`map`."""
    out: str
    """Output directory."""
    vehicle: str = str(config_path('a18m.yaml'))
    """Vehicle file whose identified values are replaced (the base and the priors)."""
    map: str | None = None
    """Mapping file the original logs are read through (forces then from the motion)."""
    fit_c0: bool = False
    """Fit ``CZ0`` and ``CM0`` too."""
    fit_planes: bool = False
    """Fit the dive plane's ``CZbar`` and ``CMbar`` too."""
    bounds: bool = True
    """Keep each coefficient within the sign and range physics allows."""
    priors: bool = True
    """Fit the posterior of the file's values and the data (False: the data alone)."""
    validation: bool = True
    """Hold windows out and write the model only if it predicts them no worse than the base."""
    structure: str = 'chosen'
    """Quadratic cross-flow structure: one of :data:`STRUCTURES`."""
    output_error: str = 'auto'
    """Output-error refinement: one of :data:`OUTPUT_ERROR_MODES`."""
    source: str = 'auto'
    """Forces from the force topic, the motion, or ``auto`` (:data:`auv_ident.motion.SOURCES`)."""
    equations: tuple[str, ...] | None = None
    """Equations to fit (None: all the data support)."""
    errors: str = 'hac'
    """Covariance estimator of the standard errors (:data:`auv_ident.identify.ERROR_METHODS`)."""
    window: float = WINDOW_S
    """Derivative window for forces from the motion [s]."""
    nelder_mead: bool = True
    """Compare with a Nelder-Mead fit in the report."""
    partial: bool = False
    """Fit the equations the data identify and list the others (the default with a map)."""
    strict: bool = False
    """With :attr:`map`: refuse a row that does not parse or a log without a usable segment
    (default: leave it out and say so, in the progress lines and the report's ``skipped``)."""

    def __post_init__(self) -> None:
        if not self.logs:
            raise IdentificationError('no log given')
        if not (math.isfinite(self.window) and self.window > 0):
            raise IdentificationError(f'--window must be > 0 s, got {self.window}')
        for name, value, allowed in (('--source', self.source, SOURCES),
                                     ('--structure', self.structure, STRUCTURES),
                                     ('--output-error', self.output_error, OUTPUT_ERROR_MODES),
                                     ('--errors', self.errors, ERROR_METHODS)):
            if value not in allowed:
                raise IdentificationError(f'{name} must be one of {", ".join(allowed)}, '
                                          f'got {value!r}')
        unknown = [eq for eq in self.equations or () if eq not in EQUATIONS]
        if unknown:
            raise IdentificationError(f'unknown equation(s) {", ".join(unknown)}; known: '
                                      f'{", ".join(EQUATIONS)}')
        if self.map is not None and self.source == 'forces':
            raise IdentificationError('--map logs have no force topic: use --source motion')


@dataclasses.dataclass(frozen=True)
class IdentRun:
    """The outcome of :func:`run_ident`."""

    result: Identification
    """The identified coefficients and fits."""
    outcome: Outcome
    """How they were obtained and validated (:attr:`Outcome.validation` says if written)."""
    files: dict[str, str]
    """Files written (kind -> path)."""
    source: str
    """Where the forces came from: ``forces`` or ``motion``."""
    imports: list[dict[str, Any]]
    """Import reports of the logs (original logs, or bags ``auv import`` wrote)."""
    skipped: list[str] = dataclasses.field(default_factory=list)
    """Logs left out, one line each (with a map: cut off, empty or without a usable
    segment)."""

    @property
    def written(self) -> bool:
        """Whether the identified vehicle file was written (it predicts held-out data no
        worse than the base)."""
        return bool(self.outcome.validation.written)


def run_ident(opts: IdentOptions, progress: Progress | None = None) -> IdentRun:
    """Read, identify, validate and write (see the module docstring); the actuator positions
    of each log are integrated once (:func:`auv_ident.motion.shared_actuator_tracks`).

    Raises
    ------
    IdentError
        Bad input: a log that cannot be read, too little excitation, nothing identifiable.
    ParameterError
        A bad vehicle file.
    OSError
        A file that cannot be read or written.
    """
    with shared_actuator_tracks():
        return _run_ident(opts, progress)


def _run_ident(opts: IdentOptions, progress: Progress | None) -> IdentRun:
    """:func:`run_ident`'s steps."""
    say = progress or (lambda _msg: None)
    base = load_vehicle(opts.vehicle)
    limits: dict[str, Any] = {}
    extra: dict[str, Any] = {}
    equations = list(opts.equations) if opts.equations is not None else None
    partial = opts.partial or (opts.map is not None and equations is None)
    imports: list[dict[str, Any]] = []
    skipped: list[str] = []
    if opts.map is not None:
        records, imports = load_records_from_map(opts.map, opts.logs, base, opts.window, say,
                                                 limits, strict=opts.strict, skipped=skipped)
        source = 'motion'
    else:
        records, source = load_records(opts.logs, base, opts.source, opts.window, say, limits)
        imports = bag_imports(opts.logs)
        if imports:   # bags `auv import` wrote: what their imports derived or assumed
            partial = opts.partial or equations is None
            records = with_origins(records, imports)
    if imports:
        extra['imports'] = imports
        equations, extra['not_identifiable'] = unsupported_equations(imports, equations)
        for eq, why in extra['not_identifiable'].items():
            say(f'{eq}: {why}')
    say(f'force source: {source}')
    from auv_logs.limits import describe
    for line in describe(limits):
        say(line)
    extra['logged_outside_limits'] = limits
    if skipped:
        extra['skipped'] = skipped
    result, files, outcome = identify_and_report(
        records, base, opts.out, opts.logs, fit_c0=opts.fit_c0, bounds=opts.bounds,
        errors=opts.errors, equations=equations, nelder_mead=opts.nelder_mead,
        progress=progress, extra=extra, partial=partial, fit_planes=opts.fit_planes,
        priors=opts.priors, validation=opts.validation, output_error=opts.output_error,
        structures=opts.structure == 'chosen')
    return IdentRun(result, outcome, files, source, imports, skipped)


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
        measured = [tp for tp in MEASURED_TOPICS.values() if tp in have]
        if source == 'forces':   # the commands too, when logged: for the free runs
            measured += [tp for tp in COMMAND_TOPICS.values() if tp in have]
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
    from auv_logs.contract_bag import read_provenance

    out: list[dict[str, Any]] = []
    for bag in bags:
        prov = read_provenance(bag) if pathlib.Path(bag).is_dir() else None
        out += [dict(rep) for rep in (prov or {}).get('imports', [])]
    return out


def load_records_from_map(map_path: str, logs: Sequence[str], base: VehicleParams,
                          window_s: float = WINDOW_S, progress: Progress | None = None,
                          limits: dict[str, Any] | None = None, *, strict: bool = False,
                          skipped: list[str] | None = None
                          ) -> tuple[list[ForceRecord], list[dict[str, Any]]]:
    """Import the original logs through a map (:mod:`auv_logs`) into the contract's
    arrays and build force records from motion exactly as from the imported bag; returns the
    records and each log's import report. With ``skipped`` (a list) a log that cannot be read
    or holds no usable segment is left out, its one-line reason appended there and said
    (:func:`auv_logs.importer.import_logs`; ``strict``, or a single log, refuses instead)."""
    from auv_logs.contract_bag import contract_arrays
    from auv_logs.importer import import_logs

    reasons: list[str] = []
    _, imported = import_logs(map_path, logs, strict=strict,
                              skipped=None if skipped is None else reasons)
    for line in reasons:
        if progress is not None:
            progress(line)
    if skipped is not None:
        skipped.extend(reasons)
    records: list[ForceRecord] = []
    for lg in imported:
        if progress is not None:
            progress(f'imported {lg.name}: {len(lg.t)} state samples, '
                     f'{len(lg.segments)} segment(s)')
        records += with_origins(
            records_as_logged(contract_arrays(lg), base, 'motion', lg.name, window_s,
                              {} if limits is None else limits), [dict(lg.report)])
    return records, [dict(lg.report) for lg in imported]


def with_origins(records: Sequence[ForceRecord], imports: Sequence[dict[str, Any]]
                 ) -> list[ForceRecord]:
    """``records`` with their logs marked with the state channels the imports derived or
    assumed (``origins`` of an import report; a channel derived by any import counts as
    derived): free runs are not scored against them."""
    origins: dict[str, str] = {}
    for imp in imports:
        for sig, how in (imp.get('origins') or {}).items():
            if how != 'measured' or sig not in origins:
                origins[sig] = str(how)
    if not origins:
        return list(records)
    return [r if r.log is None else dataclasses.replace(
        r, log=dataclasses.replace(r.log, origins=dict(origins))) for r in records]


def identify_and_report(records: Sequence[ForceRecord], base: VehicleParams, out: str,
                        bags: Sequence[str], *, fit_c0: bool = False, bounds: bool = True,
                        errors: str = 'hac', equations: Sequence[str] | None = None,
                        nelder_mead: bool = True, progress: Progress | None = None,
                        extra: dict[str, Any] | None = None, partial: bool = False,
                        fit_planes: bool = False, priors: bool = True,
                        validation: bool = True, output_error: str = 'auto',
                        structures: bool = True
                        ) -> tuple[Identification, dict[str, str], Outcome]:
    """Fit, refine, validate (:func:`auv_ident.workflow.run_identification`), compare with
    Nelder-Mead (optional) and write every output into ``out`` (``partial``: see
    :func:`auv_ident.identify.identify`; ``bounds`` False: no physical bounds; ``priors``
    False: the data alone). ``vehicle.yaml`` is written only when the validation passes."""
    if progress is not None:
        progress(f'fitting {", ".join(equations or EQUATIONS)} on {len(records)} record(s), '
                 f'{sum(len(r.t) for r in records)} samples')
    t0 = time.perf_counter()
    outcome = run_identification(
        records, base, equations=equations, fit_offsets=fit_c0, fit_planes=fit_planes,
        bounds=None if bounds else {}, errors=errors, partial=partial, use_priors=priors,
        hold_out=validation, output_error=output_error, structures=structures,
        progress=progress)
    result = outcome.result
    if progress is not None:
        progress(f'fitted in {time.perf_counter() - t0:.2f} s')
        for eq, why in result.not_identifiable.items():
            progress(f'{eq} left out: {why}')
        for c in result.coefficients.values():
            if c.note:
                progress(f'{c.name}: {c.note}')
    extra = dict(extra or {})
    if result.not_identifiable:
        extra['not_identifiable'] = {**result.not_identifiable,
                                     **extra.get('not_identifiable', {})}
    sources = {ch: src for r in records for ch, src in r.actuators.items()}
    if sources:
        extra['actuators'] = sources
    extra.update(outcome.report())
    nm = None
    if nelder_mead:
        t0 = time.perf_counter()
        nm = compare_nelder_mead(records, result)
        if progress is not None:
            progress(f'Nelder-Mead comparison in {time.perf_counter() - t0:.2f} s')
    files = write_outputs(result, out, bags, nm, extra, written=outcome.validation.written,
                          records=records)
    return result, files, outcome
