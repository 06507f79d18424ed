"""``auv launch`` says why: checks before anything starts, a node's last error line, logs kept
by default, no wait for subscribers nothing provides, one graph per namespace, and the
recording compared with what the nodes published (real processes over DDS where a graph
runs; the comparison itself on hand-made bags)."""
from __future__ import annotations

import json
import pathlib
import signal
import subprocess
import sys
import time

import pytest
from conftest import A18M

from auv_bag import BagWriter
from auv_bringup.errors import LaunchError
from auv_bringup.launch import GraphConfig, last_error_line, recorded_topics, run_graph
from auv_bringup.recording_check import check_recording

DEADLINE_S = 240.0  # wall s: a safety net for a loaded machine, not a timing check


def auv(env: dict[str, str], *args: str, cwd: pathlib.Path | None = None
        ) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, '-m', 'auv_bringup.cli', *args], env=env, cwd=cwd,
                          capture_output=True, text=True, timeout=DEADLINE_S)


# -- pure --------------------------------------------------------------------------------------
def test_last_error_line_of_a_node_log() -> None:
    log = ('[INFO] [1.0] [auv.pilot]: starting\n'
           'error: cannot read vehicle file /x.yaml: No such file or directory\n'
           '[INFO] [2.0] [auv.pilot]: bye\n')
    assert last_error_line(log) == ('error: cannot read vehicle file /x.yaml: No such file or '
                                    'directory')
    traceback = ('Traceback (most recent call last):\n  File "x.py", line 1\n'
                 'ValueError: bad value\n')
    assert last_error_line(traceback) == 'ValueError: bad value'
    assert last_error_line('[ERROR] [3.0] [auv.simulator]: diverged\n') == \
        '[ERROR] [3.0] [auv.simulator]: diverged'
    assert last_error_line('just a line\n\n') == 'just a line'
    assert last_error_line('') is None


def test_recorded_topics_follow_the_namespace() -> None:
    cfg = GraphConfig(record='bag', namespace='auv1')
    assert recorded_topics(cfg) == {
        '/auv1/state', '/auv1/odom', '/auv1/hydrodynamic_forces', '/auv1/bar_command',
        '/auv1/helm_command', '/auv1/thrust_command', '/auv1/depth_command', '/auv1/clock',
        '/auv1/diagnostics'}
    assert recorded_topics(GraphConfig(record='bag', topics=('state', '/clock'))) == {
        '/auv/state', '/clock'}
    assert recorded_topics(GraphConfig()) == set()


def _bag(path: pathlib.Path, counts: dict[str, int]) -> None:
    with BagWriter(path) as bag:
        for topic, n in counts.items():
            bag.add_topic(topic, 'std_msgs/msg/Float64')
            for i in range(n):
                bag.write(topic, b'\x00\x01\x00\x00' + bytes(8), log_time_ns=i)


def test_recording_check_counts_every_topic(tmp_path: pathlib.Path) -> None:
    _bag(tmp_path / 'whole', {'/a': 5, '/b': 3})
    reports = {'simulator': {'published': {'/a': 5, '/unrecorded': 9}},
               'pilot': {'published': {'/b': 3}}}
    whole = check_recording(tmp_path / 'whole', reports, {'/a', '/b'})
    assert whole.complete and [(c.topic, c.published, c.recorded) for c in whole.counts] == \
        [('/a', 5, 5), ('/b', 3, 3)]
    assert whole.summary().startswith('8 messages on 2 topics, every message')
    _bag(tmp_path / 'short', {'/a': 4, '/b': 3})
    short = check_recording(tmp_path / 'short', reports, {'/a', '/b'})
    assert not short.complete
    assert short.problems == ['messages missing from the bag (recorded of published): /a 4 of 5']
    assert [c.ratio for c in short.counts] == [0.8, 1.0]
    # a node that left no report: its topics are not counted, which is a problem too
    missing = check_recording(tmp_path / 'whole', {'simulator': reports['simulator'],
                                                   'pilot': None}, {'/a', '/b'})
    assert missing.problems == ['no report from the pilot (it did not exit cleanly): its '
                                'messages are not counted']
    # a bag its recorder did not close
    (tmp_path / 'whole' / 'metadata.yaml').unlink()
    open_bag = check_recording(tmp_path / 'whole', reports, {'/a', '/b'})
    assert len(open_bag.problems) == 1 and 'has no metadata.yaml' in open_bag.problems[0]


