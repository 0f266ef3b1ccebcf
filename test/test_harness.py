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

"""The harness itself (sim_diffdrive.harness): processes, logs, and a graph's simulators."""

import gc
import os
import re
import shutil
import signal
import sys
import time

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import pytest
import rclpy
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from sim_diffdrive.dds_teardown import held_context
from sim_diffdrive.harness import kill_all
from sim_diffdrive.harness import Process
from sim_diffdrive.harness import SimGraph
from sim_diffdrive.harness import start_python
from sim_diffdrive.harness import stop
from sim_diffdrive.harness import stop_all
import sim_diffdrive.testing.domains as domains
from sim_diffdrive.testing.domains import claim_domains
from sim_diffdrive.testing.domains import DOMAIN_BLOCK

# Waits for Ctrl-C, says so, and exits 0 (as the executables do).
INTERRUPTIBLE = """
import time
try:  # 'ready' only once a Ctrl-C lands in here
    print('ready', flush=True)
    time.sleep(30)
except KeyboardInterrupt:
    print('interrupted', flush=True)
"""
# Takes its time to exit after Ctrl-C or SIGTERM (as a ROS process leaving DDS does), saying
# when the signal came.
SLOW_TO_EXIT = """
import signal, sys, time
def leave(signum, frame):
    print('signalled', time.monotonic(), flush=True)
    time.sleep(1.0)
    sys.exit(0)
signal.signal(signal.SIGTERM, leave)
signal.signal(signal.SIGINT, leave)
print('ready', flush=True)
time.sleep(30)
"""

# Deaf to SIGTERM and stuck; shows its stack on SIGUSR1 (as runtime.run sets up), or not.
STUCK = """
import faulthandler, signal, sys, time
signal.signal(signal.SIGTERM, signal.SIG_IGN)
if sys.argv[1:] == ['stacks']:
    faulthandler.register(signal.SIGUSR1)
def stuck_in_here():
    print('ready', flush=True)
    time.sleep(30)
stuck_in_here()
"""


def wait_ready(processes):
    deadline = time.monotonic() + 20.0
    while not all('ready' in p.output() for p in processes) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert all('ready' in p.output() for p in processes), [p.output() for p in processes]


def signalled_at(output):
    return float(output.split('signalled ')[1].split()[0])


@pytest.mark.parametrize('end', ['stop_all', 'kill_all'])
def test_several_processes_are_signalled_before_any_is_waited_for(end):
    # Each takes 1 s to exit once signalled: one after the other, the last would hear its
    # signal at least 2 s after the first.
    processes = [start_python(SLOW_TO_EXIT) for _ in range(3)]
    try:
        wait_ready(processes)
        if end == 'stop_all':
            outputs = stop_all(processes)
        else:
            kill_all(processes)
            outputs = [p.output() for p in processes]
    finally:
        kill_all(processes, grace=0.0)
    # Each assertion shows the outputs: this test failed once in a busy suite, its text lost.
    assert all('signalled ' in output for output in outputs), outputs
    times = [signalled_at(output) for output in outputs]
    assert max(times) - min(times) < 1.0, outputs
    assert [p.returncode for p in processes] == [0, 0, 0], outputs
    assert not any(p.log_path.exists() for p in processes), outputs


def test_stop_returns_the_output_and_removes_the_temporary_log():
    process = start_python("print('hello', flush=True)")
    assert process.wait(20.0) == 0
    output = stop(process)
    assert 'hello' in output
    assert not process.log_path.exists()
    assert process.output() == output  # still readable after the file is gone


def test_a_process_never_stopped_leaves_no_log_behind():
    process = start_python('pass')
    log_path = process.log_path
    process.wait(20.0)
    assert log_path.exists()
    del process
    gc.collect()
    assert not log_path.exists()


def test_a_child_hears_ctrl_c_even_when_this_process_ignores_it():
    # A test run started in the background of a non-interactive shell ignores SIGINT.
    saved = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        process = start_python(INTERRUPTIBLE)
        deadline = time.monotonic() + 20.0
        while 'ready' not in process.output() and time.monotonic() < deadline:
            time.sleep(0.05)
        output = stop(process, timeout=5.0)
    finally:
        signal.signal(signal.SIGINT, saved)
    assert 'interrupted' in output, output
    assert process.returncode == 0
    assert process.exited_at - process.signalled_at < 4.0


def test_runs_on_one_machine_never_share_a_block_of_domains(tmp_path):
    # Another run (a process) holds a block; this one claims every other block, then shares.
    other = start_python('import time\nfrom sim_diffdrive.testing.domains import claim_domains\n'
                         f'print(claim_domains({str(tmp_path)!r}), flush=True)\n'
                         'time.sleep(30)')
    held = len(domains._claims)
    try:
        deadline = time.monotonic() + 20.0
        while not other.output().strip() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert other.output().strip().isdigit(), other.describe()
        others = int(other.output())
        claimed = [claim_domains(str(tmp_path)) for _ in range(24)]
        assert sorted(claimed + [others]) == list(range(1, 101, DOMAIN_BLOCK))
        # All taken: a block is shared, said so, and nothing more is locked.
        with pytest.warns(RuntimeWarning,
                          match=r'sharing domain .* \(set SIM_GRAPH_DOMAIN_ID'):
            assert claim_domains(str(tmp_path)) in claimed + [others]
        assert len(domains._claims) == held + 24
        # A claim ends with the process that holds it, however it ends.
        stop(other, signal.SIGKILL)
        assert claim_domains(str(tmp_path)) == others
    finally:
        stop(other, signal.SIGKILL)
        for lock in domains._claims[held:]:
            os.close(lock)
        del domains._claims[held:]


