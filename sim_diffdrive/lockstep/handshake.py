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
The lockstep handshake between a simulator that owns ``/clock`` and the nodes that take part.

No ROS here: the answer and roster formats and the clock owner's bookkeeping (StepLedger).
Answers carry cumulative counts, not per-step flags, because DDS orders messages per writer
only: an answer may overtake the command it covers, so the owner waits until what members
sent has been heard by every member subscribed to it.  Only members count: a non-member's
messages are surplus, forgotten at the next step, so they never stall the clock.  The protocol
in full: docs/time.md ("How a node answers").
"""

from dataclasses import dataclass
from dataclasses import field
import json

# ROS 2 housekeeping topics, never counted.
HOUSEKEEPING_TOPICS = frozenset({'/rosout', '/parameter_events'})


def answer_topic(clock_topic):
    """Return where participants answer the clock published on clock_topic."""
    return clock_topic + '/answers'


def roster_topic(clock_topic):
    """Return where the clock owner lists the nodes it waits for (see Roster)."""
    return clock_topic + '/roster'


def ignored_topics(clock_topic):
    """Return the topics that are the handshake itself or housekeeping, never counted."""
    return HOUSEKEEPING_TOPICS | {clock_topic, answer_topic(clock_topic),
                                  roster_topic(clock_topic)}


_NS = 1_000_000_000


@dataclass
class Answer:
    """One participant's answer: settled at ``step_ns``, with its cumulative message counts."""

    participant: str
    node: str
    step_ns: int
    sent: dict = field(default_factory=dict)
    heard: dict = field(default_factory=dict)
    leaving: bool = False
    # Header stamp [ns] of the latest stamped message published / handled, per topic.
    sent_stamp: dict = field(default_factory=dict)
    heard_stamp: dict = field(default_factory=dict)

    def encode(self):
        """Return the answer as the text of a std_msgs/String."""
        data = {'id': self.participant, 'node': self.node, 'step_ns': self.step_ns,
                'sent': self.sent, 'heard': self.heard, 'sent_stamp': self.sent_stamp,
                'heard_stamp': self.heard_stamp}
        if self.leaving:
            data['leaving'] = True
        return json.dumps(data, separators=(',', ':'))

    @classmethod
    def decode(cls, text):
        """Parse an answer; raise ValueError when the text is not one."""
        try:
            data = json.loads(text)
            return cls(str(data['id']), str(data['node']), _integer(data['step_ns']),
                       _counts(data.get('sent', {})), _counts(data.get('heard', {})),
                       bool(data.get('leaving', False)), _counts(data.get('sent_stamp', {})),
                       _counts(data.get('heard_stamp', {})))
        except (TypeError, KeyError, AttributeError, ValueError, RecursionError) as error:
            raise ValueError(f'not a lockstep answer: {error}') from None


def _integer(value):
    """Return value if it is a JSON integer; raise ValueError (a float, NaN, Infinity, ...)."""
    if type(value) is not int:
        raise ValueError(f'{value!r} is not an integer')
    return value


def _counts(data):
    return {str(topic): _integer(count) for topic, count in data.items()}


@dataclass
class Roster:
    """
    What the clock owner tells the participants: who is counted, and what holds the clock.

    ``heard_topics`` are the topics that some counted node handles (the owner's cmd_vel among
    them), so a controller can wait until whoever drives on its topic is counted too.  While
    the clock is held the owner repeats the roster with ``waiting`` filled in, so a participant
    can tell a held clock from a simulator that is gone.  ``dropped`` names every participant
    the owner went on without, with the time it did so [ns]: each roster carries it, so one that
    was dropped learns of it even when the roster it was left out of is lost or overtaken.
    ``step_wall_ns`` is the least wall time the owner gives a step at its real_time_factor: at
    0.01 a step of 20 ms takes 2 s, and a participant waits that long for its next step.
    """

    owner: str
    step_ns: int
    members: set = field(default_factory=set)
    heard_topics: set = field(default_factory=set)
    waiting: list = field(default_factory=list)
    dropped: dict = field(default_factory=dict)
    step_wall_ns: int = 0

    def encode(self):
        """Return the roster as the text of a std_msgs/String."""
        data = {'owner': self.owner, 'step_ns': self.step_ns, 'members': sorted(self.members),
                'heard_topics': sorted(self.heard_topics), 'waiting': self.waiting}
        if self.dropped:
            data['dropped'] = self.dropped
        if self.step_wall_ns:
            data['step_wall_ns'] = self.step_wall_ns
        return json.dumps(data, separators=(',', ':'))

    @classmethod
    def decode(cls, text):
        """Parse a roster; raise ValueError when the text is not one."""
        try:
            data = json.loads(text)
            return cls(str(data['owner']), _integer(data['step_ns']),
                       {str(m) for m in data['members']},
                       {str(t) for t in data.get('heard_topics', ())},
                       [str(w) for w in data.get('waiting', ())], _counts(data.get('dropped', {})),
                       _integer(data.get('step_wall_ns', 0)))
        except (TypeError, KeyError, ValueError, AttributeError, RecursionError) as error:
            raise ValueError(f'not a lockstep roster: {error}') from None


