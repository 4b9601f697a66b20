# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Each node on its own against bad input: refused and logged, safe output, clean shutdown."""

import math

import pytest

from actuator_core.timing import stamp_to_ns
from actuator_ros.conversions import ns_to_stamp

pytestmark = pytest.mark.usefixtures('rclpy_context')

#: Managed nodes configure and activate themselves,
#: as `ros2 run ... --ros-args -p autostart:=true` does.
AUTOSTART = ['--ros-args', '-p', 'autostart:=true']
#: The NFTSMC-ESO controller with 5 s input timeouts: its watchdog sends nothing during a test.
NFTSMC_QUIET_WATCHDOG = [
    '--ros-args',
    '-p',
    'controller:=nftsmc_eso',
    '-p',
    'measurement_timeout_s:=5.0',
    '-p',
    'estimate_timeout_s:=5.0',
]


from ros_helpers import LATCHING_CONTROLLER_ARGS, Harness, run_off  # noqa: E402
from ros_helpers import now_ns as _now_ns  # noqa: E402


@pytest.fixture
def harness(rclpy_context):
    h = Harness(rclpy_context)
    yield h
    h.close()


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
    harness.wait_matched(harness.joint)  # the controller's readers matched: nothing is lost
    harness.wait_matched(harness.estimate)
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
    harness.send_sample(t, float('nan'), estimate=False)  # NaN: refused before its stamp
    harness.spin(0.02)
    assert not [c for c in harness.got['command'] if c.header.stamp == ns_to_stamp(t)]
    harness.send_sample(t, 0.0)  # the same stamp, a good value: the NaN took nothing
    harness.wait_for(
        lambda: any(
            s.header.stamp == ns_to_stamp(t)
            and s.status in (ControllerState.STATUS_OK, ControllerState.STATUS_RECOVERING)
            for s in harness.got['state']
        ),
        what='the genuine sample of the NaN stamp controlled',
    )

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
    ctrl = ros_process(  # long timeouts: no watchdog command between
        'actuator_controller', 'controller_node', NFTSMC_QUIET_WATCHDOG + ['-p', 'autostart:=true']
    )
    harness.wait_matched(harness.joint)  # the controller's readers matched: nothing is lost
    harness.wait_matched(harness.estimate)
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
            velocity_rad_s=0.25, disturbance_rad_s2=0.0, input_current_gain=0.05
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
        0.25 + 0.05
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
        LATCHING_CONTROLLER_ARGS,
    )
    harness.wait_matched(harness.joint)  # the controller's readers matched: nothing is lost
    harness.wait_matched(harness.estimate)
    harness.spin(0.5)
    t = _now_ns(harness)
    run_off(harness, t)  # the reference starts where the joint is
    harness.wait_for(
        lambda: any(s.status == ControllerState.STATUS_LATCHED for s in harness.got['state']),
        what='latched safe stop',
    )
    first = next(
        stamp_to_ns(s.header.stamp)
        for s in harness.got['state']
        if s.status == ControllerState.STATUS_LATCHED
    )
    harness.send_sample(t + 8_000_000, 1.25e-3 * 72)  # even a good sample stays at 0 A
    harness.wait_for(lambda: len(harness.got['command']) >= 9, what='ninth command')
    after = [c for c in harness.got['command'] if stamp_to_ns(c.header.stamp) >= first]
    assert len(after) >= 3 and all(c.current_a == 0.0 and c.safe_stop for c in after), [
        (c.current_a, c.safe_stop) for c in after
    ]
    assert 'following_error_limit_rad' in ctrl.output
    # The latch holds until cleanup and configure (docs/safety.md#latch): deactivate and activate
    # alone keep it (fresh samples answered LATCHED, 0 A with the brake); deactivate, cleanup,
    # configure, activate through the lifecycle services release it: fresh samples are
    # controlled again, commands without safe_stop, no LATCHED state.
    position = 1.25e-3 * 72  # where the joint was left: the reference restarts there

    def fresh_samples():
        harness.got['state'].clear()
        harness.got['command'].clear()
        fresh = _now_ns(harness)
        stamps = [fresh + k * 1_000_000 for k in range(10)]
        for stamp in stamps:
            harness.send_sample(stamp, position)
            harness.spin(0.002)
        return stamps

    for label in ('deactivate', 'activate'):
        assert harness.transition('actuator_controller', label), label
    stamps = fresh_samples()
    harness.wait_for(
        lambda: any(stamp_to_ns(s.header.stamp) == stamps[-1] for s in harness.got['state']),
        what='the state of the last fresh sample after deactivate and activate',
    )
    answered = [c for c in harness.got['command'] if stamp_to_ns(c.header.stamp) in stamps]
    assert answered and all(c.current_a == 0.0 and c.safe_stop for c in answered)
    assert all(
        s.status == ControllerState.STATUS_LATCHED
        for s in harness.got['state']
        if stamp_to_ns(s.header.stamp) in stamps
    ), [s.status for s in harness.got['state']]
    for label in ('deactivate', 'cleanup', 'configure', 'activate'):
        assert harness.transition('actuator_controller', label), label
    assert harness.lifecycle_state('actuator_controller') == 'active'
    stamps = fresh_samples()
    harness.wait_for(
        lambda: any(
            stamp_to_ns(c.header.stamp) in stamps and not c.safe_stop
            for c in harness.got['command']
        ),
        what='a command without safe_stop for a fresh sample after cleanup and configure',
    )
    after_reset = [s for s in harness.got['state'] if stamp_to_ns(s.header.stamp) in stamps]
    assert after_reset and not any(
        s.status == ControllerState.STATUS_LATCHED for s in after_reset
    ), [s.status for s in after_reset]
    assert any(
        s.status in (ControllerState.STATUS_OK, ControllerState.STATUS_RECOVERING)
        for s in after_reset
    ), [s.status for s in after_reset]
    assert ctrl.stop() == 0 and 'Traceback' not in ctrl.output


