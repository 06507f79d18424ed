"""Presets and scalar options against numbers worked by hand: a DVL
(``geometry_msgs/TwistWithCovarianceStamped``, FLU) for u v w, an IMU for attitude and rates,
``sensor_msgs/FluidPressure`` for depth, a ``std_msgs/Float64MultiArray`` of fin angles
(indexed elements summed into BAR), thrust in percent of a full scale, and a
``std_msgs/Float64`` depth preset. Messages written with rosbags' rosbag2 writer (sqlite3)."""
from __future__ import annotations

import math
import pathlib
from typing import Any

import numpy as np
import pytest

from auv_logs.importer import import_log
from auv_logs.mapping import load_map

D = math.radians
MAP = """format: auv-log-map/1
kind: bag
time: {stamp: header, base: /imu, max_age: 0.0}
sources:
  - {preset: imu, topic: /imu, frame: ENU/FLU}
  - {preset: dvl, topic: /dvl, frame: FLU}
  - {preset: DEPTH_PRESET}
signals:
  bar:
    unit: deg
    sum:
      - {topic: /fins, field: 'data[0]', gain: 0.5}
      - {topic: /fins, field: 'data[1]', gain: -0.5}
  helm: {topic: /fins, field: 'data[2]', unit: deg}
  thrust: {topic: /throttle, field: data, unit: percent, full_scale: 50.0}
segments: {min_duration: 1}
"""
PRESSURE = ('fluid_pressure, topic: /pressure, density: 1000.0, surface_pressure: 100000.0, '
            'g: 10.0')
FLOAT64 = 'float64, topic: /depth, signal: z, unit: cm, frame: NED'


def _bag(path: pathlib.Path, n: int = 20) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.LATEST)
    T = store.types
    V3 = T['geometry_msgs/msg/Vector3']
    cov9, cov36 = np.zeros(9), np.zeros(36)
    s5, c5 = math.sin(D(5)), math.cos(D(5))
    with Writer(path, version=9, storage_plugin=StoragePlugin.SQLITE3) as w:
        conns: dict[str, Any] = {}

        def put(topic: str, msgtype: str, ns: int, msg: Any) -> None:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msgtype, typestore=store)
            w.write(conns[topic], ns, store.serialize_cdr(msg, msgtype))

        dim = T['std_msgs/msg/MultiArrayDimension']
        put('/fins', 'std_msgs/msg/Float64MultiArray', 10**9, T['std_msgs/msg/Float64MultiArray'](
            layout=T['std_msgs/msg/MultiArrayLayout'](dim=[dim(label='fins', size=3,
                                                               stride=3)], data_offset=0),
            data=np.array([10.0, -10.0, 5.0])))
        put('/throttle', 'std_msgs/msg/Float64', 10**9, T['std_msgs/msg/Float64'](data=40.0))
        for k in range(n):
            ns = 10**9 + k * 10**8
            hdr = T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
                sec=ns // 10**9, nanosec=ns % 10**9), frame_id='x')
            # heading east, nose up 10 deg (ENU yaw 0, FLU pitch -10 deg)
            put('/imu', 'sensor_msgs/msg/Imu', ns, T['sensor_msgs/msg/Imu'](
                header=hdr, orientation=T['geometry_msgs/msg/Quaternion'](x=0.0, y=-s5, z=0.0,
                                                                         w=c5),
                orientation_covariance=cov9, angular_velocity=V3(x=0.01, y=0.02, z=0.03),
                angular_velocity_covariance=cov9, linear_acceleration=V3(x=0.0, y=0.0, z=0.0),
                linear_acceleration_covariance=cov9))
            put('/dvl', 'geometry_msgs/msg/TwistWithCovarianceStamped', ns,
                T['geometry_msgs/msg/TwistWithCovarianceStamped'](
                    header=hdr, twist=T['geometry_msgs/msg/TwistWithCovariance'](
                        twist=T['geometry_msgs/msg/Twist'](linear=V3(x=1.5, y=0.2, z=0.1),
                                                           angular=V3(x=0.0, y=0.0, z=0.0)),
                        covariance=cov36)))
            # 12.5 m deep: P = 1e5 + 1000 * 10 * 12.5 Pa
            put('/pressure', 'sensor_msgs/msg/FluidPressure', ns,
                T['sensor_msgs/msg/FluidPressure'](header=hdr, fluid_pressure=225000.0,
                                                   variance=0.0))
            put('/depth', 'std_msgs/msg/Float64', ns, T['std_msgs/msg/Float64'](data=1250.0))


@pytest.mark.parametrize('depth', [PRESSURE, FLOAT64])
def test_presets_worked_by_hand(depth: str, tmp_path: pathlib.Path) -> None:
    _bag(tmp_path / 'bag')
    (tmp_path / 'map.yaml').write_text(MAP.replace('DEPTH_PRESET', depth))
    log = import_log(load_map(tmp_path / 'map.yaml'), tmp_path / 'bag')
    expected = [12.5, 0.0, D(10), D(90), 1.5, -0.2, -0.1, 0.01, -0.02, -0.03]
    for row in log.state:
        assert row[2:] == pytest.approx(expected, abs=1e-9)
    (_, bar), (_, helm), (_, thrust) = (log.commands[c] for c in ('bar', 'helm', 'thrust'))
    assert bar == pytest.approx([D(10)])      # (10 - (-10)) / 2 deg
    assert helm == pytest.approx([D(5)])
    assert thrust == pytest.approx([20.0])    # 40 % of 50 N
    assert [line.split(':')[0] for line in log.report['derived']] == ['x', 'y']
