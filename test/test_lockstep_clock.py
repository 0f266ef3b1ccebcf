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

"""The lockstep clock across nodes: answers pace it, its timer only watches, and its bytes."""

import math
import time
from types import SimpleNamespace

from geometry_msgs.msg import Twist
from motion_challenges.rotate_robot import RotateRobot
from nav_msgs.msg import Odometry
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from rclpy.serialization import serialize_message
from sim_diffdrive.cdr import read_string
from sim_diffdrive.cdr import string_message
from sim_diffdrive.dds_teardown import held_context
from sim_diffdrive.harness import isolated_domain_id
from sim_diffdrive.lockstep import participant as participant_module
from sim_diffdrive.lockstep.counter import MessageCounter
from sim_diffdrive.lockstep.handshake import Answer
from sim_diffdrive.lockstep.handshake import Roster
from sim_diffdrive.lockstep.owner import LockstepOwner
from sim_diffdrive.lockstep.participant import ANSWER_QOS
from sim_diffdrive.lockstep.participant import take_part
from sim_diffdrive.sim import clock as clock_module
from std_msgs.msg import String

NS = 1_000_000_000


@pytest.mark.parametrize('text', ['', 'step', '{"id":"/m#1","heard":{"/odom":3}}', 'héllo'])
def test_an_answer_as_bytes_is_the_string_rclpy_serializes(text):
    data = string_message(text)
    assert data == serialize_message(String(data=text))
    assert read_string(data) == text == deserialize_message(data, String).data


def test_a_string_in_another_layout_is_refused_not_misread():
    little = string_message('abc')
    big = b'\x00\x00\x00\x00' + (4).to_bytes(4, 'big') + b'abc\x00'
    assert read_string(big) == 'abc'
    for data in (b'\x00\x03' + little[2:], little[:9], b''):
        with pytest.raises(ValueError):
            read_string(data)


def test_a_motions_command_bytes_are_the_twist_rclpy_serializes(graph):
    motion = graph.node(RotateRobot, angular_speed_deg=30.0, angle_deg=90.0, clockwise=False)
    sent = []
    motion.cmd_pub.publish = sent.append
    motion.publish_command(0.25, -1)
    twist = Twist()
    twist.linear.x, twist.angular.z = 0.25, -1.0
    assert sent == [serialize_message(twist)]


class Driver(Node):
    """A controller on sim time: a command at every 20 ms step, in the simulator's lockstep."""

    def __init__(self, **kwargs):
        super().__init__('driver', **kwargs)
        self.pub = self.create_publisher(Twist, 'cmd_vel', 10)
        self.create_subscription(Odometry, 'odom', lambda msg: None, 10)
        self.create_timer(0.02, lambda: self.pub.publish(Twist()))
        self.lockstep = take_part(self)


