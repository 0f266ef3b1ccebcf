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

``integrate`` is the one exact-arc formula; ``integrate_all`` does the same operations in the
same order on numpy arrays, equal to it bit for bit; ``arcs`` is the one acceleration ramp.
"""

import math

import numpy as np
from sim_diffdrive.angles import normalize_angle

_TWO_PI = 2.0 * math.pi
# Within this |angle| one turn up or down wraps exactly (a - 2 pi is exact for pi <= a <= 4 pi,
# Sterbenz); beyond it, math.remainder does it.  6 < 3 pi, so at most one turn is needed.
_ONE_TURN_WRAP = 6.0
# Below this |x| the series for sin(x)/x is exact to double precision and avoids 0/0.
SMALL_ANGLE = 1e-4


def _sinc(x):
    """Return sin(x)/x, continuous through x = 0."""
    if abs(x) < SMALL_ANGLE:
        return 1.0 - x * x / 6.0
    return math.sin(x) / x


def integrate(x, y, yaw, linear, angular, dt):
    """
    Return (x, y, yaw) after holding (linear, angular) for dt seconds along the exact arc.

    sin(a + b) - sin(a) = 2 cos(a + b/2) sin(b/2): the arc's chord is a straight step along the
    mid-heading, shortened by sinc(turn/2).  No case split, so no jump as angular -> 0.
    """
    turn = angular * dt
    chord = linear * dt * _sinc(0.5 * turn)
    mid = yaw + 0.5 * turn
    return x + chord * math.cos(mid), y + chord * math.sin(mid), normalize_angle(yaw + turn)


def normalize_angles(angles):
    """Wrap an array of angles to (-pi, pi], equal element by element to normalize_angle."""
    wrapped = np.where(angles > math.pi, angles - _TWO_PI,
                       np.where(angles < -math.pi, angles + _TWO_PI, angles))
    wrapped[wrapped == -math.pi] = math.pi
    far = np.flatnonzero(np.abs(angles) > _ONE_TURN_WRAP)
    for i in far.tolist():
        wrapped[i] = normalize_angle(float(angles[i]))
    return wrapped


def integrate_all(x, y, yaw, linear, angular, dt):
    """Return arrays (x, y, yaw): integrate() element by element; dt a number or an array."""
    turn = angular * dt
    half = 0.5 * turn
    with np.errstate(invalid='ignore', divide='ignore'):
        sinc = np.where(np.abs(half) < SMALL_ANGLE, 1.0 - half * half / 6.0, np.sin(half) / half)
    chord = linear * dt * sinc
    mid = yaw + 0.5 * turn
    return x + chord * np.cos(mid), y + chord * np.sin(mid), normalize_angles(yaw + turn)


def limit_command(target, current, max_speed, max_accel, dt):
    """Limit one velocity component: |target| <= max_speed, |change| <= max_accel dt (0: none)."""
    if max_speed > 0.0:
        target = max(-max_speed, min(max_speed, target))
    if max_accel > 0.0 and dt > 0.0:
        step = max_accel * dt
        target = max(current - step, min(current + step, target))
    return target


def arcs(linear, angular, target_linear, target_angular, max_linear_accel, max_angular_accel,
         ramp_step, dt):
    """
    Yield the arcs a robot drives in dt seconds while its velocity ramps towards its target.

    Each is (seconds, linear, angular held, linear and angular at its end): sub-steps of at most
    ramp_step holding the velocity at their middle while ramping, then the rest in one arc.  A
    sub-step ends where a ramp does, so that each speed is linear in time within it: holding
    the middle is then exact for a straight ramp and for a turn in place.
    """
    while dt > 0.0:
        if linear != target_linear or angular != target_angular:
            linear_left = _ramp_left(linear, target_linear, max_linear_accel)
            angular_left = _ramp_left(angular, target_angular, max_angular_accel)
            step = min(dt, ramp_step, linear_left, angular_left)
            held_linear = limit_command(target_linear, linear, 0.0, max_linear_accel, 0.5 * step)
            held_angular = limit_command(target_angular, angular, 0.0, max_angular_accel,
                                         0.5 * step)
            # At a ramp's end the target itself, not a rounding short of it (a ramp of 1e-17).
            linear = (target_linear if step >= linear_left
                      else limit_command(target_linear, linear, 0.0, max_linear_accel, step))
            angular = (target_angular if step >= angular_left
                       else limit_command(target_angular, angular, 0.0, max_angular_accel, step))
            yield step, held_linear, held_angular, linear, angular
        else:
            step = dt
            yield step, linear, angular, linear, angular
        dt -= step


def _ramp_left(speed, target, max_accel):
    """Return the seconds a ramp from speed to target takes (inf: none, or already there)."""
    if speed == target or max_accel <= 0.0:
        return math.inf
    return abs(target - speed) / max_accel


class UnicycleModel:
    """A unicycle driven by velocity commands, advanced piecewise: sim.world's one-robot twin."""

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
        self.x, self.y, self.yaw = x, y, normalize_angle(yaw)
        self.linear = self.angular = self.target_linear = self.target_angular = 0.0

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
        if dt <= 0.0:
            return
        for step, held_linear, held_angular, self.linear, self.angular in arcs(
                self.linear, self.angular, self.target_linear, self.target_angular,
                self.max_linear_accel, self.max_angular_accel, self.ramp_step, dt):
            self.x, self.y, self.yaw = integrate(self.x, self.y, self.yaw, held_linear,
                                                 held_angular, step)
