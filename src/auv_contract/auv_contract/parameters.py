"""A node parameter as data: default, description with its unit, range, choices and whether
it applies at start only (ROS-free).

Each node keeps its parameters as a tuple of :class:`ParameterSpec` in a pure module
(:mod:`auv_depth_lqr.parameters`, :mod:`auv_sim.sim_settings`,
:mod:`auv_ident.node_parameters`) and checks values against them there; the node turns each
into a ``ParameterDescriptor`` (:func:`auv_sim.parameter_descriptor.descriptor`), validates a
change in its ``on_set`` callback and applies it in its ``post_set`` callback.
"""
from __future__ import annotations

import dataclasses
import math

__all__ = ['INT64_MAX', 'NON_NEGATIVE', 'POSITIVE', 'SHARE', 'ParameterSpec', 'Range']

INT64_MAX = 2**63 - 1  # largest value of an integer ROS parameter (its range's 'inf')


@dataclasses.dataclass(frozen=True)
class Range:
    """An interval of allowed values, in the parameter's unit.

    Parameters
    ----------
    lower, upper : float
        Bounds; ``math.inf`` for none above.
    lower_open, upper_open : bool
        True when the bound itself is excluded (``(0, 1]``: lower open, upper closed).
    """

    lower: float
    upper: float = math.inf
    lower_open: bool = False
    upper_open: bool = False

    def __contains__(self, value: float) -> bool:
        above = value > self.lower if self.lower_open else value >= self.lower
        below = value < self.upper if self.upper_open else value <= self.upper
        return above and below

    def text(self) -> str:
        """The interval in mathematical notation, e.g. ``(0, 1]`` or ``[0, inf)``.

        Returns
        -------
        str
            Bounds printed with ``%g``; an infinite bound always open.
        """
        left = '(' if self.lower_open else '['
        right = ')' if self.upper_open or math.isinf(self.upper) else ']'
        return f'{left}{self.lower:g}, {self.upper:g}{right}'


    def condition(self) -> str:
        """The interval as a condition on the value: ``> 0``, ``>= 0`` for a half line,
        ``within (-1.5708, 1.5708)`` for a bounded one.

        Returns
        -------
        str
            Bounds printed with ``%g``.
        """
        if math.isinf(self.upper):
            return f'{">" if self.lower_open else ">="} {self.lower:g}'
        return f'within {self.text()}'


POSITIVE = Range(0.0, lower_open=True)
NON_NEGATIVE = Range(0.0)
SHARE = Range(0.0, 1.0, lower_open=True)


@dataclasses.dataclass(frozen=True)
class ParameterSpec:
    """One parameter of a node.

    Parameters
    ----------
    name : str
        The ROS parameter name.
    default : float | int | str | bool | tuple of str
        Its value when not given; its type is the parameter's (a float parameter also takes an
        integer; a tuple is a string array).
    description : str
        One line with its unit in brackets and its frame where it has one.
    unit : str
        The unit written in ``description`` (``'Hz'``, ``'rad'``, ...); ``''`` when the
        parameter is unitless (a name, a flag, a count, a share).
    range : Range | None
        Allowed numeric values; None when there is no static range.
    nan : bool
        A float parameter whose NaN means "derived" (see its description).
    choices : tuple of str
        Allowed values of a text parameter; empty when any text goes.
    start_only : bool
        Applied at start only; a change while running is refused.
    setting : str
        The pure-core setting it feeds when named otherwise (``'pilot setting rate_hz'``).
    constraint : str
        Further limits in plain words (ROS ``additional_constraints``), '' if none.
    """

    name: str
    default: float | int | str | bool | tuple[str, ...]
    description: str
    unit: str = ''
    range: Range | None = None
    nan: bool = False
    choices: tuple[str, ...] = ()
    start_only: bool = False
    setting: str = ''
    constraint: str = ''
