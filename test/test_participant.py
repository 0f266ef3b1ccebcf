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


"""A node's side of the lockstep: what take_part() counts and when it answers."""

from types import SimpleNamespace

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.time import Time
from rosgraph_msgs.msg import Clock as ClockMsg
from sim_diffdrive.dds_profile import PROFILE_VARIABLE
from sim_diffdrive.lockstep.handshake import Answer
from sim_diffdrive.lockstep.handshake import Roster
from sim_diffdrive.lockstep.participant import ANSWER_QOS
from sim_diffdrive.lockstep.participant import ROSTER_QOS
from sim_diffdrive.lockstep.participant import take_part
from std_msgs.msg import String


@pytest.fixture
def node(ros_context):
    node = Node('controller', context=ros_context,
                parameter_overrides=[Parameter('use_sim_time', value=True)])
    try:
        yield node
    finally:
        node.destroy_node()


def test_counts_what_the_node_publishes_and_handles(node):
    pub = node.create_publisher(Twist, 'cmd_vel', 10)
    heard = []
    sub = node.create_subscription(Odometry, 'odom', heard.append, 10)
    lockstep = take_part(node)
    pub.publish(Twist())
    pub.publish(Twist())
    odom = Odometry()
    odom.header.stamp = Time(seconds=3).to_msg()
    sub.callback(odom)
    counter = lockstep.counter
    assert counter.sent == {'/cmd_vel': 2}
    assert counter.heard == {'/odom': 1} and heard == [odom]
    assert counter.heard_stamp == {'/odom': 3_000_000_000}


def tick_at(node):
    """
    Give node a 0.1 s timer on sim time and take part; return (clock_at, event, ticks, lockstep).

    clock_at(t_ns) hands node a /clock message as its TimeSource's subscription gets one;
    event(times) runs the timer's event as the EventsExecutor does: rcl's call (which moves
    rcl's schedule a period on, due or not), then the callback.
    """
    ticks = []
    timer = node.create_timer(0.1, lambda: ticks.append(node.get_clock().now().nanoseconds))
    lockstep = take_part(node)
    clock_sub = next(sub for sub in node.subscriptions if sub.msg_type is ClockMsg)

    def clock_at(t_ns):
        clock_sub.callback(ClockMsg(clock=Time(nanoseconds=t_ns).to_msg()))

    def event(times=1):
        for _ in range(times):
            timer.handle.call_timer()
            timer.callback()
    return clock_at, event, ticks, SimpleNamespace(timer=timer, lockstep=lockstep)


def test_a_timer_runs_once_per_clock_time_however_often_its_event_comes(node):
    clock_at, event, ticks, the = tick_at(node)
    clock_at(5_000_000_000)
    event(times=3)  # what a loaded EventsExecutor can deliver for one period
    assert ticks == [5_000_000_000]
    # The next call is a period after this time, not three periods later.
    assert the.lockstep.until_next_call_ns(the.timer) == 100_000_000
    clock_at(5_100_000_000)
    assert ticks == [5_000_000_000, 5_100_000_000]


def test_a_timer_event_that_comes_between_two_due_times_runs_nothing(node):
    # A duplicate event that waited in a loaded EventsExecutor's queue while the clock moved
    # on: run, it sent a motion's command after the node had answered the step.
    clock_at, event, ticks, the = tick_at(node)
    clock_at(5_000_000_000)
    event()
    clock_at(5_040_000_000)
    event()  # the stale event
    assert ticks == [5_000_000_000]
    # Still due a period after its last run, not a period after the stale event.
    assert the.lockstep.until_next_call_ns(the.timer) == 60_000_000
    clock_at(5_100_000_000)
    assert not the.timer.is_ready()  # rcl's schedule: a period ahead
    assert ticks == [5_000_000_000, 5_100_000_000]


def test_a_period_off_the_clock_steps_keeps_its_schedule_through_duplicate_events(node):
    # 125 ms on 20 ms steps: due at 5.125, 5.25, 5.375 ..., run at the first step at or after
    # each (5.14, 5.26, 5.38, 5.5, 5.64), duplicates or not.  Run a period after each run
    # instead, the schedule drifted a step late every period (5.14, 5.28, 5.42 ...), and a
    # timed motion at 8 Hz ended 0.36 deg off.
    clock = node.get_clock()
    clock.set_ros_time_override(Time(nanoseconds=5_000_000_000))
    ticks = []
    timer = node.create_timer(0.125, lambda: ticks.append(clock.now().nanoseconds))
    take_part(node)
    clock_sub = next(sub for sub in node.subscriptions if sub.msg_type is ClockMsg)
    for t_ns in range(5_020_000_000, 5_660_000_000, 20_000_000):
        clock_sub.callback(ClockMsg(clock=Time(nanoseconds=t_ns).to_msg()))
        while timer.is_ready():  # an event, and a duplicate of it, as a loaded executor runs
            for _ in range(2):
                timer.handle.call_timer()
                timer.callback()
    assert ticks == [5_140_000_000, 5_260_000_000, 5_380_000_000, 5_500_000_000, 5_640_000_000]


