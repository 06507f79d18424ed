"""``auv campaign``: gap and ident campaigns over simulated missions on a real local Dask
cluster, the cache, failed missions, a worker killed mid-task, an unreachable scheduler, and
the closed-loop Monte Carlo against the same runs made without the engine.

The missions are short (200 s) simulated logs whose true effects are known: the estimates are
checked against the simulator's truth, not against numbers of the code under test."""
from __future__ import annotations

import json
import os
import pathlib
import socket
import subprocess
import sys
import time
from collections.abc import Mapping
from typing import Any

import numpy as np
import pytest
from conftest import A18M

from auv_campaign import engine, inputs, report
from auv_campaign.errors import CampaignError
from auv_campaign.montecarlo import Draw, run_chunk
from auv_campaign.runner import run_missions
from auv_campaign.synthetic import write_campaign
from auv_campaign.tasks import run_mission
from auv_sim.params import load_vehicle

N_MISSIONS = 4
BIAS_FROM = 2
BIAS = 0.04          # rad
DURATION = 200.0     # s per mission


def _effects(i: int) -> dict[str, dict[str, float]]:
    eff = {'buoyancy_offset': {'dB': 10.0 + 10.0 * i}}
    if i >= BIAS_FROM:
        eff['bar_bias'] = {'bias': BIAS}
    return eff


def _auv(*args: str, timeout: float = 600.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, '-m', 'auv_bringup.cli', *args],
                          capture_output=True, text=True, timeout=timeout, check=False)


@pytest.fixture(scope='module')
def logs(tmp_path_factory: pytest.TempPathFactory) -> tuple[pathlib.Path, list[Any]]:
    d = tmp_path_factory.mktemp('campaign_logs')
    missions = write_campaign(d, load_vehicle(A18M), N_MISSIONS, _effects, duration=DURATION)
    (d / 'broken.mcap').write_bytes(b'this is not a bag')
    return d, missions


def _inside(q: Mapping[str, Any], truth: float) -> bool:
    """The quantity ``q``'s 95 % interval holds ``truth``; or, not identified (a parameter
    whose fitted value did not predict the held-out equation samples is left at its absent
    value, without an interval), its value is exactly ``truth``: only an absent truth."""
    if q['ci95'] is None:
        return not q['identified'] and q['value'] == truth
    lo, hi = q['ci95']
    return bool(lo <= truth <= hi)


def test_gap_campaign_report_cache_and_failed_mission(logs: tuple[pathlib.Path, list[Any]],
                                                      tmp_path: pathlib.Path) -> None:
    d, missions = logs
    out = tmp_path / 'out'
    proc = _auv('campaign', 'gap', str(d), '--vehicle', str(A18M), '--out', str(out),
                '--workers', '2', '--options=--no-plots')
    assert proc.returncode == 0, proc.stderr
    progress = [ln for ln in proc.stderr.splitlines() if ln.startswith('[')]
    assert len(progress) >= N_MISSIONS + 1       # one line per task, both passes
    doc = json.loads((out / 'campaign.json').read_text())
    assert doc['counts']['missions'] == N_MISSIONS + 1
    assert doc['counts']['failed'] == 1
    (failed,) = doc['failed']
    assert failed['name'] == 'broken' and 'MCAP' in failed['reason']
    ok = [m for m in doc['missions'] if m['status'] == 'ok']
    # mission time = the log time written into the bag; ordered by it
    assert [m['start_time'] for m in ok] == pytest.approx([m.start_s for m in missions])
    for m in ok:
        assert m['duration_s'] == pytest.approx(DURATION, abs=0.05)
        assert (out / m['report']).is_file()
    # the joint second pass: every mission has both quantities, intervals hold the truth
    # The joint pass refits every effect a mission named; a mission may be `ambiguous` and
    # name an alternative the truth lacks (at one speed a cg offset pitches the vehicle like a
    # plane bias): the true effects hold the truth, any other its absent value 0, everywhere.
    assert doc['series_from'] == 'refit'
    assert {'bar_bias', 'buoyancy_offset'} <= set(doc['effect_set'])
    for m, truth in zip(doc['refit'], missions):
        q = m['quantities']
        assert _inside(q['buoyancy_offset.dB'], truth.effects['buoyancy_offset']['dB'])
        assert _inside(q['bar_bias.bias'], truth.effects.get('bar_bias', {}).get('bias', 0.0))
        for key, quantity in q.items():
            if key.split('.')[0] not in ('bar_bias', 'buoyancy_offset'):
                assert _inside(quantity, 0.0), (m['name'], key, quantity)
    assert {'bar_bias.bias', 'buoyancy_offset.dB'} <= set(doc['trends'])
    assert (out / 'plots' / 'bar_bias.bias.png').stat().st_size > 1000
    md = (out / 'campaign.md').read_text()
    assert '| broken |' in md and 'mission_003' in md and '| joint fit [95 % interval] |' in md
    # again: every mission from the cache, same numbers
    proc = _auv('campaign', 'gap', str(d), '--vehicle', str(A18M), '--out', str(out),
                '--workers', '1', '--options=--no-plots')
    assert proc.returncode == 0, proc.stderr
    again = json.loads((out / 'campaign.json').read_text())
    assert again['counts']['cached'] == N_MISSIONS
    assert [m['quantities'] for m in again['refit'] if m['status'] == 'ok'] == \
        [m['quantities'] for m in doc['refit'] if m['status'] == 'ok']


