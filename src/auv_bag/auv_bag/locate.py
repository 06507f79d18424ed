"""Where the messages of an MCAP chunk lie: channel, log time and the span of each message's CDR
data, as int64 arrays over the uncompressed chunk (a :class:`Block`), without a Python object
per message.

Schema and channel records are parsed by the ``mcap`` package's record classes
(:class:`mcap.records.Schema`, :class:`mcap.records.Channel`). Message records and message
index records are located here with numpy, because ``mcap``'s parsers build one Python object
(or tuple) per message: on an hour of 50 Hz state (180 000 messages) its
:class:`~mcap.records.MessageIndex` reader alone takes about twice as long as this package's
whole bag-to-arrays decode (``bench/bench_bag.py``), and its chunk reader
(:func:`mcap.stream_reader.breakup_chunk`) longer still.
"""
from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import IO, NamedTuple, cast

import numpy as np
from mcap.data_stream import ReadDataStream
from mcap.exceptions import EndOfFile, McapError
from mcap.opcode import Opcode
from mcap.records import Channel, Message, Schema

from .columnar import gather

__all__ = ['Block', 'ChannelInfo', 'Definitions', 'RecordBody', 'UnreadableRecord',
           'indexed_records', 'loose_block', 'walk_chunk']

MSG_HEAD_SIZE = 22  # channel id (2), sequence (4), log time (8), publish time (8)
RECORD_PREFIX = 9 + MSG_HEAD_SIZE  # opcode, length and message head before the CDR data
_U8 = struct.Struct('<Q')
_OP_MESSAGE = int(Opcode.MESSAGE)
_MSG_HEAD = struct.Struct('<HIQQ')
_MSG_RECORD_HEAD = np.dtype([('op', 'u1'), ('length', '<u8'), ('channel', '<u2'),
                             ('sequence', '<u4'), ('log_time', '<u8'), ('publish_time', '<u8')])


class Block(NamedTuple):
    """Whole messages found in one chunk (or run of loose message records); int64 arrays."""

    data: bytes
    channel: np.ndarray
    log_time: np.ndarray  # ns
    offset: np.ndarray  # start of the CDR data in ``data`` (bytes)
    length: np.ndarray  # CDR data length (bytes)
    #: publish times (ns) of loose messages; None in a chunk, where each message record holds
    #: its publish time in the 8 bytes before its data (see :func:`publish_times`)
    publish_time: np.ndarray | None = None


def publish_times(block: Block) -> np.ndarray:
    """The publish times (ns, int64) of a block's messages."""
    if block.publish_time is not None:
        return block.publish_time
    if not len(block.offset):
        return np.empty(0, np.int64)
    return gather(block.data, block.offset - 8, 8).view('<u8')[:, 0].astype(np.int64)


class ChannelInfo(NamedTuple):
    """A channel of an MCAP file (its topic, schema id and message encoding)."""

    topic: str
    schema_id: int
    encoding: str
    metadata: tuple[tuple[str, str], ...] = ()  # e.g. ('offered_qos_profiles', '<yaml>')


class UnreadableRecord(Exception):
    """A schema or channel record whose fields do not fit in it (internal)."""


class _View:
    """A read-only file over a buffer whose reads are memoryview slices (no copy)."""

    def __init__(self, body: bytes | bytearray | memoryview) -> None:
        self._view = memoryview(body)
        self._pos = 0

    def read(self, length: int) -> memoryview:
        out = self._view[self._pos:self._pos + length]
        self._pos += len(out)
        return out


class RecordBody(ReadDataStream):
    """One record body as ``mcap``'s record parsers read it, without copying: byte fields
    (a chunk's data, a message's data) are memoryviews of the body; a field running past the
    end of the body raises :class:`mcap.exceptions.EndOfFile` (the stock stream returns it
    short)."""

    def __init__(self, body: bytes | bytearray | memoryview) -> None:
        super().__init__(cast(IO[bytes], _View(body)))

    def read(self, length: int) -> bytes:
        data = super().read(length)
        if len(data) != length:
            raise EndOfFile()
        return data


