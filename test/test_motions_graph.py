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

"""The motions against the simulator in one process, on lockstep simulated time."""

import math
import re

from motion_challenges.circle_back_and_forth import CircleBackAndForth
from motion_challenges.odom_out_and_back import OdomOutAndBack
from motion_challenges.prompts import RotationRequest
from motion_challenges.rotate_robot import RotateRobot
from motion_challenges.timed_out_and_back import TimedOutAndBack
import pytest
from sim_diffdrive.harness import angle_error
from sim_diffdrive.harness import pose_of
from sim_diffdrive.sim.node import UnicycleSim

MM = 1e-3
HUNDREDTH_DEG = math.radians(0.01)


def run_to_end(graph, node, sim_timeout):
    graph.step_until(lambda: node.done, sim_timeout)
    assert node.exit_code == 0
    # Odometry after the stop shows where the robot came to rest.
    graph.step_for(0.2)


# Each mode turns a quarter either way, and twice round (each mode one way: the wrap past
# +-pi is the same code for both signs, and each turn costs a simulated second per 60 deg).
@pytest.mark.parametrize('mode,clockwise,angle_deg', [
    (mode, clockwise, 90.0) for mode in ('timed', 'odom') for clockwise in (True, False)]
    + [('timed', False, 720.0), ('odom', True, 720.0)])
def test_rotate_ends_at_goal_yaw(graph, mode, clockwise, angle_deg):
    graph.sim()
    probe = graph.probe()
    node = graph.node(RotateRobot, mode=mode)
    node.start(RotationRequest(60.0, angle_deg, clockwise))
    run_to_end(graph, node, sim_timeout=angle_deg / 60.0 + 5.0)
    _, _, yaw = pose_of(probe.odom)
    goal = math.radians(-angle_deg if clockwise else angle_deg)
    assert angle_error(yaw, goal) < HUNDREDTH_DEG
    assert node.turned.total == pytest.approx(goal, abs=HUNDREDTH_DEG)
    assert probe.odom.twist.twist.angular.z == 0.0


@pytest.mark.parametrize('clockwise', [True, False])
def test_rotate_on_odometry_far_slower_than_its_control_rate_ends_at_goal_yaw(graph, clockwise):
    """Twenty commands between two odometry messages all count in the lag compensation."""
    graph.sim(rate_hz=200.0)  # owns the clock, in steps of 5 ms
    graph.node(UnicycleSim, namespace='/robot1', rate_hz=10.0)
    robot = graph.probe('odom_listener', namespace='/robot1', listen_only=True)
    node = graph.node(RotateRobot, namespace='/robot1', mode='odom', rate_hz=200.0)
    node.start(RotationRequest(60.0, 90.0, clockwise))
    run_to_end(graph, node, sim_timeout=5.0)
    _, _, yaw = pose_of(robot.odoms[-1])
    assert angle_error(yaw, math.radians(-90.0 if clockwise else 90.0)) < 1e-9
    assert robot.odoms[-1].twist.twist.angular.z == 0.0


@pytest.mark.parametrize('rate_hz', [8.0, 7.0])
def test_timed_motions_at_a_rate_off_the_clock_steps_end_exact(graph, rate_hz):
    """
    A control period that is no whole number of the clock's 20 ms steps: exact all the same.

    A tick fires at the first step at or after it is due, so commands hold for uneven times
    (at 8 Hz: 140, 120, 120, 120, 140 ms ...); each covers the plan until the next tick.
    """
    graph.sim()
    robot = graph.probe()
    node = graph.node(RotateRobot, rate_hz=rate_hz)
    node.start(RotationRequest(33.0, 100.0, False))
    run_to_end(graph, node, sim_timeout=10.0)
    assert angle_error(pose_of(robot.odom)[2], math.radians(100.0)) < 1e-9
    node = graph.node(TimedOutAndBack, rate_hz=rate_hz, linear_speed=0.3, angular_speed=0.7,
                      goal_distance=0.5, pause=0.3)
    run_to_end(graph, node, sim_timeout=20.0)
    x, y, yaw = pose_of(robot.odom)
    assert math.hypot(x, y) < 1e-9 and angle_error(yaw, math.radians(100.0)) < 1e-9


@pytest.mark.parametrize('node_class', [TimedOutAndBack, OdomOutAndBack])
def test_out_and_back_returns_to_start(graph, node_class):
    graph.sim(initial_x=1.0, initial_y=-2.0, initial_yaw=0.5)
    probe = graph.probe()
    node = graph.node(node_class)
    run_to_end(graph, node, sim_timeout=40.0)
    x, y, yaw = pose_of(probe.odom)
    assert math.hypot(x - 1.0, y + 2.0) < MM
    assert angle_error(yaw, 0.5) < HUNDREDTH_DEG
    # Halfway, the robot stood goal_distance away, facing back.
    assert probe.odom.twist.twist.linear.x == 0.0


