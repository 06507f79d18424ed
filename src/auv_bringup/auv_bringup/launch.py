"""``auv launch``: start the node graph (simulator, depth pilot, recorder) as processes.

Each node runs in its own process (``python -m <module> --ros-args -p ...``), sharing the
caller's environment (``ROS_DOMAIN_ID`` etc.). The graph stops cleanly: when the simulator
reaches its ``stop_time`` (or on SIGINT/SIGTERM of ``auv launch``, or ``--duration`` wall
seconds), the simulator and pilot get SIGINT, then the recorder gets SIGTERM so it closes its
bag with every message it received; each stop has a deadline, after which the process is
killed and the fact reported. On Linux every node also gets SIGTERM from the kernel when
``auv launch`` itself dies (even by SIGKILL), so no node outlives it.

Namespaces: every node's topics are relative to its namespace, ``/auv`` by default. With
``namespace`` (``auv launch --namespace auv1``) every node of the graph runs in ``/auv1``
(``-r __ns:=/auv1``), and on simulated time its clock moves too (``-r /clock:=/auv1/clock``),
so several simulated vehicles, each with its own simulated time, share one ROS graph.
"""
from __future__ import annotations

import argparse
import contextlib
import ctypes
import dataclasses
import os
import pathlib
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Sequence

from auv_bringup.errors import LaunchError

ROOT = pathlib.Path(__file__).resolve().parents[3]
STOP_DEADLINE = 10.0  # s a node gets to exit after its signal
PR_SET_PDEATHSIG = 1  # prctl(2) option: signal sent to this process when its parent dies


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


