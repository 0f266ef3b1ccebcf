# Copyright 2026 motion_challenges contributors
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
Start unicycle_sim owning the clock, and optionally a motion on its time and RViz.

    ros2 launch motion_challenges unicycle.launch.py
    ros2 launch motion_challenges unicycle.launch.py motion:=odom_out_and_back rviz:=true
    ros2 launch motion_challenges unicycle.launch.py motion:=rotate_robot real_time_factor:=5.0

The motion runs with use_sim_time and its params file from share/motion_challenges/config
(rotate_robot's answers are in it, so nothing prompts); the launch shuts down when it ends.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.actions import EmitEvent
from launch.actions import OpaqueFunction
from launch.actions import RegisterEventHandler
from launch.conditions import IfCondition
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

PACKAGE = 'motion_challenges'
MOTIONS = ('rotate_robot', 'circle_back_and_forth', 'timed_out_and_back', 'odom_out_and_back')


def motion_actions(context):
    """Return the motion's node and the handler that ends the launch with it (or nothing)."""
    motion = LaunchConfiguration('motion').perform(context)
    if not motion:
        return []
    if motion not in MOTIONS:
        raise RuntimeError(f"motion:='{motion}' is not one of {', '.join(MOTIONS)}")
    params_file = os.path.join(get_package_share_directory(PACKAGE), 'config', motion + '.yaml')
    node = Node(package=PACKAGE, executable=motion, output='screen',
                parameters=[params_file, {'use_sim_time': True}])
    ended = RegisterEventHandler(OnProcessExit(
        target_action=node,
        on_exit=[EmitEvent(event=Shutdown(reason=f'{motion} finished'))]))
    return [node, ended]


def generate_launch_description():
    rviz_config = os.path.join(get_package_share_directory(PACKAGE), 'rviz', 'unicycle.rviz')
    return LaunchDescription([
        DeclareLaunchArgument('real_time_factor', default_value='1.0',
                              description='Simulated seconds per wall second (an upper bound '
                                          'in lockstep).'),
        DeclareLaunchArgument('motion', default_value='',
                              description='Also run this motion on simulated time, and shut '
                                          'down when it ends: ' + ', '.join(MOTIONS)),
        DeclareLaunchArgument('rviz', default_value='false',
                              description='Also start RViz with rviz/unicycle.rviz.'),
        Node(package=PACKAGE, executable='unicycle_sim', output='screen',
             parameters=[{'publish_clock': True,
                          'real_time_factor': LaunchConfiguration('real_time_factor')}]),
        OpaqueFunction(function=motion_actions),
        Node(package='rviz2', executable='rviz2', arguments=['-d', rviz_config],
             parameters=[{'use_sim_time': True}],
             condition=IfCondition(LaunchConfiguration('rviz'))),
    ])
