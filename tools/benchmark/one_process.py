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
Rows 1-6 and 11's runs: the motion nodes and the originals against the simulator node.

In one process, stepped in lockstep (``lockstep_graph``), so results are exact whatever the
machine's load: accuracy against the reproduced originals, the exact arc against Euler, and the
real-time factor of the motions, one robot or N.
"""

from contextlib import contextmanager
from dataclasses import astuple
import math
import os
import time

from benchmark import core
from benchmark import originals
from benchmark.core import Row
from benchmark.core import row
from motion_challenges.circle_back_and_forth import CircleBackAndForth
from motion_challenges.odom_out_and_back import OdomOutAndBack
from motion_challenges.prompts import RotationRequest
from motion_challenges.rotate_robot import RotateRobot
from motion_challenges.timed_out_and_back import TimedOutAndBack
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.parameter import Parameter
from sim_diffdrive.harness import SimGraph
from sim_diffdrive.sim.node import UnicycleSim

ROTATION = RotationRequest(60.0, 90.0, True)  # deg/s, deg, clockwise
GOAL = -math.radians(ROTATION.angle_deg)
MOTIONS = {'rotate': RotateRobot, 'circle': CircleBackAndForth, 'out_and_back': TimedOutAndBack}
EXECUTORS = {'events': EventsExecutor, 'single_threaded': SingleThreadedExecutor}
DISCOVERY = 'ROS_AUTOMATIC_DISCOVERY_RANGE'


@contextmanager
def lockstep_graph(executor_class=EventsExecutor, namespace=None, **sim_params):
    """
    Yield a SimGraph holding a simulator it steps, on a context of its own with discovery off.

    The nodes of one context match without discovery, and no other run on this machine can add
    to the graph's message count.  No probe: pose() reads what the odometry reports.
    """
    context, saved = Context(), os.environ.get(DISCOVERY)
    os.environ[DISCOVERY] = 'OFF'
    try:
        rclpy.init(context=context)
    finally:
        os.environ.pop(DISCOVERY)
        os.environ.update({DISCOVERY: saved} if saved else {})
    graph = SimGraph(context, executor_class)
    try:
        params = {'publish_clock': True, 'lockstep': False, **sim_params}
        graph.add_clock_owner(UnicycleSim(
            stepped=True, context=context, namespace=namespace, enable_rosout=False,
            parameter_overrides=[Parameter(k, value=v) for k, v in params.items()]))
        yield graph
    finally:
        graph.close()
        rclpy.try_shutdown(context=context)


def pose(graph):
    """Return the stepped simulator's (first) robot's (x, y, yaw)."""
    fleet = graph.clock_owner.fleet
    return float(fleet.x[0]), float(fleet.y[0]), float(fleet.yaw[0])


def drive(graph, done, rest_steps, begin):
    """Step until done() after begin(), then rest_steps more; return poses, sim s, wall s."""
    start, steps, wall = pose(graph), graph.steps, time.perf_counter()
    begin()
    graph.step_until(done, 600.0)
    graph.step(rest_steps)
    wall = time.perf_counter() - wall
    return start, pose(graph), (graph.steps - steps) * graph.step_ns / core.NS, wall


def finished(node, result):
    if node.exit_code != 0:
        raise RuntimeError(f'{node.get_name()} exited with {node.exit_code}')
    return result


def play(graph, probe, rate_hz, script):
    """Play an original script (on the model first, for its ticks) on probe; drive()'s."""
    robot = originals.ModelRobot(graph.now_ns + round(core.NS / rate_hz))
    robot.play(script(robot), rate_hz)
    probe.script_done_at = None
    return drive(graph, lambda: not probe.playing, 2, lambda: probe.play(
        [(v, w, 1) for v, w in robot.ticks], 1.0 / rate_hz))


