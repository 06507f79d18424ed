"""Exception family of the auv_logs package (logs in: real vehicles' logs, simulated logs).

Every error on bad input derives from :class:`LogError` (a ``ValueError``), so ``auv
import``, ``auv ident --map`` and ``auv gap --map`` print one line ``error: ...`` and exit 1.
Messages name the map key and line, or the log file and row, and hide library internals.
Bag errors come from the auv_bag package (:class:`auv_bag.errors.BagError`, re-exported
here): front ends catch it beside :class:`LogError`.
"""
from __future__ import annotations

from auv_bag.errors import BagError

__all__ = ['BagError', 'LogError', 'LogReadError', 'MapError', 'NoSegmentError', 'RealLogError']


class LogError(ValueError):
    """Base class of every error the auv_logs package raises on bad input."""


class RealLogError(LogError):
    """Base class of every error raised while importing a real log."""


class MapError(RealLogError):
    """The mapping file is invalid: unknown key, unit or frame, missing source, bad value."""


class LogReadError(RealLogError):
    """A log cannot be read as the map says: missing topic, column or field path, ragged
    rows, unknown log kind or message type, unusable time stamps."""


class NoSegmentError(RealLogError):
    """A log holds no usable segment (empty after the segment rules: surfaced, propeller
    off, too short); a batch import leaves such a log out and says so, unless strict."""
