"""The nominal model on the logs: its free runs over every window, their noise floor, the
channels with a gap, and whether it diverges (stage 1 of :func:`auv_gap.diagnose.diagnose`);
for a model that diverges, whether the effect its equations want most keeps the runs with
the logs (:func:`steadied_by`, :func:`keeps_runs`), and the statement when none does.

Units: pitch [rad], times [s]; the free-run channels are those of
:data:`auv_gap.problem.CH_NAMES` in their own units.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence

import numpy as np

from auv_gap import analysis
from auv_gap.catalogue import Perturbation
from auv_gap.fit import EquationFit, FitResult
from auv_gap.logs import GapLog, Weighting, other_hold
from auv_gap.problem import CH_INDEX, CH_NAMES, Problem
from auv_gap.verdict import plausibility

GAP_FACTOR = analysis.GAP_FACTOR
MC_RUNS = 4

Progress = Callable[[str], None]


@dataclasses.dataclass
class NominalRuns:
    """Stage 1: the nominal model's free runs over every window against the log, their noise
    floor, the states with a gap, the channel scales of the cost, and whether the model
    diverges on the logs."""

    all_w: list[int]                # the windows kept (the diverging ones left out)
    err: np.ndarray                 # S x 12, nominal free run minus smoothed log
    rms: np.ndarray                 # per channel of CH_NAMES
    floor: np.ndarray               # per channel of CH_NAMES
    gap_channels: list[str]
    scales: np.ndarray
    rms_z_win: np.ndarray           # depth RMS per window
    other_logs: list[GapLog] | None
    diverging: list[bool]           # per window of all windows
    diverges: bool


#: A free run diverges when its pitch leaves the log's by more than this [rad] (a vehicle
#: tumbling in the model, not a biased flight) or its output is not finite; the nominal
#: model diverges on the logs when at least :data:`DIVERGE_SHARE` of its runs do.
DIVERGE_PITCH = math.radians(45.0)
DIVERGE_SHARE = 0.1


def nominal_runs(pr: Problem, weighting: Weighting, say: Progress) -> NominalRuns:
    """Stage 1 (see :class:`NominalRuns`): a Monte Carlo over the initial-state uncertainty,
    the plain smoother's bias and the commands between rows (where a log records them only at
    its rows) make the floor; channels whose RMS exceeds ``GAP_FACTOR`` times it carry a
    gap."""
    nom = Perturbation.nominal(pr.vehicle)
    every = pr.select(None)

    def runs(windows: list[int]) -> tuple[np.ndarray, np.ndarray]:
        rng = np.random.default_rng(12345)
        x0_noise = np.zeros((MC_RUNS + 1, len(windows), 12))
        x0_noise[1:] = pr.initial_noise(rng, MC_RUNS, windows)
        return pr.free_run([nom] * (MC_RUNS + 1), windows, x0_noise=x0_noise)

    out, meas = runs(every)
    diverging = diverging_runs(pr, every, out[0] - meas)
    diverges = bool(np.mean(diverging) >= DIVERGE_SHARE) if diverging else False
    # runs on which the nominal model leaves the logs would weigh more than all the others
    # together (a change that merely steadies the model would explain them): out of the
    # free-run fits and scores, said
    if any(diverging) and not diverges \
            and pr.exclude([i for i, d in zip(every, diverging) if d]):
        say(f'{int(np.sum(diverging))} of {len(every)} runs on which the nominal model '
            'diverges are left out of the free-run fits and scores')
        out, meas = runs(pr.select(None))
    all_w = pr.select(None)
    err_nom = out[0] - meas
    rows_all = pr.window_rows(all_w)
    finite = np.all(np.isfinite(err_nom[:, CH_INDEX]), axis=1)
    if not finite.all():
        say('the nominal free run diverges in some windows')
    rms_nom = np.sqrt(np.nanmean(np.where(finite[:, None], err_nom, np.nan)[:, CH_INDEX] ** 2,
                                 axis=0))
    spread = np.sqrt(np.nanmean((out[1:] - out[0][None])[:, :, CH_INDEX] ** 2, axis=(0, 1)))
    out_b, _ = pr.free_run([nom], all_w, x0_bias=True)
    bias_spread = np.sqrt(np.nanmean((out_b[0] - out[0])[:, CH_INDEX] ** 2, axis=0))
    # commands logged only at the state rows: held and linear between rows bracket what
    # they did in between; the difference of the two free runs is in the floor
    command_spread = np.zeros(len(CH_INDEX))
    other = [other_hold(lg) for lg in pr.logs]
    other_logs: list[GapLog] | None = None
    if any(lg is not None for lg in other):
        other_logs = [o or lg for o, lg in zip(other, pr.logs)]
        act_other = pr.actuators_of(other_logs, nom)
        out_c, _ = pr.free_run([nom], all_w, act_override=act_other)
        command_spread = np.sqrt(np.nanmean((out_c[0] - out[0])[:, CH_INDEX] ** 2, axis=0))
    floor = np.sqrt((pr.noise[list(CH_INDEX)] * pr.smooth_gain) ** 2 + spread ** 2
                    + bias_spread ** 2 + command_spread ** 2)
    gap_channels = [CH_NAMES[i] for i in range(len(CH_INDEX))
                    if rms_nom[i] > GAP_FACTOR * floor[i]]
    scales = np.maximum(rms_nom, floor)
    # derived or assumed signals: their free-run channels weigh nothing
    scales = np.where(weighting.channel_mask(CH_NAMES), np.inf, scales)
    gap_channels = [c for c in gap_channels if c not in weighting.channels]
    rms_z_win = np.array([np.sqrt(np.nanmean(err_nom[r, 2] ** 2)) for r in rows_all])
    return NominalRuns(all_w, err_nom, rms_nom, floor, gap_channels, scales, rms_z_win,
                       other_logs, diverging, diverges)


def diverging_runs(pr: Problem, windows: Sequence[int], err: np.ndarray) -> list[bool]:
    """Per window of ``windows``: whether the free run whose errors against the log are
    ``err`` (rows of :meth:`Problem.window_rows`) diverges (pitch off by more than
    :data:`DIVERGE_PITCH`, or not finite)."""
    return [bool(not np.all(np.isfinite(err[r][:, list(CH_INDEX)]))
                 or np.max(np.abs(err[r, 4])) > DIVERGE_PITCH)
            for r in pr.window_rows(windows)]


def steadied_by(pr: Problem, names: Sequence[str], before: Sequence[bool], say: Progress
                 ) -> tuple[dict[str, FitResult], list[str]]:
    """A nominal model that diverges on the logs either has dynamics the logs do not
    follow (re-identify it) or misses an effect large enough to throw its runs off (a 10 deg
    fin zero error). Each effect is fitted by equation error alone (the model's equations at
    the logged states: no free run that a steadying change could win); the one the equations
    want most (the lowest held-out equation-error cost among those within what physics
    allows that identify something) is run over every window: when it keeps them with the
    logs (:func:`keeps_runs`), the divergence was that effect's (returned in the list);
    otherwise the model is what diverges (an empty list: any other effect that steadies it
    would do so by taking something away, a plane's lift, not by adding what is missing).
    ``before``: per run of every window, whether the nominal model's run diverged. Returns
    the fits too (the search reuses them)."""
    eqf = EquationFit(pr)
    say(f'the nominal model diverges: equation-error fits of {len(names)} effects')
    fits = {n: eqf.fit(pr.effect_set([n])) for n in names}
    usable = [n for n in names if fits[n].n_active > 0
              and not plausibility(fits[n])[1] and not plausibility(fits[n])[2]]
    if not usable:
        return fits, []
    wanted = min(usable, key=lambda n: eqf.cost(fits[n].effects, fits[n].values,
                                                held_out=True))
    all_w = pr.select(None)
    out, meas = pr.free_run([fits[wanted].effects.perturbation(fits[wanted].values)], all_w)
    after = diverging_runs(pr, all_w, out[0] - meas)
    steady = keeps_runs(before, after)
    say(f'the effect the equations want most, {wanted}, '
        + ('keeps' if steady else 'does not keep') + ' the free runs with the logs '
        f'({sum(after)} of {len(after)} diverge, against {sum(before)} of the nominal '
        'model\'s)')
    return fits, [wanted] if steady else []


#: One-sided level of the sign test by which an effect keeps a diverging model's runs with
#: the logs (:func:`keeps_runs`).
STEADY_LEVEL = 0.05


def keeps_runs(before: Sequence[bool], after: Sequence[bool]) -> bool:
    """Whether a model change keeps with the logs the free runs of a model that diverges on
    them: ``before`` and ``after`` say, per run (the same windows), whether the run diverged
    without and with the change.

    Kept when fewer than half of :data:`DIVERGE_SHARE` of the runs still diverge, or when the
    change ends the divergence of significantly more runs than it starts (an exact one-sided
    sign test over the runs whose outcome it changes, level :data:`STEADY_LEVEL`) and leaves
    most runs with the logs (fewer than half diverge). On a vehicle unstable without feedback
    a free run of four e-folding times grows an initial error 55-fold: a pitch error of
    0.8 deg at the start reaches the 45 deg of :data:`DIVERGE_PITCH`, so even the true model
    leaves a few runs (the small-sample count alone would turn an effect down because one
    run of 14 went over); the test asks whether the change is what stops the divergence.

    Parameters
    ----------
    before, after
        per run: diverged (pitch off by more than :data:`DIVERGE_PITCH`, or no finite
        state), without and with the change.

    Returns
    -------
    bool
        whether the change keeps the runs with the logs.

    Raises
    ------
    ValueError
        ``before`` and ``after`` of different lengths.
    """
    if len(before) != len(after):
        raise ValueError(f'{len(before)} runs before, {len(after)} after')
    n = len(after)
    if n == 0:
        return False
    left = sum(after)
    if left < 0.5 * DIVERGE_SHARE * n:
        return True
    ended = sum(b and not a for b, a in zip(before, after))
    started = sum(a and not b for b, a in zip(before, after))
    # P(X >= ended) for X ~ Binomial(ended + started, 1/2): the change as likely to start a
    # divergence as to end one
    changed = ended + started
    p = sum(math.comb(changed, k) for k in range(ended, changed + 1)) / 2.0 ** changed \
        if changed else 1.0
    return p < STEADY_LEVEL and left < 0.5 * n


def divergence_text(pr: Problem, nominal: NominalRuns) -> str:
    """Why the diagnosis stops on a model that diverges on the logs."""
    k = int(np.sum(nominal.diverging))
    unstable = 'unstable' in pr.run_why
    return (f'The nominal model diverges on these logs: {k} of {len(nominal.diverging)} free '
            f'runs of {pr.run:.3g} s leave the logged motion (pitch off by more than '
            f'{math.degrees(DIVERGE_PITCH):.0f} deg, or no finite state'
            + (f'; {pr.run_why}' if unstable else '')
            + '), and the effect its equations want most does not keep them with the logs. '
            'Any effect that merely steadies it would seem to explain the gap, so none is '
            'named: '
            're-identify the model first (auv ident on these logs, or logs with manoeuvres), '
            'then diagnose the identified file'
            + ('; if the model is right and only unstable, log the pitch rate and heave '
               'velocity (or faster rows): the runs start from states differenced at the '
               'log\'s rows' if unstable and pr.x0_states else '') + '.')
