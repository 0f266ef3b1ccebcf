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
A motion interrupted as a user meets it: killed, Ctrl-C, SIGTERM, its simulator restarted.

Ctrl-C and SIGTERM come at every phase; a closed loop's simulator is killed, or restarted.
Several scenarios run at once, each in its own ROS namespace.  Those on sim time share one
simulator process, a robot each (its ``robots`` parameter), and its lockstep, with ``/clock``
remapped into the simulator's namespace; a scenario whose simulator is killed has one of its
own.  A probe per namespace records odometry (and cmd_vel where it matters) with the wall
time it arrived.  Phases are recognised from odometry and from the motion's log.
"""

from dataclasses import dataclass
import math
import os
import re
import signal
import subprocess
import time

import pytest
from sim_diffdrive.harness import angle_error
from sim_diffdrive.harness import is_moving as moving
from sim_diffdrive.harness import pose_of
from sim_diffdrive.harness import ros_params
from sim_diffdrive.harness import stamp_s
from sim_diffdrive.harness import twist_of as twist
from sim_diffdrive.participant import take_part
from sim_diffdrive.sim.node import UnicycleSim

# Simulated seconds per wall second, and simulator steps per simulated second: a step every
# 10 ms of wall time keeps several simulators and motions within two cores.
REAL_TIME_FACTOR = 4.0
SIM_RATE_HZ = 25.0
SIM_CLOCK = ('publish_clock:=true', f'real_time_factor:={REAL_TIME_FACTOR}',
             f'rate_hz:={SIM_RATE_HZ}')
# Only the motion's own last Twist may stop the robot in the interrupt tests.
KEEP_LAST_COMMAND = 'cmd_vel_timeout:=0.0'
ROTATE = ('angular_speed_deg:=60.0', 'angle_deg:=36000.0', 'clockwise:=true')
_PREFIX = f'/interrupts_{os.getpid()}'


def ros_args(namespace, *params, sim_time=False):
    """Return --ros-args putting a node in namespace, with its /clock there too."""
    return ros_params(*params, namespace=namespace, clock=f'{namespace}/clock', sim_time=sim_time)


def watch(graph, namespace, sim_time=False, **kwargs):
    """
    Add a listening probe in namespace (arrival times recorded), on wall time.

    On sim time it takes part in the simulator's lockstep: the simulator waits for it to hear
    each step's odometry, so a busy test process never sees the robot seconds late.
    """
    kwargs.setdefault('name', 'fault_watcher')
    if not sim_time:
        return graph.probe(namespace=namespace, use_sim_time=False, listen_only=True, **kwargs)
    probe = graph.probe(namespace=namespace, listen_only=True,
                        cli_args=['--ros-args', '-r', f'/clock:={namespace}/clock'], **kwargs)
    take_part(probe)
    return probe


def odoms_with_walls(watcher):
    return list(zip(watcher.odom_walls, watcher.odoms))


def wait_all(graph, procs, timeout):
    """Spin until every process has exited; return the ones still running."""
    graph.spin_until(lambda: all(p.poll() is not None for p in procs), timeout, poll=0.01)
    return [p for p in procs if p.poll() is None]


def check_stopped(watcher, motion, problems, label, sim=None):
    """
    Check that after the motion exited the robot came to rest and stayed there.

    The simulators keep the last command (cmd_vel_timeout 0), so only the motion's final stop
    can bring the robot to rest.  It is judged from the odometry at rest that arrived after the
    exit (at_rest_since), not from a fixed delay: the motion exits once the simulator's DDS
    reader has acknowledged the stop, and on a loaded machine the simulator may handle it a
    good part of a second later.
    """
    later = watcher.after(motion.exited_at)
    resting = at_rest_since(later)
    if len(resting) < 10:
        problems.append(f'{label}: no odometry at rest after the exit'
                        + (f', twist {twist(later[-1])}' if later else ', none at all')
                        + f' ({len(watcher.odoms)} heard in all)'
                        + (f'\n{motion.describe()}\n{sim.describe()}' if sim else ''))
    elif len({pose_of(o) for o in resting}) != 1:
        problems.append(f'{label}: the robot moved after it came to rest, twist '
                        f'{twist(later[-1])}')


def at_rest_since(odoms):
    """
    Return the odometry at rest that odoms end with (after the last that shows motion).

    On a busy machine odometry from before the final stop can still arrive after the exit (a
    pause, then the start of the next segment the motion began before it handled the signal);
    a robot set moving again after the final stop is never at rest again (check_stopped).
    """
    last_moving = max((i for i, o in enumerate(odoms) if moving(o)), default=-1)
    return odoms[last_moving + 1:]


def check_clean_interrupt(proc, signum, problems, label):
    output = proc.output()
    if proc.poll() != 0:
        problems.append(f'{label}: exit code {proc.poll()}, expected 0\n{proc.describe()}')
    if 'Traceback' in output or 'Exception in' in output:
        problems.append(f'{label}: not a clean exit\n{proc.describe()}')
    said = ('Interrupted by the user' if signum == signal.SIGINT
            else f'Stopped by {signal.Signals(signum).name}')
    if said not in output:
        problems.append(f'{label}: no "{said}"\n{proc.describe()}')
    if (late := (proc.running_at or 0.0) - proc.signalled_at) > 3.0:  # seen running: no lag
        problems.append(f'{label}: running {late:.1f} s after the signal\n{proc.describe()}')


# -- SIGKILL of the controller -----------------------------------------------------------------


def test_killed_controller_is_stopped_by_the_simulator_timeout(graph, procs, capfd):
    # One controller process drives two simulators on the same cmd_vel (wall time, 50 Hz
    # odometry): one with a 0.3 s timeout, one with the timeout off (odometry remapped beside
    # it, a node name of its own).  The simulators run in this process, over DDS from the
    # controller's as from any other (what a process of its own adds, the executable's start
    # and exit, is shown in test_sim_process.py); their log is this process's output.
    namespace = f'{_PREFIX}_sigkill'
    timeout_s, period_s = 0.3, 1.0 / 50.0
    graph.add(UnicycleSim(namespace=namespace, context=graph.context, cli_args=ros_args(
        namespace, f'cmd_vel_timeout:={timeout_s}')))
    graph.add(UnicycleSim(namespace=namespace, context=graph.context, cli_args=[
        *ros_args(namespace, KEEP_LAST_COMMAND), '-r', 'odom:=odom_keep',
        '-r', '__node:=unicycle_sim_keep']))
    logged = []

    def sim_log():
        out, err = capfd.readouterr()
        logged.append(out + err)
        return ''.join(logged)
    watcher = watch(graph, namespace, record_commands=True)
    keeper = watch(graph, namespace, odom_topic='odom_keep', name='fault_watcher_keep')
    controller = procs('controller', 'circle_back_and_forth', *ros_args(
        namespace, 'half_period:=100.0'))
    assert graph.spin_until(
        lambda: watcher.moving and keeper.moving and len(watcher.commands) > 3,
        20.0), controller.describe() + sim_log()

    controller.send(signal.SIGKILL)
    # Judged by the odometry's stamps, not by when it reaches this process: on a loaded machine
    # delivery (or this process) may lag behind by a good part of a second.
    assert graph.spin_until(lambda: watcher.twist == (0.0, 0.0), 10.0), sim_log()
    assert controller.wait(10.0) == -signal.SIGKILL  # on a busy machine, not reaped at once

    # The timeout counts from when the simulator took the last command, which it logs: on a
    # busy machine that can be tens of ms after this process heard it (once 35 ms), or before,
    # so when this process heard it only checks that the logged one is about that last command.
    # (rclpy 7.1.6's EventsExecutor cannot hand a callback the sender's source timestamp.)
    pattern = (rf'No cmd_vel for {timeout_s:g} s: stopping the robot '
               r'\(the last came at (\d+\.\d{9}) s\)')
    # The stop after the kill is the last: a controller starved of the CPU for longer than the
    # timeout before it (a busy loop and a suite beside it) is rightly stopped too, and drives on
    # once its commands come again.
    heard_s = watcher.commands[-1][1]

    def last_stop():
        stops = re.findall(pattern, timed_lines())
        return float(stops[-1]) if stops else None

    def timed_lines():
        return '\n'.join(line for line in sim_log().splitlines()
                         if f'{namespace[1:]}.unicycle_sim]' in line)
    assert graph.spin_until(lambda: (last_stop() or 0.0) > heard_s - 0.4, 10.0), sim_log()
    took_s = last_stop()
    assert abs(took_s - heard_s) < 0.4, (took_s, heard_s)
    settled_s = took_s + timeout_s + 0.2
    assert graph.spin_until(lambda: watcher.stamp_s > settled_s
                            and keeper.stamp_s > settled_s, 10.0)
    last_moving = [o for o in watcher.odoms if moving(o)][-1]
    first_stopped = next(o for o in watcher.odoms
                         if stamp_s(o) > stamp_s(last_moving))
    late_s = stamp_s(last_moving) - took_s
    assert late_s <= timeout_s + period_s, (
        f'odometry shows the robot moving {late_s:.3f} s after the last cmd_vel')
    # Where it came to rest tells how long it went on: on the circle (0.5 rad/s) the heading
    # turned through what it had left until the timeout.  Judged by the pose, not by when the
    # first odometry at rest was stamped: a simulator starved on a busy machine publishes late
    # (once 0.7 s), but still stops the robot at the timeout, to the nanosecond.
    turned = angle_error(pose_of(first_stopped)[2], pose_of(last_moving)[2])
    moved_until_s = stamp_s(last_moving) + turned / 0.5
    assert moved_until_s - took_s == pytest.approx(timeout_s, abs=1e-5), (
        f'the robot moved on until {moved_until_s - took_s:.6f} s after the last cmd_vel')
    assert not any(moving(o) for o in watcher.odoms if stamp_s(o) > settled_s)

    # With the timeout off, the last command is kept, as documented.
    kept = [o for o in keeper.odoms if stamp_s(o) > settled_s]
    assert kept and all(twist(o) == (0.5, 0.5) for o in kept)
    keeping = [line for line in sim_log().splitlines() if 'unicycle_sim_keep]' in line]
    assert keeping and not [line for line in keeping if 'No cmd_vel' in line], keeping


# -- Ctrl-C and SIGTERM at every phase ---------------------------------------------------------

MOTIONS = {
    'rotate_robot': ('rotate_robot', ROTATE),
    'rotate_robot mode:=odom': ('rotate_robot', ROTATE + ('mode:=odom',)),
    'circle_back_and_forth': ('circle_back_and_forth', ()),
    'timed_out_and_back': ('timed_out_and_back', ()),
    'odom_out_and_back': ('odom_out_and_back', ()),
}
# Out-and-back legs short enough to reach the pause soon, and a pause long enough to see.
PAUSE = ('goal_distance:=0.2', 'pause:=4.0')


@dataclass
class Interruption:
    """One motion process, interrupted by signum once it is in phase."""

    motion: str
    phase: str  # waiting (for a cmd_vel subscriber), typed (input), segment or pause
    signum: int
    proc: object = None  # its harness.Process once started
    started_at: float = None

    @property
    def label(self):
        return f'{self.motion} {signal.Signals(self.signum).name} in {self.phase}'

    def args(self):
        name, params = MOTIONS[self.motion]
        if self.phase == 'typed':
            params = tuple(p for p in params if p.startswith('mode:='))
        if self.phase == 'pause':
            params += PAUSE
        return name, params


@dataclass
class Robot:
    """A namespace with its simulator (or none), a watcher, and one motion to interrupt."""

    name: str
    run: Interruption
    sim: str = 'process'  # 'process' (sim time, its own /clock), 'in-process' (wall), or ''
    watcher: object = None  # its Probe
    checked: bool = False


def reached(run, robot):
    """Return whether run's motion is in the phase it is to be interrupted in."""
    if run.phase == 'waiting':
        return 'Waiting for the robot' in run.proc.output()
    if run.phase == 'typed':
        return 'Enter desired angle (degrees): ' in run.proc.output()
    recent = [o for received, o in odoms_with_walls(robot.watcher)[-4:]
              if received > run.started_at]
    if len(recent) < 4:
        return False
    if run.phase == 'segment':
        return all(moving(o) for o in recent)
    # pause: the motion has moved the robot, and it has been at rest for the last few steps.
    moved = any(moving(o) for o in robot.watcher.after(run.started_at))
    return moved and not any(moving(o) for o in recent)


