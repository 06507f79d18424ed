"""The campaign report: ``campaign.json``, ``campaign.md`` and one plot per quantity.

Missions are ordered by mission time (the log time of the bag's first message, UTC; missions
whose bag has no readable time go last, by name). Per mission: time, duration, verdict, the
effects or coefficients with their 95 % intervals, and a link to the single-log report. Per
quantity: its values against mission time with their intervals (PNG, matplotlib Agg), and the
drift and step tests of :mod:`.trend`. Failed missions are listed with their reason, tasks
run again after a worker died or a fault are listed too.
"""
from __future__ import annotations

import datetime
import math
import pathlib
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from auv_campaign import trend
from auv_contract.jsonout import dumps, plain

#: Reorderings of the permutation tests.
PERMUTATIONS = 1999


def mission_order(records: Sequence[Mapping[str, Any]]) -> list[int]:
    """Indices of ``records`` by mission time, undated ones last by name."""
    def key(i: int) -> tuple[int, float, str]:
        t = records[i].get('start_time')
        return (0, float(t), records[i]['name']) if t is not None else (1, 0.0,
                                                                        records[i]['name'])
    return sorted(range(len(records)), key=key)


def _utc(t: float | None) -> str:
    if t is None:
        return 'unknown'
    return datetime.datetime.fromtimestamp(t, datetime.UTC).strftime('%Y-%m-%d %H:%M:%S')


def _g(v: float | None, digits: int = 4) -> str:
    return 'n/a' if v is None or not math.isfinite(v) else f'{v:.{digits}g}'


def _fmt_q(q: Mapping[str, Any]) -> str:
    ci = q.get('ci95')
    unit = f' {q["unit"]}' if q.get('unit') else ''
    rng = f' [{_g(ci[0])}, {_g(ci[1])}]' if ci else ''
    return f'{_g(q.get("value"))}{rng}{unit}'


def series(records: Sequence[Mapping[str, Any]], order: Sequence[int]
           ) -> dict[str, dict[str, Any]]:
    """Per quantity, over the ordered successful missions: names, times [s] (or mission
    numbers when a time is missing), values, 95 % intervals, unit."""
    names = sorted({q for i in order if records[i]['status'] == 'ok'
                    for q in records[i].get('quantities', {})})
    dated = all(records[i].get('start_time') is not None for i in order
                if records[i]['status'] == 'ok')
    out: dict[str, dict[str, Any]] = {}
    for qn in names:
        s: dict[str, Any] = {'missions': [], 'x': [], 'value': [], 'ci95': [], 'unit': '',
                             'x_is_time': dated}
        for pos, i in enumerate(order):
            r = records[i]
            q = r.get('quantities', {}).get(qn) if r['status'] == 'ok' else None
            if q is None or q.get('value') is None:
                continue
            s['missions'].append(r['name'])
            s['x'].append(float(r['start_time']) if dated else float(pos))
            s['value'].append(float(q['value']))
            s['ci95'].append(q.get('ci95'))
            s['unit'] = q.get('unit') or s['unit']
        out[qn] = s
    return out


def tests(ser: Mapping[str, Mapping[str, Any]], alpha: float = 0.01,
          permutations: int = 999) -> dict[str, dict[str, Any]]:
    """The drift and step tests of every quantity (see :func:`trend.analyse`); slopes are
    per day when the missions are dated, else per mission."""
    out: dict[str, dict[str, Any]] = {}
    for qn, s in ser.items():
        se = [trend.standard_error(c) if c else math.nan for c in s['ci95']]
        x = np.asarray(s['x'], dtype=np.float64)
        scale = trend.SECONDS_PER_DAY if s['x_is_time'] else 1.0
        res = trend.analyse(x / scale, s['value'], se, alpha=alpha, permutations=permutations)
        used = res.get('used', [])
        res['slope_per'] = 'day' if s['x_is_time'] else 'mission'
        if res['verdict'] != 'too_few':
            k = res['step_index']
            res['step_mission'] = s['missions'][used[k]]
            res['last_before_step'] = s['missions'][used[k - 1]]
        out[qn] = res
    return out


