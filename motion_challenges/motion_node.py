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
What every motion node shares: parameters, cmd_vel out, odometry in, a timer-driven state machine.

A motion waits for its robot (RobotWatch), runs on a timer on the node clock (wall or sim time
alike), and ends with a zero Twist and a closing line comparing the goal with what odometry says
was achieved; ``shutdown_hook`` (runtime.run, every exit path) sends the zero Twist again.
"""

import time

from geometry_msgs.msg import Twist
from geometry_msgs.msg import TwistStamped
from motion_challenges.controllers import CommandLog
from motion_challenges.controllers import NS
from motion_challenges.controllers import odometry_fault
from motion_challenges.controllers import Standstill
from motion_challenges.plotting import plot_file_problem
from motion_challenges.plotting import write_plot
from motion_challenges.robot_watch import MotionState
from motion_challenges.robot_watch import RobotWatch
from motion_challenges.robot_watch import WATCHDOG_PERIOD_S
from nav_msgs.msg import Odometry
from rclpy.clock import Clock
from rclpy.clock import ClockType
from rclpy.clock import JumpThreshold
from rclpy.duration import Duration
from rclpy.node import Node
from sim_diffdrive.angles import YawAccumulator
from sim_diffdrive.cdr import twist_message
from sim_diffdrive.lockstep.participant import take_part
from sim_diffdrive.parameters import declare
from sim_diffdrive.parameters import frame_problem
from sim_diffdrive.parameters import Spec
from sim_diffdrive.runtime import destroyed_if_refused
from sim_diffdrive.runtime import EXIT_FAILED
from sim_diffdrive.runtime import EXIT_OK
from sim_diffdrive.throttle import Throttle

# How long to wait for the odometry that shows where the robot came to rest: this many control
# periods, or odom_timeout if longer.
_SETTLE_TICKS = 20
# Every motion declares these besides its own.
COMMON_PARAMETERS = (
    Spec('start_timeout', 10.0,
         'How long to wait for the robot (see wait_for_odom) before giving up [s, wall time], '
         'from when the goal is known (typed).',
         low=0.0, high=3600.0, low_open=True, live=True),
    Spec('wait_for_odom', True,
         'Start only once odometry has come and the node that publishes it subscribes cmd_vel '
         '(the robot). false: any cmd_vel subscriber will do (a robot without odometry); the '
         'open-loop motions then run blind and cannot confirm where the robot ended.'),
    Spec('odom_timeout', 1.0,
         'Stop and fail when no odometry came for this long mid-motion (closed loop), or, on '
         'sim time, when simulated time stood still this long with no word from the simulator '
         "(in lockstep: beyond a step's wall time at its real_time_factor) [s, wall time].",
         low=0.0, high=3600.0, low_open=True, live=True),
    Spec('plot_file', '',
         'Write a PNG of the run here as it ends (a run cut off: as far as it got): the path '
         'beside the heading and the speeds over time; empty = no plot. Needs matplotlib.',
         live=True, problem=plot_file_problem),
    Spec('stamped', False,
         'Publish geometry_msgs/TwistStamped, stamped with the node clock, instead of Twist '
         "(ros2_control's diff_drive_controller takes only TwistStamped)."),
    Spec('frame_id', 'base_footprint', 'Frame of the commands (stamped).', live=True,
         problem=frame_problem),
)
# How a motion's closing line starts when it reached its goal.
DONE = 'Done in '


def rate_spec(default):
    """Return the control rate parameter, rate_hz, with the motion's default."""
    return Spec('rate_hz', default, 'Control rate [Hz] of the timer that publishes cmd_vel.',
                low=0.0, high=1000.0, low_open=True)


def closing_for(sim_s, wall_s, achieved, measured, wait_for_odom):
    """
    Return (exit code, closing line) of a run that stopped sim_s [s] (wall_s wall) after its start.

    measured: whether odometry came after the stop.
    """
    if measured:
        return EXIT_OK, f'{DONE}{sim_s:.3f} s ({wall_s:.3f} s wall): {achieved}'
    if not wait_for_odom:
        return EXIT_OK, (f'Sent the whole plan in {sim_s:.3f} s ({wall_s:.3f} s wall) to a '
                         f'robot without odometry: {achieved}')
    return EXIT_FAILED, (f'Stopped after {sim_s:.3f} s, but no odometry came after the stop: '
                         'where the robot ended is unknown (is the simulator still running?)')


