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
``rotate_robot``: turn in place by a typed (or given) angle at a typed (or given) speed.

``mode``: open loop (``timed``) or closed loop on accumulated odometry yaw (``odom``).
"""

import math
import sys

from motion_challenges.controllers import SpinController
from motion_challenges.motion_node import rate_spec
from motion_challenges.plans import rotation_plan
from motion_challenges.prompts import ask_rotation
from motion_challenges.prompts import InputEnded
from motion_challenges.prompts import MAX_ANGLE_DEG
from motion_challenges.prompts import MAX_ANGULAR_SPEED_DEG
from motion_challenges.prompts import stream_writer
from motion_challenges.timed_motion import TimedMotion
from sim_diffdrive.parameters import Spec
from sim_diffdrive.runtime import destroyed_if_refused
from sim_diffdrive.runtime import run
from sim_diffdrive.runtime import UsageError

PARAMETERS = (
    Spec('angular_speed_deg', None, 'Turn rate [deg/s]; asked for when not given.',
         low=0.0, high=MAX_ANGULAR_SPEED_DEG, low_open=True, kind=float),
    Spec('angle_deg', None, 'Angle to turn [deg]; asked for when not given.',
         low=0.0, high=MAX_ANGLE_DEG, low_open=True, kind=float),
    Spec('clockwise', None, 'Turn clockwise (negative angular.z); asked for when not given.',
         kind=bool),
    Spec('mode', 'timed', 'timed: open loop on the clock; odom: closed loop on odometry.',
         choices=('timed', 'odom')),
    rate_spec(10.0),
    Spec('angular_accel_deg', 180.0,
         'odom mode: deceleration used to slow down near the goal [deg/s^2].',
         low=0.0, high=100000.0, low_open=True),
    Spec('min_angular_speed_deg', 2.0,
         'odom mode: slowest turn rate while approaching the goal [deg/s].',
         low=0.0, high=MAX_ANGULAR_SPEED_DEG, low_open=True),
    Spec('robot_angular_accel_deg', 0.0,
         "odom mode: the robot's angular acceleration limit (its controller's, or "
         "unicycle_sim's max_angular_accel) [deg/s^2], so that it stops on the goal; 0: it "
         'takes each command at once.', low=0.0, high=100000.0),
)


class RotateRobot(TimedMotion):
    """Turn in place by ``angle_deg`` at ``angular_speed_deg``."""

    def __init__(self, **kwargs):
        super().__init__('rotate_robot', PARAMETERS, **kwargs)
        self.needs_odom = self.params.mode == 'odom'
        self.robot_accel = (0.0, math.radians(self.params.robot_angular_accel_deg))
        self.request = None

    def start(self, request):
        """Set the goal (from parameters and answers) and begin waiting for the robot."""
        p = self.params
        self.request = request
        self.speed = math.radians(request.angular_speed_deg)
        self.goal = math.radians(request.angle_deg)
        self.spin = SpinController(
            self.goal, request.clockwise, self.speed, math.radians(p.min_angular_speed_deg),
            math.radians(p.angular_accel_deg), self.period, robot_accel=self.robot_accel[1])
        self.get_logger().info(
            f'Rotating {request.angle_deg:g} deg '
            f'{"clockwise" if request.clockwise else "counter-clockwise"} at '
            f'{request.angular_speed_deg:g} deg/s ({p.mode} mode)')
        self.ready()

    def plan(self):
        return rotation_plan(self.speed, self.goal, self.request.clockwise)

    def control(self, now_ns):
        if self.params.mode == 'timed':
            command = super().control(now_ns)
            turned = self.elapsed(now_ns) * self.speed
        else:
            (_, predicted), (_, turn_rate) = self.predict(now_ns)
            angular = self.spin.command(self.turned.total, predicted, turn_rate)
            command = None if angular is None else (0.0, angular)
            turned = self.spin.progress(self.turned.total, predicted)
        self.progress(f'Turned {math.degrees(min(turned, self.goal)):.1f} of '
                      f'{self.request.angle_deg:g} deg')
        return command

    def goal_pose(self, start):
        return start.x, start.y, start.yaw + self.spin.sign * self.goal

    def summary(self, end_odom):
        goal_deg = self.spin.sign * self.request.angle_deg
        if end_odom is None:
            return f'commanded {goal_deg:.4f} deg; no odometry, achieved angle unknown'
        turned_deg = math.degrees(self.turned.total)
        return (f'goal {goal_deg:.4f} deg, turned {turned_deg:.4f} deg (odometry), '
                f'error {abs(turned_deg - goal_deg):.4f} deg')


def ask_missing(node, read_line=None, write=None):
    """Ask on stdin for the values not given as parameters, then start the node."""
    p = node.params
    if read_line is None and hasattr(sys.stdin, 'reconfigure'):
        # Strict decoding drops the whole buffered chunk at one undecodable byte, and with it
        # the answers piped after it: keep such bytes as escapes, so only their line is refused.
        sys.stdin.reconfigure(errors='surrogateescape')
    with destroyed_if_refused(node):  # input that ends, or Ctrl-C while asking
        try:
            request = ask_rotation(
                read_line or sys.stdin.readline, write or stream_writer(sys.stdout),
                angular_speed_deg=p.angular_speed_deg, angle_deg=p.angle_deg,
                clockwise=p.clockwise)
        except InputEnded as error:
            raise UsageError(f'{error}; nothing moved') from None
        node.start(request)
    return node


def main(args=None):
    """Ask, rotate, stop; returns the exit code."""
    return run(lambda: ask_missing(RotateRobot()), args, 'rotate_robot')
