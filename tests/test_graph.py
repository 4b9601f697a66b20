# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The closed-loop run description (actuator_bringup.run_description), and the runner options."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from actuator_bringup import runner as bringup
from actuator_bringup.composition import compose
from actuator_bringup.ros_arguments import ros_arguments
from actuator_bringup.run_description import (
    JOINTS,
    LIVE_DIAGNOSTICS_RATE_HZ,
    RECORDER_NICE,
    SYNC_PRODUCER_GRACE_S,
    closed_loop,
    default_scenario,
)
from actuator_sim.params_yaml import node_parameters


def _rates(specs) -> dict:
    """Return {key: rate} of controller/state and plant/truth in ``specs``."""
    by_key = {s.key: s.parameters for s in specs}
    return {
        'state': by_key['controller']['state_rate_hz'],
        'truth': by_key['plant']['truth_rate_hz'],
    }


@pytest.mark.parametrize(
    'mode, record, expected',
    [
        ('realtime', True, 0.0),  # the bag analysis needs every sample
        ('sim', False, 0.0),  # the paper's analysis: every sample
        ('realtime', False, LIVE_DIAGNOSTICS_RATE_HZ),  # live use only
    ],
)
def test_diagnostic_topics_default_to_every_sample_unless_nothing_records(mode, record, expected):
    """controller/state and plant/truth: every sample when recorded or in sim, else decimated."""
    assert _rates(closed_loop(mode, 5.0, record=record)) == {'state': expected, 'truth': expected}


@pytest.mark.parametrize('mode, record', [('realtime', True), ('realtime', False), ('sim', True)])
def test_a_diagnostics_rate_the_user_sets_reaches_both_topics(mode, record):
    """diagnostics_rate_hz overrides the default for the controller and the plant alike."""
    specs = closed_loop(mode, 5.0, record=record, diagnostics_rate_hz=250.0)
    assert _rates(specs) == {'state': 250.0, 'truth': 250.0}
    assert _rates(closed_loop(mode, 5.0, record=record, diagnostics_rate_hz=0.0)) == {
        'state': 0.0,
        'truth': 0.0,
    }


@pytest.mark.parametrize('rate', ['-1', '20000', 'nan'])
def test_bringup_refuses_a_diagnostics_rate_out_of_range_in_one_line(rate, capsys):
    """A rate outside limits.DIAGNOSTICS_RATE_RANGE_HZ: argparse's one-line error, exit 2."""
    with pytest.raises(SystemExit) as stop:
        bringup.main(['--diagnostics-rate', rate, '--duration', '1'])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err.endswith(
        f'bringup: error: --diagnostics-rate = {float(rate):g} is outside [0, 10000] Hz\n'
    )


def _arguments_of(spec, scenario):
    """{name: value} of a spec's ``-p`` arguments, and its remaps."""
    args = ros_arguments(spec, scenario)
    values = {a.partition(':=')[0]: a.partition(':=')[2] for a in args[2::2] if ':=' in a}
    return args, values


#: The nodes of one joint's loop in a run of several joints.
KEYS = ('controller', 'eso', 'driver')


def test_two_joints_on_one_bus_each_loop_under_its_namespace():
    """joints=2: node ids 1 and 2, one SYNC producer, distinct masters, the bus load of both."""
    specs = closed_loop('realtime', 5.0, joint='cia402_sim', joints=2, thread_priority=50)
    by_key = {s.key: s for s in specs}
    assert set(by_key) == {
        'recorder',
        'drive',
        'controller1',
        'eso1',
        'controller2',
        'eso2',
        'driver1',
        'driver2',
    }
    assert [s.key for s in specs][-2:] == ['driver1', 'driver2']  # the producer stops last
    for i in (1, 2):
        for key in KEYS:
            assert by_key[f'{key}{i}'].namespace == f'joint{i}'
        driver = by_key[f'driver{i}'].parameters
        assert (
            driver['node_id'] == i and driver['joints_on_bus'] == 2 and by_key[f'driver{i}'].leader
        )
    assert [by_key[f'driver{i}'].parameters['sync_producer'] for i in (1, 2)] == [True, False]
    for i in (1, 2):  # each joint its own name in its joint_states
        assert {by_key[f'{k}{i}'].parameters['joint_name'] for k in KEYS} == {f'joint{i}'}
    # the producer outlives the consumer in a bounded run: the consumer keeps its SYNC to the end
    stops = [by_key[f'driver{i}'].parameters['stop_after_s'] for i in (1, 2)]
    assert stops == [5.0 + SYNC_PRODUCER_GRACE_S, 5.0]
    masters = {by_key[f'driver{i}'].parameters['master_node_id'] for i in (1, 2)}
    assert masters == {127, 126}  # two heartbeats, two ids
    drive = list(by_key['drive'].arguments)
    ids = [drive[i + 1] for i, a in enumerate(drive) if a == '--node-id']
    assert ids == ['1', '2']
    ports = {by_key[f'driver{i}'].parameters['channel'] for i in (1, 2)}
    assert len(ports) == 1 and ports.pop().endswith(drive[drive.index('--port') + 1])
    topics = by_key['recorder'].parameters['topics']
    assert '/joint1/joint_states' in topics and '/joint2/controller/state' in topics
    assert len(topics) == 8


