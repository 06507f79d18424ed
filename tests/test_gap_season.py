"""The gap diagnosis on logs as they come: short segments in any order, few windows, a model
that diverges, values beyond the typical range, the quiet stretches of a log.

Oracles: windows counted by hand; a covariance worked by hand on a one-cluster fit; the
surface reading's mean and Student interval by hand; a simulated small AUV (the diagnosis is
not told its effects) whose coasts must give its buoyancy and centre of gravity with the
right sign and intervals that hold the truth.
"""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
from scipy import stats

from auv_gap.catalogue import CATALOGUE
from auv_gap.errors import GapError
from auv_gap.fit import cluster_covariance
from auv_gap.logs import from_arrays, log_period
from auv_gap.manoeuvres import Envelope, manoeuvre
from auv_gap.problem import Problem, data_window, window_starts
from auv_gap.ranges import default_ranges, load_ranges
from auv_gap.static import surface_finding
from auv_gap.wording import interval
from auv_sim.params import load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]
A18M = ROOT / 'config' / 'a18m.yaml'
REMUS = ROOT / 'config' / 'remus100.yaml'


def _pieces(durations: list[float], period: float = 0.5, name: str = 'log') -> list:  # type: ignore[type-arg]
    """Log pieces of the given lengths [s], 10 s apart, level at 5 m and 1.5 m/s."""
    out = []
    t0 = 0.0
    for k, d in enumerate(durations):
        t = t0 + np.arange(0.0, d + 1e-9, period)
        state = np.zeros((t.size, 12))
        state[:, 2] = 5.0
        state[:, 6] = 1.5
        cmds = {'bar': (t, np.zeros(t.size)), 'thrust': (np.array([t[0]]), np.array([10.0]))}
        out += from_arrays(f'{name}{k}', t, state, cmds)
        t0 = t[-1] + 10.0
    return out


def test_window_starts_and_the_window_chosen_from_the_data() -> None:
    # a 30 s piece at 2 Hz (61 samples), 10 s windows from 5 s: starts 10, 30, 50 (samples);
    # the last (50 -> 60, 5 s) is half a window, so it stays
    assert window_starts(61, 0.5, 10.0) == [(10, 30), (30, 50), (50, 60)]
    # a piece shorter than the window is one window from 5 s to its end
    assert window_starts(61, 0.5, 60.0) == [(10, 60)]
    # a piece of 8 s has less than the 4 s tail after 5 s: none
    assert window_starts(17, 0.5, 60.0) == []
    # long logs keep 60 s: a 300 s piece gives starts 5, 65, 125, 185, 245 s
    w, why = data_window(_pieces([300.0]))
    assert w == 60.0 and '5 window(s)' in why
    # three 30 s pieces: 60 s gives 3 windows (one a piece), enough
    assert data_window(_pieces([30.0, 30.0, 30.0]))[0] == 60.0
    # two: 60 s gives 2; a piece holds two windows from 16 s on (5 -> 21 -> 30 s: the 9 s
    # tail is more than half a window, so it stays; at 17 s the 8 s tail is less than half
    # and joins the first): 16 s, 4 windows
    pieces = _pieces([30.0, 30.0])
    w, why = data_window(pieces)
    assert w == 16.0, why
    assert sum(len(window_starts(p.t.size, 0.5, w)) for p in pieces) == 4


def test_two_vehicle_files_get_the_same_windows_and_held_out_samples() -> None:
    """The window comes from the data: the A18M (stable) and the REMUS 100 (unstable without
    feedback) on the same logs hold out the same samples; the REMUS's free runs restart
    within the windows."""
    logs = _pieces([200.0, 45.0, 15.0, 120.0])
    a = Problem(load_vehicle(A18M), logs)
    r = Problem(load_vehicle(REMUS), logs)
    assert a.window == r.window
    held = {(w.log, t) for w in a.windows if w.held_out for t in range(w.i0, w.i0 + w.n)}
    held_r = {(w.log, t) for w in r.windows if w.held_out for t in range(w.i0, w.i0 + w.n)}
    assert held == held_r
    assert r.run < r.window and a.run == a.window
    assert 'unstable without feedback' in r.run_why


