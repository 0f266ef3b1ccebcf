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

Messages are the CDR that went out on DDS, with rosbag2's ``ros2msg`` schemas.  A file cut off
before ``close()`` (kill -9) still reads up to its last chunk, without the index.
"""

import contextlib
import os
import signal
import threading

from mcap.well_known import MessageEncoding
from mcap.well_known import SchemaEncoding
from mcap.writer import Writer
from rclpy.serialization import serialize_message
from sim_diffdrive.taps.msg_definitions import message_class
from sim_diffdrive.taps.msg_definitions import message_definition
from sim_diffdrive.taps.msg_definitions import type_name

_LIBRARY = 'motion_challenges unicycle_sim'
_SIGNALS = {signal.SIGINT, signal.SIGTERM}


class McapRecorder:
    """
    A tap writing every message it is given to an MCAP file.

    log_time and publish_time are ``stamp_ns``, simulated time (rosbag2 logs receive time): a
    run recorded at 50x real time plays back at the pace of its header stamps.
    """

    wants_path = True

    def __init__(self, path, node):
        """Open path for writing (OSError if it cannot be, e.g. no such directory)."""
        self.path = os.fspath(path)
        self.name = f'record_file {self.path}'
        self._node = node
        self._logger = node.get_logger()
        self._closed = self._failed = False
        self._count = 0
        self._schemas = {}  # type name -> schema id
        self._channels = {}  # (topic, message class) -> channel id
        self._types = {}  # topic -> message class of the bytes given on it
        self._file = open(self.path, 'wb')
        try:
            self._writer = Writer(self._file)
            self._writer.start(profile='ros2', library=_LIBRARY)
            # A disk that cannot take even the header says so now, not messages later.
            self._file.flush()
        except OSError as error:
            self._abandon()
            raise OSError(error.errno, error.strerror, self.path) from error
        except BaseException:
            self._abandon()
            raise
        self._logger.info(f'Recording to {os.path.abspath(self.path)} (MCAP)')

    def write(self, topic, msg, stamp_ns):
        """Append msg (a message or its CDR bytes) on topic at simulated time stamp_ns."""
        if self._closed:
            return
        try:
            msg_class = message_class(self._node, topic, msg, self._types)
            key = (topic, msg_class)
            channel = self._channels.get(key)
            if channel is None:
                channel = self._channels[key] = self._writer.register_channel(
                    topic=topic, message_encoding=MessageEncoding.CDR,
                    schema_id=self._schema(msg_class))
            data = msg if isinstance(msg, bytes) else serialize_message(msg)
            self._writer.add_message(channel_id=channel, log_time=stamp_ns,
                                     publish_time=stamp_ns, sequence=self._count, data=data)
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
            self._logger.info(f'Wrote {self._count} messages to {os.path.abspath(self.path)}')

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
        with contextlib.suppress(OSError):  # the buffered bytes cannot be written either
            self._file.close()


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
