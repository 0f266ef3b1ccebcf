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

"""What every motion node does around its motion: waiting for the robot, states, giving up."""

import math
import re
import time

from motion_challenges.motion_node import MotionState
from motion_challenges.prompts import RotationRequest
from motion_challenges.rotate_robot import ask_missing
from motion_challenges.rotate_robot import RotateRobot
from motion_challenges.timed_out_and_back import TimedOutAndBack
from nav_msgs.msg import Odometry
import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from rclpy.time import Time
from rosgraph_msgs.msg import Clock as ClockMsg
from sim_diffdrive.harness import angle_error
from sim_diffdrive.lockstep.handshake import answer_topic
from sim_diffdrive.lockstep.participant import ANSWER_QOS
from sim_diffdrive.runtime import EXIT_FAILED
from sim_diffdrive.runtime import UsageError
from std_msgs.msg import String

TYPING_S = 1.2  # how long the user takes to answer the questions [s, wall time]
START_TIMEOUT = 0.5


def rotate_robot(graph, **params):
    params.setdefault('use_sim_time', True)
    return graph.add(RotateRobot(context=graph.context, parameter_overrides=[
        Parameter(name, value=value) for name, value in params.items()]))


def test_start_timeout_does_not_count_the_time_spent_typing(graph):
    node = rotate_robot(graph, mode='odom', start_timeout=START_TIMEOUT)
    graph.spin_for(TYPING_S)  # rotate_robot asks its questions after building the node
    node.start(RotationRequest(90.0, 45.0, False))
    # No robot yet, TYPING_S after the node was made and just after the answers: it waits on
    # (its watchdog ran meanwhile, so no stall of its own excuses anything).
    node.watch.on_watchdog()
    assert not node.done
    # The robot comes, and the motion runs as if no time had passed.  (The check above is
    # done: the robot's coming need not race a 0.5 s wall-clock timeout on a busy machine.)
    node.set_parameters([Parameter('start_timeout', value=60.0)])
    graph.sim()
    graph.step_until(lambda: node.done, sim_timeout=5.0)
    assert node.exit_code == 0
    graph.step_for(0.1)
    assert angle_error(graph.pose()[2], math.radians(45.0)) < 1e-9


def test_a_stall_of_its_own_is_not_counted_as_waiting_for_the_robot(graph):
    # A process that did not run (a starved machine, a debugger) could not hear the robot.
    node = rotate_robot(graph, start_timeout=START_TIMEOUT)
    graph.spin_for(0.6)  # its watchdog runs
    node.start(RotationRequest(90.0, 45.0, False))
    time.sleep(2 * START_TIMEOUT)  # it does not run
    node.watch.on_watchdog()  # late: what it did not run is excused
    assert not node.done


def test_without_a_robot_it_gives_up_start_timeout_after_the_answers(graph, capfd):
    node = rotate_robot(graph, start_timeout=START_TIMEOUT)
    time.sleep(TYPING_S)
    started = time.monotonic()
    node.start(RotationRequest(90.0, 45.0, False))
    assert graph.spin_until(lambda: node.done, timeout=5.0)
    waited = time.monotonic() - started
    assert node.exit_code == EXIT_FAILED
    assert node.state is MotionState.FINISHED
    # Counted from the answers, not from the node's start (then it would have given up
    # TYPING_S sooner).  How late after that the watchdog notices is load, not behaviour.
    assert waited >= START_TIMEOUT
    # It says the timeout it was given (a newcomer read 'Gave up after 2.5 s' for 2.0).
    said = f'Gave up after start_timeout ({START_TIMEOUT:g} s) waiting for'
    assert said in capfd.readouterr().err


def test_on_sim_time_beside_a_simulator_without_a_clock_it_names_the_clock(graph, capfd):
    # A ROS 1 habit: use_sim_time against unicycle_sim without publish_clock.  The motion said
    # it waited for odometry, while odometry came at 50 Hz.
    graph.sim(stepped=False, publish_clock=False)
    node = rotate_robot(graph, mode='odom', start_timeout=START_TIMEOUT)
    node.start(RotationRequest(90.0, 45.0, False))
    assert graph.spin_until(lambda: node.done, timeout=5.0)
    assert node.exit_code == EXIT_FAILED and graph.odom() is not None
    assert (f'start_timeout ({START_TIMEOUT:g} s) waiting for simulated time on /clock '
            '(use_sim_time is true); does unicycle_sim run with -p publish_clock:=true? Nothing '
            'moved.') in capfd.readouterr().err


def test_a_simulator_in_lockstep_that_never_takes_it_in_is_named_not_taken_for_absent(
        graph, capfd):
    # On a link losing packets both ways, the simulator can learn of a motion seconds after
    # the motion learned of it (Fast DDS repairs lost discovery with a heartbeat a second).
    # Here a node listens for lockstep answers and never sends a roster: the motion must give
    # up saying that the simulator is there, not ask whether it runs.
    graph.sim()
    owner = graph.add(Node('silent_owner', context=graph.context))
    owner.create_subscription(String, answer_topic('/clock'), lambda _: None, ANSWER_QOS)
    node = rotate_robot(graph, start_timeout=START_TIMEOUT)
    node.start(RotationRequest(90.0, 45.0, False))
    graph.step()
    assert graph.spin_until(lambda: node.done, timeout=5.0)
    assert node.exit_code == EXIT_FAILED
    assert node.start_ns is None  # never started
    err = capfd.readouterr().err
    assert 'waiting for the simulator to take this node into its lockstep; it runs but has ' \
        'not heard this node yet (a slow or lossy link: raise start_timeout; a process killed ' \
        'while it ran on this machine can leave it deaf to new ones: restart it). Nothing ' \
        'moved.' in err, err
    graph.step_for(0.1)
    assert graph.pose() == (0.0, 0.0, 0.0)


