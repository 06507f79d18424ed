"""Benchmark: timing of `auv play` as a process over Fast DDS.

A bag of 1000 VehicleState messages at 200 Hz (log times 5 ms apart, 5 s) is replayed with
`auv play --wait-for-subscribers` to a subscriber process at rates 1 and 2, three times each.
For each replay: the span of the arrivals against the bag's span / rate (relative error) and
the p95 of the per-message lag (arrival offset - log-time offset / rate, s, at the
subscriber's monotonic clock). Medians over the repeats are reported, with the range.

The tests check the same quantities with margins that hold on a busy 2-core machine
(`tests/test_record_play.py`); the figures here need an idle machine.

Run: ``. .venv/bin/auv-env && python bench/bench_replay.py`` (writes
bench/results/replay.json).
"""
from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys
import tempfile
from typing import Any

import numpy as np
from timing import save_figures

from auv_bag import BagWriter, read_arrays, typestore

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / 'tests'))
from conftest import reserve_domain_id  # the tests' domain-id reservation

N = 1000
RATE_HZ = 200.0
REPEATS = 3
TOPIC = '/auv/state'

LISTENER = r'''
import json, sys, time
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from auv_msgs.msg import VehicleState

n = int(sys.argv[1])
rclpy.init()
node = rclpy.create_node('bench_replay_listener')
arrivals = []
node.create_subscription(VehicleState, '/auv/state',
                         lambda m: arrivals.append((time.monotonic(), m.x)),
                         QoSProfile(depth=2000, reliability=ReliabilityPolicy.RELIABLE))
print('ready', flush=True)
deadline = time.monotonic() + 120.0
while len(arrivals) < n and time.monotonic() < deadline:
    rclpy.spin_once(node, timeout_sec=0.05)
print(json.dumps(arrivals), flush=True)
rclpy.shutdown()
'''


def _write_bag(path: pathlib.Path) -> None:
    store = typestore()
    state = store.types['auv_msgs/msg/VehicleState']
    header = store.types['std_msgs/msg/Header']
    stamp = store.types['builtin_interfaces/msg/Time']
    with BagWriter(path) as bag:
        bag.add_topic(TOPIC, 'auv_msgs/msg/VehicleState')
        for i in range(N):
            t_ns = 1_000_000_000_000 + int(round(i * 1e9 / RATE_HZ))
            msg = state(header=header(stamp=stamp(sec=t_ns // 10**9, nanosec=t_ns % 10**9),
                                      frame_id='ned'),
                        x=float(i), y=0.0, z=0.0, phi=0.0, theta=0.0, psi=0.0,
                        u=0.0, v=0.0, w=0.0, p=0.0, q=0.0, r=0.0)
            bag.write(TOPIC, msg, log_time_ns=t_ns)


def _replay(bag: pathlib.Path, rate: float, env: dict[str, str]) -> dict[str, float]:
    listener = subprocess.Popen([sys.executable, '-c', LISTENER, str(N)], env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert listener.stdout is not None and listener.stderr is not None
        if listener.stdout.readline().strip() != 'ready':
            raise RuntimeError(f'listener failed: {listener.stderr.read()}')
        subprocess.run([sys.executable, '-m', 'auv_bringup.cli', 'play', str(bag), '--rate',
                        str(rate), '--wait-for-subscribers'], env=env, check=True,
                       capture_output=True, timeout=120)
        out, _ = listener.communicate(timeout=150)
    finally:
        if listener.poll() is None:
            listener.kill()
            listener.communicate()
    got = np.array(json.loads(out.strip().splitlines()[-1]))
    log_t = read_arrays(bag, [TOPIC])[TOPIC]['t_log']
    if len(got) != N:
        raise RuntimeError(f'the listener heard {len(got)} of {N} messages')
    bag_span = (log_t[-1] - log_t[0]) / rate
    lag = (got[:, 0] - got[0, 0]) - (log_t - log_t[0]) / rate
    return {'span_error': float((got[-1, 0] - got[0, 0]) / bag_span - 1.0),
            'lag_p95_s': float(np.percentile(np.abs(lag), 95))}


def run() -> dict[str, Any]:
    domain = reserve_domain_id()
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain.domain_id),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', PYTHONUNBUFFERED='1')
    figures: dict[str, Any] = {'messages': N, 'rate_hz': RATE_HZ, 'repeats': REPEATS}
    with tempfile.TemporaryDirectory() as tmp:
        bag = pathlib.Path(tmp) / 'replay'
        _write_bag(bag)
        for rate in (1.0, 2.0):
            runs = [_replay(bag, rate, env) for _ in range(REPEATS)]
            figures[f'rate_{rate:g}'] = {
                key: {'median': float(np.median([r[key] for r in runs])),
                      'min': float(min(r[key] for r in runs)),
                      'max': float(max(r[key] for r in runs))}
                for key in ('span_error', 'lag_p95_s')}
    domain.release()
    return figures


if __name__ == '__main__':
    result = run()
    print(json.dumps(result, indent=2))
    print(save_figures('replay', result))
