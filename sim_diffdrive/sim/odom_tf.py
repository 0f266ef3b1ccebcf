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
multi-robot setups of Nav2 and TurtleBot name them (``robot1/odom``).  Frames that tf2 would
reject are refused by name (``check_frames``), at start and as a live set.
"""

from rclpy.qos import QoSProfile
from sim_diffdrive.cdr import TransformLayout
from sim_diffdrive.parameters import frame_problem
from sim_diffdrive.parameters import ParameterError
from tf2_msgs.msg import TFMessage

_NS = 1_000_000_000
TF_TOPIC = '/tf'
# What tf2_ros's TransformBroadcaster uses (DynamicBroadcasterQoS): reliable, volatile, 100 deep.
TF_QOS = QoSProfile(depth=100)
# The parameters that name a robot's frames and their defaults (node.py's Specs take them from
# here); only a default gets the namespace's prefix.
DEFAULT_FRAMES = {'odom_frame_id': 'odom', 'base_frame_id': 'base_footprint'}
# The frames that get the namespace's (and a fleet robot's) prefix by default: their defaults.
_PREFIXED = {**DEFAULT_FRAMES, 'scan_frame_id': 'base_scan'}


def namespaced_frame(namespace, frame):
    """Return frame prefixed with namespace minus its leading slash ('/robot1' -> 'robot1/')."""
    prefix = namespace.strip('/')
    return f'{prefix}/{frame}' if prefix else frame


def resolve_frame(namespace, frame, default):
    """Return the frame a node in namespace uses: the default gets the prefix, others not."""
    return namespaced_frame(namespace, frame) if frame == default else frame


def published_frame(namespace, robot, parameter, value):
    """Return the frame that value of parameter gives robot ('' for a simulator's one robot)."""
    if parameter not in _PREFIXED:
        return value  # the map's: shared by every robot, as given
    frame = resolve_frame(namespace, value, _PREFIXED[parameter])
    return namespaced_frame(robot, frame) if robot else frame


def check_frames(namespace, robots, frames, blame):
    """
    Raise ParameterError, naming the parameter, if tf2 could not use the frames given.

    frames maps each parameter of DEFAULT_FRAMES (and with a map, map_frame_id and
    scan_frame_id) to its value; robots are the simulator's robot names ('' for its one
    robot).  The frames are compared as each robot publishes them, after the prefixes (the
    map's is shared, as given): two that are one would make a transform from a frame to
    itself, or give a frame two parents.  blame is the parameter named then.
    """
    for parameter, value in frames.items():
        why = frame_problem(value)
        if why:
            raise ParameterError(f"parameter '{parameter}' {why}; got {value!r}")
    for robot in robots:
        published = {}
        for parameter in sorted(frames, key=lambda name: name == blame):  # blame's last
            frame = published_frame(namespace, robot, parameter, frames[parameter])
            if frame in published:
                raise ParameterError(
                    f"parameter '{parameter}' gives the same frame as '{published[frame]}', "
                    f'{frame!r}: /tf would carry a transform from {frame} to itself or give it '
                    f'two parents, which tf2 rejects; got {frames[parameter]!r}')
            published[frame] = parameter


class OdomTransform:
    """
    Publish a transform frame_id -> child_frame_id per robot on /tf: its odometry, map -> odom.

    One TFMessage carries every robot's transform, its bytes laid out once for ``frames``,
    (frame_id, child_frame_id) per robot (cdr.TransformLayout; ``set_frames()`` again when
    they change), as rclpy's serialization of it would cost as much as the odometry.
    """

    def __init__(self, node, frames=None):
        self.publisher = node.create_publisher(TFMessage, TF_TOPIC, TF_QOS)
        if frames is not None:  # else set_frames() before the first publish()
            self.set_frames(frames)

    def set_frames(self, frames):
        """Lay the bytes out anew for frames, (frame_id, child_frame_id) per robot."""
        self._layout = TransformLayout(list(frames))

    def listened(self, taps):
        """Return whether anyone takes the transforms: publish only then (a step costs them)."""
        return bool(taps) or self.publisher.get_subscription_count() > 0

    def publish(self, stamp_ns, x, y, qz, qw, taps):
        """Publish (and tap) every robot's pose (one entry each) at stamp_ns."""
        data = self._layout.serialize(*divmod(stamp_ns, _NS), x, y, qz, qw)
        self.publisher.publish(data)
        if taps:
            taps.write(self.publisher.topic_name, data, stamp_ns)
