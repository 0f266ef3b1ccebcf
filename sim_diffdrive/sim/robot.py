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
One robot of ``unicycle_sim``: its topics, frames, messages and warnings.

What is each robot's own on the ROS side, as a turtle is in turtlesim; its state lives in the
world (world.py).  A command is checked here and handed to the world at the moment it arrives,
so it takes effect then, whatever the step.  Commands arrive as their CDR bytes (a raw
subscription), read where their fields lie (cdr.py); odometry leaves as bytes the simulator
writes for every robot at once (node.py, cdr.OdometryLayout).
"""

from collections import deque
import math
import struct

from builtin_interfaces.msg import Time as TimeMsg
from geometry_msgs.msg import PoseStamped
from geometry_msgs.msg import PoseWithCovarianceStamped
from geometry_msgs.msg import Twist
from geometry_msgs.msg import TwistStamped
from nav_msgs.msg import Odometry
from nav_msgs.msg import Path
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.serialization import deserialize_message
from sim_diffdrive.angles import yaw_from_quaternion
from sim_diffdrive.cdr import read_twist
from sim_diffdrive.cdr import read_twist_stamped
from sim_diffdrive.cdr import UnsupportedEncoding
from sim_diffdrive.sim.odom_tf import published_frame
from sim_diffdrive.sim.world import PlacementError
from sim_diffdrive.throttle import Throttle

_NS = 1_000_000_000
# No ground robot commands more than this [m/s or rad/s]; larger values are refused as garbage.
COMMAND_LIMIT = 1e4
# How many cmd_vel messages wait to be handled.  Every publisher on a robot's cmd_vel shares
# this queue, so in a short one a teleop's burst while the simulator is held up pushes out a
# lockstep participant's command; 1000 holds 3 s of a teleop at 333 Hz.
CMD_VEL_DEPTH = 1000


class Robot:
    """
    Robot number ``index`` of the simulator ``sim``: its topics and messages.

    ``name`` is '' for the simulator's one robot in its own namespace.  The node ``sim`` is
    used to make the robot's topics only: a robot holds what it hands commands and poses to
    (the world, the clock, the taps, the logger), not the node.  ``on_command(robot, data)``
    is what the cmd_vel subscription calls with each command's bytes: the node hands them to
    ``take``, then steps if due, so that nothing the robot calls calls back into the node.
    """

    def __init__(self, sim, index, name, on_command):
        self.world, self.clock, self.taps, self.params = sim.world, sim.clock, sim.taps, sim.params
        self.logger = sim.get_logger()
        self._namespace = sim.get_namespace()
        self._map_frame = sim.surroundings.map_frame if sim.surroundings else None
        self.index, self.name = index, name
        self._warned_publishers = self._warned_type = False
        # How many publishers' commands reach cmd_vel, as DDS last said (its matched event).
        self.cmd_publishers = 0
        self._refusals = Throttle(1.0)  # one warning a second per kind of refused command
        prefix = f'{name}/' if name else ''
        self.label = f'{name}: ' if name else ''
        p = sim.params
        self.odom_pub = sim.create_publisher(Odometry, prefix + 'odom', 10)
        self.path_pub = sim.create_publisher(Path, prefix + 'path', 1)
        self.cmd_type = TwistStamped if p.stamped else Twist
        self.take = self.take_stamped if p.stamped else self.take_twist
        # DDS says when a publisher on cmd_vel comes or goes (matched), so a second one is
        # warned about at once, with no graph query per robot per step or second.
        sub = sim.create_subscription(
            self.cmd_type, prefix + 'cmd_vel', lambda data: on_command(self, data),
            CMD_VEL_DEPTH, raw=True,
            event_callbacks=SubscriptionEventCallbacks(matched=self._on_publishers_matched))
        self.cmd_topic = sub.topic_name
        sim.create_subscription(PoseWithCovarianceStamped, prefix + 'initialpose',
                                self.on_initial_pose, 10)
        self.path = DrivenPath(p.path_length)
        self.odom_frame = self.base_frame = ''
        for parameter in ('odom_frame_id', 'base_frame_id'):
            self.set_frame(parameter, getattr(p, parameter))

    @property
    def frames(self):
        """Return (odometry frame, base frame), as the odometry and /tf carry them."""
        return self.odom_frame, self.base_frame

    def reset(self, x, y, yaw):
        """Put the robot back at (x, y, yaw), at rest; forget commands and the driven path."""
        self.world.place(self.index, x, y, yaw)
        self.placed()

    def placed(self):
        """Forget the driven path: the world has put the robot somewhere else."""
        self.path.clear()

    def on_initial_pose(self, msg):
        """Set the robot down at the pose given (in its odometry frame or the map), at rest."""
        frame, map_frame = self.odom_frame, self._map_frame
        given = msg.header.frame_id.lstrip('/')
        p = msg.pose.pose
        values = (p.position.x, p.position.y, p.orientation.x, p.orientation.y,
                  p.orientation.z, p.orientation.w)
        if given not in (frame, map_frame):
            why = f"it is in frame '{given}', not in the odometry frame '{frame}'" + (
                f" or the map frame '{map_frame}'" if map_frame else '')
        elif not all(math.isfinite(v) for v in values) or max(map(abs, values[:2])) > 1e6:
            why = 'it holds a non-finite or absurd value'
        elif not any(values[2:]):
            why = 'it has a zero quaternion'
        else:
            why = None
        if why is None:
            yaw = yaw_from_quaternion(*values[2:])
            self.world.step_to(self.clock.now_ns())
            try:
                if given == frame:
                    self.reset(p.position.x, p.position.y, yaw)
                else:  # in the map: odometry goes on where it was, map -> odom moves
                    self.world.place_in_map(self.index, p.position.x, p.position.y, yaw)
            except PlacementError as error:
                why = str(error)  # the robot at ... would be inside a wall, say
        if why is not None:
            self.logger.warning(f'{self.label}Refusing initialpose: {why}; the robot stays '
                                'where it is')
            return
        # The next step's odometry shows it: one published now would bear the stamp of the
        # step already out with another pose (tf2 drops a repeated stamp).
        self.logger.info(f'{self.label}Set to ({p.position.x:.3f}, {p.position.y:.3f}, '
                         f'{yaw:.3f} rad) in {given} by initialpose, at rest')
        walls = self.world.walls
        x, y = (float(xy[self.index]) for xy in self.world.map_poses()[:2])
        if walls is not None and (outside := walls.grid.outside(x, y)):  # as a start there is
            self.logger.warning(f'{self.label}Set to ({x:.3f}, {y:.3f}) in the map, {outside}')

    # -- commands ---------------------------------------------------------------------------

    def take_twist(self, data):
        """Take a geometry_msgs/Twist's bytes and follow it."""
        command = self._read(data, read_twist, _twist_fields)
        if command is not None:
            self.command(*command)

    def take_stamped(self, data):
        """Take a geometry_msgs/TwistStamped's bytes: refuse it when stale, else follow it."""
        command = self._read(data, read_twist_stamped, _stamped_fields)
        if command is None:
            return
        stamp_ns, linear, angular = command
        age_ns = self.clock.now_ns() - stamp_ns
        limit_ns = round(self.params.max_command_age * _NS)
        if stamp_ns != 0 and limit_ns > 0 and abs(age_ns) > limit_ns:
            if self._refusals.allows('stamp'):
                when = 'old' if age_ns > 0 else 'in the future'
                self.logger.warning(
                    f'{self.label}Refusing cmd_vel stamped {abs(age_ns) / _NS:.3f} s {when} (more '
                    f'than max_command_age {self.params.max_command_age:g} s); keeping the last '
                    'command')
            return
        self.command(linear, angular, stamp_ns)

    def _read(self, data, read, fields):
        """Tap data; return read(data) (through rclpy in another encoding), None if bad."""
        if self.taps:
            self.taps.write(self.cmd_topic, data, self.clock.now_ns())
        try:
            try:
                return read(data)
            except UnsupportedEncoding:
                return fields(deserialize_message(data, self.cmd_type))
        except (struct.error, RuntimeError, ValueError) as error:
            if self._refusals.allows('decode'):
                self.logger.warning(
                    f'{self.label}Refusing cmd_vel that does not decode as '
                    f'{self.cmd_type.__name__} ({error}); keeping the last command')
            return None

    def command(self, linear, angular, stamp_ns=None):
        """Follow (linear.x, angular.z) from now on (from stamp_ns on, when that is ahead)."""
        if not (abs(linear) <= COMMAND_LIMIT and abs(angular) <= COMMAND_LIMIT):
            # NaN fails both comparisons, so it is refused here too.
            if self._refusals.allows('value'):
                self.logger.warning(
                    f'{self.label}Refusing cmd_vel with a non-finite or absurd value (linear.x='
                    f'{linear}, angular.z={angular}; the limit is {COMMAND_LIMIT:g}); keeping '
                    'the last command')
            return
        now_ns = self.clock.now_ns()
        if self.clock.participant is not None and stamp_ns is not None and stamp_ns > now_ns:
            # Sent for a clock step that is on its way to us: take effect then, not now.
            self.world.hold(self.index, stamp_ns, linear, angular)
            return
        self.world.command(self.index, linear, angular, now_ns)
        self.clock.command_arrived()

    def check_command_type(self, types, publishers_of):
        """
        Warn once while a publisher on cmd_vel sends another type.

        types: the topic's types in the graph; publishers_of(topic): its publishers' infos.
        """
        ours = f'geometry_msgs/msg/{self.cmd_type.__name__}'
        others = [name for name in types if name != ours]
        if others:  # the types of its subscribers show there too: which publish?
            others = sorted({info.topic_type for info in publishers_of(self.cmd_topic)} - {ours})
        if others and not self._warned_type:
            self._warned_type = True
            stamped = {'geometry_msgs/msg/Twist': 'false',
                       'geometry_msgs/msg/TwistStamped': 'true'}
            hint = (f' (stamped:={stamped[others[0]]} takes it)'
                    if len(others) == 1 and others[0] in stamped else '')
            self.logger.warning(
                f'{self.label}A publisher on {self.cmd_topic} sends {", ".join(others)}, but this '
                f'simulator takes {ours}{hint}: its commands never arrive')
        elif not others:
            self._warned_type = False

    def _on_publishers_matched(self, info):
        """Warn once when more than one publisher's commands reach this robot's cmd_vel."""
        count = self.cmd_publishers = info.current_count
        if count > 1 and not self._warned_publishers:
            self._warned_publishers = True
            self.logger.warning(f'{count} nodes publish on {self.cmd_topic}: their commands '
                                'interleave and the latest one wins')
        elif count <= 1:
            self._warned_publishers = False

    # -- odometry ---------------------------------------------------------------------------

    def set_frame(self, parameter, value):
        """Use value for odom_frame_id or base_frame_id (the default frames get a prefix)."""
        frame = published_frame(self._namespace, self.name, parameter, value)
        if parameter == 'odom_frame_id':
            self.odom_frame = frame
            self.path.clear()  # a path is in one frame
        else:
            self.base_frame = frame

    def record_path(self, stamp_ns, x, y, qz, qw):
        """Add the pose just published to the driven path; publish the path if anyone looks."""
        self.path.append((stamp_ns, x, y, qz, qw))
        taps = self.taps
        if self.path_pub.get_subscription_count() == 0 and not taps.wants_path:
            return  # converting a long path to a message is the costliest thing here
        path = Path()
        path.header.stamp = _stamp(stamp_ns)
        path.header.frame_id = self.odom_frame
        path.poses = self.path.messages(self.odom_frame)
        self.path_pub.publish(path)
        if taps:
            taps.write(self.path_pub.topic_name, path, stamp_ns)


