"""Deprecated: bag I/O moved to the :mod:`auv_bag` package; import from there.

This module only re-exports :mod:`auv_bag` names under their old spellings, for one release.
"""
from __future__ import annotations

import warnings

from auv_bag import *  # noqa: F403  (the whole public API, as before)
from auv_bag import __all__ as _public
from auv_bag.columnar import layout_of as _layout
from auv_bag.typestore import types_from_schema as _types_from_schema

__all__ = [*_public, '_layout', '_types_from_schema']

warnings.warn('auv_ident.bag is deprecated: import from auv_bag', DeprecationWarning,
              stacklevel=2)
