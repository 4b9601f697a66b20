# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The reference pages of docs/reference/, generated from the code.

    python -m actuator_bringup.reference_docs            # rewrite the pages
    python -m actuator_bringup.reference_docs --check    # exit 1 when one is not current

- parameters.md: each node is built in this process with its defaults and its declared
  parameters are read back (name, type, default, description with unit and range: the
  specifications' descriptors), so the tables say what ``ros2 param describe`` says;
- nodes.md and topics.md: each node is configured in this process (the CiA 402 driver against a
  simulated drive in a process of its own) and what it created is read back: its publishers,
  subscriptions and services, by name and type;
- launch.md: the run's options (actuator_bringup.run_options), the launch arguments and the
  runner's flags;
- cli.md: the ``--help`` of every command-line tool.

A test keeps every page current (tests/test_param_docs.py).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Iterator, Sequence

#: (title, module, class) of every managed node, in the order of the file (the recorder opens
#: its bag when built: docs/bags.md#recording and `recorder --help` give its options).
NODES = (
    ('Simulated joint (`actuator_plant plant_node`)', 'actuator_plant.plant_node', 'PlantNode'),
    ('Extended state observer (`actuator_eso eso_node`)', 'actuator_eso.eso_node', 'EsoNode'),
    (
        'Controller (`actuator_controller controller_node`)',
        'actuator_controller.controller_node',
        'ControllerNode',
    ),
    (
        'CiA 402 driver (`actuator_cia402 cia402_driver`)',
        'actuator_cia402.driver_node',
        'Cia402DriverNode',
    ),
)
#: Declared by rclpy itself, not by the project.
SKIPPED = ('use_sim_time', 'start_type_description_service')
FOLDER = Path('docs/reference')
#: The command-line tools of cli.md: (package, executable, module with ``main``).
TOOLS = (
    ('actuator_bringup', 'bringup', 'actuator_bringup.runner'),
    ('actuator_analysis', 'bag_analyze', 'actuator_analysis.cli'),
    ('actuator_analysis', 'bag_identify', 'actuator_analysis.identify_cli'),
    ('actuator_bag', 'bag_repair', 'actuator_bag.repair'),
    ('actuator_bag', 'recorder', 'actuator_bag.recorder_node'),
    ('actuator_bag', 'player', 'actuator_bag.player_node'),
    ('actuator_sim', 'offline_sim', 'actuator_sim.offline'),
    ('actuator_sim', 'stability_check', 'actuator_sim.stability'),
    ('actuator_sim', 'late_commands', 'actuator_sim.late_commands'),
    ('actuator_sim', 'late_answers', 'actuator_sim.late_answers'),
    ('actuator_cia402', 'cia402_sim_drive', 'actuator_cia402.sim_drive_main'),
    ('actuator_cia402', 'cia402_torque_test', 'actuator_cia402.torque_test'),
    ('actuator_bench', 'bench', 'actuator_bench.bench'),
    ('actuator_bench', 'cia402_bench', 'actuator_bench.cia402_bench'),
)
#: What every node has from rclpy itself: left out of nodes.md.
RCLPY_SERVICES = re.compile(
    r'/(describe_parameters|get_parameter_types|get_parameters|get_type_description|'
    r'list_parameters|set_parameters|set_parameters_atomically|get_available_states|'
    r'get_available_transitions|get_state|get_transition_graph|change_state)$'
)


def _cell(text: str) -> str:
    """Return ``text`` safe inside a Markdown table cell."""
    return str(text).replace('|', '\\|').replace('\n', ' ')


def node_table(node) -> list[str]:
    """Markdown rows (name, default, description) of the parameters ``node`` declared."""
    rows = ['| parameter | default | description |', '|---|---|---|']
    for name in sorted(node._parameters):
        if name in SKIPPED:
            continue
        descriptor = node.describe_parameter(name)
        value = node.get_parameter(name).value
        default = f'`{value!r}`' if value != '' else '`""`'
        rows.append(f'| `{name}` | {_cell(default)} | {_cell(descriptor.description)} |')
    return rows


@contextlib.contextmanager
def _configured(module: str, cls: str) -> Iterator:
    """Yield node ``cls`` of ``module`` built with its defaults and configured (then destroyed).

    The CiA 402 driver is configured against a simulated drive in a process of its own.
    """
    overrides, drive = [], None
    if cls == 'Cia402DriverNode':
        from actuator_cia402.launch_spec import free_port

        port = free_port()
        drive = subprocess.Popen(
            [sys.executable, '-m', 'actuator_cia402.sim_drive_main', '--port', str(port)],
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        assert drive.stdout is not None  # stdout=PIPE
        while 'ready' not in (drive.stdout.readline() or 'ready'):
            pass
        overrides = [
            ('simulated_drive', True),
            ('interface', 'hub'),
            ('channel', f'127.0.0.1:{port}'),
        ]
    import rclpy.parameter

    node = (
        getattr(importlib.import_module(module), cls)(
            parameter_overrides=[rclpy.parameter.Parameter(n, value=v) for n, v in overrides]
        )
        if overrides
        else getattr(importlib.import_module(module), cls)()
    )
    try:
        node.trigger_configure()
        yield node
    finally:
        with contextlib.suppress(Exception):
            node.trigger_cleanup()
        node.destroy_node()
        if drive is not None:
            drive.terminate()
            drive.wait(10)


def _entities(node) -> dict[str, list[tuple[str, str]]]:
    """Return what a configured node created: (name, type) per kind, not rclpy's services."""

    def kind(entity) -> str:
        t = getattr(entity, 'msg_type', None) or getattr(entity, 'srv_type', None)
        assert t is not None  # a publisher, a subscription or a service
        return f'{t.__module__.split(".")[0]}/{t.__name__}'

    from rclpy.action import get_action_server_names_and_types_by_node

    actions = get_action_server_names_and_types_by_node(
        node, node.get_name(), node.get_namespace()
    )  # the node's own, in its local graph at once
    return {
        'action servers': sorted((n, t[0].replace('/action/', '/')) for n, t in actions),
        'publishes': sorted(
            (e.topic_name, kind(e)) for e in node.publishers if e.topic_name != '/parameter_events'
        ),
        'subscribes': sorted((e.topic_name, kind(e)) for e in node.subscriptions),
        'services': sorted(
            (e.srv_name, kind(e)) for e in node.services if not RCLPY_SERVICES.search(e.srv_name)
        ),
    }


def _with_rclpy(build):
    """Run ``build()`` with rclpy initialised in this process (quiet), and return what it gave."""
    import rclpy

    rclpy.init(args=['--ros-args', '--log-level', 'fatal'])
    try:
        return build()
    finally:
        rclpy.shutdown()


def render_parameters() -> str:
    """Return docs/reference/parameters.md."""
    lines = [
        '# Parameters of every node',
        '',
        'Generated by `python -m actuator_bringup.reference_docs` from what each node declares',
        '(its specifications: unit, valid range, description); `tests/test_param_docs.py` keeps',
        'it current. Every parameter is read at configure and refused with one line when out of',
        'range, of the wrong type or unknown',
        '([the policy](../concepts/architecture.md#parameters)).',
    ]

    def build():
        out = []
        for title, module, cls in NODES:
            node = getattr(importlib.import_module(module), cls)()
            try:
                out += ['', f'## {title}', ''] + node_table(node)
            finally:
                node.destroy_node()
        return out

    return '\n'.join(lines + _with_rclpy(build)) + '\n'


def render_nodes_and_topics() -> tuple[str, str]:
    """Return docs/reference/nodes.md and topics.md, from the nodes as they configure."""

    def build():
        found = {}
        for title, module, cls in NODES:
            with _configured(module, cls) as node:
                found[title] = (node.get_name(), _entities(node))
                goals = getattr(getattr(node, 'goals', None), 'node', None)
                if goals is not None:  # the controller's goal interface: a node of its own
                    section = f"{title.split(' (')[0]}'s goal interface (a node in its process)"
                    found[section] = (goals.get_name(), _entities(goals))
        return found

    found = _with_rclpy(build)
    nodes = [
        '# Nodes',
        '',
        'Generated by `python -m actuator_bringup.reference_docs`: each managed node of the loop',
        'configured in this process with its defaults (the CiA 402 driver against the simulated',
        'drive), and what it created read back. Every node also has the lifecycle services',
        '(`<node>/change_state`, `get_state`, ...) and the parameter services rclpy gives it;',
        "names are relative to the node's namespace (several joints: `/joint<i>`).",
    ]
    topics: dict[str, dict] = {}
    for title, (name, entities) in found.items():
        nodes += ['', f'## {title}', '', f'Node name: `{name}`.', '', '| | name | type |']
        nodes.append('|---|---|---|')
        for kind, rows in entities.items():
            for entity, type_name in rows:
                nodes.append(f'| {kind} | `{entity}` | `{type_name}` |')
                if kind in ('publishes', 'subscribes'):
                    entry = topics.setdefault(entity, {'type': type_name, 'by': {}})
                    entry['by'].setdefault(kind, []).append(f'`{name}`')
    lines = [
        '# Topics',
        '',
        'Generated by `python -m actuator_bringup.reference_docs` from the nodes as they',
        'configure (nodes.md). QoS: the 1 kHz streams are best effort in real time and reliable',
        'in sim time ([architecture](../concepts/architecture.md#topics)).',
        '',
        '| topic | type | published by | subscribed by |',
        '|---|---|---|---|',
    ]
    for topic, entry in sorted(topics.items()):
        by = entry['by']
        lines.append(
            f'| `{topic}` | `{entry["type"]}` | {", ".join(by.get("publishes", [])) or "-"} | '
            f'{", ".join(by.get("subscribes", [])) or "-"} |'
        )
    return '\n'.join(nodes) + '\n', '\n'.join(lines) + '\n'


def render_launch() -> str:
    """Return docs/reference/launch.md, from the run's options."""
    from actuator_bringup.run_options import RUN_OPTIONS, default_for

    lines = [
        '# Launch arguments and runner flags',
        '',
        'Generated by `python -m actuator_bringup.reference_docs` from',
        '`actuator_bringup/run_options.py`: one table for both starters,',
        '`ros2 launch actuator_bringup closed_loop.launch.py <argument>:=<value>` and',
        '`bringup <flag> <value>` (`scripts/ros2run actuator_bringup bringup` without ros2cli).',
        'A value outside its range is refused with one line naming it.',
        '',
        '| launch argument | runner flag | default | values | description |',
        '|---|---|---|---|---|',
    ]
    for o in RUN_OPTIONS:
        launch = f'`{o.name}`' if o.launch else '-'
        flag = f'`{o.cli}`' if o.runner else '-'
        default = default_for(o)
        lines.append(
            f'| {launch} | {flag} | `{default if default != "" else chr(34) * 2}` | '
            f'{_cell(o.range_text())} | {_cell(o.description)} |'
        )
    return '\n'.join(lines) + '\n'


def render_cli() -> str:
    """Return docs/reference/cli.md: each tool's ``--help``, at 100 columns."""
    lines = [
        '# Command-line tools',
        '',
        "Generated by `python -m actuator_bringup.reference_docs` from each tool's `--help`. Run",
        'them with `ros2 run <package> <tool>` (here `scripts/ros2run <package> <tool>`). Bad',
        'input is refused with one line and exit 2.',
    ]
    env = {**os.environ, 'COLUMNS': '100'}
    for package, executable, module in TOOLS:
        done = subprocess.run(
            [sys.executable, '-m', module, '--help'],
            capture_output=True,
            text=True,
            env=env,
            timeout=120,
        )
        if done.returncode != 0 or not done.stdout.startswith('usage: '):
            raise RuntimeError(f'{module} --help printed no usage: {done.stderr.strip()[-500:]}')
        text = done.stdout.replace(f'usage: {Path(sys.argv[0]).name}', f'usage: {executable}')
        lines += ['', f'## `{executable}` ({package})', '', '```', text.rstrip(), '```']
    return '\n'.join(lines) + '\n'


def render() -> dict[Path, str]:
    """Return every reference page by its path."""
    nodes, topics = render_nodes_and_topics()
    return {
        FOLDER / 'parameters.md': render_parameters(),
        FOLDER / 'nodes.md': nodes,
        FOLDER / 'topics.md': topics,
        FOLDER / 'launch.md': render_launch(),
        FOLDER / 'cli.md': render_cli(),
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Write the reference pages, or check that each is current."""
    parser = argparse.ArgumentParser(prog='reference_docs', description=__doc__.splitlines()[0])
    parser.add_argument('--check', action='store_true', help='exit 1 if a page is not current')
    parser.add_argument(
        '--root', type=Path, default=Path('.'), help='the repository (default: the current folder)'
    )
    args = parser.parse_args(argv)
    stale = []
    for path, text in render().items():
        target = args.root / path
        if args.check:
            if not target.exists() or target.read_text() != text:
                stale.append(str(path))
            continue
        target.write_text(text)
        print(f'wrote {path}')
    if stale:
        print(
            f'not current: {", ".join(stale)}: run python -m actuator_bringup.reference_docs',
            file=sys.stderr,
        )
        return 1
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
