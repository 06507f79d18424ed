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
import json
import math
import pathlib
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from auv_ident.identify import AXES, EquationFit, Identification, summary
from auv_sim.params import save_vehicle

SOURCE_TEXT = {'forces': 'forces from the /auv/hydrodynamic_forces topic',
               'motion': 'forces reconstructed from the logged motion (M nu_dot minus '
                         'Coriolis, restoring and actuator terms)'}
_MAX_PLOT_POINTS = 20000


def _jsonable(obj: Any) -> Any:
    """``obj`` with non-finite floats as None and numpy values as Python ones."""
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def coefficient_sources(result: Identification) -> dict[str, str]:
    """The vehicle-file source text of every identified coefficient."""
    out = {}
    for name, fit in result.fits.items():
        for c in fit.coefficients:
            where = ', '.join(c.records) or ', '.join(dict.fromkeys(fit.record_names))
            half = 0.5 * (c.ci95[1] - c.ci95[0])
            bound = ', on its bound' if c.at_bound else ''
            out[c.name] = (f'identified from {where} ({name} fit), '
                           f'{SOURCE_TEXT[result.source].split(" (")[0]}, '
                           f'+-{half:.3g} (95 %){bound}')
    return out


def plot_fit(fit: EquationFit, path: pathlib.Path) -> None:
    """Figure of one equation: measured and fitted component over time, and their scatter."""
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
    for i, rec in enumerate(dict.fromkeys(fit.record_names)):
        sel = np.flatnonzero(fit.record_index == i)
        if len(sel) == 0:
            continue
        t = fit.t[sel] - fit.t[sel[0]] + offset
        ax_t.plot(t[::step], fit.measured[sel][::step], color='0.35', lw=0.8,
                  label='measured' if i == 0 else None)
        ax_t.plot(t[::step], fit.fitted[sel][::step], color='tab:red', lw=0.8, ls='--',
                  label='fitted' if i == 0 else None)
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


def _fmt(x: float, digits: int = 5) -> str:
    return f'{x:.{digits}g}' if math.isfinite(x) else 'n/a'


