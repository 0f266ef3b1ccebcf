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
The real ``unicycle_sim`` executable, driven over DDS by a probe in this process.

The probe takes part in the simulator's lockstep, so each command takes effect on the step it
was meant for however busy the machine is, and the turn ends exact.  A bad parameter goes
through the executable's main() in this process.
"""

import signal
import subprocess

import pytest
from sim_diffdrive.harness import angle_error
from sim_diffdrive.harness import pose_of
from sim_diffdrive.lockstep.participant import take_part
from sim_diffdrive.sim.node import main

NS = 1_000_000_000
SIM_ARGS = ('--ros-args', '-p', 'publish_clock:=true', '-p', 'real_time_factor:=5.0')


@pytest.fixture
def start_sim(procs):
    """Start unicycle_sim with the given arguments; whatever still runs is killed afterwards."""
    return lambda *args: procs('unicycle_sim', 'unicycle_sim', *args)


def stop_with(sim, signum, timeout=5.0):
    """Send signum and return the exit code; fail if the process does not exit in time."""
    sim.send(signum)
    try:
        return sim.wait(timeout)
    except subprocess.TimeoutExpired:
        pytest.fail(f'unicycle_sim still running {timeout} s after signal {signum}')


def stamp_ns(odom):
    return odom.header.stamp.sec * NS + odom.header.stamp.nanosec


def wait_for_odometry(graph, probe, sim):
    if not graph.spin_until(lambda: probe.odom is not None, timeout=20.0):
        pytest.fail('no odometry from unicycle_sim:\n' + sim.output())


def test_shows_its_stacks_turns_on_command_and_exits_cleanly_on_sigint(graph, start_sim):
    # One process for three things a user does to it in turn.  (SIGTERM ends it as SIGINT
    # does, through the same handler: test_recorder.py stops a recording simulator with it.)
    sim = start_sim(*SIM_ARGS)
    probe = graph.probe()
    lockstep = take_part(probe)
    wait_for_odometry(graph, probe, sim)
    assert pose_of(probe.odom) == (0.0, 0.0, 0.0)
    # Every thread's Python stack, as `kill -USR1` from a shell gives it (runtime.run), and
    # the run goes on: the turn below is exact all the same.
    sim.send(signal.SIGUSR1)
    assert graph.spin_until(lambda: 'in spin_until_done' in sim.output(), timeout=10.0), (
        sim.output())
    assert sim.poll() is None
    # Play only once the simulator counts the probe: before, it freewheels past the probe.
    assert graph.spin_until(
        lambda: lockstep.joined and lockstep.counted_on(probe.cmd_pub.topic_name),
        timeout=20.0), sim.output()

    # 1 rad/s, re-sent on every 0.1 s sim tick (well inside the 0.5 s cmd_vel timeout), for
    # 1.5 s, then a zero Twist.
    probe.play([(0.0, 1.0, 15)], period=0.1)
    assert graph.spin_until(lambda: not probe.playing, timeout=20.0), sim.output()
    assert graph.spin_until(
        lambda: stamp_ns(probe.odom) > probe.script_done_at + NS // 5, timeout=10.0)
    odom = probe.odom
    x, y, yaw = pose_of(odom)
    assert (x, y) == (0.0, 0.0)
    assert angle_error(yaw, 1.5) < 1e-12
    assert (odom.twist.twist.linear.x, odom.twist.twist.angular.z) == (0.0, 0.0)

    assert stop_with(sim, signal.SIGINT) == 0
    output = sim.output()
    assert 'Traceback' not in output
    assert 'publishing /clock at up to 5x real time in lockstep' in output


def test_bad_parameter_exits_with_usage_code_naming_it(run_main):
    # Its main() in this process, as the console script calls it (test_colcon_layout.py); a
    # process shows main()'s return is the exit code once per package (test_faults.py).
    code, output = run_main(main, 'unicycle_sim', '--ros-args', '-p', 'rate_hz:=-5.0')
    assert code == 2, output
    assert "'rate_hz'" in output
    assert '-5.0' in output
    assert 'Traceback' not in output
