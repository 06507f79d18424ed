"""Run every benchmark of ``bench/`` (each ``bench_*.py`` module's ``run() -> dict``).

Writes each benchmark's figures to ``bench/results/<name>.json`` (as the benchmark does when
run alone), the combined figures as JSON (``{name: figures}``, name = module without
``bench_``) to ``--out``, and prints a short table (one row per scalar figure) to stdout.
A benchmark that fails is reported as ``{"error": "..."}`` and makes the exit status 1; the
others still run.

Run: ``. .venv/bin/auv-env && python bench/run_all.py --out bench/results/latest.json``
(``make bench``); ``--only sim,bag`` runs a subset.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import pathlib
import sys
import time
import traceback
from types import ModuleType
from typing import Any

from timing import save_figures

BENCH_DIR = pathlib.Path(__file__).resolve().parent


def discover() -> dict[str, pathlib.Path]:
    """name -> path of every ``bench_*.py`` next to this file, sorted by name."""
    return {p.stem.removeprefix('bench_'): p for p in sorted(BENCH_DIR.glob('bench_*.py'))}


def load(name: str, path: pathlib.Path) -> ModuleType:
    spec = importlib.util.spec_from_file_location(f'bench_{name}', path)
    if spec is None or spec.loader is None:
        raise ImportError(f'cannot load {path}')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def flatten(figures: Any, prefix: str = '') -> list[tuple[str, Any]]:
    """Scalar leaves of nested dicts as ``(dotted.key, value)`` rows (lists are skipped)."""
    if isinstance(figures, dict):
        rows: list[tuple[str, Any]] = []
        for key, value in figures.items():
            rows += flatten(value, f'{prefix}.{key}' if prefix else str(key))
        return rows
    if isinstance(figures, (int, float, str, bool)) or figures is None:
        return [(prefix, figures)]
    return []


def table(results: dict[str, Any]) -> str:
    """A plain-text table: benchmark, figure, value."""
    rows = [(name, key, value) for name, figures in results.items()
            for key, value in flatten(figures)]
    if not rows:
        return '(no benchmarks)'
    w1 = max(len('benchmark'), *(len(r[0]) for r in rows))
    w2 = max(len('figure'), *(len(r[1]) for r in rows))
    lines = [f'{"benchmark":<{w1}}  {"figure":<{w2}}  value', '-' * (w1 + w2 + 14)]
    for name, key, value in rows:
        text = f'{value:.6g}' if isinstance(value, float) else str(value)
        lines.append(f'{name:<{w1}}  {key:<{w2}}  {text}')
    return '\n'.join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--out', type=pathlib.Path, default=BENCH_DIR / 'results' / 'latest.json',
                        help='JSON file for the combined figures')
    parser.add_argument('--only', default='', help='comma-separated benchmark names to run')
    args = parser.parse_args(argv)
    found = discover()
    wanted = [n.strip() for n in args.only.split(',') if n.strip()] or list(found)
    unknown = [n for n in wanted if n not in found]
    if unknown:
        print(f'error: unknown benchmark(s) {", ".join(unknown)} (known: {", ".join(found)})',
              file=sys.stderr)
        return 1
    results: dict[str, Any] = {}
    failed = False
    for name in wanted:
        print(f'bench {name} ...', file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        try:
            module = load(name, found[name])
            figures = module.run()
            save_figures(name, figures)
        except Exception as exc:
            traceback.print_exc()
            figures = {'error': f'{type(exc).__name__}: {exc}'}
            failed = True
        results[name] = figures
        print(f'bench {name}: {time.perf_counter() - t0:.1f} s', file=sys.stderr, flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_name(args.out.name + '.tmp')
    tmp.write_text(json.dumps(results, indent=2) + '\n')
    tmp.replace(args.out)
    print(table(results))
    print(f'\nwritten: {args.out}')
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
