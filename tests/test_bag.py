"""Bag layer: write -> read round trips, interoperability, damage, topic and order errors."""
from __future__ import annotations

import itertools
import math
import pathlib

import numpy as np
import pytest

import auv_bag as bag
from auv_bag.columnar import layout_of
from auv_bag.errors import BagError

N_STATE = 300  # 6 s at 50 Hz
STATE = '/auv/state'


def _types():
    ts = bag.typestore()
    return ts, ts.types


def _stamp(t: float):
    _, T = _types()
    sec = math.floor(t)
    return T['builtin_interfaces/msg/Time'](sec=sec, nanosec=round((t - sec) * 1e9))


def _header(t: float, frame: str = 'ned'):
    _, T = _types()
    return T['std_msgs/msg/Header'](stamp=_stamp(t), frame_id=frame)


def _state(i: int, frame: str = 'ned'):
    _, T = _types()
    t = 100.0 + 0.02 * i
    v = [float(i) + k / 16 for k in range(12)]
    return T['auv_msgs/msg/VehicleState'](_header(t, frame), *v)


def _wrench(base: float):
    _, T = _types()
    V = T['geometry_msgs/msg/Vector3']
    return T['geometry_msgs/msg/Wrench'](force=V(x=base, y=base + 1, z=base + 2),
                                         torque=V(x=base + 3, y=base + 4, z=base + 5))


def write_full_bag(path: pathlib.Path, *, compression: str = 'zstd') -> None:
    """Every project message type, interleaved as in a simulator run; frame ids vary in
    length so the CDR offsets vary per message."""
    _, T = _types()
    frames = ['ned', 'base_link_frd', '', 'x']
    with bag.BagWriter(path, compression=compression, chunk_size=4096) as w:
        for i in range(N_STATE):
            log = 1_000_000_000 + i * 20_000_000
            w.write(STATE, _state(i, frames[i % 4]), log_time_ns=log)
            w.write('/auv/hydrodynamic_forces',
                    T['auv_msgs/msg/HydrodynamicForces'](
                        _header(100.0 + 0.02 * i, frames[(i + 1) % 4]), _wrench(i),
                        _wrench(10 * i), _wrench(-i), _wrench(0.5 * i)),
                    log_time_ns=log + 1)
            w.write('/clock', T['rosgraph_msgs/msg/Clock'](clock=_stamp(100.0 + 0.02 * i)),
                    log_time_ns=log + 2)
            if i % 5 == 0:
                for k, topic in enumerate(('/auv/bar_command', '/auv/helm_command',
                                           '/auv/thrust_command')):
                    w.write(topic, T['auv_msgs/msg/ActuatorSetpoint'](
                        _header(100.0 + 0.02 * i), 0.01 * i + k), log_time_ns=log + 3 + k)
            if i % 100 == 0:
                w.write('/auv/depth_command', T['std_msgs/msg/Float64'](data=5.0 + i),
                        log_time_ns=log + 7)


@pytest.fixture(scope='module')
def full_bag(tmp_path_factory: pytest.TempPathFactory) -> pathlib.Path:
    path = tmp_path_factory.mktemp('bags') / 'full'
    write_full_bag(path)
    return path


ALL_TOPICS = [STATE, '/auv/hydrodynamic_forces', '/clock', '/auv/bar_command',
              '/auv/helm_command', '/auv/thrust_command', '/auv/depth_command']


def test_layout_is_rosbag2_mcap(full_bag: pathlib.Path) -> None:
    assert sorted(p.name for p in full_bag.iterdir()) == ['full_0.mcap', 'metadata.yaml']
    from mcap.reader import make_reader

    with open(full_bag / 'full_0.mcap', 'rb') as f:
        reader = make_reader(f)
        assert reader.get_header().profile == 'ros2'
        summary = reader.get_summary()
        assert summary is not None
        schemas = {s.name: s for s in summary.schemas.values()}
        state = schemas['auv_msgs/msg/VehicleState']
        assert state.encoding == 'ros2msg'
        text = state.data.decode()
        assert text.startswith('# Vehicle state in Fossen')  # the .msg text itself
        assert '\n' + '=' * 80 + '\nMSG: std_msgs/Header\n' in text
        assert 'MSG: builtin_interfaces/Time' in text
        channels = list(summary.channels.values())
        assert {c.message_encoding for c in channels} == {'cdr'}
        assert all('reliability: reliable' in c.metadata['offered_qos_profiles']
                   for c in channels)
        assert summary.statistics.message_count == N_STATE * 3 + 3 * N_STATE // 5 + 3


