"""Bag-to-arrays throughput for /auv/state: vectorised CDR decoding against rosbags.

One hour of VehicleState at 50 Hz (180 000 messages) is written to a bag, then read into
numpy arrays by two paths over the same file scan:

* ``vectorised``: :func:`auv_bag.read_arrays` (fields gathered from the CDR bytes);
* ``rosbags``: the same with ``fast=False``, which deserializes every message with
  ``typestore.deserialize_cdr`` and copies its fields into the arrays;
* ``rosbags_reader``: rosbags end to end, its own container reader
  (``rosbags.rosbag2.Reader``) and ``deserialize_cdr`` per message, fields copied into the
  same arrays (the peer a user would otherwise call).

Also timed, to show why ``auv_bag`` keeps its own record framing: walking the same file's
records with ``mcap``'s ``StreamReader(emit_chunks=True)`` (no decompression, no decoding),
as ``mcap_stream_walk_s``.

All three must give identical arrays (asserted). The paths run ``repeats`` times each, alternating;
the median wall time is reported (and the minimum), in messages per second. Both share the
file scan, decompression and CRC check (done by :func:`auv_bag.default_workers` threads
ahead of the decoding), which bounds the ratio. Run as a script to write
``bench/results/bag.json``; the CPU count and the 1-minute load average at the start of the
measurement are recorded with the figures, since a busy machine lowers the ratio.

Figures on a 2-core x86_64 machine shared with other work (1-minute load 10.9): vectorised
0.111 s median (1.6 M msg/s), rosbags over the same scan 1.97 s (17.8x), rosbags end to end
2.85 s (25.6x), mcap's StreamReader walk alone 0.20 s; ``bench/results/bag.json`` holds the
latest run. More than half of the vectorised path's time in one thread is the file scan (zstd
decompression, CRC check, locating the messages: 0.073 s of 0.124 s, minima at load 12),
whose decompression and CRC check a second free core shares.
"""
from __future__ import annotations

import json
import os
import pathlib
import platform
import statistics
import tempfile
import time

import numpy as np
from timing import save_figures

import auv_bag as bag

STATE = '/auv/state'


def write_state_bag(path: pathlib.Path, n: int, rate_hz: float = 50.0) -> None:
    """A bag of ``n`` VehicleState messages at ``rate_hz`` (frame ids of two lengths)."""
    ts = bag.typestore()
    types = ts.types
    state = types['auv_msgs/msg/VehicleState']
    header = types['std_msgs/msg/Header']
    stamp = types['builtin_interfaces/msg/Time']
    rng = np.random.default_rng(1)
    values = rng.normal(size=(n, 12))
    with bag.BagWriter(path) as writer:
        writer.add_topic(STATE, 'auv_msgs/msg/VehicleState')
        for i in range(n):
            t_ns = 1_700_000_000_000_000_000 + int(i * 1e9 / rate_hz)
            sec, nsec = divmod(t_ns, 1_000_000_000)
            msg = state(header(stamp(sec=sec, nanosec=nsec), 'ned' if i % 10 else 'base_link'),
                        *values[i].tolist())
            writer.write(STATE, bytes(ts.serialize_cdr(msg, 'auv_msgs/msg/VehicleState')),
                         log_time_ns=t_ns + 1000)


def rosbags_reader_arrays(path: pathlib.Path, names: tuple[str, ...]) -> np.ndarray:
    """``/auv/state`` read by rosbags alone: fields ``t`` (header stamp, s), ``t_log`` (log
    time, s) and then ``names``, attributes of the message (flat VehicleState fields)."""
    from rosbags.rosbag2 import Reader

    ts = bag.typestore()
    rows = []
    with Reader(path) as reader:
        conns = [c for c in reader.connections if c.topic == STATE]
        for conn, log_ns, raw in reader.messages(connections=conns):
            msg = ts.deserialize_cdr(raw, conn.msgtype)
            stamp = msg.header.stamp
            sec, nsec = divmod(log_ns, 1_000_000_000)
            rows.append((stamp.sec + stamp.nanosec * 1e-9, sec + nsec * 1e-9,
                         *(getattr(msg, n) for n in names)))
    dtype = np.dtype([(n, '<f8') for n in ('t', 't_log', *names)])
    return np.array(rows, dtype=dtype)


def mcap_stream_walk(path: pathlib.Path) -> int:
    """Records of ``path`` walked by ``mcap``'s StreamReader, chunks left compressed."""
    from mcap.stream_reader import StreamReader

    with open(path, 'rb') as fh:
        return sum(1 for _ in StreamReader(fh, emit_chunks=True).records)


def _timed(fn) -> tuple[float, object]:  # type: ignore[no-untyped-def]
    t0 = time.perf_counter()
    result = fn()
    return time.perf_counter() - t0, result


def run(n: int = 180_000, repeats: int = 5) -> dict[str, object]:
    """Measure both paths; returns the figures (times in s, rates in messages/s)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = pathlib.Path(tmp) / 'state'
        t0 = time.perf_counter()
        write_state_bag(path, n)
        t_write = time.perf_counter() - t0
        size = (path / 'state_0.mcap').stat().st_size
        bag.read_arrays(path, [STATE])  # warm-up: imports, typestore, page cache
        load = os.getloadavg()[0]
        # The two paths alternate, so that both see the same load on a shared machine.
        names = bag.read_arrays(path, [STATE])[STATE].dtype.names[2:]
        fast_times, slow_times, peer_times, walk_times = [], [], [], []
        for _ in range(repeats):
            t, fast = _timed(lambda: bag.read_arrays(path, [STATE]))
            fast_times.append(t)
            t, slow = _timed(lambda: bag.read_arrays(path, [STATE], fast=False))
            slow_times.append(t)
            t, peer = _timed(lambda: rosbags_reader_arrays(path, names))
            peer_times.append(t)
            t, _ = _timed(lambda: mcap_stream_walk(path / 'state_0.mcap'))
            walk_times.append(t)
        t_fast, t_slow = statistics.median(fast_times), statistics.median(slow_times)
        t_peer = statistics.median(peer_times)
    a, b = fast[STATE], slow[STATE]  # type: ignore[index]
    assert len(a) == n and a.dtype == b.dtype
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a, peer)
    return {
        'messages': n,
        'bag_bytes': size,
        'write_s': round(t_write, 3),
        'vectorised_s': round(t_fast, 4),
        'rosbags_s': round(t_slow, 4),
        'vectorised_msgs_per_s': round(n / t_fast),
        'rosbags_msgs_per_s': round(n / t_slow),
        'speedup': round(t_slow / t_fast, 1),
        'vectorised_min_s': round(min(fast_times), 4),
        'rosbags_min_s': round(min(slow_times), 4),
        'speedup_of_minima': round(min(slow_times) / min(fast_times), 1),
        'rosbags_reader_s': round(t_peer, 4),
        'rosbags_reader_msgs_per_s': round(n / t_peer),
        'speedup_vs_rosbags_reader': round(t_peer / t_fast, 1),
        'mcap_stream_walk_s': round(statistics.median(walk_times), 4),
        'repeats': repeats,
        'workers': bag.default_workers(),
        'cpus': os.cpu_count(),
        'load_1min': round(load, 2),
        'python': platform.python_version(),
        'machine': platform.machine(),
    }


if __name__ == '__main__':
    figures = run()
    save_figures('bag', figures)
    print(json.dumps(figures, indent=2))
