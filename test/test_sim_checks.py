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
What ``unicycle_sim`` refuses or warns about in its own setup: frames and a second clock owner.

Frame names that tf2 cannot use (one frame for both ends of the odometry, an empty name, a
name with whitespace or a leading '/') are refused by name, at start (exit 2) and as a live
set (the frames stay).  A simulator that owns ``/clock`` warns once when another node
publishes on the same clock topic, and about a publisher on a robot's ``cmd_vel`` that sends
another message type, which DDS never matches.  When it goes on without a message a
participant sent, it says which publishers of that topic its discovery knows (on a lossy link
one side can match a writer seconds before the other, and what is sent meanwhile never
arrives).  A tap whose Python package is missing (MCAP, Foxglove, the browser view) is named
with the package to install, and the simulator runs without it.
"""

from contextlib import contextmanager
import os
from pathlib import Path
import re
import sys
import time

from geometry_msgs.msg import Twist
from geometry_msgs.msg import TwistStamped
import pytest
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.srv import SetParameters
from rclpy.node import Node
from rclpy.parameter import get_parameter_value
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock as ClockMsg
from sim_diffdrive.dds_teardown import held_context
from sim_diffdrive.lockstep.owner import UNDISCOVERED_TIMEOUTS
from sim_diffdrive.lockstep.participant import take_part
from sim_diffdrive.parameters import ParameterError
import sim_diffdrive.sim.clock as clock_module
import sim_diffdrive.sim.node as node_module
from sim_diffdrive.sim.node import UnicycleSim

ROOM = str(Path(__file__).resolve().parents[1] / 'maps' / 'room.yaml')


class Logs:
    """Stand in for a node's logger and keep what it was told."""

    def __init__(self):
        self.lines = []

    def __getattr__(self, level):
        return lambda text, **_: self.lines.append((level, text))

    def clock_warnings(self):
        return [text for level, text in self.lines
                if level == 'warning' and 'publish on' in text and 'clock' in text]


def overrides(**params):
    return [Parameter(name, value=value) for name, value in params.items()]


def set_param(graph, client, name, text):
    """Set name from text as ``ros2 param set`` does, through the service; return the result."""
    assert graph.spin_until(client.service_is_ready, timeout=10.0)
    parameter = ParameterMsg(name=name, value=get_parameter_value(text))
    future = client.call_async(SetParameters.Request(parameters=[parameter]))
    assert graph.spin_until(future.done, timeout=5.0, poll=0.001)
    return future.result().results[0]


def frames(odom):
    return odom.header.frame_id, odom.child_frame_id


# -- frames at start ---------------------------------------------------------------------------

@pytest.mark.parametrize('namespace, params, named', [
    # One frame at both ends: tf2 rejects base_footprint -> base_footprint.
    ('/', {'odom_frame_id': 'base_footprint'}, 'odom_frame_id'),
    ('/', {'base_frame_id': 'odom'}, 'base_frame_id'),
    ('/', {'odom_frame_id': 'base_link', 'base_frame_id': 'base_link'}, 'odom_frame_id'),
    # Compared as published: in /robot1 the default base frame is robot1/base_footprint.
    ('/robot1', {'odom_frame_id': 'robot1/base_footprint'}, 'odom_frame_id'),
    # With robots every frame gets the robot's prefix: robot1/base_footprint at both ends.
    ('/', {'robots': ['robot1', 'robot2'], 'odom_frame_id': 'base_footprint'}, 'odom_frame_id'),
    # Names tf2 cannot use.
    ('/', {'odom_frame_id': ''}, 'odom_frame_id'),
    ('/', {'odom_frame_id': '   '}, 'odom_frame_id'),
    ('/', {'base_frame_id': 'base link'}, 'base_frame_id'),
    ('/', {'base_frame_id': 'base_link\t'}, 'base_frame_id'),
    ('/', {'odom_frame_id': '/map'}, 'odom_frame_id'),
    ('/robot1', {'base_frame_id': '/base_link'}, 'base_frame_id'),
    # With a map, its frame and the scan's too: map -> map, map -> odom -> map, a frame that
    # /tf_static's base -> scan would give a second parent.
    ('/', {'map_file': ROOM, 'odom_frame_id': 'map'}, 'odom_frame_id'),
    ('/', {'map_file': ROOM, 'base_frame_id': 'map'}, 'base_frame_id'),
    ('/', {'map_file': ROOM, 'map_frame_id': 'odom'}, 'map_frame_id'),
    ('/', {'map_file': ROOM, 'map_frame_id': '/map'}, 'map_frame_id'),
    ('/', {'map_file': ROOM, 'map_frame_id': ''}, 'map_frame_id'),
    ('/', {'map_file': ROOM, 'scan_frame_id': 'base_footprint'}, 'scan_frame_id'),
    ('/', {'map_file': ROOM, 'scan_frame_id': 'map'}, 'scan_frame_id'),
    ('/', {'map_file': ROOM, 'robots': ['r1', 'r2'], 'scan_frame_id': 'odom'}, 'scan_frame_id'),
])
def test_a_bad_frame_at_start_is_refused_by_name(ros_context, namespace, params, named):
    with pytest.raises(ParameterError) as info:
        UnicycleSim(namespace=namespace, context=ros_context,
                    parameter_overrides=overrides(**params))
    assert f"parameter '{named}'" in str(info.value)


