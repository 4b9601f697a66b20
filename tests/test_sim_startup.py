# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The sim lockstep's start and its end without commands, node by node.

A RELIABLE writer keeps nothing for a reader that has not matched, and the lockstep answers each
sample once: what the observer and the controller send before their readers matched must wait
for them, and a joint that hears no command ends the run with the reason.
"""

import pytest

from actuator_core.timing import stamp_to_ns
from actuator_ros.conversions import ns_to_stamp

pytestmark = pytest.mark.usefixtures('rclpy_context')

#: Managed nodes configure and activate themselves,
#: as `ros2 run ... --ros-args -p autostart:=true` does.
AUTOSTART = ['--ros-args', '-p', 'autostart:=true']


def test_a_sim_lockstep_without_commands_ends_the_run_with_its_reason(ros_process):
    """No node answers the sim plant's samples: the run ends, exit 1, the reason on stderr.

    Stepping on without commands ran the plant open loop one step per timeout: a 3 s run would
    have taken hours (a launch whose controller missed its activation).
    """
    plant = ros_process(
        'actuator_plant',
        'plant_node',
        [
            *AUTOSTART,
            '-p',
            'mode:=sim',
            '-p',
            'stop_after_s:=3.0',
            '-p',
            'wait_for_subscribers:=0',
            '-p',
            'lockstep_timeout_s:=0.3',
        ],
    )
    assert plant.wait(60) == 1, plant.describe()
    assert (
        'control ended: sim: no command for sample 0 within 0.3 s of wall time '
        '(lockstep_timeout_s); 0 A, brake engaged'
    ) in plant.output, plant.output[-1500:]
    assert 'the run of 3 s ended early: sim: no command for sample 0' in plant.output


def test_a_sim_observer_holds_its_first_estimate_until_a_subscriber_matched(
    rclpy_context, ros_process
):
    """x_hat(0) made before the controller's subscription matched is sent once it has.

    RELIABLE does not keep a message for a reader that has not matched: a lost x_hat(0) left the
    controller waiting for it and the observer for u(0), and the lockstep stopped at start-up.
    """
    from sensor_msgs.msg import JointState

    from actuator_msgs.msg import StateEstimate
    from actuator_ros.qos import control_qos
    from ros_helpers import TestNode

    eso = ros_process('actuator_eso', 'eso_node', [*AUTOSTART, '-p', 'mode:=sim'])
    test = TestNode(rclpy_context, 'late_subscriber')
    qos = control_qos('sim')
    joint = test.node.create_publisher(JointState, 'joint_states', qos)
    test.wait_for(lambda: joint.get_subscription_count() >= 1, what='the observer subscribed')
    eso.wait_for_output(r'\]: active', timeout=30)
    y0 = JointState(name=['joint'], position=[0.25])
    y0.header.stamp = ns_to_stamp(10**9)
    joint.publish(y0)
    test.spin(0.5)  # x_hat(0) is made now, with no one to take it
    got = []
    test.node.create_subscription(StateEstimate, 'eso/estimate', got.append, qos)
    test.wait_for(lambda: got, timeout=10.0, what='the held x_hat(0)')
    first = got[0]
    assert first.initial and stamp_to_ns(first.header.stamp) == 10**9
    assert first.position_rad == 0.25
    test.close()


def test_a_sim_controller_holds_its_commands_until_every_reader_matched(
    rclpy_context, ros_process
):
    """u(0) waits for lockstep_subscribers readers of current_command, not the first one.

    The recorder's reader matched first and the joint's not yet: u(0) went to the recorder
    alone, and the joint waited for it until its lockstep timeout.
    """
    from rclpy.event_handler import SubscriptionEventCallbacks
    from sensor_msgs.msg import JointState

    from actuator_msgs.msg import CurrentCommand, StateEstimate
    from actuator_ros.qos import control_qos
    from ros_helpers import TestNode

    args = [
        *AUTOSTART,
        '-p',
        'mode:=sim',
        '-p',
        'use_sim_time:=true',
        '-p',
        'lockstep_subscribers:=2',
    ]
    controller = ros_process('actuator_controller', 'controller_node', args)
    test = TestNode(rclpy_context, 'readers')
    qos = control_qos('sim')
    joint = test.node.create_publisher(JointState, 'joint_states', qos)
    estimate = test.node.create_publisher(StateEstimate, 'eso/estimate', qos)
    controller.wait_for_output(r'\]: active', timeout=30)
    for pub in (joint, estimate):
        test.wait_for(lambda: pub.get_subscription_count() >= 1, what='the controller subscribed')
    first, second, matched = [], [], []
    test.node.create_subscription(
        CurrentCommand,
        'current_command',
        first.append,
        qos,
        event_callbacks=SubscriptionEventCallbacks(matched=matched.append),
    )
    test.wait_for(lambda: matched, what="the first reader matched the controller's writer")
    y0 = JointState(name=['joint'], position=[0.0])
    y0.header.stamp = ns_to_stamp(10**9)
    joint.publish(y0)
    test.spin(0.05)
    x0 = StateEstimate(position_rad=0.0)
    x0.header.stamp = ns_to_stamp(10**9)
    estimate.publish(x0)
    test.spin(1.0)  # u(0) is made now: one reader of two
    assert first == []
    test.node.create_subscription(CurrentCommand, 'current_command', second.append, qos)
    test.wait_for(lambda: first and second, timeout=10.0, what='the held u(0) to both readers')
    assert [stamp_to_ns(m.header.stamp) for m in first] == [10**9]
    assert stamp_to_ns(second[0].header.stamp) == 10**9
    test.close()
