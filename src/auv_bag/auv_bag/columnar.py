"""Columnar decoding of CDR messages into numpy: a type's layout compiled once, then every
message of a block decoded at once.

A message type compiles to a :class:`Layout`, the walk of its CDR serialization: one column
per numeric field (named by its path joined with ``_``: ``z``, ``hydrodynamic_force_z``,
``pose_covariance_0``), builtin ``Time``/``Duration`` as one column in s, strings and
sequences of primitives skipped. :func:`decode_vectorised` then reads a field for all the
messages of a block with one numpy gather (XCDR1, little endian). Types the vectorised walk
cannot locate fields in (sequences of messages, wide strings) and messages that do not fit
the layout are deserialized message by message with rosbags (:func:`decode_per_message`, the
reference path), which names a message that does not decode.

Why not rosbags for every message: its ``deserialize_cdr`` builds one Python object per
message and field (about 5 us per VehicleState); the gather costs a few ns per field and
message (``bench/bench_bag.py`` measures both on the same bag).
"""
from __future__ import annotations

import functools
import os
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys.store import Typestore

from .errors import BagError

__all__ = ['Layout', 'TopicRows', 'assemble', 'decode_per_message', 'decode_vectorised',
           'gather', 'layout_of', 'out_names']

_TIME_TYPES = frozenset({'builtin_interfaces/msg/Time', 'builtin_interfaces/msg/Duration'})


def gather(data: bytes | np.ndarray, offs: np.ndarray, width: int) -> np.ndarray:
    """The ``width`` bytes at each of the byte offsets ``offs`` of ``data``: a new
    (len(offs), width) uint8 array (its rows 8-byte aligned when ``width`` is a multiple of 8).

    One gather of ``width``-byte items from a view whose items start at every byte, so no
    alignment is required of the offsets; every offset + ``width`` must lie within ``data``.
    """
    n = len(data) - width + 1
    if n <= 0:
        return np.empty((0, width), np.uint8)
    items = np.ndarray((n,), dtype=np.dtype(('V', width)), buffer=data, strides=(1,))
    rows: np.ndarray = items[offs].view(np.uint8).reshape(len(offs), width)
    return rows


class _Op(NamedTuple):
    """One step of walking a CDR message.

    kind: ``num`` (a primitive, one column), ``time`` (builtin Time/Duration, one column in
    s), ``string`` (skipped), ``pseq`` (sequence of primitives, skipped).
    """

    kind: str
    name: str
    dtype: str  # numpy dtype of the primitive ('' for string)
    path: tuple[str | int, ...]  # attribute path in the deserialized object


_PRIMS = {
    'bool': '<u1', 'byte': '<u1', 'char': '<u1', 'uint8': '<u1', 'int8': '<i1',
    'uint16': '<u2', 'int16': '<i2', 'uint32': '<u4', 'int32': '<i4',
    'uint64': '<u8', 'int64': '<i8', 'float32': '<f4', 'float64': '<f8',
}


class Layout(NamedTuple):
    """How to walk the CDR serialization of one message type (see :func:`layout`)."""

    ops: tuple[_Op, ...]
    has_header: bool
    vectorisable: bool


@functools.cache
def _layout_cached(store_id: int, msgtype: str) -> Layout:
    return _compile(_STORES[store_id], msgtype)


_STORES: dict[int, Typestore] = {}


def layout_of(store: Typestore, msgtype: str) -> Layout:
    """The layout of ``msgtype`` as ``store`` defines it (compiled once per store and type)."""
    _STORES[id(store)] = store
    return _layout_cached(id(store), msgtype)


def _compile(store: Typestore, msgtype: str) -> Layout:
    ops: list[_Op] = []
    ok = [True]

    def name_of(path: tuple[str | int, ...]) -> str:
        if path == ('header', 'stamp'):
            return 't'
        return '_'.join(str(p) for p in path)

    def walk(typ: str, path: tuple[str | int, ...]) -> None:
        if typ in _TIME_TYPES:
            ops.append(_Op('time', name_of(path), '', path))
            return
        # (node, spec) pairs: spec's shape depends on node, which mypy cannot follow here
        fields: Sequence[tuple[str, tuple[Nodetype, Any]]] = store.fielddefs[typ][1]
        for fname, (node, spec) in fields:
            fpath = (*path, fname)
            if node == Nodetype.BASE:
                base(spec[0], fpath)
            elif node == Nodetype.NAME:
                walk(spec, fpath)
            elif node == Nodetype.ARRAY:
                sub, count = spec
                for i in range(count):
                    elem(sub, (*fpath, i))
            elif node == Nodetype.SEQUENCE:
                sub, _ = spec
                if sub[0] == Nodetype.BASE and sub[1][0] in _PRIMS:
                    ops.append(_Op('pseq', name_of(fpath), _PRIMS[sub[1][0]], fpath))
                else:
                    ok[0] = False
                    ops.append(_Op('seq', name_of(fpath), '', fpath))
                    return  # nothing after a complex sequence can be located
            else:
                ok[0] = False

    def elem(sub: tuple[Any, Any], path: tuple[str | int, ...]) -> None:
        node, spec = sub
        if node == Nodetype.BASE:
            base(spec[0], path)
        elif node == Nodetype.NAME:
            walk(spec, path)
        else:
            ok[0] = False

    def base(typ: str, path: tuple[str | int, ...]) -> None:
        if typ in _PRIMS:
            ops.append(_Op('num', name_of(path), _PRIMS[typ], path))
        elif typ == 'string':
            ops.append(_Op('string', name_of(path), '', path))
        else:  # wstring: not in the project's types
            ok[0] = False
            ops.append(_Op('skip', name_of(path), '', path))

    walk(msgtype, ())
    has_header = any(op.name == 't' and op.kind == 'time' for op in ops)
    return Layout(tuple(ops), has_header, ok[0])


