"""The tables of figures, generated from the benchmark results files.

Every figure is read from ``bench/results/<name>.json`` (written by ``make bench`` or by
``python bench/bench_<name>.py``): a cell is a template whose fields ``{name:dotted.key:format}``
name the results file, the key path inside it and the Python format of the value. The full
table (:data:`ROWS`) sits in ``docs/benchmarks.md``, the key figures (:data:`KEY_ROWS`, the
same rows) in README.md, each between the lines ``<!-- figures:begin -->`` and
``<!-- figures:end -->``.

Run: ``python tools/readme_figures.py`` rewrites both blocks; ``--check`` exits 1 (and says
which line differs) when a file does not match the results files.
``tests/test_readme_figures.py`` runs the check.
"""
from __future__ import annotations

import argparse
import json
import pathlib
import re
import sys
from typing import Any

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / 'bench' / 'results'
README = ROOT / 'README.md'
BENCHMARKS = ROOT / 'docs' / 'benchmarks.md'
BEGIN, END = '<!-- figures:begin -->', '<!-- figures:end -->'

_CL = 'closed_loop:results.default'
#: (what, figure template, target); every value comes from a results file
ROWS: list[tuple[str, str, str]] = [
    ('single-vehicle RK4 step (4 model evaluations)',
     '{sim:single_us_per_step:.2f} us (real-time factor {sim:single_real_time_factor:.0f})',
     '<= 7 us'),
    ('batch, 10 000 vehicles, vehicle-steps/s on all cores (one thread)',
     '{sim:batch.10000.parallel_vehicle_steps_per_s:.3g} '
     '({sim:batch.10000.serial_vehicle_steps_per_s:.3g})',
     '>= 1e6'),
    ('40 m -> 10 m at 2 m/s: settling to +-0.1 m',
     f'{{{_CL}.climb_40_10_u2.settling_time_s:.1f}} s = '
     f'{{{_CL}.climb_40_10_u2.settling_over_kinematic_bound:.3f}} T_kin = '
     f'{{{_CL}.climb_40_10_u2.settling_over_time_optimal_bound:.3f}}x the time-optimal bound '
     f'{{{_CL}.climb_40_10_u2.time_optimal_bound_s:.1f}} s (report: ~379 s)',
     '1.5 T_kin'),
    ('same: overshoot / peak pitch / RMS q after settling',
     f'{{{_CL}.climb_40_10_u2.overshoot_m:.4f}} m / '
     f'{{{_CL}.climb_40_10_u2.peak_pitch_deg:.2f}} deg / '
     f'{{{_CL}.climb_40_10_u2.rms_q_settled_deg_s:.3f}} deg/s',
     '0.2 m / 25 deg / 0.05 deg/s'),
    ('10 -> 40 m; 40 -> 10 m at 1.5 / 2.5 / 1.83 m/s (T_kin ratio)',
     f'{{{_CL}.dive_10_40_u2.settling_over_kinematic_bound:.3f}}; '
     f'{{{_CL}.climb_40_10_u1.5.settling_over_kinematic_bound:.3f}} / '
     f'{{{_CL}.climb_40_10_u2.5.settling_over_kinematic_bound:.3f}} / '
     f'{{{_CL}.climb_40_10_u1.83.settling_over_kinematic_bound:.3f}}',
     '1.5 T_kin'),
    ('40 -> 10 m in a 0.3 m/s following / head / cross current, pilot told its water speed '
     '(head current, pilot on ground speed: information)',
     f'{{{_CL}.climb_40_10_u2_current_following_0.3.settling_over_kinematic_bound:.3f}} / '
     f'{{{_CL}.climb_40_10_u2_current_head_0.3.settling_over_kinematic_bound:.3f}} / '
     f'{{{_CL}.climb_40_10_u2_current_cross_0.3.settling_over_kinematic_bound:.3f}} T_kin '
     f'({{{_CL}.climb_40_10_u2_current_head_0.3_ground_speed.settling_over_kinematic_bound:.3f}})',
     '1.5 T_kin'),
    ('every closed-loop case within its targets',
     '{closed_loop:all_pass_default}', 'True'),
    ('lockstep graph real-time factor (3 processes; the recorder keeps every message)',
     '{graph:lockstep.real_time_factor:.1f}', '>= 20'),
    ('README recipes in lockstep (`launch --lockstep --real-time-factor 0 --record`, '
     '`--mission pitch --real-time-factor 0 --record`, the demo): messages recorded / '
     'published, lowest topic; machine as it is / two CPU-bound processes beside / another '
     'node graph and a test file beside (load average)',
     '{graph:completeness.lockstep_min_ratio_by_load.idle:.3f} / '
     '{graph:completeness.lockstep_min_ratio_by_load.cpu2:.3f} / '
     '{graph:completeness.lockstep_min_ratio_by_load.graph_and_tests:.3f} '
     '(load {graph:completeness.idle.mission_pitch.load_average_1min_before:.0f} / '
     '{graph:completeness.cpu2.mission_pitch.load_average_1min_before:.0f} / '
     '{graph:completeness.graph_and_tests.mission_pitch.load_average_1min_before:.0f})',
     '1.000'),
    ('the same, real time (`launch --depth 10 --record`, 30 s)',
     '{graph:completeness.realtime_min_ratio_by_load.idle:.3f} / '
     '{graph:completeness.realtime_min_ratio_by_load.cpu2:.3f} / '
     '{graph:completeness.realtime_min_ratio_by_load.graph_and_tests:.3f}', ''),
    ('start to first plane command, plain `auv launch`, median of 5 (start-up cache warm): '
     'as it is / two CPU-bound beside / another graph and tests beside (load average), as '
     'received by a subscriber listening since before the start; as published by the pilot; '
     'CPU s before it, launcher + max(pilot, simulator)',
     '{graph:startup.idle.median_s:.1f} / {graph:startup.cpu2.median_s:.1f} / '
     '{graph:startup.graph_and_tests.median_s:.1f} s '
     '(load {graph:startup.idle.load_average_1min_before:.0f} / '
     '{graph:startup.cpu2.load_average_1min_before:.0f} / '
     '{graph:startup.graph_and_tests.load_average_1min_before:.0f}); '
     '{graph:startup.idle.published_median_s:.1f} / {graph:startup.cpu2.published_median_s:.1f}'
     ' / {graph:startup.graph_and_tests.published_median_s:.1f} s; '
     '{graph:startup.idle.cpu_s_critical_path:.1f} s', '< 3 s'),
    ('pilot publish period, wall clock, DDS source stamps: median, p99 jitter '
     '(as received by the recorder)',
     '{graph:timer.period_median_ms:.2f} ms, {graph:timer.jitter_p99_ms:.2f} ms '
     '({graph:timer.as_received.jitter_p99_ms:.2f} ms)', 'p99 < 2 ms'),
    ('the same, pilot on SCHED_FIFO (`realtime_priority` 50)',
     '{graph:timer_realtime.jitter_p99_ms:.2f} ms', 'p99 < 2 ms'),
    ('state -> BAR latency through the pilot: median, p99',
     '{graph:latency.median_ms:.2f} ms, {graph:latency.p99_ms:.2f} ms', 'p99 < 5 ms'),
    ('replay (`auv play`) at rate 1 / 2: p95 message lag (median of 3)',
     '{replay:rate_1.lag_p95_s.median:.4f} s / {replay:rate_2.lag_p95_s.median:.4f} s', ''),
    ('bag -> arrays, /auv/state, 180 000 messages; ratio to rosbags per message, same run',
     '{bag:vectorised_s:.3f} s; {bag:speedup:.1f}x', '>= 10x'),
    ('identification, one hour of 50 Hz data: from forces / from motion',
     '{ident:total_forces_s:.2f} s / {ident:total_motion_s:.2f} s', '< 10 s'),
    ('gap diagnosis, 20-minute 50 Hz log', '{gap:total_s:.1f} s', '< 60 s'),
    ('identification from motion: 95 % interval coverage over 100 noise replications, lowest '
     '/ highest of the nine coefficients',
     '{ident_coverage:min_coverage:.2f} / {ident_coverage:max_coverage:.2f} '
     '({ident_coverage:runs} runs)', '0.95'),
    ('identification panel: plants not of the base file\'s structure (cross-flow terms 0.1x and '
     '20x the plant\'s, strip-theory hull, plane 40 % weaker; 2 Hz quantised text, 10 Hz ROS 2, '
     '50 Hz bags with and without forces; 2, 15, 30 min): runs; wrong-sign coefficients '
     'written; written models predicting an independent flight worse than the base '
     '(significantly / by any amount); true values inside the 95 % intervals; median depth rms '
     'improvement over the base; the former method on the cases it ran: wrong signs, worse, '
     'coverage, improvement',
     '{ident_panel:new.runs}; {ident_panel:new.wrong_sign_written}; '
     '{ident_panel:new.worse_than_base} / {ident_panel:new.worse_than_base_any_amount}; '
     '{ident_panel:new.coverage:.2f} ({ident_panel:new.intervals_with_truth}); '
     '{ident_panel:new.median_improvement:.2f}; former ({ident_panel:former.runs} runs): '
     '{ident_panel:former.wrong_sign_written}, {ident_panel:former.worse_than_base_any_amount}, '
     '{ident_panel:former.coverage:.2f}, {ident_panel:former.median_improvement:.2f}',
     '0; 0; >= 0.9'),
    ('identification of a 2-minute log, slowest of the panel (output error on 2 Hz included)',
     '{ident_panel:two_minute_log_seconds_max:.1f} s', '< 30 s'),
    ('gap diagnosis on vendor text logs at 2 / 10 / 50 Hz, five plants: right; honest '
     '(cannot be seen at that rate, said so); missed; wrong',
     '{poor_data:right}; {poor_data:honest}; {poor_data:missed}; {poor_data:wrong} '
     '(of {poor_data:text_cases})', '0 wrong'),
    ('a season of real-log stand-ins (short, slow, quantised, cut-off logs; 4 vehicles): '
     'crashes; confident wrong answers; effects a hand analysis finds named with the right '
     'sign; campaign tasks failed other than by an honest refusal; 26 logs through `auv '
     'campaign gap` on 2 workers',
     '{real_season:crashes}; {real_season:confident_wrong}; {real_season:hand_named} of '
     '{real_season:hand_total}; {real_season:campaign_failed_other}; '
     '{real_season:season_wall_s:.0f} s', '0; 0; all; 0; < 120 s'),
    ('import of one hour of 50 Hz Odometry + Imu + FluidPressure + fin commands: time, peak '
     'memory; rosbags per-message deserialisation of the same bag, same run',
     '{import:import_s:.2f} s, {import:import_peak_rss_mb:.0f} MB; '
     '{import:rosbags_deserialise_s:.1f} s (ratio {import:import_over_rosbags:.3f})',
     '< 10 s, < 1 GB'),
    ('REMUS 100 at 1.5 m/s, 20 -> 10 / 10 -> 30 / 5 -> 40 m: settling over the time-optimal '
     'bound',
     '{vehicles:vehicles.remus100.20->10m.settling_over_time_optimal_bound:.2f} / '
     '{vehicles:vehicles.remus100.10->30m.settling_over_time_optimal_bound:.2f} / '
     '{vehicles:vehicles.remus100.5->40m.settling_over_time_optimal_bound:.2f}', '<= 1.5'),
    ('NPS AUV II, the same depth changes',
     '{vehicles:vehicles.npsauv2.20->10m.settling_over_time_optimal_bound:.2f} / '
     '{vehicles:vehicles.npsauv2.10->30m.settling_over_time_optimal_bound:.2f} / '
     '{vehicles:vehicles.npsauv2.5->40m.settling_over_time_optimal_bound:.2f}', '<= 1.5'),
    ('foreign plants (plane force x0.5, moment x0.6, no Munk moment, trim 9 deg off, thrust '
     'held, cold start, learning off): settling over the plant\'s own bound, worst of 20 -> 10 '
     '/ 10 -> 30 / 5 -> 40 m on the three vehicles; pitch past the limit, worst case of the '
     'foreign plants and the held-thrust family',
     '{foreign_plants:worst_settling_over_bound_without_learning:.2f}; '
     '{foreign_plants:worst_over_limit_deg:.2f} deg', '<= 1.3; <= 1 deg'),
    ('the same plants with learning on (`learn: true`): worst settling over the bound; the A18M '
     'plant\'s first climb 20 -> 10 m over its fifth (ten alternating changes)',
     '{foreign_plants:worst_settling_over_bound:.2f}; '
     '{foreign_plants:sequence.a18m.first_over_ninth:.2f}', '<= 1.3; 1.0'),
    ('the file\'s own REMUS 100 and A18M on realistic sensor noise (2 cm, 0.1 deg, 1 cm/s, 0.1 '
     'deg/s), 10 -> 20 and 20 -> 10 m, six seeds each: slowest settling and largest depth error '
     'over the last 30 s, learning off / on (nothing to learn)',
     '{noisy_learning:worst.without_learning.settling_s:.1f} / '
     '{noisy_learning:worst.learning.settling_s:.1f} s; '
     '{noisy_learning:worst.without_learning.hold_error_m:.2f} / '
     '{noisy_learning:worst.learning.hold_error_m:.2f} m', 'no target'),
    ('time-optimal settling bound, 8 changes of the three vehicles: largest move when the speed '
     'or every coefficient changes in its twelfth digit',
     '{bound:largest_spread_s:.3f} s', '< 0.1 s'),
    ('gap honesty panel: right effect in the catalogue (else not `explained`); model '
     'coefficients named; out-of-catalogue cases wrongly `explained`; false alarms on clean '
     'logs; median held-out shrink (in the catalogue); true values inside their 95 % intervals',
     '{gap_honest:panel.inside_right}; {gap_honest:panel.coefficients_right}; '
     '{gap_honest:panel.outside_wrongly_explained} of {gap_honest:panel.outside_cases}; '
     '{gap_honest:panel.clean_false_alarms} of {gap_honest:panel.clean_cases}; '
     '{gap_honest:panel.median_shrink_inside:.2f}; {gap_honest:panel.truth_in_ci95}',
     '0 wrong'),
    ('gap effect panel, one 15-minute log per file of `config/effects` (and a clean log, two '
     'effects at once): cases judged right',
     '{gap_panel:passed} of {gap_panel:total}', 'all'),
    ('gap: 95 % interval coverage over noise seeds, every effect of the catalogue fitted alone '
     'on 5-minute closed-loop logs: effects, seeds each; parameters identified in at least '
     'half the seeds: lowest (which) and median coverage among the seeds that identify them; '
     'parameters significantly below 0.95 (Wilson)',
     '{gap_coverage:summary.effects}, {gap_coverage:summary.min_seeds}; '
     '{gap_coverage:summary.parameters_identified}: '
     '{gap_coverage:summary.lowest_coverage:.2f} ({gap_coverage:summary.lowest_parameter}) '
     'and {gap_coverage:summary.median_coverage:.2f}; '
     '{gap_coverage:summary.significantly_low_count}',
     '0.95'),
    ('campaign of 40 simulated missions: buoyancy drift found; plane bias step found at its '
     'mission',
     '{campaign:gap_campaign.found.buoyancy_offset.dB.verdict} '
     '({campaign:gap_campaign.found.buoyancy_offset.dB.slope_per_day:.2f} N/day, true 2.31); '
     '{campaign:gap_campaign.found.bar_bias.bias.verdict} at '
     '{campaign:gap_campaign.found.bar_bias.bias.step_mission} (true mission_020)', ''),
    ('campaign: speed-up with 2 workers over 1; overhead per task; peak memory per worker',
     '{campaign:gap_campaign.speed_up_2_workers:.2f}; '
     '{campaign:gap_campaign.overhead_per_task_s:.4f} s; '
     '{campaign:gap_campaign.worker_peak_rss_mb:.0f} MB', ''),
    ('Monte Carlo through Dask over the bare runs, same run: per CPU second / wall clock',
     '{campaign:montecarlo.engine_1_worker_over_bare_per_cpu_s:.2f} / '
     '{campaign:montecarlo.engine_1_worker_over_bare:.2f}', '>= 0.8'),
    ('pilot on plants that are not its design model, Monte Carlo (all errors at once, '
     'coefficients x U(0.7, 1.3)): plants; settled within 2x the bound; tumbled; pitch limit '
     'exceeded by > 2 deg; worst steady depth error',
     '{robustness:monte_carlo.all.plants}; '
     '{robustness:monte_carlo.all.share_settled_within_2x_bound:.1%}; '
     '{robustness:monte_carlo.all.share_tumbled:.1%}; '
     '{robustness:monte_carlo.all.share_pitch_limit_exceeded_by_more_than_2deg:.2%}; '
     '{robustness:monte_carlo.all.worst_steady_error_m:.1f} m',
     '1000; >= 99 %; 0; 0; < 0.1 m'),
    ('the same plants with the pilot learning its plant (`learn: true`, '
     '`--learn`): settled within 2x the bound; pitch limit exceeded by > 2 deg; worst steady '
     'depth error',
     '{robustness:monte_carlo_learning.all.share_settled_within_2x_bound:.1%}; '
     '{robustness:monte_carlo_learning.all.share_pitch_limit_exceeded_by_more_than_2deg:.2%}; '
     '{robustness:monte_carlo_learning.all.worst_steady_error_m:.1f} m',
     '>= 99 %; 0; < 0.1 m'),
    ('the same, first plants also against their own time-optimal bound (their coefficients, '
     'buoyancy and lag; no delay, bias or current: optimistic): plants; settled within 2x the '
     'design bound / 2x their own; own bound over the design\'s, median (range)',
     '{robustness:monte_carlo.own_bound.plants}; '
     '{robustness:monte_carlo.own_bound.settled_within_2x_design_bound:.1%} / '
     '{robustness:monte_carlo.own_bound.settled_within_2x_own_bound:.1%}; '
     '{robustness:monte_carlo.own_bound.own_over_design_bound.median:.2f} '
     '({robustness:monte_carlo.own_bound.own_over_design_bound.min:.2f}-'
     '{robustness:monte_carlo.own_bound.own_over_design_bound.max:.2f})',
     '>= 99 %'),
    ('the same on the identification\'s intervals (the six coefficients `auv ident '
     '--fit-planes` fits vary within the larger of their 95 % interval and the error it made '
     'on a known vehicle, as apparent values: a plant\'s CMuw carries the Munk moment of its '
     'heave added mass; Iy, Mqdot, Zwdot x U(0.7, 1.3)): spread of CMbar / CMuw / CMuq; '
     'plants; settled within 2x the bound; tumbled; pitch limit exceeded by > 2 deg; worst '
     'steady depth error',
     '+-{robustness:monte_carlo_ident.distribution.factor_spreads.CMbar:.1%} / '
     '+-{robustness:monte_carlo_ident.distribution.factor_spreads.CMuw:.1%} / '
     '+-{robustness:monte_carlo_ident.distribution.factor_spreads.CMuq:.1%}; '
     '{robustness:monte_carlo_ident.all.plants}; '
     '{robustness:monte_carlo_ident.all.share_settled_within_2x_bound:.1%}; '
     '{robustness:monte_carlo_ident.all.share_tumbled:.1%}; '
     '{robustness:monte_carlo_ident.all.share_pitch_limit_exceeded_by_more_than_2deg:.2%}; '
     '{robustness:monte_carlo_ident.all.worst_steady_error_m:.3f} m',
     'none; 1000; >= 99 %; 0; 0; < 0.1 m'),
    ('the same plants with the pilot learning its plant (`--family ident --learn`): '
     'settled within 2x the bound; pitch limit exceeded by > 2 deg; worst steady depth error',
     '{robustness:monte_carlo_ident_learning.all.share_settled_within_2x_bound:.1%}; '
     '{robustness:monte_carlo_ident_learning.all'
     '.share_pitch_limit_exceeded_by_more_than_2deg:.2%}; '
     '{robustness:monte_carlo_ident_learning.all.worst_steady_error_m:.1f} m',
     '>= 99 %; 0; < 0.1 m'),
    ('Foxglove live view, 50 Hz state: delivered share; latency p95; bridge CPU',
     '{foxglove:summary./auv/state.delivered.median:.3f}; '
     '{foxglove:summary./auv/state.latency_ms_p95.median:.1f} ms; '
     '{foxglove:summary.bridge_cpu_percent.median:.1f} % of a core', ''),
]

