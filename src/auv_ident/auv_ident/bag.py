"""Bag I/O: rosbag2 bags in MCAP storage, written and read without a ROS graph.

A bag is what ``ros2 bag record -s mcap`` writes: a directory holding ``metadata.yaml`` and
one ``.mcap`` file per split (MCAP profile ``ros2``, schema encoding ``ros2msg`` with the full
concatenated message definition, message encoding ``cdr``, the offered QoS profiles in each
channel's metadata). Every function here also takes a bare ``.mcap`` file.

Times: ``log_time`` is when the recorder received a message (ns since the Unix epoch, or since
the start of simulated time); ``publish_time`` is when the publisher sent it (the DDS source
timestamp, as rosbag2 records it; the log time where none is known); ``t`` in the arrays is the
message's header stamp (s).

Damage: a bag cut short (a recorder killed mid-write, a copy interrupted) or with garbage
bytes is read record by record from the start without seeking; every whole message before the
first bad record is returned and the damage is reported as one :class:`BagError` naming the
file, the byte offset and how many whole messages were read.

This module never imports rclpy: it runs offline, in tests and in benchmarks.
"""
from __future__ import annotations

import functools
import math
import os
import pathlib
import struct
import time
import zlib
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from io import StringIO
from typing import IO, Any, NamedTuple

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from .errors import BagError

__all__ = [
    'BagArrays',
    'BagError',
    'BagMessage',
    'BagWriter',
    'ProgressCallback',
    'bag_files',
    'bag_topics',
    'default_workers',
    'msg_dir',
    'normalize_msgtype',
    'qos_profiles_yaml',
    'read_arrays',
    'read_messages',
    'typestore',
]

ProgressCallback = Callable[[int, int], None]
"""Called as ``progress(bytes_read, bytes_total)`` while a bag is read."""

#: Depth of the keep-last QoS history the project's recorder and player use (messages).
DEFAULT_QOS_DEPTH = 1000

_MAGIC = b'\x89MCAP0\r\n'
_OP_HEADER, _OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK = 1, 2, 3, 4, 5, 6
_OP_MESSAGE_INDEX = 0x07
_OP_DATA_END = 0x0F
_KNOWN_OPS = frozenset(range(0x01, 0x10))
_U8 = struct.Struct('<Q')
_MSG_HEAD = struct.Struct('<HIQQ')  # channel id, sequence, log time (ns), publish time (ns)
_MSG_HEAD_SIZE = _MSG_HEAD.size  # 22 bytes
_RECORD_PREFIX = 9 + _MSG_HEAD_SIZE  # opcode, length and message head before the CDR data
_CHUNK_HEAD = struct.Struct('<QQQI')  # start time, end time, uncompressed size, uncompressed crc
_TIME_TYPES = frozenset({'builtin_interfaces/msg/Time', 'builtin_interfaces/msg/Duration'})
_SECTION = '=' * 80 + '\n'
_INFINITE = {'sec': 9223372036, 'nsec': 854775807}  # rmw's "infinite" duration


# --------------------------------------------------------------------------------------------
# Message definitions


def msg_dir() -> pathlib.Path:
    """Directory holding the auv_msgs ``.msg`` files.

    Looks in the source tree first (``src/auv_msgs/msg`` next to this package), then in the
    colcon install space (``install/auv_msgs/share/auv_msgs/msg``) and in every prefix of
    ``AMENT_PREFIX_PATH``.

    Raises:
        BagError: no directory with ``.msg`` files was found; the message names where it looked.
    """
    here = pathlib.Path(__file__).resolve()
    candidates = [here.parents[2] / 'auv_msgs' / 'msg']
    if len(here.parents) > 3:
        candidates.append(here.parents[3] / 'install' / 'auv_msgs' / 'share' / 'auv_msgs' / 'msg')
    for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        if prefix:
            candidates.append(pathlib.Path(prefix) / 'share' / 'auv_msgs' / 'msg')
    for cand in candidates:
        if cand.is_dir() and any(cand.glob('*.msg')):
            return cand
    looked = ', '.join(str(c) for c in candidates)
    raise BagError(f'auv_msgs message definitions not found (looked in {looked})')


def _base_store() -> Typestore:
    """A fresh typestore of the newest ROS 2 distribution rosbags knows (Kilted or later)."""
    store = getattr(Stores, 'ROS2_KILTED', None) or Stores.LATEST
    return get_typestore(store)


@functools.lru_cache(maxsize=1)
def typestore() -> Typestore:
    """The ROS 2 Kilted typestore with the auv_msgs types registered from their ``.msg`` text.

    Shared and cached: do not register further types into it; build your own with
    ``get_typestore`` if you need to.
    """
    store = _base_store()
    types = {}
    for path in sorted(msg_dir().glob('*.msg')):
        types.update(get_types_from_msg(path.read_text(), f'auv_msgs/msg/{path.stem}'))
    store.register(types)
    return store


@functools.cache
def _msg_text(msgtype: str) -> str | None:
    """The original ``.msg`` text of an auv_msgs type (comments kept), or None."""
    pkg, _, name = msgtype.split('/')
    if pkg != 'auv_msgs':
        return None
    path = msg_dir() / f'{name}.msg'
    return path.read_text() if path.is_file() else None


def normalize_msgtype(msgtype: str) -> str:
    """``pkg/Type`` or ``pkg/msg/Type`` -> ``pkg/msg/Type``.

    Raises:
        BagError: the name has neither form.
    """
    parts = msgtype.strip('/').split('/')
    if len(parts) == 2 and all(parts):
        return f'{parts[0]}/msg/{parts[1]}'
    if len(parts) == 3 and all(parts):
        return '/'.join(parts)
    raise BagError(f'bad message type name {msgtype!r}: expected pkg/msg/Type')


def _message_definition(store: Typestore, msgtype: str) -> str:
    """Full ``ros2msg`` schema text as rosbag2 stores it: the type's own definition, then each
    dependency after a line of 80 ``=`` and a ``MSG: pkg/Type`` line."""
    text, _ = store.generate_msgdef(msgtype, ros_version=2)
    own = _msg_text(msgtype)
    if own is None:
        return text
    sep = text.find(_SECTION)
    return own.rstrip('\n') + '\n' + (text[sep:] if sep >= 0 else '')