def _column_names(layout: Layout) -> list[str]:
    return [op.name for op in layout.ops if op.kind in ('num', 'time')]


# --------------------------------------------------------------------------------------------
# Vectorised CDR decoding


def out_names(layout: Layout) -> list[str]:
    """Fields of the arrays: ``t``, ``t_log``, then the message's columns (header stamp
    excluded: it is ``t``)."""
    return ['t', 't_log'] + [n for n in _column_names(layout) if n != 't']


@functools.cache
def _out_index(layout: Layout) -> dict[str, int]:
    return {n: i for i, n in enumerate(out_names(layout))}


def decode_vectorised(layout: Layout, data: bytes, offs: np.ndarray, lens: np.ndarray,
                       out: np.ndarray) -> bool:
    """Columns of the messages at ``offs`` (start of their CDR data, ``lens`` bytes each) in
    ``data``, vectorised over the messages, written into ``out`` (messages x
    :func:`out_names`; column ``t_log`` is left unset).

    CDR (XCDR1, little endian): a 4-byte encapsulation header, then each primitive aligned to
    its size relative to the end of that header (the origin). The message is cut into
    segments in which every field lies at the same offset from the segment's start in all
    messages: a segment ends at a string or sequence (whose length varies per message) and
    wherever the alignment padding differs between messages. Each segment is one gather of
    its bytes for all messages (no alignment needed of the offsets), then its fields are
    strided views of the gathered rows.

    Returns
    -------
    False when a message does not fit the layout (nothing else is meaningful in ``out``;
    the caller then decodes message by message, which names the bad one).
    """
    n_msg = len(offs)
    if n_msg == 0:
        return True
    index = _out_index(layout)
    ops = layout.ops
    stop = offs + lens  # absolute end of each message in data
    # Segment: absolute start ``base``, cursor ``off`` (bytes from base), ``brel`` the
    # residue (base - origin) % 8 (an int when equal for all messages), fields to extract.
    base = offs
    brel: int | np.ndarray = 4
    off = 4
    fields: list[tuple[str, int, int, str, int]] = []  # kind, column, offset, dtype, count
    # (kinds: encap, time, run of float64, num, count of a string or sequence)

    def flush() -> np.ndarray | None:
        """Gather the segment's bytes and extract its fields; None if a message is short."""
        if np.any(base + off > stop):
            return None
        if not fields:
            return np.empty((n_msg, 0), np.uint8)
        rows = gather(data, base, off)
        for kind, col, at, dtype, count in fields:
            if kind == 'encap':
                if np.any(rows[:, 0] != 0) or np.any(rows[:, 1] != 1):  # not CDR_LE
                    return None
                continue
            if kind == 'time':
                sec = np.ndarray((n_msg,), '<i4', rows, at, (off,)).astype(np.float64)
                nsec = np.ndarray((n_msg,), '<u4', rows, at + 4, (off,)).astype(np.float64)
                out[:, col] = sec + nsec * 1e-9
            elif kind == 'run':
                out[:, col:col + count] = np.ndarray((n_msg, count), '<f8', rows, at, (off, 8))
            elif kind == 'num':
                out[:, col] = np.ndarray((n_msg,), dtype, rows, at, (off,))
        fields.clear()
        return rows

    def align(size: int) -> bool:
        """Pad the cursor to ``size`` relative to the origin; a new segment starts where the
        padding differs between messages. False if a message is short."""
        nonlocal base, brel, off
        if isinstance(brel, int):
            off += -(brel + off) & (size - 1)  # sizes are powers of 2
            return True
        pad = -(brel + off) & (size - 1)
        if np.all(pad == pad[0]):
            off += int(pad[0])
            return True
        if flush() is None:
            return False
        base = base + off + pad
        brel = _uniform((brel + off + pad) & 7)
        off = 0
        return True

    fields.append(('encap', 0, 0, '', 0))
    i = 0
    while i < len(ops):
        op = ops[i]
        i += 1
        if op.kind == 'num' and op.dtype == '<f8':
            k = 1
            while i < len(ops) and ops[i].kind == 'num' and ops[i].dtype == '<f8':
                k += 1
                i += 1
            if not align(8):
                return False
            fields.append(('run', index[op.name], off, '', k))
            off += 8 * k
        elif op.kind == 'num':
            size = np.dtype(op.dtype).itemsize
            if not align(size):
                return False
            fields.append(('num', index[op.name], off, op.dtype, 1))
            off += size
        elif op.kind == 'time':
            if not align(4):
                return False
            fields.append(('time', index[op.name], off, '', 1))
            off += 8
        elif op.kind in ('string', 'pseq'):
            if not align(4):
                return False
            fields.append(('count', -1, off, '<u4', 1))
            at = off
            off += 4
            rows = flush()
            if rows is None:
                return False
            count = np.ndarray((n_msg,), '<u4', rows, at, (off,)).astype(np.int64)
            if op.kind == 'pseq':
                esize = np.dtype(op.dtype).itemsize
                pad = -(brel + off) & (esize - 1)
                count = np.where(count > 0, pad, 0) + count * esize
            base = base + off + count
            brel = _uniform((brel + off + count) & 7)
            off = 0
        else:
            return False
    return flush() is not None


