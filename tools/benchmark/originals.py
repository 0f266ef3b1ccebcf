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
The original ROS 1 tutorial programs as pure scripts, and the pure maths of the rows (no ROS).

A script publishes with ``robot.publish(linear, angular)``, reads ``robot.now_ns()``, and each
``yield`` waits for its next tick, as rospy's ``rate.sleep()`` on sim time.  It runs on the
kinematic model (``ModelRobot``), whose ticks a Probe replays to the simulator node.
"""

import math

import numpy as np
from sim_diffdrive.kinematics import integrate
from sim_diffdrive.kinematics import UnicycleModel

NS = 1_000_000_000
ORIGINAL_PI = 3.14


def original_rotate(robot, speed_deg, angle_deg, clockwise):
    """
    Rotate as The Construct's ``rotate_robot.py`` did at 10 Hz (topic and final stop fixed).

    3.14/180; t0 = ``rospy.Time.now().secs``; stop once speed x (now.secs - t0) reaches goal.
    """
    angular_speed = speed_deg * ORIGINAL_PI / 180.0
    t0 = robot.now_ns() // NS
    while True:
        robot.publish(0.0, -angular_speed if clockwise else angular_speed)
        if angular_speed * (robot.now_ns() // NS - t0) >= angle_deg * ORIGINAL_PI / 180.0:
            break
        yield
    robot.publish(0.0, 0.0)


def rbx1_timed_out_and_back(robot, rate=50, linear_speed=0.2, goal_distance=1.0,
                            angular_speed=1.0, goal_angle=math.pi):
    """Drive rbx1's ``timed_out_and_back.py``: two legs, ticks as rbx1 counts them (rbx1_ticks)."""
    drive, turn, _ = rbx1_ticks(rate, linear_speed, goal_distance, angular_speed, goal_angle)
    for _ in range(2):
        for ticks, linear, angular in ((drive, linear_speed, 0.0), (turn, 0.0, angular_speed)):
            for _ in range(ticks):
                robot.publish(linear, angular)
                yield
            robot.publish(0.0, 0.0)
            yield from range(rate)  # rospy.sleep(1)
    robot.publish(0.0, 0.0)


def rbx1_ticks(rate=50, linear_speed=0.2, goal_distance=1.0, angular_speed=1.0,
               goal_angle=math.pi):
    """Return rbx1's drive and turn ticks (from the angle, not the turn's duration) and angle."""
    turn = int(goal_angle * rate)
    return int(goal_distance / linear_speed * rate), turn, turn / rate * angular_speed


def move_rob(robot, cycles, rate=10, linear_speed=0.5, angular_speed=0.5, half_period=15.0):
    """
    Drive ``move_rob.py``'s circle back and forth at 10 Hz, a Twist every tick.

    A flip is published twice, a tick apart, the first Twist only angular; the final stop is
    there to measure (the original never stops).
    """
    half_ticks = round(half_period * rate)
    for tick in range(2 * cycles * half_ticks):
        sign = 1.0 if (tick // half_ticks) % 2 == 0 else -1.0
        flip = tick and tick % half_ticks == 0
        robot.publish(0.0 if flip else sign * linear_speed, sign * angular_speed)
        yield
    robot.publish(0.0, 0.0)


class ModelRobot:
    """Play a script against the exact kinematic model on a simulated clock (no ROS)."""

    def __init__(self, start_ns=0):
        self.model, self.start_ns, self._now_ns = UnicycleModel(), start_ns, start_ns
        self.command, self.ticks = (0.0, 0.0), []

    def now_ns(self):
        return self._now_ns

    def publish(self, linear, angular):
        self.model.command(linear, angular)
        self.command = linear, angular

    def play(self, script, rate_hz):
        """Run script to its end; return the final pose and seconds; ticks: each tick's command."""
        for _ in script:
            self.ticks.append(self.command)
            self.model.advance(1.0 / rate_hz)
            self._now_ns += round(NS / rate_hz)
        return (self.model.x, self.model.y, self.model.yaw), (self._now_ns - self.start_ns) / NS


def start_times(count, step_s, after_s):
    """Return count start times [ns] spread over one second, on the step grid, 3 s apart."""
    step_ns = round(step_s * NS)
    return [(math.floor(after_s) + 1 + 3 * i) * NS + round(i * NS / count / step_ns) * step_ns
            for i in range(count)]


def yaw_error_deg(start_yaw, end_yaw, goal):
    """Return |turned - goal| in degrees, turned being the wrapped change of heading."""
    return math.degrees(abs(math.remainder(end_yaw - start_yaw - goal, 2.0 * math.pi)))


def closure(start, end):
    """Return (mm, deg) from the start pose to the end pose."""
    mm = 1000.0 * math.hypot(end[0] - start[0], end[1] - start[1])
    return mm, yaw_error_deg(start[2], end[2], 0.0)


def integration_errors(laps=100, linear=0.5, angular=0.5, dt=0.02):
    """Return the exact arc's and forward Euler's position errors [m] on a circle: max, end."""
    end_t = laps * 2.0 * math.pi / angular
    steps = int(end_t / dt)
    dts = np.append(np.full(steps, dt), end_t - steps * dt)
    times = np.cumsum(dts)
    exact = linear / angular * np.array([np.sin(angular * times), 1.0 - np.cos(angular * times)])
    # Forward Euler as turtlesim, ArbotiX and nav2_loopback_sim: move along the old heading.
    headings = np.concatenate(([0.0], np.cumsum(angular * dts)[:-1]))
    euler = np.cumsum(linear * dts * np.array([np.cos(headings), np.sin(headings)]), axis=1)
    arc, pose = [], (0.0, 0.0, 0.0)
    for step in dts:
        pose = integrate(*pose, linear, angular, step)
        arc.append(pose[:2])
    euler, arc = (np.hypot(*(path - exact)) for path in (euler, np.array(arc).T))
    return {'arc_end_m': float(arc[-1]), 'arc_max_m': float(arc.max()),
            'euler_end_m': float(euler[-1]), 'euler_max_m': float(euler.max()),
            'steps': int(steps + 1)}
