"""One log, one task: thin wrappers that run the single-log tools on a worker.

Each wrapper runs the very command a user would run on one log (``auv gap`` through
:func:`auv_ident.gap_cli.run`, ``auv ident`` through :func:`auv_ident.cli.run`), writing that
tool's full report into the mission's own directory, then extracts the few numbers the
campaign report tabulates. A mission whose log the tool rejects (damaged bag, too little
excitation, ...) returns a ``failed`` record with the tool's one-line reason; the campaign
goes on. Records are cached by the log's content hash and the settings (:mod:`.cache`).
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import os
import pathlib
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from auv_ident.campaign.cache import Cache, content_hash, mission_key
from auv_ident.errors import IdentError

KINDS = ('ident', 'gap')
#: Errors of bad input that fail a mission (the tool's own one-line reason); anything else
#: is a fault of the run and is raised, so that Dask retries it.
INPUT_ERRORS: tuple[type[Exception], ...] = (IdentError, ValueError, OSError)

MissionTask = Callable[[str, str, str, Mapping[str, Any]], dict[str, Any]]


def log_span(path: str | os.PathLike[str]) -> tuple[float | None, float | None]:
    """Log time of the first and last message of a bag [s since the Unix epoch], from the
    MCAP summaries (None, None when a file has no summary, e.g. after a recorder crash)."""
    from mcap.reader import make_reader

    from auv_ident.bag import bag_files

    starts, ends = [], []
    try:
        for f in bag_files(path):
            with open(f, 'rb') as fh:
                summary = make_reader(fh).get_summary()
            if summary is None or summary.statistics is None \
                    or summary.statistics.message_count == 0:
                return None, None
            starts.append(summary.statistics.message_start_time)
            ends.append(summary.statistics.message_end_time)
    except Exception:  # a damaged bag: the tool itself says what is wrong
        return None, None
    return min(starts) * 1e-9, max(ends) * 1e-9


def _tool_args(kind: str, bag: str, out: str, settings: Mapping[str, Any]
               ) -> argparse.Namespace:
    """The single-log tool's parsed arguments for one bag (its own parser, its defaults)."""
    from auv_ident import cli, gap_cli

    parser = argparse.ArgumentParser(prog=f'auv {kind}', add_help=False)
    if kind == 'gap':
        gap_cli.add_arguments(parser)
        argv = [bag, '--model', str(settings['model']), '--out', out, '--quiet']
        if settings.get('effect_set'):
            argv += ['--effects', *settings['effect_set'],
                     '--top', str(len(settings['effect_set']))]
    else:
        cli.add_arguments(parser)
        argv = [bag, '--base', str(settings['model']), '--out', out]
    return parser.parse_args([*argv, *settings.get('options', [])])


def check_options(kind: str, model: str, options: Sequence[str]) -> None:
    """Parse the pass-through options with the tool's own parser (bad ones fail now, once,
    not in every task).

    Raises:
        CampaignError: an option the single-log tool does not accept.
    """
    from auv_ident.campaign.errors import CampaignError

    try:
        with contextlib.redirect_stderr(io.StringIO()) as err:
            _tool_args(kind, 'LOG', 'OUT', {'model': model, 'options': list(options)})
    except SystemExit:
        lines = [ln for ln in err.getvalue().splitlines() if ln.strip()]
        raise CampaignError(f'--options for auv {kind}: '
                            f'{lines[-1] if lines else " ".join(options)}') from None


def _interval(ci: Any) -> list[float] | None:
    if not isinstance(ci, (list, tuple)) or len(ci) != 2 or ci[0] is None or ci[1] is None:
        return None
    lo, hi = float(ci[0]), float(ci[1])
    return [lo, hi] if math.isfinite(lo) and math.isfinite(hi) else None


