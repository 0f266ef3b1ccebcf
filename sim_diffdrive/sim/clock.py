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
How ``unicycle_sim`` keeps time: one of four clocks, chosen once at start (``make_clock``).

``FollowedClock`` follows the node's own clock (wall time, or another simulator's /clock and
lockstep); the others own time and publish it on /clock: ``FreeClock``, ``LockstepClock``, and
``SteppedClock`` (stepped by SimGraph).  Simulated time is kept in integer nanoseconds, so many
steps add up without rounding drift.
"""

import time

from rclpy.clock import Clock
from rclpy.clock import ClockType
from rclpy.qos import QoSProfile
from rclpy.qos import ReliabilityPolicy
from rosgraph_msgs.msg import Clock as ClockMsg
from sim_diffdrive.cdr import clock_message
from sim_diffdrive.lockstep.owner import LockstepOwner
from sim_diffdrive.lockstep.participant import ANSWER_QOS
from sim_diffdrive.lockstep.participant import take_part
from sim_diffdrive.node_names import node_names
from std_msgs.msg import String

_NS = 1_000_000_000
# Free clock pacing: wait this many times the graph's recent reaction time between steps; the
# remembered reaction time shrinks by this factor per step, so a spike is forgotten in a
# second of simulated time and an idle graph runs at the full real_time_factor.
_PACING_MARGIN = 2.0
_REACTION_DECAY = 0.98
# In lockstep the clock timer paces and watches for laggards (answers drive the steps), so it
# need not fire more often than this [s]; without members it catches up in bursts.
_LOCKSTEP_TICK_S = 0.0005
# With members, news paces a step shorter than its budget, so the timer only watches (re-sends
# after 10 ms or more, timeouts of seconds); ticking faster costs more than the step [s].
_WATCH_TICK_S = 0.002
# How often a simulator that owns time looks for another publisher on its clock topic [s, wall]:
# at a high real_time_factor a graph query every step would cost more than the step.
_OWNERS_CHECK_S = 1.0


def make_clock(sim, stepped=False):
    """Return the clock sim.params ask for (call before the robots' subscriptions exist)."""
    p = sim.params
    if not p.publish_clock:
        return FollowedClock(sim)
    if stepped:
        return SteppedClock(sim)
    return LockstepClock(sim) if p.lockstep else FreeClock(sim)


class FollowedClock:
    """
    The node's own clock (wall or another /clock): odometry on a timer of it.

    On wall time the commands and the odometry timer share the executor's one queue, so a
    backlog of commands (more than the simulator can handle, or a burst while it was held up)
    would hold the odometry back until it was worked off.  So each command is followed by the
    step if one is due (``take_due_step``), as the timer would have taken it just after that
    command, and the timer skips a step that a command took less than half a period before.
    On another simulator's /clock that simulator's steps set the pace instead.
    """

    def __init__(self, sim):
        self.sim = sim
        self.participant = None  # its side of another simulator's lockstep, on its /clock
        self._clock = sim.get_clock()
        # use_sim_time is read-only here (parameters.py): the clock is chosen once.
        self._wall = not sim.get_parameter('use_sim_time').value
        self._stepped_ns = 0  # the time of the last odometry step, on wall time

    def start(self):
        sim = self.sim
        sim.create_timer(sim.step_ns / _NS, self._on_timer)
        if not self._wall:
            self.participant = take_part(sim)
            self.participant.name_unmatched = False

    def now_ns(self):
        if self._wall:
            # The system clock, read as an integer: Clock.now() builds a Time object, and
            # asking rclpy's clock whether ROS time is active takes its lock at every step.
            return time.time_ns()
        return self._clock.now().nanoseconds  # the time /clock gave

    def take_due_step(self):
        """On wall time, after a command: return the time of the step now due (taken), or None."""
        if self._wall:
            now_ns = time.time_ns()
            if self._since_step_ns(now_ns) >= self.sim.step_ns:
                self._stepped_ns = now_ns
                return now_ns
        return None

    def command_arrived(self):
        """Nothing to do: this clock does not wait for the graph."""

    def set_real_time_factor(self, value):
        """Nothing to do: another node sets the pace."""

    def _on_timer(self):
        now_ns = self.now_ns()
        if self._wall and self._since_step_ns(now_ns) < self.sim.step_ns // 2:
            return  # a command took this step
        self._stepped_ns = now_ns
        self.sim.step_to(now_ns)

    def _since_step_ns(self, now_ns):
        """Return the wall time since the last step; a whole step if the clock went back."""
        since_ns = now_ns - self._stepped_ns
        return since_ns if since_ns >= 0 else self.sim.step_ns


class OwnedClock:
    """Simulated time that this node owns and publishes on /clock, stepped by ``step()``."""

    participant = None

    def __init__(self, sim):
        self.sim = sim
        self.sim_ns = 0
        self.publisher = sim.create_publisher(
            ClockMsg, '/clock', QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
        self.topic = self.publisher.topic_name
        self._data = clock_message(0)
        # When the last step was taken [s, monotonic], and the wall time a step may take.
        self.wall = time.monotonic()
        self.budget_s = sim.step_ns / _NS / sim.params.real_time_factor
        self._owners_checked = self.wall
        self._warned_owners = False

    def start(self):
        self.sim.world.begin(0)
        self.publish()

    def now_ns(self):
        return self.sim_ns

    def take_due_step(self):
        """Return None: on owned time a late step only makes simulated time slower."""
        return None

    def step(self):
        """Advance simulated time by one step and publish odometry and then /clock."""
        self.sim_ns += self.sim.step_ns
        # Odometry first: a participant that gets it before the /clock of its step waits for
        # that /clock to answer, so one answer a step covers both (participant.py).
        self.sim.step_to(self.sim_ns)
        self.publish()
        self.wall = time.monotonic()
        if self.wall - self._owners_checked >= _OWNERS_CHECK_S:
            self._owners_checked = self.wall
            self.check_owners()

    def publish(self):
        # As bytes: rclpy's Clock and Time objects cost more than the rest of an idle step.
        self._data = clock_message(self.sim_ns)
        self.publisher.publish(self._data)
        if self.sim.taps:
            self.sim.taps.write(self.topic, self._data, self.sim_ns)

    def check_owners(self):
        """Warn once when another node publishes on this clock's topic too (until it leaves)."""
        sim = self.sim
        owners = sim.get_publishers_info_by_topic(self.topic)
        if len(owners) > 1 and not self._warned_owners:
            self._warned_owners = True
            names = ', '.join(node_names(owners))
            namespace = sim.get_namespace().rstrip('/') or '/robot1'
            sim.get_logger().warning(
                f'{len(owners)} nodes publish on {self.topic} ({names}): their simulated times '
                'interleave, so the runs on sim time jump between them and fail; give each '
                f'simulator its own clock (e.g. -r /clock:={namespace}/clock for it and the '
                'nodes on its time), or let one own time and the others follow it with '
                'use_sim_time (docs/time.md)')
        elif len(owners) <= 1:
            self._warned_owners = False

    def repeat(self):
        """Publish the current /clock again, for a participant that may have lost it."""
        self.publisher.publish(self._data)

    def command_arrived(self):
        """Note that a robot's command arrived (a hook)."""

    def set_real_time_factor(self, value):
        self.budget_s = self.sim.step_ns / _NS / value


class SteppedClock(OwnedClock):
    """Owned time stepped from outside: SimGraph calls ``step()`` once the graph settled."""


class _TimedClock(OwnedClock):
    """Owned time stepped from a wall timer that fires every ``period_s()``."""

    def start(self):
        self.timer = self.sim.create_timer(
            self.period_s(), self._on_timer, clock=Clock(clock_type=ClockType.STEADY_TIME))
        super().start()

    def period_s(self):
        return self.budget_s

    def set_real_time_factor(self, value):
        super().set_real_time_factor(value)
        self._set_period()

    def _set_period(self):
        self.timer.timer_period_ns = round(self.period_s() * _NS)
        self.timer.reset()


class FreeClock(_TimedClock):
    """
    Owned time on a wall timer at up to real_time_factor, paced by the graph's reactions.

    real_time_factor is an upper bound: a step waits until the graph has had a few times its
    recent reaction time to answer the previous one, so that a command lands on the step it was
    sent for even when the machine is loaded.
    """

    def __init__(self, sim):
        super().__init__(sim)
        self._reaction_s = 0.0
        self._answered = True
        # Pacing never makes simulated time slower than real time.
        self._max_reaction_s = sim.step_ns / _NS / _PACING_MARGIN

    def _on_timer(self):
        if time.monotonic() - self.wall >= _PACING_MARGIN * self._reaction_s:
            self._reaction_s *= _REACTION_DECAY
            self.step()

    def step(self):
        super().step()
        self._answered = False

    def command_arrived(self):
        """Note a robot's command: the first after a step answers it."""
        if not self._answered:
            # Commands from a publisher that does not follow the clock (teleop, a second
            # controller, a flood) arrive at any time: counting each would double the wait
            # every step until time stood still.
            self._answered = True
            reaction_s = min(time.monotonic() - self.wall, self._max_reaction_s)
            self._reaction_s = max(reaction_s, self._reaction_s)


class LockstepClock(_TimedClock):
    """Owned time stepped when every participant has answered (see lockstep/owner.py)."""

    def __init__(self, sim):
        super().__init__(sim)
        self.owner = LockstepOwner(sim, self.topic, self.budget_s)
        # Before the robots' cmd_vel subscriptions: discovery announces a node's subscriptions
        # in the order they were made, so a motion that has discovered its robot's cmd_vel
        # subscription knows of this one too, and cannot take a lockstep owner for a free
        # clock on a lossy link (Participant.owner_present).  As bytes (read_string).
        sim.create_subscription(String, self.owner.answer_topic, self._on_answer, ANSWER_QOS,
                                raw=True)
        self._watching = False  # whether the owner has members, so news paces the steps

    def start(self):
        self.owner.start().listeners.append(self._on_heard)
        super().start()

    def _on_answer(self, data):
        if self.owner.hear_answer(data):
            self._look()

    def _on_heard(self):
        if self.owner.heard_message():
            self._look()

    def period_s(self):
        if self.budget_s >= _LOCKSTEP_TICK_S:
            return self.budget_s
        return _WATCH_TICK_S if self._watching else _LOCKSTEP_TICK_S

    def set_real_time_factor(self, value):
        super().set_real_time_factor(value)
        self.owner.rescheduled(self.budget_s)  # the time since the last look is no stall

    def _look(self):
        """Take the steps the owner allows now; re-send /clock when it says so."""
        wall, owner = self.wall, self.owner
        steps, resend = owner.may_step(time.monotonic(), wall, self.budget_s, self.period_s())
        if resend:
            self.repeat()
        watching = owner.has_members()
        if watching != self._watching:
            self._watching = watching
            self._set_period()
        if steps < 0:
            if self.period_s() <= self.budget_s:
                return  # the next tick comes when the budget is over
            # The budget is shorter than a tick: wait out the rest of it here.
            time.sleep(max(wall + self.budget_s - time.monotonic(), 0.0))
            steps = 1
        for _ in range(steps):
            self.step()
        if steps:
            # The steps are dated on the schedule, not when they ended: the timer fires once per
            # step budget, and were the last step dated when it ended, the next tick would find a
            # little less than a budget waited and skip, halving the rate.  Far behind (the
            # clock was held, or the machine is slower than real_time_factor), the schedule
            # starts again from now rather than catching up in a burst.
            scheduled = wall + steps * self.budget_s
            now = time.monotonic()
            self.wall = scheduled if now - scheduled < self.budget_s else now

    _on_timer = _look

    def step(self):
        self.owner.next_step(self.sim_ns + self.sim.step_ns)
        super().step()
