"""The sim-to-real gap diagnosis: where the nominal model departs from a log, and which
catalogue effect (or combination) explains it, scored on held-out windows.

Steps (see :func:`diagnose`; each a function that returns its data):

1. Nominal free runs over all windows and their noise floor (a Monte Carlo over the
   initial-state uncertainty plus the sensor noise); channels whose RMS exceeds the floor by
   ``GAP_FACTOR`` carry a gap. No such channel: ``no_gap``
   (:func:`auv_gap.nominal.nominal_runs`). A model whose runs diverge on the logs
   (``DIVERGE_SHARE`` of them) is reported as such unless the effect its equations want most
   keeps them with the logs (:func:`auv_gap.nominal.steadied_by`).
2. Equation error of the nominal model; where the gap lies (:mod:`auv_gap.analysis`,
   :func:`locate_gap`); what the coasts and surface passes give (:mod:`auv_gap.static`).
3. Every catalogue effect (among them ``coefficients``: the model's own vertical-plane
   coefficients re-fitted) fitted by equation error on the training windows, scored by free
   run on the held-out windows; the ``top`` best refined by free-run error and scored again.
4. Combinations, greedily: the best plausible set plus each other effect, refitted jointly,
   kept while the held-out score improves, every parameter stays plausible and the added
   effect identifies something (an interval that excludes its "absent" value).
5. Verdict (:func:`judge`, :func:`auv_gap.verdict.verdict_and_rivals`): typical and possible
   ranges (an atypical fit that predicts the held-out windows significantly better is a
   finding, at most ``partly_explained``: :func:`_atypical`), the held-out share of the gap
   explained, the residual tests of :mod:`auv_gap.residuals`, and the candidates the held-out
   windows cannot tell from the best (within ``AMBIGUOUS_RATIO`` of its held-out cost and of
   its explained share, and not worse by ``AMBIGUOUS_T`` standard errors over the windows;
   typical or beyond the typical range, never beyond what physics allows). When the best
   leaves structure in its residuals, a larger plausible set that leaves none, within
   ``RESCUE`` of its score, replaces it.

Score: ``ln(J_nominal / J_candidate) - PARAM_PRICE * k`` with ``J`` the held-out free-run
cost (mean over samples of the squared channel errors over their scales) and ``k`` the number
of identified parameters: a parameter must buy a PARAM_PRICE share of the held-out cost.
Scores within ``TIE`` of each other are a tie, which goes to the simpler candidate.
``explained = (J_nominal - J) / (J_nominal - J_floor)``, clipped to [0, 1]: the share of what
could shrink (the gap above the noise floor) that did. ``held_out.shrink`` is this same share
for the chosen candidate; ``held_out.shrink_depth`` the same in depth RMS alone.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from auv_contract import STATE_FIELDS
from auv_gap import analysis, residuals
from auv_gap.catalogue import (
    CATALOGUE,
    Perturbation,
    get_effect,
    separating_manoeuvre,
)
from auv_gap.fit import EquationFit, FitResult, FreeRunFit
from auv_gap.logs import (
    GapLog,
    Weighting,
    measurement_weighting,
)
from auv_gap.manoeuvres import Envelope
from auv_gap.nominal import (
    NominalRuns,
    Progress,
    divergence_text,
    nominal_runs,
    steadied_by,
)
from auv_gap.problem import CH_INDEX, CH_NAMES, EQUATIONS, Problem
from auv_gap.ranges import Ranges
from auv_gap.static import Finding, coast_findings, surface_finding
from auv_gap.verdict import (
    AMBIGUOUS_RATIO,
    AMBIGUOUS_T,
    PARTLY,
    Candidate,
    Diagnosis,
    Judgement,
    candidate_details,
    candidate_entry,
    compose_statement,
    entry_params,
    held_out_entry,
    implausible_entries,
    nested,
    plausibility,
    verdict_and_rivals,
    window_t_stat,
    with_quiet,
)
from auv_sim.params import VehicleParams

GAP_FACTOR = analysis.GAP_FACTOR
PARAM_PRICE = 0.05
TIE = 0.02               # scores closer than this are a tie: the simpler candidate wins
RESCUE = 0.1             # a larger set with white residuals may score this much less
GAIN_LEVEL = 0.01        # one-sided level of the held-out predictive-gain test (a rival)


class _Scorer:
    """Held-out free-run scoring against the nominal model."""

    def __init__(self, pr: Problem, frf: FreeRunFit, nominal_cost: float, floor_cost: float,
                 other_logs: list[GapLog] | None = None) -> None:
        self.pr, self.frf = pr, frf
        self.nominal_cost, self.floor_cost = nominal_cost, floor_cost
        self.rows = pr.window_rows(frf.held)
        #: the logs with their commands logged at the rows reconstructed the other way
        #: (:func:`other_hold`), or None
        self.other_logs = other_logs
        #: Newey-West lags of the predictive-gain test: half the shortest held-out window
        self.lags = max(1, min(r.stop - r.start for r in self.rows) // 2)

    def gain(self, base: Candidate, cand: Candidate) -> tuple[float, float]:
        """``(t, p)`` of the Diebold-Mariano test that ``cand`` predicts the held-out
        windows better than ``base`` (:func:`auv_gap.residuals.predictive_gain`)."""
        t, p, _ = residuals.predictive_gain(base.loss, cand.loss, self.lags)
        return t, p

    def _errors(self, out: np.ndarray, meas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Scaled held-out errors of one free run (S x channels, clipped at 1e3 and
        non-finite as 1e3) and their cost per held-out window."""
        err = (out[:, CH_INDEX] - meas[:, CH_INDEX]) / self.frf.scales
        err = np.clip(np.where(np.isfinite(err), err, 1e3), -1e3, 1e3)
        per_w = np.array([np.mean(np.sum(err[r][1:] ** 2, axis=1)) for r in self.rows])
        return err, per_w

    def window_cost_other(self, cand: Candidate) -> np.ndarray | None:
        """The cost per held-out window of ``cand`` with the commands a log records only at
        its rows reconstructed the other way (held or linear between rows), or None when
        every command carries its own stamp."""
        if self.other_logs is None:
            return None
        pert = cand.fit.effects.perturbation(cand.fit.values)
        act = self.pr.actuators_of(self.other_logs, pert)
        out, meas = self.pr.free_run([pert], self.frf.held, act_override=act)
        return self._errors(out[0], meas)[1]

    def evaluate(self, fits: Sequence[FitResult]) -> list[Candidate]:
        """Score ``fits`` on the held-out windows."""
        if not fits:
            return []
        perts = [f.effects.perturbation(f.values) for f in fits]
        out, meas = self.pr.free_run(perts, self.frf.held)
        res = []
        for c, f in enumerate(fits):
            err, per_w = self._errors(out[c], meas)
            cost = float(np.mean(np.sum(err[np.concatenate(
                [np.arange(r.start + 1, r.stop) for r in self.rows])] ** 2, axis=1)))
            phys = out[c][:, CH_INDEX] - meas[:, CH_INDEX]
            phys = np.where(np.isfinite(phys), phys, 1e3)
            rms = {n: float(np.sqrt(np.mean(phys[:, i] ** 2))) for i, n in enumerate(CH_NAMES)}
            cand = Candidate(f, cost, per_w, rms,
                             loss=[np.sum(err[r][1:] ** 2, axis=1) for r in self.rows])
            cand.score = self.score(cost, f.n_active)
            gap = self.nominal_cost - self.floor_cost
            cand.explained = float(np.clip((self.nominal_cost - cost) / gap, 0.0, 1.0)) \
                if gap > 0 else 0.0
            cand.beyond, cand.impossible, cand.empty = plausibility(f)
            res.append(cand)
        return res

    def score(self, cost: float, k: int) -> float:
        return float(math.log(self.nominal_cost / max(cost, 1e-12)) - PARAM_PRICE * k)


