"""Benchmark: a season of real-looking logs through `auv import`, `auv gap` and
`auv campaign gap`.

The logs are stand-ins for what real vehicles log (:mod:`auv_campaign.season`): a small
AUV from ``auv vehicle-init`` porpoising between the surface and 2-5 m, logged by a vendor's
text logger at 2 Hz with rows 0.39 and 0.61 s apart, a 1 Hz DVL repeated on the rows, depth in
0.1 m steps, cut-off rows, ``nan`` values, empty logs and logs with surface data only,
thruster-off coasts on which it rises hanging nose down (2 N buoyant, its centre of gravity
5 mm forward of the file's), a depth sensor reading 0.085 m at the surface; a 1.2 m AUV's MCAP
bag with three fins in a Y, thrust in per cent, zero-stamped IMU headers, unstamped fin
topics, raw gyro counts and a 10 deg fin zero error; the A18M (a 10 deg fin zero error, a
30 N buoyancy error), the REMUS 100 (a current) and the NPS AUV II (a forward centre of gravity
and positive buoyancy, with coasts), all as 2 Hz jittered text logs.

Counted (goals in brackets):

* ``crashes`` (0): a tool run that ends in a Python traceback, or a campaign task failed by an
  exception rather than the tool's one-line refusal;
* ``confident_wrong`` (0): an ``explained`` verdict naming an effect not flown, or a
  significant finding (of a coast or surface pass) of an effect not flown or of the wrong sign
  (:func:`auv_campaign.season.wrong_claims`);
* ``hand_named`` of ``hand_total`` (all): the effects a hand analysis of each log finds (a
  coast: buoyancy and the centre of gravity; a surface pass: the depth sensor's zero; a fin
  zero error, a buoyancy error, a current where the log shows them) named with the right sign
  (:func:`auv_campaign.season.named`);
* ``campaign_failed_other`` (0): campaign tasks failed other than by an honest refusal (an
  empty log, a log without a usable segment);
* ``season_wall_s`` (< 120 s): the 26 logs through ``auv campaign gap`` on 2 local workers,
  wall clock, the second pass included, no cache; with ``season_cpu_s``, the CPU time of the
  campaign's processes, and the load average before and after (the machine is shared: on a
  loaded one the wall clock is many times the CPU over the workers).

Run: ``. .venv/bin/auv-env && python bench/bench_real_season.py [--logs 26] [--skip-panel]``
(writes ``bench/results/real_season.json``). While working on one case:
``--case a18m_fin_zero [--case ...] --skip-season`` runs only those panel cases (and no
season) and prints their rows without writing the results file.
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time
from typing import Any

from timing import save_figures

ROOT = pathlib.Path(__file__).resolve().parents[1]
#: Campaign failures that are an honest refusal of the log, by their one-line reason.
HONEST = ('no data rows', 'no usable segment', 'do not parse', 'every log was left out')


def _auv(*args: str, timeout: float = 1800.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, '-m', 'auv_bringup.cli', *args],
                          capture_output=True, text=True, timeout=timeout, check=False)


def _crashed(proc: subprocess.CompletedProcess[str]) -> bool:
    """A Python traceback, or an exit status other than 0 and 1."""
    return 'Traceback (most recent call last)' in proc.stderr or proc.returncode not in (0, 1)


def _score(report: dict[str, Any], case: Any, hand: Any) -> dict[str, Any]:
    from auv_campaign.season import named, wrong_claims

    found = {}
    for effect, param, sign in hand:
        v = named(report, effect, param)
        found[f'{effect}.{param}'] = (v is not None and (v > 0) == (sign > 0), v)
    return {'verdict': report['verdict'], 'best': report['best'],
            'diverges': report.get('diverges'),
            'hand': {k: {'named_right': ok, 'value': v} for k, (ok, v) in found.items()},
            'wrong': wrong_claims(report, case.truth),
            'findings': [f['text'] for f in report.get('findings') or [] if f['significant']],
            'statement': report['statement'][:600]}


def run_import(case: Any, out: pathlib.Path) -> dict[str, Any]:
    """`auv import` over the whole season: the batch goes on, one line per log left out."""
    proc = _auv('import', '--map', str(case.map), *map(str, case.logs), '--out',
                str(out / 'season_bag'), '--vehicle', str(case.vehicle))
    doc = json.loads(proc.stdout) if proc.returncode == 0 else {}
    left = [ln for imp in doc.get('imports', []) for ln in imp.get('left_out', [])]
    return {'exit': proc.returncode, 'crashed': _crashed(proc),
            'logs_imported': len(doc.get('imports', [])), 'logs_left_out': len(doc.get(
                'skipped', [])), 'skipped': doc.get('skipped', []),
            'cut_off_rows_said': sum('cut off' in ln for ln in left),
            'non_finite_said': sum('non-finite' in ln for ln in left),
            'error': proc.stderr.strip().splitlines()[-1] if proc.returncode else None}


def run_campaign(case: Any, out: pathlib.Path, workers: int) -> dict[str, Any]:
    """The season through `auv campaign gap` on ``workers`` local workers."""
    import resource

    from auv_campaign.season import season_expectations

    load = os.getloadavg()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = _auv('campaign', 'gap', str(case.logs[0].parent), '--map', str(case.map),
                '--vehicle', str(case.vehicle), '--out', str(out / 'campaign'),
                '--workers', str(workers), '--no-cache', '--no-plots', '--quiet',
                '--options=--no-plots')
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    doc = json.loads((out / 'campaign' / 'campaign.json').read_text()) \
        if proc.returncode == 0 else {}
    expect = season_expectations(case)
    rows, other, hand_named, hand_total, wrong, crashes = {}, [], 0, 0, [], 0
    for m in doc.get('missions', []):
        name = pathlib.Path(m['log']).name
        exp = expect[name]
        row: dict[str, Any] = {'status': m['status'], 'start_time': m.get('start_time')}
        if m['status'] == 'failed':
            reason = str(m.get('reason'))
            row['reason'] = reason
            honest = any(h in reason for h in HONEST) and exp['refusal'] is not None
            crashes += int(':' in reason.split(' ')[0] and reason.split(':')[0].endswith(
                'Error'))
            if not honest:
                other.append(f'{name}: {reason}')
        else:
            report = json.loads((pathlib.Path(m['report']).parent / 'report.json').read_text())
            scored = _score(report, case, exp['hand'])
            row.update(scored)
            hand_total += len(exp['hand'])
            hand_named += sum(v['named_right'] for v in scored['hand'].values())
            wrong += [f'{name}: {w}' for w in scored['wrong']]
            if exp['refusal'] is not None:
                other.append(f'{name}: diagnosed, expected a refusal ({exp["refusal"]})')
        rows[name] = row
    dated = sum(1 for r in rows.values() if r.get('start_time'))
    return {'exit': proc.returncode, 'crashed': _crashed(proc), 'wall_s': wall,
            'cpu_s': cpu, 'workers': workers, 'load_before': load,
            'load_after': os.getloadavg(),
            'missions': len(rows), 'ok': sum(r['status'] == 'ok' for r in rows.values()),
            'failed': sum(r['status'] == 'failed' for r in rows.values()),
            'failed_other': other, 'crashes': crashes, 'hand_named': hand_named,
            'hand_total': hand_total, 'confident_wrong': wrong, 'dated': dated,
            'logs': rows,
            'error': proc.stderr.strip().splitlines()[-1] if proc.returncode else None}


def run_case(case: Any, out: pathlib.Path) -> dict[str, Any]:
    """`auv gap --map` on one panel case."""
    t0 = time.perf_counter()
    proc = _auv('gap', '--map', str(case.map), *map(str, case.logs), '--vehicle',
                str(case.vehicle), '--out', str(out / case.name), '--no-plots', '--quiet')
    row: dict[str, Any] = {'seconds': time.perf_counter() - t0, 'exit': proc.returncode,
                           'crashed': _crashed(proc), 'properties': list(case.properties)}
    if case.refusal is not None:
        line = proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else ''
        row.update({'refused': proc.returncode == 1 and case.refusal in line,
                    'one_line': len(proc.stderr.strip().splitlines()) == 1, 'error': line})
        return row
    if proc.returncode != 0:
        row['error'] = proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else ''
        return row
    report = json.loads((out / case.name / 'report.json').read_text())
    row.update(_score(report, case, case.hand))
    return row


def _reuse(directory: pathlib.Path, count: int) -> Any:
    """The season kept in ``directory`` by an earlier run with ``--keep`` (the logs are
    seeded: the same code writes the same logs), or None."""
    from auv_campaign.season import COAST_HAND, SMALL_TRUTH, SURFACE_HAND, Case

    kinds = directory / 'season.json'
    if not kinds.is_file() or len(json.loads(kinds.read_text())) != count:
        return None
    logs = tuple(directory / n for n in json.loads(kinds.read_text()))
    return Case('small_auv_season', directory / 'small_auv.yaml',
                directory / 'small_auv_map.yaml', logs, SMALL_TRUTH, COAST_HAND + SURFACE_HAND,
                None, ())


def _partial(args: argparse.Namespace, season: Any, panel: list[Any],
             out: pathlib.Path) -> None:
    """The panel cases named by ``--case`` (all with none) and, without
    ``--skip-season``, the season: rows printed, no results file written."""
    known = [c.name for c in panel]
    unknown = [n for n in args.case if n not in known]
    if unknown:
        sys.exit(f'error: unknown case(s) {", ".join(unknown)} (known: {", ".join(known)})')
    out.mkdir(parents=True, exist_ok=True)
    rows: dict[str, Any] = {c.name: run_case(c, out) for c in panel
                            if not args.case or c.name in args.case}
    if not args.skip_season:
        rows['season'] = {k: v for k, v in run_campaign(season, out, args.workers).items()
                          if k != 'logs'}
    print(json.dumps(rows, indent=1, default=str))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--logs', type=int, default=26, help='logs in the season (26)')
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--skip-panel', action='store_true')
    parser.add_argument('--keep', default=None, help='write the logs here and keep them')
    parser.add_argument('--case', action='append', default=[],
                        help='run only this panel case (repeatable): rows printed, no file')
    parser.add_argument('--skip-season', action='store_true',
                        help='no import and campaign of the season (with --case)')
    args = parser.parse_args()
    from auv_campaign.season import write_panel, write_season

    tmp = tempfile.TemporaryDirectory(prefix='real_season_')
    base = pathlib.Path(args.keep or tmp.name)
    t0 = time.perf_counter()
    season = None if args.skip_season else (
        _reuse(base / 'season', args.logs) or write_season(base / 'season', args.logs, seed=0))
    panel = [] if args.skip_panel else write_panel(base / 'panel', seed=0)
    made = time.perf_counter() - t0
    if args.case or args.skip_season:
        _partial(args, season, panel, base / 'out')
        tmp.cleanup()
        return
    out = base / 'out'
    out.mkdir(parents=True, exist_ok=True)
    imported = run_import(season, out)
    campaign = run_campaign(season, out, args.workers)
    cases = {c.name: run_case(c, out) for c in panel}
    crashes = (int(imported['crashed']) + int(campaign['crashed']) + campaign['crashes']
               + sum(int(r['crashed']) for r in cases.values()))
    wrong = campaign['confident_wrong'] + [f'{n}: {w}' for n, r in cases.items()
                                           for w in r.get('wrong', [])]
    hand_named = campaign['hand_named'] + sum(
        sum(v['named_right'] for v in r.get('hand', {}).values()) for r in cases.values())
    hand_total = campaign['hand_total'] + sum(
        len(c.hand) for c in panel if c.refusal is None)
    refusals = {n: r for n, r in cases.items() if 'refused' in r}
    figures = {
        'benchmark': 'a season of real-looking logs through auv import, auv gap and auv '
                     'campaign gap (bench/bench_real_season.py)',
        'crashes': crashes,
        'confident_wrong': len(wrong),
        'confident_wrong_list': wrong,
        'hand_named': hand_named,
        'hand_total': hand_total,
        'campaign_failed_other': len(campaign['failed_other']),
        'season_logs': args.logs,
        'season_wall_s': campaign['wall_s'],
        # the CPU the campaign took (its processes and workers), and what two idle cores
        # would take for it: the machine is shared and its load is recorded
        'season_cpu_s': campaign['cpu_s'],
        'season_cpu_over_workers_s': campaign['cpu_s'] / args.workers,
        'season_workers': args.workers,
        'refusals_right': sum(r['refused'] and r['one_line'] for r in refusals.values()),
        'refusals': len(refusals),
        'import': imported,
        'campaign': campaign,
        'cases': cases,
        'logs_written_s': made,
        'machine': {'cpus': os.cpu_count(), 'load_at_end': os.getloadavg()},
    }
    path = save_figures('real_season', figures)
    print(json.dumps({k: v for k, v in figures.items()
                      if k not in ('import', 'campaign', 'cases')}, indent=1))
    print(f'wrote {path}')
    tmp.cleanup()


if __name__ == '__main__':
    main()
