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

"""A motion that did not run for a while (a debugger, a starved process) blames nobody."""

import math
import time

from motion_challenges.odom_out_and_back import OdomOutAndBack
from motion_challenges.timed_out_and_back import TimedOutAndBack
import pytest
from rclpy.parameter import Parameter
from sim_diffdrive.harness import angle_error
from sim_diffdrive.harness import pose_of
from sim_diffdrive.runtime import EXIT_FAILED


@pytest.mark.parametrize('node_class', [OdomOutAndBack, TimedOutAndBack])
def test_a_pause_of_the_motion_s_process_is_not_a_silent_simulator(graph, node_class):
    # The process does not run for 2 s mid-motion (a debugger, a starved machine), longer
    # than odom_timeout: its watchdog then runs late, before anything else, and must not take
    # the silence it did not look at for a simulator that stopped.
    graph.sim()
    probe = graph.probe()
    node = graph.node(node_class, legs=1, goal_distance=0.2, pause=0.1, odom_timeout=1.5)
    graph.step_until(lambda: probe.odom is not None and probe.odom.twist.twist.linear.x > 0.0,
                     5.0)
    graph.spin_until(lambda: node.done, 0.55)  # the watchdog sees simulated time stand still
    time.sleep(2.0)
    graph.spin_until(lambda: node.done, 0.1)  # the watchdog, overdue, runs first
    assert not node.done, node.exit_code
    graph.step_until(lambda: node.done, 10.0)
    assert node.exit_code == 0
    graph.step_for(0.2)
    x, y, yaw = pose_of(probe.odom)
    assert math.hypot(x - 0.2, y) < 1e-6 and angle_error(yaw, math.pi) < 1e-6


def test_a_simulator_gone_mid_motion_is_asked_after_not_called_restarted(graph, capfd):
    # A simulator stopped with SIGTERM made odom_out_and_back say '(simulator restarted?)'.
    graph.sim()
    node = graph.node(OdomOutAndBack, legs=1, goal_distance=0.5)
    graph.step_until(lambda: node.start_ns is not None, 5.0)
    graph.remove(graph.clock_owner)  # its odometry publisher goes with it
    graph.spin_until(lambda: node.done, 5.0)  # the watchdog looks (on wall time)
    assert node.exit_code == EXIT_FAILED
    assert ('0 publishers on /odom mid-motion; stopped the robot (is the simulator still '
            'running?)') in capfd.readouterr().err


def test_a_simulator_slowed_down_live_is_not_taken_for_a_silent_one(graph):
    # A user slows the simulator down mid-motion to watch: at real_time_factor 0.02 a 20 ms
    # step takes 1 s of wall time, longer than odom_timeout (0.5 s), and odometry and the
    # clock come that far apart.  The simulator's roster says how long a step takes.  (At
    # 0.04 and 0.3 s, a suite at load 13 once brought a step 0.4 s late: past the 0.3 s left.)
    sim = graph.sim(stepped=False, publish_clock=True, lockstep=True, real_time_factor=5.0)
    probe = graph.probe()
    node = graph.node(OdomOutAndBack, legs=1, goal_distance=0.1, odom_timeout=0.5)
    assert graph.spin_until(lambda: node.start_ns is not None, 10.0)
    assert sim.set_parameters([Parameter('real_time_factor', value=0.02)])[0].successful
    now_ns = sim.now_ns()
    assert graph.spin_until(lambda: sim.now_ns() >= now_ns + 2 * sim.step_ns, 5.0)
    assert not node.done, node.exit_code
    assert sim.set_parameters([Parameter('real_time_factor', value=5.0)])[0].successful
    assert graph.spin_until(lambda: node.done, 10.0)
    assert node.exit_code == 0
    graph.spin_for(0.2)  # the final stop's step, and more
    x, y, yaw = pose_of(probe.odom)
    assert math.hypot(x - 0.1, y) < 1e-6 and angle_error(yaw, math.pi) < 1e-6