def test_plant_refuses_bad_commands_and_drops_to_zero_when_commands_stop(harness, ros_process):
    plant = ros_process(
        'actuator_plant',
        'plant_node',
        [
            '--ros-args',
            '-p',
            'autostart:=true',
            '-p',
            'command_timeout_s:=0.1',
            '-p',
            'current_limit_a:=25.0',
        ],
    )
    harness.wait_for(lambda: len(harness.got['truth']) > 10, what='plant samples')

    def held_current():
        harness.got['truth'].clear()
        harness.wait_for(lambda: len(harness.got['truth']) > 3, what='truth')
        return harness.got['truth'][-1].current_a

    def sample_ns_of(truth):
        return stamp_to_ns(truth.header.stamp)

    def sample_ns():  # a command answers a sample the plant published
        return sample_ns_of(harness.got['truth'][-1])

    flowing = len(harness.got['truth'])
    for _ in range(20):
        harness.send_command(sample_ns(), 2.0)
        harness.spin(0.002)
    # applied while the commands came (read after them, a host stall beyond the 10 ms timeout
    # made it 0 A on one CI run)
    assert 2.0 in [t.current_a for t in harness.got['truth'][flowing:]]
    harness.spin(0.25)  # commands stopped: 0 A after the timeout
    assert held_current() == 0.0
    for bad in (float('nan'), float('inf'), 1.0e6):
        for _ in range(5):
            harness.send_command(sample_ns(), 2.0)
            harness.spin(0.002)
        bad_ns = sample_ns()
        harness.got['truth'].clear()
        harness.send_command(bad_ns, bad)
        # never integrated: zero instead, well before the 100 ms command timeout would give it
        # (up to 30 ms for the command to reach the plant on a loaded machine: 12 ms seen)
        window = (bad_ns + 30 * 10**6, bad_ns + 60 * 10**6)
        harness.wait_for(
            lambda: any(sample_ns_of(t) > window[1] for t in harness.got['truth']),
            what='truth after the bad command',
        )
        held = [
            t.current_a for t in harness.got['truth'] if window[0] < sample_ns_of(t) <= window[1]
        ]
        assert held and all(c == 0.0 for c in held), (bad, held)
    # The gate's own refusal (actuator_core.gate), not any line that says 'refused' (the
    # SCHED_FIFO warning does): the first of the three in its second of the rate-limited log.
    assert 'command nan A refused (valid: finite, |u| <= 25 A); applying 0 A' in plant.output
    assert plant.stop() == 0 and 'Traceback' not in plant.output
    # each of the three refused by value, and only those (the summary line at stop)
    assert 'refused commands 3 by value and ' in plant.output, plant.output[-600:]


