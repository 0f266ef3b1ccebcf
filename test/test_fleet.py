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

"""Many robots in numpy arrays, bit for bit the single robot's kinematics (no ROS)."""

import math
import random
import struct

import numpy as np
import pytest
from sim_diffdrive.angles import normalize_angle
from sim_diffdrive.sim.fleet import Fleet
from sim_diffdrive.sim.fleet import integrate_all
from sim_diffdrive.sim.fleet import normalize_angles
from sim_diffdrive.sim.fleet import ONE_BY_ONE
from sim_diffdrive.sim.kinematics import integrate
from sim_diffdrive.sim.kinematics import SMALL_ANGLE
from sim_diffdrive.sim.kinematics import UnicycleModel


def state(model):
    return (model.x, model.y, model.yaw, model.linear, model.angular)


def test_normalize_angles_equals_normalize_angle_bit_for_bit():
    rng = random.Random(7)
    angles = [rng.uniform(-9.0, 9.0) for _ in range(20000)]
    # The edges: +-pi (a tie that math.remainder breaks to +pi), several turns, huge ones.
    angles += [math.pi, -math.pi, 2 * math.pi, -2 * math.pi, 3 * math.pi, -3 * math.pi,
               math.nextafter(math.pi, 10.0), math.nextafter(-math.pi, -10.0), 6.0, -6.0,
               100.0, -1e5, 0.0, -0.0]
    wrapped = normalize_angles(np.array(angles)).tolist()
    assert wrapped == [normalize_angle(a) for a in angles]


def test_integrate_all_equals_integrate_bit_for_bit_through_the_small_angle_switch():
    rng = random.Random(8)
    rows = [(rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-3.2, 3.2),
             rng.uniform(-2, 2), rng.choice([0.0, 1e-9, 2 * SMALL_ANGLE, rng.uniform(-4, 4)]),
             rng.choice([0.02, 0.001, 0.37])) for _ in range(5000)]
    x, y, yaw, linear, angular, dt = (np.array(column) for column in zip(*rows))
    batch = zip(*(a.tolist() for a in integrate_all(x, y, yaw, linear, angular, dt)))
    assert list(batch) == [integrate(*row) for row in rows]


# No limits, and every kind of limit (some robots then ramp).
LIMITS = [{}, {'max_linear_accel': 0.5, 'max_angular_accel': 1.0, 'max_linear_speed': 0.8,
               'max_angular_speed': 2.0}]


def fleet_and_twins(rng, count, limits):
    """Return a Fleet of count robots at random poses and a lone UnicycleModel for each."""
    poses = [(rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-3, 3)) for _ in range(count)]
    return Fleet(poses, **limits), [UnicycleModel(*pose, **limits) for pose in poses]


def random_command(rng):
    """Return (linear, angular): zero, tiny or any, as controllers send them."""
    return (rng.choice([0.0, rng.uniform(-1, 1)]), rng.choice([0.0, 1e-7, rng.uniform(-3, 3)]))


@pytest.mark.parametrize('limits', LIMITS)
def test_a_fleet_moves_each_robot_as_a_unicycle_model_alone_would(limits):
    """Random commands to 64 robots, some ramping: every state equals its lone twin's."""
    rng = random.Random(9)
    fleet, alone = fleet_and_twins(rng, 64, limits)
    ramped = 0
    for _ in range(300):
        for robot, twin in zip(fleet.robots, alone):
            if rng.random() < 0.05:
                command = random_command(rng)
                robot.command(*command)
                twin.command(*command)
        ramped += int(fleet.ramping().sum())
        fleet.advance(0.02)
        for twin in alone:
            twin.advance(0.02)
    assert [state(robot) for robot in fleet.robots] == [state(twin) for twin in alone]
    assert any(state(twin)[3] for twin in alone)  # some robots were moving at the end
    assert bool(ramped) == bool(limits)


