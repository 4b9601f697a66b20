# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The project's modules import each other without a circle, and so do its packages.

The graph's nodes are the modules of the Python packages under src/*/ (``actuator_x.y``); an edge
``a -> b`` is an import of project module ``b`` that runs when ``a`` is imported: a statement of
the module's body, also inside ``if``, ``try``, ``with`` or a class body, but not inside a
function (a deliberate lazy import, run only when the function is called) and not under
``if TYPE_CHECKING:`` (never run). ``import a.b`` and ``from a.b import c`` give an edge to
``a.b``, or to ``a.b.c`` when ``c`` is a module; the parent packages' ``__init__`` modules are
left out (Python imports a package before its submodules, so they close no harmful circle).

A circle is reported as its modules in import order, each edge with the line of its import.
A lazy import that closes a circle is reported too (test_no_lazy_import_closes_a_circle): a
function-level import is the way to break a circle only where the import is lazy by nature,
and then it is listed in LAZY_CIRCLES with why.
"""

from __future__ import annotations

import ast
import functools
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
SRC = REPO / 'src'

#: Function-level imports allowed to close a circle of module imports: {(module, imported
#: module): why the import is lazy by nature}. None so far.
LAZY_CIRCLES: dict[tuple[str, str], str] = {}

Graph = dict[str, dict[str, str]]


def _modules(src: Path) -> dict[str, Path]:
    """Return {dotted name: file} of every module of the Python packages under ``src``/*/."""
    out = {}
    for init in sorted(src.glob('*/*/__init__.py')):
        root = init.parent
        for path in sorted(root.rglob('*.py')):
            if '__pycache__' in path.parts:
                continue
            parts = list(path.relative_to(root.parent).with_suffix('').parts)
            if parts[-1] == '__init__':
                parts.pop()
            out['.'.join(parts)] = path
    return out


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == 'TYPE_CHECKING') or (
        isinstance(test, ast.Attribute) and test.attr == 'TYPE_CHECKING'
    )


def _statements(body: list[ast.stmt], lazy: bool):
    """Yield (statement, in a function) for the statements of ``body`` and those inside them.

    A function's body is entered only when ``lazy``; an ``if TYPE_CHECKING:`` body never.
    """
    for stmt in body:
        yield stmt
        if isinstance(stmt, (ast.FunctionDef, ast.AsyncFunctionDef)):
            if lazy:
                yield from _statements(stmt.body, lazy)
            continue
        if isinstance(stmt, ast.If) and _is_type_checking(stmt.test):
            yield from _statements(stmt.orelse, lazy)
            continue
        for field in ('body', 'orelse', 'finalbody'):
            yield from _statements(getattr(stmt, field, []), lazy)
        for handler in getattr(stmt, 'handlers', []):
            yield from _statements(handler.body, lazy)
        for case in getattr(stmt, 'cases', []):
            yield from _statements(case.body, lazy)


@functools.lru_cache(maxsize=None)
def _body(path: Path) -> list[ast.stmt]:
    """Return the statements of a file's module body."""
    return ast.parse(path.read_text(), str(path)).body


def _imports(name: str, path: Path, modules: dict[str, Path], lazy: bool) -> dict[str, int]:
    """Return {imported project module: line} of a module's imports.

    Those run at import time, and with ``lazy`` also those inside its functions.
    """
    package = name if path.name == '__init__.py' else name.rpartition('.')[0]
    out: dict[str, int] = {}
    for stmt in _statements(_body(path), lazy):
        if isinstance(stmt, ast.Import):
            targets = [alias.name for alias in stmt.names]
        elif isinstance(stmt, ast.ImportFrom):
            if stmt.level:
                base = package.split('.')
                base = base[: len(base) - stmt.level + 1]
                source = '.'.join(base + ([stmt.module] if stmt.module else []))
            else:
                source = stmt.module or ''
            targets = [
                f'{source}.{alias.name}' if f'{source}.{alias.name}' in modules else source
                for alias in stmt.names
            ]
        else:
            continue
        for target in targets:
            if target in modules and target != name:
                out.setdefault(target, stmt.lineno)
    return out


@functools.lru_cache(maxsize=None)
def _graph(src: Path, lazy: bool) -> tuple[dict[str, Path], Graph]:
    """Return (modules, {module: {imported module: 'file:line'}})."""
    modules = _modules(src)
    graph = {
        name: {
            target: f'{path.relative_to(src)}:{line}'
            for target, line in _imports(name, path, modules, lazy).items()
        }
        for name, path in modules.items()
    }
    return modules, graph


def _parts(graph: Graph) -> list[list[str]]:
    """Return the strongly connected parts of more than one node, each sorted.

    Tarjan's algorithm, iterative.
    """
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    parts: list[list[str]] = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, edges = work[-1]
            for nxt in edges:
                if nxt not in index:
                    index[nxt] = low[nxt] = len(index)
                    stack.append(nxt)
                    on_stack.add(nxt)
                    work.append((nxt, iter(sorted(graph[nxt]))))
                    break
                if nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    part = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        part.append(member)
                        if member == node:
                            break
                    if len(part) > 1:
                        parts.append(sorted(part))
    return sorted(parts)


