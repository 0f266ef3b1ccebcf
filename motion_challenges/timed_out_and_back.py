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

"""``timed_out_and_back``: rbx1's out-and-back on the clock only, integral-exact."""

import math

from motion_challenges.motion_node import rate_spec
from motion_challenges.plans import out_and_back_end
from motion_challenges.plans import out_and_back_plan
from motion_challenges.timed_motion import TimedMotion
from sim_diffdrive.parameters import Spec
from sim_diffdrive.runtime import run

# odom_out_and_back shares these.
PARAMETERS = (
    Spec('goal_distance', 1.0, 'Distance of each straight leg [m].',
         low=0.0, high=1000.0, low_open=True),
    Spec('linear_speed', 0.2, 'Forward speed [m/s].', low=0.0, high=10.0, low_open=True),
    Spec('angular_speed', 1.0, 'Turn rate [rad/s].', low=0.0, high=10.0, low_open=True),
    Spec('goal_angle', math.pi, 'Angle of each turn [rad], counter-clockwise.',
         low=0.0, high=100.0, low_open=True),
    Spec('legs', 2, 'Number of drive-and-turn legs.', low=1, high=1000),
    Spec('pause', 1.0, 'Pause after each stop [s].', low=0.0, high=3600.0),
    rate_spec(50.0),
)


class TimedOutAndBack(TimedMotion):
    """Out and back on the clock."""

    def __init__(self, **kwargs):
        super().__init__('timed_out_and_back', PARAMETERS, **kwargs)
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
    return run(TimedOutAndBack, args, 'timed_out_and_back')
