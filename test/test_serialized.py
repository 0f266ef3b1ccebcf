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
The simulator's messages as CDR bytes: written and read with numpy and struct, as rclpy would.

Odometry for many robots, with frame names of every length modulo 8 (CDR aligns what follows
a string), decodes with rclpy to exactly the message built field by field; so does every
robot's odometry heard over DDS from a simulator in a namespace, before and after its frames
and covariances change live.  Commands read from their bytes equal rclpy's deserialize bit for
bit (NaN, infinities and -0.0 included), in both byte orders; bytes in an encapsulation the
reader does not know go through rclpy, and bytes that decode as nothing are refused with a
warning while the robot keeps its last command.  The lockstep's message counter reads the stamps
of bytes it sees published and handled as it reads those of message objects.
"""

import math
import random
import struct
import time

from geometry_msgs.msg import Twist
from geometry_msgs.msg import TwistStamped
from motion_challenges.robot_watch import OdomPose
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock as ClockMsg
from sim_diffdrive.cdr import clock_message
from sim_diffdrive.cdr import covariance
from sim_diffdrive.cdr import header_stamp_ns
from sim_diffdrive.cdr import OdometryLayout
from sim_diffdrive.cdr import read_odometry
from sim_diffdrive.cdr import read_twist
from sim_diffdrive.cdr import read_twist_stamped
from sim_diffdrive.cdr import UnsupportedEncoding
from sim_diffdrive.lockstep.counter import MessageCounter
from sim_diffdrive.sim.node import UnicycleSim

NS = 1_000_000_000
SPECIAL = (math.nan, math.inf, -math.inf, -0.0, 0.0, 5e-324, -1.7976931348623157e308, 1e4)


def expected_odometry(stamp_ns, frames, covariances, x, y, qz, qw, linear, angular):
    """Return the Odometry the simulator means, built field by field."""
    msg = Odometry()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, NS)
    msg.header.frame_id, msg.child_frame_id = frames
    pose, twist = msg.pose.pose, msg.twist.twist
    pose.position.x, pose.position.y = x, y
    pose.orientation.z, pose.orientation.w = qz, qw
    twist.linear.x, twist.angular.z = linear, angular
    msg.pose.covariance, msg.twist.covariance = covariances
    return msg


def random_frame(rng, length):
    return ''.join(rng.choice('abcxyz_/019') for _ in range(length))


# -- pure: the layouts and the readers ---------------------------------------------------------

def test_every_robots_odometry_bytes_decode_to_the_message_field_by_field():
    rng = random.Random(19)
    # Every pair of string lengths modulo 8, and some long ones.
    frames = [(random_frame(rng, a), random_frame(rng, b)) for a in range(8) for b in range(8)]
    frames += [(random_frame(rng, 40 + i), random_frame(rng, 3 * i)) for i in range(8)]
    covariances = (covariance([rng.uniform(0, 1e3) for _ in range(6)]),
                   covariance([rng.uniform(0, 1e-3) for _ in range(6)]))
    layout = OdometryLayout(frames, *covariances)
    assert len(layout) == len(frames)
    for stamp_ns in (0, 1, 1_795_515_697_795_092_236, 2 ** 31 * NS - 1):
        values = [np.array([rng.uniform(-1e6, 1e6) for _ in frames]) for _ in range(6)]
        sec, nanosec = divmod(stamp_ns, NS)
        messages = layout.serialize(sec, nanosec, *values)
        assert len(messages) == len(frames)
        # From floats (a simulator of a few robots): the same bytes.
        assert layout.serialize(sec, nanosec, *(v.tolist() for v in values)) == messages
        for i, (data, pair) in enumerate(zip(messages, frames)):
            expected = expected_odometry(stamp_ns, pair, covariances,
                                         *(float(v[i]) for v in values))
            assert deserialize_message(data, Odometry) == expected, (i, pair)
            assert len(data) == len(serialize_message(expected))
            assert read_odometry(data) == (stamp_ns, *pair, (values[0][i], values[1][i], 0.0),
                                           (0.0, 0.0, values[2][i], values[3][i]),
                                           (values[4][i], values[5][i]))
            assert header_stamp_ns(data) == stamp_ns


def test_clock_bytes_equal_rclpys_serialized_clock():
    for stamp_ns in (0, 1, NS - 1, NS, 20_000_000 * 7, 1_795_515_697_795_092_236,
                     2 ** 31 * NS - 1):
        msg = ClockMsg()
        msg.clock.sec, msg.clock.nanosec = divmod(stamp_ns, NS)
        assert clock_message(stamp_ns) == serialize_message(msg)
        assert deserialize_message(clock_message(stamp_ns), ClockMsg) == msg


def test_an_odometry_layout_without_robots_is_empty():
    assert OdometryLayout([], covariance([0] * 6), covariance([0] * 6)).serialize(
        1, 2, *[np.zeros(0)] * 6) == []


def random_twist(rng):
    msg = Twist()
    for vector in (msg.linear, msg.angular):
        vector.x, vector.y, vector.z = (rng.choice(SPECIAL) if rng.random() < 0.2
                                        else rng.uniform(-1e5, 1e5) for _ in range(3))
    return msg


def bits(*values):
    """Return values as their IEEE 754 bits, so NaN equals NaN and -0.0 differs from 0.0."""
    return struct.pack(f'<{len(values)}d', *values)


def random_header(rng, msg, frame_length):
    """Give msg's header any stamp and a random frame_id of frame_length characters."""
    msg.header.stamp.sec = rng.randint(-2 ** 31, 2 ** 31 - 1)
    msg.header.stamp.nanosec = rng.randint(0, NS - 1)
    msg.header.frame_id = random_frame(rng, frame_length)
    return msg


