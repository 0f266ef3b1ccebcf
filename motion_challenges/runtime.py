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
rclpy's signal handlers, SIGTERM is turned into KeyboardInterrupt like SIGINT, the executor
waits with a timeout so Python gets to run its handler, and the node's ``shutdown_hook`` (the
motions' final stop) runs while the context is still valid.
"""

import signal

from motion_challenges.parameters import ParameterError
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.signals import SignalHandlerOptions

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2

# Bounds how long a signal waits for Python's handler while the executor sleeps in rcl.
_SPIN_TIMEOUT = 0.1


def _raise_keyboard_interrupt(signum, frame):
    raise KeyboardInterrupt


class UsageError(Exception):
    """The user's input cannot start a run (the message says why)."""


def spin_until_done(executor, node, timeout_sec=_SPIN_TIMEOUT):
    """Spin until ``node.done`` is true or the context shuts down."""
    while executor.context.ok() and not getattr(node, 'done', False):
        executor.spin_once(timeout_sec=timeout_sec)


def run(make_node, args=None):
    """
    Initialise rclpy, build a node with ``make_node()``, spin it until done, clean up.

    Returns the process exit code: the node's ``exit_code`` when it finishes by itself, 0 for
    a user interrupt (Ctrl-C or SIGTERM), 2 for a bad parameter or input, 1 otherwise.
    """
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGTERM, _raise_keyboard_interrupt)
    logger = rclpy.logging.get_logger('motion_challenges')
    node = None
    exit_code = EXIT_FAILED
    try:
        node = make_node()
        logger = node.get_logger()
        executor = EventsExecutor()
        executor.add_node(node)
        spin_until_done(executor, node)
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
        if node is not None:
            try:
                hook = getattr(node, 'shutdown_hook', None)
                if hook is not None:
                    hook()
            except KeyboardInterrupt:
                # A second Ctrl-C during the final stop must not skip the cleanup below.
                pass
            node.destroy_node()
        rclpy.try_shutdown()
    return exit_code