def interrupt_all(graph, procs, robots, timeout=40.0):
    """Start the robots' simulators and motions, interrupt each in its phase, check the ends."""
    # The robots on sim time share one simulator process (its robots parameter) and its
    # lockstep: a motion that is interrupted leaves it, and the others go on.
    shared = [robot.name for robot in robots if robot.sim == 'process']
    sim_namespace = f'{_PREFIX}_{shared[0]}_sim' if shared else None
    if shared:
        procs('sim', 'unicycle_sim', *ros_args(
            sim_namespace, *SIM_CLOCK, KEEP_LAST_COMMAND, f'robots:={shared}'))
    args = {}  # per robot: the --ros-args of its motion but for the parameters
    for robot in robots:
        if robot.sim == 'process':
            namespace = f'{sim_namespace}/{robot.name}'
            args[robot.name] = {'namespace': namespace, 'clock': f'{sim_namespace}/clock',
                                'sim_time': True}
        else:
            namespace = f'{_PREFIX}_{robot.name}'
            args[robot.name] = {'namespace': namespace, 'clock': f'{namespace}/clock'}
        if robot.sim == 'in-process':
            graph.add(UnicycleSim(namespace=namespace, context=graph.context,
                                  cli_args=ros_args(namespace, KEEP_LAST_COMMAND)))
        if robot.sim:
            robot.watcher = watch(graph, namespace, record_commands=robot.sim == 'in-process')
    for robot in robots:
        run = robot.run
        name, params = run.args()
        typed = run.phase == 'typed'
        run.proc = procs(f'{robot.name}_{run.phase}', name,
                         *ros_params(*params, **args[robot.name]),
                         stdin=subprocess.PIPE if typed else subprocess.DEVNULL)
        run.started_at = time.monotonic()
        if typed:
            # Answer the first question and leave the pipe open: it waits for the second.
            run.proc.write('60\n')
    problems = []

    def step():
        for robot in robots:
            run = robot.run
            if robot.checked:
                continue
            if run.proc.signalled_at is None and reached(run, robot):
                run.proc.send(run.signum)
            elif run.proc.poll() is not None and (
                    not robot.sim or run.proc.signalled_at is None or settled(robot, run)):
                robot.checked = True
                check_run(robot, run, problems)
        return all(robot.checked for robot in robots)

    finished = graph.spin_until(step, timeout, poll=0.01)
    for robot in robots:
        if not robot.checked:
            if robot.run.proc.poll() is None:
                robot.run.proc.kill(grace=1.0)  # with its threads' stacks: where it hung
            problems.append(f'{robot.run.label}: never got there, or never exited\n'
                            + robot.run.proc.describe())
    assert finished and not problems, '\n\n'.join(problems)


