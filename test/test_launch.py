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
params files it has; the RViz configuration is YAML with the displays the README promises.
Where `launch` is importable (a machine with ROS 2 Jazzy), the launch description is built too.
"""

import ast
import importlib.util
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
LAUNCH_FILE = ROOT / 'launch' / 'unicycle.launch.py'
RVIZ_FILE = ROOT / 'rviz' / 'unicycle.rviz'
ARGUMENTS = {'real_time_factor', 'motion', 'rviz'}


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
    return {line.split('=')[0].strip().strip("'") for line in text.splitlines()
            if ' = ' in line and ':main' in line}


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
    assert started == {'unicycle_sim', 'rviz2'}


def test_the_rviz_configuration_shows_the_robot_from_odom():
    config = yaml.safe_load(RVIZ_FILE.read_text())
    manager = config['Visualization Manager']
    assert manager['Global Options']['Fixed Frame'] == 'odom'
    displays = {d['Class']: d for d in manager['Displays']}
    assert displays['rviz_default_plugins/Odometry']['Topic']['Value'] == '/odom'
    assert displays['rviz_default_plugins/Path']['Topic']['Value'] == '/path'
    assert 'rviz_default_plugins/TF' in displays
    assert displays['rviz_default_plugins/Axes']['Reference Frame'] == 'base_footprint'


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
