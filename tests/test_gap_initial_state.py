"""Initial states of the gap diagnosis's free runs on logs without rate sensors, and the
commands a log records only at its rows.

Oracles: the simulator's true state behind an imported vendor text log (``w`` and ``q``
derived by the import, not measured), against which the estimate of
:meth:`auv_gap.problem.Problem.estimate_initial` and its stated covariance are checked;
and hand-worked command series for :func:`auv_gap.logs.other_hold`.
"""
from __future__ import annotations

import pathlib

import numpy as np
import pytest
from test_import_gap_2hz import dive

from auv_gap.logs import FOH_STEPS, from_arrays, other_hold

ROOT = pathlib.Path(__file__).resolve().parents[1]
MAP = ROOT / 'config' / 'maps' / 'text_2hz_deg_cm.yaml'
W, Q, Z, TH = 8, 10, 2, 4


@pytest.fixture(scope='module')
def text_log(tmp_path_factory: pytest.TempPathFactory) -> tuple:  # type: ignore[type-arg]
    """A 5-minute closed-loop flight of the A18M logged as the vendor's 10 Hz text log."""
    from auv_gap import synth
    from auv_gap.logs import from_contract_arrays
    from auv_logs import synth as realsynth
    from auv_logs.contract_bag import contract_arrays
    from auv_logs.importer import import_log
    from auv_logs.mapping import load_map
    from auv_sim.params import load_vehicle

    vehicle = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    log = synth.simulate(vehicle, {'effects': {}}, dive(), seed=7)
    path = tmp_path_factory.mktemp('text') / 'dive.txt'
    realsynth.write_text(path, realsynth.record_of(log.t, log.state, log.commands), every=5)
    imported = import_log(load_map(MAP), path)
    pieces = from_contract_arrays('dive', contract_arrays(imported), [imported.report])
    return vehicle, log, pieces


def test_initial_rates_fitted_to_depth_and_pitch_beat_the_differenced_rates(
        text_log: tuple) -> None:  # type: ignore[type-arg]
    """At each window start the heave velocity and pitch rate fitted to the first seconds of
    measured depth and pitch are nearer the simulator's true state than the smoothed
    differenced rates, and their errors agree with the covariance the fit states."""
    from auv_gap.catalogue import Perturbation
    from auv_gap.problem import Problem

    vehicle, log, pieces = text_log
    pr = Problem(vehicle, pieces, window=20.0)
    wins = pr.select(None)
    nom = Perturbation.nominal(vehicle)

    def starts() -> np.ndarray:
        """The free runs' initial states (nw x 12): their first output rows."""
        out, _ = pr.free_run([nom], wins)
        return out[0][[r.start for r in pr.window_rows(wins)]]

    t = np.array([pr.logs[w.log].t[w.i0] for w in pr.windows])
    truth = np.column_stack([np.interp(t, log.t, log.true_state[:, k]) for k in range(12)])
    before = starts() - truth
    pr.estimate_initial(['w', 'q'])
    assert pr.x0_states == (Z, TH, W, Q)
    after = starts() - truth
    rms_b = np.sqrt(np.mean(before ** 2, axis=0))
    rms_a = np.sqrt(np.mean(after ** 2, axis=0))
    # the differenced heave velocity is the worst start a free run has (depth noise over a
    # tenth of a second); the fitted one is several times better
    assert rms_a[W] < 0.5 * rms_b[W], (rms_a[W], rms_b[W])
    assert rms_a[Q] < 1.2 * rms_b[Q], (rms_a[Q], rms_b[Q])
    # the stated covariance: errors over their standard deviations spread about one
    sd = np.sqrt(np.array([np.diag(c) for c in pr.x0_cov if c is not None]))
    assert sd.shape == (len(wins), 4)
    zs = after[:, [Z, TH, W, Q]] / sd
    spread = np.sqrt(np.mean(zs ** 2, axis=0))
    assert np.all(spread > 0.3) and np.all(spread < 3.0), spread
    # the Monte Carlo of the noise floor draws the fitted states from that covariance
    draws = pr.initial_noise(np.random.default_rng(3), 4000, wins)
    assert np.allclose(np.std(draws[:, :, W], axis=0), sd[:, 2], rtol=0.1)
    assert np.allclose(np.std(draws[:, :, 6], axis=0), pr.noise[6] * pr.initial_gain,
                       rtol=0.1)


