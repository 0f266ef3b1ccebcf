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
The shipped params files (config/<executable>.yaml) against the nodes that read them.

Each file must name only declared parameters, with values of the declared type, list every
parameter of its node, and hold the defaults (rotate_robot's three answers aside).
rotate_robot run from its params file as a user would, over DDS against the simulator, is in
test_motion_processes.py (its simulator process serves that run too).
"""

from pathlib import Path

from motion_challenges.circle_back_and_forth import CircleBackAndForth
from motion_challenges.odom_out_and_back import OdomOutAndBack
from motion_challenges.rotate_robot import RotateRobot
from motion_challenges.timed_out_and_back import TimedOutAndBack
import pytest
from sim_diffdrive.sim.node import UnicycleSim
import yaml

CONFIG = Path(__file__).resolve().parents[1] / 'config'

NODES = {
    'unicycle_sim': UnicycleSim,
    'rotate_robot': RotateRobot,
    'circle_back_and_forth': CircleBackAndForth,
    'timed_out_and_back': TimedOutAndBack,
    'odom_out_and_back': OdomOutAndBack,
}

# rclpy declares these on every node; a params file need not repeat them.
BUILT_IN = {'use_sim_time', 'start_type_description_service'}


def load(name):
    with open(CONFIG / f'{name}.yaml') as f:
        document = yaml.safe_load(f)
    assert list(document) == [name], 'the top-level key must be the node name'
    return document[name]['ros__parameters']


def parameters_of(node_class, context, cli_args=None):
    """Build the node, return {name: value} of its own parameters, destroy it."""
    node = node_class(context=context, cli_args=cli_args)
    try:
        names = set(node.list_parameters([], 0).names) - BUILT_IN
        return {name: node.get_parameter(name).value for name in names}
    finally:
        node.destroy_node()


def test_every_executable_has_a_params_file():
    # motion_fleet's speaks to several nodes; test_motion_fleet.py checks it against them.
    assert {path.stem for path in CONFIG.glob('*.yaml')} == set(NODES) | {'motion_fleet'}


@pytest.mark.parametrize('name', sorted(NODES))
def test_params_file_matches_the_node(ros_context, name):
    params = load(name)
    loaded = parameters_of(NODES[name], ros_context, cli_args=[
        '--ros-args', '--params-file', str(CONFIG / f'{name}.yaml')])
    defaults = parameters_of(NODES[name], ros_context)
    assert set(params) == set(loaded)
    for key, value in params.items():
        assert (loaded[key], type(loaded[key])) == (value, type(value)), key
        # Parameters without a default (rotate_robot's answers) are the file's to choose.
        if defaults[key] is not None:
            assert value == defaults[key], f'{key} is not the default'
