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
controller's answer always lands on its step, whatever the machine's load.  What is owed is
the clock owner's StepLedger (lockstep/handshake.py), as across processes: each node is a
member whose answer is its MessageCounter's live counts (lockstep/counter.py), so no answer
travels.  Tests, tools and users reach it through sim_diffdrive.harness.SimGraph.
"""

import itertools
import time

from sim_diffdrive.lockstep.counter import clock_topic
from sim_diffdrive.lockstep.counter import MessageCounter
from sim_diffdrive.lockstep.handshake import Answer
from sim_diffdrive.lockstep.handshake import StepLedger
from sim_diffdrive.sim.clock import SteppedClock

_NS = 1_000_000_000


class Lockstep:
    """
    The nodes of one test or benchmark run, spun by ``executor``, stepped by ``step()``.

    Each node the graph has discovered is a member of ``ledger``, answering with its
    counter's own dicts, so its counts are live, and the clock's time from each step on: what
    a participant checks before it answers (its clock shows the time, no timer is due) is
    checked here after the ledger's rule (settled()).  The answers carry no stamps: read
    together and live, counts are exact on every topic, where across processes a stamp stands
    in for counts of different ages.  So a node added to a running graph joins once
    discovered and is counted once nothing else is owed; a removed one leaves, and what it
    sent is still waited for; what members hear beyond what members sent (sent before the
    nodes matched, or by a node outside the graph) is forgotten before the next step.
    """

    def __init__(self, executor):
        self.executor = executor
        self.nodes = []
        self.clock_owner = None
        self.steps = 0
        # No member is ever dropped here: no owner to spare (see StepLedger.drop).
        self.ledger = StepLedger(None)
        self._answers = {}  # node -> its answer in the ledger
        self._ids = itertools.count()  # a removed node's id stays taken (its goodbye is final)
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
        answer = self._answers.pop(node, None)
        if answer is not None:  # a goodbye: what it sent is still waited for, not what it hears
            answer.leaving = True
            self.ledger.receive(answer, answer.step_ns)

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
        subscribers = {}
        for node in self.nodes:
            for sub in node.subscriptions:
                subscribers[sub.topic_name] = subscribers.get(sub.topic_name, 0) + 1

        def matched():
            return all(pub.get_subscription_count() >= subscribers.get(pub.topic_name, 0)
                       for node in self.nodes for pub in node.publishers)
        if not self.spin_until(matched, timeout, poll=0.01):
            raise RuntimeError('in-process nodes did not discover each other')
        # Count traffic from here on: what was sent before the nodes matched may never arrive.
        now_ns = self._now_ns()
        for node in self.nodes:
            counter = MessageCounter.of(node, clock_topic(node), fixed=True)
            counter.wrap_new()  # entities made since it was last looked at
            answer = self._answers.get(node)
            if answer is None:  # it joins
                name = node.get_fully_qualified_name()
                answer = self._answers[node] = Answer(f'{name}#{next(self._ids)}', name, now_ns,
                                                      counter.sent, counter.heard)
            # A member's again: a topic it hears since is owed from here on.
            self.ledger.receive(answer, now_ns)
        self._discovered = True

    def settled(self, now_ns):
        """Return whether every message sent was handled and every node's timers have run."""
        if self.ledger.waiting_for(now_ns):
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
        if not self.spin_until(lambda: not self.ledger.waiting_for(now_ns), timeout):
            raise RuntimeError(f'messages sent at t={now_ns / _NS:.3f} s were not handled')
        for _ in range(steps):
            self.ledger.next_step(now_ns)  # forgets what was heard beyond what was sent
            self.clock_owner.clock.step()
            self.steps += 1
            now_ns = self.clock_owner.now_ns()
            for answer in self._answers.values():
                answer.step_ns = now_ns  # each node answers at once: settled() checks the rest
            self._settle(now_ns, timeout)

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
        return sum(due for _, _, due in self.ledger.waiting_for(self._now_ns()))

    def _now_ns(self):
        return self.clock_owner.now_ns() if self.clock_owner is not None else 0