def test_duplicate_events_never_move_the_schedule(node):
    # On a lossy link a loaded EventsExecutor ran one motion's tick event thousands of times
    # at one clock time, each run moving rcl's schedule a period on before the callback.
    # Each reset of the schedule queued another update of the executor's timers, which queued
    # the event again once the clock moved: the duplicates doubled at every step.  The
    # lockstep moves no schedule; it runs the calls rcl's schedule skips.
    clock_at, event, ticks, the = tick_at(node)
    timer = the.timer
    moved = []
    timer.reset = lambda: moved.append('reset')
    for t_ns in (5_000_000_000, 5_100_000_000, 5_200_000_000):
        clock_at(t_ns)
        if timer.is_ready():
            event(times=10)
        assert ticks[-1] == t_ns
    assert ticks == [5_000_000_000, 5_100_000_000, 5_200_000_000]
    assert moved == [] and timer.timer_period_ns == 100_000_000
    clock_at(5_250_000_000)
    assert the.lockstep.until_next_call_ns(timer) == 50_000_000
    assert timer.time_until_next_call() > 50_000_000  # rcl's own: whole periods ahead


def test_a_destroyed_timer_leaves_the_others_catching_up(node):
    # Three timers, the middle one destroyed: duplicate events on the last still leave none of
    # its calls skipped (each /clock looks for every live timer among the node's).
    ticks = {name: [] for name in 'abc'}
    timers = {name: node.create_timer(
        0.1, lambda name=name: ticks[name].append(node.get_clock().now().nanoseconds))
        for name in 'abc'}
    lockstep = take_part(node)
    clock_sub = next(sub for sub in node.subscriptions if sub.msg_type is ClockMsg)
    node.destroy_timer(timers.pop('b'))
    for t_ns in (5_000_000_000, 5_100_000_000, 5_200_000_000):
        clock_sub.callback(ClockMsg(clock=Time(nanoseconds=t_ns).to_msg()))
        for timer in timers.values():
            while timer.is_ready():  # an event and a duplicate, as a loaded executor runs
                for _ in range(2):
                    timer.handle.call_timer()
                    timer.callback()
    expected = [5_000_000_000, 5_100_000_000, 5_200_000_000]
    assert ticks == {'a': expected, 'b': [], 'c': expected}
    assert lockstep.until_next_call_ns(timers['c']) == 100_000_000


def test_a_timer_runs_at_once_after_the_clock_went_back(node):
    # A replayed or restarted /clock: the timer's schedule starts afresh, not 90 s from now.
    clock_at, event, ticks, _ = tick_at(node)
    clock_at(100_000_000_000)
    event()
    clock_at(10_000_000_000)
    event()
    assert ticks == [100_000_000_000, 10_000_000_000]


def test_a_late_event_never_wakes_a_canceled_timer(node):
    # A motion cancels its tick when it finishes; an event still queued for it must not
    # start the tick again, nor may the clock.
    clock_at, event, ticks, the = tick_at(node)
    clock_at(5_000_000_000)
    event()
    the.timer.cancel()
    clock_at(5_040_000_000)
    the.timer.callback()  # queued before the cancel (rcl's call of a canceled timer fails)
    clock_at(5_200_000_000)
    the.timer.callback()
    assert ticks == [5_000_000_000]
    assert the.timer.is_canceled()


def test_take_part_needs_sim_time(ros_context):
    node = Node('wall', context=ros_context)
    try:
        with pytest.raises(ValueError, match='use_sim_time is false'):
            take_part(node)
    finally:
        node.destroy_node()


