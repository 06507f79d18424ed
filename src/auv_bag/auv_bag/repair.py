"""Repairing a damaged bag: every whole message before the damage, written to a new bag.

A bag whose recorder was killed has no ``metadata.yaml`` and an MCAP file without summary or
footer, often with its last chunk cut short; a copy cut short or with garbage bytes is
damaged the same way. Every ``auv`` command and rosbags refuse such a bag (the project's
readers read it with ``allow_truncated``). :func:`repair_bag` reads it from the start, as the
readers do (:mod:`auv_bag.damage`), and writes what it holds to a new bag with
:class:`~auv_bag.writer.BagWriter`: the same topics, types and offered QoS profiles, every
whole message with its log time, publish time and bytes unchanged, in file order. The
damaged bag is left as it is; the report says how many messages were recovered per topic and
where the damage was. Nothing is filled in or guessed: what was after the damage is lost.
"""
from __future__ import annotations

import os
import pathlib
from typing import NamedTuple

from auv_contract import parse_yaml

from .damage import Damage
from .errors import BagError
from .locate import ChannelInfo, publish_times
from .metadata import bag_files
from .scan import Scanner
from .typestore import bag_store, normalize_msgtype
from .writer import BagWriter

__all__ = ['RepairReport', 'repair_bag']


class RepairReport(NamedTuple):
    """What :func:`repair_bag` recovered.

    Attributes
    ----------
    source
        the damaged bag.
    out
        the repaired bag.
    counts
        topic -> messages written to ``out``.
    damage
        the damage report (one line: file, byte offset, whole messages before it), or
        None when the bag was whole (then ``out`` is a plain copy).
    """

    source: str
    out: str
    counts: dict[str, int]
    damage: str | None

    @property
    def messages(self) -> int:
        return sum(self.counts.values())

    def text(self) -> str:
        """One paragraph for the command line."""
        topics = ', '.join(f'{t} {n}' for t, n in sorted(self.counts.items())) or 'none'
        where = (f'damage: {self.damage}; what followed it is lost' if self.damage
                 else 'no damage found: the copy holds the whole bag')
        return (f'recovered {self.messages} messages from {self.source} into {self.out} '
                f'({topics}); {where}')


def repair_bag(source: str | os.PathLike[str], out: str | os.PathLike[str], *,
               compression: str = 'zstd') -> RepairReport:
    """Write every whole message of the (possibly damaged) bag ``source`` to the new bag
    ``out`` (a directory, or a ``.mcap`` file name).

    Parameters
    ----------
    source
        bag directory (with or without ``metadata.yaml``) or ``.mcap`` file.
    out
        the repaired bag to create (must not exist, or be an empty directory).
    compression
        chunk compression of ``out`` (``zstd``, ``lz4`` or ``none``).

    Returns
    -------
    What was recovered, per topic, and the damage found.

    Raises
    ------
    BagError
        ``source`` is missing or not an MCAP bag; ``out`` exists; a message type
        has no definition in the file.
    """
    try:
        files = bag_files(source)
    except BagError:
        # metadata.yaml unreadable: the directory's MCAP files, as without one
        files = sorted(pathlib.Path(source).glob('*.mcap'))
        if not pathlib.Path(source).is_dir() or not files:
            raise
    if pathlib.Path(out).resolve() in {f.resolve() for f in files} | {
            pathlib.Path(source).resolve()}:
        raise BagError(f'the repaired bag {out} must not be the damaged one')
    schemas: dict[int, tuple[str, str, str]] = {}
    damage = None
    for file in files:  # first pass: every definition before the damage
        scanner = Scanner(file)
        try:
            for _ in scanner.blocks():
                pass
        except Damage:
            damage = True
        schemas.update(scanner.defs.schemas)
        if damage:
            break
    writer = BagWriter(out, compression=compression, store=bag_store(schemas))
    counts: dict[str, int] = {}
    damage_text = None
    whole = 0
    try:
        for file in files:
            scanner = Scanner(file)
            try:
                for block in scanner.blocks():
                    whole += len(block.channel)
                    published = publish_times(block)
                    for i, (cid, log_ns, off, n) in enumerate(zip(
                            block.channel.tolist(), block.log_time.tolist(),
                            block.offset.tolist(), block.length.tolist())):
                        chan = scanner.defs.channels.get(cid)
                        if chan is None:
                            raise BagError(f'bag file {file}: message on undeclared channel '
                                           f'{cid}')
                        if chan.topic not in counts:
                            _declare(writer, scanner, chan, file)
                            counts[chan.topic] = 0
                        writer.write(chan.topic, block.data[off:off + n], log_ns,
                                     int(published[i]))
                        counts[chan.topic] += 1
            except Damage as dmg:
                damage_text = dmg.message(whole)
            for chan in scanner.defs.channels.values():  # topics declared, no message kept
                if chan.topic not in counts:
                    _declare(writer, scanner, chan, file)
                    counts[chan.topic] = 0
            if damage_text is not None:
                break
    finally:
        writer.close()
    return RepairReport(str(source), str(out), counts, damage_text)


def _declare(writer: BagWriter, scanner: Scanner, chan: ChannelInfo,
             file: pathlib.Path) -> None:
    """Declare ``chan``'s topic in ``writer`` with its type and offered QoS profiles."""
    schema = scanner.defs.schemas.get(chan.schema_id)
    if schema is None:
        raise BagError(f'bag file {file}: topic {chan.topic} has no schema')
    qos = dict(chan.metadata).get('offered_qos_profiles')
    try:
        parse_yaml(qos or '')
    except Exception:  # damaged metadata text: the writer's default profile instead
        qos = None
    writer.add_topic(chan.topic, normalize_msgtype(schema[0]), qos)
