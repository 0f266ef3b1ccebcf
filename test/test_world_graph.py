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
``unicycle_sim`` with ``map_file`` in one process: walls, scans, map -> odom, by closed forms.

The example room (maps/room.yaml): walls along its borders, the inner faces at x = -0.45 and
3.45, y = -0.45 and 2.45, and an inner wall x 2.00 .. 2.10, y 0.00 .. 1.80.  Every expected
value is worked out here from those faces, independently of the simulator's geometry.
"""

import math
from pathlib import Path
import signal

from geometry_msgs.msg import PoseWithCovarianceStamped
from geometry_msgs.msg import Twist
from motion_challenges.odom_out_and_back import OdomOutAndBack
from nav_msgs.msg import OccupancyGrid
import numpy as np
import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import LaserScan
from sim_diffdrive.angles import quaternion_from_yaw
from sim_diffdrive.harness import SimGraph
from sim_diffdrive.harness import twist_of
from sim_diffdrive.lockstep.participant import take_part
from sim_diffdrive.parameters import ParameterError
from sim_diffdrive.sim.node import main as sim_main
from sim_diffdrive.sim.node import UnicycleSim
from sim_diffdrive.sim.surroundings import LATCHED_QOS
from std_srvs.srv import Empty
from tf2_msgs.msg import TFMessage

ROOM = str(Path(__file__).resolve().parents[1] / 'maps' / 'room.yaml')
RADIUS = 0.105
# The room's walls as boxes (x0, x1, y0, y1) in the map frame.
WALLS = [(-0.5, -0.45, -0.5, 2.5), (3.45, 3.5, -0.5, 2.5), (-0.5, 3.5, -0.5, -0.45),
         (-0.5, 3.5, 2.45, 2.5), (2.0, 2.1, 0.0, 1.8)]


def ray_to_box(x, y, heading, box):
    """Return the distance along the ray from (x, y) to the box (slab method), or inf."""
    x0, x1, y0, y1 = box
    near, far = 0.0, math.inf
    for origin, direction, low, high in ((x, math.cos(heading), x0, x1),
                                         (y, math.sin(heading), y0, y1)):
        if abs(direction) < 1e-15:
            if not low <= origin <= high:
                return math.inf
            continue
        t0, t1 = sorted(((low - origin) / direction, (high - origin) / direction))
        near, far = max(near, t0), min(far, t1)
    return near if near <= far else math.inf


def expected_ranges(x, y, yaw, beams=360, range_max=3.5):
    ranges = []
    for k in range(beams):
        heading = yaw - math.pi + k * 2.0 * math.pi / beams
        r = min(ray_to_box(x, y, heading, box) for box in WALLS)
        ranges.append(r if r <= range_max else math.inf)
    return ranges


def assert_scan_is(scan, expected):
    """Each range as float32 is the exact distance within one float32 step."""
    ranges = np.array(scan.ranges, dtype=np.float64)
    exact = np.array(expected)
    finite = np.isfinite(exact)
    assert (np.isinf(ranges) == ~finite).all()
    step = np.spacing(exact[finite].astype(np.float32)).astype(np.float64)
    assert (np.abs(ranges[finite] - exact[finite]) <= step).all(), (
        np.abs(ranges[finite] - exact[finite]).max())


def pose_estimate(frame, x, y, yaw):
    msg = PoseWithCovarianceStamped()
    msg.header.frame_id = frame
    msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
    q = msg.pose.pose.orientation
    q.x, q.y, q.z, q.w = quaternion_from_yaw(yaw)
    return msg


def test_the_scan_shows_the_exact_distances_to_the_walls_from_any_pose(graph):
    graph.sim(map_file=ROOM, initial_x=0.5, initial_y=0.3, initial_yaw=0.3)
    graph.step_for(0.2)
    scan = graph.scan()
    assert scan.header.frame_id == 'base_scan'
    assert (scan.angle_min, len(scan.ranges)) == (pytest.approx(-math.pi), 360)
    assert_scan_is(scan, expected_ranges(0.5, 0.3, 0.3))


def test_a_robot_driven_into_a_wall_stops_at_contact_and_drives_away_again(graph, capfd):
    graph.sim(map_file=ROOM, initial_x=0.5, initial_y=0.3, cmd_vel_timeout=0.0)
    probe = graph.probe()
    probe.send(0.5, 0.0)
    graph.step_for(5.0)
    x, y, yaw = graph.pose()
    assert x == pytest.approx(2.0 - RADIUS, abs=1e-9) and (y, yaw) == (0.3, 0.0)
    assert twist_of(graph.odom()) == (0.0, 0.0)
    probe.send(0.5, 0.0)  # into the wall again: it stays
    graph.step_for(0.5)
    assert graph.pose()[0] == pytest.approx(2.0 - RADIUS, abs=1e-9)
    probe.send(-0.3, 0.0)
    graph.step_for(1.0)
    assert graph.pose()[0] == pytest.approx(2.0 - RADIUS - 0.3, abs=1e-9)
    warnings = [line for line in capfd.readouterr().err.splitlines() if 'Hit a wall' in line]
    assert len(warnings) == 1 and '(1.895, 0.300) in map' in warnings[0]


def test_a_closed_loop_driven_into_a_wall_fails_and_leaves_the_robot_stopped(graph, capfd):
    # 3 m out from x = 0.5: the inner wall's face is at x = 2.0.  The motion's odometry stands
    # still at contact while it still commands 0.2 m/s: a second later it gives up.
    graph.sim(map_file=ROOM, initial_x=0.5, initial_y=0.3)
    motion = graph.node(OdomOutAndBack, legs=1, goal_distance=3.0)
    graph.step_until(lambda: motion.done, 20.0)
    graph.step_for(0.1)
    assert motion.exit_code == 1
    assert graph.pose()[0] == pytest.approx(2.0 - RADIUS, abs=1e-9)
    assert twist_of(graph.odom()) == (0.0, 0.0)
    errors = [line for line in capfd.readouterr().err.splitlines() if '[ERROR]' in line]
    assert len(errors) == 1 and 'The robot has stood still at (1.895, 0.300) for 1.0 s' in \
        errors[0] and 'against a wall or another robot?' in errors[0], errors


def test_a_robot_on_an_arc_stops_where_its_arc_meets_the_wall(graph):
    graph.sim(map_file=ROOM, initial_x=0.5, initial_y=1.0, cmd_vel_timeout=0.0)
    probe = graph.probe()
    probe.send(0.5, 0.2)  # a circle of radius 2.5 about (0.5, 3.5)
    graph.step_for(5.0)
    x, y, yaw = graph.pose()
    turned = math.asin((2.0 - RADIUS - 0.5) / 2.5)  # where the centre is RADIUS from x = 2.0
    assert x == pytest.approx(2.0 - RADIUS, abs=1e-9)
    assert y == pytest.approx(3.5 - 2.5 * math.cos(turned), abs=1e-9)
    assert yaw == pytest.approx(turned, abs=1e-9)
    assert twist_of(graph.odom()) == (0.0, 0.0)


def test_two_robots_see_each_other_and_stop_on_contact(graph, capfd):
    graph.sim(map_file=ROOM, robots=['a', 'b'], cmd_vel_timeout=0.0,
              initial_poses=[0.3, 1.0, 0.0, 1.3, 1.0, math.pi])
    graph.step_for(0.2)
    # Beam 180 looks along the heading: the other robot's disc, 1.0 - RADIUS away.
    assert graph.scan('a').ranges[180] == pytest.approx(1.0 - RADIUS, abs=1e-6)
    assert graph.scan('b').ranges[180] == pytest.approx(1.0 - RADIUS, abs=1e-6)
    probe = graph.probe(namespace='a')
    graph.probe(name='b_driver', namespace='b').send(0.0, 0.1)  # b turns on the spot
    probe.send(0.2, 0.0)
    graph.step_for(5.0)
    assert graph.pose('a')[0] == pytest.approx(1.3 - 2 * RADIUS, abs=1e-6)
    assert graph.pose('b')[0] == 1.3
    assert twist_of(graph.odom('a')) == twist_of(graph.odom('b')) == (0.0, 0.0)
    err = capfd.readouterr().err  # who drove into whom: b only turned
    assert 'a: Ran into b at (1.090, 1.000) in map: stopped' in err
    assert 'b: Was run into by a at (1.300, 1.000) in map: stopped' in err


def test_a_robot_started_outside_the_map_is_warned_about(graph, capfd):
    # A wrong origin in a map's YAML is the classic mistake: nothing stops or scans out there.
    graph.sim(map_file=ROOM, robots=['a', 'b'], initial_poses=[0.5, 0.3, 0.0, 1.0, -10.0, 0.0])
    err = capfd.readouterr().err
    assert ('b: Starts at (1.000, -10.000) in map, outside the map (80 x 60 cells from its '
            'origin): no wall or scan return out there') in err
    assert 'a: Starts' not in err
    # Set there by an initialpose, as RViz's 2D Pose Estimate does: the same word.
    rviz = graph.add(Node('rviz', context=graph.context))
    rviz.create_publisher(PoseWithCovarianceStamped, 'a/initialpose', 10).publish(
        pose_estimate('map', 10.0, 10.0, 0.0))
    graph.step_for(0.1)
    assert ('a: Set to (10.000, 10.000) in the map, outside the map (80 x 60 cells from its '
            'origin): no wall or scan return out there') in capfd.readouterr().err


def test_initialpose_in_the_map_moves_map_to_odom_and_keeps_odometry_continuous(graph):
    graph.sim(map_file=ROOM, initial_x=0.5, initial_y=0.3)
    rviz = graph.add(Node('rviz', context=graph.context))
    publisher = rviz.create_publisher(PoseWithCovarianceStamped, 'initialpose', 10)
    transforms = {}
    rviz.create_subscription(TFMessage, '/tf', lambda msg: transforms.update(
        {(t.header.frame_id, t.child_frame_id): t for t in msg.transforms}), 100)
    graph.step_for(0.2)
    publisher.publish(pose_estimate('map', 1.0, 2.0, math.pi / 2))
    graph.step_for(0.5)
    assert graph.pose() == (0.5, 0.3, 0.0)  # odometry goes on where it was
    assert_scan_is(graph.scan(), expected_ranges(1.0, 2.0, math.pi / 2))
    map_odom = transforms[('map', 'odom')].transform
    # map -> odom turns the odometry pose (0.5, 0.3, 0) into the map pose (1, 2, pi/2).
    assert map_odom.translation.x == pytest.approx(1.0 + 0.3, abs=1e-12)
    assert map_odom.translation.y == pytest.approx(2.0 - 0.5, abs=1e-12)
    assert map_odom.rotation.z == pytest.approx(math.sin(math.pi / 4), abs=1e-12)


def test_the_tf_chain_runs_from_the_map_to_each_robots_scanner(graph):
    graph.sim(map_file=ROOM, robots=['r1', 'r2'], initial_poses=[0.0, 0.0, 0.0, 1.0, 1.0, 0.0])
    listener = graph.add(Node('listener', context=graph.context))
    edges = set()
    for topic, qos in (('/tf', 100), ('/tf_static', LATCHED_QOS)):
        listener.create_subscription(TFMessage, topic, lambda msg: edges.update(
            (t.header.frame_id, t.child_frame_id) for t in msg.transforms), qos)
    graph.step_for(0.2)
    # The static transforms were sent before this listener came: they arrive on discovery.
    graph.spin_until(lambda: ('r2/base_footprint', 'r2/base_scan') in edges, timeout=10.0)
    for robot in ('r1', 'r2'):
        for edge in (('map', f'{robot}/odom'), (f'{robot}/odom', f'{robot}/base_footprint'),
                     (f'{robot}/base_footprint', f'{robot}/base_scan')):
            assert edge in edges
    assert graph.scan('r1').header.frame_id == 'r1/base_scan'
    # A base frame set live gets the scanner too: the scans' frame stays in the tree.
    sim = graph.clock_owner
    assert sim.set_parameters([Parameter('base_frame_id', value='base_link')])[0].successful
    assert graph.spin_until(lambda: ('r2/base_link', 'r2/base_scan') in edges, timeout=10.0)
    graph.step()
    assert {('r1/odom', 'r1/base_link'), ('r1/base_link', 'r1/base_scan')} <= edges


def scans_with(seed, steps=0.5):
    with SimGraph() as graph:
        graph.sim(map_file=ROOM, scan_noise_std=0.01, seed=seed, initial_x=0.5,
                  initial_y=0.3)
        seen = []
        node = graph.add(Node('noise', context=graph.context))
        node.create_subscription(LaserScan, 'scan', lambda msg: seen.append(
            np.array(msg.ranges, dtype=np.float32).tobytes()), 10)
        graph.step_for(steps)
        return seen


def test_seeded_noise_repeats_bit_for_bit_and_another_seed_differs():
    first, again, other = scans_with(7), scans_with(7), scans_with(8)
    assert len(first) >= 4 and first == again
    assert first[0] != other[0]
    exact = np.array(expected_ranges(0.5, 0.3, 0.0), dtype=np.float32)
    noisy = np.frombuffer(first[0], dtype=np.float32)
    assert 0.005 < float(np.std(noisy - exact)) < 0.02  # the noise asked for


def test_a_late_subscriber_gets_the_map(graph):
    graph.sim(map_file=ROOM)
    graph.step_for(1.0)
    late = graph.add(Node('late', context=graph.context))
    maps = []
    late.create_subscription(OccupancyGrid, 'map', maps.append, LATCHED_QOS)
    graph.spin_until(lambda: maps, timeout=10.0)
    (grid,) = maps
    assert (grid.info.width, grid.info.height) == (80, 60)
    assert grid.info.resolution == np.float32(0.05)  # a float32 field
    assert grid.header.frame_id == 'map'
    assert (grid.info.origin.position.x, grid.info.origin.position.y) == (-0.5, -0.5)
    data = np.array(grid.data, dtype=np.int8).reshape(60, 80)
    assert (data[0] == 100).all() and (data[30, 1:49] == 0).all() and data[30, 50] == 100


def bad_world(ros_context, **params):
    with pytest.raises(ParameterError) as refused:
        UnicycleSim(context=ros_context, parameter_overrides=[
            Parameter(name, value=value) for name, value in params.items()])
    return str(refused.value)


def test_bad_worlds_are_refused_by_name(ros_context, tmp_path):
    assert 'map_file' in bad_world(ros_context, map_file=str(tmp_path / 'missing.yaml'))
    (tmp_path / 'no_resolution.yaml').write_text('image: room.pgm\norigin: [0, 0, 0]\n')
    assert 'resolution' in bad_world(ros_context, map_file=str(tmp_path / 'no_resolution.yaml'))
    (tmp_path / 'no_image.yaml').write_text('resolution: 0.05\norigin: [0, 0, 0]\n')
    assert 'image' in bad_world(ros_context, map_file=str(tmp_path / 'no_image.yaml'))
    (tmp_path / 'text.pgm').write_text('not an image')
    (tmp_path / 'text.yaml').write_text('image: text.pgm\nresolution: 0.05\n'
                                        'origin: [0, 0, 0]\n')
    assert 'text.pgm' in bad_world(ros_context, map_file=str(tmp_path / 'text.yaml'))
    (tmp_path / 'thresholds.yaml').write_text(
        f'image: {ROOM[:-4]}pgm\nresolution: 0.05\norigin: [0, 0, 0]\n'
        'occupied_thresh: 0.2\nfree_thresh: 0.6\n')
    assert 'thresh' in bad_world(ros_context, map_file=str(tmp_path / 'thresholds.yaml'))
    in_wall = bad_world(ros_context, map_file=ROOM, initial_x=2.05, initial_y=1.0)
    assert 'wall' in in_wall and '(2.050, 1.000)' in in_wall
    on_robot = bad_world(ros_context, map_file=ROOM, robots=['a', 'b'],
                         initial_poses=[0.0, 0.0, 0.0, 0.1, 0.0, 0.0])
    assert 'on a' in on_robot or 'on b' in on_robot
    assert 'scan_range_min' in bad_world(ros_context, map_file=ROOM, scan_range_min=3.0,
                                         scan_range_max=2.0)


def test_a_missing_map_file_ends_unicycle_sim_with_exit_2_naming_it(
        run_main, tmp_path, monkeypatch):
    # Its main() in this process, as the console script calls it (test_colcon_layout.py; a
    # process shows main()'s return is the exit code once per package, test_faults.py).
    # A relative path is from where it was started: the error says where that is.
    monkeypatch.chdir(tmp_path)
    code, output = run_main(sim_main, 'unicycle_sim', '--ros-args', '-p',
                            'map_file:=maps/nowhere.yaml')
    assert code == 2, output
    assert "[unicycle_sim]: parameter 'map_file'" in output, output  # its name, no node yet
    assert f'maps/nowhere.yaml ({tmp_path}/maps/nowhere.yaml)' in output
    assert 'Traceback' not in output


class StopBeforeTheWall(Node):
    """docs/world.md's controller, held until the test lets it go (enabled)."""

    def __init__(self, **kwargs):
        super().__init__('stop_before_the_wall', **kwargs)
        self.enabled = False
        self.scans = 0
        self.cmd_pub = self.create_publisher(Twist, 'cmd_vel', 10)
        self.create_subscription(LaserScan, 'scan', self.on_scan, 10)

    def on_scan(self, scan):
        self.scans += 1
        ahead = scan.ranges[round(-scan.angle_min / scan.angle_increment)]
        # A scan from before this node was counted can come late on a lossy link; only a
        # scan of the step the clock is at (or the next, on its way) is answered with a move.
        stamp_ns = scan.header.stamp.sec * 1_000_000_000 + scan.header.stamp.nanosec
        current = stamp_ns >= self.get_clock().now().nanoseconds
        cmd = Twist()
        if self.enabled and current and ahead > 0.5:
            cmd.linear.x = 0.3
        self.cmd_pub.publish(cmd)


