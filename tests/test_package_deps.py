# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Each package's package.xml declares exactly what its Python code imports.

For every ament_python package in src/ (interface packages, built by ament_cmake and rosidl, have
no Python code of their own and are skipped), every Python file of the package except setup.py
(its Python package, launch files and any other script it installs) is read with ``ast``. Every
``import x`` and ``from x import ...``, at any level of the file (a function's import is a run-time
dependency too, only a later one; an ``if TYPE_CHECKING:`` import names a dependency as well),
gives its top-level module; relative imports, the package itself, ``__future__`` and the standard
library (``sys.stdlib_module_names``) are left out. DEPENDENCY_KEYS maps each module to the key a
package.xml names it by: an in-repo package by its name, a ROS package by its name, a plain Python
distribution by its rosdep key. BY_NAME adds the packages a package uses by name only (a message
module imported from a type name, another package's executable started), each with the string of
the package's code that names it.

The rules, each failure naming the package, the module and the file:

* every dependency is declared, as <depend> or <exec_depend> (the file is run), or as
  <test_depend> when only test code of the package (``test/``, ``test_*.py``) uses it;
* every <depend> and <exec_depend> is used somewhere in the package (no stale declaration), and
  every <test_depend> by its test code, except TEST_TOOLS (the runner and linters colcon test
  calls);
* <buildtool_depend> and <build_depend> are build tools (BUILD_TOOLS): an ament_python package
  is built by setuptools through colcon, and nothing its Python code imports is needed at build
  time;
* nothing is declared twice.
"""

from __future__ import annotations

import ast
import functools
import sys
import xml.etree.ElementTree as ET
from collections import Counter
from pathlib import Path
from typing import Iterable

import pytest

REPO = Path(__file__).resolve().parent.parent
SRC = REPO / 'src'

#: Top-level module -> the key a package.xml declares it by (the in-repo packages are added from
#: src/). ROS packages are named as themselves. Plain Python distributions by their rosdep key,
#: one convention: python3-<name> where rosdep (or Debian, for a key rosdep does not have yet)
#: knows the module as a system package, python3-<PyPI name>-pip where only PyPI has it (as
#: rosdep's own python3-rosbags-pip).
DEPENDENCY_KEYS = {
    # ROS 2 (Jazzy) packages
    'action_msgs': 'action_msgs',
    'ament_index_python': 'ament_index_python',
    'builtin_interfaces': 'builtin_interfaces',
    'control_msgs': 'control_msgs',
    'diagnostic_msgs': 'diagnostic_msgs',
    'launch': 'launch',
    'launch_ros': 'launch_ros',
    'lifecycle_msgs': 'lifecycle_msgs',
    'rcl_interfaces': 'rcl_interfaces',
    'rclpy': 'rclpy',
    'rosbag2_py': 'rosbag2_py',
    'rosgraph_msgs': 'rosgraph_msgs',
    'rosidl_runtime_py': 'rosidl_runtime_py',
    'sensor_msgs': 'sensor_msgs',
    'std_msgs': 'std_msgs',
    'std_srvs': 'std_srvs',
    'trajectory_msgs': 'trajectory_msgs',
    # Python distributions with a system package
    'can': 'python3-can',
    'matplotlib': 'python3-matplotlib',
    'numpy': 'python3-numpy',
    'optuna': 'python3-optuna',
    'psutil': 'python3-psutil',
    'pytest': 'python3-pytest',
    'scipy': 'python3-scipy',
    'tabulate': 'python3-tabulate',
    'tqdm': 'python3-tqdm',
    'yaml': 'python3-yaml',
    'zstandard': 'python3-zstandard',
    # Python distributions from PyPI only
    'canopen': 'python3-canopen-pip',
    'foxglove': 'python3-foxglove-sdk-pip',
    'mcap': 'python3-mcap-pip',
    'pyarrow': 'python3-pyarrow-pip',
    'ray': 'python3-ray-pip',
    'rosbags': 'python3-rosbags-pip',
}

#: Packages a package uses by name, which no import statement shows: {package: {dependency:
#: a string constant of the package's Python code that names it}}. The string must still be
#: there (so an entry cannot outlive its use).
BY_NAME = {
    # recording.SYSTEM_TOPICS: the recorder imports each recorded type's module by its name
    # (ros_common.message_class) and reads its .msg file (msgdefs).
    'actuator_bag': {
        'actuator_msgs': 'actuator_msgs/msg/CurrentCommand',
        'diagnostic_msgs': 'diagnostic_msgs/msg/DiagnosticArray',
        'rosgraph_msgs': 'rosgraph_msgs/msg/Clock',
        'sensor_msgs': 'sensor_msgs/msg/JointState',
    },
    # run_description: the run starts the live view's executable (a NodeSpec of its package).
    'actuator_bringup': {'actuator_live_view': 'actuator_live_view'},
}

#: Declared but not imported: what `colcon test` runs on a package.
TEST_TOOLS = frozenset(
    {
        'python3-pytest',
        'ament_copyright',
        'ament_flake8',
        'ament_pep257',
        'ament_lint_auto',
        'ament_lint_common',
    }
)
#: What a <buildtool_depend> or <build_depend> of a package may name.
BUILD_TOOLS = frozenset(
    {'ament_cmake', 'ament_python', 'python3-setuptools', 'rosidl_default_generators'}
)
RUNTIME_TAGS = ('depend', 'exec_depend')
BUILD_TAGS = ('buildtool_depend', 'build_depend')


def _packages() -> dict[str, tuple[Path, str]]:
    """Return {name: (folder, build_type)} of every package in src/."""
    out = {}
    for xml in sorted(SRC.glob('*/package.xml')):
        root = ET.parse(xml).getroot()
        out[root.findtext('name')] = (xml.parent, root.findtext('export/build_type') or 'catkin')
    return out


PACKAGES = _packages()
PYTHON_PACKAGES = sorted(n for n, (_, bt) in PACKAGES.items() if bt == 'ament_python')


def _declared(folder: Path) -> dict[str, list[str]]:
    """Return {tag: [keys in order]} of the package.xml's dependency elements."""
    root = ET.parse(folder / 'package.xml').getroot()
    tags = (*RUNTIME_TAGS, *BUILD_TAGS, 'test_depend', 'build_export_depend')
    return {tag: [(e.text or '').strip() for e in root.findall(tag)] for tag in tags}


def _python_files(folder: Path) -> list[Path]:
    """Every Python file of the package but setup.py (what the build runs, not the package)."""
    return sorted(
        p
        for p in folder.rglob('*.py')
        if p != folder / 'setup.py' and '__pycache__' not in p.parts
    )


def _is_test_code(path: Path, folder: Path) -> bool:
    rel = path.relative_to(folder)
    return rel.parts[0] in ('test', 'tests') or rel.name.startswith('test_')


@functools.lru_cache(maxsize=None)
def _nodes(path: Path) -> tuple[ast.AST, ...]:
    """Every node of a file's syntax tree."""
    return tuple(ast.walk(ast.parse(path.read_text(), str(path))))


def _imported_modules(path: Path) -> set[str]:
    """Top-level modules a file imports (absolute imports, anywhere in the file)."""
    out = set()
    for node in _nodes(path):
        if isinstance(node, ast.Import):
            out.update(alias.name.split('.')[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.add(node.module.split('.')[0])
    return out


def _string_constants(path: Path) -> set[str]:
    return {
        node.value
        for node in _nodes(path)
        if isinstance(node, ast.Constant) and isinstance(node.value, str)
    }


def _used(
    name: str, folder: Path, in_repo: Iterable[str], by_name: dict[str, str]
) -> tuple[dict[str, set[str]], dict[str, set[str]], list[str]]:
    """Return ({key: uses} of run-time code, {key: uses} of test code, problems).

    A use is '<file> imports <module>' (or names it: ``by_name``, the package's BY_NAME entry).
    A problem is an import DEPENDENCY_KEYS does not know, or a ``by_name`` string no longer there.
    """
    keys = {**DEPENDENCY_KEYS, **{p: p for p in in_repo}}
    runtime: dict[str, set[str]] = {}
    test: dict[str, set[str]] = {}
    problems = []
    files = _python_files(folder)
    for path in files:
        rel = str(path.relative_to(folder.parent))
        for module in sorted(_imported_modules(path)):
            if module in sys.stdlib_module_names or module in ('__future__', name):
                continue
            if module not in keys:
                problems.append(
                    f'{name}: {rel} imports {module!r}, which DEPENDENCY_KEYS of '
                    f'{Path(__file__).name} does not map to a dependency key: add it'
                )
                continue
            used = test if _is_test_code(path, folder) else runtime
            used.setdefault(keys[module], set()).add(f'{rel} imports {module}')
    for dependency, evidence in by_name.items():
        where = [
            str(p.relative_to(folder.parent)) for p in files if evidence in _string_constants(p)
        ]
        if not where:
            problems.append(
                f'{name}: BY_NAME says it uses {dependency} by the name {evidence!r}, but no '
                f'Python file of {folder.name}/ has that string any more: update BY_NAME'
            )
            continue
        runtime.setdefault(dependency, set()).update(f'{w} names {evidence!r}' for w in where)
    return runtime, test, problems


def _doubled(name: str, xml: str, declared: dict[str, list[str]]) -> list[str]:
    """Every key the package.xml declares more than once under one tag."""
    problems = []
    for tag, keys in declared.items():
        for key, count in Counter(keys).items():
            if count > 1:
                problems.append(f'{name}: {xml} declares <{tag}>{key}</{tag}> {count} times')
    return problems


def _undeclared(
    name: str,
    xml: str,
    runtime: dict[str, set[str]],
    test: dict[str, set[str]],
    runtime_declared: set[str],
    test_declared: set[str],
) -> list[str]:
    """Every key used by the run-time code, then by the test code, that package.xml omits."""
    problems = []
    for key, uses in sorted(runtime.items()):
        if key not in runtime_declared:
            problems.append(
                f'{name}: {"; ".join(sorted(uses))}, but {xml} does not declare {key}: add '
                f'<exec_depend>{key}</exec_depend>'
            )
    for key, uses in sorted(test.items()):
        if key not in runtime_declared | test_declared:
            problems.append(
                f'{name}: test code: {"; ".join(sorted(uses))}, but {xml} does not declare '
                f'{key}: add <test_depend>{key}</test_depend>'
            )
    return problems


def _stale(
    name: str,
    xml: str,
    declared: dict[str, list[str]],
    runtime: dict[str, set[str]],
    test: dict[str, set[str]],
) -> list[str]:
    """Every <depend>, <exec_depend>, then <test_depend>, that the code it is for does not use."""
    problems = []
    for tag in RUNTIME_TAGS:
        for key in declared[tag]:
            if key not in runtime and key not in test:
                problems.append(
                    f'{name}: {xml} declares <{tag}>{key}</{tag}>, but no Python file of the '
                    f'package imports it (nor names it, BY_NAME): remove it'
                )
            elif key not in runtime:
                problems.append(
                    f'{name}: {xml} declares <{tag}>{key}</{tag}>, but only test code '
                    f'({", ".join(sorted(test[key]))}) uses it: make it a <test_depend>'
                )
    for key in declared['test_depend']:
        if key not in test and key not in TEST_TOOLS:
            problems.append(
                f'{name}: {xml} declares <test_depend>{key}</test_depend>, but no test code of '
                f'the package imports it and it is no test tool (TEST_TOOLS): remove it'
            )
    return problems


def _not_build_tools(name: str, xml: str, declared: dict[str, list[str]]) -> list[str]:
    """Every <buildtool_depend> and <build_depend> that is no build tool (BUILD_TOOLS)."""
    problems = []
    for tag in BUILD_TAGS:
        for key in declared[tag]:
            if key not in BUILD_TOOLS:
                problems.append(
                    f'{name}: {xml} declares <{tag}>{key}</{tag}>, which is no build tool '
                    f'(BUILD_TOOLS); what the Python code imports is an <exec_depend>'
                )
    return problems


def _problems(
    name: str, folder: Path, in_repo: Iterable[str], by_name: dict[str, str]
) -> list[str]:
    """Every way the package.xml in ``folder`` differs from what the package's code uses."""
    xml = f'{folder.parent.name}/{folder.name}/package.xml'
    declared = _declared(folder)
    runtime, test, problems = _used(name, folder, in_repo, by_name)
    runtime_declared = {k for tag in RUNTIME_TAGS for k in declared[tag]}
    test_declared = set(declared['test_depend'])
    return (
        problems
        + _doubled(name, xml, declared)
        + _undeclared(name, xml, runtime, test, runtime_declared, test_declared)
        + _stale(name, xml, declared, runtime, test)
        + _not_build_tools(name, xml, declared)
    )


def test_the_packages_are_found():
    """The scan sees the workspace: its Python packages and the interface package it skips."""
    assert PACKAGES.get('actuator_msgs', (None, ''))[1] == 'ament_cmake'
    assert len(PYTHON_PACKAGES) >= 10 and 'actuator_core' in PYTHON_PACKAGES
    assert set(BY_NAME) <= set(PYTHON_PACKAGES)
    # every entry of the table names a key a package.xml can declare (no typo of a module)
    assert all(k and ' ' not in k for k in DEPENDENCY_KEYS.values())


@pytest.mark.slow  # parses every Python file of src/: about 1 s in all
@pytest.mark.parametrize('package', PYTHON_PACKAGES)
def test_package_xml_declares_what_the_code_imports(package):
    problems = _problems(package, PACKAGES[package][0], PACKAGES, BY_NAME.get(package, {}))
    assert not problems, '\n'.join(problems)


def test_the_rules_catch_a_missing_a_stale_and_a_doubled_declaration(tmp_path):
    """A made-up package shows each rule at work, and what is left out of the scan."""
    folder = tmp_path / 'src' / 'demo_pkg'
    (folder / 'demo_pkg').mkdir(parents=True)
    (folder / 'test').mkdir()
    (folder / 'package.xml').write_text(
        '<package format="3"><name>demo_pkg</name>'
        '<exec_depend>rclpy</exec_depend><exec_depend>rclpy</exec_depend>'
        '<exec_depend>std_msgs</exec_depend><exec_depend>python3-numpy</exec_depend>'
        '<exec_depend>python3-tqdm</exec_depend><exec_depend>sensor_msgs</exec_depend>'
        '<test_depend>python3-pytest</test_depend><test_depend>python3-scipy</test_depend>'
        '<buildtool_depend>ament_python</buildtool_depend>'
        '<build_depend>python3-yaml</build_depend>'
        '<export><build_type>ament_python</build_type></export></package>'
    )
    (folder / 'setup.py').write_text('from setuptools import setup\n')
    (folder / 'demo_pkg' / 'node.py').write_text(
        'from __future__ import annotations\n'
        'import os.path\n'
        'from . import helpers\n'
        'import demo_pkg.helpers\n'
        'import rclpy.node\n'
        'def later():\n'
        '    from other_pkg import thing\n'
        '    import yaml\n'
        'TOPIC = ("joint_states", "sensor_msgs/msg/JointState")\n'
    )
    (folder / 'demo_pkg' / 'helpers.py').write_text('import numpy as np\nimport not_mapped\n')
    (folder / 'test' / 'test_node.py').write_text('import pytest\nimport tqdm\n')
    problems = _problems(
        'demo_pkg',
        folder,
        ['demo_pkg', 'other_pkg'],
        {'sensor_msgs': 'sensor_msgs/msg/JointState', 'std_msgs': 'std_msgs/msg/Header'},
    )
    text = '\n'.join(problems)
    expected = [
        'src/demo_pkg/package.xml declares <exec_depend>rclpy</exec_depend> 2 times',
        "demo_pkg/demo_pkg/helpers.py imports 'not_mapped', which DEPENDENCY_KEYS",
        'demo_pkg/demo_pkg/node.py imports other_pkg, but src/demo_pkg/package.xml does not '
        'declare other_pkg: add <exec_depend>other_pkg</exec_depend>',
        'demo_pkg/demo_pkg/node.py imports yaml, but src/demo_pkg/package.xml does not declare '
        'python3-yaml',
        "BY_NAME says it uses std_msgs by the name 'std_msgs/msg/Header', but no Python file",
        'declares <exec_depend>std_msgs</exec_depend>, but no Python file of the package '
        'imports it',
        'declares <exec_depend>python3-tqdm</exec_depend>, but only test code '
        '(demo_pkg/test/test_node.py imports tqdm) uses it: make it a <test_depend>',
        'declares <test_depend>python3-scipy</test_depend>, but no test code',
        'declares <build_depend>python3-yaml</build_depend>, which is no build tool',
    ]
    for line in expected:
        assert line in text, f'{line!r} not in:\n{text}'
    # declared and used: rclpy, numpy (helpers), sensor_msgs (by name); pytest a test tool;
    # setup.py, relative imports, the package itself and the standard library are left out
    assert len(problems) == len(expected), text
    for word in ('setuptools', 'numpy', 'sensor_msgs/msg', "'os'", 'python3-pytest'):
        assert word not in text.replace('std_msgs/msg', ''), word
