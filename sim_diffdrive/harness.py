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
Test robot code against the simulator: an in-process graph stepped in lockstep, and processes.

``SimGraph`` is the harness the project's tests, ``make demo``, ``make bench`` and
``make stress`` use, and the one the ``sim_graph`` pytest fixture (sim_diffdrive.pytest_plugin)
gives a user to test their own controller: build nodes with ``graph.context``, start a
simulator that owns the clock with ``graph.sim(**params)``, ``graph.add(node)``, then
``graph.step_for(seconds)`` or ``graph.step_until(predicate, sim_timeout)`` and read
``graph.pose()``.

Each step advances simulated time by one simulator step and then spins until every message
sent in the graph has been handled and no node has a timer due, so a controller's answer
always lands on the step it was meant for, whatever the machine's load.

The process helpers start the package's executables (or any code) as a user would, with this
process's environment (ROS_DOMAIN_ID, discovery range), and stop them like Ctrl-C.
"""

import math
import os
import random
import shutil
import signal
import subprocess
import sys
import time

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sim_diffdrive.angles import yaw_from_quaternion
from sim_diffdrive.sim_node import UnicycleSim

_NS = 1_000_000_000
# Simulated seconds per wall second of a simulator started by sim(lockstep=False): fast, with a
# wide margin for a command to cross the graph before the next clock step.
FREE_REAL_TIME_FACTOR = 10.0
DOMAIN_VARIABLE = 'SIM_GRAPH_DOMAIN_ID'


def pose_of(odom):
    """Return (x, y, yaw) of an Odometry message."""
    p = odom.pose.pose
    return p.position.x, p.position.y, yaw_from_quaternion(
        p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w)


def stamp_s(msg):
    """Return a stamped message's header time in seconds."""
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def angle_error(a, b):
    """Return the absolute difference of two angles, wrapped to [0, pi] [rad]."""
    return abs(math.remainder(a - b, 2.0 * math.pi))


def isolated_domain_id():
    """
    Return this test run's ROS domain, chosen at random once and exported; discovery local.

    A run never joins the domain a shell happens to export (a robot, a simulator someone left
    running): the first call picks a domain in 1..100 and stores it in SIM_GRAPH_DOMAIN_ID
    (set that to pin one), later calls and the processes started afterwards reuse it through
    ROS_DOMAIN_ID, and ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST keeps it on this machine.
    """
    # Fast DDS maps a domain to UDP ports; 1..100 stays clear of 0 (everyone's default) and of
    # the top of the valid range.
    domain = os.environ.setdefault(DOMAIN_VARIABLE, str(random.SystemRandom().randint(1, 100)))
    os.environ['ROS_DOMAIN_ID'] = domain
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    return int(domain)


