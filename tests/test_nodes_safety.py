# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Each node on its own against bad input: refused and logged, safe output, clean shutdown."""

import math
import os
import time

import pytest

from actuator_core.timing import stamp_to_ns
from actuator_ros.conversions import ns_to_stamp

pytestmark = pytest.mark.usefixtures('rclpy_context')

#: Managed nodes configure and activate themselves,
#: as `ros2 run ... --ros-args -p autostart:=true` does.
AUTOSTART = ['--ros-args', '-p', 'autostart:=true']


class Harness:
    """A test-side node that publishes into and records from the node under test."""

    def __init__(self, context):
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        from actuator_ros.qos import control_qos
        from actuator_msgs.msg import ControllerState, CurrentCommand, PlantTruth, StateEstimate
        from sensor_msgs.msg import JointState

        self.node = Node('harness', context=context)
        qos = control_qos('realtime')
        self.joint = self.node.create_publisher(JointState, 'joint_states', qos)
        self.estimate = self.node.create_publisher(StateEstimate, 'eso/estimate', qos)
        self.qos = qos
        self.command = (
            None  # created by the first send_command: another publisher on it stops a controller
        )
        self.got = {'command': [], 'state': [], 'estimate': [], 'truth': []}
        self.node.create_subscription(
            CurrentCommand, 'current_command', self.got['command'].append, qos
        )
        self.node.create_subscription(
            ControllerState, 'controller/state', self.got['state'].append, qos
        )
        self.node.create_subscription(
            StateEstimate, 'eso/estimate', self.got['estimate'].append, qos
        )
        self.node.create_subscription(PlantTruth, 'plant/truth', self.got['truth'].append, qos)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.types = {
            'JointState': JointState,
            'StateEstimate': StateEstimate,
            'CurrentCommand': CurrentCommand,
        }

    def spin(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.005)

    def wait_for(self, predicate, timeout: float = 20.0, what: str = '') -> None:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate():
                return
            self.executor.spin_once(timeout_sec=0.01)
        raise AssertionError(f'timed out waiting for {what}')

    def send_sample(
        self, stamp_ns: int, position: float, velocity=0.0, disturbance=0.0, estimate=True
    ) -> None:
        js = self.types['JointState'](name=['joint'], position=[position])
        js.header.stamp = ns_to_stamp(stamp_ns)
        if estimate:
            est = self.types['StateEstimate'](
                velocity_rad_s=velocity, disturbance_rad_s2=disturbance
            )
            est.header.stamp = ns_to_stamp(stamp_ns)
            self.estimate.publish(est)
            self.spin(0.002)
        self.joint.publish(js)

    def send_command(self, stamp_ns: int, current: float) -> None:
        if self.command is None:
            self.command = self.node.create_publisher(
                self.types['CurrentCommand'], 'current_command', self.qos
            )
            self.spin(0.3)  # discovery before the first command
        cmd = self.types['CurrentCommand'](current_a=current)
        cmd.header.stamp = ns_to_stamp(stamp_ns)
        self.command.publish(cmd)


@pytest.fixture
def harness(rclpy_context):
    h = Harness(rclpy_context)
    yield h
    h.executor.shutdown()
    h.node.destroy_node()


def _now_ns(harness) -> int:
    return harness.node.get_clock().now().nanoseconds


