# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The closed loop across processes.

Sim time equals the offline core, the main job reports. The real-time runs are in
tests/test_realtime_closed_loop.py.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from actuator_bringup.supervisor import executable_path


@pytest.mark.parametrize(
    'controller, composed',
    [
        ('pp_nftsmc_eso', False),
        ('nftsmc_eso', False),
        ('smc_eso', False),
        ('pi', False),
        ('pp_nftsmc_eso', True),
        ('pi', True),
    ],
)
def test_sim_mode_across_three_processes_equals_the_offline_core(isolated, controller, composed):
    """Separate processes, or the three nodes composed in one (``composed``): bit for bit."""
    from actuator_analysis.analyze import load_run
    from actuator_bringup.main import compare_with_offline
    from actuator_bringup.runner import run_closed_loop
    from actuator_sim.loop import ClosedLoop
    from actuator_sim.params_yaml import all_scenarios

    scenario_name = f'case2_{controller}'
    result = run_closed_loop(
        scenario_name,
        'sim',
        2.0,
        record=True,
        bag_root=isolated / 'bags',
        results_root=isolated / 'runs',
        quiet=True,
        composed=composed,
    )
    assert all(code == 0 for code in result.exit_codes.values()), result.exit_codes
    assert ('loop' in result.exit_codes) == composed  # one process holds the three nodes
    scenario = all_scenarios()[scenario_name]
    scenario.duration_s = 2.0
    offline = ClosedLoop(scenario).run()
    run = load_run(result.bag, quiet=True)
    comparison = compare_with_offline(run, offline)
    assert comparison['samples_compared'] == 2000
    assert comparison['identical'], comparison  # bit for bit, sample by sample
    eso = json.loads((result.run_dir / 'eso_stats.json').read_text())
    assert eso['substituted_pairs'] == 0 and eso['exact_pairs'] >= 2000


def test_a_node_that_refuses_its_parameter_ends_the_run_with_its_own_line(isolated):
    """A misspelled gain in a parameter file: the runner's one line is the node's refusal."""
    from actuator_bringup.runner import run_closed_loop

    params = isolated / 'gains.yaml'
    params.write_text(
        'actuator_controller:\n  ros__parameters:\n    pp_nftsmc_eso:\n      k0_per_sec: 80.0\n'
    )
    with pytest.raises(SystemExit) as ended:
        run_closed_loop(
            'case2_pp_nftsmc_eso',
            'sim',
            2.0,
            record=False,
            results_root=isolated / 'runs',
            quiet=True,
            params_files=[params],
        )
    said = str(ended.value)
    assert said.startswith('bringup: controller exited early with code 2: '), said
    assert "'pp_nftsmc_eso.k0_per_sec' is not a parameter of actuator_controller" in said, said
    assert "did you mean 'pp_nftsmc_eso.k0_per_s'" in said and '\n' not in said, said


def test_a_joint_that_refuses_its_parameter_is_named_with_its_line_by_the_runner(isolated, capsys):
    """The joint ends the run itself (it leads it): the runner still says why, in one line."""
    from actuator_bringup.runner import main

    params = isolated / 'joint.yaml'
    params.write_text('actuator_plant:\n  ros__parameters:\n    depth_meters: 100.0\n')
    args = ['--scenario', 'case2_pp_nftsmc_eso', '--mode', 'sim', '--duration', '2']
    assert main([*args, '--no-record', '--params-file', str(params)]) == 1
    said = [x for x in capsys.readouterr().err.splitlines() if x.startswith('bringup: ')]
    assert len(said) == 1 and said[0].startswith('bringup: plant exited with code 2: '), said
    assert "'depth_meters' is not a parameter of actuator_plant" in said[0], said


def test_sim_mode_equals_the_offline_core_through_a_latch_safe_stop_and_brake(isolated):
    """A following-error latch at about 1 s: safe-stop commands, 0 A, the joint braked.

    The joint's true velocity and angle (plant/truth) and every command equal the offline
    loop's sample by sample, after the latch too: both hold the same joint, gate and brake.
    """
    from actuator_analysis.analyze import load_run
    from actuator_bringup.runner import run_closed_loop
    from actuator_core.status import Status
    from actuator_sim.loop import ClosedLoop
    from actuator_sim.params_yaml import all_scenarios

    limit = 7.5e-4  # |e| passes it between 0.5 and 1.0 s of the fast trajectory
    result = run_closed_loop(
        'case2_pp_nftsmc_eso',
        'sim',
        2.0,
        record=True,
        bag_root=isolated / 'bags',
        results_root=isolated / 'runs',
        extra_params=[
            '-p',
            f'following_error_limit_rad:={limit}',
            '-p',
            'allow_unknown_parameters:=true',
        ],
        quiet=True,
    )
    assert all(code == 0 for code in result.exit_codes.values()), result.exit_codes
    scenario = all_scenarios()['case2_pp_nftsmc_eso']
    scenario.duration_s = 2.0
    loop = ClosedLoop(scenario)
    loop.assembly.following_error_limit_rad = limit
    offline = loop.run(stop_on_divergence=False)
    latched = np.flatnonzero(offline['status'] == Status.LATCHED)
    assert 500 < latched[0] < 1000 and latched[-1] == 1999  # latched once, for good
    braked = offline['true_velocity_rad_s'][latched[0] + 100 :]
    assert np.all(braked == 0.0)  # the brake holds the joint against the external torque
    run = load_run(result.bag, quiet=True)
    index = np.rint(run.t * 1000.0).astype(int)
    assert index.size == 2000 and np.all(run.status[index > latched[0]] == Status.LATCHED)
    assert np.array_equal(run.current, offline['current_a'][index])
    assert np.array_equal(run.measured, offline['measured_position_rad'][index])
    truth_index = np.rint((run.truth_t - run.truth_t[0]) * 1000.0).astype(int)
    assert truth_index.size >= 2000
    assert np.array_equal(
        run.truth_velocity[truth_index < 2000],
        offline['true_velocity_rad_s'][truth_index[truth_index < 2000]],
    )


