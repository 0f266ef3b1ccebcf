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

"""Rows 1-6 (and row 11's runs): the motions and the originals in one process, in lockstep."""

from contextlib import contextmanager
from contextlib import ExitStack
from dataclasses import astuple
import math
import os
import sys
import time
from unittest import mock

from benchmark import core
from benchmark import originals
from benchmark.core import Row
from benchmark.core import row
from motion_challenges.circle_back_and_forth import CircleBackAndForth
from motion_challenges.odom_out_and_back import OdomOutAndBack
from motion_challenges.prompts import RotationRequest
from motion_challenges.rotate_robot import RotateRobot
from motion_challenges.timed_out_and_back import TimedOutAndBack
from rclpy.executors import SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.parameter import Parameter
from sim_diffdrive.dds_teardown import held_context
from sim_diffdrive.harness import SimGraph
from sim_diffdrive.sim.node import UnicycleSim

ROTATION = RotationRequest(60.0, 90.0, True)  # deg/s, deg, clockwise
GOAL = -math.radians(ROTATION.angle_deg)
MOTIONS = {'rotate': RotateRobot, 'circle': CircleBackAndForth, 'out_and_back': TimedOutAndBack}
EXECUTORS = {'events': EventsExecutor, 'single_threaded': SingleThreadedExecutor}


@contextmanager
def lockstep_graph(executor_class=EventsExecutor, namespace=None, **sim_params):
    """Yield a SimGraph stepping a simulator; discovery off: no other run adds messages."""
    with ExitStack() as stack:
        with mock.patch.dict(os.environ, {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'OFF'}):
            context = stack.enter_context(held_context())  # its participant goes safely
        graph = stack.enter_context(SimGraph(context, executor_class))
        params = {'publish_clock': True, 'lockstep': False, **sim_params}
        graph.add_clock_owner(UnicycleSim(
            stepped=True, context=context, namespace=namespace, enable_rosout=False,
            parameter_overrides=[Parameter(k, value=v) for k, v in params.items()]))
        yield graph


def pose(graph):
    world = graph.clock_owner.world
    return float(world.x[0]), float(world.y[0]), float(world.yaw[0])


def drive(graph, node, rest_steps, begin):
    """Step until node is done after begin(), and rest_steps more; return poses, sim s, s."""
    start, steps, wall = pose(graph), graph.steps, time.perf_counter()
    begin()
    graph.step_until(lambda: node.done if hasattr(node, 'done') else not node.playing, 600.0)
    graph.step(rest_steps)
    wall = time.perf_counter() - wall
    if getattr(node, 'exit_code', 0) != 0:
        raise RuntimeError(f'{node.get_name()} exited with {node.exit_code}')
    return start, pose(graph), (graph.steps - steps) * graph.step_ns / core.NS, wall


def play(graph, script, rate_hz, probe=None):
    """Play an original script on the model, then its ticks from a Probe; drive()'s."""
    probe = probe or graph.probe('original')
    robot = originals.ModelRobot(graph.now_ns + round(core.NS / rate_hz))
    robot.play(script(robot), rate_hz)
    probe.script_done_at = None  # playing again
    return drive(graph, probe, 2, lambda: probe.play([(*tick, 1) for tick in robot.ticks],
                                                     1.0 / rate_hz))


