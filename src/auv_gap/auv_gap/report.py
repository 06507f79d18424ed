"""Writing a diagnosis: ``report.json`` (the contract of the architecture document),
``details.json`` (everything else), and ``report.md`` with PNG plots (matplotlib, Agg)."""
from __future__ import annotations

import math
import pathlib
from typing import Any

import numpy as np

from auv_contract.jsonout import dumps, plain
from auv_gap.catalogue import CATALOGUE
from auv_gap.errors import GapError
from auv_gap.problem import EQ_UNITS, EQUATIONS
from auv_gap.verdict import Diagnosis

REPORT_KEYS = ('verdict', 'gap', 'candidates', 'best', 'ambiguous_with',
               'suggested_manoeuvre', 'held_out', 'statement', 'residual_tests', 'implausible',
               'signals', 'findings', 'diverges')


def write_report(diag: Diagnosis, out: str | pathlib.Path, plots: bool = True) -> pathlib.Path:
    """Write ``report.json``, ``details.json``, ``report.md`` and PNG plots into ``out``."""
    out = pathlib.Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise GapError(f'cannot create output directory {out}: {exc.strerror}') from None
    report = plain(diag.report)
    assert tuple(report) == REPORT_KEYS
    (out / 'report.json').write_text(dumps(report, indent=2) + '\n')
    (out / 'details.json').write_text(dumps(diag.details, indent=2) + '\n')
    figures = _plots(diag, out) if plots else []
    (out / 'report.md').write_text(_markdown(diag, figures))
    return out / 'report.json'


def _fmt(v: float | None, unit: str = '', digits: int = 4) -> str:
    if v is None or not math.isfinite(v):
        return 'n/a'
    return f'{v:.{digits}g}{(" " + unit) if unit else ""}'


