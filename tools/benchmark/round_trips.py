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
Row 7's references: what the messages of a lockstep step cost between two processes alone.

``ping_pong``: two processes that only bounce one raw std_msgs/UInt64.  ``bare_step``: the
four messages of a lockstep step and nothing else: one process publishes an Odometry's bytes
and then a /clock, the other takes both and publishes a Twist's and an answer's bytes from its
/clock callback, and the first waits for both before the next step.  (From the callback, not
from a timer on sim time: the EventsExecutor's duplicate timer events, lockstep/counter.py,
would make such a timer skip a step now and then, and the pair would wait for ever; the timer
costs about as much, 479 against 457 us a step in one measurement.)  Both use rclpy's
serialized publish, raw subscriptions, EventsExecutor spin_once loops as the executables spin,
and the package's DDS profile.
"""

import json
import subprocess
import sys

SCRIPT = """
import json, sys, time
import rclpy
from rclpy.experimental import EventsExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from sim_diffdrive.cdr import clock_message, string_message, twist_message
from sim_diffdrive.dds_profile import use_package_profile
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String, UInt64
use_package_profile()  # before the first node, as runtime.run() does for the executables
rclpy.init()
role, executor, heard = sys.argv[1], EventsExecutor(), []
step = role.endswith('step')
CLOCK = ['--ros-args', '-r', '/clock:=/bench_clock']  # this pair's own clock topic
node = rclpy.create_node(f'bench_{role}', enable_rosout=False, cli_args=CLOCK)
executor.add_node(node)
if not step:
    out, back = ('bench_ping', 'bench_pong')[::1 if role == 'ping' else -1]
    publisher = node.create_publisher(UInt64, out, 10)
    node.create_subscription(UInt64, back, heard.append if role == 'ping' else publisher.publish,
                             10, raw=True)  # pong: each ping's bytes straight back
elif role == 'owner_step':
    odom = node.create_publisher(Odometry, 'bench_odom', 10)
    publisher = node.create_publisher(Clock, '/clock', QoSProfile(
        depth=1, reliability=ReliabilityPolicy.RELIABLE))
    back = 'bench_answers'
    node.create_subscription(Twist, 'bench_cmd', heard.append, 1000, raw=True)
    node.create_subscription(String, back, heard.append, 10, raw=True)
else:
    cmd = node.create_publisher(Twist, 'bench_cmd', 10)
    answers = node.create_publisher(String, 'bench_answers', 10)
    node.create_subscription(Odometry, 'bench_odom', heard.append, 10, raw=True)
    command, answer = twist_message(0.2, 0.0), string_message('{}')
    node.create_subscription(Clock, '/clock', lambda _: (cmd.publish(command),
                                                         answers.publish(answer)),
                             QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE),
                             raw=True)
try:
    while role in ('pong', 'member_step') and rclpy.ok():
        executor.spin_once(timeout_sec=0.1)
        heard.clear()
    due, times, warm_ups = time.monotonic() + 30.0, [], int(sys.argv[3])
    while not publisher.get_subscription_count() or not node.count_publishers(back):
        if time.monotonic() > due:
            sys.exit('no partner process matched')
        executor.spin_once(timeout_sec=0.01)
    odom_data = serialize_message(Odometry())
    for k in range(warm_ups + int(sys.argv[2])):
        sent = time.perf_counter_ns()
        if step:  # odometry, then the /clock of its step, as the simulator sends them
            odom.publish(odom_data)
            publisher.publish(clock_message((k + 1) * 20_000_000))
        else:
            publisher.publish(serialize_message(UInt64(data=k)))
        while len(heard) < (2 if step else 1):  # (a lost answer: the caller's wait ends it)
            executor.spin_once(timeout_sec=0.1)
        times.append(time.perf_counter_ns() - sent)
        heard.clear()
    print('round trips ns:', json.dumps(times[warm_ups:]), flush=True)
except KeyboardInterrupt:
    pass
"""


def ping_pong(run):
    """Return the round trips [us] of the ping-pong pair (core.SIZES 'ping_pongs')."""
    return _pair(run, 'ping', 'pong')


def bare_step(run):
    """Return the steps [us] of the bare lockstep pair (as many as ping_pong's)."""
    return _pair(run, 'owner_step', 'member_step')


def _pair(run, first, second):
    round_trips, warm_ups = run.sizes.ping_pongs
    partner = run.start(sys.executable, '-c', SCRIPT, second)
    timed = run.start(sys.executable, '-c', SCRIPT, first, str(round_trips), str(warm_ups))
    wait_s = 60.0 + 0.05 * (round_trips + warm_ups)
    try:
        timed.wait(wait_s)
        late = ''
    except subprocess.TimeoutExpired:
        late = f' did not end within {wait_s:g} s'  # stopped below, its log raised
    finally:
        out, _ = run.stop(timed), run.stop(partner)
    lines = [line for line in out.splitlines() if line.startswith('round trips ns: ')]
    if late or timed.returncode or not lines:
        raise RuntimeError(f'the {first} and {second} processes failed ({timed.returncode})'
                           f'{late}:\n{out}')
    return [ns / 1000.0 for ns in json.loads(lines[0][len('round trips ns: '):])]
