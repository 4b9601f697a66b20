# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The one joint node, driven call by call in this process (sim mode: the sample clock is ours)."""

import pytest

from actuator_core.joint import Joint, JointSample

P = 1_000_000


def make(node_class, context, **parameters):
    from rclpy.parameter import Parameter

    overrides = [Parameter('mode', value='sim')] + [
        Parameter(k, value=v) for k, v in parameters.items()
    ]
    node = node_class(context=context, parameter_overrides=overrides)
    node.trigger_configure()
    node.trigger_activate()
    assert node.active
    node._start_sampling()  # sample 0 published; the node waits for its command
    return node


def command(stamp_ns: int, current_a: float, safe_stop: bool = False):
    from builtin_interfaces.msg import Time

    from actuator_msgs.msg import CurrentCommand

    msg = CurrentCommand(current_a=current_a, safe_stop=safe_stop)
    msg.header.stamp = Time(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000)
    return msg


def assert_stopped_for_good(node) -> None:
    """Check a stopped joint: 0 A, brake, gate closed, no fault; a command moves nothing."""
    assert node.joint.command == (0.0, True) and not node.gate.active and node.fault == ''
    index = node.sample_index
    node.on_command(command(node.published_ns, 10.0))
    assert node.sample_index == index
    node.destroy_node()


def test_the_plant_steps_only_for_a_command_that_answers_its_newest_sample(rclpy_context):
    from actuator_plant.plant_node import PlantNode

    node = make(PlantNode, rclpy_context)
    t0 = node.published_ns
    for stamp in (t0 + P, t0 - P, t0 + 1, 0, -5 * P):  # ahead, before sample 0, off grid, ...
        node.on_command(command(stamp, 5.0))
        assert node.sample_index == 0 and node.refused > 0  # refused: no step, nothing held
    assert node.refused == 5 and node.gate.hold(t0).reason == 'no command yet'
    node.on_command(command(t0, 5.0))
    assert node.sample_index == 1 and node.held.current_a == 5.0 and not node.held.brake
    node.on_command(command(t0, 7.0))  # a second command for sample 0: a duplicate, refused
    assert node.sample_index == 1 and node.refused == 6
    assert node.gate.hold(node.published_ns).current_a == 5.0
    node.on_command(command(t0 + P, 6.0, safe_stop=True))
    assert node.sample_index == 2 and node.held.brake and node.held.current_a == 0.0
    node.destroy_node()


def test_a_bad_current_brakes_the_joint_whatever_sample_it_claims(rclpy_context):
    """NaN for a sample already applied still gives 0 A (docs/safety.md#values-before-stamps)."""
    from actuator_plant.plant_node import PlantNode

    node = make(PlantNode, rclpy_context)
    t0 = node.published_ns
    node.on_command(command(t0, 5.0))
    assert node.gate.hold(node.published_ns).current_a == 5.0
    for bad in (float('nan'), 1.0e6):
        node.on_command(command(t0, 5.0))  # the same sample again: refused by its stamp
        assert node.gate.hold(node.published_ns).current_a == 5.0
        node.on_command(command(t0, bad))  # the same stamp with a bad value: the safe state
        held = node.gate.hold(node.published_ns)
        assert (held.current_a, held.brake) == (0.0, True), bad
        node.on_command(command(node.published_ns, 5.0))  # the next genuine sample
        assert node.gate.hold(node.published_ns).current_a == 5.0
        t0 = node.published_ns - P
    node.destroy_node()


def past_the_soft_limit(rclpy_context):
    """Return a plant node driven up at +10 A, one sample at a time, past its 0.3 rad limit."""
    from actuator_plant.plant_node import PlantNode

    node = make(
        PlantNode,
        rclpy_context,
        position_max_rad=0.3,
        initial_position_rad=0.299,
        brake_delay_s=0.0,
    )
    k = 0
    while not node.stopped_reason and k < 200:
        node.on_command(command(node.published_ns, 10.0))
        k += 1
    return node


def test_a_soft_limit_crossed_ends_control_with_the_brake(rclpy_context):
    node = past_the_soft_limit(rclpy_context)
    assert 'outside the soft limits [-100, 0.3] rad' in node.stopped_reason
    assert_stopped_for_good(node)


