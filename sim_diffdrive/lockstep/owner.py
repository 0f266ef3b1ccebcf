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
The clock owner's side of the lockstep: a policy that says when the simulator may step.

sim/clock.py's LockstepClock hands the owner each answer (``hear_answer``) and tells it of each
message the simulator handled (``heard_message``); each says whether the step may have
settled, and the clock then asks ``may_step``: how many steps it may take now (it freewheels
until the first answer, as PX4's lockstep does) and whether to re-send the current /clock.
The owner publishes who is counted on ``<clock>/roster``; it neither steps nor writes the
clock, and calls nobody back.  Why it re-sends a held /clock (RESEND_S) and when it goes on
without a participant (never without itself): docs/time.md ("When things go wrong").
"""

import math
import time

from rclpy.serialization import deserialize_message
from sim_diffdrive.cdr import read_string
from sim_diffdrive.lockstep.counter import MessageCounter
from sim_diffdrive.lockstep.handshake import Answer
from sim_diffdrive.lockstep.handshake import answer_topic
from sim_diffdrive.lockstep.handshake import roster_topic
from sim_diffdrive.lockstep.handshake import StepLedger
from sim_diffdrive.lockstep.participant import ROSTER_QOS
from sim_diffdrive.node_names import node_names
from sim_diffdrive.throttle import Throttle
from std_msgs.msg import String

_NS = 1_000_000_000
# Freewheeling takes at most this many steps per timer call.
_MAX_CATCH_UP = 20
# While the clock is held, /clock and the roster are re-sent [s, wall]: a participant that lost
# the step's /clock gets it again, and takes the roster for a sign that the simulator is alive
# (its odometry is late because time stands still).  First after RESEND_S, then twice as long
# each time up to RESEND_MAX_S: every re-send makes every participant answer again, so at a
# fixed short interval a busy graph spends its time answering re-sends (docs/time.md).
RESEND_S = 0.01
RESEND_MAX_S = 0.32
# Weight of the newest step in the moving average of the wall time between steps.
_STEP_WEIGHT = 0.1
# A look at the step (the clock timer, or news) later than this beyond the timer's period means
# the simulator did not listen meanwhile: it did not run (a machine too busy to run it, a
# debugger) or was busy in a long callback of its own [s, wall]; see _own_stall.
_STALLED_S = 0.05
# A message the simulator owes from a sender whose writer its discovery has not matched yet is
# not lost (on a lossy link one side of a match can come seconds before the other, and the
# message follows it): it is waited for this many lockstep_timeouts before it is forgiven,
# unless every node that sent on its topic has left and is gone from the graph (_gone).
UNDISCOVERED_TIMEOUTS = 3


class LockstepOwner:
    """Decide when the simulator ``sim`` may step its clock, published on ``clock_topic``."""

    def __init__(self, sim, clock_topic, budget_s):
        self.sim = sim
        self._clock_topic = clock_topic
        self._owner_id = sim.get_fully_qualified_name() + '#owner'
        self.ledger = StepLedger(self._owner_id)
        self._bad_answers = Throttle(5.0)
        self.answer_topic = answer_topic(clock_topic)
        self._waiting = None  # what the current step waits for; None: to be worked out
        self._announced = set()
        self._roster_version = -1
        self._resent_wall = 0.0
        self._resend_s = RESEND_S  # the wait before the next re-send of this step
        self._step_s = 0.0  # recent wall time between steps [s; moving average]
        self._warned_wall = 0.0
        self._discovery_said = None  # the step the wait for discovery was logged at
        self._looked = time.monotonic()  # when may_step last ran [s, wall]
        self._stalled_s = 0.0  # how long the simulator itself did not run during this step
        self._step_wall_ns = round(budget_s * _NS)  # told to the participants in the roster
        self._roster_pub = None

    def start(self):
        """Count the simulator's own traffic (its robots exist now); return its MessageCounter."""
        sim = self.sim
        self._roster_pub = sim.create_publisher(String, roster_topic(self._clock_topic),
                                                ROSTER_QOS)
        # The simulator's own traffic (cmd_vel heard, odom sent) is counted like a
        # participant's; its answer holds the counter's live dicts, so only its step changes.
        # A stamped command's first message is waited for too (-1 until heard, for good).
        counter = MessageCounter.of(sim, self._clock_topic, fixed=True, unheard_s=math.inf)
        self._own_answer = Answer(self._owner_id, sim.get_fully_qualified_name(), sim.now_ns(),
                                  counter.sent, counter.heard, False, counter.sent_stamp,
                                  counter.heard_stamp)
        self.ledger.receive(self._own_answer, sim.now_ns())
        self.ledger.waiting_for(sim.now_ns())  # counts itself from the start
        self._publish_roster()
        return counter

    def next_step(self, step_ns):
        """Start counting answers for the step to step_ns (the simulator is about to take it)."""
        self.ledger.next_step(self.sim.now_ns())
        self._waiting = None
        self._stalled_s = 0.0
        # Not before a step had twice its usual time: a graph of many processes on a busy
        # machine takes longer than RESEND_S for every step, lost sample or not.
        self._resend_s = min(max(RESEND_S, 2.0 * self._step_s), RESEND_MAX_S)
        self._own_answer.step_ns = step_ns

    def may_step(self, now, wall, budget_s, period_s):
        """
        Return (steps the clock may take now, whether to re-send the current /clock).

        Steps is -1 when the step has settled before budget_s has passed since wall: one
        step once it has.

        now: the wall time of this look [s, monotonic]; wall: when the clock last stepped (on
        its schedule); budget_s: the wall time a step may take at real_time_factor; period_s:
        how often the clock looks without news.
        """
        sim = self.sim
        ledger = self.ledger
        self._own_stall(now, wall, period_s)
        waited = now - wall
        if len(ledger.members) <= 1:
            self._publish_roster(wall=wall)
            # Freewheel until the first answer: the steps the timer's period holds and one
            # more (a late tick), no more.  After a stall of the simulator the clock goes on
            # from now rather than run through seconds of simulated time with no command
            # handled in between (cmd_vel_timeout would stop a robot whose teleop never paused).
            most = min(math.ceil(period_s / budget_s - 1e-9) + 1, _MAX_CATCH_UP)
            return min(int(waited / budget_s), most), False
        if self._waiting is None:
            # Worked out again only after news; the clock timer in between only paces.
            self._waiting = ledger.waiting_for(sim.now_ns())
        waiting = self._waiting
        resend = self._publish_roster(waiting, wall)
        if waiting:
            held = waited - self._stalled_s  # while the simulator ran, and could hear
            if held <= sim.params.lockstep_timeout or not self._give_up(waiting, held):
                return 0, resend
        if waited >= budget_s:
            self._step_s += _STEP_WEIGHT * (waited - self._step_s)
            return 1, resend
        return -1, resend  # settled before its budget is over

    def has_members(self):
        """Return whether a participant answers (then answers pace the steps)."""
        return len(self.ledger.members) > 1

    def _own_stall(self, now, wall, period_s):
        """
        Excuse everyone the time the simulator itself did not run since it last looked.

        Answers sent meanwhile wait in its queue, unheard, and may be handled only after this
        look: a simulator that was stopped for longer than lockstep_timeout would otherwise
        take its live participants for silent ones and go on without them.
        """
        stalled = now - self._looked - period_s
        self._looked = now
        if stalled > _STALLED_S:
            # Only what fell after the step began counts against its hold.
            self._stalled_s += min(stalled, max(now - wall, 0.0))
            self.ledger.excuse(stalled, now)
            if stalled > self.sim.params.lockstep_timeout and self.has_members():
                # Its participants heard nothing meanwhile, not even a re-sent roster: a motion
                # may have given up on it (odom_timeout), and this says why.
                self.sim.get_logger().info(
                    f'Lockstep: this simulator did not run for {stalled:.1f} s (a busy machine, '
                    'a debugger?); nobody is dropped for it')

    def rescheduled(self, budget_s):
        """
        Look from now on: the clock timer starts its period again (a new real_time_factor).

        budget_s: the wall time a step takes at least from now on [s]; the participants are
        told at once (a motion takes a simulator slower than its watchdog for a silent one).
        """
        self._looked = time.monotonic()
        self._step_wall_ns = round(budget_s * _NS)
        if self._roster_pub is not None:  # started
            self._publish_roster(force=True)

    def hear_answer(self, data):
        """Take an answer (a std_msgs/String's bytes); return whether the step may have settled."""
        try:
            try:
                text = read_string(data)
            except ValueError:  # another encoding: through rclpy
                try:
                    text = deserialize_message(data, String).data
                except RuntimeError as error:
                    raise ValueError(f'not a std_msgs/String ({error})') from None
            answer = Answer.decode(text)
        except ValueError as error:
            if self._bad_answers.allows():
                self.sim.get_logger().warning(
                    f'Ignoring a message on {self.answer_topic}: {error}')
            return False
        now_ns = self.sim.now_ns()
        if self.ledger.receive(answer, now_ns, time.monotonic()) == 'left':
            member = self.ledger.members[answer.participant]
            steps = (now_ns - member.joined_ns) // self.sim.step_ns
            self.sim.get_logger().info(f'Lockstep: {answer.node} left at {now_ns / _NS:.3f} s '
                                       f'({member.answers} answers in {steps} steps)')
        return self._news()

    def heard_message(self):
        """After a message the simulator handled (a command): return whether to look again."""
        self._waiting = None
        # A step's command comes just before its answer, which is news of its own: looking
        # now costs the simulator a look at every step on the way to stepping.  A command
        # that comes after every answer (it was overtaken) is looked at.
        return self.ledger.answered(self.sim.now_ns()) and self._news()

    def _news(self):
        """Something the step may wait for has arrived: return whether it paces the steps."""
        self._waiting = None
        # Without participants the clock timer alone paces the steps: stepping on news too
        # would run catch-up bursts inside command callbacks and overflow the cmd_vel queues.
        return len(self.ledger.members) > 1

    def _publish_roster(self, waiting=(), wall=None, force=False):
        """
        Tell the participants who is counted when that changed (or force); while waiting, re-send.

        Return whether the clock should re-send its current /clock too (the step has been held
        since wall for longer than the re-send wait).
        """
        ledger = self.ledger
        now = time.monotonic()
        resend = bool(waiting) and now - max(wall, self._resent_wall) >= self._resend_s
        if ledger.version == self._roster_version and not resend and not force:
            return False
        if resend:
            self._resent_wall = now
            self._resend_s = min(2.0 * self._resend_s, RESEND_MAX_S)
        now_ns = self.sim.now_ns()
        roster = ledger.roster(self.sim.get_fully_qualified_name(), now_ns,
                               [ledger.describe(reason, now_ns) for reason in waiting])
        roster.step_wall_ns = self._step_wall_ns
        for pid in roster.members - self._announced - {self._owner_id}:
            self.sim.get_logger().info(
                f'Lockstep: {ledger.members[pid].answer.node} takes part from '
                f'{now_ns / _NS:.3f} s on; {len(roster.members) - 1} participant(s)')
        self._announced = roster.members
        self._roster_version = ledger.version
        self._roster_pub.publish(String(data=roster.encode()))
        return resend

    def _gone(self, topic):
        """
        Return the nodes that sent on topic, if each has left and is gone from the graph.

        Their writers can no longer be discovered, so what they sent that this simulator never
        had cannot come (a motion that stopped its robot as this simulator started, before it
        matched the motion's writer, then said goodbye and exited).  [] while any sender stays.
        """
        senders = self.ledger.senders(topic)
        if not senders or not all(member.leaving for member in senders):
            return []
        present = {f'{namespace.rstrip("/")}/{name}'
                   for name, namespace in self.sim.get_node_names_and_namespaces()}
        names = sorted(member.answer.node for member in senders)
        return [] if present.intersection(names) else names

    def _give_up(self, waiting, held_s):
        """
        After lockstep_timeout: drop the silent, forgive what the live have not heard.

        Return whether the step may go on; a live participant that has not answered the step
        is waited for still (it answers again at each re-sent /clock), with a warning, and so
        is a message to this simulator on a topic none of whose publishers it has discovered
        yet, up to UNDISCOVERED_TIMEOUTS lockstep_timeouts (held_s: how long the step has
        been held [s, wall]).
        """
        ledger = self.ledger
        logger = self.sim.get_logger()
        timeout = self.sim.params.lockstep_timeout
        now_ns = self.sim.now_ns()
        wall = time.monotonic()
        for pid in ledger.silent(wall, timeout):
            answer = ledger.members[pid].answer
            logger.warning(f'Lockstep: nothing heard from {answer.node} for {timeout:g} s (its '
                           f'last answer: {answer.step_ns / _NS:.3f} s); going on without it')
            ledger.drop(pid, now_ns)
        held, undiscovered = [], []
        for reason in waiting:
            pid, topic, _ = reason
            if pid not in ledger.members:
                continue  # dropped as silent
            if topic is None:
                held.append(reason)
                continue
            unseen = pid == self._owner_id and not self.sim.count_publishers(topic)
            gone = self._gone(topic) if unseen else []
            if unseen and not gone and held_s <= UNDISCOVERED_TIMEOUTS * timeout:
                undiscovered.append(reason)
                continue
            names = node_names(self.sim.get_publishers_info_by_topic(topic))
            logger.warning(f'Lockstep: {ledger.describe(reason, now_ns)} within {held_s:.1f} s; '
                           'going on without those message(s) ('
                           + (f'publishers of {topic} discovered here: {", ".join(names)}'
                              if names else f'no publisher of {topic} discovered here')
                           + (f'; {", ".join(gone)} left and is gone' if gone else '') + ')')
            ledger.forgive(pid, topic)
        self._waiting = None
        self._publish_roster()
        if undiscovered and self._discovery_said != now_ns:
            self._discovery_said = now_ns
            logger.info('Lockstep: holding the clock for ' + '; '.join(
                ledger.describe(reason, now_ns) for reason in undiscovered)
                + ': no publisher of it discovered here yet, so it is not lost (waited for up '
                f'to {UNDISCOVERED_TIMEOUTS * timeout:g} s)')
        if held and wall - self._warned_wall >= timeout:
            self._warned_wall = wall
            logger.warning('Lockstep: holding the clock for ' + '; '.join(
                ledger.describe(reason, now_ns) for reason in held)
                + ' (it still answers, so it is waited for)')
        return not held and not undiscovered
