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

"""``circle_back_and_forth``: move_rob.py's arc, retraced with both signs flipped."""

from motion_challenges.motion_node import rate_spec
from motion_challenges.plans import circle_plan
from motion_challenges.timed_motion import TimedMotion
from sim_diffdrive.parameters import Spec
from sim_diffdrive.runtime import run

PARAMETERS = (
    Spec('linear_speed', 0.5, 'Forward speed of the first half period [m/s].',
         low=0.0, high=10.0, low_open=True),
    Spec('angular_speed', 0.5, 'Turn rate of the first half period [rad/s], CCW positive.',
         low=-10.0, high=10.0),
    Spec('half_period', 15.0, 'Time before both signs flip [s].',
         low=0.0, high=3600.0, low_open=True),
    Spec('cycles', 0, 'Out-and-back cycles to drive; 0 = until stopped.', low=0, high=1000000),
    rate_spec(10.0),
)


class CircleBackAndForth(TimedMotion):
    """Drive the arc out and back."""

    def __init__(self, **kwargs):
        super().__init__('circle_back_and_forth', PARAMETERS, **kwargs)
        p = self.params
        radius = (f'radius {p.linear_speed / abs(p.angular_speed):.3f} m'
                  if p.angular_speed else 'a straight line')
        cycles = f'{p.cycles} cycle(s)' if p.cycles else 'until stopped'
        self.get_logger().info(f'Driving {radius} at {p.linear_speed:g} m/s, flipping every '
                               f'{p.half_period:g} s, {cycles}')
        self.ready()

    def plan(self):
        p = self.params
        return circle_plan(p.linear_speed, p.angular_speed, p.half_period, p.cycles)

    def control(self, now_ns):
        command = super().control(now_ns)
        if command is not None:  # not on the tick that ends the last cycle
            p = self.params
            cycles, into_cycle = divmod(self.elapsed(now_ns), 2.0 * p.half_period)
            leg = 'out' if into_cycle < p.half_period else 'back'
            total = f' of {p.cycles}' if p.cycles else ''
            self.progress(f'Cycle {int(cycles) + 1}{total}, driving {leg}', phase=True)
        return command

    def goal_pose(self, start):
        return start.x, start.y, start.yaw  # each arc retraced: back where it started


def main(args=None):
    """Drive out and back until done or stopped; returns the exit code."""
    return run(CircleBackAndForth, args, 'circle_back_and_forth')
