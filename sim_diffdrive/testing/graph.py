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
Test robot code against the simulator: SimGraph, an in-process graph stepped in lockstep.

Its engine, ``Lockstep``, steps a simulator built with ``stepped=True``: each step advances the
clock one simulator step, then spins until every message sent has been handled and no timer is
due, so an answer lands on its step whatever the machine's load.
"""

import collections
import contextlib
import difflib
import itertools
import time

from rclpy.exceptions import InvalidHandle
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import LaserScan
from sim_diffdrive.dds_profile import use_package_profile
from sim_diffdrive.dds_teardown import held_context
from sim_diffdrive.lockstep.counter import clock_topic
from sim_diffdrive.lockstep.counter import MessageCounter
from sim_diffdrive.lockstep.handshake import Answer
from sim_diffdrive.lockstep.handshake import StepLedger
from sim_diffdrive.lockstep.participant import say_unmatched
from sim_diffdrive.sim.clock import SteppedClock
from sim_diffdrive.sim.node import PARAMETERS
from sim_diffdrive.sim.node import UnicycleSim
from sim_diffdrive.testing.domains import isolated_domain_id
from sim_diffdrive.testing.domains import spare_domain
from sim_diffdrive.testing.probe import pose_of
from sim_diffdrive.testing.probe import Probe

_NS = 1_000_000_000
# Simulated seconds per wall second of a simulator started by sim(lockstep=False): fast, with a
# wide margin for a command to cross the graph before the next clock step.
FREE_REAL_TIME_FACTOR = 10.0
_open_domains = []  # those of the SimGraphs open in this process
_SIM_PARAMETERS = [spec.name for spec in PARAMETERS] + ['use_sim_time']


class Lockstep:
    """
    The nodes of one test or benchmark run, spun by ``executor``, stepped by ``step()``.

    What is owed is the clock owner's StepLedger, as across processes (docs/time.md, "In
    tests"): each discovered node is a member whose answer is its MessageCounter's live dicts,
    so no answer travels and counts are exact without stamps; what a participant checks before
    it answers (its clock shows the time, no timer is due) is checked in settled().
    """

    def __init__(self, executor):
        self.executor = executor
        self.nodes = []
        self.clock_owner = None
        self.steps = 0
        # No member is ever dropped here: no owner to spare (see StepLedger.drop).
        self.ledger = StepLedger(None)
        self._answers = {}  # node -> its answer in the ledger
        self._counters = {}  # node -> its MessageCounter (counted from discovery on)
        self._ids = itertools.count()  # a removed node's id stays taken (its goodbye is final)
        self._names = {}  # node -> its fully qualified name
        self._discovered = False

    def add(self, node):
        """Spin node with the graph and count its traffic."""
        if node in self.nodes:
            raise ValueError(f'{node.get_fully_qualified_name()} is in the graph already')
        self.nodes.append(node)
        self._names[node] = node.get_fully_qualified_name()  # to name it once destroyed
        self.executor.add_node(node)
        self._discovered = False
        return node

    def add_clock_owner(self, sim):
        """Add a UnicycleSim built with publish_clock and stepped=True: ``step()`` steps it."""
        if not isinstance(sim.clock, SteppedClock):
            raise ValueError(
                'the graph steps a simulator built with publish_clock:=true and stepped=True; '
                f'this one keeps time with a {type(sim.clock).__name__}')
        self.clock_owner = sim
        return self.add(sim)

    def remove(self, node):
        """
        Stop spinning node and destroy it; wait until the graph has forgotten its publishers.

        Returns whether it has within 10 s.  Only the node's own are waited for: other
        processes publish on its topics too (every node on /rosout and /parameter_events).
        """
        ours = collections.Counter(pub.topic_name for pub in node.publishers)
        left = {topic: node.count_publishers(topic) - count for topic, count in ours.items()}
        self.executor.remove_node(node)
        # An EventsExecutor lets go of a removed node's entities when it next runs, after the
        # events it has queued for them: a task queued now runs after both.  Destroyed before,
        # the node would have its callbacks run on its destroyed publishers and timers.
        released = self.executor.create_task(lambda: None)
        self.spin_until(released.done, 10.0, poll=0.005)
        self.nodes.remove(node)
        self._names.pop(node)
        if node is self.clock_owner:
            self.clock_owner = None
        node.destroy_node()
        self._counters.pop(node, None)
        answer = self._answers.pop(node, None)
        if answer is not None:  # a goodbye: what it sent is still waited for, not what it hears
            answer.leaving = True
            self.ledger.receive(answer, answer.step_ns)

        # A destroyed publisher leaves the graph a little later: wait, so that the next node on
        # its topic is not taken for a second publisher.
        def forgotten():
            return not self.nodes or all(
                self.nodes[0].count_publishers(topic) <= count for topic, count in left.items())
        return self.spin_until(forgotten, 10.0, poll=0.005)

    def close(self):
        """Shut the executor down, then destroy every node (the context is the caller's)."""
        # The executor first: it keeps the last wait set's entities between spin_once calls,
        # and destroying a node under it crashed rclpy now and then (under load).
        self.executor.shutdown()
        for node in reversed(self.nodes):
            node.destroy_node()
        self.nodes = []

    def spin_until(self, predicate, timeout=10.0, poll=0.01):
        """Spin until predicate() is true; False after timeout [s, wall] of waiting for it."""
        now = time.monotonic()
        deadline = now + timeout
        while not predicate():
            if now > deadline:
                return False
            self.executor.spin_once(timeout_sec=poll)
            # A callback that ran past the poll (a motion drawing its plot_file as it ends)
            # kept the graph busy, not waiting: the timeout is for what never comes.
            start, now = now, time.monotonic()
            deadline += max(0.0, now - start - poll)
        return True

    def wait_for_discovery(self, timeout=10.0):
        """Spin until every publisher has matched every in-graph subscription of its topic."""
        subscribers = collections.Counter(
            sub.topic_name for node in self.nodes for sub in node.subscriptions)

        def matched():
            return all(pub.get_subscription_count() >= subscribers[pub.topic_name]
                       for node in self.nodes for pub in node.publishers)
        if not self.spin_until(matched, timeout, poll=0.01):
            raise RuntimeError('in-process nodes did not discover each other')
        # Count traffic from here on: what was sent before the nodes matched may never arrive.
        now_ns = self.now_ns
        for node in self.nodes:
            counter = self._counters[node] = MessageCounter.of(node, clock_topic(node), fixed=True)
            counter.wrap_new()  # entities made since it was last looked at
            answer = self._answers.get(node)
            if answer is None:  # it joins
                if node is not self.clock_owner:
                    _say_what_it_misses(node)
                name = self._names[node]
                answer = self._answers[node] = Answer(f'{name}#{next(self._ids)}', name, now_ns,
                                                      counter.sent, counter.heard)
            # A member's again: a topic it hears since is owed from here on.
            self.ledger.receive(answer, now_ns)
        self._discovered = True

    def settled(self, now_ns):
        """Return whether every message sent was handled and every node's timers have run."""
        return next(self._unsettled(now_ns), None) is None

    def _unsettled(self, now_ns):
        """Yield what the step at now_ns still waits for, in words (settled(): none)."""
        # The nodes first: while a step settles, a node yet to take its /clock or run a due
        # timer is found at a glance, where the ledger weighs every member's every topic (and
        # counts the caught-up members in, once nothing is owed).
        counters = self._counters
        for node in self.nodes:
            if node is self.clock_owner:
                continue
            counter = counters.get(node)
            if counter is not None and counter.clock_ns not in (None, now_ns):
                yield f'{self._names[node]} to take its /clock'  # seen without rclpy
                return
            clock = node.get_clock()  # on sim time (use_sim_time) while ROS time is active
            if clock.ros_time_is_active and clock.now().nanoseconds != now_ns:
                yield f'{self._names[node]} to take its /clock'
                return
            for timer in node.timers:
                if not timer.is_canceled():
                    due = timer.time_until_next_call()
                    if due is not None and due <= 0:
                        yield f'a due timer of {self._names[node]} to run'
                        return
        for member, topic, due in self.ledger.waiting_for(now_ns):
            yield (f'{member} to answer' if topic is None else f'{member} to take {due} '
                   f'message(s) on {topic}' if due else f'{member} to hear the latest on {topic}')

    @property
    def now_ns(self):
        return self.clock_owner.now_ns() if self.clock_owner is not None else 0

    @property
    def step_ns(self):
        return round(_NS / self._stepped().params.rate_hz)

    def _stepped(self):
        if self.clock_owner is None:
            raise RuntimeError('nothing to step: start a simulator with sim() first')
        return self.clock_owner

    def step(self, steps=1, timeout=10.0):
        """Advance simulated time by whole steps, settling after each (what was sent first)."""
        self._stepped()
        for node in self.nodes:
            try:
                with node.handle:
                    pass
            except InvalidHandle:
                raise RuntimeError(f'{self._names[node]} was destroyed in the graph: take a '
                                   'node out with remove(node), which destroys it') from None
        if not self._discovered:
            self.wait_for_discovery()
        now_ns = self.clock_owner.now_ns()
        if not self.spin_until(lambda: not self.ledger.waiting_for(now_ns), timeout):
            raise RuntimeError(f'messages sent at t={now_ns / _NS:.3f} s were not handled')
        for _ in range(steps):
            self.ledger.next_step(now_ns)  # forgets what was heard beyond what was sent
            self.clock_owner.clock.step()
            self.steps += 1
            now_ns = self.clock_owner.now_ns()
            for answer in self._answers.values():
                answer.step_ns = now_ns  # each node answers at once: settled() checks the rest
            if not self.spin_until(lambda: self.settled(now_ns), timeout):
                waiting = '; '.join(self._unsettled(now_ns)) or 'nothing (settled just then)'
                raise RuntimeError(f'graph did not settle at t={now_ns / _NS:.3f} s within '
                                   f'{timeout:g} s: waiting for {waiting}')

    def step_until(self, predicate, sim_timeout):
        """Step until predicate() holds; raise after sim_timeout simulated seconds."""
        end_ns = self.now_ns + round(sim_timeout * _NS)
        while not predicate():
            if self.now_ns >= end_ns:
                raise RuntimeError(f'condition not reached within {sim_timeout:g} s of '
                                   f'simulated time (now t={self.now_ns / _NS:.3f} s)')
            self.step()

    def step_for(self, seconds):
        """Step for a number of simulated seconds (rounded to whole steps)."""
        self.step(round(seconds * _NS / self.step_ns))

    def pending(self):
        """Return how many messages sent in the graph have not been handled yet."""
        return sum(due for _, _, due in self.ledger.waiting_for(self.now_ns))


class SimGraph(Lockstep):
    """
    A simulator and the nodes under test in this process, stepped in lockstep.

    Without a context, the graph makes its own on an isolated domain and shuts it down on
    close(); executor_class may be any callable taking context=.
    """

    def __init__(self, context=None, executor_class=EventsExecutor):
        use_package_profile()  # takes effect if no node of this process was made before
        # A context of its own goes on close(), its participant the safe way (dds_teardown.py).
        self._own = contextlib.ExitStack()
        if context is None:
            domain = isolated_domain_id()
            if domain in _open_domains:  # another graph is open on it: one would hear the other
                # (processes started meanwhile are still on the first's)
                domain = spare_domain(_open_domains)
            context = self._own.enter_context(held_context(domain_id=domain))
        super().__init__(executor_class(context=context))
        self.context = context
        if context.ok():  # (a graph on a context shut down already: nothing to register)
            _open_domains.append(context.get_domain_id())
            self._own.callback(_open_domains.remove, context.get_domain_id())
        self._probes = {}  # robot name (None: the one on odom) -> listening Probe
        self._scans = {}  # robot name -> its latest LaserScan (a deque of one)

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
        """Start a simulator with any of unicycle_sim's params; the graph steps it if stepped."""
        for name in params:
            if name not in _SIM_PARAMETERS:
                close = difflib.get_close_matches(name, _SIM_PARAMETERS, n=1)
                raise TypeError(f'sim() got {name!r}, which is not a parameter of unicycle_sim'
                                + (f' (did you mean {close[0]!r}?)' if close else ''))
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
            self.listener(robot)
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
        return self.listener()

    def listener(self, robot=None):
        """Return the graph's listening Probe on robot's ``<robot>/odom`` (see ``robots``)."""
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
        return self.listener(robot).odom

    def scan(self, robot=None):
        """Return the latest LaserScan the graph has seen (robot's, if named), or None."""
        latest = self._listen_to_scan(robot)
        return latest[0] if latest else None

    def _listen_to_scan(self, robot=None):
        latest = self._scans.get(robot)
        if latest is None:
            latest = self._scans[robot] = collections.deque(maxlen=1)
            node = Node('sim_graph_scan', namespace=robot, context=self.context,
                        parameter_overrides=_overrides({'use_sim_time': True}))
            # A lambda: rclpy reads the callback's signature, which a builtin lacks.
            node.create_subscription(LaserScan, 'scan', lambda msg: latest.append(msg), 10)
            self.add(node)
        return latest

    def wait_for_odometry(self, timeout=20.0, process=None):
        """Spin (wall time) until odometry comes; return it, else RuntimeError (process's log)."""
        if not self.spin_until(lambda: self.odometry.odom is not None, timeout):
            log = f':\n{process.describe()}' if process is not None else ''
            raise RuntimeError(f'no odometry within {timeout} s: is a simulator running?{log}')
        return self.odometry.odom

    def spin_for(self, seconds):
        """Spin for a number of wall seconds."""
        end = time.monotonic() + seconds
        self.spin_until(lambda: time.monotonic() >= end, seconds)

    def close(self):
        try:
            super().close()
        finally:
            self._probes, self._scans = {}, {}
            self._own.close()


def _overrides(params):
    return [Parameter(name, value=value) for name, value in params.items()]


def _say_what_it_misses(node):
    """Warn about a node whose timers run on wall time; say which topics nobody hears yet."""
    timed = any(not timer.is_canceled() for timer in node.timers)  # (node.timers: a generator)
    owns_a_clock = any(pub.msg_type is ClockMsg for pub in node.publishers)  # a free simulator
    if timed and not owns_a_clock and not node.get_parameter('use_sim_time').value:
        node.get_logger().warning(
            'On wall time (use_sim_time is false) in a SimGraph: its timers do not follow the '
            "graph's steps; build it with parameter_overrides=sim_time_params(), or add it "
            'with node()')
    if isinstance(node, UnicycleSim) or owns_a_clock:
        return  # a simulator publishes for whoever listens
    say_unmatched(node, ' in the graph')  # once, as it joins: pytest shows it if a test fails
