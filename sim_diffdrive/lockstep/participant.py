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
Take part in the simulator's lockstep: ``take_part(node)`` is the one call a node needs.

The node runs on simulated time; its callbacks and publishers are counted by its
MessageCounter (counter.py), so its code does not change; ``take_part(first).add(node)``
makes several nodes of a process one participant.  The rules for a node that takes part, and
for several nodes: docs/time.md ("Take part with your own node").
"""

import os
import time
import uuid

from rclpy.clock import ClockType
from rclpy.duration import Duration
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.executors import MultiThreadedExecutor
from rclpy.qos import DurabilityPolicy
from rclpy.qos import QoSProfile
from rclpy.qos import ReliabilityPolicy
from sim_diffdrive.cdr import string_message
from sim_diffdrive.dds_profile import PROFILE_VARIABLE
from sim_diffdrive.lockstep.counter import clock_topic
from sim_diffdrive.lockstep.counter import MessageCounter
from sim_diffdrive.lockstep.counter import UNHEARD_S
from sim_diffdrive.lockstep.handshake import Answer
from sim_diffdrive.lockstep.handshake import answer_topic
from sim_diffdrive.lockstep.handshake import Roster
from sim_diffdrive.lockstep.handshake import roster_topic
from std_msgs.msg import String

_NS = 1_000_000_000
# How long after joining a participant says which of its topics nothing in the graph matches
# [s, wall]: discovery of the simulator's topics may come after the roster that counts it.
UNMATCHED_CHECK_S = 3.0
ANSWER_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
ROSTER_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)


class Participant:
    """A process's side of the lockstep: answers for its node and every node ``add``-ed."""

    def __init__(self, node):
        _check_sim_time(node)
        self.node = node
        self._name = node.get_fully_qualified_name()
        self.id = f'{self._name}#{uuid.uuid4().hex[:8]}'
        self.owner = None
        self.joined = False
        # The latest roster from the clock owner, and when it came [s, monotonic].
        self.roster = self.roster_wall = None
        self._roster_steps = {}  # owner -> the time of its latest roster [ns]
        self._latest_ns = 0  # the latest /clock answered at, since time last went back [ns]
        self._check_wall = None  # when to say which topics nothing matches [s, monotonic]
        # Off for a simulator on another's clock: it publishes for whoever listens.
        self.name_unmatched = True
        self._last = None
        self._last_clock_messages = 0
        self.left = False
        # When the clock owner last went on without this node [ns, its clock], or None.
        self.dropped_ns = None
        self._clock_topic = clock_topic(node)
        self._answer_topic = answer_topic(self._clock_topic)
        # DDS says when the simulator's answer reader goes: a node whose simulator was
        # stopped waits for /clock, and says why once.
        self._owner_listening = False
        self._publisher = node.create_publisher(
            String, self._answer_topic, ANSWER_QOS,
            event_callbacks=PublisherEventCallbacks(matched=self._on_owner_matched))
        node.create_subscription(String, roster_topic(self._clock_topic), self._on_roster,
                                 ROSTER_QOS)
        # Every node answered for, with its counter; the clock time each is settled at (None:
        # not settled), and how many are settled at each time, so a callback looks at its own
        # node only.
        self._nodes = {}
        self._active = 0
        self._settled_at = {}
        self.counter = self._answer_for(node)

    def can_add(self, node):
        """Return whether add(node) would take it: on sim time, on this clock, not yet added."""
        return (node.get_parameter('use_sim_time').value and node not in self._nodes
                and clock_topic(node) == self._clock_topic)

    def add(self, node):
        """
        Answer for node too, from now on; return its view of this participant (a Member).

        Add a process's nodes before it answers the first time (once the simulator is
        found), with their subscriptions made: counts are summed from the nodes' start, and a
        topic two nodes handle counts as far as both have got (a subscription made later on
        such a topic would start from nothing).
        """
        _check_sim_time(node)
        if self._last is not None or self.left:
            raise RuntimeError(f'{node.get_fully_qualified_name()} cannot join '
                               f'{self.node.get_fully_qualified_name()} in lockstep after it '
                               'has answered: add nodes before spinning')
        if not self.can_add(node):
            raise ValueError(f'{node.get_fully_qualified_name()} cannot be added: it is '
                             f'already, or it runs on {clock_topic(node)}, not on '
                             f'{self._clock_topic}')
        self._answer_for(node)
        return Member(self, node)

    def _answer_for(self, node):
        counter = MessageCounter.of(node, self._clock_topic, timers=True, unheard_s=UNHEARD_S)
        self._nodes[node] = _NodeState(counter)
        self._active += 1
        counter.listeners.append(lambda: self._answer_if_settled(node))
        return counter

    @property
    def clock_step_ns(self):
        """
        Return the simulated time between the node's last two /clock messages [ns], or None.

        The node this participant was made on; None until its clock has moved once.  A
        simulator steps evenly: it is the step the clock will next advance by.
        """
        return self.counter.clock_step_ns

    def until_next_call_ns(self, timer):
        """
        Return the simulated time until the next call of timer, one of the node's [ns].

        As the lockstep runs it: after duplicate events of rclpy's EventsExecutor rcl's own
        schedule (``timer.time_until_next_call()``) may lie whole periods ahead (counter.py).
        """
        return self.counter.until_next_call_ns(timer)

    @property
    def owner_present(self):
        """Whether a simulator that steps in lockstep listens for answers."""
        return self.node.count_subscribers(self._answer_topic) > 0

    def counted_on(self, topic):
        """Return whether some node that handles topic is counted (say, the robot's simulator)."""
        return self.roster is not None and topic in self.roster.heard_topics

    def settled(self):
        """
        Return whether every node answered for has run everything due at one clock time.

        As each node's own callbacks last found it (only they change what it has run).
        """
        if len(self._settled_at) != 1:
            return False
        (count,) = self._settled_at.values()
        return count == self._active

    def answer(self, leaving=False):
        """
        Publish the answer, unless nobody listens or it says nothing new.

        An answer already sent is sent again when /clock came again since: the simulator
        re-sends /clock while it waits, so an answer lost on the way is repeated too (once,
        whatever the number of nodes: the first node's /clock tells).  Once rclpy is shut down
        (its SIGINT handler may do that between two callbacks) nothing is said.
        """
        try:
            self._answer(leaving)
        except RuntimeError:  # rclpy's RCLError: its context is no longer valid
            if self.node.context.ok():
                raise

    def _answer(self, leaving):
        self._latest_ns = max(self._latest_ns, self.counter.clock_ns or 0)
        if self.left or self._publisher.get_subscription_count() == 0:
            return  # gone, or no simulator steps in lockstep (or none yet): spare the hot path
        if self._check_wall is not None and time.monotonic() >= self._check_wall:
            self._check_wall = None  # once: a user's controller waiting on a misnamed topic
            for node in self._nodes:
                say_unmatched(node)
        step_ns, counts = self._totals()
        clock_messages = self.counter.clock_messages
        answer = Answer(self.id, self._name, step_ns, *counts[:2], leaving, *counts[2:])
        repeated_clock = clock_messages != self._last_clock_messages
        if (answer == self._last and not repeated_clock) or not self.node.context.ok():
            return
        self._last = answer
        self._last_clock_messages = clock_messages
        # As bytes: a String message object and its conversion cost more than the text.
        self._publisher.publish(string_message(answer.encode()))

    def _totals(self):
        """Return (step [ns], (sent, heard, sent_stamp, heard_stamp)) of the nodes together."""
        if len(self._nodes) == 1:  # one node (self.counter's): its own counts
            c = self.counter
            return c.clock_ns or 0, (
                dict(c.sent), dict(c.heard), dict(c.sent_stamp), dict(c.heard_stamp))
        sent, heard, sent_stamp, heard_stamp = {}, {}, {}, {}
        step_ns = 0
        for state in self._nodes.values():
            c = state.counter
            # What a node sent counts for good (a gone node's last stop too); what it heard,
            # only while it is answered for: a topic counts as handled by all that handle it.
            for topic, count in (c.sent if state.active else state.sent).items():
                sent[topic] = sent.get(topic, 0) + count
            for topic, stamp in (c.sent_stamp if state.active else state.sent_stamp).items():
                sent_stamp[topic] = max(sent_stamp.get(topic, stamp), stamp)
            if not state.active:
                continue
            step_ns = max(step_ns, c.clock_ns or 0)
            for topic, count in c.heard.items():
                heard[topic] = min(heard.get(topic, count), count)
            # While joining, a node's -1 (nothing heard yet) holds the count back for all
            # (counter.py); once counted it does not lower what those that have heard say.
            for topic, stamp in c.heard_stamp.items():
                low, high = sorted((heard_stamp.get(topic, stamp), stamp))
                heard_stamp[topic] = low if low >= 0 or not self.joined else high
        return step_ns, (sent, heard, sent_stamp, heard_stamp)

    def leave(self, ack_timeout=0.5):
        """
        Tell the simulator not to wait for this participant any more (before destroying it).

        Final, for every node answered for: nothing is answered afterwards.  Waits up to
        ack_timeout [s, wall] until the simulator has the goodbye, so it goes on at once rather
        than after lockstep_timeout; returns False when it did not have it by then.
        """
        acknowledged = True
        if self._last is not None and not self.left:
            if not self.node.context.ok():
                # rclpy is shut down (by its own SIGINT handler, say): no goodbye can go, and the
                # simulator goes on without this participant after its lockstep_timeout.
                acknowledged = False
            else:
                self.answer(leaving=True)
                if ack_timeout > 0.0:
                    acknowledged = self.wait_acknowledged(ack_timeout)
        self.left = True
        return acknowledged

    def wait_acknowledged(self, timeout):
        """Wait up to timeout [s, wall] until the simulator has every answer sent (a goodbye)."""
        return self._publisher.wait_for_all_acked(Duration(seconds=timeout))

    def _leave_node(self, node, ack_timeout):
        """Stop answering for node (its last messages still count); see Member.leave."""
        state = self._nodes[node]
        if state.active:
            state.sent, state.sent_stamp = dict(state.counter.sent), dict(state.counter.sent_stamp)
            self._mark(state, None)
            state.active = False
            self._active -= 1
        if not self._active:
            return self.leave(ack_timeout)
        if not self.node.context.ok():
            return False  # rclpy is shut down: nothing can be said any more
        if self.settled():
            self.answer()  # its last messages: what the simulator waits for now
        return self.wait_acknowledged(ack_timeout) if ack_timeout > 0.0 else True

    def _answer_if_settled(self, node):
        state = self._nodes[node]
        if not state.executor_checked:
            state.executor_checked = _check_executor(node)
        if state.counter.unheard_expired:
            self._say_unheard(node, state.counter)
        if not state.active:
            return
        if self._answered_later(state.counter):
            self._mark(state, None)  # it heard a later step's message: not settled at this one
            return
        self._mark(state, _settled_ns(node, state.counter))
        if self.settled():
            self.answer()

    def _say_unheard(self, node, counter):
        """Say which topics a joining node stops waiting to hear (counter.unheard_expired)."""
        topics, counter.unheard_expired = counter.unheard_expired, []
        if not self.joined and self.owner_present:
            node.get_logger().info(
                f'Lockstep: nothing heard on {", ".join(topics)} within {counter.unheard_s:g} '
                's of the first /clock; to be counted without waiting for a first message')

    def _answered_later(self, counter):
        """Return whether the message just handled is better answered by a later callback."""
        offset = counter.heard_offset_ns
        if offset is None:
            return False
        # A message stamped up to a step ahead of the clock (the simulator publishes a step's
        # odometry before its /clock) is answered with that step: its /clock is on its way,
        # and an answer for the step before would be one the simulator no longer waits for.
        if 0 < offset <= (counter.clock_step_ns or 0):
            return True
        # Not in the lockstep yet, this node catches up on what the simulator published
        # before (up to a subscription's depth of odometry per robot, behind its clock): the
        # simulator holds the clock until it has heard the newest, so answering each older
        # one only costs both sides.  The newest is stamped at the clock, or a step ahead;
        # should a topic's newest be stamped behind it, the re-sent /clock brings the answer.
        return offset < 0 and not self.joined

    def _mark(self, state, settled_ns):
        """Note the time node's state is settled at (None: not settled)."""
        if state.settled_ns == settled_ns:
            return
        if state.settled_ns is not None:
            left = self._settled_at[state.settled_ns] - 1
            if left:
                self._settled_at[state.settled_ns] = left
            else:
                del self._settled_at[state.settled_ns]
        if settled_ns is not None:
            self._settled_at[settled_ns] = self._settled_at.get(settled_ns, 0) + 1
        state.settled_ns = settled_ns

    def _on_owner_matched(self, info):
        listening, self._owner_listening = self._owner_listening, info.current_count > 0
        if listening and not self._owner_listening and not self.left:
            self.node.get_logger().warning(
                f'Lockstep: {self.owner or "the simulator"} no longer listens for this '
                "node's answers (was it stopped?); simulated time waits for it or another")

    def _on_roster(self, msg):
        try:
            roster = Roster.decode(msg.data)
        except ValueError:
            return
        self.roster = roster
        self.roster_wall = time.monotonic()
        # Per owner: two on one clock (warned about apart) interleave their rosters.
        last_ns = self._roster_steps.get(roster.owner)
        self._roster_steps[roster.owner] = roster.step_ns
        if last_ns is not None and roster.step_ns < last_ns:  # once: rosters go on from there
            # From the latest time this node answered for: a roster comes when who takes
            # part changes, and the last may be from when it joined.
            self.node.get_logger().warning(
                f'Simulated time went back from {max(last_ns, self._latest_ns) / _NS:.3f} s to '
                f'{roster.step_ns / _NS:.3f} s ({roster.owner} restarted?): times this node '
                'took from the old clock lie ahead of the new one')
            self._latest_ns = roster.step_ns
        self.owner = roster.owner
        dropped_ns = roster.dropped.get(self.id)
        if dropped_ns is not None and dropped_ns != self.dropped_ns:
            self.dropped_ns = dropped_ns
            self.node.get_logger().warning(
                f'{roster.owner} went on without this node at {dropped_ns / _NS:.3f} s: it heard '
                'nothing from it for its lockstep_timeout (a stalled process, or a lossy link?)'
                + ('' if os.environ.get(PROFILE_VARIABLE) else "; without the package's Fast DDS "
                   f'profile ({PROFILE_VARIABLE}, docs/time.md) a lost message waits 3 s'))
        joined = self.id in roster.members
        if joined != self.joined:
            self.joined = joined
            if joined and self._check_wall is None and self.name_unmatched:
                self._check_wall = time.monotonic() + UNMATCHED_CHECK_S
            self.node.get_logger().info(
                f'Taking part in lockstep with {roster.owner}' if joined
                else f'No longer in lockstep with {roster.owner}')


