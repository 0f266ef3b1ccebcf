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
The simulator's odometry as a transform on ``/tf``, and the frame names both carry.

``/tf`` is global (absolute, whatever the node's namespace), so robots side by side tell their
frames apart by a prefix: the node's namespace without its leading slash, as tf2 and the
multi-robot setups of Nav2 and TurtleBot name them (``robot1/odom``).
"""

import struct

from geometry_msgs.msg import TransformStamped
import numpy as np
from rclpy.qos import QoSProfile
from tf2_msgs.msg import TFMessage

TF_TOPIC = '/tf'
# What tf2_ros's TransformBroadcaster uses (DynamicBroadcasterQoS): reliable, volatile, 100 deep.
TF_QOS = QoSProfile(depth=100)


def namespaced_frame(namespace, frame):
    """Return frame prefixed with namespace minus its leading slash ('/robot1' -> 'robot1/')."""
    prefix = namespace.strip('/')
    return f'{prefix}/{frame}' if prefix else frame


def resolve_frame(namespace, frame, default):
    """Return the frame a node in namespace uses: the default gets the prefix, others not."""
    return namespaced_frame(namespace, frame) if frame == default else frame


class OdomTransform:
    """
    Publish each robot's odometry as the transform header.frame_id -> child_frame_id on /tf.

    One TFMessage carries every robot's transform (as robot_state_publisher sends a robot's
    joints together).  With many robots, turning that message into bytes costs rclpy as much
    as publishing the odometry, so it is serialized here instead: the CDR bytes are laid out
    once (``set_frames()`` again when the frames change), and each publish writes the stamp and
    the poses into them with numpy.  ``message(...)`` fills the same TFMessage as an object,
    for the taps (a recording, Foxglove) and for a reader to compare.
    """

    def __init__(self, node, odoms):
        self.publisher = node.create_publisher(TFMessage, TF_TOPIC, TF_QOS)
        self._odoms = list(odoms)
        self._msg = TFMessage(transforms=[TransformStamped() for _ in self._odoms])
        self.set_frames()

    def set_frames(self):
        """Copy each odometry's frames into its transform and lay out the bytes anew."""
        for transform, odom in zip(self._msg.transforms, self._odoms):
            transform.header.frame_id = odom.header.frame_id
            transform.child_frame_id = odom.child_frame_id
        self._layout = TransformLayout(self._msg)

    def publish(self, sec, nanosec, x, y, qz, qw):
        """Publish every robot's pose (arrays, one entry per robot), stamped sec.nanosec."""
        self.publisher.publish(self._layout.serialize(sec, nanosec, x, y, qz, qw))

    def message(self, sec, nanosec, x, y, qz, qw):
        """Return the TFMessage publish() sends for the same values, as an object."""
        for i, transform in enumerate(self._msg.transforms):
            transform.header.stamp.sec = sec
            transform.header.stamp.nanosec = nanosec
            transform.transform.translation.x = float(x[i])
            transform.transform.translation.y = float(y[i])
            transform.transform.rotation.z = float(qz[i])
            transform.transform.rotation.w = float(qw[i])
        return self._msg


def _cdr_string(text):
    data = text.encode() + b'\0'
    return struct.pack('<I', len(data)) + data


class TransformLayout:
    """
    The CDR bytes of a TFMessage with fixed frames; ``serialize`` fills in stamps and poses.

    Little endian XCDR1, as rmw_fastrtps writes it; translations have z = 0 and rotations turn
    about z only, as a unicycle's do.

    Within the payload (after the 4-byte encapsulation header) a 4-byte value is aligned to 4
    and an 8-byte one to 8.  Each transform: stamp (int32 sec, uint32 nanosec), frame_id,
    child_frame_id (uint32 length with the NUL, the bytes, the NUL), translation (3 doubles),
    rotation (4 doubles).
    """

    def __init__(self, msg):
        payload = bytearray(struct.pack('<I', len(msg.transforms)))
        stamps, translations, rotations = [], [], []
        for transform in msg.transforms:
            _pad(payload, 4)
            stamps.append(len(payload))
            payload += bytes(8)
            payload += _cdr_string(transform.header.frame_id)
            _pad(payload, 4)
            payload += _cdr_string(transform.child_frame_id)
            _pad(payload, 8)
            translations.append(len(payload))
            payload += bytes(24)
            rotations.append(len(payload))
            payload += bytes(32)
        self._bytes = bytearray(_ENCAPSULATION) + payload
        self._view = np.frombuffer(self._bytes, dtype=np.uint8)
        start = len(_ENCAPSULATION)
        self._stamp = start + np.array(stamps, dtype=np.intp)
        self._xy = start + np.array(translations, dtype=np.intp)
        self._zw = start + np.array(rotations, dtype=np.intp) + 16

    def serialize(self, sec, nanosec, x, y, qz, qw):
        """Return the message's bytes for these values (arrays with one entry per transform)."""
        count = len(self._stamp)
        stamp = np.array([[sec, nanosec]], dtype='<u4').repeat(count, axis=0)
        _scatter(self._view, self._stamp, stamp)
        _scatter(self._view, self._xy, np.stack([x, y], axis=1).astype('<f8'))
        _scatter(self._view, self._zw, np.stack([qz, qw], axis=1).astype('<f8'))
        return bytes(self._bytes)


# CDR, little endian, no options.
_ENCAPSULATION = b'\x00\x01\x00\x00'


def _pad(payload, alignment):
    payload += bytes(-len(payload) % alignment)


def _scatter(view, offsets, rows):
    """Write each row of rows (as bytes) at its offset in view."""
    raw = np.ascontiguousarray(rows).view(np.uint8).reshape(len(offsets), -1)
    view[offsets[:, None] + np.arange(raw.shape[1])] = raw