def _quick_gap_settings(out: pathlib.Path) -> dict[str, Any]:
    """Task settings of a fast diagnosis (one effect tried, no plots, no cache)."""
    return {'model': str(A18M), 'options': ['--no-plots', '--effects', 'buoyancy_offset',
                                            '--top', '1'],
            'out': str(out), 'cache': None, 'key_settings': {}}


def _kill_worker_once(kind: str, name: str, log: str, settings: Mapping[str, Any]
                      ) -> dict[str, Any]:
    """The campaign task, but the first task to start kills its own worker process."""
    marker = pathlib.Path(settings['out']) / 'killed'
    if not marker.exists():
        marker.write_text(name)
        os._exit(9)
    return run_mission(kind, name, log, settings)


def test_worker_killed_mid_task_is_rerun_and_reported(logs: tuple[pathlib.Path, list[Any]],
                                                      tmp_path: pathlib.Path) -> None:
    _, missions = logs
    settings = _quick_gap_settings(tmp_path)
    chosen = [('mission_000', str(missions[0].path)), ('mission_001', str(missions[1].path))]
    with engine.client(workers=1) as c:
        records = run_missions(c, 'gap', chosen, settings, task=_kill_worker_once)
    assert [r['status'] for r in records] == ['ok', 'ok']
    killed = (tmp_path / 'killed').read_text()
    # the task that killed its worker was run again; a task queued on that worker may count
    # the death too (it was held there), never more than once
    deaths = {r['name']: r['worker_deaths'] for r in records}
    assert deaths[killed] == 1 and max(deaths.values()) == 1
    for r, truth in zip(records, missions):
        assert _inside(r['quantities']['buoyancy_offset.dB'],
                       truth.effects['buoyancy_offset']['dB'])
    doc = report.write(tmp_path / 'report', 'gap', records, {'out': str(tmp_path)},
                       plots=False)
    assert killed in [r['name'] for r in doc['rerun']]
    md = (tmp_path / 'report' / 'campaign.md').read_text()
    assert '## Tasks run again' in md and f'| {killed} | 1 |' in md


def _fault_once(kind: str, name: str, log: str, settings: Mapping[str, Any]) -> dict[str, Any]:
    """The campaign task, but its first attempt fails with a fault (not a rejected log)."""
    marker = pathlib.Path(settings['out']) / f'fault-{name}'
    if not marker.exists():
        marker.write_text('1')
        raise RuntimeError('transient fault')
    return run_mission(kind, name, log, settings)


def test_task_that_raises_is_retried_and_reported(logs: tuple[pathlib.Path, list[Any]],
                                                  tmp_path: pathlib.Path) -> None:
    _, missions = logs
    settings = _quick_gap_settings(tmp_path)
    chosen = [('mission_001', str(missions[1].path))]
    with engine.client(workers=1) as c:
        (ok,) = run_missions(c, 'gap', chosen, settings, task=_fault_once, retries=2)
        (failed,) = run_missions(c, 'gap', [('mission_002', str(missions[2].path))],
                                 settings, task=_fault_once, retries=0, label='-again')
    assert ok['status'] == 'ok' and ok['retries'] == 1 and ok['worker_deaths'] == 0
    assert _inside(ok['quantities']['buoyancy_offset.dB'], 20.0)
    # no retry left: a failed mission with the fault as its reason, the campaign goes on
    assert failed['status'] == 'failed'
    assert failed['reason'] == 'RuntimeError: transient fault'


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return int(s.getsockname()[1])


