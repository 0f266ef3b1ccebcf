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

"""The table's Row, the registry of rows, the Run (sizes, processes, measurements), formats."""

from dataclasses import asdict
from dataclasses import dataclass
import math
import subprocess
from types import SimpleNamespace

from sim_diffdrive import harness

NS = 1_000_000_000
# Targets: goals of the project, reported as met or missed, never asserted.
TARGET_YAW_DEG, TARGET_CLOSURE_MM = 0.01, 1.0
TARGET_RTF_IN_PROCESS, TARGET_RTF_PROCESSES = 25.0, 10.0
TARGET_LATENCY_P99_MS = 20.0 + 2.0  # one odometry period at 50 Hz, plus 2 ms
# Issue "Python at the speed of rclpy": an idle simulator under 1 % of a core, the largest
# fleet (256 robots), each commanded at 50 Hz, in real time within one core, a robot's step
# within 5 us idle and 20 us commanded, 16 motions on one simulator at 5x real time.
TARGET_IDLE_CPU_PERCENT = 1.0
TARGET_FLEET_CORES = 1.0
TARGET_PER_ROBOT_US = (5.0, 20.0)  # idle, commanded
TARGET_FLEET_MOTIONS_RTF = 5.0
TARGET_SUITE_S = 60.0  # make test, 2 cores, a warm venv
SIZES = {  # each: (make bench, --quick)
    'starts': (20, 1), 'laps': (100, 10), 'latency_samples': (200, 5),
    'circle_cycles': (10, 1), 'circle_half_period': (15.0, 1.0),
    'cpu_settle_s': (0.5, 0.2), 'cpu_seconds': (5.0, 0.2),  # wall s to settle, per sample
    # The three default motions of the real-time factor rows, shortened with --quick.
    'circle_rtf': ({'cycles': 1, 'half_period': 15.0}, {'cycles': 1, 'half_period': 0.2}),
    'out_and_back_rtf': ({}, {'goal_distance': 0.05, 'angular_speed': 8.0, 'pause': 0.0}),
    'process_motions': (('rotate', 'circle', 'out_and_back'), ('rotate',)), 'process_runs': (2, 1),
    'robots': ((1, 4, 16), (1, 2)), 'robots_processes': ((1, 4, 16), (1,)),
    # What each robot of rows 11, 12 and 17 drives: odom_out_and_back, shortened.
    'scaling_motion': ({'goal_distance': 0.2, 'angular_speed': 2.0, 'pause': 0.2},
                       {'goal_distance': 0.1, 'angular_speed': 4.0, 'pause': 0.1, 'legs': 1}),
    'scaling_window_s': (2.0, 0.5), 'fleet_settle_s': (0.5, 0.0), 'fleet_window_s': (3.0, 0.05),
    'fleet_robots': ((1, 16, 64, 256), (1, 4)), 'fleet_free_robots': ((1, 16, 64, 256), (4,)),
    'fleet_messages': (10000, 500),  # Odometry publishes for rclpy's cost per message
    'fleet_motion_robots': (16, 1),  # robots_processes[-1]: row 17 reuses row 12's pairs
    'fleet_idle_robots': (1024, 4),  # row 18: the largest idle fleet (quick: row 13's)
    'scan_repeats': (5, 1),  # row 20: casts timed, best of
    'scan_loop_robots': (64, 8),  # row 20: robots the per-ray loop is timed on (of 64)
    'call_steps': (200, 20),  # row 6: steps whose calls are counted
    'ping_pongs': ((2000, 200), (100, 20)),  # row 7's reference: round trips, warm-ups
}
ROWS = {}  # key -> (group, function(run) -> Row), in table order


def row(group):
    """Register a function as the table's next row; its name is the row's key."""
    def register(measure):
        ROWS[measure.__name__] = (group, measure)
        return measure
    return register


@dataclass
class Row:
    """The table's cells of a row (met: None without a target), its note, its raw numbers."""

    measure: str
    project: str
    reference: str
    note: str
    target: str = '-'
    met: bool = None
    data: dict = None

    def report(self):
        met = None if self.met is None else bool(self.met)
        result = {None: '-', True: 'met', False: 'missed'}[met]
        return {**asdict(self), 'met': met, 'result': result}


class Run:
    """One run: its sizes, the processes it started, what its rows have measured."""

    def __init__(self, quick=False, rtf=100.0):
        self.sizes = SimpleNamespace(quick=quick, **{k: v[quick] for k, v in SIZES.items()})
        self.rtf, self.running, self.measurements = rtf, [], {}

    def once(self, measure, *args, **kwargs):
        """Return measure(run, *args, **kwargs), measured at its first use in this run."""
        key = (measure.__name__, args, tuple(kwargs.items()))
        if key not in self.measurements:
            self.measurements[key] = measure(self, *args, **kwargs)
        return self.measurements[key]

    def start(self, executable, *args, namespace=None, stdin=subprocess.DEVNULL, **params):
        """Start an executable (harness.start) with ROS parameters, bools as true/false."""
        params = [f'{k}:={str(v).lower() if isinstance(v, bool) else v}' for k, v in
                  params.items()]
        self.running.append(harness.start(
            executable, *args, *harness.ros_params(*params, namespace=namespace), stdin=stdin))
        return self.running[-1]

    def stop(self, process):
        """Stop a process as Ctrl-C does (a motion then stops its robot); return its output."""
        if process in self.running:
            self.running.remove(process)
            harness.stop(process, timeout=3.0)
        return process.output()

    def stop_all(self, processes=None):
        """Stop several processes (all by default) at once, as stop() does; their outputs."""
        processes = list(self.running if processes is None else processes)
        self.running = [process for process in self.running if process not in processes]
        return harness.stop_all(processes, timeout=3.0)


def tail(output, lines=12):
    return '\n'.join('    ' + line for line in output.splitlines()[-lines:])


def fmt_small(value, decimals=4):
    """Format with fixed decimals, or in scientific notation when that would show zeros."""
    small = value != 0.0 and abs(value) < 10.0 ** -(decimals - 1)
    return f'{value:.1e}' if small else f'{value:.{decimals}f}'


def fmt_closure(mm, deg):
    return f'{fmt_small(mm, 3)} mm, {fmt_small(deg)} deg'


def fmt_x(factor):
    return f'{factor:.1f}x' if math.isfinite(factor) else '-'


def by_n(values, fmt=fmt_x):  # 'N=1: 2.0x, N=4: ...'
    return ', '.join(f'N={n}: {fmt(value)}' for n, value in values.items())