def test_commands_read_from_their_bytes_equal_rclpys_deserialize():
    rng = random.Random(7)
    for _ in range(500):
        msg = random_twist(rng)
        decoded = deserialize_message(serialize_message(msg), Twist)
        assert bits(*read_twist(serialize_message(msg))) == bits(decoded.linear.x,
                                                                 decoded.angular.z)
    for length in range(21):
        for _ in range(20):
            msg = random_header(rng, TwistStamped(), length)
            msg.twist = random_twist(rng)
            data = serialize_message(msg)
            decoded = deserialize_message(data, TwistStamped)
            stamp_ns, linear, angular = read_twist_stamped(data)
            assert stamp_ns == decoded.header.stamp.sec * NS + decoded.header.stamp.nanosec
            assert stamp_ns == header_stamp_ns(data)
            assert bits(linear, angular) == bits(decoded.twist.linear.x,
                                                 decoded.twist.angular.z)


def test_odometry_read_from_any_publishers_bytes_equals_rclpys_deserialize():
    # A motion reads its odometry from the bytes (odometry.OdomPose): frames of every length
    # (so every alignment of the doubles after them), any numbers, as any publisher sends them.
    rng = random.Random(11)
    for length in range(21):
        for _ in range(10):
            msg = random_header(rng, Odometry(), length)
            msg.child_frame_id = random_frame(rng, rng.randint(0, 20))
            p, q = msg.pose.pose.position, msg.pose.pose.orientation
            p.x, p.y, p.z, q.x, q.y, q.z, q.w = (rng.uniform(-1e5, 1e5) for _ in range(7))
            msg.twist.twist = random_twist(rng)
            msg.pose.covariance = [rng.uniform(-1, 1) for _ in range(36)]
            data = serialize_message(msg)
            d = deserialize_message(data, Odometry)
            stamp_ns, frame, child, position, orientation, twist = read_odometry(data)
            assert stamp_ns == d.header.stamp.sec * NS + d.header.stamp.nanosec
            assert (frame, child) == (d.header.frame_id, d.child_frame_id)
            p, q = d.pose.pose.position, d.pose.pose.orientation
            assert bits(*position, *orientation) == bits(p.x, p.y, p.z, q.x, q.y, q.z, q.w)
            assert bits(*twist) == bits(d.twist.twist.linear.x, d.twist.twist.angular.z)


def test_a_motion_reads_odometry_in_another_encapsulation_through_rclpy():
    # XCDR2 (encapsulation 00 07) aligns doubles to 4, not 8; with these frames the pose starts
    # at a multiple of 8 either way, so the same body is valid in both.
    msg = Odometry()
    msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 345
    msg.header.frame_id, msg.child_frame_id = 'odom', 'chassis'
    msg.pose.pose.position.x, msg.pose.pose.position.y = 1.5, -2.5
    msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = math.sin(0.3), math.cos(0.3)
    msg.twist.twist.linear.x, msg.twist.twist.angular.z = 0.25, -0.75
    data = bytearray(serialize_message(msg))
    data[1] = 7
    with pytest.raises(UnsupportedEncoding):
        read_odometry(bytes(data))
    pose = OdomPose(bytes(data))
    assert (pose.x, pose.y, pose.stamp_ns, pose.twist) == (1.5, -2.5, 12 * NS + 345, (0.25, -0.75))
    assert pose.yaw == pytest.approx(0.6, abs=1e-15)
    assert vars(OdomPose(serialize_message(msg))) == vars(pose)


