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

"""The lockstep bookkeeping without ROS: who is waited for, and for what."""

import pytest
from sim_diffdrive.lockstep.handshake import Answer
from sim_diffdrive.lockstep.handshake import Roster
from sim_diffdrive.lockstep.handshake import StepLedger

MS = 1_000_000
ODOM = '/odom'
CMD = '/cmd_vel'


class Owner:
    """The simulator's own counts, as it feeds them to its ledger."""

    def __init__(self, ledger):
        self.ledger = ledger
        self.now = 0
        self.odom_sent = 0
        self.cmd_heard = 0
        self.report()
        assert ledger.waiting_for(self.now) == []  # the owner counts itself from the start
        assert ledger.synced() == {'sim'}

    def report(self):
        self.ledger.receive(Answer('sim', '/unicycle_sim', self.now, {ODOM: self.odom_sent},
                                   {CMD: self.cmd_heard}, sent_stamp={ODOM: self.now}),
                            self.now)

    def step(self):
        self.ledger.next_step(self.now)
        self.now += 20 * MS
        self.odom_sent += 1
        self.report()

    def hear_command(self):
        self.cmd_heard += 1
        self.report()


def motion(step, cmds, odoms, odom_stamp, pid='m'):
    return Answer(pid, '/motion', step, {CMD: cmds}, {ODOM: odoms},
                  heard_stamp={ODOM: odom_stamp})


@pytest.fixture
def joined():
    """Return a ledger and an owner at 20 ms with one motion that joined and caught up."""
    ledger = StepLedger('sim')
    owner = Owner(ledger)
    owner.step()
    ledger.receive(motion(owner.now, 0, 1, owner.now), owner.now)
    assert ledger.waiting_for(owner.now) == []
    assert ledger.synced() == {'sim', 'm'}
    return ledger, owner


def test_answer_round_trip():
    answer = Answer('a#1', '/ns/node', 123, {CMD: 4}, {ODOM: 7}, True, {}, {ODOM: 100})
    assert Answer.decode(answer.encode()) == answer


# Anybody can publish on the handshake topics: what is not an answer or a roster is a
# ValueError, which the owner and the participants log and go on after (numbers that are not
# integers too: int() of Infinity or 1e400 raises OverflowError; deep nesting RecursionError).
NOT_INTEGERS = ('1e400', 'Infinity', 'NaN', '1.5', 'true', '"7"')
DEEP = '[' * 100000 + ']' * 100000


@pytest.mark.parametrize('text', ['', 'hello', '[]', '{"id": "x"}', '{"id":1,"node":2,'
                                  '"step_ns":"soon"}', DEEP] + [
    f'{{"id":"x","node":"/x","step_ns":{n}}}' for n in NOT_INTEGERS] + [
    f'{{"id":"x","node":"/x","step_ns":0,"sent":{{"/cmd_vel":{n}}}}}' for n in NOT_INTEGERS])
def test_garbage_is_not_an_answer(text):
    with pytest.raises(ValueError):
        Answer.decode(text)


@pytest.mark.parametrize('text', ['{"owner": "/sim"}', DEEP] + [
    f'{{"owner":"/s","step_ns":{n},"members":[]}}' for n in NOT_INTEGERS] + [
    f'{{"owner":"/s","step_ns":0,"members":[],"dropped":{{"/a":{n}}}}}' for n in NOT_INTEGERS])
def test_garbage_is_not_a_roster(text):
    with pytest.raises(ValueError):
        Roster.decode(text)


def test_roster_round_trip():
    roster = Roster('/sim', 5, {'b', 'a'}, {CMD}, ['/m did not answer'], {'c': 40}, 2 * 10**9)
    assert Roster.decode(roster.encode()) == roster
    assert Roster.decode(Roster('/sim', 5).encode()) == Roster('/sim', 5)  # 0 and {} unsent