def test_a_controller_in_another_process_reads_the_scan_in_lockstep_exactly(graph, procs):
    sim = procs('unicycle_sim', 'unicycle_sim', '--ros-args', '-p', f'map_file:={ROOM}',
                '-p', 'publish_clock:=true', '-p', 'real_time_factor:=20.0',
                '-p', 'initial_x:=0.5', '-p', 'initial_y:=0.3')
    controller = graph.add(StopBeforeTheWall(context=graph.context,
                                             parameter_overrides=graph.sim_time_params()))
    lockstep = take_part(controller)
    # Once counted, every scan is waited for, the first too: the simulator counts a joiner
    # only once it has heard a scan (counted before, a reply to its first scan could land a
    # step late: 1.514 m, not 1.52, in 1 run of 30).
    assert graph.spin_until(
        lambda: lockstep.joined and lockstep.counted_on(controller.cmd_pub.topic_name),
        timeout=30.0), sim.output()
    controller.enabled = True  # from a scan on: 0.03 m a scan, each command on its step
    assert graph.spin_until(lambda: graph.odom() is not None and graph.odom().header.stamp.sec
                            > 0 and twist_of(graph.odom()) == (0.3, 0.0), timeout=30.0)
    assert graph.spin_until(lambda: twist_of(graph.odom()) == (0.0, 0.0), timeout=60.0), (
        sim.output())
    x, y, yaw = graph.pose()
    assert x == pytest.approx(0.5 + 34 * 0.03, abs=1e-9) and (y, yaw) == (0.3, 0.0), (
        sim.output())
    lockstep.leave()
    sim.send(signal.SIGINT)
    assert sim.wait(10.0) == 0
    assert f'in the map {ROOM} (80 x 60 cells of 0.05 m), scans at 10 Hz' in sim.output()
    assert 'Traceback' not in sim.output()


