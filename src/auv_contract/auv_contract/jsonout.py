"""The JSON every ``auv`` command prints and every report file holds: strict JSON (RFC 8259).

A figure that has no value, such as the settling time of a step that never settled, or a
ratio whose divisor is zero, is written as ``null``: never as the ``NaN`` or ``Infinity``
that Python's ``json`` writes by default and strict parsers (``jq``, JavaScript's
``JSON.parse``, most languages' standard readers) refuse. Numbers keep their units, which are
the ones named in the keys or the producing function's docstring.
"""
from __future__ import annotations

import json
import math
from typing import Any

__all__ = ['dumps', 'plain']


def plain(value: Any) -> Any:
    """``value`` as plain JSON types: mappings with string keys, lists, finite floats.

    Tuples become lists; numpy arrays and scalars (anything with ``tolist()``) their Python
    values; every non-finite float ``None``. Other values are returned as they are.

    Parameters
    ----------
    value : Any
        A document of dicts, lists, tuples, numbers, strings, booleans and numpy values.

    Returns
    -------
    Any
        A copy ``json.dumps(..., allow_nan=False)`` writes.
    """
    if isinstance(value, dict):
        return {str(key): plain(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(item) for item in value]
    if isinstance(value, float):
        return float(value) if math.isfinite(value) else None
    tolist = getattr(value, 'tolist', None)
    if callable(tolist) and not isinstance(value, (str, bytes)):
        return plain(tolist())
    return value


def dumps(value: Any, **kwargs: Any) -> str:
    """Strict JSON text of ``value`` (:func:`plain`, then ``json.dumps`` with
    ``allow_nan=False``); ``kwargs`` go to ``json.dumps`` (``indent``, ``sort_keys``)."""
    return json.dumps(plain(value), allow_nan=False, **kwargs)
