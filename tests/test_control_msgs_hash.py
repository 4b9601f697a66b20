# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""control_msgs/action/FollowJointTrajectory here is the Jazzy release's type, hash for hash.

Where no control_msgs is installed (the PyPI wheels) scripts/build.sh builds
interfaces/control_msgs; a Jazzy install keeps its own. Either way the type description hashes
(RIHS01) must be the release's, so goals from MoveIt, rqt_joint_trajectory_controller or
``ros2 action send_goal`` on a Jazzy machine match this controller's action server.

The expected values: ros-controls/control_msgs at tag 5.8.0 (commit f901df2662f2, the newest
release on its jazzy branch; FollowJointTrajectory.action, JointTolerance.msg and
JointComponentTolerance.msg are unchanged on that branch since 5.0.0), configured with this
project's pinned Jazzy wheels (common_interfaces 5.3.6, rosidl 4.6.6) in a scratch folder
outside the repository and its target control_msgs__rosidl_generator_type_description run;
the values are from rosidl_generator_type_description/control_msgs/*/*.json (2026-12-07).
"""

import json
from pathlib import Path

import pytest

#: RIHS01 hashes of the Jazzy release of control_msgs (source: module docstring).
JAZZY_HASHES = {
    'control_msgs/action/FollowJointTrajectory': (
        'RIHS01_738ebcb7a2d7cfa42f9f1001cc99ce3a4383d1cfe508015d9be8485e4b1c66f6'
    ),
    'control_msgs/action/FollowJointTrajectory_Goal': (
        'RIHS01_8a9060704b269608f5a340934cc26e66869dd14bdac29e2e7fd9ec8b9882d205'
    ),
    'control_msgs/action/FollowJointTrajectory_Result': (
        'RIHS01_8002e99ed2c14c6faa522f2a93c26d744c5982f254f9e98ff9c6f19789bdb220'
    ),
    'control_msgs/action/FollowJointTrajectory_Feedback': (
        'RIHS01_3fd0aaecf71725121ae1ff7f01098a5e0da581e672be18a6b2c286cb43d96b49'
    ),
    'control_msgs/action/FollowJointTrajectory_FeedbackMessage': (
        'RIHS01_80398fcb9674a79081a9906e2ccf0c804dd7cb15e22e362e606ee87186beab71'
    ),
    'control_msgs/action/FollowJointTrajectory_SendGoal': (
        'RIHS01_b13789dddc325a7a962825c45e28c77d37237ec129dd0c34dc5994562938c57f'
    ),
    'control_msgs/action/FollowJointTrajectory_GetResult': (
        'RIHS01_e3ceb38e3e1867c8dc0f46014df26e90eb93422f27e9e97f936e07f94be4bc8b'
    ),
    'control_msgs/msg/JointTolerance': (
        'RIHS01_c254f9cece0f3b733017b6990fd46d1326e25242d6b8844398c97d9a88e7d648'
    ),
    'control_msgs/msg/JointComponentTolerance': (
        'RIHS01_739ea7566931944d33830fa10f1bf5e7a7fbdc3172bce7a7eaac642bd6e3ffa4'
    ),
}


def _installed_hashes() -> dict:
    """Every type hash the installed control_msgs' type descriptions state."""
    from ament_index_python.packages import get_package_share_directory

    share = Path(get_package_share_directory('control_msgs'))
    hashes = {}
    for name in ('action/FollowJointTrajectory', 'msg/JointTolerance'):
        description = json.loads((share / f'{name}.json').read_text())
        hashes.update({h['type_name']: h['hash_string'] for h in description['type_hashes']})
    return hashes


def test_installed_follow_joint_trajectory_hashes_are_the_jazzy_releases():
    installed = _installed_hashes()
    for type_name, expected in JAZZY_HASHES.items():
        assert installed.get(type_name) == expected, type_name


@pytest.mark.ros
def test_the_wire_carries_the_jazzy_hashes(rclpy_context):
    """What a node announces on the graph (the hash a subscriber matches) is the release's."""
    from control_msgs.action import FollowJointTrajectory
    from rclpy.node import Node

    node = Node('hash_probe', context=rclpy_context)
    try:
        types = {
            'FollowJointTrajectory_Goal': FollowJointTrajectory.Goal,
            'FollowJointTrajectory_Result': FollowJointTrajectory.Result,
            'FollowJointTrajectory_Feedback': FollowJointTrajectory.Feedback,
            'FollowJointTrajectory_FeedbackMessage': FollowJointTrajectory.Impl.FeedbackMessage,
        }
        for name, msg_type in types.items():
            topic = f'/probe_{name.lower()}'
            node.create_publisher(msg_type, topic, 1)
            (info,) = node.get_publishers_info_by_topic(topic)
            assert str(info.topic_type_hash) == JAZZY_HASHES[f'control_msgs/action/{name}']
    finally:
        node.destroy_node()
