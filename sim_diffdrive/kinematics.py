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
Exact unicycle kinematics and command limits for the simulator (no ROS imports).

The pose is advanced along the exact arc a constant (v, w) command drives, as ros2_control's
diff_drive odometry does, instead of the forward-Euler step of turtlesim or ArbotiX, so
accuracy does not depend on the step length.
"""

import math

from motion_challenges.angles import normalize_angle

# Below this |w * dt| the arc formulas lose precision; the series below is exact to ~1e-18.
_SMALL_TURN = 1e-4


def _sinc_terms(phi):
    """
    Return (sin(phi)/phi, (1 - cos(phi))/phi), continuous through phi = 0.

    The Taylor series is used for small phi, where the closed forms cancel catastrophically.
    """
    if abs(phi) < _SMALL_TURN:
        phi2 = phi * phi
        return 1.0 - phi2 / 6.0, phi * (0.5 - phi2 / 24.0)
    return math.sin(phi) / phi, (1.0 - math.cos(phi)) / phi


def integrate(x, y, yaw, linear, angular, dt):
    """
    Advance a pose by holding (linear, angular) for dt seconds.

    Returns the new (x, y, yaw) with yaw wrapped to (-pi, pi].  The chord of the arc is
    v*dt*sinc(w*dt) long and leaves at the mean heading, which is exact for any w*dt and
    becomes the straight line smoothly as w -> 0.
    """
    phi = angular * dt
    along, across = _sinc_terms(phi)
    distance = linear * dt
    cos_yaw = math.cos(yaw)
    sin_yaw = math.sin(yaw)
    dx_body = distance * along
    dy_body = distance * across
    return (
        x + dx_body * cos_yaw - dy_body * sin_yaw,
        y + dx_body * sin_yaw + dy_body * cos_yaw,
        normalize_angle(yaw + phi),
    )


def limit_command(target, current, max_speed, max_accel, dt):
    """
    Apply a speed limit and an acceleration limit to one velocity component.

    A limit of 0 means unlimited.  The acceleration limit bounds the change from the velocity
    currently applied over dt seconds.
    """
    if max_speed > 0.0:
        target = max(-max_speed, min(max_speed, target))
    if max_accel > 0.0 and dt > 0.0:
        step = max_accel * dt
        target = max(current - step, min(current + step, target))
    return target


class UnicycleModel:
    """
    A unicycle driven by (linear, angular) velocity commands, advanced piecewise in time.

    ``advance(dt)`` integrates with the command currently applied; callers bring the pose up
    to the moment a new command arrives before ``command()`` changes it, so the result does
    not depend on how often the pose is published.  With an acceleration limit the applied
    velocity ramps towards the command in sub-steps of at most ``ramp_step`` seconds.
    """

    def __init__(self, x=0.0, y=0.0, yaw=0.0, max_linear_speed=0.0, max_angular_speed=0.0,
                 max_linear_accel=0.0, max_angular_accel=0.0, ramp_step=0.001):
        self.max_linear_speed = max_linear_speed
        self.max_angular_speed = max_angular_speed
        self.max_linear_accel = max_linear_accel
        self.max_angular_accel = max_angular_accel
        self.ramp_step = ramp_step
        self.reset(x, y, yaw)

    def reset(self, x, y, yaw):
        """Put the robot at (x, y, yaw), at rest, with a zero command."""
        self.x = x
        self.y = y
        self.yaw = normalize_angle(yaw)
        self.linear = 0.0
        self.angular = 0.0
        self.target_linear = 0.0
        self.target_angular = 0.0

    def command(self, linear, angular):
        """Set the velocity command; speed limits apply at once, acceleration limits over time."""
        self.target_linear = limit_command(linear, 0.0, self.max_linear_speed, 0.0, 0.0)
        self.target_angular = limit_command(angular, 0.0, self.max_angular_speed, 0.0, 0.0)
        if self.max_linear_accel <= 0.0:
            self.linear = self.target_linear
        if self.max_angular_accel <= 0.0:
            self.angular = self.target_angular

    @property
    def ramping(self):
        return self.linear != self.target_linear or self.angular != self.target_angular

    def advance(self, dt):
        """Move the robot forward in time by dt seconds."""
        while dt > 0.0:
            step = min(dt, self.ramp_step) if self.ramping else dt
            if self.ramping:
                # Hold the velocity reached at the middle of the sub-step: second-order accurate.
                linear = limit_command(self.target_linear, self.linear, 0.0,
                                       self.max_linear_accel, 0.5 * step)
                angular = limit_command(self.target_angular, self.angular, 0.0,
                                        self.max_angular_accel, 0.5 * step)
                self.x, self.y, self.yaw = integrate(
                    self.x, self.y, self.yaw, linear, angular, step)
                self.linear = limit_command(self.target_linear, self.linear, 0.0,
                                            self.max_linear_accel, step)
                self.angular = limit_command(self.target_angular, self.angular, 0.0,
                                             self.max_angular_accel, step)
            else:
                self.x, self.y, self.yaw = integrate(
                    self.x, self.y, self.yaw, self.linear, self.angular, step)
            dt -= step
