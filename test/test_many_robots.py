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
Many robots in one ``unicycle_sim`` (parameter ``robots``), in one process on lockstep time.

Each robot runs what it would run alone: the same motion ends exact, the same commands give
bit-identical odometry, and nothing one robot is sent or misses touches another.
"""

import math

from motion_challenges.circle_back_and_forth import CircleBackAndForth
from motion_challenges.odom_out_and_back import OdomOutAndBack
from motion_challenges.prompts import RotationRequest
from motion_challenges.rotate_robot import RotateRobot
from motion_challenges.timed_out_and_back import TimedOutAndBack
import pytest
from rclpy.experimental import EventsExecutor
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from sim_diffdrive.harness import angle_error
from sim_diffdrive.harness import pose_of
from sim_diffdrive.harness import SimGraph
from sim_diffdrive.parameters import ParameterError
from sim_diffdrive.sim.node import UnicycleSim
from std_srvs.srv import Empty
from tf2_msgs.msg import TFMessage

MM = 1e-3
HUNDREDTH_DEG = math.radians(0.01)
ROBOTS = [f'robot{i}' for i in range(8)]
# Robot i starts at (i, -i / 2), heading i / 4 rad.
POSES = [(float(i), -i / 2.0, i / 4.0) for i in range(8)]


def flat(poses):
    return [value for pose in poses for value in pose]


@pytest.fixture
def fast_graph():
    """Yield a graph spun by the EventsExecutor: with many nodes it steps about 3x faster."""
    with SimGraph(executor_class=EventsExecutor) as graph:
        yield graph


def test_eight_robots_running_different_motions_in_one_simulator_each_end_exact(fast_graph):
    graph = fast_graph
    graph.sim(robots=ROBOTS, initial_poses=flat(POSES))
    short = {'goal_distance': 0.5, 'linear_speed': 1.0, 'angular_speed': 3.0, 'pause': 0.1}
    nodes = {
        'robot0': graph.node(RotateRobot, namespace='robot0', mode='timed'),
        'robot1': graph.node(RotateRobot, namespace='robot1', mode='odom'),
        'robot2': graph.node(TimedOutAndBack, namespace='robot2', **short),
        'robot3': graph.node(TimedOutAndBack, namespace='robot3', legs=4, **short),
        'robot4': graph.node(OdomOutAndBack, namespace='robot4', **short),
        'robot5': graph.node(OdomOutAndBack, namespace='robot5', goal_distance=0.3,
                             linear_speed=0.6, angular_speed=2.5, pause=0.3),
        'robot6': graph.node(CircleBackAndForth, namespace='robot6', half_period=2.0, cycles=1),
        'robot7': graph.node(CircleBackAndForth, namespace='robot7', angular_speed=-0.8,
                             half_period=1.0, cycles=2),
    }
    nodes['robot0'].start(RotationRequest(90.0, 180.0, True))
    nodes['robot1'].start(RotationRequest(120.0, 450.0, False))
    graph.step_until(lambda: all(node.done for node in nodes.values()), 30.0)
    graph.step_for(0.2)  # odometry after the last stop shows where each came to rest
    assert {name: node.exit_code for name, node in nodes.items()} == dict.fromkeys(ROBOTS, 0)

    goals = dict(zip(ROBOTS, POSES))  # out and back, circles: home
    x0, y0, yaw0 = POSES[0]
    goals['robot0'] = (x0, y0, yaw0 - math.pi)
    x1, y1, yaw1 = POSES[1]
    goals['robot1'] = (x1, y1, yaw1 + math.radians(450.0))
    for name, (x, y, yaw) in goals.items():
        odom = graph.odom(name)
        assert odom.header.frame_id == f'{name}/odom'
        assert odom.child_frame_id == f'{name}/base_footprint'
        end_x, end_y, end_yaw = pose_of(odom)
        assert math.hypot(end_x - x, end_y - y) < MM, name
        assert angle_error(end_yaw, yaw) < HUNDREDTH_DEG, name
        assert (odom.twist.twist.linear.x, odom.twist.twist.angular.z) == (0.0, 0.0), name


SCRIPTS = {
    'a': [(0.5, 1.0, 10), (0.3, -2.0, 7), (0.0, 0.0, 3), (-0.2, 0.4, 9)],
    'b': [(0.0, 3.0, 12), (1.0, 0.0, 5)],
    'c': [(1e-9, 1e-9, 4), (0.7, 0.35, 11), (0.2, 0.0, 1)],
}
LIMITS = {'max_linear_accel': 2.0, 'max_angular_accel': 4.0}  # some steps ramp


def play_and_record(graph, scripts):
    """Play each robot's script on 0.1 s sim ticks; return the robot's odometry."""
    probes = {name: graph.probe(f'driver_{name}', namespace=name or None) for name in scripts}
    for name, probe in probes.items():
        probe.play(scripts[name], period=0.1)
    graph.step_until(lambda: not any(probe.playing for probe in probes.values()), 10.0)
    graph.step_for(1.0)  # and past the cmd_vel timeout of the last ones
    return {name: [(o.header.stamp.sec, o.header.stamp.nanosec, pose_of(o),
                    o.twist.twist.linear.x, o.twist.twist.angular.z) for o in probe.odoms]
            for name, probe in probes.items()}


@pytest.mark.parametrize('limits', [{}, LIMITS])
def test_each_robot_moves_bit_for_bit_as_the_single_robot_simulator_would(graph, limits):
    poses = {'a': (0.0, 0.0, 0.0), 'b': (1.0, -1.0, 3.0), 'c': (-2.0, 0.5, -1.5)}
    graph.sim(robots=list(poses), initial_poses=flat(poses.values()), **limits)
    together = play_and_record(graph, SCRIPTS)
    graph.close()
    for name, (x, y, yaw) in poses.items():
        with SimGraph() as alone:
            alone.sim(initial_x=x, initial_y=y, initial_yaw=yaw, **limits)
            single = play_and_record(alone, {'': SCRIPTS[name]})['']
        # (The fleet recorded on while the others' longer scripts played; the robot had stopped.)
        assert together[name][:len(single)] == single, name
        assert len(single) > 100 and single[-1][3:] == (0.0, 0.0)


def test_a_robots_commands_never_move_another(graph):
    sim = graph.sim(robots=['left', 'middle', 'right'], initial_poses=[0.0, 1.0, 0.0] * 3)
    driver = graph.probe('driver', namespace='middle')
    driver.play([(1.0, 0.5, 20)], period=0.1)
    graph.step_until(lambda: not driver.playing, 5.0)
    graph.step_for(0.2)
    for name in ('left', 'right'):
        odoms = graph.listener(name).odoms
        assert len(odoms) > 100
        assert {(pose_of(o), o.twist.twist.linear.x, o.twist.twist.angular.z)
                for o in odoms} == {((0.0, 1.0, 0.0), 0.0, 0.0)}
    x, y, yaw = graph.pose('middle')
    assert yaw == pytest.approx(1.0, abs=1e-12)  # 2 s at 0.5 rad/s
    assert math.hypot(x - 2 * math.sin(1.0), y - 1.0 - 2 * (1 - math.cos(1.0))) < 1e-9
    assert sim.robots[1].cmd_topic == '/middle/cmd_vel'


def test_one_robots_cmd_vel_timeout_stops_only_that_robot(graph):
    graph.sim(robots=['steady', 'forgotten'], cmd_vel_timeout=0.5)
    steady = graph.probe('steady_driver', namespace='steady')
    forgotten = graph.probe('forgotten_driver', namespace='forgotten')
    graph.step()  # (the graph counts messages once its nodes have discovered each other)
    forgotten.send(1.0, 0.0)  # once, at t = 0.02 s: stops at the timeout, 0.5 s later
    steady.play([(1.0, 0.0, 30)], period=0.1)  # 3 s of fresh commands
    graph.step_until(lambda: not steady.playing, 5.0)
    start_ns = steady.script_started_at
    assert graph.pose('forgotten') == pytest.approx((0.5, 0.0, 0.0), abs=1e-12)
    stopped = graph.listener('forgotten').odom_after(round(0.52e9))
    assert stopped.header.stamp.nanosec == 520_000_000
    assert stopped.twist.twist.linear.x == 0.0
    assert graph.odom('forgotten').twist.twist.linear.x == 0.0
    # The steady robot drove the whole 3 s and was still moving when its script ended.
    moving = graph.listener('steady').odom_after(steady.script_done_at - 1)
    assert moving.twist.twist.linear.x == 1.0
    assert pose_of(moving)[0] == pytest.approx((steady.script_done_at - start_ns) / 1e9,
                                               abs=1e-9)


def test_reset_puts_every_robot_back_at_its_initial_pose(graph):
    sim = graph.sim(robots=['one', 'two'], initial_poses=[1.0, 2.0, 0.5, -1.0, 0.0, 3.0])
    for name in ('one', 'two'):
        graph.probe(f'{name}_driver', namespace=name).play([(1.0, 1.0, 10)])
    graph.step_for(1.5)
    assert graph.pose('one') != (1.0, 2.0, 0.5)
    client = graph.probe('resetter').create_client(Empty, '/unicycle_sim/reset')
    future = client.call_async(Empty.Request())
    graph.step_until(future.done, 2.0)
    graph.step_for(0.1)
    assert graph.pose('one') == (1.0, 2.0, 0.5)
    assert graph.pose('two') == pytest.approx((-1.0, 0.0, 3.0), abs=1e-15)
    assert sim.world.moving().tolist() == [False, False]


def test_one_tf_message_carries_every_robots_transform(graph):
    graph.sim(robots=['r1', 'r2', 'r3'])
    heard = []
    listener = graph.probe('tf_listener')
    listener.create_subscription(TFMessage, '/tf', heard.append, QoSProfile(depth=100))
    graph.step_for(0.5)
    assert len(heard) >= 20
    assert {(t.header.frame_id, t.child_frame_id) for t in heard[-1].transforms} == {
        (f'r{i}/odom', f'r{i}/base_footprint') for i in (1, 2, 3)}


@pytest.mark.parametrize('params, words', [
    ({'robots': ['a', 'a', 'b']}, "parameter 'robots' names a more than once"),
    ({'robots': ['a', '2b']}, "parameter 'robots' holds '2b'"),
    ({'robots': ['/a']}, "parameter 'robots' holds '/a'"),
    ({'robots': ['a', 'b'], 'initial_poses': [0.0, 0.0, 0.0]},
     "parameter 'initial_poses' must hold x, y, yaw for each of the 2 robot(s), 6 values; "
     'got 3'),
    ({'robots': [1, 2]}, "parameter 'robots' must be a list of strings"),
])
def test_bad_robots_are_refused_by_name(ros_context, params, words):
    overrides = [Parameter(name, value=value) for name, value in params.items()]
    with pytest.raises(ParameterError) as error:
        UnicycleSim(context=ros_context, parameter_overrides=overrides)
    assert words in str(error.value)


def test_a_live_cmd_vel_timeout_counts_for_every_robot_from_its_own_last_command(graph):
    sim = graph.sim(robots=['early', 'late'], cmd_vel_timeout=0.5)
    drivers = {name: graph.probe(f'{name}_driver', namespace=name) for name in ('early', 'late')}
    graph.step()
    drivers['early'].send(1.0, 0.0)  # at 0.02 s
    graph.step_for(0.2)
    drivers['late'].send(1.0, 0.0)  # at 0.22 s
    graph.step()
    assert sim.set_parameters([Parameter('cmd_vel_timeout', value=1.0)])[0].successful
    graph.step_for(2.0)
    # Each stopped 1.0 s after its own last command: 1.0 m driven, whatever the other did.
    for name in ('early', 'late'):
        assert graph.pose(name) == pytest.approx((1.0, 0.0, 0.0), abs=1e-12), name
    stops = {name: next(o for o in graph.listener(name).odoms if o.twist.twist.linear.x == 0.0
                        and pose_of(o)[0] > 0.5).header.stamp.nanosec
             for name in ('early', 'late')}
    assert stops == {'early': 20_000_000, 'late': 220_000_000}  # at 1.02 s and 1.22 s


def test_two_controllers_on_one_robot_of_a_fleet_are_warned_about_once_and_again_after_one_left(
        fast_graph, capfd):
    # DDS tells the simulator when a publisher on a robot's cmd_vel comes or goes (the
    # subscription's matched event): no graph query per robot, no step needed for it.
    graph = fast_graph
    sim = graph.sim(robots=ROBOTS[:3])
    robot = sim.robots[2]
    log = []

    def warnings():
        log.append(capfd.readouterr().err)
        return ''.join(log).count('nodes publish on')
    names = ('controller_a', 'controller_b')
    controllers = [graph.probe(name, namespace='/robot2') for name in names]
    assert graph.spin_until(lambda: warnings() == 1, 10.0), log
    graph.step_for(1.1)
    assert warnings() == 1, log
    assert '2 nodes publish on /robot2/cmd_vel' in ''.join(log), log
    assert [r.cmd_publishers for r in sim.robots] == [0, 0, 2]
    graph.remove(controllers.pop())
    assert graph.spin_until(lambda: robot.cmd_publishers == 1, 10.0)
    graph.step_for(0.5)
    assert warnings() == 1, log
    graph.probe('controller_c', namespace='/robot2')
    assert graph.spin_until(lambda: warnings() == 2, 10.0), log
