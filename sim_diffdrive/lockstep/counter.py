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
The one way the lockstep counts a node's messages: its MessageCounter (docs/time.md).

Participants, the simulator and the in-process engine (testing/graph.py) all count so, by
wrapping the node's subscription and timer callbacks and ``publish`` methods, so the node's
code does not change.  ``MessageCounter.of(node, ...)`` is the only place that wraps (one
counter a node, however many use it), and so relies on rclpy behaviours that no API
promises: a subscription's (a raw one's too) and a timer's ``callback`` attribute is read at
dispatch, under both executors; a ``publish`` set on a publisher shadows the method, and
``node.publishers`` holds the objects created; the TimeSource's /clock subscription is one of
``node.subscriptions``, and its callback has set the clock when it returns; when a sim-time
timer's callback runs, rcl has moved its schedule on; and the EventsExecutor runs a sim-time
timer's event more than once for one due time, each run moving rcl's schedule a whole period
on (_SimTimeCalls).  test/test_rclpy_behaviour.py pins each, so an rclpy update that changes
one fails there.  No rcl schedule is moved here: no ``reset()``, no period written.
"""

import math
import struct
import time

from rclpy.clock import ClockType
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock as ClockMsg
from sim_diffdrive.cdr import header_stamp_ns
from sim_diffdrive.cdr import UnsupportedEncoding
from sim_diffdrive.lockstep.handshake import ignored_topics

_NS = 1_000_000_000
# How long a participant's stamped subscription says "nothing heard yet" (-1) [s, wall, from
# its first /clock]: a joiner is counted once it has heard each (see StepLedger.waiting_for),
# or after this.  The clock owner says it for good: it waits for the first message on it as
# for any other.
UNHEARD_S = 2.0


class MessageCounter:
    """
    Count what a node publishes and handles on its topics (get one with ``of``).

    Every function in ``listeners`` is called after each wrapped subscription or timer
    callback.  With ``timers`` false the node's timers are left alone (a clock owner's timers
    are its own).  Entities the node creates later are wrapped after its next callback, unless
    ``fixed`` says it creates none (a simulator with hundreds of robots need not look each
    time; whoever adds entities to it calls ``wrap_new``).  With ``unheard_s`` a stamped topic
    it subscribes to and has heard nothing on is in ``heard_stamp`` as -1 for that long from
    its first /clock [s, wall; math.inf: for good], so the clock owner can wait for its first
    message too; the topics whose -1 went so are added to ``unheard_expired``.
    """

    @classmethod
    def of(cls, node, clock_topic, timers=False, fixed=False, unheard_s=None):
        """
        Return node's counter, made on first use; ``timers`` true also counts its timers.

        The first caller's clock_topic, ``fixed`` and ``unheard_s`` hold (though one comes
        with an ``unheard_s`` to a counter without); ``timers`` once true stays true.
        """
        counter = getattr(node, '_message_counter', None)
        if counter is None:
            counter = node._message_counter = cls(node, clock_topic, timers, fixed, unheard_s)
        else:
            if timers and not counter._timers:
                counter._timers = True
                counter.wrap_new()
            if unheard_s is not None and counter.unheard_s is None:
                counter.unheard_s = unheard_s
                for topic in counter._stamped:
                    counter._declare_unheard(topic)
        return counter

    def __init__(self, node, clock_topic, timers, fixed, unheard_s=None):
        self.node = node
        self._timers = timers
        self._fixed = fixed
        self.unheard_s = unheard_s
        self._stamped = set()  # the stamped topics it subscribes to
        self._unheard_since = {}  # topic -> since when unheard [s, monotonic; None: no clock]
        self.unheard_expired = []
        self._ignored = ignored_topics(clock_topic)
        self.listeners = []
        self.sent = {}
        self.heard = {}
        # The highest header stamp [ns] published / handled per topic: a foreign node's stale
        # or zero stamp never lowers what was heard (-1: nothing heard yet, see ``unheard_s``).
        self.sent_stamp = {}
        self.heard_stamp = {}
        self.clock_ns = None
        self.clock_messages = 0  # /clock messages handled, repeats included
        # The last step the clock took [ns] (None until it has stepped), and, while the
        # listeners run after a subscription callback, how far ahead of the clock the message
        # it handled was stamped [ns] (None: no stamp, or no clock yet; see participant.py).
        self.clock_step_ns = None
        self.heard_offset_ns = None
        self._sim_time_calls = {}  # sim-time timer -> its _SimTimeCalls
        self.wrap_new()

    def wrap_new(self):
        """Wrap the node's entities that are not wrapped yet (cheap when there are none)."""
        node = self.node
        for sub in node.subscriptions:
            if not getattr(sub, '_lockstep_counter', None):
                topic = sub.topic_name
                if sub.msg_type is ClockMsg:
                    sub.callback = self._clock_callback(sub.callback)
                elif topic not in self._ignored:
                    self.heard.setdefault(topic, 0)
                    stamp_ns = _stamp_reader(sub.msg_type)
                    if stamp_ns is not None:
                        self._stamped.add(topic)
                        if self.unheard_s is not None:
                            self._declare_unheard(topic)
                    sub.callback = self._heard_callback(sub.callback, topic, stamp_ns)
                sub._lockstep_counter = self
        for timer in node.timers if self._timers else ():
            if not getattr(timer, '_lockstep_counter', None):
                timer.callback = self._timer_callback(timer)
                timer._lockstep_counter = self
        for pub in node.publishers:
            if not getattr(pub, '_lockstep_counter', None):
                if pub.topic_name not in self._ignored:
                    self.sent.setdefault(pub.topic_name, 0)
                    pub.publish = self._counted_publish(pub.publish, pub.topic_name,
                                                        _stamp_reader(pub.msg_type))
                pub._lockstep_counter = self

    def _declare_unheard(self, topic):
        if topic not in self.heard_stamp:
            self.heard_stamp[topic] = -1
            if self.unheard_s < math.inf:  # counted from the first /clock: a simulator is up
                self._unheard_since[topic] = None if self.clock_ns is None else time.monotonic()

    def _expire_unheard(self):
        """Stop saying -1 for a topic heard since, or unheard for unheard_s (it may never come)."""
        now = time.monotonic()
        for topic, since in list(self._unheard_since.items()):
            if self.heard_stamp.get(topic, 0) >= 0:
                del self._unheard_since[topic]
            elif since is None:
                if self.clock_ns is not None:
                    self._unheard_since[topic] = now
            elif now - since > self.unheard_s:
                del self.heard_stamp[topic], self._unheard_since[topic]
                self.unheard_expired.append(topic)

    def _after(self):
        if not self._fixed:
            self.wrap_new()
        if self._unheard_since:
            self._expire_unheard()
        for listener in self.listeners:
            listener()
        self.heard_offset_ns = None

    def _clock_callback(self, callback):
        def counted(msg):
            callback(msg)
            clock_ns = msg.clock.sec * _NS + msg.clock.nanosec
            if self.clock_ns is not None and clock_ns > self.clock_ns:
                self.clock_step_ns = clock_ns - self.clock_ns
            self.clock_ns = clock_ns
            self.clock_messages += 1
            if self._sim_time_calls:  # run the calls duplicate events made rcl skip, now due
                timers = set(self.node.timers)  # node.timers is a generator: one pass, kept
                for timer, calls in list(self._sim_time_calls.items()):
                    if timer in timers:
                        calls.catch_up()
                    else:  # destroyed
                        del self._sim_time_calls[timer]
            self._after()
        return counted

    def _heard_callback(self, callback, topic, stamp_ns):
        def counted(*args):
            self.heard[topic] += 1
            offset = None
            if stamp_ns is not None:
                stamp = stamp_ns(args[0])
                if stamp > self.heard_stamp.get(topic, -1):
                    self.heard_stamp[topic] = stamp
                if self.clock_ns is not None:
                    offset = stamp - self.clock_ns
            callback(*args)
            self.heard_offset_ns = offset  # for the listeners only (reset by _after)
            self._after()
        return counted

    def _timer_callback(self, timer):
        callback = timer.callback
        if timer.clock.clock_type != ClockType.ROS_TIME:
            def counted(*args):
                callback(*args)
                self._after()
            return counted
        calls = self._sim_time_calls[timer] = _SimTimeCalls(timer, callback, self._after)
        return calls.on_event

    def until_next_call_ns(self, timer):
        """Return the simulated time until timer's next call [ns], as this counter runs it."""
        calls = self._sim_time_calls.get(timer)
        if calls is None or calls.due_ns is None:
            return timer.time_until_next_call()
        return max(0, calls.due_ns - timer.clock.now().nanoseconds)

    def _counted_publish(self, publish, topic, stamp_ns):
        def counted(msg):
            self.sent[topic] += 1
            if stamp_ns is not None:
                stamp = stamp_ns(msg)
                if stamp > self.sent_stamp.get(topic, -1):
                    self.sent_stamp[topic] = stamp
            publish(msg)
        return counted


