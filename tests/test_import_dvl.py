"""A DVL mounted rotated and away from the body origin: its velocities are turned into the
body axes and moved to the origin by the map's ``mounting`` and ``lever_arm``.

Hand-worked case: the vehicle flies straight at u = 2 m/s (v = w = 0 at the body origin)
while pitching up at a constant q = 0.01 rad/s (pitch 0.01 t rad; no roll, constant heading).
The DVL sits 1 m aft and 0.2 m below the origin, r = (-1, 0, 0.2) m (body FRD), so it moves
at v + omega x r = (2 + 0.01 * 0.2, 0, 0.01 * 1) = (2.002, 0, 0.01) m/s in body axes; it is
mounted yawed +45 deg (its x axis points forward-starboard), so it logs
R_z(45 deg)^T (2.002, 0, 0.01) = (2.002 cos 45, -2.002 sin 45, 0.01) m/s. Imported, the
body-origin velocity must be (2, 0, 0) m/s.
"""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest

from auv_logs.errors import MapError
from auv_logs.importer import import_log
from auv_logs.mapping import load_map

MAP = """format: auv-log-map/1
kind: text
text: {delimiter: comma, header: true}
time: {column: t, unit: s}
vectors:
  - kind: linear_velocity
    columns: [vx, vy, vz]
    frame: NED/FRD
    unit: m/s
    MOUNT
signals:
  z: {column: depth, unit: m, frame: NED}
  theta: {column: pitch, unit: rad, frame: NED/FRD}
  psi: {column: yaw, unit: rad, frame: NED}
  bar: {column: bar, unit: rad}
  thrust: {column: thrust, unit: N}
"""


def _log(path: pathlib.Path) -> None:
    t = np.arange(0.0, 30.0, 0.1)
    c, s = math.cos(math.radians(45.0)), math.sin(math.radians(45.0))
    rows = ['t,depth,pitch,yaw,vx,vy,vz,bar,thrust']
    for tk in t:
        # depth as the kinematics give it: z_dot = -u sin(theta), theta = 0.01 t
        depth = 10.0 + 200.0 * (math.cos(0.01 * tk) - 1.0)
        rows.append(f'{tk:.1f},{depth:.17g},{0.01 * tk:.17g},0.3,'
                    f'{2.002 * c:.17g},{-2.002 * s:.17g},0.01,0.0,50.0')
    path.write_text('\n'.join(rows) + '\n')


def test_dvl_mounting_rotation_and_lever_arm_hand_worked(tmp_path: pathlib.Path) -> None:
    (tmp_path / 'm.yaml').write_text(MAP.replace(
        'MOUNT', 'mounting: {rpy: [0, 0, 45], unit: deg}\n    lever_arm: [-1.0, 0.0, 0.2]'))
    _log(tmp_path / 'dvl.csv')
    log = import_log(load_map(tmp_path / 'm.yaml'), tmp_path / 'dvl.csv')
    u, v, w = log.state[:, 6], log.state[:, 7], log.state[:, 8]
    assert np.max(np.abs(u - 2.0)) < 1e-12
    assert np.max(np.abs(v)) < 1e-12
    assert np.max(np.abs(w)) < 1e-12
    notes = ' '.join(log.report['notes'])
    assert 'velocity moved from the sensor at (-1, 0, 0.2) m' in notes
    assert 'yaw 0, 0, 45 deg (mounting)' in notes
    # without the lever arm the pitch rate leaves omega x r = (0.002, 0, 0.01) m/s in
    (tmp_path / 'n.yaml').write_text(MAP.replace('MOUNT', 'mounting: {rpy: [0, 0, 45], '
                                                 'unit: deg}'))
    plain = import_log(load_map(tmp_path / 'n.yaml'), tmp_path / 'dvl.csv')
    assert np.allclose(plain.state[:, 6:9], [2.002, 0.0, 0.01], atol=1e-12)


def test_mounting_on_an_orientation_is_a_one_line_error(tmp_path: pathlib.Path) -> None:
    text = MAP.replace('MOUNT', 'lever_arm: [1, 0]')
    (tmp_path / 'm.yaml').write_text(text)
    with pytest.raises(MapError, match=r'map vectors\[0\]\.lever_arm \(line \d+\): expected '
                                       r'three numbers'):
        load_map(tmp_path / 'm.yaml')
    (tmp_path / 'o.yaml').write_text(text.replace('kind: linear_velocity', 'kind: euler')
                                     .replace('unit: m/s', 'unit: deg')
                                     .replace('lever_arm: [1, 0]', 'lever_arm: [1, 0, 0]'))
    with pytest.raises(MapError, match=r'lever_arm is for a linear velocity \(a DVL\), not a '
                                       r'euler'):
        load_map(tmp_path / 'o.yaml')