def test_short_pieces_in_any_order_do_not_break_the_spectrum() -> None:
    """The crash of a log whose first piece is short ("operands could not be broadcast
    together with shapes (41,) (38,)"): the noise spectrum was simulated at the first piece's
    length. Now any order gives the same band and no error."""
    from auv_gap.analysis import band

    vehicle = load_vehicle(A18M)
    rng = np.random.default_rng(1)
    short_first = _pieces([25.0, 300.0])
    long_first = _pieces([300.0, 25.0])
    results = []
    for logs in (short_first, long_first):
        logs = [lg.__class__(**{**lg.__dict__, 'state': lg.state + 0.01 * rng.standard_normal(
            lg.state.shape)}) for lg in logs]
        pr = Problem(vehicle, logs)
        residual = rng.standard_normal(pr.eq_index.size)
        results.append(band(pr, residual, 1))
    for _, info in results:
        assert info['psd'].shape == info['noise'].shape


def test_one_cluster_never_gives_an_interval_of_zero_width() -> None:
    """Hand-worked: one parameter, one cluster of 6 residuals. CR2 alone is 0 at the
    least-squares optimum (J^T r = 0); the floor is s^2 (J^T J)^-1 (1 + rho) / (1 - rho) with
    rho the lag-1 correlation (clipped to [0, 0.95])."""
    J = np.ones((6, 1))
    r = np.array([1.0, -1.0, 2.0, -2.0, 1.0, -1.0])     # sums to 0: the optimum
    V, df = cluster_covariance(J, r, np.zeros(6, int))
    s2 = float(r @ r) / 5.0                                # 12 / 5
    # lag-1: sum r_k r_{k-1} = -1 -2 -4 -2 -1 = -10 < 0: clipped to 0
    assert V[0, 0] == pytest.approx(s2 / 6.0, rel=1e-12)
    assert df[0] == 1.0
    assert interval(3.3312, 3.3349) == '3.331 to 3.335'
    assert interval(3.33, 3.33) == '3.33 to 3.33'


def test_surface_passes_give_the_depth_zero_by_hand() -> None:
    passes = [{'depth_median': 0.08, 'depth_spread': 0.01, 'samples': 40},
              {'depth_median': 0.09, 'depth_spread': 0.01, 'samples': 40}]
    f = surface_finding(passes, noise=0.001)
    assert f is not None
    assert f.value == pytest.approx(0.085)
    within = math.sqrt(2 * (0.01 / math.sqrt(40)) ** 2) / 2
    se = math.hypot(np.std([0.08, 0.09], ddof=1) / math.sqrt(2), within)
    half = float(stats.t.ppf(0.975, 1)) * se
    assert f.lo == pytest.approx(0.085 - half) and f.hi == pytest.approx(0.085 + half)
    # a reading in 0.1 m steps: never narrower than twice its rounding noise
    g = surface_finding([{'depth_median': 0.1, 'depth_spread': 0.0, 'samples': 50}],
                        noise=0.1 / math.sqrt(12.0))
    assert g is not None and g.hi - g.lo == pytest.approx(4 * 0.1 / math.sqrt(12.0))
    assert surface_finding([]) is None


def test_ranges_from_the_file_and_a_users_file(tmp_path: pathlib.Path) -> None:
    vehicle = load_vehicle(A18M)
    table = default_ranges()
    (bias,) = table.apply('bar_bias', CATALOGUE['bar_bias'].parameters(vehicle), vehicle)
    assert bias.plausible_range == (-0.1, 0.1) and bias.possible_range == (-0.35, 0.35)
    assert bias.check.startswith('the fin zero')
    (db,) = table.apply('buoyancy_offset', CATALOGUE['buoyancy_offset'].parameters(vehicle),
                        vehicle)
    assert db.plausible_range == pytest.approx((-0.02 * vehicle.W, 0.02 * vehicle.W))
    # the file and the catalogue's built-in ranges agree (the file is the one to edit)
    for name, effect in CATALOGUE.items():
        for p, q in zip(effect.parameters(vehicle),
                        table.apply(name, effect.parameters(vehicle), vehicle)):
            assert p.plausible_range == pytest.approx(q.plausible_range), (name, p.name)
    mine = tmp_path / 'ranges.yaml'
    mine.write_text('format: auv-plausible-ranges/1\neffects:\n  bar_bias:\n'
                    '    bias: {typical: [-0.2, 0.2], possible: [-0.3, 0.3], unit: rad}\n')
    (wide,) = load_ranges(mine).apply('bar_bias', CATALOGUE['bar_bias'].parameters(vehicle),
                                      vehicle)
    assert wide.plausible_range == (-0.2, 0.2)
    mine.write_text('format: auv-plausible-ranges/1\neffects:\n  bar_bias:\n'
                    '    bias: {typical: [-0.2, 0.2], unit: deg}\n')
    with pytest.raises(GapError, match=r"effects\.bar_bias\.bias\.unit: 'deg', but "
                                       r"bar_bias\.bias is in 'rad'"):
        load_ranges(mine)


