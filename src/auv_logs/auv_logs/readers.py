"""Readers of real logs into columns: bags through rosbags, text logs through numpy.

Bags: rosbag2 directories (``metadata.yaml`` with MCAP or sqlite3 storage) and ROS 1 ``.bag``
files are read with :class:`rosbags.highlevel.AnyReader`, which takes every message type from
the definitions embedded in the bag (a vendor's custom message needs no code); types a bag
does not define come from the ROS 2 typestore of :func:`auv_bag.typestore` (standard
types and ``auv_msgs``). A bare ``.mcap`` file (no ``metadata.yaml``) is read with the
``mcap`` package's reader and its schemas registered into rosbags. Messages are deserialized
one by one by rosbags and only the mapped fields are kept.

MCAP storage (a rosbag2 directory or a bare ``.mcap`` file) is first tried through this
project's columnar decoder (:func:`auv_bag.read_arrays`: vectorised CDR decoding on top
of the ``mcap`` container; a damaged file is reported as one line naming the byte offset);
fields it does not give as plain columns fall back to the per-message path above. A rosbag2
directory compressed by the recorder (``compression_format`` in ``metadata.yaml``: a
``.mcap.zstd`` file or compressed messages) is read by rosbags, which decompresses it.

Text logs: CSV, semicolon, tab or whitespace separated, with or without a header line; a row
with another number of fields or a field that is not a number (a last row cut off mid-line)
is left out and said in the table's ``skipped`` lines (``strict``: an error naming the file
and line);
lines starting with the comment character are skipped; a UTF-8 byte-order mark at the
start of the file is dropped; LF or CRLF line ends; double-quoted fields (``"Depth (cm)"``)
are unquoted.

Stamps: ``header`` (the message's ``header.stamp``, s) or ``log`` (the recorder's receive
time, s); a text log's time column in its unit. Nothing is resampled here.
"""
from __future__ import annotations

import csv
import dataclasses
import os
import pathlib
import re
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from typing import Any

import numpy as np

from auv_contract import YamlError, read_yaml
from auv_logs.errors import LogReadError

#: File kinds the readers know.
KNOWN_KINDS = ('rosbag2 directory (metadata.yaml; MCAP or sqlite3 storage)', '.mcap file',
               'ROS 1 .bag file', 'text log (.csv, .txt, .log, .dat, .tsv)')
TEXT_SUFFIXES = ('.csv', '.txt', '.log', '.dat', '.tsv')
_STEP = re.compile(r'^([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)$')


@dataclasses.dataclass(frozen=True)
class Table:
    """Columns of one topic (or one text file): ``stamps`` [s] (N) and, per requested field
    path or column, its values (N, float64) as logged (no unit conversion); ``stamp_kind``
    says which stamps: ``header``, ``log`` or ``column``; for a text log, the rows left out
    (``skipped``) and the file line of each row kept (``lines``)."""

    source: str
    msgtype: str
    stamps: np.ndarray
    columns: Mapping[str, np.ndarray]
    stamp_kind: str = 'header'
    #: rows of a text log left out, one line per kind of problem (see :func:`read_text`)
    skipped: tuple[str, ...] = ()
    #: the file line of each row (text logs), for messages that name a row
    lines: np.ndarray | None = None


def log_kind(path: str | os.PathLike[str]) -> str:
    """``rosbag2``, ``mcap``, ``ros1`` or ``text``.

    Raises
    ------
    LogReadError
        the path is missing or of a kind the readers do not know.
    """
    p = pathlib.Path(path)
    if not p.exists():
        raise LogReadError(f'log {p} does not exist')
    if p.is_dir():
        if (p / 'metadata.yaml').exists():
            return 'rosbag2'
        raise LogReadError(f'{p} is a directory without metadata.yaml: not a rosbag2 bag '
                           f'(known log kinds: {"; ".join(KNOWN_KINDS)})')
    suffix = p.suffix.lower()
    if suffix == '.mcap':
        return 'mcap'
    if suffix == '.bag':
        return 'ros1'
    if suffix == '.db3':
        if (p.parent / 'metadata.yaml').exists():
            return 'rosbag2'
        raise LogReadError(f'{p}: a sqlite3 bag file is read with its bag directory (holding '
                           'metadata.yaml); give the directory')
    if suffix in TEXT_SUFFIXES:
        return 'text'
    raise LogReadError(f'{p}: unknown log kind {suffix or "(no suffix)"!r} (known log kinds: '
                       f'{"; ".join(KNOWN_KINDS)})')


