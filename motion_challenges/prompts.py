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

"""Typed input for the rotate motion: a bad answer is explained and asked again (no ROS)."""

from dataclasses import dataclass
import functools
import math

MAX_ANGULAR_SPEED_DEG = 720.0
MAX_ANGLE_DEG = 36000.0

SPEED_PROMPT = 'Enter desired angular speed (degrees): '
ANGLE_PROMPT = 'Enter desired angle (degrees): '
CLOCKWISE_PROMPT = 'Do you want to rotate clockwise? (y/n): '

_YES = frozenset(('y', 'yes', 'true', '1'))
_NO = frozenset(('n', 'no', 'false', '0'))
# Echoing a huge pasted line back in an error message helps nobody.
_MAX_SHOWN = 40


class InputEnded(Exception):
    """Input ended (EOF) before every answer was given."""


@dataclass(frozen=True)
class RotationRequest:
    """What the user asked for, in the units of the prompts."""

    angular_speed_deg: float
    angle_deg: float
    clockwise: bool


def _shown(text):
    text = text.strip()
    # repr() escapes control characters, so garbage cannot drive the terminal.
    return repr(text[:_MAX_SHOWN] + '...' if len(text) > _MAX_SHOWN else text)


def _accepted(what, max_value):
    return f'enter the {what} as a positive number up to {max_value:g}, e.g. 60'


def _check_positive(value, shown, what, max_value):
    accepted = _accepted(what, max_value)
    if math.isnan(value):
        raise ValueError(f'{shown} is not a number; {accepted}')
    if math.isinf(value):
        raise ValueError(f'{shown} is not a finite number; {accepted}')
    if value <= 0.0:
        raise ValueError(f'{shown} is not positive; {accepted}')
    if value > max_value:
        raise ValueError(f'{shown} is more than the maximum of {max_value:g}; {accepted}')
    return float(value)


def parse_positive_number(text, what, max_value):
    """Parse a positive, finite number up to max_value; ``what`` names it in the ValueError."""
    stripped = text.strip()
    if not stripped:
        raise ValueError(f'nothing was entered; {_accepted(what, max_value)}')
    try:
        value = float(stripped)
    except ValueError:
        value = math.nan  # refused as 'not a number', as 'nan' typed is
    return _check_positive(value, _shown(stripped), what, max_value)


def parse_yes_no(text):
    """Parse a yes/no answer (y, yes, true, 1 / n, no, false, 0; any case)."""
    answer = text.strip().casefold()
    if answer in _YES:
        return True
    if answer in _NO:
        return False
    shown = _shown(text) if answer else 'nothing was entered'
    raise ValueError(f'{shown}: answer y or n')


def stream_writer(stream):
    """Return a write(text) that flushes, so a prompt shows before the input is read."""
    return functools.partial(print, end='', file=stream, flush=True)


def _ask(read_line, write, prompt, parse, missing):
    while True:
        write(prompt)
        try:
            line = read_line()
        except EOFError:
            # input() signals EOF this way; sys.stdin.readline returns ''.
            line = ''
        except UnicodeDecodeError:
            write('that was not valid text; try again\n')
            continue
        if not line:
            write('\n')
            raise InputEnded(f'input ended before the {missing} was given')
        try:
            return parse(line)
        except ValueError as error:
            write(f'{error}\n')


def ask_rotation(read_line, write, angular_speed_deg=None, angle_deg=None, clockwise=None):
    """
    Ask for the values left as None, in the order speed, angle, clockwise.

    ``read_line()`` returns one line ('' or EOFError at end of input); ``write(text)`` shows
    text.  Values passed in are checked by the same rules (ValueError).  Raise InputEnded if
    input ends before every value is known.
    """
    def number(value, prompt, what, max_value, missing):
        if value is None:
            return _ask(read_line, write, prompt,
                        lambda text: parse_positive_number(text, what, max_value), missing)
        return _check_positive(float(value), repr(value), what, max_value)

    angular_speed_deg = number(angular_speed_deg, SPEED_PROMPT,
                               'angular speed in degrees per second', MAX_ANGULAR_SPEED_DEG,
                               'angular speed')
    angle_deg = number(angle_deg, ANGLE_PROMPT, 'angle in degrees', MAX_ANGLE_DEG, 'angle')
    if clockwise is None:
        clockwise = _ask(read_line, write, CLOCKWISE_PROMPT, parse_yes_no, 'direction (y/n)')
    elif isinstance(clockwise, str):
        # bool('n') is True: a string answer must be parsed, not truth-tested.
        clockwise = parse_yes_no(clockwise)
    return RotationRequest(angular_speed_deg, angle_deg, bool(clockwise))
