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
Rows 7-12: the executables as a user starts them, over DDS, watched from this process.

``watch_motion`` (row 7) is also ``make demo``'s run; ``motions_run`` (row 12) also row 17's.
"""

import itertools
import math
import os
import random
import re
import sys
import time

from benchmark import core
from benchmark.core import Row
from benchmark.core import row
from benchmark.one_process import one_process
from benchmark.originals import closure
from benchmark.round_trips import round_trips
import numpy as np
from rclpy.clock import Clock
from rclpy.clock import ClockType
from rclpy.experimental import EventsExecutor
from sim_diffdrive import harness

ROTATE = {'angular_speed_deg': 60.0, 'angle_deg': 90.0, 'clockwise': True}
# name: label, executable, parameters, simulated seconds (about), turn from the start [deg].
MOTIONS = {
    'rotate': ('rotate_robot (timed)', 'rotate_robot', {**ROTATE, 'mode': 'timed'}, 1.5, -90),
    'rotate_odom': ('rotate_robot (odom)', 'rotate_robot', {**ROTATE, 'mode': 'odom'}, 1.5, -90),
    'circle': ('circle_back_and_forth', 'circle_back_and_forth', {'cycles': 1}, 30.0, 0),
    'circle_5s': ('circle_back_and_forth (1 cycle, 5 s half period)', 'circle_back_and_forth',
                  {'cycles': 1, 'half_period': 5.0}, 10.0, 0),
    'out_and_back': ('timed_out_and_back', 'timed_out_and_back', {}, 20.3, 0),
    'odom_out_and_back': ('odom_out_and_back', 'odom_out_and_back', {}, 21.0, 0),
}
TIMEOUT_S = 20.0  # wall s (and 4 per robot) for the motion processes of rows 12 and 17
# What rclpy alone costs for an idle one-robot simulator's work: an EventsExecutor, a 50 Hz
# steady timer, and the simulator's odometry and /tf bytes published at each tick (the same
# sizes, through rclpy's serialized publish).  Row 9's reference: the floor under its figure.
# With the argument 'loop', the same publishes from a plain sleeping loop, no executor: what
# delivering them costs, under any Python node that publishes odometry at 50 Hz.
FLOOR = """
import sys
import time

import numpy as np
import rclpy
from nav_msgs.msg import Odometry
from rclpy.clock import Clock, ClockType
from rclpy.experimental import EventsExecutor
from sim_diffdrive.cdr import covariance, OdometryLayout, TransformLayout
from sim_diffdrive.sim.odom_tf import TF_QOS
from tf2_msgs.msg import TFMessage
rclpy.init()
node = rclpy.create_node('bench_floor', enable_rosout=False)
odom = node.create_publisher(Odometry, 'bench_floor_odom', 10)
tf = node.create_publisher(TFMessage, 'bench_floor_tf', TF_QOS)
frames, zero, one = [('odom', 'base_footprint')], np.zeros(1), np.ones(1)
odom_bytes = OdometryLayout(frames, covariance([0.0] * 6), covariance([0.0] * 6)).serialize(
    0, 0, zero, zero, zero, one, zero, zero)[0]
tf_bytes = TransformLayout(frames).serialize(0, 0, zero, zero, zero, one)


def tick():
    odom.publish(odom_bytes)
    tf.publish(tf_bytes)


try:
    if sys.argv[1:2] == ['loop']:  # run.start appends --ros-args
        due = time.monotonic()
        while rclpy.ok():
            due += 0.02
            time.sleep(max(0.0, due - time.monotonic()))
            tick()
    else:
        node.create_timer(0.02, tick, clock=Clock(clock_type=ClockType.STEADY_TIME))
        executor = EventsExecutor()
        executor.add_node(node)
        while rclpy.ok():  # as the executables spin (runtime.spin_until_done)
            executor.spin_once(timeout_sec=0.1)
except KeyboardInterrupt:
    pass
"""
# Row 9's second reference: a Python process that only sleeps and wakes at 50 Hz, no ROS: what
# each wake of a thread costs on this machine, whatever it then does.
SLEEPER = """
import time
due = time.monotonic()
try:
    while True:
        due += 0.02
        time.sleep(max(0.0, due - time.monotonic()))
