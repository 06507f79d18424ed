"""No module reaches into another's private names: a name with a leading underscore that a
project module defines (``def _f``, ``class _C``, ``_X = ...``, ``self._x = ...``) is used
only in the file that defines it (``self``/``cls`` access aside), and no file imports a
private name from a project package."""
from __future__ import annotations

import ast
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[1]
TREES = ('src', 'tests', 'bench', 'tools')


def _private(name: str) -> bool:
    return name.startswith('_') and not name.startswith('__')


def _files() -> list[pathlib.Path]:
    return [p for tree in TREES for p in sorted((ROOT / tree).rglob('*.py'))
            if not {'build', 'install', '.venv'} & set(p.relative_to(ROOT).parts)]


def _defined(tree: ast.AST) -> set[str]:
    """Private names a file defines: functions, classes, assigned names and attributes."""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            names.add(node.attr)
    return {n for n in names if _private(n)}


def reach_ins(files: list[pathlib.Path]) -> list[str]:
    """``path:line: what`` for each use of another file's private name."""
    trees = {p: ast.parse(p.read_text(), str(p)) for p in files}
    owners: dict[str, set[pathlib.Path]] = {}
    for path, tree in trees.items():
        if path.is_relative_to(ROOT / 'src'):
            for name in _defined(tree):
                owners.setdefault(name, set()).add(path)
    found = []
    for path, tree in trees.items():
        where = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or '').startswith('auv_'):
                found += [f'{where}:{node.lineno}: imports {a.name} from '
                          f'{node.module}' for a in node.names if _private(a.name)]
            elif (isinstance(node, ast.Attribute) and node.attr in owners
                  and path not in owners[node.attr]
                  and not (isinstance(node.value, ast.Name) and node.value.id in ('self', 'cls'))):
                found.append(f'{where}:{node.lineno}: {ast.unparse(node)}')
    return found


def test_no_file_uses_another_files_private_names() -> None:
    assert reach_ins(_files()) == []


def test_the_check_sees_a_reach_in(tmp_path: pathlib.Path) -> None:
    owner = ROOT / 'src' / 'auv_depth_lqr' / 'auv_depth_lqr' / 'controller.py'
    probe = tmp_path / 'probe.py'
    probe.write_text('from auv_sim.model import _clip\n'
                     'def f(ctrl):\n    ctrl._bar_prev = 0.0\n    return ctrl._bar_prev\n')
    assert '_bar_prev' in _defined(ast.parse(owner.read_text()))
    found = reach_ins([owner, probe])
    assert any('imports _clip from auv_sim.model' in f for f in found), found
    assert sum('ctrl._bar_prev' in f for f in found) == 2, found   # set and read
