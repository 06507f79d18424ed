"""Exception family of the auv_gap package (the sim-to-real gap diagnosis).

Every error on bad input derives from :class:`GapError` (a ``ValueError``), so ``auv gap``
prints one line ``error: ...`` and exits 1 without catching programming errors.
"""
from __future__ import annotations

__all__ = ['GapError']


class GapError(ValueError):
    """The gap diagnosis cannot run: bad model or log, unknown effect, too little data."""
