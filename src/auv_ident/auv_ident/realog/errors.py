"""Exception family of :mod:`auv_ident.realog` (importing real vehicles' logs).

Every error on bad input derives from :class:`RealLogError`, itself an
:class:`auv_ident.errors.IdentError`, so ``auv import``, ``auv ident --map`` and ``auv gap
--map`` print one line ``error: ...`` and exit 1. Messages name the map key and line, or the
log file and row, and hide library internals.
"""
from __future__ import annotations

from auv_ident.errors import IdentError


class RealLogError(IdentError, ValueError):
    """Base class of every error raised while importing a real log."""


class MapError(RealLogError):
    """The mapping file is invalid: unknown key, unit or frame, missing source, bad value."""


class LogReadError(RealLogError):
    """A log cannot be read as the map says: missing topic, column or field path, ragged
    rows, unknown log kind or message type, unusable time stamps."""


class NoSegmentError(RealLogError):
    """A log holds no usable segment (empty after the segment rules: surfaced, propeller
    off, too short); a batch import leaves such a log out and says so, unless strict."""
