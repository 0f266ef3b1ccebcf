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
launch/unicycle.launch.py and rviz/unicycle.rviz, checked where they can be.

`launch` and RViz are not on PyPI, so the wheel environment checks the files themselves: the
launch file parses, declares its arguments, starts executables this package installs with the
params files it has; the RViz configuration is YAML with the displays the README promises, on
relative topics, and its copies for a namespace or a fleet name the frames and topics that a
real simulator there uses.  Where `launch` is importable (a machine with ROS 2 Jazzy), the
launch description is built too.
"""

import ast
import importlib.util
from pathlib import Path
import re

import pytest
from sim_diffdrive.taps.rviz_config import FLEET_FRAME
from sim_diffdrive.taps.rviz_config import robot_views
from sim_diffdrive.taps.rviz_config import rviz_config
import yaml

ROOT = Path(__file__).resolve().parents[1]
LAUNCH_FILE = ROOT / 'launch' / 'unicycle.launch.py'
RVIZ_FILE = ROOT / 'rviz' / 'unicycle.rviz'
ARGUMENTS = {'real_time_factor', 'motion', 'rviz', 'namespace', 'params_file', 'robots', 'map'}


def launch_tree():
    return ast.parse(LAUNCH_FILE.read_text(), filename=str(LAUNCH_FILE))


def calls(tree, name):
    return [node for node in ast.walk(tree) if isinstance(node, ast.Call)
            and getattr(node.func, 'id', getattr(node.func, 'attr', None)) == name]


def keyword(call, name):
    return next((k.value for k in call.keywords if k.arg == name), None)


def executables():
    """Return the console_scripts of setup.py, read from its source (no setuptools run)."""
    text = (ROOT / 'setup.py').read_text()
    return set(re.findall(r"'(\w+) = [\w.]+:\w+'", text))


def test_the_launch_file_declares_its_arguments_and_a_generate_function():
    tree = launch_tree()
    assert any(isinstance(node, ast.FunctionDef) and node.name == 'generate_launch_description'
               for node in tree.body)
    declared = {call.args[0].value for call in calls(tree, 'DeclareLaunchArgument')}
    assert declared == ARGUMENTS


def test_the_launch_file_starts_what_this_package_installs():
    tree = launch_tree()
    motions = next(node.value for node in tree.body if isinstance(node, ast.Assign)
                   and node.targets[0].id == 'MOTIONS')
    motions = {element.value for element in motions.elts}
    installed = executables()
    assert motions | {'unicycle_sim'} <= installed, installed
    for motion in motions:  # each motion runs with its params file
        assert (ROOT / 'config' / f'{motion}.yaml').is_file(), motion
    started = {keyword(call, 'executable').value for call in calls(tree, 'Node')
               if isinstance(keyword(call, 'executable'), ast.Constant)}
    assert started == {'unicycle_sim', 'motion_fleet', 'rviz2', 'static_transform_publisher'}
    assert 'motion_fleet' in installed


def displays_of(config):
    return {d['Name']: d for d in config['Visualization Manager']['Displays']}


def test_the_rviz_configuration_shows_the_robot_from_odom_on_relative_topics():
    config = yaml.safe_load(RVIZ_FILE.read_text())
    manager = config['Visualization Manager']
    assert manager['Global Options']['Fixed Frame'] == 'odom'
    displays = {d['Class']: d for d in manager['Displays']}
    # Relative, so RViz started in a namespace (/robot1) reads that robot's topics.
    assert displays['rviz_default_plugins/Odometry']['Topic']['Value'] == 'odom'
    assert displays['rviz_default_plugins/Path']['Topic']['Value'] == 'path'
    assert 'rviz_default_plugins/TF' in displays
    assert displays['rviz_default_plugins/Axes']['Reference Frame'] == 'base_footprint'
    assert displays['rviz_default_plugins/LaserScan']['Topic']['Value'] == 'scan'
    the_map = displays['rviz_default_plugins/Map']['Topic']
    assert (the_map['Value'], the_map['Durability Policy']) == ('map', 'Transient Local')
    tools = {tool['Class']: tool for tool in manager['Tools']}
    assert tools['rviz_default_plugins/SetInitialPose']['Topic']['Value'] == 'initialpose'


def test_the_rviz_configuration_for_a_namespace_uses_its_frames_and_topics():
    config = yaml.safe_load(rviz_config(RVIZ_FILE.read_text(), '/robot1'))
    manager = config['Visualization Manager']
    assert manager['Global Options']['Fixed Frame'] == 'robot1/odom'
    displays = displays_of(config)
    assert displays['Odometry']['Topic']['Value'] == '/robot1/odom'
    assert displays['Driven path']['Topic']['Value'] == '/robot1/path'
    assert displays['Robot']['Reference Frame'] == 'robot1/base_footprint'
    assert displays['LaserScan']['Topic']['Value'] == '/robot1/scan'
    assert displays['Map']['Topic']['Value'] == '/robot1/map'
    assert displays['Map']['Update Topic']['Value'] == '/robot1/map_updates'
    assert displays['Grid']['Reference Frame'] == '<Fixed Frame>'
    tools = {tool['Class']: tool for tool in manager['Tools']}
    assert tools['rviz_default_plugins/SetInitialPose']['Topic']['Value'] == '/robot1/initialpose'
    assert rviz_config(RVIZ_FILE.read_text(), 'robot1') == rviz_config(
        RVIZ_FILE.read_text(), '/robot1/')


def test_the_rviz_configuration_for_a_fleet_shows_every_robot_from_world():
    config = yaml.safe_load(rviz_config(RVIZ_FILE.read_text(), '', ['robot1', 'robot2']))
    manager = config['Visualization Manager']
    assert manager['Global Options']['Fixed Frame'] == FLEET_FRAME == 'world'
    displays = displays_of(config)
    for robot in ('robot1', 'robot2'):
        assert displays[f'Odometry {robot}']['Topic']['Value'] == f'/{robot}/odom'
        assert displays[f'Driven path {robot}']['Topic']['Value'] == f'/{robot}/path'
        assert displays[f'Robot {robot}']['Reference Frame'] == f'{robot}/base_footprint'
        assert displays[f'LaserScan {robot}']['Topic']['Value'] == f'/{robot}/scan'
    assert displays['Map']['Topic']['Value'] == '/map'  # one map for the fleet
    assert len(displays) == 3 + 4 * 2  # grid, map and TF once, four displays per robot
    # A pose set in RViz is in its fixed frame, world, which no robot takes: no pose tool.
    assert [tool['Class'] for tool in manager['Tools']] == ['rviz_default_plugins/MoveCamera']
    in_map = yaml.safe_load(rviz_config(RVIZ_FILE.read_text(), '', ['robot1'], fixed_frame='map'))
    assert in_map['Visualization Manager']['Global Options']['Fixed Frame'] == 'map'


@pytest.mark.parametrize('namespace, robots', [
    ('', []), ('/robot1', []), ('', ['robot1', 'robot2']), ('/site', ['a', 'team/b'])])
def test_the_rviz_frames_and_topics_are_the_simulators(ros_context, namespace, robots):
    from rclpy.parameter import Parameter
    from sim_diffdrive.sim.node import UnicycleSim
    room = str(ROOT / 'maps' / 'room.yaml')
    apart = [value for i in range(len(robots)) for value in (0.5 * i, 0.0, 0.0)]  # in the room
    overrides = [Parameter('robots', value=robots), Parameter('map_file', value=room)]
    if robots:
        overrides.append(Parameter('initial_poses', value=apart))
    sim = UnicycleSim(context=ros_context, namespace=namespace or None,
                      parameter_overrides=overrides)
    try:
        views = robot_views(namespace, robots)
        for robot, view, scan_pub in zip(sim.robots, views, sim.surroundings.scan_pubs,
                                         strict=True):
            assert (view.odom_frame, view.base_frame) == robot.frames
            assert f'{view.topics}/odom' == robot.odom_pub.topic_name
            assert f'{view.topics}/path' == robot.path_pub.topic_name
            assert f'{view.topics}/scan' == scan_pub.topic_name
        config = yaml.safe_load(rviz_config(RVIZ_FILE.read_text(), namespace, robots))
        the_map = displays_of(config)['Map']['Topic']['Value']
        assert the_map.lstrip('/') == sim.surroundings._map_pub.topic_name.lstrip('/')
    finally:
        sim.destroy_node()


@pytest.mark.skipif(importlib.util.find_spec('launch') is None
                    or importlib.util.find_spec('launch_ros') is None,
                    reason='launch and launch_ros are not on PyPI: run on a ROS 2 Jazzy machine')
def test_the_launch_description_builds_where_launch_exists():
    from launch.actions import DeclareLaunchArgument
    spec = importlib.util.spec_from_file_location('unicycle_launch', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    declared = {entity.name for entity in description.entities
                if isinstance(entity, DeclareLaunchArgument)}
    assert declared == ARGUMENTS
    assert module.robot_names('[robot1, robot2]') == ['robot1', 'robot2']
    assert module.robot_names("['robot1','robot2']") == ['robot1', 'robot2']
    assert module.robot_names('robot1,robot2') == ['robot1', 'robot2']
    assert module.robot_names('') == module.robot_names('[]') == []
