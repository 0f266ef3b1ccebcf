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
Stress the simulator longer than a test can: a cmd_vel flood into ``unicycle_sim``.

``python tools/stress.py`` (``make stress``) starts ``unicycle_sim`` on wall time (50 Hz
odometry, cmd_vel timeout off) and floods its ``cmd_vel`` at --rate messages per second for
--seconds from --publishers processes, each publishing pre-serialized Twists in a paced loop
(the fastest way rclpy publishes: no Python-to-C conversion per message).  A probe in this
process records odometry.  It prints the rate the publishers reached, the odometry rate before
and during the flood, the simulator's resident memory (RSS) and CPU over time, and whether the
last command won, then exits 0 if odometry kept its rate within 10 %, RSS did not grow during
the flood, and the final twist equals the last command; 1 otherwise.

``python tools/stress.py flood --rate R --seconds S [--final V W] [--ros-args ...]`` is one
publisher process (the tests use it too): it waits for a cmd_vel subscriber, publishes at R Hz
(0 = as fast as it can) for S seconds, cycling through 100 different commands, then sends
``--final`` once, waits until it is acknowledged and prints a JSON line with what it sent.

Runs on its own ROS domain (random in 1..100, or SIM_GRAPH_DOMAIN_ID) with localhost-only
discovery, so it never floods anyone else's robot; processes are started and stopped by
sim_diffdrive.harness.
"""

import argparse
import json
import os
import signal
import sys
import time

# Fractions of the flood at its start and end left out of the odometry-rate window, so that
# the rate measured is the one under a steady flood.
_EDGE_S = 0.5
_FINAL = (0.777, -0.555)


def _twist(linear, angular):
    from geometry_msgs.msg import Twist
    msg = Twist()
    msg.linear.x = float(linear)
    msg.angular.z = float(angular)
    return msg


def flood(argv):
    """Publish cmd_vel as told (one publisher process); print a JSON summary."""
    parser = argparse.ArgumentParser(prog='stress.py flood')
    parser.add_argument('--rate', type=float, default=10000.0, help='Hz; 0 = flat out')
    parser.add_argument('--seconds', type=float, default=10.0)
    parser.add_argument('--final', type=float, nargs=2, default=None, metavar=('V', 'W'))
    parser.add_argument('--name', default='cmd_vel_flood')
    args, ros_args = parser.parse_known_args(argv)

    from geometry_msgs.msg import Twist
    import rclpy
    from rclpy.duration import Duration
    from rclpy.serialization import serialize_message

    rclpy.init(args=['stress_flood', *ros_args])
    node = rclpy.create_node(args.name)
    publisher = node.create_publisher(Twist, 'cmd_vel', 10)
    deadline = time.monotonic() + 20.0
    while publisher.get_subscription_count() == 0:
        if time.monotonic() > deadline:
            print(json.dumps({'error': 'no cmd_vel subscriber'}), flush=True)
            return 1
        time.sleep(0.01)
    payloads = [serialize_message(_twist(0.01 * k, -0.01 * k)) for k in range(100)]
    publish = publisher.publish
    batch = 50
    sent = 0
    start_wall = time.time()
    start = time.monotonic()
    end = start + args.seconds
    while True:
        now = time.monotonic()
        if now >= end:
            break
        if args.rate > 0.0:
            ahead = start + sent / args.rate - now
            if ahead > 0.0:
                time.sleep(ahead)
                continue
        for payload in payloads[sent % 100:sent % 100 + batch]:
            publish(payload)
        sent += len(payloads[sent % 100:sent % 100 + batch])
    elapsed = time.monotonic() - start
    if args.final is not None:
        publisher.publish(_twist(*args.final))
    acked = publisher.wait_for_all_acked(Duration(seconds=5.0))
    print(json.dumps({'sent': sent, 'seconds': elapsed, 'rate': sent / elapsed,
                      'final': args.final, 'acked': acked,
                      'start_wall': start_wall, 'end_wall': start_wall + elapsed}),
          flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


def _rss_kb(pid):
    with open(f'/proc/{pid}/status') as status:
        for line in status:
            if line.startswith('VmRSS:'):
                return int(line.split()[1])
    return 0


def _cpu_s(pid):
    with open(f'/proc/{pid}/stat') as stat:
        fields = stat.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def stress(argv):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--rate', type=float, default=10000.0, help='total cmd_vel rate [Hz]')
    parser.add_argument('--seconds', type=float, default=10.0, help='flood duration [s]')
    parser.add_argument('--publishers', type=int, default=1, help='publisher processes')
    parser.add_argument('--odom-rate', type=float, default=50.0, help='simulator rate_hz')
    args = parser.parse_args(argv)

    from sim_diffdrive import harness

    harness.isolated_domain_id()  # before anything starts: children inherit it
    try:
        sim = harness.start('unicycle_sim', *harness.ros_params(
            f'rate_hz:={args.odom_rate}', 'cmd_vel_timeout:=0.0'))
    except FileNotFoundError as error:
        print(error, file=sys.stderr)
        return 1
    # A graph of our own on an isolated domain, which the processes started here share.
    graph = harness.SimGraph()
    floods = []

    def rate_between(t0, t1):
        count = sum(1 for odom in observed.odoms if t0 <= harness.stamp_s(odom) < t1)
        return count / (t1 - t0)

    try:
        graph.wait_for_odometry(20.0, process=sim)
        observed = graph.odometry  # kept: rate_between() reads it after the graph is closed
        graph.spin_for(3.0)
        idle_end = time.time()
        idle_rate = rate_between(idle_end - 2.0, idle_end)
        rss_before = _rss_kb(sim.pid)
        rss = []  # (wall time, kB) once a second while flooding
        cpu_before = _cpu_s(sim.pid)

        per_process = args.rate / args.publishers
        for i in range(args.publishers):
            final = ['--final', *map(str, _FINAL)] if args.publishers == 1 else []
            floods.append(harness.start(
                sys.executable, os.path.abspath(__file__), 'flood', '--rate', str(per_process),
                '--seconds', str(args.seconds), '--name', f'cmd_vel_flood_{i}', *final))
        next_sample = time.monotonic()
        while any(f.poll() is None for f in floods):
            graph.spin_for(0.05)
            if time.monotonic() >= next_sample:
                next_sample += 1.0
                rss.append((time.time(), _rss_kb(sim.pid)))
        cpu_flood = _cpu_s(sim.pid) - cpu_before
        results = [json.loads(f.output().strip().splitlines()[-1]) for f in floods]
        if args.publishers > 1:
            # The last command of all: sent here, once every flood has ended.
            from rclpy.duration import Duration
            sender = graph.probe('stress_final_command', use_sim_time=False)
            graph.spin_until(lambda: sender.cmd_pub.get_subscription_count() > 0, 10.0)
            sender.send(*_FINAL)
            sender.cmd_pub.wait_for_all_acked(Duration(seconds=5.0))
        graph.spin_for(1.0)
        rss_after = _rss_kb(sim.pid)
        final = harness.twist_of(observed.odom)
    finally:
        for process in floods:
            harness.stop(process, signal.SIGKILL)
        harness.stop(sim, timeout=10.0)
        graph.close()

    if any('error' in r for r in results):
        print(f'flood failed: {results}')
        return 1
    sent = sum(r['sent'] for r in results)
    start_wall = min(r['start_wall'] for r in results)
    end_wall = max(r['end_wall'] for r in results)
    seconds = end_wall - start_wall
    flood_rate = rate_between(start_wall + _EDGE_S, end_wall - _EDGE_S)
    # Growth from the first sample a second into the flood to the largest one after it.
    flooding = [(t, kb) for t, kb in rss if start_wall + 1.0 <= t <= end_wall]
    steady = flooding[0][1] if flooding else rss_before
    growth_kb = max([kb for _, kb in flooding] + [rss_after]) - steady

    print(f'cmd_vel flood into unicycle_sim ({args.odom_rate:g} Hz odometry, wall time), '
          f'{args.publishers} publisher process(es), domain {os.environ["ROS_DOMAIN_ID"]}')
    print(f'  commands sent        {sent} in {seconds:.2f} s = {sent / seconds:.0f} Hz '
          f'(target {f"{args.rate:g} Hz" if args.rate else "as fast as possible"})')
    for r in results:
        print(f'    publisher          {r["sent"]} at {r["rate"]:.0f} Hz, all acked: {r["acked"]}')
    print(f'  odometry rate        idle {idle_rate:.1f} Hz, during the flood {flood_rate:.1f} Hz '
          f'(nominal {args.odom_rate:g} Hz)')
    print(f'  simulator CPU        {cpu_flood / seconds * 100:.0f} % of a core during the flood')
    print(f'  simulator RSS [MB]   before {rss_before / 1024:.1f}; into the flood '
          + ', '.join(f'{t - start_wall:.1f} s {kb / 1024:.1f}'
                      for t, kb in rss if start_wall <= t <= end_wall)
          + f'; after {rss_after / 1024:.1f}')
    print(f'  RSS growth           {growth_kb / 1024:+.2f} MB after the first second of flood')
    print(f'  final twist          {final}, last command {_FINAL}')
    checks = {
        'odometry within 10 % of its rate': abs(flood_rate - args.odom_rate)
        <= 0.1 * args.odom_rate,
        'RSS did not grow (< 1 MB) under the flood': growth_kb < 1024,
        'the last command won': final == _FINAL,
    }
    for label, ok in checks.items():
        print(f'  {"ok  " if ok else "FAIL"} {label}')
    return 0 if all(checks.values()) else 1


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ['flood']:
        return flood(argv[1:])
    return stress(argv)


if __name__ == '__main__':
    sys.exit(main())
