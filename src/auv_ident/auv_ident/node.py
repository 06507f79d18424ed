"""The identification node (``ros2 run auv_ident identifier``, ``auv ident-node``).

Subscribes to ``/auv/state``, ``/auv/hydrodynamic_forces`` (optional: without it the forces
are reconstructed from the motion) and the actuator commands ``/auv/bar_command``,
``/auv/helm_command``, ``/auv/thrust_command`` (reliable, deep queues), stores every message's
fields in growing numpy buffers keyed by the message *header stamp* (not the arrival time),
and on request (service ``~/identify``, std_srvs/Trigger) and on shutdown runs the same
identification as ``auv ident`` (:func:`auv_ident.job.identify_and_report`), writing the same
outputs into the ``out`` directory, from every message delivered before the request (those
still queued are taken first). Fed the messages of a bag, it gives the offline command's
coefficients. With ``estimate_period > 0`` it publishes the running estimate as JSON
(std_msgs/String on ``~/estimate``) every so many seconds.

With ``--map MAP --logs LOG...`` it first reads a real vehicle's original logs through the
mapping file (:mod:`auv_logs`, as ``auv ident --map`` does) into its buffers, as if
their contract topics had been received, then goes on accumulating live topics.

Parameters: ``vehicle_file`` (the vehicle file the identified values replace), ``out``
(output directory), ``source`` (auto|forces|motion), ``fit_c0``, ``fit_planes`` (the dive
plane's CZbar and CMbar too, forces from motion), ``bounds`` (the physical bounds, default
true), ``errors`` (hac|ess|iid), ``equations`` (list; empty: all), ``window`` [s],
``estimate_period`` [s], ``qos_depth`` (messages). Each is declared with a descriptor
(:mod:`auv_ident.node_parameters`: description with its unit, range, choices); a bad value
ends the start with one line ``error: ...``; a change while running is validated first
(refused with the reason, nothing changed) and then applied: a new ``vehicle_file`` is loaded,
a new ``estimate_period`` restarts the estimate, the others are read when used; ``qos_depth``
applies at start only.
"""
from __future__ import annotations

import argparse
import signal
import sys
from collections.abc import Callable, Sequence
from types import FrameType
from typing import Any, cast

import numpy as np

from auv_contract import COMMAND_TOPICS, FORCES_TOPIC, STATE_FIELDS, STATE_TOPIC
from auv_contract.blas import use_one_blas_thread
from auv_contract.dds import use_dds_profile
from auv_contract.jsonout import dumps
from auv_ident.errors import IdentError
from auv_ident.identify import EQUATIONS, ERROR_METHODS
from auv_ident.motion import FORCE_FIELDS, SOURCES, WINDOW_S
from auv_ident.node_parameters import PARAMETERS, START_ONLY, problem
from auv_sim.cli_options import add_vehicle_option

NODE_NAME = 'identifier'


class ColumnBuffer:
    """A growing float64 table (rows x named columns) with amortised doubling, no per-sample
    Python objects kept."""

    def __init__(self, names: Sequence[str], capacity: int = 4096) -> None:
        self.names = tuple(names)
        self._data = np.empty((max(16, capacity), len(self.names)))
        self.size = 0

    def append(self, row: Sequence[float]) -> None:
        """Add one row (same order as ``names``)."""
        if self.size == len(self._data):
            grown = np.empty((2 * len(self._data), len(self.names)))
            grown[:self.size] = self._data[:self.size]
            self._data = grown
        self._data[self.size] = row
        self.size += 1

    def extend(self, rows: np.ndarray) -> None:
        """Add many rows (n x columns, same order as ``names``)."""
        for row in np.asarray(rows, float):
            self.append(row)

    def array(self) -> np.ndarray:
        """The rows so far as a structured array (float64 fields ``names``), a copy."""
        dtype = np.dtype([(n, '<f8') for n in self.names])
        return np.ascontiguousarray(self._data[:self.size]).view(dtype).reshape(self.size)


