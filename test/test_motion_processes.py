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
The real executables over DDS, as a user runs them: a simulator process and a motion process.

Typed answers through a pipe, answers given in a params file; no odometry at all
through the motion's main() in this process (input that ends too early: test_faults.py).
Exactness across processes (lockstep under load) is proven in test_lockstep_processes.py,
interrupts in test_interrupts.py; here a result is accepted within one simulator step of motion.
"""

import math
from pathlib import Path
import subprocess

from motion_challenges import odom_out_and_back
import pytest
from sim_diffdrive import harness
from sim_diffdrive.harness import angle_error
from sim_diffdrive.harness import pose_of
from sim_diffdrive.harness import ros_params

RATE_HZ = 50.0
REAL_TIME_FACTOR = 4.0
# One simulator step of turning at 60 deg/s, plus rounding.
ONE_STEP_AT_60 = math.radians(60.0 / RATE_HZ) * 1.01


# One simulator process for the module, a robot (namespace) per test: the tests never share a
# robot, so none sees another's motion, and a process start-up is saved for each.
ROBOTS = ('typed', 'parameters')
CONFIG = Path(__file__).resolve().parents[1] / 'config'


@pytest.fixture(scope='module')
def simulator(tmp_path_factory):
    """Start a unicycle_sim process owning time, with a robot for each test that drives one."""
    log_path = tmp_path_factory.mktemp('motion_processes') / 'unicycle_sim.log'
    sim = harness.start('unicycle_sim', *ros_params(
        'publish_clock:=true', f'real_time_factor:={REAL_TIME_FACTOR}', f'rate_hz:={RATE_HZ}',
        f'robots:={list(ROBOTS)}'), log_path=log_path)
    try:
        yield sim
    finally:
        harness.stop(sim)


@pytest.fixture
def robot(graph, simulator):
    """Return a function of a robot name giving an in-process probe on its odometry, once up."""
    def probe_on(name):
        probe = graph.probe(namespace=name)
        assert graph.spin_until(lambda: probe.odom is not None, 15.0), simulator.describe()
        return probe
    return probe_on


def rotate_args(robot_name, *params):
    """Return rotate_robot's arguments: on sim time, for robot_name, with params."""
    return ros_params('use_sim_time:=true', *params, namespace=f'/{robot_name}')


def finish(graph, process, timeout=30.0):
    """Wait (spinning the probe) for process to exit; return (exit code, output)."""
    if not graph.spin_until(lambda: process.poll() is not None, timeout):
        process.kill(grace=1.0)  # with its stacks in its output: where it was stuck
        raise AssertionError(f'did not exit within {timeout:g} s:\n{process.describe()}')
    return process.returncode, process.output()


def settle(graph, probe, seconds=0.3):
    """Let odometry from after the motion arrive, and return the latest pose."""
    stamp = probe.odom.header.stamp.sec + probe.odom.header.stamp.nanosec * 1e-9
    assert graph.spin_until(lambda: (probe.odom.header.stamp.sec
                                     + probe.odom.header.stamp.nanosec * 1e-9) > stamp + seconds)
    return pose_of(probe.odom)


# First, before the module's simulator starts: this test needs none, and the simulator,
# freewheeling at REAL_TIME_FACTOR with its robots, would run on through it.  The motion runs
# through its main() in this process (run_main), as its console script would run it: what is
# tested is how the motion decides that a cmd_vel subscriber is not its robot, and a process
# start-up (0.3 CPU s) is saved.  (That a console script's exit code is its main()'s return
# is shown once per package by the processes of test_faults.py.)
def test_odom_motion_without_odometry_gives_up_and_never_moves(graph, run_main):
    probe = graph.probe(use_sim_time=False)
    # Be the robot's cmd_vel subscriber, but never publish odometry.
    received = []
    probe.create_subscription(type(probe.cmd_pub.msg_type()), 'cmd_vel', received.append, 10)
    code, output = run_main(odom_out_and_back.main, 'odom_out_and_back', '--ros-args',
                            '-p', 'start_timeout:=1.0')
    graph.spin_for(0.2)  # what the motion sent, if anything, to the subscriber
    # A cmd_vel subscriber is not the robot (test_lockstep_faults.py has the robot come late):
    # it gives up, says why and never says Done.
    assert code == 1, output
    assert 'Gave up' in output and 'odometry' in output
    assert 'Done' not in output and 'Traceback' not in output
    assert all(m.linear.x == 0.0 and m.angular.z == 0.0 for m in received)


def test_typed_answers_bad_ones_explained_and_asked_again_rotate_the_robot(
        graph, robot, procs, simulator):
    probe = robot('typed')
    motion = procs('rotate_robot', 'rotate_robot', *rotate_args('typed'), stdin=subprocess.PIPE)
    motion.write('fast\n-5\nnan\n60\n\n1e9\n45\nmaybe\ny\n')
    motion.close_input()
    code, output = finish(graph, motion)
    assert code == 0, output
    assert output.count('Enter desired angular speed (degrees): ') == 4
    assert output.count('Enter desired angle (degrees): ') == 3
    assert output.count('Do you want to rotate clockwise? (y/n): ') == 2
    assert "'fast' is not a number" in output
    assert 'answer y or n' in output
    assert 'Done' in output
    _, _, yaw = settle(graph, probe)
    # (A machine too busy for the lockstep_timeout shows in both logs: going on without it.)
    assert angle_error(yaw, math.radians(-45.0)) < ONE_STEP_AT_60, (
        output + simulator.describe())
    assert probe.odom.twist.twist.angular.z == 0.0


def test_answers_from_a_params_file_skip_the_questions(graph, robot, procs, simulator):
    # The shipped params file as a user runs it (test_params_files.py checks the file against
    # the node): it gives rotate_robot's three answers, so nothing is asked.  The file is for
    # the node /rotate_robot: its topics, not its name, go to the module's robot; mode odom
    # from the command line over the file's timed (the typed answers above turn in timed mode).
    probe = robot('parameters')
    motion = procs('rotate_robot', 'rotate_robot', '--ros-args', '--params-file',
                   str(CONFIG / 'rotate_robot.yaml'), '-p', 'use_sim_time:=true',
                   '-p', 'mode:=odom', '-r', 'cmd_vel:=/parameters/cmd_vel',
                   '-r', 'odom:=/parameters/odom')
    code, output = finish(graph, motion)
    assert code == 0, output
    assert 'Enter' not in output
    assert 'Rotating 90 deg clockwise at 60 deg/s (odom mode)' in output, output
    assert 'Done' in output, output
    _, _, yaw = settle(graph, probe)
    assert angle_error(yaw, math.radians(-90.0)) < ONE_STEP_AT_60, (
        output + simulator.describe())
