"""One BLAS thread for the identification's linear algebra.

The identification's arrays are tall and narrow (a log's rows by a few coefficients): their
products and dot products are memory-bound, and OpenBLAS's worker threads only add their
start and synchronisation to each (a dot product of 16 000 samples took 8 ms with the
threads, 0.06 ms without, on a busy 2-core machine). The decorated functions run with the
BLAS libraries limited to one thread (:func:`threadpoolctl.threadpool_limits`); results are
those of any thread count to rounding. The free runs' own threads (numba) are not affected.
"""
from __future__ import annotations

import functools
from collections.abc import Callable
from typing import ParamSpec, TypeVar

from threadpoolctl import threadpool_limits

P = ParamSpec('P')
R = TypeVar('R')


def one_blas_thread(fn: Callable[P, R]) -> Callable[P, R]:
    """``fn`` run with the BLAS libraries limited to one thread (module docstring)."""

    @functools.wraps(fn)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        with threadpool_limits(limits=1, user_api='blas'):
            return fn(*args, **kwargs)

    return wrapper
