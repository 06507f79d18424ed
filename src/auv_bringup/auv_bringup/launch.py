"""``auv launch``: start the node graph (simulator, depth pilot or mission, recorder) as processes.

Each node runs in its own process (``python -m <module> --ros-args -p ...``), sharing the
caller's environment (``ROS_DOMAIN_ID`` etc.). Before anything starts, what can be checked is
checked (vehicle, effects and mission files, initial depth and depth command within the
envelope, the bag directory, the Foxglove port) and the graph's namespace is locked: a second
``auv launch`` on the same namespace and ROS domain of this machine is refused, naming the
first; a graph started otherwise on the namespace is refused by the simulator, which looks for
another publisher of its ``state``. Nodes start together and wait for each other (no fixed
sleep): the simulator for its subscribers (pilot or mission, recorder, viewer), the pilot and
the mission for the subscribers of their commands, the recorder's ``state`` subscription for
the command publishers, so the recorder gets every message from the first.

Every node's output goes to ``<name>.log`` in the log directory (``--log-dir``; by default
beside the bag, ``<bag>.logs``, or ``out/logs/launch_<date-time>`` without one), printed at
start. A node that fails is reported with the last error line of its log.

The graph stops cleanly: when the simulator reaches its ``stop_time`` (or on SIGINT/SIGTERM of
``auv launch``, or ``--duration`` wall seconds), the simulator and pilot get SIGINT, then the
recorder gets SIGTERM so it closes its bag with every message it received; each stop has a
deadline, after which the process is killed and the fact reported. On Linux every node also
gets SIGTERM from the kernel when ``auv launch`` itself dies (even by SIGKILL), so no node
outlives it.

Whole recordings: each node writes at exit how many messages it published per topic
(``<name>.report.json`` in the log directory); after the run the launcher compares them with
the bag (:mod:`auv_bringup.recording_check`) and fails (exit 1), naming every topic with
messages missing, when the bag is not whole, or when a lockstep run had an instant that went
on without its answer. Missions fly in lockstep (:mod:`auv_bringup.mission_node`), so their
commands act at their simulated instants whatever the load.

Environment given to the nodes (unless the caller set it): the Fast DDS profile
``config/dds/fastdds.xml`` (reliable writers' heartbeat every 100 ms instead of 3 s: a lost
sample is repaired, and the last ones acknowledged at exit, within about 0.1 s) and
``OPENBLAS_NUM_THREADS=1`` (the nodes' matrices are small; OpenBLAS's threads cost CPU there,
most on a busy machine).

Namespaces: every node's topics are relative to its namespace, ``/auv`` by default. With
``namespace`` (``auv launch --namespace auv1``) every node of the graph runs in ``/auv1``
(``-r __ns:=/auv1``), and on simulated time its clock moves too (``-r /clock:=/auv1/clock``),
as does the pilot's ``/diagnostics`` (``/auv1/diagnostics``), so several simulated vehicles,
each with its own simulated time, share one ROS graph and each bag holds one vehicle.
"""
from __future__ import annotations

import argparse
import contextlib
import ctypes
import dataclasses
import fcntl
import os
import pathlib
import re
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence

from auv_bringup.errors import LaunchError
from auv_bringup.options import check_number
from auv_bringup.topics import DEFAULT_TOPICS
from auv_contract import config_path, topic_basename
from auv_contract.blas import use_one_blas_thread
from auv_contract.dds import use_dds_profile

STOP_DEADLINE = 10.0  # s a node gets to exit after its signal
PR_SET_PDEATHSIG = 1  # prctl(2) option: signal sent to this process when its parent dies
#: Wall s a launched node waits for its subscribers or its controller at start: long, since on
#: a loaded machine a node's start-up alone takes tens of seconds; each wait ends as soon as
#: what it waits for is there.
STARTUP_TIMEOUT = 60.0
#: Wall s a launched lockstep simulator waits for a control instant's answer before it goes on
#: without it (then the run is not deterministic, and the launcher says so).
LOCKSTEP_TIMEOUT = 60.0
#: Wall s a launched simulator waits for a recorder that makes no progress (see auv_sim.node).
RECORDER_TIMEOUT = 120.0
LOCK_DIR = pathlib.Path(tempfile.gettempdir()) / 'auv-launch'
FOXGLOVE_APP = 'https://app.foxglove.dev/?ds=foxglove-websocket&ds.url=ws%3A%2F%2F{host}%3A{port}'
LAYOUT = config_path('foxglove', 'auv_graph_layout.json')
_ERROR_LINE = re.compile(r'^(error: |\[ERROR\]|\w+(Error|Exception)\b)')