# -- before anything starts ---------------------------------------------------------------------
@pytest.mark.parametrize(('args', 'message'), [
    (['--vehicle', '/nonexistent.yaml'],
     'error: cannot read vehicle file /nonexistent.yaml: No such file or directory\n'),
    (['--effects', '/nonexistent.yaml'],
     'error: cannot read effects file /nonexistent.yaml: No such file or directory\n'),
    (['--initial-depth', '400'],
     'error: initial depth 400 m is outside the envelope [0, 300] m of '),
    (['--depth', '-5'], 'error: depth command -5 m is outside the envelope [0, 300] m of '),
    (['--depth', 'nan'], 'error: --depth must be a finite number (m), got nan\n'),
    (['--real-time-factor', '-1'], 'error: --real-time-factor must be >= 0, got -1\n'),
    (['--stop-time', 'inf'], 'error: --stop-time must be a finite number (s), got inf\n'),
    (['--mission', 'pitch', '--depth', '10'],
     'error: --mission flies without the pilot: no --depth, --no-pilot, --pilot-state or '
     '--pilot-vehicle with it\n'),
    (['--pilot-vehicle', '/nonexistent.yaml'],
     'error: cannot read vehicle file /nonexistent.yaml: No such file or directory\n'),
    (['--no-pilot', '--pilot-vehicle', str(A18M)],
     "error: --pilot-vehicle names the pilot's file: not with --no-pilot\n"),
    (['--mission', 'nope'], 'error: cannot read mission nope: No such file or directory\n'),
])
def test_bad_launch_is_one_line_before_any_node_starts(ros_env: dict[str, str],
                                                       tmp_path: pathlib.Path,
                                                       args: list[str], message: str) -> None:
    res = auv(ros_env, 'launch', '--record', str(tmp_path / 'bag'), *args, cwd=tmp_path)
    assert res.returncode == 1
    assert res.stderr.startswith(message) and res.stderr.count('\n') == 1, res.stderr
    assert not (tmp_path / 'bag').exists() and not (tmp_path / 'bag.logs').exists()


def test_record_into_an_existing_bag_is_refused(ros_env: dict[str, str],
                                                tmp_path: pathlib.Path) -> None:
    bag = tmp_path / 'bag'
    bag.mkdir()
    (bag / 'metadata.yaml').write_text('keep me\n')
    res = auv(ros_env, 'launch', '--record', str(bag), cwd=tmp_path)
    assert res.returncode == 1
    assert res.stderr == (f'error: bag {bag} exists already and is not empty: choose another '
                          '--record, or remove it\n')
    assert (bag / 'metadata.yaml').read_text() == 'keep me\n'


@pytest.mark.parametrize(('args', 'message'), [
    (['--duration', '-1'], 'error: --duration must be > 0 s, got -1\n'),
    (['--duration', 'nan'], 'error: --duration must be a finite number (s), got nan\n'),
    (['--speed', '0'], 'error: --speed must be > 0 m/s, got 0\n'),
    (['--seed', '-3'], 'error: --seed must be >= 0, got -3\n'),
])
def test_bad_run_option_is_one_line(ros_env: dict[str, str], tmp_path: pathlib.Path,
                                    args: list[str], message: str) -> None:
    res = auv(ros_env, 'run', '--depth', '10', '--out', str(tmp_path / 'r'), *args)
    assert res.returncode == 1 and res.stderr == message, res.stderr
    assert not (tmp_path / 'r').exists()