@pytest.mark.parametrize('topic', ALL_TOPICS)
def test_round_trip_every_type(full_bag: pathlib.Path, topic: str) -> None:
    arrays = bag.read_arrays(full_bag, [topic])
    slow = bag.read_arrays(full_bag, [topic], fast=False)
    arr = arrays[topic]
    assert arr.dtype == slow[topic].dtype
    np.testing.assert_array_equal(arr, slow[topic])
    assert arr.dtype.names[:2] == ('t', 't_log')
    if topic == STATE:
        assert len(arr) == N_STATE
        i = np.arange(N_STATE)
        np.testing.assert_allclose(arr['t'], 100.0 + 0.02 * i, atol=1e-9)
        np.testing.assert_array_equal(arr['z'], i + 2 / 16)
        np.testing.assert_array_equal(arr['r'], i + 11 / 16)
        np.testing.assert_allclose(arr['t_log'], 1.0 + 0.02 * i, atol=1e-9)
    elif topic == '/auv/hydrodynamic_forces':
        np.testing.assert_array_equal(arr['coriolis_force_z'], 10 * np.arange(N_STATE) + 2)
        np.testing.assert_array_equal(arr['actuators_torque_z'], 0.5 * np.arange(N_STATE) + 5)
    elif topic == '/clock':
        np.testing.assert_allclose(arr['clock'], 100.0 + 0.02 * np.arange(N_STATE), atol=1e-9)
        np.testing.assert_array_equal(arr['t'], arr['t_log'])  # no header: t is the log time
    elif topic == '/auv/thrust_command':
        np.testing.assert_allclose(arr['value'], 0.01 * np.arange(0, N_STATE, 5) + 2)
    elif topic == '/auv/depth_command':
        np.testing.assert_array_equal(arr['data'], [5.0, 105.0, 205.0])


def test_read_messages_decodes_and_filters(full_bag: pathlib.Path) -> None:
    msgs = list(bag.read_messages(full_bag, [STATE, '/auv/depth_command']))
    assert len(msgs) == N_STATE + 3
    states = [m for m in msgs if m.topic == STATE]
    assert states[7].msgtype == 'auv_msgs/msg/VehicleState'
    assert states[7].msg.z == 7 + 2 / 16
    assert states[7].msg.header.frame_id == 'x'
    assert states[7].log_time == 1_000_000_000 + 7 * 20_000_000


def test_bare_mcap_and_uncompressed(tmp_path: pathlib.Path) -> None:
    path = tmp_path / 'bare.mcap'
    write_full_bag(path, compression='none')
    assert path.is_file() and not (tmp_path / 'metadata.yaml').exists()
    arr = bag.read_arrays(path, [STATE])[STATE]
    assert len(arr) == N_STATE
    assert bag.bag_topics(path)[STATE] == 'auv_msgs/msg/VehicleState'


def test_rosbags_and_mcap_read_our_bags(full_bag: pathlib.Path) -> None:
    from rosbags.rosbag2 import Reader

    ts = bag.typestore()
    with Reader(full_bag) as reader:
        assert {c.topic for c in reader.connections} == set(ALL_TOPICS)
        conns = [c for c in reader.connections if c.topic == STATE]
        zs = [ts.deserialize_cdr(raw, c.msgtype).z for c, _, raw in reader.messages(conns)]
    assert zs == [i + 2 / 16 for i in range(N_STATE)]

    from mcap.reader import make_reader

    with open(full_bag / 'full_0.mcap', 'rb') as f:
        count = sum(1 for _ in make_reader(f).iter_messages(topics=[STATE]))
    assert count == N_STATE


def test_raw_bytes_are_written_verbatim(tmp_path: pathlib.Path) -> None:
    ts = bag.typestore()
    raw = bytes(ts.serialize_cdr(_state(3), 'auv_msgs/msg/VehicleState'))
    with bag.BagWriter(tmp_path / 'raw') as w:
        w.add_topic(STATE, 'auv_msgs/msg/VehicleState')
        w.write(STATE, raw, log_time_ns=5)
    (msg,) = list(bag.read_messages(tmp_path / 'raw'))
    assert msg.data == raw and msg.log_time == 5