def _die_with_parent() -> Callable[[], None] | None:
    """A ``preexec_fn`` asking the kernel to SIGTERM the child when the launching process
    dies (``prctl(PR_SET_PDEATHSIG)``, Linux); None elsewhere. The child checks its parent is
    still the launcher after the call, in case the launcher died in between. The kernel sends
    the signal when the *thread* that started the child ends: nodes are started from the main
    thread (:func:`run_graph` installs signal handlers, which only the main thread can)."""
    if not sys.platform.startswith('linux'):
        return None
    prctl = ctypes.CDLL(None, use_errno=True).prctl
    parent = os.getpid()

    def preexec() -> None:
        prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
        if os.getppid() != parent:
            os.kill(os.getpid(), signal.SIGTERM)
    return preexec


def last_error_line(text: str) -> str | None:
    """The last line of a node's output that reports an error (``error: ...``, an ``[ERROR]``
    log line, the last line of a Python traceback), else its last non-empty line; None for
    no output."""
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    for line in reversed(lines):
        if _ERROR_LINE.match(line):
            return line[:400]
    return lines[-1][:400] if lines else None


@dataclasses.dataclass
class NodeProcess:
    """One node of the graph: its name, command line, log file and running process."""

    name: str
    argv: list[str]
    log_path: pathlib.Path
    proc: subprocess.Popen[bytes] | None = None

    @property
    def report_path(self) -> pathlib.Path:
        """Where the node writes its report at exit (see :mod:`auv_sim.node_report`)."""
        return self.log_path.with_name(f'{self.name}.report.json')

    def start(self, env: dict[str, str]) -> None:
        self.report_path.unlink(missing_ok=True)  # a report from an earlier run is no report
        # the log stays open for the life of the process it receives (closed with it)
        with open(self.log_path, 'wb') as out:
            self.proc = subprocess.Popen(self.argv, env=env, stdout=out,
                                         stderr=subprocess.STDOUT, start_new_session=True,
                                         preexec_fn=_die_with_parent())

    def running(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def failure(self) -> str:
        """``NAME exited with status N: <last error line of its log> (log: PATH)``."""
        code = None if self.proc is None else self.proc.poll()
        try:
            line = last_error_line(self.log_path.read_text(errors='replace'))
        except OSError:
            line = None
        return (f'{self.name} exited with status {code}' + (f': {line}' if line else '')
                + f' (log: {self.log_path})')

    def stop(self, sig: int, deadline: float = STOP_DEADLINE) -> int | None:
        """Send ``sig``, wait up to ``deadline`` s; kill if still alive. Returns exit code."""
        if self.proc is None:
            return None
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(deadline)
            except subprocess.TimeoutExpired:
                print(f'launch: {self.name} did not stop within {deadline} s; killed',
                      file=sys.stderr)
                self.proc.kill()
                self.proc.wait(5.0)
        return self.proc.returncode


def namespace_path(namespace: str) -> str:
    """``'auv1'`` or ``'/auv1'`` -> ``'/auv1'``; ``''`` -> ``'/auv'`` (the default);
    LaunchError for a name ROS does not accept."""
    ns = '/' + namespace.strip('/') if namespace.strip('/') else '/auv'
    if not re.fullmatch(r'(/[A-Za-z][A-Za-z0-9_]*)+', ns) or '__' in ns:
        raise LaunchError(f'namespace {namespace!r} is not a valid ROS namespace (letters, '
                          'digits and _ separated by /, each part starting with a letter)')
    return ns


def remaps(cfg: GraphConfig) -> list[str]:
    """``-r`` arguments that put a node into the graph's namespace (none for the default):
    its relative topics, and the graph's clock and diagnostics."""
    if not cfg.namespace:
        return []
    ns = namespace_path(cfg.namespace)
    out = ['-r', f'__ns:={ns}', '-r', f'/diagnostics:={ns}/diagnostics']
    if cfg.sim_clock:
        out += ['-r', f'/clock:={ns}/clock']
    return out


def ros_params(**params: object) -> list[str]:
    """``--ros-args -p k:=v ...`` for the given parameters (bools lower-case)."""
    out = ['--ros-args']
    for key, value in params.items():
        if isinstance(value, bool):
            value = 'true' if value else 'false'
        out += ['-p', f'{key}:={value}']
    return out


@dataclasses.dataclass
class GraphConfig:
    """What to launch; times in seconds, depths in metres, speed in m/s."""

    vehicle: str = str(config_path('a18m.yaml'))
    effects: str = ''
    lockstep: bool = False
    real_time_factor: float = 1.0
    initial_depth: float = 40.0
    initial_speed: float = 2.0
    stop_time: float = 0.0
    pilot: bool = True
    record: str | None = None
    topics: Sequence[str] = ()
    pilot_rate: float = 10.0
    weights: str = 'default'
    water_speed: float = 0.0  # speed through the water told to the pilot [m/s]; 0: ground
    realtime_priority: int = 0  # the pilot's SCHED_FIFO priority (1-99); 0: normal scheduling
    log_dir: str | None = None  # None: beside the bag, or out/logs/launch_<date-time>
    depth_command: float | None = None  # published (and answered) before the simulator starts
    mission: str | None = None  # an open-loop mission (auv mission) instead of the pilot
    sim_clock: bool = True  # simulated time and /clock; False: every node on the wall clock
    namespace: str = ''  # the nodes' namespace ('' = /auv); with sim_clock also its own clock
    pilot_state: str = 'vehicle_state'  # the pilot's state input: vehicle_state or odometry
    foxglove: int | None = None  # serve the live topics on a Foxglove WebSocket on this port
    pilot_vehicle: str = ''  # the pilot's vehicle file when it is not the simulated one's
    pilot_learn: bool = False  # the pilot learns its plant while flying (parameter learn)

    @property
    def in_lockstep(self) -> bool:
        """Whether the simulator waits for its controller at each instant (a mission always
        does)."""
        return self.lockstep or bool(self.mission)


def default_log_dir(cfg: GraphConfig) -> pathlib.Path:
    """Where node logs go without ``--log-dir``: beside the bag (``out/run1`` ->
    ``out/run1.logs``), else ``out/logs/launch_<date-time>``."""
    if cfg.record:
        bag = pathlib.Path(cfg.record)
        return bag.with_name(bag.name.removesuffix('.mcap') + '.logs')
    return pathlib.Path(time.strftime('out/logs/launch_%Y_%m_%d-%H_%M_%S'))


def records(cfg: GraphConfig, topic: str) -> bool:
    """Whether the graph ``cfg`` records ``topic`` (given by its last name, e.g.
    ``bar_command`` or ``diagnostics``): a recorder whose ``--topics``, if given, hold it."""
    return bool(cfg.record) and (not cfg.topics or any(
        topic_basename(t) == topic for t in cfg.topics))


def records_bar(cfg: GraphConfig) -> bool:
    """Whether the graph ``cfg`` records ``bar_command``."""
    return records(cfg, 'bar_command')


def recorded_topics(cfg: GraphConfig) -> set[str]:
    """Full names of the topics the graph's recorder records (its namespace and remaps
    applied)."""
    if not cfg.record:
        return set()
    ns = namespace_path(cfg.namespace)
    out = set()
    for topic in cfg.topics or DEFAULT_TOPICS:
        if topic.startswith('/'):
            moved = cfg.namespace and (topic == '/diagnostics'
                                       or (topic == '/clock' and cfg.sim_clock))
            out.add(f'{ns}{topic}' if moved else topic)
        else:
            out.add(f'{ns}/{topic}')
    return out


def state_subscribers(cfg: GraphConfig) -> int:
    """The ``state`` subscribers of the graph ``cfg`` the simulator waits for before t = 0:
    the mission or a pilot on ``VehicleState`` (a pilot on ``nav_msgs/Odometry`` subscribes
    to ``odom`` instead), the recorder and the Foxglove bridge."""
    pilot_on_state = cfg.pilot and not cfg.mission and cfg.pilot_state == 'vehicle_state'
    return (int(bool(cfg.mission) or pilot_on_state) + int(records(cfg, 'state'))
            + int(cfg.foxglove is not None))


def stream_subscribers(cfg: GraphConfig) -> int:
    """The subscribers of ``odom``, ``hydrodynamic_forces`` and ``/clock`` the simulator waits
    for before t = 0: the recorder (when it records all three) and the Foxglove bridge. No
    wait for a subscriber nothing in the graph provides."""
    recorder = all(records(cfg, t) for t in ('odom', 'hydrodynamic_forces', 'clock'))
    return int(recorder) + int(cfg.foxglove is not None)


def odom_subscribers(cfg: GraphConfig) -> int:
    """The ``odom`` subscribers of the graph ``cfg`` the simulator waits for before t = 0: a
    pilot on ``nav_msgs/Odometry``, the recorder (when it records ``odom``) and the Foxglove
    bridge. Without the pilot's, a lockstep run could publish its first state before the
    pilot's subscription was matched: the pilot never saw it, and the simulator waited its
    ``lockstep_timeout`` for an answer that could not come."""
    pilot_on_odom = cfg.pilot and not cfg.mission and cfg.pilot_state == 'odometry'
    return (int(bool(pilot_on_odom)) + int(records(cfg, 'odom'))
            + int(cfg.foxglove is not None))


def bar_subscribers(cfg: GraphConfig) -> int:
    """The ``bar_command`` subscribers of the graph ``cfg`` the pilot waits for before its
    first command: the simulator, the recorder (unless its ``--topics`` leave the command
    out) and the Foxglove bridge."""
    return command_subscribers(cfg, 'bar_command')


def command_subscribers(cfg: GraphConfig, topic: str) -> int:
    """Subscribers of a command ``topic`` (``bar_command``, ``depth_command`` ...) in the
    graph: the simulator or pilot, the recorder if it records it, the Foxglove bridge."""
    return 1 + int(records(cfg, topic)) + int(cfg.foxglove is not None)


def graph_nodes(cfg: GraphConfig, log_dir: pathlib.Path) -> list[NodeProcess]:
    """The node processes of a graph, recorder first, logs and reports in ``log_dir``."""
    py = sys.executable

    def log(name: str) -> pathlib.Path:
        return log_dir / f'{name}.log'

    def report(name: str) -> str:
        return str(log_dir / f'{name}.report.json')

    nodes = []
    if cfg.record:
        argv = [py, '-m', 'auv_bringup.record_node', '--out', cfg.record]
        if cfg.topics:
            argv += ['--topics', *cfg.topics]
        awaited = ['bar_command', 'helm_command', 'thrust_command'] if cfg.mission else \
            ['bar_command'] if cfg.pilot else []
        awaited = [t for t in awaited if records(cfg, t)]
        if awaited:
            # the graph's command publishers matched before the simulator starts
            argv += ['--await-publishers', *awaited, '--await-timeout', str(STARTUP_TIMEOUT)]
        if cfg.namespace:
            argv += ['--ros-args', *remaps(cfg)]
        nodes.append(NodeProcess('recorder', argv, log('recorder')))
    viewer = int(cfg.foxglove is not None)
    if cfg.mission:
        subscribers = min(command_subscribers(cfg, f'{c}_command')
                          for c in ('bar', 'helm', 'thrust'))
        argv = [py, '-m', 'auv_bringup.cli', 'mission', cfg.mission, '--vehicle', cfg.vehicle,
                '--control-period', repr(1.0 / cfg.pilot_rate), '--timeout',
                str(STARTUP_TIMEOUT), '--await-subscribers', str(subscribers),
                '--report-file', report('mission')]
        if cfg.namespace:
            argv += ['--ros-args', *remaps(cfg)]
        nodes.append(NodeProcess('mission', argv, log('mission')))
    elif cfg.pilot:
        nodes.append(NodeProcess('pilot', [py, '-m', 'auv_depth_lqr.node', *ros_params(
            vehicle_file=cfg.pilot_vehicle or cfg.vehicle, lockstep=cfg.lockstep,
            rate=cfg.pilot_rate, learn=cfg.pilot_learn,
            weights=cfg.weights, water_speed=float(cfg.water_speed),
            realtime_priority=int(cfg.realtime_priority), use_sim_time=cfg.sim_clock,
            state_source=cfg.pilot_state, start_subscribers=bar_subscribers(cfg),
            diagnostics_subscribers=int(records(cfg, 'diagnostics')) + viewer,
            startup_timeout=STARTUP_TIMEOUT, report_file=report('pilot')),
            *remaps(cfg)], log('pilot')))
    if cfg.foxglove is not None:
        nodes.append(NodeProcess('foxglove', [py, '-m', 'auv_bringup.foxglove_node', '--port',
                                              str(cfg.foxglove), '--vehicle', cfg.vehicle],
                                 log('foxglove')))
    nodes.append(NodeProcess('simulator', [py, '-m', 'auv_sim.node', *ros_params(
        vehicle_file=cfg.vehicle, effects_file=cfg.effects or '""', lockstep=cfg.in_lockstep,
        lockstep_channels='bar,helm,thrust' if cfg.mission else 'bar',
        lockstep_timeout=LOCKSTEP_TIMEOUT, lockstep_startup_timeout=STARTUP_TIMEOUT,
        use_sim_clock=cfg.sim_clock,
        real_time_factor=cfg.real_time_factor, initial_depth=cfg.initial_depth,
        initial_speed=cfg.initial_speed, stop_time=cfg.stop_time,
        start_subscribers=float(state_subscribers(cfg)),
        start_stream_subscribers=float(stream_subscribers(cfg)),
        start_odom_subscribers=float(odom_subscribers(cfg)),
        await_recorder=bool(cfg.record) and cfg.real_time_factor == 0.0 and cfg.sim_clock,
        recorder_timeout=RECORDER_TIMEOUT, report_file=report('simulator'),
        control_period=1.0 / cfg.pilot_rate), *remaps(cfg)], log('simulator')))
    return nodes


@contextlib.contextmanager
def namespace_lock(env: dict[str, str], namespace: str) -> Iterator[None]:
    """Hold the graph lock of (ROS domain, namespace) on this machine for the ``with`` block;
    LaunchError naming the holder when another ``auv launch`` holds it. The kernel releases
    the lock when the holder exits, however it exits."""
    domain = env.get('ROS_DOMAIN_ID') or '0'
    ns = namespace_path(namespace)
    LOCK_DIR.mkdir(parents=True, exist_ok=True)
    path = LOCK_DIR / f'domain{domain}{ns.replace("/", "_")}.lock'
    handle = path.open('a+')
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        handle.seek(0)
        holder = handle.read().strip() or 'another process'
        handle.close()
        raise LaunchError(f'another auv launch ({holder}) runs a graph on namespace {ns} in ROS '
                          f'domain {domain}: stop it first, or give this graph its own '
                          'namespace (--namespace)') from None
    try:
        handle.truncate(0)
        handle.write(f'pid {os.getpid()}')
        handle.flush()
        yield
    finally:
        handle.close()


def check_before_start(cfg: GraphConfig) -> None:
    """What can be checked before any node starts; one-line errors (LaunchError, or the
    vehicle's, effects' or mission's own ParameterError)."""
    from auv_sim.params import load_vehicle

    params = load_vehicle(cfg.vehicle)
    if cfg.pilot_vehicle:
        load_vehicle(cfg.pilot_vehicle)
    if cfg.effects:
        # the environment module loads the compiled model (numba): only when there are effects
        from auv_sim.environment import load_environment

        load_environment(cfg.effects)
    namespace_path(cfg.namespace)
    if not params.depth_min <= cfg.initial_depth <= params.depth_max:
        raise LaunchError(f'initial depth {cfg.initial_depth:g} m is outside the envelope '
                          f'[{params.depth_min:g}, {params.depth_max:g}] m of {cfg.vehicle}')
    if cfg.depth_command is not None and \
            not params.depth_min <= cfg.depth_command <= params.depth_max:
        raise LaunchError(f'depth command {cfg.depth_command:g} m is outside the envelope '
                          f'[{params.depth_min:g}, {params.depth_max:g}] m of {cfg.vehicle}')
    if cfg.record:
        bag = pathlib.Path(cfg.record)
        if bag.exists() and (not bag.is_dir() or any(bag.iterdir())):
            raise LaunchError(f'bag {bag} exists already and is not empty: choose another '
                              '--record, or remove it')
    if cfg.foxglove is not None:
        from auv_bringup.foxglove_node import check_port_free

        check_port_free('127.0.0.1', cfg.foxglove)


def send_depth_command(z: float, env: dict[str, str], subscribers: int = 1,
                       timeout: float = STARTUP_TIMEOUT, namespace: str = '') -> None:
    """Command ``z`` [m] with ``auv depth`` on ``<namespace>/depth_command`` once
    ``subscribers`` nodes (pilot, recorder, viewer) have matched it, and wait for the pilot's
    answer; LaunchError with its reason when it is not accepted. A process that dies after
    the answer (exit status non-zero in the DDS teardown, nothing else on stderr) has
    delivered its command: said on stderr, not an error."""
    try:
        proc = subprocess.run([sys.executable, '-m', 'auv_bringup.cli', 'depth', str(z),
                               '--namespace', namespace_path(namespace),
                               '--timeout', str(timeout), '--min-subscribers',
                               str(subscribers)], env=env, capture_output=True,
                              text=True, timeout=2 * timeout + 10.0)
    except subprocess.TimeoutExpired:
        raise LaunchError(f'depth command {z} m not answered within {2 * timeout:g} s') from None
    if proc.returncode != 0 and ' accepted by ' not in proc.stderr:
        raise LaunchError(f'depth command {z:g} m: ' + (last_error_line(proc.stderr) or
                                                       f'auv depth exited {proc.returncode}'))
    if proc.returncode != 0:
        print(f'launch: auv depth exited with status {proc.returncode} after its command was '
              'answered', file=sys.stderr, flush=True)


def run_graph(cfg: GraphConfig, duration: float | None = None,
              env: dict[str, str] | None = None) -> dict[str, int | None]:
    """Check, start the graph, wait for the simulator to finish (or ``duration`` wall s, or a
    signal), stop everything cleanly, and check the recording. Returns each node's exit code.

    Raises
    ------
    LaunchError
        a check before the start failed; a node failed (its last error line);
        the recording is not whole (what is missing, per topic); a lockstep run went on
        without an answer.
    """
    env = dict(env or os.environ)
    use_dds_profile(env)  # the nodes' Fast DDS timings (auv_contract.dds), unless the user's
    # The nodes' matrices are small (6 x 6 to 12 x 12): OpenBLAS's worker threads only cost
    # there, and on a busy machine they spin against other jobs (the pilot's design took 1.4 s
    # of CPU instead of 0.4 s at load 14, 4.2 s of wall time instead of 1.2 s).
    use_one_blas_thread(env)
    check_before_start(cfg)
    with namespace_lock(env, cfg.namespace):
        log_dir = pathlib.Path(cfg.log_dir) if cfg.log_dir else default_log_dir(cfg)
        log_dir.mkdir(parents=True, exist_ok=True)
        print(f'launch: node logs in {log_dir}', file=sys.stderr, flush=True)
        if cfg.foxglove is not None:
            print(f'launch: Foxglove at ws://127.0.0.1:{cfg.foxglove} (in a browser: '
                  f'{FOXGLOVE_APP.format(host="127.0.0.1", port=cfg.foxglove)}; layout '
                  f'{LAYOUT})', file=sys.stderr, flush=True)
        nodes = graph_nodes(cfg, log_dir)
        codes = _run_nodes(cfg, nodes, env, duration)
        failed = [n.failure() for n in nodes if codes.get(n.name) not in (0, None, -2, 130)]
        if failed:
            raise LaunchError('; '.join(failed))
        _check_run(cfg, nodes)
    return codes


def _run_nodes(cfg: GraphConfig, nodes: list[NodeProcess], env: dict[str, str],
               duration: float | None) -> dict[str, int | None]:
    """Start ``nodes``, wait for the end of the run, stop them; their exit codes."""
    stop_requested = []

    def on_signal(signum: int, _frame: object) -> None:
        stop_requested.append(signum)

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    codes: dict[str, int | None] = {}
    try:
        sim = nodes[-1]
        for node in nodes[:-1]:
            node.start(env)
        if cfg.depth_command is not None and cfg.pilot and not cfg.mission:
            # answered before the simulator starts: the command acts from t = 0
            send_depth_command(cfg.depth_command, env,
                               command_subscribers(cfg, 'depth_command'),
                               namespace=cfg.namespace)
        sim.start(env)
        end = time.monotonic() + duration if duration else None
        while not stop_requested and sim.running():
            if end is not None and time.monotonic() > end:
                break
            for node in nodes:
                if not node.running() and node.name not in ('simulator', 'mission') \
                        and node.proc is not None and node.proc.returncode != 0:
                    raise LaunchError(node.failure())
                if node.name == 'mission' and not node.running() and node.proc is not None \
                        and node.proc.returncode not in (0, None):
                    raise LaunchError(node.failure())
            time.sleep(0.05)
    finally:
        for node in reversed(nodes):
            if node.name == 'mission' and node.proc is not None and not stop_requested:
                # a mission ends by itself with the simulator's last state
                with contextlib.suppress(subprocess.TimeoutExpired):
                    node.proc.wait(5.0)
            if node.name != 'recorder':
                codes[node.name] = node.stop(signal.SIGINT)
        time.sleep(0.3)  # let the last messages reach the recorder
        for node in nodes:
            if node.name == 'recorder':
                codes[node.name] = node.stop(signal.SIGTERM)
        for s, handler in old.items():
            signal.signal(s, handler)
    return codes


def _check_run(cfg: GraphConfig, nodes: list[NodeProcess]) -> None:
    """After the run: lockstep instants without their answer, and the recording compared with
    what the nodes published (LaunchError naming what is missing)."""
    from auv_bringup.recording_check import check_recording
    from auv_sim.node_report import read_report

    reports = {n.name: read_report(n.report_path) for n in nodes
               if n.name in ('simulator', 'pilot', 'mission')}
    sim = reports.get('simulator') or {}
    missed = sim.get('lockstep_missed', 0)
    if cfg.in_lockstep and missed:
        raise LaunchError(f'lockstep: {missed} control instant(s) went on without their answer '
                          f'within {LOCKSTEP_TIMEOUT:g} s: the run is not deterministic (see '
                          f'{nodes[-1].log_path})')
    if not cfg.record:
        return
    check = check_recording(cfg.record, reports, recorded_topics(cfg))
    if not check.complete:
        raise LaunchError(f'recording {cfg.record} is not whole: {check.summary()}')
    print(f'launch: bag {cfg.record}: {check.summary()}', file=sys.stderr, flush=True)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('--vehicle', default=str(config_path('a18m.yaml')),
                        help='vehicle file (default config/a18m.yaml)')
    parser.add_argument('--effects', default='', help='effects file for the simulated vehicle')
    parser.add_argument('--lockstep', action='store_true',
                        help='simulator waits for the pilot each control instant (deterministic)')
    parser.add_argument('--real-time-factor', type=float, default=1.0,
                        help='simulated seconds per wall second; 0 = as fast as possible')
    parser.add_argument('--initial-depth', type=float, default=40.0, help='m')
    parser.add_argument('--initial-speed', type=float, default=2.0, help='m/s')
    parser.add_argument('--stop-time', type=float, default=0.0,
                        help='simulated time at which the graph stops [s]; 0 = never')
    parser.add_argument('--duration', type=float, default=None, help='wall-time limit [s]')
    parser.add_argument('--no-pilot', action='store_true', help='do not start the depth pilot')
    parser.add_argument('--water-speed', type=float, default=0.0,
                        help='[m/s] speed through the water told to the pilot (0: it '
                             'schedules on the measured surge over ground)')
    parser.add_argument('--realtime-priority', type=int, default=0,
                        help='run the pilot SCHED_FIFO at this priority (1-99; needs '
                             'CAP_SYS_NICE or an rtprio limit); 0 = normal scheduling')
    parser.add_argument('--record', default=None,
                        help='record the topics to this bag directory; the run fails (exit 1) '
                             'naming what is missing unless the bag holds every message the '
                             "graph's nodes published")
    parser.add_argument('--log-dir', default=None,
                        help="write each node's output here (default: beside the bag, "
                             'BAG.logs, or out/logs/launch_<date-time>)')
    parser.add_argument('--wall-clock', action='store_true',
                        help='every node on the wall clock (real time, no /clock), as on a '
                             'vehicle; not with --lockstep or --mission')
    parser.add_argument('--mission', default=None,
                        help='fly an open-loop mission (surge, pitch, yaw or a file) instead of '
                             'the pilot, in lockstep on simulated time; start depth, speed and '
                             'stop time come from it')
    parser.add_argument('--namespace', default='',
                        help='run every node in this namespace (e.g. auv1: topics /auv1/state, '
                             '/auv1/depth_command, ...; default /auv), on simulated time with '
                             'its own clock /NS/clock; for several vehicles in one graph')
    parser.add_argument('--pilot-state', choices=['vehicle_state', 'odometry'],
                        default='vehicle_state',
                        help="the pilot's state input: the simulator's state (VehicleState, "
                             'NED/FRD) or its odom (nav_msgs/Odometry, ENU/FLU), as from a '
                             "vehicle's navigation solution")
    parser.add_argument('--pilot-vehicle', default='',
                        help="the pilot's vehicle file when it is not the simulated vehicle's "
                             '(a pilot on a vehicle it was not designed on; default: '
                             '--vehicle)')
    parser.add_argument('--learn', action='store_true',
                        help='the pilot learns what its vehicle file gets wrong while flying '
                             '(trim, plane effectiveness, buoyancy, plane delay) in its depth '
                             'changes and flies the learned model (docs/pilot-design.md; off '
                             'by default)')

    from auv_bringup.foxglove_node import DEFAULT_PORT

    parser.add_argument('--foxglove', type=int, nargs='?', const=DEFAULT_PORT, default=None,
                        metavar='PORT', help='serve the live topics on a Foxglove WebSocket '
                        f'(ws://127.0.0.1:PORT, default port {DEFAULT_PORT}; see '
                        'docs/foxglove.md)')
    parser.add_argument('--depth', type=float, default=None,
                        help='depth command [m] delivered to the pilot (and answered) before '
                             'the simulator starts (for deterministic lockstep runs)')


def mission_config(mission: str, **kwargs: object) -> GraphConfig:
    """A graph that flies ``mission`` open loop in lockstep: trimmed at its start, stopped at
    its end."""
    from auv_sim.missions import load_mission

    m = load_mission(mission)
    return GraphConfig(mission=mission, pilot=False, initial_depth=m.z0, initial_speed=m.u0,
                       stop_time=m.duration, **kwargs)  # type: ignore[arg-type]


def check_options(args: argparse.Namespace) -> None:
    """Every option of ``auv launch`` checked (one-line CliError / LaunchError)."""
    check_number('--real-time-factor', args.real_time_factor, minimum=0.0)
    check_number('--initial-depth', args.initial_depth, unit='m')
    check_number('--initial-speed', args.initial_speed, above=0.0, unit='m/s')
    check_number('--stop-time', args.stop_time, minimum=0.0, unit='s')
    check_number('--duration', args.duration, above=0.0, unit='s')
    check_number('--water-speed', args.water_speed, minimum=0.0, unit='m/s')
    check_number('--realtime-priority', args.realtime_priority, minimum=0, maximum=99)
    check_number('--depth', args.depth, unit='m')
    if args.foxglove is not None:
        check_number('--foxglove', args.foxglove, minimum=0, maximum=65535)
    if args.wall_clock and (args.lockstep or args.mission):
        raise LaunchError('--wall-clock is not available with --lockstep or --mission (they '
                          'need simulated time)')
    if args.wall_clock and args.real_time_factor != 1.0:
        raise LaunchError('--wall-clock runs in real time: --real-time-factor must be 1')
    if args.mission and (args.no_pilot or args.depth is not None
                         or args.pilot_state != 'vehicle_state' or args.pilot_vehicle):
        raise LaunchError('--mission flies without the pilot: no --depth, --no-pilot, '
                          '--pilot-state or --pilot-vehicle with it')
    if args.no_pilot and args.pilot_vehicle:
        raise LaunchError('--pilot-vehicle names the pilot\'s file: not with --no-pilot')
    namespace_path(args.namespace)


def run(args: argparse.Namespace) -> int:
    check_options(args)
    if args.mission:
        cfg = mission_config(args.mission, vehicle=args.vehicle, effects=args.effects,
                             real_time_factor=args.real_time_factor, record=args.record,
                             log_dir=args.log_dir, namespace=args.namespace)
    else:
        cfg = GraphConfig(vehicle=args.vehicle, effects=args.effects, lockstep=args.lockstep,
                          real_time_factor=args.real_time_factor,
                          initial_depth=args.initial_depth, initial_speed=args.initial_speed,
                          stop_time=args.stop_time, pilot=not args.no_pilot,
                          record=args.record, log_dir=args.log_dir,
                          sim_clock=not args.wall_clock, depth_command=args.depth,
                          water_speed=args.water_speed,
                          realtime_priority=args.realtime_priority, namespace=args.namespace,
                          pilot_state=args.pilot_state, pilot_learn=args.learn,
                          pilot_vehicle=args.pilot_vehicle)
    if args.foxglove is not None:
        if args.namespace:
            raise LaunchError('--foxglove serves the /auv topics; it does not follow --namespace '
                              f'{args.namespace} (run auv foxglove with remapped topics)')
        cfg.foxglove = args.foxglove
    run_graph(cfg, duration=args.duration)
    return 0