def test_the_roster_names_counted_members_and_the_topics_they_handle():
    ledger = StepLedger('sim')
    owner = Owner(ledger)
    owner.step()
    # A simulator on sim time (another robot's) joins: its cmd_vel is not counted on yet.
    robot = Answer('r1', '/robot1/unicycle_sim', owner.now - 20 * MS, {}, {'/robot1/cmd_vel': 0})
    ledger.receive(robot, owner.now)
    assert ledger.waiting_for(owner.now) == []  # not waited for in the step it joined
    assert ledger.roster('/sim', owner.now).heard_topics == {CMD}
    owner.step()
    assert ledger.waiting_for(owner.now) == [('r1', None, 0)]
    version = ledger.version
    robot.step_ns = owner.now
    ledger.receive(robot, owner.now)
    assert ledger.waiting_for(owner.now) == []
    roster = ledger.roster('/sim', owner.now)
    assert roster.members == {'sim', 'r1'}
    assert roster.heard_topics == {CMD, '/robot1/cmd_vel'}
    assert ledger.version > version
    ledger.drop('r1', owner.now)
    roster = ledger.roster('/sim', owner.now)
    assert roster.heard_topics == {CMD}
    # Every later roster says when it was dropped, also once it has joined again.
    assert roster.dropped == {'r1': owner.now}
    ledger.receive(robot, owner.now)
    owner.step()
    assert ledger.roster('/sim', owner.now).dropped == {'r1': owner.now - 20 * MS}


def test_alone_the_owner_never_waits():
    ledger = StepLedger('sim')
    owner = Owner(ledger)
    for _ in range(3):
        owner.step()
        assert ledger.waiting_for(owner.now) == []


def test_a_step_waits_for_the_answer_then_for_the_command_it_covers(joined):
    ledger, owner = joined
    owner.step()
    assert ('m', None, 0) in ledger.waiting_for(owner.now)
    # The answer overtook its command: it says one was sent, the owner has not heard it.
    ledger.receive(motion(owner.now, 1, 2, owner.now), owner.now)
    assert ledger.waiting_for(owner.now) == [('sim', CMD, 1)]
    owner.hear_command()
    assert ledger.waiting_for(owner.now) == []


def test_a_step_waits_until_the_member_heard_the_odometry(joined):
    ledger, owner = joined
    owner.step()
    ledger.receive(motion(owner.now, 0, 1, owner.now - 20 * MS), owner.now)
    assert {reason[:2] for reason in ledger.waiting_for(owner.now)} == {('m', ODOM)}
    ledger.receive(motion(owner.now, 0, 2, owner.now), owner.now)
    assert ledger.waiting_for(owner.now) == []


def test_a_non_member_publisher_never_stalls_and_its_surplus_is_forgotten(joined):
    ledger, owner = joined
    for _ in range(5):  # a teleop's commands, heard by the simulator only
        owner.hear_command()
    owner.step()
    ledger.receive(motion(owner.now, 0, 2, owner.now), owner.now)
    assert ledger.waiting_for(owner.now) == []
    owner.step()
    # The surplus from the teleop does not cover the member's next command.
    ledger.receive(motion(owner.now, 1, 3, owner.now), owner.now)
    assert ledger.waiting_for(owner.now) == [('sim', CMD, 1)]


def test_a_joining_member_is_counted_once_it_caught_up():
    ledger = StepLedger('sim')
    owner = Owner(ledger)
    for _ in range(10):
        owner.step()  # freewheeling: ten odometry messages before the motion answers
    # It answers an older step and has heard only the first few messages: not counted yet,
    # and the step it joined in is not held for it.
    assert ledger.receive(motion(owner.now - 40 * MS, 0, 3, 60 * MS), owner.now) == 'joined'
    assert ledger.waiting_for(owner.now) == []
    assert ledger.synced() == {'sim'}
    # The next step is held for its answer, not for what it has not heard.
    owner.step()
    assert ledger.waiting_for(owner.now) == [('m', None, 0)]
    ledger.receive(motion(owner.now, 0, 9, owner.now - 20 * MS), owner.now)
    assert ledger.waiting_for(owner.now) == []
    assert ledger.synced() == {'sim'}
    owner.step()
    ledger.receive(motion(owner.now, 0, 12, owner.now), owner.now)
    assert ledger.waiting_for(owner.now) == []
    assert ledger.synced() == {'sim', 'm'}
    # From here on it is counted exactly.
    owner.step()
    ledger.receive(motion(owner.now, 0, 12, owner.now - 20 * MS), owner.now)
    assert ledger.waiting_for(owner.now) == [('m', ODOM, 0)]
    ledger.receive(motion(owner.now, 0, 13, owner.now), owner.now)
    assert ledger.waiting_for(owner.now) == []


