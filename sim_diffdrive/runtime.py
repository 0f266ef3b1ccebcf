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
after which a last zero Twist can no longer be published.  So the context is started without
rclpy's signal handlers and SIGINT and SIGTERM are handled here: while Python code waits (for
typed input, say) they raise KeyboardInterrupt; while the executor spins they only set a flag,
checked between waits of at most 0.1 s, so no callback is cut off halfway.  The node's
``shutdown_hook`` (the motions' final stop) then runs while the context is still valid; should
it fail, the error is logged, the exit code is 1, and the node is destroyed and rclpy shut down
all the same.
"""

import signal

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.signals import SignalHandlerOptions
from sim_diffdrive.parameters import ParameterError

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2

# Bounds how long a signal waits for Python's handler while the executor sleeps in rcl.
_SPIN_TIMEOUT = 0.1


class _Interrupts:
    """SIGINT/SIGTERM handler: a flag while spinning, KeyboardInterrupt otherwise."""

    def __init__(self):
        self.spinning = False
        self.requested = False

    def __call__(self, signum, frame):
        if not self.spinning:
            raise KeyboardInterrupt
        self.requested = True


class UsageError(Exception):
    """The user's input cannot start a run (the message says why)."""


def spin_until_done(executor, node, interrupts):
    """Spin until ``node.done`` is true, the context shuts down or the user interrupts."""
    interrupts.spinning = True
    try:
        while executor.context.ok() and not getattr(node, 'done', False):
            executor.spin_once(timeout_sec=_SPIN_TIMEOUT)
            if interrupts.requested:
                raise KeyboardInterrupt
    finally:
        interrupts.spinning = False


def run(make_node, args=None):
    """
    Initialise rclpy, build a node with ``make_node()``, spin it until done, clean up.

    Returns the process exit code: the node's ``exit_code`` when it finishes by itself, 0 for
    a user interrupt (Ctrl-C or SIGTERM), 2 for a bad parameter or input, 1 otherwise.
    """
    logger = rclpy.logging.get_logger('motion_challenges')
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except rclpy_implementation.RCLError as error:
        # A malformed command line (say -p rate_hz:=[1) is bad input, not a crash.
        logger.error(f'Bad command-line arguments: {error}')
        return EXIT_USAGE
    interrupts = _Interrupts()
    signal.signal(signal.SIGINT, interrupts)
    signal.signal(signal.SIGTERM, interrupts)
    node = None
    exit_code = EXIT_FAILED
    try:
        node = make_node()
        logger = node.get_logger()
        executor = EventsExecutor()
        executor.add_node(node)
        spin_until_done(executor, node, interrupts)
        exit_code = getattr(node, 'exit_code', EXIT_OK)
    except (ParameterError, UsageError) as error:
        logger.error(str(error))
        exit_code = EXIT_USAGE
    except KeyboardInterrupt:
        logger.info('Interrupted by the user')
        exit_code = EXIT_OK
    except ExternalShutdownException:
        exit_code = EXIT_FAILED
    finally:
        try:
            if node is not None:
                if not _run_shutdown_hook(node, logger):
                    exit_code = EXIT_FAILED
                node.destroy_node()
        finally:
            rclpy.try_shutdown()
    return exit_code


def _run_shutdown_hook(node, logger):
    """Call the node's shutdown_hook, if any; return False when it failed (it is logged)."""
    hook = getattr(node, 'shutdown_hook', None)
    try:
        if hook is not None:
            hook()
    except KeyboardInterrupt:
        # A second Ctrl-C during the final stop must not skip the cleanup after it.
        pass
    except Exception as error:
        logger.error(f'shutdown_hook failed ({type(error).__name__}: {error}); the robot '
                     'may not have been told to stop')
        return False
    return True
