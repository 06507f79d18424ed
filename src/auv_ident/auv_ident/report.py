"""Outputs of an identification: vehicle file, ``report.json``, fit plots and ``report.md``.

* ``<out>/vehicle.yaml``: the base vehicle file (same format as ``config/a18m.yaml``, written
  by :func:`auv_sim.params.save_vehicle`) with the identified coefficients replaced, each
  with its source ``identified from <records> (<equation> fit), <force source>, +-<95 % CI>``
  and a ``provenance`` block (bags, base file, method, time).
* ``<out>/report.json``: :func:`auv_ident.identify.summary` plus bags, files and the
  Nelder-Mead comparison.
* ``<out>/fig<N>_<equation>.png``: measured against fitted force or moment over time and as a
  scatter (the report's figures 2-6), degrees and SI units on the axes.
* ``<out>/report.md``: the readable report linking the figures.
"""
from __future__ import annotations

import datetime
import math
import pathlib
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from auv_contract.jsonout import dumps
from auv_ident.identify import AXES, EquationFit, Identification, summary
from auv_sim.params import save_vehicle

SOURCE_TEXT = {'forces': 'forces from the /auv/hydrodynamic_forces topic',
               'motion': 'forces reconstructed from the logged motion (M nu_dot minus '
                         'Coriolis, restoring and actuator terms)'}
_MAX_PLOT_POINTS = 6000


def coefficient_sources(result: Identification) -> dict[str, str]:
    """The vehicle-file source text of every identified coefficient and of every term a
    chosen structure sets (a coefficient left at its prior keeps the file's source)."""
    out = {}
    for name, fit in result.fits.items():
        if not fit.identified:
            continue
        for c in fit.coefficients:
            if c.at_prior:
                continue
            where = ', '.join(c.records) or ', '.join(dict.fromkeys(fit.record_names)) \
                or 'the logs'
            half = 0.5 * (c.ci95[1] - c.ci95[0])
            bound = ', on its physical bound' if c.at_bound else ''
            how = f'{name} fit' if c.method == 'equation error' else f'{name}, output error'
            out[c.name] = (f'identified from {where} ({how}), '
                           f'{SOURCE_TEXT[result.source].split(" (")[0]}, '
                           f'+-{half:.3g} (95 %){bound}')
        for term, value in fit.structures.get('set', {}).items():
            out[term] = (f'set to {value:g}: the {fit.structure} structure predicted held-out '
                         f'data of the {name} equation best (auv ident)')
    return out