def test_a_message_a_joining_member_never_gets_does_not_hold_the_clock():
    # The odometry of the step it joined in was written while its subscription was being
    # matched, and never reaches it: it answers each re-sent /clock with what it has heard.
    ledger = StepLedger('sim')
    owner = Owner(ledger)
    owner.step()
    owner.step()
    for _ in range(3):
        ledger.receive(motion(owner.now, 0, 1, owner.now - 20 * MS), owner.now)
        assert ledger.waiting_for(owner.now) == []
    assert ledger.synced() == {'sim'}
    owner.step()  # the next odometry does reach it, after the one it missed
    ledger.receive(motion(owner.now, 0, 2, owner.now), owner.now)
    assert ledger.waiting_for(owner.now) == []
    assert ledger.synced() == {'sim', 'm'}


def test_what_a_member_sent_before_joining_is_not_owed():
    ledger = StepLedger('sim')
    owner = Owner(ledger)
    owner.step()
    ledger.receive(motion(owner.now, 5, 1, owner.now), owner.now)  # 5 commands, maybe lost
    assert ledger.waiting_for(owner.now) == []
    owner.step()
    ledger.receive(motion(owner.now, 6, 2, owner.now), owner.now)
    assert ledger.waiting_for(owner.now) == [('sim', CMD, 1)]


def test_leaving_and_dropping_release_the_clock(joined):
    ledger, owner = joined
    owner.step()
    assert ledger.waiting_for(owner.now)
    assert ledger.receive(Answer('m', '/motion', 0, leaving=True), owner.now) == 'left'
    assert ledger.waiting_for(owner.now) == []
    ledger.receive(motion(owner.now, 0, 2, owner.now, pid='late'), owner.now)
    owner.step()
    waiting = ledger.waiting_for(owner.now)
    assert waiting == [('late', None, 0)]
    assert 'did not answer' in ledger.describe(waiting[0], owner.now)
    ledger.drop('late', owner.now)
    assert ledger.waiting_for(owner.now) == []


def test_a_goodbye_holds_the_clock_until_its_last_message_is_handled(joined):
    # Ctrl-C: the motion publishes its final stop, then says goodbye; the step must not go on
    # before the simulator has the stop, or the robot drives on for the steps in between.
    ledger, owner = joined
    owner.step()
    goodbye = Answer('m', '/motion', owner.now, {CMD: 1}, {ODOM: 2}, leaving=True)
    assert ledger.receive(goodbye, owner.now) == 'left'
    assert ledger.waiting_for(owner.now) == [('sim', CMD, 1)]
    assert ledger.synced() == {'sim'}  # no longer counted as hearing anything
    owner.hear_command()
    assert ledger.waiting_for(owner.now) == []
    assert set(ledger.members) == {'sim'}  # gone once its messages were handled
    owner.step()
    owner.hear_command()  # a non-member's command (a teleop) holds nothing
    assert ledger.waiting_for(owner.now) == []


def test_a_member_gone_after_its_goodbye_never_covers_another_members_command(joined):
    ledger, owner = joined
    ledger.receive(motion(owner.now, 0, 1, owner.now, pid='n'), owner.now)
    assert ledger.waiting_for(owner.now) == []
    assert ledger.synced() == {'sim', 'm', 'n'}
    owner.step()
    ledger.receive(motion(owner.now, 0, 2, owner.now, pid='n'), owner.now)
    ledger.receive(Answer('m', '/motion', owner.now, {CMD: 2}, {ODOM: 2}, leaving=True),
                   owner.now)
    owner.hear_command()
    owner.hear_command()
    assert ledger.waiting_for(owner.now) == []
    assert set(ledger.members) == {'sim', 'n'}
    # Within the same step, the other member's command is owed until it is handled.
    ledger.receive(motion(owner.now, 1, 2, owner.now, pid='n'), owner.now)
    assert ledger.waiting_for(owner.now) == [('sim', CMD, 1)]
    owner.hear_command()
    assert ledger.waiting_for(owner.now) == []


