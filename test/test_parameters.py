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

"""Parameter tables: descriptors, conversions and refusals that name the parameter."""

import math

import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from sim_diffdrive.parameters import declare
from sim_diffdrive.parameters import frame_problem
from sim_diffdrive.parameters import ParameterError
from sim_diffdrive.parameters import Spec
from sim_diffdrive.sim.node import UnicycleSim

SPEED = Spec('speed', 0.5, 'Forward speed [m/s].', low=0.0, high=2.0)
RATE = Spec('rate', 10.0, 'Tick rate [Hz].', low=0.0, high=100.0, low_open=True)
COUNT = Spec('count', 3, 'How many laps.', low=1, high=10)
FLAG = Spec('flag', False, 'Say more.')
MODE = Spec('mode', 'timed', 'How to know when to stop.', choices=('timed', 'odom'))
COVARIANCE = Spec('covariance', [0.1, 0.1, 0.1], 'Diagonal.', low=0.0, high=1.0, length=3)
GOAL = Spec('goal', None, 'Angle to turn [rad]; asked for when unset.', kind=float,
            low=-100.0, high=100.0)
TABLE = (SPEED, RATE, COUNT, FLAG, MODE, COVARIANCE, GOAL)


@pytest.fixture
def make_node(ros_context):
    nodes = []

    def make(*overrides, node_class=Node, **kwargs):
        if node_class is Node:
            kwargs.setdefault('node_name', 'parameter_test')
        node = node_class(context=ros_context, parameter_overrides=[
            Parameter(name, value=value) for name, value in overrides], **kwargs)
        nodes.append(node)
        return node
    try:
        yield make
    finally:
        for node in nodes:
            node.destroy_node()


def declare_with(make_node, *overrides, specs=TABLE):
    node = make_node(*overrides)
    return node, declare(node, specs)


def refusal(make_node, name, value, specs=TABLE):
    with pytest.raises(ParameterError) as info:
        declare_with(make_node, (name, value), specs=specs)
    message = str(info.value)
    assert f"'{name}'" in message
    return message


def test_a_parameter_spelt_like_one_of_the_nodes_is_warned_about_others_are_not(
        make_node, capfd):
    # rclpy ignores them all without a word; one like none of the node's is another node's
    # (a params file's /** section, -p in a process of several nodes).
    _, values = declare_with(make_node, ('sped', 1.0), ('rates', 5.0), ('speed', 1.5),
                             ('linear_velocity', 1), ('mdoe', 'odom'), ('z', 1))
    err = capfd.readouterr().err
    assert "Ignoring parameter 'mdoe'" in err  # four letters, one off: 0.75 alike
    assert ("Ignoring parameter 'sped': parameter_test has none by that name (did you mean "
            "'speed'?)") in err
    assert "Ignoring parameter 'rates'" in err and "(did you mean 'rate'?)" in err
    assert 'linear_velocity' not in err and "'speed':" not in err and "'z'" not in err
    assert values.speed == 1.5


def test_a_misspelt_simulator_parameter_is_warned_about_and_leaves_the_default(
        make_node, capfd):
    sim = make_node(node_class=UnicycleSim, cli_args=[
        '--ros-args', '-p', 'initail_x:=1.0', '-p', 'use_sim_tme:=true'])
    err = capfd.readouterr().err
    assert "Ignoring parameter 'initail_x'" in err
    assert "Ignoring parameter 'use_sim_tme'" in err and "(did you mean 'use_sim_time'?)" in err
    assert sim.params.initial_x == 0.0


@pytest.mark.parametrize('value,why', [('', 'must name a frame'), ('/base', "start with '/'"),
                                       ('base link', 'whitespace')])
def test_a_frame_parameter_takes_only_what_tf2_takes(make_node, value, why):
    # A motion's frame_id took '' and '/base', which the simulator refuses for its frames.
    frame = Spec('frame', 'base', 'A frame.', problem=frame_problem, live=True)
    assert why in refusal(make_node, 'frame', value, specs=(frame,))


def test_defaults(make_node):
    node, values = declare_with(make_node)
    assert values.speed == 0.5
    assert values.rate == 10.0
    assert values.count == 3
    assert values.flag is False
    assert values.mode == 'timed'
    assert values.covariance == [0.1, 0.1, 0.1]
    assert values.goal is None
    assert node.get_parameter('goal').type_ == Parameter.Type.NOT_SET
    assert node.get_parameter('speed').value == 0.5