def plot_fit(fit: EquationFit, path: pathlib.Path) -> None:
    """Figure of one equation: measured and fitted component over time (every record, one
    after another), and their scatter."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    eq = fit.equation
    label = f'{AXES[eq.axis]} [{eq.unit}]'
    names = ', '.join(c.name for c in fit.coefficients)
    fig, (ax_t, ax_s) = plt.subplots(1, 2, figsize=(12, 4.2),
                                     gridspec_kw={'width_ratios': [2.2, 1]})
    offset = 0.0
    step = max(1, len(fit.t) // _MAX_PLOT_POINTS)
    for i, rec in enumerate(fit.record_names):
        sel = np.flatnonzero(fit.record_index == i)
        if len(sel) == 0:
            continue
        t = fit.t[sel] - fit.t[sel[0]] + offset
        ax_t.plot(t[::step], fit.measured[sel][::step], color='0.35', lw=0.8,
                  label='measured' if offset == 0 else None)
        ax_t.plot(t[::step], fit.fitted[sel][::step], color='tab:red', lw=0.8, ls='--',
                  label='fitted' if offset == 0 else None)
        if offset > 0:
            ax_t.axvline(offset, color='0.8', lw=0.6)
        ax_t.text(offset, 1.0, f' {rec}', transform=ax_t.get_xaxis_transform(), va='top',
                  fontsize=7, color='0.4')
        offset = float(t[-1]) + 1.0
    ax_t.set_xlabel('time in the data set [s] (records one after another)')
    ax_t.set_ylabel(f'hydrodynamic {label}')
    ax_t.set_title(f'Figure {eq.figure}: {eq.name} fit ({names}), R$^2$ = {fit.r2:.4f}')
    ax_t.legend(loc='lower right', fontsize=8)
    ax_t.grid(alpha=0.3)
    ax_s.plot(fit.measured[::step], fit.fitted[::step], '.', ms=1.5, color='tab:blue')
    lo = float(min(fit.measured.min(), fit.fitted.min())) if fit.n_samples else 0.0
    hi = float(max(fit.measured.max(), fit.fitted.max())) if fit.n_samples else 1.0
    ax_s.plot([lo, hi], [lo, hi], color='k', lw=0.8)
    ax_s.set_xlabel(f'measured {label}')
    ax_s.set_ylabel(f'fitted {label}')
    ax_s.set_title(f'NRMSE = {fit.nrmse:.4f}')
    ax_s.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_record(result: Identification, index: int, name: str, path: pathlib.Path) -> bool:
    """Figure of one record: for every fitted equation, its measured and fitted component
    over the record's time. False when no equation has samples of the record."""
    fits = [f for f in result.fits.values()
            if len(f.record_index) and np.any(f.record_index == index)]
    if not fits:
        return False
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(fits), 1, figsize=(11, 2.3 * len(fits) + 0.6), squeeze=False,
                             sharex=True)
    for ax, fit in zip(axes[:, 0], fits):
        sel = np.flatnonzero(fit.record_index == index)
        step = max(1, len(sel) // (_MAX_PLOT_POINTS // 2))
        t = fit.t[sel] - fit.t[sel[0]]
        ax.plot(t[::step], fit.measured[sel][::step], color='0.35', lw=0.8, label='measured')
        ax.plot(t[::step], fit.fitted[sel][::step], color='tab:red', lw=0.8, ls='--',
                label='fitted')
        ax.set_ylabel(f'{fit.equation.name}\n{AXES[fit.equation.axis]} '
                      f'[{fit.equation.unit}]', fontsize=8)
        ax.grid(alpha=0.3)
    axes[0, 0].set_title(f'record {name}: hydrodynamic forces, measured and fitted')
    axes[0, 0].legend(loc='lower right', fontsize=8)
    axes[-1, 0].set_xlabel('time in the record [s] (samples used by the fit)')
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return True


def _fmt(x: float, digits: int = 5) -> str:
    return f'{x:.{digits}g}' if math.isfinite(x) else 'n/a'


def markdown(result: Identification, doc: Mapping[str, Any], figures: Mapping[str, str],
             nelder_mead: Mapping[str, Mapping[str, Any]] | None,
             record_figures: Mapping[str, str] | None = None) -> str:
    """The readable report (Markdown)."""
    offsets = 'fitted' if result.fit_offsets else 'fixed at the base values (as the report)'
    bounds = ', '.join(f'{k} in [{v[0]:g}, {v[1]:g}]' for k, v in result.bounds.items())
    val = doc.get('validation') or {}
    lines = [f'# Identified hydrodynamic coefficients: {result.base.name}', '']
    if val:
        head = 'Written' if val.get('written', True) else '**Not written**'
        lines += [f'{head}: {val.get("message", "")}', '']
    lines += [f'- Bags: {", ".join(doc["bags"])}',
              f'- Base vehicle: `{result.base.path}`',
              f'- Force source: {SOURCE_TEXT[result.source]}',
              f'- Derivatives: {doc.get("derivatives", "equation error")}',
              f'- Standard errors: {doc["errors_text"]}',
              f'- CZ0 and CM0: {offsets}',
              f'- Physical bounds: {result.method.get("bounds", "physical")}'
              + (f' (given: {bounds})' if bounds else ''),
              f'- Priors: {result.method.get("priors", "")}',
              '', 'Each equation is linear in its coefficients. The fit is the posterior of the '
              'file\'s values (each with a width set by its source) and the data, inside the '
              'signs and ranges physics allows (bounded least squares); a coefficient the data '
              'do not inform stays at its file value, and one on its bound says what that '
              'suggests. An equation with R^2 < 0 is not identified.', '']
    if result.source == 'motion':
        lines += ['Forces from motion: the regressors and the forces are passed through the '
                  'same low-pass as the Savitzky-Golay derivative, and the regressors are '
                  'instrumented by their values one filter window before and after (two-stage '
                  'least squares), so velocity noise does not bias the coefficients.', '']
    lines += ['## Coefficients', '',
              '| coefficient | value | std. error | 95 % interval | base | prior sd | data '
              'share | change | fit | note |',
              '| --- | ---: | ---: | --- | ---: | ---: | ---: | ---: | --- | --- |']
    for name, fit in result.fits.items():
        for c in fit.coefficients:
            change = f'{100 * (c.value - c.base) / c.base:+.2f} %' if c.base else 'n/a'
            flag = ' (on bound)' if c.at_bound else (' (prior)' if c.at_prior else '')
            how = name if c.method == 'equation error' else f'{name}, output error'
            if not fit.identified:
                how += ', not identified'
            lines.append(f'| {c.name} | {_fmt(c.value)}{flag} | {_fmt(c.std_error, 3)} | '
                         f'[{_fmt(c.ci95[0])}, {_fmt(c.ci95[1])}] | {_fmt(c.base)} | '
                         f'{_fmt(c.prior_sd, 3)} | {c.informed:.2f} | {change} | {how} | '
                         f'{c.note} |')
    lines += ['', 'Data share: the data\'s part of the coefficient\'s posterior precision '
              '(1 - posterior variance / prior variance): near 0 the logs did not inform it.',
              '', '## Fits', '',
              '| equation | component | structure | R^2 | NRMSE | RMSE | condition number | '
              'samples (effective) | fixed |',
              '| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | --- |']
    for name, fit in result.fits.items():
        eq = fit.equation
        fixed = ', '.join(f'{k} = {_fmt(v)}' for k, v in fit.fixed.items()) or '-'
        lines.append(f'| {name} | {AXES[eq.axis]} [{eq.unit}] | {fit.structure} | '
                     f'{_fmt(fit.r2, 5)} | {_fmt(fit.nrmse, 4)} | {_fmt(fit.rmse, 3)} | '
                     f'{_fmt(fit.condition_number, 3)} | {fit.n_samples} '
                     f'({_fmt(fit.n_effective, 4)}) | {fixed} |')
    lines += ['', 'Condition number of the column-scaled regressor; NRMSE = rms(residual) / '
              '(max - min of the measured component). Structure: `file` (quadratic cross-flow '
              'terms at the file\'s values), `linear` (none), `quadratic` (fitted), chosen by '
              'held-out prediction.', '']
    why = {n: f.why for n, f in result.fits.items() if f.why}
    if why or result.not_identifiable:
        lines += ['## Not identified, refined or left out', '']
        lines += [f'- {k}: {v}' for k, v in {**result.not_identifiable, **why}.items()]
        lines.append('')
    if val and val.get('rms'):
        lines += ['## Validation on held-out data', '',
                  f'{val["windows"]} held-out window(s), {val["seconds"]:.0f} s; initial '
                  f'states: {val["initial_state"]}.', '',
                  '| model | depth rms [m] | pitch rms [deg] | heading rms [deg] |',
                  '| --- | ---: | ---: | ---: |']
        for model in ('base', 'identified'):
            r = val['rms'][model]
            lines.append(f'| {model} | {r["z"]:.4g} | {math.degrees(r["theta"]):.4g} | '
                         f'{math.degrees(r["psi"]):.4g} |')
        lines.append('')
    lines += ['## Coefficient correlations', '']
    for name, fit in result.fits.items():
        cn = [c.name for c in fit.coefficients]
        if len(cn) < 2 or fit.correlation.shape != (len(cn), len(cn)):
            continue
        lines.append(f'- {name}: ' + '; '.join(
            f'{cn[i]}-{cn[j]} {fit.correlation[i, j]:+.3f}'
            for i in range(len(cn)) for j in range(i + 1, len(cn))))
    if nelder_mead:
        lines += ['', '## Bounded Nelder-Mead on the same data (the report\'s method)', '',
                  'Against the data\'s own least-squares solution (no prior, no bound).', '',
                  '| equation | coefficients | least squares | Nelder-Mead '
                  '| max rel. difference |',
                  '| --- | --- | --- | --- | ---: |']
        for name, cmp in nelder_mead.items():
            lines.append(f'| {name} | {", ".join(cmp["names"])} | '
                         f'{", ".join(_fmt(v, 7) for v in cmp["least_squares"])} | '
                         f'{", ".join(_fmt(v, 7) for v in cmp["nelder_mead"])} | '
                         f'{cmp["max_relative_difference"]:.2e} |')
    lines += ['', '## Figures', '']
    for name, fig in figures.items():
        fit = result.fits[name]
        lines += [f'### Figure {fit.equation.figure}: {name}', '', f'![{name} fit]({fig})', '']
    for rec, fig in (record_figures or {}).items():
        lines += [f'### Record {rec}', '', f'![record {rec}]({fig})', '']
    return '\n'.join(lines) + '\n'


def write_outputs(result: Identification, out_dir: str | pathlib.Path, bags: Sequence[str],
                  nelder_mead: Mapping[str, Mapping[str, Any]] | None = None,
                  extra: Mapping[str, Any] | None = None, written: bool = True,
                  records: Sequence[Any] = ()) -> dict[str, str]:
    """Write vehicle file, report.json, figures and report.md into ``out_dir``.

    ``written`` False (the validation rejected the model): the identified vehicle goes to
    ``vehicle.rejected.yaml`` for inspection and no ``vehicle.yaml`` is written (one left
    from an earlier run is removed). ``records``: one figure per record.

    Returns
    -------
    name -> path of every file written.
    """
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files: dict[str, str] = {}
    errors_text = {
        'hac': 'from motion: sensor noise propagated through the filtered equation of motion '
               '(noise levels estimated from the log), or, where the residual is not that '
               'noise, a flat-top lag window (Politis bandwidth); from the force topic: the '
               'flat-top lag window; combined with the priors (posterior covariance)',
        'jackknife': 'delete-a-block jackknife over contiguous blocks of the record',
        'ess': 'sigma^2 (A\'A)^-1 inflated by n / n_eff (residual correlation time)',
        'iid': 'sigma^2 (A\'A)^-1 (white residuals assumed)'}.get(result.errors, result.errors)
    stamp = datetime.datetime.now(datetime.UTC).isoformat(timespec='seconds')
    provenance = {'identification': {
        'tool': 'auv ident', 'time_utc': stamp, 'bags': list(bags),
        'base_vehicle': result.base.path, 'force_source': result.source,
        'standard_errors': result.errors, 'fit_CZ0_CM0': result.fit_offsets,
        'identified': sorted(result.coefficients),
        'validation': str((extra or {}).get('validation', {}).get('message', ''))}}
    vehicle_path = out / ('vehicle.yaml' if written else 'vehicle.rejected.yaml')
    if not written and (out / 'vehicle.yaml').exists():
        (out / 'vehicle.yaml').unlink()
    save_vehicle(result.params, vehicle_path, sources=coefficient_sources(result),
                 provenance=provenance)
    files['vehicle' if written else 'vehicle_rejected'] = str(vehicle_path)
    figures: dict[str, str] = {}
    for name, fit in result.fits.items():
        if fit.n_samples == 0 or len(fit.t) == 0:
            continue
        fname = f'fig{fit.equation.figure}_{name}.png'
        plot_fit(fit, out / fname)
        figures[name] = fname
        files[f'figure_{name}'] = str(out / fname)
    record_figures: dict[str, str] = {}
    for i, rec in enumerate(records):
        safe = ''.join(ch if ch.isalnum() or ch in '-_.' else '_' for ch in str(rec.name))
        fname = f'record_{i:02d}_{safe}.png'
        if plot_record(result, i, rec.name, out / fname):
            record_figures[rec.name] = fname
            files[f'figure_record_{i:02d}'] = str(out / fname)
    doc = summary(result)
    doc.update({'bags': list(bags), 'base_vehicle': result.base.path, 'time_utc': stamp,
                'errors_text': errors_text, 'figures': figures,
                'record_figures': record_figures,
                'nelder_mead': dict(nelder_mead) if nelder_mead else None,
                'written': written})
    if extra:
        doc.update(extra)
    files['report_md'] = str(out / 'report.md')
    files['report_json'] = str(out / 'report.json')
    doc['files'] = dict(files)
    (out / 'report.md').write_text(markdown(result, doc, figures, nelder_mead, record_figures))
    (out / 'report.json').write_text(dumps(doc, indent=2) + '\n')
    return files
