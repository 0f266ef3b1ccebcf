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

"""The load process of rows 13-16: commands to a fleet, or a subscriber (fleet.py starts it)."""

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import rclpy
from rclpy.clock import Clock
from rclpy.clock import ClockType
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sim_diffdrive.participant import take_part

RATE_HZ = 50.0


def twist(linear, angular):
    msg = Twist()
    msg.linear.x, msg.angular.z = float(linear), float(angular)
    return msg


class Commander(Node):
    """Twists to robots r0.. in namespace at 50 Hz, alternating two values."""

    def __init__(self, robots, namespace, sim_time, counts):
        super().__init__('bench_fleet_commander', namespace=namespace, enable_rosout=False,
                         parameter_overrides=[Parameter('use_sim_time', value=sim_time)])
        self.pubs = [self.create_publisher(Twist, f'r{k}/cmd_vel', 10) for k in range(robots)]
        self.twists = twist(0.1, 0.2), twist(0.1, 0.3)
        self.counts, self.matched = counts, False
        self.create_timer(1.0 / RATE_HZ, self.send)
        self.participant = take_part(self) if sim_time else None

    def send(self):
        # As a motion waits for its robot: in lockstep, a command sent early would be lost.
        self.matched = self.matched or (self.get_clock().now().nanoseconds > 0 and all(
            pub.get_subscription_count() for pub in self.pubs))
        if self.matched:
            for pub in self.pubs:
                pub.publish(self.twists[self.counts['ticks'] % 2])
            self.counts['ticks'] += 1


def load(mode, robots, namespace):
    """
    Load a simulator from a process of its own, so that the simulator's CPU is its own.

    ``wall``: Twists to namespace/r0.. at 50 Hz; ``lockstep``: the same on sim time, in the
    simulator's lockstep; ``listen``: bench_odom's subscriber.  Prints its counts every 10 ms.
    """
    rclpy.init()
    counts, executor, node = {'ticks': 0, 'heard': 0}, EventsExecutor(), Node('bench_load')
    node.create_subscription(Odometry, 'bench_odom', lambda _: counts.update(
        heard=counts['heard'] + 1), 10)
    commander = Commander(int(robots), namespace, mode == 'lockstep', counts) \
        if mode != 'listen' else None
    part = getattr(commander, 'participant', None)
    node.create_timer(0.01, lambda: print(f'load {counts["ticks"]} {counts["heard"]} '
                                          f'{int(bool(part and part.joined))}', flush=True),
                      clock=Clock(clock_type=ClockType.STEADY_TIME))
    for each in filter(None, (node, commander)):
        executor.add_node(each)
    try:
        while rclpy.ok():  # (EventsExecutor.spin() runs no timer in rclpy 7.1.6)
            executor.spin_once(timeout_sec=0.01)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