def stamp_seconds(stamp: Any) -> float:
    """Header stamp as seconds, computed as the bag reader does (``sec + nanosec * 1e-9``)."""
    return float(np.float64(stamp.sec) + np.float64(stamp.nanosec) * 1e-9)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``auv ident-node`` (each sets the ROS parameter of the same name)."""
    add_vehicle_option(parser, old_names=('--base',),
                       help_text='vehicle file the identified values replace '
                                 '(default: config/a18m.yaml)')
    parser.add_argument('--out', default='out/ident', help='output directory')
    parser.add_argument('--source', choices=SOURCES, default='auto',
                        help='fit from the force topic, from the motion, or from what the '
                             'topics hold (default: %(default)s)')
    parser.add_argument('--fit-c0', action='store_true',
                        help='fit CZ0 and CM0 too (default: fixed at the vehicle file values)')
    parser.add_argument('--fit-planes', action='store_true',
                        help='fit the dive plane\'s CZbar and CMbar too (forces from motion)')
    parser.add_argument('--unbounded', action='store_true',
                        help='no physical bounds on the coefficients (default: bounded)')
    parser.add_argument('--errors', choices=ERROR_METHODS, default='hac',
                        help='covariance estimator of the intervals (default: %(default)s)')
    parser.add_argument('--equations', nargs='+', choices=list(EQUATIONS), default=[],
                        help='equations to identify (default: all)')
    parser.add_argument('--window', type=float, default=WINDOW_S,
                        help='length of the motion fit windows [s] (default: %(default)s)')
    parser.add_argument('--estimate-period', type=float, default=0.0,
                        help='publish the running estimate every S seconds (0: never)')
    parser.add_argument('--qos-depth', type=int, default=10000,
                        help='subscription queue depth [messages] (default: %(default)s)')
    parser.add_argument('--map', default=None, metavar='MAP',
                        help='mapping file of the logs given with --logs')
    parser.add_argument('--logs', nargs='+', default=[], metavar='LOG',
                        help='original logs read through --map at start')


def _make_node(overrides: dict[str, Any]) -> Any:
    """Build the rclpy node (imports rclpy here: the rest of the package never does)."""
    from rcl_interfaces.msg import SetParametersResult
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String
    from std_srvs.srv import Trigger

    from auv_ident.job import (
        identify_and_report,
        records_as_logged,
        unsupported_equations,
    )
    from auv_msgs.msg import ActuatorSetpoint, HydrodynamicForces, VehicleState
    from auv_sim.errors import AuvSimError
    from auv_sim.parameter_descriptor import descriptor
    from auv_sim.params import load_vehicle

    class IdentifierNode(Node):
        """Accumulates the topics and identifies on request (see module docstring)."""

        def __init__(self) -> None:
            super().__init__(NODE_NAME, parameter_overrides=[
                Parameter(k, value=v) for k, v in overrides.items()])
            # ranges after the check, so that a bad value at start gets the message naming it
            for spec in PARAMETERS.values():
                default = list(spec.default) if isinstance(spec.default, tuple) \
                    else spec.default
                self.declare_parameter(spec.name, default, descriptor(spec, ranged=False))
            wrong = problem({n: self.get_parameter(n).value for n in PARAMETERS})
            if wrong:
                raise IdentError(wrong)
            for spec in PARAMETERS.values():
                if spec.range is not None:
                    self.set_descriptor(spec.name, descriptor(spec))
            # a change validated by _on_set, applied by _post_set once ROS has stored it
            self._candidate: dict[str, Any] | None = None
            self.add_on_set_parameters_callback(self._on_set)
            self.add_post_set_parameters_callback(self._post_set)
            self.base = load_vehicle(self.get_parameter('vehicle_file').value)
            self.state = ColumnBuffer(('t', *STATE_FIELDS))
            self.forces = ColumnBuffer(('t', *FORCE_FIELDS))
            self.commands = {topic: ColumnBuffer(('t', 'value')) for topic in
                             COMMAND_TOPICS.values()}
            qos = QoSProfile(depth=int(self.get_parameter('qos_depth').value),
                             reliability=ReliabilityPolicy.RELIABLE,
                             history=HistoryPolicy.KEEP_LAST)
            self.create_subscription(VehicleState, STATE_TOPIC, self._on_state, qos)
            self.create_subscription(HydrodynamicForces, FORCES_TOPIC, self._on_forces, qos)
            for topic, buf in self.commands.items():
                self.create_subscription(ActuatorSetpoint, topic,
                                         lambda msg, buf=buf: buf.append(
                                             (stamp_seconds(msg.header.stamp), msg.value)),
                                         qos)
            self.create_service(Trigger, '~/identify', self._on_identify)
            self.estimate_pub = self.create_publisher(String, '~/estimate', 10)
            self.estimate_timer: Any = None
            self._start_estimates(float(self.get_parameter('estimate_period').value))
            self._string = String
            self._identify_and_report = identify_and_report
            self.imports: list[dict[str, Any]] = []

        def preload(self, map_path: str, logs: Sequence[str]) -> None:
            """Read original logs through a map into the buffers (contract arrays)."""
            from auv_logs.contract_bag import contract_arrays
            from auv_logs.importer import import_logs

            _, imported = import_logs(map_path, logs)
            for lg in imported:
                arrays = contract_arrays(lg)
                st = arrays[STATE_TOPIC]
                self.state.extend(np.column_stack([st[f] for f in ('t', *STATE_FIELDS)]))
                for topic, buf in self.commands.items():
                    if topic in arrays:
                        buf.extend(np.column_stack([arrays[topic]['t'],
                                                    arrays[topic]['value']]))
                self.imports.append(dict(lg.report))
                self.get_logger().info(f'read {lg.name} through {map_path}: {len(lg.t)} state '
                                       f'samples, {len(lg.segments)} segment(s)')

        def _records(self, source: str, window: float) -> list[Any]:
            limits: dict[str, Any] = {}
            records = records_as_logged(self.arrays(), self.base, source, 'live', window,
                                        limits)
            for ch, r in limits.items():
                self.get_logger().warning(
                    f'{ch}: {r["count"]} logged commands outside the vehicle file\'s limits '
                    f'(logged {r["min"]:.4g} .. {r["max"]:.4g}): used as logged')
            return records

        def _equations(self, requested: list[str]) -> list[str] | None:
            eqs = [e for e in (requested or []) if e] or None
            if self.imports:
                eqs, _ = unsupported_equations(self.imports, eqs)
            return eqs

        def _start_estimates(self, period: float) -> None:
            """(Re)start the running estimate every ``period`` [s]; 0 stops it."""
            if self.estimate_timer is not None:
                self.destroy_timer(self.estimate_timer)
                self.estimate_timer = None
            if period > 0:
                self.estimate_timer = self.create_timer(period, self._publish_estimate)

        def _on_set(self, params: list[Any]) -> Any:
            """Validate a change (nothing is applied here: see :meth:`_post_set`).

            Parameters
            ----------
            params : list of rclpy.parameter.Parameter
                What a ``set_parameters`` request asks for, all or nothing.

            Returns
            -------
            SetParametersResult
                Refused, with the reason, for a parameter applied at start only, a value
                :func:`~auv_ident.node_parameters.problem` finds wrong or a vehicle file that
                does not load.
            """
            self._candidate = None
            changes = {p.name: p.value for p in params if p.name in PARAMETERS}
            fixed = [n for n in changes if n in START_ONLY
                     and changes[n] != self.get_parameter(n).value]
            if fixed:
                return SetParametersResult(successful=False, reason=(
                    f'{", ".join(fixed)} applied at start only; restart the node to change '
                    f'it'))
            wrong = problem(changes)
            if wrong:
                return SetParametersResult(successful=False, reason=wrong)
            candidate: dict[str, Any] = {}
            if 'vehicle_file' in changes:
                try:
                    candidate['base'] = load_vehicle(changes['vehicle_file'])
                except (AuvSimError, ValueError) as exc:
                    return SetParametersResult(successful=False, reason=str(exc))
            if 'estimate_period' in changes:
                candidate['estimate_period'] = float(changes['estimate_period'])
            self._candidate = candidate
            return SetParametersResult(successful=True)

        def _post_set(self, params: list[Any]) -> None:
            """Apply the change :meth:`_on_set` accepted: the vehicle file loaded there, the
            period of the running estimate; the other parameters are read when used.

            Parameters
            ----------
            params : list of rclpy.parameter.Parameter
                The parameters set (the candidate holds what needs applying).
            """
            candidate, self._candidate = self._candidate, None
            if candidate is None:
                return
            if 'base' in candidate:
                self.base = candidate['base']
            if 'estimate_period' in candidate:
                self._start_estimates(candidate['estimate_period'])
            self.get_logger().info(
                f'parameters changed: {", ".join(p.name for p in params)}')

        def _on_state(self, msg: Any) -> None:
            self.state.append((stamp_seconds(msg.header.stamp), msg.x, msg.y, msg.z, msg.phi,
                               msg.theta, msg.psi, msg.u, msg.v, msg.w, msg.p, msg.q, msg.r))

        def _on_forces(self, msg: Any) -> None:
            f, m = msg.hydrodynamic.force, msg.hydrodynamic.torque
            self.forces.append((stamp_seconds(msg.header.stamp), f.x, f.y, f.z, m.x, m.y, m.z))

        def arrays(self) -> dict[str, np.ndarray]:
            """Topic arrays as the bag reader gives them (topics with messages only)."""
            out = {STATE_TOPIC: self.state.array()}
            if self.forces.size:
                out[FORCES_TOPIC] = self.forces.array()
            for topic, buf in self.commands.items():
                if buf.size:
                    out[topic] = buf.array()
            return out

        def drain(self) -> int:
            """Take every message already delivered to the subscriptions' queues; returns
            how many. The executor takes one message per subscription per wait, so a
            request served between two takes would otherwise see a replay's tail still
            queued (a replay acknowledged to the end, 3568 of 4001 states taken on a
            loaded machine): an identification answers on every message delivered before
            it was asked for."""
            taken = 0
            for sub in list(self.subscriptions):
                while True:
                    with sub.handle:
                        got = sub.handle.take_message(sub.msg_type, sub.raw)
                    if got is None:
                        break
                    # every subscription of this node takes the message alone
                    cast(Callable[[Any], None], sub.callback)(got[0])
                    taken += 1
            return taken

        def identify(self, nelder_mead: bool = True) -> dict[str, Any]:
            """Identify from everything received (:meth:`drain` first); writes the outputs;
            returns a summary."""
            self.drain()
            p = {k: self.get_parameter(k).value for k in
                 ('out', 'source', 'fit_c0', 'fit_planes', 'bounds', 'errors', 'equations',
                  'window')}
            equations = self._equations(p['equations'])
            records = self._records(p['source'], p['window'])

            def log_info(text: str) -> None:
                self.get_logger().info(text)

            result, files, outcome = self._identify_and_report(
                records, self.base, p['out'], ['live topics'], fit_c0=p['fit_c0'],
                bounds=p['bounds'], errors=p['errors'], equations=equations,
                nelder_mead=nelder_mead, progress=log_info,
                partial=bool(self.imports) and not any(p['equations'] or []),
                fit_planes=bool(p['fit_planes']))
            return {'source': result.source, 'files': files,
                    'validation': outcome.validation.verdict,
                    'written': outcome.validation.written,
                    'coefficients': {n: {'value': c.value, 'std_error': c.std_error,
                                         'ci95': list(c.ci95)}
                                     for n, c in result.coefficients.items()},
                    'samples': {STATE_TOPIC: self.state.size, FORCES_TOPIC: self.forces.size}}

        def _on_identify(self, request: Any, response: Any) -> Any:
            try:
                response.message = dumps(self.identify())
                response.success = True
            except (IdentError, ValueError) as exc:
                response.success = False
                response.message = f'error: {exc}'
                self.get_logger().error(response.message)
            return response

        def _publish_estimate(self) -> None:
            if self.state.size < 100:
                return
            try:
                p = {k: self.get_parameter(k).value for k in
                     ('source', 'fit_c0', 'fit_planes', 'errors', 'equations', 'window')}
                from auv_ident.identify import identify
                equations = self._equations(p['equations'])
                records = self._records(p['source'], p['window'])
                result = identify(records, self.base, equations=equations,
                                  fit_offsets=p['fit_c0'], errors=p['errors'],
                                  fit_planes=bool(p['fit_planes']))
                text = dumps({'t': float(self.state.array()['t'][-1]),
                                   'coefficients': {n: [c.value, c.std_error] for n, c in
                                                    result.coefficients.items()}})
            except (IdentError, ValueError) as exc:
                text = dumps({'error': str(exc)})
            self.estimate_pub.publish(self._string(data=text))

    return IdentifierNode()


def run(args: argparse.Namespace, ros_args: Sequence[str] | None = None) -> int:
    """Run the node until SIGINT/SIGTERM; then identify once more and write the outputs."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    overrides: dict[str, Any] = {'out': args.out, 'source': args.source,
                                 'fit_c0': bool(args.fit_c0),
                                 'fit_planes': bool(args.fit_planes),
                                 'bounds': not bool(args.unbounded),
                                 'errors': args.errors,
                                 'equations': list(args.equations) or [''],
                                 'window': float(args.window),
                                 'estimate_period': float(args.estimate_period),
                                 'qos_depth': int(args.qos_depth)}
    if args.vehicle:
        overrides['vehicle_file'] = args.vehicle
    stop = {'signal': 0}

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        stop['signal'] = signum

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    use_dds_profile()  # before the first participant (auv_contract.dds)
    use_one_blas_thread()  # small matrices: one BLAS thread (auv_contract.blas)
    rclpy.init(args=['--ros-args', *ros_args] if ros_args else None,
               signal_handler_options=SignalHandlerOptions.NO)
    status = 0
    try:
        node = _make_node(overrides)
        if args.map is not None:
            node.preload(args.map, args.logs)
        elif args.logs:
            raise IdentError('--logs needs --map (the mapping file of those logs)')
        node.get_logger().info('identifier ready: call ~/identify (std_srvs/Trigger)')
        while not stop['signal'] and rclpy.ok():
            rclpy.spin_once(node, timeout_sec=0.1)
        if node.state.size:
            try:
                summary = node.identify()
                node.get_logger().info(f'identified on shutdown: {summary["files"]}')
            except (IdentError, ValueError) as exc:
                print(f'error: {exc}', file=sys.stderr)
                status = 1
        node.destroy_node()
    finally:
        if rclpy.ok():
            rclpy.shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return status


def main() -> None:
    """``ros2 run auv_ident identifier [options] [--ros-args ...]``."""
    argv = sys.argv[1:]
    ros_args: list[str] = []
    if '--ros-args' in argv:
        i = argv.index('--ros-args')
        argv, ros_args = argv[:i], argv[i + 1:]
    parser = argparse.ArgumentParser(prog='identifier', description=__doc__.splitlines()[0])
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        sys.exit(run(args, ros_args))
    except (IdentError, ValueError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        sys.exit(1)


if __name__ == '__main__':
    main()