class Definitions:
    """The schemas and channels of one MCAP file, as its records are met."""

    def __init__(self) -> None:
        self.schemas: dict[int, tuple[str, str, str]] = {}  # id -> name, encoding, text
        self.channels: dict[int, ChannelInfo] = {}

    def add(self, op: int, body: bytes | memoryview) -> None:
        """Parse a schema or channel record body.

        Raises
        ------
        UnreadableRecord
            a field runs past the body, or a text is not UTF-8.
        """
        stream = RecordBody(body)
        try:
            if op == Opcode.SCHEMA:
                schema = Schema.read(stream)
                self.schemas[schema.id] = (schema.name, schema.encoding, str(schema.data, 'utf-8'))
            else:
                chan = Channel.read(stream)
                self.channels[chan.id] = ChannelInfo(chan.topic, chan.schema_id,
                                                     chan.message_encoding,
                                                     tuple(chan.metadata.items()))
        except (McapError, struct.error, UnicodeDecodeError) as exc:
            raise UnreadableRecord(str(exc)) from None


def walk_chunk(data: bytes, defs: Definitions) -> tuple[Block, bool]:
    """Messages of an uncompressed chunk, record by record (definitions go to ``defs``);
    False if a record is cut short or unreadable (the messages before it are returned).

    A run of message records of equal length (one topic at a fixed message size, the usual
    case) is located vectorised: the next records are assumed to follow at a fixed stride and
    the assumption is checked on every one of them (opcode and length).
    """
    pieces: list[tuple[np.ndarray, ...]] = []
    channel: list[int] = []
    log_time: list[int] = []
    offset: list[int] = []
    length: list[int] = []
    add_c, add_t, add_o, add_l = channel.append, log_time.append, offset.append, length.append
    unpack_len = _U8.unpack_from
    unpack_msg = _MSG_HEAD.unpack_from
    buf = np.frombuffer(data, np.uint8)
    view = memoryview(data)
    n = len(data)
    pos = 0
    prev_len = -1
    same = 0  # message records of equal length in a row
    complete = True
    while pos < n:
        if pos + 9 > n:
            complete = False
            break
        op = data[pos]
        (rlen,) = unpack_len(data, pos + 1)
        start = pos + 9
        end = start + rlen
        if end > n:
            complete = False
            break
        pos = end
        if op == _OP_MESSAGE:
            if rlen < MSG_HEAD_SIZE:
                complete = False
                break
            cid, _, log_ns, _ = unpack_msg(data, start)
            add_c(cid)
            add_t(log_ns)
            add_o(start + MSG_HEAD_SIZE)
            add_l(rlen - MSG_HEAD_SIZE)
            same = same + 1 if rlen == prev_len else 0
            if same >= 8:
                run = _message_run(buf, pos, rlen)
                same = 0
                if run is not None:
                    pieces.append(_lists_to_arrays(channel, log_time, offset, length))
                    channel.clear()
                    log_time.clear()
                    offset.clear()
                    length.clear()
                    pieces.append(run)
                    pos += len(run[0]) * (9 + rlen)
            prev_len = rlen
        elif op in (Opcode.SCHEMA, Opcode.CHANNEL):
            prev_len = -1
            try:
                defs.add(op, view[start:end])
            except UnreadableRecord:
                complete = False
                break
        else:
            prev_len = -1
    pieces.append(_lists_to_arrays(channel, log_time, offset, length))
    cols = [np.concatenate([p[i] for p in pieces]) for i in range(4)]
    return Block(data, *cols), complete


