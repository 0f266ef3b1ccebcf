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

"""A node that stands in for a controller or a listener in tests, and what reads its messages."""

from collections.abc import Sequence
import math
import time

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from sim_diffdrive.angles import yaw_from_quaternion
from sim_diffdrive.cdr import header_stamp_ns
from sim_diffdrive.cdr import read_odometry

_NS = 1_000_000_000


def pose_of(odom):
    """Return (x, y, yaw) of an Odometry message."""
    p = odom.pose.pose
    return p.position.x, p.position.y, yaw_from_quaternion(
        p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w)


def twist(linear, angular):
    """Return a Twist commanding linear.x [m/s] and angular.z [rad/s]."""
    msg = Twist()
    msg.linear.x = float(linear)
    msg.angular.z = float(angular)
    return msg


def twist_of(odom):
    """Return (linear.x, angular.z) of an Odometry message's twist."""
    return odom.twist.twist.linear.x, odom.twist.twist.angular.z


def is_moving(odom):
    """Return whether odometry (None: none yet) shows the robot moving."""
    return odom is not None and twist_of(odom) != (0.0, 0.0)


def stamp_s(msg):
    """Return a stamped message's header time in seconds."""
    return _seconds(msg.header.stamp.sec, msg.header.stamp.nanosec)


def _seconds(sec, nanosec):
    # One formula for a stamp read from a message and one read from its bytes: equal floats.
    return sec + nanosec * 1e-9


def angle_error(a, b):
    """Return the absolute difference of two angles, wrapped to [0, pi] [rad]."""
    return abs(math.remainder(a - b, 2.0 * math.pi))


class Received(Sequence):
    """
    Messages in the order they came, kept as bytes; each becomes its message when first read.

    A test reads a few of the thousands of Odometry a run sends; building each costs far more.
    """

    def __init__(self, msg_type):
        self._type = msg_type
        self._data = []
        self._messages = {}  # index -> the message, once read

    def append(self, data):
        self._data.append(data)

    def __len__(self):
        return len(self._data)

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self._data)))]
        index = range(len(self._data))[index]  # negative indices; IndexError
        msg = self._messages.get(index)
        if msg is None:
            msg = self._messages[index] = deserialize_message(self._data[index], self._type)
        return msg

    def stamp_ns(self, index):
        """Return the header stamp [ns] of a message, without making the message."""
        return header_stamp_ns(self._data[index])

    def data(self, index):
        """Return a message's bytes (CDR), as they came."""
        return self._data[index]


class Probe(Node):
    """Record odometry and send Twist commands, or play a script of them on sim-time ticks."""

    def __init__(self, name='probe', odom_topic='odom', cmd_topic='cmd_vel', listen_only=False,
                 record_commands=False, depth=200, **kwargs):
        # Without the parameter and type description services (seven, each discovered by every
        # process) a probe is far cheaper to make.
        kwargs.setdefault('start_parameter_services', False)
        overrides = list(kwargs.pop('parameter_overrides', None) or ())
        if not any(p.name == 'start_type_description_service' for p in overrides):
            overrides.append(Parameter('start_type_description_service', value=False))
        super().__init__(name, parameter_overrides=overrides, **kwargs)
        self.odoms = Received(Odometry)
        self.odom_walls = []  # the monotonic wall time each odometry message arrived
        self.commands = []  # with record_commands: (monotonic, time.time(), Twist) heard
        # depth: the odometry kept while this process is busy (a simulator that runs free
        # publishes thousands a second; older ones go).
        self.create_subscription(Odometry, odom_topic, self._on_odom, depth, raw=True)
        # A listener only: a second publisher on cmd_vel would make the simulator warn.
        self.cmd_pub = None if listen_only else self.create_publisher(Twist, cmd_topic, 10)
        if record_commands:
            self.create_subscription(Twist, cmd_topic, lambda msg: self.commands.append(
                (time.monotonic(), time.time(), msg)), 200)
        self._script = []
        self._tick = None
        self.script_started_at = self.script_done_at = None

    @property
    def odom(self):
        """Return the latest odometry, or None."""
        return self.odoms[-1] if self.odoms else None

    # For the conditions a test spins on (asked after every message): read from the bytes.
    @property
    def twist(self):
        """Return (linear.x, angular.z) of the latest odometry, or None; read from its bytes."""
        return read_odometry(self.odoms.data(-1))[5] if self.odoms else None

    @property
    def moving(self):
        """Return whether the latest odometry shows the robot in motion; False before any."""
        return bool(self.odoms) and self.twist != (0.0, 0.0)

    @property
    def stamp_s(self):
        """Return the latest odometry's stamp [s] (sec + nanosec * 1e-9), or None."""
        return _seconds(*divmod(self.odoms.stamp_ns(-1), _NS)) if self.odoms else None

    def send(self, linear=0.0, angular=0.0):
        self.cmd_pub.publish(twist(linear, angular))

    def play(self, script, period=0.1):
        """Play (linear, angular, ticks) steps on a sim-time timer, then send one zero Twist."""
        self._script = [(v, w) for v, w, ticks in script for _ in range(ticks)] + [(0.0, 0.0)]
        self._tick = self.create_timer(period, self._on_tick)

    @property
    def playing(self):
        return self.script_done_at is None

    def _on_tick(self):
        now = self.get_clock().now().nanoseconds
        if now == 0:
            return
        if self.script_started_at is None:
            self.script_started_at = now
        self.send(*self._script.pop(0))
        if not self._script:
            self.script_done_at = now
            self._tick.cancel()

    def after(self, wall):
        """Return the odometry messages that arrived at or after monotonic wall time wall."""
        return [self.odoms[i] for i, received in enumerate(self.odom_walls) if received >= wall]

    def _on_odom(self, msg):
        self.odom_walls.append(time.monotonic())
        self.odoms.append(msg)

    def odom_after(self, t_ns):
        """Return the first odometry stamped at or after t_ns (sim time), or None."""
        return next((self.odoms[i] for i in range(len(self.odoms))
                     if self.odoms.stamp_ns(i) >= t_ns), None)
