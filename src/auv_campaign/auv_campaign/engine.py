"""The Dask client of a campaign: an embedded local cluster, or an existing scheduler.

By default a :class:`distributed.LocalCluster` of ``workers`` processes (one thread each: the
single-log tools are CPU-bound Python and numba code, and a process per worker isolates a
crash) is started inside the command and shut down with it. ``scheduler='tcp://host:8786'``
connects to a running cluster instead (started with ``dask scheduler`` / ``dask worker`` on
machines that see the same files); a scheduler that does not answer within ``timeout`` seconds
is a one-line :class:`CampaignError`.

A worker that dies while running a task (killed, out of memory) makes the scheduler run the
task again on another worker, up to ``allowed_failures`` times
(``distributed.scheduler.allowed-failures``; set here for the embedded cluster, and in the
scheduler's own configuration for an external one).

``fork=True`` starts the embedded cluster's worker processes by forking this process (POSIX
only; ``spawn`` otherwise): what this process has already imported, compiled (numba kernels)
and built (a pilot designed here) the workers inherit instead of paying for it again. Used by
the Monte Carlo, whose fixed cost per worker is exactly that; the campaign of logs keeps
``spawn`` (a fresh interpreter per worker). The embedded workers' statistical profiler (it
samples the running task for a dashboard the embedded cluster does not start) is off.

A worker is one CPU: a mission runs with one numba thread and one BLAS thread
(:func:`one_cpu`). The diagnosis' free runs spread their windows over numba's threads; with
two workers on two cores each worker's second thread only competes with the other worker
(on a busy 2-core machine one season log took 72 s with two threads, 37 s with one, the
same report).
"""
from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
from collections.abc import Iterator
from typing import Any

from auv_campaign.errors import CampaignError

#: Seconds to wait for an external scheduler to answer.
CONNECT_TIMEOUT_S = 5.0
#: Times a task is started again after the worker running it died.
ALLOWED_FAILURES = 3


@contextlib.contextmanager
def one_cpu() -> Iterator[None]:
    """Run the body with one numba thread (the parallel free-run kernels) and one BLAS thread
    (:func:`threadpoolctl.threadpool_limits`); numba's thread count is restored after.
    A parallel kernel's jobs (one free run each) compute the same numbers on any thread
    count, so results do not change."""
    import numba
    from threadpoolctl import threadpool_limits

    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        with threadpool_limits(limits=1, user_api='blas'):
            yield
    finally:
        numba.set_num_threads(before)


def default_workers() -> int:
    """Workers of the embedded cluster: the CPUs this process may use."""
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity')
               else (os.cpu_count() or 1))


@contextlib.contextmanager
def client(workers: int | None = None, scheduler: str | None = None,
           timeout: float = CONNECT_TIMEOUT_S, allowed_failures: int = ALLOWED_FAILURES,
           memory_limit: str | float | None = 'auto', fork: bool = False) -> Iterator[Any]:
    """A :class:`distributed.Client` for the campaign, closed (and its cluster shut down) on
    exit.

    Parameters
    ----------
    workers
        processes of the embedded cluster (default: the usable CPUs).
    scheduler
        address of an existing scheduler; None starts the embedded cluster.
    timeout
        seconds to wait for ``scheduler`` to answer.
    allowed_failures
        task restarts after worker deaths (embedded cluster).
    memory_limit
        per-worker memory limit of the embedded cluster (Dask's syntax).
    fork
        start the embedded cluster's workers by forking this process (see the module
        docstring); ignored with ``scheduler`` and where fork is not available.

    Raises
    ------
    CampaignError
        bad worker count, or no scheduler answering at ``scheduler``.
    """
    import dask
    import distributed

    dist: Any = distributed

    if workers is not None and workers < 1:
        raise CampaignError(f'--workers must be >= 1, got {workers}')
    if not (timeout > 0):
        raise CampaignError(f'scheduler timeout must be > 0 s, got {timeout}')
    quiet = {'distributed.scheduler.allowed-failures': int(allowed_failures),
             'distributed.admin.tick.limit': '1h'}   # long numba/numpy tasks hold the GIL
    if scheduler is not None:
        with dask.config.set({'distributed.comm.timeouts.connect': f'{timeout}s'}):
            try:
                c = dist.Client(scheduler, timeout=f'{timeout}s', set_as_default=False)
            except (OSError, TimeoutError, ValueError) as exc:
                detail = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
                raise CampaignError(f'no Dask scheduler answers at {scheduler} within '
                                    f'{timeout:g} s ({detail})') from None
        try:
            yield c
        finally:
            c.close()
        return
    n = workers or default_workers()
    # the workers' statistical profiler samples the running task every 10 ms for a dashboard
    # the embedded cluster does not have: off
    quiet['distributed.worker.profile.enabled'] = False
    if fork and 'fork' in multiprocessing.get_all_start_methods():
        quiet['distributed.worker.multiprocessing-method'] = 'fork'
    with dask.config.set(quiet):
        cluster = dist.LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=logging.CRITICAL,
                               memory_limit=memory_limit)
        c = dist.Client(cluster, set_as_default=False)
    try:
        yield c
    finally:
        c.close()
        cluster.close()


def describe(c: Any) -> dict[str, Any]:
    """Scheduler address, workers and threads of a client's cluster (for the report)."""
    info = c.scheduler_info(n_workers=-1)
    workers = info.get('workers', {})
    return {'scheduler': info.get('address', ''), 'workers': len(workers),
            'threads': int(sum(w.get('nthreads', 0) for w in workers.values())),
            'memory_limit_bytes': [int(w.get('memory_limit') or 0) for w in workers.values()]}


def task_history(c: Any, keys: list[str]) -> dict[str, dict[str, int]]:
    """Per task key: ``worker_deaths`` (times a worker holding it, running it or with it
    queued, died, so it was run elsewhere) and ``retries_left`` (of the ``retries=`` given
    at submission), asked of the scheduler while the tasks are still held."""
    def _ask(dask_scheduler: Any, keys: list[str] = keys) -> dict[str, dict[str, int]]:
        out = {}
        for k in keys:
            ts = dask_scheduler.tasks.get(k)
            if ts is not None:
                out[k] = {'worker_deaths': int(ts.suspicious), 'retries_left': int(ts.retries)}
        return out
    result: dict[str, dict[str, int]] = c.run_on_scheduler(_ask)
    return result
