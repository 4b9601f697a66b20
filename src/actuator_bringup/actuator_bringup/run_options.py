# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The options of a closed-loop run, written once: the runner's flags and the launch arguments.

``bringup`` (actuator_bringup.runner) builds its command line from ``RUN_OPTIONS`` and
``closed_loop.launch.py`` its launch arguments; both read the values back through ``parse``, so
a name, a default, a range or a description cannot drift between them, and the reference page
(docs/reference/launch.md) is generated from the same table. Pure data, no launch import.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional, Sequence

import yaml

from actuator_bringup.run_description import JOINTS, LIVE_DIAGNOSTICS_RATE_HZ, MAX_JOINTS_ON_BUS
from actuator_core import limits
from actuator_core.identified import SECTION as IDENTIFIED_SECTION
from actuator_core.loop_params import MODES
from actuator_sim.params_yaml import node_parameters

#: The executors a node can run (actuator_ros.runner).
EXECUTORS = ('events', 'single_threaded')


@dataclass(frozen=True)
class RunOption:
    """One option of a run: its launch argument, its runner flag, its type, range and meaning."""

    name: str  # the launch argument; the runner's flag is --name with '-' for '_'
    kind: type  # str, float, int, bool or list (a list of paths: repeatable / comma-separated)
    default: Any
    description: str
    choices: tuple = ()
    low: float = -math.inf
    high: float = math.inf
    unit: str = ''
    flag: str = ''  # the runner's flag when it is not --name (e.g. --no-record for record)
    flag_help: str = ''  # the flag's help when it turns a default-true option off
    runner: bool = True  # the runner offers it
    launch: bool = True  # the launch file offers it

    @property
    def cli(self) -> str:
        """Return the runner's flag."""
        return self.flag or '--' + self.name.replace('_', '-')

    def range_text(self) -> str:
        """Return the valid values in words (docs and refusals)."""
        if self.choices:
            return ', '.join(self.choices)
        if self.kind is bool:
            return 'true, false'
        if self.kind in (int, float):
            return f'[{self.low:g}, {self.high:g}]' + (f' {self.unit}' if self.unit else '')
        return 'a path' if self.kind is list else 'text'


