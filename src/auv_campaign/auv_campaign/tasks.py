"""One log, one task: thin wrappers that run the single-log tools on a worker.

Each wrapper calls the library a single-log tool is an adapter of (``auv gap``:
:func:`auv_gap.job.run_gap`, ``auv ident``: :func:`auv_ident.job.run_ident`) with that tool's
options object (:func:`tool_options`), writing the tool's full report into the mission's own
directory, and keeps the few numbers the campaign report tabulates. A mission whose log the
tool rejects (damaged bag, too little excitation, ...) returns a ``failed`` record with the
tool's one-line reason (its exception); the campaign goes on. Records are cached by the log's
content hash and the settings (:mod:`.cache`).

With a map (``settings['map']``) the tools read the original log through it
(:mod:`auv_logs`); the mission's time and duration are then those of the imported
log's time base: the first and last state samples the import kept (from the import report the
tool writes, or the joint pass's own import), a date when the clock is absolute (stamps after
:data:`EPOCH_MIN_S`), else no date (a log timed from its own start) but a duration.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import math
import os
import pathlib
import time
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from auv_campaign.cache import Cache, content_hash, mission_key
from auv_campaign.engine import one_cpu
from auv_contract.jsonout import dumps
from auv_gap.errors import GapError
from auv_ident.errors import IdentError
from auv_logs.errors import LogError

if TYPE_CHECKING:
    from auv_gap.job import GapOptions
    from auv_ident.job import IdentOptions

KINDS = ('ident', 'gap')
#: Errors of bad input that fail a mission (the tool's own one-line reason); anything else
#: is a fault of the run and is raised, so that Dask retries it.
INPUT_ERRORS: tuple[type[Exception], ...] = (IdentError, GapError, LogError, ValueError, OSError)

MissionTask = Callable[[str, str, str, Mapping[str, Any]], dict[str, Any]]
#: Stamps at or after this [s since the Unix epoch, 1990-01-01 UTC] are a date; earlier ones
#: are taken as a clock started with the log (text logs timed from 0).
EPOCH_MIN_S = 631_152_000.0


def import_span(imports: Sequence[Mapping[str, Any]]) -> tuple[float | None, float | None]:
    """First and last kept state stamps [s] of imported logs, from their import reports
    (:func:`auv_logs.importer.import_log`: ``segments``); (None, None) if none. A log
    timed from its own start (stamps before :data:`EPOCH_MIN_S`) that states its start time
    (in its name or a header comment: the report's ``start.file_time_s``) is placed on that
    clock: its stamps plus the file's time less its first stamp."""
    spans = []
    for imp in imports:
        segs = imp.get('segments') or []
        if not segs:
            continue
        a, b = min(float(s['start']) for s in segs), max(float(s['end']) for s in segs)
        start = imp.get('start') or {}
        clock = start.get('file_time_s')
        if a < EPOCH_MIN_S and clock is not None:
            shift = float(clock) - float(start.get('stamp_s') or 0.0)
            a, b = a + shift, b + shift
        spans.append((a, b))
    if not spans:
        return None, None
    return min(a for a, _ in spans), max(b for _, b in spans)


def _timing(start: float | None, end: float | None) -> dict[str, Any]:
    """``start_time`` (a date, or None for a clock started with the log) and ``duration_s``."""
    return {'start_time': start if start is not None and start >= EPOCH_MIN_S else None,
            'duration_s': None if start is None or end is None else end - start}


def log_span(path: str | os.PathLike[str]) -> tuple[float | None, float | None]:
    """Log time of the first and last message of a bag [s since the Unix epoch]: from the
    MCAP summaries, or, for a file without one (a recorder that crashed), from the log times
    of the ``/auv/state`` messages read up to any damage. (None, None) when neither can be
    read: the single-log tool then says what is wrong with the bag."""
    from mcap.reader import make_reader

    from auv_bag import bag_files, read_arrays

    starts, ends = [], []
    try:
        for f in bag_files(path):
            with open(f, 'rb') as fh:
                try:
                    summary = make_reader(fh).get_summary()
                except Exception:  # no summary section or a cut-off file
                    summary = None
            if summary is None or summary.statistics is None \
                    or summary.statistics.message_count == 0:
                t_log = read_arrays(path, ['/auv/state'], allow_truncated=True
                                    )['/auv/state']['t_log']
                return (float(t_log.min()), float(t_log.max())) if t_log.size else (None, None)
            starts.append(summary.statistics.message_start_time)
            ends.append(summary.statistics.message_end_time)
    except Exception:  # a damaged bag: the tool itself says what is wrong
        return None, None
    return min(starts) * 1e-9, max(ends) * 1e-9


def peak_rss_mb() -> float:
    """Peak resident memory of this (worker) process so far [MiB]."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def tool_options(kind: str, bag: str, out: str, settings: Mapping[str, Any]
                 ) -> GapOptions | IdentOptions:
    """The single-log tool's options for one log: the campaign's vehicle file and map, the
    pass-through options (``settings['options']``, as a user writes them for ``auv gap`` or
    ``auv ident``) read by that tool's own parser, and the tool's defaults.

    Raises
    ------
    CampaignError
        A pass-through option the tool does not accept.
    GapError, IdentError
        An option value out of its range.
    """
    from auv_campaign.errors import CampaignError
    from auv_gap import cli as gap_cli
    from auv_ident import cli as ident_cli

    parser = argparse.ArgumentParser(prog=f'auv {kind}', add_help=False, exit_on_error=False)
    (gap_cli if kind == 'gap' else ident_cli).add_arguments(parser)
    argv = [bag, '--vehicle', str(settings['model']), '--out', out]
    if settings.get('map'):
        argv += ['--map', str(settings['map'])]
    options = list(settings.get('options', []))
    try:
        with contextlib.redirect_stderr(io.StringIO()) as err:
            args = parser.parse_args([*argv, *options])
    except (SystemExit, argparse.ArgumentError) as exc:
        lines = [ln for ln in err.getvalue().splitlines() if ln.strip()]
        why = lines[-1] if lines else str(exc) if isinstance(exc, argparse.ArgumentError) \
            else ' '.join(options)
        raise CampaignError(f'--options for auv {kind}: {why}') from None
    if kind == 'gap':
        return gap_cli.options_from_args(args)
    return ident_cli.options_from_args(args)


def check_options(kind: str, model: str, options: Sequence[str],
                  map_path: str | None = None) -> None:
    """Read the pass-through options with the tool's own parser and check their values (bad
    ones fail now, once, not in every task).

    Raises
    ------
    CampaignError
        An option the single-log tool does not accept, or a value out of its range.
    """
    from auv_campaign.errors import CampaignError

    try:
        tool_options(kind, 'LOG', 'OUT', {'model': model, 'options': list(options),
                                          'map': map_path})
    except (GapError, IdentError) as exc:
        raise CampaignError(f'--options for auv {kind}: {exc}') from None


def _interval(ci: Any) -> list[float] | None:
    if not isinstance(ci, (list, tuple)) or len(ci) != 2 or ci[0] is None or ci[1] is None:
        return None
    lo, hi = float(ci[0]), float(ci[1])
    return [lo, hi] if math.isfinite(lo) and math.isfinite(hi) else None


def gap_quantities(report: Mapping[str, Any], details: Mapping[str, Any]
                   ) -> dict[str, dict[str, Any]]:
    """Effect parameters ``effect.param`` -> value, 95 % interval, unit, of the best candidate
    of a gap report (empty when the verdict names none)."""
    best = report.get('best')
    entry = next((c for c in report.get('candidates') or [] if c['effect'] == best), None)
    if entry is None:
        return {}
    units: Mapping[str, str] = next((c.get('units', {}) for c in details.get('candidates') or []
                  if c['effect'] == best), {})
    names = entry['effect'].split('+')
    out = {}
    for key, value in entry['params'].items():
        full = key if '.' in key else f'{names[0]}.{key}'
        out[full] = {'value': None if value is None else float(value),
                     'ci95': _interval(entry.get('ci95', {}).get(key)),
                     'unit': units.get(key, '')}
    return out


def _run_gap(bag: str, out: pathlib.Path, settings: Mapping[str, Any]) -> dict[str, Any]:
    from auv_gap.job import GapOptions, run_gap

    opts = tool_options('gap', bag, str(out), settings)
    assert isinstance(opts, GapOptions)
    done = run_gap(opts)
    report, details = done.diagnosis.report, done.diagnosis.details
    return {'span': import_span(done.imports),
            'verdict': report['verdict'], 'best': report['best'],
            'ambiguous_with': list(report.get('ambiguous_with') or []),
            'held_out_shrink': report.get('held_out', {}).get('shrink'),
            'quantities': gap_quantities(report, details)}


def gap_logs(bag: str, map_path: str | None) -> tuple[list[Any], list[dict[str, Any]]]:
    """The diagnosis' log pieces of one log, read as ``auv gap`` reads it (a contract bag, or
    the original log through ``map_path``), and the import reports (empty for a bag)."""
    from auv_gap.logs import from_contract_arrays, load_bag

    if not map_path:
        return list(load_bag(bag)), []
    from auv_logs.contract_bag import contract_arrays
    from auv_logs.importer import import_log
    from auv_logs.mapping import load_map

    imported = import_log(load_map(map_path), bag)
    return (list(from_contract_arrays(imported.name, contract_arrays(imported))),
            [dict(imported.report)])


def joint_fit(vehicle: Any, logs: Sequence[Any], window: float | None,
              effect_names: Sequence[str]
              ) -> tuple[str, dict[str, dict[str, Any]]]:
    """Fit the effects ``effect_names`` jointly to ``logs`` with the diagnosis' own
    equation-error fit (:class:`auv_gap.fit.EquationFit`: its training windows of
    ``window`` [s], None: the vehicle's, see :func:`auv_gap.problem.free_run_window`;
    its 95 % cluster-robust intervals). Returns the set's label and
    ``effect.param`` -> value, interval (None where not identified), unit, identified.

    Logs whose velocities or rates were derived or assumed by the import (a vendor text log
    without a DVL or gyro) get no values (None, with ``why``): the equation error reads those
    signals, and the diagnosis itself finds such effects only through its free runs (on clean
    5 Hz text logs the equation-error fit gave a current of 0.48 [0.40, 0.55] m/s that was not
    there).

    The only place the campaign calls into the diagnosis' fitting code."""
    from auv_gap.fit import EquationFit
    from auv_gap.logs import measurement_weighting
    from auv_gap.problem import EffectSet, Problem

    problem = Problem(vehicle, list(logs), window=window)
    effects = EffectSet(list(effect_names), vehicle)
    unmeasured = [c for c in measurement_weighting(problem.logs).channels
                  if c in ('u', 'v', 'w', 'q', 'r')]
    if unmeasured:
        why = (f'not fitted: {", ".join(unmeasured)} derived or assumed by the import, which '
               'the equation error would read as measured; see the mission\'s diagnosis')
        return str(effects.label), {
            f'{effect}.{p.name}': {'value': None, 'ci95': None, 'unit': p.unit,
                                   'identified': False, 'why': why}
            for effect, p in effects.params}
    fit = EquationFit(problem).fit(effects)
    quantities = {}
    for (effect, p), v, lo, hi, active in zip(effects.params, fit.values, fit.lo95, fit.hi95,
                                             fit.active):
        quantities[f'{effect}.{p.name}'] = {
            'value': float(v), 'ci95': _interval([lo, hi]) if active else None,
            'unit': p.unit, 'identified': bool(active)}
    return str(effects.label), quantities