@dataclasses.dataclass
class GapSite:
    """Stage 2: where the gap lies (the ``gap`` entry of the report), the nominal equation
    error, the signals the residuals are tested against, and what the plots need."""

    gap: dict[str, Any]
    e_nom: np.ndarray
    eq_rms: np.ndarray
    focus: int
    corr: list[dict[str, Any]]
    band_info: dict[str, Any]
    signals: dict[str, np.ndarray]


def locate_gap(pr: Problem, nominal: NominalRuns) -> GapSite:
    """Stage 2 (see :class:`GapSite`): the nominal model's equation error at the logged
    states, the dominant equation, the regimes and frequency band of its residual, and its
    correlation with the inputs and states."""
    nom = Perturbation.nominal(pr.vehicle)
    act_nom = pr.actuators(nom)
    e_nom = pr.equation_error(nom, act_nom)
    eq_rms = np.sqrt(np.mean(e_nom ** 2, axis=0))
    dom = analysis.dominant_equation(eq_rms, pr.eq_sigma)
    ratio = eq_rms / pr.eq_sigma
    focus = EQUATIONS.index(dom) if dom else int(np.argmax(ratio))
    residual = e_nom[:, focus]
    bar_act = np.interp(pr.eq_fine, np.arange(act_nom.shape[0]), act_nom[:, 0])
    band_hz, band_info = analysis.band(pr, residual, focus)
    pieces = [pr.eq_log == li for li in range(len(pr.logs))]
    bar_cmd = np.concatenate([_held_at(lg.commands['bar'], pr.eq_t[m])
                              for m, lg in zip(pieces, pr.logs)])
    thr_cmd = np.concatenate([_held_at(lg.commands['thrust'], pr.eq_t[m])
                              for m, lg in zip(pieces, pr.logs)])
    bar_rate = np.concatenate([np.gradient(bar_cmd[m], pr.eq_t[m]) if m.sum() > 1 else
                               np.zeros(int(m.sum())) for m in pieces])
    signals = {'bar_command_rate': bar_rate, 'bar_command': bar_cmd, 'thrust_command': thr_cmd,
               'u': pr.eq_state[:, 6], 'w': pr.eq_state[:, 8], 'q': pr.eq_state[:, 10],
               'z': pr.eq_state[:, 2], 'theta': pr.eq_state[:, 4]}
    corr = analysis.correlations(pr, residual, signals)
    gap = {
        'free_run_rms': {n: float(nominal.rms[CH_NAMES.index(n)])
                         for n in ('z', 'theta', 'w', 'q', 'u')},
        'equation_rms': {n: float(eq_rms[i]) for i, n in enumerate(EQUATIONS[:5])},
        'dominant_equation': dom,
        'segments': analysis.segments(pr, nominal.all_w, nominal.rms_z_win),
        'regimes': {'equation': EQUATIONS[focus],
                    **analysis.regimes(pr, residual, bar_act)},
        'band_hz': band_hz,
        'time_origin': analysis.time_origin(pr),
    }
    return GapSite(gap, e_nom, eq_rms, focus, corr, band_info, signals)


