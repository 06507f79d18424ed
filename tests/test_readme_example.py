"""The README's Python example runs as printed, and says what it claims."""
from __future__ import annotations

import pathlib
import re
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_readme_python_example_runs() -> None:
    text = (ROOT / 'README.md').read_text()
    blocks = re.findall(r'```python\n(.*?)```', text, re.S)
    assert len(blocks) == 1, 'the README holds one Python example'
    proc = subprocess.run([sys.executable, '-c', blocks[0]], capture_output=True, text=True,
                          timeout=600, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    m = re.fullmatch(r'within 0\.1 m from ([\d.]+) s; peak pitch ([\d.]+) deg\n', proc.stdout)
    assert m, proc.stdout
    # a 30 m climb at 2 m/s and at most 25 deg of pitch takes at least T_kin = 35.5 s; the
    # example flies 150 s, and the pilot keeps its 25 deg limit (2 deg of margin)
    assert 30.0 / (2.0 * 0.4226) < float(m.group(1)) < 150.0
    assert float(m.group(2)) < 27.0