@pytest.mark.parametrize('params', [{'odom_frame_id': '/map'}, {'initial_poses': [0.0]}])
def test_a_simulator_refused_at_start_leaves_no_node_behind(graph, params):
    # Refused after its parameter callbacks were attached (reference cycles), a node waited
    # for the garbage collector, which once collected it in the workers that test_flake8's
    # pool had forked from the pytest process: its DDS handles crashed them, and the pool
    # waited forever for their results.
    with pytest.raises(ParameterError):
        UnicycleSim(namespace='/refused', context=graph.context,
                    parameter_overrides=overrides(**params))
    observer = graph.probe('observer', use_sim_time=False, listen_only=True)
    assert not [name for name, namespace in observer.get_node_names_and_namespaces()
                if namespace == '/refused']


@pytest.mark.parametrize('namespace, params, expected', [
    # In /robot1 these are two frames: base_footprint -> robot1/base_footprint.
    ('/robot1', {'odom_frame_id': 'base_footprint'}, ('base_footprint', 'robot1/base_footprint')),
    ('/', {'odom_frame_id': 'map', 'base_frame_id': 'base_link'}, ('map', 'base_link')),
])
def test_distinct_frames_start(graph, namespace, params, expected):
    sim = graph.add_clock_owner(UnicycleSim(
        stepped=True, namespace=namespace, context=graph.context, parameter_overrides=overrides(
            publish_clock=True, lockstep=False, **params)))
    assert sim.robots[0].frames == expected


def test_a_real_time_factor_without_publish_clock_is_said_to_do_nothing(graph, capfd):
    graph.sim(stepped=False, publish_clock=False, real_time_factor=5.0)  # it was silent
    assert ', in real time (real_time_factor 5 needs publish_clock:=true)' in \
        capfd.readouterr().err


def test_a_simulator_with_a_bad_frame_on_its_command_line_exits_2_naming_it(run_main):
    # Every refusal of a frame is tested in-process above: the executable's main() shows the
    # path from -p to exit 2 once, with the value that the command line hands over as one word
    # (test_faults.py shows main()'s return as the exit code of a process once per package).
    named = 'base_frame_id'
    code, output = run_main(node_module.main, 'unicycle_sim', '--ros-args', '-p',
                            'base_frame_id:=base link')
    assert code == 2 and f"parameter '{named}'" in output, output
    assert 'Traceback' not in output


# -- frames set live ---------------------------------------------------------------------------

