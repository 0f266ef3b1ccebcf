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
Every robot of the simulator in numpy arrays, advanced in one step (no ROS imports).

The fleet owns each robot's state: pose and velocities, the command it follows, the time its
pose is integrated up to, its cmd_vel deadline and the stamped commands it holds for later.
``integrate_all`` is ``kinematics.integrate`` on arrays: the same operations in the same order,
element by element, so a robot advanced with the others ends bit-identical to one advanced
alone.  Each robot of a Fleet is also a ``UnicycleModel`` (a ``FleetRobot`` whose pose and
velocities are views into the fleet's arrays), so commands, limits and the acceleration ramp
are the single-robot code; only a robot that ramps is advanced on its own.  A fleet of up
to ``ONE_BY_ONE`` robots (a simulator of one robot above all) is stepped robot by robot on
floats instead, the same operations again, where numpy's cost per call would be most of it;
the values of its odometry (``odometry()``) are floats too.
"""

import bisect
import math

import numpy as np
from sim_diffdrive.angles import normalize_angle
from sim_diffdrive.sim.kinematics import integrate
from sim_diffdrive.sim.kinematics import SMALL_ANGLE
from sim_diffdrive.sim.kinematics import UnicycleModel

_NS = 1_000_000_000
_TWO_PI = 2.0 * math.pi
# In Fleet.deadline_ns: no cmd_vel timeout pending.
NO_DEADLINE = 2 ** 63 - 1
# In Fleet.integrated_ns: not integrated yet.
NOT_YET = -1
# Within this |angle| one turn up or down wraps exactly (a - 2 pi is exact for pi <= a <= 4 pi,
# Sterbenz); beyond it, math.remainder does it.  6 < 3 pi, so at most one turn is needed.
_ONE_TURN_WRAP = 6.0
# Up to this many robots, advance_to goes robot by robot on floats: numpy's cost per call
# outweighs what it saves (a step of one moving robot: 36 us in numpy, 2 robot by robot;
# of 16: 39 and 27).
ONE_BY_ONE = 16


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


def _array_attribute(name, velocity=False):
    def get(robot):
        return float(getattr(robot.fleet, name)[robot.index])

    def set_(robot, value):
        getattr(robot.fleet, name)[robot.index] = value
        if velocity and value:
            robot.fleet.resting = False
    return property(get, set_, doc=f"This robot's entry of Fleet.{name}.")


class FleetRobot(UnicycleModel):
    """One robot of a Fleet: a UnicycleModel whose pose and velocities are the fleet's."""

    x = _array_attribute('x')
    y = _array_attribute('y')
    yaw = _array_attribute('yaw')
    linear = _array_attribute('linear', velocity=True)
    angular = _array_attribute('angular', velocity=True)
    target_linear = _array_attribute('target_linear', velocity=True)
    target_angular = _array_attribute('target_angular', velocity=True)

    def __init__(self, fleet, index, x, y, yaw, **limits):
        self.fleet = fleet
        self.index = index
        super().__init__(x, y, yaw, **limits)

    def moving(self):
        """Return whether the robot moves or is commanded to (its entry of Fleet.moving)."""
        fleet, i = self.fleet, self.index
        return bool(fleet.linear[i] != 0.0 or fleet.angular[i] != 0.0
                    or fleet.target_linear[i] != 0.0 or fleet.target_angular[i] != 0.0)

    def advance(self, dt):
        """Move the robot forward in time by dt seconds (UnicycleModel.advance)."""
        # A robot that does not ramp takes one arc (the loop of UnicycleModel.advance runs
        # once, with the same floats): read where it is once, not field by field through the
        # properties, which cost a command more than half its time.
        fleet, i = self.fleet, self.index
        linear, angular = float(fleet.linear[i]), float(fleet.angular[i])
        if linear != fleet.target_linear[i] or angular != fleet.target_angular[i]:
            super().advance(dt)
        elif dt > 0.0:
            fleet.x[i], fleet.y[i], fleet.yaw[i] = integrate(
                float(fleet.x[i]), float(fleet.y[i]), float(fleet.yaw[i]), linear, angular, dt)


class Fleet:
    """
    N unicycles: their state in arrays, robot i also ``fleet.robots[i]``.

    ``poses`` is a sequence of (x, y, yaw); ``names`` the robots' names ('' for a simulator's
    one robot without a name); ``timeout_ns`` the cmd_vel timeout (0: none); ``limits`` are
    UnicycleModel's keyword arguments, the same for every robot at start
    (``robots[i].set_limit`` changes one).  ``on_timeout(i, last_ns)`` is called when robot
    i is stopped because its commands stopped coming, with the time its last command came.
    """

    def __init__(self, poses, *, names=None, timeout_ns=0, on_timeout=None, **limits):
        n = len(poses)
        self.names = list(names) if names is not None else [''] * n
        for name in ('x', 'y', 'yaw', 'linear', 'angular', 'target_linear', 'target_angular'):
            setattr(self, name, np.zeros(n))
        # The time each pose is integrated up to, each cmd_vel deadline, who holds early
        # commands: arrays, so one numpy step finds who has something to do on the way.
        self.integrated_ns = np.full(n, NOT_YET, dtype=np.int64)
        self.deadline_ns = np.full(n, NO_DEADLINE, dtype=np.int64)
        self.has_early = np.zeros(n, dtype=bool)
        self.last_command_ns = [None] * n
        # Stamped commands ahead of the clock, (stamp_ns, linear, angular) in stamp order.
        self.early = [[] for _ in range(n)]
        self.timeout_ns = timeout_ns
        self.on_timeout = on_timeout
        # True while every robot is known to be at rest with no early command: set by
        # advance_to when it finds them so, cleared by any nonzero velocity a robot is given
        # (FleetRobot's attributes) and by hold().  Then a step only moves the time on.
        self.resting = False
        self.robots = [FleetRobot(self, i, x, y, yaw, **limits)
                       for i, (x, y, yaw) in enumerate(poses)]
        # How advance_to goes: robot by robot on floats, or all robots at once in numpy.
        self.one_by_one = n <= ONE_BY_ONE

    def __len__(self):
        return len(self.robots)

    def ramping(self):
        """Return a boolean array: which robots are still ramping towards their command."""
        return (self.linear != self.target_linear) | (self.angular != self.target_angular)

    def moving(self):
        """Return a boolean array: which robots move or are commanded to."""
        return ((self.linear != 0.0) | (self.angular != 0.0)
                | (self.target_linear != 0.0) | (self.target_angular != 0.0))

    def odometry(self):
        """
        Return (time [ns], x, y, qz, qw, linear, angular): what every robot's odometry carries.

        The time is the latest any robot is integrated up to; (qz, qw) is the quaternion of the
        robot's yaw about z.  Lists of floats for a fleet stepped one by one (math.sin and
        math.cos, bit for bit numpy's: test_fleet), arrays otherwise.
        """
        if self.one_by_one:
            half = [0.5 * yaw for yaw in self.yaw.tolist()]
            return (max(self.integrated_ns.tolist()), self.x.tolist(), self.y.tolist(),
                    [math.sin(h) for h in half], [math.cos(h) for h in half],
                    self.linear.tolist(), self.angular.tolist())
        half = 0.5 * self.yaw
        return (int(self.integrated_ns.max()), self.x, self.y, np.sin(half), np.cos(half),
                self.linear, self.angular)

    # -- commands and time ------------------------------------------------------------------

    def command(self, i, linear, angular, at_ns):
        """Robot i follows (linear, angular) from at_ns on (integrate it up to at_ns first)."""
        self.robots[i].command(linear, angular)
        self._set_last_command(i, at_ns)

    def hold(self, i, stamp_ns, linear, angular):
        """Keep a command stamped ahead of the clock for robot i; it applies at its stamp."""
        bisect.insort(self.early[i], (stamp_ns, linear, angular))
        self.has_early[i] = True
        self.resting = False

    def set_timeout(self, timeout_ns):
        """Use a new cmd_vel timeout [ns] (0: none) for every robot, from its last command."""
        self.timeout_ns = timeout_ns
        for i in range(len(self.robots)):
            self._set_last_command(i, self.last_command_ns[i])

    def reset(self, i, x, y, yaw):
        """Put robot i back at (x, y, yaw), at rest; forget its commands."""
        self.robots[i].reset(x, y, yaw)
        self._set_last_command(i, None)
        self.early[i].clear()
        self.has_early[i] = False

    def advance_to(self, now_ns):
        """
        Integrate every robot up to now_ns.

        One numpy step for all but the robots with a cmd_vel timeout, an early command or a
        clock jump on the way, which go one by one.  A fleet at rest only moves its time on: at
        rest, a cmd_vel deadline or a clock jump changes nothing until the robot's next
        command, which brings that robot up to its time first (advance_robot_to).
        """
        integrated = self.integrated_ns
        if self.resting:
            integrated[:] = now_ns
            return
        if self.one_by_one:
            self._advance_each_to(now_ns)
            return
        special = ((self.deadline_ns <= now_ns) | self.has_early | (integrated > now_ns)
                   | (integrated == NOT_YET))
        if special.any():
            for i in np.flatnonzero(special).tolist():
                self.advance_robot_to(i, now_ns)
        behind = integrated < now_ns
        # A robot at rest stays where it is: only the time it is integrated up to moves on.
        moving = behind & self.moving()
        if moving.all():
            self.advance((now_ns - integrated) / _NS)
        elif moving.any():
            index = np.flatnonzero(moving)
            self.advance((now_ns - integrated[index]) / _NS, index)
        else:
            self.resting = not (self.moving().any() or self.has_early.any())
        integrated[behind] = now_ns

    def _advance_each_to(self, now_ns):
        """advance_to robot by robot: the same choices per robot, the same floats."""
        advanced = False
        for i, robot in enumerate(self.robots):
            integrated = int(self.integrated_ns[i])
            if (self.deadline_ns[i] <= now_ns or self.has_early[i] or integrated > now_ns
                    or integrated == NOT_YET):
                self.advance_robot_to(i, now_ns)
            elif integrated < now_ns:
                if robot.moving():
                    robot.advance((now_ns - integrated) / _NS)
                    advanced = True
                self.integrated_ns[i] = now_ns
        if not advanced:
            self.resting = not (self.moving().any() or self.has_early.any())

    def advance_robot_to(self, i, now_ns):
        """Integrate robot i up to now_ns, applying its early commands at their stamps."""
        early = self.early[i]
        integrated = int(self.integrated_ns[i])
        if integrated != NOT_YET and now_ns < integrated:
            early.clear()  # the clock jumped back: they were meant for a time that is gone
        while early and early[0][0] <= now_ns:
            stamp_ns, linear, angular = early.pop(0)
            self._integrate_robot_to(i, stamp_ns)
            self.command(i, linear, angular, stamp_ns)
        self.has_early[i] = bool(early)
        self._integrate_robot_to(i, now_ns)

    def _integrate_robot_to(self, i, now_ns):
        """Integrate robot i up to now_ns, stopping it at its cmd_vel timeout on the way."""
        integrated = int(self.integrated_ns[i])
        last = self.last_command_ns[i]
        if integrated == NOT_YET or now_ns < integrated:
            # First call, or the clock jumped back (e.g. a replayed /clock): restart from here,
            # and count the cmd_vel timeout from here too, not from a time that is now ahead.
            self.integrated_ns[i] = now_ns
            if last is not None:
                self._set_last_command(i, min(last, now_ns))
            return
        robot = self.robots[i]
        deadline = int(self.deadline_ns[i])
        if deadline <= now_ns:
            if robot.target_linear or robot.target_angular or robot.linear or robot.angular:
                robot.advance(max(0, deadline - integrated) / _NS)
                integrated = max(integrated, deadline)
                robot.command(0.0, 0.0)
                if self.on_timeout is not None:
                    self.on_timeout(i, last)
            # At rest, a passed deadline changes nothing until the next command.
            self._set_last_command(i, None)
        robot.advance((now_ns - integrated) / _NS)
        self.integrated_ns[i] = now_ns

    def _set_last_command(self, i, at_ns):
        self.last_command_ns[i] = at_ns
        self.deadline_ns[i] = (NO_DEADLINE if at_ns is None or self.timeout_ns <= 0
                               else at_ns + self.timeout_ns)

    # -- kinematics -------------------------------------------------------------------------

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
