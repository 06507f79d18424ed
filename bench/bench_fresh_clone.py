"""Fresh-clone ``make test`` runs in a row with two CPU-bound processes beside them.

Each run clones the repository at one commit into a new folder (a new machine: its own
``.venv``, build and install), runs ``make test`` there, and records the exit code, pytest's
summary line (passed, failed, errors, xfailed, xpassed), the wall time with set-up and the
machine's load average before and after. Two ``while True: pass`` processes run for the
whole series (the ``cpu2`` load of ``bench_graph.py``); with ``--parallel K``, K clones run
their ``make test`` at the same time, each beside the two processes and the other clones'
suites. Whatever else the machine runs is recorded in the load averages. The results file
is rewritten after every run, so an interrupted series keeps the runs it finished.

Usage: ``python bench/bench_fresh_clone.py [--runs 10] [--parallel 1] [--commit HEAD]
[--out PATH]``
(default output ``bench/results/fresh_clone.json``). Goal: the last :data:`GOAL_RUNS` runs
of the series green, in a row (a red run starts the count again; a shorter series is
recorded, its ``goal_met`` false).
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import re
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any

ROOT = pathlib.Path(__file__).resolve().parent.parent

#: Green runs in a row the goal asks for, at the end of the series.
GOAL_RUNS = 10

#: pytest's last summary line, e.g. "903 passed, 7 xfailed in 994.12s (0:16:34)".
SUMMARY = re.compile(r'^=*\s*(?P<body>(\d+ \w+(, )?)+) in [\d.]+s', re.MULTILINE)


def summary_counts(text: str) -> dict[str, int]:
    """The counts of pytest's last summary line in ``text`` ({} if there is none)."""
    found = list(SUMMARY.finditer(text))
    if not found:
        return {}
    return {word: int(n) for n, word in re.findall(r'(\d+) (\w+)', found[-1]['body'])}


def one_run(commit: str, index: int, logs: pathlib.Path) -> dict[str, Any]:
    """Clone ``commit`` into a new folder, ``make test`` there; what happened."""
    with tempfile.TemporaryDirectory(prefix=f'fresh{index}-') as tmp:
        clone = pathlib.Path(tmp) / 'repo'
        subprocess.run(['git', 'clone', '-q', str(ROOT), str(clone)], check=True)
        subprocess.run(['git', '-C', str(clone), 'checkout', '-q', commit], check=True)
        load_before = os.getloadavg()[0]
        start = time.monotonic()
        env = {k: v for k, v in os.environ.items()
               if not k.startswith(('AMENT', 'COLCON', 'ROS_', 'VIRTUAL_ENV', 'PYTHONPATH'))}
        proc = subprocess.run(['make', 'test'], cwd=clone, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True)
        wall = time.monotonic() - start
        log = logs / f'run{index}.log'
        log.write_text(proc.stdout)
        counts = summary_counts(proc.stdout)
        green = proc.returncode == 0 and counts.get('passed', 0) > 0 and not any(
            counts.get(k, 0) for k in ('failed', 'error', 'errors', 'xpassed'))
        failed = re.findall(r'^(?:FAILED|ERROR) (\S+)', proc.stdout, re.MULTILINE)
        return {'run': index, 'exit_code': proc.returncode, 'green': green,
                'counts': counts, 'failed': failed, 'wall_s_with_setup': round(wall, 1),
                'load_average_1min_before': round(load_before, 2),
                'load_average_1min_after': round(os.getloadavg()[0], 2), 'log': str(log)}


def score(figures: dict[str, Any]) -> dict[str, Any]:
    """``figures`` with the series' counts and verdict from its ``runs`` (in the order
    run): ``green`` and ``done`` runs, the median wall time [s], ``green_in_a_row`` (the
    green runs since the last red one) and ``goal_met`` (at least :data:`GOAL_RUNS` of
    them)."""
    runs = figures['runs']
    figures['green'] = sum(r['green'] for r in runs)
    figures['done'] = len(runs)
    figures['median_wall_s'] = sorted(r['wall_s_with_setup'] for r in runs)[len(runs) // 2]
    in_a_row = 0
    for r in reversed(runs):
        if not r['green']:
            break
        in_a_row += 1
    figures['green_in_a_row'] = in_a_row
    figures['goal_runs'] = GOAL_RUNS
    figures['goal_met'] = in_a_row >= GOAL_RUNS
    return figures


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--runs', type=int, default=10, help='runs in the series (default 10)')
    parser.add_argument('--parallel', type=int, default=1,
                        help='clones running make test at the same time (default 1)')
    parser.add_argument('--commit', default='HEAD', help='commit to clone (default HEAD)')
    parser.add_argument('--out', type=pathlib.Path,
                        default=ROOT / 'bench' / 'results' / 'fresh_clone.json',
                        help='results file (rewritten after every run)')
    args = parser.parse_args()
    if args.runs < 1:
        parser.error(f'--runs must be at least 1, not {args.runs}')
    if args.parallel < 1:
        parser.error(f'--parallel must be at least 1, not {args.parallel}')
    commit = subprocess.run(['git', '-C', str(ROOT), 'rev-parse', args.commit], check=True,
                            stdout=subprocess.PIPE, text=True).stdout.strip()
    logs = pathlib.Path(tempfile.mkdtemp(prefix='fresh-clone-logs-'))
    hogs = [subprocess.Popen([sys.executable, '-c', 'while True: pass'],
                             start_new_session=True) for _ in range(2)]
    figures: dict[str, Any] = {'commit': commit, 'runs_planned': args.runs,
                               'load_beside': 'two CPU-bound processes',
                               'goal': f'the last {GOAL_RUNS} runs green in a row',
                               'machine_cpus': os.cpu_count(),
                               'nice': os.nice(0), 'parallel': args.parallel, 'runs': []}
    done = threading.Lock()

    def run_and_record(index: int) -> None:
        result = one_run(commit, index, logs)
        with done:
            figures['runs'].append(result)
            figures['runs'].sort(key=lambda r: r['run'])
            args.out.write_text(json.dumps(score(figures), indent=2) + '\n')
            print(json.dumps(result), flush=True)

    try:
        with ThreadPoolExecutor(max_workers=args.parallel) as pool:
            list(pool.map(run_and_record, range(args.runs)))
    finally:
        for hog in hogs:
            hog.kill()
    return 0 if figures.get('goal_met') else 1


if __name__ == '__main__':
    sys.exit(main())
