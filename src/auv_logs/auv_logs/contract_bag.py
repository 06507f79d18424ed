"""An imported log (:class:`auv_logs.importer.ContractLog`) as the contract's arrays and as a
contract bag, with the provenance of the import.

:func:`contract_arrays` gives the arrays :func:`auv_bag.read_arrays` gives for the contract
bag of a log; :func:`write_contract_bag` writes that bag (``/auv/state`` in the ``ned``
frame: NED position [m], Euler angles [rad], FRD body velocities [m/s] and rates [rad/s];
each command and measured fin position [rad or N] on its contract topic, its channel as
``frame_id``), stamps [s] rounded to the nanosecond. :func:`provenance` is what the bag was
made from (source files and their SHA-256, the map, each log's import report, the logs left
out); it is stored in the bag's ``metadata.yaml`` and read back by
:func:`read_provenance`.
"""
from __future__ import annotations

import datetime
import hashlib
import itertools
import json
import os
import pathlib
import shutil
import tempfile
from collections.abc import Sequence
from typing import Any

import numpy as np

from auv_contract import COMMAND_TOPICS, MEASURED_TOPICS, STATE_TOPIC, read_yaml
from auv_logs.errors import RealLogError
from auv_logs.importer import ContractLog
from auv_logs.mapping import STATE, LogMap

#: Map signal -> contract topic of the measured fin positions
#: (:data:`auv_contract.MEASURED_TOPICS`).
MEASURED_SIGNAL_TOPICS = {f'{ch}_measured': topic for ch, topic in MEASURED_TOPICS.items()}
#: Nanoseconds in a second (bag stamps are integer nanoseconds).
NS = 1_000_000_000


def _file_hash(path: pathlib.Path) -> dict[str, str]:
    files = sorted(p for p in path.rglob('*') if p.is_file()) if path.is_dir() else [path]
    out = {}
    for f in files:
        h = hashlib.sha256()
        with open(f, 'rb') as fh:
            for block in iter(lambda: fh.read(1 << 20), b''):
                h.update(block)
        out[str(f)] = h.hexdigest()
    return out


def _ns(t: np.ndarray) -> np.ndarray:
    out: np.ndarray = np.round(np.asarray(t, float) * NS).astype(np.int64)
    return out


def _seconds(ns: np.ndarray) -> np.ndarray:
    """As :func:`auv_bag.read_arrays` computes stamps: ``sec + nanosec * 1e-9``."""
    sec, nsec = np.divmod(ns, NS)
    out: np.ndarray = sec.astype(np.float64) + nsec.astype(np.float64) * 1e-9
    return out


def contract_arrays(log: ContractLog) -> dict[str, np.ndarray]:
    """The arrays :func:`auv_bag.read_arrays` gives for the contract bag of ``log``
    (``/auv/state`` with ``t``, ``t_log`` and the 12 state fields; each command topic with
    ``t``, ``t_log``, ``value``), stamps rounded to the nanosecond as the bag stores them."""
    ts = _seconds(_ns(log.t))
    dtype = np.dtype([(n, '<f8') for n in ('t', 't_log', *STATE)])
    st = np.empty(len(ts), dtype)
    st['t'] = ts
    st['t_log'] = ts
    for k, sig in enumerate(STATE):
        st[sig] = log.state[:, k]
    out = {STATE_TOPIC: st}
    cdt = np.dtype([('t', '<f8'), ('t_log', '<f8'), ('value', '<f8')])
    for ch, topic in {**COMMAND_TOPICS, **MEASURED_SIGNAL_TOPICS}.items():
        if ch not in log.commands:
            continue
        ct, cv = log.commands[ch]
        arr = np.empty(len(ct), cdt)
        arr['t'] = _seconds(_ns(ct))
        arr['t_log'] = arr['t']
        arr['value'] = cv
        out[topic] = arr
    return out


