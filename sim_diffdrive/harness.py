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
from pathlib import Path
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import weakref

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sim_diffdrive.angles import yaw_from_quaternion
from sim_diffdrive.dds_profile import use_package_profile
from sim_diffdrive.lockstep import Lockstep
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


def twist(linear, angular):
    """Return a Twist commanding linear.x [m/s] and angular.z [rad/s]."""
    msg = Twist()
    msg.linear.x = float(linear)
    msg.angular.z = float(angular)
    return msg


def twist_of(odom):
    """Return (linear.x, angular.z) of an Odometry message's twist."""
    return odom.twist.twist.linear.x, odom.twist.twist.angular.z


def is_moving(odom):
    """Return whether odometry (None: none yet) shows the robot moving."""
    return odom is not None and twist_of(odom) != (0.0, 0.0)


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


class Probe(Node):
    """Record odometry and send Twist commands, or play a script of them on sim-time ticks."""

    def __init__(self, name='probe', odom_topic='odom', cmd_topic='cmd_vel', listen_only=False,
                 record_commands=False, **kwargs):
        super().__init__(name, **kwargs)
        self.odoms = []
        self.odom_walls = []  # the monotonic wall time each odometry message arrived
        self.commands = []  # with record_commands: (monotonic, time.time(), Twist) heard
        self.create_subscription(Odometry, odom_topic, self._on_odom, 200)
        # A listener only: a second publisher on cmd_vel would make the simulator warn.
        self.cmd_pub = None if listen_only else self.create_publisher(Twist, cmd_topic, 10)
        if record_commands:
            self.create_subscription(Twist, cmd_topic, lambda msg: self.commands.append(
                (time.monotonic(), time.time(), msg)), 200)
        self._script = []
        self._tick = None
        self.script_started_at = None
        self.script_done_at = None

    @property
    def odom(self):
        """Return the latest odometry, or None."""
        return self.odoms[-1] if self.odoms else None

    def send(self, linear=0.0, angular=0.0):
        self.cmd_pub.publish(twist(linear, angular))

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

    def after(self, wall):
        """Return the odometry messages that arrived at or after monotonic wall time wall."""
        return [msg for received, msg in zip(self.odom_walls, self.odoms) if received >= wall]

    def _on_odom(self, msg):
        self.odom_walls.append(time.monotonic())
        self.odoms.append(msg)

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
    close(); ``context`` is what to build the nodes under test with.  executor_class may be
    any callable taking context= (rclpy.experimental.EventsExecutor, for one).
    """

    def __init__(self, context=None, executor_class=SingleThreadedExecutor):
        self._own_context = context is None
        use_package_profile()  # takes effect if no node of this process was made before
        if context is None:
            context = Context()
            rclpy.init(context=context, domain_id=isolated_domain_id())
        super().__init__(executor_class(context=context))
        self.context = context
        self._probes = {}  # robot name (None: the one on odom) -> listening Probe

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    @staticmethod
    def sim_time_params(**params):
        """Return parameter_overrides for a node under test: use_sim_time and name=value."""
        params.setdefault('use_sim_time', True)
        return _overrides(params)

    def sim(self, stepped=True, **params):
        """
        Start a simulator with the given parameters (any of unicycle_sim's).

        stepped (the default): it owns time (publish_clock) and the graph steps it, not the
        wall clock.  stepped=False: it runs on its own timers, pacing its clock at
        ``real_time_factor`` (publish_clock) or following another /clock (use_sim_time).
        """
        params.setdefault('publish_clock', stepped)
        if stepped and (not params['publish_clock'] or self.clock_owner is not None):
            raise ValueError('a stepped simulator owns the clock: one per graph, with '
                             'publish_clock true (use stepped=False for any other)')
        params.setdefault('real_time_factor', FREE_REAL_TIME_FACTOR)
        # The graph steps the clock itself, not the simulator's handshake with other processes.
        params.setdefault('lockstep', False)
        sim = UnicycleSim(context=self.context, parameter_overrides=_overrides(params))
        self.add_clock_owner(sim) if stepped else self.add(sim)
        # Listen to odometry from the first message on (each robot's, with robots).
        for robot in params.get('robots') or [None]:
            self._listen(robot)
        return sim

    def node(self, node_class, namespace=None, **params):
        """Build node_class(context=, parameter_overrides=) on sim time with params; add it."""
        return self.add(node_class(namespace=namespace, context=self.context,
                                   parameter_overrides=self.sim_time_params(**params)))

    def probe(self, name='probe', namespace=None, use_sim_time=True, **kwargs):
        """Add a Probe (see its arguments), on sim time unless use_sim_time is False."""
        return self.add(Probe(name, namespace=namespace, context=self.context,
                              parameter_overrides=_overrides({'use_sim_time': use_sim_time}),
                              **kwargs))

    @property
    def odometry(self):
        """Return the graph's listening Probe on ``odom`` (odoms, odom_walls)."""
        return self._listen()

    def listener(self, robot):
        """Return the graph's listening Probe on robot's ``<robot>/odom`` (see ``robots``)."""
        return self._listen(robot)

    def _listen(self, robot=None):
        probe = self._probes.get(robot)
        if probe is None:
            probe = self._probes[robot] = self.probe(
                name='sim_graph_odom', namespace=robot, listen_only=True)
        return probe

    def pose(self, robot=None):
        """Return (x, y, yaw) of the latest odometry the graph has seen (of robot, if named)."""
        odom = self.odom(robot)
        if odom is None:
            raise RuntimeError('no odometry yet: start a simulator with sim() and step')
        return pose_of(odom)

    def odom(self, robot=None):
        """Return the latest Odometry message the graph has seen (robot's, if named), or None."""
        return self._listen(robot).odom

    def wait_for_odometry(self, timeout=20.0, process=None):
        """
        Spin (wall time) until odometry arrives, e.g. from a simulator process; return it.

        Raises RuntimeError after timeout, with process's output when one is given.
        """
        if not self.spin_until(lambda: self.odometry.odom is not None, timeout):
            log = f':\n{process.describe()}' if process is not None else ''
            raise RuntimeError(f'no odometry within {timeout} s: is a simulator running?{log}')
        return self.odometry.odom

    def spin_until(self, predicate, timeout=10.0, poll=0.01):
        """Spin until predicate() is true; return whether it became true within timeout (wall)."""
        return super().spin_until(predicate, timeout, poll)

    def spin_for(self, seconds):
        """Spin for a number of wall seconds."""
        self.spin_until(lambda: False, seconds, poll=0.01)

    def close(self):
        super().close()
        self._probes = {}
        if self._own_context:
            rclpy.try_shutdown(context=self.context)


def _overrides(params):
    return [Parameter(name, value=value) for name, value in params.items()]


# -- processes -------------------------------------------------------------------------------


def ros_params(*params, namespace=None, clock=None, sim_time=False):
    """
    Return the command-line arguments after the executable: each 'name:=value' as a parameter.

    namespace puts the node there; clock remaps /clock (several simulators owning time side by
    side need one each); sim_time adds use_sim_time:=true.
    """
    args = ['--ros-args']
    if namespace:
        args += ['-r', f'__ns:={namespace}']
    if clock:
        args += ['-r', f'/clock:={clock}']
    params = (('use_sim_time:=true',) if sim_time else ()) + params
    return args + [arg for param in params for arg in ('-p', param)]


class Process:
    """A started process; its output goes to a file, as a pipe could fill up and block it."""

    def __init__(self, command, log_path=None, stdin=subprocess.DEVNULL, env=None):
        self.command = command
        self._temporary = log_path is None
        if log_path is None:
            fd, log_path = tempfile.mkstemp(prefix='sim_graph_', suffix='.log')
            os.close(fd)
        self.log_path = Path(log_path)
        with open(self.log_path, 'w') as log:
            _let_children_hear_ctrl_c()
        with open(self.log_path, 'w') as log:
            self.popen = subprocess.Popen(
                command, stdin=stdin, stdout=log, stderr=subprocess.STDOUT,
                env=dict(os.environ if env is None else env))
        self.pid = self.popen.pid
        self._final_output = None  # kept once kill() has removed a temporary log
        if self._temporary:
            # Also removed when the Process is forgotten (or at exit) without being stopped.
            weakref.finalize(self, self.log_path.unlink, missing_ok=True)
        self.signalled_at = None  # monotonic time of the last send()
        self.exited_at = None  # monotonic time at which poll() or wait() first saw the exit

    @property
    def returncode(self):
        return self.poll()

    def poll(self):
        code = self.popen.poll()
        if code is not None and self.exited_at is None:
            self.exited_at = time.monotonic()
        return code

    def wait(self, timeout=None):
        """Wait for the exit (subprocess.TimeoutExpired after timeout); return the exit code."""
        self.popen.wait(timeout)
        return self.poll()

    def send(self, signum):
        self.signalled_at = time.monotonic()
        self.popen.send_signal(signum)

    def write(self, data):
        """Write text or bytes to the process's stdin (started with stdin=subprocess.PIPE)."""
        self.popen.stdin.write(data.encode() if isinstance(data, str) else data)
        self.popen.stdin.flush()

    def close_input(self):
        """Close the process's stdin: it reads end of input after what was written."""
        self.popen.stdin.close()

    def output(self):
        """Return everything the process has written so far (stdout and stderr)."""
        if self._final_output is not None:
            return self._final_output
        return self.log_path.read_text(errors='replace')

    def kill(self, grace=3.0):
        """
        End the process unless it has exited; a temporary log is read and removed.

        SIGTERM first, so that it leaves DDS cleanly (a ROS node killed outright can leave
        shared-memory transport state behind that other processes trip over); SIGKILL after
        grace seconds.
        """
        if self.popen.poll() is None:
            self.popen.terminate()
            try:
                self.popen.wait(grace)
            except subprocess.TimeoutExpired:
                self.popen.kill()
                self.popen.wait()
        self.poll()
        if self.popen.stdin:
            self.popen.stdin.close()
        if self._temporary and self._final_output is None:
            self._final_output = self.output()
            self.log_path.unlink(missing_ok=True)

    def describe(self):
        """Return the command line and the output, for an assertion message."""
        return f'$ {" ".join(str(arg) for arg in self.command[-12:])}\n{self.output()}'


def start(executable, *args, stdin=subprocess.DEVNULL, log_path=None, env=None):
    """Start an executable (a name on PATH, or a path) as a user would; return its Process."""
    path = shutil.which(executable)
    if path is None:
        raise FileNotFoundError(f'{executable} is not on PATH; install the package (make venv)')
    return Process([path, *args], log_path, stdin, env)


def start_python(code, log_path=None):
    """Start this Python interpreter on a piece of code (a load, a listener, ...)."""
    return Process([sys.executable, '-c', code], log_path)


def stop(process, signum=signal.SIGINT, timeout=5.0):
    """Send signum (Ctrl-C) unless it has exited, kill it after timeout; return its output."""
    if process.poll() is None:
        process.send(signum)
        try:
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            pass
    process.kill()
    return process.output()


def _let_children_hear_ctrl_c():
    # A process started from a non-interactive shell's background job ignores SIGINT, and so
    # would its children: a handler (reset to the default at exec) rather than an ignored
    # signal lets a child hear a user's Ctrl-C.
    if (signal.getsignal(signal.SIGINT) is signal.SIG_IGN
            and threading.current_thread() is threading.main_thread()):
        signal.signal(signal.SIGINT, signal.default_int_handler)


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
