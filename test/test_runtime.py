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
The one main() shape (sim_diffdrive.runtime.run), in this process: every exit path cleans up.

run() initialises rclpy's default context (on this run's domain, see conftest.py) and installs
its own SIGINT/SIGTERM handlers; each test puts the handlers back and shuts the context down.
"""

import gc
import importlib
import signal
import time

from geometry_msgs.msg import Twist
from motion_challenges import console
import pytest
import rclpy
from rclpy.node import Node
from sim_diffdrive import console as sim_diffdrive_console
from sim_diffdrive.harness import kill_all
from sim_diffdrive.harness import start_python
from sim_diffdrive.runtime import destroyed_if_refused
from sim_diffdrive.runtime import EXIT_FAILED
from sim_diffdrive.runtime import EXIT_OK
from sim_diffdrive.runtime import EXIT_USAGE
from sim_diffdrive.runtime import run

MOTIONS = ('rotate_robot', 'circle_back_and_forth', 'timed_out_and_back', 'odom_out_and_back',
           'motion_fleet')


class Finished(Node):
    """A node that is done at once with exit_code; its shutdown_hook can fail."""

    def __init__(self, exit_code=EXIT_OK, hook_error=None, name='finished', done=True,
                 journal=None):
        super().__init__(name)
        self.done = done
        self.exit_code = exit_code
        self.hook_error = hook_error
        self.calls = []
        self.journal = [] if journal is None else journal  # (name, call) across nodes

    def shutdown_hook(self):
        self._called('shutdown_hook')
        if self.hook_error is not None:
            raise self.hook_error

    def destroy_node(self):
        self._called('destroy_node')
        super().destroy_node()

    def _called(self, what):
        self.calls.append(what)
        self.journal.append((self.get_name(), what))


def run_node(node_kwargs):
    nodes = []

    def make_node():
        nodes.append(Finished(**node_kwargs))
        return nodes[0]
    return run(make_node, args=[]), nodes[0]


@pytest.mark.parametrize('exit_code', [EXIT_OK, EXIT_FAILED])
def test_run_returns_the_exit_code_after_the_hook_and_cleans_up(main_process, exit_code):
    code, node = run_node({'exit_code': exit_code})
    assert code == exit_code
    assert node.calls == ['shutdown_hook', 'destroy_node']
    assert not rclpy.ok()


@pytest.mark.parametrize('exit_code', [EXIT_OK, EXIT_FAILED])
def test_a_failing_shutdown_hook_still_destroys_the_node_and_shuts_down(
        main_process, capfd, exit_code):
    code, node = run_node({'exit_code': exit_code,
                           'hook_error': RuntimeError('publisher is gone')})
    assert node.calls == ['shutdown_hook', 'destroy_node']
    assert not rclpy.ok()
    # The final stop may not have reached the robot: that is a failure, and it says why.
    assert code == EXIT_FAILED
    assert 'publisher is gone' in capfd.readouterr().err


def test_a_second_ctrl_c_during_the_hook_still_cleans_up(main_process):
    code, node = run_node({'hook_error': KeyboardInterrupt()})
    assert node.calls == ['shutdown_hook', 'destroy_node']
    assert not rclpy.ok()
    assert code == EXIT_OK


class InterruptedWhileBuilt(Node):
    """A node whose constructor Ctrl-C interrupts inside rclpy's create_publisher."""

    def __init__(self, monkeypatch):
        super().__init__('interrupted')
        wake_executor = Node._wake_executor

        def interrupt(node):  # as the signal handler would, at this point of rclpy's code
            monkeypatch.setattr(Node, '_wake_executor', wake_executor)
            raise KeyboardInterrupt
        monkeypatch.setattr(Node, '_wake_executor', interrupt)
        with destroyed_if_refused(self):
            self.create_publisher(Twist, 'cmd_vel', 10)


