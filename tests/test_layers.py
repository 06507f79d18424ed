"""The packages form layers, and no module imports upwards or in a circle.

Every import statement of every module under ``src/`` is parsed, function-level imports
included (they hide a dependency from a reader, not from the graph). The layers, lowest first
(a package may import its own modules and the packages of lower layers only; packages of one
layer do not import each other)::

    auv_msgs, auv_contract <- auv_bag <- auv_sim <- auv_depth_lqr, auv_logs
        <- auv_ident, auv_gap <- auv_campaign <- auv_bringup
"""
from __future__ import annotations

import ast
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[1]
LAYERS: tuple[tuple[str, ...], ...] = (
    ('auv_msgs', 'auv_contract'),
    ('auv_bag',),
    ('auv_sim',),
    ('auv_depth_lqr', 'auv_logs'),
    ('auv_ident', 'auv_gap'),
    ('auv_campaign',),
    ('auv_bringup',),
)
RANK = {pkg: rank for rank, layer in enumerate(LAYERS) for pkg in layer}


def _modules() -> dict[str, pathlib.Path]:
    """Dotted module name -> file, for every package module under ``src/`` (tests left out)."""
    out: dict[str, pathlib.Path] = {}
    for path in sorted((ROOT / 'src').glob('*/*/**/*.py')):
        rel = path.relative_to(ROOT / 'src')
        if rel.parts[1] != rel.parts[0] or 'test' in rel.parts:
            continue   # setup.py, package tests
        parts = list(rel.with_suffix('').parts[1:])
        if parts[-1] == '__init__':
            parts.pop()
        out['.'.join(parts)] = path
    return out


def _imports(module: str, path: pathlib.Path, known: set[str]) -> set[str]:
    """Modules of ``known`` that ``module`` imports (absolute and relative, at any depth)."""
    package = module if path.name == '__init__.py' else module.rpartition('.')[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ''
            if node.level:
                parts = package.split('.')[:len(package.split('.')) - (node.level - 1)]
                base = '.'.join(parts + ([base] if base else []))
            targets = [base] + [f'{base}.{a.name}' for a in node.names]
        for target in targets:
            while target and target not in known:
                target = target.rpartition('.')[0]
            if target and target != module and not module.startswith(target + '.'):
                found.add(target)
    return found


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    known = set(modules)
    return {m: _imports(m, p, known) for m, p in modules.items()}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    out: list[list[str]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            v, children = work[-1]
            for w in children:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
    return out


def test_every_package_has_a_layer() -> None:
    packages = {p.parent.name for p in (ROOT / 'src').glob('*/package.xml')}
    assert packages - set(RANK) == set(), sorted(packages - set(RANK))


def test_no_import_goes_up_or_sideways() -> None:
    bad = []
    for module, targets in sorted(_graph().items()):
        own = module.split('.')[0]
        for target in sorted(targets):
            other = target.split('.')[0]
            if other != own and RANK[other] >= RANK[own]:
                bad.append(f'{module} -> {target}')
    assert not bad, 'imports against the layers: ' + '; '.join(bad)


def test_no_import_cycle() -> None:
    assert _cycles(_graph()) == []


def test_the_checks_see_a_hidden_cycle_and_an_upward_import() -> None:
    """The graph is built from function-level imports too: a cycle closed inside a function
    and an import of a higher layer are both found (a hand-made graph of three modules)."""
    graph = {'auv_sim.a': {'auv_sim.b'}, 'auv_sim.b': {'auv_sim.a'}, 'auv_bag.c': set()}
    assert _cycles(graph) == [['auv_sim.a', 'auv_sim.b']]
    source = 'def f():\n    from auv_sim.model import NX\n    return NX\n'
    tmp = ROOT / 'build' / 'layers_probe.py'
    tmp.parent.mkdir(exist_ok=True)
    tmp.write_text(source)
    try:
        found = _imports('auv_bag.probe', tmp, {'auv_sim.model', 'auv_bag.probe'})
    finally:
        tmp.unlink()
    assert found == {'auv_sim.model'}
    assert RANK['auv_sim'] > RANK['auv_bag']
