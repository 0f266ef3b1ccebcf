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
motion_fleet: one motion per robot in one process, each in its robot's namespace.

In this process (build_fleet in a SimGraph) every robot ends at its analytic pose from its own
start; as processes (the motion_fleet executable with the shipped params file against the
simulator), likewise from each robot's odometry, and Ctrl-C leaves every robot stopped.  A
simulator killed mid-motion stops every motion, and the fleet names each robot left unheard.
Parameter mistakes are refused with exit code 2 and the parameter named.
"""

from contextlib import contextmanager
import math
from pathlib import Path
import re
import signal

from motion_challenges import motion_fleet
from motion_challenges.circle_back_and_forth import CircleBackAndForth
from motion_challenges.motion_fleet import build_fleet
from motion_challenges.motion_fleet import fleet_plan
from motion_challenges.motion_fleet import motion_classes
from motion_challenges.motion_fleet import MotionFleet
from motion_challenges.motion_node import DONE
from motion_challenges.odom_out_and_back import OdomOutAndBack
from motion_challenges.plans import out_and_back_end
from motion_challenges.prompts import RotationRequest
from motion_challenges.rotate_robot import RotateRobot
from motion_challenges.timed_out_and_back import TimedOutAndBack
import pytest
from rclpy.parameter import Parameter
from sim_diffdrive.dds_teardown import held_context
from sim_diffdrive.harness import angle_error
from sim_diffdrive.harness import is_moving
from sim_diffdrive.harness import isolated_domain_id
from sim_diffdrive.harness import pose_of
from sim_diffdrive.harness import ros_params
from sim_diffdrive.harness import stamp_s
from sim_diffdrive.harness import stop
from sim_diffdrive.parameters import ParameterError
import yaml

CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'motion_fleet.yaml'
EXACT = 1e-9  # [m] and [rad]: what lockstep gives, in one process or across several
# Short motions: one 0.3 m leg and a half turn; a half turn on the spot; one 1 s arc and back.
SHORT = {'goal_distance': 0.3, 'pause': 0.1, 'legs': 1, 'half_period': 1.0, 'cycles': 1,
         'angular_speed_deg': 90.0, 'angle_deg': 180.0, 'clockwise': True}


def start_of(i):
    """Return robot i's start pose (x, y, yaw): each robot somewhere else, facing elsewhere."""
    return (1.0 + i, 0.5 * i, 0.3 * (i + 1))


def end_of(motion, start):
    """Return where motion (with SHORT's parameters) leaves a robot that started at start."""
    x, y, yaw = start
    if motion in ('odom_out_and_back', 'timed_out_and_back'):
        return out_and_back_end((x, y, yaw), SHORT['goal_distance'], math.pi, SHORT['legs'])
    if motion == 'rotate_robot':
        return x, y, yaw - math.radians(SHORT['angle_deg'])
    return start  # circle_back_and_forth: out along the arc and back


def assert_at(odom, expected, output=''):
    x, y, yaw = pose_of(odom)
    assert math.hypot(x - expected[0], y - expected[1]) < EXACT, output
    assert angle_error(yaw, expected[2]) < EXACT, output


# -- the plan: names and motions -------------------------------------------------------------


def test_motion_classes_are_the_four_motions():
    assert motion_classes() == {
        'rotate_robot': RotateRobot, 'circle_back_and_forth': CircleBackAndForth,
        'timed_out_and_back': TimedOutAndBack, 'odom_out_and_back': OdomOutAndBack}


def test_plan_puts_each_robot_in_its_namespace_with_one_motion_for_all_or_one_each():
    assert fleet_plan(['robot1', 'site_a/robot2'], ['rotate_robot']) == [
        ('robot1', '/robot1', 'rotate_robot'), ('site_a/robot2', '/site_a/robot2', 'rotate_robot')]
    assert fleet_plan(['a', 'b'], ['rotate_robot', 'odom_out_and_back'], '/site') == [
        ('a', '/site/a', 'rotate_robot'), ('b', '/site/b', 'odom_out_and_back')]