@pytest.mark.parametrize('compression', ['zstd', 'none'])
def test_truncated_bag_keeps_every_whole_message(tmp_path: pathlib.Path,
                                                compression: str) -> None:
    src = tmp_path / 'whole.mcap'
    write_full_bag(src, compression=compression)
    data = src.read_bytes()
    clean = bag.read_arrays(src, [STATE])[STATE]
    previous = -1
    for frac in (0.1, 0.37, 0.5, 0.83, 0.97):
        cut = int(len(data) * frac)
        bad = tmp_path / f'cut_{cut}.mcap'
        bad.write_bytes(data[:cut])
        with pytest.raises(BagError, match=rf'bag {bad} is truncated at byte \d+ .*: '
                                           r'\d+ whole messages before the damage were read'):
            bag.read_arrays(bad, [STATE])
        got = bag.read_arrays(bad, [STATE], allow_truncated=True)
        assert got.truncated and 'truncated' in got.damage
        arr = got[STATE]
        assert 0 < len(arr) <= len(clean)
        assert len(arr) < len(clean) or frac > 0.9  # the last cut falls in the summary
        np.testing.assert_array_equal(arr, clean[:len(arr)])  # a prefix, exact
        assert len(arr) >= previous
        previous = len(arr)
        msgs = []
        with pytest.raises(BagError, match='truncated'):
            for m in bag.read_messages(bad, decode=False):
                msgs.append(m)
        assert sum(m.topic == STATE for m in msgs) == len(arr)
    # No compression: each message sits verbatim in the file, so the exact number of whole
    # messages before a cut is known; a cut inside a chunk keeps the chunk's whole messages.
    if compression == 'none':
        ends, pos = [], 0
        for m in bag.read_messages(src, decode=False):
            pos = data.index(m.data, pos) + len(m.data)
            ends.append(pos)
        cut = int(len(data) * 0.5)
        n_before = sum(e <= cut for e in ends)
        bad = tmp_path / 'mid.mcap'
        bad.write_bytes(data[:cut])
        got = bag.read_arrays(bad, ALL_TOPICS, allow_truncated=True)
        assert sum(len(a) for a in got.values()) == n_before
        assert f': {n_before} whole messages' in got.damage


def test_missing_summary_only(tmp_path: pathlib.Path) -> None:
    """A recorder killed after its last flush: data complete, no summary or footer."""
    src = tmp_path / 'whole.mcap'
    write_full_bag(src)
    data = src.read_bytes()
    footer_at = len(data) - 8 - (1 + 8 + 20)
    (summary_offset,) = np.frombuffer(data[footer_at + 9:footer_at + 17], '<u8')
    cut = data[:int(summary_offset)]
    bad = tmp_path / 'nosummary.mcap'
    bad.write_bytes(cut)
    with pytest.raises(BagError, match=rf'truncated at byte {len(cut)} .*no footer.*: '
                                       rf'{N_STATE * 3 + 3 * N_STATE // 5 + 3} whole messages'):
        bag.read_arrays(bad, [STATE])
    got = bag.read_arrays(bad, [STATE], allow_truncated=True)
    assert len(got[STATE]) == N_STATE


def test_garbage_bytes_are_corruption(tmp_path: pathlib.Path) -> None:
    src = tmp_path / 'whole.mcap'
    write_full_bag(src)
    data = bytearray(src.read_bytes())
    at = len(data) // 2
    data[at:at + 64] = b'\xa5' * 64
    bad = tmp_path / 'garbage.mcap'
    bad.write_bytes(bytes(data))
    with pytest.raises(BagError, match=rf'bag {bad} is (corrupt|truncated) at byte \d+'):
        bag.read_arrays(bad, [STATE])
    got = bag.read_arrays(bad, [STATE], allow_truncated=True)
    clean = bag.read_arrays(src, [STATE])[STATE]
    assert 0 < len(got[STATE]) < N_STATE
    np.testing.assert_array_equal(got[STATE], clean[:len(got[STATE])])

    not_mcap = tmp_path / 'junk.mcap'
    not_mcap.write_bytes(b'hello world, not a bag at all')
    with pytest.raises(BagError, match='is not an MCAP file'):
        bag.read_arrays(not_mcap, [STATE])


