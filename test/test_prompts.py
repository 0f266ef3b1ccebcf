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

import io

from motion_challenges.prompts import ANGLE_PROMPT
from motion_challenges.prompts import ask_rotation
from motion_challenges.prompts import CLOCKWISE_PROMPT
from motion_challenges.prompts import InputEnded
from motion_challenges.prompts import MAX_ANGLE_DEG
from motion_challenges.prompts import MAX_ANGULAR_SPEED_DEG
from motion_challenges.prompts import parse_positive_number
from motion_challenges.prompts import parse_yes_no
from motion_challenges.prompts import RotationRequest
from motion_challenges.prompts import SPEED_PROMPT
from motion_challenges.prompts import stream_writer
import pytest


class Console:
    """Scripted user: answers lines in order, then EOF; records everything written."""

    def __init__(self, *lines):
        self._lines = list(lines)
        self.written = []

    def read_line(self):
        return self._lines.pop(0) if self._lines else ''

    def write(self, text):
        self.written.append(text)

    @property
    def prompts(self):
        return [text for text in self.written if text.endswith(': ')]

    @property
    def explanations(self):
        return [text for text in self.written if text.endswith('\n') and text != '\n']


def test_prompts_are_the_originals():
    assert SPEED_PROMPT == 'Enter desired angular speed (degrees): '
    assert ANGLE_PROMPT == 'Enter desired angle (degrees): '
    assert CLOCKWISE_PROMPT == 'Do you want to rotate clockwise? (y/n): '
    assert MAX_ANGULAR_SPEED_DEG == 720.0
    assert MAX_ANGLE_DEG == 36000.0


@pytest.mark.parametrize('text, expected', [
    ('60', 60.0), (' 90.5 ', 90.5), ('1e2', 100.0), ('60\n', 60.0), ('+7', 7.0),
    ('0.001', 0.001), ('720', 720.0),
])
def test_parse_positive_number_accepts(text, expected):
    value = parse_positive_number(text, 'angular speed in degrees', 720.0)
    assert value == expected
    assert isinstance(value, float)


@pytest.mark.parametrize('text, reason', [
    ('abc', "'abc' is not a number"),
    ('', 'nothing was entered'),
    ('   \n', 'nothing was entered'),
    ('0', "'0' is not positive"),
    ('-0', "'-0' is not positive"),
    ('-5', "'-5' is not positive"),
    ('nan', "'nan' is not a number"),
    ('inf', "'inf' is not a finite number"),
    ('-inf', "'-inf' is not a finite number"),
    ('1e400', "'1e400' is not a finite number"),
    ('720.5', "'720.5' is more than the maximum of 720"),
    ('1,5', "'1,5' is not a number"),
    ('60 deg', "'60 deg' is not a number"),
])
def test_parse_positive_number_rejects_with_explanation(text, reason):
    with pytest.raises(ValueError) as error:
        parse_positive_number(text, 'angular speed in degrees', 720.0)
    message = str(error.value)
    assert message.startswith(reason)
    assert 'enter the angular speed in degrees' in message
    assert 'up to 720' in message
    assert 'e.g. 60' in message


def test_parse_positive_number_survives_garbage():
    garbage = 'x' * 1_000_000
    with pytest.raises(ValueError) as error:
        parse_positive_number(garbage, 'angle', 10.0)
    assert len(str(error.value)) < 200
    for text in ('\u00e9\u6f22\u5b57\U0001f916', '\x00\x1b[2J', '\udc80', '\u202e60'):
        with pytest.raises(ValueError) as error:
            parse_positive_number(text, 'angle', 10.0)
        assert '\x1b' not in str(error.value)


@pytest.mark.parametrize('text', ['y', 'Y', 'yes', ' YES\n', 'true', 'True', '1'])
def test_parse_yes_no_yes(text):
    assert parse_yes_no(text) is True


@pytest.mark.parametrize('text', ['n', 'N', 'no', ' No\n', 'false', 'FALSE', '0'])
def test_parse_yes_no_no(text):
    assert parse_yes_no(text) is False


@pytest.mark.parametrize('text', ['', '\n', 'maybe', 'yess', '2', 'o', 'x' * 100000, '\u00ff'])
def test_parse_yes_no_rejects(text):
    with pytest.raises(ValueError, match='answer y or n'):
        parse_yes_no(text)


