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

"""Rows 13-18: many robots in one ``unicycle_sim`` process (its ``robots`` parameter)."""

import math
import os
import sys
import time

from benchmark import core
from benchmark.core import Row
from benchmark.core import row
from benchmark.load import RATE_HZ
from benchmark.processes import drive_text
from benchmark.processes import motions_run
from builtin_interfaces.msg import Time
from nav_msgs.msg import Odometry
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from sim_diffdrive import harness
from sim_diffdrive.sim.node import PARAMETERS

FREE_CLOCK_RTF = 10000.0  # the achievable factor's real_time_factor: far above what it reaches
fmt3 = '{:.3f}'.format
# The load's own module (benchmark/load.py) imports rclpy and the lockstep only: not this one's
# harness, numpy and motions, 0.2 CPU s more at each of its starts.
LOAD = ('import sys; sys.path.insert(0, %r); from benchmark.load import load; '
        'load(*sys.argv[1:4])' % os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def publish_cost(pub, count):
    """Publish the simulator's Odometry `count` times; return this process's CPU s per publish."""
    msg = Odometry()
    msg.header.frame_id, msg.child_frame_id = 'r0/odom', 'r0/base_footprint'
    defaults = {spec.name: spec.default for spec in PARAMETERS}
    msg.pose.covariance[::7] = defaults['pose_covariance_diagonal']
    msg.twist.covariance[::7] = defaults['twist_covariance_diagonal']
    start = harness.cpu_seconds(os.getpid())
    for k in range(count):
        msg.header.stamp = Time(sec=k // 50, nanosec=k % 50 * 20_000_000)
        msg.pose.pose.position.x = 0.001 * k
        pub.publish(msg)
    return (harness.cpu_seconds(os.getpid()) - start) / count


def window(graph, pid, first, seconds):
    """Measure CPU s of pid, wall s, steps and sim s (r0's odometry): `seconds`, 5 steps."""
    cpu, steps, wall = harness.cpu_seconds(pid), len(first.odoms), time.monotonic()
    stamp = harness.stamp_s(first.odom)
    graph.spin_until(lambda: time.monotonic() - wall >= seconds
                     and len(first.odoms) - steps >= 5, seconds + 10.0, poll=0.005)
    return {'cpu_s': harness.cpu_seconds(pid) - cpu, 'wall_s': time.monotonic() - wall,
            'steps': len(first.odoms) - steps, 'sim_s': harness.stamp_s(first.odom) - stamp}


def start_sims(run, graph, counts, free_clock):
    """
    Start a unicycle_sim with robots r0.. per count; return {count: (process, ...)}.

    Each: (process, namespace, probe of r0, probe of the last robot, parameter client or None).

    free_clock: owning /clock at FREE_CLOCK_RTF (with --quick at real time until measure_sim
    sets it: not a core burnt while it is found); start one just before measuring it.  Its
    parameter client is made before the probes' odometry subscriptions, which discovery
    announces in that order, so odometry heard shows that the simulator has matched the
    client's reply reader too: a request sent before that is answered into the void
    (rmw_fastrtps waits 100 ms for the match, then drops the response; under load discovery
    takes longer).
    """
    sims = {}
    for n in counts:
        ns = f'/fleet_{"lockstep" if free_clock else "wall"}_{n}'
        client = None if not free_clock else AsyncParameterClient(
            graph.add(Node('fleet_parameters', context=graph.context, enable_rosout=False)),
            ns + '/unicycle_sim')
        probes = {k: graph.probe('fleet', f'{ns}/r{k}', False, listen_only=True,
                                 enable_rosout=False) for k in {0, n - 1}}
        sims[n] = (run.start('unicycle_sim', namespace=ns, rate_hz=RATE_HZ, **(
            {'publish_clock': True, 'real_time_factor': 1.0 if run.sizes.quick
             else FREE_CLOCK_RTF} if free_clock else {}),
            robots=str([f'r{k}' for k in range(n)])), ns, probes[0], probes[n - 1], client)
    return sims


def measure_sim(run, graph, robots, sim, free_clock):
    """Measure a started simulator idle, then commanded by a load process; stop both."""
    (sim, namespace, first, last, client), sizes, load = sim, run.sizes, None

    def real_time_factor(value):
        done = client.set_parameters([Parameter('real_time_factor', value=value)])
        if not graph.spin_until(done.done, 10.0):
            raise RuntimeError(f'unicycle_sim did not answer setting real_time_factor {value:g}')
        if not done.result().results[0].successful:
            raise RuntimeError(f'unicycle_sim refused real_time_factor {value:g}: '
                               + done.result().results[0].reason)
    try:
        if not graph.spin_until(lambda: len(first.odoms) > 2, 30.0, poll=0.005):
            raise RuntimeError(f'no odometry from unicycle_sim:\n{run.stop(sim)}')
        if free_clock and sizes.quick:
            real_time_factor(FREE_CLOCK_RTF)  # --quick: started at real time (start_sims)
        graph.spin_for(sizes.fleet_settle_s)
        idle = window(graph, sim.pid, first, sizes.fleet_window_s)
        if free_clock:
            # A participant answers once it has handled a step; at full speed the first steps
            # come faster than a commander of 256 robots handles one.  So: join at real time.
            real_time_factor(1.0)
        load = run.start(sys.executable, '-c', LOAD, 'lockstep' if free_clock else 'wall',
                         str(robots), namespace)
        if not graph.spin_until(lambda: harness.is_moving(last.odom) and (
                not free_clock or status(load)['joined']), 30.0, poll=0.005):
            raise RuntimeError(f'the load did not drive {namespace}:\n{run.stop(load)}')
        if free_clock:
            real_time_factor(FREE_CLOCK_RTF)
        graph.spin_for(sizes.fleet_settle_s)
        ticks = status(load)['ticks']
        commands = window(graph, sim.pid, first, sizes.fleet_window_s)
        # The load says its count every 10 ms of wall time: on a busy machine the line read at
        # the end of a short window (--quick) can be the one read at its start, though the load
        # commanded every step of it (it takes part: the steps waited for it).
        graph.spin_until(lambda: status(load)['ticks'] > ticks, 10.0, poll=0.005)
        commands['commands_per_robot'] = status(load)['ticks'] - ticks
    finally:
        run.stop_all([sim] + ([load] if load is not None else []))
    return {'idle': idle, 'commands': commands}


def status(load):
    lines = [line.split() for line in load.output().splitlines() if line.startswith('load ')]
    _, ticks, heard, joined = lines[-1] if lines else ('load', 0, 0, 0)
    return {'ticks': int(ticks), 'heard': int(heard), 'joined': joined == '1'}


def fleet_windows(run):
    """
    Measure the simulators of rows 13-16 and rclpy's cost per Odometry message.

    rclpy's cost with nobody listening comes before any process starts (no discovery traffic).
    """
    s = run.sizes
    with harness.SimGraph(executor_class=EventsExecutor) as graph:
        pub = graph.probe('bench_fleet', use_sim_time=False, listen_only=True,
                          enable_rosout=False).create_publisher(Odometry, 'bench_odom', 10)
        alone = publish_cost(pub, s.fleet_messages)
        wall = start_sims(run, graph, s.fleet_robots, False)
        # Smallest first, each stopped once measured: the largest, near a core, runs alone.
        for n in sorted(wall):
            wall[n] = measure_sim(run, graph, n, wall[n], False)
        free = {n: measure_sim(run, graph, n, start_sims(run, graph, [n], True)[n], True)
                for n in s.fleet_free_robots}
        load = run.start(sys.executable, '-c', LOAD, 'listen', '0', '/')
        if not graph.spin_until(lambda: pub.get_subscription_count(), 30.0):
            raise RuntimeError(f'the load did not subscribe to bench_odom:\n{run.stop(load)}')
        heard = status(load)['heard']
        one = publish_cost(pub, s.fleet_messages)
        graph.spin_for(0.1)
        heard = status(load)['heard'] - heard
        run.stop(load)
    return dict(sorted(wall.items())), free, {
        'no_subscriber_s': alone, 'one_subscriber_s': one, 'published': s.fleet_messages,
        'heard': heard}


def in_real_time(run):
    """Return the windows on wall time, CPU per sim s (cores) idle and commanded, steps/s."""
    windows = run.once(fleet_windows)[0]

    def cores(w):  # CPU s per step, times the steps of a simulated second
        return w['cpu_s'] / w['steps'] * RATE_HZ if w['steps'] else math.nan
    return (windows, {n: cores(w['idle']) for n, w in windows.items()},
            {n: cores(w['commands']) for n, w in windows.items()},
            {n: w['commands']['steps'] / w['commands']['wall_s'] for n, w in windows.items()})


@row('fleet')
def fleet_cpu(run):
    windows, idle, busy, steps_s = in_real_time(run)
    return Row(
        'one unicycle_sim, N robots at 50 Hz in real time: CPU per simulated second',
        f'idle {core.by_n(idle, fmt3)}; every robot commanded at 50 Hz {core.by_n(busy, fmt3)} '
        'cores', 'a simulator process per robot (N x the idle N=1 figure): '
        + core.by_n({n: n * idle[min(idle)] for n in idle}, fmt3) + ' cores',
        'unicycle_sim with robots r0..r(N-1), 50 Hz on wall time; CPU of its process per step '
        f'over {run.sizes.fleet_window_s:g} s, times 50. Idle: odometry of every robot and /tf '
        'each step. Commanded: a load process sends every robot a Twist at 50 Hz (alternating '
        'values: piecewise integration); steps per wall second then: '
        + core.by_n(steps_s, lambda v: f'{v:.1f}') + ' (50: kept up). The simulators of every '
        'N start at once and are measured smallest first, each stopped once measured.',
        data={'idle_cores': idle, 'commands_cores': busy, 'commanded_steps_per_s': steps_s,
              'windows': windows})


@row('fleet')
def fleet_real_time(run):
    windows, idle, busy, steps_s = in_real_time(run)
    n = max(windows)
    return Row(
        f'{n} robots at 50 Hz in real time, each commanded at 50 Hz: CPU',
        f'{busy[n]:.2f} of a core ({steps_s[n]:.1f} steps/s)', f'idle: {idle[n]:.2f}',
        f'The commanded figure of the row above at N={n}; met when it is within one core and '
        'the simulator kept its 50 steps per second.', f'<= {core.TARGET_FLEET_CORES:g} core',
        busy[n] <= core.TARGET_FLEET_CORES and steps_s[n] >= 0.95 * RATE_HZ,
        {'robots': n, 'cores': busy[n], 'steps_per_s': steps_s[n]})


@row('fleet')
def fleet_rtf(run):
    free = run.once(fleet_windows)[1]
    rtf, cpu = ({key: {n: w[key][a] / w[key][b] for n, w in free.items()} for key in (
        'idle', 'commands')} for a, b in (('sim_s', 'wall_s'), ('cpu_s', 'sim_s')))
    # Steps from the stamps: at thousands of steps per second this process may miss some.
    answered = {n: w['commands']['commands_per_robot'] / (w['commands']['sim_s'] * RATE_HZ)
                for n, w in free.items()}
    return Row(
        'one unicycle_sim, N robots: achievable real-time factor',
        f'idle {core.by_n(rtf["idle"])}; every robot commanded each step '
        f'{core.by_n(rtf["commands"])}', 'CPU-bound: 1 / (its idle CPU per simulated s) '
        + core.by_n({n: 1.0 / v for n, v in cpu['idle'].items()}),
        f'As above with publish_clock at real_time_factor {FREE_CLOCK_RTF:g} (1 through its '
        'parameter service while the load joins), lockstep; sim s per wall s over '
        f'{run.sizes.fleet_window_s:g} s. '
        'Idle: no participant. Commanded: the load takes part in the lockstep (as a motion '
        'does) and commands every robot at every step; commands per robot per step: '
        + core.by_n(answered, lambda v: f'{v:.2f}') + '. Simulator CPU per simulated s, idle: '
        + core.by_n(cpu['idle'], fmt3) + '; commanded: ' + core.by_n(cpu['commands'], fmt3)
        + '.', data={'idle_rtf': rtf['idle'], 'commands_rtf': rtf['commands'],
                     'commands_per_robot_step': answered, 'idle_cpu_per_sim_s': cpu['idle'],
                     'commands_cpu_per_sim_s': cpu['commands'], 'windows': free})


@row('fleet')
def fleet_per_robot(run):
    windows, idle, busy, _ = in_real_time(run)
    message, low, high = run.once(fleet_windows)[2], min(windows), max(windows)
    per_robot = {key: (c[high] - c[low]) / RATE_HZ / (high - low) for key, c in (
        ('idle', idle), ('commands', busy))}
    ratio, ratio_reader = (per_robot['idle'] / message[key] for key in (
        'no_subscriber_s', 'one_subscriber_s'))

    def us(seconds):
        return f'{seconds * 1e6:.1f} us'
    return Row(
        'simulator cost per robot vs rclpy cost per Odometry message',
        f'{us(per_robot["idle"])} per robot per step idle, {us(per_robot["commands"])} '
        f'commanded', f'rclpy publish of one Odometry: {us(message["no_subscriber_s"])} (no '
        f'subscriber), {us(message["one_subscriber_s"])} (one, in another process)',
        f'Per robot: (CPU per step at N={high} - at N={low}) / {high - low} (row 13). Per '
        "message: this process publishes the simulator's Odometry (frames, covariances) "
        f"{message['published']} times, its CPU per publish; with no subscriber before any "
        "other process starts (as all robots' odometry but r0's), then with the load "
        f"subscribed ({message['heard']} heard). Idle ratio {ratio:.2f}x (to one subscriber: "
        f'{ratio_reader:.2f}x).',
        '<= {:g} us idle, <= {:g} us commanded'.format(*core.TARGET_PER_ROBOT_US),
        all(per_robot[key] * 1e6 <= target
            for key, target in zip(('idle', 'commands'), core.TARGET_PER_ROBOT_US)),
        {'per_robot_s': per_robot, 'per_message_s': message, 'ratio': ratio,
         'ratio_one_subscriber': ratio_reader})


@row('fleet')
def fleet_motions(run):
    n = run.sizes.fleet_motion_robots
    reused = ('motions_run', (n, False), ()) in run.measurements  # by row 12
    one, many = run.once(motions_run, n, True), run.once(motions_run, n, False)

    def text(m, processes):
        return (f'{processes}: wall {m["wall_s"]:.1f} s, {core.fmt_x(m["rtf"])}, '
                f'{m["robots"] - m["failed"]}/{m["robots"]} finished, worst '
                f'{m["worst_mm"]:.3f} mm, {m["worst_deg"]:.4f} deg')
    return Row(
        f'{n} robots with motions: one simulator vs pairs',
        text(one, 'one unicycle_sim + one motion_fleet (2 processes)'),
        text(many, f'{n} unicycle_sim + motion pairs ({2 * n} processes)'),
        f'Each robot runs {drive_text(run)}. One simulator: unicycle_sim with robots robot0.., '
        f'owning /clock (real_time_factor {run.rtf:g}, lockstep) once motion_fleet (one motion '
        'per robot namespace, on sim time) is up. Pairs: as in row 12'
        + (' (measured there, in this run)' if reused else '') + '. Factor and error as there.',
        f'>= {core.TARGET_FLEET_MOTIONS_RTF:g}x (one simulator)',
        not one['failed'] and one['rtf'] >= core.TARGET_FLEET_MOTIONS_RTF,
        data={'one_simulator': one, 'pairs': many, 'pairs_from_row_12': reused})


@row('fleet')
def fleet_idle_large(run):
    n = run.sizes.fleet_idle_robots
    # --quick measures as many robots as row 13's largest: its idle window is this row's.
    reused = n in run.sizes.fleet_robots
    idle = run.once(fleet_windows)[0][n]['idle'] if reused else idle_window(run, n)
    cores, steps_s = idle['cpu_s'] / idle['wall_s'], idle['steps'] / idle['wall_s']
    return Row(
        f'{n} robots idle at 50 Hz in real time: CPU', f'{cores:.2f} of a core '
        f'({steps_s:.1f} steps/s)', f'a simulator process per robot: {n} processes',
        f'unicycle_sim with robots r0..r{n - 1} on wall time, none commanded: odometry of every '
        f'robot and /tf each step; CPU of its process over {run.sizes.fleet_window_s:g} s '
        "(wall) and the steps r0's odometry shows" + (
            ' (measured in row 13, this run)' if reused else '') + '. Met within one core at '
        '50 steps/s.',
        f'<= {core.TARGET_FLEET_CORES:g} core, 50 steps/s',
        cores <= core.TARGET_FLEET_CORES and steps_s >= 0.95 * RATE_HZ,
        {'robots': n, 'cores': cores, 'steps_per_s': steps_s, 'window': idle,
         'from_row_13': reused})


def idle_window(run, n):
    """Start a unicycle_sim with n robots on wall time; measure it idle (window()); stop it."""
    with harness.SimGraph(executor_class=EventsExecutor) as graph:
        (sim, _, first, _, _), = start_sims(run, graph, [n], False).values()
        try:
            # Making a thousand robots' publishers and subscriptions takes a few seconds.
            if not graph.spin_until(lambda: len(first.odoms) > 2, 120.0, poll=0.005):
                raise RuntimeError(f'no odometry from unicycle_sim:\n{run.stop(sim)}')
            graph.spin_for(run.sizes.fleet_settle_s)
            return window(graph, sim.pid, first, run.sizes.fleet_window_s)
        finally:
            run.stop(sim)