def indexed_records(data: bytes, indexes: Sequence[bytes]) -> Block | None:
    """Messages of an uncompressed chunk located through its message index record bodies.

    Every indexed record is checked (opcode, channel, log time, no overlap); from the first
    indexed record on, the records must tile the chunk with no gap, since a gap may hold a
    schema, a channel or an unindexed message (the part before the first indexed record is
    walked by the caller). Returns None when the index does not describe the chunk exactly
    (the caller then walks the chunk record by record).
    """
    cids, pairs = [], []
    try:
        for body in indexes:
            cid, nbytes = struct.unpack_from('<HI', body, 0)
            if nbytes % 16 or 6 + nbytes > len(body):
                return None
            pair = np.frombuffer(body, '<u8', count=nbytes // 8, offset=6).reshape(-1, 2)
            pairs.append(pair)
            cids.append(np.full(len(pair), cid, np.int64))
    except struct.error:
        return None
    if not pairs:
        return None
    pair = pairs[0] if len(pairs) == 1 else np.concatenate(pairs)
    offs = pair[:, 1].astype(np.int64)
    log = pair[:, 0]
    chan = cids[0] if len(cids) == 1 else np.concatenate(cids)
    if len(offs) > 1 and not np.all(offs[1:] > offs[:-1]):
        order = np.argsort(offs, kind='stable')
        offs, log, chan = offs[order], log[order], chan[order]
    head = _MSG_RECORD_HEAD.itemsize
    if len(offs) == 0 or offs[0] < 0 or offs[-1] + head > len(data):
        return None
    rec = gather(data, offs, head).view(_MSG_RECORD_HEAD)[:, 0]
    ends = offs + 9 + rec['length'].astype(np.int64)
    if not (np.all(rec['op'] == _OP_MESSAGE) and np.all(rec['channel'] == chan)
            and np.all(rec['log_time'] == log) and np.all(rec['length'] >= MSG_HEAD_SIZE)
            and np.all(ends[:-1] == offs[1:]) and ends[-1] == len(data)):
        return None
    return Block(data, chan, log.astype(np.int64), offs + 9 + MSG_HEAD_SIZE,
                 rec['length'].astype(np.int64) - MSG_HEAD_SIZE)


def loose_block(messages: Sequence[Message]) -> Block:
    """The messages of an unchunked run of message records (parsed by ``mcap``), as a block."""
    sizes = np.fromiter((len(m.data) for m in messages), np.int64, len(messages))
    offset = np.zeros(len(messages), np.int64)
    np.cumsum(sizes[:-1], out=offset[1:])
    return Block(b''.join(m.data for m in messages),
                 np.fromiter((m.channel_id for m in messages), np.int64, len(messages)),
                 np.fromiter((m.log_time for m in messages), np.int64, len(messages)),
                 offset, sizes,
                 np.fromiter((m.publish_time for m in messages), np.int64, len(messages)))


def _lists_to_arrays(*lists: list[int]) -> tuple[np.ndarray, ...]:
    return tuple(np.asarray(x, np.int64) for x in lists)


def _message_run(buf: np.ndarray, pos: int, rlen: int) -> tuple[np.ndarray, ...] | None:
    """Message records of length ``rlen`` following each other from byte ``pos`` of an
    uncompressed chunk: (channel, log time, data offset, data length) arrays, or None.

    The record heads are seen at a fixed stride (a strided view, no copy) and every one is
    checked (opcode and length) before it is accepted.
    """
    stride = 9 + rlen
    head = _MSG_RECORD_HEAD.itemsize  # 31 bytes
    avail = (len(buf) - pos) // stride
    if avail == 0:
        return None
    heads = np.lib.stride_tricks.as_strided(buf[pos:], shape=(avail, head),
                                            strides=(stride, 1), writeable=False)
    window = 64
    count = 0
    parts = []
    while count < avail:
        k = min(window, avail - count)
        rec = np.ascontiguousarray(heads[count:count + k]).view(_MSG_RECORD_HEAD)[:, 0]
        good = (rec['op'] == _OP_MESSAGE) & (rec['length'] == rlen)
        if good.all():
            parts.append(rec)
            count += k
            window *= 4
            continue
        n_good = int(np.argmin(good))
        parts.append(rec[:n_good])
        count += n_good
        break
    if count == 0:
        return None
    rec = np.concatenate(parts)
    body = pos + np.arange(count, dtype=np.int64) * stride + 9
    return (rec['channel'].astype(np.int64), rec['log_time'].astype(np.int64),
            body + MSG_HEAD_SIZE, np.full(count, rlen - MSG_HEAD_SIZE, np.int64))
