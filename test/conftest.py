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
Launch-free test harness: a fresh rclpy Context per test, one executor, bounded spinning.

The graph and process helpers are sim_diffdrive.harness, the same a user tests with.  Every
test run picks its own ROS domain and keeps discovery on localhost, so parallel runs on one
machine (and the subprocesses they start) never hear each other.
"""

import os

import pytest
import rclpy
from rclpy.context import Context
from sim_diffdrive import harness
from sim_diffdrive.dds_profile import use_package_profile
from sim_diffdrive.harness import DOMAIN_VARIABLE
from sim_diffdrive.harness import isolated_domain_id
from sim_diffdrive.harness import SimGraph
from sim_diffdrive.testing.graph import DOMAIN_BLOCK

DOMAIN_ID = isolated_domain_id()
if os.environ.get('PYTEST_XDIST_WORKER', 'gw0') != 'gw0':
    # pytest -n: each worker on a domain of its own, the next ones of the block that the run
    # claimed (DOMAIN_BLOCK of them); workers beyond those claim a block each.
    worker = int(os.environ['PYTEST_XDIST_WORKER'][2:])
    if worker < DOMAIN_BLOCK:
        os.environ[DOMAIN_VARIABLE] = str((DOMAIN_ID - 1 + worker) % 100 + 1)
    else:
        del os.environ[DOMAIN_VARIABLE]  # beyond the block: a block of its own
    DOMAIN_ID = isolated_domain_id()
use_package_profile()  # before this process makes its first node
# Subprocesses write each log line at once, so a test reads their output as it happens.
os.environ.setdefault('RCUTILS_LOGGING_BUFFERED_STREAM', '0')
# numpy's OpenBLAS starts a thread per core on import, spinning: 0.1 CPU s of the 0.5 each
# started process spends importing, for matrix work that nothing here does.
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')


@pytest.fixture
def ros_context():
    """Yield a fresh rclpy Context (no signal handlers) on this run's domain."""
    context = Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    try:
        yield context
    finally:
        rclpy.try_shutdown(context=context)


@pytest.fixture
def graph(ros_context):
    # SimGraph's default executor, the EventsExecutor the executables spin.
    g = SimGraph(ros_context)
    try:
        yield g
    finally:
        g.close()


@pytest.fixture
def procs(tmp_path):
    """
    Start processes as the tests need them; each returns a harness.Process.

    ``procs(label, executable, *args, **kwargs)`` logs to tmp_path/<n>_<label>.log; whatever
    still runs at the end is killed.
    """
    started = []

    def start(label, executable, *args, **kwargs):
        log_path = tmp_path / f'{len(started):02d}_{label}.log'
        started.append(harness.start(executable, *args, log_path=log_path, **kwargs))
        return started[-1]

    try:
        yield start
    finally:
        harness.kill_all(started)


# The longest modules start first, so that with pytest -n the short ones fill in around them
# instead of one long test running alone at the end.
_FIRST = ('test_lockstep_processes', 'test_view', 'test_interrupts', 'test_bench', 'test_faults')


def pytest_collection_modifyitems(items):
    def rank(item):
        name = item.module.__name__.rpartition('.')[2]
        return _FIRST.index(name) if name in _FIRST else len(_FIRST)
    items.sort(key=rank)