def _types_from_schema(name: str, text: str) -> dict[str, Any]:
    """Types defined by one ``ros2msg`` schema (the message and its dependencies)."""
    types: dict[str, Any] = {}
    sections = text.split(_SECTION)
    types.update(get_types_from_msg(sections[0], name))
    for section in sections[1:]:
        head, _, body = section.partition('\n')
        if head.startswith('MSG: '):
            types.update(get_types_from_msg(body, normalize_msgtype(head[5:].strip())))
    return types


def qos_profiles_yaml(
    reliability: str = 'reliable', durability: str = 'volatile', depth: int = DEFAULT_QOS_DEPTH
) -> str:
    """The ``offered_qos_profiles`` text rosbag2 (metadata version 9) stores for one publisher.

    Args:
        reliability: ``reliable`` or ``best_effort``.
        durability: ``volatile`` or ``transient_local``.
        depth: keep-last history depth (messages).
    """
    return _yaml_dump([_qos_dict(reliability, durability, depth)])


def _qos_dict(reliability: str, durability: str, depth: int) -> dict[str, Any]:
    return {
        'history': 'keep_last',
        'depth': depth,
        'reliability': reliability,
        'durability': durability,
        'deadline': dict(_INFINITE),
        'lifespan': dict(_INFINITE),
        'liveliness': 'automatic',
        'liveliness_lease_duration': dict(_INFINITE),
        'avoid_ros_namespace_conventions': False,
    }


def _yaml_dump(data: Any) -> str:
    from ruamel.yaml import YAML

    yaml = YAML(typ='safe')
    yaml.default_flow_style = False
    out = StringIO()
    yaml.dump(data, out)
    return out.getvalue()


# --------------------------------------------------------------------------------------------
# Writer


class _TopicInfo(NamedTuple):
    channel_id: int
    msgtype: str
    qos: str