def settled(robot, run):
    """Return whether ten odometry messages at rest, none moving since, came after the exit."""
    at_rest = at_rest_since(robot.watcher.after(run.proc.exited_at))
    return len(at_rest) >= 10 or time.monotonic() > run.proc.exited_at + 5.0


def check_run(robot, run, problems):
    if run.proc.signalled_at is None:
        problems.append(f'{run.label}: exited before the phase was reached\n'
                        + run.proc.describe())
        return
    check_clean_interrupt(run.proc, run.signum, problems, run.label)
    if robot.sim:
        check_stopped(robot.watcher, run.proc, problems, run.label)


def test_interrupt_while_waiting_for_the_robot_or_for_typed_input(graph, procs):
    # Each signal meets each phase and each motion (in this test or the next); the signal
    # path is one for all motions, so not every pair is run.  The wait for the robot is
    # MotionNode's, the same in every motion: an open and a closed loop, a signal each, show
    # it (rotate_robot meets both signals at its prompt below, every motion one mid-segment).
    runs = [('timed_out_and_back', signal.SIGINT), ('odom_out_and_back', signal.SIGTERM)]
    robots = [Robot(f'waiting_{i}', Interruption(motion, 'waiting', signum), sim='')
              for i, (motion, signum) in enumerate(runs)]
    robots += [
        Robot('typed_0', Interruption('rotate_robot', 'typed', signal.SIGINT), sim='in-process'),
        Robot('typed_1', Interruption('rotate_robot mode:=odom', 'typed', signal.SIGTERM),
              sim='in-process'),
    ]
    interrupt_all(graph, procs, robots)
    for robot in robots[-2:]:
        # Nothing but the final zero Twist was sent, and the robot never moved.
        assert all(command_of(m) == (0.0, 0.0) for _, _, m in robot.watcher.commands)
        assert robot.watcher.odoms
        assert all(not moving(o) and pose_of(o) == (0.0, 0.0, 0.0)
                   for o in robot.watcher.odoms)


