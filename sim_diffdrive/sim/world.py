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
The pure world: every robot's state and the simulated time, stepped in one place (no ROS).

``World`` owns every robot's pose, velocities, command, limits, cmd_vel deadline, held stamped
commands and map -> odom, and its time in integer nanoseconds; ``step_to(t_ns)`` returns what
the odometry carries; timeouts and contacts wait in ``events`` for the node to log.  Every
robot is advanced by one path, ``_advance``; a fleet larger than ``ONE_BY_ONE`` with nothing
special on the way and no walls moves in one numpy call (``kinematics.integrate_all``, bit for
bit the same).  With walls, robots are solid to each other: a command brings every robot up to
its time, and after the step the pairs that came within reach are searched along their arcs.
"""

import bisect
from collections import namedtuple
import math
from operator import itemgetter

import numpy as np
from sim_diffdrive.angles import normalize_angle
from sim_diffdrive.kinematics import arcs
from sim_diffdrive.kinematics import integrate
from sim_diffdrive.kinematics import integrate_all
from sim_diffdrive.kinematics import limit_command
from sim_diffdrive.kinematics import normalize_angles
from sim_diffdrive.world.contact import earliest_touch
from sim_diffdrive.world.contact import overlaps_robot
from sim_diffdrive.world.contact import ROBOT_TOL
from sim_diffdrive.world.contact import Track

_NS = 1_000_000_000
# In World.deadline_ns: no cmd_vel timeout pending.
NO_DEADLINE = 2 ** 63 - 1
# In World.integrated_ns: not integrated yet.
NOT_YET = -1
# Up to this many robots, step_to goes robot by robot on floats: numpy's cost per call
# outweighs what it saves.
ONE_BY_ONE = 16
LIMITS = ('max_linear_speed', 'max_angular_speed', 'max_linear_accel', 'max_angular_accel')
_VELOCITIES = ('linear', 'angular', 'target_linear', 'target_angular')

# What every robot's odometry carries: the time [ns], and per robot x, y, the quaternion's z and
# w, linear and angular velocity (lists of floats for a small world, arrays otherwise).
Odometry = namedtuple('Odometry', 'stamp_ns x y qz qw linear angular')
# Something that happened during a step: kind 'timeout' (data: when the last command came
# [ns]), 'wall' (data: (x, y) in the map where it touched) or 'robot' (data: (other, whether
# this one was driving towards it, x, y)).
Event = namedtuple('Event', 'kind robot data')
_STAMP = itemgetter(0)  # of a held command (stamp_ns, ...): the order they are held in


class PlacementError(ValueError):
    """A robot may not be placed there: in a wall, or on another robot."""


class World:
    """
    N unicycle robots and the time they are integrated up to (see the module docstring).

    ``poses``: (x, y, yaw) per robot in its odometry frame; ``timeout_ns``: the cmd_vel
    timeout (0: none); ``limits``: the four LIMITS for every robot (0: none); ``walls``: a
    world.contact.Walls, or None for the empty plane (robots then pass through each other).
    """

    def __init__(self, poses, *, names=None, timeout_ns=0, limits=None, walls=None):
        n = len(poses)
        self.names = list(names) if names is not None else [''] * n
        self.x, self.y = (np.array([float(p[k]) for p in poses]) for k in (0, 1))
        self.yaw = np.array([normalize_angle(float(p[2])) for p in poses])
        for name in _VELOCITIES:
            setattr(self, name, np.zeros(n))
        self.commanded = [(0.0, 0.0)] * n
        self.limits = {name: [float((limits or {}).get(name, 0.0))] * n for name in LIMITS}
        self.ramp_step = 0.001  # [s] the longest sub-step of a speed ramp (kinematics.arcs)
        self.integrated_ns = np.full(n, NOT_YET, dtype=np.int64)
        self.deadline_ns = np.full(n, NO_DEADLINE, dtype=np.int64)
        self.last_command_ns = [None] * n
        # Stamped commands ahead of the clock, (stamp_ns, linear, angular) in stamp order.
        self.early = [[] for _ in range(n)]
        self.has_early = np.zeros(n, dtype=bool)
        self.timeout_ns = timeout_ns
        # True while every robot is known to be at rest with no early command: a step then only
        # moves the time on.  Set by step_to; cleared by whatever gives a robot something to do.
        self.resting = False
        self.one_by_one = n <= ONE_BY_ONE
        self.walls = walls
        self.radius = walls.radius if walls is not None else 0.0
        # Where each robot's odometry frame lies in the map (map -> odom): x, y, yaw.
        self.map_x, self.map_y, self.map_yaw = np.zeros(n), np.zeros(n), np.zeros(n)
        # What each robot rests against since its last contact ('wall', 'robot' or None), so
        # that one contact is one Event however long the robot pushes.
        self.touching = [None] * n
        self.events = []
        # While a step of solid robots runs: per robot that moves, its pose where it began to
        # move and its arcs, timed from _begin_ns (see _collide).
        self._drives, self._begin_ns = None, 0
        if walls is not None:
            for i in range(n):
                self._check_place(i, *self._to_map(i, self.x[i], self.y[i], self.yaw[i])[:2])

    def __len__(self):
        return len(self.names)

    # -- what the node reads --------------------------------------------------------------

    def moving(self):
        """Return a boolean array: which robots move or are commanded to."""
        return ((self.linear != 0.0) | (self.angular != 0.0)
                | (self.target_linear != 0.0) | (self.target_angular != 0.0))

    def odometry(self):
        """Return the Odometry of every robot at the latest time any is integrated up to."""
        if self.one_by_one:
            half = (0.5 * self.yaw).tolist()
            return Odometry(max(self.integrated_ns.tolist()), self.x.tolist(), self.y.tolist(),
                            list(map(math.sin, half)), list(map(math.cos, half)),
                            self.linear.tolist(), self.angular.tolist())
        half = 0.5 * self.yaw
        return Odometry(int(self.integrated_ns.max()), self.x, self.y, np.sin(half),
                        np.cos(half), self.linear, self.angular)

    def map_poses(self):
        """Return arrays (x, y, yaw) of every robot in the map frame."""
        c, s = np.cos(self.map_yaw), np.sin(self.map_yaw)
        return (self.map_x + c * self.x - s * self.y, self.map_y + s * self.x + c * self.y,
                normalize_angles(self.yaw + self.map_yaw))

    def begin(self, now_ns):
        """Start every robot's time at now_ns (a simulator that owns time, at its start)."""
        self.integrated_ns[:] = now_ns

    def take_events(self):
        """Return what happened since the last call (a list of Event) and forget it."""
        events, self.events = self.events, []
        return events

    # -- what the node tells it -------------------------------------------------------------

    def command(self, i, linear, angular, at_ns):
        """Robot i follows (linear, angular) from at_ns on (integrated up to at_ns first)."""
        if self.walls is not None:
            self.step_to(at_ns)  # solid robots share one time
        else:
            self._advance(i, at_ns)
        self._command(i, linear, angular)
        self._set_last_command(i, at_ns)

    def hold(self, i, stamp_ns, linear, angular):
        """Keep a command stamped ahead of the clock for robot i; it applies at its stamp."""
        # After those of the same stamp: of two commands for one moment the later counts.
        bisect.insort(self.early[i], (stamp_ns, linear, angular), key=_STAMP)
        self.has_early[i] = True
        self.resting = False

    def set_timeout(self, timeout_ns):
        """Use a new cmd_vel timeout [ns] (0: none) for every robot, from its last command."""
        self.timeout_ns = timeout_ns
        for i in range(len(self)):
            self._set_last_command(i, self.last_command_ns[i])

    def set_limit(self, i, name, value):
        """Change one of robot i's LIMITS; the command in force is limited anew."""
        if name not in self.limits:
            raise KeyError(f'no limit {name!r}')
        self.limits[name][i] = float(value)
        self._command(i, *self.commanded[i])

    def place(self, i, x, y, yaw):
        """Put robot i at (x, y, yaw) in its odometry frame, at rest; forget its commands."""
        if self.walls is not None:
            self._check_place(i, *self._to_map(i, x, y, yaw)[:2])
        self._rest(i, x, y, yaw)

    def place_in_map(self, i, x, y, yaw):
        """Put robot i at (x, y, yaw) in the map, at rest; its odometry goes on where it was."""
        if self.walls is not None:
            self._check_place(i, x, y)
        ox, oy, oyaw = float(self.x[i]), float(self.y[i]), float(self.yaw[i])
        turn = normalize_angle(yaw - oyaw)
        c, s = math.cos(turn), math.sin(turn)
        self.map_x[i], self.map_y[i] = x - (c * ox - s * oy), y - (s * ox + c * oy)
        self.map_yaw[i] = turn
        self._rest(i, ox, oy, oyaw)

    def reset_all(self, poses):
        """
        Put every robot back as at the start, all at once: at rest at (x, y, yaw), map -> odom.

        The poses are in each odometry frame, which lies on the map again (map -> odom the
        identity).  One whose pose is in a wall is refused first, then one on another's new pose
        or on a robot that stays: it stays where it is.  Return {robot: PlacementError}.
        """
        refused = {}
        if self.walls is not None:
            targets = [(x, y) for x, y, _ in poses]
            while True:
                mx, my, _ = self.map_poses()
                where = [(mx[j], my[j]) if j in refused else targets[j] for j in range(len(self))]
                errors = {}
                for i in set(range(len(self))) - set(refused):
                    try:
                        self._check_place(i, *targets[i], where)
                    except PlacementError as error:
                        errors[i] = error
                if not errors:
                    break
                # Not kept off a place that a robot refused for a wall will never take.
                refused.update({i: e for i, e in errors.items() if self.walls.overlaps(
                    *targets[i])} or errors)
        for i, pose in enumerate(poses):
            if i not in refused:
                self.map_x[i] = self.map_y[i] = self.map_yaw[i] = 0.0
                self._rest(i, *pose)
        return refused

    def _rest(self, i, x, y, yaw):
        self.x[i], self.y[i], self.yaw[i] = x, y, normalize_angle(yaw)
        self._halt(i)
        self._set_last_command(i, None)
        self.early[i].clear()
        self.has_early[i] = False
        self.touching[i] = None
        self.resting = False

    def _check_place(self, i, x, y, others=None):
        """
        Raise PlacementError if robot i at (x, y) in the map would be in a wall or a robot.

        others: (x, y) in the map of every robot (i's own is not looked at); default: where
        they are.
        """
        name = self.names[i] or 'the robot'
        if self.walls.overlaps(x, y):
            raise PlacementError(f'{name} at ({x:.3f}, {y:.3f}) in the map would be inside a '
                                 f'wall (robot_radius {self.radius:g} m)')
        if others is None:
            others = list(zip(*self.map_poses()[:2]))
        for j, (ox, oy) in enumerate(others):
            if j != i and overlaps_robot(self.radius, x, y, float(ox), float(oy)):
                raise PlacementError(
                    f'{name} at ({x:.3f}, {y:.3f}) in the map would be on '
                    f'{self.names[j] or "another robot"} at ({ox:.3f}, {oy:.3f})')

    def _command(self, i, linear, angular):
        limits = self.limits
        self.commanded[i] = (linear, angular)
        target_linear = limit_command(linear, 0.0, limits['max_linear_speed'][i], 0.0, 0.0)
        target_angular = limit_command(angular, 0.0, limits['max_angular_speed'][i], 0.0, 0.0)
        self.target_linear[i], self.target_angular[i] = target_linear, target_angular
        if limits['max_linear_accel'][i] <= 0.0:
            self.linear[i] = target_linear
        if limits['max_angular_accel'][i] <= 0.0:
            self.angular[i] = target_angular
        if target_linear or target_angular:
            self.resting = False

    def _set_last_command(self, i, at_ns):
        self.last_command_ns[i] = at_ns
        self.deadline_ns[i] = (NO_DEADLINE if at_ns is None or self.timeout_ns <= 0
                               else at_ns + self.timeout_ns)

    # -- the step ---------------------------------------------------------------------------

    def step_to(self, now_ns):
        """Integrate every robot up to now_ns; return the Odometry at now_ns."""
        integrated = self.integrated_ns
        if self.resting:
            integrated[:] = now_ns
            return self.odometry()
        if self.walls is not None:
            # As command() does: every robot up to a held command's stamp, touches resolved,
            # then the command (a touch before it must not cancel it).
            for stamp_ns, i, linear, angular in self._due(now_ns):
                self._solid_step(max(stamp_ns, int(integrated.max())))
                self._command(i, linear, angular)
                self._set_last_command(i, stamp_ns)
            self._solid_step(now_ns)
        elif self.one_by_one:
            for i in range(len(self.names)):
                self._advance(i, now_ns)
        else:
            self._advance_in_numpy(now_ns)
        # moving().any(), a reduction at a time (most often the first says it): a few us a step.
        if not (self.linear.any() or self.angular.any() or self.target_linear.any()
                or self.target_angular.any() or self.has_early.any()):
            self.resting = True
        return self.odometry()

    def _due(self, now_ns):
        """Take the held commands due by now_ns out: (stamp, robot, linear, angular) in order."""
        integrated = self.integrated_ns
        if not self.has_early.any() or NOT_YET in integrated or now_ns < integrated.max():
            return []  # none held; or a first step, a clock gone back: _advance's way
        due = []
        for i, early in enumerate(self.early):
            while early and early[0][0] <= now_ns:
                stamp_ns, linear, angular = early.pop(0)
                due.append((stamp_ns, i, linear, angular))
            self.has_early[i] = bool(early)
        due.sort(key=_STAMP)  # stable: one robot's keep their order
        return due

    def _solid_step(self, now_ns):
        """Advance every robot up to now_ns; stop those that touched each other on the way."""
        known = self.integrated_ns[self.integrated_ns != NOT_YET]
        begin_ns = min(int(known.min()), now_ns) if known.size else now_ns
        self._drives, self._begin_ns, events_from = {}, begin_ns, len(self.events)
        for i in range(len(self)):
            self._advance(i, now_ns)
        drives, self._drives = self._drives, None
        self._collide(begin_ns, drives, events_from)

    def _advance_in_numpy(self, now_ns):
        """step_to for a large fleet on the empty plane: one numpy call for the steady."""
        integrated = self.integrated_ns
        special = ((self.deadline_ns <= now_ns) | self.has_early | (integrated > now_ns)
                   | (integrated == NOT_YET)
                   | (self.linear != self.target_linear) | (self.angular != self.target_angular))
        for i in np.flatnonzero(special).tolist():
            self._advance(i, now_ns)
        moving = (integrated < now_ns) & self.moving()
        index = np.flatnonzero(moving)
        if index.size:
            dt = (now_ns - integrated[index]) / _NS
            self.x[index], self.y[index], self.yaw[index] = integrate_all(
                self.x[index], self.y[index], self.yaw[index], self.linear[index],
                self.angular[index], dt)
        integrated[integrated < now_ns] = now_ns

    def _advance(self, i, now_ns):
        """Integrate robot i up to now_ns: early commands at their stamps, then its deadline."""
        integrated = int(self.integrated_ns[i])
        early = self.early[i]
        if integrated == NOT_YET or now_ns < integrated:
            # First call, or the clock jumped back (a replayed /clock): restart from here, count
            # the timeout from here too, and drop commands meant for a time that is gone.
            self.integrated_ns[i] = now_ns
            last = self.last_command_ns[i]
            if last is not None:
                self._set_last_command(i, min(last, now_ns))
            if integrated != NOT_YET:
                early.clear()
        while early and early[0][0] <= now_ns:
            stamp_ns, linear, angular = early.pop(0)
            self._timeout_to(i, stamp_ns)
            self._drive(i, stamp_ns)
            self._command(i, linear, angular)
            self._set_last_command(i, stamp_ns)
        self.has_early[i] = bool(early)
        self._timeout_to(i, now_ns)
        self._drive(i, now_ns)

    def _timeout_to(self, i, now_ns):
        """Stop robot i at its cmd_vel deadline, if that falls by now_ns."""
        deadline = int(self.deadline_ns[i])
        if deadline > now_ns:
            return
        if self._moves(i):
            self._drive(i, max(deadline, int(self.integrated_ns[i])))
            self._command(i, 0.0, 0.0)
            self.events.append(Event('timeout', i, self.last_command_ns[i]))
        # At rest, a passed deadline changes nothing until the next command.
        self._set_last_command(i, None)

    def _moves(self, i):
        return bool(self.linear[i] or self.angular[i] or self.target_linear[i]
                    or self.target_angular[i])

    def _drive(self, i, to_ns):
        """Drive robot i on its command from its time to to_ns, stopping where it touches."""
        start_ns = int(self.integrated_ns[i])
        if to_ns <= start_ns:
            return
        self.integrated_ns[i] = to_ns
        if not self._moves(i):
            return
        x, y, yaw = float(self.x[i]), float(self.y[i]), float(self.yaw[i])
        linear, angular = float(self.linear[i]), float(self.angular[i])
        limits, walls = self.limits, self.walls
        pieces = None
        if self._drives is not None:  # a step of solid robots: keep the arcs (_collide)
            pieces = self._drives.setdefault(i, ((x, y, yaw), self._to_map(i, x, y, yaw), []))[2]
            begin = (start_ns - self._begin_ns) / _NS
        for step, held_linear, held_angular, linear, angular in arcs(
                linear, angular, float(self.target_linear[i]), float(self.target_angular[i]),
                limits['max_linear_accel'][i], limits['max_angular_accel'][i], self.ramp_step,
                (to_ns - start_ns) / _NS):
            if walls is not None and held_linear:
                touch = walls.contact(*self._to_map(i, x, y, yaw), held_linear, held_angular, step)
                if touch is not None:
                    x, y, yaw = integrate(x, y, yaw, held_linear, held_angular, touch)
                    if pieces is not None:
                        pieces.append((begin, touch, held_linear, held_angular))
                    self.x[i], self.y[i], self.yaw[i] = x, y, yaw
                    self._stop(i, 'wall', self._to_map(i, x, y, yaw)[:2])
                    return
                if self.touching[i] == 'wall':
                    self.touching[i] = None
            x, y, yaw = integrate(x, y, yaw, held_linear, held_angular, step)
            if pieces is not None:
                pieces.append((begin, step, held_linear, held_angular))
                begin += step
        self.x[i], self.y[i], self.yaw[i] = x, y, yaw
        self.linear[i], self.angular[i] = linear, angular

    def _stop(self, i, kind, data):
        """Robot i touched something: at rest, its command zero; the first touch is an Event."""
        self._halt(i)
        if self.touching[i] != kind:
            self.touching[i] = kind
            self.events.append(Event(kind, i, data))

    def _halt(self, i):
        for name in _VELOCITIES:
            getattr(self, name)[i] = 0.0
        self.commanded[i] = (0.0, 0.0)

    def _to_map(self, i, x, y, yaw):
        """Return robot i's pose (x, y, yaw) given in its odometry frame, in the map."""
        turn = float(self.map_yaw[i])
        if turn == 0.0:
            return float(self.map_x[i]) + x, float(self.map_y[i]) + y, yaw
        c, s = math.cos(turn), math.sin(turn)
        return (float(self.map_x[i]) + c * x - s * y, float(self.map_y[i]) + s * x + c * y,
                normalize_angle(yaw + turn))

    # -- robots solid to each other ---------------------------------------------------------

    def _collide(self, begin_ns, drives, events_from):
        """
        Stop each pair of robots that touched during the step, at the moment they touched.

        drives: per robot that moved since begin_ns, (its start pose in the odometry frame and
        in the map, its arcs (begin [s after begin_ns], seconds, linear, angular)); events_from:
        the step's first Event.  The earliest touch of any pair puts both back where they were
        then, at rest, their arcs cut there; then the next earliest, until none is left.
        """
        if not drives:
            return
        mx, my, myaw = self.map_poses()
        tracks = [Track(*drives[i][1], drives[i][2]) if i in drives
                  else Track(float(mx[i]), float(my[i]), float(myaw[i]), [])
                  for i in range(len(self))]
        moved = set(drives)
        touched = set()  # pairs stopped against each other (their cut tracks end touching)
        while True:
            first = earliest_touch(tracks, self.radius, touched)
            if first is None:
                break
            at, i, j = first
            touched.add((i, j))
            speed = {}  # of each at the touch: 0 for one that stood (or was stopped before)
            for k in (i, j):
                speed[k] = self._replay(k, drives.pop(k), at, events_from) if k in drives else 0.0
                tracks[k] = tracks[k].cut(at)
            mx, my, myaw = self.map_poses()
            into = [speed[k] * (math.cos(myaw[k]) * (mx[m] - mx[k])
                                + math.sin(myaw[k]) * (my[m] - my[k])) > 0.0
                    for k, m in ((i, j), (j, i))]  # was it driving towards the other?
            self._stop(i, 'robot', (j, into[0], float(mx[i]), float(my[i])))
            self._stop(j, 'robot', (i, into[1], float(mx[j]), float(my[j])))
            moved -= {i, j}
        for i in moved:  # drove free of every robot
            if self.touching[i] == 'robot':
                self.touching[i] = None
        # One that stood while the other drove off is free too: its next touch is said again.
        paired = {k for pair in touched for k in pair}
        standing = [i for i, kind in enumerate(self.touching) if kind == 'robot'
                    and i not in paired and i not in moved]
        if standing:
            mx, my, _ = self.map_poses()
            for i in standing:
                gaps = np.hypot(mx - mx[i], my - my[i])
                gaps[i] = np.inf
                if gaps.min() > 2.0 * self.radius + 2.0 * ROBOT_TOL:  # robot_contact's, rounded
                    self.touching[i] = None

    def _replay(self, i, drive, at, events_from):
        """Put robot i back where its drive had it at [s into the step]; return its speed then."""
        start, _, pieces = drive
        x, y, yaw, speed, _ = Track(*start, pieces).at(at)
        self.x[i], self.y[i], self.yaw[i] = x, y, yaw
        if pieces and at < pieces[-1][0] + pieces[-1][1]:  # a wall after the touch, a timeout?
            self.events[events_from:] = [e for e in self.events[events_from:] if e.robot != i or (
                e.kind == 'timeout' and e.data + self.timeout_ns - self._begin_ns <= at * _NS)]
        return speed
