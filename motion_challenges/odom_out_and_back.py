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

"""``odom_out_and_back``: rbx1's closed-loop out-and-back, on odometry (controllers.OutAndBack)."""

import math

from motion_challenges import timed_out_and_back
from motion_challenges.controllers import Approach
from motion_challenges.controllers import OutAndBack
from motion_challenges.motion_node import MotionNode
from sim_diffdrive.parameters import Spec
from sim_diffdrive.runtime import run

PARAMETERS = timed_out_and_back.PARAMETERS + (
    Spec('linear_accel', 0.5, 'Deceleration used to slow down near the goal distance [m/s^2].',
         low=0.0, high=100.0, low_open=True),
    Spec('angular_accel', 2.0, 'Deceleration used to slow down near the goal angle [rad/s^2].',
         low=0.0, high=100.0, low_open=True),
    Spec('min_linear_speed', 0.01, 'Slowest forward speed while approaching the goal [m/s].',
         low=0.0, high=10.0, low_open=True),
    Spec('min_angular_speed', 0.05, 'Slowest turn rate while approaching the goal [rad/s].',
         low=0.0, high=10.0, low_open=True),
    Spec('robot_linear_accel', 0.0, "The robot's linear acceleration limit (its controller's, "
         "or unicycle_sim's max_linear_accel) [m/s^2], so that it stops on the goal; 0: it "
         'takes each command at once.', low=0.0, high=1000.0),
    Spec('robot_angular_accel', 0.0, "The robot's angular acceleration limit (as "
         'robot_linear_accel) [rad/s^2]; 0: it takes each command at once.',
         low=0.0, high=1000.0),
)


class OdomOutAndBack(MotionNode):
    """Out and back closed loop on odometry."""

    needs_odom = True
    goal_pose = timed_out_and_back.TimedOutAndBack.goal_pose  # the same legs, so the same end

    def __init__(self, **kwargs):
        super().__init__('odom_out_and_back', PARAMETERS, **kwargs)
        p = self.params
        self.robot_accel = (p.robot_linear_accel, p.robot_angular_accel)
        self.legs = OutAndBack(
            p.legs, p.goal_distance, p.goal_angle, p.pause,
            drive=Approach(p.linear_speed, p.min_linear_speed, p.linear_accel, self.period,
                           robot_accel=p.robot_linear_accel),
            turn=Approach(p.angular_speed, p.min_angular_speed, p.angular_accel, self.period,
                          robot_accel=p.robot_angular_accel))
        self.get_logger().info(
            f'{p.legs} leg(s) on odometry: {p.goal_distance:g} m at up to {p.linear_speed:g} '
            f'm/s, turn {math.degrees(p.goal_angle):g} deg at up to {p.angular_speed:g} rad/s')
        self.ready()

    def begin(self, now_ns):
        self.legs.start(now_ns, self.odom, self.turned.total)

    def control(self, now_ns):
        command = self.legs.command(now_ns, self.odom, self.turned.total, *self.predict(now_ns))
        if command is not None:
            self.progress(f'Leg {self.legs.leg} of {self.params.legs}: {self.legs.step.value}',
                          phase=True)
        return command


def main(args=None):
    """Drive the legs on odometry and stop; returns the exit code."""
    return run(OdomOutAndBack, args, 'odom_out_and_back')