def test_each_phase_is_logged_as_it_begins_however_fast_the_clock_runs(graph, capfd):
    # In process the run takes a fraction of a wall second: a line a second would skip most.
    graph.sim()
    node = graph.node(OdomOutAndBack, goal_distance=0.2, angular_speed=4.0, pause=0.1)
    capfd.readouterr()
    run_to_end(graph, node, sim_timeout=20.0)
    logged = re.findall(r'\]: (Leg \d of 2: \w+)', capfd.readouterr().err)
    assert logged == [f'Leg {leg} of 2: {step}' for leg in (1, 2)
                      for step in ('drive', 'pause', 'turn', 'pause')]
    node = graph.node(CircleBackAndForth, half_period=0.2, cycles=2)
    run_to_end(graph, node, sim_timeout=20.0)
    logged = re.findall(r'\]: (Cycle \d of 2, driving \w+)', capfd.readouterr().err)
    assert logged == [f'Cycle {cycle} of 2, driving {leg}' for cycle in (1, 2)
                      for leg in ('out', 'back')]


def test_circle_returns_after_each_cycle_and_reaches_two_radii(graph):
    graph.sim()
    probe = graph.probe()
    v, w, half = 0.5, 0.5, 3.0
    node = graph.node(CircleBackAndForth, linear_speed=v, angular_speed=w,
                      half_period=half, cycles=2)
    run_to_end(graph, node, sim_timeout=20.0)
    start_ns = node.start_ns
    for cycle in (1, 2):
        x, y, _ = pose_of(probe.odom_after(start_ns + int(cycle * 2 * half * 1e9)))
        assert math.hypot(x, y) < MM
    far = max(math.hypot(*pose_of(o)[:2]) for o in probe.odoms)
    # Chord of an arc of radius v/w over angle w*half.
    assert far == pytest.approx(2 * v / w * math.sin(w * half / 2), abs=MM)
    assert probe.odom.twist.twist.linear.x == 0.0


def test_circle_with_defaults_reaches_the_diameter_and_comes_back(graph):
    graph.sim()
    probe = graph.probe()
    # Defaults: 0.5 m/s, 0.5 rad/s, 15 s: the 7.5 rad arc passes the far side of its circle.
    node = graph.node(CircleBackAndForth, cycles=1)
    run_to_end(graph, node, sim_timeout=40.0)
    far = max(math.hypot(*pose_of(o)[:2]) for o in probe.odoms)
    assert far == pytest.approx(2 * 0.5 / 0.5, abs=MM)
    x, y, _ = pose_of(probe.odom)
    assert math.hypot(x, y) < MM


# A robot whose speed ramps: the simulator's acceleration limits, told to the closed loops.
LIMITS = {'max_linear_accel': 0.5, 'max_angular_accel': 2.0}
# The simulator integrates a ramp in 1 ms sub-steps, each at the speed of its middle: exact
# for a straight ramp, a few 1e-7 off where a ramp ends inside a sub-step.
RAMP_TOLERANCE = 1e-6


# Each control rate, each turning one way: the slow-down is the same for both signs.
@pytest.mark.parametrize('clockwise,rate_hz', [(False, 10.0), (True, 50.0)])
def test_rotate_on_odometry_stops_on_the_goal_of_a_robot_that_ramps(graph, clockwise, rate_hz):
    # 135 deg at 60 deg/s, slowing down at 180 deg/s^2, on a robot that can do 114.6: told the
    # robot's limit, the loop commands what lets it stop in time (it overshot by 9 deg).
    graph.sim(**LIMITS)
    probe = graph.probe()
    node = graph.node(RotateRobot, mode='odom', rate_hz=rate_hz,
                      robot_angular_accel_deg=math.degrees(LIMITS['max_angular_accel']))
    node.start(RotationRequest(60.0, 135.0, clockwise))
    run_to_end(graph, node, sim_timeout=10.0)
    assert angle_error(pose_of(probe.odom)[2], math.radians(-135.0 if clockwise else 135.0)) \
        < RAMP_TOLERANCE
    assert probe.odom.twist.twist.angular.z == 0.0


@pytest.mark.parametrize('rate_hz', [10.0, 50.0])
def test_odom_out_and_back_stops_on_each_goal_of_a_robot_that_ramps(graph, rate_hz):
    graph.sim(**LIMITS)
    probe = graph.probe()
    node = graph.node(OdomOutAndBack, rate_hz=rate_hz, goal_distance=0.5,
                      robot_linear_accel=LIMITS['max_linear_accel'],
                      robot_angular_accel=LIMITS['max_angular_accel'])
    run_to_end(graph, node, sim_timeout=40.0)
    x, y, yaw = pose_of(probe.odom)
    # Two legs of 0.5 m and a half turn each: back where it started (it ended 9.9 mm and 2.2
    # deg off before the loop knew the limits).
    assert math.hypot(x, y) < RAMP_TOLERANCE and angle_error(yaw, 0.0) < RAMP_TOLERANCE
    assert probe.odom.twist.twist.linear.x == 0.0 and probe.odom.twist.twist.angular.z == 0.0