@pytest.mark.parametrize('given,worker,domain', [
    ('40', None, 40), ('40', 'gw0', 40), ('40', 'gw3', 43), ('0', 'gw2', 2),
    ('300', None, '=300: a ROS domain is a whole number from 0 to 232'), ('x1', 'gw1', '=x1:'),
    ('231', 'gw2', r'=231 \+ 2 \(worker gw2\): a ROS domain'),
])
def test_a_given_domain_is_each_pytest_workers_own_and_checked(
        monkeypatch, given, worker, domain):
    # SIM_GRAPH_DOMAIN_ID pinned with pytest -n 4 put every worker on it, and the graphs of
    # one heard the others'; 300 ended pytest without a word (Fast DDS exits).
    for name in ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE', domains.WORKER_VARIABLE):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv(domains.DOMAIN_VARIABLE, given)
    if worker:
        monkeypatch.setenv('PYTEST_XDIST_WORKER', worker)
    else:
        monkeypatch.delenv('PYTEST_XDIST_WORKER', raising=False)
    if isinstance(domain, str):
        with pytest.raises(ValueError, match=domain):
            domains.isolated_domain_id()
        return
    assert domains.isolated_domain_id() == domain
    assert domains.isolated_domain_id() == domain  # once: its children's is the same
    assert os.environ['ROS_DOMAIN_ID'] == os.environ[domains.DOMAIN_VARIABLE] == str(domain)


def test_graphs_open_at_once_are_on_domains_of_their_own(graph):
    # A second graph took the first's domain: the test's node drove the other's robot.
    def open_graphs():
        with SimGraph() as one, SimGraph() as two:
            return {graph.context.get_domain_id(), one.context.get_domain_id(),
                    two.context.get_domain_id()}
    held = len(domains._claims)
    first = open_graphs()
    assert len(first) == 3 and domains.isolated_domain_id() in first
    # Again: the block claimed for them is this process's, and serves again (25 in all).
    assert open_graphs() == first and len(domains._claims) <= held + 1


def test_a_graph_without_a_stepped_simulator_removes_nodes(ros_context):
    graph = SimGraph(ros_context)
    try:
        probe = graph.probe(listen_only=True)
        other = graph.probe('other', listen_only=True)
        graph.remove(probe)
        assert graph.nodes == [other]
    finally:
        graph.close()


def test_removing_a_node_waits_for_its_own_publishers_only(ros_context, graph):
    # Another participant (as another process is) publishes on the topics every node has.
    with held_context(domain_id=ros_context.get_domain_id()) as other:
        elsewhere = rclpy.create_node('elsewhere', context=other)
        probe = graph.probe(listen_only=True)
        graph.probe('other', listen_only=True)
        assert graph.spin_until(lambda: probe.count_publishers('/parameter_events') == 3)
        assert graph.remove(probe)  # not held until the other participant leaves
        assert graph.nodes[0].count_publishers('/parameter_events') == 2
        elsewhere.destroy_node()


def test_a_removed_node_never_runs_a_callback_once_destroyed(graph):
    # Messages reach a relay's subscription, which republishes each, while the graph does not
    # spin: the executor has queued their events when the relay is removed.  Run after the
    # relay was destroyed, the callback's publish raised InvalidHandle out of remove().
    talker = graph.probe('talker', listen_only=True)
    chatter = talker.create_publisher(Twist, 'chatter', 10)
    for i in range(3):
        relay = graph.probe(f'relay{i}', listen_only=True)
        echo = relay.create_publisher(Twist, 'echo', 10)
        handled = []

        def republish(msg, echo=echo, handled=handled):
            echo.publish(msg)
            handled.append(msg)
        relay.create_subscription(Twist, 'chatter', republish, 10)
        for _ in range(100):  # until the relay hears the talker
            chatter.publish(Twist())
            if graph.spin_until(lambda: handled, 0.05):
                break
        assert handled, 'the relay never heard the talker'
        for _ in range(5):
            chatter.publish(Twist())
        time.sleep(0.1)  # delivered, not handled
        assert graph.remove(relay)
        assert relay not in graph.nodes


def test_one_stepped_simulator_per_graph_and_it_owns_the_clock(graph):
    sim = graph.sim()
    with pytest.raises(ValueError, match='one per graph'):
        graph.sim()
    graph.remove(sim)
    assert graph.clock_owner is None
    with pytest.raises(ValueError, match='publish_clock true'):
        graph.sim(publish_clock=False)
    graph.sim(stepped=False, publish_clock=False)  # on someone else's clock: fine


