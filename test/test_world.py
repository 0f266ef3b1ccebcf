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

"""The pure world: many robots, bit for bit the single robot's kinematics (no ROS)."""

import math
import random
import struct

import numpy as np
import pytest
from sim_diffdrive.angles import normalize_angle
from sim_diffdrive.kinematics import integrate
from sim_diffdrive.kinematics import integrate_all
from sim_diffdrive.kinematics import normalize_angles
from sim_diffdrive.kinematics import SMALL_ANGLE
from sim_diffdrive.kinematics import UnicycleModel
from sim_diffdrive.sim.world import ONE_BY_ONE
from sim_diffdrive.sim.world import World
from sim_diffdrive.world.contact import Walls
from sim_diffdrive.world.grid import GridMap

_NS = 1_000_000_000


def state(world, i):
    return tuple(float(getattr(world, name)[i]) for name in ('x', 'y', 'yaw', 'linear', 'angular'))


def twin_state(model):
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


def random_command(rng):
    """Return (linear, angular): zero, tiny or any, as controllers send them."""
    return (rng.choice([0.0, rng.uniform(-1, 1)]), rng.choice([0.0, 1e-7, rng.uniform(-3, 3)]))


def world_and_twins(rng, count, limits):
    """Return a World of count robots at random poses and a lone UnicycleModel for each."""
    poses = [(rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-3, 3)) for _ in range(count)]
    world = World(poses, limits=limits)
    world.begin(0)
    return world, [UnicycleModel(*pose, **limits) for pose in poses]


# Robot by robot, and in numpy: any count above ONE_BY_ONE takes the same arrays (64 robots
# took 3 CPU s of twins ramping in 1 ms sub-steps for what 24 show).
@pytest.mark.parametrize('count', [ONE_BY_ONE, ONE_BY_ONE + 8])
@pytest.mark.parametrize('limits', LIMITS)
def test_a_world_moves_each_robot_as_a_unicycle_model_alone_would(limits, count):
    """Random commands, some robots ramping, in numpy or robot by robot: each as its twin."""
    rng = random.Random(9)
    world, alone = world_and_twins(rng, count, limits)
    ramped = 0
    now = 0
    for _ in range(300):
        for i, twin in enumerate(alone):
            if rng.random() < 0.05:
                command = random_command(rng)
                world.command(i, *command, now)
                twin.command(*command)
        ramped += int(((world.linear != world.target_linear)
                       | (world.angular != world.target_angular)).sum())
        now += 20_000_000
        world.step_to(now)
        for twin in alone:
            twin.advance(0.02)
    assert [state(world, i) for i in range(count)] == [twin_state(twin) for twin in alone]
    assert any(twin.linear for twin in alone)  # some robots were moving at the end
    assert bool(ramped) == bool(limits)


@pytest.mark.parametrize('limits', LIMITS)
def test_a_robot_commanded_at_any_moment_moves_as_its_lone_twin(limits):
    """As the simulator does at each command: one robot brought up to then, bit for bit."""
    rng = random.Random(11)
    world, alone = world_and_twins(rng, 16, limits)
    times = [0] * 16
    for _ in range(400):
        k = rng.randrange(len(alone))
        dt_ns = rng.choice([0, 1, 3_000_000, 20_000_000, rng.randrange(0, 500_000_000)])
        times[k] += dt_ns
        command = random_command(rng) if rng.random() < 0.3 else world.commanded[k]
        world.command(k, *command, times[k])
        alone[k].advance(dt_ns / _NS)
        alone[k].command(*command)
    assert [state(world, i) for i in range(16)] == [twin_state(twin) for twin in alone]
    assert sum(bool(twin.linear) for twin in alone) > 4  # many were moving at the end


def test_commands_limits_and_places_are_the_worlds_own():
    world = World([(0.0, 0.0, 0.0)] * 2, limits={'max_angular_speed': 1.0})
    world.command(1, 0.3, 5.0, 0)
    assert (world.linear.tolist(), world.angular.tolist()) == ([0.0, 0.3], [0.0, 1.0])
    world.set_limit(1, 'max_angular_speed', 2.0)
    assert world.angular[1] == 2.0
    assert world.moving().tolist() == [False, True]
    world.place(1, 1.0, 1.0, 4.0)
    assert (world.x[1], world.yaw[1], world.moving()[1]) == (1.0, normalize_angle(4.0), False)
    with pytest.raises(KeyError):
        world.set_limit(0, 'max_speed', 1.0)


