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
What every motion node shares: cmd_vel out, odometry in, a timer-driven state machine.

A motion waits until its robot is there: odometry has come, and the node that publishes it
(the robot) is matched on cmd_vel, so a logger or a bridge listening to cmd_vel is not taken
for the robot; with ``wait_for_odom`` false, any cmd_vel subscriber will do.  Then it runs
on a timer on the node clock, so it works on wall time and on sim time alike, and finishes by
publishing a zero Twist and one closing line that compares the goal with what odometry says was
achieved.  ``shutdown_hook`` (called by runtime.run on every exit
path) publishes the zero Twist again, so Ctrl-C or SIGTERM mid-motion stops the robot.

The laws themselves are plain code: the closed loops, the lag compensation (CommandLog) and the
odometry checks in controllers.py, the open-loop plans in plans.py (see timed_motion.py).
"""

import enum
import time

from geometry_msgs.msg import Twist
from geometry_msgs.msg import TwistStamped
from motion_challenges.controllers import CommandLog
from motion_challenges.controllers import odometry_fault
from motion_challenges.odometry import OdomPose
from motion_challenges.specs import COMMON_PARAMETERS
from nav_msgs.msg import Odometry
from rclpy.clock import Clock
from rclpy.clock import ClockType
from rclpy.clock import JumpThreshold
from rclpy.duration import Duration
from rclpy.node import Node
from sim_diffdrive.angles import YawAccumulator
from sim_diffdrive.lockstep.participant import take_part
from sim_diffdrive.node_names import node_names
from sim_diffdrive.parameters import declare
from sim_diffdrive.runtime import destroyed_if_refused
from sim_diffdrive.runtime import EXIT_FAILED
from sim_diffdrive.runtime import EXIT_OK
from sim_diffdrive.throttle import Throttle

_NS = 1_000_000_000
# How long to wait for the odometry that shows where the robot came to rest: this many control
# periods, or odom_timeout if longer.
_SETTLE_TICKS = 20
# Odometry stamped this far from a wall-time node's clock, with /clock published, is on
# simulated time [s]: further than any clock skew between two hosts.
_CLOCKS_APART_S = 60.0


# How a motion's closing line starts when it reached its goal (closing_line finds it).
DONE = 'Done in '


def closing_line(output):
    """Return a motion's closing line ('Done in ...') from its output, or its last error line."""
    lines = output.splitlines()
    for line in reversed(lines):
        if DONE in line:
            return line
    for line in reversed(lines):
        if '[ERROR]' in line or 'Error' in line:
            return line
    return lines[-1] if lines else ''


class MotionState(str, enum.Enum):
    """Where a motion is (a str too, equal to its value, for code that compares with one)."""

    WAITING = 'waiting'  # for the goal, then for the robot (see MotionNode._missing)
    RUNNING = 'running'  # control() is called every tick
    SETTLING = 'settling'  # stopped; waiting for odometry that shows where the robot came to rest
    FINISHED = 'finished'  # done or given up: see exit_code