def test_crashed_recording_without_metadata(tmp_path: pathlib.Path) -> None:
    """A bag directory whose recorder died: no metadata.yaml, file without summary."""
    write_full_bag(tmp_path / 'run')
    (tmp_path / 'run' / 'metadata.yaml').unlink()
    arr = bag.read_arrays(tmp_path / 'run', [STATE])[STATE]
    assert len(arr) == N_STATE


def test_missing_topic_names_topic_and_lists_present(full_bag: pathlib.Path) -> None:
    with pytest.raises(BagError, match=r'topic /auv/odom is not in bag .*full \(topics present: '
                                       r'/auv/bar_command, .*/clock\)'):
        bag.read_arrays(full_bag, ['/auv/odom'])
    with pytest.raises(BagError, match='topic /nope is not in bag'):
        list(bag.read_messages(full_bag, ['/nope']))


def test_missing_bag(tmp_path: pathlib.Path) -> None:
    with pytest.raises(BagError, match=f'bag {tmp_path / "absent"} does not exist'):
        bag.read_arrays(tmp_path / 'absent', [STATE])
    assert issubclass(BagError, ValueError) and BagError.__module__.startswith('auv_')


def test_out_of_order_stamps(tmp_path: pathlib.Path) -> None:
    with bag.BagWriter(tmp_path / 'ooo') as w:
        for i in [0, 1, 2, 3, 5, 4, 6]:
            w.write(STATE, _state(i), log_time_ns=1000 + i)
    with pytest.raises(BagError, match=r'topic /auv/state in bag .*ooo: time stamps go back at '
                                       r'message 5 \(100\.100000000 s, then 100\.080000000 s\)'):
        bag.read_arrays(tmp_path / 'ooo', [STATE])
    assert len(bag.read_arrays(tmp_path / 'ooo', [STATE], check_order=False)[STATE]) == 7


def test_progress_reports_bytes(full_bag: pathlib.Path) -> None:
    seen: list[tuple[int, int]] = []
    bag.read_arrays(full_bag, [STATE], progress=lambda n, total: seen.append((n, total)))
    size = (full_bag / 'full_0.mcap').stat().st_size
    assert seen and seen[-1] == (size, size)
    assert all(a <= b for (a, _), (b, _) in itertools.pairwise(seen))


def test_writer_errors(tmp_path: pathlib.Path) -> None:
    with bag.BagWriter(tmp_path / 'b') as w:
        w.add_topic(STATE, 'auv_msgs/VehicleState')
        with pytest.raises(BagError, match='topic /auv/state is auv_msgs/msg/VehicleState'):
            w.add_topic(STATE, 'std_msgs/msg/Float64')
        with pytest.raises(BagError, match='message type nope/msg/X of topic /x is unknown'):
            w.add_topic('/x', 'nope/msg/X')
        with pytest.raises(BagError, match='topic /y was not declared'):
            w.write('/y', b'\x00\x01\x00\x00')
    with pytest.raises(BagError, match='exists already and is not empty'):
        bag.BagWriter(tmp_path / 'b')