@dataclasses.dataclass
class Search:
    """Stage 3: every candidate scored on the held-out windows, the best plausible set the
    greedy search reached, and the fits and scorer that made them."""

    candidates: list[Candidate]
    best: Candidate
    nominal: Candidate
    scorer: _Scorer
    eqf: EquationFit
    frf: FreeRunFit
    nominal_cost: float
    floor_cost: float


def search_candidates(pr: Problem, nominal: NominalRuns, names: Sequence[str], top: int,
                      max_effects: int, say: Progress,
                      fitted: Mapping[str, FitResult] | None = None,
                      prefer: Sequence[str] = ()) -> Search:
    """Stage 3: every catalogue effect fitted by equation error and scored by held-out free
    run; the ``top`` plausible ones refined by free run (and the best one beyond its typical
    range that physics allows, when it scores above them, and those of ``prefer``);
    combinations grown greedily from the best plausible one (see the module docstring).
    ``fitted``: equation-error fits already made."""
    frf = FreeRunFit(pr, nominal.scales)
    nom = Perturbation.nominal(pr.vehicle)
    held_rows = pr.window_rows(frf.held)
    held_idx = np.concatenate([np.arange(r.start + 1, r.stop) for r in held_rows])
    out_h, meas_h = pr.free_run([nom], frf.held)
    err_h = (out_h[0][:, CH_INDEX] - meas_h[:, CH_INDEX]) / nominal.scales
    err_h = np.clip(np.where(np.isfinite(err_h), err_h, 1e3), -1e3, 1e3)
    nominal_cost = float(np.mean(np.sum(err_h[held_idx] ** 2, axis=1)))
    # the floor of each channel, but never above what the nominal model already reaches on
    # the held-out windows (a channel without a gap can shrink by nothing)
    floor_cost = float(np.sum(np.minimum((nominal.floor / nominal.scales) ** 2,
                                         np.mean(err_h[held_idx] ** 2, axis=0))))
    scorer = _Scorer(pr, frf, nominal_cost, floor_cost, nominal.other_logs)
    nominal_cand = scorer.evaluate([FitResult(pr.effect_set([]), np.zeros(0),
                                              np.zeros(0, bool), np.zeros(0), np.zeros(0),
                                              'nominal')])[0]
    eqf = EquationFit(pr)
    say(f'equation-error fits of {len(names)} effects')
    singles_a = {n: fitted[n] if fitted and n in fitted else eqf.fit(pr.effect_set([n]))
                 for n in names}
    cands_a = {c.label: c for c in scorer.evaluate(list(singles_a.values()))}
    order = sorted(names, key=lambda n: -cands_a[n].score)
    found = [n for n in order if singles_a[n].n_active > 0]
    # refine the best that identify something, plausible ones first; and the best one
    # beyond its typical range (but possible), when it scores above them (an atypical
    # value is a finding, see _atypical)
    refine = [n for n in found if cands_a[n].plausible][:top]
    refine += [n for n in found if not cands_a[n].plausible][:max(0, top - len(refine))]
    odd = next((n for n in found if cands_a[n].possible and not cands_a[n].plausible), None)
    if odd is not None and odd not in refine and (
            not refine or cands_a[odd].score > cands_a[refine[0]].score):
        refine.append(odd)
    refine += [n for n in prefer if n in found and n not in refine]
    say(f'free-run refinement of {", ".join(refine)}')
    singles: dict[str, Candidate] = dict(cands_a)
    refined = scorer.evaluate([frf.fit(singles_a[n]) for n in refine])
    for c in refined:
        if c.score >= singles[c.label].score:
            singles[c.label] = c
    ranked_singles = sorted(singles.values(), key=lambda c: -c.score)
    candidates: list[Candidate] = list(ranked_singles)
    # combinations: equation error ranks every addition, free run refines the best ones;
    # only plausible sets whose every effect identifies something count
    viable = [c for c in ranked_singles if c.plausible and c.identifies]
    best = _simplest(viable) if viable else nominal_cand
    pool = list(names)
    while nominal.gap_channels and viable and best.score > 0 and \
            len(best.names) < max_effects and best.explained < 1.0:
        base_cost = eqf.cost(best.fit.effects, best.fit.values, held_out=True)
        ranked, joint = [], {}
        for n in pool:
            if n in best.names:
                continue
            es = pr.effect_set((*best.names, n))
            start = np.concatenate([best.fit.values, singles_a[n].values])
            fa = joint[n] = eqf.fit(es, start=start)
            cost = eqf.cost(es, fa.values, held_out=True)
            if cost < base_cost:
                ranked.append((cost, fa))
        ranked.sort(key=lambda item: item[0])
        chosen = [fa for _, fa in ranked[:max(1, top - 1)]]
        # and the addition of the best single effect by held-out free run not yet tried
        # (equation error ranks actuator effects poorly: their signature is in the free run)
        tried = {fa.effects.names[-1] for fa in chosen}
        extra = next((c.names[0] for c in viable if len(c.names) == 1
                      and c.names[0] not in best.names and c.names[0] not in tried), None)
        if extra is not None:
            chosen.append(joint[extra])
        trials = [frf.fit(fa) for fa in chosen]
        if not trials:
            break
        say(f'combinations: {", ".join(t.effects.label for t in trials)}')
        evaluated = scorer.evaluate(trials)
        candidates.extend(evaluated)
        good = [c for c in evaluated if c.plausible and c.identifies]
        if not good:
            break
        top_trial = max(good, key=lambda c: c.score)
        if top_trial.score <= best.score + TIE:
            break
        best = top_trial
    _rank(candidates, best)
    return Search(candidates, best, nominal_cand, scorer, eqf, frf, nominal_cost, floor_cost)


