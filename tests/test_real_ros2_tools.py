# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The real ROS 2 Jazzy tools on the project: ros2 launch, run, param, lifecycle and bag.

These need ros2cli and launch_ros (and rosbag2 for ``ros2 bag``), which are not on PyPI: they run
on a machine with /opt/ros/jazzy, or in a checkout prepared as ../shared/real-ros2-tools.md says,
and skip elsewhere with that reason.
"""

import importlib.util
import os
import re
import shutil
import signal
import subprocess
import tempfile
import time
from collections import Counter

import psutil
import pytest
import yaml

from actuator_bringup.supervisor import RosProcess
from ros_helpers import WORKSPACE

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
#: ``ros2 launch`` of the closed loop (its arguments follow).
LOOP = ('launch', 'actuator_bringup', 'closed_loop.launch.py')


#: How launch reports a launch file's refusal: one line, and ros2 launch exits 1.
REFUSED = '[ERROR] [launch]: Caught exception in launch (see debug for traceback): '
#: The sample counts of a 3 s sim run: one per sample, and the ESO's first estimate (at its
#: restart from the first measurement) with the command answering it.
SIM_3S_COUNTS = {
    '/joint_states': 3000,
    '/plant/truth': 3000,
    '/controller/state': 3000,
    '/eso/estimate': 3001,
    '/current_command': 3001,
}


def ros2(env, *args, timeout=60.0) -> subprocess.CompletedProcess:
    """Run one ros2 command, its output captured; a hung one fails the test and leaves nothing.

    The command runs in its own session (RosProcess): on timeout it and every process it
    started get SIGINT, then SIGTERM and SIGKILL, as Ctrl-C would reach them in a terminal.
    Without the daemon (one left from another test's domain answers stale), given 2 s more of
    discovery at each new attempt.
    """
    args = list(args)
    discovers = args[:2] in (
        ['lifecycle', 'get'],
        ['lifecycle', 'set'],
        ['param', 'list'],
        ['param', 'describe'],
    )
    for attempt in range(5):  # discovery without the daemon can miss the node on a loaded machine
        spin = ['--no-daemon', '--spin-time', str(2 * (attempt + 1))] if discovers else []
        command = ['ros2', *args[:2], *spin, *args[2:]]
        with tempfile.TemporaryDirectory(prefix='ros2-') as logs:
            proc = RosProcess(command, env=env, log_dir=logs, name='ros2')
            try:
                code = proc.wait(timeout)
            except TimeoutError as exc:
                raise AssertionError(f'hung, ended by {proc.stopped_by}: {exc}') from None
            result = subprocess.CompletedProcess(proc.cmd, code, proc.stdout, proc.stderr)
        if 'Node not found' not in result.stderr:
            break
    return result


def ours_running(env) -> list:
    """Return this checkout's executables still running on the test's ROS domain.

    None may outlive a test. By the domain: other checkouts and other tests on the same machine
    run the same executables.
    """
    install = f'{WORKSPACE / "install"}/'
    found = []
    for p in psutil.process_iter(['cmdline', 'environ']):
        cmd = ' '.join(p.info['cmdline'] or [])
        domain = (p.info['environ'] or {}).get('ROS_DOMAIN_ID')
        if install in cmd and domain == env['ROS_DOMAIN_ID']:
            found.append(cmd)
    return found


def lines(out: str) -> list:
    """Return the output's lines with each node's log stamp taken out (they differ per run)."""
    return [re.sub(r'\] \[\d+\.\d+\] \[', '] [', line) for line in out.splitlines()]


def topic_counts(bag) -> dict:
    """Return the bag's message count per topic, /diagnostics left out (its rate is wall time)."""
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    return {
        t['topic_metadata']['name']: t['message_count']
        for t in info['topics_with_message_count']
        if t['topic_metadata']['name'] != '/diagnostics'
    }


def lifecycle_lines(out: str) -> Counter:
    """Return how often each node said it was configured and active."""
    pattern = r'^\S+ \[INFO\] \[(actuator_\w+)\]: (configured|active)$'
    return Counter(re.findall(pattern, '\n'.join(lines(out)), re.M))


def finished_cleanly(out: str) -> list:
    """Return the executables launch saw finish cleanly, sorted."""
    return sorted(re.findall(r'^\[INFO\] \[(\w+)-\d\]: process has finished cleanly', out, re.M))


#: The processes of a recorded run of the plant's loop, sorted.
LOOP_PROCESSES = ['controller_node', 'eso_node', 'plant_node', 'recorder']
#: Each managed node of the plant's loop configures and activates itself once.
SELF_STARTED = Counter(
    {(node[1:], state): 1 for _, _, node in NODES for state in ('configured', 'active')}
)


@NEEDS_LAUNCH
def test_ros2_launch_ends_a_sim_run_by_itself_with_every_exit_code_0(ros_env, tmp_path):
    """The nodes start themselves (autostart); the plant's end ends the run, every count exact."""
    bag = tmp_path / 'bag'
    proc = ros2(ros_env, *LOOP, 'duration:=3', 'mode:=sim', f'bag:={bag}', timeout=120)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-3000:]
    assert '[INFO] [launch.user]: plant_node-4 exited with code 0: ending the run' in lines(out)
    assert finished_cleanly(out) == LOOP_PROCESSES, out
    assert lifecycle_lines(out) == SELF_STARTED
    assert 'ERROR' not in out, out[-3000:]  # a clean run prints none
    assert topic_counts(bag) == SIM_3S_COUNTS
    assert not ours_running(ros_env)