@pytest.mark.parametrize('name, text', [
    ('odom_frame_id', 'base_footprint'),
    ('base_frame_id', 'odom'),
    ('odom_frame_id', "''"),
    ('odom_frame_id', "'  '"),
    ('base_frame_id', "'base link'"),
    ('odom_frame_id', '/map'),
])
def test_a_bad_frame_set_live_is_refused_by_name_and_the_frames_stay(graph, name, text):
    sim = graph.sim()
    probe = graph.probe()
    client = probe.create_client(SetParameters, '/unicycle_sim/set_parameters')
    graph.step_for(0.1)
    assert frames(probe.odom) == ('odom', 'base_footprint')
    result = set_param(graph, client, name, text)
    assert not result.successful
    assert f"parameter '{name}'" in result.reason
    seen = len(probe.odoms)
    graph.step_for(0.1)
    assert {frames(o) for o in probe.odoms[seen:]} == {('odom', 'base_footprint')}
    assert (sim.params.odom_frame_id, sim.params.base_frame_id) == ('odom', 'base_footprint')
    # A refusal does not stick: a good frame is taken next.
    assert set_param(graph, client, 'odom_frame_id', 'map').successful
    graph.step()
    assert frames(probe.odom) == ('map', 'base_footprint')


def test_a_frame_set_live_is_compared_with_the_maps(graph):
    sim = graph.sim(map_file=ROOM, initial_x=0.5, initial_y=0.3)
    for name in ('odom_frame_id', 'base_frame_id'):
        result = sim.set_parameters([Parameter(name, value='map')])[0]
        assert not result.successful and f"parameter '{name}'" in result.reason
        result = sim.set_parameters([Parameter(name, value='base_scan')])[0]
        assert not result.successful and "as 'scan_frame_id'" in result.reason
    graph.step()
    assert frames(graph.odom()) == ('odom', 'base_footprint')


def test_a_frame_set_live_is_compared_as_the_robots_publish_it(graph):
    sim = graph.sim(robots=['robot1', 'robot2'])
    probe = graph.probe()
    client = probe.create_client(SetParameters, '/unicycle_sim/set_parameters')
    graph.step()
    # base_footprint becomes robot1/base_footprint: the robot's base frame.
    result = set_param(graph, client, 'odom_frame_id', 'base_footprint')
    assert not result.successful and "parameter 'odom_frame_id'" in result.reason
    graph.step()
    assert frames(graph.odom('robot2')) == ('robot2/odom', 'robot2/base_footprint')
    # Set together, the two frames may swap: each is checked against the other's new value.
    result = sim.set_parameters_atomically(overrides(
        odom_frame_id='base_footprint', base_frame_id='odom'))
    assert result.successful, result.reason
    graph.step()
    assert frames(graph.odom('robot2')) == ('robot2/base_footprint', 'robot2/odom')


# -- a second clock owner ----------------------------------------------------------------------

LOOK_S = 0.1  # how often a clock owner looks for others in these tests [s, wall]


@pytest.fixture
def looks_often(monkeypatch):
    """Have a clock owner look for others every 0.1 s (once a wall second as shipped)."""
    monkeypatch.setattr(clock_module, '_OWNERS_CHECK_S', LOOK_S)


def clock_owner(graph, namespace, logs):
    """Add a simulator in namespace that owns /clock on its own wall timer; log into logs."""
    sim = UnicycleSim(namespace=namespace, context=graph.context, parameter_overrides=overrides(
        publish_clock=True, lockstep=False, real_time_factor=1.0))
    sim.get_logger = lambda: logs
    return graph.add(sim)


# A clock topic of this test run alone: a simulator that another test left on /clock cannot make
# a lone owner warn or keep one from seeing itself alone again.
_CLOCK = f'/sim_checks_{os.getpid()}/clock'


def stepped_owner(graph):
    """Add a simulator that the graph steps, on the clock topic _CLOCK."""
    return graph.add_clock_owner(UnicycleSim(
        stepped=True, context=graph.context, cli_args=['--ros-args', '-r', f'/clock:={_CLOCK}'],
        parameter_overrides=overrides(publish_clock=True, lockstep=False)))


def step_wall(graph, seconds, until=lambda: False):
    """
    Step the graph for seconds of wall time, or until until() holds; return until().

    A step every millisecond or so: hundreds of steps per look (LOOK_S), not a core spent.
    """
    deadline = time.monotonic() + seconds
    while not until() and time.monotonic() < deadline:
        graph.step()
        time.sleep(0.001)
    return until()


