"""Bad input to the import: each is one line naming the map key and line, or the file and row,
and nothing is written. Logs: a short constant run (10 m deep, 1.5 m/s) written as a ROS 2
bag (rosbags' writer), a sqlite3 bag and a text log."""
from __future__ import annotations

import pathlib
import re
import sqlite3
import subprocess
import sys

import numpy as np
import pytest

from auv_logs import synth
from auv_logs.contract_bag import write_contract_bag
from auv_logs.errors import LogReadError, MapError, RealLogError
from auv_logs.importer import import_log
from auv_logs.mapping import load_map
from auv_sim.simulator import Record

ROOT = pathlib.Path(__file__).resolve().parents[1]
MAPS = ROOT / 'config' / 'maps'


@pytest.fixture(scope='module')
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, pathlib.Path]:
    n = 1500   # 30 s at 50 Hz
    t = np.arange(n) * 0.02
    x = np.zeros((n, 15))
    x[:, 2], x[:, 6] = 10.0, 1.5
    rec = Record(t, x, x.copy(), np.tile([0.0, 0.0, 20.0], (n, 1)), np.zeros((n, 4, 6)))
    root = tmp_path_factory.mktemp('bad_input')
    synth.write_ros2(root / 'bag', rec, custom_fins=True)
    synth.write_ros2(root / 'db', rec, storage='sqlite3', custom_fins=True)
    synth.write_text(root / 'log.txt', rec)
    return {'bag': root / 'bag', 'db': root / 'db', 'text': root / 'log.txt'}


def _map(tmp: pathlib.Path, base: str, old: str, new: str) -> pathlib.Path:
    text = (MAPS / base).read_text()
    assert old in text
    path = tmp / 'map.yaml'
    path.write_text(text.replace(old, new))
    return path


def _line_of(path: pathlib.Path, needle: str) -> int:
    return next(i for i, line in enumerate(path.read_text().splitlines(), 1) if needle in line)


def test_topic_not_in_the_bag(logs: dict[str, pathlib.Path], tmp_path: pathlib.Path) -> None:
    m = _map(tmp_path, 'ros2_custom_fins.yaml', 'topic: /thruster/rpm', 'topic: /thruster/rev')
    with pytest.raises(LogReadError, match=r'^bag .*bag has no topic /thruster/rev \(it has: '
                                           r'/fins, /imu/data, /odom, /pressure, '
                                           r'/thruster/rpm\)$'):
        import_log(load_map(m), logs['bag'])


def test_field_path_not_in_the_message(logs: dict[str, pathlib.Path],
                                       tmp_path: pathlib.Path) -> None:
    m = _map(tmp_path, 'ros2_custom_fins.yaml', 'field: upper_rudder', 'field: top_rudder')
    with pytest.raises(LogReadError, match=re.escape(
            "topic /fins (lab_msgs/msg/FinAngles) has no field 'top_rudder': "
            "lab_msgs/msg/FinAngles has no 'top_rudder' (it has: header, port_elevator, "
            "starboard_elevator, upper_rudder, lower_rudder)")):
        import_log(load_map(m), logs['bag'])


def test_unknown_unit_names_the_map_line(tmp_path: pathlib.Path) -> None:
    m = _map(tmp_path, 'text_2hz_deg_cm.yaml', 'unit: cm/s', 'unit: furlong/fortnight')
    line = _line_of(m, 'furlong')
    with pytest.raises(MapError, match=rf'^{re.escape(str(m))}: map signals\.u\.unit \(line '
                                       rf'{line}\): unknown unit \'furlong/fortnight\' \(known: '
                                       r'm, cm, mm, '):
        load_map(m)


def test_undeclared_frame_names_the_map_line(tmp_path: pathlib.Path) -> None:
    m = _map(tmp_path, 'text_2hz_deg_cm.yaml', ', unit: deg, frame: NED/FRD}\n  psi',
             ', unit: deg}\n  psi')
    line = _line_of(m, 'theta:')
    with pytest.raises(MapError, match=rf'map signals\.theta \(line {line}\): no frame '
                                       r'declared \(say NED/FRD or ENU/FLU\)$'):
        load_map(m)