@pytest.mark.parametrize('limits', LIMITS)
def test_a_robot_advanced_on_its_own_moves_as_its_lone_twin(limits):
    """As the simulator does at each command: one robot at a time, by any dt, bit for bit."""
    rng = random.Random(11)
    fleet, alone = fleet_and_twins(rng, 16, limits)
    for _ in range(400):
        k = rng.randrange(len(alone))
        robot, twin = fleet.robots[k], alone[k]
        dt = rng.choice([0.0, -0.01, 1e-9, 0.003, 0.02, rng.uniform(0.0, 0.5)])
        robot.advance(dt)
        twin.advance(dt)
        if rng.random() < 0.3:
            command = random_command(rng)
            robot.command(*command)
            twin.command(*command)
    assert [state(robot) for robot in fleet.robots] == [state(twin) for twin in alone]
    assert sum(bool(state(twin)[3]) for twin in alone) > 4  # many were moving at the end


def test_advancing_some_robots_leaves_the_others_where_they_are():
    fleet = Fleet([(0.0, 0.0, 0.0), (1.0, 2.0, 0.5), (3.0, 0.0, -1.0)])
    for robot in fleet.robots:
        robot.command(1.0, 0.5)
    fleet.advance([0.5, 0.25], which=[0, 2])
    assert state(fleet.robots[1]) == (1.0, 2.0, 0.5, 1.0, 0.5)
    expected = UnicycleModel(3.0, 0.0, -1.0)
    expected.command(1.0, 0.5)
    expected.advance(0.25)
    assert state(fleet.robots[2]) == state(expected)
    assert fleet.robots[0].x == pytest.approx(2.0 * math.sin(0.25), rel=1e-12)  # (v/w) sin(wt)


def test_a_robot_is_a_unicycle_model_on_the_fleets_arrays():
    fleet = Fleet([(0.0, 0.0, 0.0)] * 2, max_angular_speed=1.0)
    robot = fleet.robots[1]
    assert isinstance(robot, UnicycleModel)
    robot.command(0.3, 5.0)
    assert (fleet.linear.tolist(), fleet.angular.tolist()) == ([0.0, 0.3], [0.0, 1.0])
    robot.set_limit('max_angular_speed', 2.0)
    assert fleet.angular[1] == 2.0
    assert fleet.moving().tolist() == [False, True]
    robot.reset(1.0, 1.0, 4.0)
    assert (fleet.x[1], fleet.yaw[1], fleet.moving()[1]) == (1.0, normalize_angle(4.0), False)


def _arrays(fleet):
    return [getattr(fleet, name).tolist() for name in (
        'x', 'y', 'yaw', 'linear', 'angular', 'target_linear', 'target_angular',
        'integrated_ns')]


def _odometry_bits(fleet):
    """Return what fleet.odometry() gives, its floats as their IEEE 754 bits (-0.0 is not 0.0)."""
    stamp_ns, *values = fleet.odometry()
    return stamp_ns, [struct.pack(f'<{len(v)}d', *v) for v in values]


def play_events(seed, fleets, before_step):
    """
    Step two fleets through the same random events, asserting their arrays equal after each.

    The events: commands, stops, early commands, resets, cmd_vel timeouts, clock jumps.
    before_step(fleets) runs before each step.  Return how many steps began with the first
    fleet at rest.
    """
    rng = random.Random(seed)
    now, rested = 0, 0
    for _ in range(600):
        now += -500_000_000 if rng.random() < 0.02 else rng.choice([20_000_000, 1_000_000])
        event = rng.random()
        i = rng.randrange(len(fleets[0]))
        for fleet in fleets:  # as robot.py hands a command over, at the moment it arrives
            if event < 0.04:
                fleet.advance_robot_to(i, now)
                fleet.command(i, 0.3, -0.7, now)
            elif event < 0.10:
                fleet.advance_robot_to(i, now)
                fleet.command(i, 0.0, 0.0, now)
            elif event < 0.12:
                fleet.hold(i, now + 30_000_000, 0.0, 1.5)
            elif event < 0.13:
                fleet.reset(i, 1.0, 2.0, 0.5)
        rested += fleets[0].resting
        before_step(fleets)
        for fleet in fleets:
            fleet.advance_to(now)
        assert _arrays(fleets[0]) == _arrays(fleets[1])
        assert _odometry_bits(fleets[0]) == _odometry_bits(fleets[1])
    return rested


