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
The console scripts' first step: SIGINT, SIGTERM and SIGHUP taken before the heavy imports.

A console script imports its executable's module (rclpy, numpy: 0.1 s, a second and more on a
busy machine) before its main() and runtime.run, which handles signals, can run: a Ctrl-C then
ended the start with a traceback, and SIGTERM without a word.  launch() notes a signal from its
first line on; the imports go on (an exception raised inside one, from C, came out as another:
ImportError), then the start ends quietly, exit 0, nothing published.  One that comes after the
imports, before runtime.run took over, is its first interrupt (early_signal).  Only the
executables do this: a module that set handlers as it is imported would impose them on whoever
imports it.
"""

import importlib
import signal
import sys
import time

SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
_STOPPED_BY = {signal.SIGTERM: 'Stopped by SIGTERM',
               signal.SIGHUP: 'Stopped by SIGHUP (its terminal closed)'}
_received = []  # the signals noted since launch(), until runtime.run takes them (early_signal)


def _note(signum, frame):
    _received.append(signum)


def stopped_by(signum):
    """Return what a run or a start ended by signum says (SIGTERM is not a user's Ctrl-C)."""
    return _STOPPED_BY.get(signum, 'Interrupted by the user')


def early_signal():
    """Return the first signal that came while the executable started (None: none); forget."""
    first = _received[0] if _received else None
    _received.clear()
    return first


def launch(module, name):
    """Import module, return its main()'s exit code; 0 after a signal during the imports."""
    for signum in SIGNALS:
        if signal.getsignal(signum) is not signal.SIG_IGN:  # nohup: the terminal may go
            signal.signal(signum, _note)
    main = importlib.import_module(module).main
    if not _received:
        return main()
    for signum in SIGNALS:
        signal.signal(signum, signal.SIG_IGN)
    said = stopped_by(_received[0])
    try:  # as rclpy logs (its logging is not set up yet); to a closed terminal: EIO
        print(f'[INFO] [{time.time():.9f}] [{name}]: {said} as it started', file=sys.stderr)
    except OSError:
        pass
    return 0


def unicycle_sim():
    """Launch the executable unicycle_sim: sim_diffdrive.sim.node's main()."""
    return launch('sim_diffdrive.sim.node', 'unicycle_sim')