def test_answers_pace_the_clock_and_its_timer_only_watches(graph, monkeypatch):
    # Ticks longer than a step's budget (4 ms at real_time_factor 5), as 0.5 and 2 ms are at
    # factors above 40 across processes: a step that settles sooner waits out the rest of its
    # budget, neither stepping at once nor waiting for a tick.
    monkeypatch.setattr(clock_module, '_LOCKSTEP_TICK_S', 0.02)
    monkeypatch.setattr(clock_module, '_WATCH_TICK_S', 0.05)
    sim = graph.sim(stepped=False, publish_clock=True, lockstep=True, real_time_factor=5.0)
    clock = sim.clock
    assert clock.timer.timer_period_ns == 20_000_000  # freewheeling: it catches up in bursts
    ticks = []
    clock.timer.callback = lambda: (ticks.append(sim.now_ns()), clock._on_timer())
    driver = graph.node(Driver)
    assert graph.spin_until(lambda: driver.lockstep.joined, 10.0)
    assert clock.timer.timer_period_ns == 50_000_000  # answers drive the steps now
    # From the step's place on the clock's schedule, not from when this test saw it: a step is
    # dated on the schedule, up to a budget before it was taken, and this test sees it later
    # still, so a wall time read here would miss both and make the clock look fast.
    start_ns, start_wall, ticked = sim.now_ns(), clock.wall, len(ticks)
    assert graph.spin_until(lambda: sim.now_ns() - start_ns >= NS // 2, 30.0)
    sim_s, wall_s = (sim.now_ns() - start_ns) / NS, time.monotonic() - start_wall
    assert sim_s <= 5.0 * wall_s + 1e-6  # never ahead of its schedule (float sums)
    assert len(ticks) - ticked < 25 / 2  # 25 steps, most of them taken on answers
    driver.lockstep.leave()
    assert graph.spin_until(lambda: clock.timer.timer_period_ns == 20_000_000, 5.0)


def test_steps_slower_than_lockstep_timeout_drop_nobody(graph):
    # A participant answers only when a step (or a message) comes: quiet between steps longer
    # than lockstep_timeout (0.5 s here, 1 s a step), two participants either, is not silence.
    sim = graph.sim(stepped=False, publish_clock=True, lockstep=True, real_time_factor=0.02,
                    lockstep_timeout=0.5)
    one, two = graph.node(Driver, namespace='one'), graph.node(Driver, namespace='two')
    assert graph.spin_until(lambda: one.lockstep.joined and two.lockstep.joined, 10.0)
    now_ns = sim.now_ns()
    assert graph.spin_until(lambda: sim.now_ns() - now_ns >= 40_000_000, 10.0)  # two steps
    assert sim.clock.owner.ledger.dropped == {}


def test_the_simulator_says_it_has_heard_no_stamped_command_yet_for_good(graph):
    # -1 for good on its stamped subscriptions: with it the ledger waits for a member's first
    # TwistStamped (test_handshake.py's owner test), not only for those after it.
    sim = graph.sim(stepped=False, publish_clock=True, lockstep=True, stamped=True)
    counter = MessageCounter.of(sim, '/clock')
    assert counter.heard_stamp == {'/cmd_vel': -1, '/initialpose': -1}
    assert counter.unheard_s == math.inf


def on_sim_time(context, name):
    return Node(name, context=context, parameter_overrides=[Parameter('use_sim_time', value=True)])


def simulator_side(context):
    """Return a node that listens for lockstep answers, as a simulator does."""
    owner = Node('owner', context=context)
    owner.create_subscription(String, '/clock/answers', lambda msg: None, ANSWER_QOS)
    return owner


def test_answer_or_leave_after_rclpy_shut_down_raise_nothing():
    # rclpy's default SIGINT handler shuts the context down before a program's `finally:
    # lockstep.leave()` runs (docs/time.md's example, Ctrl-C); leave() then raised RCLError.
    with held_context(domain_id=isolated_domain_id()) as context:
        node, owner = on_sim_time(context, 'leaving'), simulator_side(context)
        lockstep = take_part(node)
        member = lockstep.add(on_sim_time(context, 'other'))
        deadline = time.monotonic() + 10.0
        while lockstep._publisher.get_subscription_count() == 0:
            assert time.monotonic() < deadline, 'the answer topic never matched'
            time.sleep(0.01)
        lockstep.answer()  # it has said something: leave() owes a goodbye
        rclpy.shutdown(context=context)
        lockstep.answer()  # a callback run after the handler: nothing said, nothing raised
        assert member.leave() is False
        assert lockstep.leave() is False and lockstep.left
        for each in (member.node, node, owner):
            each.destroy_node()


def test_a_step_held_past_lockstep_timeout_drops_the_silent_and_waits_for_the_live():
    # Silence counts from a participant's last answer; a participant answers only when a step
    # (or a message) comes, so only a step held past lockstep_timeout is looked at for it: one
    # silent for as long while the steps are slower than that is not gone.
    now, warned = [0], []
    sim = SimpleNamespace(get_fully_qualified_name=lambda: '/sim', now_ns=lambda: now[0],
                          params=SimpleNamespace(lockstep_timeout=0.5),
                          get_logger=lambda: SimpleNamespace(warning=warned.append))
    owner = LockstepOwner(sim, '/clock', 0.02)
    owner._roster_pub = SimpleNamespace(publish=lambda msg: None)
    ledger, wall = owner.ledger, time.monotonic()
    for pid, heard_wall in (('/sim#owner', wall), ('/gone#1', wall - 0.6), ('/live#1', wall)):
        ledger.receive(Answer(pid, pid[:-2], 0), 0, wall_s=heard_wall)
    ledger.next_step(0)
    now[0] = 20_000_000
    ledger.receive(Answer('/sim#owner', '/sim', now[0]), now[0], wall_s=wall)
    assert owner.may_step(wall, wall - 0.01, 0.02, 0.002)[0] == 0  # held 10 ms: both waited for
    assert ledger.dropped == {} and warned == []
    assert owner.may_step(wall + 0.01, wall - 0.6, 0.02, 0.002)[0] == 0  # held 0.6 s
    assert set(ledger.dropped) == {'/gone#1'}
    assert warned[0] == ('Lockstep: nothing heard from /gone for 0.5 s (its last answer: 0.000 '
                         's); going on without it')
    # The one that still answers is waited for, and said so.
    assert len(warned) == 2 and warned[1].startswith('Lockstep: holding the clock for /live')
    assert warned[1].endswith('(it still answers, so it is waited for)')


def test_a_node_whose_simulator_started_again_is_told_once(ros_context):
    # A user's node in lockstep saw only 'No longer in lockstep' and 'Taking part' in the same
    # millisecond after a restart, and went on planning with its old end time.
    node = on_sim_time(ros_context, 'planner')
    lockstep, warned = take_part(node), []
    node.get_logger = lambda: SimpleNamespace(warning=warned.append, info=lambda text: None)
    for step_ns in (3_000_000_000, 3_020_000_000, 160_000_000, 180_000_000):
        lockstep._on_roster(String(data=Roster('/sim', step_ns).encode()))
        # Another simulator on the same clock (its rosters interleave): not a restart.
        lockstep._on_roster(String(data=Roster('/other_sim', 10_000_000).encode()))
        if step_ns == 3_020_000_000:  # it ran on to 5.82 s with no roster (nobody joined)
            for clock_ns in (5_820_000_000, 140_000_000):  # and heard the new clock first
                lockstep.counter.clock_ns = clock_ns
                lockstep.answer()
    assert warned == ['Simulated time went back from 5.820 s to 0.160 s (/sim restarted?): times '
                      'this node took from the old clock lie ahead of the new one']
    lockstep.leave()
    node.destroy_node()


def test_a_node_whose_simulator_stops_listening_says_so_once(capfd):
    # A newcomer's node waited for ever, silent, after its simulator was stopped.
    with held_context(domain_id=isolated_domain_id()) as context:
        node, owner = on_sim_time(context, 'waiting'), simulator_side(context)
        lockstep = take_part(node)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)

        def spin_until(done):
            deadline = time.monotonic() + 10.0
            while not done() and time.monotonic() < deadline:
                executor.spin_once(timeout_sec=0.01)
            return done()
        assert spin_until(lambda: lockstep._owner_listening)  # as DDS told it
        assert 'no longer listens' not in capfd.readouterr().err
        owner.destroy_node()
        err = []  # stderr as it comes
        assert spin_until(
            lambda: err.append(capfd.readouterr().err) or 'no longer' in ''.join(err))
        assert ("Lockstep: the simulator no longer listens for this node's answers (was it "
                'stopped?)') in ''.join(err)
        for _ in range(20):  # whatever else DDS says of the gone reader, the line came once
            executor.spin_once(timeout_sec=0.01)
        assert (''.join(err) + capfd.readouterr().err).count('no longer listens') == 1
        executor.shutdown()
        node.destroy_node()


def test_a_participant_says_which_of_its_topics_nothing_matches(graph, capfd, monkeypatch):
    # A student's controller in its own process published on cmdvel and waited, as time.md
    # says, until the robot's cmd_vel was counted: for ever, and nothing said why.
    monkeypatch.setattr(participant_module, 'UNMATCHED_CHECK_S', 0.2)
    graph.sim(stepped=False, publish_clock=True, lockstep=True, real_time_factor=5.0)
    driver = graph.node(Driver, namespace='student')  # publishes /student/cmd_vel
    assert graph.spin_until(lambda: driver.lockstep.joined, 10.0)
    err = []
    assert graph.spin_until(lambda: err.append(capfd.readouterr().err) or 'Nothing' in err[-1])
    graph.spin_for(0.5)  # said once
    err = ''.join(err) + capfd.readouterr().err
    assert err.count('driver]: Nothing') == 2, err
    assert ('driver]: Nothing subscribes (yet) to /student/cmd_vel, which it publishes: a topic '
            'named wrong?') in err
    assert ('driver]: Nothing publishes (yet) /student/odom, which it subscribes to: a topic '
            'named wrong?') in err
    driver.lockstep.leave()
