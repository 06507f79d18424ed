"""The verdict of the gap diagnosis and the words that state it: the scored candidate
(:class:`Candidate`), the judgement (:class:`Judgement`), the outcome (:class:`Diagnosis`),
the rule that turns held-out scores and residual tests into a verdict
(:func:`decide_verdict`), and the report entries and statement built from them.

Shares and costs (see :mod:`auv_gap.diagnose` for their definition):

- ``explained``: share of the held-out free-run cost above the noise floor that a candidate
  removes, dimensionless in [0, 1]; ``EXPLAINED`` and ``PARTLY`` are thresholds on it.
- ``cost`` / ``window_cost``: held-out free-run cost J, the mean over samples of the squared
  channel errors over their scales (dimensionless), in total and per held-out window;
  ``AMBIGUOUS_RATIO`` is a factor on it, ``AMBIGUOUS_T`` a t statistic over the windows.
- Parameter values and their ranges are in the units of each catalogue parameter
  (:attr:`auv_gap.catalogue.Param.unit`), named in the statement.

Verdicts: ``no_gap``, ``explained``, ``partly_explained``, ``ambiguous``, ``unexplained``.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from auv_gap import residuals
from auv_gap.catalogue import get_effect, separating_manoeuvre
from auv_gap.fit import FitResult
from auv_gap.manoeuvres import Envelope
from auv_gap.problem import CH_NAMES
from auv_gap.static import Finding
from auv_gap.wording import describe

EXPLAINED = 0.9          # explained share of the held-out gap for "explained"
PARTLY = 0.3             # ... for "partly_explained"
AMBIGUOUS_RATIO = 1.25   # held-out cost within this factor of the best ...
AMBIGUOUS_T = 2.0        # ... and not worse by this many standard errors over the windows


@dataclasses.dataclass
class Candidate:
    """A fitted effect set and its held-out scores."""

    fit: FitResult
    cost: float                 # held-out free-run cost J
    window_cost: np.ndarray     # J per held-out window
    rms: dict[str, float]       # held-out free-run RMS per state of CH_NAMES
    score: float = -math.inf
    explained: float = 0.0
    #: identified parameters beyond their typical range -> that range
    beyond: dict[str, tuple[float, float]] = dataclasses.field(default_factory=dict)
    #: ... of them, those beyond what physics allows -> that range
    impossible: dict[str, tuple[float, float]] = dataclasses.field(default_factory=dict)
    empty: list[str] = dataclasses.field(default_factory=list)
    #: per held-out window: the loss of each sample (squared scaled errors over the states)
    loss: list[np.ndarray] = dataclasses.field(default_factory=list)

    @property
    def plausible(self) -> bool:
        """Every identified parameter lies inside its typical range."""
        return not self.beyond

    @property
    def possible(self) -> bool:
        """Every identified parameter lies inside the range physics allows."""
        return not self.impossible

    @property
    def identifies(self) -> bool:
        """Every effect of the set identifies something: at least one of its parameters is
        identified with a 95 % interval that excludes its "absent" value."""
        return not self.empty

    @property
    def label(self) -> str:
        """Effect name, or names joined with '+'."""
        return self.fit.effects.label

    @property
    def names(self) -> tuple[str, ...]:
        """Effect names."""
        return self.fit.effects.names


@dataclasses.dataclass
class Judgement:
    """Stage 4: the answer and how sure it is."""

    verdict: str
    best: Candidate | None          # the candidate named (None: no_gap, unexplained)
    atypical: bool                  # named although beyond its typical range
    ambiguous: list[str]
    suggestion: str | None
    white: bool
    findings: list[residuals.Finding]
    left: list[str]
    #: the candidates behind ``ambiguous`` (for the statement)
    rivals: list[Candidate] = dataclasses.field(default_factory=list)


@dataclasses.dataclass
class Diagnosis:
    """The outcome: ``report`` (the report.json contract), ``details`` (everything else the
    readable report shows) and arrays for plots in ``plots``."""

    report: dict[str, Any]
    details: dict[str, Any]
    plots: dict[str, Any]


def plausibility(f: FitResult) -> tuple[dict[str, tuple[float, float]],
                                         dict[str, tuple[float, float]], list[str]]:
    """Identified parameters at or beyond their typical range (key -> range), those of them
    beyond what physics allows (key -> that range), and the effects of the set that identify
    nothing (no identified parameter whose 95 % interval, the fit's own before widening,
    excludes its "absent" value)."""
    single = len(f.effects.names) == 1
    beyond: dict[str, tuple[float, float]] = {}
    impossible: dict[str, tuple[float, float]] = {}
    found: dict[str, bool] = {n: False for n in f.effects.names}
    sig = f.significant if f.significant is not None else (f.lo95 > f.absent_values) | (
        f.hi95 < f.absent_values)
    for (e, p), v, a, s in zip(f.effects.params, f.values, f.active, sig):
        if not a:
            continue
        key = p.name if single else f'{e}.{p.name}'
        if not p.is_plausible(float(v)):
            beyond[key] = p.plausible_range
        if not p.is_possible(float(v)):
            impossible[key] = p.possible_range
        if s:
            found[e] = True
    return beyond, impossible, [n for n, ok in found.items() if not ok]


def nested(a: set[str], b: set[str]) -> bool:
    """Every effect of ``a`` is in ``b`` or a special case of one in ``b``."""
    return all(n in b or set(get_effect(n).within) & b for n in a)


def decide_verdict(gap_channels: list[str], best: Candidate | None,
                   candidates: list[Candidate], white: bool,
                   other: Callable[[Candidate], np.ndarray | None] = lambda _c: None,
                   envelope: Envelope | None = None) -> tuple[str, list[str], str | None]:
    """``(verdict, ambiguous_with, suggested_manoeuvre)``: :func:`verdict_and_rivals`
    without the rival candidates."""
    verdict, ambiguous, manoeuvre, _ = verdict_and_rivals(gap_channels, best, candidates,
                                                          white, other, envelope)
    return verdict, ambiguous, manoeuvre


def verdict_and_rivals(gap_channels: list[str], best: Candidate | None,
                       candidates: list[Candidate], white: bool,
                       other: Callable[[Candidate], np.ndarray | None] = lambda _c: None,
                       envelope: Envelope | None = None
                       ) -> tuple[str, list[str], str | None, list[Candidate]]:
    """``(verdict, ambiguous_with, suggested_manoeuvre, rivals)``.

    ``explained`` needs all of: a plausible best that identifies every effect it names, an
    explained share of at least ``EXPLAINED`` and white, independent residuals; a plausible
    best short of one of the last two is ``partly_explained``; implausible fits never count.
    A contender (``rivals``) is ambiguous with the best when the held-out windows cannot tell
    them apart with the commands as reconstructed, or, for commands logged only at the rows,
    with them reconstructed the other way (``other``: cost per held-out window, or None). A
    contender beyond its typical range but within what physics allows counts as well (a
    10 deg fin zero error that predicts the held-out windows as well as a typical plane
    effectiveness: the data cannot choose, only the typical ranges would, and an atypical
    value is a finding to check, not an answer to rule out); one beyond what physics allows
    never does. Contenders make the verdict ``ambiguous`` only when the best would be
    ``explained``: rivals of an answer that falls short leave it ``partly_explained``, with
    the rivals listed. The separating manoeuvre (the one that best tells the best from the
    rival closest to it in held-out cost) is stated in the terms of the vehicle's
    ``envelope``.
    """
    if not gap_channels:
        return 'no_gap', [], None, []
    if best is None or best.score <= 0 or best.explained < PARTLY:
        return 'unexplained', [], None, []
    verdict = 'explained' if best.explained >= EXPLAINED and white else 'partly_explained'
    mine = set(best.names)
    ambiguous: list[str] = []
    rivals: list[Candidate] = []
    for c in candidates:
        s = set(c.names)
        # a contender is close in held-out cost and in the share of the gap above the floor
        # it explains (the cost alone is dominated by the floor when the gap sits in one
        # channel, e.g. depth only)
        if not (c.possible and c.identifies) or nested(s, mine) or nested(mine, s) \
                or c.cost > AMBIGUOUS_RATIO * best.cost \
                or c.explained < best.explained / AMBIGUOUS_RATIO:
            continue
        t = window_t_stat(c.window_cost - best.window_cost)
        if t >= AMBIGUOUS_T:
            alt_best, alt_c = other(best), other(c)
            if alt_best is not None and alt_c is not None:
                t = min(t, window_t_stat(alt_c - alt_best))
        if t < AMBIGUOUS_T:
            new = [n for n in c.names if n not in mine and n not in ambiguous]
            ambiguous += new
            if new:
                rivals.append(c)
    if ambiguous:
        # the manoeuvre that tells the best from the rival closest to it on held-out data
        closest = min(rivals, key=lambda c: c.cost)
        other_name = next(n for n in closest.names if n not in mine)
        return ('ambiguous' if verdict == 'explained' else verdict), ambiguous, \
            separating_manoeuvre(best.names[0], other_name, envelope), rivals
    return verdict, [], None, []


def window_t_stat(d: np.ndarray) -> float:
    """t statistic of the mean of the per-window cost differences ``d`` (inf for one)."""
    se = float(np.std(d, ddof=1) / np.sqrt(d.size)) if d.size > 1 else math.inf
    return float(np.mean(d) / se) if se > 0 else math.inf


def with_quiet(j: Judgement, quiet: Sequence[Finding]) -> Judgement:
    """A significant buoyancy or centre-of-gravity offset from the coasts that the answer
    does not hold (or holds with the other sign) keeps it from ``explained``."""
    if j.best is None:
        return j
    names = j.best.names
    values = entry_params(j.best)
    missing = []
    for f in quiet:
        if not f.significant or f.effect not in ('buoyancy_offset', 'cg_offset'):
            continue
        key = f.param if len(names) == 1 else f'{f.effect}.{f.param}'
        if f.effect not in names or np.sign(values.get(key, 0.0)) != np.sign(f.value):
            missing.append(f'the coasts show {f.text}, which the answer does not hold')
    if not missing:
        return j
    verdict = 'partly_explained' if j.verdict == 'explained' else j.verdict
    return dataclasses.replace(j, verdict=verdict, left=[*missing, *j.left])


def entry_params(c: Candidate) -> dict[str, float]:
    """The fitted value of every parameter of ``c`` (unit of each parameter), keyed as in
    the report (:func:`param_key`)."""
    return {param_key(c, e, p.name): float(v) for (e, p), v in zip(c.fit.effects.params,
                                                                     c.fit.values)}


def compose_statement(j: Judgement, implausible: Sequence[Mapping[str, Any]],
               envelope: Envelope) -> str:
    """One paragraph for the user: what the diagnosis found, in words and units (an
    atypical value named with its typical range, what to check and how to confirm it; the
    rivals the held-out data cannot tell from the best, ``ambiguous``)."""
    parts = []
    best = j.best
    if j.verdict == 'no_gap':
        parts.append('The model matches the logs to within the noise floor.')
    elif best is None:
        parts.append('No plausible effect of the catalogue explains the gap.')
    elif j.atypical:
        parts.append(f'{j.verdict.replace("_", " ").capitalize()}, by a value beyond the '
                     f'typical range: {describe(best.fit)} ({best.explained:.0%} of the '
                     'held-out gap above the noise floor).')
        parts += beyond_typical(best)
        if j.ambiguous:
            texts = []
            for c in j.rivals[:3]:
                extra = ' '.join(beyond_typical(c)).rstrip('.')
                texts.append(f'{c.label} ({c.explained:.0%} of the gap'
                             + (f'; {extra}' if extra else '') + ')')
            parts.append('The held-out data cannot tell it from '
                         + ('; '.join(texts) if texts else ', '.join(j.ambiguous))
                         + ' (values in the candidates).')
            parts.append(f'To tell them apart, fly {j.suggestion}.')
        else:
            parts.append(f'To confirm it, fly {get_effect(best.names[0]).advice(envelope)}.')
    else:
        parts.append(f'{j.verdict.replace("_", " ").capitalize()}: '
                     + describe(best.fit) + f' ({best.explained:.0%} of the held-out gap '
                     'above the noise floor).')
        if j.ambiguous:
            atypical = [c for c in j.rivals if not c.plausible]
            texts = [f'{c.label} ({c.explained:.0%} of the gap; '
                     + ' '.join(beyond_typical(c)).rstrip('.') + ')' for c in atypical]
            named = {n for c in atypical for n in c.names}
            texts += [n for n in j.ambiguous if n not in named]
            parts.append('The held-out data cannot tell it from ' + ', '.join(texts) + '.')
            if atypical and j.suggestion:
                parts.append(f'To tell them apart, fly {j.suggestion}.')
    for item in implausible[:3]:
        tier = 'typical' if item['kind'] == 'atypical' else 'possible'
        ks = ', '.join(f'{k} = {v[0]:.4g} ({tier} {v[1]:.4g} to {v[2]:.4g})'
                       for k, v in item['beyond'].items())
        what = ('only beyond the typical range' if item['kind'] == 'atypical'
                else 'only beyond what physics allows')
        tail = (': a finding only if the better answers fail' if item['kind'] == 'atypical'
                else ': not a physical explanation')
        parts.append(f'{item["effect"]} would explain {item["explained"]:.0%} but {what}, with '
                     f'{ks}{tail}.')
    if j.left and best is not None:
        parts.append('Left over in the held-out residuals: ' + '; '.join(j.left[:4]) + '.')
    return ' '.join(parts)


def beyond_typical(c: Candidate) -> list[str]:
    """One sentence per identified parameter of ``c`` beyond its typical range: the value,
    the range and what to check."""
    out = []
    for (e, p), v, a in zip(c.fit.effects.params, c.fit.values, c.fit.active):
        if a and not p.is_plausible(float(v)):
            lo, hi = p.plausible_range
            unit = '' if p.unit == '-' else f' {p.unit}'
            out.append(f'{e}.{p.name} = {v:.4g}{unit} is beyond the typical range '
                       f'({lo:.4g} to {hi:.4g}{unit}): check '
                       f'{p.check or "how the vehicle is rigged"}.')
    return out


def param_key(c: Candidate, effect: str, name: str) -> str:
    """Report key of parameter ``name`` of ``effect``: the bare name for a single effect,
    ``effect.name`` in a set."""
    return name if len(c.names) == 1 else f'{effect}.{name}'


def candidate_entry(c: Candidate) -> dict[str, Any]:
    """The report.json entry of candidate ``c``: parameters and their 95 % intervals (unit
    of each parameter), score, explained share in [0, 1], plausibility."""
    f = c.fit
    params = {param_key(c, e, p.name): float(v)
              for (e, p), v in zip(f.effects.params, f.values)}
    ci = {param_key(c, e, p.name): [float(lo), float(hi)]
          for (e, p), lo, hi in zip(f.effects.params, f.lo95, f.hi95)}
    return {'effect': c.label, 'params': params, 'ci95': ci, 'score': float(c.score),
            'explained': float(c.explained), 'plausible': c.plausible,
            'beyond_plausible': {k: list(v) for k, v in c.beyond.items()},
            'identifies': c.identifies}


def candidate_details(c: Candidate) -> dict[str, Any]:
    """The readable report's entry of candidate ``c``: fit stage, parameter units, which
    parameters are identified, held-out cost (dimensionless) and RMS (SI unit per state)."""
    f = c.fit
    return {'effect': c.label, 'stage': f.stage,
            'units': {param_key(c, e, p.name): p.unit for e, p in f.effects.params},
            'identified': {param_key(c, e, p.name): bool(a)
                           for (e, p), a in zip(f.effects.params, f.active)},
            'held_out_cost': c.cost, 'held_out_rms': c.rms, 'n_params': f.n_active}


def implausible_entries(candidates: Sequence[Candidate], best: Candidate | None,
                        rivals: Sequence[Candidate] = ()) -> list[dict[str, Any]]:
    """The ``implausible`` entries of the report.

    Parameters
    ----------
    candidates
        every scored candidate.
    best
        the candidate named (left out), or None.
    rivals
        the candidates the answer is ambiguous with (left out: the statement names them).

    Returns
    -------
    list of dict
        per candidate that explains at least ``PARTLY`` of the gap but only with parameters
        beyond their typical range (``kind`` ``atypical``) or beyond what physics allows
        (``impossible``): its ``effect`` label, ``explained`` share in [0, 1], ``kind``, and
        ``beyond``, each such parameter -> ``[value, low, high]`` in the parameter's unit.
    """
    return [{'effect': c.label, 'explained': c.explained,
             'kind': 'impossible' if not c.possible else 'atypical',
             'beyond': ({k: [v, *c.impossible[k]] for k, v in entry_params(c).items()
                         if k in c.impossible} if not c.possible else
                        {k: [v, *c.beyond[k]] for k, v in entry_params(c).items()
                         if k in c.beyond})}
            for c in candidates if not c.plausible and c.explained >= PARTLY
            and c is not best and all(c is not r for r in rivals)]


def _shrink(before: float, after: float, floor: float) -> float:
    """Share of the RMS above the noise floor that a candidate removes, in [0, 1]."""
    room = before - floor
    return float(np.clip((before - after) / room, 0.0, 1.0)) if room > 0 else 0.0


def held_out_entry(nominal: Candidate | None, after: Candidate | None, rms: np.ndarray,
                   floor: np.ndarray) -> dict[str, Any]:
    """The ``held_out`` entry of the report.

    Parameters
    ----------
    nominal
        the nominal model scored on the held-out windows, or None without a search.
    after
        the answer named, or the nominal when none is.
    rms
        nominal free-run RMS over all windows per channel of
        :data:`auv_gap.problem.CH_NAMES` (SI unit of each state); used without a search.
    floor
        free-run noise floor per channel of :data:`auv_gap.problem.CH_NAMES`.

    Returns
    -------
    dict
        ``rms_before`` and ``rms_after`` (depth ``z`` [m], pitch ``theta`` [rad]), the
        explained share ``shrink`` and its depth-only counterpart ``shrink_depth`` (both in
        [0, 1]; 0 without a search) and the ``floor`` of depth and pitch.
    """
    z_i, th_i = CH_NAMES.index('z'), CH_NAMES.index('theta')
    if nominal is not None and after is not None:
        return {
            'rms_before': {'z': nominal.rms['z'], 'theta': nominal.rms['theta']},
            'rms_after': {'z': after.rms['z'], 'theta': after.rms['theta']},
            'shrink': after.explained,
            'shrink_depth': _shrink(nominal.rms['z'], after.rms['z'], float(floor[z_i])),
            'floor': {'z': float(floor[z_i]), 'theta': float(floor[th_i])},
        }
    before = {'z': float(rms[z_i]), 'theta': float(rms[th_i])}
    return {'rms_before': before, 'rms_after': before, 'shrink': 0.0, 'shrink_depth': 0.0,
            'floor': {'z': float(floor[z_i]), 'theta': float(floor[th_i])}}