def test_integer_accepted_for_float_and_stored_as_float(make_node):
    node, values = declare_with(make_node, ('speed', 1), ('goal', -2))
    assert values.speed == 1.0 and type(values.speed) is float
    assert values.goal == -2.0 and type(values.goal) is float
    for name, value in (('speed', 1.0), ('goal', -2.0)):
        stored = node.get_parameter(name)
        assert stored.type_ == Parameter.Type.DOUBLE
        assert stored.value == value


def test_integer_array_accepted_for_float_array_and_stored_as_floats(make_node):
    node, values = declare_with(make_node, ('covariance', [1, 0, 1]))
    assert values.covariance == [1.0, 0.0, 1.0]
    assert all(type(v) is float for v in values.covariance)
    stored = node.get_parameter('covariance')
    assert stored.type_ == Parameter.Type.DOUBLE_ARRAY
    assert list(stored.value) == [1.0, 0.0, 1.0]


@pytest.mark.parametrize('name,value', [
    ('speed', 0.0), ('speed', 2.0), ('speed', 1.25), ('rate', 1e-9), ('rate', 100.0),
    ('count', 1), ('count', 10), ('goal', -100.0), ('goal', 0.0)])
def test_values_in_range_and_on_closed_bounds_accepted(make_node, name, value):
    node, values = declare_with(make_node, (name, value))
    assert getattr(values, name) == value
    assert node.get_parameter(name).value == value


@pytest.mark.parametrize('name,value', [
    ('speed', -0.1), ('speed', 2.0000001), ('count', 0), ('count', 11), ('goal', 100.5),
    ('rate', 1000.0)])
def test_out_of_range_refused_with_the_range(make_node, name, value):
    message = refusal(make_node, name, value)
    assert 'must be in' in message
    assert repr(value) in message


def test_low_open_refused_at_the_bound(make_node):
    message = refusal(make_node, 'rate', 0.0)
    assert '(0.0, 100.0]' in message
    assert 'rate' in refusal(make_node, 'rate', 0)
    assert 'rate' in refusal(make_node, 'rate', -1.0)


@pytest.mark.parametrize('name,value,why', [
    ('speed', 'fast', 'must be a number'),
    ('speed', True, 'must be a number'),
    ('speed', [0.1], 'must be a number'),
    ('count', 2.5, 'must be an integer'),
    ('count', '3', 'must be a number'),
    ('flag', 1, 'must be true or false'),
    ('flag', 0.0, 'must be true or false'),
    ('flag', 'yes', 'must be true or false'),
    ('mode', 3, 'must be a string'),
    ('mode', True, 'must be a string'),
    ('covariance', 0.5, 'must be a list of numbers'),
    ('covariance', 'a,b,c', 'must be a list of numbers'),
    ('covariance', [True, False, True], 'must be a number'),
    ('goal', 'half a turn', 'must be a number'),
])
def test_wrong_type_refused(make_node, name, value, why):
    assert why in refusal(make_node, name, value)


@pytest.mark.parametrize('name,value', [
    ('speed', math.nan), ('goal', math.nan), ('goal', math.inf), ('goal', -math.inf),
    ('covariance', [0.1, math.nan, 0.1])])
def test_non_finite_refused(make_node, name, value):
    assert 'finite' in refusal(make_node, name, value)


def test_non_finite_refused_without_a_range(make_node):
    unbounded = Spec('gain', 1.0, 'A gain without a range.')
    assert 'finite' in refusal(make_node, 'gain', math.inf, specs=(unbounded,))
    assert 'finite' in refusal(make_node, 'gain', math.nan, specs=(unbounded,))


@pytest.mark.parametrize('value', [[], [0.1, 0.2], [0.1, 0.2, 0.3, 0.4]])
def test_array_length_checked(make_node, value):
    assert 'exactly 3 values' in refusal(make_node, 'covariance', value)


def test_array_elements_range_checked(make_node):
    assert 'must be in [0.0, 1.0]' in refusal(make_node, 'covariance', [0.1, 1.5, 0.1])
    assert 'must be in [0.0, 1.0]' in refusal(make_node, 'covariance', [-0.1, 0.5, 0.1])