def test_a_last_stop_heard_before_the_goodbye_that_claims_it_is_not_owed(joined):
    # odom_out_and_back ends beside a slow participant (a CI run, and 3 in 86 runs of the
    # lockstep tests with four workers): at its last tick it publishes a stop and answers;
    # on its way out it publishes another stop and then says goodbye.  The simulator heard the
    # second stop first, the other participant's answer let it step, and that step forgot the
    # stop as a non-member's: the goodbye then claimed a message nobody would send again, and
    # the simulator held the clock for lockstep_timeout before it went on with a warning.
    ledger, owner = joined
    owner.step()
    ledger.receive(motion(owner.now, 1, 2, owner.now), owner.now)  # its last tick: one stop
    owner.hear_command()
    owner.hear_command()  # the way-out stop, ahead of the goodbye
    assert ledger.waiting_for(owner.now) == []
    owner.step()  # forgets the second stop as surplus
    goodbye = Answer('m', '/motion', owner.now - 20 * MS, {CMD: 2}, {ODOM: 2}, leaving=True)
    assert ledger.receive(goodbye, owner.now) == 'left'
    assert ledger.waiting_for(owner.now) == []  # it was handled: nothing owed
    assert set(ledger.members) == {'sim'}


def test_a_stop_from_a_publisher_made_after_the_last_answer_is_taken_back_too():
    # The same, from a member whose cmd_vel publisher did not exist at its last answer (its
    # answers list a publisher's topic from when it is made): all it claims was sent since.
    ledger = StepLedger('sim')
    owner = Owner(ledger)
    owner.step()
    ledger.receive(Answer('m', '/motion', owner.now, {}, {ODOM: 1}), owner.now)
    owner.step()
    ledger.receive(Answer('m', '/motion', owner.now, {}, {ODOM: 2}), owner.now)
    owner.hear_command()  # its first command, sent after that answer, heard before the next
    owner.step()  # forgets it as surplus
    goodbye = Answer('m', '/motion', owner.now - 20 * MS, {CMD: 1}, {ODOM: 2}, leaving=True)
    assert ledger.receive(goodbye, owner.now) == 'left'
    assert ledger.waiting_for(owner.now) == []  # it was handled: nothing owed


def test_surplus_forgotten_before_a_members_step_never_covers_what_it_claims(joined):
    # The same take-back must not let a teleop's command, forgotten at a step, stand for a
    # member's command of a later step that has not arrived.
    ledger, owner = joined
    owner.step()
    ledger.receive(motion(owner.now, 0, 2, owner.now), owner.now)
    owner.hear_command()  # a teleop's, at 40 ms
    owner.step()  # forgotten
    ledger.receive(motion(owner.now, 1, 3, owner.now), owner.now)  # claims a command at 60 ms
    assert ledger.waiting_for(owner.now) == [('sim', CMD, 1)]
    owner.hear_command()
    assert ledger.waiting_for(owner.now) == []


def test_a_lost_message_is_forgiven_once(joined):
    ledger, owner = joined
    owner.step()
    ledger.receive(motion(owner.now, 1, 2, owner.now), owner.now)
    waiting = ledger.waiting_for(owner.now)
    assert waiting == [('sim', CMD, 1)]
    assert 'has not handled 1 message(s) on /cmd_vel' in ledger.describe(waiting[0], owner.now)
    ledger.forgive('sim', CMD)
    assert ledger.waiting_for(owner.now) == []
    owner.step()
    ledger.receive(motion(owner.now, 2, 3, owner.now), owner.now)
    assert ledger.waiting_for(owner.now) == [('sim', CMD, 1)]


