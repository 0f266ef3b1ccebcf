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
record_file: the simulator's traffic as an MCAP file that ROS 2 tools and Foxglove open.

In process: every message decodes with rclpy, the last odometry in the file is the last one
seen live, the commands are the ones sent, the summary counts the messages, and a generic ROS 2
reader (mcap_ros2) understands the ros2msg schemas.  As a process: the file is complete after
SIGTERM.  And when the file cannot be written (no such directory, a full disk) the simulator
says so once and runs on.
"""

import errno
import functools
import os
from pathlib import Path as FilePath
import signal

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from nav_msgs.msg import Path
import pytest
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock
from sim_diffdrive.harness import ros_params
from sim_diffdrive.harness import start
from sim_diffdrive.harness import stop
from sim_diffdrive.taps.msg_definitions import message_definition
from sim_diffdrive.taps.msg_definitions import SEPARATOR
from tf2_msgs.msg import TFMessage

# Optional dependencies (pip install mcap mcap-ros2-support): without them, skipped.
mcap_reader = pytest.importorskip('mcap.reader')
recorder = pytest.importorskip('sim_diffdrive.taps.recorder')

ROOM = str(FilePath(__file__).resolve().parents[1] / 'maps' / 'room.yaml')
TYPES = {'/cmd_vel': Twist, '/odom': Odometry, '/tf': TFMessage, '/clock': Clock, '/path': Path}
COMMANDS = [(0.4, 0.0), (0.3, 0.5), (0.0, -0.8)]


def read(path):
    """Return (summary, [(topic, schema name, log_time, message)]) of an MCAP file."""
    with open(path, 'rb') as stream:
        reader = mcap_reader.make_reader(stream)
        summary = reader.get_summary()
        messages = [(channel.topic, schema.name, message.log_time,
                     deserialize_message(message.data, TYPES[channel.topic]))
                    for schema, channel, message in reader.iter_messages(log_time_order=False)]
    return summary, messages


def of(messages, topic):
    return [msg for t, _, _, msg in messages if t == topic]


def stamp_ns(msg):
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def test_the_definition_is_the_msg_text_then_each_dependency_once():
    text = message_definition('nav_msgs/msg/Odometry')
    assert text.startswith('# This represents an estimate of a position and velocity')
    parts = text.split(f'\n{SEPARATOR}\nMSG: ')
    names = [part.partition('\n')[0] for part in parts[1:]]
    assert len(names) == len(set(names))
    assert {'std_msgs/Header', 'builtin_interfaces/Time', 'geometry_msgs/PoseWithCovariance',
            'geometry_msgs/Pose', 'geometry_msgs/Point', 'geometry_msgs/Quaternion',
            'geometry_msgs/TwistWithCovariance', 'geometry_msgs/Twist',
            'geometry_msgs/Vector3'} == set(names)


def test_a_run_is_recorded_as_it_went_out(graph, tmp_path, capfd):
    path = tmp_path / 'run.mcap'
    sim = graph.sim(record_file=str(path), cmd_vel_timeout=0.0)
    probe = graph.probe()
    for linear, angular in COMMANDS:
        probe.send(linear, angular)
        graph.step_for(1.0)
    graph.spin_for(0.3)  # the clock stands still: the odometry of the last step arrives
    live = graph.odom()
    graph.remove(sim)
    sim.destroy_node()  # a second close does nothing

    summary, messages = read(path)
    channels = {c.topic: c for c in summary.channels.values()}
    assert set(channels) == set(TYPES)
    assert {c.message_encoding for c in channels.values()} == {'cdr'}
    schemas = {channels[t].topic: summary.schemas[channels[t].schema_id] for t in channels}
    assert {s.encoding for s in schemas.values()} == {'ros2msg'}
    assert schemas['/odom'].name == 'nav_msgs/msg/Odometry'
    assert schemas['/tf'].name == 'tf2_msgs/msg/TFMessage'
    assert schemas['/odom'].data.decode() == message_definition('nav_msgs/msg/Odometry')

    odoms = of(messages, '/odom')
    last = odoms[-1]
    assert stamp_ns(last) == stamp_ns(live)
    assert last.pose.pose == live.pose.pose and last.twist.twist == live.twist.twist
    assert live.pose.pose.position.x > 0.5  # it did drive
    assert [(c.linear.x, c.angular.z) for c in of(messages, '/cmd_vel')] == COMMANDS
    # Sim time: log time is the header stamp; the path ends at the pose it was built from.
    assert all(t == stamp_ns(m) for topic, _, t, m in messages if topic == '/odom')
    assert of(messages, '/path')[-1].poses[-1].pose.position.x > 0.0
    assert of(messages, '/tf')[-1].transforms[0].transform.translation.x == (
        last.pose.pose.position.x)

    stats = summary.statistics
    assert stats.message_count == len(messages)
    counts = {channels[t].id: len(of(messages, t)) for t in channels}
    assert dict(stats.channel_message_counts) == counts
    assert stats.message_end_time == stamp_ns(live)

    output = capfd.readouterr().err
    assert output.count('(MCAP)') == 1 and output.count(f'Wrote {len(messages)} messages') == 1


def test_a_generic_ros2_reader_decodes_every_message(graph, tmp_path):
    decoder = pytest.importorskip('mcap_ros2.decoder')
    path = tmp_path / 'run.mcap'
    sim = graph.sim(record_file=str(path), cmd_vel_timeout=0.0)
    graph.probe().send(0.5, 0.5)
    graph.step_for(1.5)
    graph.remove(sim)
    with open(path, 'rb') as stream:
        reader = mcap_reader.make_reader(stream, decoder_factories=[decoder.DecoderFactory()])
        decoded = {}
        for _, channel, _, msg in reader.iter_decoded_messages():
            decoded.setdefault(channel.topic, []).append(msg)
    assert set(decoded) == set(TYPES)
    odom = decoded['/odom'][-1]
    assert odom.header.frame_id == 'odom' and odom.pose.pose.position.x > 0.0
    assert decoded['/cmd_vel'][0].linear.x == 0.5
    assert decoded['/tf'][-1].transforms[0].child_frame_id == odom.child_frame_id


def test_a_run_in_a_map_records_the_map_and_the_scans(graph, tmp_path):
    decoder = pytest.importorskip('mcap_ros2.decoder')
    path = tmp_path / 'run.mcap'
    sim = graph.sim(map_file=ROOM, record_file=str(path))
    graph.step_for(0.5)
    graph.remove(sim)
    with open(path, 'rb') as stream:
        reader = mcap_reader.make_reader(stream, decoder_factories=[decoder.DecoderFactory()])
        schemas = {channel.topic: (schema.name, schema.encoding)
                   for schema, channel, _ in reader.iter_messages(log_time_order=False)}
        stream.seek(0)
        reader = mcap_reader.make_reader(stream, decoder_factories=[decoder.DecoderFactory()])
        decoded = {}
        for _, channel, _, msg in reader.iter_decoded_messages():
            decoded.setdefault(channel.topic, []).append(msg)
    assert schemas['/scan'] == ('sensor_msgs/msg/LaserScan', 'ros2msg')
    assert schemas['/map'] == ('nav_msgs/msg/OccupancyGrid', 'ros2msg')
    assert schemas['/tf_static'] == ('tf2_msgs/msg/TFMessage', 'ros2msg')
    scan = decoded['/scan'][-1]
    assert len(scan.ranges) == 360 and scan.header.frame_id == 'base_scan'
    (room,) = decoded['/map']
    assert (room.info.width, room.info.height) == (80, 60) and len(room.data) == 80 * 60
    assert room.header.frame_id == 'map'
    assert decoded['/tf_static'][0].transforms[0].child_frame_id == 'base_scan'


def test_the_file_is_complete_after_the_process_is_stopped(graph, tmp_path):
    # SIGTERM, as a launch file or a service manager stops it.  Ctrl-C takes the same path
    # (runtime.run handles both signals alike; test_sim_process.py ends a simulator with it).
    signum = signal.SIGTERM
    path = tmp_path / 'run.mcap'
    sim = start('unicycle_sim', *ros_params(f'record_file:={path}', 'cmd_vel_timeout:=0.0'))
    try:
        graph.wait_for_odometry(process=sim)
        probe = graph.probe('commander', use_sim_time=False)
        graph.spin_until(lambda: sim_hears(graph, probe), 10.0)
        probe.send(0.3, 0.3)
        graph.spin_for(0.5)
    finally:
        output = stop(sim, signum)
    assert sim.returncode == 0, output
    summary, messages = read(path)
    assert summary is not None and summary.statistics.message_count == len(messages) > 0
    assert of(messages, '/odom')[-1].twist.twist.linear.x == 0.3
    assert output.count('Wrote ') == 1, output


def sim_hears(graph, probe):
    return probe.cmd_pub.get_subscription_count() > 0


@pytest.mark.parametrize('where, why', [
    ('missing/run.mcap', 'No such file or directory'),
    pytest.param('/dev/full', 'No space left on device', marks=pytest.mark.skipif(
        not os.access('/dev/full', os.W_OK), reason='no writable /dev/full')),
], ids=['no-such-directory', 'full-disk-at-start'])
def test_a_file_that_cannot_be_written_is_said_once_and_the_run_goes_on(
        graph, tmp_path, capfd, where, why):
    # In process: the simulator opens its file as it starts, the same in an executable.
    path = tmp_path / where  # an absolute where (/dev/full) stays as it is
    sim = graph.sim(record_file=str(path))
    graph.step_for(0.2)
    assert not sim.taps  # none to write
    seen = len(graph.odometry.odoms)
    graph.step_for(1.0)
    assert len(graph.odometry.odoms) >= seen + 40
    graph.remove(sim)
    output = capfd.readouterr().err
    assert output.count('record_file') == 1, output
    assert why in output and 'Running without it' in output
    assert not (tmp_path / 'missing').exists()


class FillingFile:
    """A file that takes the header, then fails like a full disk."""

    def __init__(self, path):
        self._file = open(path, 'wb')
        self.flushed = False

    def write(self, data):
        if self.flushed:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return self._file.write(data)

    def flush(self):
        self._file.flush()
        self.flushed = True

    def tell(self):
        return self._file.tell()

    def close(self):
        self._file.close()


def test_a_full_disk_during_the_run_is_said_once_and_the_run_goes_on(
        graph, tmp_path, monkeypatch, capfd):
    # Small chunks, so the failing write comes within the run rather than at close().
    monkeypatch.setattr(recorder, 'open', lambda path, mode='r', **kwargs: FillingFile(path)
                        if mode == 'wb' else open(path, mode, **kwargs), raising=False)
    monkeypatch.setattr(recorder, 'Writer', functools.partial(recorder.Writer, chunk_size=512))
    sim = graph.sim(record_file=str(tmp_path / 'run.mcap'))
    graph.step_for(1.0)
    assert not sim.taps  # dropped
    seen = len(graph.odometry.odoms)
    graph.step_for(1.0)
    assert len(graph.odometry.odoms) >= seen + 40
    graph.remove(sim)
    output = capfd.readouterr().err
    assert output.count('No space left on device') == 1, output
    assert output.count('record_file') == 1, output
    assert 'stopped writing to it, the simulation goes on' in output
    assert 'Wrote' not in output