class FaultyJoint(Joint):
    """A joint that stops applying torque at sample 3 (as a drive's STO would)."""

    kind = 'faulty'
    supports_sim_time = True

    def __init__(self):
        self.reads, self.written = 0, []

    def write(self, current_a, brake):
        self.written.append((current_a, brake))

    def read(self, stamp_ns):
        self.reads += 1
        return JointSample(stamp_ns, 0.0, 0.0, 'safe torque off' if self.reads > 3 else '')


def faulty_node_class():
    """Return the joint node class holding a FaultyJoint (rclpy imported on demand)."""
    from actuator_ros.joint_node import JointNode

    class FaultyNode(JointNode):
        summary = 'faulty joint'

        def __init__(self, **kwargs):
            super().__init__('faulty_joint', **kwargs)

        def make_joint(self):
            return FaultyJoint()

    return FaultyNode


def test_a_joint_fault_ends_control_and_goes_through_error_processing(rclpy_context):
    node = make(faulty_node_class(), rclpy_context)
    joint = node.joint
    for _ in range(5):
        node.on_command(command(node.published_ns, 2.0))
    assert node.fault == 'safe torque off' and joint.written[-1] == (0.0, True)
    timer = node.timer
    node.on_tick()  # supervision: deactivate -> error processing -> unconfigured
    assert node._state_machine.current_state[1] == 'unconfigured' and not node.active
    # nothing destroyed inside the timer's own callback: dropped at the next configure
    assert node.joint is joint and not timer.is_canceled() and timer in node.timers
    node.trigger_configure()
    assert node._state_machine.current_state[1] == 'inactive'
    assert timer not in node.timers and node.timer in node.timers
    assert node.joint is not joint and node.fault == ''
    node.destroy_node()


def test_a_joint_fault_in_real_time_ends_the_sampling_thread(rclpy_context):
    # Before: the thread kept running after control ended; no cycle advanced the grid, so it
    # spun without sleeping at the joint's SCHED_FIFO priority until someone deactivated the node
    # (a driver counted 11 million skipped cycles in 0.13 s of it).
    from rclpy.parameter import Parameter

    node = faulty_node_class()(
        context=rclpy_context, parameter_overrides=[Parameter('mode', value='realtime')]
    )
    node.trigger_configure()
    node.trigger_activate()
    node._start_sampling()
    node.sampler.join(timeout=2.0)
    assert not node.sampler.is_alive() and node.stopped_reason == 'safe torque off'
    assert node.joint.reads == 4 and node.joint.written[-1] == (0.0, True)
    assert node.skipped_cycles < 100, node.skipped_cycles
    node.destroy_node()


class StallingJoint(Joint):
    """A real joint (no replay of missed samples) whose first read from instant 5 holds the host.

    It returns 0.6 of a period into the second instant after it: too late for that cycle.
    """

    kind = 'stalling'
    supports_sim_time = True

    def __init__(self):
        self.node, self.instants, self.stalled_at = None, [], None

    def write(self, current_a, brake):
        pass

    def read(self, stamp_ns):
        import time

        node = self.node
        k = (stamp_ns - node.start_ns) // node.period_ns
        self.instants.append(k)
        if self.stalled_at is None and k >= 5:
            self.stalled_at = k
            wake_ns = node.start_mono_ns + (k + 2) * node.period_ns + 6 * node.period_ns // 10
            time.sleep(max(0, wake_ns - time.monotonic_ns()) * 1e-9)
        if len(self.instants) >= 10:
            node.stopped_reason = 'enough samples'
        return JointSample(stamp_ns, 0.0, 0.0)


def test_a_real_joint_skips_a_cycle_it_woke_too_late_for(rclpy_context):
    # A real joint samples when its cycle runs (the drive, when the SYNC reaches it). Before, the
    # thread woke 0.6 ms into an instant and ran its cycle there: the drive sampled 0.6 ms after
    # the stamp, and a SYNC-locked drive took it for the next one (a measurement step).
    from rclpy.parameter import Parameter

    from actuator_ros.joint_node import JointNode

    class StallingNode(JointNode):
        def make_joint(self):
            return StallingJoint()

    node = StallingNode(
        'stalling_joint',
        context=rclpy_context,
        parameter_overrides=[Parameter('mode', value='realtime')],
    )
    node.trigger_configure()
    node.trigger_activate()
    node.joint.node = node
    node._start_sampling()
    node.sampler.join(timeout=2.0)
    k, stalled = node.joint.instants, node.joint.stalled_at
    after = k[k.index(stalled) + 1]
    # instant stalled+1 passed during the stall, stalled+2 was 0.6 of a period gone
    assert after >= stalled + 3, k
    assert node.longest_stall_cycles >= after - stalled - 1
    node.destroy_node()