class MotionNode(Node):
    """
    Base class: subclasses set ``needs_odom`` and implement ``begin``, ``control``, ``summary``.

    ``control(now_ns)`` returns (linear, angular) to publish each tick, or None when done.  On
    sim time the node takes part in the lockstep on its own or through ``participant``.
    """

    needs_odom = False
    # The robot's (linear, angular) acceleration limits: its speed ramps towards each command
    # at them (0: it takes a command at once), as the closed loops predict (CommandLog).
    robot_accel = (0.0, 0.0)
    # How long shutdown_hook waits for the final stop to be acknowledged [s, wall time], and
    # whether it plots: a fleet sets 0 and False, and waits once for all, then plots them.
    stop_ack_timeout, plots_itself = 0.2, True

    def __init__(self, node_name, specs, participant=None, **kwargs):
        super().__init__(node_name, **kwargs)
        with destroyed_if_refused(self):
            self.params = declare(self, tuple(specs) + COMMON_PARAMETERS)
        self.period = 1.0 / self.params.rate_hz
        self.cmd_pub = self.create_publisher(
            TwistStamped if self.params.stamped else Twist, 'cmd_vel', 10)
        self.watch = RobotWatch(self, self.resolve_topic_name('odom'), self._use_odom,
                                self._distrust)
        # As bytes: rclpy's Odometry object costs about 100 us a message; a motion reads five.
        self.create_subscription(Odometry, 'odom', self.watch.on_odom, 50, raw=True)
        self._progress_log = Throttle(1.0)  # a progress line a second
        self._logged = None
        self.run_odoms = []  # the OdomPose of each odometry while running or settling
        self.sent_commands = []  # for plot_file: (time_ns, linear, angular) of each command
        self.turned = YawAccumulator()
        self.commands = CommandLog()
        self._standstill = Standstill()
        self.state = MotionState.WAITING
        self.done = self._primed = self._plotted = False
        self.odom = self.start_odom = self.exit_code = self.start_ns = None
        self._stop_ns = self._wall_begun = self._tick_timer = self.plot_end = None
        self.ending = 'stopped before the end'  # until finish() says how it ended (its plot)
        # Waiting is timed on the wall clock: on sim time, node timers do not fire until the
        # simulator publishes /clock, and a missing simulator is exactly what to report.
        self._watchdog = self.create_timer(WATCHDOG_PERIOD_S, self.watch.on_watchdog,
                                           clock=Clock(clock_type=ClockType.STEADY_TIME))
        # A restarted simulator's clock starts again from zero, and its first odometry may
        # reach us only once its time has passed the last we had: watch the clock itself.
        self._time_jump = self.get_clock().create_jump_callback(
            JumpThreshold(min_forward=None, min_backward=Duration(nanoseconds=-1),
                          on_clock_change=False), post_callback=self.watch.on_time_jump)
        # On sim time: take part in the simulator's lockstep, and act at each tick on the
        # odometry measured before it, so that the decision never depends on whether this
        # step's odometry or clock crossed the graph first (runs are bit-identical).
        self.sim_time = self.get_parameter('use_sim_time').value
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

    def ready(self):
        """Start waiting for the robot and then move (called once the goal is known)."""
        self.watch.start()
        self._tick_timer = self.create_timer(self.period, self._on_tick)

    def finish(self, exit_code, message):
        self.stop_robot()
        log = self.get_logger().info if exit_code == EXIT_OK else self.get_logger().error
        log(message)
        self.state = MotionState.FINISHED
        self.watch.stop()
        self.exit_code = exit_code
        self.done = True
        self.ending = message
        for timer in (self._tick_timer, self._watchdog):
            if timer is not None:
                timer.cancel()
        if not (self.lockstep and self.lockstep.owner_present):  # no clock waits for this node
            self._plot()

    def shutdown_hook(self):
        """Leave the robot stopped, whatever ended the run; then plot it (unless in a fleet)."""
        if self.context.ok():
            self.stop_robot()
            said_goodbye = (self.lockstep is None
                            or self.lockstep.leave(ack_timeout=self.stop_ack_timeout))
            # Fast DDS sends within publish(); its acknowledgement waits for a heartbeat that
            # can be seconds away, so only a short wait covers a resend on a lossy link.
            if self.stop_ack_timeout > 0.0:
                readers = self.cmd_pub.get_subscription_count()  # with none, all is acknowledged
                stopped = self.cmd_pub.wait_for_all_acked(Duration(seconds=self.stop_ack_timeout))
                unheard = ' and '.join(what for what, heard in (
                    ('the final stop', stopped), ('the lockstep goodbye', said_goodbye))
                    if not heard)
                if unheard:
                    self.get_logger().warning(
                        f'Not acknowledged within {self.stop_ack_timeout:g} s: {unheard} (a '
                        'subscriber is gone or stalled, or the link is lossy)')
                else:
                    self.get_logger().debug(
                        f'Final stop acknowledged by the {readers} subscriber(s) of cmd_vel')
        else:
            self.get_logger().warning('ROS was shut down before the final stop could be sent '
                                      '(a stop sent before stands)')
        self._plot()  # once the simulator no longer waits for this node

    def _plot(self):
        if self.plots_itself and not self._plotted:
            self._plotted = True
            write_plot(self)

    def now_ns(self):
        return self.get_clock().now().nanoseconds

    def publish_command(self, linear, angular):
        linear, angular = float(linear), float(angular)
        if self.cmd_pub.msg_type is TwistStamped:  # stamped:=true
            msg = TwistStamped()
            msg.twist.linear.x = linear
            msg.twist.angular.z = angular
            msg.header.stamp = self.get_clock().now().to_msg()
            msg.header.frame_id = self.params.frame_id
            self.cmd_pub.publish(msg)
        else:
            # As CDR bytes: building a Twist and rclpy's conversion of it cost ~40 us a command.
            self.cmd_pub.publish(twist_message(linear, angular))
        now_ns = self.now_ns()
        self.commands.add(now_ns, linear, angular)
        if self.state in (MotionState.RUNNING, MotionState.SETTLING):
            self.sent_commands.append((now_ns, linear, angular))

    def stop_robot(self):
        self.publish_command(0.0, 0.0)

    def predict(self, now_ns):
        """Return the robot's (metres, radians) since the latest odometry, and speeds now."""
        return self.commands.predict(self.odom.stamp_ns, now_ns, self.odom.twist, self.robot_accel)

    def progress(self, text, phase=False):
        """Log text, called each tick: a line a second at most; a new phase (phase) at once."""
        if text != self._logged if phase else self._progress_log.allows():
            self._logged = text
            self.get_logger().info(text)

    def _use_odom(self, odom):
        if self.needs_odom and self.state == MotionState.RUNNING and self.odom is not None:
            fault = odometry_fault(self.odom, odom, self.commands,
                                   velocity=self.odom.twist, accel=self.robot_accel)
            if fault:
                self._distrust(fault)
                return
            stuck = self._standstill.update(self.odom, odom, self.commands,
                                            velocity=self.odom.twist, accel=self.robot_accel)
            if stuck:
                self.odom = odom
                self.finish(EXIT_FAILED, stuck + '; stopped the robot')
                return
        self.odom = odom
        self.turned.update(odom.yaw)
        # Nothing before the latest odometry is asked for again (see predict).
        self.commands.forget_before(odom.stamp_ns)
        if self.state in (MotionState.RUNNING, MotionState.SETTLING):
            self.run_odoms.append(odom)

    def _distrust(self, why):
        self.finish(EXIT_FAILED, f'{why}; stopped the robot rather than drive on odometry that '
                                 'cannot be trusted (simulator restarted?)')

    def _on_tick(self):
        now_ns = self.now_ns()
        if now_ns == 0:
            return
        self.watch.take_early_odoms(now_ns)
        if (self.state in (MotionState.RUNNING, MotionState.SETTLING)
                and self.watch.dropped_mid_run()):
            return
        if self.state == MotionState.WAITING:
            if self.watch.missing():
                return
            clash = self.watch.clock_clash(now_ns)
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

    def _settle(self, now_ns):
        fresh = self.odom is not None and self.odom.stamp_ns > self._stop_ns
        # Long enough for a robot whose odometry is much slower than the control rate; on the
        # node clock, so a loaded machine on sim time waits no less.
        waited = (now_ns - self._stop_ns) / NS > max(_SETTLE_TICKS * self.period,
                                                     self.params.odom_timeout)
        if fresh or waited or self.start_odom is None:
            sim_s = (self._stop_ns - self.start_ns) / NS
            wall_s = time.monotonic() - self._wall_begun
            end_odom = self.odom if fresh else None
            achieved = self.summary(end_odom)
            self.plot_end = end_odom, achieved
            self.finish(*closing_for(sim_s, wall_s, achieved, end_odom is not None,
                                     self.params.wait_for_odom))

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
