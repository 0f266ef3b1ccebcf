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
Many unicycles in numpy arrays, advanced in one step (no ROS imports).

``integrate_all`` is ``kinematics.integrate`` on arrays: the same operations in the same order,
element by element, so a robot advanced with the others ends bit-identical to one advanced
alone.  Each robot of a Fleet is also a ``UnicycleModel`` (a ``FleetRobot`` whose pose and
velocities live in the fleet's arrays), so commands, limits and the acceleration ramp are the
single-robot code; only a robot that ramps is advanced on its own.
"""

import math

import numpy as np
from sim_diffdrive.angles import normalize_angle
from sim_diffdrive.sim.kinematics import SMALL_ANGLE
from sim_diffdrive.sim.kinematics import UnicycleModel

_TWO_PI = 2.0 * math.pi
# Within this |angle| one turn up or down wraps exactly (a - 2 pi is exact for pi <= a <= 4 pi,
# Sterbenz); beyond it, math.remainder does it.  6 < 3 pi, so at most one turn is needed.
_ONE_TURN_WRAP = 6.0


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
    """
    Advance arrays of poses, each holding its (linear, angular) for dt seconds (see integrate).

    dt is a number or an array.  Returns new arrays (x, y, yaw), yaw wrapped to (-pi, pi].
    """
    turn = angular * dt
    half = 0.5 * turn
    with np.errstate(invalid='ignore', divide='ignore'):
        sinc = np.where(np.abs(half) < SMALL_ANGLE, 1.0 - half * half / 6.0, np.sin(half) / half)
    chord = linear * dt * sinc
    mid = yaw + 0.5 * turn
    return x + chord * np.cos(mid), y + chord * np.sin(mid), normalize_angles(yaw + turn)


def _array_attribute(name):
    def get(robot):
        return float(getattr(robot.fleet, name)[robot.index])

    def set_(robot, value):
        getattr(robot.fleet, name)[robot.index] = value
    return property(get, set_, doc=f"This robot's entry of Fleet.{name}.")


class FleetRobot(UnicycleModel):
    """One robot of a Fleet: a UnicycleModel whose pose and velocities are the fleet's."""

    x = _array_attribute('x')
    y = _array_attribute('y')
    yaw = _array_attribute('yaw')
    linear = _array_attribute('linear')
    angular = _array_attribute('angular')
    target_linear = _array_attribute('target_linear')
    target_angular = _array_attribute('target_angular')

    def __init__(self, fleet, index, x, y, yaw, **limits):
        self.fleet = fleet
        self.index = index
        super().__init__(x, y, yaw, **limits)


class Fleet:
    """
    N unicycles: poses and velocities in arrays, robot i also ``fleet.robots[i]``.

    ``poses`` is a sequence of (x, y, yaw); ``names`` the robots' names ('' for a simulator's
    one robot without a name); ``limits`` are UnicycleModel's keyword arguments, the same for
    every robot at start (``robots[i].set_limit`` changes one).
    """

    def __init__(self, poses, names=None, **limits):
        n = len(poses)
        self.names = list(names) if names is not None else [''] * n
        for name in ('x', 'y', 'yaw', 'linear', 'angular', 'target_linear', 'target_angular'):
            setattr(self, name, np.zeros(n))
        self.robots = [FleetRobot(self, i, x, y, yaw, **limits)
                       for i, (x, y, yaw) in enumerate(poses)]

    def __len__(self):
        return len(self.robots)

    def ramping(self):
        """Return a boolean array: which robots are still ramping towards their command."""
        return (self.linear != self.target_linear) | (self.angular != self.target_angular)

    def moving(self):
        """Return a boolean array: which robots move or are commanded to."""
        return ((self.linear != 0.0) | (self.angular != 0.0)
                | (self.target_linear != 0.0) | (self.target_angular != 0.0))

    def advance(self, dt, which=None):
        """
        Advance robots by dt seconds (a number, or an array with one entry per robot chosen).

        ``which`` is an index array (default: every robot).  Robots that ramp go one by one
        through UnicycleModel.advance; the others in one numpy step.  Equal, robot by robot, to
        ``robots[i].advance(dt)``.
        """
        index = np.arange(len(self.robots)) if which is None else np.asarray(which, dtype=np.intp)
        dt = np.broadcast_to(np.asarray(dt, dtype=float), index.shape)
        keep = dt > 0.0
        ramping = self.ramping()[index]
        for i, step in zip(index[ramping & keep].tolist(), dt[ramping & keep].tolist()):
            self.robots[i].advance(step)
        steady = keep & ~ramping
        if which is None and steady.all():
            self.x, self.y, self.yaw = integrate_all(
                self.x, self.y, self.yaw, self.linear, self.angular, dt)
            return
        index, dt = index[steady], dt[steady]
        if index.size:
            self.x[index], self.y[index], self.yaw[index] = integrate_all(
                self.x[index], self.y[index], self.yaw[index], self.linear[index],
                self.angular[index], dt)