def _uniform(values: np.ndarray) -> int | np.ndarray:
    """``values`` as one int when they are all equal, else as they are."""
    first = int(values[0])
    return first if np.all(values == first) else values


def decode_per_message(layout: Layout, store: Typestore, msgtype: str, data: bytes,
                        offs: Sequence[int], lens: Sequence[int], topic: str,
                        file: str | os.PathLike[str]) -> np.ndarray:
    """Columns by deserializing message by message with rosbags (the reference path).

    Returns the columns :func:`decode_vectorised` gives (messages x :func:`out_names`).
    """
    names = out_names(layout)
    index = {n: i for i, n in enumerate(names)}
    ops = [(index[op.name], op.kind == 'time', op.path) for op in layout.ops
           if op.kind in ('num', 'time')]
    mat = np.empty((len(offs), len(names)))
    mv = memoryview(data)
    deserialize = store.deserialize_cdr
    for i, (off, n) in enumerate(zip(offs, lens)):
        try:
            msg = deserialize(mv[off:off + n], msgtype)
        except Exception as exc:  # rosbags raises assorted errors on bad bytes
            raise BagError(f'bag {file}: message {i} on topic {topic} ({msgtype}) does not '
                           f'decode: {exc}') from None
        row = mat[i]
        for j, is_time, path in ops:
            obj: Any = msg  # a generated message class: its fields are known at run time
            for key in path:
                obj = obj[key] if isinstance(key, int) else getattr(obj, key)
            row[j] = obj.sec + obj.nanosec * 1e-9 if is_time else obj
    return mat


class TopicRows:
    """The columns of one topic, decoded block by block as the bag is read (so that no
    uncompressed chunk is kept), in a matrix that grows as messages come."""

    def __init__(self, msgtype: str, layout: Layout, store: Typestore, capacity: int) -> None:
        self.msgtype = msgtype
        self.layout = layout
        self.store = store
        self.mat = np.empty((capacity, len(out_names(layout))))  # pages touched when filled
        self.n = 0
        self.logs: list[np.ndarray] = []  # log times (ns) of each block
        self.error: BagError | None = None  # a message that does not decode

    def add(self, data: bytes, offs: np.ndarray, lens: np.ndarray, log: np.ndarray,
            topic: str, path: str | os.PathLike[str], fast: bool) -> None:
        """Decode the messages at ``offs`` (``lens`` bytes each) of ``data`` into new rows."""
        if self.error is not None or not len(offs):
            return
        k = len(offs)
        if self.n + k > len(self.mat):
            grown = np.empty((max(2 * len(self.mat), self.n + k, 1024), self.mat.shape[1]))
            grown[:self.n] = self.mat[:self.n]
            self.mat = grown
        rows = self.mat[self.n:self.n + k]
        if not (fast and self.layout.vectorisable
                and decode_vectorised(self.layout, data, offs, lens, rows)):
            try:
                rows[:] = decode_per_message(self.layout, self.store, self.msgtype, data,
                                             offs.tolist(), lens.tolist(), topic, path)
            except BagError as exc:  # raised once the whole bag has been read
                self.error = exc
                return
        self.n += k
        self.logs.append(log)


def assemble(layout: Layout, mat: np.ndarray, log_ns: np.ndarray) -> np.ndarray:
    """The structured array (fields of :func:`out_names`, float64, s) over ``mat``, no copy.

    Fills ``t_log`` from the log times (ns) and, for types with no header, ``t`` too.
    """
    sec, nsec = np.divmod(log_ns, 1_000_000_000)
    mat[:, 1] = sec.astype(np.float64) + nsec.astype(np.float64) * 1e-9
    if not layout.has_header:
        mat[:, 0] = mat[:, 1]
    dtype = np.dtype([(n, '<f8') for n in out_names(layout)])
    return np.ascontiguousarray(mat).view(dtype).reshape(len(mat))