def gap_quantities(report: Mapping[str, Any], details: Mapping[str, Any],
                   effect_set: Sequence[str] = ()) -> dict[str, dict[str, Any]]:
    """Effect parameters ``effect.param`` -> value, 95 % interval, unit, from a gap report.

    Without ``effect_set``: those of the best candidate. With it: those of the candidate
    whose effects are exactly ``effect_set`` when the diagnosis fitted it, else, per effect,
    those of the highest-scoring candidate that contains the effect.
    """
    cands = list(report.get('candidates') or [])
    units = {c['effect']: c.get('units', {}) for c in details.get('candidates') or []}

    def take(entry: Mapping[str, Any], only: str | None = None) -> dict[str, dict[str, Any]]:
        names = entry['effect'].split('+')
        out = {}
        for key, value in entry['params'].items():
            full = key if '.' in key else f'{names[0]}.{key}'
            if only is not None and full.split('.')[0] != only:
                continue
            out[full] = {'value': None if value is None else float(value),
                         'ci95': _interval(entry.get('ci95', {}).get(key)),
                         'unit': units.get(entry['effect'], {}).get(key, '')}
        return out

    if not effect_set:
        best = report.get('best')
        entry = next((c for c in cands if c['effect'] == best), None)
        return take(entry) if entry is not None else {}
    wanted = set(effect_set)
    exact = next((c for c in cands if set(c['effect'].split('+')) == wanted), None)
    if exact is not None:
        return take(exact)
    out: dict[str, dict[str, Any]] = {}
    for effect in effect_set:
        entry = next((c for c in cands if effect in c['effect'].split('+')), None)
        if entry is not None:
            out.update(take(entry, effect))
    return out


def ident_quantities(report: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """Coefficients -> value, 95 % interval, unit ('' : dimensionless) from an ident report."""
    return {name: {'value': float(c['value']), 'ci95': _interval(c.get('ci95')), 'unit': ''}
            for name, c in (report.get('coefficients') or {}).items()}


def _run_gap(bag: str, out: pathlib.Path, settings: Mapping[str, Any]) -> dict[str, Any]:
    from auv_ident import gap_cli

    args = _tool_args('gap', bag, str(out), settings)
    with contextlib.redirect_stderr(io.StringIO()) as err:
        status = gap_cli.run(args)
    if status != 0:
        lines = [ln for ln in err.getvalue().splitlines() if ln.strip()]
        reason = lines[-1] if lines else f'auv gap exited {status}'
        raise _ToolFailed(reason.removeprefix('error: '))
    report = json.loads((out / 'report.json').read_text())
    details = json.loads((out / 'details.json').read_text())
    return {'verdict': report['verdict'], 'best': report['best'],
            'ambiguous_with': list(report.get('ambiguous_with') or []),
            'held_out_shrink': report.get('held_out', {}).get('shrink'),
            'quantities': gap_quantities(report, details, settings.get('effect_set') or ())}


def _run_ident(bag: str, out: pathlib.Path, settings: Mapping[str, Any]) -> dict[str, Any]:
    from auv_ident import cli

    args = _tool_args('ident', bag, str(out), settings)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        cli.run(args)
    report = json.loads((out / 'report.json').read_text())
    return {'verdict': 'identified', 'best': None, 'ambiguous_with': [],
            'source': report.get('source'), 'quantities': ident_quantities(report)}


class _ToolFailed(Exception):
    """The single-log tool rejected the log (message: its one-line reason)."""


def run_mission(kind: str, name: str, bag: str, settings: Mapping[str, Any]
                ) -> dict[str, Any]:
    """Run the single-log tool ``kind`` on ``bag``; the mission's record (see module doc).

    ``settings``: ``model`` (vehicle file), ``options`` (pass-through options of the tool),
    ``out`` (campaign directory; the tool writes into ``out/missions/<name>[-refit]``),
    ``cache`` (cache directory or None), ``key_settings`` (what the cache key covers),
    ``effect_set`` (gap only: refit this set of effects in every mission).
    """
    t0 = time.perf_counter()
    start, end = log_span(bag)
    record: dict[str, Any] = {
        'name': name, 'log': bag, 'start_time': start,
        'duration_s': None if start is None or end is None else end - start,
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
        result = (_run_gap if kind == 'gap' else _run_ident)(bag, out, settings)
    except _ToolFailed as exc:
        return {**record, 'status': 'failed', 'reason': str(exc),
                'elapsed_s': time.perf_counter() - t0}
    except INPUT_ERRORS as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        return {**record, 'status': 'failed', 'reason': reason,
                'elapsed_s': time.perf_counter() - t0}
    record.update(result)
    record['report'] = str(out / 'report.md')
    record['elapsed_s'] = time.perf_counter() - t0
    if cache is not None:
        cache.put(key, record)
    return record
