"""Scanning an MCAP file front to back, record by record, stopping at the first bad record.

The records are parsed by the ``mcap`` package (:mod:`mcap.records`: header fields, schemas,
channels, chunks, unchunked messages) from the file as it is read, with no seeking: a file
cut short or damaged gives every block of whole messages before the damage, then
:class:`~auv_bag.damage.Damage`. This module keeps only the framing loop (opcode and length of
each record, checked against the file's size before a record is read) and the damage checks
``mcap``'s :class:`~mcap.stream_reader.StreamReader` does not make (it reads a record that
runs past the end of the file as a short one, cannot resume after a bad chunk, and parses every
message index entry into a Python tuple, which costs more than the whole columnar decode;
message indexes and chunk contents are located with numpy in :mod:`auv_bag.locate`).

Chunks are decompressed and CRC-checked by worker threads (the codecs and ``zlib.crc32``
release the GIL) a few chunks ahead of the consumer; blocks are still handed out in file
order, and a bad chunk ends the scan after every block before it.
"""
from __future__ import annotations

import os
import pathlib
import struct
import zlib
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from typing import IO, Any, NamedTuple

import numpy as np
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Chunk, Message
from mcap.writer import MCAP0_MAGIC

from .damage import Damage, partial_chunk
from .errors import BagError
from .locate import (
    RECORD_PREFIX,
    Block,
    Definitions,
    RecordBody,
    UnreadableRecord,
    indexed_records,
    loose_block,
    walk_chunk,
)

__all__ = ['ProgressCallback', 'Scanner', 'default_workers']

ProgressCallback = Callable[[int, int], None]
"""Called as ``progress(bytes_read, bytes_total)`` while a bag is read."""

_KNOWN_OPS = frozenset(int(op) for op in Opcode)


def default_workers() -> int:
    """Threads that decompress and check chunks by default: the CPU count, at most 4."""
    return max(1, min(4, os.cpu_count() or 1))


class _Pending(NamedTuple):
    """A block read but not yet handed out: loose messages (``block``) or a chunk whose
    decompression and CRC check run in the background (``inflated``)."""

    block: Block | None
    inflated: Future[bytes] | None
    pos: int  # file offset of the chunk record
    indexes: list[bytes]  # message index record bodies of the chunk
    buffer: bytearray | None  # holding the chunk record, reused once it is inflated


