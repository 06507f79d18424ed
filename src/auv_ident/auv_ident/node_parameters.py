"""The identification node's parameters as data (ROS-free): default, description with its
unit, range, choices and whether each applies at start only, and the check of a set of
values.

:mod:`auv_ident.node` turns each :class:`~auv_contract.parameters.ParameterSpec` into a
``ParameterDescriptor`` (:func:`auv_sim.parameter_descriptor.descriptor`), calls
:func:`problem` at start and on every change (its ``on_set`` callback) and applies an
accepted change in its ``post_set`` callback. The ranges are the ones the node checked
before they were written here: ``window`` > 0 s, ``estimate_period`` >= 0 s, ``qos_depth``
>= 1 message.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

from auv_contract import config_path
from auv_contract.parameters import NON_NEGATIVE, POSITIVE, ParameterSpec, Range
from auv_ident.identify import EQUATIONS, ERROR_METHODS
from auv_ident.motion import SOURCES, WINDOW_S

__all__ = ['PARAMETERS', 'START_ONLY', 'problem']

_SPECS = (
    ParameterSpec('vehicle_file', str(config_path('a18m.yaml')),
                  'vehicle parameter file (YAML) the identified values replace; default the '
                  'shipped a18m.yaml', constraint='a valid vehicle file'),
    ParameterSpec('out', 'out/ident', 'output directory of the identification files'),
    ParameterSpec('source', 'auto', 'fit from the force topic, from the motion, or from what '
                  'the topics hold', choices=SOURCES),
    ParameterSpec('fit_c0', False, 'fit CZ0 and CM0 too (false: fixed at the vehicle file '
                  'values)'),
    ParameterSpec('fit_planes', False, "fit the dive plane's CZbar and CMbar too (forces "
                  'from motion)'),
    ParameterSpec('bounds', True, 'physical bounds on the coefficients'),
    ParameterSpec('errors', 'hac', 'covariance estimator of the intervals',
                  choices=ERROR_METHODS),
    ParameterSpec('equations', ('',), "equations to identify; [''] = all",
                  constraint=f'each one of {", ".join(EQUATIONS)} or empty'),
    ParameterSpec('window', WINDOW_S, 'length of the motion fit windows [s]', 's', POSITIVE,
                  constraint='finite'),
    ParameterSpec('estimate_period', 0.0, 'period of the running estimate on ~/estimate [s]; '
                  '0 = never', 's', NON_NEGATIVE, constraint='finite'),
    ParameterSpec('qos_depth', 10000, 'queue depth of the subscriptions [messages]',
                  'messages', Range(1), start_only=True),
)
#: Every parameter of the node by name, in declaration order.
PARAMETERS: Mapping[str, ParameterSpec] = MappingProxyType({s.name: s for s in _SPECS})
#: Parameters applied at start only: a change while running is refused.
START_ONLY = tuple(s.name for s in _SPECS if s.start_only)


def _number_problem(spec: ParameterSpec, value: Any) -> str | None:
    """What is wrong with a numeric value of ``spec``, or None.

    Parameters
    ----------
    spec, value : ParameterSpec, Any
        A parameter with a range (float or integer) and the value set for it; an integer
        stands for a float too.

    Returns
    -------
    str or None
        ``parameter NAME must be CONDITION UNIT, got VALUE`` for a value of the wrong type,
        not finite or outside the range; None when it is fine.
    """
    assert spec.range is not None
    unit = f' {spec.unit}' if spec.unit else ''
    wrong = (f'parameter {spec.name} must be {spec.range.condition()}{unit}, '
             f'got {value!r}')
    if isinstance(value, bool):
        return wrong
    if isinstance(spec.default, int):
        return None if isinstance(value, int) and value in spec.range else wrong
    if not isinstance(value, (int, float)) or not math.isfinite(value):
        return wrong
    return None if value in spec.range else wrong


def problem(values: Mapping[str, Any]) -> str | None:
    """What is wrong with a set of the node's parameter values, or None.

    Parameters
    ----------
    values : mapping of str to Any
        Values of some or all names of :data:`PARAMETERS` (the others are not checked).

    Returns
    -------
    str or None
        A one-line message naming the first wrong parameter (a text not among its choices,
        an unknown equation, a number outside its range); None when all are fine.
    """
    for name, value in values.items():
        spec = PARAMETERS.get(name)
        if spec is None:
            continue
        if spec.choices and value not in spec.choices:
            return f'parameter {name} must be one of {spec.choices}, got {value!r}'
        if name == 'equations':
            for eq in value or []:
                if eq and eq not in EQUATIONS:
                    return f'parameter equations: unknown equation {eq!r}'
        if spec.range is not None:
            wrong = _number_problem(spec, value)
            if wrong:
                return wrong
    return None
