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
What an ordinary graph does to simulated time and to a motion's start, with the real executables.

A node that does not take part publishing stale or zero stamps on cmd_vel, a participant that
leaves, a participant spun by a MultiThreadedExecutor, and a cmd_vel listener that is not the
robot: none of them may stall the clock, drop anyone from the lockstep, or let a motion say
Done without its robot (one that never comes: test_motion_processes.py).  The executable under
test runs as a process; a node that only serves it (the simulator that comes late, the
participant after a flood) is a node of this process, met over DDS all the same.  (The lossy
link is test_two_hosts.py; a participant killed mid-run, a busy machine and a slow participant
are test_lockstep_processes.py; open-loop motions whose simulator is killed mid-motion are
test_motion_fleet.py's, on the simulator process of its other checks.)
"""

import math
import re
import time

from geometry_msgs.msg import TwistStamped
from motion_challenges.prompts import RotationRequest
from motion_challenges.rotate_robot import RotateRobot
import pytest
from rclpy.clock import Clock
from rclpy.clock import ClockType
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock as ClockMsg
from sim_diffdrive import harness
from sim_diffdrive.harness import angle_error
from sim_diffdrive.harness import pose_of
from sim_diffdrive.harness import stamp_s
from sim_diffdrive.harness import stop
from sim_diffdrive.lockstep.participant import take_part
from sim_diffdrive.sim.node import UnicycleSim

# The pace of lockstep, and of the simulator freewheeling while nobody takes part: at 40x (as
# in test_lockstep_processes.py) the freewheeling alone cost 0.2 CPU s more here.
FACTOR = 10.0
# A whole turn (200 steps), so that a flood at 1 kHz overlaps it with over a hundred messages
# however fast the handshake (a quarter turn took 0.1 s wall, 34 messages at 3 ms apart).
FLOODED_ROTATE = ('angular_speed_deg:=90.0', 'angle_deg:=360.0', 'clockwise:=false')
# On wall time: the robot turns while the commands' wall times say, so a slower turn keeps a
# starved simulator's late first command a small angle (7.2 deg short once, against 30 allowed).
WALL_ROTATE = ('angular_speed_deg:=30.0', 'angle_deg:=90.0', 'clockwise:=false')


def start(executable, *params):
    return harness.start(executable, *harness.ros_params(*params))


def finish(graph, process, timeout=60.0):
    """Spin until process exits; return (exit code, output)."""
    try:
        assert graph.spin_until(lambda: process.poll() is not None, timeout), process.describe()
    finally:
        output = stop(process)
    return process.returncode, output


def at_rest_after(graph, probe, stamp):
    """Spin until odometry stamped 0.1 s after stamp came; return its yaw."""
    assert graph.spin_until(lambda: probe.stamp_s > stamp + 0.1, 10.0)
    return pose_of(probe.odom)[2]


def warnings(output):
    return [line for line in output.splitlines() if '[WARN]' in line]


def test_foreign_stale_and_zero_stamps_and_leavers_never_stall_or_drop_anyone(graph, capfd):
    sim = start('unicycle_sim', 'publish_clock:=true', f'real_time_factor:={FACTOR}',
                'stamped:=true')
    probe = graph.probe(use_sim_time=False, listen_only=True)
    foreign = probe.create_publisher(TwistStamped, 'cmd_vel', 10)
    stale = []

    def publish_stale():
        # All-zero commands from a node that does not take part, stamped 0 or 1 s ago, every
        # millisecond: some land between a motion's command and the end of its step.
        msg = TwistStamped()
        stamp_ns = 0 if len(stale) % 2 else max(0, round((probe.stamp_s - 1.0) * 1e9))
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 10 ** 9)
        foreign.publish(msg)
        stale.append(stamp_ns)

    try:
        assert graph.spin_until(lambda: probe.odom is not None, 20.0), sim.describe()
        timer = probe.create_timer(0.001, publish_stale,
                                   clock=Clock(clock_type=ClockType.STEADY_TIME))
        # The zero commands stamped 0 do reach the robot (the latest command wins), so this
        # turn falls short; what matters is that it ran to its end without a stall.
        code, output = finish(graph, start('rotate_robot', 'use_sim_time:=true',
                                           'stamped:=true', *FLOODED_ROTATE))
        assert code == 0 and 'Done in 4.000 s' in output, output
        timer.cancel()
        # The simulator is still in its own lockstep: the next turn is exact.  Its participant
        # is the same node in this process, run as run() runs it (spun until done, then its
        # shutdown_hook: the final stop and the goodbye): what is tested is the simulator, and
        # a process start-up is saved.
        yaw = at_rest_after(graph, probe, stamp_s(probe.odom))
        capfd.readouterr()
        turn = graph.add(RotateRobot(context=graph.context, parameter_overrides=[
            Parameter('use_sim_time', value=True), Parameter('stamped', value=True)]))
        turn.start(RotationRequest(90.0, 90.0, False))
        assert graph.spin_until(lambda: turn.done, 30.0), sim.describe()
        turn.shutdown_hook()
        output = capfd.readouterr().err
        assert turn.exit_code == 0, output
        done = re.search(r'error ([0-9.]+) deg', output)
        assert done and float(done.group(1)) < 1e-9, output
        end_yaw = at_rest_after(graph, probe, stamp_s(probe.odom))
        assert angle_error(end_yaw, yaw + math.radians(90.0)) < 1e-9, (yaw, end_yaw)
        # A participant that leaves never stalls the clock: it freewheels again at once, a
        # simulated second within a few wall seconds, the robot at rest.  (Waiting for the
        # leaver would be dropping it after lockstep_timeout, with a warning, checked below.)
        stamp = stamp_s(probe.odom)
        assert graph.spin_until(lambda: probe.stamp_s > stamp + 1.0, 5.0)
        assert probe.twist == (0.0, 0.0)
    finally:
        sim_output = stop(sim)
    assert len(stale) > 100
    assert not [line for line in warnings(sim_output) if 'Lockstep' in line], sim_output
    assert 'Refusing cmd_vel stamped' in sim_output  # the foreign commands came
    assert sim_output.count('takes part from') == 2 and 'going on without' not in sim_output
    assert sim_output.count('Lockstep: /rotate_robot left at') == 2, sim_output


def test_a_multithreaded_executor_is_refused_by_name(graph):
    context = graph.context
    clock = graph.add(Node('clock_source', context=context))
    clock_pub = clock.create_publisher(ClockMsg, '/clock', 10)
    participant = Node('mt_participant', context=context,
                       parameter_overrides=[Parameter('use_sim_time', value=True)])
    take_part(participant)
    # Two threads on any machine: by default it has one a core (one, and a warning, on one).
    executor = MultiThreadedExecutor(num_threads=2, context=context)
    executor.add_node(participant)
    try:
        with pytest.raises(RuntimeError, match='MultiThreadedExecutor'):
            deadline = time.monotonic() + 10.0
            while time.monotonic() < deadline:
                msg = ClockMsg()
                msg.clock.sec = 1
                clock_pub.publish(msg)
                graph.spin_for(0.01)
                executor.spin_once(timeout_sec=0.01)
    finally:
        executor.shutdown()
        participant.destroy_node()


def test_a_cmd_vel_listener_is_not_the_robot(graph):
    # A listener on cmd_vel (as ros2 topic echo or a bridge) is there first; the simulator
    # comes 1 s after the motion (which would start within a tick of discovering a subscriber,
    # 0.3 s at most).  Wall time throughout.  The motion is the executable under test; the
    # simulator is a node of this process, which the motion meets over DDS as it would a
    # process (a process start-up saved).
    listener = graph.probe('cmd_vel_listener', use_sim_time=False, listen_only=True,
                           odom_topic='unused_odom', record_commands=True)
    motion = start('rotate_robot', *WALL_ROTATE)
    try:
        assert graph.spin_until(lambda: 'Waiting for the robot' in motion.output(), 20.0)
        graph.spin_for(1.0)
        assert motion.poll() is None, motion.output()
        assert not listener.commands or all(
            msg.angular.z == 0.0 for _, _, msg in listener.commands)
        graph.add(UnicycleSim(context=graph.context))
        code, output = finish(graph, motion)
        probe = graph.probe(use_sim_time=False, listen_only=True)
        assert graph.spin_until(lambda: probe.odom is not None, 10.0)
    finally:
        stop(motion)
    assert code == 0, output
    # It turned the robot, which came after it: on wall time, not to a fraction of a degree.
    # A simulator starved of the CPU for a while handles the first command late, and the robot
    # turns that much less (7.2 deg short, once, in a busy suite; sim time is exact).
    done = re.search(r'Done in .*turned ([0-9.]+) deg \(odometry\)', output)
    assert done and abs(float(done.group(1)) - 90.0) < 30.0, output
    assert angle_error(pose_of(probe.odom)[2], math.radians(90.0)) < math.radians(30.0)