@pytest.mark.parametrize('robots,motions,words', [
    ([], ['rotate_robot'], ["'robots'", 'at least one']),
    (['robot1', 'robot1'], ['rotate_robot'], ["'robots'", "'robot1' twice"]),
    (['robot-1'], ['rotate_robot'], ["'robots'", "'robot-1'", 'not a valid ROS name']),
    (['1robot'], ['rotate_robot'], ["'robots'", "'1robot'"]),
    (['/robot1'], ['rotate_robot'], ["'robots'", 'relative', "'/robot1'"]),
    (['a/'], ['rotate_robot'], ["'robots'", "'a/'"]),
    (['a', 'b', 'c'], ['rotate_robot', 'odom_out_and_back'], ["'motions'", 'one per robot (3)']),
    (['a'], [], ["'motions'", 'got 0']),
    (['a', 'b'], ['rotate_robot', 'dance'], ["'motions'", "'dance'", 'odom_out_and_back']),
])
def test_plan_refuses_what_cannot_run_and_names_the_parameter(robots, motions, words):
    with pytest.raises(ParameterError) as error:
        fleet_plan(robots, motions)
    for word in words:
        assert word in str(error.value)


# -- in this process: build_fleet against the simulator ---------------------------------------


def closing_line(output):
    """Return a motion's closing line ('Done in ...') from its output, or its last error line."""
    lines = output.splitlines()
    for line in reversed(lines):
        if DONE in line:
            return line
    return next((line for line in reversed(lines) if '[ERROR]' in line or 'Error' in line),
                lines[-1] if lines else '')


def initial_poses(robots):
    """Return unicycle_sim's initial_poses: robot i at start_of(i)."""
    return [v for i in range(len(robots)) for v in start_of(i)]


def test_four_motions_in_one_executor_each_end_at_their_own_robots_goal(graph):
    robots = ['robot1', 'robot2', 'robot3', 'site_a/robot4']
    motions = ['odom_out_and_back', 'timed_out_and_back', 'rotate_robot',
               'circle_back_and_forth']
    graph.sim(robots=robots, initial_poses=initial_poses(robots))
    nodes = build_fleet(graph.context, robots, motions, use_sim_time=True, **SHORT)
    for node in nodes:
        graph.add(node)
    assert [node.get_fully_qualified_name() for node in nodes] == [
        f'/{robot}/{motion}' for robot, motion in zip(robots, motions)]
    assert [node.cmd_pub.topic_name for node in nodes] == [f'/{r}/cmd_vel' for r in robots]
    graph.step_until(lambda: all(node.done for node in nodes), sim_timeout=30.0)
    graph.step_for(0.2)
    for i, (node, robot, motion) in enumerate(zip(nodes, robots, motions)):
        assert node.exit_code == 0, motion
        assert not is_moving(graph.odom(robot)), motion
        assert_at(graph.odom(robot), end_of(motion, start_of(i)), motion)


def test_rotate_robot_in_a_fleet_asks_nothing_and_refuses_without_its_answers(ros_context):
    with pytest.raises(ParameterError) as error:
        build_fleet(ros_context, ['robot1'], ['rotate_robot'], angle_deg=90.0)
    assert "'robot1' (rotate_robot)" in str(error.value)
    assert 'angular_speed_deg, clockwise' in str(error.value)
    assert 'asks nothing' in str(error.value)


def test_a_motions_own_bad_parameter_names_the_robot_and_the_parameter(ros_context):
    with pytest.raises(ParameterError) as error:
        build_fleet(ros_context, ['robot1', 'robot2'], ['timed_out_and_back'],
                    goal_distance=-1.0)
    assert "robot 'robot1' (timed_out_and_back): parameter 'goal_distance'" in str(error.value)


@contextmanager
def fleet_in(args):
    """Build MotionFleet and its motions in a context with args as the process's arguments."""
    with held_context(args, isolated_domain_id()) as context:
        fleet = MotionFleet(context=context)
        nodes = fleet.build()
        try:
            yield fleet, nodes
        finally:
            for node in (*nodes, fleet):
                node.destroy_node()


def test_the_shipped_params_file_reaches_every_node_and_one_robots_section_only_it(capfd):
    with fleet_in(['--ros-args', '--params-file', str(CONFIG), '-p', 'pause:=0.25']) as (
            fleet, nodes):
        odom, timed, rotate = nodes
        # Each section names only parameters that the nodes it speaks to declare.
        sections = {'/motion_fleet': [fleet], '/**': [fleet, *nodes],
                    '/**/odom_out_and_back': [odom], '/robot3/rotate_robot': [rotate]}
        document = yaml.safe_load(CONFIG.read_text())
        assert set(document) == set(sections)
        for section, addressed in sections.items():
            for name in document[section]['ros__parameters']:
                assert all(node.has_parameter(name) for node in addressed), (section, name)
        assert [n.get_fully_qualified_name() for n in nodes] == [
            '/robot1/odom_out_and_back', '/robot2/timed_out_and_back', '/robot3/rotate_robot']
        assert all(n.get_parameter('use_sim_time').value for n in nodes)  # /**
        # On sim time the fleet is one lockstep participant for all its motions.
        assert all(n.lockstep.participant is fleet.lockstep for n in nodes)
        assert (odom.params.legs, timed.params.legs) == (1, 2)  # /**/odom_out_and_back
        assert (odom.params.pause, timed.params.pause) == (0.25, 0.25)  # -p: every node
        assert rotate.request == RotationRequest(90.0, 180.0, True)  # /robot3/rotate_robot
        # What is given to every node (-p pause, /** use_sim_time) is no node's misspelling.
        assert 'Ignoring parameter' not in capfd.readouterr().err


