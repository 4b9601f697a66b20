# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""docs/safety.md's rule map holds against the code: each rule's class, node and test exist.

Every row names a safety rule (a section of the page), the class that applies it (imported
here), the nodes that hold it (their executables; the class is used by the node's package or the
shared node code of actuator_ros) and a test of it (a function of that test file).
"""

from __future__ import annotations

import ast
import configparser
import importlib
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / 'docs' / 'safety.md'
HEADER = '| rule | class | node | test |'
#: Code every node of the loop runs besides its own package's (the joint node, parameters, ...).
SHARED_NODE_CODE = ROOT / 'src' / 'actuator_ros' / 'actuator_ros'


def _rows() -> list[list[str]]:
    """Return the rule map's rows, each its four cells."""
    text = PAGE.read_text()
    section = text.split('\n## Rule map\n', 1)[1].split('\n## ', 1)[0]
    lines = section.splitlines()
    start = lines.index(HEADER)
    rows = []
    for line in lines[start + 2 :]:
        if not line.startswith('|'):
            break
        rows.append([c.strip() for c in line.strip().strip('|').split('|')])
    return rows


def _executables() -> dict[str, Path]:
    """Return {'package executable': the package's source folder} of every console script."""
    out = {}
    for cfg in sorted((ROOT / 'src').glob('*/setup.cfg')):
        parser = configparser.ConfigParser()
        parser.read(cfg)
        package = cfg.parent.name
        scripts = parser.get('options.entry_points', 'console_scripts', fallback='')
        for line in filter(None, (x.strip() for x in scripts.splitlines())):
            out[f'{package} {line.split("=")[0].strip()}'] = cfg.parent / package
    return out


def _uses(folder: Path, name: str) -> bool:
    """Return whether a Python file of ``folder`` names ``name`` as a word."""
    pattern = re.compile(rf'\b{re.escape(name)}\b')
    return any(pattern.search(p.read_text()) for p in folder.glob('*.py'))


def _test_functions(path: Path) -> set[str]:
    """Return the names of the functions a test file defines."""
    tree = ast.parse(path.read_text())
    return {n.name for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)}


@pytest.mark.slow
def test_every_row_names_a_class_a_node_and_a_test_that_exist():
    rows = _rows()
    assert len(rows) >= 12, rows
    executables = _executables()
    anchors = {
        re.sub(r'[^a-z0-9 -]', '', h[3:].strip().lower()).replace(' ', '-')
        for h in PAGE.read_text().splitlines()
        if h.startswith('## ')
    }
    for rule, cls, nodes, test in rows:
        link = re.fullmatch(r'\[[^\]]+\]\(#([a-z0-9-]+)\)', rule)
        assert link and link.group(1) in anchors, rule
        dotted = re.fullmatch(r'`([\w.]+)`', cls)
        assert dotted, cls
        module, _, name = dotted.group(1).rpartition('.')
        assert hasattr(importlib.import_module(module), name), cls
        held = re.findall(r'`([\w]+ [\w-]+)`', nodes)
        assert held, nodes
        for node in held:
            assert node in executables, (node, sorted(executables))
            assert _uses(executables[node], name) or _uses(SHARED_NODE_CODE, name), (rule, node)
        where = re.fullmatch(r'`(tests/test_\w+\.py)::(test_\w+)`', test)
        assert where, test
        assert where.group(2) in _test_functions(ROOT / where.group(1)), test


def test_the_map_is_checked_against_a_made_up_row(tmp_path, monkeypatch):
    """A class, node or test that does not exist fails the check (the checker checks)."""
    rows = _rows()
    good = rows[0]
    for bad in (
        [good[0], '`actuator_core.binding.NoSuchRule`', good[2], good[3]],
        [good[0], good[1], '`actuator_plant no_such_node`', good[3]],
        [good[0], good[1], good[2], '`tests/test_binding.py::test_no_such_test`'],
    ):
        page = tmp_path / 'safety.md'
        table = [HEADER, '|---|---|---|---|'] + [
            '| ' + ' | '.join(r) + ' |' for r in [bad] + rows[1:]
        ]
        head = PAGE.read_text().split('\n## Rule map\n')[0]
        page.write_text(head + '\n## Rule map\n\n' + '\n'.join(table) + '\n')
        monkeypatch.setattr(sys.modules[__name__], 'PAGE', page)
        with pytest.raises(AssertionError):
            test_every_row_names_a_class_a_node_and_a_test_that_exist()