# --------------------------------------------------------------------------------------------
# the file's own time

#: A date and time in a file name or a header comment: ``2025-04-10T14:33:41``,
#: ``2025-04-10_14-33-41``, ``20250410_143341``, ``2025-04-10 14:33`` (seconds optional), an
#: optional ``Z`` or ``+hh:mm`` zone (default UTC).
_DATETIME = re.compile(
    r'(?<!\d)(\d{4})-?(\d{2})-?(\d{2})[T_ \-]?(\d{2})[:\-h]?(\d{2})(?:[:\-m]?(\d{2})'
    r'(?:\.(\d+))?)?(Z|[+\-]\d{2}:?\d{2})?(?!\d)')
#: Leading lines of a text log searched for a start time in a comment.
HEADER_LINES = 20


def _parse_datetime(text: str) -> float | None:
    """The first plausible date and time in ``text`` as seconds since the epoch, or None."""
    import datetime

    for m in _DATETIME.finditer(text):
        y, mo, d, h, mi, sec, frac, zone = m.groups()
        try:
            tz = datetime.UTC
            if zone and zone != 'Z':
                sign = 1 if zone[0] == '+' else -1
                hh, mm = int(zone[1:3]), int(zone[-2:])
                tz = datetime.timezone(sign * datetime.timedelta(hours=hh, minutes=mm))
            stamp = datetime.datetime(int(y), int(mo), int(d), int(h), int(mi),
                                      int(sec or 0), tzinfo=tz).timestamp()
        except ValueError:
            continue
        if 1990 <= int(y) <= 2100:
            return stamp + (float(f'0.{frac}') if frac else 0.0)
    return None


def file_time(path: str | os.PathLike[str]) -> float | None:
    """The start time a log file states of itself [s since the epoch, UTC unless a zone is
    given], or None: a date and time in a comment among the first :data:`HEADER_LINES` lines
    of a text log (``# start 2025-04-10T14:33:41Z``), else in the file's name
    (``dive_2025-04-10_14-33-41.txt``, ``20250410_143341.log``). For a log timed from its own
    start, this is the clock of its first row."""
    p = pathlib.Path(path)
    if p.is_file() and p.suffix.lower() in TEXT_SUFFIXES:
        try:
            with open(p, encoding='utf-8-sig', errors='replace') as fh:
                head = [fh.readline() for _ in range(HEADER_LINES)]
        except OSError:
            head = []
        for line in head:
            s = line.strip()
            if s.startswith(('#', '%', ';', '//')):
                found = _parse_datetime(s)
                if found is not None:
                    return found
    return _parse_datetime(p.stem if p.is_file() else p.name)


# --------------------------------------------------------------------------------------------
# field paths

def compile_path(path: str) -> Callable[[Any], Any]:
    """A getter for a field path such as ``pose.pose.position.x`` or ``data[2]`` or
    ``fins[1].angle``.

    Raises
    ------
    LogReadError
        the path is not well formed.
    """
    steps: list[tuple[str, tuple[int, ...]]] = []
    for part in path.split('.'):
        m = _STEP.match(part)
        if m is None:
            raise LogReadError(f'field path {path!r} is not well formed at {part!r}')
        steps.append((m.group(1), tuple(int(i) for i in re.findall(r'\[(\d+)\]', m.group(2)))))

    def get(msg: Any) -> Any:
        obj = msg
        for name, idx in steps:
            obj = getattr(obj, name)
            for i in idx:
                obj = obj[i]
        return obj

    return get


def _fields_of(msg: Any) -> str:
    names: Iterable[str] = (getattr(type(msg), '__dataclass_fields__', None)
                            or getattr(msg, '__slots__', None) or ())
    return ', '.join(n for n in names if not n.startswith('_'))