def test_a_roster_that_says_it_was_dropped_is_noted_once_per_drop(node, monkeypatch):
    lockstep = take_part(node)
    warned = []
    logger = SimpleNamespace(warning=warned.append, info=lambda text: None)
    node.get_logger = lambda: logger

    def roster(members, dropped):
        return String(data=Roster('/sim', 0, members, set(), [], dropped).encode())
    lockstep._on_roster(roster({lockstep.id}, {'/other#1': 5}))
    assert lockstep.joined and lockstep.dropped_ns is None and warned == []
    # Left out of a roster that was lost; the next one, with it back in, still says so.
    for _ in range(2):
        lockstep._on_roster(roster({lockstep.id}, {lockstep.id: 2_500_000_000}))
    assert lockstep.dropped_ns == 2_500_000_000 and lockstep.joined
    assert len(warned) == 1 and 'went on without this node at 2.500 s' in warned[0]
    assert 'Fast DDS' not in warned[0]  # this process loads the package's profile (conftest)
    # A user's node without it is told: on a lossy link repairs wait for a 3 s heartbeat.
    monkeypatch.delenv(PROFILE_VARIABLE)
    lockstep._on_roster(roster({lockstep.id}, {lockstep.id: 4_000_000_000}))
    assert lockstep.dropped_ns == 4_000_000_000 and len(warned) == 2
    assert f'profile ({PROFILE_VARIABLE}, docs/time.md) a lost message waits 3 s' in warned[1]


def test_nothing_heard_is_minus_one_for_a_while_and_a_stale_stamp_never_lowers(node):
    # -1: the owner counts a joiner once it has heard each (test_handshake.py), and after
    # UNHEARD_S it is said no more (a message that never comes holds no join up).
    sub = node.create_subscription(Odometry, 'odom', lambda msg: None, 10)
    node.create_subscription(Odometry, 'never', lambda msg: None, 10)
    node.create_subscription(Twist, 'unstamped', lambda msg: None, 10)
    counter = take_part(node).counter
    assert counter.heard_stamp == {'/odom': -1, '/never': -1} and counter.unheard_s == 2.0
    counter.unheard_s = 0.0  # from the first /clock (a simulator is there) on
    clock = next(sub for sub in node.subscriptions if sub.msg_type is ClockMsg)
    sub.callback(Odometry())  # no /clock yet: '/never' still -1 after this callback
    assert counter.heard_stamp == {'/odom': 0, '/never': -1}
    clock.callback(ClockMsg())
    for seconds in (3, 0, 2):
        odom = Odometry()
        odom.header.stamp = Time(seconds=seconds).to_msg()
        sub.callback(odom)
    assert counter.heard['/odom'] == 4
    assert counter.heard_stamp == {'/odom': 3_000_000_000}


class Listener:
    """The simulator's side in these tests: a node hearing the answers, spun with the nodes."""

    def __init__(self, context, *nodes):
        self.node = Node('owner', context=context)
        self.answers = []
        self.node.create_subscription(
            String, '/clock/answers', lambda msg: self.answers.append(Answer.decode(msg.data)),
            ANSWER_QOS)
        self.executor = SingleThreadedExecutor(context=context)
        for each in (*nodes, self.node):
            self.executor.add_node(each)

    def spin_until(self, predicate, tries=1000):
        for _ in range(tries):
            if predicate():
                return True
            self.executor.spin_once(timeout_sec=0.01)
        return predicate()

    def said(self, count):
        """Return whether exactly count answers have come (none more after a while)."""
        return self.spin_until(lambda: len(self.answers) >= count) and not self.spin_until(
            lambda: len(self.answers) > count, tries=20)

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()


def answering_node(ros_context, node, odom_depth):
    """Give node an odom subscription and make it take part; return the three helpers."""
    odom = node.create_subscription(Odometry, 'odom', lambda msg: None, odom_depth)
    lockstep = take_part(node)
    return lockstep, Listener(ros_context, node), Handed(node, odom)


class Handed:
    """The simulator's /clock and odometry handed to a node's callbacks, at times in ms."""

    def __init__(self, node, odom):
        self.clock = next(sub for sub in node.subscriptions if sub.msg_type is ClockMsg)
        self.odom = odom

    def tick(self, ms):
        self.clock.callback(ClockMsg(clock=Time(nanoseconds=ms * 1_000_000).to_msg()))

    def measured(self, ms):
        msg = Odometry()
        msg.header.stamp = Time(nanoseconds=ms * 1_000_000).to_msg()
        self.odom.callback(msg)


