# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The test files a mutation run uses: every test module that reaches a mutated module.

Read from the imports, not kept by hand: the test module's own, those of the helper modules
under tests/ it imports, and one step further, those of the project's modules it imports (a
test of ``actuator_sim.late_answers`` exercises ``actuator_sim.loop``). A new test of the core is
in the next run without a list to edit; the run's pytest arguments (``-m "unit and not slow"``)
then pick the tests it can afford.

    python scripts/mutation/test_selection.py [--pyproject scripts/mutation/pyproject.toml]
"""

from __future__ import annotations

import argparse
import ast
import fnmatch
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TESTS = ROOT / 'tests'
PYPROJECT = Path(__file__).resolve().parent / 'pyproject.toml'


def mutated_modules(pyproject: Path) -> set[str]:
    """Return the dotted names of the modules the configuration mutates."""
    config = tomllib.loads(pyproject.read_text())['tool']['mutmut']
    out = set()
    for package in config['source_paths']:
        for path in sorted((ROOT / 'src' / package / package).glob('*.py')):
            relative = f'{package}/{path.name}'
            mutated = any(fnmatch.fnmatch(relative, p) for p in config['only_mutate'])
            excluded = any(fnmatch.fnmatch(relative, p) for p in config.get('do_not_mutate', []))
            if mutated and not excluded:
                out.add(f'{package}.{path.stem}')
    return out


def imported(path: Path) -> set[str]:
    """Return every module a file imports (``from p import m`` gives p and p.m)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names.add(node.module)
            names.update(f'{node.module}.{alias.name}' for alias in node.names)
    return names


def source_file(module: str) -> Path | None:
    """Return the source of a project module (actuator_sim.loop), or None for anything else."""
    package, _, rest = module.partition('.')
    path = ROOT / 'src' / package / package / f'{rest.replace(".", "/")}.py'
    return path if package.startswith('actuator_') and rest and path.is_file() else None


def closure(path: Path, seen: set[Path] | None = None) -> set[str]:
    """Return what ``path`` imports, with what the helper modules of tests/ it imports import.

    And what the project's modules it imports import themselves (one step).
    """
    seen = set() if seen is None else seen
    seen.add(path)
    names = imported(path)
    for name in list(names):
        helper = TESTS / f'{name}.py'
        if helper.is_file() and helper not in seen:
            names |= closure(helper, seen)
        source = source_file(name)
        if source is not None:
            names |= imported(source)
    return names


def selection(pyproject: Path = PYPROJECT) -> list[str]:
    """Return the test files (repository-relative) that import a mutated module."""
    mutated = mutated_modules(pyproject)
    return [
        str(path.relative_to(ROOT))
        for path in sorted(TESTS.glob('test_*.py'))
        if closure(path) & mutated
    ]


def main(argv: list[str] | None = None) -> int:
    """Print the selection, one file a line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--pyproject', type=Path, default=PYPROJECT)
    args = parser.parse_args(argv)
    print('\n'.join(selection(args.pyproject)))
    return 0


if __name__ == '__main__':
    sys.exit(main())