def test_ask_rotation_good_answers():
    console = Console('60\n', '90\n', 'y\n')
    request = ask_rotation(console.read_line, console.write)
    assert request == RotationRequest(angular_speed_deg=60.0, angle_deg=90.0, clockwise=True)
    assert console.prompts == [SPEED_PROMPT, ANGLE_PROMPT, CLOCKWISE_PROMPT]
    assert console.explanations == []


def test_ask_rotation_last_line_without_newline():
    console = Console('30', '45', 'n')
    assert ask_rotation(console.read_line, console.write) == RotationRequest(30.0, 45.0, False)


def test_ask_rotation_repeats_question_after_bad_answer():
    console = Console('fast\n', '0\n', '60\n', '-90\n', '90\n', 'maybe\n', '\n', 'n\n')
    request = ask_rotation(console.read_line, console.write)
    assert request == RotationRequest(60.0, 90.0, False)
    assert console.prompts == [SPEED_PROMPT] * 3 + [ANGLE_PROMPT] * 2 + [CLOCKWISE_PROMPT] * 3
    explanations = console.explanations
    assert len(explanations) == 5
    assert explanations[0].startswith("'fast' is not a number")
    assert explanations[1].startswith("'0' is not positive")
    assert explanations[2].startswith("'-90' is not positive")
    assert 'angle in degrees' in explanations[2]
    assert 'answer y or n' in explanations[3]
    assert 'answer y or n' in explanations[4]
    # Each explanation comes right after the answer it explains, before the question again.
    index = console.written.index(explanations[0])
    assert console.written[index - 1:index + 2] == [SPEED_PROMPT, explanations[0], SPEED_PROMPT]


def test_ask_rotation_rejects_values_above_maximum():
    console = Console('721\n', '720\n', '36001\n', '36000\n', 'y\n')
    request = ask_rotation(console.read_line, console.write)
    assert request == RotationRequest(720.0, 36000.0, True)
    assert 'maximum of 720' in console.explanations[0]
    assert 'maximum of 36000' in console.explanations[1]


@pytest.mark.parametrize('lines, missing', [
    ((), 'angular speed'),
    (('60\n',), 'angle'),
    (('60\n', 'abc\n'), 'angle'),
    (('60\n', '90\n'), 'direction'),
    (('60\n', '90\n', 'perhaps\n'), 'direction'),
])
def test_ask_rotation_eof_raises_input_ended(lines, missing):
    console = Console(*lines)
    with pytest.raises(InputEnded, match=missing):
        ask_rotation(console.read_line, console.write)


def test_ask_rotation_eof_error_from_input_counts_as_end():
    def read_line():
        raise EOFError

    with pytest.raises(InputEnded, match='angular speed'):
        ask_rotation(read_line, lambda text: None)


def test_ask_rotation_does_not_ask_given_values():
    console = Console('45\n')
    request = ask_rotation(console.read_line, console.write, angular_speed_deg=30,
                           clockwise=False)
    assert request == RotationRequest(30.0, 45.0, False)
    assert console.prompts == [ANGLE_PROMPT]

    console = Console()
    request = ask_rotation(console.read_line, console.write, 10.0, 20.0, True)
    assert request == RotationRequest(10.0, 20.0, True)
    assert console.written == []


def test_ask_rotation_checks_given_values():
    console = Console()
    with pytest.raises(ValueError, match='maximum of 720'):
        ask_rotation(console.read_line, console.write, angular_speed_deg=1000.0)
    with pytest.raises(ValueError, match='not positive'):
        ask_rotation(console.read_line, console.write, angular_speed_deg=10.0, angle_deg=-1.0)
    request = ask_rotation(console.read_line, console.write, 10.0, 20.0, 'n')
    assert request.clockwise is False


def test_ask_rotation_survives_garbage_lines():
    garbage = '\U0001f916\x1b[31m' * 100000 + '\n'
    console = Console(garbage, '\udcff\n', '60\n', garbage, '90\n', garbage, 'yes\n')
    request = ask_rotation(console.read_line, console.write)
    assert request == RotationRequest(60.0, 90.0, True)
    assert len(console.explanations) == 4
    assert all(len(text) < 300 for text in console.explanations)


def test_ask_rotation_on_streams():
    stdin = io.StringIO('60\n90\ny\n')
    stdout = io.StringIO()
    request = ask_rotation(stdin.readline, stream_writer(stdout))
    assert request == RotationRequest(60.0, 90.0, True)
    assert stdout.getvalue() == SPEED_PROMPT + ANGLE_PROMPT + CLOCKWISE_PROMPT
