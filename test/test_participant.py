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


"""A node's side of the lockstep: what take_part() counts and when it answers."""

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.time import Time
from sim_diffdrive.participant import take_part


@pytest.fixture
def node(ros_context):
    node = Node('controller', context=ros_context,
                parameter_overrides=[Parameter('use_sim_time', value=True)])
    try:
        yield node
    finally:
        node.destroy_node()


def test_counts_what_the_node_publishes_and_handles(node):
    pub = node.create_publisher(Twist, 'cmd_vel', 10)
    heard = []
    sub = node.create_subscription(Odometry, 'odom', heard.append, 10)
    lockstep = take_part(node)
    pub.publish(Twist())
    pub.publish(Twist())
    odom = Odometry()
    odom.header.stamp = Time(seconds=3).to_msg()
    sub.callback(odom)
    counter = lockstep.counter
    assert counter.sent == {'/cmd_vel': 2}
    assert counter.heard == {'/odom': 1} and heard == [odom]
    assert counter.heard_stamp == {'/odom': 3_000_000_000}


def test_a_timer_runs_once_per_clock_time_however_often_its_event_comes(node):
    ticks = []
    timer = node.create_timer(0.1, lambda: ticks.append(node.get_clock().now().nanoseconds))
    take_part(node)
    node.get_clock().set_ros_time_override(Time(seconds=5))
    for _ in range(3):  # what a loaded EventsExecutor can deliver for one period
        timer.callback()
    assert ticks == [5_000_000_000]
    # The period starts again at this time, not three periods later.
    assert timer.time_until_next_call() == 100_000_000


def test_take_part_needs_sim_time(ros_context):
    node = Node('wall', context=ros_context)
    try:
        with pytest.raises(ValueError, match='use_sim_time is false'):
            take_part(node)
    finally:
        node.destroy_node()
