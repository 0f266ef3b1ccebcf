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
    ros2 launch motion_challenges unicycle.launch.py namespace:=robot1 rviz:=true
    ros2 launch motion_challenges unicycle.launch.py map:=maps/room.yaml rviz:=true
    ros2 launch motion_challenges unicycle.launch.py robots:=[robot1,robot2] \
        motion:=odom_out_and_back rviz:=true

The motion runs with use_sim_time and the parameters of its file in share/motion_challenges/
config (rotate_robot's answers are in it, so nothing prompts); the launch shuts down when it
ends.  ``namespace`` puts every node in it (topics /robot1/odom, frames robot1/odom ->
robot1/base_footprint, as the simulator names them).  ``robots`` simulates a fleet (each
robot's topics and frames under its name) and runs the motion on every robot with
motion_fleet.  ``map`` (a map_server YAML) is the simulator's ``map_file``: the robots drive in
that map, and RViz shows it and each robot's scan.  ``params_file`` is given to every node
after the launch's own values, so its sections (``unicycle_sim:``, ``/**/odom_out_and_back:``)
win.  RViz shows the robot from its
odometry frame; for a namespace or a fleet the launch writes a copy of rviz/unicycle.rviz
with the robots' frames and topics (sim_diffdrive/taps/rviz_config.py), and for a fleet ties
every robot's odometry frame to ``world`` with a static transform, so one view shows them all
(with a map, whose frame is already each odometry frame's parent, the fleet is seen from it).
"""

import os
import tempfile

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.actions import EmitEvent
from launch.actions import OpaqueFunction
from launch.actions import RegisterEventHandler
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from sim_diffdrive.taps.rviz_config import FLEET_FRAME
from sim_diffdrive.taps.rviz_config import robot_views
from sim_diffdrive.taps.rviz_config import rviz_config
import yaml

PACKAGE = 'motion_challenges'
MAP_FRAME = 'map'  # unicycle_sim's map_frame_id
MOTIONS = ('rotate_robot', 'circle_back_and_forth', 'timed_out_and_back', 'odom_out_and_back')


def robot_names(text):
    """Return the robots of ``robots:=[robot1,robot2]`` (also ``robot1,robot2``), or []."""
    return [name.strip().strip('\'"') for name in text.strip().strip('[]').split(',')
            if name.strip().strip('\'"')]


def motion_parameters(motion):
    """Return the parameters of config/<motion>.yaml, for the motion's node wherever it runs."""
    path = os.path.join(get_package_share_directory(PACKAGE), 'config', motion + '.yaml')
    with open(path) as config:
        return yaml.safe_load(config)[motion]['ros__parameters']


def launch_actions(context):
    """Return the simulator, the motion (one per robot for a fleet) and RViz, as asked."""
    value = {name: LaunchConfiguration(name).perform(context) for name in (
        'namespace', 'params_file', 'robots', 'motion', 'real_time_factor', 'rviz', 'map')}
    namespace, motion = value['namespace'].strip('/'), value['motion']
    node_namespace = namespace or None  # (no namespace rather than an empty one)
    robots = robot_names(value['robots'])
    if motion and motion not in MOTIONS:
        raise RuntimeError(f"motion:='{motion}' is not one of {', '.join(MOTIONS)}")
    user_file = [value['params_file']] if value['params_file'] else []
    sim = {'publish_clock': True, 'real_time_factor': float(value['real_time_factor'])}
    if robots:
        sim['robots'] = robots
    if value['map']:  # absolute, as the simulator may not start where the launch was asked
        sim['map_file'] = os.path.abspath(os.path.expanduser(value['map']))
    actions = [Node(package=PACKAGE, executable='unicycle_sim', namespace=node_namespace,
                    output='screen', parameters=[sim, *user_file])]
    if motion:
        on_sim_time = {**motion_parameters(motion), 'use_sim_time': True}
        if robots:  # the fleet's parameters reach each of its motion nodes
            node = Node(package=PACKAGE, executable='motion_fleet', namespace=node_namespace,
                        output='screen', parameters=[
                            on_sim_time, {'robots': robots, 'motions': [motion]}, *user_file])
        else:
            node = Node(package=PACKAGE, executable=motion, namespace=node_namespace,
                        output='screen', parameters=[on_sim_time, *user_file])
        actions += [node, RegisterEventHandler(OnProcessExit(
            target_action=node,
            on_exit=[EmitEvent(event=Shutdown(reason=f'{motion} finished'))]))]
    if value['rviz'].lower() in ('true', '1', 'yes'):
        actions += rviz_actions(namespace, robots, with_map=bool(value['map']))
    return actions


def rviz_actions(namespace, robots, with_map=False):
    """
    Return RViz with the configuration for namespace and robots (and the fleet's frames).

    A fleet in a map is seen from the map frame, every odometry frame's parent already.
    """
    config = os.path.join(get_package_share_directory(PACKAGE), 'rviz', 'unicycle.rviz')
    actions = []
    fleet_in_map = bool(robots) and with_map
    if namespace or robots:
        with open(config) as template:
            text = rviz_config(template.read(), namespace, robots,
                               fixed_frame=MAP_FRAME if fleet_in_map else None)
        handle, config = tempfile.mkstemp(prefix='unicycle_', suffix='.rviz')
        with os.fdopen(handle, 'w') as generated:
            generated.write(text)
    if robots and not fleet_in_map:
        for view in robot_views(namespace, robots):
            actions.append(Node(
                package='tf2_ros', executable='static_transform_publisher',
                name=f"world_to_{view.odom_frame.replace('/', '_')}", output='log',
                arguments=['--frame-id', FLEET_FRAME, '--child-frame-id', view.odom_frame]))
    actions.append(Node(package='rviz2', executable='rviz2', arguments=['-d', config],
                        parameters=[{'use_sim_time': True}]))
    return actions


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('real_time_factor', default_value='1.0',
                              description='Simulated seconds per wall second (an upper bound '
                                          'in lockstep).'),
        DeclareLaunchArgument('motion', default_value='',
                              description='Also run this motion on simulated time (on every '
                                          'robot of robots), and shut down when it ends: '
                                          + ', '.join(MOTIONS)),
        DeclareLaunchArgument('rviz', default_value='false',
                              description='Also start RViz with rviz/unicycle.rviz (rewritten '
                                          'for namespace and robots).'),
        DeclareLaunchArgument('namespace', default_value='',
                              description='Namespace of every node: topics /<namespace>/odom, '
                                          'frames <namespace>/odom -> '
                                          '<namespace>/base_footprint.'),
        DeclareLaunchArgument('map', default_value='',
                              description='A map_server YAML (e.g. maps/room.yaml) for the '
                                          "simulator's map_file: the robots drive in that map, "
                                          'stop at its walls and scan it; RViz shows the map '
                                          "and each robot's scan. Empty = no map (the empty "
                                          'plane).'),
        DeclareLaunchArgument('params_file', default_value='',
                              description='ROS 2 parameters file for every node, applied after '
                                          "the launch's own values (e.g. "
                                          'config/unicycle_sim.yaml).'),
        DeclareLaunchArgument('robots', default_value='',
                              description='A fleet, e.g. [robot1,robot2]: one simulator for '
                                          'all, and motion on each with motion_fleet.'),
        OpaqueFunction(function=launch_actions),
    ])
