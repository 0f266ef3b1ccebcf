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

"""A motion's view of its robot's odometry: the few numbers it needs, read from the bytes."""

from motion_challenges.controllers import NS
from motion_challenges.controllers import Pose
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message
from sim_diffdrive.angles import yaw_from_quaternion
from sim_diffdrive.cdr import read_odometry
from sim_diffdrive.cdr import UnsupportedEncoding


class OdomPose(Pose):
    """The Pose an Odometry message reports (position, yaw, stamp), read from its bytes."""

    def __init__(self, data):
        try:
            stamp_ns, _, _, (x, y, _), orientation, twist = read_odometry(data)
        except UnsupportedEncoding:  # not plain CDR: let rclpy read it
            msg = deserialize_message(data, Odometry)
            p, q, t = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist
            stamp_ns = msg.header.stamp.sec * NS + msg.header.stamp.nanosec
            x, y, orientation, twist = p.x, p.y, (q.x, q.y, q.z, q.w), (t.linear.x, t.angular.z)
        super().__init__(x, y, yaw_from_quaternion(*orientation), stamp_ns)
        self.twist = twist  # (linear.x, angular.z)