class _SimTimeCalls:
    """
    One sim-time timer's calls: each run once, at the first clock time at or after it is due.

    rclpy's EventsExecutor queues a timer's event once for every update of its timers that
    finds it due, so a loaded executor runs the event several times for one due time (rclcpp
    #2771 has the same bug), and each run moves rcl's schedule a period on.  ``on_event`` runs
    the callback only when it is due: a second event at the same clock time would run it
    twice, and one that waited in the queue until the clock had moved on would run it between
    two due times, after the node had answered its step.  rcl's schedule is left whole periods
    ahead, and ``catch_up`` (after each /clock) runs each call it skips, at its due time: a
    reset of the schedule would make its timers manager queue the event again.
    """

    def __init__(self, timer, callback, after):
        self.timer = timer
        self._callback = callback
        self._after = after
        self.fired_ns = None  # the clock time of the last run
        self.due_ns = None  # the next call's due time: rcl's, or before it after duplicates

    def on_event(self, *args):
        timer = self.timer
        if timer.is_canceled():
            return  # an event queued before the cancel
        now_ns = timer.clock.now().nanoseconds
        if self.fired_ns is not None and self.fired_ns <= now_ns < self.due_ns:
            return  # a duplicate (rcl moved its schedule a period on: catch_up covers it)
        # rcl moved its schedule on before this event ran, past now if it fell behind (a
        # clock that went back, replayed or restarted, starts it afresh).
        until_ns = timer.time_until_next_call()
        self.fired_ns = now_ns
        self.due_ns = now_ns + (until_ns if until_ns and until_ns > 0 else timer.timer_period_ns)
        self._callback(*args)
        self._after()

    def catch_up(self):
        """Run the call due by now if rcl's schedule, ahead after duplicates, skips it."""
        timer = self.timer
        if self.due_ns is None or timer.is_canceled():
            return
        now_ns = timer.clock.now().nanoseconds
        if now_ns < self.fired_ns:
            self.fired_ns = self.due_ns = None  # the clock went back: rcl's schedule holds
        elif self.due_ns <= now_ns and timer.time_until_next_call() > 0:
            # Due: the next due time a whole number of periods on, after now (as rcl does).
            period_ns = timer.timer_period_ns
            self.fired_ns = now_ns
            self.due_ns += period_ns * (1 + (now_ns - self.due_ns) // period_ns)
            self._callback()  # the /clock callback's listeners run next


def clock_topic(node):
    """Return the clock topic node runs on (its TimeSource's subscription, remapped or not)."""
    return next((sub.topic_name for sub in node.subscriptions if sub.msg_type is ClockMsg),
                '/clock')


def _stamp_reader(msg_type):
    """
    Return how to read the header stamp [ns] of msg_type's messages, or None if they have none.

    A message is stamped when its first field is a std_msgs/Header.  The function takes the
    message as an object or as its CDR bytes (a raw subscription, a serialized publish), where
    the stamp lies right after the encapsulation header; bytes that do not hold one give -1.
    """
    fields = iter(msg_type.get_fields_and_field_types().items())
    if next(fields, None) != ('header', 'std_msgs/Header'):
        return None

    def stamp_ns(msg):
        if isinstance(msg, bytes):
            try:
                return header_stamp_ns(msg)
            except UnsupportedEncoding:
                try:
                    msg = deserialize_message(msg, msg_type)
                except RuntimeError:
                    return -1
            except struct.error:
                return -1
        stamp = msg.header.stamp
        return stamp.sec * _NS + stamp.nanosec
    return stamp_ns
