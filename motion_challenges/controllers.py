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
The closed loops of the motions on plain numbers (no ROS imports).

SI units, times in integer nanoseconds of the node clock, REP 103 signs.
"""

import collections
from dataclasses import dataclass
import enum
import itertools
import math

from motion_challenges.plans import approach_speed
from motion_challenges.plans import speed_ramp

NS = 1_000_000_000
# A goal is reached once less than this is left to go [m or rad] (about 6e-6 degrees).
TOLERANCE = 1e-7
# How long a CommandLog keeps a command after the next one [ns of the node clock] when no
# odometry asks for it: longer than odom_timeout lets a running motion go without odometry.
HORIZON_NS = 30 * NS
# Odometry that moves further than commanded by more than this between two messages is
# taken for a jump (e.g. a restarted simulator) [m or rad, plus half the commanded motion].
JUMP_TOLERANCE = 0.02


@dataclass
class Pose:
    """A pose in the odometry frame [m, m, rad], measured at stamp_ns [ns, node clock]."""

    x: float
    y: float
    yaw: float
    stamp_ns: int = 0

    def distance_to(self, other):
        return math.hypot(self.x - other.x, self.y - other.y)

    def error_text(self, goal_x, goal_y, goal_yaw):
        """Describe how far this pose is from the goal pose (metres and degrees)."""
        error_m = math.hypot(self.x - goal_x, self.y - goal_y)
        error_deg = math.degrees(abs(math.remainder(self.yaw - goal_yaw, 2.0 * math.pi)))
        return (f'goal ({goal_x:.4f}, {goal_y:.4f}, {math.degrees(goal_yaw):.3f} deg), '
                f'achieved ({self.x:.4f}, {self.y:.4f}, {math.degrees(self.yaw):.3f} deg): '
                f'error {error_m * 1000:.3f} mm, {error_deg:.4f} deg')


class CommandLog:
    """
    The commands a node published, to predict its progress since the last odometry.

    Odometry stamped at s reports the pose at s; adding the integral of the commands since
    (each holds until the next) removes the lag that would make a closed loop overshoot.
    """

    def __init__(self, horizon_ns=HORIZON_NS):
        self.horizon_ns = horizon_ns
        self._entries = collections.deque()  # (time_ns, linear, angular), oldest first

    def __len__(self):
        return len(self._entries)

    def add(self, now_ns, linear, angular):
        self._entries.append((now_ns, linear, angular))
        self.forget_before(now_ns - self.horizon_ns)

    def forget_before(self, t_ns):
        """Drop the commands that ended before t_ns (the latest one always stays)."""
        entries = self._entries
        while len(entries) > 1 and entries[1][0] <= t_ns:
            entries.popleft()

    def predict(self, since_ns, now_ns, velocity=(0.0, 0.0), accel=(0.0, 0.0)):
        """Return the robot's ((metres, radians), (linear, angular)) from since_ns to now_ns."""
        (linear, angular), (speed, turn_rate) = (0.0, 0.0), velocity
        linear_accel, angular_accel = accel
        for (start, v, w), (end, *_) in itertools.pairwise([*self._entries, (now_ns,)]):
            overlap = (min(end, now_ns) - max(start, since_ns)) / NS
            if overlap > 0.0:
                metres, speed = speed_ramp(speed, v, linear_accel, overlap)
                radians, turn_rate = speed_ramp(turn_rate, w, angular_accel, overlap)
                linear += metres
                angular += radians
        return (linear, angular), (speed, turn_rate)


def odometry_fault(last, pose, commands, velocity=(0.0, 0.0), accel=(0.0, 0.0)):
    """
    Return why odometry pose cannot follow odometry last, or '' when it can.

    Time must not go back, nor the robot move or turn further than commanded, nor the other
    way, as a restarted simulator back at its initial pose would (even one whose clock has run
    ahead, allowing for the distance).
    """
    if pose.stamp_ns < last.stamp_ns:
        return (f'Odometry went back in time from {last.stamp_ns / NS:.3f} s to '
                f'{pose.stamp_ns / NS:.3f} s')
    (metres, radians), _ = commands.predict(last.stamp_ns, pose.stamp_ns, velocity, accel)
    moved = pose.distance_to(last)
    turned = math.remainder(pose.yaw - last.yaw, 2.0 * math.pi)
    # How far along its heading: an arc's chord points half its turn ahead of the start.
    chord = last.yaw + 0.5 * turned
    ahead = (pose.x - last.x) * math.cos(chord) + (pose.y - last.y) * math.sin(chord)
    # The robot may move and turn less than commanded (or not at all), but not more, nor the
    # other way.
    if (moved > 1.5 * abs(metres) + JUMP_TOLERANCE or not _within(ahead, metres, JUMP_TOLERANCE)
            or not _within(turned, radians, JUMP_TOLERANCE)):
        return (f'Odometry jumped {moved:.3f} m ({ahead:+.3f} m along the heading) and '
                f'{math.degrees(abs(turned)):.1f} deg between two messages')
    return ''


def _within(done, commanded, tolerance):
    """Return whether done lies between 0 and 1.5 times commanded, give or take tolerance."""
    return min(0.0, 1.5 * commanded) - tolerance <= done <= max(0.0, 1.5 * commanded) + tolerance


