"""The identification of ``auv ident`` and the identification node, from force records to a
validated model: what is held out, what is fitted how, and whether the result is written.

1. The log is cut into windows (:func:`auv_ident.freerun.split_windows`); every third is held
   out of the fit (fewer on a long log).
2. The equations are fitted on the rest (:func:`auv_ident.identify.identify`: the posterior
   of the file's priors and the data inside the physical bounds, the cross-flow structure
   chosen by held-out prediction; an equation with R^2 < 0 stays at the base).
3. Where the equation error's derivatives are poor (:func:`auv_ident.output_error.
   needs_output_error`: a slow log, derived heave velocity or pitch rate, quantised depth),
   the heave and pitch coefficients are refined by output error (multiple shooting,
   :func:`auv_ident.output_error.refine`), and the report says why.
4. The identified model is validated against the base on the held-out windows
   (:func:`auv_ident.validate.validate`); a model that predicts them worse, or diverges, is not
   the answer.

A log without commands (a force-topic bag without command topics) cannot be run freely: it is
fitted on all its samples and written without validation, and the report says so.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from auv_contract.blas import one_blas_thread
from auv_ident.errors import NotIdentifiableError
from auv_ident.freerun import Window, split_windows, use_masks, window_length
from auv_ident.identify import (
    EQUATIONS,
    CoefficientEstimate,
    EquationFit,
    ForceRecord,
    Identification,
    identify,
)
from auv_ident.identify.fit import UNINFORMED
from auv_ident.identify.physics import at_bound_note, constraint
from auv_ident.identify.priors import CROSSFLOW, prior
from auv_ident.identify.regressors import component_terms
from auv_ident.output_error import (
    OutputErrorFit,
    OutputErrorImpossible,
    needs_output_error,
    refine,
)
from auv_ident.validate import Validation, not_validated, validate
from auv_sim.params import VehicleParams

Progress = Callable[[str], None]
#: The logged pitch must vary by this much (99th percentile of |theta - median|) [rad] for
#: output error to refine the heave and pitch coefficients.
PITCH_EXCITATION = math.radians(1.0)


@dataclasses.dataclass
class Outcome:
    """An identification with how it was obtained and validated."""

    result: Identification
    validation: Validation
    output_error: OutputErrorFit | None
    windows: list[Window]
    window_s: float
    window_why: str
    derivatives: str          # how the heave and pitch derivatives were handled, and why

    def report(self) -> dict[str, Any]:
        """The report.json keys of the procedure."""
        oe = self.output_error
        return {
            'validation': self.validation.as_dict(),
            'windows': {'length_s': self.window_s, 'why': self.window_why,
                        'count': len(self.windows),
                        'held_out': sum(w.held_out for w in self.windows)},
            'derivatives': self.derivatives,
            'output_error': None if oe is None else {
                'why': oe.why, 'coefficients': list(oe.names), 'start': oe.start,
                'rms': oe.rms, 'rms_start': oe.rms_start, 'windows': oe.windows,
                'samples': oe.samples, 'model_runs': oe.evaluations},
        }


@one_blas_thread
def run_identification(records: Sequence[ForceRecord], base: VehicleParams, *,
                       equations: Sequence[str] | None = None, fit_offsets: bool = False,
                       fit_planes: bool = False,
                       bounds: Mapping[str, tuple[float, float]] | None = None,
                       errors: str = 'hac', partial: bool = False, use_priors: bool = True,
                       hold_out: bool = True, output_error: str = 'auto',
                       structures: bool = True,
                       progress: Progress | None = None) -> Outcome:
    """Identify, refine and validate (module docstring). ``output_error``: ``auto`` (when the
    derivatives are poor), ``always`` or ``never``; ``hold_out`` False fits every sample and
    writes without validation; ``structures`` False keeps the file's cross-flow structure."""
    say = progress or (lambda _text: None)
    logs = [r.log for r in records]
    runnable = all(lg is not None for lg in logs)
    windows: list[Window] = []
    length, why_len = math.nan, ''
    if runnable:
        plain = [lg for lg in logs if lg is not None]
        length, why_len = window_length(base, plain)
        windows = split_windows(plain, length, hold=hold_out)
    use = use_masks(records, windows) if windows else None
    tracks: dict[tuple[float, ...], np.ndarray] = {}    # actuator positions of the free runs
    result = identify(records, base, equations=equations, fit_offsets=fit_offsets,
                      bounds=bounds, errors=errors, partial=partial, fit_planes=fit_planes,
                      use_priors=use_priors, use=use, structures=structures)
    oe_fit = None
    derivatives = ('equation error: derivatives from the force topic' if result.source ==
                   'forces' else 'equation error: Savitzky-Golay derivatives of the logged '
                   'velocities (logged at a rate that resolves them, heave velocity and pitch '
                   'rate measured)')
    if runnable and result.source == 'motion' and output_error != 'never':
        plain = [lg for lg in logs if lg is not None]
        poor = needs_output_error(plain)
        if output_error == 'always' and not poor:
            poor = 'asked for (--output-error always)'
        names = _output_error_names(result, equations, fit_offsets, fit_planes, plain)
        if poor and names:
            say(f'output error on {", ".join(names)}: {poor}')
            try:
                oe_fit = refine(plain, windows, result.params, base, names, poor, bounds,
                                use_priors, tracks)
            except OutputErrorImpossible as exc:
                derivatives = (f'equation error: the derivatives are poor ({poor}), but {exc}; '
                               'heave and pitch not refined (equation error\'s values stand '
                               'where R^2 >= 0, the base\'s where not)')
                say(derivatives)
            else:
                _apply(result, oe_fit, base)
                derivatives = (f'output error (multiple shooting over {oe_fit.windows} '
                               f'segments) for {", ".join(names)}: {poor}')
        elif poor:
            derivatives += f'; poor derivatives ({poor}) but no heave and pitch excitation'
    if not runnable:
        val = not_validated('the log has no command topics: the model cannot be run freely '
                            'against it (fitted on every sample)')
    elif not hold_out:
        val = not_validated('no data held out (--no-validation)')
    else:
        lateral = any(e in result.fits and result.fits[e].identified for e in ('sway', 'yaw'))
        val = validate([lg for lg in logs if lg is not None], windows, base, result.params,
                       lateral, tracks)
    say(val.message)
    return Outcome(result=result, validation=val, output_error=oe_fit, windows=windows,
                   window_s=length, window_why=why_len, derivatives=derivatives)


