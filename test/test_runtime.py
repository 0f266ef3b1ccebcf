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

import signal

import pytest
import rclpy
from rclpy.node import Node
from sim_diffdrive.runtime import EXIT_FAILED
from sim_diffdrive.runtime import EXIT_OK
from sim_diffdrive.runtime import run


class Finished(Node):
    """A node that is done at once with exit_code; its shutdown_hook can fail."""

    def __init__(self, exit_code=EXIT_OK, hook_error=None):
        super().__init__('finished')
        self.done = True
        self.exit_code = exit_code
        self.hook_error = hook_error
        self.calls = []

    def shutdown_hook(self):
        self.calls.append('shutdown_hook')
        if self.hook_error is not None:
            raise self.hook_error

    def destroy_node(self):
        self.calls.append('destroy_node')
        super().destroy_node()


@pytest.fixture
def main_process():
    """Give run() the process: restore the signal handlers and the default context after it."""
    handlers = {signum: signal.getsignal(signum) for signum in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        rclpy.try_shutdown()
        for signum, handler in handlers.items():
            signal.signal(signum, handler)


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
