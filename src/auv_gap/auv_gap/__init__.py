"""Sim-to-real gap diagnosis: where a vehicle model departs from logs of the real vehicle,
and which unmodelled effect of the catalogue explains it (see :func:`diagnose`).

The names below load their module on first use (the diagnosis' numba kernels take seconds
to import; ``auv gap --help`` and the modules that need only the catalogue do not wait).
"""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from auv_gap.catalogue import CATALOGUE, Effect, Parameter, Perturbation, register
    from auv_gap.diagnose import diagnose
    from auv_gap.logs import GapLog, from_arrays, load_bag
    from auv_gap.report import write_report
    from auv_gap.verdict import Diagnosis

_HOME = {'CATALOGUE': 'catalogue', 'Effect': 'catalogue', 'Parameter': 'catalogue',
         'Perturbation': 'catalogue', 'register': 'catalogue', 'Diagnosis': 'verdict',
         'diagnose': 'diagnose', 'GapLog': 'logs', 'from_arrays': 'logs', 'load_bag': 'logs',
         'write_report': 'report'}

__all__ = ['CATALOGUE', 'Diagnosis', 'Effect', 'GapLog', 'Parameter', 'Perturbation',
           'diagnose', 'from_arrays', 'load_bag', 'register', 'write_report']


def __getattr__(name: str) -> Any:
    """The public name ``name``, imported from its module on first use."""
    if name not in _HOME:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    return getattr(importlib.import_module(f'auv_gap.{_HOME[name]}'), name)
