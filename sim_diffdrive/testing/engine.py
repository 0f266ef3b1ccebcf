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
Step an in-process graph in lockstep with a simulator that owns time: the engine of SimGraph.

A ``UnicycleSim`` built with ``publish_clock`` and ``stepped=True`` takes no step of its own.
Here the caller steps it: each step advances the clock by one simulator step, then spins until
every message sent in the graph has been handled and no timer of a node is due, so a
controller's answer always lands on its step, whatever the machine's load.  Messages are
counted by each node's MessageCounter (lockstep/counter.py), the same counts a participant
sends the simulator across processes.  Tests, tools and users reach it through
sim_diffdrive.harness.SimGraph.
"""

import time

from rosgraph_msgs.msg import Clock as ClockMsg
from sim_diffdrive.lockstep.counter import MessageCounter
from sim_diffdrive.sim.clock import SteppedClock

_NS = 1_000_000_000


class Lockstep:
    """
    The nodes of one test or benchmark run, spun by ``executor``, stepped by ``step()``.

    Once the nodes have discovered each other, each message a node publishes must arrive at
    every in-graph subscription of its topic, and a step is settled when all that must arrive
    has been handled (per topic, summed over the nodes' MessageCounters).  What arrives beyond
    that (sent before the nodes matched, or by a process outside the graph) is forgotten
    before the next step, as the lockstep across processes does (handshake.py).
    """

    def __init__(self, executor):
        self.executor = executor
        self.nodes = []
        self.clock_owner = None
        self.steps = 0
        self._counters = []
        self._fanout = []  # per counter: (topic, in-graph subscriptions) of what it publishes
        # Per topic, added to (to arrive - handled): what was on its way when the counters
        # were last taken, less the counts then, less the surplus forgotten since.
        self._offset = {}
        self._plan, self._plan_sizes = [], None  # for _laid_out(); None: to be laid out
        self._discovered = False

    def add(self, node):
        """Spin node with the graph and count its traffic."""
        self.nodes.append(node)
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
        """Stop spinning node and destroy it; wait until the graph has forgotten its publishers."""
        topics = {pub.topic_name for pub in node.publishers}
        self.executor.remove_node(node)
        self.nodes.remove(node)
        if node is self.clock_owner:
            self.clock_owner = None
        node.destroy_node()
        self._instrument()

        if not self.nodes:
            return

        # A destroyed publisher leaves the graph a little later: wait, so that the next node on
        # its topic is not taken for a second publisher.
        def forgotten():
            return all(self.nodes[0].count_publishers(topic) <= sum(
                pub.topic_name == topic for n in self.nodes for pub in n.publishers)
                for topic in topics)
        self.spin_until(forgotten, 10.0, poll=0.005)

    def close(self):
        """Shut the executor down, then destroy every node (the context is the caller's)."""
        # The executor first: between two spin_once calls it keeps the last wait set and its
        # entities, and destroying a node under it crashed rclpy now and then (a segfault in
        # destroy_node under load).
        self.executor.shutdown()
        for node in reversed(self.nodes):
            node.destroy_node()
        self.nodes = []

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
        subscribers = self._graph_subscribers()

        def matched():
            return all(pub.get_subscription_count() >= subscribers.get(pub.topic_name, 0)
                       for node in self.nodes for pub in node.publishers)
        if not self.spin_until(matched, timeout, poll=0.01):
            raise RuntimeError('in-process nodes did not discover each other')
        # Count traffic from here on: what was sent before the nodes matched may never arrive.
        self._instrument()
        self._discovered = True

    def settled(self, now_ns):
        """Return whether every message sent was handled and every node's timers have run."""
        if self._owes():
            return False
        for node in self.nodes:
            if node is self.clock_owner:
                continue
            clock = node.get_clock()  # on sim time (use_sim_time) while ROS time is active
            if clock.ros_time_is_active and clock.now().nanoseconds != now_ns:
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
        """
        Advance simulated time by whole steps, letting the graph settle after each.

        What the caller sent between two steps (a command published from the test) is handled
        first, at the time it was sent, not one step later.
        """
        if not self._discovered:
            self.wait_for_discovery()
        now_ns = self.clock_owner.now_ns()
        if not self.spin_until(lambda: not self.pending(), timeout):
            raise RuntimeError(f'messages sent at t={now_ns / _NS:.3f} s were not handled')
        for _ in range(steps):
            self._forget_surplus()
            self.clock_owner.clock.step()
            self.steps += 1
            self._settle(self.clock_owner.now_ns(), timeout)

    def _settle(self, now_ns, timeout):
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

    def pending(self):
        """Return how many messages sent in the graph have not been handled yet."""
        return sum(owed for owed in self._owed().values() if owed > 0)

    def _owes(self):
        """Return whether pending() is not 0, from the first topic owed (asked per callback)."""
        offset = self._offset
        for topic_sums in self._laid_out():
            if _owed_on(offset, *topic_sums) > 0:
                return True
        return False

    def _owed(self, offset=None):
        """Per topic: messages to arrive at in-graph subscriptions less those handled."""
        offset = self._offset if offset is None else offset
        owed = dict(offset)
        for topic_sums in self._laid_out():
            owed[topic_sums[0]] = _owed_on(offset, *topic_sums)
        return owed

    def _laid_out(self):
        """
        Return, per topic: the counters' sent dicts with their fanout, and their heard dicts.

        Laid out once for as long as no counter handles a new topic (a node wrapping a
        subscription made later); the dicts are the counters' own, so the counts are live.
        """
        sizes = [len(counter.heard) for counter in self._counters]
        if sizes != self._plan_sizes:
            plan = {}
            for counter, fanout in zip(self._counters, self._fanout):
                for topic, count in fanout:
                    plan.setdefault(topic, ([], []))[0].append((counter.sent, count))
                for topic in counter.heard:
                    plan.setdefault(topic, ([], []))[1].append(counter.heard)
            self._plan = [(topic, senders, hearers) for topic, (senders, hearers) in plan.items()]
            self._plan_sizes = sizes
        return self._plan

    def _forget_surplus(self):
        """Forget messages handled beyond what the graph sent (they owe nothing)."""
        for topic, owed in self._owed().items():
            if owed < 0:
                self._offset[topic] = self._offset.get(topic, 0) - owed

    def _graph_subscribers(self):
        """Return how many subscriptions the graph's nodes have, per topic."""
        subscribers = {}
        for node in self.nodes:
            for sub in node.subscriptions:
                subscribers[sub.topic_name] = subscribers.get(sub.topic_name, 0) + 1
        return subscribers

    def _instrument(self):
        """Take every node's counter and the graph's subscriptions afresh (nodes came or went)."""
        carried = {topic: owed for topic, owed in self._owed().items() if owed > 0}
        subscribers = self._graph_subscribers()
        self._counters = [MessageCounter.of(node, _clock_topic(node), fixed=True)
                          for node in self.nodes]
        for counter in self._counters:
            counter.wrap_new()
        self._fanout = [[(topic, subscribers[topic]) for topic in counter.sent
                         if subscribers.get(topic)] for counter in self._counters]
        self._plan_sizes = None
        counted = self._owed({})
        self._offset = {topic: carried.get(topic, 0) - counted.get(topic, 0)
                        for topic in set(carried) | set(counted)}


def _owed_on(offset, topic, senders, hearers):
    """Return what topic owes: offset, plus what its senders sent times its fanout, less heard."""
    owed = offset.get(topic, 0)
    for sent, fanout in senders:
        owed += fanout * sent[topic]
    for heard in hearers:
        owed -= heard[topic]
    return owed


def _clock_topic(node):
    """Return the clock topic node runs on (its TimeSource's subscription, remapped or not)."""
    return next((sub.topic_name for sub in node.subscriptions if sub.msg_type is ClockMsg),
                '/clock')