def test_two_simulators_on_one_clock_each_warn_once(graph, looks_often):
    first, second = Logs(), Logs()
    clock_owner(graph, '/robot1', first)
    clock_owner(graph, '/robot2', second)
    assert graph.spin_until(
        lambda: first.clock_warnings() and second.clock_warnings(), timeout=10.0), (
        first.lines, second.lines)
    graph.spin_for(3 * LOOK_S)  # two more looks at the graph at least
    for logs, namespace in ((first, '/robot1'), (second, '/robot2')):
        warnings = logs.clock_warnings()
        assert len(warnings) == 1, warnings
        assert 'nodes publish on /clock (' in warnings[0]
        assert '/robot1/unicycle_sim' in warnings[0] and '/robot2/unicycle_sim' in warnings[0]
        assert 'interleave' in warnings[0]
        assert f'-r /clock:={namespace}/clock' in warnings[0]


def test_the_warning_comes_again_only_after_the_other_owner_left_and_came_back(
        graph, monkeypatch, looks_often):
    sim = stepped_owner(graph)
    logs = Logs()
    monkeypatch.setattr(sim, 'get_logger', lambda: logs)
    other = Node('other_clock', context=graph.context)
    try:
        publisher = other.create_publisher(ClockMsg, _CLOCK, 1)
        assert step_wall(graph, 10.0, lambda: logs.clock_warnings())
        step_wall(graph, 3 * LOOK_S)
        assert len(logs.clock_warnings()) == 1
        assert f'2 nodes publish on {_CLOCK}' in logs.clock_warnings()[0]
        assert '/other_clock' in logs.clock_warnings()[0]
        other.destroy_publisher(publisher)
        step_wall(graph, 3 * LOOK_S)  # the simulator saw itself alone again
        assert len(logs.clock_warnings()) == 1
        other.create_publisher(ClockMsg, _CLOCK, 1)
        assert step_wall(graph, 10.0, lambda: len(logs.clock_warnings()) == 2)
        step_wall(graph, 3 * LOOK_S)
        assert len(logs.clock_warnings()) == 2
    finally:
        other.destroy_node()


def test_a_lone_clock_owner_does_not_warn_and_looks_at_its_pace_not_every_step(
        graph, monkeypatch, looks_often):
    sim = stepped_owner(graph)
    logs = Logs()
    monkeypatch.setattr(sim, 'get_logger', lambda: logs)
    looks = []
    look = sim.get_publishers_info_by_topic
    monkeypatch.setattr(sim, 'get_publishers_info_by_topic',
                        lambda topic, **kwargs: looks.append(topic) or look(topic, **kwargs))
    start = time.monotonic()
    step_wall(graph, 5 * LOOK_S)
    seconds = time.monotonic() - start
    assert logs.clock_warnings() == [] and not [
        text for level, text in logs.lines if level == 'warning'], logs.lines
    clock_looks = [topic for topic in looks if topic == _CLOCK]
    # Once per interval of wall time, however many steps: not once per step (a look a step
    # would be more looks than the bound below).
    assert graph.steps > 2 * (seconds / LOOK_S + 1), graph.steps
    assert 2 <= len(clock_looks) <= seconds / LOOK_S + 1, (clock_looks, graph.steps)


# -- a message that never comes ----------------------------------------------------------------

LATE_TIMEOUT_S = 0.4


def never_graph(graph, name, lockstep_timeout=LATE_TIMEOUT_S):
    """
    Return (the simulator's Logs, 'ghost', its Participant): a simulator owning a clock.

    lockstep_timeout (0.4 s) above the longest wait between two re-sent /clock (0.32 s), at
    which a participant held up answers again, so that it is not taken for a silent one.
    """
    clock = f'/{name}_{os.getpid()}/clock'
    remap = ['--ros-args', '-r', f'/clock:={clock}']
    sim = UnicycleSim(namespace=f'/{name}', context=graph.context, cli_args=remap,
                      parameter_overrides=overrides(publish_clock=True, real_time_factor=20.0,
                                                    lockstep_timeout=lockstep_timeout))
    logs = Logs()
    sim.get_logger = lambda: logs
    graph.add(sim)
    ghost = graph.add(Node('ghost', namespace=f'/{name}', context=graph.context, cli_args=remap,
                           parameter_overrides=overrides(use_sim_time=True)))
    lockstep = take_part(ghost)
    assert graph.spin_until(lambda: any('takes part' in text for _, text in logs.lines), 10.0)
    return logs, ghost, lockstep


