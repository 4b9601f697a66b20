# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Every node's contract with its user: parameters refused in one line, signals, a clean exit."""

import os
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.usefixtures('rclpy_context')

#: Managed nodes configure and activate themselves,
#: as `ros2 run ... --ros-args -p autostart:=true` does.
AUTOSTART = ['--ros-args', '-p', 'autostart:=true']


@pytest.mark.parametrize(
    'package, executable, args, names',
    [
        (
            'actuator_controller',
            'controller_node',
            ['-p', 'pp_nftsmc_eso.k0_per_s:=-5.0'],
            ['k0_per_s', '(0, 1e+06]'],
        ),
        (
            'actuator_controller',
            'controller_node',
            ['-p', 'controller:=lqr'],
            ['controller', 'pp_nftsmc_eso'],
        ),
        (
            'actuator_controller',
            'controller_node',
            ['-p', 'current_limit_a:=0.0'],
            ['current_limit_a'],
        ),
        (
            'actuator_plant',
            'plant_node',
            ['-p', 'working_condition:=custom', '-p', 'condition.temperature_c:=500.0'],
            ['temperature_c', '[-10, 80] degC'],
        ),
        (
            'actuator_plant',
            'plant_node',
            ['-p', 'drift.inertia_amplitude:=1.5'],
            ['inertia_amplitude', '[0, 0.99]'],
        ),
        ('actuator_eso', 'eso_node', ['-p', 'l3:=1.0e6'], ['l3']),
        ('actuator_eso', 'eso_node', ['-p', 'omega0_rad_s:=-60.0'], ['omega0_rad_s']),
    ],
)
def test_invalid_parameter_is_refused_with_name_and_range(
    ros_process, package, executable, args, names
):
    proc = ros_process(package, executable, ['--ros-args', *args])
    assert proc.wait(20.0) == 2
    for name in names:
        assert name in proc.stderr
    assert 'Traceback' not in proc.output


@pytest.mark.parametrize(
    'package, executable',
    [
        ('actuator_plant', 'plant_node'),
        ('actuator_eso', 'eso_node'),
        ('actuator_controller', 'controller_node'),
    ],
)
@pytest.mark.parametrize('signal_name', ['SIGINT', 'SIGTERM'])
def test_nodes_stop_cleanly_on_signals(ros_process, package, executable, signal_name):
    import signal

    proc = ros_process(package, executable, AUTOSTART)
    proc.wait_for_output(r'\]: ', timeout=20.0)
    time.sleep(0.5)
    proc.popen.send_signal(getattr(signal, signal_name))
    assert proc.wait(10.0) == 0
    assert 'Traceback' not in proc.output and 'Failed to publish' not in proc.output


def test_exit_waits_until_reliable_subscribers_have_everything(
    rclpy_context, ros_process, tmp_path
):
    """wait_for_acknowledgements (run_node's exit).

    True once a RELIABLE subscriber has all, False when it does not answer.
    """
    import os
    import signal

    from sensor_msgs.msg import JointState

    from actuator_ros.qos import control_qos
    from actuator_ros.runner import wait_for_acknowledgements
    from ros_helpers import TestNode

    recorder = ros_process(
        'actuator_bag',
        'recorder',
        ['--ros-args', '-p', f'output:={tmp_path / "bag"}', '-p', 'reliability:=reliable'],
    )
    recorder.wait_for_output('recording', timeout=20.0)
    probe = TestNode(rclpy_context, 'ack_test')
    node = probe.node
    reliable = node.create_publisher(JointState, 'joint_states', control_qos('sim'))
    probe.wait_matched(reliable)  # the recorder
    msg = JointState(name=['joint'], position=[0.0])
    try:
        for _ in range(20):
            reliable.publish(msg)
        assert wait_for_acknowledgements(node, timeout_s=5.0)
        os.kill(recorder.pid, signal.SIGSTOP)  # a subscriber that no longer answers
        try:
            for _ in range(20):
                reliable.publish(msg)
            started = time.monotonic()
            assert not wait_for_acknowledgements(node, timeout_s=1.0)
            assert time.monotonic() - started < 3.0  # bounded by the timeout, not the subscriber
        finally:
            os.kill(recorder.pid, signal.SIGCONT)
        assert wait_for_acknowledgements(node, timeout_s=10.0)  # resent and acknowledged after all
    finally:
        probe.close()
    recorder.stop()
    assert 'Traceback' not in recorder.output