def _rank(candidates: list[Candidate], best: Candidate) -> None:
    """Sort in place: the chosen best first, then the plausible candidates that identify
    something, then the rest, each by score (ties: fewer parameters first)."""
    candidates.sort(key=lambda c: (c is not best, not (c.plausible and c.identifies),
                                   -c.score, c.fit.n_active, len(c.names)))


def judge(pr: Problem, search: Search, nominal: NominalRuns, site: GapSite,
          weighting: Weighting, envelope: Envelope, say: Progress,
          steadied: Sequence[str] = ()) -> Judgement:
    """Stage 4: residual tests of the best (a larger plausible set with white residuals may
    replace it), a better fit beyond physics as structure left, a better fit beyond the
    typical range as the finding (verdict at most ``partly_explained`` or ``ambiguous``,
    with the manoeuvre that would confirm it), and the verdict
    (:func:`auv_gap.verdict.verdict_and_rivals`).
    ``steadied``: the effect whose equation-error fit kept the runs of a diverging nominal
    model with the logs (:func:`auv_gap.nominal.steadied_by`); beyond its typical range, it
    is the finding (the divergence was its) when it explains at least ``PARTLY`` of the gap."""
    best = search.best
    candidates = search.candidates
    gap_channels = nominal.gap_channels
    res_signals = {'z': pr.eq_state[:, 2], 'u': pr.eq_state[:, 6], 'theta': pr.eq_state[:, 4],
                   'w': pr.eq_state[:, 8], 'q': pr.eq_state[:, 10]}
    res_signals.update({k: site.signals[k] for k in ('bar_command', 'bar_command_rate',
                                                     'thrust_command')})
    # a derived signal shares its noise with the equation errors: not a test signal
    res_signals = {k: v for k, v in res_signals.items() if k not in weighting.channels}
    tested = best if best.names else None
    white, findings, left = (_residual_tests(pr, search.eqf, search.frf, tested, res_signals)
                             if tested is not None and gap_channels else (False, [], []))
    if tested is not None and gap_channels and not white:
        # a larger plausible set whose residuals are white, within RESCUE of the score,
        # is the better answer (the score alone cannot see structure below the floor)
        larger = [c for c in candidates if c.plausible and c.identifies
                  and set(c.names) > set(best.names) and c.score >= best.score - RESCUE]
        for c in sorted(larger, key=lambda c: -c.score)[:3]:
            w2, f2, l2 = _residual_tests(pr, search.eqf, search.frf, c, res_signals)
            if w2:
                say(f'{c.label}: white residuals where {best.label} leaves structure')
                best = tested = c
                white, findings, left = w2, f2, l2
                _rank(candidates, best)
                break
    odd = _atypical(search.scorer, tested or search.nominal, candidates) \
        if gap_channels else None
    cause = next((c for c in candidates if c.names == tuple(steadied) and c.possible
                  and not c.plausible and c.identifies and c.explained >= PARTLY), None)
    if cause is not None and gap_channels:
        odd = cause
    if odd is not None:
        say(f'{odd.label}: beyond its typical range, and a better fit than any typical set')
        # rivals: typical or atypical (not impossible) answers the held-out windows cannot
        # tell from it
        rivals = [c for c in candidates if c is not odd and c.possible and c.identifies
                  and not (nested(set(c.names), set(odd.names))
                           or nested(set(odd.names), set(c.names)))
                  and c.cost <= AMBIGUOUS_RATIO * odd.cost
                  and c.explained >= odd.explained / AMBIGUOUS_RATIO
                  and window_t_stat(c.window_cost - odd.window_cost) < AMBIGUOUS_T]
        ambiguous = list(dict.fromkeys(n for c in rivals for n in c.names
                                       if n not in odd.names))
        rivals = list({c.label: c for c in reversed(rivals)}.values())[::-1]
        _rank(candidates, odd)
        eff = get_effect(odd.names[0])
        hint = (separating_manoeuvre(odd.names[0], ambiguous[0], envelope)
                if ambiguous else f'to confirm: {eff.advice(envelope)}')
        return Judgement('ambiguous' if ambiguous else 'partly_explained', odd, True,
                         ambiguous, hint, False, findings, left, rivals)
    if tested is not None and gap_channels:
        # a fit beyond physics that predicts the held-out windows significantly better than
        # the answer shows structure the answer leaves: not explained (its form is the hint)
        rival = _better_implausible(search.scorer, tested, candidates)
        if rival is not None:
            white = False
            left = [rival, *left]
    verdict, ambiguous, suggestion, rivals = verdict_and_rivals(
        gap_channels, tested, candidates, white, search.scorer.window_cost_other, envelope)
    named = best if verdict not in ('no_gap', 'unexplained') else None
    return Judgement(verdict, named, False, ambiguous, suggestion, white, findings, left,
                     rivals)