class Lockstep:
    """
    The nodes of one test or benchmark run, spun by ``executor``, stepped by ``step()``.

    Once the nodes have discovered each other, every publish adds the number of in-graph
    subscriptions of its topic to what must arrive, every subscription callback counts one
    arrival, and a step is settled when the two agree.
    """

    def __init__(self, executor):
        self.executor = executor
        self.nodes = []
        self.clock_owner = None
        self.steps = 0
        self._subscribers = {}
        self._sent = 0
        self._handled = 0
        self._discovered = False

    def add(self, node):
        """Spin node with the graph and count its traffic."""
        self.nodes.append(node)
        self.executor.add_node(node)
        self._discovered = False
        return node

    def add_clock_owner(self, sim):
        """Add a UnicycleSim with publish_clock whose clock ``step()`` advances (not a timer)."""
        sim.clock_timer.cancel()
        self.clock_owner = sim
        return self.add(sim)

    def remove(self, node):
        """Stop spinning node and destroy it; wait until the graph has forgotten its publishers."""
        topics = {pub.topic_name for pub in node.publishers}
        self.executor.remove_node(node)
        self.nodes.remove(node)
        node.destroy_node()
        self._instrument()

        # A destroyed publisher leaves the graph a little later: wait, so that the next node on
        # its topic is not taken for a second publisher.
        def forgotten():
            return all(self.clock_owner.count_publishers(topic) <= sum(
                pub.topic_name == topic for n in self.nodes for pub in n.publishers)
                for topic in topics)
        self.spin_until(forgotten, 10.0, poll=0.005)

    def close(self):
        """Destroy every node and shut the executor down (the context is the caller's)."""
        for node in reversed(self.nodes):
            self.executor.remove_node(node)
            node.destroy_node()
        self.nodes = []
        self.executor.shutdown()

    # -- spinning -----------------------------------------------------------------------------

    def spin_until(self, predicate, timeout, poll=0.001):
        """Spin until predicate() is true; return whether it became true within timeout (wall)."""
        deadline = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > deadline:
                return False
            self.executor.spin_once(timeout_sec=poll)
        return True

    def wait_for_discovery(self, timeout=10.0):
        """Spin until every publisher has matched every in-graph subscription of its topic."""
        def matched():
            return all(pub.get_subscription_count() >= self._subscribers.get(pub.topic_name, 0)
                       for node in self.nodes for pub in node.publishers)
        if not self.spin_until(matched, timeout, poll=0.01):
            raise RuntimeError('in-process nodes did not discover each other')
        # Count traffic from here on: what was sent before the nodes matched may never arrive.
        self._instrument()
        self._discovered = True

    def settled(self, now_ns):
        """Return whether every message sent was handled and every node's timers have run."""
        if self._handled != self._sent:
            return False
        for node in self.nodes:
            if node is self.clock_owner:
                continue
            if (node.get_parameter('use_sim_time').value
                    and node.get_clock().now().nanoseconds != now_ns):
                return False
            for timer in node.timers:
                if not timer.is_canceled():
                    due = timer.time_until_next_call()
                    if due is not None and due <= 0:
                        return False
        return True

    # -- stepping -----------------------------------------------------------------------------

    @property
    def now_ns(self):
        return self.clock_owner.now_ns()

    @property
    def step_ns(self):
        return round(_NS / self.clock_owner.params.rate_hz)

    def step(self, steps=1, timeout=10.0):
        """Advance simulated time by whole steps, letting the graph settle after each."""
        if not self._discovered:
            self.wait_for_discovery()
        for _ in range(steps):
            self.clock_owner.step()
            self.steps += 1
            now_ns = self.clock_owner.now_ns()
            if not self.spin_until(lambda: self.settled(now_ns), timeout):
                raise RuntimeError(f'graph did not settle at t={now_ns / _NS:.3f} s')

    def step_until(self, predicate, sim_timeout):
        """Step until predicate() holds; raise after sim_timeout simulated seconds."""
        end_ns = self.now_ns + round(sim_timeout * _NS)
        while not predicate():
            if self.now_ns >= end_ns:
                raise RuntimeError('condition not reached in simulated time')
            self.step()

    def step_for(self, seconds):
        """Step for a number of simulated seconds (rounded to whole steps)."""
        self.step(round(seconds * _NS / self.step_ns))

    def _instrument(self):
        self._subscribers = {}
        for node in self.nodes:
            for sub in node.subscriptions:
                topic = sub.topic_name
                self._subscribers[topic] = self._subscribers.get(topic, 0) + 1
                if not getattr(sub, '_lockstep_counted', False):
                    sub.callback = self._counted_callback(sub.callback)
                    sub._lockstep_counted = True
            for pub in node.publishers:
                if not getattr(pub, '_lockstep_counted', False):
                    pub.publish = self._counted_publish(pub.publish, pub.topic_name)
                    pub._lockstep_counted = True

    def _counted_callback(self, callback):
        def counted(msg):
            self._handled += 1
            callback(msg)
        return counted

    def _counted_publish(self, publish, topic):
        def counted(msg):
            self._sent += self._subscribers.get(topic, 0)
            publish(msg)
        return counted


class Probe(Node):
    """Record odometry and send Twist commands, or play a script of them on sim-time ticks."""

    def __init__(self, name='probe', odom_topic='odom', cmd_topic='cmd_vel', **kwargs):
        super().__init__(name, **kwargs)
        self.odoms = []
        self.create_subscription(Odometry, odom_topic, self.odoms.append, 50)
        # Without cmd_topic the probe only listens (a second cmd_vel publisher is a warning).
        self.cmd_pub = self.create_publisher(Twist, cmd_topic, 10) if cmd_topic else None
        self._script = []
        self._tick = None
        self.script_started_at = None
        self.script_done_at = None

    @property
    def odom(self):
        """Return the latest odometry, or None."""
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
            if odom.header.stamp.sec * _NS + odom.header.stamp.nanosec >= t_ns:
                return odom
        return None