def markdown(result: Identification, doc: Mapping[str, Any], figures: Mapping[str, str],
             nelder_mead: Mapping[str, Mapping[str, Any]] | None) -> str:
    """The readable report (Markdown)."""
    offsets = 'fitted' if result.fit_offsets else 'fixed at the base values (as the report)'
    bounds = ', '.join(f'{k} in [{v[0]:g}, {v[1]:g}]' for k, v in result.bounds.items())
    bounds = bounds or 'none'
    lines = [f'# Identified hydrodynamic coefficients: {result.base.name}', '',
             f'- Bags: {", ".join(doc["bags"])}',
             f'- Base vehicle: `{result.base.path}`',
             f'- Force source: {SOURCE_TEXT[result.source]}',
             f'- Standard errors: {doc["errors_text"]}',
             f'- CZ0 and CM0: {offsets}',
             f'- Bounds: {bounds}',
             '', 'Each equation is linear in its coefficients, so its sum of squares is a '
             'quadratic form with a single minimum, solved exactly by linear least squares. ',
             '']
    if result.source == 'motion':
        lines += ['Forces from motion: the regressors and the forces are passed through the '
                  'same low-pass as the Savitzky-Golay derivative, and the regressors are '
                  'instrumented by their values one filter window before and after (two-stage '
                  'least squares), so velocity noise does not bias the coefficients.', '']
    lines += ['## Coefficients', '',
              '| coefficient | value | std. error | 95 % interval | base | change | fit |',
              '| --- | ---: | ---: | --- | ---: | ---: | --- |']
    for name, fit in result.fits.items():
        for c in fit.coefficients:
            change = f'{100 * (c.value - c.base) / c.base:+.2f} %' if c.base else 'n/a'
            flag = ' (on bound)' if c.at_bound else ''
            lines.append(f'| {c.name} | {_fmt(c.value)}{flag} | {_fmt(c.std_error, 3)} | '
                         f'[{_fmt(c.ci95[0])}, {_fmt(c.ci95[1])}] | {_fmt(c.base)} | {change} '
                         f'| {name} |')
    lines += ['', '## Fits', '',
              '| equation | component | R^2 | NRMSE | RMSE | condition number | samples '
              '(effective) | fixed |', '| --- | --- | ---: | ---: | ---: | ---: | ---: | --- |']
    for name, fit in result.fits.items():
        eq = fit.equation
        fixed = ', '.join(f'{k} = {_fmt(v)}' for k, v in fit.fixed.items()) or '-'
        lines.append(f'| {name} | {AXES[eq.axis]} [{eq.unit}] | {fit.r2:.5f} | {fit.nrmse:.4f} '
                     f'| {_fmt(fit.rmse, 3)} | {fit.condition_number:.3g} | {fit.n_samples} '
                     f'({fit.n_effective:.0f}) | {fixed} |')
    lines += ['', 'Condition number of the column-scaled regressor; NRMSE = rms(residual) / '
              '(max - min of the measured component).', '', '## Coefficient correlations', '']
    for name, fit in result.fits.items():
        cn = [c.name for c in fit.coefficients]
        if len(cn) < 2:
            continue
        lines.append(f'- {name}: ' + '; '.join(
            f'{cn[i]}-{cn[j]} {fit.correlation[i, j]:+.3f}'
            for i in range(len(cn)) for j in range(i + 1, len(cn))))
    if nelder_mead:
        lines += ['', '## Bounded Nelder-Mead on the same data (the report\'s method)', '',
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
    return '\n'.join(lines) + '\n'


def write_outputs(result: Identification, out_dir: str | pathlib.Path, bags: Sequence[str],
                  nelder_mead: Mapping[str, Mapping[str, Any]] | None = None,
                  extra: Mapping[str, Any] | None = None) -> dict[str, str]:
    """Write vehicle file, report.json, figures and report.md into ``out_dir``.

    Returns:
        name -> path of every file written.
    """
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files: dict[str, str] = {}
    errors_text = {
        'hac': 'from motion: sensor noise propagated through the filtered equation of motion '
               '(noise levels estimated from the log), or, where the residual is not that '
               'noise, a flat-top lag window (Politis bandwidth); from the force topic: the '
               'flat-top lag window',
        'jackknife': 'delete-a-block jackknife over contiguous blocks of the record',
        'ess': 'sigma^2 (A\'A)^-1 inflated by n / n_eff (residual correlation time)',
        'iid': 'sigma^2 (A\'A)^-1 (white residuals assumed)'}.get(result.errors, result.errors)
    stamp = datetime.datetime.now(datetime.UTC).isoformat(timespec='seconds')
    provenance = {'identification': {
        'tool': 'auv ident', 'time_utc': stamp, 'bags': list(bags),
        'base_vehicle': result.base.path, 'force_source': result.source,
        'standard_errors': result.errors, 'fit_CZ0_CM0': result.fit_offsets,
        'identified': sorted(result.coefficients)}}
    vehicle_path = out / 'vehicle.yaml'
    save_vehicle(result.params, vehicle_path, sources=coefficient_sources(result),
                 provenance=provenance)
    files['vehicle'] = str(vehicle_path)
    figures: dict[str, str] = {}
    for name, fit in result.fits.items():
        fname = f'fig{fit.equation.figure}_{name}.png'
        plot_fit(fit, out / fname)
        figures[name] = fname
        files[f'figure_{name}'] = str(out / fname)
    doc = summary(result)
    doc.update({'bags': list(bags), 'base_vehicle': result.base.path, 'time_utc': stamp,
                'errors_text': errors_text, 'figures': figures,
                'nelder_mead': dict(nelder_mead) if nelder_mead else None})
    if extra:
        doc.update(extra)
    files['report_md'] = str(out / 'report.md')
    files['report_json'] = str(out / 'report.json')
    doc['files'] = dict(files)
    (out / 'report.md').write_text(markdown(result, doc, figures, nelder_mead))
    (out / 'report.json').write_text(json.dumps(_jsonable(doc), indent=2) + '\n')
    return files