def test_a_message_that_never_comes_is_forgiven_naming_the_publishers_discovered(graph):
    # A participant counts a command that no publisher of the simulator's discovery sent (as
    # when the simulator has not matched its writer yet), then one from a publisher it knows.
    logs, ghost, lockstep = never_graph(graph, 'never')
    counter = lockstep.counter

    def forgiven():
        return [text for level, text in logs.lines
                if level == 'warning' and 'going on without those' in text]
    counter.sent['/never/cmd_vel'] = 1  # counted, never published
    assert graph.spin_until(lambda: forgiven(), 10.0), logs.lines
    # Not before three lockstep_timeouts: from a writer not discovered, it may still come.  The
    # step was held from its /clock on, which on a busy machine can come before this test's
    # line above has run: the simulator's own count, not this test's clock, is the measure.
    held = re.search(r' within ([0-9.]+) s; going on without those message\(s\) '
                     r'\(no publisher of /never/cmd_vel discovered here\)$', forgiven()[0])
    assert held, forgiven()
    assert float(held.group(1)) >= round(UNDISCOVERED_TIMEOUTS * LATE_TIMEOUT_S, 1)  # as said
    said = [text for _, text in logs.lines]
    bound = f'not lost (waited for up to {UNDISCOVERED_TIMEOUTS * LATE_TIMEOUT_S:g} s)'
    waited = next(k for k, text in enumerate(said) if bound in text)
    assert waited < said.index(forgiven()[0])
    publisher = ghost.create_publisher(Twist, 'cmd_vel', 10)
    assert graph.spin_until(lambda: ghost.count_subscribers('/never/cmd_vel') == 1, 10.0)
    assert graph.spin_until(lambda: publisher.get_subscription_count() == 1, 10.0)
    counter.sent['/never/cmd_vel'] += 1  # the publisher is wrapped: counted, never published
    assert graph.spin_until(lambda: len(forgiven()) == 2, 10.0), logs.lines
    assert forgiven()[1].endswith('(publishers of /never/cmd_vel discovered here: /never/ghost)')


def test_a_message_from_a_writer_not_discovered_yet_is_waited_for(graph):
    # On a lossy link a motion matched the simulator's cmd_vel reader and sent, seconds before
    # the simulator matched its writer: the command came late, after it had been forgiven with
    # a warning (test_two_hosts, once in 86 runs with four pytest workers).  Now the clock is
    # held for it, and it lands at its step.
    # 1 s: the writer is made and discovered within the two seconds left before the bound.
    logs, ghost, lockstep = never_graph(graph, 'late', lockstep_timeout=1.0)
    counter = lockstep.counter
    counter.sent['/late/cmd_vel'] = 1  # sent from a writer the simulator has not discovered
    assert graph.spin_until(lambda: any('no publisher of it discovered here yet' in text
                                        for _, text in logs.lines), 10.0), logs.lines
    held_ns = ghost.get_clock().now().nanoseconds
    # The writer is discovered, and its message comes: the clock goes on, nothing forgiven.
    courier = graph.add(Node('courier', namespace='/late', context=graph.context))
    late = courier.create_publisher(Twist, 'cmd_vel', 10)
    assert graph.spin_until(lambda: late.get_subscription_count() == 1, 10.0)
    late.publish(Twist())
    assert graph.spin_until(lambda: ghost.get_clock().now().nanoseconds > held_ns, 10.0)
    assert not [text for level, text in logs.lines if level == 'warning'], logs.lines


