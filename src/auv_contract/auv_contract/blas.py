"""One BLAS thread for the toolkit's small and narrow linear algebra.

The toolkit's matrices are small (a pilot's 5 x 5 and 6 x 6 designs, its stop model's
one-sample maps) or tall and narrow (a log's rows by a few coefficients): their products are
too small or too memory-bound to share between threads, and OpenBLAS's worker threads only
add their start and synchronisation to each. On a busy 2-core machine a 5 x 5 matrix
exponential took 8 ms with the threads and 0.02 ms without, and a dot product of 16 000
samples 8 ms and 0.06 ms; results are those of any thread count to rounding.

* :func:`one_blas_thread` runs one function with the BLAS libraries limited to one thread
  (:func:`threadpoolctl.threadpool_limits`), the thread count restored after.
* :func:`use_one_blas_thread` limits a node's process for its whole life, or names one thread
  in the environment of processes about to start (``OPENBLAS_NUM_THREADS``, read when their
  BLAS library loads). A count the user names in that variable is left as it is.

numba's threads (the batch integrator, the diagnosis' free runs) are not affected.
"""
from __future__ import annotations

import functools
import os
from collections.abc import Callable, MutableMapping
from typing import ParamSpec, TypeVar

from threadpoolctl import threadpool_limits

__all__ = ['BLAS_THREADS_VARIABLE', 'one_blas_thread', 'use_one_blas_thread']

P = ParamSpec('P')
R = TypeVar('R')

BLAS_THREADS_VARIABLE = 'OPENBLAS_NUM_THREADS'
"""The environment variable OpenBLAS (numpy's and scipy's BLAS) takes its thread count from."""


def one_blas_thread(fn: Callable[P, R]) -> Callable[P, R]:
    """``fn`` run with the BLAS libraries limited to one thread (module docstring)."""

    @functools.wraps(fn)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        with threadpool_limits(limits=1, user_api='blas'):
            return fn(*args, **kwargs)

    return wrapper


def use_one_blas_thread(env: MutableMapping[str, str] | None = None) -> str:
    """One BLAS thread, unless the user names a count in :data:`BLAS_THREADS_VARIABLE`.

    With ``env`` None: this process's BLAS libraries, from now on (a node calls it before it
    builds its design); the variable of ``os.environ`` is set too, for the processes this one
    starts. With ``env``: that variable in ``env`` only (the environment of processes to
    start, whose BLAS then starts with one thread).

    Returns
    -------
    str
        The thread count the variable names afterwards (the user's, or ``'1'``).
    """
    target = os.environ if env is None else env
    user = target.get(BLAS_THREADS_VARIABLE)
    if user:
        return user
    target[BLAS_THREADS_VARIABLE] = '1'
    if env is None:
        threadpool_limits(limits=1, user_api='blas')
    return '1'