except KeyboardInterrupt:
    pass
"""
LEFT = re.compile(r'Lockstep: \S+ left at \S+ s \((\d+) answers in (\d+) steps\)')
DONE = re.compile(r'Done in ([0-9.]+) s \(([0-9.]+) s wall\).* error ([0-9.]+) mm, ([0-9.]+) deg')


def watch_motion(graph, start, stop, motion, rtf, **sim_params):
    """
    Run a motion (of MOTIONS) against a fresh unicycle_sim owning the clock at rtf; watch it.

    Returns the exit code, log and odometry heard (and when); then the goal, the resting pose,
    its error, and the sim and wall s of the movement, from rest to rest.
    """
    _, executable, params, sim_seconds, turn_deg = MOTIONS[motion]
    # One observer per motion in the same graph: without /rosout, rcl does not warn about the
    # name used again.  It keeps 4 s of odometry at the simulator's free pace: descheduled
    # on a busy machine, it kept 200, and the simulator running free again after the motion
    # left pushed out every moving one unread.
    probe = graph.probe('motion_observer', listen_only=True, enable_rosout=False, depth=10_000)
    processes, code = [], 'no odometry'
    try:
        processes.append(start('unicycle_sim', publish_clock=True, real_time_factor=rtf,
                               **sim_params))
        if graph.spin_until(lambda: probe.odom is not None, 15.0):
            processes.insert(0, start(executable, use_sim_time=True, **params))
            # In lockstep the pace is the graph's, not rtf's: allow down to real time.
            exited = graph.spin_until(lambda: processes[0].poll() is not None,
                                      15.0 + sim_seconds / min(rtf, 1.0))
            code, seen = processes[0].returncode if exited else 'timeout', len(probe.odoms)
            graph.spin_until(lambda: len(probe.odoms) > seen + 2  # at rest, the motion gone
                             and not harness.is_moving(probe.odom), 2.0)
    finally:
        logs = [stop(process) for process in processes] or ['']
        graph.remove(probe)
    result = {'exit': code, 'log': logs[0], 'odoms': probe.odoms, 'walls': probe.odom_walls}
    # The simulator's count of the motion's lockstep answers, logged when the motion left.
    left = LEFT.search(logs[-1]) if len(logs) > 1 else None
    if left:
        result['answers_per_step'] = int(left.group(1)) / max(int(left.group(2)), 1)
    moving = [i for i, odom in enumerate(probe.odoms) if harness.is_moving(odom)]
    if probe.odoms:
        x, y, yaw = harness.pose_of(probe.odoms[0])
        goal = x, y, math.remainder(yaw + math.radians(turn_deg), 2.0 * math.pi)
        result.update(goal=goal, end=harness.pose_of(probe.odom))
        result['error_mm'], result['error_deg'] = closure(goal, result['end'])
    if moving and moving[-1] + 1 < len(probe.odoms):  # at rest before and after
        before, after = max(moving[0] - 1, 0), moving[-1] + 1
        result['sim_s'] = (harness.stamp_s(probe.odoms[after])
                           - harness.stamp_s(probe.odoms[before]))
        result['wall_s'] = probe.odom_walls[after] - probe.odom_walls[before]
    else:  # why the run could not be timed, with what both processes said
        last = 'none' if not probe.odoms else 'moving' if moving else 'at rest'
        result['untimed'] = (f'{len(probe.odoms)} odometry heard, {len(moving)} of it moving, '
                             f'the last {last}:\n' + '\n'.join(core.tail(log) for log in logs))
    return result


def motion_processes(run):
    with harness.SimGraph(executor_class=EventsExecutor) as graph:
        return {motion: [watch_motion(graph, run.start, run.stop, motion, run.rtf)
                         for _ in range(run.sizes.process_runs)]
                for motion in run.sizes.process_motions}


@row('processes')
def rtf_processes(run):
    results = run.once(motion_processes)
    failed = [f'{m}: {r["exit"]}' for m, runs in results.items() for r in runs if r['exit']]
    timed = {m: [r for r in runs if not r['exit'] and 'sim_s' in r] for m, runs in results.items()}
    rtf = {m: sum(r['sim_s'] for r in rs) / sum(r['wall_s'] for r in rs) if rs else math.nan
           for m, rs in timed.items()}
    errors = {m: [(r.get('error_mm', math.nan), r.get('error_deg', math.nan)) for r in runs]
              for m, runs in results.items()}
    # Whether the runs of each motion ended at the same pose (None: one run each).
    identical = None if run.sizes.process_runs < 2 else not failed and all(
        r['end'] == runs[0]['end'] for runs in results.values() for r in runs)
    worst_mm, worst_deg = np.nanmax(list(errors.values()), axis=(0, 1))
    answers = {m: np.mean([r.get('answers_per_step', math.nan) for r in runs])
               for m, runs in results.items()}
    pair = run.once(round_trips)  # beside it: two processes' round trips [us]
    pings = pair['ping_pong']
    round_trip_us, p90_us = np.median(pings), np.percentile(pings, 90)
    bare_us = np.median(pair['bare_step'])  # and a step's four messages alone
    # A step is 20 ms of simulated time: its wall cost at the slowest motion's factor.
    step_us = 2e4 / min((x for x in rtf.values() if math.isfinite(x)), default=math.nan)
    ratio = step_us / round_trip_us
    return Row(
        'real-time factor across processes (sim s / wall s), from odometry',
        ', '.join(f'{m} {core.fmt_x(x)}' for m, x in rtf.items()) + '; identical: '
        + {True: 'yes', False: 'no', None: '- (one run)'}[identical]
        + (f'; {len(failed)} runs failed' if failed else ''),
        f"clock set to {run.rtf:g}x; ping-pong round trip {round_trip_us:.0f} us; a step's "
        f'four messages alone {bare_us:.0f} us; a step costs {step_us:.0f} us = {ratio:.1f}x '
        f'the round trip, {step_us / bare_us:.1f}x its messages',
        f'unicycle_sim (publish_clock, real_time_factor {run.rtf:g}, 50 Hz) and the motion '
        'executables, a fresh simulator each run; sim and wall s of the movement on odometry. '
        "In lockstep: one round trip per 20 ms step; answers per step (the simulator's "
        'count): ' + ', '.join(f'{m} {a:.2f}' for m, a in answers.items())
        + '. Ping-pong: two Python processes that only bounce one raw std_msgs/UInt64 '
        "(rclpy's serialized publish, raw subscriptions, EventsExecutor spin_once loops, the "
        f"package's DDS profile): median of {len(pings)} round trips after "
        f"{run.sizes.ping_pongs[1]} warm-up (p90 {p90_us:.0f} us). A step's messages alone: "
        'one process publishes odometry bytes and a /clock, the other answers from a 50 Hz '
        "timer on that clock with a Twist and an answer, as many steps (median). A step's "
        "cost: 20 ms of simulated time at the slowest motion's factor. Worst error "
        f'{worst_mm:.3g} mm, {worst_deg:.3g} deg.' + ''.join(f' Failed: {f}.' for f in failed),
        f'>= {core.TARGET_RTF_PROCESSES:g}x',
        not failed and min(rtf.values()) >= core.TARGET_RTF_PROCESSES,
        {'rtf': rtf, 'identical': identical, 'errors_mm_deg': errors, 'failures': failed,
         'answers_per_step': answers, 'round_trip_us': float(round_trip_us),
         'round_trip_p90_us': float(p90_us), 'bare_step_us': float(bare_us),
         'step_us': step_us, 'step_over_round_trip': ratio,
         'untimed': [r['untimed'] for rs in results.values() for r in rs if 'untimed' in r],
         'failure_logs': [core.tail(r['log']) for rs in results.values() for r in rs
                          if r['exit']]})


def wakes(pid):
    """
    Return how often each thread of pid has gone to sleep and woken since it started.

    Voluntary context switches (/proc), summed by thread name: the main thread is 'main', the
    threads that kept the process's name (rclpy's) 'unnamed'.
    """
    counts = {}
    with open(f'/proc/{pid}/comm') as comm:
        process_name = comm.read().strip()
    for task in os.listdir(f'/proc/{pid}/task'):
        try:
            with open(f'/proc/{pid}/task/{task}/status') as status:
                fields = dict(line.split(':', 1) for line in status)
        except (FileNotFoundError, ProcessLookupError):
            continue  # a thread that just ended
        # Fast DDS numbers its threads (dds.shm.7000): one name for each kind.
        name = re.sub(r'(\.\d+)+$', '', fields['Name'].strip())
        name = 'main' if task == str(pid) else 'unnamed' if name == process_name else name
        counts[name] = counts.get(name, 0) + int(fields['voluntary_ctxt_switches'])
    return counts


def cpu_percent(pid, wait, seconds):
    """Return the CPU of process pid [% of a core] while wait(seconds) passes (/proc)."""
    used, wall = harness.cpu_seconds(pid), time.monotonic()
    wait(seconds)
    return 100.0 * (harness.cpu_seconds(pid) - used) / (time.monotonic() - wall)


def sim_process(run):
    """Measure a unicycle_sim at 50 Hz on wall time: CPU and wakes idle, commanded; latency."""
    with harness.SimGraph(executor_class=EventsExecutor) as graph:
        probe, sim = graph.probe('bench_observer', use_sim_time=False), run.start(
            'unicycle_sim', rate_hz=50.0)
        try:
            if not graph.spin_until(lambda: probe.odom is not None
                                    and probe.cmd_pub.get_subscription_count() > 0, 15.0):
                raise RuntimeError(f'no odometry from unicycle_sim:\n{run.stop(sim)}')
            graph.spin_for(run.sizes.cpu_settle_s)
            before, heard = wakes(sim.pid), len(probe.odoms)
            idle = cpu_percent(sim.pid, graph.spin_for, run.sizes.cpu_seconds)
            after, steps = wakes(sim.pid), len(probe.odoms) - heard
            # Per odometry step, by thread: what the idle figure is made of on a machine where
            # a wake costs more than the work it wakes for.
            woken = {name: (count - before.get(name, 0)) / max(steps, 1)
                     for name, count in after.items() if count > before.get(name, 0)}
            sent = itertools.count()  # then 10 Hz commands on wall time
            timer = probe.create_timer(0.1, lambda: probe.send(0.1, (0.2, 0.3)[next(sent) % 2]),
                                       clock=Clock(clock_type=ClockType.STEADY_TIME))
            busy = cpu_percent(sim.pid, graph.spin_for, run.sizes.cpu_seconds)
            probe.destroy_timer(timer)
            latencies, lost, pause = [], 0, random.Random(1)
            for k in range(run.sizes.latency_samples):
                angular, sent_at = 0.1 + 0.001 * k, time.monotonic()
                probe.send(0.0, angular)
                if graph.spin_until(lambda: harness.twist_of(probe.odom) == (0.0, angular)
                                    and probe.odom_walls[-1] >= sent_at, 1.0, poll=0.0005):
                    latencies.append(1000.0 * (probe.odom_walls[-1] - sent_at))
                else:
                    lost += 1
                # A random pause samples every phase of the simulator's 50 Hz odometry timer.
                graph.spin_for(pause.uniform(0.02, 0.045))
        finally:
            run.stop(sim)
    return idle, busy, latencies, lost, woken


def sleeper_process(run):
    """Measure SLEEPER's CPU [% of a core] over as long a window as the simulator's."""
    sleeper = run.start(sys.executable, '-c', SLEEPER)
    try:
        time.sleep(run.sizes.cpu_settle_s)
        return cpu_percent(sleeper.pid, time.sleep, run.sizes.cpu_seconds)
    finally:
        run.stop(sleeper)


def floor_process(run, *args):
    """Measure FLOOR's CPU [% of a core] as the simulator's is measured, one subscriber here."""
    with harness.SimGraph(executor_class=EventsExecutor) as graph:
        listener = graph.probe('bench_floor_listener', use_sim_time=False, listen_only=True,
                               odom_topic='bench_floor_odom')
        floor = run.start(sys.executable, '-c', FLOOR, *args)
        try:
            if not graph.spin_until(lambda: len(listener.odoms) > 2, 15.0):
                raise RuntimeError(f'nothing from the rclpy floor process:\n{run.stop(floor)}')
            graph.spin_for(run.sizes.cpu_settle_s)
            return cpu_percent(floor.pid, graph.spin_for, run.sizes.cpu_seconds)
        finally:
            run.stop(floor)


@row('sim')
def latency(run):
    _, _, latencies, lost, _ = run.once(sim_process)
    p50, p99 = np.percentile(latencies, (50, 99)) if latencies else (math.nan, math.nan)
    return Row(
        'cmd_vel -> odom latency across processes, wall time',
        f'p50 {p50:.1f} ms, p99 {p99:.1f} ms' if latencies else 'no sample',
        'one odometry period: 20.0 ms', 'unicycle_sim at 50 Hz on wall time; this process '
        'sends a Twist with a new value and times the first odometry whose twist equals it '
        f'({len(latencies)} samples, {lost} lost, random 20-45 ms pauses). Odometry comes on '
        'the 50 Hz timer only, so the wait for its next tick (0-20 ms) dominates.',
        f'p99 <= {core.TARGET_LATENCY_P99_MS:g} ms',
        p99 <= core.TARGET_LATENCY_P99_MS and not lost,
        {'p50_ms': p50, 'p99_ms': p99, 'samples': len(latencies), 'lost': lost,
         'max_ms': max(latencies, default=None)})


@row('sim')
def cpu_idle(run):
    idle, busy, _, _, woken = run.once(sim_process)
    floor, publishing = run.once(floor_process), run.once(floor_process, 'loop')
    sleeping = run.once(sleeper_process)
    return Row(
        'unicycle_sim CPU, idle (50 Hz odometry, one subscriber)', f'{idle:.2f} % of a core',
        f'rclpy alone: {floor:.2f} %; its publishes alone: {publishing:.2f} %; a loop that only '
        f'wakes: {sleeping:.2f} %; under 10 Hz cmd_vel: {busy:.2f} %', 'CPU time of its threads '
        f'(/proc) over {run.sizes.cpu_seconds:g} s of wall time, on wall time, publishing '
        'odometry to this process. rclpy alone: a process with an EventsExecutor and a 50 Hz '
        "timer publishing the simulator's odometry and /tf bytes, measured the same way: the "
        "floor under the simulator's figure on this machine. Its publishes alone: the same "
        'bytes from a plain 50 Hz sleeping loop, no executor: what delivering them costs any '
        'Python node. A loop that only wakes: Python sleeping to the next 20 ms and nothing '
        "else, no ROS: one thread's wake at 50 Hz on this machine. The simulator's threads "
        f'woke {sum(woken.values()):.1f} times a step ('
        + ', '.join(f'{name} {count:.1f}' for name, count in sorted(
            woken.items(), key=lambda item: -item[1])) + ').',
        f'<= {core.TARGET_IDLE_CPU_PERCENT:g} %', idle <= core.TARGET_IDLE_CPU_PERCENT,
        {'idle_percent': idle, 'commands_percent': busy, 'rclpy_floor_percent': floor,
         'publish_floor_percent': publishing, 'sleep_floor_percent': sleeping,
         'wakes_per_step': woken})


@row('sim')
def cpu_commands(run):
    idle, busy, _, _, _ = run.once(sim_process)
    return Row(
        'unicycle_sim CPU under 10 Hz cmd_vel', f'{busy:.2f} % of a core', f'idle: {idle:.2f} %',
        f'Same process, {run.sizes.cpu_seconds:g} s with a Twist every 100 ms (alternating '
        'values) from this process.', data={'idle_percent': idle, 'commands_percent': busy})


def motions_run(run, robots, one_simulator):
    """
    Run `robots` odom_out_and_back motions on sim time; start the clock owner once connected.

    one_simulator: one motion_fleet and one unicycle_sim; otherwise a pair per robot, stamped
    (a command overtaking its /clock is still applied at its step).  Sums up closing lines.
    """
    names = [f'robot{k}' for k in range(robots)]
    motion = {'use_sim_time': True, 'start_timeout': 120.0, **run.sizes.scaling_motion}
    if one_simulator:
        owner, followers = {'robots': str(names)}, []
        motions = [run.start('motion_fleet', robots=str(names),
                             motions='[odom_out_and_back]', **motion)]
    else:
        owner = {'namespace': '/robot0', 'stamped': True}
        followers = [run.start('unicycle_sim', namespace=f'/{name}', use_sim_time=True,
                               stamped=True) for name in names[1:]]
        motions = [run.start('odom_out_and_back', namespace=f'/{name}', stamped=True, **motion)
                   for name in names]
    with harness.SimGraph(executor_class=EventsExecutor) as graph:
        probe = graph.probe('bench_probe', listen_only=True)
        try:
            if not graph.spin_until(lambda: all(
                    probe.count_publishers(f'/{name}/cmd_vel') and (
                        one_simulator or k == 0 or probe.count_subscribers(f'/{name}/cmd_vel'))
                    for k, name in enumerate(names)), 30.0 + 2.0 * robots, poll=0.05):
                raise RuntimeError(f'{robots} robots did not come up')
            started = time.monotonic()
            followers.append(run.start('unicycle_sim', publish_clock=True, **owner,
                                       real_time_factor=run.rtf, lockstep_timeout=TIMEOUT_S))
            done = graph.spin_until(lambda: all(m.poll() is not None for m in motions),
                                    TIMEOUT_S + 4.0 * robots, poll=0.05)
            wall_s = max(m.exited_at for m in motions) - started if done else math.nan
        finally:
            outputs = run.stop_all(motions) + run.stop_all(followers)
    outputs, simulators = outputs[:len(motions)], outputs[len(motions):]
    closings = [tuple(map(float, m.groups())) for out in outputs for m in DONE.finditer(out)]
    return {'rtf': min((s / w if w > 0 else math.inf for s, w, _, _ in closings),
                       default=math.nan),
            'worst_mm': max((mm for _, _, mm, _ in closings), default=math.nan),
            'worst_deg': max((deg for *_, deg in closings), default=math.nan),
            'failed': robots - len(closings), 'robots': robots, 'wall_s': wall_s,
            'exit_codes': [m.returncode for m in motions],
            'logs': ([core.tail(out, 30) for out in outputs + simulators]
                     if len(closings) < robots else [])}


def drive_text(run):
    return 'odom_out_and_back (' + ', '.join(
        f'{k} {v:g}' for k, v in run.sizes.scaling_motion.items()) + ')'


def scaling(run):  # rows 11 and 12's runs and texts
    one = {n: run.once(one_process, n) for n in run.sizes.robots}
    many = {n: run.once(motions_run, n, False) for n in run.sizes.robots_processes}
    return one, many, core.by_n(one), ', '.join(
        f'N={n}: {core.fmt_x(m["rtf"])} ({m["worst_mm"]:.3f} mm'
        + (f', {m["failed"]} not done)' if m['failed'] else ')') for n, m in many.items())


@row('scaling')
def scaling_one_process(run):
    one, _, one_text, many_text = scaling(run)
    return Row(
        'N robots in one process, real-time factor', one_text, 'as 2N processes: ' + many_text,
        f'Simulator + {drive_text(run)} pairs (/robotK) in one EventsExecutor, stepped in '
        f'lockstep over {run.sizes.scaling_window_s:g} s of simulated time.', data={'rtf': one})


@row('scaling')
def scaling_processes(run):
    _, many, one_text, many_text = scaling(run)
    return Row(
        'N robots as 2N processes, real-time factor (worst closure)', many_text,
        'one process: ' + one_text,
        f"unicycle_sim and {drive_text(run)} per robot (/robotK), robot 0's simulator owning "
        f'/clock (real_time_factor {run.rtf:g}) and waiting for the 2N-1 others each step; '
        "TwistStamped commands. Factor: the slowest motion's sim s / wall s; error: the "
        "largest; from the motions' closing lines (not done: none within "
        f'{TIMEOUT_S:g} s + 4 s per robot).',
        data={'rtf': {n: m['rtf'] for n, m in many.items()},
              'worst_error_mm': {n: m['worst_mm'] for n, m in many.items()},
              'not_done': {n: m['failed'] for n, m in many.items()}, 'runs': many})
