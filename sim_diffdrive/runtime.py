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
The one ``main()`` shape every executable of this package uses.

rclpy's default SIGINT handler shuts the context down before Python sees KeyboardInterrupt,
and a last zero Twist could no longer be published.  So SIGINT, SIGTERM and SIGHUP (the
terminal closed; not under nohup, which ignores it) are handled here:
KeyboardInterrupt while Python code waits (typed input), a flag checked between spins once the
executor runs, so neither a callback nor the final stop (``shutdown_hook``) is cut off.
"""

from contextlib import contextmanager
from contextlib import suppress
import faulthandler
import gc
import signal

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.signals import SignalHandlerOptions
from sim_diffdrive.console import early_signal
from sim_diffdrive.console import SIGNALS
from sim_diffdrive.console import stopped_by
from sim_diffdrive.dds_profile import use_package_profile
from sim_diffdrive.dds_teardown import ParticipantHold
from sim_diffdrive.parameters import ParameterError

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2

# Bounds how long a signal waits for Python's handler while the executor sleeps in rcl.
_SPIN_TIMEOUT = 0.1
# How long destroying the nodes and shutting rclpy down may take [s] before the process ends
# anyway, with every thread's stack and exit code 1.  Fast DDS spun for ever deleting the
# participant with a discovery callback in flight, until run() held it (dds_teardown.py).
CLEANUP_TIMEOUT_S = 30.0


class _Interrupts:
    """SIGINT/SIGTERM: KeyboardInterrupt once, before the run spins; a flag otherwise."""

    def __init__(self):
        self.deferred = self.requested = False
        self.signum = None

    def __call__(self, signum, frame):
        self.requested = True
        self.signum = self.signum or signum
        if not self.deferred:
            self.deferred = True
            raise KeyboardInterrupt


class UsageError(Exception):
    """The user's input cannot start a run (the message says why)."""


@contextmanager
def destroyed_if_refused(node):
    """
    Destroy node if the block raises (a bad parameter or input refused it), then re-raise.

    Left to the garbage collector, it could go in a process forked later, on its DDS handles.
    """
    try:
        yield node
    except KeyboardInterrupt:
        # An interrupt inside an rclpy call can leave the node half made, and rclpy then fails
        # to destroy it; the process is ending, and what is left goes with it.
        with suppress(Exception):
            node.destroy_node()
        raise
    except BaseException:
        node.destroy_node()
        raise


def spin_until_done(executor, nodes, interrupts):
    """Spin until every node with a ``done`` attribute is done, or the run is stopped."""
    waiting = [node for node in nodes if hasattr(node, 'done')]
    interrupts.deferred = True
    while executor.context.ok() and not (waiting and all(n.done for n in waiting)):
        executor.spin_once(timeout_sec=_SPIN_TIMEOUT)
        if interrupts.requested:
            raise KeyboardInterrupt


def worst_exit_code(nodes):
    """Return the largest ``exit_code`` among the nodes that have one (0 when none has)."""
    codes = [getattr(node, 'exit_code', None) for node in nodes]
    return max((code for code in codes if code is not None), default=EXIT_OK)