def test_eso_in_sim_mode_survives_the_largest_stamp(harness, ros_process):
    """A stamp of sec = 2^31 - 1 is refused.

    x_hat one sample later would not fit builtin_interfaces/Time.
    """
    eso = ros_process(
        'actuator_eso',
        'eso_node',
        [*AUTOSTART, '-p', 'mode:=sim', '-p', 'use_sim_time:=true'],
    )
    from actuator_ros.qos import control_qos

    qos = control_qos('sim')  # RELIABLE: what a sim-mode subscription matches
    joint = harness.node.create_publisher(harness.types['JointState'], 'joint_states', qos)
    command = harness.node.create_publisher(
        harness.types['CurrentCommand'], 'current_command', qos
    )
    estimates = []
    harness.node.create_subscription(
        harness.types['StateEstimate'], 'eso/estimate', estimates.append, qos
    )
    harness.wait_matched(joint)  # the observer's readers matched: nothing is lost
    harness.wait_matched(command)
    harness.spin(1.0)

    def send(stamp_ns, current):
        js = harness.types['JointState'](name=['joint'], position=[0.0])
        js.header.stamp = ns_to_stamp(stamp_ns)
        joint.publish(js)
        harness.spin(0.01)
        cmd = harness.types['CurrentCommand'](current_a=current)
        cmd.header.stamp = js.header.stamp
        command.publish(cmd)
        harness.spin(0.01)

    top = (2**31 - 1) * 1_000_000_000
    send(top, 1.0)
    harness.spin(0.3)
    for k in range(3):  # and it goes on estimating from ordinary stamps
        send(10**9 + k * 1_000_000, 0.0)
    harness.wait_for(lambda: len(estimates) >= 3, what='estimates')
    assert eso.running
    assert f'measurement stamped {top} ns refused: not a stamp' in eso.output
    assert eso.stop() == 0 and 'Traceback' not in eso.output


def test_eso_refuses_non_finite_measurements_and_commands(harness, ros_process):
    eso = ros_process('actuator_eso', 'eso_node', AUTOSTART)
    harness.wait_matched(harness.joint)  # the observer's reader matched: nothing is lost
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
    # the ESO's own refusals of each (eso_node.on_command, on_measurement), word for word
    assert 'command nan A refused (non-finite or beyond 20.0 A)' in eso.output
    assert (
        "measurement refused (joint 'joint' missing, non-finite or beyond 100.0 rad): [nan]"
        in eso.output
    )
    assert eso.stop() == 0


def test_eso_reactivation_restarts_the_observer_without_back_fill(harness, ros_process):
    """Deactivate, 5 samples go by, activate: the next measurement restarts x_hat (initial)."""
    eso = ros_process('actuator_eso', 'eso_node', AUTOSTART)
    harness.wait_for(lambda: harness.lifecycle_state('actuator_eso') == 'active', what='active')

    def change(label):
        return harness.transition('actuator_eso', label)

    t, period = _now_ns(harness), 1_000_000
    for k in range(10):
        harness.send_sample(t + k * period, 0.01, estimate=False)
        harness.send_command(t + k * period, 1.0)
        harness.spin(0.003)
    assert change('deactivate')
    for k in range(10, 15):  # 5 ms the observer does not see (shorter than its gap restart)
        harness.send_sample(t + k * period, 0.02, estimate=False)
        harness.spin(0.001)
    assert change('activate')
    harness.got['estimate'].clear()
    harness.send_sample(t + 15 * period, 0.03, estimate=False)
    harness.wait_for(lambda: harness.got['estimate'], what='the estimate after activation')
    first = harness.got['estimate'][0]
    assert first.initial and stamp_to_ns(first.header.stamp) == t + 15 * period
    assert first.position_rad == 0.03 and first.velocity_rad_s == 0.0
    assert 'observer restarted from the measurement at' in eso.output
    assert "lifecycle transition 'deactivate' requested from outside" in eso.output
    assert eso.stop() == 0 and 'Traceback' not in eso.output


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


