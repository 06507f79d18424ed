"""Damage: how a damaged MCAP file is reported, and what is saved from a chunk cut short.

A bag cut short (a recorder killed mid-write, a copy interrupted) or holding garbage bytes is
read record by record from the start without seeking; every whole message before the first
bad record is kept, and the damage is reported as one line naming the file, the byte offset of
the bad record and how many whole messages were read before it. A chunk cut by the end of the
file gives the whole messages at the start of its compressed stream (zstd and lz4 decode a
prefix of a stream).
"""
from __future__ import annotations

import pathlib
from io import BytesIO

from mcap.data_stream import ReadDataStream
from mcap.records import Chunk

from .locate import Block, Definitions, walk_chunk

__all__ = ['Damage', 'partial_chunk']


class Damage(Exception):
    """The first bad record of a file (caught by the readers, which turn it into a
    :class:`~auv_bag.errors.BagError` or a damage report)."""

    def __init__(self, file: pathlib.Path, kind: str, offset: int, detail: str) -> None:
        """Args: file; kind ``truncated`` or ``corrupt``; offset (bytes from the file's
        start) of the bad record; detail, what is wrong with it."""
        super().__init__(detail)
        self.file, self.kind, self.offset, self.detail = file, kind, offset, detail

    def message(self, whole: int) -> str:
        """The one-line report, given the number of whole messages read before the damage."""
        what = 'truncated' if self.kind == 'truncated' else 'corrupt'
        return (f'bag {self.file} is {what} at byte {self.offset} ({self.detail}): '
                f'{whole} whole messages before the damage were read')


def partial_chunk(body: bytes, defs: Definitions) -> Block | None:
    """Whole messages at the start of a chunk record body cut short by the end of the file.

    The chunk header is parsed by :meth:`mcap.records.Chunk.read`, which returns the data
    field as far as the body goes.
    """
    try:
        chunk = Chunk.read(ReadDataStream(BytesIO(body)))
        data = _decompress_prefix(chunk.data, chunk.compression)
    except Exception:  # too short for the header, or no whole frame: each codec has its own
        return None
    block, _ = walk_chunk(data, defs)
    return block if len(block.offset) else None


def _decompress_prefix(data: bytes, comp: str) -> bytes:
    """As much of a cut-short compressed stream as can be decoded."""
    if comp == '':
        return data
    if comp == 'zstd':
        import zstandard

        prefix: bytes = zstandard.ZstdDecompressor().decompressobj().decompress(data)
        return prefix
    if comp == 'lz4':
        import lz4.frame

        head: bytes = lz4.frame.LZ4FrameDecompressor().decompress(data)
        return head
    return b''
