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
Rows 13-17: many robots in one ``unicycle_sim`` process (its ``robots`` parameter).

The simulator's CPU per simulated second and its achievable real-time factor for N robots,
idle and with every robot commanded each step; its cost per robot next to rclpy's cost of
publishing one Odometry, measured in the same run; and N robots running a motion against one
simulator and one ``motion_fleet`` process, next to N simulator + motion process pairs.

The commands come from a load process of its own (fleet_load.py), so the simulator's CPU,
read from /proc, is the simulator's alone; this process only counts odometry.
"""

import math
import os
import time

from benchmark.config import NS
from benchmark.config import SCALING_TIMEOUT_S
from benchmark.config import TARGET_FLEET_CORES
from benchmark.config import TARGET_PER_ROBOT_RATIO
from benchmark.fleet_load import LISTEN_TOPIC
from benchmark.fleet_load import LoadProcess
from benchmark.fleet_load import RATE_HZ
from benchmark.fleet_load import robot_name
from benchmark.graph import BenchGraph
from benchmark.processes import cpu_seconds
from benchmark.processes import tail
from benchmark.scaling import closing
from benchmark.scaling import DONE_LINE
from benchmark.scaling import scaling_processes
from benchmark.scaling import summary
from benchmark.table import fmt_x
from benchmark.table import met
from benchmark.table import row
from builtin_interfaces.msg import Time
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from sim_diffdrive.sim.node import PARAMETERS as SIM_PARAMETERS
from sim_diffdrive.sim.robot import covariance

# The simulator's real_time_factor for the achievable factor: far above what it reaches.
FREE_CLOCK_RTF = 10000.0
# Its real_time_factor until measured: one step per 20 s of wall time.
PAUSED_RTF = 0.001


def cpu_ns(pid):
    """
    Return the CPU time [ns] process pid has used so far, summed over its threads.

    From /proc/<pid>/task/*/schedstat (nanoseconds; stat's clock ticks are 10 ms, too coarse
    for short windows), or from /proc/<pid>/stat where the kernel keeps no schedstat.
    """
    total = 0
    try:
        tasks = os.listdir(f'/proc/{pid}/task')
        for task in tasks:
            try:
                with open(f'/proc/{pid}/task/{task}/schedstat') as schedstat:
                    total += int(schedstat.read().split()[0])
            except ProcessLookupError:
                pass  # a thread that just ended
    except FileNotFoundError:
        return round(cpu_seconds(pid) * NS)
    return total


def names(robots):
    return [robot_name(k) for k in range(robots)]


def yaml_list(values):
    return '[' + ', '.join(str(v) for v in values) + ']'


class Counter(Node):
    """
    Count robot r0's odometry (one per simulator step) and watch the last robot's twist.

    One node for every simulator of the rows, as a node removed from the session is waited for
    until the graph forgets it; watch() follows the next simulator, in a namespace of its own.
    """

    def __init__(self, context):
        super().__init__('bench_fleet_counter', context=context, enable_rosout=False)
        self._subs = []
        self.watch(1, '/')

    def watch(self, robots, namespace):
        """Follow a new simulator with `robots` robots in namespace: count from nothing."""
        for sub in self._subs:
            self.destroy_subscription(sub)
        self.count = 0
        self.stamp_ns = None
        self.last_twist = None
        # A destroyed subscription can still deliver what it holds while the executor does:
        # each callback knows which simulator it was made for.
        self._watching = watching = object()
        prefix = namespace.rstrip('/') + '/'
        self._subs = [
            self.create_subscription(Odometry, prefix + robot_name(0) + '/odom',
                                     lambda msg: self._on_first(msg, watching), 100),
            self.create_subscription(Odometry, prefix + robot_name(robots - 1) + '/odom',
                                     lambda msg: self._on_last(msg, watching), 10)]

    def _on_first(self, msg, watching):
        if watching is self._watching:
            self.count += 1
            self.stamp_ns = msg.header.stamp.sec * NS + msg.header.stamp.nanosec

    def _on_last(self, msg, watching):
        if watching is self._watching:
            self.last_twist = msg.twist.twist.linear.x, msg.twist.twist.angular.z


def window(session, pid, counter, seconds, min_steps=5):
    """
    Measure over `seconds` of wall time: CPU s of pid, wall s, steps and simulated s.

    The window goes on until it holds min_steps steps too (a busy machine can stall a process
    for longer than a short window), for at most 10 s more.
    """
    cpu, steps, stamp, wall = cpu_ns(pid), counter.count, counter.stamp_ns, time.monotonic()
    session.spin_until(lambda: time.monotonic() - wall >= seconds
                       and counter.count - steps >= min_steps, seconds + 10.0, poll=0.005)
    return {'cpu_s': (cpu_ns(pid) - cpu) / NS, 'wall_s': time.monotonic() - wall,
            'steps': counter.count - steps, 'sim_s': (counter.stamp_ns - stamp) / NS}


def start_sim(children, robots, free_clock):
    """
    Start a unicycle_sim with `robots` robots in a namespace of its own; return (process, ns).

    free_clock false: on wall time.  True: owning /clock (lockstep), held at PAUSED_RTF (a step
    every 20 s wall) until measure_sim sets its real_time_factor, so that it costs nothing
    while it waits.
    """
    mode = 'lockstep' if free_clock else 'wall'
    namespace = f'/fleet_{mode}_{robots}'
    params = {'robots': yaml_list(names(robots)), 'rate_hz': RATE_HZ}
    if free_clock:
        params.update(publish_clock=True, real_time_factor=PAUSED_RTF)
    return children.start('unicycle_sim', namespace=namespace, **params), namespace


def wait_up(session, probe, children, sims):
    """Wait until every started simulator, (process, namespace), has its odometry publisher."""
    if not session.spin_until(
            lambda: all(probe.count_publishers(f'{ns}/{robot_name(0)}/odom') >= 1
                        for _, ns in sims) or any(p.poll() is not None for p, _ in sims),
            30.0, poll=0.01) or any(p.poll() is not None for p, _ in sims):
        output = '\n'.join(tail(children.stop(p)) for p, _ in sims)
        raise RuntimeError(f'unicycle_sim did not come up:\n{output}')


def measure_sim(session, counter, children, load, robots, sim, sizes, free_clock):
    """
    Measure a running unicycle_sim (start_sim's (process, ns)) idle, then commanded; stop it.

    free_clock false: on wall time, the load sending a Twist to every robot at 50 Hz (its
    own timer).  True: owning the clock, set to FREE_CLOCK_RTF (publish_clock, lockstep): idle
    with no participant, so it steps as fast as it can; commanded, the load takes part in its
    lockstep and sends every robot a Twist at every step, applied before the next.
    Returns {'idle': window, 'commands': window}.
    """
    sim, namespace = sim
    mode = 'lockstep' if free_clock else 'wall'
    counter.watch(robots, namespace)
    settle_s, window_s = sizes.fleet_settle_s, sizes.fleet_window_s
    try:
        if free_clock:
            factor = RealTimeFactor(counter, namespace + '/unicycle_sim', session)
            factor.change(FREE_CLOCK_RTF)
        if not session.spin_until(lambda: counter.count > 2, 30.0, poll=0.005):
            raise RuntimeError(f'no odometry from unicycle_sim:\n{tail(children.stop(sim))}')
        session.spin_for(settle_s)
        idle = window(session, sim.pid, counter, window_s)
        if free_clock:
            # A participant answers once it has handled a step; at full speed the first steps
            # come faster than a commander of 256 robots handles one.  So: join at real time.
            factor.change(1.0)
        load.switch(mode, robots, namespace)
        if not session.spin_until(lambda: counter.last_twist not in (None, (0.0, 0.0)), 30.0,
                                  poll=0.005):
            raise RuntimeError(f"robot {robots - 1} did not move on the load's commands")
        if free_clock:
            if not session.spin_until(lambda: load.switch('status')['joined'], 30.0):
                raise RuntimeError("the load did not join the simulator's lockstep")
            factor.change(FREE_CLOCK_RTF)
        session.spin_for(settle_s)
        ticks = load.switch('status')['ticks']
        commands = window(session, sim.pid, counter, window_s)
        commands['commands_per_robot'] = load.switch('off')['ticks'] - ticks
    finally:
        children.stop(sim)
    return {'idle': idle, 'commands': commands}


class RealTimeFactor:
    """Set a unicycle_sim's real_time_factor (a live parameter) from node, spinning session."""

    def __init__(self, node, sim_name, session):
        self.client = AsyncParameterClient(node, sim_name)
        self.session = session

    def change(self, value):
        if not self.session.spin_until(self.client.services_are_ready, 30.0):
            raise RuntimeError('the parameter services of unicycle_sim did not come up')
        future = self.client.set_parameters([Parameter('real_time_factor', value=value)])
        if not self.session.spin_until(future.done, 10.0) or not all(
                result.successful for result in future.result().results):
            raise RuntimeError(f'could not set real_time_factor {value:g} on unicycle_sim')


class OdometryPublisher(Node):
    """Publish the simulator's own Odometry (frames, covariances) on LISTEN_TOPIC, timed."""

    def __init__(self, context):
        super().__init__('bench_odom_publisher', context=context, enable_rosout=False)
        self.pub = self.create_publisher(Odometry, LISTEN_TOPIC, 10)
        msg = self.msg = Odometry()
        msg.header.frame_id = robot_name(0) + '/odom'
        msg.child_frame_id = robot_name(0) + '/base_footprint'
        defaults = {spec.name: spec.default for spec in SIM_PARAMETERS}
        msg.pose.covariance = covariance(defaults['pose_covariance_diagonal'])
        msg.twist.covariance = covariance(defaults['twist_covariance_diagonal'])

    def cost(self, count):
        """
        Publish `count` times; return the CPU s per publish.

        The CPU is this process's, every thread (rclpy's conversion, Fast DDS's sending), as
        for the simulator.
        """
        msg, pub = self.msg, self.pub
        start = cpu_ns(os.getpid())
        for k in range(count):
            msg.header.stamp = Time(sec=k // 50, nanosec=k % 50 * 20_000_000)
            msg.pose.pose.position.x = 0.001 * k
            pub.publish(msg)
        return (cpu_ns(os.getpid()) - start) / NS / count


def rclpy_per_message(session, publisher, load, count, alone):
    """
    Return rclpy's CPU s per Odometry publish without and with a subscriber in another process.

    alone: the cost without, measured before; the subscriber is the load process.  Also
    returns how many messages it heard.
    """
    load.switch('listen')
    if not session.spin_until(lambda: publisher.pub.get_subscription_count() > 0, 30.0):
        raise RuntimeError('the load did not subscribe to ' + LISTEN_TOPIC)
    heard = load.switch('status')['heard']
    with_reader = publisher.cost(count)
    session.spin_for(0.1)
    heard = load.switch('off')['heard'] - heard
    return {'no_subscriber_s': alone, 'one_subscriber_s': with_reader, 'published': count,
            'heard': heard}


def fleet_motions(children, session, probe, robots, motion, rtf):
    """
    Run `robots` odom_out_and_back motions in one motion_fleet against one unicycle_sim.

    The fleet starts first (on sim time); once every robot's cmd_vel has its publisher, the
    simulator starts with ``robots``, owning /clock at rtf in lockstep with the fleet's
    motions.  Returns the summary of scaling.summary, from the motions' closing lines.
    """
    fleet_names = [f'robot{k}' for k in range(robots)]
    fleet = children.start('motion_fleet', robots=yaml_list(fleet_names),
                           motions='[odom_out_and_back]', use_sim_time=True,
                           start_timeout=120.0, **motion)
    sim = None
    try:
        if not session.spin_until(
                lambda: all(probe.count_publishers(f'/{name}/cmd_vel') >= 1
                            for name in fleet_names) or fleet.poll() is not None,
                30.0 + 0.5 * robots, poll=0.05):
            raise RuntimeError(f'motion_fleet did not come up:\n{tail(children.stop(fleet))}')
        started = time.monotonic()
        sim = children.start('unicycle_sim', robots=yaml_list(fleet_names), publish_clock=True,
                             real_time_factor=rtf, lockstep_timeout=SCALING_TIMEOUT_S)
        session.spin_until(lambda: fleet.poll() is not None, SCALING_TIMEOUT_S + 4.0 * robots,
                           poll=0.05)
        wall_s = fleet.exited_at - started if fleet.poll() is not None else math.nan
    finally:
        children.stop(fleet)
        if sim is not None:
            children.stop(sim)
    output = children.stop(fleet)
    finished = [closing(line) for line in output.splitlines() if DONE_LINE.search(line)]
    finished += [None] * (robots - len(finished))
    result = summary(finished, wall_s)
    result['exit_code'] = fleet.returncode
    if result['failed']:
        result['log'] = tail(output, 30)  # what the motions said, for whoever reads the JSON
    return result


def rows_fleet(sizes, children, domain_id, rtf, pairs=None):
    """
    Measure rows 13-17; pairs: row 12's results by robot count (str), reused when present.

    Row 12 runs the same motion as pairs, so a full run measures 16 pairs once.
    """
    with BenchGraph(domain_id=domain_id, offline=False) as session:
        # Before any other process, so no discovery traffic: rclpy's cost with nobody listening.
        publisher = session.add(OdometryPublisher(session.context))
        alone = publisher.cost(sizes.fleet_messages)
        counter = session.add(Counter(session.context))
        # The simulators on wall time start at once, with the load: their discoveries overlap
        # (one now and then waits for Fast DDS's next announcement, 3 s; not one after another).
        # Measured largest first, each stopped once measured; the others idle meanwhile.
        load = LoadProcess(children)
        try:
            real_time = {n: start_sim(children, n, False) for n in sizes.fleet_robots}
            wait_up(session, counter, children, list(real_time.values()))
            for n in sorted(real_time, reverse=True):
                real_time[n] = measure_sim(session, counter, children, load, n, real_time[n],
                                           sizes, False)
            # One clock owner at a time: each starts once the last has stopped.
            free = {}
            for n in sizes.fleet_free_robots:
                sim = start_sim(children, n, True)
                wait_up(session, counter, children, [sim])
                free[n] = measure_sim(session, counter, children, load, n, sim, sizes, True)
            per_message = rclpy_per_message(session, publisher, load, sizes.fleet_messages,
                                            alone)
        finally:
            load.close()
        one = fleet_motions(children, session, counter, sizes.fleet_motion_robots,
                            sizes.scaling_motion, rtf)
    n = sizes.fleet_motion_robots
    reused = bool(pairs and str(n) in pairs)
    many = pairs[str(n)] if reused else scaling_processes(
        children, domain_id, n, sizes.scaling_motion, rtf)
    return fleet_rows(sizes, rtf, per_message, real_time, free, one, many, reused)


def _cores(w):
    """CPU per simulated second at 50 Hz [cores at real time], from a wall-time window."""
    return w['cpu_s'] / w['steps'] * RATE_HZ if w['steps'] else math.nan


def _per_step_s(w):
    return w['cpu_s'] / w['steps'] if w['steps'] else math.nan


def _rtf(w):
    return w['sim_s'] / w['wall_s']


def _us(seconds):
    return f'{seconds * 1e6:.1f} us'


def _motions_text(m, processes):
    return (f'{processes}: wall {m["wall_s"]:.1f} s, {fmt_x(m["rtf"])}, '
            f'{m["robots"] - m["failed"]}/{m["robots"]} finished, worst '
            f'{m["worst_mm"]:.3f} mm, {m["worst_deg"]:.4f} deg')


def fleet_rows(sizes, rtf, per_message, real_time, free, one, many, reused):
    counts = sizes.fleet_robots
    low, high = counts[0], counts[-1]
    idle = {n: _cores(r['idle']) for n, r in real_time.items()}
    busy = {n: _cores(r['commands']) for n, r in real_time.items()}
    steps_s = {n: r['commands']['steps'] / r['commands']['wall_s'] for n, r in real_time.items()}
    target_n = 64 if 64 in counts else high
    per_robot = {key: (_per_step_s(real_time[high][key]) - _per_step_s(real_time[low][key]))
                 / (high - low) for key in ('idle', 'commands')}
    ratio = per_robot['idle'] / per_message['no_subscriber_s']
    ratio_reader = per_robot['idle'] / per_message['one_subscriber_s']
    rtf_idle = {n: _rtf(r['idle']) for n, r in free.items()}
    rtf_busy = {n: _rtf(r['commands']) for n, r in free.items()}
    # Steps from the stamps: at thousands of steps per second this process may miss some.
    answered = {n: r['commands']['commands_per_robot'] / (r['commands']['sim_s'] * RATE_HZ)
                for n, r in free.items()}
    free_cores = {n: r['idle']['cpu_s'] / r['idle']['sim_s'] for n, r in free.items()}
    free_busy_cores = {n: r['commands']['cpu_s'] / r['commands']['sim_s']
                       for n, r in free.items()}
    drive = 'odom_out_and_back (' + ', '.join(
        f'{k} {v:g}' for k, v in sizes.scaling_motion.items()) + ')'
    window_s = sizes.fleet_window_s

    def by_n(values, fmt):
        return ', '.join(f'N={n}: {fmt(v)}' for n, v in values.items())

    def cores(value):
        return f'{value:.3f}'
    return {
        'fleet_cpu': row(
            'one unicycle_sim, N robots at 50 Hz in real time: CPU per simulated second',
            f'idle {by_n(idle, cores)}; every robot commanded at 50 Hz {by_n(busy, cores)} '
            'cores',
            'a simulator process per robot (N x the idle N=1 figure): '
            + by_n({n: n * idle[low] for n in counts}, cores) + ' cores',
            '-', '-',
            'unicycle_sim with robots r0..r(N-1) on wall time, rate_hz 50. CPU of its process '
            f'(every thread, /proc/<pid>/task/*/schedstat) per step over {window_s:g} s, times '
            '50: the fraction of one core it needs in real time. Idle: no command; odometry of '
            'every robot and one /tf message each step (this process listens to the odometry '
            'of r0 and of the last robot only). Commanded: a load process sends every robot a '
            'Twist at 50 Hz on its own timer (alternating values, so each is integrated '
            'piecewise); steps per wall second then: '
            + by_n(steps_s, lambda v: f'{v:.1f}') + ' (50: kept up). The simulators of every N '
            'start at once (namespaces of their own) and are measured largest first, each '
            'stopped once measured: the smaller ones idle meanwhile.',
            idle_cores=idle, commands_cores=busy, commanded_steps_per_s=steps_s,
            windows={str(n): r for n, r in real_time.items()}),
        'fleet_real_time': row(
            f'{target_n} robots at 50 Hz in real time, each commanded at 50 Hz: CPU',
            f'{busy[target_n]:.2f} of a core ({steps_s[target_n]:.1f} steps/s)',
            f'idle: {idle[target_n]:.2f}', f'<= {TARGET_FLEET_CORES:g} core',
            met(busy[target_n] <= TARGET_FLEET_CORES and steps_s[target_n] >= 0.95 * RATE_HZ),
            f'The commanded figure of the row above at N={target_n}; met when it is within one '
            'core and the simulator kept its 50 steps per second.', robots=target_n,
            cores=busy[target_n], steps_per_s=steps_s[target_n]),
        'fleet_rtf': row(
            'one unicycle_sim, N robots: achievable real-time factor',
            f'idle {by_n(rtf_idle, fmt_x)}; every robot commanded each step '
            f'{by_n(rtf_busy, fmt_x)}',
            'CPU-bound: 1 / (its idle CPU per simulated s) '
            + by_n({n: 1.0 / v for n, v in free_cores.items()}, fmt_x), '-', '-',
            'unicycle_sim with robots r0..r(N-1), rate_hz 50, publish_clock (started held at '
            f'real_time_factor {PAUSED_RTF:g}, one at a time, then set through its parameter '
            f'service) at real_time_factor {FREE_CLOCK_RTF:g} (no limit in practice), lockstep '
            'as by default; simulated s (odometry stamps of r0) per wall s over '
            f'{window_s:g} s. Idle: no participant, so it steps as fast as it can. Commanded: '
            'the load process takes part in the lockstep (as a motion does) and sends every '
            'robot a Twist at every step, which the simulator applies before the next step '
            '(so this is the factor of simulator, handshake and commander together); commands '
            'per robot per step: ' + by_n(answered, lambda v: f'{v:.2f}') + '. Simulator CPU '
            'per simulated s, idle: ' + by_n(free_cores, cores) + '; commanded: '
            + by_n(free_busy_cores, cores) + '.',
            idle_rtf=rtf_idle, commands_rtf=rtf_busy, commands_per_robot_step=answered,
            idle_cpu_per_sim_s=free_cores, commands_cpu_per_sim_s=free_busy_cores,
            windows={str(n): r for n, r in free.items()}),
        'fleet_per_robot': row(
            'simulator cost per robot vs rclpy cost per Odometry message',
            f'{_us(per_robot["idle"])} per robot per step idle, '
            f'{_us(per_robot["commands"])} commanded',
            f'rclpy publish of one Odometry: {_us(per_message["no_subscriber_s"])} (no '
            f'subscriber), {_us(per_message["one_subscriber_s"])} (one, in another process)',
            f'<= {TARGET_PER_ROBOT_RATIO:g}x per message',
            met(ratio <= TARGET_PER_ROBOT_RATIO),
            f'Per robot: (CPU per step at N={high} - at N={low}) / {high - low}, in real time '
            '(the first of these rows). Per message: this process publishes the '
            f"simulator's Odometry (frames, covariances) {per_message['published']} times, "
            "CPU of this process per publish; first with no subscriber (as the simulator's "
            f"robots' odometry but r0's; before any other process starts), then with the load "
            f"process subscribed ({per_message['heard']} heard; keep last 10). Idle ratio "
            f'{ratio:.2f}x (to one subscriber: {ratio_reader:.2f}x); target on no subscriber.',
            per_robot_s=per_robot, per_message_s=per_message, ratio=ratio,
            ratio_one_subscriber=ratio_reader),
        'fleet_motions': row(
            f'{many["robots"]} robots with motions: one simulator vs pairs',
            _motions_text(one, 'one unicycle_sim + one motion_fleet (2 processes)'),
            _motions_text(many, f'{many["robots"]} unicycle_sim + motion pairs '
                                f'({2 * many["robots"]} processes)'), '-', '-',
            f'Each robot runs {drive}. One simulator: unicycle_sim with robots robot0.., '
            f'owning /clock (real_time_factor {rtf:g}, lockstep) once motion_fleet (one '
            'odom_out_and_back per robot namespace, on sim time) is up. Pairs: as in row '
            '"N robots as 2N processes"' + (' (measured there, in this run)' if reused else '')
            + ". Wall: from the clock owner's start to the last motion's exit; factor: the "
            "slowest motion's sim s / wall s; error: the largest closure error from the start "
            "pose (the analytic answer), from the motions' closing lines.",
            one_simulator=one, pairs=many, pairs_from_row_12=reused),
    }
