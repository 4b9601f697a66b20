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
from actuator_bringup.run_description import closed_loop, default_scenario
from actuator_bringup.run_options import (
    OPTIONS,
    RUN_OPTIONS,
    OptionError,
    check_parameter_files,
    eds_parameters,
    joint_overrides,
    node_names,
    node_section,
    parse,
)
from actuator_core import limits


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
            for n in (
                '/**',
                'actuator_plant',
                '/actuator_eso',
                'actuator_controller',
                'identified_joint',
            )
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
        'actuator_eso:\n  ros__parameters:\n    omega0_rad_s: 70.0\n'
    )
    code = bringup.main(
        ['--mode', 'sim', '--duration', '1', '--no-record', '--params-file', str(params)]
    )
    assert code == 0
    run = next((isolated / 'results' / 'runs').iterdir())
    assert 'T = 25.0 degC' in (run / 'plant.stderr').read_text()
    assert 'w0 = 70.0 rad/s' in (run / 'eso.stderr').read_text()


def test_table_4_gains_are_refused_on_a_synchronous_drive_before_anything_starts(isolated):
    """The paper's gains with one SYNC of delay: radius 1.003 at a drift vertex, refused."""
    from actuator_bringup.gain_check import check_gains, loop_radius
    from actuator_bringup.runner import scenario_file

    paper = [scenario_file('case2_pp_nftsmc_eso')]
    assert loop_radius('case2_pp_nftsmc_eso', paper, 'plant')[1] < 1.0  # the paper's own loop
    name, radius = loop_radius('case2_pp_nftsmc_eso', paper, 'cia402_sim')
    assert name == 'pp_nftsmc_eso' and 1.0 < radius < 1.01
    drive = [scenario_file('drive_pp_nftsmc_eso')]
    assert check_gains('drive_pp_nftsmc_eso', drive, 'cia402_sim', False) == (
        pytest.approx(loop_radius('drive_pp_nftsmc_eso', drive, 'cia402_sim')[1]),
        '',
    )
    with pytest.raises(SystemExit) as stop:
        bringup.run_closed_loop('case2_pp_nftsmc_eso', 'realtime', 1.0, joint='cia402_sim')
    assert str(stop.value) == (
        'bringup: the pp_nftsmc_eso gains of case2_pp_nftsmc_eso are unstable with joint '
        f'cia402_sim (1 sample(s) of command delay): linearised radius {radius:.3f} >= 1 at a '
        'vertex of the drift; name gains stable there, or insist with allow_unstable_gains'
    )
    assert not (isolated / 'bags').exists()  # refused before anything started
    insisted = check_gains('case2_pp_nftsmc_eso', paper, 'cia402_sim', True)
    assert insisted[1].endswith('run anyway (allow_unstable_gains)')


@pytest.mark.slow
def test_a_users_parameter_file_is_part_of_the_gains_judged(tmp_path):
    """A file that raises k3 beyond what one sample of delay allows is judged with it."""
    from actuator_bringup.gain_check import loop_radius
    from actuator_bringup.runner import scenario_file

    files = [scenario_file('drive_pp_nftsmc_eso')]
    stable = loop_radius('drive_pp_nftsmc_eso', files, 'cia402_sim')[1]
    hot = tmp_path / 'hot.yaml'
    hot.write_text(
        'actuator_controller:\n  ros__parameters:\n    pp_nftsmc_eso:\n      k3_per_s: 2000.0\n'
    )
    assert loop_radius('drive_pp_nftsmc_eso', [*files, hot], 'cia402_sim')[1] > stable


@pytest.mark.slow
def test_the_simulated_joint_judged_is_the_one_the_files_give_the_plant_node(tmp_path):
    """An identified nominal model (b0 20) is unstable on the paper's joint, stable on its own."""
    from actuator_bringup.gain_check import loop_radius
    from actuator_bringup.runner import scenario_file
    from actuator_plant.model import plant_from_values
    from actuator_sim.params_yaml import all_scenarios

    for name, scenario in all_scenarios().items():  # each scenario file holds its joint
        assert plant_from_values(node_section([scenario_file(name)], 'actuator_plant')) == (
            scenario.plant
        )
    files = [scenario_file('case2_pp_nftsmc_eso')]
    model = tmp_path / 'model.yaml'
    model.write_text(
        ''.join(
            f'{node}:\n  ros__parameters:\n    {prefix}theta1n: 20.0\n'
            for node, prefix in (('actuator_eso', ''), ('actuator_controller', 'common.'))
        )
    )
    assert loop_radius('case2_pp_nftsmc_eso', [*files, model], 'plant')[1] > 1.0
    joint = tmp_path / 'joint.yaml'  # the joint whose theta1 is 20 (J larger by 31.44 / 20)
    inertia = limits.NOMINAL_INERTIA_KG_M2 * limits.THETA1N / 20.0
    joint.write_text(
        'actuator_plant:\n  ros__parameters:\n    with_drift: false\n'
        f'    nominal:\n      inertia_kg_m2: {inertia!r}\n'
    )
    assert loop_radius('case2_pp_nftsmc_eso', [*files, joint, model], 'plant')[1] < 1.0


def test_a_real_drive_is_judged_before_start_with_the_values_of_the_users_files(tmp_path):
    eds = tmp_path / 'drive.eds'
    eds.write_text('[FileInfo]\n')
    travel = _file(
        tmp_path,
        '/**:\n  ros__parameters:\n    position_min_rad: -1.5\n    position_max_rad: 1.5\n'
        '    pp_nftsmc_eso:\n      k0_per_s: 2.0\n',  # another node's name: not the driver's
    )
    drive = tmp_path / 'drive.yaml'
    drive.write_text(
        'actuator_cia402_driver:\n  ros__parameters:\n    brake_status_index: 0\n'
        '    quick_stop_deceleration_rad_s2: 40.0\n'
    )
    given = joint_overrides('cia402', str(eds), [travel, drive])
    assert given == {
        'position_min_rad': -1.5,
        'position_max_rad': 1.5,
        'brake_status_index': 0,
        'quick_stop_deceleration_rad_s2': 40.0,
        'eds_file': str(eds.resolve()),
    }
    specs = closed_loop('realtime', 1.0, record=False, joint='cia402', joint_parameters=given)
    assert any(s.name == 'actuator_cia402_driver' for s in specs)
    # without the drive's section, the refusal names what is missing, in one line
    missing = joint_overrides('cia402', str(eds), [travel])
    with pytest.raises(ValueError, match='^a real drive needs brake_status_index .*quick_stop'):
        closed_loop('realtime', 1.0, record=False, joint='cia402', joint_parameters=missing)
    with pytest.raises(SystemExit) as stop:
        bringup.run_closed_loop(
            default_scenario('cia402'),
            'realtime',
            1.0,
            record=False,
            joint='cia402',
            joint_parameters=missing,
            results_root=tmp_path / 'runs',
        )
    assert str(stop.value).startswith('bringup: a real drive needs brake_status_index')
    assert not (tmp_path / 'runs').exists()  # nothing made for a refused run
    # a plant takes no driver values from the files
    assert joint_overrides('plant', '', [drive]) == {}


def test_a_run_is_named_by_its_scenario_mode_and_utc_time_for_runner_and_launch():
    from actuator_bringup.run_description import run_name

    assert re.fullmatch(
        r'hold_pp_nftsmc_eso_sim_\d{8}T\d{6}Z', run_name('hold_pp_nftsmc_eso', 'sim')
    )
    assert '<scenario>_<mode>_<UTC time>' in OPTIONS['bag'].description