def _output_error_names(result: Identification, equations: Sequence[str] | None,
                        fit_offsets: bool, fit_planes: bool,
                        logs: Sequence[Any]) -> list[str]:
    """The heave and pitch coefficients output error refines: those of the fitted heave and
    pitch equations and of those equation error left out or could not fit (R^2 < 0); their
    quadratic cross-flow terms only where the structure chosen by held-out prediction fitted
    them (:func:`auv_ident.identify.fit.choose_structure`), or, for an equation equation error
    could not fit, where the file has them; none when the logged pitch does not vary."""
    theta = np.concatenate([lg.state[:, 4] for lg in logs])
    if float(np.percentile(np.abs(theta - np.median(theta)), 99.0)) < PITCH_EXCITATION:
        return []
    names: list[str] = []
    for eq_name in ('heave', 'pitch'):
        if equations is not None and eq_name not in equations:
            continue
        eq = EQUATIONS[eq_name]
        left = result.not_identifiable.get(eq_name, '')
        if eq_name not in result.fits and 'never varies' in left and 'window' not in left:
            continue
        names += list(eq.coefficients)
        if fit_offsets and eq.offset:
            names.append(eq.offset)
        if fit_planes and eq.plane and result.base.values[eq.plane] != 0.0:
            names.append(eq.plane)
        fit = result.fits.get(eq_name)
        fitted = {c.name for c in fit.coefficients} if fit is not None else set()
        names += [k for k in component_terms(eq) if k in CROSSFLOW
                  and (k in fitted if fit is not None else result.base.values[k] != 0.0)]
    return list(dict.fromkeys(names))


def _apply(result: Identification, oe: OutputErrorFit, base: VehicleParams) -> None:
    """Put the output-error coefficients into ``result`` (in place): the heave and pitch
    fits' coefficients replaced, equations equation error left out added, marked as such."""
    for eq_name in ('heave', 'pitch'):
        eq = EQUATIONS[eq_name]
        mine = [n for n in oe.names if n in (*eq.coefficients, eq.offset, eq.plane,
                                              *component_terms(eq))]
        if not mine:
            continue
        coefs = []
        for n in mine:
            con = constraint(n, base)
            pr = prior(n, base)
            value, se, ci = oe.values[n], oe.std_error[n], oe.ci95[n]
            note = at_bound_note(n, value, con) if oe.at_bound[n] else ''
            if oe.informed[n] < UNINFORMED:
                value, se, ci = pr.mean, pr.sd, (pr.mean - 1.96 * pr.sd, pr.mean + 1.96 * pr.sd)
                share = 100 * (1 - math.sqrt(max(1.0 - oe.informed[n], 0.0)))
                note = (f'left at its prior (the file value): the data reduced its spread by '
                        f'{share:.0f} % only (output error); prior {pr.why}')
            coefs.append(CoefficientEstimate(
                name=n, value=value, std_error=se, ci95=ci,
                base=float(base.values[n]), at_bound=oe.at_bound[n] and not note.startswith(
                    'left at'), records=(), prior_sd=pr.sd, informed=oe.informed[n],
                note=note, bounds=(con.lo, con.hi), method='output error'))
        old = result.fits.get(eq_name)
        if old is not None:
            kept_fixed = {k: v for k, v in old.fixed.items() if k not in mine}
            result.fits[eq_name] = dataclasses.replace(
                old, coefficients=tuple(coefs), fixed=kept_fixed, identified=True,
                why=(f'equation error: {old.why}; ' if old.why else '')
                + f'refined by output error ({oe.why})',
                structures={**old.structures, 'set': {}},
                covariance=f'output error: cluster sandwich over {oe.windows} windows')
        else:
            empty = np.zeros(0)
            result.fits[eq_name] = EquationFit(
                equation=eq, coefficients=tuple(coefs), fixed={}, r2=math.nan,
                nrmse=math.nan, rmse=math.nan, condition_number=math.nan,
                correlation=np.eye(len(coefs)), n_samples=oe.samples,
                n_effective=math.nan, hac_lags=0, errors='output error', t=empty,
                measured=empty, fitted=empty, record_index=np.zeros(0, int),
                record_names=(), covariance=f'output error: cluster sandwich over '
                                            f'{oe.windows} windows',
                structure='quadratic' if any(n in CROSSFLOW for n in mine) else 'file',
                identified=True,
                why=f'fitted by output error only ({oe.why}); equation error: '
                    f'{result.not_identifiable.get(eq_name, "")}')
        result.not_identifiable.pop(eq_name, None)
    try:
        result.params = base.replace(**result.written())
    except ValueError as exc:
        raise NotIdentifiableError(f'output error gave no valid vehicle: {exc}') from None
