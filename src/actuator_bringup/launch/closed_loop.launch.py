"""ros2 launch actuator_bringup closed_loop.launch.py [scenario:=...] [mode:=realtime|sim] [record:=true]

The same bring-up as the ``bringup`` executable, for Jazzy installations with ``ros2 launch``:
plant, ESO and controller as separate processes with the scenario's parameter file from
share/actuator_bringup/config/, the recorder when record:=true. In sim mode the plant owns
/clock and the other nodes use sim time. Swap the plant for a hardware driver with
plant:=false and start the driver yourself: it must implement the topic contract of the README.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from actuator_tools.bringup import recorder_parameters


def _nodes(context):
    scenario = LaunchConfiguration('scenario').perform(context)
    mode = LaunchConfiguration('mode').perform(context)
    record = LaunchConfiguration('record').perform(context).lower() == 'true'
    with_plant = LaunchConfiguration('plant').perform(context).lower() == 'true'
    duration = float(LaunchConfiguration('duration').perform(context))
    params = os.path.join(get_package_share_directory('actuator_bringup'), 'config', f'{scenario}.yaml')
    if not os.path.isfile(params):
        raise RuntimeError(f'no scenario {scenario!r}: {params} does not exist')
    sim = mode == 'sim'
    common = {'mode': mode, 'use_sim_time': sim}
    nodes = [
        Node(package='actuator_controller', executable='controller_node', name='actuator_controller',
             parameters=[params, common], output='screen'),
        Node(package='actuator_eso', executable='eso_node', name='actuator_eso',
             parameters=[params, common], output='screen'),
    ]
    if with_plant:
        nodes.append(Node(package='actuator_plant', executable='plant_node', name='actuator_plant',
                          parameters=[params, {'mode': mode, 'stop_after_s': duration,
                                               'wait_for_subscribers': 3 if record else 2}],
                          output='screen'))
    if record:
        nodes.append(Node(package='actuator_bag', executable='recorder', name='recorder',
                          parameters=[{'use_sim_time': sim, **recorder_parameters(mode)}],
                          output='screen'))
    return nodes


def generate_launch_description():
    """Launch arguments and the nodes of one closed-loop run."""
    return LaunchDescription([
        DeclareLaunchArgument('scenario', default_value='case2_pp_nftsmc_eso',
                              description='parameter file share/actuator_bringup/config/<scenario>.yaml'),
        DeclareLaunchArgument('mode', default_value='realtime', choices=['realtime', 'sim'],
                              description='realtime: wall-clock 1 kHz; sim: lockstep on the plant\'s /clock'),
        DeclareLaunchArgument('record', default_value='true', description='record all topics to bags/'),
        DeclareLaunchArgument('plant', default_value='true',
                              description='start the simulated plant (false: a hardware driver provides the joint)'),
        DeclareLaunchArgument('duration', default_value='0.0',
                              description='simulated run length [s]; 0 runs until stopped'),
        OpaqueFunction(function=_nodes),
    ])
