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

from geometry_msgs.msg import TransformStamped
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
    Publish header.frame_id -> child_frame_id of each robot's odometry on ``/tf``.

    One TFMessage carries every robot's transform (as robot_state_publisher sends a robot's
    joints together), and its TransformStamped objects are reused, as the simulator reuses its
    Odometry messages; each ``publish(odoms)`` copies the frames (they may change at runtime),
    the stamps and the poses.
    """

    def __init__(self, node, count=1):
        self.publisher = node.create_publisher(TFMessage, TF_TOPIC, TF_QOS)
        self.transforms = [TransformStamped() for _ in range(count)]
        self._msg = TFMessage(transforms=self.transforms)

    def publish(self, odoms):
        """Publish each odometry's pose as the transform from its frame to its child frame."""
        for t, odom in zip(self.transforms, odoms):
            t.header.frame_id = odom.header.frame_id
            t.child_frame_id = odom.child_frame_id
            t.header.stamp = odom.header.stamp
            pose = odom.pose.pose
            translation = t.transform.translation
            translation.x, translation.y, translation.z = (
                pose.position.x, pose.position.y, pose.position.z)
            rotation = t.transform.rotation
            q = pose.orientation
            rotation.x, rotation.y, rotation.z, rotation.w = q.x, q.y, q.z, q.w
        self.publisher.publish(self._msg)
        return self._msg