def test_an_interrupt_inside_rclpy_while_a_node_is_built_is_an_interrupt(
        main_process, monkeypatch, capfd):
    # Once in a suite beside a busy loop, SIGTERM to unicycle_sim as it built its robots ended
    # in a traceback and exit code 1: rclpy failed to destroy the half-made node (ValueError:
    # list.remove(x): x not in list), and that error replaced the interrupt.
    assert run(lambda: InterruptedWhileBuilt(monkeypatch), args=[]) == EXIT_OK
    err = capfd.readouterr().err
    assert 'Interrupted by the user' in err and 'Traceback' not in err, err
    assert not rclpy.ok()


class Endless(Node):
    """A node with no ``done`` (a simulator, say): it never ends the run by itself."""

    def __init__(self):
        super().__init__('endless')
        self.destroyed = False

    def destroy_node(self):
        self.destroyed = True
        super().destroy_node()


def run_nodes(*node_kwargs, extra=()):
    """Run Finished nodes built from node_kwargs (plus extra nodes) as one list; return them."""
    nodes = []

    def make_nodes():
        nodes.extend(Finished(name=f'finished_{i}', **kwargs)
                     for i, kwargs in enumerate(node_kwargs))
        nodes.extend(make() for make in extra)
        return nodes
    return run(make_nodes, args=[]), nodes


@pytest.mark.parametrize('codes', [(EXIT_OK, EXIT_OK), (EXIT_OK, EXIT_FAILED),
                                   (EXIT_FAILED, EXIT_OK), (EXIT_OK, EXIT_USAGE, EXIT_FAILED)])
def test_several_nodes_return_the_worst_exit_code_and_all_are_cleaned_up(main_process, codes):
    code, nodes = run_nodes(*({'exit_code': c} for c in codes))
    assert code == max(codes)
    for node in nodes:
        assert node.calls == ['shutdown_hook', 'destroy_node']
    assert not rclpy.ok()


def test_one_failing_hook_among_several_still_runs_the_others_and_destroys_all(
        main_process, capfd):
    journal = []
    code, (failing, other) = run_nodes(
        {'hook_error': RuntimeError('publisher is gone'), 'journal': journal},
        {'journal': journal})
    assert code == EXIT_FAILED
    assert failing.calls == other.calls == ['shutdown_hook', 'destroy_node']
    # Every hook runs before any node is destroyed (a motion's final stop may need the others).
    assert journal == [('finished_0', 'shutdown_hook'), ('finished_1', 'shutdown_hook'),
                       ('finished_0', 'destroy_node'), ('finished_1', 'destroy_node')]
    assert not rclpy.ok()
    assert 'publisher is gone' in capfd.readouterr().err


def test_a_tuple_of_nodes_works_like_a_list(main_process):
    built = []

    def make_nodes():
        built.extend((Finished(name='a', exit_code=EXIT_FAILED), Finished(name='b')))
        return tuple(built)
    assert run(make_nodes, args=[]) == EXIT_FAILED
    assert [node.calls for node in built] == [['shutdown_hook', 'destroy_node']] * 2


def test_a_node_without_done_does_not_hold_the_run_once_the_others_are_done(main_process):
    code, nodes = run_nodes({}, {'exit_code': EXIT_FAILED}, extra=[Endless])
    assert code == EXIT_FAILED
    assert nodes[-1].destroyed
    assert all(node.calls == ['shutdown_hook', 'destroy_node'] for node in nodes[:-1])


class Lingering(Finished):
    """Not done; a run that nothing ends ends after 10 s, failed, rather than spin for ever."""

    def __init__(self, name='lingering'):
        super().__init__(name=name, done=False)
        self.create_timer(10.0, self._given_up)

    def _given_up(self):
        self.exit_code, self.done = EXIT_FAILED, True


class Interrupting(Lingering):
    """Not done; a timer sends this process SIGINT, as Ctrl-C would, once spinning."""

    signum = signal.SIGINT

    def __init__(self):
        super().__init__(name='interrupting')
        self.create_timer(0.01, lambda: signal.raise_signal(self.signum))