def test_answers_again_on_a_repeated_clock_and_never_after_leaving(ros_context, node):
    lockstep = take_part(node)
    clock = next(sub for sub in node.subscriptions if sub.msg_type is ClockMsg)
    owner = Listener(ros_context, node)
    answers, spin_until = owner.answers, owner.spin_until

    def tick(seconds):
        clock.callback(ClockMsg(clock=Time(seconds=seconds).to_msg()))

    try:
        assert spin_until(lambda: owner.node.count_publishers('/clock/answers') == 1
                          and lockstep._publisher.get_subscription_count() == 1)
        tick(1)
        assert spin_until(lambda: len(answers) == 1)
        tick(1)  # the simulator re-sent /clock: its answer may have been lost
        assert spin_until(lambda: len(answers) == 2)
        assert answers[0] == answers[1] and answers[1].step_ns == 1_000_000_000
        lockstep.leave(ack_timeout=1.0)
        assert spin_until(lambda: len(answers) == 3) and answers[2].leaving
        tick(2)  # a callback after leave(): nothing more is said
        owner.executor.spin_once(timeout_sec=0.2)
        assert len(answers) == 3
    finally:
        owner.close()


def test_odometry_a_step_ahead_is_answered_with_the_clock_of_its_step(ros_context, node):
    # The simulator publishes a step's odometry and then its /clock: a node that handles the
    # odometry first answers once, after the clock, not for the step before and again.  A
    # stamp further ahead is no sign of a coming step (a foreign node on wall time): answered.
    lockstep, owner, handed = answering_node(ros_context, node, odom_depth=10)
    answers, spin_until, said = owner.answers, owner.spin_until, owner.said
    tick, measured = handed.tick, handed.measured
    try:
        assert spin_until(lambda: lockstep._publisher.get_subscription_count() == 1)
        tick(1000)
        measured(1020)  # the clock has not stepped yet: nothing tells a step is coming
        assert said(2) and answers[1].heard == {'/odom': 1}
        tick(1020)
        assert said(3) and answers[2].step_ns == 1_020_000_000
        measured(1040)  # one step (20 ms) ahead: its clock is on its way
        assert said(3)
        tick(1040)
        assert said(4)
        assert answers[3].step_ns == 1_040_000_000 and answers[3].heard == {'/odom': 2}
        assert answers[3].heard_stamp == {'/odom': 1_040_000_000}
        measured(1040)  # at the clock: answered at once
        assert said(5) and answers[4].heard == {'/odom': 3}
        measured(3_601_040)  # an hour ahead: no step of this clock, answered at once
        assert said(6) and answers[5].heard == {'/odom': 4}
        measured(1060)  # a step ahead, but its clock was lost: the simulator re-sends the last
        assert said(6)
        tick(1040)
        assert said(7) and answers[6].step_ns == 1_040_000_000
        assert answers[6].heard == {'/odom': 5}
    finally:
        owner.close()


def test_a_joining_node_answers_the_newest_of_the_odometry_it_catches_up_on(ros_context, node):
    # A node that joins a running simulator finds odometry queued from before, stamped behind
    # its clock (a 16-motion fleet, some 800 messages): the simulator waits for the newest, so
    # answering each older one only costs both sides.  Once the roster lists the node, every
    # message is answered as it comes again.
    lockstep, owner, handed = answering_node(ros_context, node, odom_depth=50)
    answers, spin_until, said = owner.answers, owner.spin_until, owner.said
    tick, measured = handed.tick, handed.measured
    roster = owner.node.create_publisher(String, '/clock/roster', ROSTER_QOS)

    try:
        assert spin_until(lambda: lockstep._publisher.get_subscription_count() == 1)
        tick(1000)
        assert said(1)
        for ms in range(900, 1000, 20):  # queued while the simulator ran on without it
            measured(ms)
        assert said(1)
        measured(1000)  # the newest, at its clock
        assert said(2) and answers[1].heard == {'/odom': 6}
        assert answers[1].heard_stamp == {'/odom': 1_000_000_000}
        measured(990)  # a stale stamp as the newest (a foreign node's): the re-sent clock tells
        assert said(2)
        tick(1000)
        assert said(3) and answers[2].heard == {'/odom': 7}
        msg = String()
        msg.data = Roster('/unicycle_sim', 1_000_000_000, {lockstep.id}).encode()
        roster.publish(msg)
        assert spin_until(lambda: lockstep.joined)
        measured(980)  # in the lockstep: answered at once
        assert said(4) and answers[3].heard == {'/odom': 8}
    finally:
        owner.close()


