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
Benchmark this package against the programs it replaces and print one table (``make bench``).

Each row puts this project's figure next to a reference measured in the same run and, where
the project has a target, whether it was met; the raw numbers go to the JSON.  On a ROS domain
of its own (one no other run on this machine holds, unless --domain-id), discovery on this
machine only.
"""

import argparse
import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import textwrap
import time

from benchmark import fleet  # noqa: F401  (each module registers its rows, in table order)
from benchmark import one_process  # noqa: F401
from benchmark import processes  # noqa: F401
from benchmark import suite  # noqa: F401
from benchmark import world  # noqa: F401
from benchmark.core import ROWS
from benchmark.core import Run
import rclpy
from rclpy.logging import LoggingSeverity
from sim_diffdrive.harness import DOMAIN_VARIABLE
from sim_diffdrive.harness import isolated_domain_id

WRAP_AT = {'#': 2, 'measure': 34, 'this project': 38, 'reference': 38, 'target': 12, 'result': 6}


def print_table(rows):
    """Print the rows as a table with wrapped cells, then their numbered notes."""
    table = [list(WRAP_AT)] + [[str(i), r['measure'], r['project'], r['reference'], r['target'],
                                r['result']] for i, r in enumerate(rows.values(), 1)]
    widths = [min(max(len(cells[i]) for cells in table), w) for i, w in
              enumerate(WRAP_AT.values())]
    for cells in table:
        wrapped = [textwrap.wrap(cell, width, break_long_words=False, break_on_hyphens=False)
                   or [''] for cell, width in zip(cells, widths)]
        for i in range(max(map(len, wrapped))):
            print(' | '.join((w[i] if i < len(w) else '').ljust(width)
                             for w, width in zip(wrapped, widths)).rstrip())
        print('-+-'.join('-' * w for w in widths))
    print('\nNotes:\n' + '\n'.join(f'{i}. {r["note"]}' for i, r in enumerate(rows.values(), 1)))


def commit():
    """Return the checked-out commit, '+' if tracked files changed since; '?' outside git."""
    def git(*args):
        return subprocess.run(('git', *args), cwd=Path(__file__).parent, capture_output=True,
                              text=True, check=True).stdout.strip()
    try:
        head = git('rev-parse', '--short', 'HEAD')
        return head + ('+' if git('status', '--porcelain', '--untracked-files=no') else '')
    except (OSError, subprocess.CalledProcessError):
        return '?'


def main(argv=None):
    groups = list(dict.fromkeys(group for group, _ in ROWS.values()))
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='small sizes and short runs')
    parser.add_argument('--json', default='out/bench.json', help='default: %(default)s')
    parser.add_argument('--domain-id', type=int,
                        help='ROS domain (default: one that no other run holds)')
    parser.add_argument('--only', help='comma-separated groups to run, of: ' + ', '.join(groups))
    parser.add_argument('--rtf', type=float, default=100.0, help='real_time_factor (a bound) of '
                        'the simulator across processes (default: %(default)g)')
    options = parser.parse_args(argv)
    selected = options.only.split(',') if options.only else groups
    if set(selected) - set(groups):
        parser.error(f'unknown group(s) for --only: {", ".join(set(selected) - set(groups))}')
    if options.domain_id:
        os.environ[DOMAIN_VARIABLE] = str(options.domain_id)
    domain_id = isolated_domain_id()  # the processes started inherit it
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # stop them on SIGTERM too
    rclpy.logging.set_logger_level('', LoggingSeverity.WARN)  # the nodes here log at INFO
    with open('/proc/cpuinfo') as cpuinfo:
        cpu = next((line.split(':')[1].strip() for line in cpuinfo if 'model name' in line), '?')
    info = {'nproc': os.cpu_count(), 'cpu': cpu, 'loadavg': list(os.getloadavg()),
            'python': sys.version.split()[0], 'commit': commit()}
    print(f'{info["nproc"]} x {cpu}, load {info["loadavg"][0]:.2f}, commit {info["commit"]}; '
          f'ROS_DOMAIN_ID={domain_id}, localhost only{", --quick" if options.quick else ""}',
          flush=True)
    run, rows, start = Run(options.quick, options.rtf), {}, time.monotonic()
    try:
        for key, (group, measure) in ROWS.items():
            if group in selected:
                print(f'[{time.monotonic() - start:6.1f} s] {key}', flush=True)
                rows[key] = measure(run).report()
    except (KeyboardInterrupt, FileNotFoundError) as error:  # not on PATH: make venv
        print(error or 'Interrupted', file=sys.stderr)
        return 130 if isinstance(error, KeyboardInterrupt) else 2
    finally:
        run.stop_all()
    wall_s = time.monotonic() - start
    print(f'\nMachine: {info["nproc"]} cores, {cpu}; Python {info["python"]}; load average at '
          f'start {info["loadavg"][0]:.2f}; commit {info["commit"]}; total {wall_s:.0f} s '
          'wall\n')
    print_table(rows)
    path = Path(options.json)
    path.parent.mkdir(parents=True, exist_ok=True)
    report = json.dumps({'machine': info, 'quick': options.quick, 'domain_id': domain_id,
                         'wall_s': wall_s, 'rows': rows})  # then NaN and infinity as null
    path.write_text(json.dumps(json.loads(report, parse_constant=lambda _: None), indent=2))
    print(f'\nJSON: {path}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