def test_controller_refuses_nan_and_goes_safe_on_stale_inputs(harness, ros_process):
    from actuator_msgs.msg import ControllerState

    ctrl = ros_process(
        'actuator_controller',
        'controller_node',
        [
            '--ros-args',
            '-p',
            'autostart:=true',
            '-p',
            'measurement_timeout_s:=0.05',
            '-p',
            'estimate_timeout_s:=0.05',
            '-p',
            'controller:=nftsmc_eso',
        ],
    )
    harness.wait_for(
        lambda: harness.node.count_subscribers('joint_states') >= 1, what='controller subscription'
    )
    harness.spin(0.5)
    period = 5_000_000
    t = _now_ns(harness)
    for k in range(40):  # valid pairs at 200 Hz
        harness.send_sample(t + k * period, 0.0)
        harness.spin(0.003)
    harness.wait_for(
        lambda: any(s.status == ControllerState.STATUS_OK for s in harness.got['state']),
        what='a controlled sample',
    )
    ok = [c for c in harness.got['command'] if not c.safe_stop]
    assert ok and all(math.isfinite(c.current_a) and abs(c.current_a) <= 20.0 for c in ok)

    t += 40 * period  # the next sample, later than every stamp sent so far
    harness.send_sample(t, float('nan'))  # NaN measurement: refused, 0 A
    harness.wait_for(
        lambda: any(
            s.status == ControllerState.STATUS_INVALID_INPUT for s in harness.got['state']
        ),
        what='invalid-input status',
    )
    bad = [c for c in harness.got['command'] if c.header.stamp == ns_to_stamp(t)]
    assert bad and bad[-1].current_a == 0.0 and bad[-1].safe_stop

    harness.got['state'].clear()  # silence: stale measurement, 0 A
    harness.wait_for(
        lambda: any(
            s.status == ControllerState.STATUS_STALE_MEASUREMENT for s in harness.got['state']
        ),
        what='stale-measurement status',
    )
    harness.got['command'].clear()
    harness.spin(0.2)
    assert harness.got['command'], 'the watchdog keeps commanding while stale'
    assert all(c.current_a == 0.0 and c.safe_stop for c in harness.got['command'])

    harness.got['state'].clear()  # measurements without estimates: stale estimate
    t = _now_ns(harness)  # fresh stamps (a new grid: the controller resyncs)
    for k in range(60):
        harness.send_sample(t + k * period, 0.0, estimate=False)
        harness.spin(0.004)
    assert any(s.status == ControllerState.STATUS_STALE_ESTIMATE for s in harness.got['state'])
    assert 'measurement refused' in ctrl.output and 'stale' in ctrl.output
    assert ctrl.stop() == 0 and 'Traceback' not in ctrl.output


def test_controller_corrects_an_estimate_integrated_with_a_substituted_current(
    harness, ros_process
):
    """x_hat(k) says it integrated 1 A less than the controller commanded for k-1.

    x2_hat gains 1 A * gain.
    """
    ctrl = ros_process(
        'actuator_controller',
        'controller_node',  # long timeouts: no watchdog command between
        [
            '--ros-args',
            '-p',
            'autostart:=true',
            '-p',
            'controller:=nftsmc_eso',
            '-p',
            'measurement_timeout_s:=5.0',
            '-p',
            'estimate_timeout_s:=5.0',
        ],
    )
    harness.wait_for(
        lambda: harness.node.count_subscribers('joint_states') >= 1, what='controller subscription'
    )
    harness.spin(0.5)
    t, period = _now_ns(harness), 1_000_000
    harness.send_sample(t, 0.0)
    harness.wait_for(
        lambda: any(c.header.stamp == ns_to_stamp(t) for c in harness.got['command']),
        what='command 0',
    )
    commanded = next(
        c.current_a for c in harness.got['command'] if c.header.stamp == ns_to_stamp(t)
    )
    for k, (input_ns, input_current) in enumerate(
        [(t, commanded - 1.0), (t + period, None)], start=1
    ):
        est = harness.types['StateEstimate'](
            velocity_rad_s=0.25, disturbance_rad_s2=0.0, input_current_gain=0.5
        )
        est.header.stamp, est.input_stamp = ns_to_stamp(t + k * period), ns_to_stamp(input_ns)
        if input_current is None:  # sample 1's estimate integrated what was commanded: left alone
            input_current = next(
                c.current_a
                for c in harness.got['command']
                if c.header.stamp == ns_to_stamp(t + period)
            )
        est.input_current_a = input_current
        harness.estimate.publish(est)
        harness.spin(0.01)
        js = harness.types['JointState'](name=['joint'], position=[0.0])
        js.header.stamp = est.header.stamp
        harness.joint.publish(js)
        harness.wait_for(
            lambda: any(s.header.stamp == est.header.stamp for s in harness.got['state']),
            what=f'state {k}',
        )
    states = {s.header.stamp.nanosec: s for s in harness.got['state']}
    assert states[ns_to_stamp(t + period).nanosec].estimated_velocity_rad_s == pytest.approx(
        0.25 + 0.5
    )
    assert states[ns_to_stamp(t + 2 * period).nanosec].estimated_velocity_rad_s == pytest.approx(
        0.25
    )
    assert ctrl.stop() == 0


