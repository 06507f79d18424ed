"""Import of one hour of a real vehicle's 50 Hz log through a map, against rosbags.

The log: a rosbag2 bag (MCAP, zstd) of one hour at 50 Hz of ``nav_msgs/Odometry`` (ENU/FLU),
``sensor_msgs/Imu``, ``sensor_msgs/FluidPressure``, the custom fin message
``lab_msgs/msg/FinAngles`` and ``std_msgs/Float64`` propeller rpm (5 x 180 000 messages),
with a smooth synthetic motion (pitch and heading oscillations, depth changes). It is imported
through ``config/maps/ros2_custom_fins.yaml`` (:func:`auv_logs.importer.import_log`:
read, convert frames and units, hold onto the IMU stamps, segment) in a fresh process that
reports its wall time and peak resident memory (``ru_maxrss``: Python, numpy and rosbags
included). The reference, in another fresh process of the same run: rosbags' ``AnyReader``
deserialising every message of the same five topics one by one (nothing else done with them).
Targets (the issue's): import < 10 s and < 1 GB. Run as a script to write
``bench/results/import.json``.
"""
from __future__ import annotations

import json
import os
import pathlib
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np
from timing import save_figures

from auv_logs import synth

ROOT = pathlib.Path(__file__).resolve().parents[1]
MAP = ROOT / 'config' / 'maps' / 'ros2_custom_fins.yaml'
TOPICS = ('/odom', '/imu/data', '/pressure', '/fins', '/thruster/rpm')

IMPORT = """
import json, resource, sys, time
t0 = time.perf_counter()
from auv_logs.importer import import_log
from auv_logs.mapping import load_map
t1 = time.perf_counter()
log = import_log(load_map(sys.argv[1]), sys.argv[2])
t2 = time.perf_counter()
print(json.dumps({'import_s': t2 - t1, 'startup_s': t1 - t0, 'samples': len(log.t),
                  'segments': len(log.segments),
                  'peak_rss_mb': resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""

ROSBAGS = """
import json, pathlib, resource, sys, time
from rosbags.highlevel import AnyReader
t0 = time.perf_counter()
n = 0
with AnyReader([pathlib.Path(sys.argv[1])]) as reader:
    conns = [c for c in reader.connections if c.topic in sys.argv[2:]]
    for conn, _, raw in reader.messages(connections=conns):
        reader.deserialize(raw, conn.msgtype)
        n += 1