def _plot(qn: str, s: Mapping[str, Any], t: Mapping[str, Any], path: pathlib.Path) -> None:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    x = np.asarray(s['x'], dtype=np.float64)
    xs: Any = [datetime.datetime.fromtimestamp(v, datetime.UTC) for v in x] \
        if s['x_is_time'] else x
    y = np.asarray(s['value'])
    lo = np.array([c[0] if c else np.nan for c in s['ci95']])
    hi = np.array([c[1] if c else np.nan for c in s['ci95']])
    fig, ax = plt.subplots(figsize=(8, 3.6))
    ax.errorbar(xs, y, yerr=[np.nan_to_num(y - lo), np.nan_to_num(hi - y)], fmt='o', ms=3,
                capsize=2, lw=1, label='estimate, 95 % interval')
    verdict = t.get('verdict')
    if verdict == 'drift':
        scale = trend.SECONDS_PER_DAY if s['x_is_time'] else 1.0
        xu = x[t['used']] / scale
        ax.plot([xs[i] for i in t['used']], t['intercept'] + t['slope'] * xu, 'r-', lw=1.2,
                label=f'drift {t["slope"]:.3g} /{t["slope_per"]}')
    elif verdict == 'step':
        used, k = t['used'], t['step_index']
        ax.plot([xs[i] for i in used[:k]], [t['before']['mean']] * k, 'r-', lw=1.5,
                label='step')
        ax.plot([xs[i] for i in used[k:]], [t['after']['mean']] * (len(used) - k), 'r-',
                lw=1.5)
    ax.set_title(f'{qn}: {verdict}')
    ax.set_ylabel(f'{qn} [{s["unit"]}]' if s['unit'] else qn)
    ax.set_xlabel('mission start (UTC)' if s['x_is_time'] else 'mission')
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.autofmt_xdate()
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def write(out: str | pathlib.Path, kind: str, records: Sequence[Mapping[str, Any]],
          meta: Mapping[str, Any], refit: Sequence[Mapping[str, Any]] | None = None,
          effect_set: Sequence[str] = (), alpha: float = 0.01, plots: bool = True
          ) -> dict[str, Any]:
    """Write ``campaign.json``, ``campaign.md`` and ``plots/*.png`` into ``out``; returns
    the JSON document.

    ``refit``: for a gap campaign, the records of the second pass that fitted
    ``effect_set`` in every mission; the series and tests use them when given.
    """
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    order = mission_order(records)
    basis = refit if refit is not None else records
    ser = series(basis, order)
    tst = tests(ser, alpha=alpha, permutations=PERMUTATIONS)
    figures: dict[str, str] = {}
    if plots:
        (out / 'plots').mkdir(exist_ok=True)
        for qn, s in ser.items():
            if s['value']:
                fname = f'plots/{qn.replace("/", "_")}.png'
                _plot(qn, s, tst[qn], out / fname)
                figures[qn] = fname
    ok = [records[i] for i in order if records[i]['status'] == 'ok']
    failed = [records[i] for i in order if records[i]['status'] != 'ok']
    all_recs = list(records) + list(refit or [])
    rerun = [{'task': r.get('task'), 'name': r['name'], 'worker_deaths': r['worker_deaths'],
              'retries': r['retries']}
             for r in all_recs if r.get('worker_deaths', 0) or r.get('retries', 0)]
    doc = {
        'kind': kind, **meta,
        'missions': [records[i] for i in order],
        'counts': {'missions': len(records), 'ok': len(ok), 'failed': len(failed),
                   'cached': sum(1 for r in records if r.get('cached')),
                   'rerun_tasks': len(rerun)},
        'failed': [{'name': r['name'], 'log': r['log'], 'reason': r['reason']} for r in failed],
        'rerun': rerun,
        'worker_peak_rss_mb': max((float(r['worker_peak_rss_mb']) for r in all_recs
                                   if r.get('worker_peak_rss_mb') and not r.get('cached')),
                                  default=None),
        'series_from': 'refit' if refit is not None else 'missions',
        'effect_set': list(effect_set),
        'series': ser, 'trends': tst, 'figures': figures,
        'tests': {'alpha': alpha, 'permutations': PERMUTATIONS},
    }
    if refit is not None:
        doc['refit'] = [refit[i] for i in order]
    doc = plain(doc)
    (out / 'campaign.json').write_text(dumps(doc, indent=1) + '\n')
    (out / 'campaign.md').write_text(_markdown(doc))
    return dict(doc)


