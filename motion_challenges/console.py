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

"""The motions' console scripts: each launched by sim_diffdrive.console (signals first)."""

from sim_diffdrive.console import launch


def rotate_robot():
    """Launch the executable rotate_robot: its module's main()."""
    return launch('motion_challenges.rotate_robot', 'rotate_robot')


def circle_back_and_forth():
    """Launch the executable circle_back_and_forth: its module's main()."""
    return launch('motion_challenges.circle_back_and_forth', 'circle_back_and_forth')


def timed_out_and_back():
    """Launch the executable timed_out_and_back: its module's main()."""
    return launch('motion_challenges.timed_out_and_back', 'timed_out_and_back')


def odom_out_and_back():
    """Launch the executable odom_out_and_back: its module's main()."""
    return launch('motion_challenges.odom_out_and_back', 'odom_out_and_back')


def motion_fleet():
    """Launch the executable motion_fleet: its module's main()."""
    return launch('motion_challenges.motion_fleet', 'motion_fleet')