def test_big_endian_commands_are_read_too():
    # What a big-endian machine sends: encapsulation 00 00, every number big endian.
    twist = struct.pack('>4x6d', 0.25, 1.0, 2.0, 3.0, 4.0, -0.5)
    assert read_twist(twist) == (0.25, -0.5)
    frame = b'base_link\0'
    stamped = (struct.pack('>4xiII', -3, 999, len(frame)) + frame + bytes(2)
               + struct.pack('>6d', 1.5, 9.0, 9.0, 9.0, 9.0, 2.5))
    assert read_twist_stamped(stamped) == (-3 * NS + 999, 1.5, 2.5)
    assert header_stamp_ns(stamped) == -3 * NS + 999
    odom = (struct.pack('>4xiII', 7, 5, len(frame)) + frame + bytes(2)
            + struct.pack('>I', 2) + b'b\0' + bytes(2) + struct.pack('>7d', *range(1, 8))
            + bytes(8 * 36) + struct.pack('>6d', 0.75, 9.0, 9.0, 9.0, 9.0, -1.25))
    assert read_odometry(odom) == (7 * NS + 5, 'base_link', 'b', (1.0, 2.0, 3.0),
                                   (4.0, 5.0, 6.0, 7.0), (0.75, -1.25))


def test_bytes_in_another_encoding_or_too_short_are_not_taken_for_a_command():
    data = bytearray(serialize_message(Twist()))
    data[1] = 7  # XCDR2, little endian
    with pytest.raises(UnsupportedEncoding):
        read_twist(bytes(data))
    with pytest.raises(UnsupportedEncoding):
        read_twist(b'\x00')
    with pytest.raises(struct.error):
        read_twist(serialize_message(Twist())[:30])
    stamped = serialize_message(TwistStamped())
    with pytest.raises(struct.error):
        read_twist_stamped(stamped[:-1])


# -- the simulator: what a user hears and what it follows ----------------------------------------

ROBOTS = ['a', 'bb', 'ccc', 'robot_4', 'team/r5', 'rob_six', 'seven_7', 'eight_88', 'n9']


def namespaced_sim(graph, namespace, **params):
    params = {'publish_clock': True, 'lockstep': False, 'real_time_factor': 10.0, **params}
    sim = UnicycleSim(stepped=True, namespace=namespace, context=graph.context,
                      parameter_overrides=[Parameter(name, value=value)
                                           for name, value in params.items()])
    return graph.add_clock_owner(sim)


def assert_heard_is_the_simulators_state(sim, listeners, frames, diagonals):
    fleet = sim.world
    stamp_ns = sim.now_ns()
    covariances = tuple(covariance(d) for d in diagonals)
    for i, (listener, pair) in enumerate(zip(listeners, frames)):
        yaw = float(fleet.yaw[i])
        expected = expected_odometry(
            stamp_ns, pair, covariances, float(fleet.x[i]), float(fleet.y[i]),
            math.sin(yaw / 2), math.cos(yaw / 2), float(fleet.linear[i]),
            float(fleet.angular[i]))
        assert listener.odom == expected, ROBOTS[i]


