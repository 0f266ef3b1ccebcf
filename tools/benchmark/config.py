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
What the benchmark measures: row order, groups, targets, and the sizes of a full or --quick run.

The targets are goals of the project, reported as met or missed in the table, never asserted.
"""

from motion_challenges.prompts import RotationRequest

NS = 1_000_000_000
DEFAULT_JSON = 'out/bench.json'

TARGET_YAW_DEG = 0.01
TARGET_CLOSURE_MM = 1.0
TARGET_RTF_IN_PROCESS = 25.0
TARGET_RTF_PROCESSES = 10.0
TARGET_LATENCY_P99_MS = 20.0 + 2.0  # one odometry period at 50 Hz, plus 2 ms
TARGET_IDLE_CPU_PERCENT = 2.0
# 64 robots at 50 Hz in real time within one core; a robot costs at most 2 Odometry publishes.
TARGET_FLEET_CORES = 1.0
TARGET_PER_ROBOT_RATIO = 2.0

ROTATION = RotationRequest(60.0, 90.0, True)  # deg/s, deg, clockwise

# Wall seconds (plus four per robot) the scaling rows wait for the motion processes.
SCALING_TIMEOUT_S = 20.0

# The rows of the table, in order (the keys of the JSON's "rows").
ROW_KEYS = (
    'rotate_timed', 'rotate_odom', 'out_and_back_closure', 'circle_closure',
    'integration_error', 'rtf_in_process', 'rtf_processes', 'latency', 'cpu_idle',
    'cpu_commands', 'scaling_one_process', 'scaling_processes', 'fleet_cpu', 'fleet_real_time',
    'fleet_rtf', 'fleet_per_robot', 'fleet_motions',
)

# The groups --only selects from, in the order they run.
GROUPS = ('rotate', 'rtf', 'out_and_back', 'circle', 'integration', 'processes', 'sim',
          'scaling', 'fleet')


class Sizes:
    """How big each measurement is: full for ``make bench``, small for --quick (tests)."""

    def __init__(self, quick):
        self.quick = quick
        self.starts = 2 if quick else 20
        self.circle_cycles = 2 if quick else 10
        self.circle_half_period = 3.0 if quick else 15.0
        self.laps = 100
        self.latency_samples = 5 if quick else 200
        # Wall seconds for the simulator to settle after its start, then of each CPU sample.
        self.cpu_settle_s = 0.2 if quick else 0.5
        self.cpu_seconds = 0.2 if quick else 5.0
        self.robots = (1, 2) if quick else (1, 4, 16)
        self.robots_processes = (1,) if quick else self.robots
        # What each robot drives in the scaling rows: odom_out_and_back, shortened.
        self.scaling_motion = (
            {'goal_distance': 0.1, 'angular_speed': 4.0, 'pause': 0.1, 'legs': 1} if quick
            else {'goal_distance': 0.2, 'angular_speed': 2.0, 'pause': 0.2})
        self.scaling_window_s = 0.5 if quick else 2.0
        # The three default scenarios for the real-time factor (shortened with --quick).
        self.circle_rtf = {'cycles': 1, 'half_period': 0.5 if quick else 15.0}
        self.out_and_back_rtf = (
            {'goal_distance': 0.05, 'angular_speed': 4.0, 'pause': 0.0} if quick else {})
        self.process_scenarios = ('rotate',) if quick else ('rotate', 'circle', 'out_and_back')
        # Runs of each motion across processes; two show whether runs are identical.
        self.process_runs = 1 if quick else 2
        # Many robots in one simulator: robot counts (in real time; with a free clock),
        # wall seconds to settle and to measure each, Odometry publishes for rclpy's cost per
        # message, robots running a motion.
        self.fleet_robots = (1, 4) if quick else (1, 16, 64, 256)
        self.fleet_free_robots = self.fleet_robots[-1:] if quick else self.fleet_robots
        self.fleet_settle_s = 0.05 if quick else 0.5
        self.fleet_window_s = 0.1 if quick else 3.0
        self.fleet_messages = 500 if quick else 10000
        # As many as row 12's largest run of pairs, which the fleet row then reuses.
        self.fleet_motion_robots = self.robots_processes[-1]
