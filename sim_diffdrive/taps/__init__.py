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
Where else the simulator's traffic goes: an MCAP file, Foxglove, a browser (view_port).

A tap has a ``name``, ``wants_path`` (build the path message even with no DDS subscriber),
``write(topic, msg, stamp_ns)`` (a message or its CDR bytes), ``close()``, and optionally
``step(stamp_ns, world)`` once per odometry publish.  A tap whose package, file or port is
missing, or that fails while writing, is reported once and the simulator runs without it.
"""

import importlib

from sim_diffdrive.parameters import Spec

TAP_PARAMETERS = (
    Spec('record_file', '',
         'Record cmd_vel, odom, /tf, /clock and path (with map_file also map, scan and '
         '/tf_static) to this MCAP file (ROS 2 encoding: cdr messages, ros2msg schemas; ros2 '
         'bag and Foxglove open it), closed with its index on Ctrl-C and SIGTERM; empty = off. '
         'Needs the mcap package.'),
    Spec('foxglove_port', 0,
         'Serve the run live to Foxglove (its WebSocket protocol) on this port, e.g. '
         "8765, Foxglove's usual one; 0 = off. Needs foxglove-sdk.",
         low=0, high=65535),
    Spec('view_port', 0,
         'Serve a live view of every robot (pose, path, commanded and achieved speeds) to a '
         'web browser on this port of 127.0.0.1 (the simulator logs the address to open), '
         'e.g. 9090; 0 = off. Needs rerun-sdk.',
         low=0, high=65535),
)


class Taps:
    """The simulator's taps; false when there are none, so the hot path costs one check."""

    def __init__(self, node, taps):
        self._node = node
        self._taps = list(taps)

    @property
    def wants_path(self):
        return any(tap.wants_path for tap in self._taps)

    def __bool__(self):
        return bool(self._taps)

    def named(self, name):
        """Return the tap called name (its parameter, e.g. 'view_port'), or None."""
        return next((tap for tap in self._taps if tap.name == name), None)

    def write(self, topic, msg, stamp_ns):
        for tap in list(self._taps):
            self._call(tap, tap.write, topic, msg, stamp_ns)

    def _call(self, tap, method, *args):
        try:
            method(*args)
        except Exception as error:  # whatever a file or a socket raises: report, go on
            self._node.get_logger().error(
                f'{tap.name}: {type(error).__name__}: {error}; stopped writing to it, the '
                'simulation goes on')
            self._taps.remove(tap)
            self._close(tap)

    def step(self, stamp_ns, world):
        """Hand every tap that draws the whole world its state at stamp_ns."""
        for tap in list(self._taps):
            if hasattr(tap, 'step'):
                self._call(tap, tap.step, stamp_ns, world)

    def close(self):
        """Close every tap (idempotent)."""
        taps, self._taps = self._taps, []
        for tap in taps:
            self._close(tap)

    def _close(self, tap):
        try:
            tap.close()
        except Exception as error:  # closing must not stop the others from closing
            self._node.get_logger().error(f'{tap.name}: closing failed: {error}')


# Each tap's parameter, the package it needs, its module and class (imported only when asked).
_TAPS = (
    ('record_file', 'mcap', 'recorder', 'McapRecorder'),
    ('foxglove_port', 'foxglove-sdk', 'foxglove_live', 'FoxgloveLive'),
    ('view_port', 'rerun-sdk', 'view', 'BrowserView'),
)


def open_taps(node):
    """Return the Taps node.params ask for (record_file, foxglove_port, view_port)."""
    taps = []
    for parameter, package, module, name in _TAPS:
        value = getattr(node.params, parameter)
        try:
            if value:
                tap_class = getattr(importlib.import_module(f'sim_diffdrive.taps.{module}'), name)
                taps.append(tap_class(value, node))
        except ImportError as error:
            node.get_logger().error(
                f'{parameter} needs the Python package {package} ({error}); pip install '
                f'{package}. Running without it.')
        except OSError as error:
            node.get_logger().error(f'{parameter}: {error}. Running without it.')
    return Taps(node, taps)