def test_choices_enforced(make_node):
    _, values = declare_with(make_node, ('mode', 'odom'))
    assert values.mode == 'odom'
    message = refusal(make_node, 'mode', 'fast')
    assert 'one of timed, odom' in message
    assert "'fast'" in message
    assert 'mode' in refusal(make_node, 'mode', 'Timed')


def test_first_bad_parameter_is_named(make_node):
    with pytest.raises(ParameterError, match="'count'"):
        declare_with(make_node, ('count', 0), ('mode', 'fast'))


def test_descriptor_carries_description_and_range(make_node):
    node, _ = declare_with(make_node)
    speed = node.describe_parameter('speed')
    assert speed.description == 'Forward speed [m/s]. Read-only: set at start.'
    assert speed.read_only
    assert [(r.from_value, r.to_value) for r in speed.floating_point_range] == [(0.0, 2.0)]
    assert not speed.integer_range
    assert '[0.0, 2.0]' in speed.additional_constraints

    assert '(0.0, 100.0]' in node.describe_parameter('rate').additional_constraints

    count = node.describe_parameter('count')
    assert count.description == 'How many laps. Read-only: set at start.'
    assert [(r.from_value, r.to_value, r.step) for r in count.integer_range] == [(1, 10, 1)]
    assert not count.floating_point_range

    covariance = node.describe_parameter('covariance')
    assert [(r.from_value, r.to_value) for r in covariance.floating_point_range] == [(0.0, 1.0)]
    assert '3 values' in covariance.additional_constraints

    mode = node.describe_parameter('mode')
    assert mode.description == 'How to know when to stop. Read-only: set at start.'
    assert 'one of timed, odom' in mode.additional_constraints
    assert not mode.floating_point_range and not mode.integer_range

    goal = node.describe_parameter('goal')
    assert goal.description.startswith('Angle to turn')
    assert [(r.from_value, r.to_value) for r in goal.floating_point_range] == [(-100.0, 100.0)]


def test_read_only_unless_live(make_node):
    live_speed = Spec('speed', 0.5, 'Forward speed [m/s].', low=0.0, high=2.0, live=True)
    node, values = declare_with(make_node, specs=(live_speed, RATE))
    refused = node.set_parameters([Parameter('rate', value=20.0)])[0]
    assert not refused.successful and 'read-only' in refused.reason
    assert node.get_parameter('rate').value == 10.0
    assert not node.set_parameters([Parameter('speed', value=5.0)])[0].successful
    assert node.get_parameter('speed').value == 0.5
    assert node.set_parameters([Parameter('speed', value=1.5)])[0].successful
    assert values.speed == 1.5
    assert node.describe_parameter('speed').description == 'Forward speed [m/s].'


# -- the simulator refuses bad values at start ---------------------------------------------------

@pytest.mark.parametrize('name,value', [
    ('rate_hz', -1.0), ('rate_hz', 0.0), ('rate_hz', 'fast'), ('cmd_vel_timeout', -0.5),
    ('real_time_factor', 0.0), ('max_linear_speed', math.nan), ('initial_yaw', math.inf),
    ('pose_covariance_diagonal', [0.1, 0.1]), ('stamped', 1)])
def test_simulator_refuses_a_bad_value_at_start(make_node, name, value):
    with pytest.raises(ParameterError, match=f"'{name}'"):
        make_node((name, value), node_class=UnicycleSim)


def test_simulator_refuses_publish_clock_with_use_sim_time(make_node):
    with pytest.raises(ParameterError) as info:
        make_node(('publish_clock', True), ('use_sim_time', True), node_class=UnicycleSim)
    assert 'publish_clock' in str(info.value)
    assert 'use_sim_time' in str(info.value)


def test_simulator_accepts_integers_for_floats(make_node):
    sim = make_node(('rate_hz', 20), ('initial_x', 1), node_class=UnicycleSim)
    assert sim.params.rate_hz == 20.0
    assert sim.get_parameter('rate_hz').type_ == Parameter.Type.DOUBLE
    assert (sim.world.x[0], sim.world.y[0]) == (1.0, 0.0)
    assert sim.describe_parameter('rate_hz').description.startswith('Odometry publish rate')