class Terminating(Interrupting):
    """Not done; a timer sends this process SIGTERM, as a launch file or systemd would."""

    signum = signal.SIGTERM


class HangingUp(Interrupting):
    """Not done; a timer sends this process SIGHUP, as closing its terminal does."""

    signum = signal.SIGHUP


def test_ctrl_c_runs_every_hook_and_keeps_a_failure_already_there(main_process):
    code, nodes = run_nodes({'exit_code': EXIT_FAILED}, extra=[Interrupting])
    assert code == EXIT_FAILED
    assert all(node.calls == ['shutdown_hook', 'destroy_node'] for node in nodes)


@pytest.mark.parametrize('signaller,said', [
    (Interrupting, 'Interrupted by the user'), (Terminating, 'Stopped by SIGTERM'),
    (HangingUp, 'Stopped by SIGHUP (its terminal closed)')])
def test_ctrl_c_or_sigterm_with_nothing_failed_exits_0_and_says_which(
        main_process, capfd, signaller, said):
    code, nodes = run_nodes({}, extra=[signaller])
    assert code == EXIT_OK
    assert all(node.calls == ['shutdown_hook', 'destroy_node'] for node in nodes)
    err = capfd.readouterr().err
    assert said in err and 'Traceback' not in err, err
    # A second signal after the run changes nothing: Python would put the default action back
    # as it finalizes, and a second Ctrl-C then killed the process (exit 130, not 0).
    assert signal.getsignal(signal.SIGINT) == signal.getsignal(signal.SIGTERM) == signal.SIG_IGN


class HungUpThenDone(Finished):
    """Done once a timer has sent this process SIGHUP three times."""

    def __init__(self):
        super().__init__(name='hung_up', done=False)
        self.sent = 0
        self.create_timer(0.01, self._hang_up)

    def _hang_up(self):
        if self.sent == 3:
            self.done = True
        else:
            self.sent += 1
            signal.raise_signal(signal.SIGHUP)


def test_under_nohup_sighup_is_left_ignored(main_process, capfd):
    # nohup starts a process with SIGHUP ignored, to outlive its terminal: the run keeps that.
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    code, nodes = run_nodes({}, extra=[HungUpThenDone])
    assert code == EXIT_OK and nodes[-1].sent == 3
    assert all(node.calls == ['shutdown_hook', 'destroy_node'] for node in nodes)
    assert 'SIGHUP' not in capfd.readouterr().err


class SignalledWhileEnding(Finished):
    """Done at once; Ctrl-C comes during its final stop, SIGTERM while it is destroyed."""

    def __init__(self):
        super().__init__(name='signalled_while_ending')

    def shutdown_hook(self):
        self._called('shutdown_hook')
        signal.raise_signal(signal.SIGINT)
        self._called('final stop sent')

    def destroy_node(self):
        signal.raise_signal(signal.SIGTERM)
        super().destroy_node()


def test_a_signal_while_the_run_ends_cuts_off_neither_the_final_stop_nor_the_cleanup(
        main_process):
    # As when Ctrl-C comes just after a motion said Done, or a second time during its stop.
    code, nodes = run_nodes({}, extra=[SignalledWhileEnding])
    assert code == EXIT_OK
    assert nodes[-1].calls == ['shutdown_hook', 'final stop sent', 'destroy_node']
    assert nodes[0].calls == ['shutdown_hook', 'destroy_node']
    assert not rclpy.ok()


def test_ctrl_c_twice_before_the_run_spins_is_one_interrupt(main_process):
    handled = []

    def make_node():
        try:
            signal.raise_signal(signal.SIGINT)  # at a prompt, say
        except KeyboardInterrupt:
            signal.raise_signal(signal.SIGINT)  # pressed again while the first is handled
            handled.append('the first')
            raise
    assert run(make_node, args=[]) == EXIT_OK
    assert handled == ['the first']
    assert not rclpy.ok()