def test_a_burst_on_a_stamped_topic_is_judged_by_its_stamp_not_by_counts():
    # A simulator on sim time catches up after a clock jump with a burst of odometry all
    # stamped alike; its answer may report fewer messages than its robot's controller heard.
    ledger = StepLedger('sim')
    owner = Owner(ledger)
    owner.step()
    robot = Answer('r', '/r/unicycle_sim', owner.now, {'/r/odom': 20},
                   sent_stamp={'/r/odom': owner.now})
    controller = Answer('c', '/r/controller', owner.now, heard={'/r/odom': 44},
                        heard_stamp={'/r/odom': owner.now})
    for answer in (robot, controller):
        ledger.receive(answer, owner.now)
    owner.step()
    for answer in (robot, controller):
        answer.step_ns = owner.now
        ledger.receive(answer, owner.now)
    assert ledger.waiting_for(owner.now) == []
    robot.sent['/r/odom'] = 44  # the rest of the burst, now reported
    ledger.receive(robot, owner.now)
    assert ledger.waiting_for(owner.now) == []
    # A newer message the controller has not heard does hold the clock.
    owner.step()
    robot.step_ns = controller.step_ns = owner.now
    robot.sent_stamp['/r/odom'] = owner.now
    ledger.receive(robot, owner.now)
    ledger.receive(controller, owner.now)
    assert ledger.waiting_for(owner.now) == [('c', '/r/odom', 0)]
    assert 'has not heard the latest message on /r/odom' in ledger.describe(
        ('c', '/r/odom', 0), owner.now)


def test_the_owner_is_never_dropped_and_only_the_silent_are(joined):
    ledger, owner = joined
    ledger.drop('sim', owner.now)
    assert ledger.synced() == {'sim', 'm'} and ledger.dropped == {}
    # Heard from at 1.0 s of wall time: silent only once the timeout has passed since.
    ledger.receive(motion(owner.now, 0, 1, owner.now), owner.now, wall_s=1.0)
    assert ledger.silent(2.5, 2.0) == []
    assert ledger.silent(3.5, 2.0) == ['m']
    # The same answer again (a re-sent /clock) counts as being heard from.
    ledger.receive(motion(owner.now, 0, 1, owner.now), owner.now, wall_s=3.0)
    assert ledger.silent(3.5, 2.0) == []


def test_time_the_owner_did_not_run_is_nobody_s_silence(joined):
    ledger, owner = joined
    ledger.receive(motion(owner.now, 0, 1, owner.now), owner.now, wall_s=1.0)
    # The owner did not run from 1.5 s to 4.5 s: at 5.0 s the motion was silent for 1.0 s.
    ledger.excuse(3.0, 5.0)
    assert ledger.silent(5.0, 2.0) == []
    assert ledger.silent(6.5, 2.0) == ['m']
    # An answer handled after the stall (it waited in the queue) is no credit for the future.
    ledger.receive(motion(owner.now, 0, 1, owner.now), owner.now, wall_s=7.0)
    ledger.excuse(3.0, 7.0)
    assert ledger.silent(9.5, 2.0) == ['m']


def test_a_foreign_stale_stamp_never_holds_the_clock(joined):
    # The owner heard a member's command stamped at the step, then a foreign one stamped 0:
    # it keeps the highest stamp heard (MessageCounter), so nothing is owed.
    ledger, owner = joined
    owner.step()
    ledger.receive(Answer('sim', '/unicycle_sim', owner.now, {ODOM: owner.odom_sent},
                          {CMD: 2}, sent_stamp={ODOM: owner.now},
                          heard_stamp={CMD: owner.now}), owner.now)
    ledger.receive(Answer('m', '/motion', owner.now, {CMD: 1}, {ODOM: 2},
                          sent_stamp={CMD: owner.now}, heard_stamp={ODOM: owner.now}),
                   owner.now)
    assert ledger.waiting_for(owner.now) == []


def test_forgiving_a_stamped_topic_keeps_the_member(joined):
    ledger, owner = joined
    owner.step()
    ledger.receive(motion(owner.now, 0, 1, owner.now - 20 * MS), owner.now)
    assert ledger.waiting_for(owner.now) == [('m', ODOM, 0)]
    ledger.forgive('m', ODOM)
    assert ledger.waiting_for(owner.now) == []
    assert ledger.synced() == {'sim', 'm'}
    owner.step()  # the next odometry is waited for again
    ledger.receive(motion(owner.now, 0, 1, owner.now - 20 * MS), owner.now)
    assert ledger.waiting_for(owner.now) == [('m', ODOM, 0)]