def _stamp(stamp_ns):
    sec, nanosec = divmod(stamp_ns, _NS)
    return TimeMsg(sec=sec, nanosec=nanosec)


def _twist_fields(msg):
    return msg.linear.x, msg.angular.z


def _stamped_fields(msg):
    stamp = msg.header.stamp
    return stamp.sec * _NS + stamp.nanosec, msg.twist.linear.x, msg.twist.angular.z


class DrivenPath:
    """
    The poses a robot drove through, newest last, at most ``maxlen`` of them.

    Kept as plain tuples (stamp [ns], x, y, qz, qw); PoseStamped messages are made only for a path
    someone looks at, and each pose only once.
    """

    def __init__(self, maxlen):
        self._poses = deque(maxlen=maxlen)
        self._messages = deque(maxlen=maxlen)
        self._unconverted = 0

    def __iter__(self):
        return iter(self._poses)

    def append(self, pose):
        self._poses.append(pose)
        self._unconverted += 1

    def clear(self):
        self._poses.clear()
        self._messages.clear()
        self._unconverted = 0

    def resize(self, maxlen):
        """Keep at most maxlen poses from now on (the newest ones)."""
        self._poses = deque(self._poses, maxlen=maxlen)
        self._messages = deque(self._messages, maxlen=maxlen)

    def messages(self, frame_id):
        """Return the path as a list of PoseStamped in frame_id."""
        new = min(self._unconverted, len(self._poses))
        for i in range(len(self._poses) - new, len(self._poses)):
            stamp_ns, x, y, qz, qw = self._poses[i]
            pose = PoseStamped()
            pose.header.frame_id = frame_id
            pose.header.stamp = _stamp(stamp_ns)
            pose.pose.position.x, pose.pose.position.y = x, y
            pose.pose.orientation.z, pose.pose.orientation.w = qz, qw
            self._messages.append(pose)
        self._unconverted = 0
        return list(self._messages)
