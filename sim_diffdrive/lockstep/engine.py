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

A ``UnicycleSim`` with ``publish_clock`` normally steps its clock on a wall timer.  Here the
caller steps it instead: each step advances the clock by one simulator step, then spins until
every message sent in the graph has been handled and no timer of a node is due, so a
controller's answer always lands on its step, whatever the machine's load.  Tests, tools and
users reach it through sim_diffdrive.harness.SimGraph.
"""

import time

_NS = 1_000_000_000


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
        """
        Advance simulated time by whole steps, letting the graph settle after each.

        What the caller sent between two steps (a command published from the test) is handled
        first, at the time it was sent, not one step later.
        """
        if not self._discovered:
            self.wait_for_discovery()
        now_ns = self.clock_owner.now_ns()
        if not self.spin_until(lambda: self._handled == self._sent, timeout):
            raise RuntimeError(f'messages sent at t={now_ns / _NS:.3f} s were not handled')
        for _ in range(steps):
            self.clock_owner.step()
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