@pytest.mark.parametrize('name, value', [('current_limit_a', 0.0), ('brake_delay_s', -1.0)])
def test_joint_settings_out_of_range_are_refused_in_one_line(rclpy_context, name, value):
    from rclpy.parameter import Parameter

    from actuator_plant.plant_node import PlantNode
    from actuator_ros.parameters import ParameterError

    with pytest.raises(ParameterError, match=name):
        PlantNode(context=rclpy_context, parameter_overrides=[Parameter(name, value=value)])


def test_the_joint_reports_its_health_on_diagnostics(rclpy_context):
    from actuator_core.health import Level
    from actuator_plant.plant_node import PlantNode

    node = make(PlantNode, rclpy_context)
    first = node.diagnostics.publish()
    assert first.level == Level.OK and first.value('samples') == '1'
    assert first.hardware_id == 'plant' and first.value('mode') == 'sim'
    node.on_command(command(node.published_ns + P, 1.0))  # ahead: refused by stamp
    node.on_command(command(node.published_ns, 1.0))
    second = node.diagnostics.publish()
    assert second.level == Level.WARN and '1 commands refused by stamp' in second.message
    assert second.value('samples') == '2' and second.value('refused_by_stamp') == '1'
    node.destroy_node()


def _fresh_then_stale(node, fresh: int, stale: int) -> None:
    """Answer ``fresh`` samples in time, then step ``stale`` samples with no new command.

    The first step without a command is still fresh: the held command answered the sample
    before the newest (one sample late, which the protocol allows).
    """
    for _ in range(fresh):
        node.on_command(command(node.published_ns, 1.0))
    for _ in range(stale):
        node._sim_step()  # as a lockstep timeout does: the held command is older each sample


def test_a_loop_whose_commands_come_late_makes_the_joint_warn_until_they_are_in_time(
    rclpy_context,
):
    """Loop health: below half the samples of the window with a fresh command, WARN."""
    from actuator_core.health import Level
    from actuator_plant.plant_node import PlantNode

    node = make(PlantNode, rclpy_context, fresh_command_window_s=0.05)  # 50 samples
    _fresh_then_stale(node, 60, 26)  # 25 of the last 50 fresh: at the minimum, not below
    report = node.diagnostics.publish()  # WARN of the command timeout, not of the loop
    assert report.value('fresh commands [%]') == '50.0' and 'loop too slow' not in report.message
    _fresh_then_stale(node, 0, 1)
    report = node.diagnostics.publish()
    assert report.level == Level.WARN and node.freshness.degraded
    assert 'loop too slow: fresh commands 48.0% of the last 50 samples (minimum 50%)' in (
        report.message
    )
    assert not node.stopped_reason and node.gate.active  # warned only: control goes on
    # In time again: the stale samples leave the window after the 24 fresh ones before them.
    _fresh_then_stale(node, 29, 0)  # 29 of 50 (58 %): below the 60 % of healthy again
    assert node.freshness.degraded and node.freshness.share == 0.58
    _fresh_then_stale(node, 1, 0)
    assert not node.freshness.degraded and node.diagnostics.publish().level == Level.OK
    node.destroy_node()


def test_stop_on_stale_loop_ends_control_with_the_brake_and_its_reason(rclpy_context):
    from actuator_plant.plant_node import PlantNode

    node = make(PlantNode, rclpy_context, fresh_command_window_s=0.05, stop_on_stale_loop=True)
    _fresh_then_stale(node, 60, 27)
    assert node.stopped_reason.startswith('loop too slow: fresh commands 48.0%')
    assert_stopped_for_good(node)


