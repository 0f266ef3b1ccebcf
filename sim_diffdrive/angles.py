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

"""Planar angle maths shared by the simulator and the motions (no ROS imports)."""

import math


def normalize_angle(angle):
    """Wrap an angle in radians to the interval (-pi, pi]."""
    wrapped = math.remainder(angle, 2.0 * math.pi)
    # math.remainder gives [-pi, pi]; REP 103 code conventionally reports +pi, not -pi.
    return math.pi if wrapped == -math.pi else wrapped


def quaternion_from_yaw(yaw):
    """Return the unit quaternion (x, y, z, w) of a rotation by yaw about +z."""
    half = 0.5 * yaw
    return (0.0, 0.0, math.sin(half), math.cos(half))


# Within this size (and above its inverse) a quaternion's products are exact enough as they are.
_SCALE_FREE = 2.0 ** 500


def yaw_from_quaternion(x, y, z, w):
    """Return the yaw in (-pi, pi] of a quaternion (tolerates a non-unit one)."""
    # w^2 + x^2 - y^2 - z^2 rather than 1 - 2(y^2 + z^2): the same for a unit quaternion, and
    # scale-free.  atan2 can return -pi for a half turn (yaw -pi in): wrap it to +pi.
    largest = max(abs(x), abs(y), abs(z), abs(w))
    if largest > _SCALE_FREE or 0.0 < largest < 1.0 / _SCALE_FREE:
        # Products would overflow to inf (a NaN yaw) or underflow to 0: scale by a power of
        # two, which changes no digit.
        exponent = math.frexp(largest)[1]
        x, y, z, w = (math.ldexp(c, -exponent) for c in (x, y, z, w))
    return normalize_angle(math.atan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z))


class YawAccumulator:
    """
    Sum the wrapped yaw changes between successive headings: 720 degrees means two turns.

    Readings must come often enough that the robot turns less than pi between two of them.
    """

    def __init__(self, yaw=None):
        self.reset(yaw)

    def reset(self, yaw):
        """Start counting from heading yaw."""
        self._last_yaw = yaw
        self.total = 0.0

    def update(self, yaw):
        """Add the change from the previous heading and return the total turned so far."""
        if self._last_yaw is not None:
            self.total += normalize_angle(yaw - self._last_yaw)
        self._last_yaw = yaw
        return self.total
