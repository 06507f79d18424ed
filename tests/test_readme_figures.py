"""The README's figures are the benchmark results files' (tools/readme_figures.py)."""
from __future__ import annotations

import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'tools'))
import readme_figures  # noqa: E402  (a tool script, not a package)


def test_readme_table_matches_the_results_files() -> None:
    res = subprocess.run([sys.executable, str(ROOT / 'tools' / 'readme_figures.py'), '--check'],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr


def test_a_field_reads_dotted_keys_and_formats() -> None:
    results = {'cl': {'runs': {'u1.5': {'ratio': 1.23456}, 'u1': {'ratio': 9.0}}, 'ok': True,
                      'none': None}}
    assert readme_figures.render('{cl:runs.u1.5.ratio:.2f} / {cl:runs.u1.ratio:.0f}',
                                 results) == '1.23 / 9'
    assert readme_figures.render('{cl:ok} {cl:none:.1f}', results) == 'True n/a'
    with pytest.raises(readme_figures.FigureError, match=r"cl\.json has no 'runs\.u2\.ratio'"):
        readme_figures.render('{cl:runs.u2.ratio}', results)
