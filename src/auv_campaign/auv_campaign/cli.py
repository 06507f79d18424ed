"""``auv campaign ident|gap|montecarlo``: campaigns on a Dask cluster.

``auv campaign gap LOGS... --vehicle VEHICLE.yaml --out DIR`` runs ``auv gap`` on every log
as its own task (``ident``: ``auv ident``), each writing its full report under
``DIR/missions/<name>/``, and gathers them into ``DIR/campaign.json`` and
``DIR/campaign.md`` with plots of every quantity against mission time and the drift and
step tests. LOGS: bags (``.mcap`` files or bag directories), directories of bags, globs, or
``.txt``/``.list`` files naming one log per line; with ``--map MAP`` the original logs of
another vehicle (text logs, ROS 1 bags, rosbag2 bags of any message types) read through the
mapping file, as ``auv ident --map`` / ``auv gap --map`` read them. Options of the single-log
tool pass through ``--options '...'``. Missions already done with the same log content,
settings and code version are taken from the cache. ``auv campaign montecarlo`` flies
chunks of closed-loop runs per task.

The cluster: an embedded local one (``--workers N``) or ``--scheduler ADDRESS``. Progress
lines go to stderr; bad input is one line ``error: ...`` and exit status 1.
"""
from __future__ import annotations

import argparse
import csv
import math
import pathlib
import shlex
import sys
import time
from collections.abc import Sequence
from typing import Any

from auv_campaign import engine, inputs, report
from auv_campaign.cache import code_version, file_hash
from auv_campaign.errors import CampaignError
from auv_campaign.runner import run_missions, stderr_lines
from auv_contract import config_path
from auv_contract.jsonout import dumps
from auv_sim.cli_options import add_vehicle_option


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument('--out', required=True, metavar='DIR', help='output directory')
    p.add_argument('--workers', type=int, default=None,
                   help='worker processes of the embedded cluster (default: the CPUs)')
    p.add_argument('--scheduler', default=None, metavar='ADDRESS',
                   help='run on an existing Dask cluster (e.g. tcp://head:8786) instead')
    p.add_argument('--timeout', type=float, default=engine.CONNECT_TIMEOUT_S, metavar='S',
                   help=f'seconds to wait for --scheduler (default {engine.CONNECT_TIMEOUT_S:g})')
    p.add_argument('--retries', type=int, default=2,
                   help='re-runs of a task that failed by a fault (default 2)')
    p.add_argument('--quiet', action='store_true', help='no progress lines')


