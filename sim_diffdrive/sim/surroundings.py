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
The world around the robots on the ROS side: the map, the laser scans, map -> odom.

With ``map_file`` the robots drive in a map_server map, as in Nav2's loopback simulator
(docs/world.md): the map on ``map``, each robot's LaserScan, map -> odom on ``/tf`` and base
-> scan on ``/tf_static``.  The geometry is ROS-free (sim_diffdrive/world/).
"""

import array
import math

from geometry_msgs.msg import TransformStamped
from nav_msgs.msg import OccupancyGrid
import numpy as np
from rclpy.qos import DurabilityPolicy
from rclpy.qos import QoSProfile
from rclpy.time import Time
from sensor_msgs.msg import LaserScan
from sim_diffdrive.angles import quaternion_from_yaw
from sim_diffdrive.parameters import ParameterError
from sim_diffdrive.parameters import Spec
from sim_diffdrive.sim.odom_tf import OdomTransform
from sim_diffdrive.sim.odom_tf import published_frame
from sim_diffdrive.world.contact import Walls
from sim_diffdrive.world.grid import load_map
from sim_diffdrive.world.grid import MapError
from sim_diffdrive.world.scan import Scanner
from std_msgs.msg import Header
from tf2_msgs.msg import TFMessage

# As map_server's map and tf2_ros's StaticTransformBroadcaster: reliable, kept for late comers.
LATCHED_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
# Reliable: it serves Nav2's best-effort (SensorDataQoS) subscribers as well.
SCAN_QOS = QoSProfile(depth=10)

WORLD_PARAMETERS = (
    Spec('map_file', '', 'A map_server YAML (image, resolution, origin, negate, '
         'occupied_thresh, free_thresh, mode): the robots drive in that map, stop at its walls '
         'and at each other, and scan it; empty = the empty plane (no walls, no scan).'),
    Spec('map_frame_id', 'map', 'Frame of the map (REP 105), shared by every robot: map -> '
         "each robot's odometry frame goes on /tf; initialpose may be given in it."),
    Spec('publish_map_odom_tf', True, 'With map_file: publish map -> odom on /tf; false when '
         'a localization (AMCL, say) publishes it.'),
    Spec('robot_radius', 0.105, "Radius of a robot's disc [m] (with map_file): it stops where "
         'the disc touches a wall or another robot.', low=0.0, high=100.0, low_open=True),
    Spec('scan_rate_hz', 10.0, "LaserScan rate on each robot's scan [Hz] (with map_file): "
         'the nearest of rate_hz over a whole number of steps; 0 = no scan.', low=0.0,
         high=1000.0),
    Spec('scan_beams', 360, 'Beams per scan, over the full turn counter-clockwise from -pi.',
         low=1, high=100000),
    Spec('scan_range_min', 0.12, 'Nearest range the scanner reports [m]; closer is -inf.',
         low=0.0, high=1000.0),
    Spec('scan_range_max', 3.5, 'Farthest range the scanner reports [m]; no return is +inf.',
         low=0.0, high=1000.0, low_open=True),
    Spec('scan_noise_std', 0.0, 'Standard deviation of the Gaussian noise on each range [m]; '
         '0 = exact.', low=0.0, high=100.0),
    Spec('seed', 0, "Seed of the scan noise, drawn from the seed and each scan's stamp: runs "
         'with one seed give the same scans at the same times, bit for bit.', low=0,
         high=2 ** 31 - 1),
    Spec('scan_frame_id', 'base_scan', "Frame of the scan, at the robot's centre; base frame "
         "-> scan frame goes on /tf_static (a default name gets the robot's prefix)."),
)


def open_surroundings(node, names):
    """Return the world around the robots that node's parameters ask for, or None (no map)."""
    p = node.params
    if not p.map_file:
        return None
    try:
        grid = load_map(p.map_file)
    except MapError as error:
        raise ParameterError(f"parameter 'map_file': {error}") from None
    if p.scan_range_min >= p.scan_range_max:
        raise ParameterError(f"parameter 'scan_range_min' ({p.scan_range_min:g}) must be below "
                             f"'scan_range_max' ({p.scan_range_max:g})")
    return Surroundings(node, names, grid)