RUN_OPTIONS = (
    RunOption(
        'scenario',
        str,
        '',
        "parameter file share/actuator_bringup/config/<scenario>.yaml; empty: the joint's own "
        '(run_description.DEFAULT_SCENARIOS)',
    ),
    RunOption(
        'mode',
        str,
        'realtime',
        "realtime: wall-clock 1 kHz; sim: lockstep on the joint's /clock",
        choices=MODES,
    ),
    RunOption(
        'duration',
        float,
        0.0,
        "run length of the whole run; 0: the scenario's own for the runner, until Ctrl-C for "
        'launch',
        low=0.0,
        high=3600.0,
        unit='s',
    ),
    RunOption(
        'joint',
        str,
        'plant',
        'plant: the simulated joint; cia402_sim: the CiA 402 driver and its simulated drive; '
        'cia402: the driver on a real bus; none: a driver started elsewhere',
        choices=JOINTS,
    ),
    RunOption(
        'record',
        bool,
        True,
        'record the run to a bag',
        flag='--no-record',
        flag_help='do not record the run',
    ),
    RunOption(
        'params_file',
        list,
        (),
        "ROS 2 parameter files loaded after the scenario's, sections by node name "
        '(actuator_plant, actuator_cia402_driver, actuator_eso, actuator_controller, or /** for '
        'all); a section for a node the run does not have is refused',
    ),
    RunOption(
        'eds_file',
        str,
        '',
        "the drive's EDS file (CiA 306), required for joint cia402 (a real drive)",
    ),
    RunOption(
        'thread_priority',
        int,
        0,
        'SCHED_FIFO priority of the ESO and controller, the joint one above (0: normal '
        'scheduling); see docs/how-to/realtime-permissions.md',
        low=0,
        high=99,
    ),
    RunOption('executor', str, 'events', "the nodes' rclpy executor", choices=EXECUTORS),
    RunOption('composed', bool, False, 'the joint, the ESO and the controller in one process'),
    RunOption(
        'record_in_process',
        bool,
        False,
        "with composed and mode sim: the loop's process writes the bag itself, no recorder "
        'process',
    ),
    RunOption(
        'pin',
        bool,
        False,
        'the joint on CPU 0, the ESO and controller on CPU 1 (a composed process on CPU 0); on '
        'isolated cores of a real-time host only',
    ),
    RunOption(
        'live_view',
        bool,
        False,
        'also serve the loop to Foxglove (actuator_live_view on ws://127.0.0.1:8765)',
    ),
    RunOption(
        'diagnostics_rate_hz',
        float,
        math.nan,
        'rate of controller/state and plant/truth (0: every sample; unset: every sample when '
        f'recording or in sim, {LIVE_DIAGNOSTICS_RATE_HZ:g} Hz otherwise)',
        low=limits.DIAGNOSTICS_RATE_RANGE_HZ[0],
        high=limits.DIAGNOSTICS_RATE_RANGE_HZ[1],
        unit='Hz',
        flag='--diagnostics-rate',
    ),
    RunOption(
        'joints',
        int,
        1,
        'CiA 402 drives on one bus (joint cia402_sim or cia402): node ids 1..N, each with its '
        'driver, ESO and controller under /joint<i>',
        low=1,
        high=MAX_JOINTS_ON_BUS,
    ),
    RunOption(
        'allow_unstable_gains',
        bool,
        False,
        "run gains the linearised loop finds unstable at the joint's delay (a synchronous "
        "drive's SYNC included) instead of refusing them before start",
    ),
    RunOption(
        'autostart',
        bool,
        True,
        'the managed nodes configure and activate themselves; false: they wait unconfigured for '
        '`ros2 lifecycle set` (or a lifecycle manager)',
        runner=False,
    ),
    RunOption(
        'bag', str, '', 'bag folder (default bags/<scenario>_<mode>_<UTC time>)', runner=False
    ),
    RunOption('bags', str, 'bags', "folder the run's bag goes into", launch=False),
    RunOption(
        'logs',
        str,
        '',
        'folder for the per-node timing files of the benchmark (default none)',
        runner=False,
    ),
)
#: By name.
OPTIONS = {o.name: o for o in RUN_OPTIONS}


class OptionError(ValueError):
    """A run option's value is refused; the message is one line naming it."""


def parse(option: RunOption, text: Any, label: str = '') -> Any:
    """Return an option's typed value from its text (a launch argument) or value; refuse bad ones.

    Booleans accept true/false/1/0 (any case), as launch's conditions do; a list is
    comma-separated; an unset float (empty text) is NaN. ``label`` names the option in a
    refusal (the runner's flag; default the launch argument's name).
    """
    name = label or option.name
    if option.kind is bool:
        if isinstance(text, bool):
            return text
        value = str(text).strip().lower()
        if value not in ('true', 'false', '1', '0'):
            raise OptionError(f'{name} must be true or false, not {text!r}')
        return value in ('true', '1')
    if option.kind is list:
        items = text if isinstance(text, (list, tuple)) else str(text).split(',')
        return tuple(str(p).strip() for p in items if str(p).strip())
    if option.kind is str:
        value = str(text)
        if option.choices and value not in option.choices:
            raise OptionError(f'{option.name} must be one of {option.range_text()}, not {value!r}')
        return value
    if isinstance(text, str) and not text.strip():
        return math.nan if option.kind is float else option.default
    try:
        value = option.kind(text)
    except (TypeError, ValueError):
        raise OptionError(
            f'{name} must be a number in {option.range_text()}, not {text!r}'
        ) from None
    if not (option.low <= value <= option.high):
        raise OptionError(f'{name} = {value:g} is outside {option.range_text()}')
    return value


#: Sections of a parameter file that name no node: rcl's every-node one, and the identified
#: joint's model that bag_identify writes beside the nodes' sections (actuator_core.identified).
NOT_NODES = frozenset({'/**', IDENTIFIED_SECTION})