def test_controller_latches_safe_stop_beyond_following_error(harness, ros_process):
    from actuator_msgs.msg import ControllerState

    ctrl = ros_process(
        'actuator_controller',
        'controller_node',
        [
            '--ros-args',
            '-p',
            'autostart:=true',
            '-p',
            'following_error_limit_rad:=0.1',
            '-p',
            'measurement_timeout_s:=0.05',
            '-p',
            'estimate_timeout_s:=0.05',
        ],
    )
    harness.wait_for(
        lambda: harness.node.count_subscribers('joint_states') >= 1, what='controller subscription'
    )
    harness.spin(0.5)
    t = _now_ns(harness)
    harness.send_sample(t, 0.0)  # the reference starts where the joint is
    harness.send_sample(t + 5_000_000, 0.5)  # 0.5 rad off the reference 5 ms later
    harness.wait_for(
        lambda: any(s.status == ControllerState.STATUS_LATCHED for s in harness.got['state']),
        what='latched safe stop',
    )
    harness.send_sample(t + 10_000_000, 0.0)  # even a good sample stays at 0 A
    harness.wait_for(lambda: len(harness.got['command']) >= 3, what='third command')
    assert all(c.current_a == 0.0 and c.safe_stop for c in harness.got['command'][1:])
    assert 'following_error_limit_rad' in ctrl.output
    assert ctrl.stop() == 0


def test_plant_refuses_bad_commands_and_drops_to_zero_when_commands_stop(harness, ros_process):
    plant = ros_process(
        'actuator_plant',
        'plant_node',
        [
            '--ros-args',
            '-p',
            'autostart:=true',
            '-p',
            'command_timeout_s:=0.02',
            '-p',
            'current_limit_a:=25.0',
        ],
    )
    harness.wait_for(lambda: len(harness.got['truth']) > 10, what='plant samples')

    def held_current():
        harness.got['truth'].clear()
        harness.wait_for(lambda: len(harness.got['truth']) > 3, what='truth')
        return harness.got['truth'][-1].current_a

    def sample_ns():  # a command answers a sample the plant published
        return stamp_to_ns(harness.got['truth'][-1].header.stamp)

    for _ in range(20):
        harness.send_command(sample_ns(), 2.0)
        harness.spin(0.002)
    assert held_current() == 2.0
    harness.spin(0.1)  # commands stopped: 0 A after the timeout
    assert held_current() == 0.0
    for bad in (float('nan'), float('inf'), 1.0e6):
        for _ in range(5):
            harness.send_command(sample_ns(), 2.0)
            harness.spin(0.002)
        harness.send_command(sample_ns(), bad)
        harness.spin(0.003)
        assert held_current() == 0.0, bad  # never integrated: zero instead
    assert 'refused' in plant.output
    assert plant.stop() == 0 and 'Traceback' not in plant.output


def test_eso_refuses_non_finite_measurements_and_commands(harness, ros_process):
    eso = ros_process('actuator_eso', 'eso_node', AUTOSTART)
    harness.wait_for(
        lambda: harness.node.count_subscribers('joint_states') >= 1, what='eso subscription'
    )
    harness.spin(0.5)
    t = _now_ns(harness)
    period = 1_000_000
    for k in range(20):
        harness.send_sample(t + k * period, 0.01, estimate=False)
        harness.send_command(t + k * period, float('nan') if k == 5 else 1.0)
        harness.spin(0.002)
    harness.send_sample(t + 20 * period, float('nan'), estimate=False)
    harness.spin(0.3)
    assert len(harness.got['estimate']) >= 15
    assert all(
        math.isfinite(e.velocity_rad_s) and math.isfinite(e.disturbance_rad_s2)
        for e in harness.got['estimate']
    )
    assert all(math.isfinite(e.input_current_a) for e in harness.got['estimate'])
    assert any(e.current_substituted for e in harness.got['estimate'])  # the NaN command's sample
    assert 'refused' in eso.output
    assert eso.stop() == 0


