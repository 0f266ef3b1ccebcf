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
import time

from geometry_msgs.msg import Twist
from motion_challenges.angles import yaw_from_quaternion
from nav_msgs.msg import Odometry
import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
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


class Graph:
    """The nodes of one test, spun by one executor in this process."""

    def __init__(self, context):
        self.context = context
        self.executor = SingleThreadedExecutor(context=context)
        self.nodes = []
        self.lockstep_sim = None
        self._published = {}
        self._received = [0]

    def add(self, node):
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def sim(self, lockstep=True, **params):
        """
        Start a simulator that owns time (publish_clock) with the given parameters.

        In lockstep (the default) the test, not the wall clock, steps simulated time, and each
        step waits until every message and every due timer in this graph has been handled, so
        results are exact and independent of machine load.
        """
        params.setdefault('publish_clock', True)
        params.setdefault('real_time_factor', TEST_REAL_TIME_FACTOR)
        sim = self.add(UnicycleSim(context=self.context, parameter_overrides=[
            Parameter(name, value=value) for name, value in params.items()]))
        if lockstep:
            sim.clock_timer.cancel()
            self.lockstep_sim = sim
        return sim

    # -- lockstep -----------------------------------------------------------------------------

    def _count_traffic(self):
        """Count every message sent and handled by the graph's nodes from now on."""
        for node in self.nodes:
            for pub in node.publishers:
                if getattr(pub, '_counted', False):
                    continue
                counter = self._published.setdefault(pub.topic_name, [0])
                original = pub.publish

                def publish(msg, original=original, counter=counter):
                    counter[0] += 1
                    original(msg)
                pub.publish = publish
                pub._counted = True
            for sub in node.subscriptions:
                if getattr(sub, '_counted', False):
                    continue
                original = sub.callback

                def callback(msg, original=original):
                    self._received[0] += 1
                    original(msg)
                sub.callback = callback
                sub._counted = True

    def _subscribers(self, topic):
        return sum(1 for n in self.nodes for s in n.subscriptions if s.topic_name == topic)

    def _settled(self, now_ns):
        expected = sum(c[0] * self._subscribers(t) for t, c in self._published.items())
        if self._received[0] != expected:
            return False
        for node in self.nodes:
            if node is self.lockstep_sim:
                continue
            if node.get_parameter('use_sim_time').value and (
                    node.get_clock().now().nanoseconds != now_ns):
                return False
            if any(not t.is_canceled() and t.time_until_next_call() is not None
                   and t.time_until_next_call() <= 0 for t in node.timers):
                return False
        return True

    def _wait_for_discovery(self, timeout=10.0):
        def matched():
            return all(pub.get_subscription_count() >= self._subscribers(pub.topic_name)
                       for node in self.nodes for pub in node.publishers)
        assert self.spin_until(matched, timeout), 'nodes in the graph did not discover each other'

    def step(self, steps=1, timeout=5.0):
        """Advance simulated time by whole simulator steps, letting the graph settle after each."""
        sim = self.lockstep_sim
        self._count_traffic()
        for _ in range(steps):
            sim.step()
            now_ns = sim.now_ns()
            assert self.spin_until(lambda: self._settled(now_ns), timeout, poll=0.001), (
                f'graph did not settle at t={now_ns * 1e-9:.3f} s')

    def step_until(self, predicate, sim_timeout):
        """Step until predicate() holds; fail after sim_timeout simulated seconds."""
        self._wait_for_discovery()
        end_ns = self.lockstep_sim.now_ns() + int(sim_timeout * 1e9)
        while not predicate():
            assert self.lockstep_sim.now_ns() < end_ns, 'condition not reached in sim time'
            self.step()

    def step_for(self, seconds):
        self._wait_for_discovery()
        self.step(round(seconds * self.lockstep_sim.params.rate_hz))

    def probe(self, **params):
        params.setdefault('use_sim_time', True)
        return self.add(Probe(context=self.context, parameter_overrides=[
            Parameter(name, value=value) for name, value in params.items()]))

    def spin_until(self, predicate, timeout=10.0, poll=0.05):
        """Spin until predicate() is true; return whether it became true within timeout (wall)."""
        deadline = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > deadline:
                return False
            self.executor.spin_once(timeout_sec=poll)
        return True

    def spin_for(self, seconds):
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)

    def close(self):
        for node in reversed(self.nodes):
            self.executor.remove_node(node)
            node.destroy_node()
        self.executor.shutdown()


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