def _check_path(msg: Any, path: str, topic: str, msgtype: str) -> None:
    """Resolve ``path`` on one message; raise naming the part that does not exist."""
    obj = msg
    walked: list[str] = []
    for part in path.split('.'):
        m = _STEP.match(part)
        if m is None:
            raise LogReadError(f'field path {path!r} is not well formed at {part!r}')
        name = m.group(1)
        if not hasattr(obj, name) or name.startswith('_'):
            where = '.'.join(walked) or msgtype
            raise LogReadError(f'topic {topic} ({msgtype}) has no field {path!r}: {where} has '
                               f'no {name!r} (it has: {_fields_of(obj)})')
        obj = getattr(obj, name)
        walked.append(name)
        for i in re.findall(r'\[(\d+)\]', m.group(2)):
            try:
                obj = obj[int(i)]
            except (IndexError, TypeError):
                raise LogReadError(f'topic {topic} ({msgtype}): field {path!r}: '
                                   f'{".".join(walked)} has no element {i}') from None
    try:
        float(obj)
    except (TypeError, ValueError):
        has = _fields_of(obj)
        raise LogReadError(f'topic {topic} ({msgtype}): field {path!r} is not a number '
                           f'({getattr(obj, "__msgtype__", type(obj).__name__)}'
                           f'{"; it has: " + has if has else ""})') from None


# --------------------------------------------------------------------------------------------
# bags

def _seconds(ns: int) -> float:
    """A receive time [ns] in seconds, computed as a header stamp is (``sec + nanosec 1e-9``)
    so that equal instants compare equal."""
    sec, nsec = divmod(int(ns), 1_000_000_000)
    return float(sec) + float(nsec) * 1e-9


def _stamp_of(msg: Any) -> float:
    st = msg.header.stamp
    return float(st.sec) + 1e-9 * float(st.nanosec)


def _has_header(msg: Any) -> bool:
    """Whether ``msg`` has a ``std_msgs/Header`` ``header`` (a stamp of sec and nanosec; a
    vendor's own ``header`` type does not count)."""
    st = getattr(getattr(msg, 'header', None), 'stamp', None)
    return hasattr(st, 'sec') and hasattr(st, 'nanosec')


def _stamp_kind(stamp: str | Mapping[str, str], topic: str) -> str:
    """The stamp source asked for ``topic``: ``stamp`` itself, or its entry in a per-topic
    mapping (default ``header``)."""
    return stamp if isinstance(stamp, str) else stamp.get(topic, 'header')


def _collect(messages: Iterable[tuple[str, str, int, Any]], requests: Mapping[str, Sequence[str]],
             stamp: str | Mapping[str, str]) -> dict[str, Table]:
    """Gather (topic, msgtype, log time ns, message) into tables of the requested fields."""
    getters = {topic: [(p, compile_path(p)) for p in paths] for topic, paths in requests.items()}
    stamps: dict[str, list[float]] = {t: [] for t in requests}
    cols: dict[str, dict[str, list[float]]] = {t: {p: [] for p in ps} for t, ps in
                                                requests.items()}
    types: dict[str, str] = {}
    kinds: dict[str, str] = {}
    for topic, msgtype, log_ns, msg in messages:
        if topic not in types:
            types[topic] = msgtype
            for p in requests[topic]:
                _check_path(msg, p, topic, msgtype)
            kinds[topic] = ('header' if _stamp_kind(stamp, topic) == 'header'
                            and _has_header(msg) else 'log')
        stamps[topic].append(_stamp_of(msg) if kinds[topic] == 'header' else _seconds(log_ns))
        c = cols[topic]
        for p, get in getters[topic]:
            c[p].append(float(get(msg)))
    out = {}
    for topic in requests:
        if topic not in types:
            raise LogReadError(f'topic {topic} has no messages')
        out[topic] = Table(topic, types[topic], np.asarray(stamps[topic]),
                           {p: np.asarray(v) for p, v in cols[topic].items()}, kinds[topic])
    return out


def _unknown_type(topic: str, msgtype: str, in_bag: Iterable[str],
                  builtin: Iterable[str]) -> LogReadError:
    bag = sorted(set(in_bag) - set(builtin))
    n = len(set(builtin))
    return LogReadError(f'topic {topic}: message type {msgtype} has no definition in the bag '
                        f'and is not a type the readers know (the bag defines: '
                        f'{", ".join(bag) or "none"}; built in: {n} standard ROS 2 types and '
                        'auv_msgs)')