def test_interrupt_mid_segment_and_during_a_pause(graph, procs, terminal_sighup):
    robots = [
        # Each motion mid-segment, SIGINT and SIGTERM on open and closed loops, SIGHUP too.
        Robot('rotate_int', Interruption('rotate_robot', 'segment', signal.SIGINT)),
        Robot('rotate_odom', Interruption('rotate_robot mode:=odom', 'segment', signal.SIGTERM)),
        Robot('circle', Interruption('circle_back_and_forth', 'segment', signal.SIGTERM)),
        Robot('timed', Interruption('timed_out_and_back', 'segment', signal.SIGHUP)),
        Robot('timed_pause', Interruption('timed_out_and_back', 'pause', signal.SIGINT)),
        Robot('odom', Interruption('odom_out_and_back', 'segment', signal.SIGINT)),
        Robot('odom_pause', Interruption('odom_out_and_back', 'pause', signal.SIGTERM)),
    ]
    interrupt_all(graph, procs, robots)


def command_of(msg):
    return msg.linear.x, msg.angular.z


# -- the simulator restarted under a closed-loop motion ----------------------------------------

@dataclass
class Restart:
    """A closed-loop motion whose simulator is killed mid-motion, and restarted (or not)."""

    name: str
    motion: str
    sim_time: bool
    restart: bool = True
    expected: tuple = ()
    motion_proc: object = None  # harness.Process
    sim_proc: object = None
    new_sim: object = None
    watcher: object = None  # Probe
    killed_at: float = None

    def far_enough(self):
        """Return whether the robot is well into the motion (so a restart moves the pose)."""
        odom = self.watcher.odom
        if not moving(odom):
            return False
        if self.motion == 'odom_out_and_back':
            return odom.pose.pose.position.x > 0.2
        return abs(pose_of(odom)[2]) > math.radians(30.0)