def test_a_report_queued_before_cleanup_reports_nothing_and_raises_nothing(rclpy_context):
    """A diagnostics timer event that comes after drop (the joint gone) is a no-op, not a crash."""
    from actuator_plant.plant_node import PlantNode

    node = make(PlantNode, rclpy_context)
    diagnostics = node.diagnostics
    assert diagnostics.publish() is not None
    node.trigger_deactivate()
    node.trigger_cleanup()
    assert node.joint is None  # what the snapshot reads is gone
    assert diagnostics.publish() is None
    node.destroy_node()


def test_a_soft_limit_stop_says_0_a_and_brake_at_once_then_the_node_deactivates_itself(
    rclpy_context,
):
    # Before (issue 44): /diagnostics kept the last held current and 'brake: false' after a
    # joint-side stop, and the node stayed active until someone deactivated it.
    node = past_the_soft_limit(rclpy_context)
    report = node.diagnostics.publish()
    assert report.value('brake') == 'true' and report.value('held').startswith(
        'control ended: joint angle'
    ), report.values
    node.on_tick()  # supervision: the node's own deactivation (no fault: no error processing)
    assert node._state_machine.current_state[1] == 'inactive' and node.configured
    report = node.diagnostics.publish()
    assert report.value('held') == 'inactive' and report.value('brake') == 'true'
    node.destroy_node()


class EndingJoint(FaultyJoint):
    """A FaultyJoint that records end_control and has one warning to hand over."""

    def __init__(self):
        super().__init__()
        self.ended, self.warnings = [], ['EMCY 0xFF00 (device specific) without error register']

    def end_control(self, reason):
        self.ended.append(reason)
        return 'drive stopped'

    def take_warnings(self):
        taken, self.warnings = self.warnings, []
        return taken


def test_the_node_ends_control_through_the_joint_and_logs_and_counts_its_warnings(rclpy_context):
    # Before: the node wrote 0 A with the brake once, which a synchronous drive never took
    # without a further SYNC, and a joint's warnings (EMCY) were never asked for.
    from actuator_core.health import Level
    from actuator_ros.joint_node import JointNode

    class EndingNode(JointNode):
        def __init__(self, **kwargs):
            super().__init__('ending_joint', **kwargs)

        def make_joint(self):
            return EndingJoint()

    node = make(EndingNode, rclpy_context)
    joint = node.joint
    node.diagnostics.publish()
    node.on_tick()  # supervision takes the joint's warning: logged and counted
    report = node.diagnostics.publish()
    assert report.level == Level.WARN, report.message
    assert '1 warnings of the joint (logged) since the last report' in report.message
    for _ in range(5):
        node.on_command(command(node.published_ns, 2.0))
    assert joint.ended == ['safe torque off'] and node.fault == 'safe torque off'
    node.on_tick()  # the fault: deactivation, error processing, unconfigured
    assert node._state_machine.current_state[1] == 'unconfigured'
    node.destroy_node()


class _Said:
    """A logger stand-in that keeps what the node says at error level."""

    def __init__(self):
        self.errors = []

    def error(self, text, **kwargs):
        self.errors.append(text)

    def __getattr__(self, name):
        return lambda *args, **kwargs: None


def test_a_joint_that_cannot_be_brought_up_is_a_failed_configure_not_a_refused_parameter(
    rclpy_context,
):
    # Before (issue 44): a drive that failed at configure was reported as a ParameterError,
    # 'configure refused: ...', as if a parameter were wrong.
    from actuator_core.joint import JointError
    from actuator_ros.joint_node import JointNode

    class Unreachable(FaultyJoint):
        def configure(self):
            raise JointError('configure: node 1 sent no boot-up')

    class UnreachableNode(JointNode):
        summary = 'unreachable joint'

        def __init__(self, **kwargs):
            super().__init__('unreachable_joint', **kwargs)

        def make_joint(self):
            return Unreachable()

    from rclpy.parameter import Parameter

    node = UnreachableNode(
        context=rclpy_context, parameter_overrides=[Parameter('mode', value='sim')]
    )
    said = _Said()
    node.get_logger = lambda: said
    node.trigger_configure()
    assert not node.configured and node.joint is None
    assert said.errors == [
        'configure failed: unreachable joint: configure: node 1 sent no boot-up'
    ]
    node.destroy_node()