@pytest.mark.parametrize('sim_time,fleet_takes_part,own', [
    ({'/**': True, '/**/timed_out_and_back': False}, True, []),  # one motion on wall time
    ({'/**/odom_out_and_back': True}, False, ['robot1']),  # the fleet itself on wall time
    ({'/motion_fleet': True}, False, []),  # no motion on sim time: nobody takes part
])
def test_motions_on_the_fleets_clock_answer_through_it_and_others_on_their_own(
        tmp_path, sim_time, fleet_takes_part, own):
    params = tmp_path / 'params.yaml'
    params.write_text(yaml.safe_dump({section: {'ros__parameters': {'use_sim_time': value}}
                                      for section, value in sim_time.items()}))
    with fleet_in([
            '--ros-args', '-p', 'robots:=[robot1,robot2]',
            '-p', 'motions:=[odom_out_and_back,timed_out_and_back]', '--params-file',
            str(params)]) as (fleet, nodes):
        assert (fleet.lockstep is not None) == fleet_takes_part
        robots = dict(zip(['robot1', 'robot2'], nodes))
        assert [robot for robot, node in robots.items()
                if node.lockstep is not None and node.lockstep is not fleet.lockstep
                and getattr(node.lockstep, 'participant', None) is None] == own
        for node in nodes:
            assert (node.lockstep is not None) == node.get_parameter('use_sim_time').value
            if fleet_takes_part and node.lockstep is not None:
                assert node.lockstep.participant is fleet.lockstep


@pytest.mark.parametrize('live,files', [
    (None, ['fleet_site_a_robot1.png', 'fleet_robot2.png']),
    ('', ['fleet.png', '']),  # set live on robot2: no plot, and robot1's file is its own
])
def test_a_fleet_plots_each_robot_to_a_file_of_its_own_after_its_goodbye(
        tmp_path, monkeypatch, live, files):
    # -p plot_file:= reaches every motion: each robot's plot overwrote the one before.  And a
    # motion drew its plot as it ended, in the fleet's lockstep: it held every robot's clock,
    # past a lockstep_timeout of 0.3 s, and the others failed.
    written = []
    monkeypatch.setattr(motion_fleet, 'write_plot', lambda node, path: written.append(
        (node.get_namespace(), path, fleet.lockstep.left)))
    with fleet_in(['--ros-args', '-p', 'robots:=[site_a/robot1,robot2]', '-p',
                   'use_sim_time:=true', '-p', 'motions:=[timed_out_and_back]', '-p',
                   f'plot_file:={tmp_path}/fleet.png']) as (fleet, nodes):
        if live is not None:
            nodes[1].set_parameters([Parameter('plot_file', value=live)])
        for node in nodes:
            node.shutdown_hook()
        assert written == []
        fleet.shutdown_hook()
    assert written == [(namespace, f'{tmp_path}/{name}' if name else '', True)
                       for namespace, name in zip(('/site_a/robot1', '/robot2'), files)]


def test_a_namespace_given_to_the_process_comes_before_every_robots():
    # A global -r __ns:= would put every node of the process in one namespace under one name.
    with fleet_in([
            '--ros-args', '-r', '__ns:=/site', '-r', '__node:=renamed',
            '-p', 'robots:=[robot1,robot2]', '-p', 'motions:=[timed_out_and_back]']) as (
            fleet, nodes):
        assert fleet.get_fully_qualified_name() == '/site/renamed'
        assert [n.get_fully_qualified_name() for n in nodes] == [
            '/site/robot1/timed_out_and_back', '/site/robot2/timed_out_and_back']
        assert [n.cmd_pub.topic_name for n in nodes] == [
            '/site/robot1/cmd_vel', '/site/robot2/cmd_vel']


