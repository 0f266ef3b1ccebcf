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
foxglove_port: the run, live over Foxglove's WebSocket protocol, as the Foxglove app sees it.

A client written here from the protocol (the websockets package) connects as Foxglove does,
reads the server's channels, subscribes and decodes what arrives; the simulator runs in this
process, stepped, so the messages can be counted exactly, or as the unicycle_sim executable.
Without foxglove-sdk, or on a port already taken, the simulator says why and runs without it.
"""

import json
import socket
import struct
import time

from nav_msgs.msg import Odometry
import pytest
from rclpy.serialization import deserialize_message
from sim_diffdrive import harness
from sim_diffdrive.taps.msg_definitions import message_definition
from sim_diffdrive.taps.view_page import free_port

pytest.importorskip('foxglove')
sync_client = pytest.importorskip('websockets.sync.client')

# foxglove-sdk 0.30 speaks foxglove.sdk.v1; the Foxglove app offers it and the older name.
SUBPROTOCOLS = ['foxglove.sdk.v1', 'foxglove.websocket.v1']
MESSAGE_DATA = 0x01  # opcode, then subscription id (u32), log time (u64), payload
TIME = 0x02  # opcode, then the server's time (u64)
STEP_NS = 20_000_000  # at rate_hz 50


class FoxgloveClient:
    """The part of a Foxglove app that matters here: channels, subscriptions, messages."""

    def __init__(self, port, timeout=10.0):
        deadline = time.monotonic() + timeout
        while True:  # a simulator process may not listen yet
            try:
                self.ws = sync_client.connect(f'ws://localhost:{port}', subprotocols=SUBPROTOCOLS,
                                              open_timeout=timeout, legacy=True)
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.1)
        self.server_info = json.loads(self.ws.recv(timeout=timeout))
        self.channels = {}  # topic -> advertised channel
        self.times = []  # the server's time broadcasts
        self._subscriptions = {}  # subscription id -> topic

    def receive(self, timeout=1.0):
        """Handle one frame; return (topic, log_time, payload) for message data, else None."""
        frame = self.ws.recv(timeout=timeout)
        if isinstance(frame, str):
            op = json.loads(frame)
            if op['op'] == 'advertise':
                self.channels.update((channel['topic'], channel) for channel in op['channels'])
            elif op['op'] == 'unadvertise':
                gone = set(op['channelIds'])
                self.channels = {topic: channel for topic, channel in self.channels.items()
                                 if channel['id'] not in gone}
            return None
        if frame[0] == TIME:
            self.times.append(struct.unpack_from('<Q', frame, 1)[0])
            return None
        assert frame[0] == MESSAGE_DATA, frame[:1]
        subscription, log_time = struct.unpack_from('<IQ', frame, 1)
        return self._subscriptions[subscription], log_time, frame[13:]

    def wait_for_channels(self, *topics, timeout=10.0):
        deadline = time.monotonic() + timeout
        while not set(topics) <= set(self.channels):
            assert time.monotonic() < deadline, f'advertised: {sorted(self.channels)}'
            try:
                self.receive(timeout=0.1)
            except TimeoutError:
                pass

    def subscribe(self, topic):
        sub_id = len(self._subscriptions) + 1
        self._subscriptions[sub_id] = topic
        self.ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [
            {'id': sub_id, 'channelId': self.channels[topic]['id']}]}))

    def messages(self, timeout=0.5):
        """Return the messages that arrive until none has for timeout seconds."""
        received = []
        while True:
            try:
                message = self.receive(timeout)
            except TimeoutError:
                return received
            if message is not None:
                received.append(message)

    def next_message(self, timeout=1.0):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            message = self.receive(timeout)
            if message is not None:
                return message
        raise TimeoutError

    def close(self):
        self.ws.close()


@pytest.fixture
def client_for():
    clients = []

    def connect(port):
        clients.append(FoxgloveClient(port))
        return clients[-1]

    yield connect
    for client in clients:
        client.close()


def first_message(graph, client, steps=50):
    """Step until the server delivers on the new subscription; return that message."""
    for _ in range(steps):
        graph.step()
        try:
            return client.next_message(timeout=0.2)
        except TimeoutError:
            pass
    pytest.fail(f'nothing on the subscription after {steps} steps')


def test_advertises_the_topics_as_ros2_cdr_and_the_robot(graph, client_for):
    port = free_port()
    graph.sim(foxglove_port=port, rate_hz=50.0)
    client = client_for(port)
    assert client.server_info['op'] == 'serverInfo'
    assert 'time' in client.server_info['capabilities']
    graph.step()
    client.wait_for_channels('/odom', '/tf', '/clock', '/path', '/foxglove/robot')
    odom = client.channels['/odom']
    assert (odom['encoding'], odom['schemaName'], odom['schemaEncoding']) == (
        'cdr', 'nav_msgs/msg/Odometry', 'ros2msg')
    assert odom['schema'] == message_definition('nav_msgs/msg/Odometry')
    assert client.channels['/tf']['schemaName'] == 'tf2_msgs/msg/TFMessage'
    assert client.channels['/foxglove/robot']['schemaName'] == 'foxglove.SceneUpdate'
    # The simulator publishes /tf: no second transform from Foxglove's side.
    assert '/foxglove/odom_transform' not in client.channels


def test_one_odometry_message_per_step_equal_to_the_published_one(graph, client_for):
    port = free_port()
    graph.sim(foxglove_port=port, rate_hz=50.0)
    probe = graph.probe(name='driver')
    client = client_for(port)
    graph.step()
    client.wait_for_channels('/odom')
    client.subscribe('/odom')
    first_message(graph, client)
    probe.send(0.5, 0.4)
    start_ns = graph.now_ns
    graph.step(100)
    # The steps from here on.  A busy machine can deliver the message of a step taken while
    # waiting for the first one after that wait gave up (101 came once, beside a busy loop).
    received = [message for message in client.messages() if message[1] > start_ns]
    assert len(received) == 100
    assert {topic for topic, _, _ in received} == {'/odom'}
    stamps = [log_time for _, log_time, _ in received]
    assert [b - a for a, b in zip(stamps, stamps[1:])] == [STEP_NS] * 99
    last = deserialize_message(received[-1][2], Odometry)
    assert last == graph.odom()
    # Driving until the command timed out (0.5 s): the robot moved, as the messages show.
    assert deserialize_message(received[10][2], Odometry).twist.twist.linear.x > 0.0
    assert last.pose.pose.position.x > 0.0
    assert stamps[-1] == last.header.stamp.sec * 1_000_000_000 + last.header.stamp.nanosec
    assert client.times[-1] == stamps[-1]  # the server's time is simulated time
    client.wait_for_channels('/cmd_vel')
    assert client.channels['/cmd_vel']['schemaName'] == 'geometry_msgs/msg/Twist'


def test_the_schema_decodes_the_bytes_without_ros(graph, client_for):
    decoder = pytest.importorskip('mcap_ros2.decoder')
    records = pytest.importorskip('mcap.records')
    port = free_port()
    graph.sim(foxglove_port=port, rate_hz=50.0)
    client = client_for(port)
    graph.step()
    client.wait_for_channels('/odom', '/path')
    client.subscribe('/path')
    topic, _, payload = first_message(graph, client)
    channel = client.channels[topic]
    schema = records.Schema(id=1, name=channel['schemaName'], encoding='ros2msg',
                            data=channel['schema'].encode())
    path = decoder.DecoderFactory().decoder_for('cdr', schema)(payload)
    assert path.header.frame_id == 'odom'
    assert path.poses[-1].header.frame_id == 'odom'


def test_draws_the_robot_and_its_transform_without_tf(graph, client_for):
    port = free_port()
    graph.sim(foxglove_port=port, rate_hz=50.0, publish_tf=False)
    client = client_for(port)
    graph.step()
    client.wait_for_channels('/foxglove/robot', '/foxglove/odom_transform')
    assert '/tf' not in client.channels
    client.subscribe('/foxglove/robot')
    client.subscribe('/foxglove/odom_transform')
    first_message(graph, client)
    graph.step(5)
    by_topic = {}
    for topic, _, payload in client.messages():
        by_topic.setdefault(topic, []).append(payload)
    # The transform with every step; the scene once, then once a wall second.
    assert len(by_topic['/foxglove/odom_transform']) >= 5
    assert len(by_topic.get('/foxglove/robot', [])) <= 1
    assert b'base_footprint' in by_topic['/foxglove/odom_transform'][-1]


def test_draws_every_robot_of_a_fleet_once(graph, client_for):
    port = free_port()
    graph.sim(foxglove_port=port, robots=['r1', 'r2'])
    client = client_for(port)
    graph.step()
    client.wait_for_channels('/foxglove/robot', '/r1/odom', '/r2/odom')
    client.subscribe('/foxglove/robot')
    scenes = [first_message(graph, client)[2]]
    graph.step(5)
    scenes += [payload for topic, _, payload in client.messages() if topic == '/foxglove/robot']
    # One entity per robot (its id is its frame, so neither replaces the other), then quiet.
    assert len(scenes) == 2
    assert {b'r1/base_footprint' in scenes[0], b'r1/base_footprint' in scenes[1]} == {
        True, False}
    assert any(b'r2/base_footprint' in scene for scene in scenes)


# In process, the two ways the server cannot start: the simulator opens it as it starts, the
# same in the executable.
def test_a_port_in_use_is_reported_and_the_simulator_runs(graph, capfd):
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        sim = graph.sim(foxglove_port=port)
        graph.step_for(1.0)
    assert not sim.taps
    assert len(graph.odometry.odoms) >= 50  # it runs on
    output = capfd.readouterr().err
    assert f'foxglove_port: cannot serve Foxglove on 127.0.0.1:{port}' in output, output
    assert 'Address already in use' in output and 'Running without it.' in output


def test_unicycle_sim_serves_odometry_at_its_rate(procs, client_for):
    port = free_port()
    sim = procs('unicycle_sim', 'unicycle_sim', *harness.ros_params(
        f'foxglove_port:={port}', 'publish_clock:=true', 'rate_hz:=50.0'))
    assert wait_for_line(sim, f'Foxglove: ws://localhost:{port} (Open connection in Foxglove)')
    # Connected while the server advertises a new channel, a client may be refused it
    # ('unknown channel', foxglove-sdk 0.30.3): connect once the simulator runs.
    assert wait_for_line(sim, 'Unicycle at'), sim.describe()
    time.sleep(0.5)
    client = client_for(port)
    client.wait_for_channels('/odom')
    client.subscribe('/odom')
    stamps = []
    try:
        while len(stamps) < 120:
            stamps.append(client.next_message(timeout=5.0)[1])
    except TimeoutError:
        pytest.fail(f'{len(stamps)} messages, then none for 5 s:\n{sim.describe()}')
    # One message per 20 ms of simulated time, none lost: 50 in any simulated second.  (How
    # fast a freewheeling simulator runs on the wall clock is the bench's to say, not a test's.)
    assert sum(1 for t in stamps if stamps[10] <= t < stamps[10] + 1_000_000_000) == 50
    client.close()
    output = harness.stop(sim)
    assert 'Traceback' not in output
    assert f'Foxglove: ws://localhost:{port} closed' in output


def wait_for_line(process, text, timeout=20.0):
    deadline = time.monotonic() + timeout
    while text not in process.output():
        if time.monotonic() > deadline or process.poll() is not None:
            return False
        time.sleep(0.05)
    return True