def test_signal_unit_of_the_wrong_kind(tmp_path: pathlib.Path) -> None:
    m = _map(tmp_path, 'text_2hz_deg_cm.yaml', 'pitch_deg, unit: deg', 'pitch_deg, unit: cm')
    with pytest.raises(MapError, match=r'signals\.theta\.unit \(line \d+\): unit cm \(length\) '
                                       r'does not fit theta \(needs angle\)$'):
        load_map(m)


def test_column_not_in_the_text_log(logs: dict[str, pathlib.Path],
                                    tmp_path: pathlib.Path) -> None:
    m = _map(tmp_path, 'text_2hz_deg_cm.yaml', 'column: depth_cm', 'column: depth_m')
    with pytest.raises(LogReadError, match=r"log\.txt: no column 'depth_m' \(columns: time, "
                                           r'depth_cm, roll_deg, '):
        import_log(load_map(m), logs['text'])


def test_ragged_row_names_file_and_line(logs: dict[str, pathlib.Path],
                                        tmp_path: pathlib.Path) -> None:
    """Strict: refused naming file and line; by default the row is left out and said in one
    line, and the log keeps every other row."""
    lines = logs['text'].read_text().splitlines()
    lines[6] = ' '.join(lines[6].split()[:-1])     # the 6th data row loses its rpm
    bad = tmp_path / 'ragged.txt'
    bad.write_text('\n'.join(lines) + '\n')
    logmap = load_map(MAPS / 'text_2hz_deg_cm.yaml')
    with pytest.raises(LogReadError, match=r'ragged\.txt line 7: 9 fields, expected 10 '
                                           r'\(time, depth_cm, '):
        import_log(logmap, bad, strict=True)
    whole = import_log(logmap, logs['text'])
    log = import_log(logmap, bad)
    assert 'ragged.txt line 7: 9 fields, expected 10: left out' in log.report['left_out']
    assert len(log.t) == len(whole.t) - 1


def test_unknown_log_kind(tmp_path: pathlib.Path) -> None:
    bad = tmp_path / 'dive.xtf'
    bad.write_bytes(b'\0' * 16)
    with pytest.raises(LogReadError, match=r"dive\.xtf: unknown log kind '\.xtf' \(known log "
                                           r'kinds: rosbag2 directory .*ROS 1 \.bag file; '
                                           r'text log'):
        import_log(load_map(MAPS / 'text_2hz_deg_cm.yaml'), bad)


def test_message_type_without_definition(logs: dict[str, pathlib.Path],
                                         tmp_path: pathlib.Path) -> None:
    import shutil

    bag = tmp_path / 'db'
    shutil.copytree(logs['db'], bag)
    db = next(bag.glob('*.db3'))
    con = sqlite3.connect(db)
    con.execute("DELETE FROM message_definitions WHERE topic_type = 'lab_msgs/msg/FinAngles'")
    con.commit()
    con.close()
    with pytest.raises(LogReadError, match=r'^topic /fins: message type lab_msgs/msg/FinAngles '
                                           r'has no definition in the bag and is not a type the '
                                           r'readers know \(the bag defines: none; built in: '
                                           r'\d+ standard ROS 2 types and auv_msgs\)$'):
        import_log(load_map(MAPS / 'ros2_custom_fins.yaml'), bag)


def test_import_cli_one_line_error_and_nothing_written(logs: dict[str, pathlib.Path],
                                                       tmp_path: pathlib.Path) -> None:
    m = _map(tmp_path, 'ros2_custom_fins.yaml', 'field: upper_rudder', 'field: top_rudder')
    out = tmp_path / 'out' / 'imported'
    proc = subprocess.run([sys.executable, '-m', 'auv_bringup.cli', 'import', str(logs['bag']),
                           '--map', str(m), '--out', str(out)], capture_output=True, text=True,
                          timeout=300, check=False)
    assert proc.returncode == 1
    assert proc.stderr.startswith('error: topic /fins (lab_msgs/msg/FinAngles) has no field')
    assert len(proc.stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_overlapping_logs_refused_before_anything_is_written(
        logs: dict[str, pathlib.Path], tmp_path: pathlib.Path) -> None:
    logmap = load_map(MAPS / 'ros2_custom_fins.yaml')
    a = import_log(logmap, logs['bag'])
    out = tmp_path / 'imported'
    with pytest.raises(RealLogError, match=r'^logs bag and bag overlap in time: import them '
                                           r'into separate bags$'):
        write_contract_bag(out, logmap, [a, a])
    assert list(tmp_path.iterdir()) == []
