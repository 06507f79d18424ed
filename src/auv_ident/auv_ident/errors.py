"""Exception family of the auv_ident package.

Every error raised on bad input (a damaged bag, a missing topic, data that cannot be
identified) derives from :class:`IdentError`, so a command line front end can print one line
``error: ...`` and exit 1 without catching programming errors. Add new classes below, each
subclassing :class:`IdentError` and the built-in exception it refines.
"""
from __future__ import annotations


class IdentError(Exception):
    """Base class of every error the auv_ident package raises on bad input."""


class BagError(IdentError, ValueError):
    """A bag cannot be read or written: missing, damaged, wrong topic, bad timestamps."""


class IdentificationError(IdentError, ValueError):
    """Data or options with which the coefficients cannot be identified."""


class NotIdentifiableError(IdentificationError):
    """The data do not excite a coefficient enough, or cannot tell two coefficients apart."""


class GapError(IdentError, ValueError):
    """The gap diagnosis cannot run: bad model or log, unknown effect, too little data."""