def test_a_message_from_a_sender_that_left_and_is_gone_is_not_waited_for_long(graph):
    # A simulator started under a running motion (a restart): the motion stopped the robot
    # before the new simulator had matched its writer, said goodbye and exited.  Its stop could
    # not come any more, yet the clock was held three lockstep_timeouts for it
    # (test_interrupts' restart, once in 24 runs beside a busy loop).  Now one.
    logs, ghost, lockstep = never_graph(graph, 'gone', lockstep_timeout=1.0)
    lockstep.counter.sent['/gone/cmd_vel'] = 1  # the stop, from a writer never discovered
    assert lockstep.leave()
    graph.remove(ghost)

    def forgiven():
        return [text for level, text in logs.lines
                if level == 'warning' and 'going on without those' in text]
    assert graph.spin_until(lambda: forgiven(), 10.0), logs.lines
    held = re.search(r' within ([0-9.]+) s; going on without those message\(s\) \(no publisher '
                     r'of /gone/cmd_vel discovered here; /gone/ghost left and is gone\)$',
                     forgiven()[0])
    assert held, forgiven()
    assert 1.0 <= float(held.group(1)) < UNDISCOVERED_TIMEOUTS * 1.0


@contextmanager
def other_type_teleop(domain_id):
    """
    Yield a node of a context (a DDS participant) of its own, as another process would be.

    It publishes TwistStamped (Nav2's cmd_vel on Jazzy) on robot b's cmd_vel and only subscribes
    to it on robot a's.  One participant cannot hold two types on one topic; another can, in
    this process or in another: the simulator sees only what discovery tells it.
    """
    with held_context(domain_id=domain_id) as context:
        node = Node('stamped_teleop', context=context, enable_rosout=False)
        try:
            node.create_subscription(TwistStamped, '/a/cmd_vel', lambda msg: None, 10)
            node.create_publisher(TwistStamped, '/b/cmd_vel', 10)
            yield node
        finally:
            node.destroy_node()


def test_a_publisher_of_another_type_on_a_robots_cmd_vel_is_named_once(
        graph, capfd, monkeypatch):
    monkeypatch.setattr(node_module, 'TYPE_CHECK_S', 0.2)
    graph.sim(robots=['a', 'b'])
    log = []

    def warnings():
        log.append(capfd.readouterr().err)
        return [line for line in ''.join(log).splitlines() if 'never arrive' in line]
    with other_type_teleop(graph.context.get_domain_id()):
        deadline = time.monotonic() + 15.0
        while not warnings() and time.monotonic() < deadline:
            graph.step()
            graph.spin_for(0.05)
        for _ in range(10):  # 0.5 s more, the graph looked at again: no second warning
            graph.step()
            graph.spin_for(0.05)
    assert len(warnings()) == 1, log
    assert ('b: A publisher on /b/cmd_vel sends geometry_msgs/msg/TwistStamped, but this '
            'simulator takes geometry_msgs/msg/Twist (stamped:=true takes it)') in warnings()[0]


HALTED = 'import of {} halted; None in sys.modules'


@pytest.mark.parametrize('parameter,value,module,package,why', [
    ('record_file', 'run.mcap', 'mcap', 'mcap',
     "No module named 'mcap.well_known'; 'mcap' is not a package"),
    ('foxglove_port', 8765, 'foxglove', 'foxglove-sdk', HALTED.format('foxglove')),
    ('view_port', 9090, 'rerun', 'rerun-sdk', HALTED.format('rerun')),
])
def test_without_its_package_a_tap_is_named_and_the_simulator_runs(
        graph, capfd, monkeypatch, tmp_path, parameter, value, module, package, why):
    # As if never installed, whatever an earlier test imported: the package, its submodules
    # and the tap modules that hold them go from sys.modules (monkeypatch puts them back).
    held = (f'{module}.', 'sim_diffdrive.taps.')
    for name in [name for name in sys.modules if name.startswith(held)]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, module, None)
    if parameter == 'record_file':
        value = str(tmp_path / value)
    sim = graph.sim(**{parameter: value})
    graph.step_for(1.0)
    assert not sim.taps
    assert len(graph.odometry.odoms) >= 50  # it runs on
    output = capfd.readouterr().err
    assert (f'{parameter} needs the Python package {package} ({why}); pip install {package}. '
            'Running without it.') in output, output
    if parameter == 'record_file':
        assert not os.path.exists(value)
