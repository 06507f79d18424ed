"""Exception family of the auv_ident package.

Every error raised on bad input (data that cannot be identified, a bad base model) derives
from :class:`IdentError`, so a command line front end can print one line ``error: ...`` and
exit 1 without catching programming errors. Errors of the logs it reads come from
:mod:`auv_logs.errors` (:class:`auv_logs.errors.LogError`) and :mod:`auv_bag.errors`
(:class:`auv_bag.errors.BagError`, re-exported here): front ends catch them beside
:class:`IdentError`. Add new classes below, each subclassing :class:`IdentError` and the
built-in exception it refines.
"""
from __future__ import annotations

from auv_bag.errors import BagError

__all__ = ['BagError', 'IdentError', 'IdentificationError', 'NotIdentifiableError']


class IdentError(Exception):
    """Base class of every error the auv_ident package raises on bad input."""


class IdentificationError(IdentError, ValueError):
    """Data or options with which the coefficients cannot be identified."""


class NotIdentifiableError(IdentificationError):
    """The data do not excite a coefficient enough, or cannot tell two coefficients apart."""

