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
The simulator's odometry on /tf, and the tf2_msgs it needs.

One transform per odometry message, equal to it (stamp, frames, translation, rotation); frames
prefixed with the namespace when the simulator runs in one; nothing on /tf with publish_tf
false; tf2_msgs importable and serializable (in the wheel venv it is built by
tools/build_tf2_msgs.py); and /tf heard from the real executable in another process.
"""

import dataclasses
import math

from ament_index_python.packages import get_package_share_directory
from ament_index_python.resources import get_resource
from geometry_msgs.msg import TransformStamped
import numpy as np
import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from rclpy.serialization import serialize_message
from sim_diffdrive.cdr import TransformLayout
from sim_diffdrive.harness import pose_of
from sim_diffdrive.parameters import Spec
from sim_diffdrive.sim.node import UnicycleSim
from sim_diffdrive.sim.odom_tf import namespaced_frame
from sim_diffdrive.sim.odom_tf import resolve_frame
from sim_diffdrive.sim.odom_tf import TF_QOS
from sim_diffdrive.sim.odom_tf import TF_TOPIC
from tf2_msgs.msg import TFMessage


@pytest.mark.parametrize('frames', [
    [('odom', 'base_footprint')],
    [('a/odom', 'a/base_footprint'), ('robot12/odom', 'robot12/base_footprint'),
     ('o', 'b'), ('team_blue/robot7/odom', 'x')],  # every string length modulo 8
])
def test_the_tf_bytes_written_with_numpy_or_from_floats_are_what_rclpy_serializes(frames):
    count = len(frames)
    yaw = np.linspace(-3.1, 3.1, count)
    values = (12345, 678901234, np.linspace(-1e3, 7.5, count), np.linspace(2.0, -0.1, count),
              np.sin(yaw / 2), np.cos(yaw / 2))
    layout = TransformLayout(frames)
    raw = layout.serialize(*values)
    # From floats (a simulator of a few robots): the same bytes.
    assert layout.serialize(*values[:2], *(v.tolist() for v in values[2:])) == raw
    expected = TFMessage()
    for i, (frame, child) in enumerate(frames):
        transform = TransformStamped()
        transform.header.stamp.sec, transform.header.stamp.nanosec = values[:2]
        transform.header.frame_id, transform.child_frame_id = frame, child
        t, r = transform.transform.translation, transform.transform.rotation
        t.x, t.y, r.z, r.w = (float(v[i]) for v in values[2:])
        expected.transforms.append(transform)
    # (rclpy leaves whatever was in memory in the padding, so compare all but that.)
    assert len(raw) == len(serialize_message(expected))
    decoded = deserialize_message(raw, TFMessage)
    assert decoded == expected
    assert [(t.header.frame_id, t.child_frame_id) for t in decoded.transforms] == frames
    assert decoded.transforms[-1].transform.translation.x == values[2][-1]
    assert decoded.transforms[0].header.stamp.nanosec == 678901234


class TfListener(Node):
    """Record every TFMessage on /tf."""

    def __init__(self, **kwargs):
        super().__init__('tf_listener', **kwargs)
        self.messages = []
        self.create_subscription(TFMessage, TF_TOPIC, self.messages.append, TF_QOS)


def listen(graph):
    return graph.add(TfListener(context=graph.context))


def assert_equals_odometry(transform, odom):
    assert transform.header.stamp == odom.header.stamp
    assert transform.header.frame_id == odom.header.frame_id
    assert transform.child_frame_id == odom.child_frame_id
    t, p = transform.transform.translation, odom.pose.pose.position
    assert (t.x, t.y, t.z) == (p.x, p.y, p.z)
    r, q = transform.transform.rotation, odom.pose.pose.orientation
    assert (r.x, r.y, r.z, r.w) == (q.x, q.y, q.z, q.w)


def namespaced_sim(graph, namespace, **params):
    """Start a stepped simulator in namespace (SimGraph.sim() builds it in the root one)."""
    params = {'publish_clock': True, 'lockstep': False, 'real_time_factor': 10.0, **params}
    sim = UnicycleSim(stepped=True, namespace=namespace, context=graph.context,
                      parameter_overrides=[Parameter(name, value=value)
                                           for name, value in params.items()])
    return graph.add_clock_owner(sim)


# -- frames ------------------------------------------------------------------------------------

@pytest.mark.parametrize('namespace, frame, expected', [
    ('/', 'odom', 'odom'),
    ('', 'odom', 'odom'),
    ('/robot1', 'odom', 'robot1/odom'),
    ('/fleet/robot1', 'base_footprint', 'fleet/robot1/base_footprint'),
    ('/robot1/', 'odom', 'robot1/odom'),
])
def test_a_frame_gets_the_namespace_without_its_leading_slash(namespace, frame, expected):
    assert namespaced_frame(namespace, frame) == expected


def test_only_the_default_frame_is_prefixed():
    assert resolve_frame('/robot1', 'odom', 'odom') == 'robot1/odom'
    assert resolve_frame('/robot1', 'world', 'odom') == 'world'
    assert resolve_frame('/robot1', 'robot1/odom', 'odom') == 'robot1/odom'


# -- in process --------------------------------------------------------------------------------

def test_one_transform_per_odometry_equal_to_it_along_an_arc(graph):
    graph.sim(initial_x=0.5, initial_yaw=0.3, cmd_vel_timeout=0.0)
    tf = listen(graph)
    probe = graph.probe()
    graph.step_for(0.1)
    probe.send(0.4, 0.7)
    graph.step_for(2.0)
    assert len(probe.odoms) == 105
    assert len(tf.messages) == len(probe.odoms)
    for msg, odom in zip(tf.messages, probe.odoms):
        assert len(msg.transforms) == 1
        assert_equals_odometry(msg.transforms[0], odom)
    assert (tf.messages[-1].transforms[0].header.frame_id,
            tf.messages[-1].transforms[0].child_frame_id) == ('odom', 'base_footprint')
    # It did drive the arc: 2 s of (0.4 m/s, 0.7 rad/s) from (0.5, 0, 0.3 rad).
    x, y, yaw = pose_of(probe.odom)
    r = 0.4 / 0.7
    assert x == pytest.approx(0.5 + r * (math.sin(1.7) - math.sin(0.3)), abs=1e-9)
    assert y == pytest.approx(-r * (math.cos(1.7) - math.cos(0.3)), abs=1e-9)
    assert yaw == pytest.approx(1.7, abs=1e-9)


@pytest.mark.parametrize('frames, expected', [
    ({}, ('robot1/odom', 'robot1/base_footprint')),
    ({'odom_frame_id': 'world', 'base_frame_id': 'robot1/base_link'},
     ('world', 'robot1/base_link')),
])
def test_in_a_namespace_odometry_and_tf_carry_the_same_frames(graph, frames, expected):
    sim = namespaced_sim(graph, '/robot1', **frames)
    tf = listen(graph)  # in the root namespace: /tf is absolute
    probe = graph.probe(namespace='/robot1')
    graph.step_for(0.2)
    assert {pub.topic_name for pub in sim.publishers} >= {'/tf', '/robot1/odom'}
    assert (probe.odom.header.frame_id, probe.odom.child_frame_id) == expected
    assert len(tf.messages) == len(probe.odoms) == 10
    for msg, odom in zip(tf.messages, probe.odoms):
        assert_equals_odometry(msg.transforms[0], odom)


def test_publish_tf_false_publishes_nothing_on_tf(graph):
    sim = graph.sim(publish_tf=False)
    tf = listen(graph)
    probe = graph.probe()
    graph.step_for(0.5)
    assert len(probe.odoms) == 25
    assert tf.messages == []
    assert '/tf' not in {pub.topic_name for pub in sim.publishers}


@pytest.mark.skipif('live' not in {f.name for f in dataclasses.fields(Spec)},
                    reason='parameters have no read-only mechanism yet')
def test_publish_tf_is_read_only_at_runtime(graph):
    sim = graph.sim()
    result = sim.set_parameters([Parameter('publish_tf', value=False)])[0]
    assert not result.successful
    assert sim.get_parameter('publish_tf').value is True


# -- the tf2_msgs build --------------------------------------------------------------------------

def test_tf2_msgs_is_installed_and_round_trips_through_serialization():
    transform = TransformStamped()
    transform.header.stamp.sec, transform.header.stamp.nanosec = 12, 345
    transform.header.frame_id, transform.child_frame_id = 'robot1/odom', 'robot1/base_footprint'
    transform.transform.translation.x, transform.transform.translation.y = 1.25, -0.5
    transform.transform.rotation.z, transform.transform.rotation.w = 0.6, 0.8
    msg = TFMessage(transforms=[transform, TransformStamped()])
    data = serialize_message(msg)
    assert deserialize_message(data, TFMessage) == msg
    # rclpy and tools find interface packages through the ament index.
    assert 'msg/TFMessage.idl' in get_resource('rosidl_interfaces', 'tf2_msgs')[0].split()
    assert get_package_share_directory('tf2_msgs')


# Across processes: the executable's /tf, in a namespace, heard by another process is checked
# with its live parameters, one process for both (test_live_parameters.py,
# test_a_simulator_process_applies_a_live_set_and_refuses_a_read_only_one).
