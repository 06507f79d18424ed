"""Deprecated: bag I/O moved to the :mod:`auv_bag` package; import from there.

This module only re-exports :mod:`auv_bag` names under their old spellings, for one release.
"""
from __future__ import annotations

import warnings

from auv_bag import (
    DEFAULT_QOS_DEPTH,
    BagArrays,
    BagError,
    BagMessage,
    BagWriter,
    ProgressCallback,
    bag_files,
    bag_topics,
    default_workers,
    msg_dir,
    normalize_msgtype,
    qos_profiles_yaml,
    read_arrays,
    read_messages,
    typestore,
)
from auv_bag.columnar import layout_of as _layout
from auv_bag.typestore import types_from_schema as _types_from_schema

__all__ = [
    'DEFAULT_QOS_DEPTH',
    'BagArrays',
    'BagError',
    'BagMessage',
    'BagWriter',
    'ProgressCallback',
    '_layout',
    '_types_from_schema',
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

warnings.warn('auv_ident.bag is deprecated: import from auv_bag', DeprecationWarning,
              stacklevel=2)
