"""The rosbag2 side of a bag: ``metadata.yaml``, the QoS profiles text, and the bag's files.

A bag is what ``ros2 bag record -s mcap`` writes: a directory holding ``metadata.yaml``
(version 9) and one ``.mcap`` file per split. A bare ``.mcap`` file is a bag too.
"""
from __future__ import annotations

import os
import pathlib
from io import StringIO
from typing import Any

from auv_contract import parse_yaml

from .errors import BagError

__all__ = ['DEFAULT_QOS_DEPTH', 'bag_contents', 'bag_files', 'parse_yaml', 'qos_profiles_yaml',
           'topics_from_metadata',
           'yaml_dump']

#: Depth of the keep-last QoS history the project's recorder and player use (messages).
DEFAULT_QOS_DEPTH = 1000

_INFINITE = {'sec': 9223372036, 'nsec': 854775807}  # rmw's "infinite" duration


def qos_profiles_yaml(
    reliability: str = 'reliable', durability: str = 'volatile', depth: int = DEFAULT_QOS_DEPTH
) -> str:
    """The ``offered_qos_profiles`` text rosbag2 (metadata version 9) stores for one publisher.

    Parameters
    ----------
    reliability
        ``reliable`` or ``best_effort``.
    durability
        ``volatile`` or ``transient_local``.
    depth
        keep-last history depth (messages).
    """
    return yaml_dump([{
        'history': 'keep_last',
        'depth': depth,
        'reliability': reliability,
        'durability': durability,
        'deadline': dict(_INFINITE),
        'lifespan': dict(_INFINITE),
        'liveliness': 'automatic',
        'liveliness_lease_duration': dict(_INFINITE),
        'avoid_ros_namespace_conventions': False,
    }])


def yaml_dump(data: Any) -> str:
    """``data`` as block-style YAML (as rosbag2 writes ``metadata.yaml``)."""
    from ruamel.yaml import YAML

    yaml = YAML(typ='safe')
    yaml.default_flow_style = False
    yaml.width = 1 << 30   # no folding: ruamel can fold a long quoted string inside an escape
    out = StringIO()
    yaml.dump(data, out)
    return out.getvalue()


def bag_files(path: str | os.PathLike[str]) -> list[pathlib.Path]:
    """The ``.mcap`` files of a bag, in recording order.

    ``path`` is a bag directory (files from ``metadata.yaml``; when it is missing, as after a
    recorder crash, the directory's ``.mcap`` files in name order) or a bare ``.mcap`` file.

    Raises
    ------
    BagError
        no such bag, unreadable ``metadata.yaml``, or no MCAP file.
    """
    return bag_contents(path)[0]


def bag_contents(path: str | os.PathLike[str]) -> tuple[list[pathlib.Path], dict[str, int]]:
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
            info = parse_yaml(meta.read_text())['rosbag2_bagfile_information']
            storage = info.get('storage_identifier', 'mcap')
            names = list(info['relative_file_paths'])
        except Exception as exc:
            raise BagError(f'bag metadata {meta} is unreadable: {_one_line(exc)}') from None
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


def topics_from_metadata(meta: pathlib.Path) -> dict[str, str]:
    """Topics and their message types as ``metadata.yaml`` lists them (types as written).

    Raises
    ------
    BagError
        the file is unreadable or lacks the topic list.
    """
    try:
        info = parse_yaml(meta.read_text())['rosbag2_bagfile_information']
        return {t['topic_metadata']['name']: str(t['topic_metadata']['type'])
                for t in info['topics_with_message_count']}
    except Exception as exc:  # YAML, I/O, encoding and layout errors alike: one line
        raise BagError(f'bag metadata {meta} is unreadable: {_one_line(exc)}') from None


def _one_line(exc: BaseException) -> str:
    """An exception's text on one line (YAML parser errors span several)."""
    text = ' '.join(str(exc).split())
    return text if len(text) <= 200 else text[:197] + '...'
