# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The run's options, written once (actuator_bringup.run_options): the runner and launch read them.

A parameter file reaches any node of the loop by its name and is refused in one line for a node
the run does not have; the EDS file goes to a CiA 402 driver and is required on a real bus.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from actuator_bringup import runner as bringup
from actuator_bringup.run_description import closed_loop
from actuator_bringup.run_options import (
    OPTIONS,
    RUN_OPTIONS,
    OptionError,
    check_parameter_files,
    eds_parameters,
    node_names,
    parse,
)


def test_each_value_is_parsed_by_its_kind_and_refused_in_one_line_naming_it():
    assert parse(OPTIONS['record'], 'FALSE') is False and parse(OPTIONS['pin'], '1') is True
    assert parse(OPTIONS['params_file'], 'a.yaml, b.yaml') == ('a.yaml', 'b.yaml')
    assert math.isnan(parse(OPTIONS['diagnostics_rate_hz'], ''))
    assert parse(OPTIONS['thread_priority'], '50') == 50
    with pytest.raises(OptionError, match=r"^record must be true or false, not 'yes'$"):
        parse(OPTIONS['record'], 'yes')
    with pytest.raises(OptionError, match=r'^mode must be one of realtime, sim, not .real.$'):
        parse(OPTIONS['mode'], 'real')
    with pytest.raises(OptionError, match=r'^--thread-priority = 100 is outside \[0, 99\]$'):
        parse(OPTIONS['thread_priority'], '100', '--thread-priority')
    with pytest.raises(OptionError, match=r"^joints must be a number in \[1, 4\], not 'two'$"):
        parse(OPTIONS['joints'], 'two')


def test_the_runner_offers_every_runner_option_under_its_flag():
    help_text = bringup.build_parser().format_help()
    flags = set(re.findall(r'(--[a-z-]+)', help_text))
    assert {o.cli for o in RUN_OPTIONS if o.runner} <= flags
    assert not ({o.cli for o in RUN_OPTIONS if not o.runner} & flags)


def test_every_description_is_one_trimmed_line():
    """Descriptions go into ros2 launch --show-args and the runner's help as written."""
    untidy = [o.name for o in RUN_OPTIONS if o.description != ' '.join(o.description.split())]
    assert untidy == []


def _file(tmp_path: Path, text: str) -> Path:
    path = tmp_path / 'params.yaml'
    path.write_text(text)
    return path


def test_a_parameter_file_may_address_every_node_of_the_run_and_no_other(tmp_path):
    names = node_names(closed_loop('sim', 1.0, record=True))
    assert {'actuator_plant', 'actuator_eso', 'actuator_controller', 'recorder'} <= names
    every = _file(
        tmp_path,
        ''.join(
            f'{n}:\n  ros__parameters:\n    x: 1\n'
            for n in ('/**', 'actuator_plant', '/actuator_eso', 'actuator_controller')
        ),
    )
    check_parameter_files((str(every),), names)
    typo = _file(tmp_path, 'actuator_contoller:\n  ros__parameters:\n    k1: 1.0\n')
    with pytest.raises(OptionError) as refused:
        check_parameter_files((str(typo),), names)
    assert str(refused.value) == (
        f'params_file {typo}: no node actuator_contoller in this run (its nodes: '
        'actuator_controller, actuator_eso, actuator_plant, recorder)'
    )


def test_in_a_run_of_several_joints_a_section_names_its_node_in_full(tmp_path):
    names = node_names(closed_loop('realtime', 1.0, record=False, joint='cia402_sim', joints=2))
    assert '/joint2/actuator_controller' in names and 'actuator_controller' not in names
    plain = _file(tmp_path, 'actuator_controller:\n  ros__parameters:\n    k1: 1.0\n')
    with pytest.raises(OptionError, match='no node actuator_controller in this run'):
        check_parameter_files((str(plain),), names)


@pytest.mark.parametrize(
    'text, why',
    [
        ('a: [1, 2', 'not YAML'),
        ('- 1\n- 2\n', 'not a ROS 2 parameter file'),
        ('actuator_eso:\n  k: 1\n', 'not a ROS 2 parameter file'),
    ],
)
def test_a_file_that_is_no_parameter_file_is_refused(tmp_path, text, why):
    with pytest.raises(OptionError, match=f'^params_file .*: {why}'):
        check_parameter_files((str(_file(tmp_path, text)),), {'actuator_eso'})
    with pytest.raises(OptionError, match='no such file'):
        check_parameter_files((str(tmp_path / 'missing.yaml'),), {'actuator_eso'})


def test_the_eds_file_goes_to_a_cia402_driver_and_a_real_bus_needs_one(tmp_path):
    eds = tmp_path / 'drive.eds'
    eds.write_text('[FileInfo]\n')
    assert eds_parameters('cia402', str(eds)) == {'eds_file': str(eds.resolve())}
    assert eds_parameters('cia402_sim', '') == {}
    with pytest.raises(OptionError, match="^joint cia402 .* needs its drive's EDS file"):
        eds_parameters('cia402', '')
    with pytest.raises(OptionError, match='^eds_file is for a CiA 402 joint, not joint plant$'):
        eds_parameters('plant', str(eds))
    with pytest.raises(SystemExit) as stop:
        bringup.main(['--joint', 'cia402', '--duration', '1'])
    assert stop.value.code == 2


def test_a_parameter_file_reaches_the_plant_and_the_observer_of_a_run(isolated):
    """The runner's --params-file: a section per node, each node takes its own."""
    params = isolated / 'mine.yaml'
    params.write_text(
        'actuator_plant:\n  ros__parameters:\n    condition:\n      temperature_c: 25.0\n'
        'actuator_eso:\n  ros__parameters:\n    omega0_rad_s: 50.0\n'
    )
    code = bringup.main(
        ['--mode', 'sim', '--duration', '1', '--no-record', '--params-file', str(params)]
    )
    assert code == 0
    run = next((isolated / 'results' / 'runs').iterdir())
    assert 'T = 25.0 degC' in (run / 'plant.stderr').read_text()
    assert 'w0 = 50.0 rad/s' in (run / 'eso.stderr').read_text()