@NEEDS_LAUNCH
def test_ros2_launch_exits_1_when_the_joint_fails(ros_env, tmp_path):
    """A joint that exits non-zero (here refusing a parameter) makes ros2 launch exit 1."""
    params = tmp_path / 'params.yaml'
    params.write_text('actuator_plant:\n  ros__parameters:\n    lockstep_timeout_s: 0.0\n')
    proc = ros2(
        ros_env, *LOOP, 'duration:=3', 'mode:=sim', 'record:=false', f'params_file:={params}'
    )
    out = lines(proc.stdout + proc.stderr)
    assert proc.returncode == 1, out[-40:]
    assert '[INFO] [launch.user]: ERROR: plant_node-3 exited with code 2: ending the run' in out
    assert [line for line in out if line.startswith('[ERROR] [launch]')] == [
        REFUSED + 'the run failed: plant_node-3 exited with code 2'
    ]
    assert not ours_running(ros_env)


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
    started = re.findall(r'^\[INFO\] \[([\w-]+)\]: process started', out, re.M)
    assert started == ['loop_container-1']  # no recorder process
    assert lifecycle_lines(out) == SELF_STARTED
    assert '[INFO] [launch.user]: loop_container-1 exited with code 0: ending the run' in lines(
        out
    )
    summary = [
        line for line in out.splitlines() if line.startswith('[loop_container-1] recorder:')
    ]
    assert len(summary) == 1 and summary[0].endswith(' (in-process recording)'), summary
    assert topic_counts(bag) == SIM_3S_COUNTS
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['custom_data']['recorder'].startswith('actuator_bag in-process recording')
    refused = ros2(ros_env, *LOOP, 'record_in_process:=true')
    assert refused.returncode == 1
    assert REFUSED + 'record_in_process:=true needs composed:=true (and mode:=sim)' in lines(
        refused.stdout + refused.stderr
    )
    assert not ours_running(ros_env)


@NEEDS_LAUNCH
def test_sigint_to_ros2_launch_leaves_no_process_behind(ros_env, tmp_path):
    """Ctrl-C to the launch process alone ends every node, exit 0.

    Started with SIGINT ignored, as a background job of a non-interactive shell would start it.
    """
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        launch = RosProcess(
            ['ros2', *LOOP, f'bag:={tmp_path / "bag"}'],
            env=ros_env,
            log_dir=tmp_path,
            name='launch',
        )
    finally:
        signal.signal(signal.SIGINT, previous)
    launch.wait_for_output('sampling started', timeout=60.0)
    os.kill(launch.pid, signal.SIGINT)  # Ctrl-C to the launch process only
    assert launch.wait(30.0) == 0, launch.describe()
    out = lines(launch.output)
    assert '[WARNING] [launch]: user interrupted with ctrl-c (SIGINT)' in out
    assert finished_cleanly(launch.output) == LOOP_PROCESSES
    assert not ours_running(ros_env)
    assert 'Traceback' not in launch.output


