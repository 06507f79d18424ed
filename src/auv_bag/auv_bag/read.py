"""Reading bags: topics into numpy arrays (columnar), or messages one by one.

A bag is a rosbag2 directory in MCAP storage (``metadata.yaml`` and one ``.mcap`` file per
split) or a bare ``.mcap`` file, as :class:`auv_bag.writer.BagWriter` and ``ros2 bag record -s
mcap`` write it. Message types are decoded with the bag's own definitions where the project's
typestore does not know them.

Times: ``log_time`` is when the recorder received a message (ns); ``t`` in the arrays is the
message's header stamp (s; the log time for types with no header), ``t_log`` the log time (s).

Damage: a file cut short or with garbage bytes gives every whole message before the first bad
record (see :mod:`auv_bag.damage`); :func:`read_arrays` raises one :class:`BagError` naming the
file, the byte offset and how many whole messages were read, or, with
``allow_truncated=True``, returns them with the report in ``result.damage``.

This module never imports rclpy: it runs offline, in tests and in benchmarks.
"""
from __future__ import annotations

import os
import pathlib
from collections.abc import Iterable, Iterator, Sequence
from typing import Any, NamedTuple

import numpy as np
from rosbags.typesys.store import Typestore

from .columnar import TopicRows, assemble, layout_of, out_names
from .damage import Damage
from .errors import BagError
from .locate import Block, ChannelInfo
from .metadata import bag_contents, bag_files, topics_from_metadata
from .scan import ProgressCallback, Scanner
from .typestore import bag_store, normalize_msgtype, typestore

__all__ = ['REPAIR_HINT', 'BagArrays', 'BagMessage', 'bag_topics', 'read_arrays',
           'read_messages']

#: What a damaged bag's error adds: how to get a bag every reader takes.
REPAIR_HINT = '`auv bag repair BAG --out NEW` writes the whole messages to a readable bag'


class BagArrays(dict[str, np.ndarray]):
    """Arrays of a bag, one structured numpy array per topic (see :func:`read_arrays`).

    Attributes
    ----------
    path
        the bag that was read.
    damage
        the damage report (one line) if the bag was damaged and read with
        ``allow_truncated=True``, else None.
    """

    path: str
    damage: str | None

    @property
    def truncated(self) -> bool:
        """True if the bag was damaged and only the whole messages before the damage are here."""
        return self.damage is not None