class Member:
    """
    A node's view of the Participant that answers for it with other nodes (Participant.add).

    What the simulator says (joined, the roster, a drop) is the participant's; ``leave()``
    is this node's alone: the others go on (the participant's own ``leave()`` says goodbye for
    all of them).
    """

    def __init__(self, participant, node):
        self.participant = participant
        self.node = node
        self.counter = participant._nodes[node].counter
        self.id = participant.id

    owner = property(lambda self: self.participant.owner)
    joined = property(lambda self: self.participant.joined)
    roster = property(lambda self: self.participant.roster)
    roster_wall = property(lambda self: self.participant.roster_wall)
    dropped_ns = property(lambda self: self.participant.dropped_ns)
    owner_present = property(lambda self: self.participant.owner_present)
    # This node's clock step, read-only (see Participant.clock_step_ns).
    clock_step_ns = property(lambda self: self.counter.clock_step_ns)

    def counted_on(self, topic):
        """Return whether some node that handles topic is counted (see Participant)."""
        return self.participant.counted_on(topic)

    def until_next_call_ns(self, timer):
        """Return the simulated time until the next call of timer, one of this node's [ns]."""
        return self.counter.until_next_call_ns(timer)

    def leave(self, ack_timeout=0.5):
        """
        Stop answering for this node (call before destroying it); the others go on.

        Its messages so far (a final stop) are still waited for.  Waits up to ack_timeout
        [s, wall] until the simulator has what was answered; False when it did not by then.
        """
        return self.participant._leave_node(self.node, ack_timeout)

    def wait_acknowledged(self, timeout):
        """Wait up to timeout [s, wall] until the simulator has every answer sent."""
        return self.participant.wait_acknowledged(timeout)