def provenance(logmap: LogMap, logs: Sequence[ContractLog],
               skipped: Sequence[str] = ()) -> dict[str, Any]:
    """What the contract bag was made from: source files and their SHA-256, the map text,
    each log's import report, and the logs left out (one line each)."""
    files: dict[str, str] = {}
    for lg in logs:
        files.update(_file_hash(pathlib.Path(str(lg.report['log']))))
    return {
        'tool': 'auv import',
        'created': datetime.datetime.now(datetime.UTC).isoformat(timespec='seconds'),
        'map_path': logmap.path,
        'map_sha256': hashlib.sha256(logmap.text_source.encode()).hexdigest(),
        'map': logmap.text_source,
        'sources': files,
        'imports': [dict(lg.report) for lg in logs],
        'skipped': list(skipped),
    }


def write_contract_bag(out: str | os.PathLike[str], logmap: LogMap,
                       logs: Sequence[ContractLog], skipped: Sequence[str] = ()
                       ) -> dict[str, Any]:
    """Write the logs as one contract bag at ``out`` (a directory; written to a temporary
    directory beside it and renamed, so nothing is left half written). Returns the provenance
    stored in ``metadata.yaml`` (``custom_data.auv_provenance``, JSON) and in the MCAP file.

    Raises
    ------
    RealLogError
        ``out`` exists, or the logs overlap in time (import them one by one).
    """
    from auv_bag import BagWriter, typestore

    dest = pathlib.Path(out)
    if dest.exists():
        raise RealLogError(f'output {dest} exists already')
    spans = sorted((float(lg.t[0]), float(lg.t[-1]), lg.name) for lg in logs)
    for (_a0, a1, an), (b0, _, bn) in itertools.pairwise(spans):
        if b0 <= a1:
            raise RealLogError(f'logs {an} and {bn} overlap in time: import them into separate '
                               'bags')
    prov = provenance(logmap, logs, skipped)
    store = typestore()
    T = store.types
    Header, Time = T['std_msgs/msg/Header'], T['builtin_interfaces/msg/Time']
    State, Setpoint = T['auv_msgs/msg/VehicleState'], T['auv_msgs/msg/ActuatorSetpoint']
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = pathlib.Path(tempfile.mkdtemp(prefix=f'.{dest.name}.', dir=dest.parent))
    work = tmp / dest.name
    try:
        events: list[tuple[int, int, str, Any]] = []

        def header(ns: int, frame: str) -> Any:
            return Header(stamp=Time(sec=int(ns // NS), nanosec=int(ns % NS)), frame_id=frame)

        for lg in logs:
            for ns, row in zip(_ns(lg.t).tolist(), lg.state):
                fields = {k: float(v) for k, v in zip(STATE, row)}
                events.append((ns, 1, STATE_TOPIC, State(header=header(ns, 'ned'), **fields)))
            for ch, topic in {**COMMAND_TOPICS, **MEASURED_SIGNAL_TOPICS}.items():
                if ch not in lg.commands:
                    continue
                ct, cv = lg.commands[ch]
                for ns, v in zip(_ns(ct).tolist(), cv.tolist()):
                    events.append((ns, 0, topic, Setpoint(header=header(ns, ch), value=v)))
        events.sort(key=lambda e: (e[0], e[1]))
        meta = {'auv_provenance': json.dumps(prov)}
        with BagWriter(work, custom_data=meta) as bag:
            bag.add_topic(STATE_TOPIC, 'auv_msgs/msg/VehicleState')
            for topic in sorted({e[2] for e in events}):
                bag.add_topic(topic, 'auv_msgs/msg/ActuatorSetpoint' if topic != STATE_TOPIC
                              else 'auv_msgs/msg/VehicleState')
            for ns, _, topic, msg in events:
                bag.write(topic, msg, log_time_ns=max(ns, 0))
        work.rename(dest)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return prov


def read_provenance(bag: str | os.PathLike[str]) -> dict[str, Any] | None:
    """The provenance an imported bag carries (None for a bag not made by ``auv import``)."""
    meta = pathlib.Path(bag) / 'metadata.yaml'
    if not meta.exists():
        return None
    info = read_yaml(meta).get('rosbag2_bagfile_information', {})
    raw = (info.get('custom_data') or {}).get('auv_provenance')
    return None if raw is None else dict(json.loads(raw))