def _markdown(diag: Diagnosis, figures: list[tuple[str, str]]) -> str:
    r, d = diag.report, diag.details
    lines = ['# Sim-to-real gap diagnosis', '']
    lines += [f'**Verdict: {r["verdict"]}**' + (f' — best: `{r["best"]}`' if r['best'] else '')]
    lines += ['', r['statement']]
    rt = r['residual_tests']
    if r['best']:
        lines += ['', f'Residual tests of the best ({rt["residual"]}; Ljung-Box, mean and '
                  f'cross-correlation with inputs and states, {rt["n_tests"]} tests at a '
                  f'family-wise level of {rt["alpha"]:g}): '
                  + ('white and independent.' if rt['white'] else
                     'structure left: ' + '; '.join(rt['left_over']) + '.')]
    if r['ambiguous_with']:
        lines += ['', f'The held-out data cannot tell `{r["best"]}` from '
                  + ', '.join(f'`{n}`' for n in r['ambiguous_with'])
                  + f'. To separate them, fly {r["suggested_manoeuvre"]}.']
    elif r['suggested_manoeuvre']:
        lines += ['', f'Suggested: {r["suggested_manoeuvre"]}.']
    if r.get('findings'):
        lines += ['', '## From the quiet stretches (thruster-off coasts, surface passes)', '']
        lines += [f'- {f["text"]} ({f["source"]})' for f in r['findings']]
    held = r['held_out']
    lines += ['', '## Held-out free run (depth, pitch)', '',
              '| | before (nominal) | after (best) |', '| --- | --- | --- |',
              f'| depth RMS | {_fmt(held["rms_before"]["z"], "m")} | '
              f'{_fmt(held["rms_after"]["z"], "m")} |',
              f'| pitch RMS | {_fmt(np.degrees(held["rms_before"]["theta"]), "deg")} | '
              f'{_fmt(np.degrees(held["rms_after"]["theta"]), "deg")} |', '',
              f'Shrink: {held["shrink"]:.1%} of the held-out gap above the noise floor (all '
              f'states; depth alone {held["shrink_depth"]:.1%}, its floor '
              f'{_fmt(held["floor"]["z"], "m")}) on windows not '
              'used to fit the effects. Free runs restart from the logged state at each '
              f'{d["window_s"]:.3g}-s window'
              + (f' ({d["window_why"]})' if d.get('window_why', 'given') != 'given' else '')
              + (f', and within it every {d["run_s"]:.3g} s ({d["run_why"]})'
                 if d.get('run_s', d['window_s']) < d['window_s'] else '')
              + '; the log is compared smoothed over 1 s.']
    gap = r['gap']
    lines += ['', '## Where the gap lies', '',
              '| state | nominal free-run RMS | noise floor |', '| --- | --- | --- |']
    for n in ('z', 'theta', 'u', 'w', 'q', 'v', 'r'):
        unit = 'm' if n == 'z' else ('m/s' if n in 'uvw' else ('rad' if n == 'theta'
                                                                  else 'rad/s'))
        lines.append(f'| {n} | {_fmt(d["free_run_rms_all"][n], unit)} | '
                     f'{_fmt(d["free_run_floor"][n], unit)} |')
    lines += ['', f'States with a gap (RMS above 1.5 x floor): '
              f'{", ".join(d["gap_channels"]) or "none"}.', '',
              '| equation | RMS | noise | ratio |', '| --- | --- | --- | --- |']
    for i, n in enumerate(EQUATIONS):
        rms, sig = d['equation_rms_all'][n], d['equation_sigma'][n]
        lines.append(f'| {n} | {_fmt(rms, EQ_UNITS[i])} | {_fmt(sig, EQ_UNITS[i])} | '
                     f'{rms / sig:.2f} |')
    lines += ['', f'Dominant equation: {gap["dominant_equation"] or "none"}; frequency band: '
              + (f'{gap["band_hz"][0]:.3g}-{gap["band_hz"][1]:.3g} Hz' if gap['band_hz']
                 else 'none above the noise') + '.', '',
              'Windows with the largest nominal depth error (seconds since the start of '
              'the log; ' + _starts(gap.get('time_origin') or {}) + '):', '']
    for s in gap['segments']:
        lines.append(f'- {s.get("log", "")} {s["t0"]:.1f}-{s["t1"]:.1f} s: '
                     f'{_fmt(s["rms_z"], "m", 3)}')
    lines += ['', f'Residual of the {gap["regimes"]["equation"]} equation by regime '
              '(RMS / mean):', '']
    for key, rows in gap['regimes'].items():
        if key == 'equation':
            continue
        cells = ', '.join(f'[{b["lo"]:.3g}, {b["hi"]:.3g}]: {b["rms"]:.3g} / {b["mean"]:.3g}'
                          for b in rows)
        lines.append(f'- {key}: {cells}')
    lines += ['', 'Correlation of that residual with inputs and states (peak over '
              '+-5 s; positive lag: the signal leads):', '',
              '| signal | peak correlation | lag [s] |', '| --- | --- | --- |']
    for c in d['correlation']:
        lines.append(f'| {c["signal"]} | {c["peak_corr"]:.3f} | {c["lag_s"]:.2f} |')
    lines += ['', '## Candidates (held-out score, best first)', '',
              'A candidate with a parameter at or beyond its physically plausible range '
              '(marked !) is not an explanation, however well it fits.', '',
              '| effect | score | explained | parameters (95 % interval) |',
              '| --- | --- | --- | --- |']
    units = {c['effect']: c['units'] for c in d['candidates']}
    ident = {c['effect']: c['identified'] for c in d['candidates']}
    for c in r['candidates']:
        parts = []
        for k, v in c['params'].items():
            lo, hi = c['ci95'][k]
            tag = '' if ident[c['effect']][k] else ' (not identified: no sensitivity at the fit)'
            if k in c['beyond_plausible']:
                plo, phi = c['beyond_plausible'][k]
                tag += f' ! beyond plausible [{_fmt(plo)}, {_fmt(phi)}]'
            parts.append(f'{k} = {_fmt(v)} [{_fmt(lo)}, {_fmt(hi)}] {units[c["effect"]][k]}'
                         + tag)
        lines.append(f'| {c["effect"]} | {_fmt(c["score"], digits=3)} | '
                     f'{c["explained"]:.2f} | {"; ".join(parts)} |')
    seen = {k.split('.')[0] if '+' in c['effect'] else c['effect']
            for c in d['candidates'] for k, v in c['identified'].items() if v}
    unseen = [c['effect'] for c in d['candidates']
              if '+' not in c['effect'] and c['effect'] not in seen]
    if unseen:
        advice = d.get('advice') or {}
        lines += ['', 'Not identifiable from these logs: '
                  + ', '.join(f'`{n}`' for n in unseen) + '. '
                  + ' '.join(f'`{n}` needs {advice.get(n) or _needs(n)}.' for n in unseen)]
    lines += _signals_section(r.get('signals') or {})
    lines += ['', '## Figures', '']
    for title, name in figures:
        lines += [f'![{title}]({name})', '']
    notes = sorted({n for lg in d['logs'] for n in lg['notes']})
    notes += list(d.get('skipped') or [])
    if notes:
        lines += ['## Notes on the logs', ''] + [f'- {n}' for n in notes] + ['']
    return '\n'.join(lines) + '\n'


def _signals_section(sig: dict[str, Any]) -> list[str]:
    """What was not measured (derived, assumed), what the diagnosis left out for it, which
    actuator positions drove the model, and how that limits the answer."""
    left = sig.get('left_out') or {}
    fins = [ch for ch, src in (sig.get('actuators') or {}).items()
            if src == 'measured fin position']
    if not (sig.get('derived') or sig.get('assumed') or fins):
        return []
    lines = ['', '## Signals not measured', '',
             '| signal | | how |', '| --- | --- | --- |']
    for kind in ('derived', 'assumed'):
        for name, how in (sig.get(kind) or {}).items():
            lines.append(f'| {name} | {kind} | {how} |')
    outs = [f'free-run {c} ({why})' for c, why in (left.get('free_run') or {}).items()]
    outs += [f'{e} equation ({why})' for e, why in (left.get('equations') or {}).items()]
    if outs:
        lines += ['', 'Left out of the diagnosis so that no measurement counts twice: '
                  + '; '.join(outs) + '.']
    if fins:
        lines += ['', 'Measured fin positions drove the model for: ' + ', '.join(fins) + '.']
    if sig.get('limits'):
        lines += ['', 'How this limits the answer:', ''] + [f'- {x}' for x in sig['limits']]
    return lines