def test_on_wall_time_against_a_simulator_that_owns_time_it_says_so_and_never_moves(
        graph, capfd):
    # Without use_sim_time beside a simulator publishing /clock, it drove on its wall clock
    # and then blamed the simulator ("no odometry came after the stop").
    graph.sim()
    node = rotate_robot(graph, use_sim_time=False)
    node.start(RotationRequest(90.0, 45.0, False))
    graph.step()  # odometry at simulated time 0.02 s; the motion ticks on its wall clock
    assert graph.spin_until(lambda: node.done, timeout=5.0)
    assert node.exit_code == EXIT_FAILED
    assert node.start_ns is None  # never started
    graph.step_for(0.1)
    assert graph.pose() == (0.0, 0.0, 0.0)
    assert 'Start this motion with -p use_sim_time:=true. Nothing moved.' in capfd.readouterr().err


def test_the_state_goes_waiting_running_settling_finished(graph):
    graph.sim()
    node = rotate_robot(graph, mode='odom')
    states = [node.state]

    def record():
        if node.state is not states[-1]:
            states.append(node.state)
        return node.done
    node.start(RotationRequest(90.0, 45.0, True))
    graph.step_until(record, sim_timeout=5.0)
    assert states == [MotionState.WAITING, MotionState.RUNNING, MotionState.SETTLING,
                      MotionState.FINISHED]
    # A str Enum: code that compares with the names still works.
    assert node.state == 'finished'


def test_odometry_is_used_in_stamp_order_after_the_clock_jumps_ahead(graph):
    # Odometry at 1.0 s arrives with the clock at 1.0 s: it waits for the next tick.  The
    # clock then jumps to 2.0 s (a simulator that went on without the motion) and odometry at
    # 1.5 s arrives: it is used after the older one, never before it (which looked like time
    # going back, and ended the run with the wrong reason).
    node = rotate_robot(graph, mode='odom')
    node.state = MotionState.RUNNING
    clock = node.get_clock()

    def odometry(stamp_s):
        msg = Odometry()
        msg.header.stamp = Time(seconds=stamp_s).to_msg()
        return serialize_message(msg)
    clock.set_ros_time_override(Time(seconds=1.0, clock_type=clock.clock_type))
    node.watch.on_odom(odometry(1.0))
    assert node.odom is None  # waits for the tick after it
    clock.set_ros_time_override(Time(seconds=2.0, clock_type=clock.clock_type))
    node.watch.on_odom(odometry(1.5))
    node.watch.take_early_odoms(node.now_ns())  # what the next tick does first
    assert not node.done, node.exit_code
    assert node.odom.stamp_ns == 1_500_000_000


def refused_nodes(graph):
    observer = graph.probe('observer', use_sim_time=False, listen_only=True)
    return [name for name, namespace in observer.get_node_names_and_namespaces()
            if namespace == '/refused']


def test_input_that_ends_before_the_answers_leaves_no_node_behind(graph):
    # rotate_robot's node is built before its questions: refused, it is destroyed at once
    # (runtime.destroyed_if_refused), not whenever the refusal's traceback lets go of it.
    node = RotateRobot(namespace='/refused', context=graph.context)
    assert refused_nodes(graph) == ['rotate_robot']
    with pytest.raises(UsageError, match='nothing moved'):
        ask_missing(node, read_line=lambda: '', write=lambda text: None)
    assert refused_nodes(graph) == []


def test_a_timed_motion_whose_simulator_restarts_stops_rather_than_drive_its_plan_twice(
        graph, capfd):
    # A user killed the simulator mid-motion and started another: the new clock began near 0,
    # the motion waited for it to reach its plan's start again, drove the whole plan a second
    # time and said Done, error 0.000 mm, exit 0.
    graph.sim()
    node = graph.node(TimedOutAndBack)
    graph.step_for(3.0)  # out on the first leg
    assert node.state is MotionState.RUNNING
    graph.remove(graph.clock_owner)
    graph.sim()  # its clock starts again at 0
    graph.step_until(lambda: node.done, sim_timeout=5.0)
    assert node.exit_code == EXIT_FAILED
    assert ' mid-motion; stopped the robot rather than drive the plan again from then ' \
        '(simulator restarted?)' in capfd.readouterr().err
    graph.step_for(0.5)
    assert graph.odom().twist.twist.linear.x == 0.0


def test_time_sent_back_by_another_clock_publisher_names_it(graph, capfd):
    # A second /clock publisher (a bag played with --clock, another simulator) was taken for a
    # restart: 'simulator restarted?', where two nodes publishing on /clock said who.
    graph.sim()
    node = graph.node(TimedOutAndBack)
    graph.step_for(3.0)
    player = graph.add(Node('bag_player', context=graph.context))
    clock = player.create_publisher(ClockMsg, '/clock', 10)
    graph.step()  # it is discovered
    clock.publish(ClockMsg(clock=Time(seconds=1).to_msg()))
    assert graph.spin_until(lambda: node.done, 10.0)
    assert node.exit_code == EXIT_FAILED
    assert re.search(r'Simulated time went back 2\.\d+ s \(/bag_player, /unicycle_sim publish '
                     r'on /clock\) mid-motion', capfd.readouterr().err)
