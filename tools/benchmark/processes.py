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
Rows measured on separate processes: the executables as a user starts them, over DDS.

Row 7, the real-time factor of the motion executables against a ``unicycle_sim`` process that
owns the clock; rows 8-10, cmd_vel -> odom latency and the simulator's CPU on wall time.  The
processes start with the harness's helpers (sim_diffdrive.harness) and are all stopped,
however the run ends, by ``Children.stop_all()``.  This process watches them through a
BenchGraph with discovery on (the run's domain, this machine only).
"""

import math
import os
import random
import signal
import subprocess
import sys
import time

from benchmark.config import TARGET_IDLE_CPU_PERCENT
from benchmark.config import TARGET_LATENCY_P99_MS
from benchmark.config import TARGET_RTF_PROCESSES
from benchmark.graph import BenchGraph
from benchmark.originals import closure
from benchmark.table import fmt_rtfs
from benchmark.table import met
from benchmark.table import row
import numpy as np
from rclpy.clock import Clock
from rclpy.clock import ClockType
from sim_diffdrive.harness import is_moving
from sim_diffdrive.harness import pose_of
from sim_diffdrive.harness import Probe
from sim_diffdrive.harness import Process
from sim_diffdrive.harness import ros_params
from sim_diffdrive.harness import stamp_s
from sim_diffdrive.harness import start
from sim_diffdrive.harness import stop
from sim_diffdrive.harness import twist_of

# Executable, parameters, simulated seconds of the motion, and its turn [deg].
PROCESS_SCENARIOS = {
    'rotate': ('rotate_robot', {'angular_speed_deg': 60.0, 'angle_deg': 90.0, 'clockwise': True,
                                'mode': 'timed'}, 1.5, -90.0),
    'circle': ('circle_back_and_forth', {'cycles': 1}, 30.0, 0.0),
    'out_and_back': ('timed_out_and_back', {}, 20.3, 0.0),
}


class Children:
    """Processes started by the benchmark (harness.start), all stopped by stop_all()."""

    def __init__(self):
        self.running = []
        self._outputs = {}

    def start(self, executable, namespace=None, **params):
        """Start an executable with ROS parameters (bools as true/false) in a namespace."""
        process = start(executable, *ros_params(
            *(f'{name}:={str(value).lower() if isinstance(value, bool) else value}'
              for name, value in params.items()), namespace=namespace))
        self.running.append(process)
        return process

    def start_python(self, code, stdin=subprocess.DEVNULL):
        """Start this Python interpreter on a piece of code (a load, a listener, ...)."""
        process = Process([sys.executable, '-c', code], stdin=stdin)
        self.running.append(process)
        return process

    def interrupt(self, process):
        """Send a child Ctrl-C without waiting for it to exit (stop() or stop_all() later)."""
        if process in self.running and process.poll() is None:
            process.send(signal.SIGINT)

    def stop(self, process):
        """Stop a child as Ctrl-C does (a motion then stops its robot); return its output."""
        if process in self.running:
            self.running.remove(process)
            self._outputs[process] = stop(process, timeout=3.0)
        return self._outputs.get(process, '')

    def stop_all(self):
        for process in list(self.running):
            self.stop(process)


def tail(output, lines=12):
    """Return the last lines of a child's output, indented, for an error message."""
    return '\n'.join('    ' + line for line in output.splitlines()[-lines:])


class Observer(Probe):
    """
    A harness Probe that also follows the robot's movement on odometry.

    ``first`` is the first pose heard since restart(); ``move_start`` and ``move_end`` are the
    (sim, wall) times of the last odometry at rest before the robot moved and of the first at
    rest after it, wall times being the harness's monotonic arrival times.
    """

    def __init__(self, context, commands=False):
        # Commands only where this process drives the robot: the simulator warns of a second
        # publisher.
        super().__init__('bench_observer', listen_only=not commands, context=context,
                         enable_rosout=False)
        self.restart()

    def restart(self):
        """Forget the start pose and the movement seen so far."""
        self.first = None
        self.moving = False
        self.move_start = None
        self.move_end = None
        self._at_rest = None

    @property
    def latest(self):
        """Return the latest pose heard, or None."""
        return pose_of(self.odom) if self.odom else None

    @property
    def received_at(self):
        """Return the monotonic wall time at which the latest odometry arrived, or None."""
        return self.odom_walls[-1] if self.odom_walls else None

    def _on_odom(self, msg):
        super()._on_odom(msg)
        sample = (stamp_s(msg), self.odom_walls[-1])
        self.first = self.first or pose_of(msg)
        self.moving = is_moving(msg)
        if self.moving:
            if self.move_start is None:
                self.move_start = self._at_rest or sample
            self.move_end = None
        else:
            self._at_rest = sample
            if self.move_start is not None and self.move_end is None:
                self.move_end = sample


# -- row 7: real-time factor across processes ----------------------------------------------------


def run_process_scenarios(children, domain_id, scenarios, rtf, runs):
    """
    Run each motion executable `runs` times, each time against a fresh unicycle_sim.

    Returns {scenario: [result of each run]}, measured on odometry by an observer in this
    process.
    """
    results = {}
    with BenchGraph(domain_id=domain_id, offline=False) as session:
        observer = session.add(Observer(session.context))
        for scenario in scenarios:
            results[scenario] = [run_process_motion(children, session, observer, scenario, rtf)
                                 for _ in range(runs)]
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
    session.spin_until(lambda: time.monotonic() - (observer.received_at or 0.0) > 0.3, 10.0)
    observer.restart()
    motion = sim = None
    failure = None
    try:
        sim = children.start('unicycle_sim', publish_clock=True, real_time_factor=rtf)
        if not session.spin_until(lambda: observer.first is not None, 15.0):
            raise RuntimeError(f'no odometry from unicycle_sim:\n{tail(children.stop(sim))}')
        motion = children.start(executable, use_sim_time=True, **params)
        # Process start and discovery, then at least 2x real time.
        timeout = 10.0 + sim_seconds / 2.0
        if not session.spin_until(lambda: motion.poll() is not None, timeout):
            failure = f'{scenario}: not done after {timeout:.0f} s wall'
        elif motion.returncode != 0:
            failure = f'{scenario}: exit code {motion.returncode}'
        seen = len(observer.odoms)
        session.spin_until(lambda: len(observer.odoms) > seen + 2 and not observer.moving, 2.0)
    finally:
        for process in (motion, sim):
            if process is not None:
                children.stop(process)
    start_pose, end = observer.first, observer.latest
    mm, deg = closure((start_pose[0], start_pose[1], start_pose[2] + math.radians(turn_deg)),
                      end)
    result = {'end': end, 'error_mm': mm, 'error_deg': deg, 'failure': failure}
    if failure:
        result['log_tail'] = tail(children.stop(motion))
    if observer.move_start and observer.move_end:
        result['sim_s'] = observer.move_end[0] - observer.move_start[0]
        result['wall_s'] = observer.move_end[1] - observer.move_start[1]
    return result


def row_rtf_processes(sizes, children, domain_id, rtf):
    rtfs = {}
    errors = {}
    results = run_process_scenarios(children, domain_id, sizes.process_scenarios, rtf,
                                    sizes.process_runs)
    failures = [r['failure'] for runs in results.values() for r in runs if r['failure']]
    # Whether the runs of each motion ended at the same pose (None: one run each).
    identical = not failures if sizes.process_runs > 1 else None
    for scenario, runs in results.items():
        timed = [r for r in runs if not r['failure'] and 'sim_s' in r]
        wall_s = sum(r['wall_s'] for r in timed)
        rtfs[scenario] = sum(r['sim_s'] for r in timed) / wall_s if wall_s > 0 else math.nan
        if identical:
            identical = all(r['end'] == runs[0]['end'] for r in runs)
        errors[scenario] = [(r['error_mm'], r['error_deg']) for r in runs]
    worst_mm = max(mm for runs in errors.values() for mm, _ in runs)
    worst_deg = max(deg for runs in errors.values() for _, deg in runs)
    runs_count = sum(len(runs) for runs in results.values())
    failed = f'; {len(failures)} of {runs_count} runs failed' if failures else ''
    same = {True: 'yes', False: 'no', None: '- (one run)'}[identical]
    each = {1: 'one run', 2: 'two runs'}.get(sizes.process_runs, f'{sizes.process_runs} runs')
    return row(
        'real-time factor across processes (sim s / wall s), from odometry',
        f'{fmt_rtfs(rtfs)}; identical: {same}{failed}',
        f'clock set to {rtf:g}x', f'>= {TARGET_RTF_PROCESSES:g}x',
        met(not failures and min(rtfs.values()) >= TARGET_RTF_PROCESSES),
        f'unicycle_sim (publish_clock, real_time_factor {rtf:g}, 50 Hz) and the motion '
        'executables as separate processes over DDS, observed from this process; sim and wall '
        f'seconds from the first to the last movement on odometry; {each} per motion, each '
        'against a fresh simulator. The simulator steps in lockstep with the motion (it waits '
        "for the motion's answer to each clock step and for the commands it covers), so "
        'real_time_factor is only an upper bound and the factor is what the handshake '
        'sustains: about one round trip between two Python executors per 20 ms step. Worst '
        f'error over the runs {worst_mm:.3g} mm, {worst_deg:.3g} deg from the goal.'
        + (f' Failed: {"; ".join(failures)}.' if failures else ''),
        rtf=rtfs, identical=identical, errors_mm_deg=errors, failures=failures,
        failure_logs=[r['log_tail'] for runs in results.values() for r in runs
                      if r['failure']])


# -- rows 8-10: latency and CPU of one simulator process on wall time ----------------------------


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
    with BenchGraph(domain_id=domain_id, offline=False) as session:
        observer = session.add(Observer(session.context, commands=True))
        sim = children.start('unicycle_sim', rate_hz=50.0)
        try:
            if not session.spin_until(
                    lambda: observer.first is not None
                    and observer.cmd_pub.get_subscription_count() > 0, 15.0):
                raise RuntimeError(f'no odometry from unicycle_sim:\n{tail(children.stop(sim))}')
            session.spin_for(sizes.cpu_settle_s)
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
        sent = time.monotonic()
        observer.send(0.0, angular)
        if session.spin_until(lambda: twist_of(observer.odom) == (0.0, angular)
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
