# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The real ROS 2 Jazzy tools on the project: ros2 launch, run, param, lifecycle and bag.

These need ros2cli and launch_ros (and rosbag2 for ``ros2 bag``), which are not on PyPI: they run
on a machine with /opt/ros/jazzy, or in a checkout prepared as ../shared/real-ros2-tools.md says,
and skip elsewhere with that reason.
"""

import importlib.util
import os
import shutil
import signal
import subprocess
import time

import psutil
import pytest

from actuator_bringup.supervisor import RosProcess

pytestmark = pytest.mark.ros

HAVE_CLI = shutil.which('ros2') is not None and importlib.util.find_spec('ros2cli') is not None
HAVE_LAUNCH = HAVE_CLI and importlib.util.find_spec('launch_ros') is not None
NEEDS_CLI = pytest.mark.skipif(
    not HAVE_CLI,
    reason='ros2cli is not installed (not on PyPI): a Jazzy install or a '
    'checkout prepared as ../shared/real-ros2-tools.md says',
)
NEEDS_LAUNCH = pytest.mark.skipif(
    not HAVE_LAUNCH,
    reason='ros2 launch is not installed (not on PyPI): a Jazzy '
    'install or a checkout prepared as real-ros2-tools.md says',
)
NODES = [
    ('actuator_plant', 'plant_node', '/actuator_plant'),
    ('actuator_eso', 'eso_node', '/actuator_eso'),
    ('actuator_controller', 'controller_node', '/actuator_controller'),
]
EXECUTABLES = ('plant_node', 'eso_node', 'controller_node', 'recorder')
#: ``ros2 launch`` of the closed loop (its arguments follow).
LOOP = ('launch', 'actuator_bringup', 'closed_loop.launch.py')


def ros2(env, *args, timeout=60.0) -> subprocess.CompletedProcess:
    """Run one ros2 command, its output captured.

    Without the daemon: one left from another test's domain answers stale.
    """
    args = list(args)
    if args[:2] in (
        ['lifecycle', 'get'],
        ['lifecycle', 'set'],
        ['param', 'list'],
        ['param', 'describe'],
    ):
        args[2:2] = ['--no-daemon', '--spin-time', '2']  # 2 s of discovery without the daemon
    for _ in range(5):  # discovery without the daemon can miss the node on a loaded machine
        result = subprocess.run(
            ['ros2', *args], env=env, capture_output=True, text=True, timeout=timeout
        )
        if 'Node not found' not in result.stderr:
            break
    return result


def ours_running() -> list:
    """Our executables still running on this machine (none may outlive a test)."""
    found = []
    for p in psutil.process_iter(['cmdline']):
        cmd = ' '.join(p.info['cmdline'] or [])
        if any(f'/{exe}' in cmd for exe in EXECUTABLES) and 'pytest' not in cmd:
            found.append(cmd)
    return found


@NEEDS_LAUNCH
def test_ros2_launch_ends_a_sim_run_by_itself_with_every_exit_code_0(ros_env, tmp_path):
    proc = ros2(
        ros_env, *LOOP, 'duration:=3', 'mode:=sim', f'bag:={tmp_path / "bag"}', timeout=120
    )
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-3000:]
    assert 'plant_node-4 exited with code 0: ending the run' in out
    assert out.count('process has finished cleanly') == 4, out[-3000:]
    assert 'configured' in out and 'active' in out  # the lifecycle driven by launch_ros
    assert (tmp_path / 'bag' / 'metadata.yaml').is_file()
    assert not ours_running()


@NEEDS_LAUNCH
def test_ros2_launch_records_a_composed_lockstep_in_process(ros_env, tmp_path):
    """record_in_process:=true: one process and its writer, the bag whole; refused alone."""
    bag = tmp_path / 'bag'
    proc = ros2(
        ros_env,
        *LOOP,
        'duration:=3',
        'mode:=sim',
        'composed:=true',
        'record_in_process:=true',
        f'bag:={bag}',
        timeout=120,
    )
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-3000:]
    assert 'recorder-' not in out  # no recorder process
    assert '(in-process recording)' in out  # the writer's summary line
    metadata = (bag / 'metadata.yaml').read_text()
    assert 'in-process recording' in metadata and 'message_count: 3000' in metadata
    refused = ros2(ros_env, *LOOP, 'record_in_process:=true')
    assert refused.returncode != 0
    assert 'record_in_process:=true needs composed:=true' in refused.stdout + refused.stderr
    assert not ours_running()


@NEEDS_LAUNCH
def test_sigint_to_ros2_launch_leaves_no_process_behind(ros_env, tmp_path):
    launch = RosProcess(
        [
            'ros2',
            'launch',
            'actuator_bringup',
            'closed_loop.launch.py',
            f'bag:={tmp_path / "bag"}',
        ],
        env=ros_env,
        log_dir=tmp_path,
        name='launch',
    )
    launch.wait_for_output('sampling started', timeout=60.0)
    os.kill(launch.pid, signal.SIGINT)  # Ctrl-C to the launch process only
    assert launch.wait(30.0) == 0, launch.describe()
    deadline = time.monotonic() + 10.0
    while ours_running() and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not ours_running()
    assert 'Traceback' not in launch.output


@NEEDS_LAUNCH
@pytest.mark.parametrize('argument', ['record:=yes', 'plant:=maybe'])
def test_ros2_launch_refuses_a_boolean_it_cannot_read(ros_env, argument):
    proc = ros2(ros_env, *LOOP, argument)
    assert proc.returncode != 0
    assert 'yes' in proc.stdout + proc.stderr or 'maybe' in proc.stdout + proc.stderr
    assert not ours_running()


@NEEDS_CLI
@pytest.mark.parametrize('package, executable, node', NODES)
def test_ros2_param_describe_shows_a_description_for_every_parameter(
    ros_env, tmp_path, package, executable, node
):
    with RosProcess(
        ['ros2', 'run', package, executable], env=ros_env, log_dir=tmp_path, name=executable
    ):
        deadline = time.monotonic() + 30.0
        names = []
        while not names and time.monotonic() < deadline:
            listing = ros2(ros_env, 'param', 'list', node)
            names = [line.strip() for line in listing.stdout.splitlines() if line.startswith('  ')]
        assert len(names) > 5, listing.stdout + listing.stderr
        described = ros2(ros_env, 'param', 'describe', node, *names)
        blocks = described.stdout.split('Parameter name: ')[1:]
        assert len(blocks) == len(names)
        missing = [
            b.splitlines()[0]
            for b in blocks
            if 'Description: ' not in b
            or not b.split('Description: ', 1)[1].split('\n', 1)[0].strip()
        ]
        assert not missing, missing


@NEEDS_CLI
@pytest.mark.parametrize('package, executable, node', NODES)
def test_ros2_lifecycle_takes_each_node_through_its_states(
    ros_env, tmp_path, package, executable, node
):
    with RosProcess(
        ['ros2', 'run', package, executable, '--ros-args', '-p', 'use_sim_time:=false'],
        env=ros_env,
        log_dir=tmp_path,
        name=executable,
    ) as proc:
        deadline = time.monotonic() + 30.0
        state = ''
        while 'unconfigured' not in state and time.monotonic() < deadline:
            state = ros2(ros_env, 'lifecycle', 'get', node).stdout
        assert 'unconfigured' in state
        for transition, expected in (
            ('configure', 'inactive'),
            ('activate', 'active'),
            ('deactivate', 'inactive'),
            ('cleanup', 'unconfigured'),
            ('shutdown', 'finalized'),
        ):
            result = ros2(ros_env, 'lifecycle', 'set', node, transition)
            assert 'Transitioning successful' in result.stdout, (
                transition,
                result.stdout + result.stderr,
            )
            assert ros2(ros_env, 'lifecycle', 'get', node).stdout.startswith(expected)
        assert proc.stop() == 0 and 'Traceback' not in proc.output


HAVE_BAG = HAVE_CLI and (
    subprocess.run(['ros2', 'bag', '--help'], capture_output=True).returncode == 0
)


@pytest.mark.skipif(
    not HAVE_BAG,
    reason='rosbag2 (ros2 bag) is not installed: 6-45 min of C++ on 2 cores (real-ros2-tools.md)',
)
def test_ros2_bag_info_reads_a_fresh_bag(ros_env, tmp_path):
    from actuator_bringup.runner import run_closed_loop

    result = run_closed_loop(
        'case2_pp_nftsmc_eso',
        'sim',
        1.0,
        bag_root=tmp_path / 'bags',
        results_root=tmp_path / 'runs',
        quiet=True,
    )
    info = ros2(ros_env, 'bag', 'info', str(result.bag))
    assert (
        info.returncode == 0 and 'Messages:' in info.stdout and '/controller/state' in info.stdout
    )