# -- as processes: motion_fleet against one unicycle_sim for all robots ----------------------

ROBOTS = ['robot1', 'robot2', 'robot3']


def simulator(procs, graph, *params, robots=ROBOTS):
    """Start one unicycle_sim for robots, robot i at start_of(i); return it and a watcher each."""
    poses = ','.join(repr(float(v)) for v in initial_poses(robots))
    # The factor bounds lockstep's pace, and is the pace while nobody takes part (at startup,
    # once the motions left): 10x, not 50x, as a simulator of three robots freewheeling at 50x
    # takes about half a core (a quarter at 10x), and these motions are short (the same wall
    # time at either, 2.7-2.9 s for the params-file test, 0.6 CPU s less).
    sim = procs('unicycle_sim', 'unicycle_sim', *ros_params(
        'publish_clock:=true', 'real_time_factor:=10.0', f'robots:=[{",".join(robots)}]',
        f'initial_poses:=[{poses}]', *params))
    watchers = [graph.listener(robot) for robot in robots]
    assert graph.spin_until(lambda: all(w.odom is not None for w in watchers), 20.0), \
        'no odometry from the simulator(s)'
    return sim, watchers


def wait_for_exit(graph, process, timeout=60.0):
    assert graph.spin_until(lambda: process.poll() is not None, timeout), process.describe()
    return process.returncode, process.output()


def later_odometry(graph, watchers, seconds=0.2, since_s=None):
    """
    Let every robot's odometry run on by seconds of simulated time; return the latest.

    From since_s [s, simulated], or else from the latest each watcher has heard: a watcher on
    wall time can be behind by more than seconds (a fraction of them in wall time).
    """
    stamps = [stamp_s(w.odom) if since_s is None else since_s for w in watchers]
    assert graph.spin_until(lambda: all(w.stamp_s > s + seconds
                                        for w, s in zip(watchers, stamps)), 10.0)
    return [w.odom for w in watchers]


# Every refusal's wording is tested in process above; motion_fleet's main() shows the path to
# exit 2 for a mistake in the plan and for one in a motion's own parameters, in this process
# (run_main: the same main(), the same run(), no process start-up).  That a console script's
# exit code is its main()'s return is shown by the processes of test_faults.py and by this
# module's motion_fleet processes below (exit 0); the installed scripts name these main()s
# (test_colcon_layout.py).
def test_a_plan_mistake_exits_2_and_names_the_parameter(run_main):
    code, output = run_main(motion_fleet.main, 'motion_fleet', *ros_params())
    assert code == 2, output
    assert "parameter 'robots' must name at least one robot" in output
    assert 'Traceback' not in output


def test_a_motions_own_parameter_mistake_exits_2_and_names_robot_and_parameter(run_main):
    code, output = run_main(motion_fleet.main, 'motion_fleet', *ros_params(
        'robots:=[robot1]', 'motions:=[rotate_robot]', 'angle_deg:=90.0'))
    assert code == 2, output
    for word in ("robot 'robot1' (rotate_robot)", 'angular_speed_deg, clockwise'):
        assert word in output
    assert 'Traceback' not in output


# One simulator process for every process check below, one after the other on the same robots
# (a process start-up, and a simulator freewheeling on its own, saved each time): the fleet from
# the shipped params file, exact; a fleet stopped with Ctrl-C while the simulator runs; then a
# fleet whose simulator is killed under it.
def test_three_robots_from_the_shipped_params_file_each_end_exact_then_ctrl_c_and_a_dead_sim(
        graph, procs):
    # The simulator keeps each last command for ever: only the motions' final stops stop them.
    sim, watchers = simulator(procs, graph, 'cmd_vel_timeout:=0.0')
    params_file_fleet_ends_exact(graph, procs, sim, watchers)
    ctrl_c_stops_every_robot(graph, procs, watchers)
    a_dead_simulator_stops_every_motion_and_is_named_per_robot(graph, procs, sim, watchers)


