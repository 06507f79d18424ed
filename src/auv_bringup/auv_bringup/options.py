"""Checks of command-line numbers, one line each (``error: --NAME must be ..., got X``).

argparse turns text into numbers but lets ``nan``, ``inf`` and out-of-range values through;
each command checks its options with :func:`check_number` before it starts anything.
"""
from __future__ import annotations

import math

from auv_bringup.cli import CliError

__all__ = ['check_number']


def check_number(option: str, value: float | int | None, *, minimum: float | None = None,
                 above: float | None = None, maximum: float | None = None,
                 unit: str = '') -> None:
    """Raise :class:`CliError` unless ``value`` is finite and within the bounds.

    Parameters
    ----------
    option
        the option as the user typed it (``--duration``).
    value
        its value; None (option not given) passes.
    minimum
        smallest value allowed.
    above
        value it must exceed.
    maximum
        largest value allowed.
    unit
        unit named in the message (``s``, ``m``).

    Raises
    ------
    CliError
        not finite, or out of the bounds.
    """
    if value is None:
        return
    unit_text = f' {unit}' if unit else ''
    if not math.isfinite(value):
        raise CliError(f'{option} must be a finite number{f" ({unit})" if unit else ""}, '
                       f'got {value}')
    if minimum is not None and value < minimum:
        raise CliError(f'{option} must be >= {minimum:g}{unit_text}, got {value:g}')
    if above is not None and value <= above:
        raise CliError(f'{option} must be > {above:g}{unit_text}, got {value:g}')
    if maximum is not None and value > maximum:
        raise CliError(f'{option} must be <= {maximum:g}{unit_text}, got {value:g}')
