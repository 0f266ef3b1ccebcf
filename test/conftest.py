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

import faulthandler
import gc
import os
import signal
import sys
import time

import pytest
import rclpy
from sim_diffdrive import harness
from sim_diffdrive.dds_profile import use_package_profile
from sim_diffdrive.dds_teardown import held_context
from sim_diffdrive.harness import DOMAIN_VARIABLE
from sim_diffdrive.harness import isolated_domain_id
from sim_diffdrive.harness import SimGraph
from sim_diffdrive.testing.domains import DOMAIN_BLOCK

if int(os.environ.get('PYTEST_XDIST_WORKER', 'gw0')[2:]) >= DOMAIN_BLOCK:
    # pytest -n: worker gwN on the domain N after the first of the block its run claimed (one
    # for each of DOMAIN_BLOCK workers); the workers beyond those claim a block each.
    os.environ.pop(DOMAIN_VARIABLE, None)
DOMAIN_ID = isolated_domain_id()
use_package_profile()  # before this process makes its first node
# Subprocesses write each log line at once, so a test reads their output as it happens.
os.environ.setdefault('RCUTILS_LOGGING_BUFFERED_STREAM', '0')
# numpy's OpenBLAS starts a thread per core on import, spinning: 0.1 CPU s of the 0.5 each
# started process spends importing, for matrix work that nothing here does.
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')


def pytest_configure(config):
    """
    Keep the fault dump of a crash on this process's own stderr (a pytest worker's too).

    rclpy's EventsExecutor() calls faulthandler.enable(), which points the dump at sys.stderr:
    within a test, pytest's capture, which a crashed worker takes with it.  Four worker deaths
    (docs/robustness.md, "Known gaps") left no dump for that reason; a test that segfaults
    after making an EventsExecutor shows it.  Here stderr is still the process's own (pytest's
    faulthandler plugin relies on the same), so a call without a file goes there.
    """
    stderr = os.dup(sys.__stderr__.fileno())
    enable = faulthandler.enable

    def enable_on_stderr(file=None, all_threads=True):
        enable(file=stderr if file is None else file, all_threads=all_threads)
    faulthandler.enable = enable_on_stderr


@pytest.fixture
def ros_context():
    """
    Yield a fresh rclpy Context (no signal handlers) on this run's domain.

    Its DDS participant is held until the test is over, then let go the safe way: a test's
    last destroy_node() would otherwise delete it, and hang for good if a discovery callback
    was running then (sim_diffdrive/dds_teardown.py).
    """
    with held_context(domain_id=DOMAIN_ID) as context:
        yield context


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


@pytest.fixture
def terminal_sighup():
    """
    Give this test, and the processes it starts, SIGHUP's default action, as a terminal does.

    A suite run under nohup (a loop of runs, a CI job) inherits it ignored, and a run rightly
    keeps ignoring it: a test of a closed terminal would then wait for an end that never comes.
    """
    handler = signal.signal(signal.SIGHUP, signal.SIG_DFL)
    try:
        yield
    finally:
        signal.signal(signal.SIGHUP, handler)