def test_what_was_built_before_the_spin_is_left_out_of_garbage_collection(main_process):
    # gc.freeze() once the nodes are built: the collector walks only what the run makes, and
    # the process exits without walking and freeing every module again.
    seen = []

    class Looking(Finished):
        def shutdown_hook(self):  # after the spin, before the node is destroyed
            seen.append(any(o is self for o in gc.get_objects()))

    assert run(lambda: Looking(), args=[]) == EXIT_OK
    assert seen == [False]


# A node whose destruction never ends, as Fast DDS's participant deletion once did.
STUCK_CLEANUP = """
import time
from rclpy.node import Node
import sim_diffdrive.runtime as runtime
runtime.CLEANUP_TIMEOUT_S = 0.5


class StuckAtExit(Node):
    done, exit_code = True, 0

    def __init__(self):
        super().__init__('stuck_at_exit')

    def shutdown_hook(self):
        print('final stop sent', flush=True)

    def destroy_node(self):
        time.sleep(60)


raise SystemExit(runtime.run(StuckAtExit, args=[]))
"""


def test_a_cleanup_that_never_ends_ends_the_process_with_its_stack_after_the_final_stop():
    process = start_python(STUCK_CLEANUP)
    try:
        code = process.wait(20.0)
    finally:
        kill_all([process], grace=0.0)
    output = process.output()
    assert code == EXIT_FAILED, output
    assert 'final stop sent' in output
    assert 'Timeout (0:00:00.500000)!' in output and 'in destroy_node' in output, output


# A console script's start, its imports held up (as a busy machine holds rclpy's): the module
# says when it is being imported, and its import lasts until a signal has come (30 s at most).
SLOW_START = """
import pathlib, sys, tempfile
folder = pathlib.Path(tempfile.mkdtemp())
(folder / 'slow_imports.py').write_text(
    'import time\\nfrom sim_diffdrive import console\\nprint("importing", flush=True)\\n'
    'end = time.monotonic() + 30\\n'
    'while not console._received and time.monotonic() < end: time.sleep(0.01)\\n'
    'def main(): return 1\\n')
sys.path.insert(0, str(folder))
from sim_diffdrive.console import launch
sys.exit(launch('slow_imports', 'slow_start'))
"""


@pytest.mark.parametrize('signum,said', [
    (signal.SIGINT, 'Interrupted by the user'), (signal.SIGTERM, 'Stopped by SIGTERM'),
    (signal.SIGHUP, 'Stopped by SIGHUP (its terminal closed)')])
def test_a_signal_while_an_executable_imports_ends_it_quietly(signum, said, terminal_sighup):
    # Before sim_diffdrive/console.py, a Ctrl-C there was a traceback, SIGTERM silence.
    process = start_python(SLOW_START)
    try:
        deadline = time.monotonic() + 20.0
        while 'importing' not in process.output() and time.monotonic() < deadline:
            time.sleep(0.01)
        process.popen.send_signal(signum)
        code = process.wait(10.0)
    finally:
        kill_all([process], grace=0.0)
    output = process.output()
    assert code == EXIT_OK, output
    assert f'[slow_start]: {said} as it started' in output and 'Traceback' not in output, output


def test_a_signal_after_the_imports_is_the_runs_first_interrupt(main_process, capfd):
    # Noted by the console script once its imports were done, before run() took over.
    sim_diffdrive_console._note(signal.SIGTERM, None)
    code, nodes = run_nodes(extra=[Lingering])
    assert code == EXIT_OK and nodes == []  # ended before a node was built
    assert 'Stopped by SIGTERM' in capfd.readouterr().err
    assert sim_diffdrive_console.early_signal() is None  # taken


def test_each_console_script_launches_its_executables_main(monkeypatch):
    launched = []
    monkeypatch.setattr(console, 'launch', lambda module, name: launched.append((module, name)))
    for name in MOTIONS:
        getattr(console, name)()
    assert launched == [(f'motion_challenges.{name}', name) for name in MOTIONS]
    assert all(callable(importlib.import_module(module).main) for module, _ in launched)
