"""Benchmark: timing of the node graph (simulator, depth pilot, recorder as processes).

* ``lockstep``: 300 s of the 40 m -> 10 m manoeuvre in lockstep, as fast as the processes
  allow; real-time factor = simulated time / wall time between the first and the last state
  the recorder received (start-up excluded), and with start-up included. Target >= 20.
The two real-time runs fly 20 m -> 10 m, so that their 30 s hold the whole manoeuvre: the
pitch-up, the climb and the stop, whose planning is the pilot's heaviest computation.

* ``timer``: 30 s in real time on the wall clock (as on a vehicle: no /clock, no lockstep):
  the pilot publishes from its 10 Hz timer. Its publish period (median, p99 of the deviation
  from 0.1 s) from the DDS source stamps the recorder writes as MCAP publish times: when the
  pilot called ``publish``. Target: p99 jitter < 2 ms. Reported beside it, the same period as
  received by the recorder (DDS receive stamps), which adds the delivery delay's jitter.
* ``timer_realtime``: the same with the pilot on ``SCHED_FIFO`` (``realtime_priority`` 50, as
  on a vehicle), measured after the ``timer`` run; ``null`` figures with the reason when the
  machine does not allow it.
* ``latency``: 30 s in real time with lockstep: for each control instant, the time from the
  recorder's receipt of the state stamped t_k to its receipt of the pilot's BAR command
  stamped t_k (state -> pilot -> BAR, both legs over DDS, measured at one process clock).
  Target: p99 < 5 ms.

* ``completeness``: each README recipe run as a user runs it (``auv launch --lockstep
  --real-time-factor 0 --depth 10 --stop-time 150 --record``, ``auv launch --mission pitch
  --real-time-factor 0 --record``, ``auv demo --skip-gap`` (its graph run), and the real-time
  ``auv launch --depth 10 --duration 30 --record``) with the machine as it is (``idle``: no
  load added), beside two CPU-bound processes (``cpu2``), and beside another node graph in
  the same DDS domain plus a CPU-bound test file run again and again (``graph_and_tests``):
  per topic the messages the nodes published (their reports) and the messages in the bag,
  the exit status and what the launcher said. Goal: 1.000 for every topic of every lockstep
  recipe under every load.
* ``startup``: from starting a plain ``auv launch`` (real time) to the first BAR command a
  subscriber receives, 5 times under each load with the start-up cache warm (the pilot's
  design and the simulator's trim of an earlier start, ``auv_sim.disk_cache``), and once
  before them with it empty (``cold_cache``: a vehicle file's first start). Goal: < 3 s.
  Beside it, from the pilot's report, when the pilot published its first command (to the
  simulator, whose subscription it waits for): ``published_seconds``. The subscriber, in
  this process and listening since before the start, is matched by the new nodes only at its
  own participant's next periodic DDS announcement, which adds up to a few seconds to
  ``seconds`` whatever the graph does.
* ``join``: from starting ``auv depth Z`` (a new process, hence a new DDS participant, with
  Fast DDS's own settings, as a user's script has them) to its exit on the pilot's answer,
  against a plain ``auv launch`` running in real time, ``repeats`` times, with the graph's
  nodes on the toolkit's profile (``config/dds/fastdds.xml``: participants announce
  themselves every 0.5 s) and side by side on Fast DDS's defaults (every 3 s), alternating.
  A joining participant finds one that was there before it either at once or only at that
  one's next periodic announcement.

Each section records the load average when it ran (the machine is shared: "idle" is the
machine with nothing added by the benchmark). Run: ``. .venv/bin/auv-env && python
bench/bench_graph.py [--only timing completeness startup]`` (writes bench/results/graph.json;
with ``--only`` the other sections of the file are kept).
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import pathlib
import signal
import subprocess
import sys
import tempfile
import threading
import time
from typing import Any

import numpy as np
from timing import save_figures

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _fly(tmp: pathlib.Path, name: str, lockstep: bool, rtf: float, stop_time: float,
         env: dict[str, str], sim_clock: bool = True, z0: float = 40.0, priority: int = 0,
         ) -> tuple[dict[str, np.ndarray], float]:
    from auv_bag import read_arrays
    from auv_bringup.launch import GraphConfig, run_graph

    bag = tmp / name
    cfg = GraphConfig(vehicle=str(ROOT / 'config' / 'a18m.yaml'), lockstep=lockstep,
                      real_time_factor=rtf, initial_depth=z0, stop_time=stop_time,
                      record=str(bag), log_dir=str(tmp / f'{name}_logs'), depth_command=10.0,
                      sim_clock=sim_clock, realtime_priority=priority)
    wall = time.monotonic()
    codes = run_graph(cfg, duration=stop_time / max(rtf, 1.0) + 300.0, env=env)
    wall = time.monotonic() - wall
    if codes.get('simulator') not in (0, -2, 130):
        raise RuntimeError(f'graph run {name} failed: {codes}')
    return read_arrays(bag, ['/auv/state', '/auv/bar_command']), wall


def _publish_times(bag: pathlib.Path, topic: str) -> np.ndarray:
    """MCAP publish times (s) of ``topic`` in ``bag``: the DDS source stamps the recorder wrote."""
    from mcap.reader import make_reader

    times = []
    for file in sorted(bag.glob('*.mcap')):
        with open(file, 'rb') as fh:
            times += [m.publish_time for _, _, m in make_reader(fh).iter_messages(topics=[topic])]
    return np.array(times, dtype=np.int64) / 1e9


def _period_figures(times: np.ndarray, period: float = 0.1) -> dict[str, float]:
    """Median period and the median, p99 and largest deviation from ``period`` (ms), after
    the first ten periods (start-up)."""
    periods = np.diff(np.asarray(times))[10:]
    dev = np.abs(periods - period)
    return {'period_median_ms': float(1e3 * np.median(periods)),
            'jitter_median_ms': float(1e3 * np.median(dev)),
            'jitter_p99_ms': float(1e3 * np.percentile(dev, 99)),
            'jitter_max_ms': float(1e3 * dev.max())}


def run_timing(env: dict[str, str], lockstep_time: float = 300.0,
               real_time: float = 30.0) -> dict[str, Any]:
    """The three timing measurements (lockstep real-time factor, publish period, latency)."""
    out: dict[str, Any] = {'targets': {'lockstep_real_time_factor_min': 20.0,
                                       'timer_p99_jitter_ms_max': 2.0,
                                       'latency_p99_ms_max': 5.0}}
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = pathlib.Path(tmp_name)
        arrays, wall = _fly(tmp, 'lockstep', True, 0.0, lockstep_time, env)
        st = arrays['/auv/state']
        span = (st['t_log'][-1] - st['t_log'][0])
        sim_span = st['t'][-1] - st['t'][0]
        out['lockstep'] = {'simulated_s': float(sim_span), 'wall_s_running': float(span),
                           'real_time_factor': float(sim_span / span),
                           'wall_s_with_startup': wall,
                           'real_time_factor_with_startup': float(sim_span / wall)}

        def timer_figures(name: str, priority: int) -> dict[str, Any]:
            arrays, _ = _fly(tmp, name, False, 1.0, real_time, env, sim_clock=False, z0=20.0,
                             priority=priority)
            log = (tmp / f'{name}_logs' / 'pilot.log').read_text()
            if priority and 'threads on SCHED_FIFO' not in log:
                return {'jitter_p99_ms': None, 'reason': log.strip()[-300:]}
            bar = arrays['/auv/bar_command']
            return {'commands': int(len(bar)),
                    **_period_figures(_publish_times(tmp / name, '/auv/bar_command')),
                    'as_received': _period_figures(bar['t_log'])}

        out['timer'] = timer_figures('timer', 0)
        out['timer_realtime'] = timer_figures('timer_rt', 50)

        arrays, _ = _fly(tmp, 'latency', True, 1.0, real_time, env, z0=20.0)
        st, bar = arrays['/auv/state'], arrays['/auv/bar_command']
        state_at = dict(zip(np.round(st['t'], 6), st['t_log']))
        lat = np.array([tl - state_at[t] for t, tl in zip(np.round(bar['t'], 6), bar['t_log'])
                        if t in state_at])[5:]
        out['latency'] = {'samples': int(len(lat)), 'median_ms': float(1e3 * np.median(lat)),
                          'p99_ms': float(1e3 * np.percentile(lat, 99)),
                          'max_ms': float(1e3 * lat.max())}
    t = out['targets']
    out['targets_met'] = {
        'lockstep_real_time_factor': out['lockstep']['real_time_factor']
        >= t['lockstep_real_time_factor_min'],
        'timer_jitter': out['timer']['jitter_p99_ms'] <= t['timer_p99_jitter_ms_max'],
        'latency': out['latency']['p99_ms'] <= t['latency_p99_ms_max']}
    out['load_average_1min'] = os.getloadavg()[0]
    return out


# -- whole recordings under load ---------------------------------------------------------------
#: The README's recipes, as ``auv`` command lines (the bag, or the demo's output, appended).
RECIPES: dict[str, list[str]] = {
    'lockstep': ['launch', '--lockstep', '--real-time-factor', '0', '--depth', '10',
                 '--stop-time', '150', '--record'],
    'mission_pitch': ['launch', '--mission', 'pitch', '--real-time-factor', '0', '--record'],
    'demo': ['demo', '--skip-gap', '--out'],
    'realtime': ['launch', '--depth', '10', '--duration', '30', '--record'],
}
LOADS = ('idle', 'cpu2', 'graph_and_tests')
#: A test-like load: CPU-bound unit tests of the model, run again and again (no DDS).
TEST_LOAD = ['-m', 'pytest', '-q', '-p', 'no:cacheprovider', 'tests/test_physics.py',
             'tests/test_trim.py']


class Load:
    """What runs beside the measured graph (``idle``: nothing more than the machine's own
    jobs; ``cpu2``: two CPU-bound processes; ``graph_and_tests``: another node graph in the
    same DDS domain, a lockstep run as fast as possible in namespace ``loadgraph``, restarted
    as it ends, and a CPU-bound test file run again and again). Processes are started here,
    each in its own session, and ended by their process group id."""

    def __init__(self, kind: str, env: dict[str, str], tmp: pathlib.Path) -> None:
        self.kind, self.env, self.tmp = kind, env, tmp
        self._procs: list[subprocess.Popen[bytes]] = []
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []

    def _spawn(self, argv: list[str]) -> subprocess.Popen[bytes]:
        proc = subprocess.Popen(argv, env=self.env, cwd=ROOT, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL, start_new_session=True)
        self._procs.append(proc)
        return proc

    def _again(self, argv: list[str]) -> None:
        while not self._stop.is_set():
            proc = self._spawn(argv)
            while proc.poll() is None and not self._stop.is_set():
                time.sleep(0.2)

    def __enter__(self) -> Load:
        py = sys.executable
        if self.kind == 'cpu2':
            for _ in range(2):
                self._spawn([py, '-c', 'while True: pass'])
        elif self.kind == 'graph_and_tests':
            graph = [py, '-m', 'auv_bringup.cli', 'launch', '--namespace', 'loadgraph',
                     '--lockstep', '--real-time-factor', '0', '--depth', '20',
                     '--stop-time', '600', '--log-dir', str(self.tmp / 'loadgraph')]
            for argv in (graph, [py, *TEST_LOAD]):
                thread = threading.Thread(target=self._again, args=(argv,), daemon=True)
                thread.start()
                self._threads.append(thread)
        time.sleep(3.0)  # the load running before the measurement starts
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        for thread in self._threads:
            thread.join(30)
        for proc in self._procs:
            if proc.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.pid, signal.SIGINT)
        for proc in self._procs:
            try:
                proc.wait(30)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(10)


def _recipe(name: str, env: dict[str, str], tmp: pathlib.Path) -> dict[str, Any]:
    """Run one README recipe as a user does; what each node published against what the bag
    holds, per topic."""
    from auv_bringup.launch import GraphConfig, recorded_topics
    from auv_bringup.recording_check import check_recording
    from auv_sim.node_report import read_report

    out = tmp / name
    if name == 'demo':
        bag, logs = out / 'graph_bag', out / 'logs'
    else:
        bag, logs = out, tmp / f'{name}.logs'
    argv = [sys.executable, '-m', 'auv_bringup.cli', *RECIPES[name], str(out)]
    load = os.getloadavg()[0]
    wall = time.monotonic()
    res = subprocess.run(argv, env=env, cwd=ROOT, capture_output=True, text=True, timeout=3600)
    wall = time.monotonic() - wall
    nodes = ('simulator', 'mission') if name == 'mission_pitch' else ('simulator', 'pilot')
    reports = {n: read_report(logs / f'{n}.report.json') for n in nodes}
    check = check_recording(bag, reports, recorded_topics(GraphConfig(record=str(bag))))
    sim = reports.get('simulator') or {}
    return {'exit_status': res.returncode,
            'error': res.stderr.strip().splitlines()[-1] if res.returncode else None,
            'wall_s': wall, 'load_average_1min_before': load,
            'topics': {c.topic: {'published': c.published, 'recorded': c.recorded,
                                 'ratio': c.ratio} for c in check.counts},
            'min_ratio': min((c.ratio for c in check.counts), default=0.0),
            'complete': check.complete, 'problems': check.problems,
            'lockstep_missed': sim.get('lockstep_missed'),
            'recorder_pacing_given_up': sim.get('recorder_pacing_given_up')}


def run_completeness(env: dict[str, str], loads: tuple[str, ...] = LOADS,
                     recipes: tuple[str, ...] = tuple(RECIPES)) -> dict[str, Any]:
    """Messages recorded over messages published, per topic, for each recipe and load."""
    out: dict[str, Any] = {'cpu_count': os.cpu_count(), 'recipes': {
        name: 'auv ' + ' '.join(argv) + ' OUT' for name, argv in RECIPES.items()}}
    with tempfile.TemporaryDirectory() as tmp_name:
        for kind in loads:
            tmp = pathlib.Path(tmp_name) / kind
            tmp.mkdir()
            with Load(kind, env, tmp):
                out[kind] = {name: _recipe(name, env, tmp) for name in recipes}
    lockstep = {k: [r for n, r in out[k].items() if n != 'realtime'] for k in loads}
    out['lockstep_min_ratio_by_load'] = {k: min(r['min_ratio'] for r in rs)
                                         for k, rs in lockstep.items()}
    out['lockstep_min_ratio'] = min(out['lockstep_min_ratio_by_load'].values())
    out['lockstep_all_whole'] = all(r['complete'] and r['exit_status'] == 0
                                    for rs in lockstep.values() for r in rs)
    out['realtime_min_ratio_by_load'] = {k: out[k]['realtime']['min_ratio'] for k in loads
                                         if 'realtime' in out[k]}
    out['goal'] = 'recorded / published = 1.000, every topic of every lockstep recipe and load'
    out['goal_met'] = out['lockstep_all_whole'] and out['lockstep_min_ratio'] == 1.0
    return out


# -- start to first plane command --------------------------------------------------------------
def _cpu_seconds(pid: int) -> float:
    """CPU seconds (user + system) process ``pid`` has used so far (Linux ``/proc``)."""
    fields = pathlib.Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def _node_cpu(launch_pid: int) -> dict[str, float]:
    """CPU seconds used so far by the launcher and each node it started (by module name)."""
    out = {'launcher': _cpu_seconds(launch_pid)}
    for stat in pathlib.Path('/proc').glob('[0-9]*/stat'):
        try:
            ppid = int(stat.read_text().rsplit(')', 1)[1].split()[1])
            if ppid != launch_pid:
                continue
            cmd = (stat.parent / 'cmdline').read_bytes().split(b'\0')
            name = next((c.decode() for c in cmd if c.startswith(b'auv_')), '?')
            out[name] = _cpu_seconds(int(stat.parent.name))
        except (OSError, ValueError, IndexError):
            continue
    return out


def _first_command(env: dict[str, str], tmp: pathlib.Path,
                   i: int) -> tuple[float | None, dict[str, float], float | None]:
    """Wall s from starting a plain ``auv launch`` (real time) to the first BAR command a
    subscriber that was listening before receives (None if none within 60 s), the CPU
    seconds the launcher and each node had used by then, and the wall s to when the pilot
    published its first command (its report's ``first_command_time``; None without one)."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions

    from auv_msgs.msg import ActuatorSetpoint
    from auv_sim.node_report import read_report

    context = Context()
    rclpy.init(context=context, domain_id=int(env['ROS_DOMAIN_ID']),
               signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = rclpy.create_node('first_command_probe', context=context)
        got: list[float] = []
        node.create_subscription(ActuatorSetpoint, '/auv/bar_command',
                                 lambda _m: got.append(time.monotonic()),
                                 QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        end = time.monotonic() + 1.0
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
        start, start_epoch = time.monotonic(), time.time()
        launch = subprocess.Popen([sys.executable, '-m', 'auv_bringup.cli', 'launch',
                                   '--log-dir', str(tmp / f'startup{i}')], env=env, cwd=ROOT,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        while not got and time.monotonic() - start < 60.0:
            executor.spin_once(timeout_sec=0.01)
        cpu = _node_cpu(launch.pid)
        launch.send_signal(signal.SIGINT)
        launch.wait(60)
        executor.shutdown()
        node.destroy_node()
        report = read_report(tmp / f'startup{i}' / 'pilot.report.json') or {}
        published = report.get('first_command_time')
        return (got[0] - start if got else None), cpu, \
            (published - start_epoch if isinstance(published, float) else None)
    finally:
        context.try_shutdown()


PROCESSES = (('launcher', 'launcher'), ('pilot', 'auv_depth_lqr.node'),
             ('simulator', 'auv_sim.node'))
"""Name in the results -> key of :func:`_node_cpu` of the processes of a start."""


def run_startup(env: dict[str, str], loads: tuple[str, ...] = LOADS,
                repeats: int = 5) -> dict[str, Any]:
    """Start-to-first-plane-command of a plain ``auv launch``, ``repeats`` times per load
    with the start-up cache warm (``auv_sim.disk_cache``: the pilot's design and the
    simulator's trim kept from an earlier start, as on every start but the first with a
    vehicle file), after one start with an empty cache (``cold``, reported apart)."""
    out: dict[str, Any] = {'goal_s': 3.0}
    with tempfile.TemporaryDirectory() as tmp_name:
        for kind in loads:
            tmp = pathlib.Path(tmp_name) / kind
            tmp.mkdir()
            cache_env = dict(env, AUV_CACHE_DIR=str(tmp / 'cache'))  # empty: its own
            with Load(kind, env, tmp):
                load = os.getloadavg()[0]
                cold = _first_command(cache_env, tmp, repeats)
                runs = [_first_command(cache_env, tmp, i) for i in range(repeats)]
            times = [t for t, _, _ in runs]
            ok = [t for t in times if t is not None]
            published = [p for _, _, p in runs]
            ok_published = [p for p in published if p is not None]
            cpu = {name: float(np.median([c.get(module, np.nan) for _, c, _ in runs]))
                   for name, module in PROCESSES}
            out[kind] = {'seconds': times, 'median_s': float(np.median(ok)) if ok else None,
                         'max_s': max(ok) if ok else None,
                         # when the pilot published it (to the simulator, whose subscription
                         # it waits for): the probe above, listening since before the start,
                         # is matched by a new node only at its own participant's next
                         # periodic DDS announcement (Fast DDS: every 3 s)
                         'published_seconds': published,
                         'published_median_s': float(np.median(ok_published))
                         if ok_published else None,
                         'load_average_1min_before': load,
                         # CPU s each process used before the first command (median): what
                         # the start costs whatever the load; on two idle cores the pilot and
                         # the simulator start side by side after the launcher's checks
                         'cpu_s_before_first_command': cpu,
                         'cpu_s_critical_path': cpu['launcher'] + max(cpu['pilot'],
                                                                      cpu['simulator']),
                         # the first start of a vehicle file: the design and trim computed
                         'cold_cache': {'seconds': cold[0], 'published_seconds': cold[2],
                                        'cpu_s_before_first_command': {
                             name: cold[1].get(module) for name, module in PROCESSES}}}
    out['goal_met'] = all(out[k]['median_s'] is not None and out[k]['median_s'] < 3.0
                          for k in loads)
    out['published_goal_met'] = all(out[k]['published_median_s'] is not None
                                    and out[k]['published_median_s'] < 3.0 for k in loads)
    return out


FAST_DDS_DEFAULTS = '<?xml version="1.0"?><dds xmlns="http://www.eprosima.com"><profiles/></dds>'
"""A profile file that changes nothing: Fast DDS's own settings."""


def _join_times(env: dict[str, str], log_dir: pathlib.Path, profile: pathlib.Path,
                defaults: pathlib.Path, repeats: int) -> list[float | None]:
    """Wall s of each of ``repeats`` ``auv depth`` commands on Fast DDS's own settings
    (``defaults``), None for one not answered, against a running ``auv launch`` whose nodes
    use the profile file ``profile``."""
    py = sys.executable
    joiner = dict(env, FASTDDS_DEFAULT_PROFILES_FILE=str(defaults))
    launch = subprocess.Popen(
        [py, '-m', 'auv_bringup.cli', 'launch', '--log-dir', str(log_dir)],
        env=dict(env, FASTDDS_DEFAULT_PROFILES_FILE=str(profile)), cwd=ROOT,
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        depth = [py, '-m', 'auv_bringup.cli', 'depth', '--timeout', '30']
        # the graph up and answering before the first measured command
        subprocess.run([*depth, '10'], env=joiner, cwd=ROOT, capture_output=True, timeout=90)
        times: list[float | None] = []
        for i in range(repeats):
            start = time.monotonic()
            done = subprocess.run([*depth, str(11.0 + i % 5)], env=joiner, cwd=ROOT,
                                  capture_output=True, timeout=60)
            times.append(time.monotonic() - start if done.returncode == 0 else None)
        return times
    finally:
        os.killpg(launch.pid, signal.SIGINT)
        launch.wait(60)


def run_join(env: dict[str, str], repeats: int = 10, rounds: int = 2) -> dict[str, Any]:
    """``auv depth`` against a running graph whose nodes use the toolkit's Fast DDS profile
    and, side by side, Fast DDS's defaults: ``rounds`` alternating rounds of ``repeats``."""
    from auv_contract.dds import dds_profile

    toolkit = dds_profile()
    if toolkit is None:
        raise SystemExit('error: the toolkit\'s configuration is not found (source '
                         '.venv/bin/auv-env)')
    load = os.getloadavg()[0]
    times: dict[str, list[float | None]] = {'toolkit_profile': [], 'fast_dds_defaults': []}
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = pathlib.Path(tmp_name)
        defaults = tmp / 'fastdds_defaults.xml'
        defaults.write_text(FAST_DDS_DEFAULTS)
        profiles = {'toolkit_profile': pathlib.Path(toolkit), 'fast_dds_defaults': defaults}
        for k in range(rounds):
            for name, profile in profiles.items():
                times[name] += _join_times(env, tmp / f'{name}{k}', profile, defaults,
                                           repeats)
    out: dict[str, Any] = {'load_average_1min_before': load}
    for name, values in times.items():
        ok = [t for t in values if t is not None]
        out[name] = {'seconds': values,
                     'median_s': float(np.median(ok)) if ok else None,
                     'max_s': max(ok) if ok else None,
                     'over_1_5_s': sum(t > 1.5 for t in ok),
                     'unanswered': len(values) - len(ok)}
    return out


def _env() -> tuple[dict[str, str], Any]:
    """The environment of the measured graphs: a DDS domain id reserved as the tests reserve
    theirs (tests/conftest.py), localhost discovery."""
    sys.path.insert(0, str(ROOT / 'tests'))
    from conftest import reserve_domain_id

    reservation = reserve_domain_id()
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'  # this process's probes too
    env = dict(os.environ, ROS_DOMAIN_ID=str(reservation.domain_id))
    return env, reservation


SECTIONS = ('timing', 'completeness', 'startup', 'join')


def run(sections: tuple[str, ...] = SECTIONS) -> dict[str, Any]:
    """The graph's figures (each section with the machine's load when it ran)."""
    env, reservation = _env()
    try:
        out: dict[str, Any] = {}
        if 'timing' in sections:
            out.update(run_timing(env))
        if 'completeness' in sections:
            out['completeness'] = run_completeness(env)
        if 'startup' in sections:
            out['startup'] = run_startup(env)
        if 'join' in sections:
            out['join'] = run_join(env)
        return out
    finally:
        reservation.release()


if __name__ == '__main__':
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--only', nargs='+', choices=SECTIONS, default=list(SECTIONS),
                        help='run these sections and keep the others of the results file')
    args = parser.parse_args()
    figures = run(tuple(args.only))
    path = ROOT / 'bench' / 'results' / 'graph.json'
    if set(args.only) != set(SECTIONS) and path.is_file():
        figures = {**json.loads(path.read_text()), **figures}
    save_figures('graph', figures)
    print(json.dumps(figures, indent=2))
