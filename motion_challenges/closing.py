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

"""A motion's closing line: its exit code and the words it ends with."""

from sim_diffdrive.runtime import EXIT_FAILED
from sim_diffdrive.runtime import EXIT_OK

# How a motion's closing line starts when it reached its goal (closing_line finds it).
DONE = 'Done in '


def closing_for(sim_s, wall_s, achieved, measured, wait_for_odom):
    """
    Return (exit code, closing line) of a run that stopped sim_s [s] (wall_s wall) after its start.

    measured: whether odometry came after the stop.
    """
    if measured:
        return EXIT_OK, f'{DONE}{sim_s:.3f} s ({wall_s:.3f} s wall): {achieved}'
    if not wait_for_odom:
        return EXIT_OK, (f'Sent the whole plan in {sim_s:.3f} s ({wall_s:.3f} s wall) to a '
                         f'robot without odometry: {achieved}')
    return EXIT_FAILED, (f'Stopped after {sim_s:.3f} s, but no odometry came after the stop: '
                         'where the robot ended is unknown (is the simulator still running?)')


def closing_line(output):
    """Return a motion's closing line ('Done in ...') from its output, or its last error line."""
    lines = output.splitlines()
    for line in reversed(lines):
        if DONE in line:
            return line
    for line in reversed(lines):
        if '[ERROR]' in line or 'Error' in line:
            return line
    return lines[-1] if lines else ''