def _atypical(scorer: _Scorer, best: Candidate, candidates: Sequence[Candidate]
              ) -> Candidate | None:
    """The candidate beyond its typical range but within what physics allows that is the
    better answer: it identifies something, explains at least ``PARTLY`` of the gap, and
    scores above the plausible best by more than ``TIE`` with held-out predictions
    significantly better (Diebold-Mariano, level ``GAIN_LEVEL``), or there is no plausible
    answer. A 10 deg fin zero error is no typical plane bias, but it is a finding to check,
    not a reason to name a worse explanation."""
    pool = [c for c in candidates if c.possible and not c.plausible and c.identifies
            and c.explained >= PARTLY and c.score > 0]
    for c in sorted(pool, key=lambda c: -c.score):
        if not best.names or best.score <= 0 or best.explained < PARTLY:
            return c
        if c.score > best.score + TIE and c.loss and scorer.gain(best, c)[1] < GAIN_LEVEL:
            return c
    return None


def diagnose(vehicle: VehicleParams, logs: Sequence[GapLog], *, window: float | None = None,
             held_out_logs: Sequence[int] = (), effects: Sequence[str] | None = None,
             top: int = 3, max_effects: int = 3, progress: Progress | None = None,
             ranges: Ranges | None = None) -> Diagnosis:
    """Diagnose the gap between ``vehicle`` (the nominal model) and ``logs``.

    Parameters
    ----------
    vehicle
        nominal vehicle parameters.
    logs
        log pieces (:func:`auv_gap.logs.load_bag`).
    window
        window [s] the data is cut into (held out whole); free runs restart at each
        window, and within it every four e-folding times on a vehicle unstable without
        feedback. None: chosen from the data
        (:func:`auv_gap.problem.data_window`).
    held_out_logs
        indices of logs held out whole; default every third window.
    effects
        catalogue effects to try (default: all registered).
    top
        effects refined by free-run error and tried in combinations.
    max_effects
        largest combination.
    progress
        called with a line of text at each stage.
    ranges
        typical and possible parameter ranges (default: the ranges file,
        :mod:`auv_gap.ranges`).
    """
    say = progress or (lambda _msg: None)
    names = list(effects) if effects is not None else list(CATALOGUE)
    for n in names:
        get_effect(n)
    # derived or assumed signals of imported logs: left out, never counted twice; free runs
    # start from initial rates fitted to the measured depth and pitch
    weighting = measurement_weighting(logs)
    pr = Problem(vehicle, logs, window=window, held_out_logs=held_out_logs,
                 left_out=weighting.equations, ranges=ranges,
                 fitted_initial=[s for s in ('w', 'q') if s in weighting.channels],
                 sway_with_water='v' in weighting.channels)
    if pr.window_why != 'given' or pr.run < pr.window:
        say(f'free-run window: {pr.window_why}'
            + (f'; runs restart every {pr.run:.3g} s: {pr.run_why}' if pr.run < pr.window
               else ''))
    say(f'nominal free runs over {len(pr.select(None))} runs in windows of {pr.window:g} s')
    nominal = nominal_runs(pr, weighting, say)
    site = locate_gap(pr, nominal)
    envelope = _envelope(pr)
    quiet = _quiet_findings(pr, site)
    fitted: dict[str, FitResult] | None = None
    steadied: list[str] = []
    if nominal.diverges:
        fitted, steadied = steadied_by(pr, names, nominal.diverging, say)
        if not steadied:
            say('the nominal model diverges on the logs: re-identify it first')
            statement = divergence_text(pr, nominal)
            judgement = Judgement('unexplained', None, False, [], None, False, [], [])
            return _assemble(pr, nominal, site, None, judgement, weighting, quiet, statement,
                             envelope)
        say(f'with {", ".join(steadied)} fitted to the equations the free runs stay with the '
            'logs: the divergence is an effect\'s, diagnosing on')
    search = search_candidates(pr, nominal, names, top, max_effects, say, fitted, steadied)
    judgement = judge(pr, search, nominal, site, weighting, envelope, say,
                      steadied if fitted is not None else ())
    judgement = with_quiet(judgement, quiet)
    implausible = implausible_entries(search.candidates, judgement.best,
                                      judgement.rivals)
    statement = compose_statement(judgement, implausible, envelope)
    return _assemble(pr, nominal, site, search, judgement, weighting, quiet, statement,
                     envelope, implausible)