@dataclasses.dataclass
class NodeProcess:
    """One node of the graph: its name, command line and running process."""

    name: str
    argv: list[str]
    log_path: pathlib.Path | None = None
    proc: subprocess.Popen[bytes] | None = None

    def start(self, env: dict[str, str]) -> None:
        # the log stays open for the life of the process it receives (closed in stop())
        out = open(self.log_path, 'wb') if self.log_path else subprocess.DEVNULL  # noqa: SIM115
        self.proc = subprocess.Popen(self.argv, env=env, stdout=out, stderr=subprocess.STDOUT,
                                     start_new_session=True, preexec_fn=_die_with_parent())

    def running(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

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
    """``-r`` arguments that put a node into the graph's namespace (none for the default)."""
    if not cfg.namespace:
        return []
    ns = namespace_path(cfg.namespace)
    out = ['-r', f'__ns:={ns}']
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

    vehicle: str = str(ROOT / 'config' / 'a18m.yaml')
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
    log_dir: str | None = None
    depth_command: float | None = None  # published (and delivered) before the simulator starts
    mission: str | None = None  # an open-loop mission (auv mission) instead of the pilot
    sim_clock: bool = True  # simulated time and /clock; False: every node on the wall clock
    namespace: str = ''  # the nodes' namespace ('' = /auv); with sim_clock also its own clock
    pilot_state: str = 'vehicle_state'  # the pilot's state input: vehicle_state or odometry
    foxglove: int | None = None  # serve the live topics on a Foxglove WebSocket on this port
    pilot_vehicle: str = ''  # the pilot's vehicle file when it is not the simulated one's


def graph_nodes(cfg: GraphConfig) -> list[NodeProcess]:
    """The node processes of a graph, recorder first (so it misses nothing)."""
    py = sys.executable
    log_dir = pathlib.Path(cfg.log_dir) if cfg.log_dir else None
    if log_dir:
        log_dir.mkdir(parents=True, exist_ok=True)

    def log(name: str) -> pathlib.Path | None:
        return log_dir / f'{name}.log' if log_dir else None

    nodes = []
    if cfg.record:
        argv = [py, '-m', 'auv_bringup.record_node', '--out', cfg.record]
        if cfg.topics:
            argv += ['--topics', *cfg.topics]
        if (cfg.mission or cfg.pilot) and records_bar(cfg):
            # the graph's BAR publisher (pilot or mission) matched before the simulator starts
            argv += ['--await-publishers', 'bar_command']
        if cfg.namespace:
            argv += ['--ros-args', *remaps(cfg)]
        nodes.append(NodeProcess('recorder', argv, log('recorder')))
    if cfg.mission:
        nodes.append(NodeProcess('mission', [py, '-m', 'auv_bringup.cli', 'mission',
                                             cfg.mission, '--vehicle', cfg.vehicle],
                                 log('mission')))
    elif cfg.pilot:
        nodes.append(NodeProcess('pilot', [py, '-m', 'auv_depth_lqr.node', *ros_params(
            vehicle_file=cfg.pilot_vehicle or cfg.vehicle, lockstep=cfg.lockstep,
            rate=cfg.pilot_rate,
            weights=cfg.weights, water_speed=float(cfg.water_speed),
            realtime_priority=int(cfg.realtime_priority), use_sim_time=cfg.sim_clock,
            state_source=cfg.pilot_state, start_subscribers=bar_subscribers(cfg)),
            *remaps(cfg)], log('pilot')))
    if cfg.foxglove is not None:
        nodes.append(NodeProcess('foxglove', [py, '-m', 'auv_bringup.foxglove_node', '--port',
                                              str(cfg.foxglove), '--vehicle', cfg.vehicle],
                                 log('foxglove')))
    nodes.append(NodeProcess('simulator', [py, '-m', 'auv_sim.node', *ros_params(
        vehicle_file=cfg.vehicle, effects_file=cfg.effects or '""', lockstep=cfg.lockstep,
        use_sim_clock=cfg.sim_clock,
        real_time_factor=cfg.real_time_factor, initial_depth=cfg.initial_depth,
        initial_speed=cfg.initial_speed, stop_time=cfg.stop_time,
        start_subscribers=float(state_subscribers(cfg)),
        control_period=1.0 / cfg.pilot_rate), *remaps(cfg)], log('simulator')))
    return nodes


def state_subscribers(cfg: GraphConfig) -> int:
    """The ``/auv/state`` subscribers of the graph ``cfg`` the simulator waits for before
    t = 0: the mission or a pilot on ``VehicleState`` (a pilot on ``nav_msgs/Odometry``
    subscribes to ``odom`` instead), the recorder and the Foxglove bridge."""
    pilot_on_state = cfg.pilot and not cfg.mission and cfg.pilot_state == 'vehicle_state'
    return (int(bool(cfg.mission) or pilot_on_state) + int(bool(cfg.record))
            + int(cfg.foxglove is not None))


def bar_subscribers(cfg: GraphConfig) -> int:
    """The ``bar_command`` subscribers of the graph ``cfg`` the pilot waits for before its
    first command: the simulator, the recorder (unless its ``--topics`` leave the command
    out) and the Foxglove bridge."""
    return 1 + int(records_bar(cfg)) + int(cfg.foxglove is not None)


def records_bar(cfg: GraphConfig) -> bool:
    """Whether the graph ``cfg`` records ``bar_command`` (a recorder whose ``--topics``, if
    given, hold it)."""
    return bool(cfg.record) and (not cfg.topics or any(
        topic_basename(t) == 'bar_command' for t in cfg.topics))


def topic_basename(topic: str) -> str:
    """The last name of a topic, relative or absolute (``/auv1/bar_command`` ->
    ``bar_command``)."""
    return topic.rstrip('/').rsplit('/', 1)[-1]


def send_depth_command(z: float, env: dict[str, str], subscribers: int = 1,
                       timeout: float = 20.0, namespace: str = '') -> None:
    """Publish a depth command [m] with ``auv depth`` on ``<namespace>/depth_command`` once
    ``subscribers`` match, and wait until it is delivered (acknowledged by every matched
    subscriber: ``auv depth`` says "published on" only then). A process that dies after that
    line (seen once in 9 fresh-clone test runs: exit status non-zero, nothing else on stderr,
    i.e. in the DDS teardown) has delivered its command: said on stderr, not an error."""
    try:
        proc = subprocess.run([sys.executable, '-m', 'auv_bringup.cli', 'depth', str(z),
                               '--namespace', namespace_path(namespace),
                               '--timeout', str(timeout), '--min-subscribers',
                               str(subscribers)], env=env, capture_output=True,
                              text=True, timeout=timeout + 10.0)
    except subprocess.TimeoutExpired:
        raise LaunchError(f'depth command {z} m not delivered within {timeout} s') from None
    if proc.returncode != 0 and ' published on ' not in proc.stderr:
        raise LaunchError(f'depth command {z} m failed (exit status {proc.returncode}): '
                          f'{proc.stderr.strip()}')
    if proc.returncode != 0:
        print(f'launch: auv depth exited with status {proc.returncode} after its command was '
              'acknowledged', file=sys.stderr, flush=True)


def run_graph(cfg: GraphConfig, duration: float | None = None,
              env: dict[str, str] | None = None, settle: float = 1.5) -> dict[str, int | None]:
    """Start the graph, wait for the simulator to finish (or ``duration`` wall s, or a
    signal), stop everything cleanly. Returns each node's exit code."""
    env = dict(env or os.environ)
    nodes = graph_nodes(cfg)
    stop_requested = []

    def on_signal(signum: int, _frame: object) -> None:
        stop_requested.append(signum)

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    codes: dict[str, int | None] = {}
    try:
        for node in nodes:
            node.start(env)
            if node.name == 'recorder':
                time.sleep(settle)  # let discovery settle before the publishers start
            if not node.running():
                raise LaunchError(f'{node.name} failed to start'
                                  + (f'; see {node.log_path}' if node.log_path else ''))
            if node.name == 'pilot' and cfg.depth_command is not None:
                send_depth_command(cfg.depth_command, env, 2 if cfg.record else 1,
                                   namespace=cfg.namespace)
        sim = nodes[-1]
        end = time.monotonic() + duration if duration else None
        while not stop_requested and sim.running():
            if end is not None and time.monotonic() > end:
                break
            for node in nodes:
                if not node.running() and node.name != 'simulator' \
                        and node.proc is not None and node.proc.returncode != 0:
                    raise LaunchError(f'{node.name} died (code {node.proc and node.proc.poll()})'
                                      + (f'; see {node.log_path}' if node.log_path else ''))
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


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('--vehicle', default=str(ROOT / 'config' / 'a18m.yaml'),
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
    parser.add_argument('--record', default=None, help='record the topics to this bag directory')
    parser.add_argument('--log-dir', default=None, help='write each node\'s output here')
    parser.add_argument('--wall-clock', action='store_true',
                        help='every node on the wall clock (real time, no /clock), as on a '
                             'vehicle; not with --lockstep')
    parser.add_argument('--mission', default=None,
                        help='fly an open-loop mission (surge, pitch, yaw or a file) instead of '
                             'the pilot; start depth, speed and stop time come from it')
    parser.add_argument('--namespace', default='',
                        help='run every node in this namespace (e.g. auv1: topics /auv1/state, '
                             '/auv1/depth_command, ...; default /auv), on simulated time with '
                             'its own clock /NS/clock; for several vehicles in one graph')
    parser.add_argument('--pilot-state', choices=['vehicle_state', 'odometry'],
                        default='vehicle_state',
                        help="the pilot's state input: the simulator's state (VehicleState, "
                             'NED/FRD) or its odom (nav_msgs/Odometry, ENU/FLU), as from a '
                             "vehicle's navigation solution")

    from auv_bringup.foxglove_node import DEFAULT_PORT

    parser.add_argument('--foxglove', type=int, nargs='?', const=DEFAULT_PORT, default=None,
                        metavar='PORT', help='serve the live topics on a Foxglove WebSocket '
                        f'(ws://127.0.0.1:PORT, default port {DEFAULT_PORT}; see '
                        'docs/foxglove.md)')
    parser.add_argument('--depth', type=float, default=None,
                        help='depth command [m] delivered to the pilot before the simulator '
                             'starts (for deterministic lockstep runs)')


def mission_config(mission: str, **kwargs: object) -> GraphConfig:
    """A graph that flies ``mission`` open loop: trimmed at its start, stopped at its end."""
    from auv_sim.missions import load_mission

    m = load_mission(mission)
    return GraphConfig(mission=mission, pilot=False, initial_depth=m.z0, initial_speed=m.u0,
                       stop_time=m.duration, **kwargs)  # type: ignore[arg-type]


def run(args: argparse.Namespace) -> int:
    if args.lockstep and (args.mission or args.wall_clock):
        raise LaunchError('--lockstep needs the pilot on simulated time (no --mission, no '
                          '--wall-clock)')
    if args.namespace:
        namespace_path(args.namespace)  # checked before anything starts
        if args.mission:
            raise LaunchError('--namespace is not available with --mission (the mission node '
                              'publishes on /auv)')
    if args.mission:
        cfg = mission_config(args.mission, vehicle=args.vehicle, effects=args.effects,
                             real_time_factor=args.real_time_factor, record=args.record,
                             log_dir=args.log_dir)
    else:
        cfg = GraphConfig(vehicle=args.vehicle, effects=args.effects, lockstep=args.lockstep,
                          real_time_factor=args.real_time_factor,
                          initial_depth=args.initial_depth, initial_speed=args.initial_speed,
                          stop_time=args.stop_time, pilot=not args.no_pilot,
                          record=args.record, log_dir=args.log_dir,
                          sim_clock=not args.wall_clock, depth_command=args.depth,
                          water_speed=args.water_speed,
                          realtime_priority=args.realtime_priority, namespace=args.namespace,
                          pilot_state=args.pilot_state)
    if args.foxglove is not None:
        from auv_bringup.foxglove_node import check_port_free

        if args.namespace:
            raise LaunchError('--foxglove serves the /auv topics; it does not follow --namespace '
                              f'{args.namespace} (run auv foxglove with remapped topics)')
        check_port_free('127.0.0.1', args.foxglove)
        cfg.foxglove = args.foxglove
    codes = run_graph(cfg, duration=args.duration)
    bad = {k: v for k, v in codes.items() if v not in (0, None, -2, 130)}
    if bad:
        raise LaunchError(f'nodes exited with failures: {bad}')
    return 0