def run(make_node, args=None, name='motion_challenges'):
    """
    Initialise rclpy, build the node(s) with ``make_node()``, spin until done, clean up.

    ``make_node()`` may return a list of nodes sharing one executor.  Returns the worst
    ``exit_code`` of the nodes that finished (0 for none, after a user interrupt); 2 for a bad
    parameter or input; 1 otherwise, and whenever a ``shutdown_hook`` failed.  ``name`` is the
    logger of what is said before a node exists (a bad parameter): the executable's name.
    """
    logger = rclpy.logging.get_logger(name)
    use_package_profile()  # before the first node makes the process's DDS participant
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except rclpy_implementation.RCLError as error:
        # A malformed command line (say -p rate_hz:=[1) is bad input, not a crash.
        logger.error(f'Bad command-line arguments: {error}')
        return EXIT_USAGE
    interrupts = _Interrupts()
    nodes = []
    executor = None
    hold = None
    exit_code = EXIT_FAILED
    try:  # from the handlers on: a signal as they are set is an interrupt of the run too
        for signum in SIGNALS:
            if signum != signal.SIGHUP or signal.getsignal(signum) is not signal.SIG_IGN:
                signal.signal(signum, interrupts)  # SIGHUP stays ignored under nohup
        early = early_signal()  # one that came after a console script's imports, before this
        if early is not None:
            interrupts(early, None)
        # `kill -USR1 <pid>` writes every thread's Python stack to stderr and the run goes on:
        # where a process that does not exit is stuck, even in rclpy or DDS (Process.kill).
        faulthandler.register(signal.SIGUSR1)
        # The DDS participant outlives every node, even one refused while it is built, and goes
        # last, the safe way (sim_diffdrive/dds_teardown.py).
        hold = ParticipantHold(rclpy.get_default_context())
        built = make_node()
        nodes = list(built) if isinstance(built, (list, tuple)) else [built]
        if len(nodes) == 1:
            logger = nodes[0].get_logger()
        executor = EventsExecutor()
        for node in nodes:
            executor.add_node(node)
        # What exists now lives as long as the process: the collector need not walk it again.
        gc.freeze()
        spin_until_done(executor, nodes, interrupts)
        exit_code = worst_exit_code(nodes)
    except (ParameterError, UsageError) as error:
        logger.error(str(error))
        exit_code = EXIT_USAGE
    except KeyboardInterrupt:
        # SIGTERM is how a launch file, systemd or `kill` stops a process, not a user's Ctrl-C.
        logger.info(stopped_by(interrupts.signum))
        # A motion that had already failed before the interrupt still fails the run.
        exit_code = worst_exit_code([n for n in nodes if getattr(n, 'done', False)])
    except ExternalShutdownException:
        exit_code = EXIT_FAILED
    finally:
        # From here on a signal neither cuts off a final stop nor the cleanup, nor escapes.
        interrupts.deferred = True
        try:
            # Every hook first (the motions' final stops, while a simulator in the same
            # process still runs), then every node is destroyed.
            hooks_ok = [_cleaned(getattr(node, 'shutdown_hook', lambda: None), 'shutdown_hook',
                                 node.get_logger(), '; the robot may not have been told to stop')
                        for node in nodes]
            if not all(hooks_ok):
                exit_code = EXIT_FAILED
            # The executor lets go of the nodes' entities before they are destroyed, not after
            # rclpy's shutdown, where a QoS event handler can crash (rclpy issue 1644).  The
            # watchdog is faulthandler's thread: it needs no GIL, which a spinning call holds.
            faulthandler.dump_traceback_later(CLEANUP_TIMEOUT_S, exit=True)
            if executor is not None:  # a failure is logged and does not fail the run
                _cleaned(executor.shutdown, 'Executor shutdown', logger)
            cleaned = [_cleaned(node.destroy_node, 'destroy_node', node.get_logger())
                       for node in nodes]
            if hold is not None:
                cleaned.append(_cleaned(hold.release, 'Releasing the DDS participant', logger))
            if not all(cleaned):
                exit_code = EXIT_FAILED
        finally:
            rclpy.try_shutdown()
            faulthandler.cancel_dump_traceback_later()
            # The run is over: a signal from now on changes nothing.  Left to Python, which
            # puts the default action back as it finalizes, a second Ctrl-C then killed the
            # process after its cleanup, exit 130 where the run's code was due.
            for signum in SIGNALS:
                signal.signal(signum, signal.SIG_IGN)
    return exit_code


def _cleaned(call, what, logger, consequence=''):
    """Call call(); return False when it failed (logged: what, consequence); cleanup goes on."""
    try:
        call()
    except KeyboardInterrupt:
        # A second Ctrl-C during the final stop must not skip the rest of the cleanup.
        pass
    except Exception as error:
        logger.error(f'{what} failed ({type(error).__name__}: {error}){consequence}')
        return False
    return True
