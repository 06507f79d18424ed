"""Checks of the pilot's numbers: design settings (DesignError) and run-time inputs
(InvalidInputError), each error naming the value that is wrong."""
from __future__ import annotations

import math

from auv_depth_lqr.errors import DesignError, InvalidInputError

__all__ = ['finite', 'run_input']


def finite(name: str, value: object, positive: bool = False) -> float:
    """``value`` as a finite float (and > 0 if ``positive``), else :class:`DesignError`."""
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise DesignError(f'{name} must be a number, got {value!r}') from None
    if not math.isfinite(number) or (positive and number <= 0.0):
        need = 'finite and > 0' if positive else 'finite'
        raise DesignError(f'{name} must be {need}, got {value!r}')
    return number



def run_input(name: str, value: object) -> float:
    """A finite float run-time input, else :class:`InvalidInputError` naming it."""
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InvalidInputError(f'{name} must be a number, got {value!r}') from None
    if not math.isfinite(number):
        raise InvalidInputError(f'{name} must be finite, got {value!r}')
    return number