def test_a_process_answers_once_a_step_for_all_its_nodes(ros_context, node):
    # A fleet: the simulator waits for one participant, not one per motion.  Each node counts
    # as before; the answer sums what they sent and says a topic is handled as far as every
    # node that handles it has got.
    other, late = (Node(name, context=ros_context, parameter_overrides=[
        Parameter('use_sim_time', value=True)]) for name in ('other', 'late'))
    pubs = [each.create_publisher(Twist, 'cmd_vel', 10) for each in (node, other)]
    subs = [each.create_subscription(Odometry, 'odom', lambda msg: None, 10)
            for each in (node, other)]
    ticks = []
    other.create_timer(2.0, lambda: ticks.append(True))  # due at 2 s of sim time, and 4
    lockstep = take_part(node)
    member = lockstep.add(other)
    clocks = [next(sub for sub in each.subscriptions if sub.msg_type is ClockMsg)
              for each in (node, other)]
    owner = Listener(ros_context, node, other)
    answers, spin_until = owner.answers, owner.spin_until

    def odom(seconds):
        msg = Odometry()
        if seconds is not None:
            msg.header.stamp = Time(seconds=seconds).to_msg()
        return msg

    def clock(index, seconds):
        clocks[index].callback(ClockMsg(clock=Time(seconds=seconds).to_msg()))

    try:
        assert spin_until(lambda: lockstep._publisher.get_subscription_count() == 1)
        assert not lockstep.can_add(other) and not lockstep.can_add(owner.node)
        with pytest.raises(ValueError, match='cannot be added'):
            lockstep.add(other)  # twice would count it twice
        pubs[0].publish(Twist())
        pubs[1].publish(Twist())
        subs[0].callback(odom(1))
        subs[0].callback(odom(2))
        subs[1].callback(odom(1))
        # The first node has the step, the added one not yet: nothing is said.
        clock(0, 2)
        assert not spin_until(lambda: answers, tries=20)
        # Both at 2 s, but the added node's timer, due then, has not run: nothing sent yet.
        clock(1, 2)
        assert ticks == [] and lockstep._last is None
        assert spin_until(lambda: ticks and answers)  # run by the executor: then one answer
        assert not spin_until(lambda: len(answers) > 1, tries=20)
        answer = answers[0]
        assert answer.participant == lockstep.id and answer.node == '/controller'
        assert answer.step_ns == 2_000_000_000 and not answer.leaving
        assert answer.sent == {'/cmd_vel': 2} and answer.heard == {'/odom': 1}
        assert answer.heard_stamp == {'/odom': 1_000_000_000}
        # The other way round: the added node first, then the first.
        clock(1, 3)
        assert not spin_until(lambda: len(answers) > 1, tries=20)
        clock(0, 3)
        assert spin_until(lambda: len(answers) == 2) and answers[1].step_ns == 3_000_000_000
        # The simulator re-sends the clock: one answer again, not one per node.
        clock(0, 3)
        clock(1, 3)
        assert spin_until(lambda: len(answers) == 3)
        assert not spin_until(lambda: len(answers) > 3, tries=20) and answers[2] == answers[1]
        with pytest.raises(RuntimeError, match='after it has answered'):
            lockstep.add(late)
        # One leaves after a final stop: that stop still counts, its odometry no longer.
        pubs[1].publish(Twist())
        assert member.leave(ack_timeout=1.0)
        assert spin_until(lambda: len(answers) == 4)
        assert answers[3].sent == {'/cmd_vel': 3} and answers[3].heard == {'/odom': 2}
        assert answers[3].heard_stamp == {'/odom': 2_000_000_000} and not answers[3].leaving
        pubs[1].publish(Twist())  # after it left: not counted
        clock(0, 4)  # the node that left has not seen 4 s: it holds nothing up
        assert spin_until(lambda: len(answers) == 5)
        assert answers[4].step_ns == 4_000_000_000 and answers[4].sent == {'/cmd_vel': 3}
        # The participant's own leave() says goodbye for all.
        assert lockstep.leave(ack_timeout=1.0)
        assert spin_until(lambda: len(answers) == 6) and answers[5].leaving
    finally:
        owner.close()
        for each in (other, late):
            each.destroy_node()


def test_a_node_that_heard_no_stamp_leaves_the_others_waited_for(ros_context, node):
    # A node that has heard nothing stamped on a topic (-1) holds the count back for all while
    # they join; once counted, it does not lower what the others that have heard say.
    other = Node('other', context=ros_context,
                 parameter_overrides=[Parameter('use_sim_time', value=True)])
    try:
        subs = [each.create_subscription(Odometry, 'odom', lambda msg: None, 10)
                for each in (node, other)]
        lockstep = take_part(node)
        lockstep.add(other)
        msg = Odometry()
        msg.header.stamp = Time(seconds=4).to_msg()
        subs[0].callback(msg)
        assert lockstep._totals()[1][3] == {'/odom': -1}
        lockstep.joined = True  # as a roster that counts it says
        _, (_, heard, _, heard_stamp) = lockstep._totals()
        assert heard == {'/odom': 0} and heard_stamp == {'/odom': 4_000_000_000}
    finally:
        other.destroy_node()