#: The rows the README shows (by their first cell); the rest are in docs/benchmarks.md.
KEY_ROWS = {
    'single-vehicle RK4 step (4 model evaluations)',
    '40 m -> 10 m at 2 m/s: settling to +-0.1 m',
    'lockstep graph real-time factor (3 processes; the recorder keeps every message)',
    'README recipes in lockstep (`launch --lockstep --real-time-factor 0 --record`, '
    '`--mission pitch --real-time-factor 0 --record`, the demo): messages recorded / '
    'published, lowest topic; machine as it is / two CPU-bound processes beside / another '
    'node graph and a test file beside (load average)',
    'identification, one hour of 50 Hz data: from forces / from motion',
    'gap diagnosis, 20-minute 50 Hz log',
    'REMUS 100 at 1.5 m/s, 20 -> 10 / 10 -> 30 / 5 -> 40 m: settling over the time-optimal bound',
}

_FIELD = re.compile(r'\{([a-z_0-9]+):([^:{}]+):?([^{}]*)\}')


class FigureError(Exception):
    """A figure the table names is missing from its results file."""


def _lookup(results: dict[str, Any], name: str, key: str) -> Any:
    if name not in results:
        path = RESULTS / f'{name}.json'
        if not path.is_file():
            raise FigureError(f'{path} does not exist (run: python bench/bench_{name}.py)')
        results[name] = json.loads(path.read_text())
    value: Any = results[name]
    # keys may hold dots themselves ('climb_40_10_u1.5'): take the longest key that matches
    rest = key
    while rest:
        if not isinstance(value, dict):
            raise FigureError(f'{name}.json has no {key!r}')
        match = max((k for k in value if rest == k or rest.startswith(k + '.')), key=len,
                    default=None)
        if match is None:
            raise FigureError(f'{name}.json has no {key!r}')
        value, rest = value[match], rest[len(match) + 1:]
    return value


