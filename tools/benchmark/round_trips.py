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

One pair of processes measures both, one after the other.  The ping-pong: the first process
bounces one raw std_msgs/UInt64 off the second.  The bare step: the four messages of a
lockstep step and nothing else: the first publishes an Odometry's bytes and then a /clock, the
second takes both and publishes a Twist's and an answer's bytes from its /clock callback, and
the first waits for both before the next step.  (From the callback, not from a timer on sim
time: the EventsExecutor's duplicate timer events, lockstep/counter.py, would make such a timer
skip a step now and then, and the pair would wait for ever; the timer costs about as much, 479
against 457 us a step in one measurement.)  Both use rclpy's serialized publish, raw
subscriptions, EventsExecutor spin_once loops as the executables spin, and the package's DDS
profile.
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
CLOCK = ['--ros-args', '-r', '/clock:=/bench_clock']  # this pair's own clock topic
node = rclpy.create_node(f'bench_{role}', enable_rosout=False, cli_args=CLOCK)
executor.add_node(node)
RELIABLE = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
if role == 'timed':
    ping = node.create_publisher(UInt64, 'bench_ping', 10)
    odom = node.create_publisher(Odometry, 'bench_odom', 10)
    clock = node.create_publisher(Clock, '/clock', RELIABLE)
    for topic, type_ in (('bench_pong', UInt64), ('bench_cmd', Twist),
                         ('bench_answers', String)):
        node.create_subscription(type_, topic, heard.append, 1000, raw=True)
else:  # the partner: each ping's bytes straight back; a command and an answer per /clock
    pong = node.create_publisher(UInt64, 'bench_pong', 10)
    cmd = node.create_publisher(Twist, 'bench_cmd', 10)
    answers = node.create_publisher(String, 'bench_answers', 10)
    # Its subscriptions only once its publishers reach the first process: that one starts when
    # it sees them, and a reply sent before this side's writer matched its reader is lost for
    # good (the graph may list a publisher before the publisher knows of the subscription).
    due = time.monotonic() + 30.0
    while not all(pub.get_subscription_count() for pub in (pong, cmd, answers)):
        if time.monotonic() > due:
            sys.exit('no timed process matched')
        executor.spin_once(timeout_sec=0.01)
    node.create_subscription(UInt64, 'bench_ping', pong.publish, 10, raw=True)
    node.create_subscription(Odometry, 'bench_odom', lambda _: None, 10, raw=True)
    command, answer = twist_message(0.2, 0.0), string_message('{}')
    node.create_subscription(Clock, '/clock', lambda _: (cmd.publish(command),
                                                         answers.publish(answer)),
                             RELIABLE, raw=True)


def timed(send, replies, count):
    times = []
    for k in range(count):
        sent = time.perf_counter_ns()
        send(k)
        while len(heard) < replies:  # (a lost answer: the caller's wait ends it)
            executor.spin_once(timeout_sec=0.1)
        times.append(time.perf_counter_ns() - sent)
        heard.clear()
    return times


def step(k):  # odometry, then the /clock of its step, as the simulator sends them
    odom.publish(odom_data)
    clock.publish(clock_message((k + 1) * 20_000_000))


try:
    if role == 'partner':
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    else:
        due, count, warm_ups = time.monotonic() + 30.0, int(sys.argv[2]), int(sys.argv[3])
        while not all(pub.get_subscription_count() for pub in (ping, odom, clock)):
            if time.monotonic() > due:
                sys.exit('no partner process matched')
            executor.spin_once(timeout_sec=0.01)
        odom_data = serialize_message(Odometry())
        pings = timed(lambda k: ping.publish(serialize_message(UInt64(data=k))), 1,
                      warm_ups + count)
        steps = timed(step, 2, warm_ups + count)
        print('round trips ns:', json.dumps({'ping_pong': pings[warm_ups:],
                                             'bare_step': steps[warm_ups:]}), flush=True)
except KeyboardInterrupt:
    pass
"""


def round_trips(run):
    """
    Return {'ping_pong': round trips [us], 'bare_step': steps [us]} of one pair of processes.

    As many of each as core.SIZES 'ping_pongs' says, after its warm-ups.
    """
    count, warm_ups = run.sizes.ping_pongs
    partner = run.start(sys.executable, '-c', SCRIPT, 'partner')
    timed = run.start(sys.executable, '-c', SCRIPT, 'timed', str(count), str(warm_ups))
    wait_s = 60.0 + 0.1 * (count + warm_ups)
    try:
        timed.wait(wait_s)
        late = ''
    except subprocess.TimeoutExpired:
        late = f' did not end within {wait_s:g} s'  # stopped below, its log raised
    finally:
        out, _ = run.stop(timed), run.stop(partner)
    lines = [line for line in out.splitlines() if line.startswith('round trips ns: ')]
    if late or timed.returncode or not lines:
        raise RuntimeError(f'the round-trip processes failed ({timed.returncode}){late}:\n{out}')
    return {key: [ns / 1000.0 for ns in times]
            for key, times in json.loads(lines[0][len('round trips ns: '):]).items()}