class _NodeState:

    def __init__(self, counter):
        self.counter = counter
        self.active = True
        self.executor_checked = False
        self.settled_ns = None
        # What it had sent when it stopped being answered for.
        self.sent, self.sent_stamp = {}, {}


def _check_executor(node):
    """Raise under an executor that runs callbacks at once; return whether node has one."""
    # A MultiThreadedExecutor may take a due timer and run its callback later on another
    # thread: the node would look settled in between and answer before its command.
    executor = node.executor
    if isinstance(executor, MultiThreadedExecutor):
        raise RuntimeError(
            f'{node.get_fully_qualified_name()} cannot take part in lockstep under a '
            f'{type(executor).__name__}: its answers need one callback at a time; spin it '
            'with a SingleThreadedExecutor or rclpy.experimental.EventsExecutor')
    return executor is not None


def _check_sim_time(node):
    if not node.get_parameter('use_sim_time').value:
        raise ValueError(f'{node.get_fully_qualified_name()} cannot take part in lockstep: '
                         'use_sim_time is false')


def _settled_ns(node, counter):
    """Return the clock time [ns] node has run everything due at, or None."""
    clock_ns = counter.clock_ns
    if clock_ns is None or node.get_clock().now().nanoseconds != clock_ns:
        return None
    for timer in node.timers:
        # The clock type first: a Python attribute, where is_canceled() takes the timer's lock.
        if timer.clock.clock_type != ClockType.ROS_TIME or timer.is_canceled():
            continue
        due = timer.time_until_next_call()
        if due is not None and due <= 0:
            return None
    return clock_ns


