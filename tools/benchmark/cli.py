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

"""The command line: options, the run's domain, the groups of measurements, the report."""

import argparse
import os
import shutil
import signal
import sys
import time

from benchmark.config import DEFAULT_JSON
from benchmark.config import GROUPS
from benchmark.config import ROW_KEYS
from benchmark.config import Sizes
from benchmark.fleet import rows_fleet
from benchmark.processes import Children
from benchmark.processes import row_rtf_processes
from benchmark.processes import rows_sim_process
from benchmark.scaling import rows_scaling
from benchmark.scenarios import row_integration
from benchmark.scenarios import row_rtf_in_process
from benchmark.scenarios import rows_circle
from benchmark.scenarios import rows_out_and_back
from benchmark.scenarios import rows_rotate
from benchmark.scenarios import rtf_in_process
from benchmark.scenarios import run_motion
from benchmark.scenarios import scenario_factories
from benchmark.table import machine
from benchmark.table import print_table
from benchmark.table import write_json
import rclpy
from rclpy.experimental import EventsExecutor
from rclpy.logging import LoggingSeverity
from sim_diffdrive.harness import DOMAIN_VARIABLE
from sim_diffdrive.harness import isolated_domain_id

EXECUTABLES = ('unicycle_sim', 'rotate_robot', 'circle_back_and_forth', 'timed_out_and_back',
               'odom_out_and_back', 'motion_fleet')


def measure(selected, sizes, children, domain_id, rtf, progress):
    """Run the selected groups of measurements; return the rows in table order."""
    rows = {}
    runs = None
    if 'rotate' in selected:
        progress(f'rotate: project (timed, odom) and original from {sizes.starts} start times')
        rows.update(rows_rotate(sizes, domain_id))
    if 'rtf' in selected:
        progress('real-time factor in one process: 2 executors x 3 motions x 2 runs')
        runs = rtf_in_process(sizes, domain_id)
        rows['rtf_in_process'] = row_rtf_in_process(runs)
    if 'out_and_back' in selected:
        progress('out-and-back: project and rbx1')
        project = (runs['events']['out_and_back'][0] if runs else run_motion(
            EventsExecutor, scenario_factories(sizes)['out_and_back'], domain_id))
        rows['out_and_back_closure'] = rows_out_and_back(sizes, project, domain_id)
    if 'circle' in selected:
        progress('circle back-and-forth: project and move_rob.py')
        rows['circle_closure'] = rows_circle(sizes, domain_id)
    if 'integration' in selected:
        progress('Euler against the exact arc')
        rows['integration_error'] = row_integration(sizes)
    if 'processes' in selected:
        progress('real-time factor across processes')
        rows['rtf_processes'] = row_rtf_processes(sizes, children, domain_id, rtf)
    if 'sim' in selected:
        progress('simulator CPU and latency on wall time')
        rows.update(rows_sim_process(sizes, children, domain_id))
    if 'scaling' in selected:
        progress(f'N robots: {sizes.robots} in one process, {sizes.robots_processes} as '
                 'processes')
        rows.update(rows_scaling(sizes, children, domain_id, rtf))
    if 'fleet' in selected:
        progress(f'many robots in one simulator: {sizes.fleet_robots}; '
                 f'{sizes.fleet_motion_robots} robots with motions')
        pairs = rows.get('scaling_processes', {}).get('data', {}).get('runs')
        rows.update(rows_fleet(sizes, children, domain_id, rtf, pairs))
    return {key: rows[key] for key in ROW_KEYS if key in rows}


def parse_args(argv):
    parser = argparse.ArgumentParser(
        description='Benchmark this package against the programs it replaces; print a table.')
    parser.add_argument('--quick', action='store_true',
                        help='small sizes and short runs (for tests)')
    parser.add_argument('--json', default=DEFAULT_JSON,
                        help='where to write the results as JSON (default: %(default)s)')
    parser.add_argument('--domain-id', type=int, default=None,
                        help='ROS domain to use (default: random in 1..100)')
    parser.add_argument('--only', default=None,
                        help='comma-separated groups to run, of: ' + ', '.join(GROUPS))
    parser.add_argument('--rtf', type=float, default=100.0,
                        help='real_time_factor (an upper bound) of the simulator across '
                             'processes (default: %(default)g)')
    return parser.parse_args(argv)


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def main(argv=None):
    options = parse_args(argv)
    missing = [e for e in EXECUTABLES if shutil.which(e) is None]
    if missing:
        print(f'Not on PATH: {", ".join(missing)}; run `. .venv/bin/activate` first (or '
              '`make bench`).', file=sys.stderr)
        return 2
    selected = set(options.only.split(',')) if options.only else set(GROUPS)
    if selected - set(GROUPS):
        print(f'Unknown group(s) for --only: {", ".join(sorted(selected - set(GROUPS)))}',
              file=sys.stderr)
        return 2
    if options.domain_id:
        os.environ[DOMAIN_VARIABLE] = str(options.domain_id)
    # Children inherit it: a domain of our own, discovery on this machine only.
    domain_id = isolated_domain_id()
    signal.signal(signal.SIGTERM, _interrupt)
    # The nodes in this process log their progress at INFO: keep it out of the table's way.
    rclpy.logging.set_logger_level('', LoggingSeverity.WARN)
    sizes = Sizes(options.quick)
    info = machine()
    print(f'{info["nproc"]} x {info["cpu"]}, load {info["loadavg"][0]:.2f}; '
          f'ROS_DOMAIN_ID={domain_id}, localhost only{", --quick" if sizes.quick else ""}',
          flush=True)

    wall_start = time.monotonic()

    def progress(text):
        print(f'[{time.monotonic() - wall_start:6.1f} s] {text}', flush=True)

    children = Children()
    try:
        rows = measure(selected, sizes, children, domain_id, options.rtf, progress)
    except KeyboardInterrupt:
        print('Interrupted', file=sys.stderr)
        return 130
    finally:
        children.stop_all()
    total = time.monotonic() - wall_start

    print()
    print(f'Machine: {info["nproc"]} cores, {info["cpu"]}; Python {info["python"]}; '
          f'load average at start {info["loadavg"][0]:.2f}; total {total:.0f} s wall')
    print()
    print_table(rows)
    report = {'machine': info, 'quick': sizes.quick, 'domain_id': domain_id,
              'wall_s': total, 'rows': rows}
    print(f'\nJSON: {write_json(options.json, report)}')
    return 0