@NEEDS_LAUNCH
@pytest.mark.parametrize(
    'argument, refusal',
    [
        ('record:=yes', "record must be true or false, not 'yes'"),
        ('composed:=maybe', "composed must be true or false, not 'maybe'"),
        ('duration:=-1', 'duration = -1 is outside [0, 3600] s'),
        ('eds_file:=drive.eds', 'eds_file is for a CiA 402 joint, not joint plant'),
    ],
)
def test_ros2_launch_refuses_an_argument_it_cannot_read_in_one_line(ros_env, argument, refusal):
    proc = ros2(ros_env, *LOOP, argument)
    out = lines(proc.stdout + proc.stderr)
    assert proc.returncode == 1
    assert [line for line in out if line.startswith('[ERROR]')] == [REFUSED + refusal]
    assert not ours_running(ros_env)


@NEEDS_LAUNCH
def test_ros2_launch_refuses_a_parameter_file_for_a_node_the_run_does_not_have(ros_env, tmp_path):
    params = tmp_path / 'params.yaml'
    params.write_text('actuator_planner:\n  ros__parameters:\n    gain: 1.0\n')
    proc = ros2(ros_env, *LOOP, 'mode:=sim', f'params_file:={params}')
    out = lines(proc.stdout + proc.stderr)
    assert proc.returncode == 1
    assert [line for line in out if line.startswith('[ERROR]')] == [
        REFUSED + f'params_file {params}: no node actuator_planner in this run (its nodes: '
        'actuator_controller, actuator_eso, actuator_plant, recorder)'
    ]
    assert not ours_running(ros_env)


@NEEDS_LAUNCH
def test_ros2_launch_autostart_false_leaves_the_nodes_to_ros2_lifecycle(ros_env, tmp_path):
    """autostart:=false: each node waits unconfigured; ros2 lifecycle set starts the run."""
    launch = RosProcess(
        ['ros2', *LOOP, 'mode:=sim', 'duration:=1', 'record:=false', 'autostart:=false'],
        env=ros_env,
        log_dir=tmp_path,
        name='launch',
    )
    with launch:
        launch.wait_for_output(r'plant_node-3\]: process started', timeout=60.0)
        nodes = [node for _, _, node in NODES]
        assert [ros2(ros_env, 'lifecycle', 'get', n).stdout for n in nodes] == [
            'unconfigured [1]\n'
        ] * 3
        for node in nodes[::-1]:  # the controller, the ESO, then the plant, which then samples
            for transition in ('configure', 'activate'):
                result = ros2(ros_env, 'lifecycle', 'set', node, transition)
                assert result.stdout == 'Transitioning successful\n', (node, transition, result)
        assert launch.wait(60.0) == 0, launch.describe()
    out = lines(launch.output)
    assert '[INFO] [launch.user]: plant_node-3 exited with code 0: ending the run' in out
    outside = re.findall(
        r"\[(actuator_\w+)\]: lifecycle transition '(\w+)' requested from outside", launch.output
    )
    assert Counter(outside) == Counter(
        {(n[1:], t): 1 for n in nodes for t in ('configure', 'activate')}
    )
    assert not ours_running(ros_env)


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
        common = {  # every managed node's (actuator_ros.node.ManagedNode), beside its own
            'allow_unknown_parameters',
            'autostart',
            'cpu_affinity',
            'executor',
            'nice',
            'thread_priority',
            'use_sim_time',
        }
        assert common <= set(names), listing.stdout + listing.stderr
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
        while state != 'unconfigured [1]\n' and time.monotonic() < deadline:
            state = ros2(ros_env, 'lifecycle', 'get', node).stdout
        assert state == 'unconfigured [1]\n'
        for transition, expected in (
            ('configure', 'inactive [2]'),
            ('activate', 'active [3]'),
            ('deactivate', 'inactive [2]'),
            ('cleanup', 'unconfigured [1]'),
            ('shutdown', 'finalized [4]'),
        ):
            result = ros2(ros_env, 'lifecycle', 'set', node, transition)
            assert result.stdout == 'Transitioning successful\n', (
                transition,
                result.stdout + result.stderr,
            )
            assert ros2(ros_env, 'lifecycle', 'get', node).stdout == expected + '\n'
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