def test_a_graphs_mistakes_are_named(graph, capfd):
    # What a newcomer met: a misspelt simulator parameter passed without a word, a step before
    # sim() an AttributeError, a bare timeout, a node on wall time that never moved the robot.
    with pytest.raises(TypeError, match="'initail_x'.*did you mean 'initial_x'"):
        graph.sim(initail_x=1.0)
    with pytest.raises(RuntimeError, match='start a simulator with sim'):
        graph.step_for(1.0)
    graph.sim()
    wall = graph.add(Node('on_wall_time', context=graph.context))
    wall.create_timer(0.1, lambda: None)
    with pytest.raises(RuntimeError, match=r'within 0.5 s of simulated time \(now t=0.500 s\)'):
        graph.step_until(lambda: False, sim_timeout=0.5)
    err = capfd.readouterr().err
    assert 'On wall time (use_sim_time is false) in a SimGraph' in err
    assert 'publishing /clock as its caller steps it' in err  # not 'at up to 10x (free clock)'
    assert err.count('On wall time') == 1  # the graph's own nodes are on sim time
    # A listener on wall time has no timer to pace, a clock's owner keeps its own: no word.
    graph.probe('wall_listener', use_sim_time=False, listen_only=True)
    owner = graph.add(Node('other_clock_owner', context=graph.context))
    owner.create_publisher(ClockMsg, 'other/clock', 1)
    owner.create_timer(0.1, lambda: None)
    graph.step()
    assert 'On wall time' not in capfd.readouterr().err
    graph.sim(stepped=False, robots=['other'])  # a second simulator, on wall time: said
    graph.step()
    assert '[unicycle_sim]: On wall time (use_sim_time is false)' in capfd.readouterr().err
    steady = graph.add(Node('steady_timer', context=graph.context,
                            parameter_overrides=graph.sim_time_params()))
    # What a step that does not settle waits for, in words (its timeout: 10 s).
    graph.probe('late')
    assert [re.fullmatch(r'/\S+ to take its /clock', reason) is not None
            for reason in graph._unsettled(graph.now_ns + graph.step_ns)] == [True]
    # Added twice, or destroyed without remove(): said at once, not after that wait.
    with pytest.raises(ValueError, match='/steady_timer is in the graph already'):
        graph.add(steady)
    steady.destroy_node()
    with pytest.raises(RuntimeError, match='/steady_timer was destroyed in the graph: take a '
                                           r'node out with remove\(node\)'):
        graph.step()


def test_a_topic_nobody_in_the_graph_hears_is_named_as_its_node_joins(graph, capfd):
    # A newcomer's controller published on cmd_vell: the robot never moved, and the failing
    # test said only 'assert 0.0 > 0.9'.  pytest shows the line with the failure.
    graph.sim()
    node = graph.add(Node('controller', context=graph.context,
                          parameter_overrides=graph.sim_time_params()))
    for topic in ('cmd_vell', 'cmd_vel'):
        node.create_publisher(Twist, topic, 10)
    for topic in ('laser', 'odom'):  # and one on laser, for scan
        node.create_subscription(Odometry, topic, lambda msg: None, 10)
    graph.step()
    err = capfd.readouterr().err
    assert '[controller]: Nothing in the graph subscribes (yet) to /cmd_vell, which it ' \
        'publishes: a topic named wrong?' in err
    assert '[controller]: Nothing in the graph publishes (yet) /laser, which it subscribes ' \
        'to: a topic named wrong?' in err
    assert err.count('Nothing in the graph') == 2  # its nodes: on what they hear


def test_waiting_for_odometry_that_never_comes_says_so_with_the_process_log(graph):
    process = start_python("print('no simulator here', flush=True)")
    try:
        process.wait(20.0)
        with pytest.raises(RuntimeError, match='no simulator here'):
            graph.wait_for_odometry(0.2, process=process)
    finally:
        stop(process)


def test_step_for_moves_the_simulated_robot_as_commanded(graph):
    graph.sim(cmd_vel_timeout=0.0)  # one command, kept
    probe = graph.probe()
    graph.step_for(0.1)
    probe.send(0.5, 0.0)
    graph.step_for(2.0)
    x, y, yaw = graph.pose()
    assert x == pytest.approx(1.0, abs=1e-9) and (y, yaw) == (0.0, 0.0)


@pytest.mark.parametrize('stacks', [True, False])
def test_a_process_that_does_not_exit_is_killed_with_its_stack_in_its_log(stacks):
    process = Process([sys.executable, '-c', STUCK, *(['stacks'] if stacks else [])])
    try:
        wait_ready([process])
        process.kill(grace=0.2)
    finally:
        kill_all([process], grace=0.0)
    if stacks:  # asked for its stack, then killed STACKS_WAIT later
        assert 'in stuck_in_here' in process.output(), process.output()
        assert process.returncode == -signal.SIGKILL
        if shutil.which('gdb'):  # and its native stacks, where gdb is installed
            native = process.output().partition('Native stacks (gdb):')[2]
            assert 'Thread 1' in native and 'sleep' in native, process.output()
    else:  # not a package executable: SIGUSR1 ends it at once
        assert process.returncode == -signal.SIGUSR1