def _run_gap_joint(bag: str, out: pathlib.Path, settings: Mapping[str, Any]
                   ) -> dict[str, Any]:
    """The campaign's effect set fitted jointly to one log (:func:`joint_fit`), the log read
    as ``auv gap`` reads it (with the vehicle's limits widened to what was logged, as there),
    written to ``out/joint.json``."""
    from auv_gap.job import GapOptions
    from auv_logs.limits import as_logged
    from auv_sim.params import load_vehicle

    opts = tool_options('gap', bag, str(out), settings)
    assert isinstance(opts, GapOptions)
    logs, imports = gap_logs(bag, settings.get('map'))
    unique = {id(lg.commands): lg.commands for lg in logs}
    vehicle, _ = as_logged(load_vehicle(opts.vehicle), list(unique.values()))
    label, quantities = joint_fit(vehicle, logs, opts.window, settings['effect_set'])
    out.mkdir(parents=True, exist_ok=True)
    (out / 'joint.json').write_text(dumps({'effects': label,
                                                'quantities': quantities}, indent=1) + '\n')
    return {'span': import_span(imports), 'verdict': 'joint_fit', 'best': label,
            'ambiguous_with': [], 'quantities': quantities}


def _run_ident(bag: str, out: pathlib.Path, settings: Mapping[str, Any]) -> dict[str, Any]:
    from auv_ident.job import IdentOptions, run_ident

    opts = tool_options('ident', bag, str(out), settings)
    assert isinstance(opts, IdentOptions)
    done = run_ident(opts)
    # a model that predicts the held-out data worse than the base is not an answer: its
    # coefficients are not trended
    quantities = {name: {'value': float(c.value), 'ci95': _interval(list(c.ci95)), 'unit': ''}
                  for name, c in done.result.coefficients.items()} if done.written else {}
    return {'span': import_span(done.imports),
            'verdict': 'identified' if done.written else 'not_written', 'best': None,
            'ambiguous_with': [], 'source': done.source, 'quantities': quantities}