def say_unmatched(node, where=''):
    """Say which topics node publishes that nothing subscribes to, and the other way round."""
    clock = clock_topic(node)
    # rclpy's and lockstep's own, and tf's: a tf2 listener hears /tf_static only from some.
    own = {'/rosout', '/parameter_events', clock, answer_topic(clock), roster_topic(clock),
           '/tf', '/tf_static'}
    unheard = sorted(pub.topic_name for pub in node.publishers
                     if pub.topic_name not in own and not pub.get_subscription_count())
    unfed = sorted(sub.topic_name for sub in node.subscriptions
                   if sub.topic_name not in own and not node.count_publishers(sub.topic_name))
    logger = node.get_logger()
    if unheard:
        logger.info(f'Nothing{where} subscribes (yet) to {", ".join(unheard)}, which it '
                    'publishes: a topic named wrong?')
    if unfed:
        logger.info(f'Nothing{where} publishes (yet) {", ".join(unfed)}, which it subscribes '
                    'to: a topic named wrong?')


def take_part(node):
    """
    Make node a lockstep participant of the simulator that owns /clock; return the Participant.

    Call it once, after creating the node's publishers, subscriptions and timers (later ones
    are picked up too).  Call ``leave()`` on the result before destroying the node, so the
    simulator need not wait ``lockstep_timeout`` to go on without it.
    """
    return Participant(node)