def test_an_initialpose_into_a_wall_is_refused_and_the_robot_stays(graph, capfd):
    graph.sim(map_file=ROOM, initial_x=0.5, initial_y=0.3)
    rviz = graph.add(Node('rviz', context=graph.context))
    publisher = rviz.create_publisher(PoseWithCovarianceStamped, 'initialpose', 10)
    graph.step_for(0.2)
    publisher.publish(pose_estimate('map', 2.05, 1.0, 0.0))  # inside the inner wall
    publisher.publish(pose_estimate('odom', 0.0, -0.4, 0.0))  # 0.05 m from the bottom wall
    graph.step_for(0.3)
    assert graph.pose() == (0.5, 0.3, 0.0)
    refused = [line for line in capfd.readouterr().err.splitlines()
               if 'Refusing initialpose' in line]
    assert len(refused) == 2 and all('inside a wall' in line for line in refused)
    assert '(2.050, 1.000)' in refused[0] and '(0.000, -0.400)' in refused[1]


def test_a_reset_into_a_wall_is_refused_and_the_robot_stays(graph, capfd):
    sim = graph.sim(map_file=ROOM, initial_x=0.5, initial_y=0.3)
    client = graph.add(Node('resetter', context=graph.context)).create_client(
        Empty, '/unicycle_sim/reset')
    graph.step_for(0.2)
    assert sim.set_parameters([Parameter('initial_x', value=2.05)])[0].successful
    future = client.call_async(Empty.Request())
    graph.spin_until(future.done, timeout=10.0)
    graph.step_for(0.2)
    assert graph.pose() == (0.5, 0.3, 0.0)
    err = capfd.readouterr().err
    assert 'Refusing ~/reset: the robot at (2.050, 0.300) in the map would be inside a wall' in err
    assert 'Reset to the initial pose' not in err