@pytest.mark.parametrize(
    'package, executable, args, file_text, names',
    [
        ('actuator_controller', 'controller_node', ['-p', 'mode:=5'], None, ['mode', 'str']),
        ('actuator_plant', 'plant_node', ['-p', 'joint_name:=5'], None, ['joint_name']),
        (
            'actuator_controller',
            'controller_node',
            [],
            'actuator_controller:\n  ros__parameters:\n    controler: pi\n',
            ["'controler' is not a parameter", "did you mean 'controller'"],
        ),
        (
            'actuator_plant',
            'plant_node',
            [],
            'actuator_plant:\n  ros__parameters:\n    current_limt_a: 5.0\n',
            ["'current_limt_a'", "did you mean 'current_limit_a'"],
        ),
        (
            'actuator_eso',
            'eso_node',
            [],
            'actuator_eso: [this is: not, valid\n',
            ['ROS arguments refused'],
        ),
        (
            'actuator_controller',
            'controller_node',
            ['-p', 'timing_log:=/no/such/folder/t.npz'],
            None,
            ['timing_log', 'does not exist'],
        ),
        (
            'actuator_plant',
            'plant_node',
            ['-p', 'thread_priority:=500'],
            None,
            ['thread_priority', '[0, 99]'],
        ),
        (
            'actuator_eso',
            'eso_node',
            ['-p', 'use_sim_time:=true'],
            None,
            ["'use_sim_time' = true refused in realtime mode"],
        ),
        (
            'actuator_controller',
            'controller_node',
            ['-p', 'use_sim_time:=true'],
            None,
            ["'use_sim_time' = true refused in realtime mode"],
        ),
    ],
)
def test_every_parameter_refusal_is_one_line_and_exit_2(
    ros_process, tmp_path, package, executable, args, file_text, names
):
    extra = []
    if file_text is not None:
        path = tmp_path / 'params.yaml'
        path.write_text(file_text)
        extra = ['--params-file', str(path)]
    proc = ros_process(package, executable, ['--ros-args', *args, *extra])
    assert proc.wait(20.0) == 2
    lines = [
        line for line in proc.stderr.splitlines() if line.strip() and not line.startswith('[')
    ]
    assert len(lines) == 1, proc.stderr
    for name in names:
        assert name in lines[0], lines[0]
    assert 'Traceback' not in proc.output


def test_a_shared_parameter_file_is_accepted_with_allow_unknown_parameters(ros_process, tmp_path):
    path = tmp_path / 'shared.yaml'
    path.write_text(
        '/**:\n  ros__parameters:\n    sample_time_s: 0.001\n    only_the_plant_has_this: 1.0\n'
    )
    proc = ros_process(
        'actuator_eso',
        'eso_node',
        [
            '--ros-args',
            '--params-file',
            str(path),
            '-p',
            'autostart:=true',
            '-p',
            'allow_unknown_parameters:=true',
        ],
    )
    proc.wait_for_output(
        'ignoring parameters this node does not have: only_the_plant_has_this', timeout=20.0
    )
    proc.wait_for_output(r'\]: active', timeout=20.0)
    assert proc.stop() == 0


def _loaded(pid: int, fragment: str) -> bool:
    """Whether a file whose path contains ``fragment`` is mapped into process ``pid``."""
    try:
        return fragment in Path(f'/proc/{pid}/maps').read_text()
    except OSError:
        return False


@pytest.mark.parametrize('executable', ['plant_node', 'eso_node', 'controller_node'])
# The interpreter's own start and the console-script wrapper come first, before any code of ours
# runs; the entry point then quiets the signals (its SIGTERM handler: Python has none) while the
# node's imports run (rclpy 0.3-0.5 s). The signal goes at one of two events of those imports:
# the handler just installed, or rclpy's C extension just loaded (halfway).
@pytest.mark.parametrize('when', ['handler_installed', 'rclpy_loaded'])
def test_a_signal_while_the_node_still_imports_ends_it_quietly(ros_process, executable, when):
    import re
    import signal

    from ros_helpers import wait_for_signal_handler, wait_until

    package = {'plant_node': 'actuator_plant', 'eso_node': 'actuator_eso'}.get(
        executable, 'actuator_controller'
    )
    proc = ros_process(package, executable, AUTOSTART)
    wait_for_signal_handler(proc, signal.SIGTERM)
    if when == 'rclpy_loaded':
        assert wait_until(
            lambda: _loaded(proc.pid, 'rclpy/_rclpy_pybind11') or not proc.running,
            timeout=30.0,
            interval=0.002,
        ), proc.describe()
    said = proc.output
    proc.popen.send_signal(signal.SIGINT)
    assert not re.search(r'\]: active', said), said  # sent before the node was active
    assert proc.wait(10.0) == 0, proc.describe()
    assert 'Traceback' not in proc.output and 'KeyboardInterrupt' not in proc.output


def test_sigterm_to_bringup_stops_every_node_it_started(ros_env, tmp_path):
    import signal

    import psutil

    from actuator_bringup.supervisor import RosProcess

    runner = RosProcess.installed(
        'actuator_bringup',
        'bringup',
        ['--duration', '30', '--bags', str(tmp_path / 'b')],
        env=ros_env,
        log_dir=tmp_path,
        name='bringup',
        cwd=tmp_path,
    )
    deadline = time.monotonic() + 60.0
    children = []
    while time.monotonic() < deadline and len(children) < 4:
        children = psutil.Process(runner.pid).children(recursive=True)
        time.sleep(0.2)
    assert len(children) >= 4, runner.describe()
    time.sleep(2.0)
    os.kill(runner.pid, signal.SIGTERM)  # to the runner alone, not its group
    # docs/safety.md#signals: exit 0 after a signal
    assert runner.wait(60.0) == 0, runner.describe()
    assert not [c for c in children if c.is_running() and c.status() != psutil.STATUS_ZOMBIE]
    assert 'stopped by a signal: stopping every node' in runner.output
