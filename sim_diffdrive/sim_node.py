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
The ``unicycle_sim`` node: Twist in on ``cmd_vel``, Odometry out on ``odom``.

The pose is integrated exactly and piecewise: brought up to the moment each command arrives
before the command takes effect, so accuracy does not depend on ``rate_hz``.  With
``publish_clock`` the node owns time: it steps a simulated clock by 1/``rate_hz`` seconds per
step, ``real_time_factor`` times faster than the wall clock, and publishes it on ``/clock``
for nodes that run with ``use_sim_time``.
"""

import bisect
from collections import deque
import time

from geometry_msgs.msg import PoseStamped
from geometry_msgs.msg import Twist
from geometry_msgs.msg import TwistStamped
from nav_msgs.msg import Odometry
from nav_msgs.msg import Path
from rclpy.clock import Clock
from rclpy.clock import ClockType
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.qos import ReliabilityPolicy
from rclpy.time import Time
from rosgraph_msgs.msg import Clock as ClockMsg
from sim_diffdrive.angles import quaternion_from_yaw
from sim_diffdrive.kinematics import UnicycleModel
from sim_diffdrive.lockstep_owner import LockstepOwner
from sim_diffdrive.odom_tf import OdomTransform
from sim_diffdrive.odom_tf import resolve_frame
from sim_diffdrive.parameters import declare
from sim_diffdrive.parameters import ParameterError
from sim_diffdrive.parameters import Spec
from sim_diffdrive.participant import take_part
from sim_diffdrive.runtime import run
from sim_diffdrive.taps import open_taps
from sim_diffdrive.taps import TAP_PARAMETERS
from std_srvs.srv import Empty

_NS = 1_000_000_000
# No ground robot commands more than this [m/s or rad/s]; larger values are refused as garbage.
_COMMAND_LIMIT = 1e4
# Clock pacing: wait this many times the graph's recent reaction time between steps; the
# remembered reaction time shrinks by this factor per step, so a spike is forgotten in a
# second of simulated time and an idle graph runs at the full real_time_factor.
_PACING_MARGIN = 2.0
_REACTION_DECAY = 0.98
_POSITION_LIMIT = 1e6
# In lockstep the clock timer only paces and watches for laggards (answers drive the steps),
# so it need not fire more often than this [s]; without members it catches up in bursts.
_LOCKSTEP_TICK_S = 0.0005

PARAMETERS = (
    Spec('rate_hz', 50.0, 'Odometry publish rate [Hz]; with publish_clock also the clock step.',
         low=0.0, high=1000.0, low_open=True),
    Spec('cmd_vel_timeout', 0.5,
         'Stop the robot when no cmd_vel arrived for this long [s]; 0 keeps the last command.',
         low=0.0, high=3600.0, live=True),
    Spec('odom_frame_id', 'odom', 'Frame of the odometry pose and the path (REP 105).',
         live=True),
    Spec('base_frame_id', 'base_footprint', 'Child frame of the odometry (REP 105).',
         live=True),
    Spec('publish_tf', True,
         'Publish odom_frame_id -> base_frame_id on /tf with each odometry.'),
    Spec('initial_x', 0.0, 'Start position x in the odom frame [m]; a change takes effect at '
         'the next ~/reset.', low=-_POSITION_LIMIT, high=_POSITION_LIMIT, live=True),
    Spec('initial_y', 0.0, 'Start position y in the odom frame [m]; a change takes effect at '
         'the next ~/reset.', low=-_POSITION_LIMIT, high=_POSITION_LIMIT, live=True),
    Spec('initial_yaw', 0.0, 'Start heading in the odom frame [rad], counter-clockwise from x; '
         'a change takes effect at the next ~/reset.', low=-100.0, high=100.0, live=True),
    Spec('max_linear_speed', 0.0, 'Largest |linear.x| applied [m/s]; 0 = unlimited.',
         low=0.0, high=1000.0, live=True),
    Spec('max_angular_speed', 0.0, 'Largest |angular.z| applied [rad/s]; 0 = unlimited.',
         low=0.0, high=1000.0, live=True),
    Spec('max_linear_accel', 0.0, 'Largest linear acceleration [m/s^2]; 0 = unlimited.',
         low=0.0, high=1000.0, live=True),
    Spec('max_angular_accel', 0.0, 'Largest angular acceleration [rad/s^2]; 0 = unlimited.',
         low=0.0, high=1000.0, live=True),
    Spec('pose_covariance_diagonal', [0.001, 0.001, 0.001, 0.001, 0.001, 0.01],
         'Diagonal of the odometry pose covariance (x, y, z, roll, pitch, yaw).',
         low=0.0, high=1e9, length=6, live=True),
    Spec('twist_covariance_diagonal', [0.001, 0.001, 0.001, 0.001, 0.001, 0.01],
         'Diagonal of the odometry twist covariance (x, y, z, roll, pitch, yaw).',
         low=0.0, high=1e9, length=6, live=True),
    Spec('publish_clock', False,
         'Own time: publish /clock so nodes with use_sim_time run on simulated time.'),
    Spec('real_time_factor', 1.0,
         'With publish_clock: simulated seconds per wall second (e.g. 20.0).',
         low=0.0, high=10000.0, low_open=True, live=True),
    Spec('lockstep', True,
         'With publish_clock: step in lockstep with the nodes that take part (every motion on '
         'sim time): no step before each has answered the last one. false: a free clock.'),
    Spec('lockstep_timeout', 2.0,
         'With lockstep: how long to wait for one participant before warning and going on '
         'without it [s, wall time].', low=0.0, high=3600.0, low_open=True, live=True),
    Spec('stamped', False, 'Subscribe to geometry_msgs/TwistStamped instead of Twist.'),
    Spec('max_command_age', 0.5,
         'With stamped: refuse a command stamped further than this from now [s]; 0 = accept all.',
         low=0.0, high=3600.0, live=True),
    Spec('path_length', 1000, 'Poses kept in the driven path published on path (newest last).',
         low=1, high=1000000, live=True),
    Spec('path_rate_hz', 10.0, 'Rate at which poses are added to the path [Hz].',
         low=0.0, high=1000.0, low_open=True, live=True),
) + TAP_PARAMETERS


def _covariance(diagonal):
    covariance = [0.0] * 36
    for i, value in enumerate(diagonal):
        covariance[7 * i] = value
    return covariance


class UnicycleSim(Node):
    """Simulate one unicycle robot (see the module docstring)."""

    def __init__(self, **kwargs):
        super().__init__('unicycle_sim', **kwargs)
        self.params = declare(self, PARAMETERS, on_change=self._on_parameter)
        p = self.params
        if p.publish_clock and self.get_parameter('use_sim_time').value:
            raise ParameterError(
                "parameter 'publish_clock' is true, so this node owns time: "
                "'use_sim_time' must be false for it")
        self.model = UnicycleModel(
            p.initial_x, p.initial_y, p.initial_yaw,
            p.max_linear_speed, p.max_angular_speed, p.max_linear_accel, p.max_angular_accel)
        self._step_ns = round(_NS / p.rate_hz)
        self._odom_msg = Odometry()
        # In a namespace the default frames get its prefix (robot1/odom), as on /tf.
        frame = {spec.name: spec.default for spec in PARAMETERS}
        ns = self.get_namespace()
        self._odom_msg.header.frame_id = resolve_frame(ns, p.odom_frame_id, frame['odom_frame_id'])
        self._odom_msg.child_frame_id = resolve_frame(ns, p.base_frame_id, frame['base_frame_id'])
        self._odom_msg.pose.covariance = _covariance(p.pose_covariance_diagonal)
        self._odom_msg.twist.covariance = _covariance(p.twist_covariance_diagonal)
        self._timeout_ns = round(p.cmd_vel_timeout * _NS)

        # Simulated time in integer nanoseconds so many steps add up without rounding drift.
        self._sim_ns = 0
        self._integrated_ns = None
        self._last_cmd_ns = None
        # On another simulator's clock: stamped commands that are ahead of this node's clock
        # (sent for a step whose /clock has not reached us yet), as (stamp_ns, linear, angular).
        self._early_commands = []

        # Where else the simulator's traffic goes (an MCAP file, Foxglove): see taps.py.
        self.taps = open_taps(self)
        self._odom_pub = self.create_publisher(Odometry, 'odom', 10)
        self._path_pub = self.create_publisher(Path, 'path', 1)
        self._tf = OdomTransform(self) if p.publish_tf else None
        self._path = deque(maxlen=p.path_length)
        self._path_every = max(1, round(p.rate_hz / p.path_rate_hz))
        self._odom_count = 0
        self._check_every = max(1, round(p.rate_hz))
        self._warned_publishers = False
        if p.stamped:
            sub = self.create_subscription(TwistStamped, 'cmd_vel', self._on_twist_stamped, 10)
        else:
            sub = self.create_subscription(Twist, 'cmd_vel', self._on_twist, 10)
        self._cmd_topic = sub.topic_name
        self.create_service(Empty, '~/reset', self._on_reset)

        self.lockstep_owner = None
        self.lockstep = None
        if p.publish_clock:
            self._clock_pub = self.create_publisher(
                ClockMsg, '/clock', QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
            self.clock_topic = self._clock_pub.topic_name
            self._integrated_ns = 0
            self.clock_wall = time.monotonic()
            self._reaction_s = 0.0
            self._answered = True
            # Pacing never makes simulated time slower than real time.
            self._max_reaction_s = self._step_ns / _NS / _PACING_MARGIN
            self.step_budget_s = self._step_ns / _NS / p.real_time_factor
            period_s = self.step_budget_s
            if p.lockstep:
                self.lockstep_owner = LockstepOwner(self)
                period_s = max(period_s, _LOCKSTEP_TICK_S)
            self.clock_timer = self.create_timer(
                period_s, self._on_clock_timer, clock=Clock(clock_type=ClockType.STEADY_TIME))
            self._publish_clock()
        else:
            self._clock_pub = None
            self.clock_timer = None
            self.create_timer(self._step_ns / _NS, self._on_odom_timer)
            if self.get_parameter('use_sim_time').value:
                # Another simulator owns the clock: take part, so it waits for this robot.
                self.lockstep = take_part(self)
        self.get_logger().info(
            f'Unicycle at ({p.initial_x:.3f}, {p.initial_y:.3f}, {p.initial_yaw:.3f} rad), '
            f'odom at {p.rate_hz:g} Hz, cmd_vel timeout {p.cmd_vel_timeout:g} s'
            + (f', publishing /clock at up to {p.real_time_factor:g}x real time'
               + (' in lockstep' if p.lockstep else ' (free clock)')
               if p.publish_clock else ''))

    # -- time -------------------------------------------------------------------------------

    def now_ns(self):
        """Return the current simulated time in nanoseconds."""
        if self._clock_pub is not None:
            return self._sim_ns
        return self.get_clock().now().nanoseconds

    def _advance_to(self, now_ns):
        """Integrate the pose up to now_ns, applying early commands at their stamps on the way."""
        early = self._early_commands
        if self._integrated_ns is not None and now_ns < self._integrated_ns:
            early.clear()  # the clock jumped back: they were meant for a time that is gone
        while early and early[0][0] <= now_ns:
            stamp_ns, linear, angular = early.pop(0)
            self._integrate_to(stamp_ns)
            self._apply(linear, angular, stamp_ns)
        self._integrate_to(now_ns)

    def _integrate_to(self, now_ns):
        """Integrate the pose up to now_ns, stopping the robot at a cmd_vel timeout on the way."""
        if self._integrated_ns is None or now_ns < self._integrated_ns:
            # First call, or the clock jumped back (e.g. a replayed /clock): restart from here,
            # and count the cmd_vel timeout from here too, not from a time that is now ahead.
            self._integrated_ns = now_ns
            if self._last_cmd_ns is not None:
                self._last_cmd_ns = min(self._last_cmd_ns, now_ns)
            return
        deadline = None
        if self._timeout_ns > 0 and self._last_cmd_ns is not None and self._moving():
            deadline = self._last_cmd_ns + self._timeout_ns
        if deadline is not None and deadline <= now_ns:
            self.model.advance(max(0, deadline - self._integrated_ns) / _NS)
            self._integrated_ns = max(self._integrated_ns, deadline)
            self.model.command(0.0, 0.0)
            self._last_cmd_ns = None
            self.get_logger().warning(
                f'No cmd_vel for {self.params.cmd_vel_timeout:g} s: stopping the robot')
        self.model.advance((now_ns - self._integrated_ns) / _NS)
        self._integrated_ns = now_ns

    def _moving(self):
        m = self.model
        return bool(m.target_linear or m.target_angular or m.linear or m.angular)

    def _on_clock_timer(self):
        if self.lockstep_owner is not None:
            self.lockstep_owner.try_step()
            return
        # real_time_factor is an upper bound: a step waits until the graph has had a few times
        # its recent reaction time to answer the previous one, so that a command lands on the
        # step it was sent for even when the machine is loaded.
        if time.monotonic() - self.clock_wall >= _PACING_MARGIN * self._reaction_s:
            self._reaction_s *= _REACTION_DECAY
            self.step()

    def step(self):
        """Advance simulated time by one step and publish /clock and odometry."""
        if self.lockstep_owner is not None:
            self.lockstep_owner.next_step(self._sim_ns + self._step_ns)
        self._sim_ns += self._step_ns
        self._advance_to(self._sim_ns)
        self._publish_clock()
        self._publish_odom()
        self.clock_wall = time.monotonic()
        self._answered = False

    def _on_odom_timer(self):
        self._advance_to(self.now_ns())
        self._publish_odom()

    def _publish_clock(self):
        msg = ClockMsg()
        msg.clock = Time(nanoseconds=self._sim_ns).to_msg()
        self._clock_pub.publish(msg)
        if self.taps:
            self.taps.write(self._clock_pub.topic_name, msg, self._sim_ns)

    # -- commands ---------------------------------------------------------------------------

    def _on_twist_stamped(self, msg):
        if self.taps:
            self.taps.write(self._cmd_topic, msg, self.now_ns())
        stamp_ns = msg.header.stamp.sec * _NS + msg.header.stamp.nanosec
        age_ns = self.now_ns() - stamp_ns
        limit_ns = round(self.params.max_command_age * _NS)
        if stamp_ns != 0 and limit_ns > 0 and abs(age_ns) > limit_ns:
            when = 'old' if age_ns > 0 else 'in the future'
            self.get_logger().warning(
                f'Refusing cmd_vel stamped {abs(age_ns) / _NS:.3f} s {when} (more than '
                f'max_command_age {self.params.max_command_age:g} s); keeping the last command',
                throttle_duration_sec=1.0)
            return
        self._on_twist(msg.twist, stamp_ns)

    def _on_twist(self, twist, stamp_ns=None):
        if self.taps and stamp_ns is None:
            self.taps.write(self._cmd_topic, twist, self.now_ns())
        linear = twist.linear.x
        angular = twist.angular.z
        if not (abs(linear) <= _COMMAND_LIMIT and abs(angular) <= _COMMAND_LIMIT):
            # NaN fails both comparisons, so it is refused here too.
            self.get_logger().warning(
                f'Refusing cmd_vel with a non-finite or absurd value (linear.x={linear}, '
                f'angular.z={angular}; the limit is {_COMMAND_LIMIT:g}); keeping the last '
                'command', throttle_duration_sec=1.0)
            return
        now_ns = self.now_ns()
        if self.lockstep is not None and stamp_ns is not None and stamp_ns > now_ns:
            # Sent for a clock step that is on its way to us: take effect then, not now.
            bisect.insort(self._early_commands, (stamp_ns, linear, angular))
            return
        self._advance_to(now_ns)
        self._apply(linear, angular, now_ns)
        if self._clock_pub is not None and not self._answered:
            # Only the first command after a step answers it: commands from a publisher that
            # does not follow the clock (teleop, a second controller, a flood) arrive at any
            # time, and counting each would double the wait every step until time stood still.
            self._answered = True
            reaction_s = min(time.monotonic() - self.clock_wall, self._max_reaction_s)
            self._reaction_s = max(reaction_s, self._reaction_s)

    def _apply(self, linear, angular, at_ns):
        self.model.command(linear, angular)
        self._last_cmd_ns = at_ns

    def _check_publishers(self):
        count = self.count_publishers(self._cmd_topic)
        if count > 1 and not self._warned_publishers:
            self._warned_publishers = True
            self.get_logger().warning(
                f'{count} nodes publish on {self._cmd_topic}: their commands interleave and the '
                'latest one wins')
        elif count <= 1:
            self._warned_publishers = False

    def _on_parameter(self, name, value):
        """Make a live parameter's new value take effect (declare() has checked and stored it)."""
        self._advance_to(self.now_ns())  # up to now, the old value held
        odom = self._odom_msg
        if name == 'cmd_vel_timeout':
            self._timeout_ns = round(value * _NS)
        elif name in ('max_linear_speed', 'max_angular_speed', 'max_linear_accel',
                      'max_angular_accel'):
            self.model.set_limit(name, value)
        elif name == 'pose_covariance_diagonal':
            odom.pose.covariance = _covariance(value)
        elif name == 'twist_covariance_diagonal':
            odom.twist.covariance = _covariance(value)
        elif name in ('odom_frame_id', 'base_frame_id'):
            # As at start: in a namespace the default frame gets its prefix (robot1/odom).
            default = next(spec.default for spec in PARAMETERS if spec.name == name)
            frame = resolve_frame(self.get_namespace(), value, default)
            if name == 'odom_frame_id':
                odom.header.frame_id = frame
                self._path.clear()  # a path is in one frame
            else:
                odom.child_frame_id = frame
        elif name == 'real_time_factor' and self.clock_timer is not None:
            self.step_budget_s = self._step_ns / _NS / value
            period_s = self.step_budget_s
            if self.lockstep_owner is not None:
                period_s = max(period_s, _LOCKSTEP_TICK_S)
            self.clock_timer.timer_period_ns = round(period_s * _NS)
            if not self.clock_timer.is_canceled():  # (the harness steps it instead)
                self.clock_timer.reset()
        elif name == 'path_length':
            self._path = deque(self._path, maxlen=value)  # keeps the newest
        elif name == 'path_rate_hz':
            self._path_every = max(1, round(self.params.rate_hz / value))
        # The others are read where they are used: initial_* by ~/reset, lockstep_timeout by
        # the lockstep owner, max_command_age by the stamped subscription.

    def _on_reset(self, request, response):
        p = self.params
        self._advance_to(self.now_ns())
        self.model.reset(p.initial_x, p.initial_y, p.initial_yaw)
        self._last_cmd_ns = None
        self._early_commands.clear()
        self._path.clear()
        self.get_logger().info('Reset to the initial pose')
        self._publish_odom()
        return response

    # -- odometry ---------------------------------------------------------------------------

    def _publish_odom(self):
        m = self.model
        # One message reused: frames and covariances are set once, in __init__.
        msg = self._odom_msg
        msg.header.stamp = Time(nanoseconds=self._integrated_ns).to_msg()
        msg.pose.pose.position.x = m.x
        msg.pose.pose.position.y = m.y
        q = msg.pose.pose.orientation
        q.x, q.y, q.z, q.w = quaternion_from_yaw(m.yaw)
        msg.twist.twist.linear.x = m.linear
        msg.twist.twist.angular.z = m.angular
        self._odom_pub.publish(msg)
        tf = self._tf.publish(msg) if self._tf is not None else None
        if self.taps:
            self.taps.write(self._odom_pub.topic_name, msg, self._integrated_ns)
            if tf is not None:
                self.taps.write(self._tf.publisher.topic_name, tf, self._integrated_ns)
        if self._odom_count % self._path_every == 0:
            self._record_path(msg)
        if self._odom_count % self._check_every == 0:
            # A graph query per second, not per message: cmd_vel may arrive at kHz rates.
            self._check_publishers()
        self._odom_count += 1

    def _record_path(self, odom):
        # Copied, not referenced: the odometry message is reused for the next publish.
        pose = PoseStamped()
        pose.header.frame_id = odom.header.frame_id
        pose.header.stamp = odom.header.stamp
        pose.pose.position.x = odom.pose.pose.position.x
        pose.pose.position.y = odom.pose.pose.position.y
        pose.pose.orientation.z = odom.pose.pose.orientation.z
        pose.pose.orientation.w = odom.pose.pose.orientation.w
        self._path.append(pose)
        if self._path_pub.get_subscription_count() == 0 and not self.taps.wants_path:
            # Converting a long path to a message is the costliest thing here: skip it unseen.
            return
        path = Path()
        path.header = odom.header
        path.poses = list(self._path)
        self._path_pub.publish(path)
        if self.taps:
            self.taps.write(self._path_pub.topic_name, path, self._integrated_ns)

    def shutdown_hook(self):
        """Close what the taps write (an MCAP file gets its index), whatever ended the run."""
        self.taps.close()

    def destroy_node(self):
        self.taps.close()
        return super().destroy_node()


def main(args=None):
    """Run the simulator until interrupted; returns the exit code."""
    return run(UnicycleSim, args)
