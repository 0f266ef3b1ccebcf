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
Benchmark this package against the programs it replaces and print one table.

Every row puts this project's figure next to a reference measured in the same run (the
original algorithm reproduced here, Euler integration, another executor, ...) and, where the
project has a target, whether it was met:

* accuracy: rotate 90 deg at 60 deg/s clockwise (timed and odom mode) against the original
  ``rotate_robot.py`` algorithm over start times spread across one second; timed out-and-back
  against rbx1's tick arithmetic; circle back-and-forth against ``move_rob.py``; the simulator's
  exact arc against forward Euler over 100 laps of a circle;
* speed: real-time factor of the three default motions on simulated time, in one process
  (lockstep, SingleThreadedExecutor and EventsExecutor) and across processes (``unicycle_sim``
  and the motion executables over DDS), with a check that two runs give identical poses;
  cmd_vel -> odom latency; simulator CPU idle and under commands; N robots in one process and
  in separate processes.

In-process rows run the real simulator node and the real motion nodes in one executor, stepped
in lockstep (the harness of test/conftest.py, in compact form), so their results are exact and
independent of machine load; their context has discovery off, so nothing outside it can
interfere.  Everything else uses a ROS domain of its own (random in 1..100 unless --domain-id
is given) with localhost-only discovery, for this process and every process it starts, and all
of those are stopped before the benchmark exits.

