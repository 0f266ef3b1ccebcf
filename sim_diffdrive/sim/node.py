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
The ``unicycle_sim`` node: Twist in on ``cmd_vel``, Odometry out on ``odom``; one robot or many.

The pose is integrated exactly and piecewise: brought up to the moment each command arrives
before the command takes effect, so accuracy does not depend on ``rate_hz``.  The node wires
parameters and topics to the modules beside it (listed in the package docstring).
"""

import re
import time

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from sim_diffdrive.cdr import covariance
from sim_diffdrive.cdr import OdometryLayout
from sim_diffdrive.parameters import declare
from sim_diffdrive.parameters import ParameterError
from sim_diffdrive.parameters import Spec
from sim_diffdrive.runtime import destroyed_if_refused
from sim_diffdrive.runtime import run
from sim_diffdrive.sim.clock import make_clock
from sim_diffdrive.sim.odom_tf import check_frames
from sim_diffdrive.sim.odom_tf import DEFAULT_FRAMES
from sim_diffdrive.sim.odom_tf import OdomTransform
from sim_diffdrive.sim.robot import Robot
from sim_diffdrive.sim.surroundings import open_surroundings
from sim_diffdrive.sim.surroundings import WORLD_PARAMETERS
from sim_diffdrive.sim.world import LIMITS
from sim_diffdrive.sim.world import PlacementError
from sim_diffdrive.sim.world import World
from sim_diffdrive.taps import open_taps
from sim_diffdrive.taps import TAP_PARAMETERS
from std_srvs.srv import Empty

_NS = 1_000_000_000
# How often the graph is asked whether a publisher on a robot's cmd_vel sends another message
# type than the robot takes (its commands never arrive) [wall s].
TYPE_CHECK_S = 2.0
_POSITION_LIMIT = 1e6
# A robot name: relative ROS name tokens (robot1, team_a/robot1).
_ROBOT_NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*')

PARAMETERS = (
    Spec('rate_hz', 50.0, 'Odometry publish rate [Hz]; with publish_clock also the clock step.',
         low=0.0, high=1000.0, low_open=True),
    Spec('cmd_vel_timeout', 0.5,
         'Stop the robot when no cmd_vel arrived for this long [s]; 0 keeps the last command.',
         low=0.0, high=3600.0, live=True),
    Spec('odom_frame_id', DEFAULT_FRAMES['odom_frame_id'],
         'Frame of the odometry pose and the path (REP 105).', live=True),
    Spec('base_frame_id', DEFAULT_FRAMES['base_frame_id'],
         'Child frame of the odometry (REP 105).', live=True),
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
    Spec('robots', [], 'Names of the robots to simulate, each with its own <name>/cmd_vel, '
         '<name>/odom, <name>/path and frames <name>/odom -> <name>/base_footprint; empty: one '
         'robot on cmd_vel and odom.', items=str),
    Spec('initial_poses', [], 'Start poses as x, y, yaw [m, m, rad] per robot, one after the '
         'other; empty: every robot at initial_x, initial_y, initial_yaw.',
         low=-_POSITION_LIMIT, high=_POSITION_LIMIT),
) + WORLD_PARAMETERS + TAP_PARAMETERS


def robot_names(robots):
    """Check the robots parameter; return the names ([''] for one robot without a name)."""
    for name in robots:
        if not _ROBOT_NAME.fullmatch(name):
            raise ParameterError(
                f"parameter 'robots' holds {name!r}, which is not a relative ROS name (letters, "
                'digits and _, not starting with a digit; / between parts)')
    if len(set(robots)) != len(robots):
        twice = sorted({name for name in robots if robots.count(name) > 1})
        raise ParameterError(f"parameter 'robots' names {', '.join(twice)} more than once")
    return list(robots) or ['']


class UnicycleSim(Node):
    """Simulate one unicycle robot, or one per name in ``robots`` (see the module docstring)."""

    def __init__(self, stepped=False, **kwargs):
        """
        Build the simulator; kwargs go to rclpy's Node (context, parameter_overrides, ...).

        stepped: with publish_clock, take no step of its own; the caller calls
        ``self.clock.step()`` (SimGraph does, once the graph has settled).
        """
        super().__init__('unicycle_sim', **kwargs)
        with destroyed_if_refused(self):
            self._build(stepped)

    def _build(self, stepped):
        self.params = declare(self, PARAMETERS, on_change=self._on_parameter)
        p = self.params
        if p.publish_clock and self.get_parameter('use_sim_time').value:
            raise ParameterError("parameter 'publish_clock' is true, so this node owns time: "
                                 "'use_sim_time' must be false for it")
        names = robot_names(p.robots)
        # Of two frames that are one, name one changed from its default (the first such).
        frames = self._frame_values()
        blame = next((spec.name for spec in PARAMETERS if spec.name in frames
                      and frames[spec.name] != spec.default), 'base_frame_id')
        check_frames(self.get_namespace(), names, frames, blame)
        if p.initial_poses and len(p.initial_poses) != 3 * len(names):
            raise ParameterError(
                f"parameter 'initial_poses' must hold x, y, yaw for each of the {len(names)} "
                f'robot(s), {3 * len(names)} values; got {len(p.initial_poses)}')
        self.surroundings = open_surroundings(self, names)
        try:
            self.world = World(self._initial_poses(len(names)), names=names,
                               timeout_ns=round(p.cmd_vel_timeout * _NS),
                               limits={name: getattr(p, name) for name in LIMITS},
                               walls=self.surroundings.walls if self.surroundings else None)
        except PlacementError as error:
            raise ParameterError(f'Cannot start: {error} (initial_x, initial_y, initial_poses '
                                 'or map_file)') from None
        if self.surroundings:
            self._say_who_is_outside_the_map(names)
        self.step_ns = round(_NS / p.rate_hz)
        self.clock = make_clock(self, stepped)
        self.taps = open_taps(self)
        self.robots = [Robot(self, i, name, self.take_command) for i, name in enumerate(names)]
        # A frame is checked against the other's value and the robots' prefixes, which a Spec
        # cannot know; added after declare()'s callbacks, this one runs before them.
        self.add_on_set_parameters_callback(self._refuse_bad_frames)
        self._odometry = self._odometry_layout()
        self._tf = OdomTransform(self, self._frames()) if p.publish_tf else None
        self._path_every = max(1, round(p.rate_hz / p.path_rate_hz))
        self._odom_count = 0
        self._types_checked_at = -TYPE_CHECK_S  # (monotonic time) the first step looks
        self.create_service(Empty, '~/reset', self._on_reset)
        if self.surroundings:
            self.surroundings.start(self._frames(), self.now_ns(), self.taps)
        self.clock.start()
        where = (f"{len(names)} robot{'s' * (len(names) > 1)} ({', '.join(names)})"
                 if p.robots else
                 f'Unicycle at ({p.initial_x:.3f}, {p.initial_y:.3f}, {p.initial_yaw:.3f} rad)')
        self.get_logger().info(
            f'{where}, odom at {p.rate_hz:g} Hz, cmd_vel timeout {p.cmd_vel_timeout:g} s'
            + ((', publishing /clock as its caller steps it' if stepped else
                f', publishing /clock at up to {p.real_time_factor:g}x real time'
                + (' in lockstep' if p.lockstep else ' (free clock)'))
               if p.publish_clock else ', in real time' + (
                   f' (real_time_factor {p.real_time_factor:g} needs publish_clock:=true)'
                   if p.real_time_factor != 1.0 else ''))
            + (f'; in the map {p.map_file} ({self.surroundings.grid.width} x '
               f'{self.surroundings.grid.height} cells of {self.surroundings.grid.resolution:g} '
               f'm), scans at {self.surroundings.scan_rate_hz:g} Hz' if self.surroundings
               else ''))

    def _say_who_is_outside_the_map(self, names):
        """Warn about each robot that starts outside the map: nothing is solid out there."""
        grid = self.surroundings.grid
        for name, x, y in zip(names, *self.world.map_poses()[:2]):
            if outside := grid.outside(float(x), float(y)):
                self.get_logger().warning(f"{f'{name}: ' if name else ''}Starts at ({x:.3f}, "
                                          f'{y:.3f}) in {self.surroundings.map_frame}, {outside}')

    def _initial_poses(self, count):
        p = self.params
        if p.initial_poses:
            return [tuple(p.initial_poses[3 * i:3 * i + 3]) for i in range(count)]
        return [(p.initial_x, p.initial_y, p.initial_yaw)] * count

    # -- time -------------------------------------------------------------------------------

    def now_ns(self):
        """Return the current simulated time in nanoseconds."""
        return self.clock.now_ns()

    def step_to(self, now_ns):
        """Bring every robot up to now_ns and publish what the world says (a clock's step)."""
        self.publish_odom(self.world.step_to(now_ns))

    def take_command(self, robot, data):
        """Hand a command's bytes to its robot; then take the odometry step, if one is due."""
        robot.take(data)
        # A backlog of commands must not hold the odometry back (FollowedClock).
        now_ns = self.clock.take_due_step()
        if now_ns is not None:
            self.step_to(now_ns)

    def _log_events(self):
        """Say what happened in the world since the last look: timeouts, contacts."""
        logger = self.get_logger()
        for kind, i, data in self.world.take_events():
            label = self.robots[i].label
            if kind == 'timeout':
                # When the last command came, on the node's clock: from the outside only the
                # sender's time is known, and a busy machine can hand it over later.
                logger.warning(
                    f'{label}No cmd_vel for {self.params.cmd_vel_timeout:g} s: stopping the '
                    f'robot (the last came at {data // _NS}.{data % _NS:09d} s)')
            else:  # a contact: data is (x, y) in the map, or for a robot (other, drove, x, y)
                what = 'Hit a wall'
                if kind == 'robot':
                    other = self.robots[data[0]].name or 'another robot'
                    what = f'Ran into {other}' if data[1] else f'Was run into by {other}'
                logger.warning(f'{label}{what} at ({data[-2]:.3f}, {data[-1]:.3f}) in '
                               f'{self.surroundings.map_frame}: stopped')

    # -- parameters and reset ---------------------------------------------------------------

    def _on_parameter(self, name, value):
        """Make a live parameter's new value take effect (declare() has checked and stored it)."""
        self.world.step_to(self.now_ns())  # up to now, the old value held
        robots = self.robots
        if name == 'cmd_vel_timeout':
            self.world.set_timeout(round(value * _NS))
        elif name in LIMITS:
            for i in range(len(robots)):
                self.world.set_limit(i, name, value)
        elif name in ('pose_covariance_diagonal', 'twist_covariance_diagonal'):
            self._odometry = self._odometry_layout()
        elif name in ('odom_frame_id', 'base_frame_id'):
            for robot in robots:
                robot.set_frame(name, value)
            self._odometry = self._odometry_layout()
            if self._tf is not None:
                self._tf.set_frames(self._frames())
            if self.surroundings:
                self.surroundings.set_frames(self._frames(), self.now_ns(), self.taps)
        elif name == 'real_time_factor':
            self.clock.set_real_time_factor(value)
        elif name == 'path_length':
            for robot in robots:
                robot.path.resize(value)  # keeps the newest
        elif name == 'path_rate_hz':
            self._path_every = max(1, round(self.params.rate_hz / value))
        # The others are read where they are used: initial_* by ~/reset, lockstep_timeout by
        # the lockstep owner, max_command_age by the stamped subscription.

    def _frame_values(self):
        """Return the frame parameters' values: the robots', and with a map its frames."""
        names = [*DEFAULT_FRAMES, *(('map_frame_id', 'scan_frame_id') if self.params.map_file
                                    else ())]
        return {name: getattr(self.params, name) for name in names}

    def _refuse_bad_frames(self, parameters):
        """Refuse a live set of frames that tf2 could not use; the frames stay as they were."""
        frames = self._frame_values()
        changed = [p.name for p in parameters
                   if p.name in frames and isinstance(p.value, str)]  # else the Spec refuses
        frames.update((p.name, p.value) for p in parameters if p.name in changed)
        try:
            if changed:
                check_frames(self.get_namespace(), [robot.name for robot in self.robots],
                             frames, changed[-1])
        except ParameterError as error:
            return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    def _on_reset(self, request, response):
        self.world.step_to(self.now_ns())  # up to now, the old poses held
        # All at once: a robot may go where another stands that goes elsewhere.
        errors = self.world.reset_all(self._initial_poses(len(self.robots)))
        for i, robot in enumerate(self.robots):
            if i in errors:
                self.get_logger().warning(f'Refusing ~/reset: {errors[i]}; the robot stays '
                                          'where it is')
            else:
                robot.placed()
        refused = len(errors)
        if refused < len(self.robots):
            self.get_logger().info(
                ('Reset every robot to its initial pose' if not refused
                 else f'Reset {len(self.robots) - refused} robot(s) to their initial poses')
                if self.params.robots else 'Reset to the initial pose')
        return response  # the next step's odometry shows it (as an initialpose's)

    # -- odometry ---------------------------------------------------------------------------

    def _frames(self):
        return [robot.frames for robot in self.robots]

    def _odometry_layout(self):
        """Lay every robot's odometry bytes out for the current frames and covariances."""
        p = self.params
        return OdometryLayout(self._frames(), covariance(p.pose_covariance_diagonal),
                              covariance(p.twist_covariance_diagonal))

    def publish_odom(self, odometry=None):
        """Publish every robot's odometry (the world's, by default), /tf, the world's topics."""
        world = self.world
        stamp_ns, x, y, qz, qw, linear, angular = odometry or world.odometry()
        if world.events:  # said before the odometry that shows them goes out
            self._log_events()
        sec, nanosec = divmod(stamp_ns, _NS)
        each = world.one_by_one  # lists of floats; else arrays
        layout = self._odometry
        odometry = layout.serialize(sec, nanosec, x, y, qz, qw, linear, angular)
        robots = self.robots
        for robot, data in zip(robots, odometry):
            robot.odom_pub.publish(data)
        taps = self.taps
        tapping = bool(taps)  # asked once a step
        if tapping:
            for robot, data in zip(robots, odometry):
                taps.write(robot.odom_pub.topic_name, data, stamp_ns)
        if self._tf is not None and self._tf.listened(taps):
            self._tf.publish(stamp_ns, x, y, qz, qw, taps)
        if self.surroundings:
            self.surroundings.publish(stamp_ns, world, taps)
        if tapping:
            taps.step(stamp_ns, world)
        if self._odom_count % self._path_every == 0:
            poses = (x, y, qz, qw) if each else (v.tolist() for v in (x, y, qz, qw))
            for robot, *pose in zip(robots, *poses):
                robot.record_path(stamp_ns, *pose)
        self._odom_count += 1
        if time.monotonic() - self._types_checked_at >= TYPE_CHECK_S:
            self._check_command_types()

    def _check_command_types(self):
        """
        Warn about a publisher on a robot's cmd_vel that sends another type than it takes.

        DDS never matches such a publisher (Nav2 on Jazzy sends TwistStamped, say), so nothing
        of it arrives and no event says so: one look at the whole graph's topics and types
        (about 5 ms with 1024 robots), and a closer one only where a topic has another type.
        """
        self._types_checked_at = time.monotonic()
        types = dict(self.get_topic_names_and_types())
        for robot in self.robots:
            robot.check_command_type(types.get(robot.cmd_topic, ()),
                                     self.get_publishers_info_by_topic)

    def shutdown_hook(self):
        """Close what the taps write (an MCAP file gets its index), whatever ended the run."""
        self.taps.close()

    def destroy_node(self):
        if hasattr(self, 'taps'):  # none yet when refused while being built
            self.taps.close()
        return super().destroy_node()


def main(args=None):
    """Run the simulator until interrupted; returns the exit code."""
    return run(UnicycleSim, args, 'unicycle_sim')