def test_unreachable_scheduler_is_one_line_error(tmp_path: pathlib.Path) -> None:
    port = _free_port()
    t0 = time.monotonic()
    with pytest.raises(CampaignError, match=f'no Dask scheduler answers at tcp://127.0.0.1:'
                                            f'{port} within 2 s'), \
            engine.client(scheduler=f'tcp://127.0.0.1:{port}', timeout=2.0):
        pass
    assert time.monotonic() - t0 < 30.0   # a deadline, not a benchmark
    proc = _auv('campaign', 'montecarlo', '--out', str(tmp_path), '--runs', '2',
                '--scheduler', f'tcp://127.0.0.1:{port}', '--timeout', '2', timeout=120)
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('error: no Dask scheduler answers')


def test_bad_input_is_one_line_error(tmp_path: pathlib.Path) -> None:
    proc = _auv('campaign', 'gap', str(tmp_path / 'nothing*.mcap'), '--vehicle', str(A18M),
                '--out', str(tmp_path / 'o'), timeout=120)
    assert proc.returncode == 1 and proc.stderr.strip() == \
        f"error: no log matches '{tmp_path / 'nothing*.mcap'}'"
    (tmp_path / 'a.mcap').write_bytes(b'x')
    proc = _auv('campaign', 'gap', str(tmp_path / 'a.mcap'), '--vehicle', str(A18M),
                '--out', str(tmp_path / 'o'), '--options=--no-such-option', timeout=120)
    assert proc.returncode == 1
    assert proc.stderr.strip().startswith('error: --options for auv gap:')
    proc = _auv('campaign', 'montecarlo', '--out', str(tmp_path / 'o'),
                '--spread', 'NOT_A_COEFF=0.1', timeout=120)
    assert proc.returncode == 1 and 'NOT_A_COEFF' in proc.stderr


def test_inputs_lists_globs_and_bag_directories(tmp_path: pathlib.Path) -> None:
    for name in ('a.mcap', 'b.mcap'):
        (tmp_path / name).write_bytes(b'')
    bagdir = tmp_path / 'sub' / 'run7'
    bagdir.mkdir(parents=True)
    (bagdir / 'run7_0.mcap').write_bytes(b'')
    (bagdir / 'run7_1.mcap').write_bytes(b'')
    lst = tmp_path / 'logs.txt'
    lst.write_text('# the campaign\na.mcap\n\nsub/run7\n')
    assert inputs.find_logs([str(lst)]) == [tmp_path / 'a.mcap', bagdir]
    assert inputs.find_logs([str(tmp_path)]) == [tmp_path / 'a.mcap', tmp_path / 'b.mcap',
                                                 bagdir]
    assert inputs.find_logs([str(tmp_path / '*.mcap'), str(tmp_path / 'a.mcap')]) == \
        [tmp_path / 'a.mcap', tmp_path / 'b.mcap']
    assert inputs.mission_names([tmp_path / 'a.mcap', tmp_path / 'x' / 'a.mcap']) == \
        ['a', 'a-2']
    with pytest.raises(CampaignError, match='no log matches'):
        inputs.find_logs([str(tmp_path / 'missing')])


def test_montecarlo_through_engine_equals_bare_runs(tmp_path: pathlib.Path) -> None:
    args = ['--runs', '6', '--chunk', '4', '--duration', '90', '--seed', '3',
            '--spread', 'CMuq=0.2', 'CZuw=0.2', '--effect', 'buoyancy_offset.dB=-20:20',
            '--step', '5:15']
    proc = _auv('campaign', 'montecarlo', '--out', str(tmp_path), '--workers', '2', *args)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads((tmp_path / 'montecarlo.json').read_text())
    assert doc['chunks'] == 2 and doc['summary']['runs'] == 6
    draw = Draw(str(A18M), runs=6, seed=3, duration=90.0, spreads={'CMuq': 0.2, 'CZuw': 0.2},
                effects={'buoyancy_offset': {'dB': (-20.0, 20.0)}}, step=(5.0, 15.0))
    bare = run_chunk(draw, range(6))   # one chunk, in this process: same numbers
    for a, b in zip(doc['runs'], bare):
        assert a['run'] == b['run'] and a['z_target'] == b['z_target']
        assert a['factors'] == b['factors'] and a['effects'] == b['effects']
        assert a['settling_time'] == b['settling_time']
        assert a['final_error'] == b['final_error']
    # the draw is what was asked: step sizes in 5..15 m, dB in -20..20 N
    for r in bare:
        assert 5.0 <= abs(r['z_target'] - 40.0) <= 15.0
        assert -20.0 <= r['effects']['buoyancy_offset']['dB'] <= 20.0
        assert not r['tumbled'] and r['steps'] == 9000    # 90 s at dt = 0.01 s
    # the nominal pilot settles every run within the band (the slowest, run 0: CZuw x0.49,
    # CMuq x1.41, 12 N light, a 10.8 m dive, in 74 s)
    assert max(r['final_error'] for r in bare) < 0.1
    assert np.all(np.isfinite([r['settling_time'] for r in bare]))
    csv_rows = (tmp_path / 'runs.csv').read_text().splitlines()
    assert len(csv_rows) == 7 and 'factor.CMuq' in csv_rows[0]