def _arrays(world):
    return [getattr(world, name).tolist() for name in (
        'x', 'y', 'yaw', 'linear', 'angular', 'target_linear', 'target_angular',
        'integrated_ns')]


def _odometry_bits(world):
    """Return what world.odometry() gives, its floats as their IEEE 754 bits (-0.0 is not 0.0)."""
    stamp_ns, *values = world.odometry()
    return stamp_ns, [struct.pack(f'<{len(v)}d', *v) for v in values]


def play_events(seed, worlds, before_step):
    """
    Step two worlds through the same random events, asserting their arrays equal after each.

    The events: commands, stops, early commands, places, cmd_vel timeouts, clock jumps.
    before_step(worlds) runs before each step.  Return how many steps began with the first
    world at rest, and the timeouts of each world.
    """
    rng = random.Random(seed)
    now, rested = 0, 0
    timeouts = ([], [])
    for _ in range(600):
        now += -500_000_000 if rng.random() < 0.02 else rng.choice([20_000_000, 1_000_000])
        event = rng.random()
        i = rng.randrange(len(worlds[0]))
        for world in worlds:  # as robot.py hands a command over, at the moment it arrives
            if event < 0.04:
                world.command(i, 0.3, -0.7, now)
            elif event < 0.10:
                world.command(i, 0.0, 0.0, now)
            elif event < 0.12:
                world.hold(i, now + 30_000_000, 0.0, 1.5)
            elif event < 0.13:
                world.place(i, 1.0, 2.0, 0.5)
        rested += worlds[0].resting
        before_step(worlds)
        for world, seen in zip(worlds, timeouts):
            world.step_to(now)
            seen.extend(event.robot for event in world.take_events() if event.kind == 'timeout')
        assert _arrays(worlds[0]) == _arrays(worlds[1])
        assert _odometry_bits(worlds[0]) == _odometry_bits(worlds[1])
    return rested, timeouts


def two_worlds(count):
    """Return two worlds of count robots with a cmd_vel timeout and an acceleration limit."""
    return [World([(0.5, -0.5, 1.0)] * count, timeout_ns=300_000_000,
                  limits={'max_linear_accel': 2.0}) for _ in range(2)]


@pytest.mark.parametrize('one_by_one', [True, False])
@pytest.mark.parametrize('seed', [1, 2, 3])
def test_a_world_at_rest_steps_as_one_that_looks_at_every_robot(seed, one_by_one):
    """Commands, stops, early commands, places, timeouts, clock jumps: bit for bit the same."""
    worlds = two_worlds(4)
    for world in worlds:
        world.one_by_one = one_by_one

    def look_at_every_robot(worlds):
        worlds[1].resting = False
    rested, timeouts = play_events(seed, worlds, look_at_every_robot)
    assert timeouts[0] == timeouts[1] and timeouts[0]
    assert 50 < rested < 550  # both ways were taken, many times


@pytest.mark.parametrize('count', [1, 4, ONE_BY_ONE])
@pytest.mark.parametrize('seed', [1, 2])
def test_a_small_world_stepped_robot_by_robot_moves_as_in_numpy(seed, count):
    """
    The same events as above: robot by robot on floats, bit for bit what numpy gives.

    The odometry's values too: floats and math.sin, math.cos against arrays and numpy's.
    """
    worlds = two_worlds(count)
    assert worlds[1].one_by_one
    worlds[1].one_by_one = False
    _, timeouts = play_events(seed, worlds, lambda worlds: None)
    assert timeouts[0] == timeouts[1]
    assert timeouts[0] or count == 1  # (one robot, commanded this often, never timed out)


def test_a_world_larger_than_one_by_one_is_stepped_in_numpy():
    assert World([(0.0, 0.0, 0.0)] * ONE_BY_ONE).one_by_one
    assert not World([(0.0, 0.0, 0.0)] * (ONE_BY_ONE + 1)).one_by_one


