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
The record_file tap: the simulator's traffic as an MCAP file in the ROS 2 encoding.

Messages are CDR (``rclpy.serialization.serialize_message``, byte for byte what went out on
DDS); each type's schema is its full ``ros2msg`` definition as rosbag2 writes it: the type's
.msg text, then for each type it uses (depth first, once each) a line of 80 '=', ``MSG:
pkg/Type`` and that type's .msg text, read from the ament index.  So Foxglove, ``ros2 bag
info/play`` and any generic ROS 2 MCAP reader open the file without this package.

The file is chunked (zstd) and finished with its summary (schemas, channels, message counts,
chunk index) by ``close()``, which the simulator calls on every exit path (Ctrl-C, SIGTERM,
the node destroyed).  A file cut off before that (kill -9) still reads up to its last chunk,
but without the index that ``ros2 bag`` needs.
"""

import contextlib
import os
import re
import signal
import threading

from ament_index_python.packages import get_package_share_directory
from ament_index_python.packages import PackageNotFoundError
from mcap.well_known import MessageEncoding
from mcap.well_known import SchemaEncoding
from mcap.writer import Writer
from rclpy.serialization import serialize_message

SEPARATOR = '=' * 80
# A field's type at the start of a line of a .msg ('geometry_msgs/Pose[] poses'): the pattern
# rosbag2's LocalMessageDefinitionSource uses, so the dependencies come out in the same order.
_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
_PRIMITIVES = frozenset((
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16', 'int32',
    'uint32', 'int64', 'uint64', 'string'))
_LIBRARY = 'motion_challenges unicycle_sim'
_SIGNALS = {signal.SIGINT, signal.SIGTERM}


def type_name(message_class):
    """Return a message class's ROS 2 type name, e.g. 'nav_msgs/msg/Odometry'."""
    package = message_class.__module__.partition('.')[0]
    return f'{package}/msg/{message_class.__name__}'


def message_definition(name):
    """
    Return the full ros2msg definition of type name ('pkg/msg/Type' or 'pkg/Type').

    Raises LookupError when a .msg file is not in the ament index.
    """
    seen = set()

    def with_dependencies(name):
        text = _msg_text(name)
        package = name.partition('/')[0]
        for dependency in sorted(_dependencies(text, package)):
            if dependency not in seen:
                seen.add(dependency)
                text += f'\n{SEPARATOR}\nMSG: {dependency}\n' + with_dependencies(dependency)
        return text

    return with_dependencies(name)


def _dependencies(text, package):
    found = set()
    for match in _FIELD_TYPE.finditer(text):
        field_type = match.group(1)
        if field_type in _PRIMITIVES:
            continue
        found.add(field_type if '/' in field_type else f'{package}/{field_type}')
    return found


def _msg_text(name):
    parts = name.split('/')
    package, kind, type_ = (parts[0], 'msg', parts[1]) if len(parts) == 2 else parts
    try:
        path = os.path.join(get_package_share_directory(package), kind, f'{type_}.msg')
        with open(path, encoding='utf-8', newline='') as msg_file:
            return msg_file.read()
    except (PackageNotFoundError, OSError) as error:
        raise LookupError(f'no .msg definition of {name} in the ament index ({error})')


class McapRecorder:
    """
    A tap (see taps.py) writing every message it is given to an MCAP file.

    log_time and publish_time of each message are ``stamp_ns``, the simulated time the
    simulator stamped it with, not the wall time it was written at (rosbag2 logs receive time):
    a run recorded at 50x real time then plays back (``ros2 bag play``, Foxglove) at the pace
    of simulated time, and lines up with the messages' header stamps.  Without publish_clock
    the simulator's time is wall time, and so are the log times.
    """

    wants_path = True

    def __init__(self, path, node):
        """Open path for writing (OSError if it cannot be, e.g. no such directory)."""
        self.path = os.fspath(path)
        self.name = f'record_file {self.path}'
        self._logger = node.get_logger()
        self._closed = False
        self._failed = False
        self._count = 0
        self._schemas = {}  # type name -> schema id
        self._channels = {}  # (topic, message class) -> channel id
        self._file = open(self.path, 'wb')
        try:
            self._writer = Writer(self._file)
            self._writer.start(profile='ros2', library=_LIBRARY)
            # A disk that cannot take even the header (full, /dev/full) says so now, not a
            # megabyte of messages later.
            self._file.flush()
        except OSError as error:
            self._abandon()
            raise OSError(error.errno, error.strerror, self.path) from error
        except BaseException:
            self._abandon()
            raise
        self._logger.info(f'Recording to {os.path.abspath(self.path)} (MCAP)')

    @property
    def message_count(self):
        return self._count

    def write(self, topic, msg, stamp_ns):
        """Append msg on topic at simulated time stamp_ns (registering its channel once)."""
        if self._closed:
            return
        try:
            key = (topic, type(msg))
            channel = self._channels.get(key)
            if channel is None:
                channel = self._channels[key] = self._writer.register_channel(
                    topic=topic, message_encoding=MessageEncoding.CDR,
                    schema_id=self._schema(type(msg)))
            self._writer.add_message(channel_id=channel, log_time=stamp_ns,
                                     publish_time=stamp_ns, sequence=self._count,
                                     data=serialize_message(msg))
        except BaseException:
            # The caller reports the error and drops this tap; close() then only lets go.
            self._failed = True
            raise
        self._count += 1

    def close(self):
        """Write the summary and index and close the file (idempotent)."""
        if self._closed:
            return
        self._closed = True
        if self._failed:
            self._abandon()
            return
        with _signals_held():
            # A second Ctrl-C must not cut the index off halfway; it counts once this is done.
            try:
                self._writer.finish()
            except BaseException:
                self._abandon()
                raise
            self._file.close()
            self._logger.info(
                f'Wrote {self._count} messages to {os.path.abspath(self.path)}')

    def _schema(self, message_class):
        name = type_name(message_class)
        if name not in self._schemas:
            try:
                encoding, data = SchemaEncoding.ROS2, message_definition(name).encode()
            except LookupError as error:
                # As rosbag2 does: record the messages all the same, without a definition.
                self._logger.warning(f'{self.name}: {error}; {name} recorded without one')
                encoding, data = 'unknown', b''
            self._schemas[name] = self._writer.register_schema(name, encoding, data)
        return self._schemas[name]

    def _abandon(self):
        """Close the file without writing more (what a failed write left stays as it is)."""
        try:
            self._file.close()
        except OSError:
            pass  # the buffered bytes cannot be written either: already reported


@contextlib.contextmanager
def _signals_held():
    """Hold SIGINT and SIGTERM back (delivered at the end) where the platform allows it."""
    previous = None
    main = threading.current_thread() is threading.main_thread()
    if main and hasattr(signal, 'pthread_sigmask'):
        previous = signal.pthread_sigmask(signal.SIG_BLOCK, _SIGNALS)
    try:
        yield
    finally:
        if previous is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, previous)