def two_fleets(count, timeouts):
    """Return two fleets of count robots with a cmd_vel timeout and an acceleration limit."""
    return [Fleet([(0.5, -0.5, 1.0)] * count, timeout_ns=300_000_000,
                  on_timeout=lambda i, _, t=timeouts[k]: t.append(i), max_linear_accel=2.0)
            for k in range(2)]


@pytest.mark.parametrize('one_by_one', [True, False])
@pytest.mark.parametrize('seed', [1, 2, 3])
def test_a_fleet_at_rest_steps_as_one_that_looks_at_every_robot(seed, one_by_one):
    """Commands, stops, early commands, resets, timeouts, clock jumps: bit for bit the same."""
    timeouts = ([], [])
    fleets = two_fleets(4, timeouts)
    for fleet in fleets:
        fleet.one_by_one = one_by_one

    def look_at_every_robot(fleets):
        fleets[1].resting = False
    rested = play_events(seed, fleets, look_at_every_robot)
    assert timeouts[0] == timeouts[1] and timeouts[0]
    assert 50 < rested < 550  # both ways were taken, many times


@pytest.mark.parametrize('count', [1, 4, ONE_BY_ONE])
@pytest.mark.parametrize('seed', [1, 2])
def test_a_small_fleet_stepped_robot_by_robot_moves_as_in_numpy(seed, count):
    """
    The same events as above: robot by robot on floats, bit for bit what numpy gives.

    The odometry's values too: floats and math.sin, math.cos against arrays and numpy's.
    """
    timeouts = ([], [])
    fleets = two_fleets(count, timeouts)
    assert fleets[1].one_by_one
    fleets[1].one_by_one = False
    play_events(seed, fleets, lambda fleets: None)
    assert timeouts[0] == timeouts[1]
    assert timeouts[0] or count == 1  # (one robot, commanded this often, never timed out)


def test_a_fleet_larger_than_one_by_one_is_stepped_in_numpy():
    assert Fleet([(0.0, 0.0, 0.0)] * ONE_BY_ONE).one_by_one
    assert not Fleet([(0.0, 0.0, 0.0)] * (ONE_BY_ONE + 1)).one_by_one


@pytest.mark.parametrize('count', [4, ONE_BY_ONE + 1])
def test_the_odometry_values_are_the_latest_time_and_each_robots_pose_and_velocities(count):
    poses = [(0.1 * i, -0.2 * i, 0.3 * i - 2.5) for i in range(count)]
    fleet = Fleet(poses)
    fleet.advance_to(5_000)
    fleet.command(count - 1, 0.5, -0.25, 5_000)
    fleet.advance_robot_to(count - 1, 7_000)
    stamp_ns, x, y, qz, qw, linear, angular = fleet.odometry()
    assert stamp_ns == 7_000
    assert list(x) == pytest.approx([pose[0] for pose in poses], abs=1e-6)
    assert list(y) == pytest.approx([pose[1] for pose in poses], abs=1e-6)
    yaws = [math.atan2(2.0 * z * w, 1.0 - 2.0 * z * z) for z, w in zip(qz, qw)]
    assert yaws == pytest.approx([pose[2] for pose in poses], abs=1e-6)
    assert list(linear) == [0.0] * (count - 1) + [0.5]
    assert list(angular) == [0.0] * (count - 1) + [-0.25]
    assert isinstance(x, list) == (count <= ONE_BY_ONE)


def test_any_velocity_or_early_command_wakes_a_resting_fleet():
    fleet = Fleet([(0.0, 0.0, 0.0)] * 3)
    fleet.advance_to(1_000)
    assert fleet.resting
    fleet.robots[2].command(0.0, 0.0)
    assert fleet.resting
    fleet.robots[2].command(0.0, 0.1)
    assert not fleet.resting
    fleet.advance_to(2_000)
    assert not fleet.resting and fleet.yaw[2] == pytest.approx(1e-7)
    fleet.command(2, 0.0, 0.0, 2_000)
    fleet.advance_to(3_000)
    assert fleet.resting
    fleet.hold(0, 5_000, 1.0, 0.0)
    assert not fleet.resting
    fleet.advance_to(6_000)
    assert fleet.x[0] == pytest.approx(1e-6) and fleet.integrated_ns.tolist() == [6_000] * 3