@pytest.mark.parametrize('count', [4, ONE_BY_ONE + 1])
def test_the_odometry_values_are_the_latest_time_and_each_robots_pose_and_velocities(count):
    poses = [(0.1 * i, -0.2 * i, 0.3 * i - 2.5) for i in range(count)]
    world = World(poses)
    world.step_to(5_000)
    world.command(count - 1, 0.5, -0.25, 5_000)
    world.step_to(7_000)
    stamp_ns, x, y, qz, qw, linear, angular = world.odometry()
    assert stamp_ns == 7_000
    assert list(x) == pytest.approx([pose[0] for pose in poses], abs=1e-6)
    assert list(y) == pytest.approx([pose[1] for pose in poses], abs=1e-6)
    yaws = [math.atan2(2.0 * z * w, 1.0 - 2.0 * z * z) for z, w in zip(qz, qw)]
    assert yaws == pytest.approx([pose[2] for pose in poses], abs=1e-6)
    assert list(linear) == [0.0] * (count - 1) + [0.5]
    assert list(angular) == [0.0] * (count - 1) + [-0.25]
    assert isinstance(x, list) == (count <= ONE_BY_ONE)


def test_any_velocity_or_early_command_wakes_a_resting_world():
    world = World([(0.0, 0.0, 0.0)] * 3)
    world.step_to(1_000)
    assert world.resting
    world.command(2, 0.0, 0.0, 1_000)
    assert world.resting
    world.command(2, 0.0, 0.1, 1_000)
    assert not world.resting
    world.step_to(2_000)
    assert not world.resting and world.yaw[2] == pytest.approx(1e-7)
    world.command(2, 0.0, 0.0, 2_000)
    world.step_to(3_000)
    assert world.resting
    world.hold(0, 5_000, 1.0, 0.0)
    assert not world.resting
    world.step_to(6_000)
    assert world.x[0] == pytest.approx(1e-6) and world.integrated_ns.tolist() == [6_000] * 3


def test_a_robot_placed_in_the_map_keeps_its_odometry_and_moves_map_to_odom():
    world = World([(1.0, 0.5, 0.25)])
    world.place_in_map(0, 3.0, -1.0, 1.0)
    assert (world.x[0], world.y[0], world.yaw[0]) == (1.0, 0.5, 0.25)  # odometry continuous
    mx, my, myaw = world.map_poses()
    assert (mx[0], my[0], myaw[0]) == pytest.approx((3.0, -1.0, 1.0), abs=1e-12)
    world.command(0, 1.0, 0.0, 0)
    world.step_to(_NS)
    mx, my, myaw = world.map_poses()
    # One metre along the heading in the map, whatever the odometry frame's heading.
    assert (mx[0], my[0], myaw[0]) == pytest.approx(
        (3.0 + math.cos(1.0), -1.0 + math.sin(1.0), 1.0), abs=1e-12)
    assert (world.x[0], world.y[0]) == pytest.approx(
        (1.0 + math.cos(0.25), 0.5 + math.sin(0.25)), abs=1e-12)


def test_of_held_commands_for_one_moment_the_later_counts():
    # A controller's command and then its final stop, both stamped T and ahead of the clock.
    world = World([(0.0, 0.0, 0.0)])
    world.begin(0)
    world.hold(0, 100_000_000, 0.2, 0.0)
    world.hold(0, 100_000_000, 0.0, 0.0)
    world.hold(0, 50_000_000, 0.1, 0.0)
    world.step_to(200_000_000)
    assert world.commanded[0] == (0.0, 0.0) and world.linear[0] == 0.0
    assert world.x[0] == pytest.approx(0.1 * 0.05, abs=1e-15)


def open_floor():
    """Return the walls of a 5 m x 5 m map with none inside: robots solid to each other."""
    return Walls(GridMap.from_rows(['.' * 100] * 100, resolution=0.05), 0.1)


def test_a_held_command_after_a_touch_in_the_same_step_still_counts():
    world = World([(1.0, 1.0, 0.0), (1.25, 1.0, 0.0)], walls=open_floor())
    world.begin(0)
    world.command(0, 1.0, 0.0, 0)  # 0.05 m between the discs: they touch at 0.05 s
    world.hold(0, 100_000_000, -0.5, 0.0)  # back off from 0.1 s on
    world.step_to(100_000_000)
    assert [event.kind for event in world.take_events()] == ['robot', 'robot']
    assert world.commanded[0] == (-0.5, 0.0) and world.x[0] == pytest.approx(1.05, abs=1e-12)
    world.step_to(200_000_000)
    assert world.x[0] == pytest.approx(1.0, abs=1e-12) and world.take_events() == []


def test_held_commands_move_a_robot_among_walls_as_on_the_empty_plane():
    poses = [(1.0, 1.0, 0.3), (4.0, 4.0, 0.0)]
    plane, walled = World(poses), World(poses, walls=open_floor())
    for world in (plane, walled):
        world.begin(0)
        world.command(0, 0.3, 0.2, 0)
        world.hold(0, 30_000_000, 0.1, -0.4)
        world.hold(0, 30_000_000, 0.2, 0.5)
        world.hold(0, 40_000_000, 0.4, 0.1)
        world.step_to(50_000_000)
    assert state(walled, 0) == state(plane, 0) and walled.commanded == plane.commanded