# -- graphs ------------------------------------------------------------------------------------
def test_a_node_that_dies_is_reported_with_its_last_error_line(
        ros_env: dict[str, str], tmp_path: pathlib.Path) -> None:
    cfg = GraphConfig(vehicle=str(A18M), weights='no_such_preset', lockstep=True,
                      real_time_factor=0.0, stop_time=5.0, log_dir=str(tmp_path / 'logs'))
    with pytest.raises(LaunchError) as err:
        run_graph(cfg, duration=DEADLINE_S, env=ros_env)
    text = str(err.value)
    assert text.startswith('pilot exited with status 1: error: '), text
    assert 'no_such_preset' in text and f'(log: {tmp_path / "logs" / "pilot.log"})' in text


def test_plain_lockstep_run_waits_for_no_absent_subscriber_and_keeps_its_logs(
        ros_env: dict[str, str], tmp_path: pathlib.Path) -> None:
    """The issue's 30 s stall: no recorder or viewer, so the simulator waits for the pilot
    only (no subscriber of odom or the forces is awaited) and never times out; the node logs
    go beside the bag by default."""
    res = auv(ros_env, 'launch', '--lockstep', '--real-time-factor', '0', '--depth', '10',
              '--stop-time', '5', '--log-dir', str(tmp_path / 'L'), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert f'launch: node logs in {tmp_path / "L"}' in res.stderr
    sim_log = (tmp_path / 'L' / 'simulator.log').read_text()
    waits = next(line for line in sim_log.splitlines() if 'waiting up to' in line)
    assert '/auv/odom' not in waits and 'hydrodynamic_forces' not in waits, waits
    assert 'graph ready' in sim_log and 'starting anyway' not in sim_log, sim_log
    report = json.loads((tmp_path / 'L' / 'simulator.report.json').read_text())
    assert report['lockstep_missed'] == 0 and report['published']['/auv/state'] == 251
    # recorded, without --log-dir: logs and reports beside the bag
    bag = tmp_path / 'run1'
    res = auv(ros_env, 'launch', '--lockstep', '--real-time-factor', '0', '--depth', '10',
              '--stop-time', '5', '--record', str(bag), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    logs = tmp_path / 'run1.logs'
    assert sorted(p.name for p in logs.iterdir()) == [
        'pilot.log', 'pilot.report.json', 'recorder.log', 'simulator.log',
        'simulator.report.json']
    assert (f'launch: bag {bag}: ' in res.stderr
            and 'every message the graph published: /auv/bar_command 51, ' in res.stderr
            and '/auv/state 251, /clock 251, /diagnostics ' in res.stderr), res.stderr


def test_a_second_launch_on_the_namespace_is_refused(ros_env: dict[str, str],
                                                     tmp_path: pathlib.Path) -> None:
    first = subprocess.Popen([sys.executable, '-m', 'auv_bringup.cli', 'launch', '--log-dir',
                              str(tmp_path / 'first'), '--duration', str(DEADLINE_S)],
                             env=ros_env, cwd=tmp_path, stdout=subprocess.DEVNULL,
                             stderr=subprocess.PIPE, text=True)
    try:
        sim_log = tmp_path / 'first' / 'simulator.log'
        end = time.monotonic() + DEADLINE_S
        while not (sim_log.is_file() and 'graph ready' in sim_log.read_text()):
            assert first.poll() is None and time.monotonic() < end, first.stderr
            time.sleep(0.2)
        second = auv(ros_env, 'launch', '--log-dir', str(tmp_path / 'second'), '--stop-time',
                     '1', cwd=tmp_path)
        assert second.returncode == 1
        domain = ros_env['ROS_DOMAIN_ID']
        assert second.stderr == (f'error: another auv launch (pid {first.pid}) runs a graph on '
                                 f'namespace /auv in ROS domain {domain}: stop it first, or '
                                 'give this graph its own namespace (--namespace)\n')
        assert not (tmp_path / 'second').exists()
        # another namespace is another graph
        other = auv(ros_env, 'launch', '--namespace', 'other', '--log-dir',
                    str(tmp_path / 'other'), '--stop-time', '1', cwd=tmp_path)
        assert other.returncode == 0, other.stderr
    finally:
        first.send_signal(signal.SIGINT)
        _, err = first.communicate(timeout=DEADLINE_S)
    assert first.returncode == 0, err