def test_mission_time_from_summary_and_from_a_cut_bag(tmp_path: pathlib.Path) -> None:
    from auv_campaign.synthetic import short_scenario
    from auv_campaign.tasks import log_span
    from auv_gap import synth

    t0_ns = 1_700_000_000 * 10**9
    log = synth.simulate(load_vehicle(A18M), None, short_scenario(30.0), seed=1)
    synth.write_bag(tmp_path / 'a.mcap', log, t0_ns=t0_ns)
    assert log_span(tmp_path / 'a.mcap') == pytest.approx((1.7e9, 1.7e9 + 30.0))
    data = (tmp_path / 'a.mcap').read_bytes()
    (tmp_path / 'cut.mcap').write_bytes(data[:len(data) // 2])   # no summary: a crash
    start, end = log_span(tmp_path / 'cut.mcap')
    assert start == pytest.approx(1.7e9) and end is not None and 1.7e9 < end < 1.7e9 + 30.0
    (tmp_path / 'junk.mcap').write_bytes(b'junk')
    assert log_span(tmp_path / 'junk.mcap') == (None, None)


def test_ident_campaign_pitch_coefficients(logs: tuple[pathlib.Path, list[Any]],
                                           tmp_path: pathlib.Path) -> None:
    """``auv ident`` on each log of the missions without the plane bias. Their 10 N and 20 N
    of buoyancy are not in the model (``CZ0`` fixed): the heave coefficients absorb them and
    the identified model predicts the held-out flight worse than the vehicle file (the
    simulator's truth but for the buoyancy), so no vehicle file is written and nothing is
    trended. The pitch coefficients of each mission's report still hold the truth (a buoyancy
    error acts at the centre of buoyancy, the body origin, so it adds no pitch moment)."""
    _, missions = logs
    out = tmp_path / 'ident'
    proc = _auv('campaign', 'ident', str(missions[0].path), str(missions[1].path),
                '--out', str(out), '--workers', '1',
                '--options=--no-nelder-mead --equations heave pitch')
    assert proc.returncode == 0, proc.stderr
    doc = json.loads((out / 'campaign.json').read_text())
    assert doc['counts'] == {'missions': 2, 'ok': 2, 'failed': 0, 'cached': 0,
                             'rerun_tasks': 0}
    truth = load_vehicle(A18M)
    for m in doc['missions']:
        assert m['verdict'] == 'not_written' and m['quantities'] == {}, m
        report = json.loads((pathlib.Path(m['report']).parent / 'report.json').read_text())
        assert report['validation']['verdict'] == 'worse'
        assert not report['validation']['written']
        for name in ('CMuw', 'CMuq'):
            assert _inside(report['coefficients'][name], truth.values[name]), (m['name'], name)
    assert doc['trends'] == {}


def test_montecarlo_on_an_existing_scheduler(tmp_path: pathlib.Path) -> None:
    """``--scheduler``: the command runs on a cluster it did not start (here one held by this
    test process) and leaves it running."""
    with engine.client(workers=1) as c:
        address = c.scheduler.address
        proc = _auv('campaign', 'montecarlo', '--out', str(tmp_path), '--runs', '3',
                    '--chunk', '2', '--duration', '20', '--step', '2:4',
                    '--scheduler', address, timeout=300)
        assert proc.returncode == 0, proc.stderr
        assert c.submit(abs, -3, pure=False).result(timeout=60) == 3   # still serving
    doc = json.loads((tmp_path / 'montecarlo.json').read_text())
    assert doc['cluster']['scheduler'] == address and doc['cluster']['workers'] == 1
    assert doc['summary']['flown'] == 3 and doc['chunks'] == 2