def _read_anyreader(path: pathlib.Path, requests: Mapping[str, Sequence[str]],
                    stamp: str | Mapping[str, str]) -> dict[str, Table]:
    from rosbags.highlevel import AnyReader
    from rosbags.interfaces import Connection

    from auv_bag import typestore

    store = typestore()
    try:
        reader = AnyReader([path], default_typestore=store)
        reader.open()
    except Exception as exc:  # rosbags raises assorted errors on a bad bag
        raise LogReadError(f'cannot open bag {path}: {exc}') from None
    try:
        present = {c.topic: c.msgtype for c in reader.connections}
        for topic in requests:
            if topic not in present:
                raise LogReadError(f'bag {path} has no topic {topic} (it has: '
                                   f'{", ".join(sorted(present))})')
        conns: list[Connection] = [c for c in reader.connections if c.topic in requests]
        known = set(reader.typestore.fielddefs) | set(store.fielddefs)
        for c in conns:
            if c.msgtype not in known:
                raise _unknown_type(c.topic, c.msgtype, reader.typestore.fielddefs,
                                    store.fielddefs)

        def messages() -> Iterator[tuple[str, str, int, Any]]:
            for conn, log_ns, raw in reader.messages(connections=conns):
                try:
                    msg = reader.deserialize(raw, conn.msgtype)
                except Exception as exc:
                    raise LogReadError(f'bag {path}: a {conn.msgtype} message on {conn.topic} '
                                       f'does not decode: {exc}') from None
                yield conn.topic, conn.msgtype, log_ns, msg

        return _collect(messages(), requests, stamp)
    finally:
        reader.close()


def _read_mcap_file(path: pathlib.Path, requests: Mapping[str, Sequence[str]],
                    stamp: str | Mapping[str, str]) -> dict[str, Table]:
    from mcap.exceptions import McapError
    from mcap.reader import make_reader
    from rosbags.typesys import Stores, get_typestore

    from auv_bag import typestore
    from auv_bag.typestore import types_from_schema

    store = get_typestore(Stores.LATEST)
    base = typestore()
    store.register({k: v for k, v in base.fielddefs.items() if k not in store.fielddefs})
    try:
        with open(path, 'rb') as fh:
            reader = make_reader(fh)
            summary = reader.get_summary()
            if summary is None:
                raise LogReadError(f'{path}: MCAP file without a summary (cut short?); '
                                   'recover it with `mcap recover`')
            present = {ch.topic: summary.schemas[ch.schema_id].name
                       for ch in summary.channels.values()}
            for topic in requests:
                if topic not in present:
                    raise LogReadError(f'bag {path} has no topic {topic} (it has: '
                                       f'{", ".join(sorted(present))})')
            for ch in summary.channels.values():
                if ch.topic not in requests:
                    continue
                sc = summary.schemas[ch.schema_id]
                if sc.data:
                    types = types_from_schema(sc.name, sc.data.decode())
                    store.register({k: v for k, v in types.items()
                                    if k not in store.fielddefs})
                if sc.name not in store.fielddefs:
                    raise _unknown_type(ch.topic, sc.name, (), base.fielddefs)

            def messages() -> Iterator[tuple[str, str, int, Any]]:
                for schema, channel, message in reader.iter_messages(topics=list(requests)):
                    assert schema is not None
                    yield (channel.topic, schema.name, message.log_time,
                           store.deserialize_cdr(message.data, schema.name))

            return _collect(messages(), requests, stamp)
    except McapError as exc:
        raise LogReadError(f'cannot read MCAP file {path}: {str(exc) or type(exc).__name__}') \
            from None


def read_bag(path: str | os.PathLike[str], requests: Mapping[str, Sequence[str]],
             stamp: str | Mapping[str, str] = 'header', fast: bool = True
             ) -> dict[str, Table]:
    """Read the requested fields of the requested topics of a bag.

    Parameters
    ----------
    path
        rosbag2 directory (MCAP or sqlite3), bare ``.mcap`` file or ROS 1 ``.bag``.
    requests
        topic -> field paths (``pose.pose.position.x``, ``data[2]``).
    stamp
        ``header`` (header stamps; the receive times for a type with no header, said
        in the table's ``stamp_kind``) or ``log`` (receive times), for every topic or
        per topic (a mapping topic -> ``header``/``log``; a topic not in it: header).
    fast
        MCAP storage through the columnar decoder of :func:`auv_bag.read_arrays`
        (falls back to rosbags for what it cannot give); False: rosbags only.

    Raises
    ------
    LogReadError
        unknown kind, missing topic, field path not in the message, message
        type the readers do not know, a topic with no messages.
    """
    p = pathlib.Path(path)
    kind = log_kind(p)
    if kind == 'text':
        raise LogReadError(f'{p} is a text log but the map is for bags (kind: bag)')
    if kind == 'rosbag2' and p.is_file():
        p = p.parent
    # a compressed rosbag2 (``--compression-mode file`` or ``message``) is read by rosbags
    if fast and (kind == 'mcap' or (_storage(p) == 'mcap'
                                    and not _storage(p, 'compression_format'))):
        tables = _read_columnar(p, requests, stamp)
        if tables is not None:
            return tables
    if kind == 'mcap':
        return _read_mcap_file(p, requests, stamp)
    return _read_anyreader(p, requests, stamp)