def test_robots_are_put_back_all_at_once():
    # robot2 stands where robot1 started, robot1 elsewhere: ~/reset puts both back, in their
    # odometry and in the map (map -> odom as at the start, though robot1 was set in the map).
    world = World([(1.0, 1.0, 0.0), (2.0, 1.0, 0.0)], names=['robot1', 'robot2'],
                  walls=open_floor())
    world.place_in_map(0, 3.0, 3.0, 1.0)
    world.place(1, 1.0, 1.05, 0.0)
    assert world.reset_all([(1.0, 1.0, 0.0), (2.0, 1.0, 0.5)]) == {}
    assert [state(world, i)[:3] for i in (0, 1)] == [(1.0, 1.0, 0.0), (2.0, 1.0, 0.5)]
    assert [pose.tolist() for pose in world.map_poses()] == [[1.0, 2.0], [1.0, 1.0], [0.0, 0.5]]


def test_a_robot_refused_its_place_stays_and_others_keep_off_it():
    world = World([(1.0, 1.0, 0.0), (3.0, 3.0, 0.0), (4.0, 4.0, 0.0), (4.0, 1.0, 0.0)],
                  names=['a', 'b', 'c', 'd'], walls=open_floor())
    refused = world.reset_all([(2.0, 2.0, 0.0), (2.0, 2.1, 0.0), (1.0, 1.0, 0.0),
                               (3.0, 1.0, 0.0)])
    assert {i: str(error) for i, error in refused.items()} == {
        0: 'a at (2.000, 2.000) in the map would be on b at (2.000, 2.100)',
        1: 'b at (2.000, 2.100) in the map would be on a at (2.000, 2.000)',
        2: 'c at (1.000, 1.000) in the map would be on a at (1.000, 1.000)'}
    assert [state(world, i)[:2] for i in range(4)] == [
        (1.0, 1.0), (3.0, 3.0), (4.0, 4.0), (3.0, 1.0)]
    # On the empty plane robots pass through each other: nothing is refused.
    plane = World([(0.0, 0.0, 0.0)] * 2)
    assert plane.reset_all([(1.0, 1.0, 0.0)] * 2) == {} and plane.x.tolist() == [1.0, 1.0]


def test_a_robot_that_stood_while_another_drove_off_says_its_next_touch_again():
    world = World([(1.0, 1.0, 0.0), (1.25, 1.0, 0.0)], walls=open_floor())
    world.begin(0)
    world.command(0, 1.0, 0.0, 0)  # robot 0 drives into robot 1, which stands
    world.step_to(100_000_000)
    assert [(event.kind, event.robot) for event in world.take_events()] == [
        ('robot', 0), ('robot', 1)]
    world.command(0, -1.0, 0.0, 100_000_000)  # off, and back into it
    world.step_to(200_000_000)
    world.command(0, 1.0, 0.0, 200_000_000)
    world.step_to(400_000_000)
    assert [(event.kind, event.robot) for event in world.take_events()] == [
        ('robot', 0), ('robot', 1)]


@pytest.mark.parametrize('accel,target', [(3.0, 1.0), (1000.0, 0.25), (0.3, 0.2)])
@pytest.mark.parametrize('kind', ['straight', 'in_place'])
def test_a_ramp_that_ends_inside_a_sub_step_is_exact(accel, target, kind):
    # Ramps of 1/3 s, 0.25 ms and 2/3 s end between the 1 ms sub-steps: a sub-step that held
    # its middle speed across the ramp's end drove up to accel (1 ms)^2 / 8 too far (3e-5 m
    # at 1000 m/s^2).  Closed form: a t^2 / 2 while ramping, then the target speed.
    straight = kind == 'straight'
    limit = 'max_linear_accel' if straight else 'max_angular_accel'
    world = World([(0.0, 0.0, 0.0)], limits={limit: accel})
    world.begin(0)
    world.command(0, target if straight else 0.0, 0.0 if straight else target, 0)
    for k in range(1, 51):
        world.step_to(k * 20_000_000)
    ramp_s = target / accel
    exact = 0.5 * accel * ramp_s ** 2 + target * (1.0 - ramp_s)
    moved = float(world.x[0]) if straight else float(world.yaw[0])
    assert moved == pytest.approx(exact, abs=1e-14)
    assert float(world.linear[0] if straight else world.angular[0]) == target


