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
Start this package's executables as a user would (separate processes) and stop them again.

No ROS here: the processes inherit this process's environment (ROS_DOMAIN_ID, discovery range),
so a test or a tool that sets those keeps its children on its own graph.
"""

import os
import shutil
import signal
import subprocess
import sys


def ros_params(*params):
    """Return the command-line arguments that set each 'name:=value' as a ROS parameter."""
    return ['--ros-args', *[arg for param in params for arg in ('-p', param)]]


def start(executable, *args, stdin=subprocess.DEVNULL):
    """Start an executable found on PATH; its output (stdout and stderr) goes to a pipe."""
    path = shutil.which(executable)
    if path is None:
        raise FileNotFoundError(f'{executable} is not on PATH; install the package (make venv)')
    return _popen([path, *args], stdin)


def start_python(code):
    """Start this Python interpreter on a piece of code (a load, a listener, ...)."""
    return _popen([sys.executable, '-c', code], subprocess.DEVNULL)


def stop(process, signum=signal.SIGINT, timeout=5.0):
    """Send signum unless the process has exited, kill it after timeout; return its output."""
    if process.poll() is None:
        process.send_signal(signum)
        try:
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    return process.stdout.read()


def _popen(args, stdin):
    return subprocess.Popen(args, stdin=stdin, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, env=dict(os.environ))
