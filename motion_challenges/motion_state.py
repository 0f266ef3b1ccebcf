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

"""Where a motion is: MotionState (also importable from motion_challenges.motion_node)."""

import enum


class MotionState(str, enum.Enum):
    """Where a motion is (a str too, equal to its value, for code that compares with one)."""

    WAITING = 'waiting'  # for the goal, then for the robot (see RobotWatch.missing)
    RUNNING = 'running'  # control() is called every tick
    SETTLING = 'settling'  # stopped; waiting for odometry that shows where the robot came to rest
    FINISHED = 'finished'  # done or given up: see exit_code
