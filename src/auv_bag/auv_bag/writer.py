"""Writing rosbag2 bags in MCAP storage, as ``ros2 bag record -s mcap`` does, without a ROS graph.

The MCAP container (records, chunks, compression, summary) is written by the ``mcap`` package's
:class:`mcap.writer.Writer`; this module adds the rosbag2 conventions: profile ``ros2``,
schema encoding ``ros2msg`` with the full concatenated message definition, message encoding
``cdr``, the offered QoS profiles in each channel's metadata, and ``metadata.yaml``.

Times: ``log_time`` is when the recorder received a message (ns since the Unix epoch, or since
the start of simulated time); ``publish_time`` is when the publisher sent it (the log time
where none is known).
"""
from __future__ import annotations

import math
import os
import pathlib
import time
from typing import IO, Any, NamedTuple

from rosbags.typesys.store import Typestore

from .errors import BagError
from .metadata import parse_yaml, qos_profiles_yaml, yaml_dump
from .typestore import message_definition, normalize_msgtype, typestore

__all__ = ['BagWriter']


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

        Parameters
        ----------
        path
            bag directory, or a file name ending in ``.mcap`` for a bare MCAP file.
        compression
            chunk compression, ``zstd`` (rosbag2's default), ``lz4`` or ``none``.
        chunk_size
            uncompressed chunk size that triggers writing the chunk (bytes).
        flush_interval
            longest time a message stays in memory before it is written (s,
            wall clock); 0 writes every message at once.
        store
            typestore for message objects and definitions (default: :func:`typestore`).
        custom_data
            strings for ``metadata.yaml``'s ``custom_data`` (and an MCAP
            metadata record ``custom_data``), e.g. an import's provenance.

        Raises
        ------
        BagError
            the path exists and is not an empty directory, or cannot be created.
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
        self._writer.start(profile='ros2', library='auv_bag (mcap-python)')
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

        Parameters
        ----------
        topic
            topic name, e.g. ``/auv/state``.
        msgtype
            message type; must be known to the typestore (its definition is stored).
        qos
            offered QoS profiles as YAML (default: :func:`qos_profiles_yaml`, reliable).

        Raises
        ------
        BagError
            the type is unknown, or the topic was declared with another type.
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
            text = message_definition(self._store, msgtype)
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

        Parameters
        ----------
        topic
            topic name; declared with :meth:`add_topic`, or declared here from the
            ``__msgtype__`` of a message object.
        message
            serialized CDR bytes (with the 4-byte encapsulation header), or a rosbags
            message object.
        log_time_ns
            receive time (ns); default: now, wall clock since the Unix epoch.
        publish_time_ns
            publish time (ns); default: the log time.

        Raises
        ------
        BagError
            undeclared topic given as bytes, or an object that cannot be serialized.
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
            self._writer.add_metadata('rosbag2', {'serialized_metadata': yaml_dump(info)})
            if self._custom:
                self._writer.add_metadata('custom_data', self._custom)
            self._writer.finish()  # type: ignore[no-untyped-call]  # mcap 1.6: unannotated
        finally:
            self._stream.close()
        if self._dir is not None:
            text = yaml_dump({'rosbag2_bagfile_information': info})
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
                        'offered_qos_profiles': parse_yaml(info.qos),
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