def _storage(bag_dir: pathlib.Path, key: str = 'storage_identifier') -> str:
    """The storage identifier of a rosbag2 directory (``mcap``, ``sqlite3``), or another
    entry of its ``metadata.yaml`` (``compression_format``: ``zstd``, or '')."""
    try:
        info = read_yaml(bag_dir / 'metadata.yaml')
        return str(info['rosbag2_bagfile_information'].get(key) or '')
    except (OSError, KeyError, TypeError, AttributeError, YamlError):
        return ''


def _column_name(path: str) -> str:
    """The :func:`auv_bag.read_arrays` column of a field path (``a.b[2]`` -> ``a_b_2``)."""
    return re.sub(r'\[(\d+)\]', r'_\1', path).replace('.', '_')


def _header_topics(files: Sequence[pathlib.Path], topics: Iterable[str]) -> dict[str, bool]:
    """Whether each topic's message type has a ``header`` (from the MCAP schemas; a topic
    whose file has no readable summary or whose schema does not parse is left out)."""
    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    from auv_bag.typestore import types_from_schema

    out: dict[str, bool] = {}
    wanted = set(topics)
    for f in files:
        try:
            with open(f, 'rb') as fh:
                summary = make_reader(fh).get_summary()
        except McapError:
            continue
        if summary is None:
            continue
        for ch in summary.channels.values():
            if ch.topic in wanted and ch.topic not in out:
                sc = summary.schemas[ch.schema_id]
                try:
                    defs = types_from_schema(sc.name, sc.data.decode()).get(sc.name)
                except Exception:  # rosbags raises assorted errors on a bad definition
                    continue
                out[ch.topic] = defs is not None and any(
                    f[0] == 'header' and f[1][1] == 'std_msgs/msg/Header' for f in defs[1])
    return out


def _read_columnar(path: pathlib.Path, requests: Mapping[str, Sequence[str]],
                   stamp: str | Mapping[str, str]) -> dict[str, Table] | None:
    """MCAP storage through this project's columnar decoder (:func:`auv_bag.read_arrays`:
    vectorised CDR decoding on the ``mcap`` container, damage reported as one line). None when
    a requested topic or field is not a plain column there (the per-message readers then
    read it and name what is wrong)."""
    from auv_bag import bag_files, bag_topics, read_arrays
    from auv_bag.errors import BagError

    try:
        present = bag_topics(path)
        if any(t not in present for t in requests):
            return None
        arrays = read_arrays(path, list(requests), check_order=False)   # damage: one line
        headers = _header_topics(bag_files(path), requests)
    except BagError as exc:
        raise LogReadError(str(exc)) from None
    tables = {}
    for topic, paths in requests.items():
        arr = arrays[topic]
        names = set(arr.dtype.names or ())
        cols = {p: _column_name(p) for p in paths}
        if any(c not in names for c in cols.values()) or topic not in headers:
            return None
        if len(arr) == 0:
            raise LogReadError(f'topic {topic} has no messages')
        kind = 'header' if _stamp_kind(stamp, topic) == 'header' and headers[topic] else 'log'
        tables[topic] = Table(topic, present[topic],
                              np.array(arr['t'] if kind == 'header' else arr['t_log']),
                              {p: np.array(arr[c]) for p, c in cols.items()}, kind)
    return tables


# --------------------------------------------------------------------------------------------
# text logs

#: Above this share of bad rows (wrong field count, a field not a number) a text log is refused
#: even when bad rows are skipped: the map's delimiter or columns do not fit the file.
BAD_ROW_SHARE = 0.2