@pytest.mark.parametrize('timeout_ns', [0, 12_000_000])
@pytest.mark.parametrize('steps', [1, 20])
def test_two_robots_that_meet_before_a_wall_or_a_timeout_say_only_that_they_met(
        timeout_ns, steps):
    # Robot 0 drives at a wall it would touch at 15 ms, robot 1 across its way: they touch at
    # about 4.6 ms.  In one 20 ms step robot 0 also said 'Hit a wall' (and, with a 12 ms
    # cmd_vel timeout, both said 'No cmd_vel'), and that it was run into rather than drove in.
    walls = Walls(GridMap.from_rows(['.' * 30 + '#' + '.' * 69] * 100, resolution=0.05), 0.1)
    world = World([(1.385, 1.0, 0.0), (1.395, 1.2045, -math.pi / 2)], walls=walls,
                  timeout_ns=timeout_ns)
    world.begin(0)
    world.command(0, 1.0, 0.0, 0)
    world.command(1, 1.0, 0.0, 0)
    for k in range(1, steps + 1):
        world.step_to(20_000_000 * k // steps)
    events = world.take_events()
    assert [(e.kind, e.robot, e.data[:2]) for e in events] == [
        ('robot', 0, (1, True)), ('robot', 1, (0, True))]
    assert world.x[0] == pytest.approx(1.3895736, abs=1e-6) and world.x[0] < 1.4


def test_robots_left_touching_are_not_touched_anew_when_a_third_one_moves():
    # A touch leaves the discs up to 1e-7 m apart (robot_contact's tolerance): taken for
    # parted as soon as any robot moved, pushing on said the same contact again.
    world = World([(1.0, 1.0, 0.0), (1.35, 1.009, 0.0), (4.0, 4.0, 0.0)], walls=open_floor())
    world.begin(0)
    world.command(0, 0.99, 1.38, 0)  # an arc into robot 1
    world.step_to(300_000_000)
    assert [(e.kind, e.robot) for e in world.take_events()] == [('robot', 0), ('robot', 1)]
    world.command(0, 0.0, 0.0, 300_000_000)
    world.command(2, 0.1, 0.0, 300_000_000)  # 3 m away
    world.step_to(320_000_000)
    world.command(0, 0.99, 1.38, 320_000_000)  # pushing again: the same contact
    world.step_to(340_000_000)
    assert world.take_events() == []


@pytest.mark.parametrize('step_ns', [1_000_000, 20_000_000])
def test_a_timeout_before_a_touch_is_kept_while_the_robot_slows_down(step_ns):
    # Under an acceleration limit a robot timed out at 0.325 s still rolls on, and touches
    # another at 0.331 s: the timeout happened, in 1 ms steps as in 20 ms ones.
    world = World([(1.0, 1.0, 0.0), (1.48, 1.0, 0.0)], walls=open_floor(),
                  timeout_ns=325_000_000, limits={'max_linear_accel': 10.0})
    world.begin(0)
    world.command(0, 1.0, 0.0, 0)
    for k in range(1, 400_000_000 // step_ns + 1):
        world.step_to(k * step_ns)
    assert [(e.kind, e.robot) for e in world.take_events()] == [
        ('timeout', 0), ('robot', 0), ('robot', 1)]


def test_a_robot_is_not_kept_off_the_place_of_one_refused_for_a_wall():
    # b's new place is in a wall, so b stays at (4, 4): a, next to where b would have been,
    # was refused too, 'on b at (2.000, 1.000)', a place b never took.
    rows = ['.' * 100] * 100
    rows[79] = '.' * 40 + '#' + '.' * 59  # one solid cell: [2.00, 2.05) x [1.00, 1.05)
    world = World([(0.5, 0.5, 0.0), (4.0, 4.0, 0.0)], names=['a', 'b'],
                  walls=Walls(GridMap.from_rows(rows, resolution=0.05), 0.1))
    refused = world.reset_all([(1.85, 1.0, 0.0), (2.0, 1.0, 0.0)])
    assert {i: str(error) for i, error in refused.items()} == {
        1: 'b at (2.000, 1.000) in the map would be inside a wall (robot_radius 0.1 m)'}
    assert [state(world, i)[:2] for i in (0, 1)] == [(1.85, 1.0), (4.0, 4.0)]