class Standstill:
    """
    Tells a robot that stands still although commanded to move: pushed against a wall, say.

    ``update`` with each odometry returns why the robot is stuck (else ''): it stayed within
    STILL_M and STILL_RAD for STUCK_S while commanded more than WAY_M or WAY_RAD.
    """

    STILL_M = 1e-9
    STILL_RAD = 1e-9
    WAY_M = 0.05
    WAY_RAD = 0.05
    STUCK_S = 1.0

    def __init__(self):
        self._since_ns = None  # since when it stood still while commanded
        self._way = (0.0, 0.0)  # metres and radians commanded since then

    def update(self, last, pose, commands, velocity=(0.0, 0.0), accel=(0.0, 0.0)):
        turned = abs(math.remainder(pose.yaw - last.yaw, 2.0 * math.pi))
        (metres, radians), _ = commands.predict(last.stamp_ns, pose.stamp_ns, velocity, accel)
        if (pose.distance_to(last) > self.STILL_M or turned > self.STILL_RAD
                or (metres == 0.0 and radians == 0.0)):
            self._since_ns = None
            return ''
        if self._since_ns is None:
            self._since_ns, self._way = last.stamp_ns, (0.0, 0.0)
        self._way = (self._way[0] + abs(metres), self._way[1] + abs(radians))
        still_s = (pose.stamp_ns - self._since_ns) / NS
        if still_s < self.STUCK_S or not (self._way[0] > self.WAY_M
                                          or self._way[1] > self.WAY_RAD):
            return ''
        return (f'The robot has stood still at ({pose.x:.3f}, {pose.y:.3f}) for {still_s:.1f} s '
                f'while commanded to go {self._way[0]:.3f} m and turn '
                f'{math.degrees(self._way[1]):.1f} deg (against a wall or another robot?)')


class Approach:
    """
    Nav2 Spin's speed law toward a goal distance or angle (plans.approach_speed).

    ``speed`` is None once less than TOLERANCE remains; a min_speed above max_speed is taken
    as max_speed.
    """

    def __init__(self, max_speed, min_speed, accel, period, robot_accel=0.0):
        self.max_speed, self.min_speed = max_speed, min(min_speed, max_speed)
        self.accel, self.period, self.robot_accel = accel, period, robot_accel
        # Refuse bad values now rather than on the first tick.
        approach_speed(1.0, self.max_speed, self.min_speed, accel, period)

    def speed(self, remaining, velocity=0.0):
        if remaining <= TOLERANCE:
            return None
        return approach_speed(remaining, self.max_speed, self.min_speed, self.accel,
                              self.period, self.robot_accel, velocity)


class SpinController:
    """
    Turn in place by goal [rad], closed loop on the yaw turned so far (rotate_robot's odom mode).

    ``turned`` is the accumulated odometry yaw (4 pi is two turns), ``predicted`` and
    ``turn_rate`` CommandLog.predict's yaw since that odometry and angular speed now.
    """

    def __init__(self, goal, clockwise, max_speed, min_speed, accel, period, robot_accel=0.0):
        self.goal = goal
        self.sign = -1.0 if clockwise else 1.0
        self.approach = Approach(max_speed, min_speed, accel, period, robot_accel)

    def progress(self, turned, predicted=0.0):
        """Return how far the robot has turned in the goal's direction [rad]."""
        return self.sign * (turned + predicted)

    def command(self, turned, predicted=0.0, turn_rate=0.0):
        """Return the angular speed to command [rad/s], or None once the goal is reached."""
        speed = self.approach.speed(self.goal - self.progress(turned, predicted),
                                    self.sign * turn_rate)
        return None if speed is None else self.sign * speed


class Step(enum.Enum):
    """What one step of an out-and-back leg does."""

    DRIVE = 'drive'
    PAUSE = 'pause'
    TURN = 'turn'


class OutAndBack:
    """
    rbx1's odom_out_and_back as a sequence: each leg drives, pauses, turns, pauses (pause 0: none).

    Progress is odometry plus CommandLog.predict's ``predicted`` at ``velocity``.
    """

    def __init__(self, legs, goal_distance, goal_angle, pause, drive, turn):
        self.legs, self._drive, self._turn = legs, drive, turn
        leg = ((Step.DRIVE, goal_distance), (Step.PAUSE, pause),
               (Step.TURN, goal_angle), (Step.PAUSE, pause))
        self.steps = [(number, kind, goal) for number in range(1, legs + 1)
                      for kind, goal in leg if goal > 0.0]
        self._index = None

    @property
    def leg(self):
        """Return the number (from 1) of the leg under way, or None before or after."""
        return self.steps[self._index][0] if self._under_way() else None

    @property
    def step(self):
        """Return the Step under way, or None before the start and after the end."""
        return self.steps[self._index][1] if self._under_way() else None

    @property
    def finished(self):
        return self._index is not None and self._index >= len(self.steps)

    def start(self, now_ns, pose, turned):
        """Begin the first step at now_ns from odometry pose, with turned [rad] accumulated."""
        self._index = -1
        self._next_step(now_ns, pose, turned)

    def command(self, now_ns, pose, turned, predicted=(0.0, 0.0), velocity=(0.0, 0.0)):
        """Return (linear, angular) to command, moving on past finished steps; None at the end."""
        while self._index < len(self.steps):
            _, kind, goal = self.steps[self._index]
            if kind is Step.DRIVE:
                speed = self._drive.speed(
                    goal - (pose.distance_to(self._step_pose) + predicted[0]), velocity[0])
                if speed is not None:
                    return speed, 0.0
            elif kind is Step.TURN:
                speed = self._turn.speed(goal - (turned - self._step_turned + predicted[1]),
                                         velocity[1])
                if speed is not None:
                    return 0.0, speed
            elif (now_ns - self._step_start_ns) / 1e9 < goal - 1e-9:  # the pause goes on
                return 0.0, 0.0
            self._next_step(now_ns, pose, turned)
        return None

    def _under_way(self):
        return self._index is not None and 0 <= self._index < len(self.steps)

    def _next_step(self, now_ns, pose, turned):
        self._index += 1
        self._step_start_ns, self._step_pose, self._step_turned = now_ns, pose, turned
