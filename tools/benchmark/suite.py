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

"""Row 19: the test suite, ``make test``, its wall time and what it cost the machine."""

import os
from pathlib import Path
import re
import subprocess
import sys
import time

from benchmark import core
from benchmark.core import Row
from benchmark.core import row
from sim_diffdrive.harness import DOMAIN_VARIABLE

ROOT = Path(__file__).resolve().parents[2]
# --quick checks the row on one module of two pure tests, without the suite's conftest.py and
# hypothesis (a third of a CPU s): the suite itself runs the quick run.
QUICK_COMMAND = (sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider', '--noconftest',
                 '-p', 'no:hypothesispytest', 'test/test_throttle.py')
# make test's whole output, from the full run: a failure's own text, not only the run's tail.
SUITE_LOG = ROOT / 'out' / 'suite.log'


def machine_busy_s():
    """Return the machine's busy CPU seconds so far: /proc/stat's first line but idle, iowait."""
    with open('/proc/stat') as stat:
        ticks = [int(field) for field in stat.readline().split()[1:]]
    return (sum(ticks[:8]) - ticks[3] - ticks[4]) / os.sysconf('SC_CLK_TCK')


def run_suite(command, timeout, log_path=None):
    """
    Run command in the package's folder; return its wall s, the machine's CPU s, counts.

    Its whole output goes to log_path too, if given.
    """
    # On ROS domains of its own, as a user's make test: not on this run's.
    env = {k: v for k, v in os.environ.items() if k not in (DOMAIN_VARIABLE, 'ROS_DOMAIN_ID')}
    busy, start = machine_busy_s(), time.monotonic()
    result = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True,
                            timeout=timeout)
    wall_s, cpu_s = time.monotonic() - start, machine_busy_s() - busy
    if log_path is not None:
        log_path.parent.mkdir(exist_ok=True)
        log_path.write_text(result.stdout + result.stderr)
    lines = result.stdout.strip().splitlines()
    summary = lines[-1] if lines else ''
    counts = {kind: int(n) for n, kind in re.findall(
        r'(\d+) (passed|failed|skipped|errors?)', summary)}
    return {'command': ' '.join(command), 'returncode': result.returncode, 'wall_s': wall_s,
            'cpu_s': cpu_s, 'summary': summary, 'counts': counts,
            'output_tail': '' if result.returncode == 0 else core.tail(
                result.stdout + result.stderr, 30)}


@row('suite')
def suite(run):
    quick = run.sizes.quick
    if not quick:  # a warm venv, as the target says: set it up first if make would, untimed
        subprocess.run(('make', '-s', 'venv'), cwd=ROOT, check=True, capture_output=True)
    measured = run_suite(QUICK_COMMAND if quick else ('make', '-s', 'test'),
                         120.0 if quick else 900.0, None if quick else SUITE_LOG)
    if measured['returncode'] != 0:
        print(f'{measured["command"]} failed ({measured["returncode"]}; '
              f'{"the whole output: " + str(SUITE_LOG) if not quick else "its tail"}):\n'
              + measured['output_tail'], file=sys.stderr)
    cores = os.cpu_count()
    counts = ', '.join(f'{n} {kind}' for kind, n in measured['counts'].items()) or 'no summary'
    return Row(
        'make test: wall time, and the CPU the machine was busy',
        f'{measured["wall_s"]:.1f} s ({counts}); the machine busy {measured["cpu_s"]:.1f} CPU s',
        f'that CPU on {cores} cores, never idle: {measured["cpu_s"] / cores:.1f} s',
        ('--quick runs test/test_throttle.py only, to check this row (no target). '
         if quick else '') + "The README's test command (make test: bytecode, then pytest with "
        'four workers), a warm venv, on ROS domains of its own; its wall time, and the '
        "machine's busy time over it from /proc/stat (every process, the browser's too). The "
        'reference is the wall time with every core busy all along: less than that needs '
        'less CPU, not better packing.',
        '-' if quick else f'<= {core.TARGET_SUITE_S:g} s',
        None if quick else measured['returncode'] == 0
        and measured['wall_s'] <= core.TARGET_SUITE_S, measured)