class Scanner:
    """Reads one MCAP file front to back and hands out its messages block by block.

    Attributes
    ----------
    file
        the file.
    defs
        its schemas and channels, as far as the scan has gone.
    size
        its size (bytes), known once :meth:`blocks` has started.
    workers
        threads that decompress and check chunks (1: the calling thread).
    """

    def __init__(self, file: pathlib.Path, progress: ProgressCallback | None = None,
                 workers: int | None = None) -> None:
        self.file = file
        self.progress = progress
        self.defs = Definitions()
        self.size = 0
        self.workers = default_workers() if workers is None else max(1, int(workers))
        self._pool: ThreadPoolExecutor | None = None
        self._spare: list[bytearray] = []  # read buffers free for the next chunk records

    def blocks(self) -> Iterator[Block]:
        """Blocks of whole messages, in file order; raises :class:`~auv_bag.damage.Damage`
        after the last good one.

        Raises
        ------
        BagError
            the file cannot be opened or is not an MCAP file.
        """
        try:
            fh = open(self.file, 'rb')  # noqa: SIM115
        except OSError as exc:
            raise BagError(f'cannot open bag file {self.file}: {exc.strerror}') from None
        pool = ThreadPoolExecutor(self.workers) if self.workers > 1 else None
        self._pool = pool
        try:
            with fh:
                self.size = os.fstat(fh.fileno()).st_size
                yield from self._records(fh)
        finally:
            self._pool = None
            if pool is not None:
                pool.shutdown(wait=True, cancel_futures=True)

    def _damage(self, kind: str, offset: int, detail: str) -> Damage:
        return Damage(self.file, kind, offset, detail)

    def _records(self, fh: IO[bytes]) -> Iterator[Block]:
        size = self.size
        magic = fh.read(8)
        if magic != MCAP0_MAGIC:
            if len(magic) < 8 and MCAP0_MAGIC.startswith(magic):
                raise self._damage('truncated', len(magic), 'the file ends in the magic bytes')
            raise BagError(f'bag file {self.file} is not an MCAP file (bad magic bytes)')
        pos = 8
        loose: list[Message] = []
        pending: deque[_Pending] = deque()  # in file order
        chunk: list[_Pending] = []  # the last chunk read, while its message indexes follow
        ahead = 2 * self.workers if self._pool is not None else 0  # chunks kept in flight
        seen_data_end = False
        while True:
            head = fh.read(9)
            if len(head) < 9:
                yield from self._take(loose, chunk, pending, 0)
                if not head:
                    where = 'after the data section' if seen_data_end else 'before the summary'
                    raise self._damage('truncated', pos, f'the file ends {where}, no footer')
                raise self._damage('truncated', pos, 'the file ends inside a record header')
            op = head[0]
            length = int.from_bytes(head[1:9], 'little')
            if op not in _KNOWN_OPS and op < 0x80:  # 0x80-0xff: user records, skipped
                yield from self._take(loose, chunk, pending, 0)
                raise self._damage('corrupt', pos, f'unknown record opcode 0x{op:02x}')
            body_start = pos + 9
            if length > size - body_start:
                yield from self._take(loose, chunk, pending, 0)
                if op == Opcode.CHUNK:
                    block = partial_chunk(fh.read(), self.defs)
                    if block is not None:
                        yield block
                raise self._damage('truncated', pos,
                                   f'a record of {length} bytes runs past the end of the file '
                                   f'({size} bytes)')
            if op == Opcode.MESSAGE:
                message = self._read(Message.read, fh.read(length), length)
                if message is None:
                    yield from self._take(loose, chunk, pending, 0)
                    raise self._damage('corrupt', pos, 'unreadable message record')
                loose.append(message)
            elif op == Opcode.CHUNK:
                yield from self._take(loose, chunk, pending, ahead)
                buffer, view = self._read_into(fh, length)
                record = self._read(Chunk.read, view)
                if record is None:
                    yield from self._take(loose, chunk, pending, 0)
                    raise self._damage('corrupt', pos, 'unreadable chunk header')
                inflated = (self._pool.submit(self._inflate, record, pos) if self._pool
                            else _done(self._inflate, record, pos))
                chunk.append(_Pending(None, inflated, pos, [], buffer))
            elif op == Opcode.MESSAGE_INDEX and chunk:
                chunk[0].indexes.append(fh.read(length))
            elif op in (Opcode.SCHEMA, Opcode.CHANNEL):
                yield from self._take(loose, chunk, pending, 0)
                try:
                    self.defs.add(op, fh.read(length))
                except UnreadableRecord:
                    raise self._damage('corrupt', pos, 'unreadable schema or channel') from None
            elif op == Opcode.FOOTER:
                yield from self._take(loose, chunk, pending, 0)
                fh.seek(length, 1)
                tail = fh.read(8)
                if tail != MCAP0_MAGIC:
                    raise self._damage('truncated' if len(tail) < 8 else 'corrupt',
                                       body_start + length, 'no closing magic after the footer')
                if self.progress:
                    self.progress(size, size)
                return
            else:
                if op == Opcode.DATA_END:
                    seen_data_end = True
                fh.seek(length, 1)
            pos = body_start + length
            if self.progress and op == Opcode.CHUNK:
                self.progress(pos, size)

    def _read_into(self, fh: IO[bytes], length: int) -> tuple[bytearray, memoryview]:
        """Read ``length`` bytes into a spare buffer (fresh memory costs page faults): the
        buffer and a view of what was read (shorter if the file shrank meanwhile)."""
        buffer = self._spare.pop() if self._spare else bytearray()
        if len(buffer) < length:
            buffer = bytearray(length)
        view = memoryview(buffer)[:length]
        got = fh.readinto(view)  # type: ignore[attr-defined]
        return buffer, view[:got or 0]

    @staticmethod
    def _read(parse: Callable[..., Any], body: bytes | memoryview, *args: Any) -> Any:
        """A record body parsed by ``mcap`` (``parse(stream, *args)``), or None when a field
        runs past the body (a record may be longer than its fields: the rest is skipped)."""
        try:
            return parse(RecordBody(body), *args)
        except (McapError, struct.error, UnicodeDecodeError):
            return None

    def _take(self, loose: list[Message], chunk: list[_Pending], pending: deque[_Pending],
              keep: int) -> Iterator[Block]:
        """Queue the messages read so far (loose ones, then the last chunk) and hand out the
        oldest queued blocks until at most ``keep`` chunks remain in flight."""
        if loose:
            pending.append(_Pending(loose_block(loose), None, 0, [], None))
            loose.clear()
        if chunk:
            pending.append(chunk.pop())
        while len(pending) > keep or (pending and pending[0].block is not None):
            item = pending.popleft()
            if item.block is not None:
                yield item.block
                continue
            try:
                data = item.inflated.result()  # type: ignore[union-attr]
            except BaseException:
                for rest in pending:
                    if rest.inflated is not None:
                        rest.inflated.cancel()
                pending.clear()
                raise
            if item.buffer is not None:
                self._spare.append(item.buffer)
            yield self._locate(data, item.pos, item.indexes)

    def _inflate(self, chunk: Chunk, pos: int) -> bytes:
        """The uncompressed data of a chunk, its size and CRC checked (runs in a worker
        thread; raises :class:`~auv_bag.damage.Damage`)."""
        usize, comp = chunk.uncompressed_size, chunk.compression
        try:
            data = _decompress(chunk.data, comp, usize)
        except Exception as exc:  # each codec raises its own type
            raise self._damage('corrupt', pos, f'chunk does not decompress ({comp}: {exc})'
                               ) from None
        if len(data) != usize:
            raise self._damage('corrupt', pos, f'chunk is {len(data)} bytes, expected {usize}')
        if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
            raise self._damage('corrupt', pos, 'chunk CRC mismatch')
        return data

    def _locate(self, data: bytes, pos: int, indexes: list[bytes]) -> Block:
        """The messages of an uncompressed chunk, through its message indexes if they describe
        it exactly, else record by record (which also reads the definitions it holds)."""
        block = indexed_records(data, indexes) if indexes else None
        if block is not None and len(block.offset) and block.offset[0] > RECORD_PREFIX:
            # Schemas and channels before the first indexed message: walk that part.
            head, complete = walk_chunk(data[:int(block.offset[0]) - RECORD_PREFIX], self.defs)
            if not complete:
                raise self._damage('corrupt', pos, 'a record inside a chunk is cut short')
            if len(head.offset):
                block = Block(data, *(np.concatenate([x, y]) for x, y in
                                      zip(head[1:5], block[1:5])))
        if block is None:
            block, complete = walk_chunk(data, self.defs)
            if not complete:
                raise self._damage('corrupt', pos, 'a record inside a chunk is cut short')
        return block


def _done(fn: Callable[..., bytes], *args: Any) -> Future[bytes]:
    """A finished future holding ``fn(*args)`` or the exception it raised."""
    fut: Future[bytes] = Future()
    try:
        fut.set_result(fn(*args))
    except Exception as exc:  # re-raised where the result is taken, in file order
        fut.set_exception(exc)
    return fut


def _decompress(data: bytes | memoryview, comp: str, usize: int) -> bytes:
    """A chunk's data decompressed (``''``: a copy of it), at most ``usize`` bytes."""
    if comp == '':
        return bytes(data)
    if comp == 'zstd':
        import zstandard

        out: bytes = zstandard.ZstdDecompressor().decompress(data, max_output_size=usize)
        return out
    if comp == 'lz4':
        import lz4.frame

        frame: bytes = lz4.frame.decompress(data)
        return frame
    raise ValueError(f'unknown compression {comp!r}')