def test_every_robot_hears_its_odometry_as_the_simulator_means_it_before_and_after_changes(
        graph):
    diagonals = ([0.1, 0.2, 0.3, 0.4, 0.5, 0.6], [1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    sim = namespaced_sim(graph, '/fleet', robots=ROBOTS, cmd_vel_timeout=0.0,
                         initial_poses=[v for i in range(len(ROBOTS))
                                        for v in (i * 1.5, -0.25 * i, 0.3 * i)],
                         pose_covariance_diagonal=diagonals[0],
                         twist_covariance_diagonal=diagonals[1])
    listeners = [graph.probe(f'listener_{i}', namespace=f'/fleet/{name}', listen_only=True)
                 for i, name in enumerate(ROBOTS)]
    drivers = [graph.probe(f'driver_{i}', namespace=f'/fleet/{name}')
               for i, name in enumerate(ROBOTS)]
    graph.wait_for_discovery()
    for i, driver in enumerate(drivers):
        driver.send(0.1 * (i + 1), 0.7 - 0.2 * i)
    graph.step(10)
    frames = [(f'{name}/fleet/odom', f'{name}/fleet/base_footprint') for name in ROBOTS]
    assert_heard_is_the_simulators_state(sim, listeners, frames, diagonals)
    assert all(listener.odom.twist.twist.linear.x == pytest.approx(0.1 * (i + 1))
               for i, listener in enumerate(listeners))

    # Frames of other lengths and new covariances, live: the next odometry carries them.
    diagonals = ([9.0, 8.0, 7.0, 6.0, 5.0, 4.0], [0.5] * 6)
    changes = {'odom_frame_id': 'map', 'base_frame_id': 'base_link_x',
               'pose_covariance_diagonal': diagonals[0],
               'twist_covariance_diagonal': diagonals[1]}
    results = sim.set_parameters([Parameter(name, value=value)
                                  for name, value in changes.items()])
    assert all(result.successful for result in results)
    graph.step(3)
    frames = [(f'{name}/map', f'{name}/base_link_x') for name in ROBOTS]
    assert_heard_is_the_simulators_state(sim, listeners, frames, diagonals)
    assert sim.robots[0].frames == frames[0]


def test_a_command_in_another_encapsulation_is_followed_and_garbage_refused(graph, capfd):
    sim = graph.sim(cmd_vel_timeout=0.0)
    driver = graph.probe('driver')
    graph.wait_for_discovery()
    driver.send(0.2, 0.1)
    graph.step(2)
    assert (sim.world.linear[0], sim.world.angular[0]) == (0.2, 0.1)

    # XCDR2 (encapsulation 00 07): the reader does not know it, rclpy decodes it.
    msg = Twist()
    msg.linear.x, msg.angular.z = 0.4, -0.3
    data = bytearray(serialize_message(msg))
    data[1] = 7
    driver.cmd_pub.publish(bytes(data))
    graph.step(2)
    assert (sim.world.linear[0], sim.world.angular[0]) == (0.4, -0.3)

    # Too short to hold a Twist: refused, the robot keeps its last command.
    driver.cmd_pub.publish(serialize_message(msg)[:20])
    graph.step(2)
    assert (sim.world.linear[0], sim.world.angular[0]) == (0.4, -0.3)
    assert graph.odom().twist.twist.linear.x == 0.4
    assert 'Refusing cmd_vel that does not decode as Twist' in capfd.readouterr().err


def test_the_lockstep_counts_the_stamps_of_bytes_as_of_messages(ros_context):
    # The lockstep waits until every participant has heard the newest stamp sent on a stamped
    # topic: a stamp missed in bytes would let a step go on before its odometry was heard.
    node = Node('counted', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    try:
        heard = []
        node.create_subscription(TwistStamped, 'cmd', heard.append, 10, raw=True)
        stamped = node.create_publisher(TwistStamped, 'cmd', 10)
        odom = node.create_publisher(Odometry, 'odom', 10)
        plain = node.create_publisher(Twist, 'plain', 10)
        counter = MessageCounter.of(node, '/clock')
        executor.add_node(node)
        deadline = time.monotonic() + 10.0
        while stamped.get_subscription_count() == 0 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.01)
        layout = OdometryLayout([('odom', 'base_footprint')], *[covariance([0] * 6)] * 2)
        odom.publish(layout.serialize(12, 345, *[np.zeros(1)] * 6)[0])
        assert counter.sent_stamp['/odom'] == 12 * NS + 345
        odom.publish(expected_odometry(11 * NS, ('o', 'b'), [[0.0] * 36] * 2, *[0.0] * 6))
        assert counter.sent_stamp['/odom'] == 12 * NS + 345  # the highest is kept
        plain.publish(serialize_message(Twist()))
        assert counter.sent['/plain'] == 1 and '/plain' not in counter.sent_stamp
        for sec, frame in ((7, 'a'), (9, 'frame_of_odd_length'), (8, '')):
            msg = TwistStamped()
            msg.header.stamp.sec, msg.header.stamp.nanosec = sec, 5
            msg.header.frame_id = frame
            stamped.publish(serialize_message(msg) if sec % 2 else msg)
        assert counter.sent_stamp['/cmd'] == 9 * NS + 5
        while len(heard) < 3 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
        assert all(isinstance(data, bytes) for data in heard) and len(heard) == 3
        assert counter.heard['/cmd'] == 3 and counter.heard_stamp['/cmd'] == 9 * NS + 5
    finally:
        executor.shutdown()
        node.destroy_node()
