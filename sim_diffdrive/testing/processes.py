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

"""Start the package's executables (or any code) as a user would, and stop them like Ctrl-C."""

import contextlib
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import weakref

# How long a process that did not exit has to write its stacks before SIGKILL (Process.kill).
STACKS_WAIT = 0.5
# How long gdb may take to attach and write a hung process's native stacks.
GDB_WAIT = 30.0


def ros_params(*params, namespace=None, clock=None, sim_time=False):
    """Return the --ros-args for 'name:=value' parameters, namespace, /clock remap, sim time."""
    args = ['--ros-args']
    if namespace:
        args += ['-r', f'__ns:={namespace}']
    if clock:
        args += ['-r', f'/clock:={clock}']
    params = (('use_sim_time:=true',) if sim_time else ()) + params
    return args + [arg for param in params for arg in ('-p', param)]


class Process:
    """A started process; its output goes to a file, as a pipe could fill up and block it."""

    def __init__(self, command, log_path=None, stdin=subprocess.DEVNULL, env=None):
        self.command = command
        self._temporary = log_path is None
        if log_path is None:
            fd, log_path = tempfile.mkstemp(prefix='sim_graph_', suffix='.log')
            os.close(fd)
        self.log_path = Path(log_path)
        # A process started from a non-interactive shell's background job ignores SIGINT, and so
        # would its children: a handler (reset to the default at exec) rather than an ignored
        # signal lets a child hear a user's Ctrl-C.
        if (signal.getsignal(signal.SIGINT) is signal.SIG_IGN
                and threading.current_thread() is threading.main_thread()):
            signal.signal(signal.SIGINT, signal.default_int_handler)
        with open(self.log_path, 'w') as log:
            self.popen = subprocess.Popen(
                command, stdin=stdin, stdout=log, stderr=subprocess.STDOUT,
                env=dict(os.environ if env is None else env))
        self.pid = self.popen.pid
        self._final_output = None  # kept once kill() has removed a temporary log
        if self._temporary:
            # Also removed when the Process is forgotten (or at exit) without being stopped.
            weakref.finalize(self, self.log_path.unlink, missing_ok=True)
        self.signalled_at = None  # monotonic time of the last send()
        self.exited_at = None  # monotonic time at which poll() or wait() first saw the exit
        # ... and the last at which poll() saw it running: it exited in between, whatever the
        # watcher's own delays (a busy test process polls late).
        self.running_at = None

    @property
    def returncode(self):
        return self.poll()

    def poll(self):
        code = self.popen.poll()
        if code is None:
            self.running_at = time.monotonic()
        elif self.exited_at is None:
            self.exited_at = time.monotonic()
        return code

    def wait(self, timeout=None):
        """Wait for the exit (subprocess.TimeoutExpired after timeout); return the exit code."""
        self.popen.wait(timeout)
        return self.poll()

    def send(self, signum):
        self.signalled_at = time.monotonic()
        self.popen.send_signal(signum)

    def write(self, data):
        """Write text or bytes to the process's stdin (started with stdin=subprocess.PIPE)."""
        self.popen.stdin.write(data.encode() if isinstance(data, str) else data)
        self.popen.stdin.flush()

    def close_input(self):
        """Close the process's stdin: it reads end of input after what was written."""
        self.popen.stdin.close()

    def output(self):
        """Return everything the process has written so far (stdout and stderr)."""
        if self._final_output is not None:
            return self._final_output
        return self.log_path.read_text(errors='replace')

    def kill(self, grace=3.0):
        """
        End the process unless it has exited; a temporary log is read and removed.

        SIGTERM first, so that it leaves DDS cleanly (a node killed outright can leave
        shared-memory state behind); after grace seconds its stacks go to its log (SIGUSR1,
        then gdb), then SIGKILL.
        """
        if self.popen.poll() is None:
            self.popen.terminate()
            try:
                self.popen.wait(grace)
            except subprocess.TimeoutExpired:
                self.popen.send_signal(signal.SIGUSR1)
                try:
                    self.popen.wait(STACKS_WAIT)  # a process without the handler dies of SIGUSR1
                except subprocess.TimeoutExpired:
                    self._write_native_stacks()
                    self.popen.kill()
                    self.popen.wait()
        self.poll()
        if self.popen.stdin:
            self.popen.stdin.close()
        if self._temporary and self._final_output is None:
            self._final_output = self.output()
            self.log_path.unlink(missing_ok=True)

    def _write_native_stacks(self):
        """Add every thread's native stack (gdb) to the log: where rclpy or DDS hangs."""
        gdb = shutil.which('gdb')
        if gdb is None:
            return
        try:
            stacks = subprocess.run(
                [gdb, '-p', str(self.popen.pid), '-batch', '-nx', '-iex', 'set auto-load off',
                 '-ex', 'thread apply all bt 30'], capture_output=True, text=True,
                timeout=GDB_WAIT).stdout
        except (OSError, subprocess.TimeoutExpired) as error:
            stacks = f'gdb gave no stacks: {error}\n'
        with open(self.log_path, 'a') as log:
            log.write('\nNative stacks (gdb):\n' + stacks)

    def describe(self):
        """Return the command line and the output, for an assertion message."""
        return f'$ {" ".join(str(arg) for arg in self.command[-12:])}\n{self.output()}'


def start(executable, *args, stdin=subprocess.DEVNULL, log_path=None, env=None):
    """Start an executable (a name on PATH, or a path) as a user would; return its Process."""
    path = shutil.which(executable)
    if path is None:
        raise FileNotFoundError(f'{executable} is not on PATH; install the package (make venv)')
    return Process([path, *args], log_path, stdin, env)


def start_python(code, log_path=None):
    """Start this Python interpreter on a piece of code (a load, a listener, ...)."""
    return Process([sys.executable, '-c', code], log_path)


def stop(process, signum=signal.SIGINT, timeout=5.0):
    """Send signum (Ctrl-C) unless it has exited, kill it after timeout; return its output."""
    return stop_all([process], signum, timeout)[0]


def stop_all(processes, signum=signal.SIGINT, timeout=5.0):
    """stop() several processes at once, each signalled before any is waited for; outputs."""
    _signal_all(processes, lambda process: process.send(signum), timeout)
    kill_all(processes)
    return [process.output() for process in processes]


def kill_all(processes, grace=3.0):
    """Process.kill() several processes at once: SIGTERM to every one, then wait."""
    _signal_all(processes, lambda process: process.popen.terminate(), grace)
    for process in processes:
        process.kill(grace=0.0)  # SIGKILL whatever still runs; read and remove its log


def _signal_all(processes, signal_one, timeout):
    """signal_one(process) for each that runs, then wait for them all up to timeout [s]."""
    running = [process for process in processes if process.poll() is None]
    for process in running:
        signal_one(process)
    deadline = time.monotonic() + timeout
    for process in running:
        with contextlib.suppress(subprocess.TimeoutExpired):
            process.wait(max(0.0, deadline - time.monotonic()))


def cpu_seconds(pid):
    """Return the CPU seconds process pid has used, every thread (Linux schedstat, in ns)."""
    total = 0
    for task in os.listdir(f'/proc/{pid}/task'):
        with contextlib.suppress(FileNotFoundError, ProcessLookupError):  # a thread just ended
            with open(f'/proc/{pid}/task/{task}/schedstat') as schedstat:
                total += int(schedstat.read().split()[0])
    return total * 1e-9