class MotionNode(Node):
    """
    Base class: subclasses set ``needs_odom`` and implement ``begin``, ``control``, ``summary``.

    ``control(now_ns)`` is called every tick once started; it returns (linear, angular) to
    publish, or None when the motion is complete.  On sim time it takes part in the
    simulator's lockstep, on its own or, given ``participant``, answering with that
    participant's other nodes (motion_fleet.py: one answer per step for a whole fleet).
    """

    needs_odom = False
    # The robot's (linear, angular) acceleration limits: its speed ramps towards each command
    # at them (0: it takes a command at once), as the closed loops predict (CommandLog).
    robot_accel = (0.0, 0.0)
    # How long shutdown_hook waits for the final stop to be acknowledged [s, wall time]; a
    # fleet of motions in one process sets 0 and waits once for all (motion_fleet.py).
    stop_ack_timeout = 0.2

    def __init__(self, node_name, specs, participant=None, **kwargs):
        super().__init__(node_name, **kwargs)
        with destroyed_if_refused(self):
            self.params = declare(self, tuple(specs) + COMMON_PARAMETERS)
        self.period = 1.0 / self.params.rate_hz
        self.cmd_pub = self.create_publisher(
            TwistStamped if self.params.stamped else Twist, 'cmd_vel', 10)
        # As bytes: rclpy's Odometry object costs about 100 us a message, a motion needs five
        # numbers of it (OdomPose).
        self._odom_topic = self.create_subscription(
            Odometry, 'odom', self._on_odom, 50, raw=True).topic_name
        self.odom = None
        self._odom_wall = None
        self._progress_log = Throttle(1.0)  # a progress line a second
        self._waiting_log = Throttle(2.0)
        self.run_odoms = []  # the OdomPose of each odometry while running or settling
        self.sent_commands = []  # for plot_file: (time_ns, linear, angular) of each command
        self.start_odom = None
        self.turned = YawAccumulator()
        self.commands = CommandLog()
        self.state = MotionState.WAITING
        self.done = False
        self.exit_code = None
        self.start_ns = None
        self._stop_ns = None
        self._wall_start = None
        self._wall_begun = None
        self._ready = False
        self._primed = False
        self._tick_timer = None
        # Waiting is timed on the wall clock: on sim time, node timers do not fire until the
        # simulator publishes /clock, and a missing simulator is exactly what to report.
        self._watchdog = self.create_timer(
            0.5, self._on_watchdog, clock=Clock(clock_type=ClockType.STEADY_TIME))
        # On sim time, the clock as the watchdog last saw it, and when it last saw it move.
        self._clock_seen_ns = None
        self._clock_moved_wall = None
        # A restarted simulator's clock starts again from zero, and its first odometry may
        # reach us only once its time has passed the last we had: watch the clock itself.
        self._time_jump = self.get_clock().create_jump_callback(
            JumpThreshold(min_forward=None, min_backward=Duration(nanoseconds=-1),
                          on_clock_change=False), post_callback=self._on_time_jump)
        # On sim time: take part in the simulator's lockstep, and act at each tick on the
        # odometry measured before it, so that the decision never depends on whether this
        # step's odometry or clock crossed the graph first (runs are bit-identical).
        self.sim_time = self.get_parameter('use_sim_time').value
        self._early_odoms = []
        self.lockstep = None if not self.sim_time else (
            participant.add(self) if participant is not None and participant.can_add(self)
            else take_part(self))

    @property
    def trajectory(self):
        """Return (x, y, yaw) of each odometry while running or settling."""
        return [(o.x, o.y, o.yaw) for o in self.run_odoms]

    @property
    def odometry_samples(self):
        """Return (stamp_ns, yaw, linear, angular) of the same odometry, for plot_file."""
        return [(o.stamp_ns, o.yaw, *o.twist) for o in self.run_odoms]

    # -- lifecycle ---------------------------------------------------------------------------

    def ready(self):
        """Start waiting for the robot and then move (called once the goal is known)."""
        # start_timeout counts from here: a user answering questions is not a missing robot.
        self._wall_start = time.monotonic()
        self._ready = True
        self._tick_timer = self.create_timer(self.period, self._on_tick)

    def finish(self, exit_code, message=None):
        self.stop_robot()
        if message:
            log = self.get_logger().info if exit_code == EXIT_OK else self.get_logger().error
            log(message)
        self.state = MotionState.FINISHED
        self._early_odoms.clear()
        self.exit_code = exit_code
        self.done = True
        for timer in (self._tick_timer, self._watchdog):
            if timer is not None:
                timer.cancel()

    def shutdown_hook(self):
        """Leave the robot stopped, whatever ended the run."""
        if self.context.ok():
            self.stop_robot()
            said_goodbye = True
            if self.lockstep is not None:
                said_goodbye = self.lockstep.leave(ack_timeout=self.stop_ack_timeout)
            # Fast DDS sends within publish(); its acknowledgement waits for a heartbeat that
            # can be seconds away, so only a short wait covers a resend on a lossy link.
            if self.stop_ack_timeout > 0.0:
                stopped = self.cmd_pub.wait_for_all_acked(Duration(seconds=self.stop_ack_timeout))
                unheard = ' and '.join(what for what, heard in (
                    ('the final stop', stopped), ('the lockstep goodbye', said_goodbye))
                    if not heard)
                if unheard:
                    self.get_logger().warning(
                        f'Not acknowledged within {self.stop_ack_timeout:g} s: {unheard} (a '
                        'subscriber is gone or stalled, or the link is lossy)')

    # -- helpers for subclasses --------------------------------------------------------------

    def now_ns(self):
        return self.get_clock().now().nanoseconds

    def publish_command(self, linear, angular):
        twist = Twist()
        twist.linear.x = float(linear)
        twist.angular.z = float(angular)
        if self.params.stamped:
            msg = TwistStamped(twist=twist)
            msg.header.stamp = self.get_clock().now().to_msg()
            msg.header.frame_id = self.params.frame_id
        else:
            msg = twist
        self.cmd_pub.publish(msg)
        now_ns = self.now_ns()
        self.commands.add(now_ns, linear, angular)
        if self.state in (MotionState.RUNNING, MotionState.SETTLING):
            self.sent_commands.append((now_ns, float(linear), float(angular)))

    def stop_robot(self):
        self.publish_command(0.0, 0.0)

    def predict(self, now_ns):
        """Return the robot's (metres, radians) since the latest odometry, and speeds now."""
        return self.commands.predict(self.odom.stamp_ns, now_ns, self.odom.twist,
                                     self.robot_accel)

    def progress(self, text):
        """Log text, called each tick: a line a second at most (sim_diffdrive/throttle.py)."""
        if self._progress_log.allows():
            self.get_logger().info(text)

    # -- callbacks ---------------------------------------------------------------------------

    def _on_odom(self, msg):
        odom = OdomPose(msg)
        self._odom_wall = time.monotonic()
        if self.sim_time and self.state != MotionState.FINISHED:
            # In stamp order (the order it arrives in), through the queue: odometry from before
            # the clock used at once while older odometry still waited for a tick was taken for
            # time going back, after a clock that jumped ahead (a simulator that went on).
            self._early_odoms.append(odom)
            self._take_early_odoms(self.now_ns())
            return
        self._use_odom(odom)

    def _take_early_odoms(self, now_ns):
        early = self._early_odoms
        while early and early[0].stamp_ns < now_ns and self.state != MotionState.FINISHED:
            self._use_odom(early.pop(0))

    def _use_odom(self, odom):
        if self.needs_odom and self.state == MotionState.RUNNING and self.odom is not None:
            fault = odometry_fault(self.odom, odom, self.commands,
                                   velocity=self.odom.twist, accel=self.robot_accel)
            if fault:
                self._distrust(fault)
                return
        self.odom = odom
        self.turned.update(odom.yaw)
        # Nothing before the latest odometry is asked for again (see predict).
        self.commands.forget_before(odom.stamp_ns)
        if self.state in (MotionState.RUNNING, MotionState.SETTLING):
            self.run_odoms.append(odom)

    def _on_time_jump(self, jump):
        self._early_odoms.clear()
        if self.needs_odom and self.state == MotionState.RUNNING:
            self._distrust(f'Simulated time went back {-jump.delta.nanoseconds / _NS:.3f} s')

    def _distrust(self, why):
        self.finish(EXIT_FAILED, f'{why}; stopped the robot rather than drive on odometry that '
                                 'cannot be trusted (simulator restarted?)')

    def _missing(self):
        """Return what the motion still waits for, or '' when it can start."""
        cmd_topic = self.cmd_pub.topic_name
        if self.params.wait_for_odom:
            robot = self._robot_node()
            if robot is None:
                return (f'the robot (a node that publishes {self._odom_topic} and subscribes '
                        f'{cmd_topic})')
            if self.cmd_pub.get_subscription_count() < self.count_subscribers(cmd_topic):
                return f'{cmd_topic} to be matched by {robot}'
        elif self.cmd_pub.get_subscription_count() == 0:
            return f'a subscriber on {cmd_topic}'
        lockstep = self.lockstep
        if lockstep is not None and lockstep.owner_present:
            if not lockstep.joined:
                return 'the simulator to take this node into its lockstep'
            if not lockstep.counted_on(cmd_topic):
                return f'the node that drives on {cmd_topic} to join the lockstep'
        if self.odom is None and (self.needs_odom or self.params.wait_for_odom
                                  or self.count_publishers(self._odom_topic)):
            # Without wait_for_odom open loop needs none, but where there is some, the closing
            # line uses it.
            return 'odometry on ' + self._odom_topic
        return ''

    def _clock_clash(self, now_ns):
        """Return why this node's wall clock cannot be the robot's, or '' (sim time: '')."""
        if self.sim_time or self.odom is None:
            return ''
        apart_s = abs(self.odom.stamp_ns - now_ns) / _NS
        clock_topic = self.resolve_topic_name('/clock')
        if apart_s < _CLOCKS_APART_S or not self.count_publishers(clock_topic):
            return ''
        # Judged by stamps and the clock alike, the run would go wrong in ways that point
        # elsewhere (no odometry after the stop, a jump): say what is wrong before moving.
        return (f'Odometry on {self._odom_topic} is stamped {self.odom.stamp_ns / _NS:.3f} s, '
                f"{apart_s:.0f} s from this node's clock (wall time), and {clock_topic} is "
                'published: the robot runs on simulated time. Start this motion with -p '
                'use_sim_time:=true. Nothing moved.')

    def _robot_node(self):
        """Return the name of a node that publishes our odometry and subscribes our cmd_vel."""
        publishers = self.get_publishers_info_by_topic(self._odom_topic)
        subscribers = self.get_subscriptions_info_by_topic(self.cmd_pub.topic_name)
        robots = set(node_names(publishers)) & set(node_names(subscribers))
        return min(robots) if robots else None

    def _on_watchdog(self):
        if self.needs_odom and self.state == MotionState.RUNNING:
            self._watch_odometry()
        elif self._ready and self.state == MotionState.WAITING:
            self._watch_start()
        if self.sim_time and self.state in (MotionState.RUNNING, MotionState.SETTLING):
            self._watch_clock()

    def _watch_clock(self):
        # On sim time the ticks come with the clock: a simulator that died mid-motion stops
        # them, and an open-loop motion would wait for its next tick forever.
        now_ns, wall = self.now_ns(), time.monotonic()
        if now_ns != self._clock_seen_ns or self._clock_moved_wall is None:
            self._clock_seen_ns, self._clock_moved_wall = now_ns, wall
            return
        last_sign = self._clock_moved_wall
        if self.lockstep is not None and self.lockstep.roster_wall is not None:
            last_sign = max(last_sign, self.lockstep.roster_wall)  # as in _watch_odometry
        silent = wall - last_sign
        if silent > self.params.odom_timeout:
            self.finish(EXIT_FAILED, f'Simulated time stood still at {now_ns / _NS:.3f} s for '
                                     f'{silent:.1f} s mid-motion with no word from the '
                                     'simulator; stopped the robot (is the simulator still '
                                     'running?)')

    def _watch_odometry(self):
        publishers = self.count_publishers(self._odom_topic)
        if publishers != 1:
            # A simulator restarted after a crash shows up beside its predecessor (gone for
            # good, but still in discovery for a while): its odometry can look continuous when
            # its clock or pose happens to have caught up with the last.
            self._distrust(f'{publishers} publishers on {self._odom_topic} mid-motion')
            return
        last_sign = self._odom_wall
        if self.lockstep is not None and self.lockstep.roster_wall is not None:
            # In lockstep the simulator repeats its roster while it holds the clock for a slow
            # or joining node: odometry is late then because time stands still.
            last_sign = max(last_sign, self.lockstep.roster_wall)
        silent = time.monotonic() - last_sign
        if silent > self.params.odom_timeout:
            self.finish(EXIT_FAILED, f'No odometry for {silent:.1f} s mid-motion; stopped '
                                     'the robot (is the simulator still running?)')

    def _watch_start(self):
        missing = self._missing()
        if not missing and self.get_parameter('use_sim_time').value and self.now_ns() == 0:
            missing = 'simulated time on /clock (use_sim_time is true)'
        if not missing:
            return
        waited = time.monotonic() - self._wall_start
        if waited > self.params.start_timeout:
            hint = ('it runs but has not heard this node yet (a slow or lossy link: raise '
                    'start_timeout; a process killed while it ran on this machine can leave '
                    'it deaf to new ones: restart it).' if 'lockstep' in missing else
                    'is the robot (or unicycle_sim) running?')
            self.finish(EXIT_FAILED, f'Gave up after {waited:.1f} s waiting for {missing}; '
                                     f'{hint} Nothing moved.')
        elif self._waiting_log.allows():
            self.get_logger().info(f'Waiting for {missing} ...')

    def _on_tick(self):
        now_ns = self.now_ns()
        if now_ns == 0:
            return
        self._take_early_odoms(now_ns)
        if self.state in (MotionState.RUNNING, MotionState.SETTLING) and self._dropped_mid_run():
            return
        if self.state == MotionState.WAITING:
            if self._missing():
                return
            clash = self._clock_clash(now_ns)
            if clash:
                self.finish(EXIT_FAILED, clash)
                return
            if not self._primed:
                # A first message on a new connection can take several times longer than the
                # next ones; a zero Twist one tick early keeps the first real command on time.
                self.stop_robot()
                self._primed = True
                return
            self.state = MotionState.RUNNING
            self.start_ns = now_ns
            self._wall_begun = time.monotonic()
            self.start_odom = self.odom
            self.turned.reset(self.odom.yaw if self.odom else None)
            self.begin(now_ns)
        if self.state == MotionState.RUNNING:
            command = self.control(now_ns)
            if command is not None:
                self.publish_command(*command)
                return
            self.stop_robot()
            self.state = MotionState.SETTLING
            self._stop_ns = now_ns
        if self.state == MotionState.SETTLING:
            self._settle(now_ns)

    def _dropped_mid_run(self):
        """Fail, stopping the robot, once the simulator has gone on without this node."""
        dropped_ns = self.lockstep.dropped_ns if self.lockstep is not None else None
        if dropped_ns is None or dropped_ns < self.start_ns:
            return False  # never, or while waiting to start: nothing was commanded yet
        into_s = (dropped_ns - self.start_ns) / _NS
        self.finish(EXIT_FAILED, f'The simulator went on without this node at '
                                 f'{dropped_ns / _NS:.3f} s, {into_s:.3f} s into the motion, '
                                 'stepping without waiting for its commands; '
                                 'stopped the robot, as the run can no longer end where it should')
        return True

    def _settle(self, now_ns):
        # Report the pose from odometry measured after the stop took effect, if there is any.
        fresh = self.odom is not None and self.odom.stamp_ns > self._stop_ns
        # Long enough for a robot whose odometry is much slower than the control rate; on the
        # node clock, so a loaded machine on sim time waits no less.
        waited = (now_ns - self._stop_ns) / _NS > max(_SETTLE_TICKS * self.period,
                                                      self.params.odom_timeout)
        if fresh or waited or self.start_odom is None:
            sim_s = (self._stop_ns - self.start_ns) / _NS
            wall_s = time.monotonic() - self._wall_begun
            end_odom = self.odom if fresh else None
            achieved = self.summary(end_odom)
            if end_odom is not None:
                self.finish(EXIT_OK, f'{DONE}{sim_s:.3f} s ({wall_s:.3f} s wall): {achieved}')
            elif not self.params.wait_for_odom:
                self.finish(EXIT_OK, f'Sent the whole plan in {sim_s:.3f} s ({wall_s:.3f} s '
                                     f'wall) to a robot without odometry: {achieved}')
            else:
                self.finish(EXIT_FAILED, f'Stopped after {sim_s:.3f} s, but no odometry came '
                                         'after the stop: where the robot ended is unknown '
                                         '(is the simulator still running?)')
            if self.params.plot_file:
                self._plot(end_odom, achieved)

    def _plot(self, end_odom, achieved):
        from motion_challenges.plotting import plot_run
        from motion_challenges.plotting import time_series
        start = self.start_odom
        goal = self.goal_pose(start) if start else None
        # The odometry the motion started on comes first: the heading starts from its yaw.
        odometry = ([(start.stamp_ns, start.yaw, *start.twist)] if start else []) + [
            s for s in self.odometry_samples if not start or s[0] > start.stamp_ns]
        try:
            plot_run(self.params.plot_file, self.trajectory,
                     start=(start.x, start.y, start.yaw) if start else None,
                     end=(end_odom.x, end_odom.y, end_odom.yaw) if end_odom else None,
                     goal=goal, title=f'{self.get_name()}: {achieved}',
                     series=time_series(odometry, self.sent_commands, self.start_ns,
                                        goal[2] if goal else None))
        except (ImportError, OSError) as error:
            self.get_logger().error(f'Could not write plot_file: {error}')
            return
        self.get_logger().info(f'Wrote {self.params.plot_file}')

    # -- for subclasses ----------------------------------------------------------------------

    def begin(self, now_ns):
        """Prepare the motion; called on the first tick once the robot is there."""

    def control(self, now_ns):
        raise NotImplementedError

    def goal_pose(self, start):
        """Return the pose (x, y, yaw) the motion should end at, starting from start."""
        raise NotImplementedError

    def summary(self, end_odom):
        """Return the closing line's goal-versus-achieved text (end_odom may be None)."""
        if self.start_odom is None or end_odom is None:
            return 'no odometry, achieved pose unknown'
        return end_odom.error_text(*self.goal_pose(self.start_odom))
