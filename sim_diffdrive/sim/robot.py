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
One robot of ``unicycle_sim``: its topics, frames, commands, cmd_vel timeout and warnings.

The simulator (sim_node.py) keeps time and steps every robot at once (fleet.py); a Robot is
what is each robot's own, as a turtle is in turtlesim: ``cmd_vel`` in, ``odom`` and ``path``
out (under ``<name>/`` when the simulator has ``robots``), frames ``<name>/odom`` ->
``<name>/base_footprint``, and the piecewise integration at each command's arrival, so a
command takes effect at the moment it arrives, whatever the step.
"""

import bisect
from collections import deque

from geometry_msgs.msg import PoseStamped
from geometry_msgs.msg import Twist
from geometry_msgs.msg import TwistStamped
from nav_msgs.msg import Odometry
from nav_msgs.msg import Path
from sim_diffdrive.sim.odom_tf import namespaced_frame
from sim_diffdrive.sim.odom_tf import resolve_frame

_NS = 1_000_000_000
# No ground robot commands more than this [m/s or rad/s]; larger values are refused as garbage.
COMMAND_LIMIT = 1e4
# In Simulator.deadline_ns: no cmd_vel timeout pending.
NO_DEADLINE = 2 ** 63 - 1
# In Simulator.integrated_ns: not integrated yet.
NOT_YET = -1


def covariance(diagonal):
    """Return the flat, row-major 6x6 matrix with the given diagonal and zeros elsewhere."""
    values = [0.0] * 36
    for i, value in enumerate(diagonal):
        values[7 * i] = value
    return values


class Robot:
    """
    Robot number ``index`` of the simulator ``sim``, moved by ``model`` (a FleetRobot).

    ``name`` is '' for the simulator's one robot in its own namespace.  The simulator holds
    this robot's integration time and cmd_vel deadline in arrays (``integrated_ns``,
    ``deadline_ns``), so that it can tell in one numpy step which robots have something to do
    on the way to the next step.
    """

    def __init__(self, sim, index, name, model):
        self.sim = sim
        self.index = index
        self.name = name
        self.model = model
        self.last_cmd_ns = None
        # On another simulator's clock: stamped commands that are ahead of this node's clock
        # (sent for a step whose /clock has not reached us yet), as (stamp_ns, linear, angular).
        self.early_commands = []
        self._warned_publishers = False
        prefix = f'{name}/' if name else ''
        self.label = f'{name}: ' if name else ''
        p = sim.params
        self.odom_pub = sim.create_publisher(Odometry, prefix + 'odom', 10)
        self.path_pub = sim.create_publisher(Path, prefix + 'path', 1)
        if p.stamped:
            sub = sim.create_subscription(TwistStamped, prefix + 'cmd_vel', self.on_stamped, 10)
        else:
            sub = sim.create_subscription(Twist, prefix + 'cmd_vel', self.on_twist, 10)
        self.cmd_topic = sub.topic_name
        self.path = DrivenPath(p.path_length)
        self.odom_msg = Odometry()
        self.odom_msg.pose.covariance = covariance(p.pose_covariance_diagonal)
        self.odom_msg.twist.covariance = covariance(p.twist_covariance_diagonal)
        for parameter in ('odom_frame_id', 'base_frame_id'):
            self.set_frame(parameter, getattr(p, parameter))
        # What each publish fills, looked up once (the message is reused).
        pose = self.odom_msg.pose.pose
        twist = self.odom_msg.twist.twist
        self._fill = (self.odom_msg.header, pose.position, pose.orientation, twist.linear,
                      twist.angular)

    # -- state in the simulator's arrays ----------------------------------------------------

    @property
    def integrated_ns(self):
        """Return the time the pose is integrated up to [ns], or None before the first time."""
        value = int(self.sim.integrated_ns[self.index])
        return None if value == NOT_YET else value

    @integrated_ns.setter
    def integrated_ns(self, value):
        self.sim.integrated_ns[self.index] = NOT_YET if value is None else value

    def _set_last_command(self, at_ns):
        self.last_cmd_ns = at_ns
        self.update_deadline()

    def update_deadline(self):
        """Put this robot's cmd_vel deadline (or none) where the simulator's step sees it."""
        timeout_ns = self.sim.timeout_ns
        self.sim.deadline_ns[self.index] = (
            NO_DEADLINE if self.last_cmd_ns is None or timeout_ns <= 0
            else self.last_cmd_ns + timeout_ns)

    # -- integration ------------------------------------------------------------------------

    def advance_to(self, now_ns):
        """Integrate the pose up to now_ns, applying early commands at their stamps on the way."""
        early = self.early_commands
        integrated = self.integrated_ns
        if integrated is not None and now_ns < integrated:
            early.clear()  # the clock jumped back: they were meant for a time that is gone
        while early and early[0][0] <= now_ns:
            stamp_ns, linear, angular = early.pop(0)
            self._integrate_to(stamp_ns)
            self.apply(linear, angular, stamp_ns)
        self.sim.has_early[self.index] = bool(early)
        self._integrate_to(now_ns)

    def _integrate_to(self, now_ns):
        """Integrate the pose up to now_ns, stopping the robot at a cmd_vel timeout on the way."""
        integrated = self.integrated_ns
        if integrated is None or now_ns < integrated:
            # First call, or the clock jumped back (e.g. a replayed /clock): restart from here,
            # and count the cmd_vel timeout from here too, not from a time that is now ahead.
            self.integrated_ns = now_ns
            if self.last_cmd_ns is not None:
                self._set_last_command(min(self.last_cmd_ns, now_ns))
            return
        deadline = int(self.sim.deadline_ns[self.index])
        if deadline <= now_ns:
            if self._moving():
                self.model.advance(max(0, deadline - integrated) / _NS)
                integrated = max(integrated, deadline)
                self.model.command(0.0, 0.0)
                self.sim.get_logger().warning(
                    f'{self.label}No cmd_vel for {self.sim.params.cmd_vel_timeout:g} s: '
                    'stopping the robot')
            # At rest, a passed deadline changes nothing until the next command.
            self._set_last_command(None)
        self.model.advance((now_ns - integrated) / _NS)
        self.integrated_ns = now_ns

    def _moving(self):
        m = self.model
        return bool(m.target_linear or m.target_angular or m.linear or m.angular)

    def reset(self, x, y, yaw):
        """Put the robot back at (x, y, yaw), at rest; forget commands and the driven path."""
        self.model.reset(x, y, yaw)
        self._set_last_command(None)
        self.early_commands.clear()
        self.sim.has_early[self.index] = False
        self.path.clear()

    # -- commands ---------------------------------------------------------------------------

    def on_stamped(self, msg):
        sim = self.sim
        if sim.taps:
            sim.taps.write(self.cmd_topic, msg, sim.now_ns())
        stamp_ns = msg.header.stamp.sec * _NS + msg.header.stamp.nanosec
        age_ns = sim.now_ns() - stamp_ns
        limit_ns = round(sim.params.max_command_age * _NS)
        if stamp_ns != 0 and limit_ns > 0 and abs(age_ns) > limit_ns:
            when = 'old' if age_ns > 0 else 'in the future'
            sim.get_logger().warning(
                f'{self.label}Refusing cmd_vel stamped {abs(age_ns) / _NS:.3f} s {when} (more '
                f'than max_command_age {sim.params.max_command_age:g} s); keeping the last '
                'command', throttle_duration_sec=1.0)
            return
        self.on_twist(msg.twist, stamp_ns)

    def on_twist(self, twist, stamp_ns=None):
        sim = self.sim
        if sim.taps and stamp_ns is None:
            sim.taps.write(self.cmd_topic, twist, sim.now_ns())
        linear = twist.linear.x
        angular = twist.angular.z
        if not (abs(linear) <= COMMAND_LIMIT and abs(angular) <= COMMAND_LIMIT):
            # NaN fails both comparisons, so it is refused here too.
            sim.get_logger().warning(
                f'{self.label}Refusing cmd_vel with a non-finite or absurd value (linear.x='
                f'{linear}, angular.z={angular}; the limit is {COMMAND_LIMIT:g}); keeping the '
                'last command', throttle_duration_sec=1.0)
            return
        now_ns = sim.now_ns()
        if sim.lockstep is not None and stamp_ns is not None and stamp_ns > now_ns:
            # Sent for a clock step that is on its way to us: take effect then, not now.
            bisect.insort(self.early_commands, (stamp_ns, linear, angular))
            sim.has_early[self.index] = True
            return
        self.advance_to(now_ns)
        self.apply(linear, angular, now_ns)
        sim.command_arrived()

    def apply(self, linear, angular, at_ns):
        self.model.command(linear, angular)
        self._set_last_command(at_ns)

    def check_publishers(self):
        """Warn once when more than one node publishes on this robot's cmd_vel."""
        count = self.sim.count_publishers(self.cmd_topic)
        if count > 1 and not self._warned_publishers:
            self._warned_publishers = True
            self.sim.get_logger().warning(
                f'{count} nodes publish on {self.cmd_topic}: their commands interleave and the '
                'latest one wins')
        elif count <= 1:
            self._warned_publishers = False

    # -- odometry ---------------------------------------------------------------------------

    def set_frame(self, parameter, value):
        """Use value for odom_frame_id or base_frame_id (the default frames get a prefix)."""
        default = 'odom' if parameter == 'odom_frame_id' else 'base_footprint'
        frame = resolve_frame(self.sim.get_namespace(), value, default)
        if self.name:
            frame = namespaced_frame(self.name, frame)
        if parameter == 'odom_frame_id':
            self.odom_msg.header.frame_id = frame
            self.path.clear()  # a path is in one frame
        else:
            self.odom_msg.child_frame_id = frame

    def publish_odom(self, stamp, stamp_ns, x, y, qz, qw, linear, angular):
        """Fill the reused odometry message and publish it; return it."""
        msg = self.odom_msg
        header, position, orientation, linear_velocity, angular_velocity = self._fill
        header.stamp = stamp
        position.x = x
        position.y = y
        orientation.z = qz
        orientation.w = qw
        linear_velocity.x = linear
        angular_velocity.z = angular
        self.odom_pub.publish(msg)
        if self.sim.taps:
            self.sim.taps.write(self.odom_pub.topic_name, msg, stamp_ns)
        return msg

    def record_path(self, stamp_ns):
        """Add the pose just published to the driven path; publish the path if anyone looks."""
        odom = self.odom_msg
        header, position, orientation, _, _ = self._fill
        self.path.append((header.stamp, position.x, position.y, orientation.z, orientation.w))
        taps = self.sim.taps
        if self.path_pub.get_subscription_count() == 0 and not taps.wants_path:
            return  # converting a long path to a message is the costliest thing here
        path = Path()
        path.header = odom.header
        path.poses = self.path.messages(header.frame_id)
        self.path_pub.publish(path)
        if taps:
            taps.write(self.path_pub.topic_name, path, stamp_ns)


class DrivenPath:
    """
    The poses a robot drove through, newest last, at most ``maxlen`` of them.

    Kept as plain tuples (stamp, x, y, qz, qw); PoseStamped messages are made only for a path
    someone looks at, and each pose only once.
    """

    def __init__(self, maxlen):
        self._poses = deque(maxlen=maxlen)
        self._messages = deque(maxlen=maxlen)
        self._unconverted = 0

    def __iter__(self):
        return iter(self._poses)

    def __len__(self):
        return len(self._poses)

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
            stamp, x, y, qz, qw = self._poses[i]
            pose = PoseStamped()
            pose.header.frame_id = frame_id
            pose.header.stamp = stamp
            pose.pose.position.x = x
            pose.pose.position.y = y
            pose.pose.orientation.z = qz
            pose.pose.orientation.w = qw
            self._messages.append(pose)
        self._unconverted = 0
        return list(self._messages)