def test_main_job_prints_the_report_and_writes_figures(ros_env, tmp_path):
    env = dict(ros_env)
    proc = subprocess.run(
        [
            sys.executable,
            '-m',
            'actuator_bringup.main',
            '--duration',
            '6',
            '--modes',
            'sim',
            '--out',
            str(tmp_path / 'out'),
        ],
        env=env,
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert 'max steady-state error [5, 6] s' in proc.stdout
    assert 'identical' in proc.stdout and 'PPF bounds kept' in proc.stdout
    report = json.loads((tmp_path / 'out' / 'report.json').read_text())
    sim = report['runs']['sim']
    assert sim['offline_comparison']['identical']
    assert sim['metrics']['max_steady_error_rad'] == pytest.approx(
        report['offline']['max_steady_error_rad']
    )
    assert {Path(f).name for f in sim['figures']} == {
        'position.png',
        'tracking_error.png',
        'velocity_estimate.png',
        'disturbance_estimate.png',
        'control_input.png',
    }
    assert all(Path(f).stat().st_size > 10_000 for f in sim['figures'])
    assert list((tmp_path / 'bags').iterdir())  # the run was recorded under bags/


@pytest.mark.slow
def test_installed_scenario_files_match_the_scenarios():
    from ament_index_python.packages import get_package_share_directory

    from actuator_sim.params_yaml import all_scenarios, scenario_parameters

    config = Path(get_package_share_directory('actuator_bringup')) / 'config'
    scenarios = all_scenarios()
    assert {p.stem for p in config.glob('*.yaml')} == set(scenarios)
    # Case 1's four runs, Case 2's four + SMC as printed, the drive's, the two that hold, the
    # excitation run
    assert len(scenarios) == 13
    for name, scenario in scenarios.items():
        assert yaml.safe_load((config / f'{name}.yaml').read_text()) == scenario_parameters(
            scenario
        ), name


def test_closed_loop_description_is_one_for_runner_and_launch():
    """graph.closed_loop.

    The processes, their parameters and real-time settings, as both starters use them.
    """
    from actuator_bringup.ros_arguments import ros_arguments
    from actuator_bringup.run_description import closed_loop

    specs = closed_loop('realtime', 5.0, record=True, thread_priority=50, cpus={'joint': '0'})
    by_key = {s.key: s for s in specs}
    assert list(by_key) == ['recorder', 'controller', 'eso', 'plant']  # the joint starts last
    assert [s.key for s in specs if s.leader] == ['plant']
    assert by_key['plant'].parameters['thread_priority'] == 51  # the sampling hardware, one above
    assert (
        by_key['eso'].parameters['thread_priority']
        == by_key['controller'].parameters['thread_priority']
        == 50
    )
    assert 'thread_priority' not in by_key['recorder'].parameters  # normal scheduling
    assert (
        by_key['plant'].parameters['cpu_affinity'] == '0'
        and by_key['plant'].parameters['stop_after_s'] == 5.0
    )
    assert by_key['plant'].parameters['wait_for_subscribers'] == 3
    assert not by_key['recorder'].managed and all(
        s.managed for k, s in by_key.items() if k != 'recorder'
    )
    args = ros_arguments(by_key['eso'], Path('/x/case.yaml'))
    assert (
        args[:3] == ['--ros-args', '--params-file', '/x/case.yaml']
        and '-p' in args
        and 'autostart:=true' in args
    )
    sim = {s.key: s for s in closed_loop('sim', 2.0, record=False)}
    assert (
        sim['controller'].parameters['use_sim_time'] is True
        and sim['plant'].parameters['wait_for_subscribers'] == 2
    )
    # Diagnostic topics: every sample when recorded or in sim, decimated for a live real-time run.
    live = {s.key: s for s in closed_loop('realtime', 2.0, record=False)}
    for run, every_sample in ((by_key, True), (sim, True), (live, False)):
        rates = (
            run['controller'].parameters['state_rate_hz'],
            run['plant'].parameters['truth_rate_hz'],
        )
        assert rates == ((0.0, 0.0) if every_sample else (100.0, 100.0)), rates
    for spec in specs:
        assert os.access(executable_path(spec.package, spec.executable), os.X_OK)


@pytest.mark.ros  # the launch API: a Jazzy install, never the unit set (no ROS)
def test_launch_description_builds_the_processes_of_the_description():
    """The installed launch file, loaded through the launch API.

    Starts exactly graph.closed_loop's processes.
    """
    # launch_ros, not launch: the symlink install puts build/actuator_bringup (with its launch/
    # folder) on sys.path, where a bare `import launch` finds that folder as a namespace package.
    pytest.importorskip(
        'launch_ros',
        reason='launch and launch_ros are not on PyPI: this runs on a Jazzy install '
        'or a checkout prepared as ../shared/real-ros2-tools.md says',
    )
    import launch
    from ament_index_python.packages import get_package_share_directory
    from launch.launch_description_sources import PythonLaunchDescriptionSource
    from launch_ros.actions import Node

    from actuator_bringup.run_description import closed_loop

    path = (
        Path(get_package_share_directory('actuator_bringup')) / 'launch' / 'closed_loop.launch.py'
    )
    description = PythonLaunchDescriptionSource(str(path)).get_launch_description(
        launch.LaunchContext()
    )
    context = launch.LaunchContext()
    for entity in description.entities:
        if isinstance(entity, launch.actions.DeclareLaunchArgument):
            entity.execute(context)
    (opaque,) = [e for e in description.entities if isinstance(e, launch.actions.OpaqueFunction)]
    # joint:=none (a driver started elsewhere) starts no joint; cia402_sim its driver and drive
    for joint in ('plant', 'none', 'cia402_sim'):
        for live_view in (False, True):
            context.launch_configurations.update(
                {
                    'duration': '5',
                    'mode': 'realtime',
                    'thread_priority': '50',
                    'live_view': str(live_view).lower(),
                    'joint': joint,
                }
            )
            actions = opaque.execute(context)
            nodes = [a for a in actions if isinstance(a, Node)]
            expected = closed_loop(
                'realtime', 5.0, thread_priority=50, live_view=live_view, joint=joint
            )
            started = [(n.node_package, n.node_executable) for n in nodes]
            assert started == [(s.package, s.executable) for s in expected], (joint, live_view)
            assert (('actuator_live_view', 'live_view') in started) is live_view
            assert (('actuator_plant', 'plant_node') in started) is (joint == 'plant'), started


@pytest.mark.ros
def test_offline_sim_cli_writes_json_and_refuses_bad_input(tmp_path):
    exe = executable_path('actuator_sim', 'offline_sim')
    out = tmp_path / 'run.json'
    proc = subprocess.run(
        [
            exe,
            'run',
            '--controller',
            'pi',
            '--duration',
            '6',
            '--json',
            str(out),
            '--traces',
            str(tmp_path / 'traces'),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    data = json.loads(out.read_text())
    metrics = data['runs'][0]['metrics']
    assert (
        metrics['samples'] == 6000
        and not metrics['diverged']
        and metrics['max_steady_error_rad'] > 0.0
    )
    trace = np.load(tmp_path / 'traces' / 'run' / 'run_pi_fast_deep_sea.npz')
    assert trace['error_rad'].shape == (6000,)
    bad = subprocess.run(
        [exe, 'run', '--duration', '-1'], capture_output=True, text=True, timeout=60
    )
    assert bad.returncode == 2 and 'duration' in bad.stderr and 'Traceback' not in bad.stderr


@pytest.mark.ros
def test_stability_check_cli_verdicts():
    exe = executable_path('actuator_sim', 'stability_check')
    stable = subprocess.run(
        [exe, '--controller', 'pp_nftsmc_eso'], capture_output=True, text=True, timeout=120
    )
    assert stable.returncode == 0 and 'STABLE' in stable.stdout
    late = subprocess.run(
        [exe, '--controller', 'pp_nftsmc_eso', '--eso-delay', '1', '--json'],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert late.returncode == 1 and json.loads(late.stdout)['stable'] is False
    smc = subprocess.run(
        [exe, '--controller', 'smc_eso'], capture_output=True, text=True, timeout=120
    )
    assert smc.returncode == 1 and 'UNSTABLE' in smc.stdout
    wrong = subprocess.run(
        [exe, '--controller', 'pi', '--set', 'k0_per_s=5'],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert wrong.returncode != 0 and 'k0_per_s' in wrong.stderr


def test_timer_trigger_is_refused_in_sim_mode(ros_process):
    proc = ros_process(
        'actuator_controller',
        'controller_node',
        ['--ros-args', '-p', 'mode:=sim', '-p', 'use_sim_time:=true', '-p', 'trigger:=timer'],
    )
    assert proc.wait(20.0) == 2 and "'trigger' = 'timer' refused in sim mode" in proc.stderr