def test_eso_repairs_its_state_when_a_command_comes_late(harness, ros_process):
    """Sample 10's command comes after y(11).

    The step is substituted, then repaired to the exact pair.
    """
    from actuator_eso.observer import EsoGains, eso_step

    eso = ros_process('actuator_eso', 'eso_node', AUTOSTART)
    harness.wait_for(
        lambda: (
            harness.node.count_subscribers('joint_states') >= 1
            and harness.node.count_subscribers('current_command') >= 1
        ),
        what='eso subscriptions',
    )
    harness.spin(0.5)
    t, period = _now_ns(harness), 1_000_000
    ys = [0.001 * k for k in range(16)]
    us = [2.0 * math.sin(k) for k in range(16)]
    for k in range(16):
        harness.send_sample(t + k * period, ys[k], estimate=False)
        harness.spin(0.01)
        if k == 11:
            harness.send_command(t + 10 * period, us[10])  # late: y(11) is already in
            harness.spin(0.01)
        if k != 10:
            harness.send_command(t + k * period, us[k])
            harness.spin(0.01)
    harness.spin(0.3)
    by_stamp = {
        e.header.stamp.sec * 1_000_000_000 + e.header.stamp.nanosec: e
        for e in harness.got['estimate']
    }
    exact, gains = [(0.0, 0.0, 0.0)], EsoGains()
    for k in range(15):
        exact.append(eso_step(*exact[-1], ys[k], us[k], 1e-3, gains))
    substituted = by_stamp[t + 11 * period]
    assert substituted.current_substituted and substituted.input_current_a == pytest.approx(us[9])
    # The controller's correction of the estimate it received ...
    corrected = (
        substituted.velocity_rad_s
        + (us[10] - substituted.input_current_a) * substituted.input_current_gain
    )
    assert corrected == pytest.approx(exact[11][1], rel=1e-9, abs=1e-12)
    assert substituted.velocity_rad_s != pytest.approx(exact[11][1], rel=1e-6)
    # ... and the observer's own repair: every later estimate is the exact one.
    last = by_stamp[t + 15 * period]
    assert not last.current_substituted
    assert (last.position_rad, last.velocity_rad_s, last.disturbance_rad_s2) == pytest.approx(
        exact[15], rel=1e-9, abs=1e-12
    )
    assert eso.stop() == 0
    assert 'repaired when the command came late: 1' in eso.output


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

    from rclpy.node import Node

    from actuator_ros.qos import control_qos
    from actuator_ros.runner import wait_for_acknowledgements
    from sensor_msgs.msg import JointState

    recorder = ros_process(
        'actuator_bag',
        'recorder',
        ['--ros-args', '-p', f'output:={tmp_path / "bag"}', '-p', 'reliability:=reliable'],
    )
    recorder.wait_for_output('recording', timeout=20.0)
    node = Node('ack_test', context=rclpy_context)
    reliable = node.create_publisher(JointState, 'joint_states', control_qos('sim'))
    deadline = time.monotonic() + 20.0
    while reliable.get_subscription_count() < 1:
        assert time.monotonic() < deadline, 'the recorder never matched'
        time.sleep(0.05)
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
        node.destroy_node()
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


