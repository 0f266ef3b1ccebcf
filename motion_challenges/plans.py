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

"""Velocity plans of the timed motions, the speed law of the closed loops (no ROS; SI, REP 103)."""

import bisect
from dataclasses import dataclass
import itertools
import math

from sim_diffdrive.angles import normalize_angle
from sim_diffdrive.kinematics import integrate

# ROS time has nanosecond resolution, so a time within 1 ns of a segment boundary is on it.
# Snapping there keeps float noise (15 * 0.1 != 1.5) from producing a sliver of a segment.
TIME_TOLERANCE = 1e-9


def _require_finite(name, value):
    if not math.isfinite(value):
        raise ValueError(f'{name} must be finite, got {value!r}')


def _require_positive(name, value):
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f'{name} must be positive and finite, got {value!r}')


@dataclass(frozen=True)
class Segment:
    """Constant velocity command (linear m/s, angular rad/s) held for duration seconds."""

    linear: float
    angular: float
    duration: float

    def __post_init__(self):
        _require_finite('linear speed', self.linear)
        _require_finite('angular speed', self.angular)
        _require_positive('segment duration', self.duration)


def pause(duration):
    """Return a segment that stands still for duration seconds."""
    return Segment(0.0, 0.0, duration)


class PiecewisePlan:
    """
    A sequence of constant velocity segments starting at t = 0, optionally repeated forever.

    Zero before t = 0 and after the end.  ``average(t, t + period)`` is what a tick at t should
    publish: the commanded integral then equals the plan's, even mid-segment.
    """

    def __init__(self, segments, repeat=False):
        self.segments = tuple(segments)
        if not self.segments:
            raise ValueError('a plan needs at least one segment')
        for segment in self.segments:
            if not isinstance(segment, Segment):
                raise TypeError(f'expected a Segment, got {segment!r}')
        self.repeat = bool(repeat)
        # _knots[i] is the start time of segment i; _linear[i], _angular[i] the integrals so far.
        self._knots = [0.0, *itertools.accumulate(s.duration for s in self.segments)]
        self._linear = [0.0, *itertools.accumulate(s.linear * s.duration for s in self.segments)]
        self._angular = [0.0, *itertools.accumulate(s.angular * s.duration for s in self.segments)]
        self.cycle_duration = self._knots[-1]

    @property
    def duration(self):
        """Total duration in seconds (math.inf for a repeating plan)."""
        return math.inf if self.repeat else self.cycle_duration

    def finished(self, t):
        """Return True once the plan commands zero from t on (never for a repeating plan)."""
        return not self.repeat and t >= self.cycle_duration - TIME_TOLERANCE

    def _segment_index(self, t):
        """Index of the segment active at t in [0, cycle_duration], snapping to boundaries."""
        i = bisect.bisect_right(self._knots, t) - 1
        i = min(max(i, 0), len(self.segments) - 1)
        if self._knots[i + 1] - t <= TIME_TOLERANCE:
            i += 1
        return i

    def _within_cycle(self, t):
        """Split t >= 0 into (completed cycles, time into the current cycle)."""
        if not self.repeat:
            return 0, min(t, self.cycle_duration)
        cycles = math.floor(t / self.cycle_duration)
        offset = t - cycles * self.cycle_duration
        return cycles, min(max(offset, 0.0), self.cycle_duration)

    def _integral_to(self, t):
        """Integral of the command over [0, t]."""
        if t <= TIME_TOLERANCE:
            return 0.0, 0.0
        cycles, offset = self._within_cycle(t)
        i = self._segment_index(offset)
        linear = cycles * self._linear[-1] + self._linear[i]
        angular = cycles * self._angular[-1] + self._angular[i]
        if i < len(self.segments):
            elapsed = offset - self._knots[i]
            if elapsed > TIME_TOLERANCE:
                linear += self.segments[i].linear * elapsed
                angular += self.segments[i].angular * elapsed
        return linear, angular

    def command_at(self, t):
        """Return the (linear, angular) command active at time t."""
        if t < -TIME_TOLERANCE or self.finished(t):
            return 0.0, 0.0
        _, offset = self._within_cycle(max(t, 0.0))
        segment = self.segments[self._segment_index(offset) % len(self.segments)]
        return segment.linear, segment.angular

    def integral(self, t0, t1):
        """Return the command integrated over [t0, t1]: metres and radians."""
        _require_finite('t0', t0)
        _require_finite('t1', t1)
        if t1 < t0:
            raise ValueError(f'window end {t1!r} is before its start {t0!r}')
        linear0, angular0 = self._integral_to(t0)
        linear1, angular1 = self._integral_to(t1)
        return linear1 - linear0, angular1 - angular0

    def average(self, t0, t1):
        """Return the mean (linear, angular) command over the window [t0, t1)."""
        if not t1 > t0:
            raise ValueError(f'window [{t0!r}, {t1!r}) is empty')
        linear, angular = self.integral(t0, t1)
        width = t1 - t0
        return linear / width, angular / width


def rotation_plan(angular_speed, angle, clockwise):
    """Turn in place by angle (rad) at angular_speed (rad/s), clockwise meaning negative."""
    _require_positive('angular speed', angular_speed)
    _require_positive('angle', angle)
    signed_speed = -angular_speed if clockwise else angular_speed
    return PiecewisePlan([Segment(0.0, signed_speed, angle / angular_speed)])


def circle_plan(linear_speed, angular_speed, half_period, cycles):
    """Drive an arc at (v, w) for half_period, retrace it at (-v, -w): cycles times (0: ever)."""
    _require_positive('half period', half_period)
    if isinstance(cycles, bool) or not isinstance(cycles, int) or cycles < 0:
        raise ValueError(f'cycles must be a non-negative integer, got {cycles!r}')
    there = Segment(linear_speed, angular_speed, half_period)
    back = Segment(-linear_speed, -angular_speed, half_period)
    return PiecewisePlan([there, back] * (cycles or 1), repeat=cycles == 0)


