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

No ROS here: the answer format and the clock owner's bookkeeping, tested with plain pytest.

Each participant answers on ``/clock/answers`` (beside whatever ``/clock`` is remapped to)
whenever it is *settled* at the latest clock
step it has seen (its clock shows that time and none of its sim-time timers is due).  An answer
carries cumulative counts: how many messages the node has published on each topic and how many
it has handled on each topic it subscribes to.  Counts, not per-step flags, because DDS orders
messages per writer only: an answer may overtake the command it covers, so the owner does not
trust the answer alone but waits until every message that a member *sent* has been *heard* by
every member subscribed to that topic (the in-process ``Lockstep.settled()`` rule, spread over
processes).  A step is settled when every member has answered it and nothing is owed.

Only members count.  A subscriber that does not take part (a logger, a recorder) is never
waited for; a publisher that does not take part (a teleop) only adds messages a member hears
beyond what it is owed, which is forgotten at the next step, so it never stalls the clock.
"""

from dataclasses import dataclass
from dataclasses import field
import json

# ROS 2 housekeeping topics, never counted.
HOUSEKEEPING_TOPICS = frozenset({'/rosout', '/parameter_events'})


def answer_topic(clock_topic):
    """Return where participants answer the clock published on clock_topic."""
    return clock_topic + '/answers'


def members_topic(clock_topic):
    """Return where the clock owner lists the nodes it waits for."""
    return clock_topic + '/members'


def ignored_topics(clock_topic):
    """Return the topics that are the handshake itself or housekeeping, never counted."""
    return HOUSEKEEPING_TOPICS | {clock_topic, answer_topic(clock_topic),
                                  members_topic(clock_topic)}


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
            answer = cls(str(data['id']), str(data['node']), int(data['step_ns']),
                         _counts(data.get('sent', {})), _counts(data.get('heard', {})),
                         bool(data.get('leaving', False)),
                         _counts(data.get('sent_stamp', {})),
                         _counts(data.get('heard_stamp', {})))
        except (TypeError, KeyError, AttributeError, json.JSONDecodeError) as error:
            raise ValueError(f'not a lockstep answer: {error}') from None
        return answer


def _counts(data):
    return {str(topic): int(count) for topic, count in data.items()}


def encode_members(owner, step_ns, members):
    """Return the owner's list of members as the text of a std_msgs/String."""
    return json.dumps({'owner': owner, 'step_ns': step_ns, 'members': sorted(members)},
                      separators=(',', ':'))


def decode_members(text):
    """Return (owner, set of member ids); raise ValueError when the text is not such a list."""
    try:
        data = json.loads(text)
        return str(data['owner']), {str(member) for member in data['members']}
    except (TypeError, KeyError, json.JSONDecodeError) as error:
        raise ValueError(f'not a lockstep member list: {error}') from None


class _Member:

    def __init__(self, answer, joined_ns):
        self.answer = answer
        self.joined_ns = joined_ns
        # Joining until it has caught up with every stamped topic it hears; then synced.
        self.synced = False
        # What this member had sent before it joined is nobody's debt.
        self.base_sent = dict(answer.sent)
        # Per subscribed topic: messages sent by members that this member will never hear
        # (sent before it joined, or beyond what it heard from non-members).
        self.offset = {}


class StepLedger:
    """
    The clock owner's view of the members and of what they still owe.

    ``receive()`` every answer (the owner's own included), ``waiting_for(now_ns)`` to know
    whether the step at now_ns is settled, ``next_step()`` when the clock moves on.
    """

    def __init__(self):
        self.members = {}

    def receive(self, answer, now_ns):
        """Record an answer; return 'joined', 'left' or None (membership unchanged)."""
        if answer.leaving:
            return 'left' if self.members.pop(answer.participant, None) else None
        member = self.members.get(answer.participant)
        if member is None:
            self.members[answer.participant] = _Member(answer, now_ns)
            return 'joined'
        member.answer = answer
        if member.synced:
            self._settle_offsets(member)
        return None

    def synced(self):
        """Return the ids of the members that are counted (joined and caught up)."""
        return {pid for pid, member in self.members.items() if member.synced}

    def drop(self, participant):
        """Go on without a participant (it may join again by answering)."""
        self.members.pop(participant, None)

    def owed(self):
        """Return {(participant, topic): messages sent by members it has not handled yet}."""
        sent = self._sent_since_join()
        debts = {}
        for pid, member in self.members.items():
            if not member.synced:
                continue
            for topic, heard in member.answer.heard.items():
                due = sent.get(topic, 0) - heard - member.offset.get(topic, 0)
                if due:
                    debts[(pid, topic)] = due
        return debts

    def waiting_for(self, now_ns):
        """
        Return what keeps the step at now_ns from being settled (empty when settled).

        Each reason is (participant, topic or None, messages owed).  A joining member holds
        the clock until it has answered this step and heard the latest stamped message that
        members sent on each topic it hears: only then is what it missed before it joined
        known, and it is counted from there (DDS delivers each writer's messages in order).
        """
        reasons = []
        stamps = self._latest_stamps()
        for pid, member in self.members.items():
            answer = member.answer
            if answer.step_ns < now_ns and (member.synced or member.joined_ns < now_ns):
                reasons.append((pid, None, 0))
                continue
            behind = [topic for topic, stamp in answer.heard_stamp.items()
                      if stamp < stamps.get(topic, stamp)]
            if not member.synced:
                if behind or answer.step_ns < now_ns:
                    reasons.extend((pid, topic, 1) for topic in behind)
                    continue
                member.synced = True
                member.offset = {}
                self._settle_offsets(member)
            reasons.extend((pid, topic, 1) for topic in behind)
        for (pid, topic), due in self.owed().items():
            if due > 0 and not any(r[:2] == (pid, topic) for r in reasons):
                reasons.append((pid, topic, due))
        return reasons

    def next_step(self):
        """Forget what members heard beyond their due (non-members' messages) before a step."""
        sent = self._sent_since_join()
        for member in self.members.values():
            if not member.synced:
                continue
            for topic, heard in member.answer.heard.items():
                if sent.get(topic, 0) - heard - member.offset.get(topic, 0) < 0:
                    member.offset[topic] = sent.get(topic, 0) - heard

    def forgive(self, participant, topic):
        """Stop waiting for messages a member will not hear (lost, or sent before a match)."""
        member = self.members[participant]
        if not member.synced:
            self.drop(participant)
            return
        member.offset[topic] = (self._sent_since_join().get(topic, 0)
                                - member.answer.heard.get(topic, 0))

    def describe(self, reason, now_ns):
        """Return a reason from waiting_for() in words, naming the node."""
        pid, topic, due = reason
        member = self.members[pid]
        if topic is None:
            return (f'{member.answer.node} did not answer the clock step at '
                    f'{now_ns / _NS:.3f} s (its last answer: {member.answer.step_ns / _NS:.3f} s)')
        if topic in member.answer.heard_stamp and not self.owed().get((pid, topic)):
            return f'{member.answer.node} has not heard the latest message on {topic}'
        return f'{member.answer.node} has not handled {due} message(s) on {topic}'

    def _latest_stamps(self):
        stamps = {}
        for member in self.members.values():
            for topic, stamp in member.answer.sent_stamp.items():
                stamps[topic] = max(stamps.get(topic, stamp), stamp)
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
                if sent is None:
                    sent = self._sent_since_join()
                member.offset[topic] = sent.get(topic, 0) - heard
