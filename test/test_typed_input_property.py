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
Property: whatever is typed, ``ask_rotation`` asks again or ends cleanly, and never guesses.

Hypothesis feeds arbitrary strings (with valid answers mixed in, so that some runs complete)
through a scripted ``read_line``.  The only exception that may come out is InputEnded, and a
RotationRequest comes out only after a valid speed, then a valid angle, then a valid y/n, each
equal to what an independent reading of the same lines gives.
"""

import math

from hypothesis import example
from hypothesis import given
from hypothesis import HealthCheck
from hypothesis import settings
from hypothesis import strategies as st
from motion_challenges.prompts import ask_rotation
from motion_challenges.prompts import InputEnded
from motion_challenges.prompts import MAX_ANGLE_DEG
from motion_challenges.prompts import MAX_ANGULAR_SPEED_DEG
from motion_challenges.prompts import RotationRequest

VALID_ANSWERS = ('60', ' 90\n', '1e2', '0.5', '720', '36000', 'y', 'N', 'yes\n', ' false ',
                 '1', '0')
# End of input as sys.stdin.readline shows it (''), as input() shows it (EOFError), and a line
# that could not be decoded.
EOF_EMPTY = ''
EOF_ERROR = EOFError
UNDECODABLE = UnicodeDecodeError('utf-8', b'\xff', 0, 1, 'invalid start byte')

answers = st.one_of(st.text(max_size=30), st.sampled_from(VALID_ANSWERS),
                    st.sampled_from(('nan', 'inf', '-60', '0', '1e999', '720.0001', '\x00',
                                     '\x1b[2J', ' ', '\n', 'y y', '٣')))
endings = st.sampled_from((EOF_EMPTY, EOF_ERROR))


def expected_number(line, high):
    try:
        value = float(line.strip())
    except ValueError:
        return None
    return value if math.isfinite(value) and 0.0 < value <= high else None


def expected_yes_no(line):
    answer = line.strip().casefold()
    if answer in ('y', 'yes', 'true', '1'):
        return True
    if answer in ('n', 'no', 'false', '0'):
        return False
    return None


def expected_request(lines):
    """Read lines the way the prompts are documented to; return the request or None."""
    parsers = [lambda line: expected_number(line, MAX_ANGULAR_SPEED_DEG),
               lambda line: expected_number(line, MAX_ANGLE_DEG),
               expected_yes_no]
    values = []
    for line in lines:
        if not isinstance(line, str):
            continue  # an undecodable line is explained and asked again
        if line == '':
            return None
        value = parsers[len(values)](line)
        if value is not None:
            values.append(value)
            if len(values) == 3:
                return RotationRequest(*values)
    return None


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(lines=st.lists(st.one_of(answers, st.just(UNDECODABLE)), max_size=12), ending=endings)
@example(lines=['fast', '-5', 'nan', '60', '', '45', 'y'], ending=EOF_EMPTY)
@example(lines=['60', '90', 'maybe', 'n'], ending=EOF_ERROR)
def test_any_typed_input_ends_in_a_valid_request_or_input_ended(lines, ending):
    script = list(lines) + [ending]
    consumed = []
    shown = []

    def read_line():
        item = script.pop(0) if script else EOF_EMPTY
        consumed.append(item)
        if isinstance(item, BaseException) or item is EOF_ERROR:
            raise item
        return item

    try:
        request = ask_rotation(read_line, shown.append)
    except InputEnded as error:
        request = None
        assert 'input ended before the' in str(error)
    assert all(isinstance(text, str) for text in shown)
    assert request == expected_request(
        [item if not (item is EOF_ERROR) else '' for item in consumed])
    if request is not None:
        # It stopped reading at the last answer it needed, and asked each question first.
        assert consumed[-1] is not UNDECODABLE and isinstance(consumed[-1], str)
        assert 0.0 < request.angular_speed_deg <= MAX_ANGULAR_SPEED_DEG
        assert 0.0 < request.angle_deg <= MAX_ANGLE_DEG
        assert isinstance(request.clockwise, bool)
    prompts = [text for text in shown if text.endswith(': ')]
    assert len(prompts) == len(consumed)


@settings(max_examples=100, deadline=None)
@given(speed=st.one_of(st.none(), st.floats(0.001, MAX_ANGULAR_SPEED_DEG)),
       angle=st.one_of(st.none(), st.floats(0.001, MAX_ANGLE_DEG)),
       clockwise=st.one_of(st.none(), st.booleans()),
       lines=st.lists(answers, max_size=8))
def test_given_values_are_not_asked_for(speed, angle, clockwise, lines):
    script = list(lines)
    asked = []

    def read_line():
        return script.pop(0) if script else ''

    try:
        request = ask_rotation(read_line, asked.append, angular_speed_deg=speed,
                               angle_deg=angle, clockwise=clockwise)
    except InputEnded:
        return
    if speed is not None:
        assert request.angular_speed_deg == speed
        assert not any('angular speed' in text for text in asked)
    if angle is not None:
        assert request.angle_deg == angle
    if clockwise is not None:
        assert request.clockwise is clockwise
        assert not any('clockwise' in text for text in asked)