def _envelope(pr: Problem) -> Envelope:
    """Where the logs fly (median surge speed and depth) and the vehicle's limits."""
    u = np.concatenate([lg.state[:, 6] for lg in pr.logs])
    z = np.concatenate([lg.state[:, 2] for lg in pr.logs])
    return Envelope(u0=float(np.median(np.abs(u))), z0=float(np.median(z)),
                    depth_max=float(pr.vehicle.depth_max), bar_max=float(pr.vehicle.bar_max))


def _quiet_findings(pr: Problem, site: GapSite) -> list[Finding]:
    """What the log's coasts and surface passes give (:mod:`auv_gap.static`)."""
    out = coast_findings(pr, site.e_nom)
    passes: dict[tuple[Any, ...], Mapping[str, Any]] = {}
    for lg in pr.logs:
        for p in lg.surface_passes:
            passes[(p.get('log'), p.get('from_s'))] = p
    surface = surface_finding(list(passes.values()), float(pr.noise[2]))
    return out + ([surface] if surface is not None else [])


def _assemble(pr: Problem, nominal: NominalRuns, site: GapSite, search: Search | None,
              j: Judgement, weighting: Weighting, quiet: Sequence[Finding], statement: str,
              envelope: Envelope, implausible: Sequence[Mapping[str, Any]] = ()
              ) -> Diagnosis:
    """Stage 5: the report (the contract's keys and more), the details and the plots."""
    nominal_cand = search.nominal if search is not None else None
    after = j.best if j.best is not None else nominal_cand
    held = held_out_entry(nominal_cand, after, nominal.rms, nominal.floor)
    candidates = search.candidates if search is not None else []
    quiet_text = '; '.join(f.text for f in quiet if f.significant)
    if quiet_text:
        statement += f' From the quiet stretches of the logs: {quiet_text}.'
    report = {
        'verdict': j.verdict,
        'gap': site.gap,
        'candidates': [candidate_entry(c) for c in candidates],
        'best': j.best.label if j.best is not None else None,
        'ambiguous_with': j.ambiguous,
        'suggested_manoeuvre': j.suggestion,
        'held_out': held,
        'statement': ' '.join(filter(None, (statement, weighting.statement))),
        'residual_tests': {'white': j.white, 'left_over': j.left,
                           'alpha': residuals.ALPHA, 'n_tests': len(j.findings),
                           'residual': 'held-out equation error, one sample per smoothing '
                                       'window'},
        'implausible': list(implausible),
        'signals': weighting.report,
        'findings': [f.as_dict() for f in quiet],
        'diverges': nominal.diverges,
    }
    scorer = search.scorer if search is not None else None
    details = {
        'logs': [{'name': lg.name, 't0': float(lg.t[0]) - lg.origin,
                  'origin_stamp_s': lg.origin, 'origin_utc': lg.origin_utc,
                  'duration_s': lg.duration, 'period_s': lg.period, 'notes': list(lg.notes)}
                 for lg in pr.logs],
        'windows': [dict(dataclasses.asdict(w), t0=w.t0 - pr.logs[w.log].origin,
                         t1=w.t1 - pr.logs[w.log].origin) for w in pr.windows],
        'sensor_noise': dict(zip(STATE_FIELDS, map(float, pr.noise))),
        'free_run_floor': dict(zip(CH_NAMES, map(float, nominal.floor))),
        'free_run_rms_all': dict(zip(CH_NAMES, map(float, nominal.rms))),
        'gap_channels': nominal.gap_channels,
        'equation_sigma': dict(zip(EQUATIONS, map(float, pr.eq_sigma))),
        'equation_rms_all': dict(zip(EQUATIONS, map(float, site.eq_rms))),
        'correlation': [{k: v for k, v in c.items() if k not in ('curve', 'lags')}
                        for c in site.corr],
        'residual_tests': [dataclasses.asdict(f) for f in j.findings],
        'held_out_cost': ({'nominal': search.nominal_cost, 'floor': search.floor_cost,
                           'best': after.cost if after is not None else math.nan}
                          if search is not None else {}),
        'candidates': [candidate_details(c) for c in candidates],
        'integration_step_s': pr.dt,
        'window_s': pr.window,
        'window_why': pr.window_why,
        'run_s': pr.run,
        'run_why': pr.run_why,
        'advice': {n: get_effect(n).advice(envelope) for n in CATALOGUE},
        'diverging_runs': int(np.sum(nominal.diverging)),
        'runs_left_out': sorted(pr.excluded),
    }
    plots = {'problem': pr, 'best': j.best, 'nominal': Perturbation.nominal(pr.vehicle),
             'e_nom': site.e_nom, 'corr': site.corr, 'band': site.band_info,
             'band_hz': site.gap['band_hz'], 'candidates': candidates,
             'focus': EQUATIONS[site.focus], 'scorer': scorer}
    return Diagnosis(report, details, plots)