def read_text(path: str | os.PathLike[str], columns: Sequence[str], time_column: str, *,
              delimiter: str | None, header: bool, names: Sequence[str] = (),
              comment: str = '#', strict: bool = False) -> Table:
    """Read a text log's columns.

    Parameters
    ----------
    path
        the file.
    columns
        column names wanted (besides the time column).
    time_column
        name of the time column (its values are returned as ``stamps``, in the
        log's unit; the caller converts).
    delimiter
        ``None`` for whitespace, else the separator character.
    header
        the first non-comment line names the columns.
    names
        column names when there is no header (or to override it).
    comment
        lines starting with this are skipped.
    strict
        refuse a row with the wrong number of fields or a field that is not a
        number; otherwise such a row (typically the last, cut off mid-line by a logger
        switched off while writing) is left out and said in :attr:`Table.skipped`, one
        line per kind of problem.

    Raises
    ------
    LogReadError
        missing file or column, no data rows, a non-finite time; with
        ``strict`` a ragged row or a field that is not a number; without it, more than
        :data:`BAD_ROW_SHARE` of the rows bad (the map does not fit the file).
    """
    p = pathlib.Path(path)
    try:
        # utf-8-sig: a byte-order mark (Windows tools write one) is not part of the first
        # column's name or value
        lines = p.read_text(encoding='utf-8-sig', errors='replace').splitlines()
    except OSError as exc:
        raise LogReadError(f'cannot read log {p}: {exc.strerror}') from None
    rows: list[list[str]] = []
    line_no: list[int] = []
    head: list[str] | None = None
    for i, line in enumerate(lines, 1):
        s = line.strip()
        if not s or (comment and s.startswith(comment)):
            continue
        if delimiter is None:
            fields = s.split()
        elif '"' in s:      # quoted fields (RFC 4180), as spreadsheets and pandas write them
            fields = next(csv.reader([s], delimiter=delimiter, skipinitialspace=True))
        else:
            fields = s.split(delimiter)
        fields = [f.strip() for f in fields]
        if header and head is None:
            head = fields
            continue
        rows.append(fields)
        line_no.append(i)
    if not rows:
        raise LogReadError(f'{p}: no data rows' + ('' if head else ' (the file is empty)'))
    col_names = list(names) if names else (head or [])
    if not col_names:
        raise LogReadError(f'{p}: no column names (no header line and no columns: in the map)')
    if len(set(col_names)) != len(col_names):
        raise LogReadError(f'{p}: column names repeat: {col_names}')
    index = {n: k for k, n in enumerate(col_names)}
    for name in [time_column, *columns]:
        if name not in index:
            raise LogReadError(f'{p}: no column {name!r} (columns: {", ".join(col_names)})')
    width = len(col_names)
    wanted = [(name, index[name]) for name in [time_column, *columns]]
    bad: dict[str, list[int]] = {}          # problem -> line numbers
    values = np.empty((len(rows), len(wanted)))
    good = np.ones(len(rows), bool)
    for j, (fields, no) in enumerate(zip(rows, line_no)):
        problem = None
        if len(fields) != width:
            problem = (f'{len(fields)} fields, expected {width} '
                       f'({", ".join(col_names)})')
        else:
            for c, (name, k) in enumerate(wanted):
                try:
                    values[j, c] = float(fields[k])
                except ValueError:
                    problem = f'column {name!r} is not a number: {fields[k]!r}'
                    break
        if problem is None:
            continue
        if strict:
            raise LogReadError(f'{p} line {no}: {problem}')
        good[j] = False
        bad.setdefault(problem if len(fields) == width else f'{len(fields)} fields, '
                       f'expected {width}', []).append(no)
    nbad = int(np.count_nonzero(~good))
    if nbad > BAD_ROW_SHARE * len(rows):
        first = next(iter(bad))
        raise LogReadError(f'{p}: {nbad} of {len(rows)} rows do not parse (line '
                           f'{bad[first][0]}: {first}): does the map\'s delimiter or '
                           'columns: fit this file?')
    skipped = []
    last = line_no[-1]
    for problem, nos in bad.items():
        where = (f'line {nos[0]}' if len(nos) == 1 else
                 f'{len(nos)} rows (lines {", ".join(map(str, nos[:5]))}'
                 f'{", ..." if len(nos) > 5 else ""})')
        cut = ' (the last row, cut off mid-line?)' if nos == [last] else ''
        skipped.append(f'{p.name} {where}: {problem}: left out{cut}')
    values = values[good]
    if not len(values):
        raise LogReadError(f'{p}: no data rows that parse ({"; ".join(skipped)})')
    out = {name: values[:, c] for c, (name, _) in enumerate(wanted)}
    stamps = out.pop(time_column)
    rows_kept = np.asarray(line_no)[good]
    nonfinite = np.flatnonzero(~np.isfinite(stamps))
    if len(nonfinite):
        raise LogReadError(f'{p} line {rows_kept[int(nonfinite[0])]}: time is not finite')
    return Table(str(p), 'text', stamps, out, 'column', tuple(skipped), rows_kept)