def run_mission(kind: str, name: str, bag: str, settings: Mapping[str, Any]
                ) -> dict[str, Any]:
    """Run the single-log tool ``kind`` on ``bag``; the mission's record (see module doc).

    ``settings``: ``model`` (vehicle file), ``options`` (pass-through options of the tool),
    ``out`` (campaign directory; the tool writes into ``out/missions/<name>[-refit]``),
    ``cache`` (cache directory or None), ``key_settings`` (what the cache key covers),
    ``effect_set`` (gap only: fit this set of effects jointly, see :func:`_run_gap_joint`).
    ``map`` (mapping file or None: the logs are original logs read through it).
    """
    t0 = time.perf_counter()
    mapped = bool(settings.get('map'))
    record: dict[str, Any] = {
        'name': name, 'log': bag, **_timing(*((None, None) if mapped else log_span(bag))),
        'status': 'ok', 'reason': None, 'cached': False}
    try:
        log_hash = content_hash(bag)
    except OSError as exc:
        return {**record, 'status': 'failed', 'reason': f'cannot read {bag}: {exc.strerror}',
                'elapsed_s': time.perf_counter() - t0}
    record['hash'] = log_hash
    cache = Cache(settings['cache']) if settings.get('cache') else None
    key = mission_key(kind, log_hash, settings.get('key_settings', {}))
    if cache is not None:
        hit = cache.get(key)
        if hit is not None:
            return {**hit, 'name': name, 'log': bag, 'cached': True,
                    'elapsed_s': time.perf_counter() - t0}
    sub = 'missions-refit' if settings.get('effect_set') else 'missions'
    out = pathlib.Path(settings['out']) / sub / name
    try:
        run = _run_ident if kind == 'ident' else \
            _run_gap_joint if settings.get('effect_set') else _run_gap
        with one_cpu():
            result = run(bag, out, settings)
    except INPUT_ERRORS as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        return {**record, 'status': 'failed', 'reason': reason,
                'elapsed_s': time.perf_counter() - t0}
    span = result.pop('span', (None, None))
    if mapped:
        record.update(_timing(*span))
    record.update(result)
    record['report'] = str(out / ('joint.json' if settings.get('effect_set') else 'report.md'))
    record['elapsed_s'] = time.perf_counter() - t0
    record['worker_peak_rss_mb'] = peak_rss_mb()
    if cache is not None:
        cache.put(key, record)
    return record
