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
The load the fleet rows put on a simulator: a process of its own, told what to do on stdin.

In a separate process so that the simulator's CPU, read from /proc, is its own.  Each line on
stdin is ``<seq> <mode> <robots> <namespace>``; the load switches and prints ``ack <seq>
ticks <t> heard <h> joined <j>`` (command rounds sent so far, odometry heard so far, 1 when
taking part in a lockstep).  ``<seq> status`` only prints that line.  Modes:

* ``wall N``: a Twist to each of robots ``r0`` ... ``r<N-1>`` (``<namespace>/r<k>/cmd_vel``) on
  every tick of a 50 Hz timer on wall time, for a simulator on wall time;
* ``lockstep N``: the same from a node on simulated time that takes part in the lockstep of the
  simulator owning ``/clock``, so that simulator applies every robot's command at every step
  before it takes the next (as it does a motion's);
* ``listen``: one subscriber on ``bench_odom``, for rclpy's per-message cost with a reader;
* ``off``: nothing.

The commands alternate between two values, so the simulator integrates piecewise at each one.
The load exits at the end of its input (the benchmark closed it, or died) or on SIGINT/SIGTERM.
LoadProcess is the benchmark's side: it starts the load and switches it.
"""

from pathlib import Path
import queue
import signal
import subprocess
import sys
import threading
import time

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import rclpy
from rclpy.clock import Clock
from rclpy.clock import ClockType
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from sim_diffdrive.lockstep.participant import take_part

LISTEN_TOPIC = 'bench_odom'
TOOLS_DIR = Path(__file__).resolve().parent.parent
RATE_HZ = 50.0


def robot_name(index):
    """Return the name of robot number index in the fleet rows (r0, r1, ...)."""
    return f'r{index}'


def load_code(tools_dir):
    """Return Python code that runs this module's load (for a process with stdin a pipe)."""
    return (f'import sys; sys.path.insert(0, {str(tools_dir)!r}); '
            'from benchmark.fleet_load import main; sys.exit(main())')


class LoadProcess:
    """The load process (fleet_load.py): switch(mode, robots) and wait for its ack."""

    def __init__(self, children):
        self.children = children
        self.process = children.start_python(load_code(TOOLS_DIR), stdin=subprocess.PIPE)
        self._seq = 0

    def switch(self, mode, robots=0, namespace='/', timeout=30.0):
        """
        Switch the load (mode 'status': only ask); wait for its answer and return it.

        The answer: {'ticks': command rounds sent so far, 'heard': odometry heard so far,
        'joined': whether it takes part in a lockstep}.
        """
        self._seq += 1
        try:
            self.process.write(f'{self._seq} {mode} {robots} {namespace}\n')
        except BrokenPipeError:
            from benchmark.processes import tail  # not in the load process
            raise RuntimeError(f'the load process has ended:\n'
                               f'{tail(self.children.stop(self.process))}') from None
        ack = f'ack {self._seq} '
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and self.process.poll() is None:
            for line in reversed(self.process.output().splitlines()):
                if line.startswith(ack):
                    fields = line.split()
                    return {'ticks': int(fields[3]), 'heard': int(fields[5]),
                            'joined': fields[7] == '1'}
            time.sleep(0.005)
        from benchmark.processes import tail
        raise RuntimeError(f'the load did not switch to {mode} {robots}:\n'
                           f'{tail(self.children.stop(self.process))}')

    def close(self):
        if self.process.poll() is None:
            self.process.close_input()  # it exits at the end of its input
            try:
                self.process.wait(3.0)
            except subprocess.TimeoutExpired:
                pass
        self.children.stop(self.process)


class Commander(Node):
    """A Twist to robots r0 ... r<robots-1> in namespace on every tick of a 50 Hz timer."""

    def __init__(self, robots, namespace, sim_time, on_tick):
        super().__init__('bench_fleet_commander', namespace=namespace, enable_rosout=False,
                         parameter_overrides=[Parameter('use_sim_time', value=sim_time)])
        self._on_tick = on_tick
        self._twists = []
        for angular in (0.2, 0.3):
            msg = Twist()
            msg.linear.x = 0.1
            msg.angular.z = angular
            self._twists.append(msg)
        self._pubs = [self.create_publisher(Twist, robot_name(k) + '/cmd_vel', 10)
                      for k in range(robots)]
        self.ticks = 0
        self._matched = False
        self.create_timer(1.0 / RATE_HZ, self._send)
        self.participant = take_part(self) if sim_time else None

    def _send(self):
        if self.get_clock().now().nanoseconds == 0:
            return  # on simulated time, before the first /clock
        if not self._matched:
            # As a motion waits for its robot: in lockstep, a command sent before the
            # simulator subscribed would be waited for and never come.
            self._matched = all(pub.get_subscription_count() > 0 for pub in self._pubs)
            if not self._matched:
                return
        msg = self._twists[self.ticks % 2]
        self.ticks += 1
        for pub in self._pubs:
            pub.publish(msg)
        self._on_tick()


class Load(Node):
    """Switches between a Commander, a listener on LISTEN_TOPIC and nothing."""

    def __init__(self, requests, executor):
        super().__init__('bench_fleet_load', enable_rosout=False)
        self.requests = requests
        self._spinner = executor
        self.ticks = 0
        self.heard = 0
        self.ended = False
        self._commander = None
        self._graveyard = []
        self._listener = None
        self.create_timer(0.01, self._on_request, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _on_request(self):
        self._bury()
        while not self.requests.empty():
            line = self.requests.get()
            if line is None:
                self.ended = True
                return
            seq, mode, robots, namespace = (line.split() + ['0', '/'])[:4]
            if mode != 'status':
                self._switch(mode, int(robots), namespace)
            commander = self._commander
            joined = int(bool(commander and commander.participant
                              and commander.participant.joined))
            print(f'ack {seq} ticks {self.ticks} heard {self.heard} joined {joined}',
                  flush=True)

    def _switch(self, mode, robots, namespace):
        self.close()
        if mode in ('wall', 'lockstep'):
            self._commander = Commander(robots, namespace, mode == 'lockstep', self._count_tick)
            self._spinner.add_node(self._commander)
        if mode == 'listen' and self._listener is None:
            self._listener = self.create_subscription(
                Odometry, LISTEN_TOPIC, self._on_odom, 10)

    def close(self):
        """Stop commanding: leave the lockstep (so the simulator need not wait), stop spinning."""
        commander, self._commander = self._commander, None
        if commander is not None:
            if commander.participant is not None:
                commander.participant.leave()
            self._spinner.remove_node(commander)
            # Destroyed on the next request tick, not now: the executor may still hold an
            # event of its, and handling it after the destruction kills the spin.
            self._graveyard.append(commander)

    def _bury(self):
        while self._graveyard:
            self._graveyard.pop().destroy_node()

    def _count_tick(self):
        self.ticks += 1

    def _on_odom(self, msg):
        self.heard += 1


def _read_lines(requests):
    for line in sys.stdin:
        if line.strip():
            requests.put(line)
    requests.put(None)


def main():
    """Run the load until its input ends, SIGINT or SIGTERM; return the exit code."""
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda signum, frame: stop.set())
    signal.signal(signal.SIGTERM, lambda signum, frame: stop.set())
    requests = queue.Queue()
    threading.Thread(target=_read_lines, args=(requests,), daemon=True).start()
    executor = EventsExecutor()
    node = Load(requests, executor)
    executor.add_node(node)
    try:
        while rclpy.ok() and not node.ended and not stop.is_set():
            # Short waits, so that a signal is seen between them.
            executor.spin_once(timeout_sec=0.1)
    except ExternalShutdownException:
        pass
    finally:
        node.close()
        executor.shutdown()
        node._bury()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0