def test_lifecycle_transitions_and_parameters_read_at_configure(harness, ros_process):
    """Take the controller through its states with the lifecycle services.

    configure -> activate -> deactivate -> cleanup -> shutdown; no command unless active;
    parameters can be set only while unconfigured.
    """
    from lifecycle_msgs.msg import Transition
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters

    ctrl = ros_process('actuator_controller', 'controller_node', NFTSMC_QUIET_WATCHDOG)
    parameters = harness.node.create_client(SetParameters, '/actuator_controller/set_parameters')

    def state():
        return harness.lifecycle_state('actuator_controller')

    def change(label):
        return harness.transition('actuator_controller', label)

    def set_gain(value):
        p = Parameter(
            name='nftsmc_eso.k1',
            value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value),
        )
        return harness.call(parameters, SetParameters.Request(parameters=[p])).results[0]

    def samples(n, start):
        for k in range(n):
            harness.send_sample(start + k * 1_000_000, 0.0)
            harness.spin(0.002)

    t = _now_ns(harness)
    assert state() == 'unconfigured'
    samples(20, t)
    assert change('configure') and state() == 'inactive'
    samples(20, t + 20_000_000)
    harness.spin(0.2)
    assert harness.got['command'] == []  # not active: no command at all
    refused = set_gain(500.0)
    assert not refused.successful and 'read at configure' in refused.reason
    assert change('activate') and state() == 'active'
    samples(20, t + 40_000_000)
    harness.wait_for(
        lambda: any(not c.safe_stop for c in harness.got['command']), what='commands while active'
    )
    last = t + 59_000_000  # every sample answered before the deactivation is judged
    harness.wait_for(
        lambda: any(stamp_to_ns(c.header.stamp) >= last for c in harness.got['command']),
        what='the command answering the last active sample',
    )
    harness.got['command'].clear()
    assert change('deactivate') and state() == 'inactive'
    harness.wait_for(lambda: harness.got['command'], what='the safe-stop command of deactivate')
    assert all(c.safe_stop and c.current_a == 0.0 for c in harness.got['command'])
    assert change('cleanup') and state() == 'unconfigured'
    assert set_gain(500.0).successful  # unconfigured: accepted, read at the next configure
    assert change('configure') and state() == 'inactive'
    assert change(Transition.TRANSITION_INACTIVE_SHUTDOWN) and state() == 'finalized'
    assert ctrl.stop() == 0 and 'Traceback' not in ctrl.output
    warnings = [line for line in ctrl.output.splitlines() if line.startswith('[WARN]')]
    for what in ('configure', 'activate', 'deactivate', 'cleanup'):
        assert any(f"lifecycle transition '{what}' requested from outside" in w for w in warnings)
    outside = [w for w in warnings if 'parameter change requested from outside' in w]
    assert len(outside) == 2 and all('nftsmc_eso.k1=500.0' in w for w in outside), outside