def params_file_fleet_ends_exact(graph, procs, sim, watchers):
    fleet = procs('motion_fleet', 'motion_fleet', '--ros-args', '--params-file', str(CONFIG),
                  *ros_params('goal_distance:=0.3', 'pause:=0.1', 'legs:=1')[1:])
    code, output = wait_for_exit(graph, fleet)
    assert code == 0, output
    motions = ['odom_out_and_back', 'timed_out_and_back', 'rotate_robot']
    assert ('Motions: robot1 odom_out_and_back: exit code 0; robot2 timed_out_and_back: '
            'exit code 0; robot3 rotate_robot: exit code 0') in output
    # At rest from the fleet's goodbye on, the final stops heard before it (in lockstep).
    assert graph.spin_until(lambda: 'left at' in sim.output(), 10.0), sim.describe()
    left_s = float(re.search(r'left at ([0-9.]+) s', sim.output()).group(1))
    ends = later_odometry(graph, watchers, since_s=left_s)
    for i, (robot, motion, odom) in enumerate(zip(ROBOTS, motions, ends)):
        lines = [line for line in output.splitlines() if f'[{robot}.{motion}]' in line]
        closing = closing_line('\n'.join(lines))
        assert 'Done in' in closing, output
        assert 'error 0.000 mm' in closing or 'error 0.0000 deg' in closing, closing
        assert not is_moving(odom), closing
        assert_at(odom, end_of(motion, start_of(i)), closing)
    # The fleet took part as one: one answer a step for its three motions, and one goodbye.
    sim_output = sim.output()
    assert re.findall(r'Lockstep: (\S+) takes part from .*; (\d+) participant', sim_output) \
        == [('/motion_fleet', '1')], sim_output
    assert re.findall(r'Lockstep: (\S+) left at', sim_output) == ['/motion_fleet'], sim_output


def ctrl_c_stops_every_robot(graph, procs, watchers):
    fleet = procs('motion_fleet', 'motion_fleet', *ros_params(
        f'robots:=[{",".join(ROBOTS)}]', 'motions:=[circle_back_and_forth]', sim_time=True))
    assert graph.spin_until(lambda: all(w.moving for w in watchers), 20.0), \
        fleet.describe()
    output = stop(fleet, signal.SIGINT)
    assert fleet.returncode == 0, output
    assert 'Interrupted by the user' in output
    assert output.count('circle_back_and_forth: stopped before the end') == len(ROBOTS)
    # Judged from the odometry that arrives after the exit: messages the test has not taken
    # yet while it waited for the exit may still show the robot moving before its stop.

    def after_rest(watcher):
        later = watcher.after(fleet.exited_at)
        rest = next((i for i, odom in enumerate(later) if not is_moving(odom)), len(later))
        return later[rest:]
    assert graph.spin_until(lambda: all(len(after_rest(w)) >= 10 for w in watchers), 10.0), \
        [w.odom for w in watchers]
    for robot, watcher in zip(ROBOTS, watchers):
        stopped = after_rest(watcher)
        assert not any(is_moving(odom) for odom in stopped), robot
        assert len({pose_of(odom) for odom in stopped}) == 1, robot


def a_dead_simulator_stops_every_motion_and_is_named_per_robot(graph, procs, sim, watchers):
    # A second fleet (a node name of its own, so that it takes part under its own name) drives
    # the robots again, and the simulator is killed mid-motion.  On sim time an open-loop
    # motion's ticks come with the clock: with its simulator killed, timed_out_and_back waited
    # for its next tick forever, silent (found running it as a user).  Each motion notices by
    # itself (odom_timeout, 1 s), stops its robot and fails.  The simulator's subscriptions
    # stay in discovery for seconds (its lease), so nothing acknowledges the final stops.
    orphaned = procs('motion_fleet_orphaned', 'motion_fleet', *ros_params(
        f'robots:=[{",".join(ROBOTS)}]', 'motions:=[circle_back_and_forth]',
        sim_time=True), '-r', 'motion_fleet:__node:=motion_fleet_orphaned')
    assert graph.spin_until(lambda: all(w.moving for w in watchers), 20.0), \
        orphaned.describe()
    # The graph's nodes go first, as nothing is left to watch: destroying a node after a peer
    # on shared memory was SIGKILLed crashed the pytest worker, in Fast DDS, once in about 30
    # suite runs (docs/robustness.md, "Known gaps").
    graph.close()
    sim.send(signal.SIGKILL)
    sim.wait(10.0)
    try:
        code = orphaned.wait(10.0)
    finally:
        output = stop(orphaned)
    assert code == 1, output
    assert output.count('with no word from the simulator; stopped the robot') == len(ROBOTS), \
        output
    assert 'Motions: ' + '; '.join(f'{robot} circle_back_and_forth: exit code 1'
                                   for robot in ROBOTS) in output, output
    assert (f'Not acknowledged within 0.2 s: the final stop of {", ".join(ROBOTS)} '
            'and the lockstep goodbye (') in output, output
    assert 'Traceback' not in output and 'Done in' not in output, output
