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
``timed_out_and_back``: drive out, turn around, drive back, turn around; on the clock only.

A port of rbx1's ``timed_out_and_back.py`` (ROS by Example): each leg drives ``goal_distance``
at ``linear_speed``, stops and pauses, turns ``goal_angle`` at ``angular_speed``, stops and
pauses.  Durations come from distance/speed and angle/speed and the plan is integral-exact,
so the robot ends where it started, facing the same way, without rbx1's tick rounding.
"""

import math

from motion_challenges.plans import out_and_back_end
from motion_challenges.plans import out_and_back_plan
from motion_challenges.specs import out_and_back_specs
from motion_challenges.timed_motion import TimedMotion
from sim_diffdrive.runtime import run


class TimedOutAndBack(TimedMotion):
    """Out and back on the clock (see the module docstring)."""

    def __init__(self, **kwargs):
        super().__init__('timed_out_and_back', out_and_back_specs(50.0), **kwargs)
        p = self.params
        self.get_logger().info(
            f'{p.legs} leg(s): {p.goal_distance:g} m at {p.linear_speed:g} m/s, turn '
            f'{math.degrees(p.goal_angle):g} deg at {p.angular_speed:g} rad/s, '
            f'pause {p.pause:g} s')
        self.ready()

    def plan(self):
        p = self.params
        return out_and_back_plan(p.goal_distance, p.linear_speed, p.goal_angle,
                                 p.angular_speed, p.legs, p.pause)

    def control(self, now_ns):
        command = super().control(now_ns)
        self.progress(f'{self.elapsed(now_ns):.1f} of {self._plan.duration:.1f} s')
        return command

    def goal_pose(self, start):
        p = self.params
        return out_and_back_end((start.x, start.y, start.yaw), p.goal_distance, p.goal_angle,
                                p.legs)


def main(args=None):
    """Drive the legs and stop; returns the exit code."""
    return run(TimedOutAndBack, args)