def _mixed_messages(n: int) -> list[tuple[str, object]]:
    """Messages of standard types whose fields sit at offsets that vary per message (frame ids
    of every length mod 8, sequences of 0..5 elements, fields of 1, 2, 4 and 8 bytes)."""
    _, T = _types()
    rng = np.random.default_rng(7)
    out: list[tuple[str, object]] = []
    for i in range(n):
        t = 100.0 + 0.02 * i
        frame = 'f' * int(rng.integers(0, 10))
        k = int(rng.integers(0, 6))
        out.append(('/range', T['sensor_msgs/msg/Range'](
            _header(t, frame), radiation_type=int(rng.integers(0, 2)),
            field_of_view=float(np.float32(rng.normal())), min_range=0.5,
            max_range=float(np.float32(rng.normal())), range=float(np.float32(rng.normal())),
            variance=0.25)))
        out.append(('/scan', T['sensor_msgs/msg/LaserScan'](
            _header(t, frame), angle_min=-1.0, angle_max=float(np.float32(rng.normal())),
            angle_increment=0.5, time_increment=0.0, scan_time=0.125, range_min=0.0,
            range_max=float(np.float32(rng.normal())),
            ranges=rng.normal(size=k).astype(np.float32),
            intensities=rng.normal(size=(k + i) % 3).astype(np.float32))))
        out.append(('/pose', T['geometry_msgs/msg/PoseWithCovarianceStamped'](
            _header(t, frame), T['geometry_msgs/msg/PoseWithCovariance'](
                T['geometry_msgs/msg/Pose'](
                    T['geometry_msgs/msg/Point'](x=float(i), y=rng.normal(), z=rng.normal()),
                    T['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0)),
                rng.normal(size=36)))))
        out.append(('/pressure', T['sensor_msgs/msg/FluidPressure'](
            _header(t, frame), fluid_pressure=rng.normal(), variance=float(i))))
    return out


MIXED_TOPICS = ['/range', '/scan', '/pose', '/pressure']


def test_vectorised_decoder_matches_rosbags_on_varying_offsets(tmp_path: pathlib.Path) -> None:
    msgs = _mixed_messages(120)
    with bag.BagWriter(tmp_path / 'mixed', chunk_size=2048) as w:
        for j, (topic, msg) in enumerate(msgs):
            w.write(topic, msg, log_time_ns=1_000_000_000 + j)
    for topic in MIXED_TOPICS:
        assert layout_of(bag.typestore(), bag.bag_topics(tmp_path / 'mixed')[topic]).vectorisable
        fast = bag.read_arrays(tmp_path / 'mixed', [topic])[topic]
        slow = bag.read_arrays(tmp_path / 'mixed', [topic], fast=False)[topic]
        assert len(fast) == 120 and fast.dtype == slow.dtype
        np.testing.assert_array_equal(fast, slow)
    pose = bag.read_arrays(tmp_path / 'mixed', ['/pose'])['/pose']
    np.testing.assert_array_equal(pose['pose_pose_position_x'], np.arange(120.0))


def _chunk_records(data: bytes) -> list[tuple[int, int]]:
    """(offset, length) of the chunk records of an MCAP file (offset of the opcode, bytes)."""
    found, pos = [], 8
    while pos + 9 <= len(data):
        op = data[pos]
        (length,) = np.frombuffer(data[pos + 1:pos + 9], '<u8')
        if op == 0x06:
            found.append((pos, int(length)))
        if op == 0x02:  # footer
            break
        pos += 9 + int(length)
    return found


@pytest.mark.parametrize('compression', ['zstd', 'lz4', 'none'])
def test_worker_threads_change_nothing(tmp_path: pathlib.Path, compression: str) -> None:
    """Chunks decompressed and checked ahead by worker threads: the same arrays and the same
    damage report as in the calling thread alone, for whole, truncated and corrupt bags."""
    src = tmp_path / 'whole.mcap'
    write_full_bag(src, compression=compression)
    data = src.read_bytes()
    bad_files = [src]
    for frac in (0.2, 0.55, 0.9):
        bad = tmp_path / f'cut_{frac}.mcap'
        bad.write_bytes(data[:int(len(data) * frac)])
        bad_files.append(bad)
    chunks = _chunk_records(data)
    garbage = bytearray(data)
    at, length = chunks[len(chunks) // 3]
    garbage[at + length // 2:at + length // 2 + 16] = b'\x5a' * 16  # inside a chunk
    (tmp_path / 'garbage.mcap').write_bytes(bytes(garbage))
    bad_files.append(tmp_path / 'garbage.mcap')
    for file in bad_files:
        ref = bag.read_arrays(file, ALL_TOPICS, allow_truncated=True, workers=1)
        for workers in (2, 4):
            got = bag.read_arrays(file, ALL_TOPICS, allow_truncated=True, workers=workers)
            assert got.damage == ref.damage
            for topic in ALL_TOPICS:
                np.testing.assert_array_equal(got[topic], ref[topic])
        if file != src:
            assert ref.damage is not None


def test_flipped_byte_in_a_chunk_is_detected(tmp_path: pathlib.Path) -> None:
    """Uncompressed chunks: a changed payload byte decodes fine, only the CRC tells, and it is
    checked by default, on every worker setting."""
    src = tmp_path / 'whole.mcap'
    write_full_bag(src, compression='none')
    data = bytearray(src.read_bytes())
    ts = bag.typestore()
    raw = bytes(ts.serialize_cdr(_state(150, ''), 'auv_msgs/msg/VehicleState'))
    at = bytes(data).index(raw) + len(raw) - 3  # inside the float64 r of state 150
    data[at] ^= 0x01
    bad = tmp_path / 'flipped.mcap'
    bad.write_bytes(bytes(data))
    for workers in (1, 2):
        with pytest.raises(BagError, match=rf'bag {bad} is corrupt at byte \d+ '
                                           r'\(chunk CRC mismatch\)'):
            bag.read_arrays(bad, [STATE], workers=workers)
        got = bag.read_arrays(bad, [STATE], allow_truncated=True, workers=workers)
        assert 0 < len(got[STATE]) <= 150
        assert np.all(got[STATE]['r'] == np.arange(len(got[STATE])) + 11 / 16)


def test_metadata_counts_are_only_a_hint(tmp_path: pathlib.Path) -> None:
    """Arrays are sized from metadata.yaml's message counts: counts too high (a bag cut after
    its metadata was written) or too low give the same arrays as the bag's own messages."""
    write_full_bag(tmp_path / 'run')
    clean = bag.read_arrays(tmp_path / 'run', ALL_TOPICS)
    mcap = tmp_path / 'run' / 'run_0.mcap'
    meta = tmp_path / 'run' / 'metadata.yaml'
    text = meta.read_text()
    assert f'message_count: {N_STATE}\n' in text
    meta.write_text(text.replace(f'message_count: {N_STATE}\n', 'message_count: 7\n'))
    low = bag.read_arrays(tmp_path / 'run', ALL_TOPICS)
    for topic in ALL_TOPICS:
        np.testing.assert_array_equal(low[topic], clean[topic])
    data = mcap.read_bytes()
    mcap.write_bytes(data[:len(data) // 3])
    meta.write_text(text)
    cut = bag.read_arrays(tmp_path / 'run', ALL_TOPICS, allow_truncated=True)
    assert cut.truncated
    assert 0 < len(cut[STATE]) < N_STATE // 2
    for topic in ALL_TOPICS:
        np.testing.assert_array_equal(cut[topic], clean[topic][:len(cut[topic])])


def _killed_recording(path: pathlib.Path, n: int = 400) -> list[tuple[str, int, int, bytes]]:
    """A bag directory as a recorder killed mid-run leaves it: raw CDR messages with publish
    times distinct from their log times, no metadata.yaml, the file cut in its middle.
    Returns the messages written (topic, log time, publish time, bytes), in order."""
    ts, T = _types()
    written = []
    qos = bag.qos_profiles_yaml('best_effort', 'volatile', 10)
    with bag.BagWriter(path, compression='none', chunk_size=2048) as w:
        w.add_topic(STATE, 'auv_msgs/msg/VehicleState')
        w.add_topic('/auv/bar_command', 'auv_msgs/msg/ActuatorSetpoint', qos)
        w.add_topic('/auv/helm_command', 'auv_msgs/msg/ActuatorSetpoint')  # never written
        for i in range(n):
            topic = STATE if i % 4 else '/auv/bar_command'
            msg = (_state(i) if topic == STATE else
                   T['auv_msgs/msg/ActuatorSetpoint'](_header(100.0 + 0.02 * i), 0.001 * i))
            data = bytes(ts.serialize_cdr(msg, msg.__msgtype__))
            log, pub = 5_000_000_000 + i * 10_000_000, 4_000_000_000 + i * 7_000_000
            w.write(topic, data, log, pub)
            written.append((topic, log, pub, data))
    (path / 'metadata.yaml').unlink()
    mcap = path / f'{path.name}_0.mcap'
    data = mcap.read_bytes()
    mcap.write_bytes(data[:len(data) // 2])
    return written


def test_repair_writes_every_whole_message_of_a_killed_recording(tmp_path: pathlib.Path
                                                                  ) -> None:
    from mcap.reader import make_reader
    from rosbags.highlevel import AnyReader

    damaged = tmp_path / 'killed'
    written = _killed_recording(damaged)
    # uncompressed: a message is whole before the cut if its bytes end before it
    cut = (damaged / 'killed_0.mcap').read_bytes()
    whole, pos = 0, 0
    for _, _, _, data in written:
        at = cut.find(data, pos)
        if at < 0:
            break
        whole, pos = whole + 1, at + len(data)
    assert 0 < whole < len(written)
    with pytest.raises(BagError, match='auv bag repair BAG --out NEW'):
        bag.read_arrays(damaged, [STATE])
    report = bag.repair_bag(damaged, tmp_path / 'fixed')
    assert report.messages == whole
    assert report.counts == {STATE: sum(t == STATE for t, *_ in written[:whole]),
                             '/auv/bar_command': sum(t != STATE for t, *_ in written[:whole]),
                             '/auv/helm_command': 0}
    assert report.damage is not None and f': {whole} whole messages before' in report.damage
    assert f'recovered {whole} messages from {damaged}' in report.text()
    with open(tmp_path / 'fixed' / 'fixed_0.mcap', 'rb') as fh:
        reader = make_reader(fh)
        got = [(ch.topic, m.log_time, m.publish_time, bytes(m.data))
               for _, ch, m in reader.iter_messages(log_time_order=False)]
        qos = {ch.topic: ch.metadata['offered_qos_profiles']
               for ch in reader.get_summary().channels.values()}
    assert got == written[:whole]  # bytes, log and publish times unchanged, in order
    assert qos['/auv/bar_command'] == bag.qos_profiles_yaml('best_effort', 'volatile', 10)
    with AnyReader([tmp_path / 'fixed']) as reader:  # rosbags takes the repaired bag
        assert sum(1 for _ in reader.messages()) == whole
    # repairing a whole bag copies it
    again = bag.repair_bag(tmp_path / 'fixed', tmp_path / 'copy')
    assert again.damage is None and again.counts == report.counts
    with pytest.raises(BagError, match='exists already'):
        bag.repair_bag(damaged, tmp_path / 'fixed')


def test_corrupt_metadata_is_one_line(tmp_path: pathlib.Path) -> None:
    write_full_bag(tmp_path / 'run')
    (tmp_path / 'run' / 'metadata.yaml').write_text('rosbag2_bagfile_information:\n  topics: [\n')
    for call in (lambda: bag.bag_topics(tmp_path / 'run'),
                 lambda: bag.read_arrays(tmp_path / 'run', [STATE])):
        with pytest.raises(BagError) as err:
            call()
        assert '\n' not in str(err.value)
        assert str(err.value).startswith(f'bag metadata {tmp_path / "run" / "metadata.yaml"} '
                                         'is unreadable: ')
    # the repair reads the MCAP file without it
    report = bag.repair_bag(tmp_path / 'run', tmp_path / 'fixed')
    assert report.damage is None and report.counts[STATE] == N_STATE


def test_auv_bag_info_and_repair_commands(tmp_path: pathlib.Path) -> None:
    import subprocess
    import sys

    damaged = tmp_path / 'killed'
    _killed_recording(damaged)

    def auv(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, '-m', 'auv_bringup.cli', 'bag', *args],
                              capture_output=True, text=True, timeout=120)

    info = auv('info', str(damaged))
    assert info.returncode == 0, info.stderr
    lines = info.stdout.splitlines()
    assert lines[0].startswith('/auv/bar_command  auv_msgs/msg/ActuatorSetpoint  ')
    assert lines[1] == '/auv/helm_command  auv_msgs/msg/ActuatorSetpoint  0 messages  no message'
    assert lines[-1].startswith(f'damaged: bag {damaged / "killed_0.mcap"} is truncated at byte')
    fixed = auv('repair', str(damaged), '--out', str(tmp_path / 'fixed'))
    assert fixed.returncode == 0, fixed.stderr
    assert fixed.stderr.startswith('recovered ') and 'what followed it is lost' in fixed.stderr
    assert 'damaged' not in auv('info', str(tmp_path / 'fixed')).stdout
    again = auv('repair', str(damaged), '--out', str(tmp_path / 'fixed'))
    assert again.returncode == 1 and again.stderr.startswith('error: bag directory ')
    assert again.stderr.count('\n') == 1