def test_composed_cia402_joints_one_process_per_joint_each_node_its_full_name(tmp_path):
    """--composed with CiA 402 joints: one container per joint, in its namespace.

    rcl's ``-p node:name:=value`` rules reach /node only, so a namespaced container gets a
    file whose sections name each node fully (/joint2/actuator_cia402_driver).
    """
    import yaml

    scenario = bringup.scenario_file('drive_pp_nftsmc_eso')
    one = compose(closed_loop('realtime', 5.0, joint='cia402_sim'))
    loop = {s.key: s for s in one}['loop']
    assert [m.key for m in loop.members] == ['driver', 'controller', 'eso']  # the joint first
    assert ros_arguments(loop, scenario)[:4] == ['--nodes', 'driver', 'controller', 'eso']
    specs = compose(closed_loop('realtime', 5.0, joint='cia402_sim', joints=2))
    assert [s.key for s in specs] == ['recorder', 'drive', 'loop1', 'loop2']  # producer: first
    for i, spec in enumerate(specs[2:], start=1):
        args = ros_arguments(spec, scenario, tmp_path)
        assert args[:6] == ['--nodes', 'driver', 'controller', 'eso', '--ros-args', '-r']
        assert args[6] == f'__ns:=/joint{i}' and args[7] == '--params-file'
        sections = yaml.safe_load(Path(args[8]).read_text())
        driver = sections[f'/joint{i}/actuator_cia402_driver']['ros__parameters']
        assert driver['node_id'] == i and driver['sync_producer'] is (i == 1)
        controller = sections[f'/joint{i}/actuator_controller']['ros__parameters']
        assert controller['controller'] == 'pp_nftsmc_eso'  # the file's section, inlined
        assert controller['joint_name'] == f'joint{i}'  # and the spec's own parameters
    with pytest.raises(ValueError, match='a joint of its own'):
        compose([s for s in closed_loop('realtime', 5.0) if s.key != 'plant'])


def test_a_namespaced_node_gets_its_file_sections_as_values():
    """A file's node section applies in the root namespace only: the runner inlines it."""
    scenario = bringup.scenario_file('case2_pp_nftsmc_eso')
    specs = {s.key: s for s in closed_loop('realtime', 5.0, joint='cia402_sim', joints=2)}
    args, values = _arguments_of(specs['controller2'], scenario)
    assert args[:3] == ['--ros-args', '-r', '__ns:=/joint2'] and '--params-file' not in args
    assert values['controller'] == 'pp_nftsmc_eso' and values['sample_time_s'] == '0.001'
    assert values['pp_nftsmc_eso.k0_per_s'] == str(
        node_parameters(scenario, 'actuator_controller')['pp_nftsmc_eso.k0_per_s']
    )
    assert values['state_rate_hz'] == '0.0'  # the spec's own parameters come after the file's
    args, _ = _arguments_of(
        {s.key: s for s in closed_loop('realtime', 5.0)}['controller'], scenario
    )
    assert '--params-file' in args and '__ns:=' not in ' '.join(args)  # one joint: as before


@pytest.mark.parametrize(
    'kwargs, why',
    [
        ({'joint': 'plant', 'joints': 2}, 'several joints share a CAN bus'),
        ({'joint': 'cia402_sim', 'joints': 5}, 'joints must be in [1, 4]'),
        ({'joint': 'cia402_sim', 'joints': 0}, 'joints must be in [1, 4]'),
        ({'joint': 'cia402_sim', 'joints': 2, 'live_view': True}, 'the live view shows one joint'),
    ],
)
def test_several_joints_are_refused_where_they_cannot_be(kwargs, why):
    with pytest.raises(ValueError, match=re.escape(why)):
        closed_loop('realtime', 5.0, **kwargs)