class Surroundings:
    """The map, the walls and the scans of a simulator with map_file (see the docstring)."""

    def __init__(self, node, names, grid):
        p = node.params
        self.grid = grid
        self.map_frame = p.map_frame_id
        self.walls = Walls(grid, p.robot_radius)
        self.scanner = Scanner(grid, beams=p.scan_beams, range_min=p.scan_range_min,
                               range_max=p.scan_range_max, noise_std=p.scan_noise_std,
                               seed=p.seed, radius=p.robot_radius)
        self.scan_pubs = [node.create_publisher(LaserScan, f'{name}/scan' if name else 'scan',
                                                SCAN_QOS) for name in names]
        self._scan_every = max(1, round(p.rate_hz / p.scan_rate_hz)) if p.scan_rate_hz > 0 else 0
        # Scans go out with a step's odometry: at rate_hz over a whole number of steps.
        self.scan_rate_hz = p.rate_hz / self._scan_every if self._scan_every else 0.0
        if self._scan_every and not math.isclose(self.scan_rate_hz, p.scan_rate_hz):
            node.get_logger().warning(
                f'scan_rate_hz {p.scan_rate_hz:g} is not rate_hz {p.rate_hz:g} over a whole '
                f'number of steps: a scan every {self._scan_every} step(s), at '
                f'{self.scan_rate_hz:g} Hz')
        # Every LaserScan's fields but its header and ranges (scan_time: between two scans [s]).
        self._scan_fields = {name: getattr(self.scanner, name) for name in (
            'angle_min', 'angle_max', 'angle_increment', 'range_min', 'range_max')}
        self._scan_fields['scan_time'] = self._scan_every / p.rate_hz
        self._steps = 0
        self._scan_frames = [published_frame(node.get_namespace(), name, 'scan_frame_id',
                                             p.scan_frame_id) for name in names]
        self._map_pub = node.create_publisher(OccupancyGrid, 'map', LATCHED_QOS)
        self._static_pub = node.create_publisher(TFMessage, '/tf_static', LATCHED_QOS)
        self._map_tf = OdomTransform(node)  # map -> odom, laid out by start()
        self._publish_map_tf = p.publish_map_odom_tf

    def start(self, frames, stamp_ns, taps=None):
        """Publish (and tap) the map, then set_frames (frames: (odom, base) per robot)."""
        map_msg = self.map_message(stamp_ns)
        self._map_pub.publish(map_msg)
        if taps:
            taps.write(self._map_pub.topic_name, map_msg, stamp_ns)
        self.set_frames(frames, stamp_ns, taps)

    def set_frames(self, frames, stamp_ns, taps=None):
        """Lay map -> odom out anew for frames, (odom, base) per robot; publish base -> scan."""
        self._map_tf.set_frames((self.map_frame, odom) for odom, _ in frames)
        # The identity (a message's quaternion is w = 1 unless set), stamped now: a base frame
        # set live gets its scanner too, or no tree would reach the scans' frame.
        stamp = Time(nanoseconds=stamp_ns).to_msg()
        static = TFMessage(transforms=[
            TransformStamped(header=Header(stamp=stamp, frame_id=base), child_frame_id=scan)
            for (_, base), scan in zip(frames, self._scan_frames)])
        self._static_pub.publish(static)
        if taps:
            taps.write(self._static_pub.topic_name, static, stamp_ns)

    def map_message(self, stamp_ns):
        """Return the map as a nav_msgs/OccupancyGrid stamped stamp_ns."""
        grid = self.grid
        msg = OccupancyGrid(header=Header(stamp=Time(nanoseconds=stamp_ns).to_msg(),
                                          frame_id=self.map_frame))
        msg.info.map_load_time = msg.header.stamp
        msg.info.resolution = float(grid.resolution)
        msg.info.width, msg.info.height = int(grid.width), int(grid.height)
        ox, oy, oyaw = grid.origin
        msg.info.origin.position.x, msg.info.origin.position.y = float(ox), float(oy)
        q = msg.info.origin.orientation
        q.x, q.y, q.z, q.w = quaternion_from_yaw(oyaw)
        msg.data = array.array('b', grid.data.astype('int8').tobytes())
        return msg

    def publish(self, stamp_ns, world, taps):
        """Publish map -> odom with this step's odometry, and the scans when they are due."""
        if self._publish_map_tf and self._map_tf.listened(taps):
            half = 0.5 * world.map_yaw
            self._map_tf.publish(stamp_ns, world.map_x, world.map_y, np.sin(half), np.cos(half),
                                 taps)
        due = self._scan_every and self._steps % self._scan_every == 0
        self._steps += 1
        if not due:
            return
        ranges = self.scanner.scan(*world.map_poses(), stamp_ns)
        stamp = Time(nanoseconds=stamp_ns).to_msg()
        for pub, frame, row in zip(self.scan_pubs, self._scan_frames, ranges):
            msg = LaserScan(header=Header(stamp=stamp, frame_id=frame),
                            ranges=array.array('f', row.tobytes()), **self._scan_fields)
            pub.publish(msg)
            if taps:
                taps.write(pub.topic_name, msg, stamp_ns)