def _logs(p: argparse.ArgumentParser) -> None:
    p.add_argument('logs', nargs='+', metavar='LOG',
                   help='bags, directories of bags, globs or list files (.list; .txt unless '
                        'the map reads text logs)')
    p.add_argument('--map', default=None, metavar='MAP',
                   help='read the original logs (text logs, ROS 1 bags, rosbag2 .db3/.mcap) '
                        'through this mapping file (see docs/real-logs.md)')
    p.add_argument('--options', default='', metavar="'OPTS'",
                   help='options passed to the single-log tool, as one word: '
                        '--options="--window 60"')
    p.add_argument('--cache', default=None, metavar='DIR',
                   help='cache directory (default DIR/cache)')
    p.add_argument('--no-cache', action='store_true', help='neither read nor write the cache')
    p.add_argument('--alpha', type=float, default=0.01,
                   help='significance level of the drift and step tests (default 0.01)')
    p.add_argument('--no-plots', action='store_true', help='skip the PNG plots')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``auv campaign``."""
    sub = parser.add_subparsers(dest='mode', required=True, metavar='ident|gap|montecarlo')
    ident = sub.add_parser('ident', help='identify the coefficients of every log')
    _logs(ident)
    add_vehicle_option(ident, default=str(config_path('a18m.yaml')), old_names=('--base',),
                       help_text='vehicle file the identified values replace')
    _common(ident)
    gap = sub.add_parser('gap', help='sim-to-real gap diagnosis of every log')
    _logs(gap)
    add_vehicle_option(gap, required=True, old_names=('--model',),
                       help_text='the nominal vehicle file')
    gap.add_argument('--no-refit', action='store_true',
                     help='skip the second pass that fits the effects named in any mission '
                          'in every mission')
    _common(gap)
    mc = sub.add_parser('montecarlo', help='closed-loop runs over a draw of vehicles')
    mc.add_argument('--vehicle', default=str(config_path('a18m.yaml')), metavar='VEHICLE.yaml',
                    help='nominal vehicle (the pilot is designed on it)')
    mc.add_argument('--runs', type=int, default=200, help='number of runs (default 200)')
    mc.add_argument('--chunk', type=int, default=25, help='runs per task (default 25)')
    mc.add_argument('--seed', type=int, default=0, help='seed of the draw (default 0)')
    mc.add_argument('--spread', nargs='+', default=[], metavar='NAME=REL',
                    help='relative 1-sigma spread of a vehicle coefficient, e.g. CMuq=0.2')
    mc.add_argument('--effect', nargs='+', default=[], metavar='EFFECT.FIELD=LO:HI',
                    help='effect field drawn uniform in [LO, HI] (SI), e.g. '
                         'buoyancy_offset.dB=-30:30; =V for a fixed value')
    mc.add_argument('--step', default='5:20', metavar='LO:HI',
                    help='depth step size [m], uniform, random sign (default 5:20)')
    mc.add_argument('--duration', type=float, default=120.0, help='run length [s]')
    mc.add_argument('--z0', type=float, default=40.0, help='trim depth [m, down]')
    mc.add_argument('--u0', type=float, default=2.0, help='trim speed [m/s]')
    mc.add_argument('--band', type=float, default=0.1, help='settling band [m]')
    mc.add_argument('--tumble-angle', type=float, default=math.radians(60.0),
                    help='|pitch| or |roll| beyond which a run counts as tumbled [rad] '
                         '(default: 60 deg)')
    _common(mc)


def _range(text: str, what: str) -> tuple[float, float]:
    try:
        parts = [float(v) for v in text.split(':')]
    except ValueError:
        raise CampaignError(f'{what}: {text!r} is not LO:HI or a number') from None
    if len(parts) == 1:
        return parts[0], parts[0]
    if len(parts) != 2:
        raise CampaignError(f'{what}: {text!r} is not LO:HI or a number')
    return parts[0], parts[1]


def parse_draw(args: argparse.Namespace) -> Any:
    """The :class:`~auv_campaign.montecarlo.Draw` of the montecarlo options, checked."""
    from auv_campaign.montecarlo import Draw

    spreads: dict[str, float] = {}
    for item in args.spread:
        key, _, val = item.partition('=')
        try:
            spreads[key] = float(val)
        except ValueError:
            raise CampaignError(f'--spread {item}: expected NAME=REL') from None
    effects: dict[str, dict[str, tuple[float, float]]] = {}
    for item in args.effect:
        key, sep, val = item.partition('=')
        effect, dot, field = key.partition('.')
        if not (sep and dot):
            raise CampaignError(f'--effect {item}: expected EFFECT.FIELD=LO:HI')
        effects.setdefault(effect, {})[field] = _range(val, f'--effect {item}')
    if args.chunk < 1:
        raise CampaignError(f'--chunk must be >= 1, got {args.chunk}')
    draw = Draw(vehicle=str(args.vehicle), runs=args.runs, seed=args.seed,
                duration=args.duration, z0=args.z0, u0=args.u0, spreads=spreads,
                effects=effects, step=_range(args.step, '--step'), band=args.band,
                tumble_angle=args.tumble_angle)
    draw.check()
    return draw


def run(args: argparse.Namespace) -> int:
    """Run the campaign of ``args``; 0 on success (failed missions included)."""
    say = (lambda _line: None) if args.quiet else stderr_lines
    if args.retries < 0:
        raise CampaignError(f'--retries must be >= 0, got {args.retries}')
    if args.mode == 'montecarlo':
        return _montecarlo(args, say)
    return _logs_campaign(args, say)


def _logs_campaign(args: argparse.Namespace, say: Any) -> int:
    from auv_campaign.tasks import check_options

    kind = args.mode
    model = args.vehicle
    if not pathlib.Path(model).is_file():
        raise CampaignError(f'vehicle file {model} does not exist')
    options = shlex.split(args.options)
    if '--map' in options or any(o.startswith('--map=') for o in options):
        raise CampaignError('give the map as the campaign\'s own --map MAP, not in --options')
    map_path, map_kind = _check_map(args.map)
    check_options(kind, model, options, map_path)
    logs = inputs.find_logs(args.logs, map_kind)
    names = inputs.mission_names(logs)
    out = pathlib.Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    settings: dict[str, Any] = {
        'model': str(pathlib.Path(model).resolve()), 'options': options, 'out': str(out),
        'map': map_path,
        'cache': None if args.no_cache else str(pathlib.Path(args.cache or out / 'cache')
                                                .resolve()),
        'key_settings': {'tool': kind, 'options': options, 'model': file_hash(model),
                         'map': file_hash(map_path) if map_path else None,
                         'code': code_version()}}
    missions = [(n, str(p.resolve())) for n, p in zip(names, logs)]
    t0 = time.perf_counter()
    with engine.client(args.workers, args.scheduler, args.timeout) as c:
        cluster = engine.describe(c)
        say(f'campaign {kind}: {len(missions)} log(s) on {cluster["workers"]} worker(s)')
        records = run_missions(c, kind, missions, settings, retries=args.retries,
                               progress=say)
        refit = None
        effect_set: list[str] = []
        if kind == 'gap' and not args.no_refit:
            effect_set = sorted({e for r in records if r['status'] == 'ok' and r.get('best')
                                 for e in r['best'].split('+')})
            if effect_set:
                say(f'second pass: {"+".join(effect_set)} in every mission')
                s2 = {**settings, 'effect_set': effect_set,
                      'key_settings': {**settings['key_settings'], 'effect_set': effect_set,
                                       'fit': 'joint equation error'}}
                ok = [m for m, r in zip(missions, records) if r['status'] == 'ok']
                refit_ok = run_missions(c, kind, ok, s2, retries=args.retries, progress=say,
                                        label='-refit')
                by_name = {r['name']: r for r in refit_ok}
                refit = [by_name.get(r['name'], r) for r in records]
    meta = {'out': str(out), 'cluster': cluster, 'wall_s': time.perf_counter() - t0,
            'settings': {'model': settings['model'], 'map': map_path, 'options': options,
                         'code': code_version(),
                         'retries': args.retries, 'cache': settings['cache']}}
    doc = report.write(out, kind, records, meta, refit=refit, effect_set=effect_set,
                       alpha=args.alpha, plots=not args.no_plots)
    c_ = doc['counts']
    say(f'{c_["ok"]} done ({c_["cached"]} cached), {c_["failed"]} failed, '
        f'{c_["rerun_tasks"]} task(s) run again; wrote {out / "campaign.md"}')
    for qn, t in doc['trends'].items():
        if t['verdict'] in ('drift', 'step'):
            where = f' at {t["step_mission"]}' if t['verdict'] == 'step' else \
                f' {t["slope"]:.3g}/{t["slope_per"]}'
            say(f'  {qn}: {t["verdict"]}{where}')
    return 0


def _check_map(path: str | None) -> tuple[str | None, str | None]:
    """The map's absolute path and kind (``bag`` or ``text``), read once here so that a bad
    map is one error before any task runs; (None, None) without a map.

    Raises
    ------
    CampaignError
        the map is missing or invalid (the map reader's one-line reason).
    """
    if path is None:
        return None, None
    from auv_logs.errors import RealLogError
    from auv_logs.mapping import load_map

    try:
        logmap = load_map(path)
    except (RealLogError, OSError) as exc:
        raise CampaignError(str(exc).splitlines()[0] if str(exc) else f'bad map {path}'
                            ) from None
    return str(pathlib.Path(path).resolve()), str(logmap.kind)


def _montecarlo(args: argparse.Namespace, say: Any) -> int:
    import distributed

    from auv_campaign.montecarlo import nominal_pilot, run_chunk, summarise, warm

    dist: Any = distributed
    draw = parse_draw(args)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    chunks = [list(range(a, min(a + args.chunk, draw.runs)))
              for a in range(0, draw.runs, args.chunk)]
    t0 = time.perf_counter()
    # the fixed cost once, here: the pilot designed (and, for the embedded cluster whose
    # workers are forked from this process, the kernels loaded) before the cluster starts
    pilot = nominal_pilot(draw.vehicle)
    if args.scheduler is None:
        warm(draw)
    with engine.client(args.workers, args.scheduler, args.timeout, fork=True) as c:
        cluster = engine.describe(c)
        t_tasks = time.perf_counter()
        say(f'montecarlo: {draw.runs} runs in {len(chunks)} task(s) on '
            f'{cluster["workers"]} worker(s)')
        shared = c.scatter(pilot, broadcast=True, hash=False)
        keys = [f'montecarlo-{i:05d}' for i in range(len(chunks))]
        futures = [c.submit(run_chunk, draw, ch, shared, key=k, retries=args.retries,
                            pure=False)
                   for k, ch in zip(keys, chunks)]
        results: dict[str, list[dict[str, Any]]] = {}
        failed_tasks = []
        for n, fut in enumerate(dist.as_completed(futures, loop=c.loop), 1):
            try:
                results[fut.key] = fut.result()
            except Exception as exc:
                failed_tasks.append({'task': fut.key, 'reason': f'{type(exc).__name__}: {exc}'})
            say(f'[{n}/{len(futures)}] {time.perf_counter() - t0:7.1f} s  {fut.key}')
        tasks_wall = time.perf_counter() - t_tasks
        history = engine.task_history(c, keys)
        del futures, shared
    wall = time.perf_counter() - t0
    runs = [r for k in keys for r in results.get(k, [])]
    summary = summarise(runs)
    rerun = [{'task': k, 'worker_deaths': h['worker_deaths'],
              'retries': args.retries - h['retries_left']}
             for k, h in history.items() if h['worker_deaths'] or h['retries_left'] < args.retries]
    doc = {'draw': {**vars(draw), 'spreads': dict(draw.spreads),
                    'effects': {e: dict(f) for e, f in draw.effects.items()}},
           'cluster': cluster, 'wall_s': wall, 'tasks_wall_s': tasks_wall,
           'chunks': len(chunks),
           'vehicle_steps_per_s': summary['vehicle_steps'] / wall if wall > 0 else None,
           'vehicle_steps_per_s_tasks': summary['vehicle_steps'] / tasks_wall
           if tasks_wall > 0 else None,
           'summary': summary, 'failed_tasks': failed_tasks, 'rerun': rerun, 'runs': runs}
    (out / 'montecarlo.json').write_text(dumps(doc, indent=1) + '\n')
    _write_csv(out / 'runs.csv', runs)
    (out / 'montecarlo.md').write_text(_mc_markdown(doc))
    say(f'{summary["flown"]} flown, {summary["tumbled"]} tumbled, {summary["not_settled"]} not '
        f'settled, {summary["failed"]} failed; {doc["vehicle_steps_per_s"]:.3g} vehicle-steps/s;'
        f' wrote {out / "montecarlo.md"}')
    return 0


def _write_csv(path: pathlib.Path, runs: Sequence[dict[str, Any]]) -> None:
    cols = ['run', 'status', 'z_target', 'settling_time', 'peak_pitch_deg', 'final_error',
            'tumbled', 'steps', 'reason']
    extra = sorted({f'factor.{k}' for r in runs for k in r['factors']}
                   | {f'{e}.{f}' for r in runs for e, fs in r['effects'].items() for f in fs})
    with open(path, 'w', newline='') as fh:
        w = csv.writer(fh)
        w.writerow(cols + extra)
        for r in runs:
            flat = {f'factor.{k}': v for k, v in r['factors'].items()}
            flat.update({f'{e}.{f}': v for e, fs in r['effects'].items() for f, v in fs.items()})
            w.writerow([r.get(k, '') for k in cols] + [flat.get(k, '') for k in extra])


def _mc_markdown(doc: dict[str, Any]) -> str:
    s = doc['summary']

    def q(key: str, unit: str) -> str:
        v = s[key]
        return 'n/a' if v is None else (f'{v["p50"]:.3g} {unit} (5-95 %: {v["p5"]:.3g} - '
                                        f'{v["p95"]:.3g})')
    d = doc['draw']
    lines = ['# Closed-loop Monte Carlo', '',
             f'{s["runs"]} runs of {d["duration"]:g} s from {d["z0"]:g} m at {d["u0"]:g} m/s, '
             f'depth steps of {d["step"][0]:g}-{d["step"][1]:g} m; pilot designed on '
             f'`{d["vehicle"]}`; seed {d["seed"]}.', '',
             f'- spreads (relative, 1 sigma): {d["spreads"] or "none"}',
             f'- effects (uniform): {d["effects"] or "none"}', '',
             '| figure | value |', '| --- | --- |',
             f'| flown / failed draws | {s["flown"]} / {s["failed"]} |',
             f'| tumbled (> {math.degrees(d["tumble_angle"]):g} deg or diverged) '
             f'| {s["tumbled"]} |',
             f'| not settled within +-{d["band"]:g} m | {s["not_settled"]} |',
             f'| settling time, median | {q("settling_time", "s")} |',
             f'| peak pitch, median | {q("peak_pitch_deg", "deg")} |',
             f'| final depth error, median | {q("final_error", "m")} |',
             f'| throughput | {doc["vehicle_steps_per_s"]:.3g} vehicle-steps/s on '
             f'{doc["cluster"]["workers"]} worker(s), {doc["wall_s"]:.1f} s |']
    if doc['rerun']:
        lines += ['', 'Tasks run again: ' + ', '.join(
            f'{r["task"]} ({r["worker_deaths"]} worker death(s), {r["retries"]} retries)'
            for r in doc['rerun'])]
    if doc['failed_tasks']:
        lines += ['', 'Tasks that failed: ' + '; '.join(
            f'{f["task"]}: {f["reason"]}' for f in doc['failed_tasks'])]
    failed = [r for r in doc['runs'] if r['status'] != 'ok']
    if failed:
        lines += ['', 'Draws that could not fly: ' + '; '.join(
            f'run {r["run"]}: {r["reason"]}' for r in failed[:20])]
    return '\n'.join(lines) + '\n'


def main(argv: Sequence[str] | None = None) -> int:
    """Stand-alone entry point (the umbrella ``auv`` command maps ``campaign`` here)."""
    parser = argparse.ArgumentParser(prog='auv campaign', description=__doc__.splitlines()[0])
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return run(args)
    except CampaignError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1


if __name__ == '__main__':
    sys.exit(main())