def test_lifecycle_transitions_and_parameters_read_at_configure(harness, ros_process):
    """Take the controller through its states with the lifecycle services.

    configure -> activate -> deactivate -> cleanup -> shutdown; no command unless active;
    parameters can be set only while unconfigured.
    """
    from lifecycle_msgs.msg import Transition
    from lifecycle_msgs.srv import ChangeState, GetState
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters

    ctrl = ros_process(
        'actuator_controller',
        'controller_node',
        [
            '--ros-args',
            '-p',
            'controller:=nftsmc_eso',
            '-p',
            'measurement_timeout_s:=5.0',
            '-p',
            'estimate_timeout_s:=5.0',
        ],
    )
    node = harness.node
    clients = {
        name: node.create_client(srv, f'/actuator_controller/{name}')
        for name, srv in (
            ('get_state', GetState),
            ('change_state', ChangeState),
            ('set_parameters', SetParameters),
        )
    }
    for client in clients.values():
        harness.wait_for(client.service_is_ready, what=f'{client.srv_name}')

    def call(name, request):
        future = clients[name].call_async(request)
        harness.wait_for(future.done, what=f'{name} answer')
        return future.result()

    def state():
        return call('get_state', GetState.Request()).current_state.label

    def change(transition):
        return call(
            'change_state', ChangeState.Request(transition=Transition(id=transition))
        ).success

    def set_gain(value):
        p = Parameter(
            name='nftsmc_eso.k1',
            value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value),
        )
        return call('set_parameters', SetParameters.Request(parameters=[p])).results[0]

    def samples(n, start):
        for k in range(n):
            harness.send_sample(start + k * 1_000_000, 0.0)
            harness.spin(0.002)

    t = _now_ns(harness)
    assert state() == 'unconfigured'
    samples(20, t)
    assert change(Transition.TRANSITION_CONFIGURE) and state() == 'inactive'
    samples(20, t + 20_000_000)
    harness.spin(0.2)
    assert harness.got['command'] == []  # not active: no command at all
    refused = set_gain(500.0)
    assert not refused.successful and 'read at configure' in refused.reason
    assert change(Transition.TRANSITION_ACTIVATE) and state() == 'active'
    samples(20, t + 40_000_000)
    harness.wait_for(
        lambda: any(not c.safe_stop for c in harness.got['command']), what='commands while active'
    )
    harness.got['command'].clear()
    assert change(Transition.TRANSITION_DEACTIVATE) and state() == 'inactive'
    harness.wait_for(lambda: harness.got['command'], what='the safe-stop command of deactivate')
    assert all(c.safe_stop and c.current_a == 0.0 for c in harness.got['command'])
    assert change(Transition.TRANSITION_CLEANUP) and state() == 'unconfigured'
    assert set_gain(500.0).successful  # unconfigured: accepted, read at the next configure
    assert change(Transition.TRANSITION_CONFIGURE) and state() == 'inactive'
    assert change(Transition.TRANSITION_INACTIVE_SHUTDOWN) and state() == 'finalized'
    assert ctrl.stop() == 0 and 'Traceback' not in ctrl.output


@pytest.mark.parametrize('executable', ['plant_node', 'eso_node', 'controller_node'])
# The interpreter's own start and the console-script wrapper take the first 0.1-0.15 s here, before
# any code of ours runs; the entry point then quiets the signals while rclpy imports (0.3-0.5 s).
@pytest.mark.parametrize('delay_s', [0.3, 0.6])
def test_a_signal_while_the_node_still_imports_ends_it_quietly(ros_process, executable, delay_s):
    import signal

    package = {'plant_node': 'actuator_plant', 'eso_node': 'actuator_eso'}.get(
        executable, 'actuator_controller'
    )
    proc = ros_process(package, executable, AUTOSTART)
    time.sleep(delay_s)  # rclpy is being imported (0.3-0.5 s)
    proc.popen.send_signal(signal.SIGINT)
    assert proc.wait(10.0) == 0
    assert 'Traceback' not in proc.output and 'KeyboardInterrupt' not in proc.output


def test_sigterm_to_bringup_stops_every_node_it_started(ros_env, tmp_path):
    import signal

    import psutil

    from actuator_tools.supervisor import RosProcess

    runner = RosProcess.installed(
        'actuator_tools',
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
    runner.wait(60.0)
    assert not [c for c in children if c.is_running() and c.status() != psutil.STATUS_ZOMBIE]
    assert 'stopped by a signal: stopping every node' in runner.output
