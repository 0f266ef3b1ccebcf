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
Stamped commands: motions that publish TwistStamped, and a simulator on another's clock.

In one process, stepped in lockstep by the test (see sim_diffdrive/testing/).
"""

import math

from geometry_msgs.msg import TwistStamped
from motion_challenges.odom_out_and_back import OdomOutAndBack
from motion_challenges.timed_out_and_back import TimedOutAndBack
from nav_msgs.msg import Odometry
import pytest
from rclpy.node import Node
from rclpy.time import Time
from sim_diffdrive.harness import angle_error
from sim_diffdrive.harness import pose_of
from sim_diffdrive.sim.node import UnicycleSim

STEP_NS = 20_000_000  # the simulators' default 50 Hz


class Driver(Node):
    """Sends TwistStamped commands and records odometry, in the namespace of one robot."""

    def __init__(self, namespace, **kwargs):
        super().__init__('driver', namespace=namespace, **kwargs)
        self.odoms = []
        self.create_subscription(Odometry, 'odom', self.odoms.append, 100)
        self.cmd_pub = self.create_publisher(TwistStamped, 'cmd_vel', 10)

    def send(self, angular, stamp_ns):
        msg = TwistStamped()
        msg.header.stamp = Time(nanoseconds=stamp_ns).to_msg()
        msg.twist.angular.z = angular
        self.cmd_pub.publish(msg)

    def yaw_at(self, stamp_ns):
        for odom in self.odoms:
            if odom.header.stamp.sec * 1_000_000_000 + odom.header.stamp.nanosec == stamp_ns:
                return pose_of(odom)[2]
        raise AssertionError(f'no odometry stamped {stamp_ns}')


@pytest.mark.parametrize('node_class', [TimedOutAndBack, OdomOutAndBack])
def test_stamped_motions_end_exact_against_a_stamped_simulator(graph, node_class):
    graph.sim(stamped=True, initial_yaw=0.5)
    watcher = graph.node(Driver, namespace='/')
    # Short legs and a quick turn: the stamps are what is tested, not the defaults
    # (test_motions_graph.py runs those).
    node = graph.node(node_class, stamped=True, goal_distance=0.3, pause=0.1,
                      angular_speed=2.0)
    graph.step_until(lambda: node.done, 40.0)
    graph.step_for(0.2)
    assert node.exit_code == 0
    x, y, yaw = pose_of(watcher.odoms[-1])
    assert math.hypot(x, y) < 1e-9 and angle_error(yaw, 0.5) < 1e-9
    # And it went out: back at the start is where a robot that never moved is too.
    far = max(math.hypot(*pose_of(odom)[:2]) for odom in watcher.odoms)
    assert far == pytest.approx(0.3, abs=1e-6)


def test_a_command_stamped_ahead_of_the_clock_waits_for_its_step(graph):
    """A simulator on another's clock applies a command at its stamp, not when it arrives."""
    graph.sim()
    graph.node(UnicycleSim, namespace='/robot1', stamped=True)
    driver = graph.node(Driver, namespace='/robot1')
    graph.step_for(0.1)
    now_ns = graph.now_ns
    # Sent for the next step, whose /clock has not reached the robot's simulator yet.
    driver.send(1.0, now_ns + STEP_NS)
    graph.spin_for(0.3)  # delivered; the clock does not move while the test does not step
    graph.step(5)
    assert driver.yaw_at(now_ns + STEP_NS) == 0.0
    assert driver.yaw_at(now_ns + 5 * STEP_NS) == pytest.approx(4 * STEP_NS * 1e-9, abs=1e-12)
    # A command stamped at the robot's own time takes effect at once, as before.
    driver.send(0.0, graph.now_ns)
    graph.step(2)
    assert driver.odoms[-1].twist.twist.angular.z == 0.0
