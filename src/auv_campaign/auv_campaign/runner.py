"""Submit one task per mission, report progress, gather the records, note the retries.

Each task is submitted with ``retries`` (Dask re-runs a task that raised: a fault of the run,
not a rejected log, which the task returns as a ``failed`` record). A task whose worker died
is run again by the scheduler on another worker (see :mod:`.engine`); after the campaign the
scheduler is asked, for every task, how many times its worker died and how many retries it
used, and the records say so (``worker_deaths``, ``retries``).
"""
from __future__ import annotations

import sys
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from auv_campaign.engine import task_history
from auv_campaign.tasks import MissionTask, run_mission

Progress = Callable[[str], None]


def stderr_lines(text: str) -> None:
    """A progress line on stderr."""
    print(text, file=sys.stderr, flush=True)


def run_missions(client: Any, kind: str, missions: Sequence[tuple[str, str]],
                 settings: Mapping[str, Any], *, retries: int = 2,
                 task: MissionTask = run_mission, progress: Progress | None = None,
                 label: str = '') -> list[dict[str, Any]]:
    """Run ``task(kind, name, log, settings)`` for every ``(name, log)`` as its own Dask task.

    Returns the records in the order of ``missions``; a task that still fails after its
    retries (or whose workers kept dying) becomes a ``failed`` record with the reason.
    """
    import distributed

    dist: Any = distributed

    say = progress or (lambda _line: None)
    keys = [f'{kind}{label}-{i:05d}-{name}' for i, (name, _) in enumerate(missions)]
    futures = [client.submit(task, kind, name, log, dict(settings), key=key, retries=retries,
                             pure=False)
               for key, (name, log) in zip(keys, missions)]
    index = {f.key: i for i, f in enumerate(futures)}
    records: list[dict[str, Any] | None] = [None] * len(futures)
    t0 = time.perf_counter()
    width = len(str(len(futures)))
    for done, fut in enumerate(dist.as_completed(futures, loop=client.loop), 1):
        i = index[fut.key]
        name, log = missions[i]
        try:
            rec = fut.result()
        except Exception as exc:  # the task kept failing: a failed mission, not the campaign
            msg = str(exc).splitlines()[0] if str(exc) else ''
            rec = {'name': name, 'log': log, 'status': 'failed', 'cached': False,
                   'reason': f'{type(exc).__name__}: {msg}'.rstrip(': ')}
        records[i] = rec
        state = 'cached' if rec.get('cached') else rec['status']
        tail = f': {rec["reason"]}' if rec['status'] == 'failed' else ''
        say(f'[{done:{width}d}/{len(futures)}] {time.perf_counter() - t0:7.1f} s  '
            f'{name} {state}{tail}')
    history = task_history(client, keys)
    out: list[dict[str, Any]] = []
    for key, rec in zip(keys, records):
        assert rec is not None
        h = history.get(key, {})
        rec['task'] = key
        rec['worker_deaths'] = h.get('worker_deaths', 0)
        rec['retries'] = retries - h.get('retries_left', retries)
        out.append(rec)
    del futures
    return out