def render(template: str, results: dict[str, Any]) -> str:
    """``template`` with each ``{name:key:format}`` replaced by the value in the results."""
    def one(m: re.Match[str]) -> str:
        value = _lookup(results, m.group(1), m.group(2))
        if value is None:
            return 'n/a'
        return format(value, m.group(3)) if m.group(3) else str(value)
    return _FIELD.sub(one, template)


def table(rows: list[tuple[str, str, str]] | None = None) -> str:
    """The block between the markers for ``rows`` (default: all), from the results files."""
    results: dict[str, Any] = {}
    lines = ['| what | figure | target |', '| --- | --- | --- |']
    lines += [f'| {what} | {render(figure, results)} | {target} |'
              for what, figure, target in (ROWS if rows is None else rows)]
    return '\n'.join([BEGIN, *lines, END])


def key_rows() -> list[tuple[str, str, str]]:
    """The rows of :data:`KEY_ROWS`, in the full table's order."""
    missing = KEY_ROWS - {what for what, _, _ in ROWS}
    if missing:
        raise FigureError(f'KEY_ROWS names rows that ROWS does not hold: {sorted(missing)}')
    return [row for row in ROWS if row[0] in KEY_ROWS]


def _block(path: pathlib.Path, text: str) -> tuple[int, int]:
    start, end = text.find(BEGIN), text.find(END)
    if start < 0 or end < start:
        raise FigureError(f'{path} has no {BEGIN} ... {END} block')
    return start, end + len(END)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--check', action='store_true',
                        help='only check that README.md and docs/benchmarks.md match the '
                             'results files')
    args = parser.parse_args(argv)
    for path, rows in ((BENCHMARKS, None), (README, 'key')):
        try:
            text = path.read_text()
            start, end = _block(path, text)
            new = table(key_rows() if rows else None)
        except FigureError as exc:
            print(f'error: {exc}', file=sys.stderr)
            return 1
        name = path.relative_to(ROOT)
        if args.check:
            old = text[start:end].splitlines()
            for a, b in zip(old, new.splitlines(), strict=False):
                if a != b:
                    print(f'error: {name} figures differ from bench/results:\n  {name}: {a}\n'
                          f'  results: {b}', file=sys.stderr)
                    return 1
            if len(old) != len(new.splitlines()):
                print(f'error: {name} figures table has a different number of rows than '
                      'tools/readme_figures.py', file=sys.stderr)
                return 1
            continue
        path.write_text(text[:start] + new + text[end:])
    return 0


if __name__ == '__main__':
    sys.exit(main())