def _held_at(cmd: tuple[np.ndarray, np.ndarray], t: np.ndarray) -> np.ndarray:
    st, va = cmd
    i = np.searchsorted(st, t, side='right') - 1
    return va[np.clip(i, 0, va.size - 1)]


def _better_implausible(scorer: _Scorer, best: Candidate, candidates: Sequence[Candidate]
                        ) -> str | None:
    """The text naming a candidate beyond what physics allows that predicts the held-out
    windows better than ``best`` (Diebold-Mariano, level ``GAIN_LEVEL``), or None. A fit
    that needs parameters beyond physics is no explanation, but when it beats the plausible
    answer on data neither was fitted to, the answer has left structure of that fit's form
    (a quadratic drag that a linear coefficient follows only on average, say). (A better fit
    beyond the typical range but possible is the finding itself: :func:`_atypical`.)"""
    for c in sorted(candidates, key=lambda c: c.cost):
        if c.possible or c.cost >= best.cost or not c.loss:
            continue
        t, p = scorer.gain(best, c)
        if p < GAIN_LEVEL:
            ks = ', '.join(f'{k} = {v:.4g}' for k, v in entry_params(c).items()
                           if k in c.impossible)
            return (f'a fit beyond the plausible range, {c.label} ({ks}), predicts the '
                    f'held-out data better (Diebold-Mariano t = {t:.1f}): structure of its '
                    'form is left')
    return None


