"""Exceptions of the depth-control package.

Every error raised on purpose by :mod:`auv_depth_lqr` derives from :class:`AuvLqrError`, and
the ones about bad input also derive from :class:`ValueError`, so callers may catch either the
package family or the built-in type. Messages name the offending value; library internals
(SciPy, python-control) are hidden with ``raise ... from None``.
"""
from __future__ import annotations

__all__ = ['AuvLqrError', 'ControllerError', 'DesignError', 'InvalidInputError',
           'NotControllableError']


class AuvLqrError(Exception):
    """Root of the exceptions of :mod:`auv_depth_lqr`."""


class DesignError(AuvLqrError, ValueError):
    """A controller cannot be designed from the given model, weights or settings.

    Raised for matrices of the wrong shape, non-finite entries, weights that are not
    symmetric positive (semi-)definite, a non-positive sample time, an inconsistent gain
    schedule, and a Riccati equation without a stabilising solution.
    """


class NotControllableError(DesignError):
    """The pair (A, B) is not controllable; the message names the rank and the modes."""


class InvalidInputError(AuvLqrError, ValueError):
    """A run-time input of the controller (state, depth reference, speed) is not usable.

    For instance a NaN depth reference or a non-finite measured depth. The depth-pilot node
    catches it, keeps the last valid command and reports the message.
    """


class ControllerError(AuvLqrError):
    """The controller cannot produce a valid command for this sample (e.g. a non-finite
    result); the pilot then falls back to its safe BAR."""
