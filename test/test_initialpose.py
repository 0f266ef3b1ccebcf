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
``initialpose`` (RViz's "2D Pose Estimate") sets a robot down there, at rest, in one process.

Each robot subscribes ``initialpose`` in its namespace (``<name>/initialpose`` in a fleet); a
pose in another frame than the robot's odometry frame, or with an unusable value, is refused
and the robot stays where it is.
"""

import math

from geometry_msgs.msg import PoseWithCovarianceStamped
import pytest
from rclpy.node import Node
from sim_diffdrive.angles import quaternion_from_yaw
from sim_diffdrive.harness import angle_error
from sim_diffdrive.harness import pose_of
from sim_diffdrive.harness import twist_of
from std_srvs.srv import Empty


def pose_estimate(frame, x, y, yaw):
    msg = PoseWithCovarianceStamped()
    msg.header.frame_id = frame
    msg.pose.pose.position.x = x
    msg.pose.pose.position.y = y
    q = msg.pose.pose.orientation
    q.x, q.y, q.z, q.w = quaternion_from_yaw(yaw)
    return msg


def rviz(graph, topic):
    """Add a node that publishes on topic as RViz's 2D Pose Estimate does; return its publisher."""
    node = graph.add(Node('rviz', context=graph.context))
    publisher = node.create_publisher(PoseWithCovarianceStamped, topic, 10)
    graph.step()  # discovery
    return publisher


def drive(graph, probe, linear, angular, seconds):
    probe.send(linear, angular)
    graph.step_for(seconds)


def test_initialpose_sets_the_robot_there_at_rest(graph):
    graph.sim(cmd_vel_timeout=0.0)
    probe = graph.probe()
    publisher = rviz(graph, 'initialpose')
    drive(graph, probe, 0.5, 0.3, 1.0)
    assert twist_of(graph.odom()) == (0.5, 0.3)
    publisher.publish(pose_estimate('odom', 2.0, -1.5, 2.5))
    graph.step_for(0.5)
    x, y, yaw = graph.pose()
    assert (x, y) == (2.0, -1.5)
    assert angle_error(yaw, 2.5) < 1e-12
    assert twist_of(graph.odom()) == (0.0, 0.0)
    # From there the robot drives as from a start: 1 s at 0.4 m/s along its heading.
    drive(graph, probe, 0.4, 0.0, 1.0)
    x, y, _ = graph.pose()
    assert x == pytest.approx(2.0 + 0.4 * math.cos(2.5), abs=1e-9)
    assert y == pytest.approx(-1.5 + 0.4 * math.sin(2.5), abs=1e-9)


def test_initialpose_moves_only_its_own_robot_of_a_fleet(graph):
    graph.sim(robots=['robot1', 'robot2'], initial_poses=[0.0, 0.0, 0.0, 1.0, 1.0, 0.0])
    publisher = rviz(graph, '/robot2/initialpose')
    publisher.publish(pose_estimate('robot2/odom', -3.0, 4.0, -1.0))
    graph.step_for(0.2)
    assert graph.pose('robot1') == (0.0, 0.0, 0.0)
    x, y, yaw = graph.pose('robot2')
    assert (x, y) == (-3.0, 4.0) and angle_error(yaw, -1.0) < 1e-12


@pytest.mark.parametrize('frame, x, yaw', [
    ('map', 1.0, 0.0),  # not the odometry frame
    ('', 1.0, 0.0),  # no frame at all
    ('odom', math.nan, 0.0),
    ('odom', 1e9, 0.0),
])
def test_an_unusable_initialpose_is_refused(graph, frame, x, yaw):
    graph.sim(initial_x=0.5)
    publisher = rviz(graph, 'initialpose')
    publisher.publish(pose_estimate(frame, x, 0.0, yaw))
    graph.step_for(0.2)
    assert pose_of(graph.odom()) == (0.5, 0.0, 0.0)


def test_a_quaternion_of_any_finite_size_gives_its_heading(graph):
    # A product of two components of 1e200 overflows: the heading was NaN, and with a map the
    # next step ended the simulator.
    graph.sim(initial_x=0.5)
    publisher = rviz(graph, 'initialpose')
    msg = pose_estimate('odom', 1.0, 1.0, 0.0)
    msg.pose.pose.orientation.z = msg.pose.pose.orientation.w = 1e200
    publisher.publish(msg)
    graph.step_for(0.2)
    x, y, yaw = pose_of(graph.odom())
    assert (x, y) == (1.0, 1.0) and yaw == pytest.approx(math.pi / 2, abs=1e-15)


def test_a_zero_quaternion_is_refused(graph):
    graph.sim(initial_x=0.5)
    publisher = rviz(graph, 'initialpose')
    msg = pose_estimate('odom', 1.0, 1.0, 0.0)
    msg.pose.pose.orientation.w = 0.0
    publisher.publish(msg)
    graph.step_for(0.2)
    assert pose_of(graph.odom()) == (0.5, 0.0, 0.0)


def test_the_new_pose_comes_with_the_next_step_never_a_stamp_twice(graph):
    # A second odometry (and /tf) at the stamp of a step already out, with another pose: tf2
    # drops it (TF_REPEATED_DATA), and a listener in lockstep may act on the first.
    graph.sim(cmd_vel_timeout=0.0)
    probe = graph.probe()
    publisher = rviz(graph, 'initialpose')
    reset = probe.create_client(Empty, '/unicycle_sim/reset')
    drive(graph, probe, 0.5, 0.3, 0.2)
    publisher.publish(pose_estimate('odom', 2.0, -1.5, 2.5))
    graph.step_for(0.2)
    assert graph.pose()[:2] == (2.0, -1.5)
    assert graph.spin_until(reset.call_async(Empty.Request()).done, timeout=10.0)
    graph.step_for(0.2)
    assert graph.pose() == (0.0, 0.0, 0.0)
    stamps = [probe.odoms.stamp_ns(i) for i in range(len(probe.odoms))]
    assert len(stamps) > 20 and all(b > a for a, b in zip(stamps, stamps[1:])), stamps
