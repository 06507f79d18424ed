"""auv_bag's container scan on files other writers make, and on damaged records: unchunked
MCAP files (loose message records), schema and chunk records whose fields lie, and the
deprecated ``auv_ident.bag`` re-export."""
from __future__ import annotations

import ast
import importlib
import pathlib
import struct
import sys

import numpy as np
import pytest
from mcap.writer import Writer

import auv_bag
from auv_bag.errors import BagError

FLOAT64 = 'std_msgs/msg/Float64'
TOPIC = '/depth'
N = 40


def _cdr_float64(value: float) -> bytes:
    """A std_msgs/Float64 in CDR by hand: encapsulation CDR_LE, then the float64."""
    return b'\x00\x01\x00\x00' + struct.pack('<d', value)


def _write_unchunked(path: pathlib.Path) -> list[bytes]:
    """An MCAP file without chunks, written by mcap's own writer (as some loggers write them);
    returns the CDR payloads in file order."""
    payloads = [_cdr_float64(0.25 * i - 3.0) for i in range(N)]
    with open(path, 'wb') as fh:
        writer = Writer(fh, use_chunking=False)
        writer.start(profile='ros2', library='test')
        sid = writer.register_schema(FLOAT64, 'ros2msg', b'float64 data\n')
        cid = writer.register_channel(TOPIC, 'cdr', sid)
        for i, data in enumerate(payloads):
            writer.add_message(cid, log_time=1_000 + i, data=data, publish_time=1_000 + i)
        writer.finish()  # type: ignore[no-untyped-call]
    return payloads


def _records(data: bytes) -> list[tuple[int, int, int]]:
    """(offset, opcode, body length) of the top-level records of an MCAP file."""
    out, pos = [], 8
    while pos + 9 <= len(data) - 8:
        op = data[pos]
        (length,) = struct.unpack_from('<Q', data, pos + 1)
        out.append((pos, op, length))
        pos += 9 + length
    return out


def test_unchunked_file_reads_every_message(tmp_path: pathlib.Path) -> None:
    path = tmp_path / 'flat.mcap'
    _write_unchunked(path)
    arr = auv_bag.read_arrays(path, [TOPIC])[TOPIC]
    np.testing.assert_array_equal(arr['data'], 0.25 * np.arange(N) - 3.0)
    np.testing.assert_array_equal(arr['t_log'], (1_000 + np.arange(N)) * 1e-9)
    msgs = list(auv_bag.read_messages(path))
    assert [m.msg.data for m in msgs] == [0.25 * i - 3.0 for i in range(N)]


def test_unchunked_file_cut_keeps_the_messages_before_the_cut(tmp_path: pathlib.Path) -> None:
    src = tmp_path / 'flat.mcap'
    payloads = _write_unchunked(src)
    data = src.read_bytes()
    # Each payload is unique and lies verbatim in the file: the whole messages before a cut
    # are those whose payload ends before it.
    ends = [data.index(p) + len(p) for p in payloads]
    cut = (ends[16] + ends[17]) // 2  # inside message 17
    bad = tmp_path / 'cut.mcap'
    bad.write_bytes(data[:cut])
    message_17 = max(off for off, op, _ in _records(data) if op == 0x05 and off < ends[17])
    with pytest.raises(BagError, match=rf'bag {bad} is truncated at byte {message_17} .*: '
                                       r'17 whole messages before the damage were read'):
        auv_bag.read_arrays(bad, [TOPIC])
    got = auv_bag.read_arrays(bad, [TOPIC], allow_truncated=True)[TOPIC]
    np.testing.assert_array_equal(got['data'], 0.25 * np.arange(17) - 3.0)


def test_schema_whose_name_runs_past_its_record_is_corrupt(tmp_path: pathlib.Path) -> None:
    src = tmp_path / 'flat.mcap'
    _write_unchunked(src)
    data = bytearray(src.read_bytes())
    (at, op, _), = [r for r in _records(bytes(data)) if r[1] == 0x03][:1]
    assert op == 0x03
    data[at + 9 + 2:at + 9 + 6] = struct.pack('<I', 10_000)  # name length: past the record
    bad = tmp_path / 'schema.mcap'
    bad.write_bytes(bytes(data))
    with pytest.raises(BagError, match=rf'bag {bad} is corrupt at byte {at} '
                                       r'\(unreadable schema or channel\): 0 whole messages'):
        auv_bag.read_arrays(bad, [TOPIC])


def test_chunk_whose_data_length_lies_is_corrupt(tmp_path: pathlib.Path) -> None:
    """A chunk record whose inner data length exceeds the record: the whole messages of the
    chunks before it are kept, the bad chunk is named by its byte offset."""
    path = tmp_path / 'run'
    with auv_bag.BagWriter(path, chunk_size=512, compression='none') as w:
        w.add_topic(TOPIC, FLOAT64)
        for i in range(N):
            w.write(TOPIC, _cdr_float64(float(i)), log_time_ns=10 + i)
    mcap = path / 'run_0.mcap'
    data = bytearray(mcap.read_bytes())
    chunks = [(off, n) for off, op, n in _records(bytes(data)) if op == 0x06]
    assert len(chunks) >= 3
    at, _ = chunks[1]
    # Uncompressed, each unique payload lies verbatim in its chunk: those before chunk 1.
    before = sum(bytes(data).index(_cdr_float64(float(i))) < at for i in range(N))
    # chunk body: start, end, size (8 each), crc (4), compression string (4 + 0), data length
    data[at + 9 + 32:at + 9 + 40] = struct.pack('<Q', 1 << 40)
    mcap.write_bytes(bytes(data))
    with pytest.raises(BagError, match=rf'is corrupt at byte {at} \(unreadable chunk header\): '
                                       rf'{before} whole messages'):
        auv_bag.read_arrays(path, [TOPIC])
    got = auv_bag.read_arrays(path, [TOPIC], allow_truncated=True)[TOPIC]
    assert len(got) == before > 0
    np.testing.assert_array_equal(got['data'], np.arange(before, dtype=float))


def test_deprecated_module_only_re_exports() -> None:
    sys.modules.pop('auv_ident.bag', None)
    with pytest.warns(DeprecationWarning, match='import from auv_bag'):
        old = importlib.import_module('auv_ident.bag')
    assert old.read_arrays is auv_bag.read_arrays and old.BagWriter is auv_bag.BagWriter
    from auv_ident.errors import BagError as IdentBagError

    assert IdentBagError is BagError
    tree = ast.parse(pathlib.Path(old.__file__ or '').read_text())
    logic = [type(n).__name__ for n in ast.walk(tree)
             if isinstance(n, (ast.FunctionDef, ast.ClassDef, ast.For, ast.While, ast.If))]
    assert logic == []
