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
The benchmark's graph: the harness's SimGraph with an executor of its choice and its own context.

In-process rows run the real simulator and the real motion nodes in one executor, stepped in
lockstep (sim_diffdrive.harness), so their results are exact and independent of machine load.
Their context has discovery off: the nodes of one context match without it, and no other run
on this machine, whatever its domain, can add to the message count.  The rows that talk to
processes use the same class with discovery on (the run's domain, this machine only).
"""

import os

from geometry_msgs.msg import Twist
import rclpy
from rclpy.context import Context
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sim_diffdrive.harness import SimGraph
from sim_diffdrive.harness import twist
from sim_diffdrive.sim.node import UnicycleSim


def init_context(domain_id, discovery_range=None):
    """Return a new initialised Context; discovery_range overrides the environment's."""
    context = Context()
    saved = os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE')
    if discovery_range is not None:
        os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = discovery_range
    try:
        rclpy.init(context=context, domain_id=domain_id)
    finally:
        if saved is None:
            os.environ.pop('ROS_AUTOMATIC_DISCOVERY_RANGE', None)
        else:
            os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = saved
    return context


def _node_kwargs(namespace, params):
    """Keyword arguments for a node: parameters, namespace, no /rosout."""
    kwargs = {'parameter_overrides': [Parameter(name, value=value)
                                      for name, value in params.items()],
              'enable_rosout': False}
    if namespace:
        kwargs['namespace'] = namespace
    return kwargs


class BenchGraph(SimGraph):
    """
    A SimGraph spun by executor_class (EventsExecutor, as the executables) on its own context.

    offline (the default): discovery off, for in-process rows; otherwise the environment's
    discovery, for talking to the processes the benchmark starts.  The simulator is added with
    add_sim(), not sim(): the graph holds only the simulator and the nodes measured (no probe
    on odometry), and pose() reads the simulated robot, which is what its odometry reports.
    """

    def __init__(self, executor_class=EventsExecutor, domain_id=None, offline=True):
        super().__init__(init_context(domain_id, 'OFF' if offline else None), executor_class)

    def close(self):
        try:
            super().close()
        finally:
            rclpy.try_shutdown(context=self.context)

    def add_sim(self, namespace=None, **params):
        """Add the simulator that owns time; the benchmark, not a wall timer, steps it."""
        params.setdefault('publish_clock', True)
        params.setdefault('lockstep', False)  # stepped by the in-process Lockstep instead
        return self.add_clock_owner(
            UnicycleSim(context=self.context, **_node_kwargs(namespace, params)))

    def add_node(self, node_class, namespace=None, **params):
        """Build a node_class node on sim time with the given parameters and add it."""
        params.setdefault('use_sim_time', True)
        return self.add(node_class(context=self.context, **_node_kwargs(namespace, params)))

    def add_script(self, rate_hz):
        """Add a ScriptNode ticking at rate_hz on sim time."""
        return self.add(ScriptNode(rate_hz, context=self.context,
                                   **_node_kwargs(None, {'use_sim_time': True})))

    def step_to(self, t_ns):
        """Step until simulated time is t_ns (a multiple of the step, not in the past)."""
        if t_ns % self.step_ns or t_ns < self.now_ns:
            raise ValueError(f'cannot step to {t_ns} ns from {self.now_ns} ns')
        self.step((t_ns - self.now_ns) // self.step_ns)

    def pose(self):
        """Return the simulated robot's (x, y, yaw): what its odometry reports."""
        m = self.clock_owner.model
        return m.x, m.y, m.yaw


class ScriptNode(Node):
    """Play a script of benchmark.originals on a timer on the node clock, like rospy.Rate."""

    def __init__(self, rate_hz, **kwargs):
        super().__init__('reference', **kwargs)
        self.rate_hz = rate_hz
        self.cmd_pub = self.create_publisher(Twist, 'cmd_vel', 10)
        self.done = True
        self._script = None
        self._timer = self.create_timer(1.0 / rate_hz, self._on_tick)
        self._timer.cancel()

    def now_ns(self):
        return self.get_clock().now().nanoseconds

    def publish(self, linear, angular):
        self.cmd_pub.publish(twist(linear, angular))

    def play(self, script):
        """Start script; its first tick comes one period from now."""
        self._script = script
        self.done = False
        self._timer.reset()

    def _on_tick(self):
        try:
            next(self._script)
        except StopIteration:
            self.done = True
            self._timer.cancel()