Usage (venv active): ``python tools/bench.py [--quick] [--json PATH] [--only GROUPS]``, or
``make bench``.  The JSON goes to out/bench.json unless --json says otherwise.
"""

import argparse
import json
import math
import os
from pathlib import Path
import random
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

from geometry_msgs.msg import Twist
from motion_challenges.circle_back_and_forth import CircleBackAndForth
from motion_challenges.odom_out_and_back import OdomOutAndBack
from motion_challenges.prompts import RotationRequest
from motion_challenges.rotate_robot import RotateRobot
from motion_challenges.timed_out_and_back import TimedOutAndBack
from nav_msgs.msg import Odometry
import numpy as np
import rclpy
from rclpy.clock import Clock
from rclpy.clock import ClockType
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.logging import LoggingSeverity
from rclpy.node import Node
from rclpy.parameter import Parameter
from sim_diffdrive.angles import yaw_from_quaternion
from sim_diffdrive.harness import Lockstep
from sim_diffdrive.kinematics import integrate
from sim_diffdrive.kinematics import UnicycleModel
from sim_diffdrive.sim_node import UnicycleSim

NS = 1_000_000_000
DEFAULT_JSON = 'out/bench.json'

# Targets (goals of the project, reported as met / missed, never asserted).
TARGET_YAW_DEG = 0.01
TARGET_CLOSURE_MM = 1.0
TARGET_RTF_IN_PROCESS = 25.0
TARGET_RTF_PROCESSES = 10.0
TARGET_LATENCY_P99_MS = 20.0 + 2.0  # one odometry period at 50 Hz, plus 2 ms
TARGET_IDLE_CPU_PERCENT = 2.0

ROTATION = RotationRequest(60.0, 90.0, True)  # deg/s, deg, clockwise

# The original programs' constants.
ORIGINAL_PI = 3.14

# Wall seconds (plus four per robot) the scaling rows wait for the motion processes.
SCALING_TIMEOUT_S = 20.0

ROW_KEYS = (
    'rotate_timed', 'rotate_odom', 'out_and_back_closure', 'circle_closure',
    'integration_error', 'rtf_in_process', 'rtf_processes', 'latency', 'cpu_idle',
    'cpu_commands', 'scaling_one_process', 'scaling_processes',
)


class Sizes:
    """How big each measurement is: full for ``make bench``, small for --quick (tests)."""

    def __init__(self, quick):
        self.quick = quick
        self.starts = 4 if quick else 20
        self.circle_cycles = 2 if quick else 10
        self.circle_half_period = 3.0 if quick else 15.0
        self.laps = 100
        self.latency_samples = 10 if quick else 200
        self.cpu_seconds = 0.5 if quick else 5.0
        self.robots = (1, 2) if quick else (1, 4, 16)
        self.robots_processes = (2,) if quick else self.robots
        # What each robot drives in the scaling rows: odom_out_and_back, shortened.
        self.scaling_motion = (
            {'goal_distance': 0.1, 'angular_speed': 4.0, 'pause': 0.1, 'legs': 1} if quick
            else {'goal_distance': 0.2, 'angular_speed': 2.0, 'pause': 0.2})
        self.scaling_window_s = 0.5 if quick else 2.0
        # The three default scenarios for the real-time factor (shortened with --quick).
        self.circle_rtf = {'cycles': 1, 'half_period': 1.0 if quick else 15.0}
        self.out_and_back_rtf = (
            {'goal_distance': 0.2, 'angular_speed': 2.0, 'pause': 0.1} if quick else {})
        self.process_scenarios = ('rotate',) if quick else ('rotate', 'circle', 'out_and_back')


# -- the original algorithms, as generators ---------------------------------------------------
#
# A script publishes through robot.publish(linear, angular), reads robot.now_ns(), and each
# ``yield`` waits for the next tick of its rate, as rospy's rate.sleep() does on a clock that
# keeps perfect time (sim time).  The same script runs against the real simulator node
# (ScriptNode, in lockstep) or against the pure kinematic model (ModelRobot, for tests).


def _sleep_ticks(rate_hz, seconds):
    for _ in range(round(rate_hz * seconds)):
        yield


def original_rotate(robot, speed_deg, angle_deg, clockwise):
    """
    Rotate as The Construct's original ``rotate_robot.py`` did (it ticked at 10 Hz).

    Degrees to radians with 3.14/180; t0 = the whole seconds of now (``rospy.Time.now().secs``);
    every tick publishes the turn, then estimates the angle turned as speed x (whole seconds of
    now - t0) and stops once that estimate reaches the goal.  The topic is fixed (cmd_vel) and
    the final stop is published, so only the time and pi bugs remain.
    """
    angular_speed = speed_deg * ORIGINAL_PI / 180.0
    relative_angle = angle_deg * ORIGINAL_PI / 180.0
    turn = -abs(angular_speed) if clockwise else abs(angular_speed)
    t0 = robot.now_ns() // NS
    while True:
        robot.publish(0.0, turn)
        current_angle = angular_speed * (robot.now_ns() // NS - t0)
        if current_angle >= relative_angle:
            break
        yield
    robot.publish(0.0, 0.0)


def rbx1_timed_out_and_back(robot, rate=50, linear_speed=0.2, goal_distance=1.0,
                            angular_speed=1.0, goal_angle=math.pi):
    """
    Drive rbx1's ``timed_out_and_back.py``: two legs, ticks counted as rbx1 counts them.

    Drive ticks = int(goal_distance / linear_speed * rate); turn ticks = int(goal_angle * rate)
    (from the angle, not the turn's duration); each tick publishes once, a stop is a zero Twist
    followed by ``rospy.sleep(1)``.
    """
    linear_duration = goal_distance / linear_speed
    for _ in range(2):
        for _ in range(int(linear_duration * rate)):
            robot.publish(linear_speed, 0.0)
            yield
        robot.publish(0.0, 0.0)
        yield from _sleep_ticks(rate, 1.0)
        for _ in range(int(goal_angle * rate)):
            robot.publish(0.0, angular_speed)
            yield
        robot.publish(0.0, 0.0)
        yield from _sleep_ticks(rate, 1.0)
    robot.publish(0.0, 0.0)


def rbx1_ticks(rate=50, linear_speed=0.2, goal_distance=1.0, angular_speed=1.0,
               goal_angle=math.pi):
    """Return rbx1's (drive ticks, turn ticks) and the angle its turn really covers [rad]."""
    drive = int(goal_distance / linear_speed * rate)
    turn = int(goal_angle * rate)
    return drive, turn, turn / rate * angular_speed


def move_rob(robot, cycles, rate=10, linear_speed=0.5, angular_speed=0.5, half_period=15.0):
    """
    Drive ``move_rob.py``'s circle back and forth at 10 Hz, modelled as described below.

    Every tick publishes the Twist.  A flip is published twice, a tick apart: first a Twist with
    only the (new) angular part, then both parts.  The original never stops; the stop at the
    end is there to measure it.
    """
    half_ticks = round(half_period * rate)
    for tick in range(2 * cycles * half_ticks):
        sign = 1.0 if (tick // half_ticks) % 2 == 0 else -1.0
        if tick and tick % half_ticks == 0:
            robot.publish(0.0, sign * angular_speed)
        else:
            robot.publish(sign * linear_speed, sign * angular_speed)
        yield
    robot.publish(0.0, 0.0)


class ModelRobot:
    """Play a script against the exact kinematic model on a simulated clock (no ROS)."""

    def __init__(self, start_ns=0):
        self.model = UnicycleModel()
        self._now_ns = start_ns

    def now_ns(self):
        return self._now_ns

    def publish(self, linear, angular):
        self.model.command(linear, angular)

    def play(self, script, rate_hz):
        """Run script to its end; return the final (x, y, yaw) and the seconds it took."""
        period_ns = round(NS / rate_hz)
        start_ns = self._now_ns
        for _ in script:
            self.model.advance(period_ns / NS)
            self._now_ns += period_ns
        m = self.model
        return (m.x, m.y, m.yaw), (self._now_ns - start_ns) / NS


# -- in-process lockstep graph -----------------------------------------------------------------


def _overrides(params):
    return [Parameter(name, value=value) for name, value in params.items()]


def _node_kwargs(namespace=None, **params):
    """Keyword arguments for an in-process node: parameters, namespace, no /rosout."""
    kwargs = {'parameter_overrides': _overrides(params), 'enable_rosout': False}
    if namespace:
        kwargs['namespace'] = namespace
    return kwargs


class Graph(Lockstep):
    """A lockstep graph (sim_diffdrive.harness) with its own context, off the network."""

    def __init__(self, executor_class=EventsExecutor, domain_id=None):
        self.context = Context()
        # The nodes of one context match without discovery: keep the graph off the network, so
        # that no other run on this machine, whatever its domain, can add to the message count.
        saved = os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE')
        os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'OFF'
        try:
            rclpy.init(context=self.context, domain_id=domain_id)
        finally:
            if saved is None:
                del os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE']
            else:
                os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = saved
        super().__init__(executor_class(context=self.context))

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        try:
            self.close()
        finally:
            rclpy.try_shutdown(context=self.context)

    def add_sim(self, namespace=None, **params):
        """Add the simulator that owns time; the benchmark, not a wall timer, steps it."""
        params.setdefault('publish_clock', True)
        params.setdefault('lockstep', False)  # stepped by the in-process Lockstep instead
        return self.add_clock_owner(
            UnicycleSim(context=self.context, **_node_kwargs(namespace, **params)))

    def add_node(self, node_class, namespace=None, **params):
        params.setdefault('use_sim_time', True)
        return self.add(node_class(context=self.context, **_node_kwargs(namespace, **params)))

    def add_script(self, rate_hz):
        return self.add(ScriptNode(rate_hz, context=self.context,
                                   **_node_kwargs(use_sim_time=True)))

    def step_to(self, t_ns):
        """Step until simulated time is t_ns (a multiple of the step, not in the past)."""
        if t_ns % self.step_ns or t_ns < self.now_ns:
            raise ValueError(f'cannot step to {t_ns} ns from {self.now_ns} ns')
        self.step((t_ns - self.now_ns) // self.step_ns)

    def pose(self):
        """Return the simulated robot's (x, y, yaw): what its odometry reports."""
        m = self.clock_owner.model
        return m.x, m.y, m.yaw


class ScriptNode(Node):
    """Play a reference script (see above) on a timer on the node clock, like rospy.Rate."""

    def __init__(self, rate_hz, **kwargs):
        super().__init__('reference', **kwargs)
        self.rate_hz = rate_hz
        self.cmd_pub = self.create_publisher(Twist, 'cmd_vel', 10)
        self.done = True
        self._script = None
        self._timer = self.create_timer(1.0 / rate_hz, self._on_tick)
        self._timer.cancel()

    def now_ns(self):
        return self.get_clock().now().nanoseconds

    def publish(self, linear, angular):
        msg = Twist()
        msg.linear.x = float(linear)
        msg.angular.z = float(angular)
        self.cmd_pub.publish(msg)

    def play(self, script):
        """Start script; its first tick comes one period from now."""
        self._script = script
        self.done = False
        self._timer.reset()

    def _on_tick(self):
        try:
            next(self._script)
        except StopIteration:
            self.done = True
            self._timer.cancel()


def start_times(count, step_s, after_s):
    """Return count start times [ns] spread over one second, on the step grid, after after_s."""
    step_ns = round(step_s * NS)
    whole_s = math.floor(after_s) + 1
    times = []
    for i in range(count):
        offset_ns = round(i * NS / count / step_ns) * step_ns
        times.append((whole_s + 3 * i) * NS + offset_ns)
    return times


def yaw_error_deg(start_yaw, end_yaw, goal):
    """Return |turned - goal| in degrees, turned being the wrapped change of heading."""
    return math.degrees(abs(math.remainder(end_yaw - start_yaw - goal, 2.0 * math.pi)))


def rotate_project(mode, count, domain_id):
    """Rotate 90 deg clockwise at 60 deg/s with rotate_robot, from count start times."""
    goal = -math.radians(ROTATION.angle_deg)
    errors = []
    with Graph(EventsExecutor, domain_id) as graph:
        graph.add_sim()
        graph.wait_for_discovery()
        for start_ns in start_times(count, 0.02, 1.0):
            node = graph.add_node(RotateRobot, mode=mode)
            graph.wait_for_discovery()
            graph.step()  # the new node hears the clock
            # Its tick timer starts at start(): the first tick primes the connection with a
            # zero Twist, the second (start_ns) starts the motion.
            graph.step_to(start_ns - 2 * round(node.period * NS))
            _, _, start_yaw = graph.pose()
            node.start(ROTATION)
            graph.step_until(lambda: node.done, 10.0)
            if node.exit_code != 0 or node.start_ns != start_ns:
                raise RuntimeError(f'rotate_robot ({mode}) did not run as planned')
            graph.step(5)
            errors.append(yaw_error_deg(start_yaw, graph.pose()[2], goal))
            graph.remove(node)
    return errors


def rotate_original(count, domain_id):
    """Rotate 90 deg clockwise at 60 deg/s with the original algorithm, from count starts."""
    goal = -math.radians(ROTATION.angle_deg)
    rate_hz = 10.0
    errors = []
    # A 20 Hz simulator puts the start offsets (multiples of 50 ms) on its steps; it integrates
    # exactly between commands, so its rate does not change the pose.
    with Graph(EventsExecutor, domain_id) as graph:
        graph.add_sim(rate_hz=20.0)
        node = graph.add_script(rate_hz)
        graph.wait_for_discovery()
        for start_ns in start_times(count, 0.05, 1.0):
            graph.step_to(start_ns - round(NS / rate_hz))
            _, _, start_yaw = graph.pose()
            node.play(original_rotate(node, ROTATION.angular_speed_deg, ROTATION.angle_deg,
                                      ROTATION.clockwise))
            graph.step_until(lambda: node.done, 10.0)
            graph.step(2)
            errors.append(yaw_error_deg(start_yaw, graph.pose()[2], goal))
    return errors


def play_reference(script_factory, rate_hz, sim_rate_hz, domain_id, sim_timeout):
    """Play a reference script once against the simulator; return start and end poses."""
    with Graph(EventsExecutor, domain_id) as graph:
        graph.add_sim(rate_hz=sim_rate_hz)
        node = graph.add_script(rate_hz)
        graph.wait_for_discovery()
        graph.step()
        start = graph.pose()
        node.play(script_factory(node))
        graph.step_until(lambda: node.done, sim_timeout)
        graph.step(2)
        return start, graph.pose()


def run_motion(executor_class, make_node, domain_id, sim_rate_hz=50.0, sim_timeout=400.0):
    """
    Run one motion node to its end against the simulator, in lockstep.

    Returns the start and end poses and the simulated and wall seconds of the stepping (to the
    end of the motion and five steps of rest after it).
    """
    with Graph(executor_class, domain_id) as graph:
        graph.add_sim(rate_hz=sim_rate_hz)
        node = make_node(graph)
        graph.wait_for_discovery()
        start = graph.pose()
        wall = time.perf_counter()
        steps = graph.steps
        graph.step_until(lambda: node.done, sim_timeout)
        graph.step(5)  # the resting pose
        wall = time.perf_counter() - wall
        if node.exit_code != 0:
            raise RuntimeError(f'{node.get_name()} exited with {node.exit_code}')
        sim_s = (graph.steps - steps) * graph.step_ns / NS
        return {'start': start, 'end': graph.pose(), 'sim_s': sim_s, 'wall_s': wall}


def make_rotate(graph):
    node = graph.add_node(RotateRobot, mode='timed')
    node.start(ROTATION)
    return node


def closure(start, end):
    """Return (mm, deg) from the start pose to the end pose."""
    mm = 1000.0 * math.hypot(end[0] - start[0], end[1] - start[1])
    return mm, math.degrees(abs(math.remainder(end[2] - start[2], 2.0 * math.pi)))


# -- rows: accuracy --------------------------------------------------------------------------


def fmt_small(value, decimals=4):
    """Format with fixed decimals, or in scientific notation when that would show zeros."""
    if value != 0.0 and abs(value) < 10.0 ** -(decimals - 1):
        return f'{value:.1e}'
    return f'{value:.{decimals}f}'


def fmt_deg(values):
    return f'mean {fmt_small(float(np.mean(values)))}, max {fmt_small(float(np.max(values)))} deg'


def fmt_closure(mm, deg):
    return f'{fmt_small(mm, 3)} mm, {fmt_small(deg)} deg'


def met(ok):
    return 'met' if ok else 'missed'


def row(measure, project, reference, target, result, note, **data):
    return {'measure': measure, 'project': project, 'reference': reference, 'target': target,
            'result': result, 'note': note, 'data': data}


def rows_rotate(sizes, domain_id):
    original = rotate_original(sizes.starts, domain_id)
    reference = f'original: {fmt_deg(original)}'
    rows = {}
    for mode in ('timed', 'odom'):
        errors = rotate_project(mode, sizes.starts, domain_id)
        if mode == 'timed':
            note = (
                'Starts spread over one second (project: on the 20 ms step of the 50 Hz '
                'simulator; original: 0.00, 0.05, ... s past a whole second, 20 Hz simulator '
                'steps). Original = rotate_robot.py reproduced: 3.14/180, t0 and now in '
                'whole seconds, 10 Hz ticks publishing the turn, stop once the estimate '
                'reaches the goal (topic and stop fixed). In-process lockstep on sim time, yaw '
                'from the simulated odometry.')
        else:
            note = ('As the row above, with rotate_robot in odom mode (closed loop on '
                    'odometry); the same runs of the original.')
        rows['rotate_' + mode] = row(
            f'rotate 90 deg cw at 60 deg/s, yaw error, {mode} mode, {sizes.starts} starts',
            fmt_deg(errors), reference, f'<= {TARGET_YAW_DEG} deg',
            met(max(errors) <= TARGET_YAW_DEG), note,
            project_errors_deg=errors, original_errors_deg=original)
    return rows


def rows_out_and_back(sizes, project_run, domain_id):
    mm, deg = closure(project_run['start'], project_run['end'])
    start, end = play_reference(rbx1_timed_out_and_back, 50.0, 50.0, domain_id, 40.0)
    ref_mm, ref_deg = closure(start, end)
    drive, turn, turned = rbx1_ticks()
    _, slow_turn, slow_turned = rbx1_ticks(angular_speed=0.5)
    changed = ', '.join(f'{k}={v}' for k, v in sizes.out_and_back_rtf.items())
    scenario = f'shortened by --quick: {changed}' if changed else 'defaults'
    return row(
        'timed out-and-back (1 m, pi, 2 legs), closure', fmt_closure(mm, deg),
        f'rbx1 ticks: {fmt_closure(ref_mm, ref_deg)}', f'<= {TARGET_CLOSURE_MM:g} mm',
        met(mm <= TARGET_CLOSURE_MM),
        f'Project: timed_out_and_back ({scenario}), in-process lockstep. rbx1 at 50 Hz on sim '
        f'time, each tick one period: drive int(1.0/0.2*50) = {drive} ticks (exact), turn '
        f'int(pi*50) = {turn} ticks = {turned:.2f} rad, {math.degrees(math.pi - turned):.4f} '
        'deg short per turn. Ticks come from goal_angle, not the duration: at 0.5 rad/s the '
        f'same {slow_turn} ticks would turn {math.degrees(slow_turned):.1f} deg.',
        project_mm=mm, project_deg=deg, rbx1_mm=ref_mm, rbx1_deg=ref_deg, rbx1_drive_ticks=drive,
        rbx1_turn_ticks=turn)


def rows_circle(sizes, domain_id):
    cycles, half = sizes.circle_cycles, sizes.circle_half_period

    def make_circle(graph):
        return graph.add_node(CircleBackAndForth, cycles=cycles, half_period=half)
    # A 10 Hz simulator steps with the 10 Hz controllers; it integrates exactly between
    # commands, so its rate does not change the pose.
    run = run_motion(EventsExecutor, make_circle, domain_id, sim_rate_hz=10.0,
                     sim_timeout=2.0 * cycles * half + 10.0)
    mm, deg = closure(run['start'], run['end'])
    start, end = play_reference(
        lambda node: move_rob(node, cycles, half_period=half), 10.0, 10.0, domain_id,
        2.0 * cycles * half + 10.0)
    ref_mm, ref_deg = closure(start, end)
    return row(
        f'circle back-and-forth, closure after {cycles} cycles ({half:g} s half period)',
        fmt_closure(mm, deg), f'move_rob.py model: {fmt_closure(ref_mm, ref_deg)}',
        f'<= {TARGET_CLOSURE_MM:g} mm', met(mm <= TARGET_CLOSURE_MM),
        'move_rob.py modelled at 10 Hz on sim time (rospy sleeps exact): every tick publishes '
        f'(0.5, 0.5) with both signs flipped every {round(10 * half)} ticks; each flip is '
        'published twice a tick apart, the first Twist with only the angular part, so the '
        'robot turns in place for 0.1 s at every flip; stopped after the last cycle to measure '
        '(the original never stops). Were both publishes in the same instant, the first would '
        'have no effect on an exact simulator. Project: circle_back_and_forth. Both in-process '
        'lockstep with 10 Hz simulator steps (exact between commands, so the step does not '
        'change the pose).',
        project_mm=mm, project_deg=deg, move_rob_mm=ref_mm, move_rob_deg=ref_deg,
        cycles=cycles, half_period=half)


def integration_errors(laps=100, linear=0.5, angular=0.5, dt=0.02):
    """
    Drive laps of a circle with the exact arc and with forward Euler at step dt.

    Returns the position errors [m] against the closed form at the end (after exactly `laps`
    laps, a last shorter step included) and the largest along the way, for both integrators.
    """
    end_t = laps * 2.0 * math.pi / angular
    steps = int(end_t / dt)
    last = end_t - steps * dt
    dts = np.full(steps + 1, dt)
    dts[-1] = last
    times = np.cumsum(dts)
    radius = linear / angular
    exact_x = radius * np.sin(angular * times)
    exact_y = radius * (1.0 - np.cos(angular * times))
    # Forward Euler as turtlesim, ArbotiX and nav2_loopback_sim: move along the old heading.
    headings = np.concatenate(([0.0], np.cumsum(angular * dts)[:-1]))
    euler_x = np.cumsum(linear * dts * np.cos(headings))
    euler_y = np.cumsum(linear * dts * np.sin(headings))
    arc_x = np.empty_like(times)
    arc_y = np.empty_like(times)
    x = y = yaw = 0.0
    for i, step in enumerate(dts):
        x, y, yaw = integrate(x, y, yaw, linear, angular, step)
        arc_x[i] = x
        arc_y[i] = y
    euler = np.hypot(euler_x - exact_x, euler_y - exact_y)
    arc = np.hypot(arc_x - exact_x, arc_y - exact_y)
    return {'arc_end_m': float(arc[-1]), 'arc_max_m': float(arc.max()),
            'euler_end_m': float(euler[-1]), 'euler_max_m': float(euler.max()),
            'steps': int(steps + 1)}


def row_integration(sizes):
    e = integration_errors(laps=sizes.laps)
    ratio = e['euler_max_m'] / max(e['arc_max_m'], 1e-300)
    return row(
        f'{sizes.laps} laps of v=0.5 m/s, w=0.5 rad/s at 0.02 s steps, position error',
        f'exact arc: max {e["arc_max_m"]:.1e} m, end {e["arc_end_m"]:.1e} m',
        f'Euler: max {e["euler_max_m"]:.1e} m, end {e["euler_end_m"]:.1e} m; '
        f'ratio {ratio:.1e}', '-', '-',
        "Against the closed-form circle, pure maths. On a constant circle Euler's heading is "
        'exact and its error a phase lag (at most v*dt), largest mid-lap and small at whole '
        'laps; the exact arc stays at rounding level.', ratio_max=ratio, **e)


# -- rows: speed in one process --------------------------------------------------------------


def scenario_factories(sizes):
    def circle(graph):
        return graph.add_node(CircleBackAndForth, **sizes.circle_rtf)

    def out_and_back(graph):
        return graph.add_node(TimedOutAndBack, **sizes.out_and_back_rtf)
    return {'rotate': make_rotate, 'circle': circle, 'out_and_back': out_and_back}


def rtf_in_process(sizes, domain_id):
    """Run each scenario twice with each executor; return the runs by executor and scenario."""
    runs = {}
    for name, executor_class in (('events', EventsExecutor),
                                 ('single_threaded', SingleThreadedExecutor)):
        runs[name] = {}
        for scenario, factory in scenario_factories(sizes).items():
            runs[name][scenario] = [run_motion(executor_class, factory, domain_id)
                                    for _ in range(2)]
    return runs


def rtf_summary(by_scenario):
    """Return ({scenario: rtf}, identical) for two runs per scenario."""
    rtfs = {}
    identical = True
    for scenario, (first, second) in by_scenario.items():
        rtfs[scenario] = (first['sim_s'] + second['sim_s']) / (first['wall_s'] + second['wall_s'])
        identical = identical and first['end'] == second['end']
    return rtfs, identical


def fmt_x(factor):
    return f'{factor:.1f}x' if math.isfinite(factor) else '-'


def fmt_rtfs(rtfs):
    return ', '.join(f'{scenario} {fmt_x(value)}' for scenario, value in rtfs.items())


def row_rtf_in_process(runs):
    events, events_same = rtf_summary(runs['events'])
    single, single_same = rtf_summary(runs['single_threaded'])
    yes = {True: 'yes', False: 'no'}
    return row(
        'real-time factor in one process (sim s / wall s), lockstep',
        f'EventsExecutor: {fmt_rtfs(events)}; identical: {yes[events_same]}',
        f'SingleThreadedExecutor: {fmt_rtfs(single)}; identical: {yes[single_same]}',
        f'>= {TARGET_RTF_IN_PROCESS:g}x', met(min(events.values()) >= TARGET_RTF_IN_PROCESS),
        'The three default motions (rotate 90 timed, circle 1 cycle, timed out-and-back) with '
        'the simulator at 50 Hz stepped in lockstep: each step waits until every message and '
        'due timer has been handled, so results are exact. Identical: final poses of two runs '
        'equal to the bit. The motion executables use EventsExecutor; the target is judged on '
        f'it (SingleThreadedExecutor: {met(min(single.values()) >= TARGET_RTF_IN_PROCESS)}).',
        events_rtf=events, single_threaded_rtf=single, events_identical=events_same,
        single_threaded_identical=single_same)


def scaling_one_process(robots, window_s, motion, domain_id):
    """Return the real-time factor of `robots` simulator+motion pairs in one executor."""
    with Graph(EventsExecutor, domain_id) as graph:
        graph.add_sim(namespace='/robot0')
        for k in range(1, robots):
            graph.add_node(UnicycleSim, namespace=f'/robot{k}')
        for k in range(robots):
            graph.add_node(OdomOutAndBack, namespace=f'/robot{k}', **motion)
        graph.wait_for_discovery()
        graph.step(10)  # the motions prime their connection and start
        steps = round(window_s * NS / graph.step_ns)
        wall = time.perf_counter()
        graph.step(steps)
        wall = time.perf_counter() - wall
        return steps * graph.step_ns / NS / wall


# -- processes -------------------------------------------------------------------------------


class Children:
    """Processes started by the benchmark: all stopped in close(), however the run ends."""

    def __init__(self, log_dir):
        self.log_dir = Path(log_dir)
        self.processes = []
        self._count = 0

    def start(self, executable, namespace=None, **params):
        args = [executable, '--ros-args']
        if namespace:
            args += ['-r', f'__ns:={namespace}']
        for name, value in params.items():
            if isinstance(value, bool):
                value = str(value).lower()
            args += ['-p', f'{name}:={value}']
        self._count += 1
        log_path = self.log_dir / f'{self._count:03d}_{executable}.log'
        with open(log_path, 'w') as log:
            process = subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT)
        process.log_path = log_path
        self.processes.append(process)
        return process

    def stop(self, process):
        """Stop a child with SIGTERM (a motion then stops its robot), then kill it."""
        # SIGTERM rather than SIGINT: a shell without job control starts background commands
        # with SIGINT ignored, and children inherit that.
        if process.poll() is None:
            process.terminate()
            try:
                process.wait(timeout=3.0)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        if process in self.processes:
            self.processes.remove(process)

    def stop_all(self):
        for process in list(self.processes):
            if process.poll() is None:
                process.terminate()
        for process in list(self.processes):
            self.stop(process)


def log_tail(process, lines=12):
    """Return the last lines a child process wrote, indented, for an error message."""
    try:
        text = process.log_path.read_text()
    except OSError:
        return ''
    return '\n'.join('    ' + line for line in text.splitlines()[-lines:])


class Observer(Node):
    """Record odometry: poses, when the robot moved (sim and wall time), and twists."""

    def __init__(self, context, commands=False):
        super().__init__('bench_observer', context=context, enable_rosout=False)
        self.count = 0
        self.latest = None
        self.twist = None
        self.received_at = None
        self.restart()
        self.create_subscription(Odometry, 'odom', self._on_odom, 100)
        # Only where this process drives the robot: the simulator warns of a second publisher.
        self.cmd_pub = self.create_publisher(Twist, 'cmd_vel', 10) if commands else None

    def restart(self):
        """Forget the start pose and the movement seen so far."""
        self.first = None
        self.moving = False
        self.move_start = None
        self.move_end = None
        self._at_rest = None

    def _on_odom(self, msg):
        now = time.perf_counter()
        p = msg.pose.pose
        pose = (p.position.x, p.position.y, yaw_from_quaternion(
            p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w))
        self.count += 1
        self.first = self.first or pose
        self.latest = pose
        self.twist = (msg.twist.twist.linear.x, msg.twist.twist.angular.z)
        self.received_at = now
        sample = (msg.header.stamp.sec + msg.header.stamp.nanosec / NS, now)
        self.moving = bool(self.twist[0] or self.twist[1])
        if self.moving:
            if self.move_start is None:
                self.move_start = self._at_rest or sample
            self.move_end = None
        else:
            self._at_rest = sample
            if self.move_start is not None and self.move_end is None:
                self.move_end = sample

    def send(self, linear, angular):
        msg = Twist()
        msg.linear.x = float(linear)
        msg.angular.z = float(angular)
        self.cmd_pub.publish(msg)


class Session:
    """An rclpy context and executor in this process for talking to child processes."""

    def __init__(self, domain_id):
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.executor = EventsExecutor(context=self.context)
        self.nodes = []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        try:
            for node in self.nodes:
                self.executor.remove_node(node)
                node.destroy_node()
            self.executor.shutdown()
        finally:
            rclpy.try_shutdown(context=self.context)

    def add(self, node):
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def spin_until(self, predicate, timeout, poll=0.005):
        deadline = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > deadline:
                return False
            self.executor.spin_once(timeout_sec=poll)
        return True

    def spin_for(self, seconds):
        self.spin_until(lambda: False, seconds)


PROCESS_SCENARIOS = {
    'rotate': ('rotate_robot', {'angular_speed_deg': 60.0, 'angle_deg': 90.0, 'clockwise': True,
                                'mode': 'timed'}, 1.5, -90.0),
    'circle': ('circle_back_and_forth', {'cycles': 1}, 30.0, 0.0),
    'out_and_back': ('timed_out_and_back', {}, 20.3, 0.0),
}


def run_process_scenarios(children, domain_id, scenarios, rtf, repeats=2):
    """
    Run each motion executable `repeats` times, each time against a fresh unicycle_sim.

    Returns {scenario: [result of each run]}, measured on odometry by an observer in this
    process.
    """
    results = {}
    with Session(domain_id) as session:
        observer = session.add(Observer(session.context))
        for scenario in scenarios:
            results[scenario] = [run_process_motion(children, session, observer, scenario, rtf)
                                 for _ in range(repeats)]
    return results


def run_process_motion(children, session, observer, scenario, rtf):
    """
    Run one motion executable against a fresh simulator that owns the clock (rtf).

    Fresh, as a user would start them, so each run starts from the simulator's initial pose
    and clock.
    Returns the resting pose, its error from the goal, the movement's sim and wall seconds,
    and why the run failed (None when the motion finished with exit code 0).
    """
    executable, params, sim_seconds, turn_deg = PROCESS_SCENARIOS[scenario]
    # Let odometry from the previous run's simulator drain, or it would be taken for the start.
    session.spin_until(lambda: time.perf_counter() - (observer.received_at or 0.0) > 0.3, 10.0)
    observer.restart()
    motion = sim = None
    failure = None
    try:
        sim = children.start('unicycle_sim', publish_clock=True, real_time_factor=rtf)
        if not session.spin_until(lambda: observer.first is not None, 15.0):
            raise RuntimeError(f'no odometry from unicycle_sim:\n{log_tail(sim)}')
        motion = children.start(executable, use_sim_time=True, **params)
        # Process start and discovery, then at least 2x real time.
        timeout = 10.0 + sim_seconds / 2.0
        if not session.spin_until(lambda: motion.poll() is not None, timeout):
            failure = f'{scenario}: not done after {timeout:.0f} s wall'
        elif motion.returncode != 0:
            failure = f'{scenario}: exit code {motion.returncode}'
        seen = observer.count
        session.spin_until(lambda: observer.count > seen + 2 and not observer.moving, 2.0)
    finally:
        for process in (motion, sim):
            if process is not None:
                children.stop(process)
    start, end = observer.first, observer.latest
    mm, deg = closure((start[0], start[1], start[2] + math.radians(turn_deg)), end)
    result = {'end': end, 'error_mm': mm, 'error_deg': deg, 'failure': failure}
    if failure:
        result['log_tail'] = log_tail(motion)
    if observer.move_start and observer.move_end:
        result['sim_s'] = observer.move_end[0] - observer.move_start[0]
        result['wall_s'] = observer.move_end[1] - observer.move_start[1]
    return result


def row_rtf_processes(sizes, children, domain_id, rtf):
    rtfs = {}
    errors = {}
    results = run_process_scenarios(children, domain_id, sizes.process_scenarios, rtf)
    failures = [r['failure'] for runs in results.values() for r in runs if r['failure']]
    identical = not failures
    for scenario, runs in results.items():
        timed = [r for r in runs if not r['failure'] and 'sim_s' in r]
        wall_s = sum(r['wall_s'] for r in timed)
        rtfs[scenario] = sum(r['sim_s'] for r in timed) / wall_s if wall_s > 0 else math.nan
        identical = identical and runs[0]['end'] == runs[1]['end']
        errors[scenario] = [(r['error_mm'], r['error_deg']) for r in runs]
    worst_mm = max(mm for runs in errors.values() for mm, _ in runs)
    worst_deg = max(deg for runs in errors.values() for _, deg in runs)
    runs_count = sum(len(runs) for runs in results.values())
    failed = f'; {len(failures)} of {runs_count} runs failed' if failures else ''
    return row(
        'real-time factor across processes (sim s / wall s), from odometry',
        f'{fmt_rtfs(rtfs)}; identical: {"yes" if identical else "no"}{failed}',
        f'clock set to {rtf:g}x', f'>= {TARGET_RTF_PROCESSES:g}x',
        met(not failures and min(rtfs.values()) >= TARGET_RTF_PROCESSES),
        f'unicycle_sim (publish_clock, real_time_factor {rtf:g}, 50 Hz) and the motion '
        'executables as separate processes over DDS, observed from this process; sim and wall '
        'seconds from the first to the last movement on odometry; two runs per motion, each '
        'against a fresh simulator. The simulator steps in lockstep with the motion (it waits '
        "for the motion's answer to each clock step and for the commands it covers), so "
        'real_time_factor is only an upper bound and the factor is what the handshake '
        'sustains: about one round trip between two Python executors per 20 ms step. Worst '
        f'error over the runs {worst_mm:.3g} mm, {worst_deg:.3g} deg from the goal.'
        + (f' Failed: {"; ".join(failures)}.' if failures else ''),
        rtf=rtfs, identical=identical, errors_mm_deg=errors, failures=failures,
        failure_logs=[r['log_tail'] for runs in results.values() for r in runs
                      if r['failure']])


def cpu_seconds(pid):
    """Return the user + system CPU seconds used so far by process pid (from /proc)."""
    with open(f'/proc/{pid}/stat') as stat:
        fields = stat.read().rsplit(')', 1)[1].split()
    # Fields 14 and 15 of stat(5) (utime, stime) are the 12th and 13th after the ')'.
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def cpu_percent(session, pid, seconds):
    """Measure the CPU use of process pid over `seconds` of wall time, in % of one core."""
    used = cpu_seconds(pid)
    wall = time.monotonic()
    session.spin_for(seconds)
    return 100.0 * (cpu_seconds(pid) - used) / (time.monotonic() - wall)


def rows_sim_process(sizes, children, domain_id):
    """Measure latency and CPU of one unicycle_sim process on wall time (50 Hz)."""
    with Session(domain_id) as session:
        observer = session.add(Observer(session.context, commands=True))
        sim = children.start('unicycle_sim', rate_hz=50.0)
        try:
            if not session.spin_until(
                    lambda: observer.first is not None
                    and observer.cmd_pub.get_subscription_count() > 0, 15.0):
                raise RuntimeError(f'no odometry from unicycle_sim:\n{log_tail(sim)}')
            session.spin_for(0.5)
            idle = cpu_percent(session, sim.pid, sizes.cpu_seconds)

            # 10 Hz commands from a wall-clock timer in this process.
            command = [0]

            def send():
                command[0] += 1
                observer.send(0.1, 0.2 if command[0] % 2 else 0.3)
            timer = observer.create_timer(0.1, send, clock=Clock(clock_type=ClockType.STEADY_TIME))
            busy = cpu_percent(session, sim.pid, sizes.cpu_seconds)
            timer.cancel()
            observer.destroy_timer(timer)

            latencies, lost = measure_latency(session, observer, sizes.latency_samples)
        finally:
            children.stop(sim)
    return {
        'latency': latency_row(latencies, lost),
        'cpu_idle': row(
            'unicycle_sim CPU, idle (50 Hz odometry, one subscriber)', f'{idle:.2f} % of a core',
            f'under 10 Hz cmd_vel: {busy:.2f} %', f'<= {TARGET_IDLE_CPU_PERCENT:g} %',
            met(idle <= TARGET_IDLE_CPU_PERCENT),
            f'utime + stime from /proc/<pid>/stat over {sizes.cpu_seconds:g} s of wall time; '
            'the simulator on wall time, publishing odometry to this process.',
            idle_percent=idle, commands_percent=busy),
        'cpu_commands': row(
            'unicycle_sim CPU under 10 Hz cmd_vel', f'{busy:.2f} % of a core',
            f'idle: {idle:.2f} %', '-', '-',
            f'Same process, {sizes.cpu_seconds:g} s with a Twist every 100 ms (alternating '
            'values) from this process.', idle_percent=idle, commands_percent=busy),
    }


def measure_latency(session, observer, samples):
    """Send changing Twists; return the ms until odometry first shows each applied, and losses."""
    rng = random.Random(1)
    latencies = []
    lost = 0
    for k in range(samples):
        angular = 0.1 + 0.001 * k
        sent = time.perf_counter()
        observer.send(0.0, angular)
        if session.spin_until(lambda: observer.twist == (0.0, angular)
                              and observer.received_at >= sent, 1.0, poll=0.0005):
            latencies.append(1000.0 * (observer.received_at - sent))
        else:
            lost += 1
        # A random pause samples every phase of the simulator's 50 Hz odometry timer.
        session.spin_for(rng.uniform(0.02, 0.045))
    return latencies, lost


def latency_row(latencies, lost):
    p50, p99 = (float(np.percentile(latencies, q)) if latencies else math.nan
                for q in (50, 99))
    return row(
        'cmd_vel -> odom latency across processes, wall time',
        f'p50 {p50:.1f} ms, p99 {p99:.1f} ms' if latencies else 'no sample',
        'one odometry period: 20.0 ms',
        f'p99 <= {TARGET_LATENCY_P99_MS:g} ms', met(p99 <= TARGET_LATENCY_P99_MS and not lost),
        f'unicycle_sim process at 50 Hz on wall time; this process publishes a Twist with a new '
        f'value and times the first odometry whose twist equals it ({len(latencies)} samples, '
        f'{lost} lost, random 20-45 ms pauses). Odometry is published on the 50 Hz timer only, '
        'so the wait for the next tick (0-20 ms) dominates.',
        p50_ms=p50, p99_ms=p99, samples=len(latencies), lost=lost,
        max_ms=float(max(latencies)) if latencies else None)


DONE_LINE = re.compile(r'Done in ([0-9.]+) s \(([0-9.]+) s wall\)')
ERROR_LINE = re.compile(r'error ([0-9.]+) mm, ([0-9.]+) deg')


def scaling_processes(children, domain_id, robots, motion, rtf):
    """
    Run `robots` odom_out_and_back + unicycle_sim pairs as separate processes.

    Robot 0's simulator owns /clock (publish_clock at rtf, in lockstep with every other process,
    all of which take part: the motions and the simulators on sim time) and starts last, once
    every other process is up and connected.  Commands are TwistStamped (stamped:=true on every
    node), so a robot's simulator applies each at the step it was sent for even when it arrives
    before that step's /clock.  Returns the slowest motion's
    sim s / wall s, the largest closure error (both from the motions' closing lines) and how
    many motions did not finish.
    """
    processes = []
    with Session(domain_id) as session:
        probe = session.add(Node('bench_probe', context=session.context, enable_rosout=False))
        try:
            for k in range(1, robots):
                processes.append(children.start('unicycle_sim', namespace=f'/robot{k}',
                                                use_sim_time=True, stamped=True))
            motions = [children.start('odom_out_and_back', namespace=f'/robot{k}',
                                      use_sim_time=True, start_timeout=120.0, stamped=True,
                                      **motion)
                       for k in range(robots)]
            processes += motions

            def ready():
                return all(probe.count_publishers(f'/robot{k}/cmd_vel') >= 1
                           and (k == 0 or probe.count_subscribers(f'/robot{k}/cmd_vel') >= 1)
                           for k in range(robots))
            if not session.spin_until(ready, 30.0 + 2.0 * robots, poll=0.05):
                raise RuntimeError(f'{robots} robots did not come up')
            # 2N Python processes on a small machine: a participant can be off the CPU for
            # seconds, which is no reason to go on without it.
            processes.append(children.start('unicycle_sim', namespace='/robot0',
                                            publish_clock=True, real_time_factor=rtf,
                                            lockstep_timeout=SCALING_TIMEOUT_S, stamped=True))
            session.spin_until(lambda: all(m.poll() is not None for m in motions),
                               SCALING_TIMEOUT_S + 4.0 * robots, poll=0.05)
        finally:
            for process in processes:
                children.stop(process)
    factors, errors, failed = [], [], 0
    for motion in motions:
        text = motion.log_path.read_text()
        done, error = DONE_LINE.search(text), ERROR_LINE.search(text)
        if motion.returncode != 0 or not done or not error:
            failed += 1
            continue
        sim_s, wall_s = float(done.group(1)), float(done.group(2))
        factors.append(sim_s / wall_s if wall_s > 0 else math.inf)
        errors.append(float(error.group(1)))
    return {'rtf': min(factors, default=math.nan), 'worst_mm': max(errors, default=math.nan),
            'failed': failed}


def rows_scaling(sizes, children, domain_id, rtf):
    motion = sizes.scaling_motion
    one = {n: scaling_one_process(n, sizes.scaling_window_s, motion, domain_id)
           for n in sizes.robots}
    many = {n: scaling_processes(children, domain_id, n, motion, rtf)
            for n in sizes.robots_processes}
    drive = 'odom_out_and_back (' + ', '.join(f'{k} {v:g}' for k, v in motion.items()) + ')'
    one_text = ', '.join(f'N={n}: {v:.1f}x' for n, v in one.items())
    many_text = ', '.join(
        f'N={n}: {fmt_x(m["rtf"])} ({m["worst_mm"]:.3f} mm'
        + (f', {m["failed"]} not done)' if m['failed'] else ')') for n, m in many.items())
    return {
        'scaling_one_process': row(
            'N robots in one process, real-time factor', one_text,
            'as 2N processes: ' + many_text, '-', '-',
            f'Simulator + {drive} pairs in namespaces /robotK, all nodes in one '
            "EventsExecutor; robot 0's simulator owns /clock and is stepped in lockstep, the "
            f'others run on sim time. Measured over {sizes.scaling_window_s:g} s of simulated '
            'time, exact.', rtf={str(n): v for n, v in one.items()}),
        'scaling_processes': row(
            'N robots as 2N processes, real-time factor (worst closure)', many_text,
            'one process: ' + one_text, '-', '-',
            f'unicycle_sim and {drive} executables per robot (-r __ns:=/robotK). '
            f"Robot 0's simulator owns /clock (real_time_factor {rtf:g} as an upper bound) "
            'and starts once all others are connected; the rest use_sim_time and take part in '
            'its lockstep, so it waits for all 2N-1 of them at every step. Commands are '
            'TwistStamped, so each simulator applies a command at the step it was sent for. '
            "Factor: slowest motion's sim s / wall s; error: "
            "largest closure error; both from the motions' closing lines of the robots that "
            f'finished (not done: no closing line within {SCALING_TIMEOUT_S:g} s + 4 s per '
            'robot of wall time).',
            rtf={str(n): m['rtf'] for n, m in many.items()},
            worst_error_mm={str(n): m['worst_mm'] for n, m in many.items()},
            not_done={str(n): m['failed'] for n, m in many.items()}),
    }


# -- table -----------------------------------------------------------------------------------


def machine():
    model = '?'
    try:
        with open('/proc/cpuinfo') as cpuinfo:
            for line in cpuinfo:
                if line.startswith('model name'):
                    model = line.split(':', 1)[1].strip()
                    break
    except OSError:
        pass
    return {'nproc': os.cpu_count(), 'cpu': model, 'loadavg': list(os.getloadavg()),
            'python': sys.version.split()[0]}


def print_table(rows, out=sys.stdout):
    header = ['#', 'measure', 'this project', 'reference', 'target', 'result']
    table = [header] + [[str(i), r['measure'], r['project'], r['reference'], r['target'],
                         r['result']] for i, r in enumerate(rows.values(), 1)]
    limits = (2, 34, 38, 38, 12, 6)
    widths = [min(max(len(cells[i]) for cells in table), limit)
              for i, limit in enumerate(limits)]

    def wrap(text, width):
        lines, line = [], ''
        for word in text.split(' '):
            if line and len(line) + 1 + len(word) > width:
                lines.append(line)
                line = word
            else:
                line = f'{line} {word}' if line else word
        return lines + [line]
    for cells in table:
        wrapped = [wrap(c, w) for c, w in zip(cells, widths)]
        for i in range(max(len(w) for w in wrapped)):
            print(' | '.join((w[i] if i < len(w) else '').ljust(width)
                             for w, width in zip(wrapped, widths)).rstrip(), file=out)
        print('-+-'.join('-' * w for w in widths), file=out)
    print('\nNotes:', file=out)
    for i, r in enumerate(rows.values(), 1):
        print(f'{i}. {r["note"]}', file=out)


GROUPS = ('rotate', 'rtf', 'out_and_back', 'circle', 'integration', 'processes', 'sim',
          'scaling')


def measure(selected, sizes, children, domain_id, rtf, progress):
    """Run the selected groups of measurements; return the rows in table order."""
    rows = {}
    runs = None
    if 'rotate' in selected:
        progress(f'rotate: project (timed, odom) and original from {sizes.starts} start times')
        rows.update(rows_rotate(sizes, domain_id))
    if 'rtf' in selected:
        progress('real-time factor in one process: 2 executors x 3 motions x 2 runs')
        runs = rtf_in_process(sizes, domain_id)
        rows['rtf_in_process'] = row_rtf_in_process(runs)
    if 'out_and_back' in selected:
        progress('out-and-back: project and rbx1')
        project = (runs['events']['out_and_back'][0] if runs else run_motion(
            EventsExecutor, scenario_factories(sizes)['out_and_back'], domain_id))
        rows['out_and_back_closure'] = rows_out_and_back(sizes, project, domain_id)
    if 'circle' in selected:
        progress('circle back-and-forth: project and move_rob.py')
        rows['circle_closure'] = rows_circle(sizes, domain_id)
    if 'integration' in selected:
        progress('Euler against the exact arc')
        rows['integration_error'] = row_integration(sizes)
    if 'processes' in selected:
        progress('real-time factor across processes')
        rows['rtf_processes'] = row_rtf_processes(sizes, children, domain_id, rtf)
    if 'sim' in selected:
        progress('simulator CPU and latency on wall time')
        rows.update(rows_sim_process(sizes, children, domain_id))
    if 'scaling' in selected:
        progress(f'N robots: {sizes.robots} in one process, {sizes.robots_processes} as '
                 'processes')
        rows.update(rows_scaling(sizes, children, domain_id, rtf))
    return {key: rows[key] for key in ROW_KEYS if key in rows}


def parse_args(argv):
    parser = argparse.ArgumentParser(
        description='Benchmark this package against the programs it replaces; print a table.')
    parser.add_argument('--quick', action='store_true',
                        help='small sizes and short runs (for tests)')
    parser.add_argument('--json', default=DEFAULT_JSON,
                        help='where to write the results as JSON (default: %(default)s)')
    parser.add_argument('--domain-id', type=int, default=None,
                        help='ROS domain to use (default: random in 1..100)')
    parser.add_argument('--only', default=None,
                        help='comma-separated groups to run, of: ' + ', '.join(GROUPS))
    parser.add_argument('--rtf', type=float, default=None,
                        help='real_time_factor (an upper bound) of the simulator across '
                             'processes (default: 100, 10 with --quick)')
    return parser.parse_args(argv)


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def main(argv=None):
    options = parse_args(argv)
    missing = [e for e in ('unicycle_sim', 'rotate_robot', 'circle_back_and_forth',
                           'timed_out_and_back') if shutil.which(e) is None]
    if missing:
        print(f'Not on PATH: {", ".join(missing)}; run `. .venv/bin/activate` first (or '
              '`make bench`).', file=sys.stderr)
        return 2
    domain_id = options.domain_id or random.SystemRandom().randint(1, 100)
    # Children inherit these: a domain of our own, discovery on this machine only.
    os.environ['ROS_DOMAIN_ID'] = str(domain_id)
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    signal.signal(signal.SIGTERM, _interrupt)
    # The nodes in this process log their progress at INFO: keep it out of the table's way.
    rclpy.logging.set_logger_level('', LoggingSeverity.WARN)
    sizes = Sizes(options.quick)
    info = machine()
    print(f'{info["nproc"]} x {info["cpu"]}, load {info["loadavg"][0]:.2f}; '
          f'ROS_DOMAIN_ID={domain_id}, localhost only{", --quick" if sizes.quick else ""}',
          flush=True)

    wall_start = time.monotonic()

    def progress(text):
        print(f'[{time.monotonic() - wall_start:6.1f} s] {text}', flush=True)

    selected = set(options.only.split(',')) if options.only else set(GROUPS)
    if selected - set(GROUPS):
        print(f'Unknown group(s) for --only: {", ".join(sorted(selected - set(GROUPS)))}',
              file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix='motion_bench_') as log_dir:
        children = Children(log_dir)
        try:
            rtf = options.rtf or (10.0 if sizes.quick else 100.0)
            rows = measure(selected, sizes, children, domain_id, rtf, progress)
        except KeyboardInterrupt:
            print('Interrupted', file=sys.stderr)
            return 130
        finally:
            children.stop_all()
    total = time.monotonic() - wall_start

    print()
    print(f'Machine: {info["nproc"]} cores, {info["cpu"]}; Python {info["python"]}; '
          f'load average at start {info["loadavg"][0]:.2f}; total {total:.0f} s wall')
    print()
    print_table(rows)
    report = {'machine': info, 'quick': sizes.quick, 'domain_id': domain_id,
              'wall_s': total, 'rows': rows}
    path = Path(options.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(_jsonable(report), indent=2, allow_nan=False) + '\n')
    print(f'\nJSON: {path}')
    return 0


def _jsonable(value):
    """Return value with numpy numbers as Python ones and NaN or infinity as None."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (np.floating, np.integer)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


if __name__ == '__main__':
    sys.exit(main())