@pytest.fixture
def main_process(terminal_sighup):
    """Give run() the process: restore the signal handlers and the default context after it."""
    handlers = {signum: signal.getsignal(signum)
                for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    finally:
        rclpy.try_shutdown()
        for signum, handler in handlers.items():
            signal.signal(signum, handler)


@pytest.fixture
def run_main(main_process, capfd):
    """
    Call an executable's main() in this process, as its console script would; (code, output).

    ``run_main(main, executable, *args)``: main gets [executable, *args] as its argv, the
    command line of the executable (test_colcon_layout.py checks that its console script calls
    that main; test_faults.py shows, once per package, that main's return is the exit code).
    The output is what the call wrote to this process's stdout and stderr (its log lines).  For
    a refusal at start: no process start-up (0.8 CPU s) to show the path from the command line
    to exit code 2.
    """
    def call(main, executable, *args):
        capfd.readouterr()
        code = main([executable, *args])
        out, err = capfd.readouterr()
        return code, out + err
    return call


# The longest tests, in seconds of a busy suite, go first; make test hands them out one at a
# time (pytest -n 4 --dist load --maxschedchunk 1 and the scheduler below), each to the worker
# that frees up next.
# Those that mostly use the CPU alternate with those that mostly wait (a lossy link, a wall-time
# motion, a timeout), so that one's wait is another's work, and the short tests fill in at the
# end instead of one long test running alone.  A test not named here keeps its file's order.
_LONGEST = (
    'test_bench.py::test_quick_run_writes_every_row',  # 16 s, 8 CPU s
    'test_two_hosts.py::test_a_lossy_link_only_slows_the_run_down',  # 8 and 4 s, waiting
    'test_view.py::test_the_browser_shows_the_robot_driving_up_the_screen',  # 14 s, Chromium
    'test_lockstep_faults.py::test_a_cmd_vel_listener_is_not_the_robot',  # 6 s, waiting
    'test_flake8.py::test_flake8',  # 6 CPU s
    'test_lockstep_processes.py::test_a_killed_participant_is_left_behind_and_a_late_one_is',
    'test_lockstep_processes.py::test_motions_end_exact_and_bit_identical_on_a_busy_machine',
    'test_faults.py::test_make_stress_reports_and_judges_a_short_flood',
    'test_foxglove.py::test_unicycle_sim_serves_odometry_at_its_rate',
    'test_interrupts.py::test_simulator_restarted_mid_motion_is_noticed',
    'test_faults.py::test_a_cmd_vel_flood_is_cheap_the_last_command_wins',
    'test_interrupts.py::test_interrupt_mid_segment_and_during_a_pause',
    'test_motion_fleet.py::test_three_robots_from_the_shipped_params_file_each_end_exact',
    'test_lockstep_faults.py::test_foreign_stale_and_zero_stamps_and_leavers_never_stall',
)


# Tests that mostly wait (a lossy link, a wall-time motion or timeout, a process to end), using
# little CPU of their own, for a second or more.  With four workers or more (make test runs four
# on two cores), the last worker takes these first and the others the rest first: no more
# CPU-bound tests run at once than with three workers, and the waits fill the time the cores
# were idle.  A worker that has run out of its own kind takes the other kind.  About one
# worker's share of the run: with more, the waits were left over for every worker at the end,
# and the cores idle then.
_WAITING = (
    'test_two_hosts.py::test_a_lossy_link_only_slows_the_run_down',
    'test_lockstep_faults.py::test_a_cmd_vel_listener_is_not_the_robot',
    'test_faults.py::test_make_stress_reports_and_judges_a_short_flood',
    'test_faults.py::test_a_cmd_vel_flood_is_cheap_the_last_command_wins',
    'test_foxglove.py::test_unicycle_sim_serves_odometry_at_its_rate',
    'test_motion_node.py::test_without_a_robot_it_gives_up_start_timeout_after_the_answers',
    'test_motion_node.py::test_start_timeout_does_not_count_the_time_spent_typing',
    'test_faults.py::test_two_controllers_at_once_are_warned_about_once',
    'test_participant.py::test_odometry_a_step_ahead_is_answered_with_the_clock_of_its_step',
    'test_participant.py::test_a_joining_node_answers_the_newest_of_the_odometry_it_catches',
    'test_sim_checks.py::test_a_message_that_never_comes_is_forgiven_naming_the_publishers',
    'test_live_parameters.py::test_a_simulator_process_applies_a_live_set_and_refuses_a_read',
    'test_lockstep_processes.py::test_a_killed_participant_is_left_behind_and_a_late_one_is',
)


# Modules whose tests go to one worker together: those that share a module fixture (a colcon
# build, a simulator process), and the plots, so that one worker, not four, imports matplotlib
# (0.35 CPU s each).
_ONE_WORKER = ('test_colcon_layout.py', 'test_motion_processes.py', 'test_path_and_plot.py')


def pytest_xdist_make_scheduler(config, log):
    """
    With --dist load, return xdist's own scheduler with this suite's two rules.

    _WAITING's tests go to the last of four workers or more, and _ONE_WORKER's tests to one
    worker together.

    With --maxschedchunk 1 it keeps one test queued behind the running one.  (xdist's
    xdist_group mark cannot group them: with pytest 9 it does nothing, pytest-xdist issue 1386,
    and its scheduler waits forever after a worker crashes.)
    """
    if config.getvalue('dist') != 'load':
        return None
    from xdist.scheduler import LoadScheduling

    class Scheduling(LoadScheduling):
        waiting = None  # the collection's indices of _WAITING's tests

        def _send_tests(self, node, num):
            if len(self.node2pending) >= 4:
                if self.waiting is None:
                    self.waiting = {k for k, nodeid in enumerate(self.collection)
                                    if _named(nodeid, _WAITING) is not None}
                waiter = max(self.node2pending, key=lambda n: int(n.gateway.id[2:]))
                own = [k for k in self.pending if (k in self.waiting) == (node is waiter)]
                taken = set(own)
                self.pending[:] = own + [k for k in self.pending if k not in taken]
            batch, rest = self.pending[:num], self.pending[num:]
            grouped = {module for module in map(self._module, batch)
                       if module.rpartition('/')[2] in _ONE_WORKER}
            together = [k for k in rest if self._module(k) in grouped]
            self.pending[:] = batch + together + [k for k in rest if k not in together]
            super()._send_tests(node, num + len(together))

        def _module(self, index):
            return self.collection[index].partition('::')[0]
    return Scheduling(config, log)


def pytest_testnodedown(node, error):
    """
    Say how a pytest worker that died ended, read from /proc while it waits to be reaped.

    xdist says only "Not properly terminated"; the exit status (proc(5): stat's exit_code, as
    waitpid() gives it) tells a signal from an exit (docs/robustness.md, "Known gaps").
    """
    if not error:
        return
    deadline = time.monotonic() + 1.0
    while time.monotonic() < deadline:
        for pid in filter(str.isdigit, os.listdir('/proc')):
            try:
                with open(f'/proc/{pid}/stat') as stat:
                    fields = stat.read().rpartition(')')[2].split()
            except OSError:
                continue
            if fields[0] == 'Z' and int(fields[1]) == os.getpid():
                status = int(fields[49])
                how = f'signal {status & 0x7f}' if status & 0x7f else f'exit code {status >> 8}'
                print(f'[{node.gateway.id}] the worker, pid {pid}, ended by {how}',
                      file=sys.stderr)
                return
        time.sleep(0.05)


def _named(nodeid, names):
    """Return the index of the first of names that nodeid's file::test starts with, or None."""
    path, _, test = nodeid.partition('::')
    name = path.rpartition('/')[2] + '::' + test
    return next((k for k, prefix in enumerate(names) if name.startswith(prefix)), None)


def pytest_collection_finish(session):
    """
    Leave what collection made (pytest, the test modules, rclpy, numpy) out of later collections.

    A worker holds about 97,000 such objects for the whole run, and each full collection the
    tests' allocations set off walked them all (gc.freeze; the executables do the same once
    their nodes are built, sim_diffdrive.runtime.run).
    """
    gc.freeze()


def pytest_collection_modifyitems(items):
    def rank(item):
        k = _named(item.nodeid, _LONGEST)
        return len(_LONGEST) if k is None else k
    items.sort(key=rank)
