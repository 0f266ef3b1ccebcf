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
In-process rows: the motions and the reproduced originals against the simulator node, in lockstep.

Rows 1-6: rotation yaw error (timed and odom mode) against the original ``rotate_robot.py``,
out-and-back closure against rbx1's tick arithmetic, circle closure against ``move_rob.py``,
the exact arc against forward Euler (pure maths), and the real-time factor of the three default
motions with EventsExecutor and SingleThreadedExecutor.
"""

import math
import time

from benchmark.config import NS
from benchmark.config import ROTATION
from benchmark.config import TARGET_CLOSURE_MM
from benchmark.config import TARGET_RTF_IN_PROCESS
from benchmark.config import TARGET_YAW_DEG
from benchmark.graph import BenchGraph
from benchmark.originals import closure
from benchmark.originals import integration_errors
from benchmark.originals import move_rob
from benchmark.originals import original_rotate
from benchmark.originals import rbx1_ticks
from benchmark.originals import rbx1_timed_out_and_back
from benchmark.originals import start_times
from benchmark.originals import yaw_error_deg
from benchmark.table import fmt_closure
from benchmark.table import fmt_deg
from benchmark.table import fmt_rtfs
from benchmark.table import met
from benchmark.table import row
from motion_challenges.circle_back_and_forth import CircleBackAndForth
from motion_challenges.rotate_robot import RotateRobot
from motion_challenges.timed_out_and_back import TimedOutAndBack
from rclpy.executors import SingleThreadedExecutor
from rclpy.experimental import EventsExecutor


# -- runs ----------------------------------------------------------------------------------------


def rotate_project(mode, count, domain_id):
    """Rotate 90 deg clockwise at 60 deg/s with rotate_robot, from count start times."""
    goal = -math.radians(ROTATION.angle_deg)
    errors = []
    with BenchGraph(EventsExecutor, domain_id) as graph:
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
    with BenchGraph(EventsExecutor, domain_id) as graph:
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
    with BenchGraph(EventsExecutor, domain_id) as graph:
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
    with BenchGraph(executor_class, domain_id) as graph:
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


def scenario_factories(sizes):
    """Return {name: make_node(graph)} for the three default motions of the speed rows."""
    def rotate(graph):
        node = graph.add_node(RotateRobot, mode='timed')
        node.start(ROTATION)
        return node

    def circle(graph):
        return graph.add_node(CircleBackAndForth, **sizes.circle_rtf)

    def out_and_back(graph):
        return graph.add_node(TimedOutAndBack, **sizes.out_and_back_rtf)
    return {'rotate': rotate, 'circle': circle, 'out_and_back': out_and_back}


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


# -- rows ----------------------------------------------------------------------------------------


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
