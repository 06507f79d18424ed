"""Benchmark: what a Foxglove client receives from ``auv foxglove`` during a real-time run.

The simulator runs on the wall clock (``--no-use-sim-clock``: each state is stamped with the
system clock when it is published, 50 Hz) at real time, the bridge serves it, and a WebSocket
client (tests/foxglove_client.py) subscribes to ``/auv/state``, ``/auv/odom``, ``/auv/pose``
and ``/auv/hydrodynamic_forces`` for ``SPAN`` seconds of stamps. Per run:

- latency [ms]: client arrival (system clock) - header stamp, p50/p95/max, for ``/auv/state``
  (forwarded CDR) and ``/auv/pose`` (decoded and re-encoded as protobuf): publication in the
  simulator, DDS, the bridge, the WebSocket, decoding in the client;
- delivered: distinct stamps received / instants of the 50 Hz grid between the first and last
  stamp (1: none lost);
- bridge CPU [% of one core]: its user + system time over the window.

Medians over ``REPEATS`` runs are reported with their range. The machine is shared: the
figures are those of the run, not bounds.

Run: ``. .venv/bin/auv-env && python bench/bench_foxglove.py`` (writes
bench/results/foxglove.json).
"""
from __future__ import annotations

import asyncio
import os
import pathlib
import signal
import subprocess
import sys
import time
from typing import Any

import numpy as np
from timing import save_figures

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / 'tests'))
from conftest import reserve_domain_id  # the tests' domain-id reservation
from foxglove_client import Decoded, LineReader, receive

ROOT = pathlib.Path(__file__).resolve().parents[1]
SPAN = 20.0  # s of stamps collected per run
REPEATS = 3
PUBLISH_PERIOD_NS = 20_000_000  # the simulator's 50 Hz
TOPICS = ['/auv/state', '/auv/odom', '/auv/pose', '/auv/hydrodynamic_forces']
NS = 1_000_000_000


def cpu_seconds(pid: int) -> float:
    """User + system CPU time [s] of a process (Linux /proc)."""
    fields = pathlib.Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def stamp_ns(topic: str, msg: Any) -> int:
    if topic == '/auv/pose':
        return int(msg.timestamp.seconds) * NS + int(msg.timestamp.nanos)
    return int(msg.header.stamp.sec) * NS + int(msg.header.stamp.nanosec)


def one_run(env: dict[str, str]) -> dict[str, Any]:
    bridge = subprocess.Popen([sys.executable, '-m', 'auv_bringup.foxglove_node', '--port', '0'],
                              cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, text=True)
    sim = None
    try:
        port = int(LineReader(bridge.stderr).wait_for('foxglove: serving', 60.0)
                   .rsplit(':', 1)[1])
        sim = subprocess.Popen([sys.executable, '-m', 'auv_sim.node', '--no-use-sim-clock',
                                '--real-time-factor', '1'], cwd=ROOT, env=env,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        window: dict[str, float] = {}

        def enough(d: Decoded) -> bool:
            states = d.messages['/auv/state']
            if states and 'cpu0' not in window:
                window['cpu0'], window['t0'] = cpu_seconds(bridge.pid), time.monotonic()
            return bool(states) and (states[-1][0] - states[0][0]) >= SPAN * NS

        got = asyncio.run(receive(port, TOPICS, enough, deadline=SPAN + 90.0))
        cpu = (cpu_seconds(bridge.pid) - window['cpu0']) / (time.monotonic() - window['t0'])
    finally:
        for proc in (sim, bridge):
            if proc is not None and proc.poll() is None:
                proc.send_signal(signal.SIGINT)
                try:
                    proc.wait(20.0)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait(5.0)
    out: dict[str, Any] = {'bridge_cpu_percent': 100.0 * cpu}
    for topic in TOPICS:
        stamps = np.array([stamp_ns(topic, m) for _, m in got.messages[topic]])
        arrivals = np.array(got.arrivals[topic])
        # wall-clock stamps jitter around the 50 Hz grid: the count of grid instants spanned
        expected = round((stamps.max() - stamps.min()) / PUBLISH_PERIOD_NS) + 1
        out[topic] = {'delivered': float(len(np.unique(stamps)) / expected),
                      'received': len(stamps)}
        if topic in ('/auv/state', '/auv/pose'):
            lat = (arrivals - stamps) / 1e6
            out[topic].update(latency_ms_p50=float(np.percentile(lat, 50)),
                              latency_ms_p95=float(np.percentile(lat, 95)),
                              latency_ms_max=float(lat.max()))
    return out


def summarize(runs: list[dict[str, Any]]) -> dict[str, Any]:
    def stat(values: list[float]) -> dict[str, float]:
        return {'median': float(np.median(values)), 'min': float(min(values)),
                'max': float(max(values))}

    summary: dict[str, Any] = {'bridge_cpu_percent': stat([r['bridge_cpu_percent']
                                                           for r in runs])}
    for topic in TOPICS:
        summary[topic] = {key: stat([r[topic][key] for r in runs])
                          for key in runs[0][topic] if key != 'received'}
    return summary


def main() -> None:
    domain = reserve_domain_id()
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain.domain_id),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', RMW_IMPLEMENTATION='rmw_fastrtps_cpp')
    try:
        runs = [one_run(env) for _ in range(REPEATS)]
    finally:
        domain.release()
    result = {'span_s': SPAN, 'repeats': REPEATS, 'publish_rate_hz': NS / PUBLISH_PERIOD_NS,
              'cpu_count': os.cpu_count(), 'summary': summarize(runs), 'runs': runs}
    print(save_figures('foxglove', result))


if __name__ == '__main__':
    main()