def out_and_back_plan(goal_distance, linear_speed, goal_angle, angular_speed, legs,
                      pause_duration):
    """Build rbx1's timed out-and-back: per leg drive, pause, turn, pause (pause 0: none)."""
    _require_positive('goal distance', goal_distance)
    _require_positive('linear speed', linear_speed)
    _require_positive('goal angle', goal_angle)
    _require_positive('angular speed', angular_speed)
    if isinstance(legs, bool) or not isinstance(legs, int) or legs < 1:
        raise ValueError(f'legs must be a positive integer, got {legs!r}')
    if not (math.isfinite(pause_duration) and pause_duration >= 0.0):
        raise ValueError(f'pause duration must be >= 0 and finite, got {pause_duration!r}')
    stop = [pause(pause_duration)] if pause_duration > 0.0 else []
    leg = ([Segment(linear_speed, 0.0, goal_distance / linear_speed)] + stop
           + [Segment(0.0, angular_speed, goal_angle / angular_speed)] + stop)
    return PiecewisePlan(leg * legs)


def out_and_back_end(start, goal_distance, goal_angle, legs):
    """Return the pose (x, y, yaw) the legs lead to from start (the start itself for pi x 2)."""
    x, y, yaw = start
    for _ in range(legs):
        x, y, yaw = integrate(x, y, yaw, goal_distance, 0.0, 1.0)
        x, y, yaw = integrate(x, y, yaw, 0.0, goal_angle, 1.0)
    return x, y, yaw


def approach_speed(remaining, max_speed, min_speed, accel, period, robot_accel=0.0, velocity=0.0):
    """
    Return the speed for a closed-loop motion with remaining distance or angle to go.

    Nav2 Spin's law clamp(sqrt(2 * accel * remaining), min_speed, max_speed), capped so that
    the last period ends on the goal (remaining / period, or stopping_speed() with robot_accel).
    """
    if math.isnan(remaining):
        raise ValueError('remaining must be a number, got nan')
    _require_positive('max speed', max_speed)
    _require_positive('min speed', min_speed)
    _require_positive('acceleration', accel)
    _require_positive('period', period)
    if min_speed > max_speed:
        raise ValueError(f'min speed {min_speed!r} is above max speed {max_speed!r}')
    if remaining <= 0.0:
        return 0.0
    speed = min(max(math.sqrt(2.0 * accel * remaining), min_speed), max_speed)
    return min(speed, stopping_speed(remaining, velocity, robot_accel, period)
               if robot_accel > 0.0 else remaining / period)


def speed_ramp(velocity, target, accel, dt):
    """Return (distance, velocity) after dt of a robot at velocity ramping at accel to target."""
    if accel <= 0.0:
        return target * dt, target
    change = target - velocity
    reach = abs(change) / accel
    if reach >= dt:
        step = math.copysign(accel * dt, change)
        return (velocity + 0.5 * step) * dt, velocity + step
    return (velocity + 0.5 * change) * reach + target * (dt - reach), target


def stopping_speed(remaining, velocity, accel, period):
    """
    Return the command on which a ramping robot comes to rest after remaining [m or rad].

    The command is held for one period, then 0 (see speed_ramp()).  Commanded c <= velocity
    it goes c t + ((v - c)^2 + c^2) / (2 a), and c >= v c (t + v / a) - v^2 / (2 a): the c that
    makes this remaining.  0 when braking at once goes further; inf when no command it reaches
    within the period would take it that far (any speed will do for now).
    """
    a, t, v = accel, period, velocity
    lowest, highest = max(0.0, v - a * t), v + a * t
    if highest <= 0.0 or remaining >= _stopping_distance(highest, v, a, t):
        return math.inf
    if remaining <= _stopping_distance(lowest, v, a, t):
        return 0.0
    if v > 0.0 and remaining < _stopping_distance(v, v, a, t):
        # c^2 + b c + v^2 / 2 - a remaining = 0, b = a t - v: its larger root (>= lowest),
        # written without subtracting nearly equal numbers.
        b = a * t - v
        root = math.sqrt(max(0.0, b * b - 2.0 * v * v + 4.0 * a * remaining))
        return (2.0 * a * remaining - v * v) / (root + b) if b > 0.0 else 0.5 * (root - b)
    return (remaining + v * v / (2.0 * a)) / (t + v / a)


def _stopping_distance(command, velocity, accel, period):
    """Return how far a robot goes commanded command for period, then 0 (see speed_ramp())."""
    distance, speed = speed_ramp(velocity, command, accel, period)
    return distance + speed * abs(speed) / (2.0 * accel)


def final_pose(plan, x=0.0, y=0.0, yaw=0.0, t_end=None):
    """Return the pose after following plan from (x, y, yaw) until t_end (default: its end)."""
    if t_end is None:
        if plan.repeat:
            raise ValueError('a repeating plan needs t_end')
        t_end = plan.duration
    if not (math.isfinite(t_end) and t_end >= 0.0):
        raise ValueError(f't_end must be >= 0 and finite, got {t_end!r}')
    t = 0.0
    for segment in itertools.cycle(plan.segments) if plan.repeat else plan.segments:
        dt = min(segment.duration, t_end - t)
        if dt <= 0.0:
            break
        x, y, yaw = integrate(x, y, yaw, segment.linear, segment.angular, dt)
        t += segment.duration
    return x, y, normalize_angle(yaw)
