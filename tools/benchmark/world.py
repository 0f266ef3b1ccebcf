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

"""The world's rows: the laser scan's cast against nav2_loopback_sim's per-ray loop (scan.py)."""

from benchmark.core import Row
from benchmark.core import row
from benchmark.scan import BEAMS
from benchmark.scan import measure
from benchmark.scan import RATE_HZ
from benchmark.scan import ROBOTS

# 64 robots x 360 beams at 10 Hz in real time beside their 50 Hz odometry, within one core.
TARGET_SCAN_CORE_PERCENT = 50.0


@row('world')
def scan_cast(run):
    figures, timed_on = measure(run.sizes.scan_repeats, run.sizes.scan_loop_robots), ''
    if run.sizes.scan_loop_robots != ROBOTS:  # --quick
        timed_on = f', timed on {run.sizes.scan_loop_robots} of the robots and scaled'
    beams = ROBOTS * BEAMS
    share = figures['fleet_scan_s'] * RATE_HZ * 100.0
    loop_share = figures['fleet_loop_s'] * RATE_HZ * 100.0
    return Row(
        f'laser scan, {ROBOTS} robots x {BEAMS} beams at {RATE_HZ:g} Hz: per beam, share of a '
        'core', f"{figures['fleet_cast_s'] / beams * 1e6:.2f} us a beam; {share:.0f} % of a "
        'core', f"per-ray loop: {figures['fleet_loop_s'] / beams * 1e6:.2f} us a beam; "
        f'{loop_share:.0f} % of a core',
        'sim_diffdrive.world.scan: every beam of every robot at once (numpy), exact to the cell '
        "boundaries, with the other robots' discs and noise. Reference: nav2_loopback_sim's "
        'method, a Python loop per ray over the grid (off by up to '
        f"{figures['loop_error_max_m']:.3f} m{timed_on}). Leaves the rest of a core for the "
        'odometry.',
        f'<= {TARGET_SCAN_CORE_PERCENT:g} %', share <= TARGET_SCAN_CORE_PERCENT, figures)
