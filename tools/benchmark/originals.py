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
The original ROS 1 tutorial programs, reproduced as pure scripts, and the pure maths of the rows.

A script publishes through ``robot.publish(linear, angular)``, reads ``robot.now_ns()``, and each
``yield`` waits for the next tick of its rate, as rospy's ``rate.sleep()`` does on a clock that
keeps perfect time (sim time).  The same script runs against the pure kinematic model
(``ModelRobot``, here, for tests) or against the real simulator node (``ScriptNode`` in
benchmark.graph, in lockstep).

Also here, without ROS: the start times of the rotation rows, the yaw and closure errors, and
forward Euler against the exact arc.
"""

import math

from benchmark.config import NS
import numpy as np
from sim_diffdrive.sim.kinematics import integrate
from sim_diffdrive.sim.kinematics import UnicycleModel

# The original programs' pi.
ORIGINAL_PI = 3.14


def _sleep_ticks(rate_hz, seconds):
    for _ in range(round(rate_hz * seconds)):
        yield


def original_rotate(robot, speed_deg, angle_deg, clockwise):
    """
    Rotate as The Construct's original ``rotate_robot.py`` did (it ticked at 10 Hz).

    Degrees to radians with 3.14/180; t0 = the whole seconds of now (``rospy.Time.now().secs``);
    every tick publishes the turn, then estimates the angle turned as speed x (whole seconds of
    now - t0) and stops once that estimate reaches the goal.  The topic is fixed (cmd_vel) and
    the final stop is published, so only the time and pi bugs remain.
    """
    angular_speed = speed_deg * ORIGINAL_PI / 180.0
    relative_angle = angle_deg * ORIGINAL_PI / 180.0
    turn = -abs(angular_speed) if clockwise else abs(angular_speed)
    t0 = robot.now_ns() // NS
    while True:
        robot.publish(0.0, turn)
        current_angle = angular_speed * (robot.now_ns() // NS - t0)
        if current_angle >= relative_angle:
            break
        yield
    robot.publish(0.0, 0.0)


def rbx1_timed_out_and_back(robot, rate=50, linear_speed=0.2, goal_distance=1.0,
                            angular_speed=1.0, goal_angle=math.pi):
    """
    Drive rbx1's ``timed_out_and_back.py``: two legs, ticks counted as rbx1 counts them.

    Drive ticks = int(goal_distance / linear_speed * rate); turn ticks = int(goal_angle * rate)
    (from the angle, not the turn's duration); each tick publishes once, a stop is a zero Twist
    followed by ``rospy.sleep(1)``.
    """
    linear_duration = goal_distance / linear_speed
    for _ in range(2):
        for _ in range(int(linear_duration * rate)):
            robot.publish(linear_speed, 0.0)
            yield
        robot.publish(0.0, 0.0)
        yield from _sleep_ticks(rate, 1.0)
        for _ in range(int(goal_angle * rate)):
            robot.publish(0.0, angular_speed)
            yield
        robot.publish(0.0, 0.0)
        yield from _sleep_ticks(rate, 1.0)
    robot.publish(0.0, 0.0)


def rbx1_ticks(rate=50, linear_speed=0.2, goal_distance=1.0, angular_speed=1.0,
               goal_angle=math.pi):
    """Return rbx1's (drive ticks, turn ticks) and the angle its turn really covers [rad]."""
    drive = int(goal_distance / linear_speed * rate)
    turn = int(goal_angle * rate)
    return drive, turn, turn / rate * angular_speed


def move_rob(robot, cycles, rate=10, linear_speed=0.5, angular_speed=0.5, half_period=15.0):
    """
    Drive ``move_rob.py``'s circle back and forth at 10 Hz, modelled as described below.

    Every tick publishes the Twist.  A flip is published twice, a tick apart: first a Twist with
    only the (new) angular part, then both parts.  The original never stops; the stop at the
    end is there to measure it.
    """
    half_ticks = round(half_period * rate)
    for tick in range(2 * cycles * half_ticks):
        sign = 1.0 if (tick // half_ticks) % 2 == 0 else -1.0
        if tick and tick % half_ticks == 0:
            robot.publish(0.0, sign * angular_speed)
        else:
            robot.publish(sign * linear_speed, sign * angular_speed)
        yield
    robot.publish(0.0, 0.0)


class ModelRobot:
    """Play a script against the exact kinematic model on a simulated clock (no ROS)."""

    def __init__(self, start_ns=0):
        self.model = UnicycleModel()
        self._now_ns = start_ns

    def now_ns(self):
        return self._now_ns

    def publish(self, linear, angular):
        self.model.command(linear, angular)

    def play(self, script, rate_hz):
        """Run script to its end; return the final (x, y, yaw) and the seconds it took."""
        period_ns = round(NS / rate_hz)
        start_ns = self._now_ns
        for _ in script:
            self.model.advance(period_ns / NS)
            self._now_ns += period_ns
        m = self.model
        return (m.x, m.y, m.yaw), (self._now_ns - start_ns) / NS


# -- the maths of the accuracy rows ------------------------------------------------------------


def start_times(count, step_s, after_s):
    """Return count start times [ns] spread over one second, on the step grid, after after_s."""
    step_ns = round(step_s * NS)
    whole_s = math.floor(after_s) + 1
    times = []
    for i in range(count):
        offset_ns = round(i * NS / count / step_ns) * step_ns
        times.append((whole_s + 3 * i) * NS + offset_ns)
    return times


def yaw_error_deg(start_yaw, end_yaw, goal):
    """Return |turned - goal| in degrees, turned being the wrapped change of heading."""
    return math.degrees(abs(math.remainder(end_yaw - start_yaw - goal, 2.0 * math.pi)))


def closure(start, end):
    """Return (mm, deg) from the start pose to the end pose."""
    mm = 1000.0 * math.hypot(end[0] - start[0], end[1] - start[1])
    return mm, math.degrees(abs(math.remainder(end[2] - start[2], 2.0 * math.pi)))


def integration_errors(laps=100, linear=0.5, angular=0.5, dt=0.02):
    """
    Drive laps of a circle with the exact arc and with forward Euler at step dt.

    Returns the position errors [m] against the closed form at the end (after exactly `laps`
    laps, a last shorter step included) and the largest along the way, for both integrators.
    """
    end_t = laps * 2.0 * math.pi / angular
    steps = int(end_t / dt)
    last = end_t - steps * dt
    dts = np.full(steps + 1, dt)
    dts[-1] = last
    times = np.cumsum(dts)
    radius = linear / angular
    exact_x = radius * np.sin(angular * times)
    exact_y = radius * (1.0 - np.cos(angular * times))
    # Forward Euler as turtlesim, ArbotiX and nav2_loopback_sim: move along the old heading.
    headings = np.concatenate(([0.0], np.cumsum(angular * dts)[:-1]))
    euler_x = np.cumsum(linear * dts * np.cos(headings))
    euler_y = np.cumsum(linear * dts * np.sin(headings))
    arc_x = np.empty_like(times)
    arc_y = np.empty_like(times)
    x = y = yaw = 0.0
    for i, step in enumerate(dts):
        x, y, yaw = integrate(x, y, yaw, linear, angular, step)
        arc_x[i] = x
        arc_y[i] = y
    euler = np.hypot(euler_x - exact_x, euler_y - exact_y)
    arc = np.hypot(arc_x - exact_x, arc_y - exact_y)
    return {'arc_end_m': float(arc[-1]), 'arc_max_m': float(arc.max()),
            'euler_end_m': float(euler[-1]), 'euler_max_m': float(euler.max()),
            'steps': int(steps + 1)}