print(json.dumps({'rosbags_s': time.perf_counter() - t0, 'messages': n,
                  'peak_rss_mb': resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def write_log(path: pathlib.Path, seconds: float, rate: float = 50.0) -> int:
    """The one-hour log (see the module docstring); returns the messages written."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    from auv_sim.frames import state_to_odometry

    n = int(seconds * rate)
    t = np.arange(n) / rate
    x = np.zeros((n, 12))
    x[:, 2] = 30.0 + 10.0 * np.sin(2 * np.pi * t / 600.0)          # depth [m]
    x[:, 4] = np.radians(5.0) * np.sin(2 * np.pi * t / 20.0)       # pitch
    x[:, 5] = np.radians(60.0) * np.sin(2 * np.pi * t / 300.0)     # heading
    x[:, 6] = 1.8
    x[:, 10] = np.radians(5.0) * 2 * np.pi / 20.0 * np.cos(2 * np.pi * t / 20.0)
    odom = state_to_odometry(x)
    fins = np.degrees(0.1 * np.sin(2 * np.pi * t / 10.0))
    rpm = synth.rpm_of_thrust(np.full(n, 60.0))
    store = get_typestore(Stores.LATEST)
    store.register(get_types_from_msg(synth.FIN_MSG, synth.FIN_TYPE))
    T = store.types
    Header, Time = T['std_msgs/msg/Header'], T['builtin_interfaces/msg/Time']
    V3, Q, Pt = T['geometry_msgs/msg/Vector3'], T['geometry_msgs/msg/Quaternion'], \
        T['geometry_msgs/msg/Point']
    cov36, cov9 = np.zeros(36), np.zeros(9)
    count = 0
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {tp: w.add_connection(tp, ty, typestore=store) for tp, ty in (
            ('/odom', 'nav_msgs/msg/Odometry'), ('/imu/data', 'sensor_msgs/msg/Imu'),
            ('/pressure', 'sensor_msgs/msg/FluidPressure'), ('/fins', synth.FIN_TYPE),
            ('/thruster/rpm', 'std_msgs/msg/Float64'))}
        for i in range(n):
            ns = 1_700_000_000_000_000_000 + i * int(1e9 / rate)
            hdr = Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id='odom')
            p, q, lin, ang = (odom.position[i], odom.orientation[i], odom.linear[i],
                              odom.angular[i])
            quat = Q(x=q[0], y=q[1], z=q[2], w=q[3])
            angv = V3(x=ang[0], y=ang[1], z=ang[2])
            msgs = (
                ('/odom', T['nav_msgs/msg/Odometry'](
                    header=hdr, child_frame_id='base_link',
                    pose=T['geometry_msgs/msg/PoseWithCovariance'](
                        pose=T['geometry_msgs/msg/Pose'](position=Pt(x=p[0], y=p[1], z=p[2]),
                                                         orientation=quat), covariance=cov36),
                    twist=T['geometry_msgs/msg/TwistWithCovariance'](
                        twist=T['geometry_msgs/msg/Twist'](
                            linear=V3(x=lin[0], y=lin[1], z=lin[2]), angular=angv),
                        covariance=cov36))),
                ('/imu/data', T['sensor_msgs/msg/Imu'](
                    header=hdr, orientation=quat, orientation_covariance=cov9,
                    angular_velocity=angv, angular_velocity_covariance=cov9,
                    linear_acceleration=V3(x=0.0, y=0.0, z=0.0),
                    linear_acceleration_covariance=cov9)),
                ('/pressure', T['sensor_msgs/msg/FluidPressure'](
                    header=hdr, fluid_pressure=synth.P0 + synth.RHO * synth.G * x[i, 2],
                    variance=0.0)),
                ('/fins', T[synth.FIN_TYPE](header=hdr, port_elevator=fins[i],
                                            starboard_elevator=-fins[i], upper_rudder=0.0,
                                            lower_rudder=0.0)),
                ('/thruster/rpm', T['std_msgs/msg/Float64'](data=float(rpm[i]))),
            )
            for tp, msg in msgs:
                w.write(conns[tp], ns, store.serialize_cdr(msg, conns[tp].msgtype))
                count += 1
    return count


def _child(code: str, *args: str) -> dict[str, float]:
    out = subprocess.run([sys.executable, '-c', code, *args], capture_output=True, text=True,
                         check=True, timeout=900)
    figures: dict[str, float] = json.loads(out.stdout)
    return figures


def run(seconds: float = 3600.0) -> dict[str, object]:
    """Write the log, import it and deserialise it with rosbags; returns the figures."""
    with tempfile.TemporaryDirectory() as tmp:
        path = pathlib.Path(tmp) / 'hour'
        t0 = time.perf_counter()
        messages = write_log(path, seconds)
        t_write = time.perf_counter() - t0
        size = sum(f.stat().st_size for f in path.iterdir())
        load = os.getloadavg()[0]
        imp = _child(IMPORT, str(MAP), str(path))
        ref = _child(ROSBAGS, str(path), *TOPICS)
    assert ref['messages'] == messages
    return {
        'log_seconds': seconds,
        'messages': messages,
        'bag_bytes': size,
        'write_s': round(t_write, 2),
        'import_s': round(imp['import_s'], 3),
        'import_peak_rss_mb': round(imp['peak_rss_mb'], 1),
        'import_state_samples': imp['samples'],
        'rosbags_deserialise_s': round(ref['rosbags_s'], 3),
        'rosbags_peak_rss_mb': round(ref['peak_rss_mb'], 1),
        'import_over_rosbags': round(imp['import_s'] / ref['rosbags_s'], 3),
        'targets': {'import_s': 10.0, 'peak_rss_mb': 1024.0},
        'cpus': os.cpu_count(),
        'load_1min': round(load, 2),
        'python': platform.python_version(),
        'machine': platform.machine(),
    }


if __name__ == '__main__':
    figures = run(float(sys.argv[1]) if len(sys.argv) > 1 else 3600.0)
    if len(sys.argv) == 1:
        save_figures('import', figures)
    print(json.dumps(figures, indent=2))