def _needs(name: str) -> str:
    """What identifies effect ``name`` (in the default envelope's terms)."""
    return CATALOGUE[name].advice()


def _starts(origin: dict[str, Any]) -> str:
    """The logs' starts in UTC, for the reader of relative times."""
    logs = origin.get('logs') or {}
    parts = [f'{name} started {v["utc"]}' if v.get('utc') else f'{name}: no date'
             for name, v in list(logs.items())[:4]]
    if not parts:
        return 'no date'
    return '; '.join(parts) + ('; ...' if len(logs) > 4 else '')


def _plots(diag: Diagnosis, out: pathlib.Path) -> list[tuple[str, str]]:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    p = diag.plots
    pr = p['problem']
    figs: list[tuple[str, str]] = []
    held = pr.select(True)
    perts = [p['nominal']] + ([p['best'].fit.effects.perturbation(p['best'].fit.values)]
                              if p['best'] is not None else [])
    pred, meas = pr.free_run(perts, held)
    # times since the start of each window's log
    t = np.concatenate([pr.output_times([i]) - pr.logs[pr.windows[i].log].origin
                        for i in held])
    rows = pr.window_rows(held)
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    for k, (idx, label, scale) in enumerate(((2, 'depth z [m]', 1.0),
                                             (4, 'pitch [deg]', 180 / np.pi))):
        ax = axes[k]
        for j, r in enumerate(rows):
            ax.plot(t[r], meas[r, idx] * scale, 'k', lw=1.2, label='log' if j == 0 else None)
            ax.plot(t[r], pred[0][r, idx] * scale, 'C3', lw=1,
                    label='nominal' if j == 0 else None)
            if len(perts) > 1:
                ax.plot(t[r], pred[1][r, idx] * scale, 'C0--', lw=1,
                        label=f'with {p["best"].label}' if j == 0 else None)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(loc='best', fontsize=8)
    axes[1].set_xlabel('time since the log\'s start [s] (held-out windows)')
    fig.tight_layout()
    fig.savefig(out / 'free_run_held_out.png', dpi=90)
    plt.close(fig)
    figs.append(('held-out free runs', 'free_run_held_out.png'))

    e = p['e_nom'] / pr.eq_sigma
    since = pr.eq_t - np.array([lg.origin for lg in pr.logs])[pr.eq_log]
    fig, ax = plt.subplots(figsize=(10, 4))
    for k, n in enumerate(EQUATIONS):
        ax.plot(since, e[:, k], '.', ms=1.5, label=n)
    ax.set_ylabel('equation error / noise')
    ax.set_xlabel('time since the log\'s start [s]')
    ax.legend(fontsize=8, markerscale=6, ncol=3)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / 'equation_error.png', dpi=90)
    plt.close(fig)
    figs.append(('nominal equation error', 'equation_error.png'))

    cands = p['candidates'][:12]
    fig, ax = plt.subplots(figsize=(8, 0.35 * len(cands) + 1.2))
    ax.barh([c.label for c in cands][::-1], [c.explained for c in cands][::-1], color='C0')
    ax.set_xlabel('share of the held-out gap explained')
    ax.set_xlim(0, 1)
    fig.tight_layout()
    fig.savefig(out / 'candidates.png', dpi=90)
    plt.close(fig)
    figs.append(('candidates', 'candidates.png'))

    band = p['band']
    if band:
        fig, ax = plt.subplots(figsize=(8, 4))
        ax.loglog(band['f'][1:], band['psd'][1:], label=f'{p["focus"]} residual')
        ax.loglog(band['f'][1:], band['noise'][1:], '--', label='sensor noise alone')
        if p['band_hz']:
            ax.axvspan(max(p['band_hz'][0], band['f'][1]), p['band_hz'][1], alpha=0.15)
        ax.set_xlabel('frequency [Hz]')
        ax.set_ylabel('PSD')
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(out / 'residual_psd.png', dpi=90)
        plt.close(fig)
        figs.append(('residual spectrum', 'residual_psd.png'))

    fig, ax = plt.subplots(figsize=(8, 4))
    for c in p['corr']:
        ax.plot(c['lags'], c['curve'], label=c['signal'])
    ax.set_xlabel('lag [s] (signal leads residual)')
    ax.set_ylabel('correlation')
    ax.legend(fontsize=7, ncol=2)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / 'correlation.png', dpi=90)
    plt.close(fig)
    figs.append(('residual correlation', 'correlation.png'))
    return figs
