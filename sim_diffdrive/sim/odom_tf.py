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

from rclpy.qos import QoSProfile
from sim_diffdrive.cdr import TransformLayout
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
    Publish each robot's odometry as the transform frame_id -> child_frame_id on /tf.

    One TFMessage carries every robot's transform (as robot_state_publisher sends a robot's
    joints together).  With many robots, turning that message into bytes costs rclpy as much
    as publishing the odometry, so it is serialized here instead (cdr.TransformLayout): the
    CDR bytes are laid out once for ``frames``, (frame_id, child_frame_id) per robot
    (``set_frames()`` again when they change), and each publish writes the stamp and the poses
    into them with numpy.
    """

    def __init__(self, node, frames):
        self.publisher = node.create_publisher(TFMessage, TF_TOPIC, TF_QOS)
        self.set_frames(frames)

    def set_frames(self, frames):
        """Lay the bytes out anew for frames, (frame_id, child_frame_id) per robot."""
        self._layout = TransformLayout(list(frames))

    def publish(self, sec, nanosec, x, y, qz, qw):
        """Publish every robot's pose (arrays, one entry per robot), stamped sec.nanosec."""
        data = self._layout.serialize(sec, nanosec, x, y, qz, qw)
        self.publisher.publish(data)
        return data