def test_each_model_fits_its_own_initial_states(text_log: tuple) -> None:  # type: ignore
    """A model 20 N heavier than the plant fits its own initial heave velocity: over the
    first seconds it must sink less than the nominal model to match the same depths, so its
    fitted w0 is smaller (NED: down positive) in every window."""
    from auv_gap.catalogue import Perturbation
    from auv_gap.problem import EffectSet, Problem

    vehicle, _, pieces = text_log
    pr = Problem(vehicle, pieces, window=20.0)
    pr.estimate_initial(['w', 'q'])
    wins = pr.select(None)
    heavy = EffectSet(['buoyancy_offset'], vehicle).perturbation(np.array([-20.0]))
    out, _ = pr.free_run([Perturbation.nominal(vehicle), heavy], wins)
    first = [r.start for r in pr.window_rows(wins)]
    assert np.all(out[1][first, W] < out[0][first, W]), out[:, first, W]


def test_clean_10hz_text_log_has_no_gap_and_a_floor_below_the_differenced_one(
        text_log: tuple) -> None:  # type: ignore[type-arg]
    """The diagnosis of the clean flight: no gap, and the depth floor of the free runs well
    below the 0.3-0.5 m that free runs from differenced rates had."""
    from auv_gap.diagnose import diagnose

    vehicle, _, pieces = text_log
    r = diagnose(vehicle, pieces, window=60.0).report
    assert r['verdict'] == 'no_gap', r['statement']
    assert r['held_out']['floor']['z'] < 0.2, r['held_out']['floor']


def _log(period: float, t_cmd: np.ndarray, v_cmd: np.ndarray) -> object:
    t = np.arange(0.0, 10.0 + 1e-9, period)
    state = np.zeros((t.size, 12))
    cmds = {'bar': (t_cmd, v_cmd), 'thrust': (np.array([0.0]), np.array([50.0]))}
    return from_arrays('log', t, state, cmds)[0]


def test_other_hold_swaps_held_and_linear_commands_logged_at_the_rows() -> None:
    """Hand-worked: commands at every row of a 0.5 s log are made linear between rows by the
    import (first-order hold); the other reconstruction holds each row's value; commands at
    every row of a 0.1 s log are held and the other reconstruction is linear; commands with
    their own stamps have none."""
    t = np.arange(0.0, 10.0 + 1e-9, 0.5)
    v = np.where(t >= 2.0, 0.1, 0.0)
    from auv_gap.logs import first_order_hold
    slow = first_order_hold(_log(0.5, t, v))  # type: ignore[arg-type]
    assert slow.linear_between_rows == ('bar',)
    st, va = slow.commands['bar']
    # between the rows at 1.5 s (0) and 2 s (0.1): linear
    assert np.interp(1.75, st, va) == pytest.approx(0.05, abs=0.1 / FOH_STEPS)
    back = other_hold(slow)
    assert back is not None
    assert np.array_equal(back.commands['bar'][0], t)
    assert np.array_equal(back.commands['bar'][1], v)
    fast_t = np.arange(0.0, 10.0 + 1e-9, 0.1)
    fast = _log(0.1, fast_t, np.where(fast_t >= 2.0, 0.1, 0.0))
    assert fast.linear_between_rows == ()  # type: ignore[attr-defined]
    lin = other_hold(fast)  # type: ignore[arg-type]
    assert lin is not None
    st, va = lin.commands['bar']
    assert np.interp(1.95, st, va) == pytest.approx(0.05, abs=0.1 / FOH_STEPS)
    # commands at their own stamps (every 0.35 s against rows of 0.1 s): nothing to swap
    own = _log(0.1, np.arange(0.0, 10.0, 0.35), np.zeros(29))
    assert other_hold(own) is None  # type: ignore[arg-type]