def _simplest(cands: Sequence[Candidate]) -> Candidate:
    """The best-scoring candidate, a tie (within ``TIE``) going to fewer parameters."""
    top = max(c.score for c in cands)
    tied = [c for c in cands if c.score >= top - TIE]
    return min(tied, key=lambda c: (c.fit.n_active, -c.score))


def _residual_tests(pr: Problem, eqf: EquationFit, frf: FreeRunFit, cand: Candidate,
                    signals: dict[str, np.ndarray]
                    ) -> tuple[bool, list[residuals.Finding], list[str]]:
    """Residual tests (:mod:`auv_gap.residuals`) of ``cand`` on the held-out windows:
    its equation errors (one sample per smoothing window) and its free-run depth and pitch
    errors (one sample a second)."""
    e = eqf.residual(cand.fit.effects, cand.fit.values)
    eq_dt = float(np.median(np.diff(pr.eq_t[pr.eq_window == pr.eq_window[0]])))
    # one sample per span of the smoothing filter as applied (at a low log rate it is
    # longer than smooth_window: at least 5 samples)
    span = max(pr.smooth_window, (pr.smoothed[0].length - 1) * pr.period)
    step = max(1, int(math.ceil(span / eq_dt - 1e-9)))
    held = sorted(set(pr.eq_window[pr.eq_held].tolist()))
    rows = [np.flatnonzero(pr.eq_window == w)[::step] for w in held]
    one_step = residuals.Group({n: [e[r, k] for r in rows] for k, n in enumerate(EQUATIONS)
                                if np.isfinite(pr.eq_sigma[k])},  # left out: infinite noise
                               {n: [v[r] for r in rows] for n, v in signals.items()},
                               eq_dt * step, white=True)
    out, meas = pr.free_run([cand.fit.effects.perturbation(cand.fit.values)], frf.held)
    t_out = pr.output_times(frf.held)
    out_dt = pr.m * pr.period
    every = max(1, int(round(1.0 / out_dt)))
    wrows = [np.arange(r.start, r.stop)[::every] for r in pr.window_rows(frf.held)]
    err = (out[0] - meas)
    fr_res = {f'free-run {n}': [err[r, i] for r in wrows] for n, i in (('depth', 2),
                                                                         ('pitch', 4))}
    logs = [pr.windows[w].log for w in frf.held]
    cmd = {ch: [_held_at(pr.logs[lg].commands[ch], t_out[r]) for r, lg in zip(wrows, logs)]
           for ch in ('bar', 'thrust')}
    fr_sig = {n: [meas[r, i] for r in wrows] for n, i in (('z', 2), ('u', 6), ('theta', 4),
                                                            ('w', 8), ('q', 10))}
    for n, i in (('w_dot', 8), ('q_dot', 10)):
        fr_sig[n] = [np.gradient(meas[r, i], out_dt * every) for r in wrows]
    fr_sig['bar_command'] = cmd['bar']
    fr_sig['thrust_command'] = cmd['thrust']
    win = max(2, min(r.size for r in wrows) // 2)
    free = residuals.Group(fr_res, fr_sig, out_dt * every, white=False, acf_lags=win)
    return residuals.residual_tests([one_step, free])