def check_parameter_files(paths: tuple, node_names: Optional[set[str]]) -> None:
    """Refuse a parameter file that is missing, is not one, or has a section for no node here.

    ``node_names``: the run's nodes, each by its name and its fully qualified name (None: the
    files' form only). A section is a node name, a fully qualified one, or one of NOT_NODES; its
    parameters are the node's own to judge (each node refuses a name it does not have when it
    configures).
    """
    for path in paths:
        file = Path(path)
        if not file.is_file():
            raise OptionError(f'params_file {path}: no such file')
        try:
            sections = yaml.safe_load(file.read_text())
        except yaml.YAMLError as exc:
            problem = str(exc).splitlines()[0]
            raise OptionError(f'params_file {path}: not YAML ({problem})') from None
        if not isinstance(sections, dict) or not all(
            isinstance(v, dict) and 'ros__parameters' in v for v in sections.values()
        ):
            raise OptionError(
                f'params_file {path}: not a ROS 2 parameter file (node: {{ros__parameters: ...}})'
            )
        if node_names is None:
            continue
        unknown = sorted(str(s) for s in sections if s not in node_names | NOT_NODES)
        if unknown:
            raise OptionError(
                f'params_file {path}: no node {", ".join(unknown)} in this run (its nodes: '
                f'{", ".join(sorted(n for n in node_names if not n.startswith("/")))})'
            )


def node_names(specs) -> set[str]:
    """Return the names a parameter file may use for the nodes of ``specs`` (members included)."""
    names = set()
    for spec in specs:
        for node in spec.members or (spec,):
            if node.arguments:  # a plain process (the simulated drive): no ROS node
                continue
            if node.namespace:  # rcl applies a plain name's section to /name only
                names.add(f'/{node.namespace}/{node.name}')
            else:
                names.update((node.name, f'/{node.name}'))
    return names


def eds_parameters(joint: str, eds_file: str) -> dict:
    """Return the driver's ``eds_file`` for a CiA 402 joint; refuse a misplaced or missing one.

    A real drive's EDS must be named (its identity is checked against it at configure); the
    simulated drive ships its own.
    """
    if eds_file and joint not in ('cia402_sim', 'cia402'):
        raise OptionError(f'eds_file is for a CiA 402 joint, not joint {joint}')
    if joint == 'cia402' and not eds_file:
        raise OptionError("joint cia402 (a real drive) needs its drive's EDS file: eds_file")
    if eds_file and not Path(eds_file).is_file():
        raise OptionError(f'eds_file {eds_file}: no such file')
    return {'eds_file': str(Path(eds_file).resolve())} if eds_file else {}


def node_section(files: Sequence[Path], node: str) -> dict:
    """Return what parameter ``files`` give ``node`` by dotted names, later files first.

    '/**' then the node's own section, as rcl applies them.
    """
    values: dict = {}
    for path in files:
        values.update(node_parameters(Path(path), node))
    return values


def joint_overrides(joint: str, eds_file: str, files: Sequence[Path]) -> dict:
    """Return the joint's parameters the run passes it: the EDS file, and a driver's own.

    For a CiA 402 driver, what the user's parameter ``files`` give it (of '/**' the names it
    has, its own section whole), so the checks before start (a real drive's reaction values)
    judge the values it will run with; ``eds_file`` over the files' one. The files' form is
    checked first, for any joint (one line).
    """
    check_parameter_files(tuple(files), None)
    if joint not in ('cia402_sim', 'cia402'):
        return eds_parameters(joint, eds_file)
    from actuator_cia402.launch_spec import DRIVER_NODE_NAME, known_names

    known = known_names()
    given = {k: v for k, v in node_section(files, '/**').items() if k in known}
    for path in files:
        given.update(node_parameters(Path(path), DRIVER_NODE_NAME, shared=False))
    return {**given, **eds_parameters(joint, eds_file or str(given.get('eds_file', '')))}


def default_for(option: RunOption) -> Optional[str]:
    """Return an option's default as a launch argument's text."""
    if option.kind is bool:
        return 'true' if option.default else 'false'
    if option.kind is list:
        return ','.join(option.default)
    if option.kind is float and math.isnan(option.default):
        return ''
    return str(option.default)
