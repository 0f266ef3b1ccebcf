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
The simulator's run, live in Foxglove: a WebSocket server (foxglove-sdk) fed by the taps.

Messages go out as CDR with rosbag2's ``ros2msg`` schemas; ``/foxglove/robot`` draws the robot
and, without /tf, ``/foxglove/odom_transform`` carries the odometry.  The server has no
authentication, so it listens on 127.0.0.1 only.
"""

from nav_msgs.msg import Odometry
from nav_msgs.msg import Path
from rclpy.serialization import serialize_message
from sim_diffdrive.cdr import read_odometry
from sim_diffdrive.taps.msg_definitions import message_class
from sim_diffdrive.taps.msg_definitions import message_definition
from sim_diffdrive.taps.msg_definitions import type_name
from sim_diffdrive.throttle import Throttle

DEFAULT_HOST = '127.0.0.1'
SCENE_TOPIC = '/foxglove/robot'
TRANSFORM_TOPIC = '/foxglove/odom_transform'
# Wall seconds between two paths, and between two scene updates, sent to Foxglove.
PATH_PERIOD_S = 0.5
SCENE_PERIOD_S = 1.0
# The robot as drawn in base_footprint: a box on the ground and an arrow along +x [m].
BODY_SIZE = (0.30, 0.25, 0.12)
ARROW_LENGTH = 0.40
_NS = 1_000_000_000


class FoxgloveLive:
    """A tap serving the run to Foxglove over WebSocket on one port."""

    name = 'foxglove_port'
    wants_path = True

    def __init__(self, port, node, host=DEFAULT_HOST):
        """Start the server on host:port (0: any, see ``port``); ImportError, OSError."""
        import foxglove
        from foxglove import channels
        from foxglove import messages
        from foxglove.websocket import Capability
        self._foxglove = foxglove
        self._messages = messages
        self._node = node
        self._context = foxglove.Context()
        try:
            self._server = foxglove.start_server(
                name=node.get_fully_qualified_name(), host=host, port=port,
                capabilities=[Capability.Time], context=self._context)
        except RuntimeError as error:  # FoxgloveError: Failed to bind port: Address in use
            raise OSError(f'cannot serve Foxglove on {host}:{port}: {error}') from error
        self.port = self._server.port
        self.url = f"ws://{'localhost' if host == DEFAULT_HOST else host}:{self.port}"
        self._channels = {}  # ROS topic -> Channel carrying CDR
        self._types = {}  # ROS topic -> message class of the bytes given on it
        self._scene = channels.SceneUpdateChannel(SCENE_TOPIC, context=self._context)
        self._transforms = None if node.params.publish_tf else channels.FrameTransformsChannel(
            TRANSFORM_TOPIC, context=self._context)
        self._scene_throttle = Throttle(SCENE_PERIOD_S)  # each robot's scene entity, by frame
        self._path_throttle = Throttle(PATH_PERIOD_S)
        node.get_logger().info(f'Foxglove: {self.url} (Open connection in Foxglove)')

    def write(self, topic, msg, stamp_ns):
        """Send msg (a message or its CDR bytes) on topic to subscribed clients."""
        if self._server is None:
            return
        msg_class = message_class(self._node, topic, msg, self._types)
        channel = self._channels.get(topic)
        if channel is None:
            name = type_name(msg_class)
            channel = self._channels[topic] = self._foxglove.Channel(
                topic, message_encoding='cdr', context=self._context, schema=self._foxglove.Schema(
                    name=name, encoding='ros2msg', data=message_definition(name).encode()))
        if msg_class is Odometry:  # the time, and what draws the robot
            self._server.broadcast_time(stamp_ns)
            self._write_robot(msg, stamp_ns)
        if not channel.has_sinks():
            return
        if msg_class is Path and not self._path_throttle.allows():  # the costliest message
            return
        channel.log(msg if isinstance(msg, bytes) else serialize_message(msg), log_time=stamp_ns)

    def close(self):
        """Stop the server (idempotent)."""
        server, self._server = self._server, None
        if server is not None:
            server.stop()
            self._node.get_logger().info(f'Foxglove: {self.url} closed')

    def _write_robot(self, odom, stamp_ns):
        """Draw the robot of odom (an Odometry or its bytes) for whoever watches."""
        m = self._messages
        transforms = self._transforms is not None and self._transforms.has_sinks()
        scene = self._scene.has_sinks()
        if not scene:
            self._scene_throttle.reset()  # a new subscriber gets every robot at once
            if not transforms:
                return  # nobody looks: the bytes need not be read
        frame, child_frame, p, q = _odometry_fields(odom)
        if transforms:
            self._transforms.log(m.FrameTransforms(transforms=[m.FrameTransform(
                timestamp=_timestamp(m, stamp_ns), parent_frame_id=frame,
                child_frame_id=child_frame, translation=m.Vector3(x=p[0], y=p[1], z=p[2]),
                rotation=m.Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]))]), log_time=stamp_ns)
        if scene and self._scene_throttle.allows(child_frame):
            self._scene.log(robot_scene(m, child_frame, stamp_ns), log_time=stamp_ns)


def _odometry_fields(odom):
    """Return (frame_id, child_frame_id, position, orientation) of an Odometry or its bytes."""
    if isinstance(odom, bytes):
        return read_odometry(odom)[1:5]
    p, q = odom.pose.pose.position, odom.pose.pose.orientation
    return (odom.header.frame_id, odom.child_frame_id, (p.x, p.y, p.z), (q.x, q.y, q.z, q.w))


def _timestamp(messages, stamp_ns):
    return messages.Timestamp(stamp_ns // _NS, stamp_ns % _NS)


def robot_scene(messages, frame, stamp_ns):
    """Return a SceneUpdate drawing the robot in frame: a box and an arrow along +x."""
    m = messages
    length, width, height = BODY_SIZE
    body = m.CubePrimitive(
        pose=m.Pose(position=m.Vector3(z=height / 2), orientation=m.Quaternion(w=1.0)),
        size=m.Vector3(x=length, y=width, z=height),
        color=m.Color(r=0.2, g=0.45, b=0.9, a=0.8))
    heading = m.ArrowPrimitive(
        pose=m.Pose(position=m.Vector3(z=height + 0.01), orientation=m.Quaternion(w=1.0)),
        shaft_length=ARROW_LENGTH * 0.7, shaft_diameter=0.04,
        head_length=ARROW_LENGTH * 0.3, head_diameter=0.09,
        color=m.Color(r=1.0, g=0.55, b=0.0, a=1.0))
    entity = m.SceneEntity(
        timestamp=_timestamp(m, stamp_ns), frame_id=frame, id=frame, frame_locked=True,
        cubes=[body], arrows=[heading])
    return m.SceneUpdate(entities=[entity])