def test_manoeuvres_in_the_vehicles_terms_and_advice_per_effect() -> None:
    small = Envelope(u0=1.0, z0=1.0, depth_max=100.0, bar_max=math.radians(14.0))
    assert manoeuvre('depth excursion', small).startswith(
        'a depth excursion from about 1 to 3 m')
    assert 'tens of metres' not in manoeuvre('depth excursion', small)
    assert 'about 0.7 -> 1.3 m/s' in manoeuvre('speed change', small)
    advice = {n: CATALOGUE[n].advice(small) for n in ('buoyancy_offset', 'actuator_delay',
                                                      'actuator_rate_limit', 'bar_bias')}
    assert len(set(advice.values())) == 4, advice
    assert advice['buoyancy_offset'].startswith('a thruster-off coast')


def test_the_period_of_jittered_rows() -> None:
    t = np.cumsum(np.resize([0.39, 0.61], 400))
    assert log_period(t) == 0.5
    assert log_period(np.arange(0.0, 10.0, 0.1)) == pytest.approx(0.1)


@pytest.fixture(scope='module')
def coasting(tmp_path_factory):  # type: ignore[no-untyped-def]
    """The first log of the small AUV's season (:func:`auv_campaign.season.
    write_season`, seed 0; the worked example of docs/real-logs.md): porpoising at 1.5 m/s
    with thruster-off coasts, 2 N buoyant, its centre of gravity 5 mm forward of the file's,
    its depth sensor reading 0.085 m at the surface, written as the vendor's 2 Hz jittered
    text log (the second log of a season of two is empty)."""
    from auv_campaign import season

    out = tmp_path_factory.mktemp('coasting')
    case = season.write_season(out, 2, seed=0)
    return case.logs[0], case.map, case.vehicle


def test_a_diverging_model_is_reported_and_the_coasts_name_what_a_hand_analysis_finds(
        coasting) -> None:  # type: ignore[no-untyped-def]
    """The small AUV's file (unstable without feedback) diverges on its 2 Hz log and the
    effect its equations want most (the centre of gravity) does not keep the runs with the
    logs: no effect is named (a plane that lost its lift would steady it), the report says to
    re-identify; the coasts still give the buoyancy (+2 N) and the centre of gravity (5 mm
    forward) with the right sign and intervals that hold them, and the surface passes the
    depth sensor's zero (0.085 m)."""
    import argparse
    import json

    from auv_gap import cli as gap_cli

    log, map_path, vpath = coasting
    out = log.parent / 'gap'
    parser = argparse.ArgumentParser()
    gap_cli.add_arguments(parser)
    args = parser.parse_args([str(log), '--map', str(map_path), '--vehicle', str(vpath),
                              '--out', str(out), '--no-plots', '--quiet'])
    assert gap_cli.run(args) == 0
    r = json.loads((out / 'report.json').read_text())
    assert r['diverges'] and r['verdict'] == 'unexplained' and r['best'] is None
    assert 're-identify the model first' in r['statement']
    found = {f['effect']: f for f in r['findings']}
    for effect, truth in (('buoyancy_offset', 2.0), ('cg_offset', 0.005),
                          ('depth_sensor_bias', 0.085)):
        f = found[effect]
        assert f['significant'] and f['value'] > 0, f
        assert f['lo'] <= truth <= f['hi'], f
    assert 'net buoyancy +' in r['statement'] and 'forward of the file' in r['statement']