def _markdown(doc: Mapping[str, Any]) -> str:
    c = doc['counts']
    title = 'Identification' if doc['kind'] == 'ident' else 'Sim-to-real gap'
    lines = [f'# {title} campaign', '',
             f'{c["missions"]} missions: {c["ok"]} done ({c["cached"]} from the cache), '
             f'{c["failed"]} failed; {c["rerun_tasks"]} task(s) run again. '
             f'Cluster: {doc.get("cluster", {}).get("workers", "?")} worker(s); '
             f'wall time {_g(doc.get("wall_s"), 3)} s.', '']
    tr = doc['trends']
    lines += ['## Drift and steps', '']
    if doc['series_from'] == 'refit':
        lines += ['Series from a second pass that fitted the effects named in any mission '
                  f'(`{"+".join(doc["effect_set"])}`) jointly to every mission (the '
                  "diagnosis' equation-error fit on its training windows), so that each "
                  'quantity has a value with its interval in every mission.', '']
    elif doc['kind'] == 'gap':
        lines += ['Series from the best effect set of each mission: a quantity is missing '
                  'from the missions whose best set lacks its effect.', '']
    lines += [f'Permutation tests ({doc["tests"]["permutations"]} reorderings), '
              f'significance level {doc["tests"]["alpha"]}: *drift* = weighted linear trend, '
              '*step* = single change point (weighted '
              'likelihood ratio); the model with the lower BIC is named when both are '
              'significant.', '',
              '| quantity | missions | verdict | slope [95 %] | p drift | step at mission | '
              'before -> after | p step |',
              '| --- | --- | --- | --- | --- | --- | --- | --- |']
    for qn, t in tr.items():
        if t['verdict'] == 'too_few':
            lines.append(f'| `{qn}` | {t["n"]} | too few | | | | | |')
            continue
        lo, hi = t['slope_ci95']
        step = t['step_mission'] if t['verdict'] == 'step' else f'({t["step_mission"]})'
        lines.append(
            f'| `{qn}` | {t["n"]} | **{t["verdict"]}** | {_g(t["slope"], 3)} '
            f'[{_g(lo, 3)}, {_g(hi, 3)}] /{t["slope_per"]} | {_g(t["p_trend"], 2)} | {step} | '
            f'{_g(t["before"]["mean"])} -> {_g(t["after"]["mean"])} | {_g(t["p_step"], 2)} |')
    lines += ['', 'Step location in parentheses: the most likely change point of a quantity '
              'not found to step.', '', '## Missions', '']
    joint = {r['name']: r for r in doc.get('refit') or []}
    head = '| mission | start (UTC) | duration [s] | verdict | values [95 % interval] |'
    if joint:
        head += ' joint fit [95 % interval] |'
    lines += [head + ' report |', '|' + ' --- |' * (head.count('|'))]
    for r in doc['missions']:
        if r['status'] != 'ok':
            continue
        verdict = r.get('verdict') or ''
        if r.get('best'):
            verdict += f' `{r["best"]}`'
        if r.get('ambiguous_with'):
            verdict += ' (or ' + ', '.join(r['ambiguous_with']) + ')'
        qs = '<br>'.join(f'{k} = {_fmt_q(q)}' for k, q in r.get('quantities', {}).items())
        rel = pathlib.Path(r['report']).relative_to(doc['out']) if r.get('report') and \
            str(r['report']).startswith(str(doc['out'])) else r.get('report', '')
        row = (f'| {r["name"]} | {_utc(r.get("start_time"))} | '
               f'{_g(r.get("duration_s"), 5)} | {verdict} | {qs or "-"} |')
        if joint:
            j = joint.get(r['name'], {})
            row += ' ' + ('<br>'.join(f'{k} = {_fmt_q(q)}' for k, q in
                                      j.get('quantities', {}).items())
                          if j.get('status') == 'ok' else j.get('reason') or '-') + ' |'
        lines.append(f'{row} {rel} |')
    if doc['failed']:
        lines += ['', '## Failed missions', '', '| mission | log | reason |',
                  '| --- | --- | --- |']
        lines += [f'| {f["name"]} | {f["log"]} | {f["reason"]} |' for f in doc['failed']]
    if doc['rerun']:
        lines += ['', '## Tasks run again', '', '| task | mission | worker deaths | retries |',
                  '| --- | --- | --- | --- |']
        lines += [f'| {r["task"]} | {r["name"]} | {r["worker_deaths"]} | {r["retries"]} |'
                  for r in doc['rerun']]
    if doc['figures']:
        lines += ['', '## Plots', '']
        lines += [f'![{qn}]({path})' for qn, path in doc['figures'].items()]
    return '\n'.join(lines) + '\n'