def read_arrays(
    path: str | os.PathLike[str],
    topics: Iterable[str],
    *,
    allow_truncated: bool = False,
    check_order: bool = True,
    fast: bool = True,
    progress: ProgressCallback | None = None,
    workers: int | None = None,
) -> BagArrays:
    """Read topics of a bag into numpy structured arrays, one per topic, without
    deserializing message by message.

    Each array has the float64 fields ``t`` (header stamp, s; the log time for types with no
    header), ``t_log`` (receive time, s) and one column per numeric field of the message,
    named by its path joined with ``_``: ``z``, ``theta`` (VehicleState; NED/FRD, SI units),
    ``value`` (ActuatorSetpoint), ``hydrodynamic_force_z`` (HydrodynamicForces, body FRD, N),
    ``data`` (std_msgs/Float64), ``clock`` (rosgraph_msgs/Clock, s). Strings are left out;
    fixed arrays give one column per element (``pose_covariance_0`` ...).

    Messages whose only variable part is a string (the header ``frame_id``) or a sequence of
    primitives are decoded vectorised from the CDR bytes (little endian XCDR1; 8-byte
    alignment of float64 relative to the end of the 4-byte encapsulation header); other types
    are deserialized with rosbags message by message.

    Parameters
    ----------
    path
        bag directory or ``.mcap`` file.
    topics
        topics to read; each must be in the bag.
    allow_truncated
        on damage, return what was read before it (``result.damage`` holds
        the report) instead of raising.
    check_order
        require non-decreasing ``t`` within each topic.
    fast
        use the vectorised decoder where it applies (False: rosbags for every message;
        the reference the benchmark compares against).
    progress
        called as ``progress(bytes_read, bytes_total)``.
    workers
        threads that decompress and CRC-check chunks ahead of the decoding (default:
        :func:`default_workers`; 1 does everything in the calling thread). The arrays
        and the damage report do not depend on it.

    Raises
    ------
    BagError
        missing bag or topic; damage (unless ``allow_truncated``), with the number of
        whole messages read before it; a topic whose stamps go back in time (topic and
        message index named).
    """
    topics = list(dict.fromkeys(topics))
    files, counts = bag_contents(path)
    total = _total_size(files)
    parts: dict[str, TopicRows] = {}
    present: dict[str, str] = {}
    damage: str | None = None
    whole = 0
    done_bytes = 0
    # Rows to reserve per topic: the count metadata.yaml states, at most one message per 8
    # bytes of the bag (a wrong count only costs a copy when rows are added or removed).
    capacity = {t: max(0, min(n, total // 8)) for t, n in counts.items()}
    for file in files:
        scanner = Scanner(file, _offset_progress(progress, done_bytes, total), workers)
        try:
            for block in scanner.blocks():
                whole += len(block.channel)
                _collect(block, scanner, topics, parts, present, file, path, fast, capacity)
        except Damage as dmg:
            damage = dmg.message(whole)
        for chan in scanner.defs.channels.values():
            present.setdefault(chan.topic, _schema_name(scanner, chan))
        done_bytes += scanner.size
        if damage is not None:
            break
    if damage is not None and not allow_truncated:
        raise BagError(f'{damage}; {REPAIR_HINT}')
    _check_topics(path, topics, present)

    result = BagArrays()
    result.path = str(path)
    result.damage = damage
    for topic in topics:
        tp = parts.get(topic)
        if tp is None:  # declared, but no message before the end (or the damage)
            layout = layout_of(typestore(), present[topic])
            result[topic] = assemble(layout, np.empty((0, len(out_names(layout)))),
                                     np.empty(0, np.int64))
            continue
        if tp.error is not None:
            raise tp.error
        mat = tp.mat[:tp.n] if 2 * tp.n >= len(tp.mat) else tp.mat[:tp.n].copy()
        logs = tp.logs
        log = logs[0] if len(logs) == 1 else np.concatenate(logs or [np.empty(0, np.int64)])
        arr = assemble(tp.layout, mat, log)
        if check_order and len(arr) > 1:
            back = np.flatnonzero(np.diff(arr['t']) < 0)
            if len(back):
                i = int(back[0]) + 1
                raise BagError(f'topic {topic} in bag {path}: time stamps go back at message '
                               f'{i} ({arr["t"][i - 1]:.9f} s, then {arr["t"][i]:.9f} s)')
        result[topic] = arr
    return result


def _collect(block: Block, scanner: Scanner, topics: list[str],
             parts: dict[str, TopicRows], present: dict[str, str], file: pathlib.Path,
             path: str | os.PathLike[str], fast: bool, capacity: dict[str, int]) -> None:
    """Decode a block's messages of the wanted topics (vectorised over the block).

    ``capacity``: rows to reserve for a topic when its first message comes (a hint).
    """
    if not len(block.channel):
        return
    chans, offs, lens, logs = block.channel, block.offset, block.length, block.log_time
    first = chans[0]
    single = bool(np.all(chans == first))
    ids = [int(first)] if single else np.unique(chans).tolist()
    for cid in ids:
        chan = scanner.defs.channels.get(int(cid))
        if chan is None:
            raise BagError(f'bag file {file}: message on undeclared channel {int(cid)}')
        if chan.topic not in topics:
            continue
        msgtype = _schema_name(scanner, chan)
        tp = parts.get(chan.topic)
        if tp is None:
            store = bag_store(scanner.defs.schemas)
            tp = TopicRows(msgtype, layout_of(store, msgtype), store,
                            capacity.get(chan.topic, 0))
            parts[chan.topic] = tp
        elif tp.msgtype != msgtype:
            raise BagError(f'bag {file}: topic {chan.topic} changes type from {tp.msgtype} '
                           f'to {msgtype}')
        if single:
            tp.add(block.data, offs, lens, logs, chan.topic, path, fast)
        else:
            idx = np.flatnonzero(chans == cid)
            tp.add(block.data, offs[idx], lens[idx], logs[idx], chan.topic, path, fast)


class BagMessage(NamedTuple):
    """One message of a bag."""

    topic: str
    msgtype: str
    log_time: int
    """Receive time (ns)."""
    data: bytes
    """Serialized CDR bytes, with the 4-byte encapsulation header."""
    msg: Any
    """The deserialized rosbags message, or None when read with ``decode=False``."""


def read_messages(
    path: str | os.PathLike[str],
    topics: Iterable[str] | None = None,
    *,
    decode: bool = True,
    progress: ProgressCallback | None = None,
) -> Iterator[BagMessage]:
    """Iterate over the messages of a bag in file order (the recording order).

    Parameters
    ----------
    path
        bag directory or ``.mcap`` file.
    topics
        only these topics (default: all). A topic not in the bag is an error.
    decode
        deserialize each message with the rosbags typestore (``msg`` field).
    progress
        called as ``progress(bytes_read, bytes_total)``.

    Raises
    ------
    BagError
        missing bag or topic; damage, after every whole message before it was
        yielded.
    """
    files = bag_files(path)
    wanted = None if topics is None else set(topics)
    if wanted is not None:
        present = bag_topics(path)
        _check_topics(path, wanted, present)
    whole = 0
    done_bytes = 0
    total = _total_size(files)
    for file in files:
        scanner = Scanner(file, _offset_progress(progress, done_bytes, total))
        store: Typestore | None = None
        try:
            for block in scanner.blocks():
                whole += len(block.channel)
                if decode and store is None:
                    store = bag_store(scanner.defs.schemas)
                for cid, log_ns, off, n in zip(block.channel.tolist(), block.log_time.tolist(),
                                               block.offset.tolist(), block.length.tolist()):
                    chan = scanner.defs.channels.get(cid)
                    if chan is None:
                        raise BagError(f'bag file {file}: message on undeclared channel {cid}')
                    if wanted is not None and chan.topic not in wanted:
                        continue
                    msgtype = _schema_name(scanner, chan)
                    data = block.data[off:off + n]
                    msg = None
                    if decode:
                        if store is None or msgtype not in store.fielddefs:
                            store = bag_store(scanner.defs.schemas)
                        msg = _deserialize(store, data, msgtype, chan.topic, file)
                    yield BagMessage(chan.topic, msgtype, log_ns, data, msg)
        except Damage as dmg:
            raise BagError(f'{dmg.message(whole)}; {REPAIR_HINT}') from None
        done_bytes += scanner.size


def _deserialize(store: Typestore, data: bytes, msgtype: str, topic: str,
                 file: pathlib.Path) -> Any:
    try:
        return store.deserialize_cdr(data, msgtype)
    except Exception as exc:  # rosbags raises assorted errors on bad bytes
        raise BagError(f'bag file {file}: a {msgtype} message on {topic} does not decode: '
                       f'{exc}') from None


def _schema_name(scanner: Scanner, chan: ChannelInfo) -> str:
    schema = scanner.defs.schemas.get(chan.schema_id)
    if schema is None:
        raise BagError(f'bag file {scanner.file}: topic {chan.topic} has no schema')
    return normalize_msgtype(schema[0])


def bag_topics(path: str | os.PathLike[str]) -> dict[str, str]:
    """Topics of a bag and their message types (``pkg/msg/Type``).

    Read from ``metadata.yaml`` when present, else from the MCAP file's channels (a damaged
    file gives the channels found before the damage).
    """
    p = pathlib.Path(path)
    meta = p / 'metadata.yaml'
    if p.is_dir() and meta.is_file():
        listed = topics_from_metadata(meta)
        try:
            return {name: normalize_msgtype(msgtype) for name, msgtype in listed.items()}
        except BagError as exc:
            raise BagError(f'bag metadata {meta} is unreadable: {exc}') from None
    found: dict[str, str] = {}
    for file in bag_files(p):
        scanner = Scanner(file)
        try:
            for _ in scanner.blocks():
                pass
        except Damage:
            pass
        for chan in scanner.defs.channels.values():
            found[chan.topic] = _schema_name(scanner, chan)
    return found


def _check_topics(path: str | os.PathLike[str], wanted: Iterable[str],
                  present: dict[str, str] | Iterable[str]) -> None:
    names = sorted(present)
    for topic in wanted:
        if topic not in names:
            listed = ', '.join(names) if names else 'none'
            raise BagError(f'topic {topic} is not in bag {path} (topics present: {listed})')


def _total_size(files: Sequence[pathlib.Path]) -> int:
    return sum(f.stat().st_size for f in files)


def _offset_progress(progress: ProgressCallback | None, done: int,
                     total: int) -> ProgressCallback | None:
    """Progress of one file expressed over the whole bag."""
    if progress is None:
        return None
    return lambda n, _size: progress(done + n, total)