# What the motion may notice first: the pose jumping back to the start, time going back, or the
# new simulator's odometry publisher beside the crashed one's (still in discovery).
WALL_RESTART = ('Odometry jumped', 'publishers on')
SIM_RESTART = ('went back', 'Odometry jumped', 'publishers on')


def test_simulator_restarted_mid_motion_is_noticed(graph, procs):
    cases = [
        # Each motion meets one clock: the pairs that a pose check alone used to miss (a turn
        # that the new simulator has partly redone; a drive that its clock has caught up with).
        Restart('restart_rotate_wall', 'rotate_robot mode:=odom', False, expected=WALL_RESTART),
        Restart('restart_oob_sim', 'odom_out_and_back', True, expected=SIM_RESTART),
        # No restart: the gap in odometry is what tells.
        Restart('gone_rotate_sim', 'rotate_robot mode:=odom', True, restart=False,
                expected=('No odometry for',)),
    ]

    def sim_command(case):
        namespace = f'{_PREFIX}_{case.name}'
        clock = SIM_CLOCK if case.sim_time else ()
        return 'unicycle_sim', *ros_args(namespace, *clock, KEEP_LAST_COMMAND)

    for case in cases:
        namespace = f'{_PREFIX}_{case.name}'
        case.sim_proc = procs(f'{case.name}_sim', *sim_command(case))
        # On sim time the watcher takes part in the lockstep: in a busy suite a wall-time one
        # fell so far behind that it saw the robot mid-motion only after the motion had
        # ended (at real_time_factor 4), and the simulator was killed too late.
        case.watcher = watch(graph, namespace, sim_time=case.sim_time)
        name, params = MOTIONS[case.motion]
        # A restart is told by the odometry it sends, not by a gap: the gap check (odom_timeout)
        # is what the case without a restart shows.
        timeout = () if not case.restart else ('odom_timeout:=30.0',)
        case.motion_proc = procs(f'{case.name}_motion', name, *ros_args(
            namespace, *params, *timeout, sim_time=case.sim_time),
            '--log-level', f'{namespace[1:]}.{name}:=debug')  # what the stop's wait found

    def step():
        for case in cases:
            if case.killed_at is None and case.far_enough():
                case.sim_proc.send(signal.SIGKILL)
                case.sim_proc.wait()
                case.killed_at = time.monotonic()
                if case.restart:
                    case.new_sim = procs(f'{case.name}_new_sim', *sim_command(case))
        return all(case.motion_proc.poll() is not None for case in cases)

    finished = graph.spin_until(step, 30.0, poll=0.01)
    problems = []
    for case in cases:
        proc = case.motion_proc
        output = proc.output()
        if proc.poll() is None:
            problems.append(f'{case.name}: did not notice\n{proc.describe()}')
            continue
        if case.killed_at is None:  # what it noticed was not the kill: a stall of the simulator?
            problems.append(f'{case.name}: the motion ended before its simulator was killed'
                            f'\n{proc.describe()}\n{case.sim_proc.describe()}')
            continue
        if (proc.poll() != 1 or not any(text in output for text in case.expected)
                or 'Traceback' in output):
            problems.append(f'{case.name}: exit code {proc.poll()}, expected 1 and one of '
                            f'{case.expected}\n' + '\n'.join(p.describe() for p in (
                                proc, case.sim_proc, case.new_sim) if p is not None))
        # The killed simulator's subscriptions stay in discovery (its lease runs for seconds):
        # the motion cannot know that its final stop was heard, and says so.
        if not case.restart and 'Not acknowledged within' not in output:
            readers = graph.nodes[0].count_subscribers(f'{_PREFIX}_{case.name}/cmd_vel')
            problems.append(f'{case.name}: no word of the unacknowledged stop (the simulator '
                            f'was killed {proc.exited_at - case.killed_at:.2f} s before the '
                            f'motion exited; cmd_vel readers seen now: {readers})\n{output}')
        if case.restart:
            settle = time.monotonic()
            graph.spin_until(lambda: len(at_rest_since(case.watcher.after(
                proc.exited_at))) >= 10 or time.monotonic() > settle + 5.0, 6.0, poll=0.01)
            check_stopped(case.watcher, proc, problems, case.name, case.new_sim)
    assert finished and not problems, '\n\n'.join(problems)