def _circle(part: list[str], graph: Graph) -> list[str]:
    """Return the shortest circle from a part's first module back to it, in import order."""
    members, start = set(part), part[0]
    previous: dict[str, str] = {}
    queue = [start]
    while queue and start not in previous:
        node = queue.pop(0)
        for nxt in sorted(graph[node]):
            if nxt in members and nxt not in previous:
                previous[nxt] = node
                queue.append(nxt)
    path = [start]
    while previous[path[0]] != start:
        path.insert(0, previous[path[0]])
    return [start, *path]


def _circles(graph: Graph) -> list[list[str]]:
    """One circle through each strongly connected part, in import order."""
    return [_circle(part, graph) for part in _parts(graph)]


def _report(graph: Graph) -> str:
    """Each part's circle, an edge a line with the file and line of its import."""
    out = []
    for number, part in enumerate(_parts(graph), 1):
        circle = _circle(part, graph)
        out.append(f'circle {number}:')
        out += [f'  {a} -> {b} ({graph[a][b]})' for a, b in zip(circle, circle[1:])]
        if len(part) > len(circle) - 1:
            out.append(
                f'  (more circles among {", ".join(part)}: each of them reaches every other)'
            )
    return '\n'.join(out)


@pytest.mark.slow  # parses every Python file of src/ (once: cached)
def test_the_graph_sees_the_project():
    modules, graph = _graph(SRC, lazy=False)
    assert 'actuator_core.limits' in modules and 'actuator_bag' in modules
    assert len(modules) > 100
    assert 'actuator_core.limits' in graph['actuator_cia402.config']
    assert sum(map(len, graph.values())) > 300


@pytest.mark.slow  # parses every Python file of src/ (once: cached)
def test_no_module_imports_in_a_circle():
    """Module-level imports among the project's modules form no circle."""
    _, graph = _graph(SRC, lazy=False)
    parts = _parts(graph)
    assert not parts, 'import circles among the modules of src/:\n' + _report(graph)


@pytest.mark.slow  # parses every Python file of src/ (once: cached)
def test_no_lazy_import_closes_a_circle():
    """With the imports inside functions added, still no circle but the allowed ones.

    A lazy import that closes a circle hides it; each allowed one is listed in LAZY_CIRCLES.
    """
    _, graph = _graph(SRC, lazy=True)
    allowed = {a: dict(b) for a, b in graph.items()}
    for (module, target), why in LAZY_CIRCLES.items():
        assert why and target in allowed.get(module, {}), (module, target)
        del allowed[module][target]
    parts = _parts(allowed)
    assert not parts, (
        'circles closed by imports inside functions (move the shared piece to the module that '
        'owns it, or a small module of its own):\n' + _report(allowed)
    )


def test_packages_depend_on_each_other_without_a_circle():
    """The in-repo dependencies of the package.xml files form no circle either."""
    names = {}
    for xml in sorted(SRC.glob('*/package.xml')):
        names[ET.parse(xml).getroot().findtext('name')] = xml
    graph: Graph = {}
    for name, xml in names.items():
        root = ET.parse(xml).getroot()
        graph[name] = {
            dep.text.strip(): f'{xml.relative_to(SRC)}'
            for tag in ('depend', 'exec_depend', 'build_depend', 'buildtool_depend')
            for dep in root.findall(tag)
            if dep.text and dep.text.strip() in names and dep.text.strip() != name
        }
    assert graph['actuator_bringup'] and not graph['actuator_core']
    parts = _parts(graph)
    assert not parts, 'package dependency circles:\n' + _report(graph)


def test_a_made_up_circle_is_reported_in_import_order(tmp_path):
    """Three modules in a circle, one lazy import, one under TYPE_CHECKING and a relative one."""
    pkg = tmp_path / 'demo' / 'demo'
    pkg.mkdir(parents=True)
    (pkg / '__init__.py').write_text('')
    (pkg / 'a.py').write_text('from demo.b import x\n')
    (pkg / 'b.py').write_text(
        'from typing import TYPE_CHECKING\n'
        'if TYPE_CHECKING:\n'
        '    from demo.a import y\n'
        'try:\n'
        '    from . import c\n'
        'except ImportError:\n'
        '    c = None\n'
    )
    (pkg / 'c.py').write_text('import os\nimport demo.a\n')
    (pkg / 'd.py').write_text('def later():\n    from demo import e\n')
    (pkg / 'e.py').write_text('class E:\n    from demo.d import later\n')
    _, graph = _graph(tmp_path, lazy=False)
    assert graph['demo.b'] == {'demo.c': 'demo/demo/b.py:5'}
    assert graph['demo.d'] == {}
    assert _circles(graph) == [['demo.a', 'demo.b', 'demo.c', 'demo.a']]
    assert 'demo.c -> demo.a (demo/demo/c.py:2)' in _report(graph)
    _, lazy_graph = _graph(tmp_path, lazy=True)
    assert ['demo.d', 'demo.e', 'demo.d'] in _circles(lazy_graph)