class SimGraph(Lockstep):
    """
    A simulator and the nodes under test in this process, stepped in lockstep (see Lockstep).

    Without a context, the graph makes its own on an isolated domain and shuts it down on
    close(); ``context`` is what to build the nodes under test with.
    """

    def __init__(self, context=None):
        self._own_context = context is None
        if context is None:
            context = Context()
            rclpy.init(context=context, domain_id=isolated_domain_id())
        super().__init__(SingleThreadedExecutor(context=context))
        self.context = context
        self._probe = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    @staticmethod
    def sim_time_params(**params):
        """Return parameter_overrides for a node under test: use_sim_time and name=value."""
        params.setdefault('use_sim_time', True)
        return _overrides(params)

    def sim(self, lockstep=True, **params):
        """
        Start a simulator that owns time (publish_clock) with the given parameters.

        In lockstep (the default) the graph, not the wall clock, steps simulated time; with
        lockstep=False it runs on its own timer at ``real_time_factor``.  Also starts the probe
        that pose() reads.
        """
        params.setdefault('publish_clock', True)
        params.setdefault('real_time_factor', FREE_REAL_TIME_FACTOR)
        # The graph steps the clock itself, not the simulator's handshake with other processes.
        params.setdefault('lockstep', False)
        sim = UnicycleSim(context=self.context, parameter_overrides=_overrides(params))
        self.add_clock_owner(sim) if lockstep else self.add(sim)
        if self._probe is None:
            self._probe = self.probe(name='sim_graph_odom', cmd_topic=None)
        return sim

    def probe(self, name='probe', cmd_topic='cmd_vel', **params):
        """Add a Probe on sim time (see Probe); it records odometry from the first message."""
        params.setdefault('use_sim_time', True)
        return self.add(Probe(name, cmd_topic=cmd_topic, context=self.context,
                              parameter_overrides=_overrides(params)))

    def pose(self):
        """Return (x, y, yaw) of the latest odometry the graph has seen."""
        odom = self.odom()
        if odom is None:
            raise RuntimeError('no odometry yet: start a simulator with sim() and step')
        return pose_of(odom)

    def odom(self):
        """Return the latest Odometry message the graph has seen, or None."""
        return self._probe.odom if self._probe is not None else None

    def wait_for_odometry(self, timeout=20.0):
        """Spin (wall time) until odometry arrives, e.g. from a simulator process; return it."""
        if self._probe is None:
            self._probe = self.probe(name='sim_graph_odom', cmd_topic=None)
        if not self.spin_until(lambda: self._probe.odom is not None, timeout):
            raise RuntimeError(f'no odometry within {timeout} s: is a simulator running?')
        return self._probe.odom

    def spin_until(self, predicate, timeout=10.0, poll=0.01):
        """Spin until predicate() is true; return whether it became true within timeout (wall)."""
        return super().spin_until(predicate, timeout, poll)

    def spin_for(self, seconds):
        """Spin for a number of wall seconds."""
        self.spin_until(lambda: False, seconds, poll=0.01)

    def close(self):
        super().close()
        self._probe = None
        if self._own_context:
            rclpy.try_shutdown(context=self.context)


def _overrides(params):
    return [Parameter(name, value=value) for name, value in params.items()]


# -- processes -------------------------------------------------------------------------------


def ros_params(*params):
    """Return the command-line arguments that set each 'name:=value' as a ROS parameter."""
    return ['--ros-args', *[arg for param in params for arg in ('-p', param)]]


def start(executable, *args, stdin=subprocess.DEVNULL):
    """Start an executable found on PATH; its output (stdout and stderr) goes to a pipe."""
    path = shutil.which(executable)
    if path is None:
        raise FileNotFoundError(f'{executable} is not on PATH; install the package (make venv)')
    return _popen([path, *args], stdin)


def start_python(code):
    """Start this Python interpreter on a piece of code (a load, a listener, ...)."""
    return _popen([sys.executable, '-c', code], subprocess.DEVNULL)


def stop(process, signum=signal.SIGINT, timeout=5.0):
    """Send signum unless the process has exited, kill it after timeout; return its output."""
    if process.poll() is None:
        process.send_signal(signum)
        try:
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    return process.stdout.read()


def _popen(args, stdin):
    return subprocess.Popen(args, stdin=stdin, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, env=dict(os.environ))


def closing_line(output):
    """Return a motion's closing line ('Done in ...') from its output, or its last error line."""
    lines = output.splitlines()
    for line in reversed(lines):
        if 'Done in ' in line:
            return line
    for line in reversed(lines):
        if '[ERROR]' in line or 'Error' in line:
            return line
    return lines[-1] if lines else ''