def test_a_reset_puts_every_robot_back_though_one_stands_on_anothers_start(graph, capfd):
    sim = graph.sim(map_file=ROOM, robots=['robot1', 'robot2'],
                    initial_poses=[0.5, 0.3, 0.0, 1.0, 0.3, 0.0])
    rviz = graph.add(Node('rviz', context=graph.context))
    publishers = [rviz.create_publisher(PoseWithCovarianceStamped, f'/{name}/initialpose', 10)
                  for name in ('robot1', 'robot2')]
    client = rviz.create_client(Empty, '/unicycle_sim/reset')
    graph.step_for(0.2)
    publishers[0].publish(pose_estimate('map', 0.5, 1.5, 0.0))
    graph.step_for(0.1)
    publishers[1].publish(pose_estimate('map', 0.5, 0.35, 0.0))  # on robot1's start
    graph.step_for(0.1)

    def in_map():
        return [(float(x), float(y)) for x, y in zip(*sim.world.map_poses()[:2])]
    assert in_map() == [(0.5, 1.5), (0.5, 0.35)]
    assert graph.spin_until(client.call_async(Empty.Request()).done, timeout=10.0)
    graph.step_for(0.1)
    # At the start again: in the map (map -> odom the identity) and in odometry.
    assert in_map() == [(0.5, 0.3), (1.0, 0.3)]
    assert [graph.pose(name) for name in ('robot1', 'robot2')] == [(0.5, 0.3, 0.0),
                                                                   (1.0, 0.3, 0.0)]
    err = capfd.readouterr().err
    assert 'Reset every robot to its initial pose' in err and 'Refusing' not in err


