"""Message types: the ROS 2 typestore with auv_msgs registered, and message definitions.

The auv_msgs types are registered from their ``.msg`` text (no import of the generated Python
module, so no ROS install is needed). A bag's own definitions (the ``ros2msg`` schemas it
embeds) give the typestore that decodes it, which covers types this project does not know.
"""
from __future__ import annotations

import functools
import os
import pathlib
from typing import Any

from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from .errors import BagError

__all__ = ['bag_store', 'message_definition', 'msg_dir', 'normalize_msgtype',
           'types_from_schema', 'typestore']

SECTION = '=' * 80 + '\n'
"""Separator between a type's definition and each dependency in a ``ros2msg`` schema."""


def msg_dir() -> pathlib.Path:
    """Directory holding the auv_msgs ``.msg`` files.

    Looks in the source tree first (``src/auv_msgs/msg`` next to this package), then in the
    colcon install space (``install/auv_msgs/share/auv_msgs/msg``) and in every prefix of
    ``AMENT_PREFIX_PATH``.

    Raises
    ------
    BagError
        no directory with ``.msg`` files was found; the message names where it looked.
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


def base_store() -> Typestore:
    """A fresh typestore of the newest ROS 2 distribution rosbags knows (Kilted or later)."""
    store = getattr(Stores, 'ROS2_KILTED', None) or Stores.LATEST
    return get_typestore(store)


@functools.lru_cache(maxsize=1)
def typestore() -> Typestore:
    """The ROS 2 Kilted typestore with the auv_msgs types registered from their ``.msg`` text.

    Shared and cached: do not register further types into it; build your own with
    ``get_typestore`` if you need to.
    """
    store = base_store()
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

    Raises
    ------
    BagError
        the name has neither form.
    """
    parts = msgtype.strip('/').split('/')
    if len(parts) == 2 and all(parts):
        return f'{parts[0]}/msg/{parts[1]}'
    if len(parts) == 3 and all(parts):
        return '/'.join(parts)
    raise BagError(f'bad message type name {msgtype!r}: expected pkg/msg/Type')


def message_definition(store: Typestore, msgtype: str) -> str:
    """Full ``ros2msg`` schema text as rosbag2 stores it: the type's own definition, then each
    dependency after a line of 80 ``=`` and a ``MSG: pkg/Type`` line."""
    text, _ = store.generate_msgdef(msgtype, ros_version=2)
    own = _msg_text(msgtype)
    if own is None:
        return text
    sep = text.find(SECTION)
    return own.rstrip('\n') + '\n' + (text[sep:] if sep >= 0 else '')


def types_from_schema(name: str, text: str) -> dict[str, Any]:
    """Types defined by one ``ros2msg`` schema (the message and its dependencies)."""
    types: dict[str, Any] = {}
    sections = text.split(SECTION)
    types.update(get_types_from_msg(sections[0], name))
    for section in sections[1:]:
        head, _, body = section.partition('\n')
        if head.startswith('MSG: '):
            types.update(get_types_from_msg(body, normalize_msgtype(head[5:].strip())))
    return types


def bag_store(schemas: dict[int, tuple[str, str, str]]) -> Typestore:
    """A typestore able to decode every schema of a bag seen so far.

    Parameters
    ----------
    schemas
        schema id -> (type name, schema encoding, definition text), as a scan of the
        bag collects them.

    The shared :func:`typestore` serves when it knows every type with the same definition;
    otherwise a fresh one is built from the bag's own definitions. Stores are kept per set
    of definitions (parsing them takes milliseconds); do not register types into them.
    """
    return _bag_store_of(tuple(schemas.values()))


@functools.lru_cache(maxsize=64)
def _bag_store_of(schemas: tuple[tuple[str, str, str], ...]) -> Typestore:
    """:func:`bag_store` of the (name, encoding, text) of a bag's schemas."""
    base = typestore()
    extra: dict[str, Any] = {}
    conflict = False
    for name, enc, text in schemas:
        if enc != 'ros2msg' or not text:
            continue
        try:
            types = types_from_schema(normalize_msgtype(name), text)
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
    store = base_store()
    if conflict:
        store = get_typestore(Stores.EMPTY)
        for name, enc, text in schemas:
            if enc == 'ros2msg' and text:
                try:
                    extra.update(types_from_schema(normalize_msgtype(name), text))
                except Exception:
                    continue
    else:
        store.register({k: v for k, v in base.fielddefs.items()
                        if k.startswith('auv_msgs/')})
    store.register(extra)
    return store