def test_the_bus_load_of_every_joint_is_checked():
    """Two joints at 1 kHz fit 1 Mbit/s (with a warning); at 500 kbit/s they are refused."""
    from actuator_cia402.busload import BusLoadError, check_bus_load, cycle_load

    two = cycle_load(1_000_000, 1e-3, joints=2)
    assert two.bits_per_cycle == 65 + 2 * (95 + 135 + 105)  # one SYNC, each drive's 3 PDOs
    assert 'for 2 joints is above 60 %' in check_bus_load(1_000_000, 1e-3, joints=2)
    assert check_bus_load(1_000_000, 1e-3) is None  # one joint: 40 %
    with pytest.raises(BusLoadError, match='for 2 joints exceeds the limit of 80 %'):
        check_bus_load(500_000, 1e-3, joints=2)


@pytest.mark.slow
def test_every_joint_holds_unless_a_scenario_is_named_a_cia402_one_with_the_drive_tuning():
    """graph.default_scenario: what bringup --joint and launch joint:= run by default.

    No joint starts a built-in trajectory unless one is named (reference hold); the tuning is
    the paper's Case 2 for the plant, the drive's for a CiA 402 joint.
    """
    from actuator_sim.params_yaml import all_scenarios, node_parameters

    assert default_scenario('plant') == default_scenario('none') == 'hold_pp_nftsmc_eso'
    assert default_scenario('cia402_sim') == default_scenario('cia402')
    assert default_scenario('cia402') == 'drive_hold_pp_nftsmc_eso'
    scenarios = all_scenarios()
    for joint in JOINTS:
        name = default_scenario(joint)
        assert scenarios[name].reference == 'hold'
        path = bringup.scenario_file(name)  # installed
        assert node_parameters(path, 'actuator_controller')['reference'] == 'hold'
    for name in ('drive_pp_nftsmc_eso', 'drive_hold_pp_nftsmc_eso'):
        drive = scenarios[name]
        assert drive.command_delay_samples == 1 and drive.gains.k3_per_s == 100.0
        assert (drive.eso.l1, drive.eso.l2, drive.eso.l3) == (12.0, 48.0, 64.0)
    assert scenarios['drive_pp_nftsmc_eso'].reference == 'fast'  # the paper's, when named
    hold, paper = scenarios['hold_pp_nftsmc_eso'], scenarios['case2_pp_nftsmc_eso']
    assert (hold.plant, hold.eso, hold.gains) == (paper.plant, paper.eso, paper.gains)
    with pytest.raises(ValueError, match='joint must be one of'):
        default_scenario('plnat')


def test_the_runners_extra_parameters_reach_the_eso_and_the_controllers_only():
    """--params-file / -p of the runner: every joint's ESO and controller, no other process.

    Before, with --joints 2 the keys controller1, eso1 ... were not recognised and the
    arguments went to every process: the simulated drive exited 2 on '--params-file'.
    """
    extra = ['--params-file', 'gains.yaml', '-p', 'x:=1']
    specs = closed_loop('realtime', 5.0, joint='cia402_sim', joints=2)
    got = {s.key: bringup._extra_arguments(s, extra) for s in specs}
    assert {k for k, v in got.items() if v} == {'controller1', 'eso1', 'controller2', 'eso2'}
    assert got['eso2'] == extra
    loop = {s.key: s for s in compose(closed_loop('realtime', 5.0))}['loop']
    assert bringup._extra_arguments(loop, extra) == [
        '--params-file',
        'gains.yaml',
        '-p',
        'actuator_controller:x:=1',
        '-p',
        'actuator_eso:x:=1',
    ]


@pytest.mark.parametrize('mode, nice', [('realtime', RECORDER_NICE), ('sim', None)])
def test_the_recorder_yields_the_cpu_to_the_loop_in_real_time_only(mode, nice):
    """Real time: the recorder's process at RECORDER_NICE, on its command line; no loop node is."""
    specs = {s.key: s for s in closed_loop(mode, 5.0)}
    assert specs['recorder'].parameters.get('nice') == nice
    assert RECORDER_NICE > 0
    for key in ('plant', 'eso', 'controller'):
        assert 'nice' not in specs[key].parameters
    if nice is not None:
        _, values = _arguments_of(specs['recorder'], None)
        assert values['nice'] == str(RECORDER_NICE)
