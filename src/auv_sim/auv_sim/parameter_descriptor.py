"""The ROS ``ParameterDescriptor`` of a node parameter described by a
:class:`auv_contract.parameters.ParameterSpec`: one function for every node of the project
(simulator, identifier, depth pilot). Imports ROS messages, not rclpy.
"""
from __future__ import annotations

import math

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType

from auv_contract.parameters import INT64_MAX, ParameterSpec

__all__ = ['descriptor']


def descriptor(spec: ParameterSpec, ranged: bool = True) -> ParameterDescriptor:
    """The ROS descriptor of one node parameter.

    Parameters
    ----------
    spec : ParameterSpec
        The parameter (e.g. :data:`auv_depth_lqr.parameters.PARAMETERS`).
    ranged : bool
        With its range (False: without, to declare it before its value is checked).

    Returns
    -------
    ParameterDescriptor
        Its description; ``additional_constraints`` with its range in words, further limits
        and "applied at start only"; its range as the closed interval over the allowed one
        (an open bound such as ``rate > 0`` is published as its edge, which ROS accepts and
        the node's own check refuses; ``inf`` where there is no upper bound, the largest
        int64 for an integer). A float parameter takes an integer too (``dynamic_typing``;
        ROS checks its range on float values only, the node's check on both). A string
        array has no range. A start-only parameter is not ``read_only``: the node refuses a
        change itself, saying why.
    """
    words = [f'in {spec.range.text()}'] if spec.range is not None else []
    if spec.choices:
        words.append(f'one of {", ".join(spec.choices)}')
    if spec.constraint:
        words.append(spec.constraint)
    if spec.start_only:
        words.append('applied at start only')
    out = ParameterDescriptor(description=spec.description,
                              additional_constraints='; '.join(words))
    if isinstance(spec.default, float):
        out.dynamic_typing = True  # 5 as well as 5.0
        if ranged and spec.range is not None:
            out.floating_point_range = [FloatingPointRange(
                from_value=float(spec.range.lower), to_value=float(spec.range.upper),
                step=0.0)]
    elif isinstance(spec.default, bool):
        out.type = ParameterType.PARAMETER_BOOL
    elif isinstance(spec.default, str):
        out.type = ParameterType.PARAMETER_STRING
    elif isinstance(spec.default, tuple):
        out.type = ParameterType.PARAMETER_STRING_ARRAY
    else:
        out.type = ParameterType.PARAMETER_INTEGER
        if ranged and spec.range is not None:
            upper = INT64_MAX if math.isinf(spec.range.upper) else int(spec.range.upper)
            out.integer_range = [IntegerRange(from_value=int(spec.range.lower),
                                              to_value=upper, step=1)]
    return out