class _Member:

    def __init__(self, answer, joined_ns, wall_s):
        self.answer = answer
        self.joined_ns = joined_ns
        self.answers = 1  # heard from it, goodbye aside (about one a step: see participant.py)
        # When anything was last heard from it [s, wall]: only a silent member is dropped.
        self.heard_wall = wall_s
        # Per stamped topic: a stamp the owner stopped waiting for (see forgive).
        self.stamp_floor = {}
        # Joining until it has caught up with every stamped topic it hears; then synced.
        self.synced = False
        # It said goodbye: it answers no more, but what it sent is still waited for.
        self.leaving = False
        # What this member had sent before it joined is nobody's debt, nor its stamps.
        self.base_sent = dict(answer.sent)
        self.base_sent_stamp = dict(answer.sent_stamp)
        # Per subscribed topic: messages sent by members that this member will never hear
        # (sent before it joined, or beyond what it heard from non-members).
        self.offset = {}


class StepLedger:
    """
    The clock owner's view of the members and of what they still owe.

    ``receive()`` every answer (the owner's own included), ``waiting_for(now_ns)`` to know
    whether the step at now_ns is settled, ``next_step(now_ns)`` when the clock moves on.  The
    owner's own id is never dropped; a participant that said it leaves is waited for only until
    what it sent has been handled, and is gone for good.
    """

    def __init__(self, owner):
        self.owner = owner
        self.members = {}
        self.left = set()
        # Every participant ever dropped, with the time of its latest drop [ns] (see Roster).
        self.dropped = {}
        # Goes up whenever what roster() returns may have changed.
        self.version = 0
        # Surplus next_step() forgot, per (member that heard it, topic): [step [ns], count]
        # records, for an answer that claims it later (_take_back).
        self._forgotten = {}

    def receive(self, answer, now_ns, wall_s=0.0):
        """Record an answer heard at wall_s; return 'joined', 'left' or None (no change)."""
        if answer.participant in self.left:
            return None  # a callback that ran after leave(): leaving is final
        member = self.members.get(answer.participant)
        if member is not None and self._forgotten:
            self._take_back(member.answer, answer)
        if answer.leaving:
            self.left.add(answer.participant)
            if member is None:
                return None
            # Its goodbye counts its last messages (a final stop): the step waits for them to
            # be handled, then it goes (waiting_for).
            member.answer = answer
            member.leaving = True
            self.version += 1
            return 'left'

        if member is None:
            self.members[answer.participant] = _Member(answer, now_ns, wall_s)
            return 'joined'
        member.answer = answer
        member.answers += 1
        member.heard_wall = wall_s
        if member.synced:
            self._settle_offsets(member)
        return None

    def synced(self):
        """Return the ids of the members that are counted (joined, caught up, not leaving)."""
        return {pid for pid, member in self.members.items()
                if member.synced and not member.leaving}

    def drop(self, participant, now_ns):
        """Go on without a participant from now_ns (it may join again by answering)."""
        if participant != self.owner and self.members.pop(participant, None) is not None:
            self.dropped[participant] = now_ns
            self.version += 1

    def excuse(self, seconds, wall_s):
        """Count nobody silent for seconds in which the owner could not hear (it did not run)."""
        for member in self.members.values():
            member.heard_wall = min(member.heard_wall + seconds, wall_s)

    def silent(self, wall_s, timeout_s):
        """Return the participants nothing was heard from for longer than timeout_s (wall)."""
        return [pid for pid, member in self.members.items() if pid != self.owner
                and not member.leaving and wall_s - member.heard_wall > timeout_s]

    def roster(self, owner, now_ns, waiting=()):
        """Return the roster to publish: the counted members and the topics they handle."""
        counted = self.synced()
        return Roster(owner, now_ns, counted,
                      {topic for pid in counted for topic in self.members[pid].answer.heard},
                      list(waiting), dict(self.dropped))

    def owed(self):
        """
        Return {(participant, topic): messages sent by members it has not handled yet}.

        Only for topics without a header stamp (a Twist on cmd_vel): on a stamped topic the
        latest stamp tells (see waiting_for), and a count could not, since a burst of messages
        may share one stamp and a member's answer may be older than what another has heard.
        """
        return self._owed(self._latest_stamps())

    def _owed(self, stamps):
        sent = self._sent_since_join()
        debts = {}
        for pid, member in self.members.items():
            if not member.synced or member.leaving:
                continue
            offset = member.offset
            for topic, heard in member.answer.heard.items():
                if topic not in stamps:
                    due = sent.get(topic, 0) - heard - offset.get(topic, 0)
                    if due:
                        debts[(pid, topic)] = due
        return debts

    def waiting_for(self, now_ns):
        """
        Return what keeps the step at now_ns from being settled (empty when settled).

        Each reason is (participant, None, 0) for a missing answer, (participant, topic, 0)
        for a stamped topic on which it has not heard the latest message members sent, or
        (participant, topic, n) for n unstamped messages it has not handled.  A joining member
        holds the clock for its answer to each step after the one it joined in, never for a
        stamped topic: it is counted from the first otherwise settled step at which it has
        caught up on every stamped topic it hears, and has heard something on each it has heard
        nothing on yet (-1, counter.py) that a member sent on since it joined or that the owner
        has a publisher on (sent on or not: at time 0 no scan has been sent yet), so that once
        counted it is waited for on all of them.  A message written while its subscription was
        being matched may never reach it (a DDS volatile reader gets what is written after both
        sides matched), and no repair brings it; the next step's does, in writer order.  A
        counted member's -1 (a subscription made since) is not waited for: it may never match.
        The owner's -1 is, as a count is.
        """
        # Most news is one more answer while others are missing: say so without the counts
        # (which cost time in proportion to members x topics).
        missing = [(pid, None, 0) for pid, member in self.members.items()
                   if self._unanswered(member, now_ns)]
        if missing:
            return missing
        # Asked after every callback in process (testing/graph.py): one pass over members.
        reasons, caught_up, leaving = [], [], []
        stamps = self._latest_stamps()
        for pid, member in self.members.items():
            if member.leaving:
                leaving.append(pid)
                continue
            answer = member.answer
            floor = member.stamp_floor
            behind = [(pid, topic, 0) for topic, stamp in answer.heard_stamp.items()
                      if max(stamp, floor.get(topic, stamp)) < stamps.get(topic, stamp)
                      and (stamp >= 0 or not member.synced or pid == self.owner)]
            if member.synced:
                reasons += behind
            elif not behind and answer.step_ns >= now_ns and not self._unheard_owned(answer):
                caught_up.append(member)
        reasons += [(pid, topic, due) for (pid, topic), due in self._owed(stamps).items()
                    if due > 0]
        if not reasons:
            for member in caught_up:
                member.synced = True
                self.version += 1
                member.offset = {}
                self._settle_offsets(member)
            # What the leaving sent has been handled: now they go, and their counts with them
            # (else they would cover what a member sends until next_step).
            for pid in leaving:
                gone = self.members.pop(pid)
                self.version += 1
                sent = {topic: count - gone.base_sent.get(topic, 0)
                        for topic, count in gone.answer.sent.items()}
                for member in self.members.values():
                    for topic in member.offset.keys() & sent.keys():
                        member.offset[topic] -= sent[topic]
        return reasons

    def _unheard_owned(self, answer):
        """Return whether answer says -1 for a topic the owner has a publisher on."""
        owner = self.members.get(self.owner)
        sent = owner.answer.sent if owner is not None else {}
        return any(stamp < 0 and topic in sent for topic, stamp in answer.heard_stamp.items())

    def answered(self, now_ns):
        """Return whether every member has answered the step at now_ns (see waiting_for)."""
        return not any(self._unanswered(member, now_ns) for member in self.members.values())

    @staticmethod
    def _unanswered(member, now_ns):
        return (member.answer.step_ns < now_ns and not member.leaving
                and (member.synced or member.joined_ns < now_ns))

    def next_step(self, now_ns):
        """
        Forget what members heard beyond their due (non-members' messages), leaving now_ns.

        Kept aside by step: a member's message sent after it answered its step (a motion's
        final stop on its way out, a wall-time timer's) may be heard before the answer that
        claims it, and that answer takes it back (_take_back).
        """
        for (pid, topic), due in self.owed().items():
            if due < 0:
                self.members[pid].offset[topic] += due
                self._forgotten.setdefault((pid, topic), []).append([now_ns, -due])
        # A record can be claimed by an answer at or before its step only, and each member's
        # answers come at or after its latest one.
        oldest = min((m.answer.step_ns for pid, m in self.members.items()
                      if pid != self.owner and not m.leaving), default=None)
        for key, records in list(self._forgotten.items()):
            records[:] = [record for record in records if record[1] and oldest is not None
                          and record[0] >= oldest]
            if not records or key[0] not in self.members:
                del self._forgotten[key]

    def _take_back(self, previous, answer):
        """
        Take back forgotten surplus that a member's new answer claims it sent.

        Only surplus forgotten at or after the answer's step: what the answer claims was sent
        at that time or before, so a non-member's surplus of an earlier step never covers it.
        """
        for (pid, topic), records in self._forgotten.items():
            if pid not in self.members:
                continue
            # Claimed since its last answer (which lists a topic once its publisher exists).
            left = answer.sent.get(topic, 0) - previous.sent.get(topic, 0)
            offset = self.members[pid].offset
            for record in records:
                if left <= 0:
                    break
                if record[0] >= answer.step_ns:
                    taken = min(left, record[1])
                    record[1] -= taken
                    left -= taken
                    offset[topic] = offset.get(topic, 0) + taken

    def forgive(self, participant, topic):
        """
        Go on without what a live member has not heard on topic (it stays a member).

        On a stamped topic the member is not waited for up to the latest stamp sent so far; on
        a counted one, for the messages sent so far: should they still come, they are surplus.
        """
        member = self.members[participant]
        stamps = self._latest_stamps()
        if topic in stamps:
            member.stamp_floor[topic] = stamps[topic]
        else:
            member.offset[topic] = (self._sent_since_join().get(topic, 0)
                                    - member.answer.heard.get(topic, 0))

    def senders(self, topic):
        """Return the members that sent on topic since they joined (leaving ones included)."""
        return [member for member in self.members.values()
                if member.answer.sent.get(topic, 0) > member.base_sent.get(topic, 0)]

    def describe(self, reason, now_ns):
        """Return a reason from waiting_for() in words, naming the node."""
        pid, topic, due = reason
        member = self.members[pid]
        if topic is None:
            return (f'{member.answer.node} did not answer the clock step at '
                    f'{now_ns / _NS:.3f} s (its last answer: {member.answer.step_ns / _NS:.3f} s)')
        if not due:
            latest = self._latest_stamps().get(topic, 0)
            heard = max(member.answer.heard_stamp.get(topic, -1),
                        member.stamp_floor.get(topic, -1))
            senders = sorted(m.answer.node for m in self.members.values()
                             if m.answer.sent_stamp.get(topic) == latest
                             and latest > m.base_sent_stamp.get(topic, -1))
            return (f'{member.answer.node} has not heard the latest message on {topic} '
                    f'(stamped {latest / _NS:.3f} s by {", ".join(senders)}; it heard '
                    + (f'up to {heard / _NS:.3f} s)' if heard >= 0 else 'none yet)'))
        return f'{member.answer.node} has not handled {due} message(s) on {topic}'

    def _latest_stamps(self):
        """Return {stamped topic: the latest stamp members sent on it since joining, or -1}."""
        stamps = {}
        for member in self.members.values():
            base = member.base_sent_stamp
            for topic, stamp in member.answer.sent_stamp.items():
                stamps[topic] = max(stamps.get(topic, -1), stamp if stamp > base.get(topic, -1)
                                    else -1)
        return stamps

    def _sent_since_join(self):
        sent = {}
        for member in self.members.values():
            base = member.base_sent
            for topic, count in member.answer.sent.items():
                sent[topic] = sent.get(topic, 0) + count - base.get(topic, 0)
        return sent

    def _settle_offsets(self, member):
        # A topic first seen in a member's answer starts with nothing owed.
        sent = None
        for topic, heard in member.answer.heard.items():
            if topic not in member.offset:
                self.version += 1
                if sent is None:
                    sent = self._sent_since_join()
                member.offset[topic] = sent.get(topic, 0) - heard
