# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""A process of the run description as its command line: ``--ros-args`` and parameter files.

The runner and the launch file start each ``NodeSpec`` of ``run_description.closed_loop`` with
what ``ros_arguments`` returns, so the two give every node the same parameters in the same
order (the scenario's file, the user's files, then the description's values).
"""

from __future__ import annotations

import hashlib
import tempfile
from pathlib import Path
from typing import Optional, Sequence

import yaml

from actuator_bringup.run_description import NodeSpec, node_kind
from actuator_sim.params_yaml import node_parameters


def ros_arguments(
    spec: NodeSpec,
    scenario_file: Optional[Path],
    workdir: Optional[Path] = None,
    params_files: Sequence[Path] = (),
) -> list[str]:
    """``--ros-args`` of a process started directly (the runner).

    The scenario's file, the user's ``params_files`` (over the scenario's values), then the
    node's parameters from this description (over both: what the run needs, such as its mode).
    rcl reads a ``-p`` value as YAML, so a string that YAML would read as something else
    (cpu_affinity '0' is an integer there) is quoted. A node in a namespace gets ``-r __ns:=``
    and the scenario file's sections for it as ``-p`` (rcl applies a file's
    ``actuator_controller:`` section to /actuator_controller only, not to
    /joint1/actuator_controller).
    """
    if spec.arguments:
        return list(spec.arguments)
    files = [a for f in params_files for a in ('--params-file', str(f))]
    if spec.members:
        args = ['--nodes', *(node_kind(m) for m in spec.members)]
        args += ['--record', spec.record_to] if spec.record_to else []
        args.append('--ros-args')
        if spec.namespace:
            # rcl's -p rules name a node without its namespace and then match /name only; a
            # parameter file's sections may name the node fully (/joint1/actuator_controller)
            args += ['-r', f'__ns:=/{spec.namespace}']
            namespaced = _namespaced_file(spec, scenario_file, workdir, params_files)
            return args + ['--params-file', str(namespaced)]
        if scenario_file is not None:
            args += ['--params-file', str(scenario_file)]
        args += files
        for member in spec.members:
            args += _parameter_arguments(member.parameters, f'{member.name}:')
        return args
    args = ['--ros-args']
    if spec.namespace:
        args += ['-r', f'__ns:=/{spec.namespace}']
        if spec.scenario_file and scenario_file is not None:
            args += _parameter_arguments(node_parameters(scenario_file, spec.name))
    elif spec.scenario_file and scenario_file is not None:
        args += ['--params-file', str(scenario_file)]
    return args + files + _parameter_arguments(spec.parameters)


def _namespaced_file(
    spec: NodeSpec,
    scenario_file: Optional[Path],
    workdir: Optional[Path],
    params_files: Sequence[Path] = (),
) -> Path:
    """Write a container's parameters, each member's section under its full name; return it.

    The scenario's values, the user's files' sections for the member (its full name or /**),
    then the description's. Into ``workdir`` (the run's folder; default the temporary one),
    named by its content.
    """
    sections = {}
    for member in spec.members:
        own = {}
        if member.scenario_file and scenario_file is not None:
            own = node_parameters(scenario_file, member.name)
        full = f'/{spec.namespace}/{member.name}'
        for path in params_files:  # its '/**' section and its own
            own.update(node_parameters(Path(path), full))
        own.update(member.parameters)
        sections[f'/{spec.namespace}/{member.name}'] = {'ros__parameters': own}
    text = yaml.safe_dump(sections, sort_keys=True)
    folder = Path(tempfile.gettempdir()) if workdir is None else Path(workdir)
    path = folder / f'{spec.key}_{hashlib.sha1(text.encode()).hexdigest()[:12]}.yaml'
    path.write_text(text)
    return path


def _parameter_arguments(parameters: dict, target: str = '') -> list[str]:
    """``-p [node:]name:=value`` for each parameter (``target`` names one node of a process)."""
    args = []
    for name, value in parameters.items():
        text = ('true' if value else 'false') if isinstance(value, bool) else str(value)
        if isinstance(value, str) and _yaml_scalar(value) != value:
            text = "'" + value.replace("'", "''") + "'"
        args += ['-p', f'{target}{name}:={text}']
    return args


def _yaml_scalar(text: str):
    """Return what rcl makes of a ``-p`` value (a YAML scalar), or None if it is not one."""
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return None