def test_leaving_is_final(joined):
    ledger, owner = joined
    assert ledger.receive(Answer('m', '/motion', owner.now, leaving=True), owner.now) == 'left'
    # A callback that ran after leave() answered once more: it is not taken back in.
    assert ledger.receive(motion(owner.now, 0, 1, owner.now), owner.now) is None
    owner.step()
    assert ledger.waiting_for(owner.now) == []
    assert ledger.synced() == {'sim'}


def test_answered_says_whether_only_counts_are_left_to_wait_for(joined):
    ledger, owner = joined
    owner.step()
    assert not ledger.answered(owner.now)  # its command may come: answers are due first
    assert ledger.waiting_for(owner.now) == [('m', None, 0)]
    ledger.receive(motion(owner.now, 1, 2, owner.now), owner.now)  # overtook its command
    assert ledger.answered(owner.now)
    assert ledger.waiting_for(owner.now) == [('sim', CMD, 1)]
    owner.hear_command()
    assert ledger.answered(owner.now) and ledger.waiting_for(owner.now) == []


def test_a_joiner_is_counted_once_it_has_heard_each_stamped_topic_members_send():
    # A controller hears scans (every fifth step, none yet at time 0) and a map sent once
    # (-1: nothing heard yet).  Counted once it has heard a scan, so every later scan is waited
    # for; its -1 for the map goes from its answer after UNHEARD_S (counter.py); a -1 once
    # counted holds nobody, nor one for what only a participant publishes and has not sent.
    ledger = StepLedger('sim')
    published = {'/scan': 0, '/map': 1, '/x': 0}  # its publishers: no scan sent yet
    ledger.receive(Answer('sim', '/sim', 0, dict(published)), 0)

    def owner(now, scan_ns):
        ledger.receive(Answer('sim', '/sim', now, published, sent_stamp={
            '/scan': scan_ns, '/map': 0, '/x': 0}), now)

    def controller(now, **heard):
        ledger.receive(Answer('p', '/p', now, {'/y': 0}), now)  # a publisher, nothing sent
        ledger.receive(Answer('c', '/c', now, heard_stamp={
            '/' + topic: stamp for topic, stamp in heard.items()}), now)
        return ledger.waiting_for(now), 'c' in ledger.synced()
    for now in (0, 20 * MS, 40 * MS):  # it never holds the clock while it joins
        assert controller(now, scan=-1, map=-1) == ([], False)
        owner(now + 20 * MS, 0 if now == 0 else 20 * MS)
    owner(100 * MS, 100 * MS)
    assert controller(100 * MS, scan=100 * MS, map=-1) == ([], False)
    assert controller(100 * MS, scan=100 * MS, y=-1) == ([], True)  # the map's -1 has gone
    owner(200 * MS, 200 * MS)  # counted: the next scan is waited for
    assert controller(200 * MS, scan=100 * MS, x=-1) == ([('c', '/scan', 0)], True)
    assert controller(200 * MS, scan=200 * MS, x=-1) == ([], True)


def test_the_owner_waits_for_the_first_message_on_a_stamped_topic(joined):
    # Its stamped cmd_vel says -1 until heard (for good, counter.py): a member's first
    # TwistStamped is waited for as a Twist is counted; one sent before it joined is not.
    ledger, owner = joined

    def answer(pid, node, **fields):
        ledger.receive(Answer(pid, node, owner.now, **fields), owner.now)
        return ledger.waiting_for(owner.now)
    # c joins having sent one, maybe before the simulator matched it: that one is not owed.
    answer('c', '/c', sent={CMD: 1}, sent_stamp={CMD: owner.now})
    assert answer('sim', '/unicycle_sim', heard={CMD: 0}, heard_stamp={CMD: -1}) == []
    reasons = answer('m', '/motion', sent={CMD: 1}, heard={ODOM: 1},
                     sent_stamp={CMD: owner.now}, heard_stamp={ODOM: owner.now})
    assert reasons == [('sim', CMD, 0)] and ledger.describe(reasons[0], owner.now) == (
        '/unicycle_sim has not heard the latest message on /cmd_vel (stamped 0.020 s by '
        '/motion; it heard none yet)')
    assert answer('sim', '/unicycle_sim', heard={CMD: 1}, heard_stamp={CMD: owner.now}) == []