def test_every_outside_parameter_request_is_logged_refused_ones_too(harness, ros_process):
    """The parameter service as ``ros2 param set`` calls it, while the node is unconfigured.

    rclpy refuses a value out of the descriptor's range, a value of another type and a name the
    node does not have before any on-set callback runs; each request is still logged, as the
    accepted one is, in the order they came.
    """
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters

    ctrl = ros_process('actuator_controller', 'controller_node', NFTSMC_QUIET_WATCHDOG)
    client = harness.node.create_client(SetParameters, '/actuator_controller/set_parameters')

    def request(name, value):
        if isinstance(value, str):
            value = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value)
        else:
            value = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
        parameter = Parameter(name=name, value=value)
        return harness.call(client, SetParameters.Request(parameters=[parameter])).results[0]

    answers = [
        request('reference_amplitude_rad', 99.0),  # valid [-10, 10]
        request('reference_amplitude_rad', 'far'),
        request('no_such_parameter', 1.0),
        request('reference_amplitude_rad', 0.5),
    ]
    assert [a.successful for a in answers] == [False, False, False, True], answers
    assert answers[0].reason == (  # rclpy's words, as ros2 param set prints them
        'Parameter reference_amplitude_rad out of range Min: -10.0, Max: 10.0, value: 99.0'
    )
    assert answers[1].reason == "Wrong parameter type, expected 'Type.DOUBLE' got 'Type.STRING'"
    assert ctrl.stop() == 0 and 'Traceback' not in ctrl.output
    prefix = 'parameter change requested from outside (caller not known to rclpy): '
    logged = [
        line.split(']: ', 1)[1]
        for line in ctrl.output.splitlines()
        if line.startswith('[WARN]') and prefix in line
    ]
    assert logged == [
        prefix + 'reference_amplitude_rad=99.0',
        prefix + "reference_amplitude_rad='far'",
        prefix + 'no_such_parameter=1.0',
        prefix + 'reference_amplitude_rad=0.5',
    ]


def test_a_decimated_controller_state_keeps_every_command_and_every_change_of_status(
    harness, ros_process
):
    """state_rate_hz: controller/state on a 20 ms grid of stamps, each change of status at once."""
    from actuator_msgs.msg import ControllerState

    ctrl = ros_process(
        'actuator_controller',
        'controller_node',
        [
            *AUTOSTART,
            '-p',
            'controller:=nftsmc_eso',
            '-p',
            'sample_time_s:=0.005',
            '-p',
            'state_rate_hz:=50.0',
            '-p',
            'measurement_timeout_s:=0.05',
            '-p',
            'estimate_timeout_s:=0.05',
        ],
    )
    harness.wait_matched(harness.joint)  # the controller's readers matched: nothing is lost
    harness.wait_matched(harness.estimate)
    harness.spin(0.5)
    period, samples = 5_000_000, 120
    t = _now_ns(harness)
    for k in range(samples):  # valid pairs at 200 Hz, the controller's own rate
        harness.send_sample(t + k * period, 0.0)
        harness.spin(0.003)
    harness.wait_for(
        lambda: any(
            s.status == ControllerState.STATUS_STALE_MEASUREMENT for s in harness.got['state']
        ),
        what='the stale-measurement status once the samples stop',
    )
    commands = {stamp_to_ns(c.header.stamp) for c in harness.got['command']}
    states = [(stamp_to_ns(s.header.stamp), s.status) for s in harness.got['state']]
    answered = [s for s in commands if t <= s < t + samples * period]
    assert len(answered) > 0.8 * samples, f'{len(answered)} of {samples} samples commanded'
    statuses = [status for _, status in states]
    assert ControllerState.STATUS_OK in statuses
    # Decimated: two states of one status closer than the 20 ms grid only when the first was
    # a change of status, which passes off the grid without moving it (decimation.Decimator).
    for before, (t0, s0), (t1, s1) in zip([(None, None)] + states, states, states[1:]):
        if s0 == s1 and 0 < t1 - t0 < 20_000_000:
            assert before[1] != s0, (before, (t0, s0), (t1, s1))
    law = [stamp for stamp, status in states if t <= stamp < t + samples * period]
    changes = sum(1 for a, b in zip(statuses, statuses[1:]) if a != b)
    assert len(law) <= samples // 4 + changes + 1, (len(law), changes)
    assert len(law) >= samples // 8, f'{len(law)} states for {samples} samples at 1/4'
    assert 'controller/state at 50 Hz' in ctrl.output
    assert ctrl.stop() == 0 and 'Traceback' not in ctrl.output
