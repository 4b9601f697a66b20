# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The joint, ESO and controller composed in one process keep every node's contract."""

import pytest

from ros_helpers import TestNode

pytestmark = pytest.mark.usefixtures('rclpy_context')


def test_a_composed_loop_keeps_lifecycle_and_the_publisher_guard(rclpy_context, ros_process):
    """Each node is driven through its own lifecycle services; a second publisher is refused."""
    from sensor_msgs.msg import JointState

    from actuator_bringup.runner import scenario_file
    from actuator_msgs.msg import CurrentCommand
    from actuator_ros.qos import control_qos

    loop = ros_process(
        'actuator_bringup',
        'loop_container',
        ['--ros-args', '--params-file', str(scenario_file('case2_pp_nftsmc_eso'))],
    )
    test = TestNode(rclpy_context, 'composed_test')
    qos = control_qos('realtime')
    got = {'joint_states': [], 'command': []}
    test.node.create_subscription(JointState, 'joint_states', got['joint_states'].append, qos)
    test.node.create_subscription(CurrentCommand, 'current_command', got['command'].append, qos)

    def wait_for(predicate, what):
        try:
            test.wait_for(predicate, what=what)
        except AssertionError as exc:
            raise AssertionError(f'{exc}; log:\n{loop.output[-3000:]}') from None

    try:
        names = ('actuator_controller', 'actuator_eso', 'actuator_plant')  # the joint last
        for name in names:
            assert test.lifecycle_state(name) == 'unconfigured'
        assert got['joint_states'] == []  # nothing samples before the lifecycle says so
        for label in ('configure', 'activate'):
            for name in names:
                assert test.transition(name, label), (name, label)
        wait_for(
            lambda: any(not c.safe_stop for c in got['command'][-50:]), 'closed-loop commands'
        )
        wait_for(lambda: len(got['joint_states']) > 200, 'samples')
        rogue = test.node.create_publisher(CurrentCommand, 'current_command', qos)
        wait_for(
            lambda: 'refusing every command (0 A, brake) until one is left' in loop.output,
            'the guard in the joint',
        )
        test.node.destroy_publisher(rogue)
        wait_for(
            lambda: 'one publisher on current_command again' in loop.output, 'the guard clears'
        )
        assert loop.stop() == 0 and 'Traceback' not in loop.output
    finally:
        test.close()


def test_sim_time_nodes_of_one_process_follow_clock_through_one_subscription(rclpy_context):
    """share_clock_subscription: one /clock subscription, every sim-time node's clock follows."""
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rosgraph_msgs.msg import Clock

    from actuator_ros.conversions import ns_to_stamp
    from actuator_ros.runner import share_clock_subscription

    sim = Parameter('use_sim_time', value=True)
    members = [
        Node(name, context=rclpy_context, parameter_overrides=[sim]) for name in ('first', 'other')
    ]
    wall = Node('wall_time', context=rclpy_context)  # not on sim time: untouched
    source = TestNode(rclpy_context, 'clock_source')
    try:
        assert share_clock_subscription([*members, wall]) == 1
        clock_subs = [
            n for n in (*members, wall) if any(s.topic_name == '/clock' for s in n.subscriptions)
        ]
        assert clock_subs == [members[0]]
        for node in (*members, wall):
            source.executor.add_node(node)
        pub = source.node.create_publisher(Clock, '/clock', 10)
        source.wait_for(lambda: pub.get_subscription_count() == 1, what='the one subscription')
        pub.publish(Clock(clock=ns_to_stamp(42_000_000_000)))
        source.wait_for(
            lambda: members[1].get_clock().now().nanoseconds == 42_000_000_000,
            what="the follower's clock at the published time",
        )
        assert members[0].get_clock().now().nanoseconds == 42_000_000_000
        assert wall.get_clock().now().nanoseconds > 10**18  # still the system clock
    finally:
        source.close()
        for node in (*members, wall):
            node.destroy_node()


@pytest.mark.parametrize('listened', [True, False])
def test_the_callback_cost_tool_runs_the_nodes_path_bit_for_bit(listened, monkeypatch):
    """actuator_bench.callback_cost: the nodes wired in-process command what the offline loop does.

    With and without a subscriber on the diagnostic topics (the recorded and the quiet path).
    """
    from actuator_bench import callback_cost

    figures = callback_cost.measure(300, listened=listened)
    assert figures['samples'] == 300 and figures['identical_to_offline']
    assert all(us > 0 for us in figures['median_us'].values()), figures['median_us']