def rotations(run, mode):
    """Return the yaw errors [deg] of rotate_robot in mode (or the original) per start."""
    errors = []
    # The original's 20 Hz simulator puts its starts (0.05 s apart) on its steps; the rate
    # does not change the pose (exact between commands).
    with lockstep_graph(rate_hz=20.0 if mode == 'original' else 50.0) as graph:
        probe = graph.probe('original') if mode == 'original' else None
        step = 0.05 if probe else 0.02
        for start_ns in originals.start_times(run.sizes.starts, step, 1.0):
            if probe:
                graph.step((start_ns - core.NS // 10 - graph.now_ns) // graph.step_ns)
                start, end, _, _ = play(graph, lambda robot: originals.original_rotate(
                    robot, *astuple(ROTATION)), 10.0, probe)
            else:
                node = graph.node(RotateRobot, mode=mode)
                graph.step()  # the new node hears the clock
                # Its first tick primes the connection with a zero Twist, the second starts.
                graph.step((start_ns - 2 * round(node.period * core.NS) - graph.now_ns)
                           // graph.step_ns)
                start, end, _, _ = drive(graph, node, 5, lambda: node.start(ROTATION))
                if node.start_ns != start_ns:
                    raise RuntimeError(f'rotate_robot ({mode}) started at {node.start_ns} ns')
                graph.remove(node)
            errors.append(originals.yaw_error_deg(start[2], end[2], GOAL))
    return errors


def original(run, script, rate_hz):  # once, the simulator stepping at the script's rate
    with lockstep_graph(rate_hz=rate_hz) as graph:
        graph.step()
        return play(graph, script, rate_hz)


def motion(run, executor, name, index=0, rate_hz=50.0, **params):
    """Run a motion of MOTIONS (index: which run) to its end and 5 steps more; drive()'s."""
    with lockstep_graph(EXECUTORS[executor], rate_hz=rate_hz) as graph:
        node = graph.node(MOTIONS[name], **params)
        graph.wait_for_discovery()
        return drive(graph, node, 5, lambda: name == 'rotate' and node.start(ROTATION))


def default_motion(run, executor, name, index=0):
    """Run a default motion of the real-time factor rows (shortened with --quick)."""
    params = {'rotate': {'mode': 'timed'}, 'circle': run.sizes.circle_rtf,
              'out_and_back': run.sizes.out_and_back_rtf}[name]
    return run.once(motion, executor, name, index, **params)


def one_process(run, robots):
    """Return the real-time factor of `robots` simulator + motion pairs in one executor."""
    with lockstep_graph(namespace='/robot0') as graph:
        for k in range(1, robots):
            graph.node(UnicycleSim, namespace=f'/robot{k}')
        for k in range(robots):
            graph.node(OdomOutAndBack, namespace=f'/robot{k}', **run.sizes.scaling_motion)
        graph.step(10)  # the motions prime their connection and start
        steps = round(run.sizes.scaling_window_s * core.NS / graph.step_ns)
        wall = time.perf_counter()
        graph.step(steps)
        return steps * graph.step_ns / core.NS / (time.perf_counter() - wall)


def fmt_deg(values):
    return (f'mean {core.fmt_small(sum(values) / len(values))}, max '
            f'{core.fmt_small(max(values))} deg')


@row('rotate')
def rotate_timed(run, mode='timed'):
    errors, reference = run.once(rotations, mode), run.once(rotations, 'original')
    return Row(
        f'rotate 90 deg cw at 60 deg/s, yaw error, {mode} mode, {run.sizes.starts} starts',
        fmt_deg(errors), f'original: {fmt_deg(reference)}', 'As row 1, closed loop on odometry.'
        if mode == 'odom' else 'Starts spread over one second. Original: rotate_robot.py '
        'reproduced (3.14/180, t0 and now in whole seconds, 10 Hz ticks; topic and final stop '
        'fixed). In-process lockstep, yaw from the simulator.',
        f'<= {core.TARGET_YAW_DEG} deg', max(errors) <= core.TARGET_YAW_DEG,
        {'project_errors_deg': errors, 'original_errors_deg': reference})


@row('rotate')
def rotate_odom(run):
    return rotate_timed(run, 'odom')


@row('out_and_back')
def out_and_back_closure(run):
    mm, deg = originals.closure(*default_motion(run, 'events', 'out_and_back')[:2])
    ref_mm, ref_deg = originals.closure(*original(
        run, originals.rbx1_timed_out_and_back, 50.0)[:2])
    ticks, turn, turned = originals.rbx1_ticks()
    changed = ', '.join(f'{k}={v}' for k, v in run.sizes.out_and_back_rtf.items())
    return Row(
        'timed out-and-back (1 m, pi, 2 legs), closure', core.fmt_closure(mm, deg),
        f'rbx1 ticks: {core.fmt_closure(ref_mm, ref_deg)}',
        f'Project: timed_out_and_back ({changed or "defaults"}), in-process lockstep. rbx1 at '
        f'50 Hz: drive int(1.0/0.2*50) = {ticks} ticks, turn int(pi*50) = {turn} ticks = '
        f'{turned:.2f} rad ({math.degrees(math.pi - turned):.4f} deg short per turn: ticks '
        'from goal_angle, not from the duration).', f'<= {core.TARGET_CLOSURE_MM:g} mm',
        mm <= core.TARGET_CLOSURE_MM, {'project_mm': mm, 'project_deg': deg, 'rbx1_mm': ref_mm,
                                       'rbx1_deg': ref_deg, 'rbx1_drive_ticks': ticks,
                                       'rbx1_turn_ticks': turn})


@row('circle')
def circle_closure(run):
    cycles, half = run.sizes.circle_cycles, run.sizes.circle_half_period
    mm, deg = originals.closure(*run.once(motion, 'events', 'circle', 0, 10.0, cycles=cycles,
                                          half_period=half)[:2])
    ref_mm, ref_deg = originals.closure(*original(
        run, lambda robot: originals.move_rob(robot, cycles, half_period=half), 10.0)[:2])
    return Row(
        f'circle back-and-forth, closure after {cycles} cycles ({half:g} s half period)',
        core.fmt_closure(mm, deg), f'move_rob.py model: {core.fmt_closure(ref_mm, ref_deg)}',
        'move_rob.py at 10 Hz: (0.5, 0.5), both signs flipped every half period, each flip '
        'published twice a tick apart (the first Twist only angular: a 0.1 s turn in place), '
        'stopped at the end. Project: circle_back_and_forth. In-process lockstep, 10 Hz steps.',
        f'<= {core.TARGET_CLOSURE_MM:g} mm', mm <= core.TARGET_CLOSURE_MM,
        {'project_mm': mm, 'project_deg': deg, 'move_rob_mm': ref_mm, 'move_rob_deg': ref_deg,
         'cycles': cycles, 'half_period': half})


@row('integration')
def integration_error(run):
    e = originals.integration_errors(laps=run.sizes.laps)
    ratio = e['euler_max_m'] / max(e['arc_max_m'], 1e-300)
    return Row(
        f'{run.sizes.laps} laps of v=0.5 m/s, w=0.5 rad/s at 0.02 s steps, position error',
        f'exact arc: max {e["arc_max_m"]:.1e} m, end {e["arc_end_m"]:.1e} m',
        f'Euler: max {e["euler_max_m"]:.1e} m, end {e["euler_end_m"]:.1e} m; ratio {ratio:.1e}',
        "Against the closed-form circle. Euler's error is a phase lag (at most v*dt), largest "
        'mid-lap; the exact arc stays at rounding level.', data={'ratio_max': ratio, **e})


PACKAGES = ('/sim_diffdrive/', '/motion_challenges/')


def step_calls(run):
    """
    Return what one in-process lockstep step calls: (all, the package's, its modules).

    A SimGraph stepping a simulator with timed_out_and_back, over ``call_steps`` steps once it
    moves; every Python and C call counted (sys.setprofile), so the figure is the same on any
    machine and at any load: the work a step does, where its CPU time is not.
    """
    steps, counts, modules = run.sizes.call_steps, [0, 0], set()

    def count(frame, event, arg):
        if event in ('call', 'c_call'):
            counts[0] += 1
            path = frame.f_code.co_filename
            if event == 'call' and any(package in path for package in PACKAGES):
                counts[1] += 1
                modules.add(path)
    with lockstep_graph() as graph:
        graph.node(TimedOutAndBack, legs=4)
        graph.step(50)  # it primes its connection and starts
        sys.setprofile(count)
        try:
            graph.step(steps)
        finally:
            sys.setprofile(None)
    return counts[0] / steps, counts[1] / steps, len(modules)


@row('rtf')
def rtf_in_process(run):
    rtf, same, text = {}, {}, {}
    for executor in EXECUTORS:
        runs = {m: [default_motion(run, executor, m, i) for i in range(2)] for m in MOTIONS}
        rtf[executor] = {m: (a[2] + b[2]) / (a[3] + b[3]) for m, (a, b) in runs.items()}
        same[executor] = all(a[1] == b[1] for a, b in runs.values())
        text[executor] = (', '.join(f'{m} {x:.1f}x' for m, x in rtf[executor].items())
                          + f'; identical: {"yes" if same[executor] else "no"}')
    calls, package_calls, modules = run.once(step_calls)
    return Row(
        'real-time factor in one process (sim s / wall s), lockstep',
        f'EventsExecutor: {text["events"]}', f'SingleThreadedExecutor: {text["single_threaded"]}'
        f'; a step (timed out-and-back) makes {calls:.0f} calls, {package_calls:.0f} of them '
        f"the package's, in {modules} modules",
        'rotate 90 timed, circle 1 cycle, timed out-and-back, two runs each, the 50 Hz simulator '
        'stepped in lockstep. Identical: the final poses equal to the bit. Target on '
        'EventsExecutor (the executables use it). Calls: every Python and C call of '
        f'{run.sizes.call_steps} steps (sys.setprofile), per step; the same on any machine.',
        f'>= {core.TARGET_RTF_IN_PROCESS:g}x',
        min(rtf['events'].values()) >= core.TARGET_RTF_IN_PROCESS,
        {'events_rtf': rtf['events'], 'single_threaded_rtf': rtf['single_threaded'],
         'events_identical': same['events'],
         'single_threaded_identical': same['single_threaded'], 'step_calls': calls,
         'step_package_calls': package_calls, 'step_modules': modules})
