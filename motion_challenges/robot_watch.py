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
A motion's eye on its robot: waiting for it to be there, then watching that it stays.

Waiting: the robot (the node that publishes the odometry and subscribes cmd_vel, or with
``wait_for_odom`` false any cmd_vel subscriber), the simulator's lockstep, odometry and, on
sim time, the clock, until ``start_timeout``.  Watching, mid-motion: odometry that stops or
comes from two publishers, simulated time that stands still or goes back, a simulator that
went on without the motion.  What the watch finds ends the run through the node.  Odometry
is read from its bytes into the few numbers a motion needs (OdomPose).
"""

import enum
import time

from motion_challenges.controllers import NS as _NS
from motion_challenges.controllers import Pose
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message
from sim_diffdrive.angles import yaw_from_quaternion
from sim_diffdrive.cdr import read_odometry
from sim_diffdrive.cdr import UnsupportedEncoding
from sim_diffdrive.node_names import node_names
from sim_diffdrive.runtime import EXIT_FAILED
from sim_diffdrive.throttle import Throttle

# Odometry stamped this far from a wall-time node's clock, with /clock published, is on
# simulated time [s]: further than any clock skew between two hosts.
_CLOCKS_APART_S = 60.0
# How often the node calls on_watchdog [s, wall time].
WATCHDOG_PERIOD_S = 0.5


class MotionState(str, enum.Enum):
    """Where a motion is (a str too, equal to its value, for code that compares with one)."""

    WAITING = 'waiting'  # for the goal, then for the robot (see RobotWatch.missing)
    RUNNING = 'running'  # control() is called every tick
    SETTLING = 'settling'  # stopped; waiting for odometry that shows where the robot came to rest
    FINISHED = 'finished'  # done or given up: see exit_code


class OdomPose(Pose):
    """The Pose an Odometry message reports (position, yaw, stamp), read from its bytes."""

    def __init__(self, data):
        try:
            stamp_ns, _, _, (x, y, _), orientation, twist = read_odometry(data)
        except UnsupportedEncoding:  # not plain CDR: let rclpy read it
            msg = deserialize_message(data, Odometry)
            p, q, t = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist
            stamp_ns = msg.header.stamp.sec * _NS + msg.header.stamp.nanosec
            x, y, orientation, twist = p.x, p.y, (q.x, q.y, q.z, q.w), (t.linear.x, t.angular.z)
        super().__init__(x, y, yaw_from_quaternion(*orientation), stamp_ns)
        self.twist = twist  # (linear.x, angular.z)


class RobotWatch:
    """
    Waits for a motion node's robot and watches it.

    ``use_odom(odom)`` takes each OdomPose once it is due; ``distrust(why)`` ends the run on
    odometry or a clock that cannot be trusted.
    """

    def __init__(self, node, odom_topic, use_odom, distrust):
        self._node, self._odom_topic = node, odom_topic
        self._use_odom, self._distrust = use_odom, distrust
        self._waiting_log = Throttle(2.0)
        self._odom_wall = None  # when odometry last came [s, monotonic]
        self._wall_start = None  # set by start()
        self._clock_seen_ns = None  # on sim time, the clock as the watchdog last saw it
        self._clock_moved_wall = None  # and when it last saw it move
        self._watched_wall = time.monotonic()  # when on_watchdog last ran
        self._early_odoms = []  # on sim time: odometry not used yet, in stamp order

    def start(self):
        """Start waiting: start_timeout counts from here, not while a user answers questions."""
        self._wall_start = time.monotonic()

    def stop(self):
        """Stop watching (the run has finished): the queued odometry is dropped."""
        self._early_odoms.clear()

    def on_odom(self, msg):
        """Take odometry (bytes): use it now, or on sim time at the first tick after it."""
        node = self._node
        odom = OdomPose(msg)
        self._odom_wall = time.monotonic()
        if node.sim_time and node.state != MotionState.FINISHED:
            # In stamp order (the order it arrives in), through the queue: odometry from before
            # the clock used at once while older odometry still waited for a tick was taken for
            # time going back, after a clock that jumped ahead (a simulator that went on).
            self._early_odoms.append(odom)
            self.take_early_odoms(node.now_ns())
            return
        self._use_odom(odom)

    def take_early_odoms(self, now_ns):
        """Use the queued odometry stamped before now_ns, oldest first."""
        early = self._early_odoms
        while early and early[0].stamp_ns < now_ns and self._node.state != MotionState.FINISHED:
            self._use_odom(early.pop(0))

    def on_time_jump(self, jump):
        """Drop the queue when simulated time goes back; mid-motion, give up."""
        self._early_odoms.clear()
        node = self._node
        if node.state not in (MotionState.RUNNING, MotionState.SETTLING):
            return
        went_back = f'Simulated time went back {-jump.delta.nanoseconds / _NS:.3f} s'
        clock = node.resolve_topic_name('/clock')
        owners = node_names(node.get_publishers_info_by_topic(clock))
        if len(owners) > 1:  # another owner of time, or a restarted one's predecessor
            went_back += f' ({", ".join(owners)} publish on {clock})'
        if node.needs_odom:
            self._distrust(went_back)
        else:  # a timed plan would wait for its clock to come round again and drive it twice
            node.finish(EXIT_FAILED, f'{went_back} mid-motion; stopped the robot rather than '
                                     'drive the plan again from then (simulator restarted?)')

    def missing(self):
        """Return what the motion still waits for, or '' when it can start."""
        node = self._node
        cmd_topic = node.cmd_pub.topic_name
        if node.params.wait_for_odom:
            robot = self._robot_node()
            if robot is None:
                return (f'the robot (a node that publishes {self._odom_topic} and subscribes '
                        f'{cmd_topic})')
            if node.cmd_pub.get_subscription_count() < node.count_subscribers(cmd_topic):
                return f'{cmd_topic} to be matched by {robot}'
        elif node.cmd_pub.get_subscription_count() == 0:
            return f'a subscriber on {cmd_topic}'
        lockstep = node.lockstep
        if lockstep is not None and lockstep.owner_present:
            if not lockstep.joined:
                return 'the simulator to take this node into its lockstep'
            if not lockstep.counted_on(cmd_topic):
                return f'the node that drives on {cmd_topic} to join the lockstep'
        if node.sim_time and node.now_ns() == 0:  # before odometry: it waits for the clock
            clock = node.resolve_topic_name('/clock')
            return f'simulated time on {clock} (use_sim_time is true)'
        if node.odom is None and (node.needs_odom or node.params.wait_for_odom
                                  or node.count_publishers(self._odom_topic)):
            # Without wait_for_odom open loop needs none, but where there is some, the closing
            # line uses it.
            return 'odometry on ' + self._odom_topic
        return ''

    def clock_clash(self, now_ns):
        """Return why this node's wall clock cannot be the robot's, or '' (sim time: '')."""
        node = self._node
        if node.sim_time or node.odom is None:
            return ''
        apart_s = abs(node.odom.stamp_ns - now_ns) / _NS
        clock_topic = node.resolve_topic_name('/clock')
        if apart_s < _CLOCKS_APART_S or not node.count_publishers(clock_topic):
            return ''
        # Judged by stamps and the clock alike, the run would go wrong in ways that point
        # elsewhere (no odometry after the stop, a jump): say what is wrong before moving.
        return (f'Odometry on {self._odom_topic} is stamped {node.odom.stamp_ns / _NS:.3f} s, '
                f"{apart_s:.0f} s from this node's clock (wall time), and {clock_topic} is "
                'published: the robot runs on simulated time. Start this motion with -p '
                'use_sim_time:=true. Nothing moved.')

    def _robot_node(self):
        """Return the name of a node that publishes our odometry and subscribes our cmd_vel."""
        node = self._node
        publishers = node.get_publishers_info_by_topic(self._odom_topic)
        subscribers = node.get_subscriptions_info_by_topic(node.cmd_pub.topic_name)
        return min(set(node_names(publishers)) & set(node_names(subscribers)), default=None)

    def dropped_mid_run(self):
        """Fail, stopping the robot, once the simulator has gone on without this node."""
        node = self._node
        dropped_ns = node.lockstep.dropped_ns if node.lockstep is not None else None
        if dropped_ns is None or dropped_ns < node.start_ns:
            return False  # never, or while waiting to start: nothing was commanded yet
        into_s = (dropped_ns - node.start_ns) / _NS
        node.finish(EXIT_FAILED, f'The simulator went on without this node at '
                                 f'{dropped_ns / _NS:.3f} s, {into_s:.3f} s into the motion, '
                                 'stepping without waiting for its commands; '
                                 'stopped the robot, as the run can no longer end where it should')
        return True

    def on_watchdog(self):
        """Look at the robot (called every WATCHDOG_PERIOD_S on the wall clock)."""
        self._excuse_own_stall(time.monotonic())
        node = self._node
        if node.needs_odom and node.state == MotionState.RUNNING:
            self._watch_odometry()
        elif self._wall_start is not None and node.state == MotionState.WAITING:
            self._watch_start()
        if node.sim_time and node.state in (MotionState.RUNNING, MotionState.SETTLING):
            self._watch_clock()

    def _excuse_own_stall(self, wall):
        """
        Count no silence over wall time this node did not run (its watchdog came late).

        A starved, debugged or paused process heard nothing because it did not look: what was
        sent meanwhile waits in its queues, and the watchdog may run before it is handled.
        """
        stalled = wall - self._watched_wall - WATCHDOG_PERIOD_S
        if stalled > 0.0:
            if self._wall_start is not None:  # nor waiting for the robot: it could not hear it
                self._wall_start = min(self._wall_start + stalled, wall)
            if self._odom_wall is not None:
                self._odom_wall = min(self._odom_wall + stalled, wall)
            if self._clock_moved_wall is not None:
                self._clock_moved_wall = min(self._clock_moved_wall + stalled, wall)
        self._watched_wall = wall

    def _watch_clock(self):
        # On sim time the ticks come with the clock: a simulator that died mid-motion stops
        # them, and an open-loop motion would wait for its next tick forever.
        node = self._node
        now_ns, wall = node.now_ns(), time.monotonic()
        if now_ns != self._clock_seen_ns or self._clock_moved_wall is None:
            self._clock_seen_ns, self._clock_moved_wall = now_ns, wall
            return
        silent = self._silent_since(self._clock_moved_wall, wall)
        if silent > self._silence_allowed_s():
            node.finish(EXIT_FAILED, f'Simulated time stood still at {now_ns / _NS:.3f} s for '
                                     f'{silent:.1f} s mid-motion with no word from the simulator; '
                                     'stopped the robot (is the simulator still running?)')

    def _silence_allowed_s(self):
        """Return odom_timeout, beyond the wall time a step takes in lockstep (its roster)."""
        lockstep = self._node.lockstep
        roster = lockstep.roster if lockstep is not None else None
        # At a real_time_factor of 0.01 each step of 20 ms takes 2 s: no silence of the
        # simulator's, but odometry and the clock come that far apart.
        step_s = roster.step_wall_ns / _NS if roster is not None else 0.0
        return self._node.params.odom_timeout + step_s

    def _silent_since(self, last_wall, wall):
        """Return how long the simulator has said nothing [s]: since last_wall or its roster."""
        lockstep = self._node.lockstep
        if lockstep is not None and lockstep.roster_wall is not None:
            # In lockstep the simulator repeats its roster while it holds the clock for a slow
            # or joining node: odometry is late then because time stands still.
            last_wall = max(last_wall, lockstep.roster_wall)
        return wall - last_wall

    def _watch_odometry(self):
        node = self._node
        publishers = node.count_publishers(self._odom_topic)
        if publishers == 0:  # stopped (restarted, the new one has not come yet)
            node.finish(EXIT_FAILED, f'0 publishers on {self._odom_topic} mid-motion; stopped '
                                     'the robot (is the simulator still running?)')
            return
        if publishers > 1:
            # A simulator restarted after a crash shows up beside its predecessor (gone for
            # good, but still in discovery for a while): its odometry can look continuous when
            # its clock or pose happens to have caught up with the last.
            self._distrust(f'{publishers} publishers on {self._odom_topic} mid-motion')
            return
        silent = self._silent_since(self._odom_wall, time.monotonic())
        if silent > self._silence_allowed_s():
            node.finish(EXIT_FAILED, f'No odometry for {silent:.1f} s mid-motion; stopped '
                                     'the robot (is the simulator still running?)')

    def _watch_start(self):
        node = self._node
        missing = self.missing()
        if not missing:
            return
        waited = time.monotonic() - self._wall_start
        if waited > node.params.start_timeout:
            hint = ('it runs but has not heard this node yet (a slow or lossy link: raise '
                    'start_timeout; a process killed while it ran on this machine can leave '
                    'it deaf to new ones: restart it).' if 'lockstep' in missing else
                    'does unicycle_sim run with -p publish_clock:=true?'
                    if missing.startswith('simulated time') else
                    'is the robot (or unicycle_sim) running?')
            # The start_timeout given, not the watchdog's moment (up to WATCHDOG_PERIOD_S on).
            node.finish(EXIT_FAILED, f'Gave up after start_timeout '
                                     f'({node.params.start_timeout:g} s) waiting for {missing}; '
                                     f'{hint} Nothing moved.')
        elif self._waiting_log.allows():
            node.get_logger().info(f'Waiting for {missing} ...')
