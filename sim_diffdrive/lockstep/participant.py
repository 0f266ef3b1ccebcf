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

The node must run on simulated time (``use_sim_time``).  From then on the simulator that owns
``/clock`` does not advance past a step until this node has run everything due at that time
and the messages it published have been handled by the simulator (see handshake.py).  The
node's subscription and timer callbacks and its publishers are counted by its MessageCounter
(counter.py), so the node's code does not change.
"""

import time
import uuid

from rclpy.clock import ClockType
from rclpy.duration import Duration
from rclpy.executors import MultiThreadedExecutor
from rclpy.qos import DurabilityPolicy
from rclpy.qos import QoSProfile
from rclpy.qos import ReliabilityPolicy
from rosgraph_msgs.msg import Clock as ClockMsg
from sim_diffdrive.lockstep.counter import MessageCounter
from sim_diffdrive.lockstep.handshake import Answer
from sim_diffdrive.lockstep.handshake import answer_topic
from sim_diffdrive.lockstep.handshake import Roster
from sim_diffdrive.lockstep.handshake import roster_topic
from std_msgs.msg import String

_NS = 1_000_000_000
ANSWER_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
ROSTER_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)


class Participant:
    """A node's side of the lockstep handshake (see the module docstring)."""

    def __init__(self, node):
        if not node.get_parameter('use_sim_time').value:
            raise ValueError(f'{node.get_fully_qualified_name()} cannot take part in lockstep: '
                             'use_sim_time is false')
        self.node = node
        self.id = f'{node.get_fully_qualified_name()}#{uuid.uuid4().hex[:8]}'
        self.owner = None
        self.joined = False
        # The latest roster from the clock owner, and when it came [s, monotonic].
        self.roster = None
        self.roster_wall = None
        self._last = None
        self._last_clock_messages = 0
        self.left = False
        # When the clock owner last went on without this node [ns, its clock], or None.
        self.dropped_ns = None
        self._executor_checked = False
        # The clock this node runs on (its TimeSource's subscription, remapped or not).
        clock_topic = next((sub.topic_name for sub in node.subscriptions
                            if sub.msg_type is ClockMsg), '/clock')
        self._answer_topic = answer_topic(clock_topic)
        self._publisher = node.create_publisher(String, self._answer_topic, ANSWER_QOS)
        node.create_subscription(String, roster_topic(clock_topic), self._on_roster,
                                 ROSTER_QOS)
        self.counter = MessageCounter.of(node, clock_topic, timers=True)
        self.counter.listeners.append(self._answer_if_settled)

    @property
    def owner_present(self):
        """Whether a simulator that steps in lockstep listens for answers."""
        return self.node.count_subscribers(self._answer_topic) > 0

    def counted_on(self, topic):
        """Return whether some node that handles topic is counted (say, the robot's simulator)."""
        return self.roster is not None and topic in self.roster.heard_topics

    def settled(self):
        """Return whether the node has run everything due at the latest clock it has seen."""
        clock_ns = self.counter.clock_ns
        if clock_ns is None or self.node.get_clock().now().nanoseconds != clock_ns:
            return False
        for timer in self.node.timers:
            if timer.is_canceled() or timer.clock.clock_type != ClockType.ROS_TIME:
                continue
            due = timer.time_until_next_call()
            if due is not None and due <= 0:
                return False
        return True

    def answer(self, leaving=False):
        """
        Publish this node's answer, unless nobody listens or it says nothing new.

        An answer already sent is sent again when /clock came again since: the simulator
        re-sends /clock while it waits, so an answer lost on the way is repeated too.
        """
        if self.left or self._publisher.get_subscription_count() == 0:
            return  # gone, or no simulator steps in lockstep (or none yet): spare the hot path
        counter = self.counter
        answer = Answer(self.id, self.node.get_fully_qualified_name(), counter.clock_ns or 0,
                        dict(counter.sent), dict(counter.heard), leaving,
                        dict(counter.sent_stamp), dict(counter.heard_stamp))
        repeated_clock = counter.clock_messages != self._last_clock_messages
        if (answer == self._last and not repeated_clock) or not self.node.context.ok():
            return
        self._last = answer
        self._last_clock_messages = counter.clock_messages
        msg = String()
        msg.data = answer.encode()
        self._publisher.publish(msg)

    def leave(self, ack_timeout=0.5):
        """
        Tell the simulator not to wait for this node any more (call before destroying it).

        Final: nothing is answered afterwards.  Waits up to ack_timeout [s, wall] until the
        simulator has the goodbye, so it goes on at once rather than after lockstep_timeout;
        returns False when it did not have it by then.
        """
        acknowledged = True
        if self._last is not None and not self.left:
            self.answer(leaving=True)
            if ack_timeout > 0.0:
                acknowledged = self.wait_acknowledged(ack_timeout)
        self.left = True
        return acknowledged

    def wait_acknowledged(self, timeout):
        """Wait up to timeout [s, wall] until the simulator has every answer sent (a goodbye)."""
        return self._publisher.wait_for_all_acked(Duration(seconds=timeout))

    def _answer_if_settled(self):
        if not self._executor_checked:
            self._check_executor()
        if self.settled():
            self.answer()

    def _check_executor(self):
        # A MultiThreadedExecutor may take a due timer and run its callback later on another
        # thread: the node would look settled in between and answer before its command.
        executor = self.node.executor
        if isinstance(executor, MultiThreadedExecutor):
            raise RuntimeError(
                f'{self.node.get_fully_qualified_name()} cannot take part in lockstep under a '
                f'{type(executor).__name__}: its answers need one callback at a time; spin it '
                'with a SingleThreadedExecutor or rclpy.experimental.EventsExecutor')
        self._executor_checked = executor is not None

    def _on_roster(self, msg):
        try:
            roster = Roster.decode(msg.data)
        except ValueError:
            return
        self.roster = roster
        self.roster_wall = time.monotonic()
        self.owner = roster.owner
        dropped_ns = roster.dropped.get(self.id)
        if dropped_ns is not None and dropped_ns != self.dropped_ns:
            self.dropped_ns = dropped_ns
            self.node.get_logger().warning(
                f'{roster.owner} went on without this node at {dropped_ns / _NS:.3f} s: it heard '
                'nothing from it for its lockstep_timeout (a stalled process, or a lossy link?)')
        joined = self.id in roster.members
        if joined != self.joined:
            self.joined = joined
            self.node.get_logger().info(
                f'Taking part in lockstep with {roster.owner}' if joined
                else f'No longer in lockstep with {roster.owner}')


def take_part(node):
    """
    Make node a lockstep participant of the simulator that owns /clock; return the Participant.

    Call it once, after creating the node's publishers, subscriptions and timers (later ones
    are picked up too).  Call ``leave()`` on the result before destroying the node, so the
    simulator need not wait ``lockstep_timeout`` to go on without it.
    """
    return Participant(node)
