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
What a SimGraph step waits for as nodes come and go: the clock owner's ledger, in process.

Each step ends once every message sent in the graph has been handled; these tests pin the
cases where that needs care: a node added or removed mid-run, a burst of messages stamped
alike, a command from a node outside the graph.
"""

import math
import time

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from sim_diffdrive.lockstep.handshake import Answer
from test_sim_graph import assert_pose
from test_sim_graph import command
from test_sim_graph import settle
from test_sim_graph import stamp_ns

NS = 1_000_000_000


def sim_time_node(graph, name):
    return graph.add(Node(name, context=graph.context, parameter_overrides=[
        Parameter('use_sim_time', value=True)]))


def test_a_node_added_to_a_running_graph_is_waited_for_from_its_first_step(graph):
    graph.sim()
    graph.step_for(0.1)
    late = graph.probe('late', listen_only=True)
    for _ in range(3):
        graph.step()
        assert stamp_ns(late.odom) == graph.now_ns


def test_each_message_of_a_burst_stamped_alike_is_handled_before_the_graph_settles(graph):
    graph.sim()
    probe = graph.probe(listen_only=True)
    burst = sim_time_node(graph, 'burst').create_publisher(Odometry, 'odom', 10)
    graph.step_for(0.1)
    seen = len(probe.odoms)
    msg = Odometry()
    msg.header.stamp = probe.odom.header.stamp  # the stamp of what the probe has heard
    for _ in range(5):
        burst.publish(msg)
    settle(graph)
    assert len(probe.odoms) == seen + 5


def test_a_removed_node_is_not_waited_for_what_it_never_handled(graph):
    graph.sim()
    chatter = sim_time_node(graph, 'talker').create_publisher(Twist, 'chatter', 10)
    listener = sim_time_node(graph, 'listener')
    listener.create_subscription(Twist, 'chatter', lambda msg: None, 10)
    graph.step_for(0.1)
    chatter.publish(Twist())  # on its way to the listener, which is removed before it spins
    graph.remove(listener)
    graph.step_for(0.1)
    assert graph.now_ns == 2 * NS // 10


def test_a_command_sent_after_a_controller_was_removed_lands_on_its_step(graph):
    graph.sim(cmd_vel_timeout=0.0)
    first, second = graph.probe('first'), graph.probe('second')
    graph.step_for(0.1)
    command(graph, first, 0.5, 0.0)
    graph.step_for(0.1)
    graph.remove(first)
    settle(graph)
    command(graph, second, 0.0, 1.0)  # what first sent must not stand for it
    graph.step_for(0.5)
    assert_pose(second.odom, (0.05, 0.0, 0.5))


def test_a_command_from_outside_the_graph_never_holds_it_nor_stands_for_a_members(graph):
    sim = graph.sim(cmd_vel_timeout=0.0)
    probe = graph.probe()
    outsider = Node('teleop', context=graph.context)  # not added: neither spun nor counted
    try:
        teleop = outsider.create_publisher(Twist, 'cmd_vel', 10)
        graph.step_for(0.1)
        assert graph.spin_until(lambda: teleop.get_subscription_count() == 1)
        turn = Twist()
        turn.angular.z = 1.0
        teleop.publish(turn)
        assert graph.spin_until(lambda: sim.world.commanded[0] == (0.0, 1.0))
        graph.step_for(0.1)
        command(graph, probe, 0.5, 0.0)
        graph.step_for(0.5)
        assert_pose(probe.odom, (0.25 * math.cos(0.1), 0.25 * math.sin(0.1), 0.1))
    finally:
        outsider.destroy_node()


def test_a_callback_longer_than_the_timeout_is_no_stall_but_a_member_that_never_answers_is(
        graph):
    # The step's timeout is for a graph that waits on what never comes: time a callback runs
    # (a motion drawing its plot_file as it ends, on a loaded machine) does not count.
    graph.sim()
    slow = sim_time_node(graph, 'slow')
    cmd_vel = slow.create_publisher(Twist, 'cmd_vel', 10)
    ran = []

    def draw_then_stop():  # first due at 0.1 s: a stop the simulator has yet to handle
        time.sleep(0.6)
        ran.append(cmd_vel.publish(Twist()))
    slow.create_timer(0.1, draw_then_stop)
    graph.step_for(0.08)
    graph.step(timeout=0.3)
    assert len(ran) == 1 and graph.now_ns == NS // 10
    assert graph.pending() == 0
    # A member that never answers the step still stops it, after the timeout of waiting.
    ghost = Answer('ghost#1', '/ghost', graph.now_ns)
    graph.ledger.receive(ghost, graph.now_ns)
    with pytest.raises(RuntimeError, match='graph did not settle'):
        graph.step(timeout=0.3)