def test_a_scan_rate_between_whole_steps_is_the_nearest_and_said(graph, capfd):
    graph.sim(map_file=ROOM, initial_x=0.5, initial_y=0.3, scan_rate_hz=30.0)
    graph.step_for(0.2)
    first = graph.scan().header.stamp
    graph.step(2)
    second = graph.scan().header.stamp
    assert (second.sec, second.nanosec - first.nanosec) == (first.sec, 40_000_000)
    assert graph.scan().scan_time == pytest.approx(0.04, abs=1e-9)  # a float32
    err = capfd.readouterr().err
    assert ('scan_rate_hz 30 is not rate_hz 50 over a whole number of steps: a scan every 2 '
            'step(s), at 25 Hz') in err
    assert 'scans at 25 Hz' in err


def test_map_to_odom_can_be_left_to_a_localization(graph):
    # AMCL publishes map -> odom itself: two publishers of one transform fight in tf2.
    graph.sim(map_file=ROOM, initial_x=0.5, initial_y=0.3, publish_map_odom_tf=False)
    listener = graph.add(Node('listener', context=graph.context))
    edges = set()
    listener.create_subscription(TFMessage, '/tf', lambda msg: edges.update(
        (t.header.frame_id, t.child_frame_id) for t in msg.transforms), 100)
    graph.step_for(0.2)
    assert edges == {('odom', 'base_footprint')}
    assert graph.scan() is not None  # the rest of the world as before