class BagWriter:
    """Write a rosbag2 bag with MCAP storage, as ``ros2 bag record -s mcap`` does.

    ``path`` is the bag directory (created; it must not exist or be empty), holding
    ``<name>_0.mcap`` and, after :meth:`close`, ``metadata.yaml``. A path ending in ``.mcap``
    writes a bare MCAP file with no ``metadata.yaml``.

    Messages are given either as serialized CDR bytes (as a raw rclpy subscription receives
    them; written as they are) or as message objects of the rosbags typestore (serialized
    here, for offline runs with no ROS graph). The chunk in progress is written to the file
    every ``flush_interval`` seconds (wall clock) and whenever it exceeds ``chunk_size`` bytes,
    so a crash loses little; :meth:`close` writes the summary and ``metadata.yaml``.

    Example::

        with BagWriter('out/run1') as bag:
            bag.add_topic('/auv/state', 'auv_msgs/msg/VehicleState')
            bag.write('/auv/state', cdr_bytes, log_time_ns=stamp_ns)
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        compression: str = 'zstd',
        chunk_size: int = 768 * 1024,
        flush_interval: float = 1.0,
        store: Typestore | None = None,
        custom_data: dict[str, str] | None = None,
    ) -> None:
        """Open the bag for writing.

        Args:
            path: bag directory, or a file name ending in ``.mcap`` for a bare MCAP file.
            compression: chunk compression, ``zstd`` (rosbag2's default), ``lz4`` or ``none``.
            chunk_size: uncompressed chunk size that triggers writing the chunk (bytes).
            flush_interval: longest time a message stays in memory before it is written (s,
                wall clock); 0 writes every message at once.
            store: typestore for message objects and definitions (default: :func:`typestore`).
            custom_data: strings for ``metadata.yaml``'s ``custom_data`` (and an MCAP
                metadata record ``custom_data``), e.g. an import's provenance.

        Raises:
            BagError: the path exists and is not an empty directory, or cannot be created.
        """
        from mcap.writer import CompressionType, Writer

        comp = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
                'none': CompressionType.NONE, '': CompressionType.NONE}.get(compression)
        if comp is None:
            raise BagError(f'unknown bag compression {compression!r}: use zstd, lz4 or none')
        if not (flush_interval >= 0 and math.isfinite(flush_interval)):
            raise BagError(f'flush_interval must be finite and >= 0 s, got {flush_interval}')
        self.path = pathlib.Path(path)
        self._store = store or typestore()
        if self.path.suffix == '.mcap':
            self._dir: pathlib.Path | None = None
            self.mcap_path = self.path
            if self.path.exists():
                raise BagError(f'bag file {self.path} exists already')
            self.path.parent.mkdir(parents=True, exist_ok=True)
        else:
            if self.path.exists() and (not self.path.is_dir() or any(self.path.iterdir())):
                raise BagError(f'bag directory {self.path} exists already and is not empty')
            self._dir = self.path
            self.mcap_path = self.path / f'{self.path.name}_0.mcap'
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            if self._dir is not None:
                self._dir.mkdir(exist_ok=True)
            self._stream: IO[bytes] = open(self.mcap_path, 'xb')  # noqa: SIM115
        except OSError as exc:
            raise BagError(f'cannot create bag {self.path}: {exc.strerror}') from None
        self._writer = Writer(self._stream, chunk_size=chunk_size, compression=comp)
        self._writer.start(profile='ros2', library='auv_ident.bag (mcap-python)')
        self._topics: dict[str, _TopicInfo] = {}
        self._schemas: dict[str, int] = {}
        self._counts: dict[str, int] = {}
        self._start_ns: int | None = None
        self._end_ns = 0
        self._flush_interval = flush_interval
        self._last_flush = time.monotonic()
        self._closed = False
        self._custom = dict(custom_data or {})

    # -- topics ------------------------------------------------------------------------------
    def add_topic(self, topic: str, msgtype: str, qos: str | None = None) -> None:
        """Declare a topic and its message type (``pkg/msg/Type``).

        Args:
            topic: topic name, e.g. ``/auv/state``.
            msgtype: message type; must be known to the typestore (its definition is stored).
            qos: offered QoS profiles as YAML (default: :func:`qos_profiles_yaml`, reliable).

        Raises:
            BagError: the type is unknown, or the topic was declared with another type.
        """
        self._check_open()
        msgtype = normalize_msgtype(msgtype)
        known = self._topics.get(topic)
        if known is not None:
            if known.msgtype != msgtype:
                raise BagError(f'topic {topic} is {known.msgtype} in bag {self.path}, '
                               f'cannot write {msgtype} on it')
            return
        if msgtype not in self._store.fielddefs:
            raise BagError(f'message type {msgtype} of topic {topic} is unknown '
                           '(not in the typestore)')
        schema_id = self._schemas.get(msgtype)
        if schema_id is None:
            text = _message_definition(self._store, msgtype)
            schema_id = self._writer.register_schema(msgtype, 'ros2msg', text.encode())
            self._schemas[msgtype] = schema_id
        qos = qos_profiles_yaml() if qos is None else qos
        channel_id = self._writer.register_channel(
            topic, 'cdr', schema_id, {'offered_qos_profiles': qos})
        self._topics[topic] = _TopicInfo(channel_id, msgtype, qos)
        self._counts[topic] = 0

    @property
    def topics(self) -> dict[str, str]:
        """Declared topics and their message types."""
        return {name: info.msgtype for name, info in self._topics.items()}

    @property
    def message_count(self) -> int:
        """Messages written so far."""
        return sum(self._counts.values())

    # -- messages ----------------------------------------------------------------------------
    def write(
        self,
        topic: str,
        message: bytes | bytearray | memoryview | object,
        log_time_ns: int | None = None,
        publish_time_ns: int | None = None,
    ) -> None:
        """Write one message.

        Args:
            topic: topic name; declared with :meth:`add_topic`, or declared here from the
                ``__msgtype__`` of a message object.
            message: serialized CDR bytes (with the 4-byte encapsulation header), or a rosbags
                message object.
            log_time_ns: receive time (ns); default: now, wall clock since the Unix epoch.
            publish_time_ns: publish time (ns); default: the log time.

        Raises:
            BagError: undeclared topic given as bytes, or an object that cannot be serialized.
        """
        self._check_open()
        info = self._topics.get(topic)
        if isinstance(message, (bytes, bytearray, memoryview)):
            if info is None:
                raise BagError(f'topic {topic} was not declared in bag {self.path} '
                               '(call add_topic first)')
            data = bytes(message)
        else:
            msgtype = getattr(message, '__msgtype__', None)
            if msgtype is None:
                raise BagError(f'cannot write a {type(message).__name__} on topic {topic}: '
                               'expected CDR bytes or a rosbags message object')
            if info is None:
                self.add_topic(topic, msgtype)
                info = self._topics[topic]
            elif normalize_msgtype(msgtype) != info.msgtype:
                raise BagError(f'topic {topic} is {info.msgtype}, got a {msgtype} message')
            try:
                data = bytes(self._store.serialize_cdr(message, info.msgtype))
            except Exception as exc:  # rosbags raises several types on a bad field
                raise BagError(f'cannot serialize a {info.msgtype} message for topic {topic}: '
                               f'{exc}') from None
        log_ns = time.time_ns() if log_time_ns is None else int(log_time_ns)
        pub_ns = log_ns if publish_time_ns is None else int(publish_time_ns)
        count = self._counts[topic]
        self._writer.add_message(info.channel_id, log_ns, data, pub_ns, sequence=count)
        self._counts[topic] = count + 1
        if self._start_ns is None or log_ns < self._start_ns:
            self._start_ns = log_ns
        self._end_ns = max(self._end_ns, log_ns)
        now = time.monotonic()
        if now - self._last_flush >= self._flush_interval:
            self.flush()

    def flush(self) -> None:
        """Write the chunk in progress and flush the file (the OS keeps it if we crash)."""
        self._check_open()
        self._writer.flush()  # type: ignore[no-untyped-call]  # mcap 1.6: unannotated
        self._last_flush = time.monotonic()

    # -- closing -----------------------------------------------------------------------------
    def close(self) -> None:
        """Write the last chunk, the summary and ``metadata.yaml``. Closing twice is a no-op."""
        if self._closed:
            return
        self._closed = True
        try:
            info = self._metadata()
            self._writer.add_metadata('rosbag2', {'serialized_metadata': _yaml_dump(info)})
            if self._custom:
                self._writer.add_metadata('custom_data', self._custom)
            self._writer.finish()  # type: ignore[no-untyped-call]  # mcap 1.6: unannotated
        finally:
            self._stream.close()
        if self._dir is not None:
            text = _yaml_dump({'rosbag2_bagfile_information': info})
            tmp = self._dir / 'metadata.yaml.tmp'
            tmp.write_text(text)
            tmp.replace(self._dir / 'metadata.yaml')

    def _metadata(self) -> dict[str, Any]:
        start = self._start_ns or 0
        duration = max(0, self._end_ns - start)
        count = self.message_count
        return {
            'version': 9,
            'storage_identifier': 'mcap',
            'duration': {'nanoseconds': duration},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': count,
            'topics_with_message_count': [
                {
                    'topic_metadata': {
                        'name': topic,
                        'type': info.msgtype,
                        'serialization_format': 'cdr',
                        'offered_qos_profiles': _parse_yaml(info.qos),
                        'type_description_hash': self._store.hash_rihs01(info.msgtype),
                    },
                    'message_count': self._counts[topic],
                }
                for topic, info in self._topics.items()
            ],
            'compression_format': '',
            'compression_mode': '',
            'relative_file_paths': [self.mcap_path.name],
            'files': [{
                'path': self.mcap_path.name,
                'starting_time': {'nanoseconds_since_epoch': start},
                'duration': {'nanoseconds': duration},
                'message_count': count,
            }],
            'custom_data': dict(self._custom),
            'ros_distro': 'kilted',
        }

    def _check_open(self) -> None:
        if self._closed:
            raise BagError(f'bag {self.path} is closed')

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _parse_yaml(text: str) -> Any:
    try:  # PyYAML's C loader: metadata.yaml in ~1 ms rather than ~50 ms
        import yaml

        return yaml.load(text, Loader=getattr(yaml, 'CSafeLoader', yaml.SafeLoader))
    except ImportError:
        from ruamel.yaml import YAML

        return YAML(typ='safe').load(text)


# --------------------------------------------------------------------------------------------
# Locating the files of a bag


def bag_files(path: str | os.PathLike[str]) -> list[pathlib.Path]:
    """The ``.mcap`` files of a bag, in recording order.

    ``path`` is a bag directory (files from ``metadata.yaml``; when it is missing, as after a
    recorder crash, the directory's ``.mcap`` files in name order) or a bare ``.mcap`` file.

    Raises:
        BagError: no such bag, unreadable ``metadata.yaml``, or no MCAP file.
    """
    return _bag_contents(path)[0]


def _bag_contents(path: str | os.PathLike[str]) -> tuple[list[pathlib.Path], dict[str, int]]:
    """:func:`bag_files`, and the message count of each topic as ``metadata.yaml`` states it
    (empty without one; a hint for sizing arrays, never trusted for results)."""
    p = pathlib.Path(path)
    if p.is_file():
        return [p], {}
    if not p.exists():
        raise BagError(f'bag {p} does not exist')
    meta = p / 'metadata.yaml'
    if meta.is_file():
        try:
            info = _parse_yaml(meta.read_text())['rosbag2_bagfile_information']
            storage = info.get('storage_identifier', 'mcap')
            names = list(info['relative_file_paths'])
        except Exception as exc:
            raise BagError(f'bag metadata {meta} is unreadable: {exc}') from None
        if storage != 'mcap':
            raise BagError(f'bag {p} uses {storage} storage; only mcap is supported')
        files = [p / name for name in names]
        for f in files:
            if not f.is_file():
                raise BagError(f'bag {p}: file {f.name} named in metadata.yaml is missing')
        counts: dict[str, int] = {}
        try:
            for entry in info.get('topics_with_message_count') or []:
                counts[str(entry['topic_metadata']['name'])] = int(entry['message_count'])
        except (KeyError, TypeError, ValueError):
            counts = {}
        return files, counts
    files = sorted(p.glob('*.mcap'))
    if not files:
        raise BagError(f'bag {p} has no metadata.yaml and no .mcap file')
    return files, {}


# --------------------------------------------------------------------------------------------
# Record scanning (sequential, no seeking, damage-tolerant)


class _Damage(Exception):
    """Internal: the first bad record of a file."""

    def __init__(self, file: pathlib.Path, kind: str, offset: int, detail: str) -> None:
        super().__init__(detail)
        self.file, self.kind, self.offset, self.detail = file, kind, offset, detail

    def message(self, whole: int) -> str:
        what = 'truncated' if self.kind == 'truncated' else 'corrupt'
        return (f'bag {self.file} is {what} at byte {self.offset} ({self.detail}): '
                f'{whole} whole messages before the damage were read')


class _Channel(NamedTuple):
    topic: str
    schema_id: int
    encoding: str


class _Block(NamedTuple):
    """Whole messages found in one chunk (or run of loose message records); int64 arrays."""

    data: bytes
    channel: np.ndarray
    log_time: np.ndarray  # ns
    offset: np.ndarray  # start of the CDR data in ``data`` (bytes)
    length: np.ndarray  # CDR data length (bytes)


def default_workers() -> int:
    """Threads that decompress and check chunks by default: the CPU count, at most 4."""
    return max(1, min(4, os.cpu_count() or 1))


class _Pending(NamedTuple):
    """A block read but not yet handed out: loose messages (``block``) or a chunk whose
    decompression and CRC check run in the background (``inflated``)."""

    block: _Block | None
    inflated: Future[bytes] | None
    pos: int  # file offset of the chunk record
    indexes: list[bytes]  # message index records of the chunk
    buffer: bytearray | None  # holding the chunk record, reused once it is inflated


class _Scanner:
    """Reads one MCAP file front to back, record by record, and stops at the first bad one.

    Chunks are decompressed and CRC-checked by ``workers`` threads (the codecs and
    ``zlib.crc32`` release the GIL) a few chunks ahead of the consumer; blocks are still handed
    out in file order, and a bad chunk ends the scan after every block before it.
    """

    def __init__(self, file: pathlib.Path, progress: ProgressCallback | None = None,
                 workers: int | None = None) -> None:
        self.file = file
        self.progress = progress
        self.schemas: dict[int, tuple[str, str, str]] = {}  # id -> name, encoding, text
        self.channels: dict[int, _Channel] = {}
        self.size = 0
        self.workers = default_workers() if workers is None else max(1, int(workers))
        self._pool: ThreadPoolExecutor | None = None
        self._spare: list[bytearray] = []  # read buffers free for the next chunk records

    def blocks(self) -> Iterator[_Block]:
        """Blocks of whole messages; raises :class:`_Damage` after the last good one."""
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

    def _damage(self, kind: str, offset: int, detail: str) -> _Damage:
        return _Damage(self.file, kind, offset, detail)

    def _records(self, fh: IO[bytes]) -> Iterator[_Block]:
        size = self.size
        magic = fh.read(8)
        if len(magic) < 8 or magic != _MAGIC:
            if len(magic) < 8 and _MAGIC.startswith(magic):
                raise self._damage('truncated', len(magic), 'the file ends in the magic bytes')
            raise BagError(f'bag file {self.file} is not an MCAP file (bad magic bytes)')
        pos = 8
        loose = _LooseMessages()
        pending: deque[_Pending] = deque()  # in file order
        chunk: list[_Pending] = []  # the last chunk read, while its message indexes follow
        ahead = 2 * self.workers if self._pool is not None else 0  # chunks kept in flight
        seen_data_end = False
        while True:
            head = fh.read(9)
            if not head:
                yield from self._take(loose, chunk, pending, 0)
                where = 'after the data section' if seen_data_end else 'before the summary'
                raise self._damage('truncated', pos, f'the file ends {where}, no footer')
            if len(head) < 9:
                yield from self._take(loose, chunk, pending, 0)
                raise self._damage('truncated', pos, 'the file ends inside a record header')
            op = head[0]
            (length,) = _U8.unpack_from(head, 1)
            if op not in _KNOWN_OPS and op < 0x80:
                yield from self._take(loose, chunk, pending, 0)
                raise self._damage('corrupt', pos, f'unknown record opcode 0x{op:02x}')
            body_start = pos + 9
            if length > size - body_start:
                yield from self._take(loose, chunk, pending, 0)
                if op == _OP_CHUNK:
                    part = fh.read()
                    block = self._partial_chunk(part)
                    if block is not None:
                        yield block
                raise self._damage('truncated', pos,
                                   f'a record of {length} bytes runs past the end of the file '
                                   f'({size} bytes)')
            if op == _OP_MESSAGE:
                body = fh.read(length)
                loose.add(body)
            elif op == _OP_CHUNK:
                yield from self._take(loose, chunk, pending, ahead)
                buffer, view = self._read_into(fh, length)
                inflated = (self._pool.submit(self._inflate, view, pos) if self._pool
                            else _done(self._inflate, view, pos))
                chunk.append(_Pending(None, inflated, pos, [], buffer))
            elif op == _OP_MESSAGE_INDEX and chunk:
                chunk[0].indexes.append(fh.read(length))
            elif op in (_OP_SCHEMA, _OP_CHANNEL):
                yield from self._take(loose, chunk, pending, 0)
                body = fh.read(length)
                try:
                    self._definition(op, body, 0, len(body))
                except (struct.error, UnicodeDecodeError, IndexError):
                    raise self._damage('corrupt', pos, 'unreadable schema or channel') from None
            elif op == _OP_FOOTER:
                yield from self._take(loose, chunk, pending, 0)
                fh.seek(length, 1)
                tail = fh.read(8)
                if tail != _MAGIC:
                    raise self._damage('truncated' if len(tail) < 8 else 'corrupt',
                                       body_start + length, 'no closing magic after the footer')
                if self.progress:
                    self.progress(size, size)
                return
            else:
                if op == _OP_DATA_END:
                    seen_data_end = True
                fh.seek(length, 1)
            pos = body_start + length
            if self.progress and op == _OP_CHUNK:
                self.progress(pos, size)

    def _take(self, loose: _LooseMessages, chunk: list[_Pending], pending: deque[_Pending],
              keep: int) -> Iterator[_Block]:
        """Queue the messages read so far (loose ones, then the last chunk) and hand out the
        oldest queued blocks until at most ``keep`` chunks remain in flight."""
        for block in loose.take():
            pending.append(_Pending(block, None, 0, [], None))
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

    def _read_into(self, fh: IO[bytes], length: int) -> tuple[bytearray, memoryview]:
        """Read ``length`` bytes into a spare buffer (fresh memory costs page faults): the
        buffer and a view of what was read (shorter if the file shrank meanwhile)."""
        buffer = self._spare.pop() if self._spare else bytearray()
        if len(buffer) < length:
            buffer = bytearray(length)
        view = memoryview(buffer)[:length]
        got = fh.readinto(view)  # type: ignore[attr-defined]
        return buffer, view[:got or 0]

    def _definition(self, op: int, body: bytes, start: int, end: int) -> None:
        """Parse a schema or channel record body lying in ``body[start:end]``."""
        if op == _OP_SCHEMA:
            (sid,) = struct.unpack_from('<H', body, start)
            name, p = _string(body, start + 2)
            enc, p = _string(body, p)
            (n,) = struct.unpack_from('<I', body, p)
            if p + 4 + n > end:
                raise IndexError
            self.schemas[sid] = (name, enc, body[p + 4:p + 4 + n].decode())
        else:
            cid, sid = struct.unpack_from('<HH', body, start)
            topic, p = _string(body, start + 4)
            enc, p = _string(body, p)
            if p > end:
                raise IndexError
            self.channels[cid] = _Channel(topic, sid, enc)

    def _inflate(self, body: bytes | memoryview, pos: int) -> bytes:
        """The uncompressed data of a chunk record body, its size and CRC checked (runs in a
        worker thread; raises :class:`_Damage`)."""
        try:
            _, _, usize, crc = _CHUNK_HEAD.unpack_from(body, 0)
            comp, p = _string(body, _CHUNK_HEAD.size)
            (clen,) = _U8.unpack_from(body, p)
            p += 8
        except (struct.error, UnicodeDecodeError):
            raise self._damage('corrupt', pos, 'unreadable chunk header') from None
        if p + clen > len(body):
            raise self._damage('corrupt', pos, 'chunk data longer than the chunk record')
        try:
            data = _decompress(memoryview(body)[p:p + clen], comp, usize)
        except Exception as exc:  # each codec raises its own type
            raise self._damage('corrupt', pos, f'chunk does not decompress ({comp}: {exc})'
                               ) from None
        if len(data) != usize:
            raise self._damage('corrupt', pos, f'chunk is {len(data)} bytes, expected {usize}')
        if crc and zlib.crc32(data) != crc:
            raise self._damage('corrupt', pos, 'chunk CRC mismatch')
        return data

    def _locate(self, data: bytes, pos: int, indexes: Sequence[bytes] = ()) -> _Block:
        """The messages of an uncompressed chunk, through its message indexes if they describe
        it exactly, else record by record (which also reads the definitions it holds)."""
        block = _indexed_records(data, indexes) if indexes else None
        if block is not None and len(block.offset) and block.offset[0] > _RECORD_PREFIX:
            # Schemas and channels before the first indexed message: walk that part.
            head, complete = self._chunk_records(data[:int(block.offset[0]) - _RECORD_PREFIX])
            if not complete:
                raise self._damage('corrupt', pos, 'a record inside a chunk is cut short')
            if len(head.offset):
                block = _Block(data, *(np.concatenate([x, y]) for x, y in
                                       zip(head[1:], block[1:])))
        if block is None:
            block, complete = self._chunk_records(data)
            if not complete:
                raise self._damage('corrupt', pos, 'a record inside a chunk is cut short')
        return block

    def _partial_chunk(self, body: bytes) -> _Block | None:
        """Whole messages at the start of a chunk cut short by the end of the file."""
        try:
            _, _, _usize, _ = _CHUNK_HEAD.unpack_from(body, 0)
            comp, p = _string(body, _CHUNK_HEAD.size)
            p += 8
            data = _decompress_prefix(body[p:], comp)
        except Exception:  # a prefix too short to hold even the header: nothing to save
            return None
        block, _ = self._chunk_records(data)
        return block if len(block.offset) else None

    def _chunk_records(self, data: bytes) -> tuple[_Block, bool]:
        """Messages (and definitions) of an uncompressed chunk; False if a record is cut.

        Records are walked one by one, except that a run of message records of equal length
        (one topic at a fixed message size, the usual case) is located vectorised: the next
        records are assumed to follow at a fixed stride and the assumption is checked on
        every one of them (opcode and length).
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
                if rlen < _MSG_HEAD_SIZE:
                    complete = False
                    break
                cid, _, log_ns, _ = unpack_msg(data, start)
                add_c(cid)
                add_t(log_ns)
                add_o(start + _MSG_HEAD_SIZE)
                add_l(rlen - _MSG_HEAD_SIZE)
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
            elif op in (_OP_SCHEMA, _OP_CHANNEL):
                prev_len = -1
                try:
                    self._definition(op, data, start, end)
                except (struct.error, UnicodeDecodeError, IndexError):
                    complete = False
                    break
            else:
                prev_len = -1
        pieces.append(_lists_to_arrays(channel, log_time, offset, length))
        cols = [np.concatenate([p[i] for p in pieces]) for i in range(4)]
        return _Block(data, *cols), complete


def _indexed_records(data: bytes, indexes: Sequence[bytes]) -> _Block | None:
    """Messages of an uncompressed chunk located through its message index records.

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
    rec = _gather(data, offs, head).view(_MSG_RECORD_HEAD)[:, 0]
    ends = offs + 9 + rec['length'].astype(np.int64)
    if not (np.all(rec['op'] == _OP_MESSAGE) and np.all(rec['channel'] == chan)
            and np.all(rec['log_time'] == log) and np.all(rec['length'] >= _MSG_HEAD_SIZE)
            and np.all(ends[:-1] == offs[1:]) and ends[-1] == len(data)):
        return None
    return _Block(data, chan, log.astype(np.int64), offs + 9 + _MSG_HEAD_SIZE,
                  rec['length'].astype(np.int64) - _MSG_HEAD_SIZE)


def _gather(data: bytes | np.ndarray, offs: np.ndarray, width: int) -> np.ndarray:
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


def _lists_to_arrays(*lists: list[int]) -> tuple[np.ndarray, ...]:
    return tuple(np.asarray(x, np.int64) for x in lists)


_MSG_RECORD_HEAD = np.dtype([('op', 'u1'), ('length', '<u8'), ('channel', '<u2'),
                             ('sequence', '<u4'), ('log_time', '<u8'), ('publish_time', '<u8')])


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
            body + _MSG_HEAD_SIZE, np.full(count, rlen - _MSG_HEAD_SIZE, np.int64))


class _LooseMessages:
    """Message records outside chunks (unchunked MCAP files), gathered into blocks."""

    def __init__(self) -> None:
        self.parts: list[bytes] = []

    def add(self, body: bytes) -> None:
        self.parts.append(body)

    def take(self) -> Iterator[_Block]:
        if not self.parts:
            return
        channel, log_time, offset, length = [], [], [], []
        pos = 0
        for body in self.parts:
            cid, _, log_ns, _ = _MSG_HEAD.unpack_from(body, 0)
            channel.append(cid)
            log_time.append(log_ns)
            offset.append(pos + _MSG_HEAD_SIZE)
            length.append(len(body) - _MSG_HEAD_SIZE)
            pos += len(body)
        data = b''.join(self.parts)
        self.parts = []
        yield _Block(data, *_lists_to_arrays(channel, log_time, offset, length))


def _string(buf: bytes | memoryview, pos: int) -> tuple[str, int]:
    (n,) = struct.unpack_from('<I', buf, pos)
    end = pos + 4 + n
    if end > len(buf):
        raise struct.error('string runs past its record')
    return str(buf[pos + 4:end], 'utf-8'), end


def _done(fn: Callable[..., bytes], *args: Any) -> Future[bytes]:
    """A finished future holding ``fn(*args)`` or the exception it raised."""
    fut: Future[bytes] = Future()
    try:
        fut.set_result(fn(*args))
    except Exception as exc:  # re-raised where the result is taken, in file order
        fut.set_exception(exc)
    return fut


def _decompress(data: bytes | memoryview, comp: str, usize: int) -> bytes:
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


# --------------------------------------------------------------------------------------------
# Reading messages one by one


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

    Args:
        path: bag directory or ``.mcap`` file.
        topics: only these topics (default: all). A topic not in the bag is an error.
        decode: deserialize each message with the rosbags typestore (``msg`` field).
        progress: called as ``progress(bytes_read, bytes_total)``.

    Raises:
        BagError: missing bag or topic; damage, after every whole message before it was
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
        scanner = _Scanner(file, _offset_progress(progress, done_bytes, total))
        store: Typestore | None = None
        try:
            for block in scanner.blocks():
                whole += len(block.channel)
                if decode and store is None:
                    store = _bag_store(scanner.schemas)
                for cid, log_ns, off, n in zip(block.channel.tolist(), block.log_time.tolist(),
                                               block.offset.tolist(), block.length.tolist()):
                    chan = scanner.channels.get(cid)
                    if chan is None:
                        raise BagError(f'bag file {file}: message on undeclared channel {cid}')
                    if wanted is not None and chan.topic not in wanted:
                        continue
                    msgtype = _schema_name(scanner, chan)
                    data = block.data[off:off + n]
                    msg = None
                    if decode:
                        if store is None or msgtype not in store.fielddefs:
                            store = _bag_store(scanner.schemas)
                        msg = _deserialize(store, data, msgtype, chan.topic, file)
                    yield BagMessage(chan.topic, msgtype, log_ns, data, msg)
        except _Damage as dmg:
            raise BagError(dmg.message(whole)) from None
        done_bytes += scanner.size


def _deserialize(store: Typestore, data: bytes, msgtype: str, topic: str,
                 file: pathlib.Path) -> Any:
    try:
        return store.deserialize_cdr(data, msgtype)
    except Exception as exc:  # rosbags raises assorted errors on bad bytes
        raise BagError(f'bag file {file}: a {msgtype} message on {topic} does not decode: '
                       f'{exc}') from None


def _schema_name(scanner: _Scanner, chan: _Channel) -> str:
    schema = scanner.schemas.get(chan.schema_id)
    if schema is None:
        raise BagError(f'bag file {scanner.file}: topic {chan.topic} has no schema')
    return normalize_msgtype(schema[0])


def _bag_store(schemas: dict[int, tuple[str, str, str]]) -> Typestore:
    """A typestore able to decode every schema seen so far.

    The shared :func:`typestore` serves when it knows every type with the same definition;
    otherwise a fresh one is built from the bag's own definitions. Stores are kept per set
    of definitions (parsing them takes milliseconds); do not register types into them.
    """
    return _bag_store_of(tuple(schemas.values()))


@functools.lru_cache(maxsize=64)
def _bag_store_of(schemas: tuple[tuple[str, str, str], ...]) -> Typestore:
    """:func:`_bag_store` of the (name, encoding, text) of a bag's schemas."""
    base = typestore()
    extra: dict[str, Any] = {}
    conflict = False
    for name, enc, text in schemas:
        if enc != 'ros2msg' or not text:
            continue
        try:
            types = _types_from_schema(normalize_msgtype(name), text)
        except Exception:  # unparsable definition: fall back on the known one, if any
            continue
        for key, value in types.items():
            known = base.fielddefs.get(key)
            if known is None:
                extra[key] = value
            elif known != value:
                conflict = True
    if not extra and not conflict:
        return base
    store = _base_store()
    if conflict:
        store = get_typestore(Stores.EMPTY)
        for name, enc, text in schemas:
            if enc == 'ros2msg' and text:
                try:
                    extra.update(_types_from_schema(normalize_msgtype(name), text))
                except Exception:
                    continue
    else:
        store.register({k: v for k, v in base.fielddefs.items()
                        if k.startswith('auv_msgs/')})
    store.register(extra)
    return store


def bag_topics(path: str | os.PathLike[str]) -> dict[str, str]:
    """Topics of a bag and their message types (``pkg/msg/Type``).

    Read from ``metadata.yaml`` when present, else from the MCAP file's channels (a damaged
    file gives the channels found before the damage).
    """
    p = pathlib.Path(path)
    meta = p / 'metadata.yaml'
    if p.is_dir() and meta.is_file():
        try:
            info = _parse_yaml(meta.read_text())['rosbag2_bagfile_information']
            return {t['topic_metadata']['name']: normalize_msgtype(t['topic_metadata']['type'])
                    for t in info['topics_with_message_count']}
        except (KeyError, TypeError, BagError) as exc:
            raise BagError(f'bag metadata {meta} is unreadable: {exc}') from None
    found: dict[str, str] = {}
    for file in bag_files(p):
        scanner = _Scanner(file)
        try:
            for _ in scanner.blocks():
                pass
        except _Damage:
            pass
        for chan in scanner.channels.values():
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


# --------------------------------------------------------------------------------------------
# Columns of a message type (compiled once per type)


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


class _Layout(NamedTuple):
    ops: tuple[_Op, ...]
    has_header: bool
    vectorisable: bool


@functools.cache
def _layout_cached(store_id: int, msgtype: str) -> _Layout:
    return _compile(_STORES[store_id], msgtype)


_STORES: dict[int, Typestore] = {}


def _layout(store: Typestore, msgtype: str) -> _Layout:
    _STORES[id(store)] = store
    return _layout_cached(id(store), msgtype)


def _compile(store: Typestore, msgtype: str) -> _Layout:
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
    return _Layout(tuple(ops), has_header, ok[0])


def _column_names(layout: _Layout) -> list[str]:
    return [op.name for op in layout.ops if op.kind in ('num', 'time')]


# --------------------------------------------------------------------------------------------
# Vectorised CDR decoding


def _out_names(layout: _Layout) -> list[str]:
    """Fields of the arrays: ``t``, ``t_log``, then the message's columns (header stamp
    excluded: it is ``t``)."""
    return ['t', 't_log'] + [n for n in _column_names(layout) if n != 't']


@functools.cache
def _out_index(layout: _Layout) -> dict[str, int]:
    return {n: i for i, n in enumerate(_out_names(layout))}


def _decode_vectorised(layout: _Layout, data: bytes, offs: np.ndarray, lens: np.ndarray,
                       out: np.ndarray) -> bool:
    """Columns of the messages at ``offs`` (start of their CDR data, ``lens`` bytes each) in
    ``data``, vectorised over the messages, written into ``out`` (messages x
    :func:`_out_names`; column ``t_log`` is left unset).

    CDR (XCDR1, little endian): a 4-byte encapsulation header, then each primitive aligned to
    its size relative to the end of that header (the origin). The message is cut into
    segments in which every field lies at the same offset from the segment's start in all
    messages: a segment ends at a string or sequence (whose length varies per message) and
    wherever the alignment padding differs between messages. Each segment is one gather of
    its bytes for all messages (no alignment needed of the offsets), then its fields are
    strided views of the gathered rows.

    Returns:
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
        rows = _gather(data, base, off)
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


def _decode_per_message(layout: _Layout, store: Typestore, msgtype: str, data: bytes,
                        offs: Sequence[int], lens: Sequence[int], topic: str,
                        file: str | os.PathLike[str]) -> np.ndarray:
    """Columns by deserializing message by message with rosbags (the reference path).

    Returns the columns :func:`_decode_vectorised` gives (messages x :func:`_out_names`).
    """
    names = _out_names(layout)
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


# --------------------------------------------------------------------------------------------
# Reading arrays


class BagArrays(dict[str, np.ndarray]):
    """Arrays of a bag, one structured numpy array per topic (see :func:`read_arrays`).

    Attributes:
        path: the bag that was read.
        damage: the damage report (one line) if the bag was damaged and read with
            ``allow_truncated=True``, else None.
    """

    path: str
    damage: str | None

    @property
    def truncated(self) -> bool:
        """True if the bag was damaged and only the whole messages before the damage are here."""
        return self.damage is not None


class _TopicRows:
    """The columns of one topic, decoded block by block as the bag is read (so that no
    uncompressed chunk is kept), in a matrix that grows as messages come."""

    def __init__(self, msgtype: str, layout: _Layout, store: Typestore, capacity: int) -> None:
        self.msgtype = msgtype
        self.layout = layout
        self.store = store
        self.mat = np.empty((capacity, len(_out_names(layout))))  # pages touched when filled
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
                and _decode_vectorised(self.layout, data, offs, lens, rows)):
            try:
                rows[:] = _decode_per_message(self.layout, self.store, self.msgtype, data,
                                              offs.tolist(), lens.tolist(), topic, path)
            except BagError as exc:  # raised once the whole bag has been read
                self.error = exc
                return
        self.n += k
        self.logs.append(log)


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

    Args:
        path: bag directory or ``.mcap`` file.
        topics: topics to read; each must be in the bag.
        allow_truncated: on damage, return what was read before it (``result.damage`` holds
            the report) instead of raising.
        check_order: require non-decreasing ``t`` within each topic.
        fast: use the vectorised decoder where it applies (False: rosbags for every message;
            the reference the benchmark compares against).
        progress: called as ``progress(bytes_read, bytes_total)``.
        workers: threads that decompress and CRC-check chunks ahead of the decoding (default:
            :func:`default_workers`; 1 does everything in the calling thread). The arrays
            and the damage report do not depend on it.

    Raises:
        BagError: missing bag or topic; damage (unless ``allow_truncated``), with the number of
            whole messages read before it; a topic whose stamps go back in time (topic and
            message index named).
    """
    topics = list(dict.fromkeys(topics))
    files, counts = _bag_contents(path)
    total = _total_size(files)
    parts: dict[str, _TopicRows] = {}
    present: dict[str, str] = {}
    damage: str | None = None
    whole = 0
    done_bytes = 0
    # Rows to reserve per topic: the count metadata.yaml states, at most one message per 8
    # bytes of the bag (a wrong count only costs a copy when rows are added or removed).
    capacity = {t: max(0, min(n, total // 8)) for t, n in counts.items()}
    for file in files:
        scanner = _Scanner(file, _offset_progress(progress, done_bytes, total), workers)
        try:
            for block in scanner.blocks():
                whole += len(block.channel)
                _collect(block, scanner, topics, parts, present, file, path, fast, capacity)
        except _Damage as dmg:
            damage = dmg.message(whole)
        for chan in scanner.channels.values():
            present.setdefault(chan.topic, _schema_name(scanner, chan))
        done_bytes += scanner.size
        if damage is not None:
            break
    if damage is not None and not allow_truncated:
        raise BagError(damage)
    _check_topics(path, topics, present)

    result = BagArrays()
    result.path = str(path)
    result.damage = damage
    for topic in topics:
        tp = parts.get(topic)
        if tp is None:  # declared, but no message before the end (or the damage)
            layout = _layout(typestore(), present[topic])
            result[topic] = _assemble(layout, np.empty((0, len(_out_names(layout)))),
                                      np.empty(0, np.int64))
            continue
        if tp.error is not None:
            raise tp.error
        mat = tp.mat[:tp.n] if 2 * tp.n >= len(tp.mat) else tp.mat[:tp.n].copy()
        logs = tp.logs
        log = logs[0] if len(logs) == 1 else np.concatenate(logs or [np.empty(0, np.int64)])
        arr = _assemble(tp.layout, mat, log)
        if check_order and len(arr) > 1:
            back = np.flatnonzero(np.diff(arr['t']) < 0)
            if len(back):
                i = int(back[0]) + 1
                raise BagError(f'topic {topic} in bag {path}: time stamps go back at message '
                               f'{i} ({arr["t"][i - 1]:.9f} s, then {arr["t"][i]:.9f} s)')
        result[topic] = arr
    return result


def _collect(block: _Block, scanner: _Scanner, topics: list[str],
             parts: dict[str, _TopicRows], present: dict[str, str], file: pathlib.Path,
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
        chan = scanner.channels.get(int(cid))
        if chan is None:
            raise BagError(f'bag file {file}: message on undeclared channel {int(cid)}')
        if chan.topic not in topics:
            continue
        msgtype = _schema_name(scanner, chan)
        tp = parts.get(chan.topic)
        if tp is None:
            store = _bag_store(scanner.schemas)
            tp = _TopicRows(msgtype, _layout(store, msgtype), store,
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


def _assemble(layout: _Layout, mat: np.ndarray, log_ns: np.ndarray) -> np.ndarray:
    """The structured array (fields of :func:`_out_names`, float64, s) over ``mat``, no copy.

    Fills ``t_log`` from the log times (ns) and, for types with no header, ``t`` too.
    """
    sec, nsec = np.divmod(log_ns, 1_000_000_000)
    mat[:, 1] = sec.astype(np.float64) + nsec.astype(np.float64) * 1e-9
    if not layout.has_header:
        mat[:, 0] = mat[:, 1]
    dtype = np.dtype([(n, '<f8') for n in _out_names(layout)])
    return np.ascontiguousarray(mat).view(dtype).reshape(len(mat))