def rotate_project(run, mode):
    """Return the yaw errors [deg] of rotate_robot in mode, from run.sizes.starts starts."""
    errors = []
    with lockstep_graph() as graph:
        for start_ns in originals.start_times(run.sizes.starts, 0.02, 1.0):
            node = graph.node(RotateRobot, mode=mode)
            graph.step()  # the new node hears the clock
            # Its first tick primes the connection with a zero Twist, the second starts.
            graph.step((start_ns - 2 * round(node.period * core.NS) - graph.now_ns)
                       // graph.step_ns)
            start, end, _, _ = finished(node, drive(graph, lambda: node.done, 5,
                                                    lambda: node.start(ROTATION)))
            if node.start_ns != start_ns:
                raise RuntimeError(f'rotate_robot ({mode}) started at {node.start_ns} ns')
            errors.append(originals.yaw_error_deg(start[2], end[2], GOAL))
            graph.remove(node)
    return errors


def rotate_original(run):
    """Return the yaw errors [deg] of the original algorithm, from run.sizes.starts starts."""
    errors = []
    # A 20 Hz simulator puts the start offsets (multiples of 50 ms) on its steps; it integrates
    # exactly between commands, so its rate does not change the pose.
    with lockstep_graph(rate_hz=20.0) as graph:
        probe = graph.probe('original')
        for start_ns in originals.start_times(run.sizes.starts, 0.05, 1.0):
            graph.step((start_ns - core.NS // 10 - graph.now_ns) // graph.step_ns)
            start, end, _, _ = play(graph, probe, 10.0, lambda robot: originals.original_rotate(
                robot, *astuple(ROTATION)))
            errors.append(originals.yaw_error_deg(start[2], end[2], GOAL))
    return errors


def play_original(script, rate_hz):
    """Play an original script once against a simulator stepping at its rate; drive()'s."""
    with lockstep_graph(rate_hz=rate_hz) as graph:
        probe = graph.probe('original')
        graph.step()
        return play(graph, probe, rate_hz, script)


def motion_run(run, executor, motion, index=0, rate_hz=50.0, **params):
    """Run motion (of MOTIONS; index tells runs apart) to its end and 5 steps more; drive()'s."""
    with lockstep_graph(EXECUTORS[executor], rate_hz=rate_hz) as graph:
        node = graph.node(MOTIONS[motion], **params)
        graph.wait_for_discovery()
        return finished(node, drive(graph, lambda: node.done, 5,
                                    lambda: motion == 'rotate' and node.start(ROTATION)))


def default_motion(run, executor, motion, index=0):
    """Run one of the three default motions of the real-time factor rows (see SIZES)."""
    params = {'rotate': {'mode': 'timed'}, 'circle': run.sizes.circle_rtf,
              'out_and_back': run.sizes.out_and_back_rtf}[motion]
    return run.once(motion_run, executor, motion, index, **params)


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
    mean, worst = (core.fmt_small(v) for v in (sum(values) / len(values), max(values)))
    return f'mean {mean}, max {worst} deg'


@row('rotate')
def rotate_timed(run, mode='timed'):
    errors, original = run.once(rotate_project, mode), run.once(rotate_original)
    return Row(
        f'rotate 90 deg cw at 60 deg/s, yaw error, {mode} mode, {run.sizes.starts} starts',
        fmt_deg(errors), f'original: {fmt_deg(original)}',
        'As the row above, with rotate_robot in odom mode (closed loop on odometry).'
        if mode == 'odom' else 'Starts spread over one second (project: on the 20 ms step of '
        'the 50 Hz simulator; original: 0.00, 0.05, ... s past a whole second). Original = '
        'rotate_robot.py reproduced: 3.14/180, t0 and now in whole seconds, 10 Hz ticks, stop '
        'once the estimate reaches the goal (topic and final stop fixed). In-process lockstep.',
        f'<= {core.TARGET_YAW_DEG} deg', max(errors) <= core.TARGET_YAW_DEG,
        {'project_errors_deg': errors, 'original_errors_deg': original})


@row('rotate')
def rotate_odom(run):
    return rotate_timed(run, 'odom')


@row('out_and_back')
def out_and_back_closure(run):
    mm, deg = originals.closure(*default_motion(run, 'events', 'out_and_back')[:2])
    ref_mm, ref_deg = originals.closure(*play_original(
        originals.rbx1_timed_out_and_back, 50.0)[:2])
    (drive_ticks, turn, turned), slow = originals.rbx1_ticks(), originals.rbx1_ticks(
        angular_speed=0.5)[2]
    changed = ', '.join(f'{k}={v}' for k, v in run.sizes.out_and_back_rtf.items())
    return Row(
        'timed out-and-back (1 m, pi, 2 legs), closure', core.fmt_closure(mm, deg),
        f'rbx1 ticks: {core.fmt_closure(ref_mm, ref_deg)}',
        f'Project: timed_out_and_back ({changed or "defaults"}), in-process lockstep. rbx1 at '
        f'50 Hz on sim time: drive int(1.0/0.2*50) = {drive_ticks} ticks (exact), turn '
        f'int(pi*50) = {turn} ticks = {turned:.2f} rad, {math.degrees(math.pi - turned):.4f} '
        'deg short per turn. Ticks come from goal_angle, not the duration: at 0.5 rad/s the '
        f'same ticks would turn {math.degrees(slow):.1f} deg.',
        f'<= {core.TARGET_CLOSURE_MM:g} mm', mm <= core.TARGET_CLOSURE_MM,
        {'project_mm': mm, 'project_deg': deg, 'rbx1_mm': ref_mm, 'rbx1_deg': ref_deg,
         'rbx1_drive_ticks': drive_ticks, 'rbx1_turn_ticks': turn})


@row('circle')
def circle_closure(run):
    cycles, half = run.sizes.circle_cycles, run.sizes.circle_half_period
    # The simulator steps at the 10 Hz of both controllers (exact between commands anyway).
    mm, deg = originals.closure(*run.once(motion_run, 'events', 'circle', 0, 10.0,
                                          cycles=cycles, half_period=half)[:2])
    ref_mm, ref_deg = originals.closure(*play_original(
        lambda node: originals.move_rob(node, cycles, half_period=half), 10.0)[:2])
    return Row(
        f'circle back-and-forth, closure after {cycles} cycles ({half:g} s half period)',
        core.fmt_closure(mm, deg), f'move_rob.py model: {core.fmt_closure(ref_mm, ref_deg)}',
        'move_rob.py at 10 Hz on sim time: every tick publishes (0.5, 0.5), both signs flipped '
        f'every {round(10 * half)} ticks and each flip published twice a tick apart, the first '
        'Twist with only the angular part (a 0.1 s turn in place); stopped after the last '
        'cycle (the original never stops). Project: circle_back_and_forth. In-process lockstep.',
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
        "Against the closed-form circle, pure maths. On a constant circle Euler's heading is "
        'exact and its error a phase lag (at most v*dt), largest mid-lap and small at whole '
        'laps; the exact arc stays at rounding level.', data={'ratio_max': ratio, **e})


@row('rtf')
def rtf_in_process(run):
    rtf, same, text = {}, {}, {}
    for executor in EXECUTORS:
        runs = {m: [default_motion(run, executor, m, i) for i in range(2)] for m in MOTIONS}
        rtf[executor] = {m: (a[2] + b[2]) / (a[3] + b[3]) for m, (a, b) in runs.items()}
        same[executor] = all(a[1] == b[1] for a, b in runs.values())
        text[executor] = (', '.join(f'{m} {x:.1f}x' for m, x in rtf[executor].items())
                          + f'; identical: {"yes" if same[executor] else "no"}')
    return Row(
        'real-time factor in one process (sim s / wall s), lockstep',
        f'EventsExecutor: {text["events"]}', f'SingleThreadedExecutor: {text["single_threaded"]}',
        'The three default motions (rotate 90 timed, circle 1 cycle, timed out-and-back), the '
        '50 Hz simulator stepped in lockstep: exact. Identical: final poses of two runs equal '
        'to the bit. The target is judged on EventsExecutor, which the executables use.',
        f'>= {core.TARGET_RTF_IN_PROCESS:g}x',
        min(rtf['events'].values()) >= core.TARGET_RTF_IN_PROCESS,
        {'events_rtf': rtf['events'], 'single_threaded_rtf': rtf['single_threaded'],
         'events_identical': same['events'], 'single_threaded_identical':
         same['single_threaded']})
