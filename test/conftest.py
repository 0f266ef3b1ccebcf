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
Launch-free test harness: a fresh rclpy Context per test, one executor, bounded spinning.

Every test run picks its own ROS domain and keeps discovery on localhost, so parallel runs
on one machine (and the subprocesses they start) never hear each other.
"""

import math
import os
import random

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sim_diffdrive.angles import yaw_from_quaternion
from sim_diffdrive.lockstep import Lockstep
from sim_diffdrive.sim_node import UnicycleSim

# Fast DDS maps a domain to UDP ports; 1..100 stays clear of 0 (everyone's default) and of the
# top of the valid range.  Chosen once per test run and inherited by subprocesses.
os.environ.setdefault('ROS_DOMAIN_ID', str(random.SystemRandom().randint(1, 100)))
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('RCUTILS_LOGGING_BUFFERED_STREAM', '0')
DOMAIN_ID = int(os.environ['ROS_DOMAIN_ID'])

# Simulated seconds per wall second in graph tests: fast, with a wide margin for a command to
# cross the graph before the simulator's next clock step.
TEST_REAL_TIME_FACTOR = 10.0


def pose_of(odom):
    """Return (x, y, yaw) of an Odometry message."""
    p = odom.pose.pose
    return p.position.x, p.position.y, yaw_from_quaternion(
        p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w)


def stamp_s(odom):
    return odom.header.stamp.sec + odom.header.stamp.nanosec * 1e-9


def angle_error(a, b):
    return abs(math.remainder(a - b, 2.0 * math.pi))


class Graph(Lockstep):
    """The nodes of one test, spun by one executor in this process (see Lockstep)."""

    def __init__(self, context):
        super().__init__(SingleThreadedExecutor(context=context))
        self.context = context

    def sim(self, lockstep=True, **params):
        """
        Start a simulator that owns time (publish_clock) with the given parameters.

        In lockstep (the default) the test, not the wall clock, steps simulated time; see
        sim_diffdrive.lockstep.
        """
        params.setdefault('publish_clock', True)
        params.setdefault('real_time_factor', TEST_REAL_TIME_FACTOR)
        # The test steps the clock itself (see sim_diffdrive.lockstep), not the handshake.
        params.setdefault('lockstep', False)
        sim = UnicycleSim(context=self.context, parameter_overrides=[
            Parameter(name, value=value) for name, value in params.items()])
        return self.add_clock_owner(sim) if lockstep else self.add(sim)

    def probe(self, **params):
        params.setdefault('use_sim_time', True)
        return self.add(Probe(context=self.context, parameter_overrides=[
            Parameter(name, value=value) for name, value in params.items()]))

    def spin_until(self, predicate, timeout=10.0, poll=0.05):
        return super().spin_until(predicate, timeout, poll)

    def spin_for(self, seconds):
        self.spin_until(lambda: False, seconds, poll=0.01)


class Probe(Node):
    """A test node: sends Twist sequences on sim-time ticks and records odometry."""

    def __init__(self, **kwargs):
        super().__init__('probe', **kwargs)
        self.odoms = []
        self.create_subscription(Odometry, 'odom', self.odoms.append, 50)
        self.cmd_pub = self.create_publisher(Twist, 'cmd_vel', 10)
        self._script = []
        self._tick = None
        self.script_started_at = None
        self.script_done_at = None

    @property
    def odom(self):
        return self.odoms[-1] if self.odoms else None

    def send(self, linear=0.0, angular=0.0):
        msg = Twist()
        msg.linear.x = float(linear)
        msg.angular.z = float(angular)
        self.cmd_pub.publish(msg)

    def play(self, script, period=0.1):
        """Play (linear, angular, ticks) steps on a sim-time timer, then send one zero Twist."""
        self._script = [(v, w) for v, w, ticks in script for _ in range(ticks)]
        self._script.append((0.0, 0.0))
        self._tick = self.create_timer(period, self._on_tick)

    @property
    def playing(self):
        return self.script_done_at is None

    def _on_tick(self):
        now = self.get_clock().now().nanoseconds
        if now == 0:
            return
        if self.script_started_at is None:
            self.script_started_at = now
        self.send(*self._script.pop(0))
        if not self._script:
            self.script_done_at = now
            self._tick.cancel()

    def odom_after(self, t_ns):
        """Return the first odometry stamped at or after t_ns (sim time), or None."""
        for odom in self.odoms:
            if odom.header.stamp.sec * 1_000_000_000 + odom.header.stamp.nanosec >= t_ns:
                return odom
        return None


@pytest.fixture
def ros_context():
    """Yield a fresh rclpy Context (no signal handlers) on this run's domain."""
    context = Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    try:
        yield context
    finally:
        rclpy.try_shutdown(context=context)


@pytest.fixture
def graph(ros_context):
    g = Graph(ros_context)
    try:
        yield g
    finally:
        g.close()
