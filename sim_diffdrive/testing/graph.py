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
Test robot code against the simulator: an in-process graph stepped in lockstep.

``SimGraph`` is the harness of the project's tests, demo and bench, and what the ``sim_graph``
pytest fixture (pytest_plugin.py) gives a user: build nodes with ``graph.context``, start a
simulator that owns the clock with ``graph.sim(**params)``, ``graph.add(node)``, then
``graph.step_for(seconds)`` or ``graph.step_until(predicate, sim_timeout)`` and read
``graph.pose()`` (with a ``map_file``, ``graph.scan()`` too).  Each step advances simulated
time by one simulator step, then spins until every message sent has been handled and no
timer is due, so an answer lands on the step it was meant for, whatever the machine's load.
"""

import fcntl
import os
import random

import rclpy
from rclpy.context import Context
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import LaserScan
from sim_diffdrive.dds_profile import use_package_profile
from sim_diffdrive.sim.node import UnicycleSim
from sim_diffdrive.testing.engine import Lockstep
from sim_diffdrive.testing.probe import pose_of
from sim_diffdrive.testing.probe import Probe

# Simulated seconds per wall second of a simulator started by sim(lockstep=False): fast, with a
# wide margin for a command to cross the graph before the next clock step.
FREE_REAL_TIME_FACTOR = 10.0
DOMAIN_VARIABLE = 'SIM_GRAPH_DOMAIN_ID'
# Domains a run claims at once: one for each of up to this many pytest workers.
DOMAIN_BLOCK = 4
# Where runs lock their blocks of domains: one place for the whole machine.
DOMAIN_LOCKS = '/tmp/sim_graph_domains'
_claims = []  # the lock files (descriptors) this process holds (claim_domains)


def isolated_domain_id():
    """
    Return this test run's ROS domain, claimed once for the run and exported; discovery local.

    Never the domain a shell exports nor another run's: the first call claims a block of
    domains (claim_domains) and stores its first in SIM_GRAPH_DOMAIN_ID (set that to pin one);
    later calls and child processes reuse it through ROS_DOMAIN_ID.  The rest of the block is
    for the run's pytest workers.
    """
    domain = os.environ.get(DOMAIN_VARIABLE)
    if domain is None:
        domain = os.environ[DOMAIN_VARIABLE] = str(claim_domains())
    os.environ['ROS_DOMAIN_ID'] = domain
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    return int(domain)


def claim_domains(directory=None):
    """
    Claim a free block of domains for this process's lifetime; return the block's first domain.

    A block is held by an exclusive lock on its file in directory (DOMAIN_LOCKS, or
    SIM_GRAPH_DOMAIN_LOCKS: one for every user, as domains are the machine's), which goes
    with the process however it ends.  When none is free, a random block is shared.
    """
    # Fast DDS maps a domain to UDP ports; 1..100 stays clear of 0 (everyone's default) and of
    # the top of the valid range.
    starts = list(range(1, 101, DOMAIN_BLOCK))
    random.SystemRandom().shuffle(starts)
    directory = directory or os.environ.get('SIM_GRAPH_DOMAIN_LOCKS', DOMAIN_LOCKS)
    try:
        os.makedirs(directory, exist_ok=True)
        os.chmod(directory, 0o1777)  # every user's runs lock here (refused if not ours)
    except OSError:
        pass
    for start in starts:
        try:
            # Read-only is enough for flock, so a file another user made serves as well.
            lock = os.open(os.path.join(directory, f'{start}.lock'), os.O_RDONLY | os.O_CREAT,
                           0o666)
        except OSError:
            continue
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(lock)
            continue
        _claims.append(lock)  # held open (and so locked) until this process ends
        return start
    return starts[0]


class SimGraph(Lockstep):
    """
    A simulator and the nodes under test in this process, stepped in lockstep (see Lockstep).

    Without a context, the graph makes its own on an isolated domain and shuts it down on
    close(); ``context`` is what to build the nodes under test with.  executor_class may be
    any callable taking context=; the default is the EventsExecutor the executables spin.
    """

    def __init__(self, context=None, executor_class=EventsExecutor):
        self._own_context = context is None
        use_package_profile()  # takes effect if no node of this process was made before
        if context is None:
            context = Context()
            rclpy.init(context=context, domain_id=isolated_domain_id())
        super().__init__(executor_class(context=context))
        self.context = context
        self._probes = {}  # robot name (None: the one on odom) -> listening Probe
        self._scans = {}  # robot name -> its _LatestScan

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
        sim = UnicycleSim(stepped=stepped, context=self.context,
                          parameter_overrides=_overrides(params))
        self.add_clock_owner(sim) if stepped else self.add(sim)
        # Listen to odometry from the first message on (each robot's, with robots).
        for robot in params.get('robots') or [None]:
            self._listen(robot)
            if params.get('map_file'):
                self._listen_to_scan(robot)
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

    def scan(self, robot=None):
        """Return the latest LaserScan the graph has seen (robot's, if named), or None."""
        return self._listen_to_scan(robot).msg

    def _listen_to_scan(self, robot=None):
        latest = self._scans.get(robot)
        if latest is None:
            latest = self._scans[robot] = _LatestScan()
            node = Node('sim_graph_scan', namespace=robot, context=self.context,
                        parameter_overrides=_overrides({'use_sim_time': True}))
            node.create_subscription(LaserScan, 'scan', latest.take, 10)
            self.add(node)
        return latest

    def wait_for_odometry(self, timeout=20.0, process=None):
        """Spin (wall time) until odometry comes; return it, else RuntimeError (process's log)."""
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
        self._scans = {}
        if self._own_context:
            rclpy.try_shutdown(context=self.context)


class _LatestScan:
    """The latest LaserScan a listener took (msg: None until the first)."""

    def __init__(self):
        self.msg = None

    def take(self, msg):
        self.msg = msg


def _overrides(params):
    return [Parameter(name, value=value) for name, value in params.items()]
