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

``python tools/stress.py [--rate 10000] [--seconds 10] [--idle 3]`` (``make stress``) floods a
wall-time ``unicycle_sim`` (cmd_vel timeout off) from a publisher process and prints the rate
reached, odometry's rate idle and during the flood, the simulator's CPU and memory (RSS) over
time and whether the last command won; exit 0 if odometry kept its rate within 10 %, RSS grew
less than 1 MB after the first second and the last command won.  ``python tools/stress.py flood
--rate R (--seconds S | --count N) [--final V W] [--refused] [--ros-args ...]`` is the
publisher (test_faults uses it): R Hz (0: flat out) of 100 pre-serialized Twists (with
--refused every other one has a NaN speed, which the simulator refuses) once a subscriber is
there, for S seconds or until N are sent, then --final, and a JSON line of what it sent.  On a
ROS domain of its own, discovery on this machine only.
"""

import argparse
import json
import math
import sys
import time

FINAL = (0.777, -0.555)
EDGE_S = 0.5  # left out of the flood's odometry rate at its start and end: a steady flood


def flood(argv):  # the publisher process (see the module's docstring)
    parser = argparse.ArgumentParser(prog='stress.py flood')
    parser.add_argument('--rate', type=float, default=10000.0, help='Hz; 0 = flat out')
    parser.add_argument('--seconds', type=float, default=10.0)
    parser.add_argument('--count', type=int, help='send this many, however long it takes '
                        '(instead of --seconds: a loaded machine sends fewer in a second)')
    parser.add_argument('--final', type=float, nargs=2, metavar=('V', 'W'))
    parser.add_argument('--refused', action='store_true', help='every other Twist has a NaN')
    args, ros_args = parser.parse_known_args(argv)
    if args.count is not None and args.count < 1:
        parser.error(f'--count must be at least 1; got {args.count}')
    from geometry_msgs.msg import Twist
    import rclpy
    from rclpy.duration import Duration
    from rclpy.serialization import serialize_message
    from sim_diffdrive.harness import twist

    rclpy.init(args=['stress_flood', *ros_args])
    publisher = rclpy.create_node('cmd_vel_flood').create_publisher(Twist, 'cmd_vel', 10)
    deadline = time.monotonic() + 20.0
    while not publisher.get_subscription_count():
        if time.monotonic() > deadline:
            print(json.dumps({'error': 'no cmd_vel subscriber'}), flush=True)
            return 1
        time.sleep(0.01)
    payloads = [serialize_message(twist(
        math.nan if args.refused and k % 2 else 0.01 * k, -0.01 * k)) for k in range(100)]
    sent, start_wall, start = 0, time.time(), time.monotonic()
    counted = args.count is not None
    while (sent < args.count if counted else time.monotonic() < start + args.seconds):
        ahead = start + sent / args.rate - time.monotonic() if args.rate else 0.0
        if ahead > 0.0:
            time.sleep(ahead)
            continue
        batch = min(50, args.count - sent) if counted else 50  # between two clock reads
        for payload in payloads[sent % 100:sent % 100 + batch]:
            publisher.publish(payload)
        sent += batch
    elapsed = time.monotonic() - start
    if args.final:
        publisher.publish(twist(*args.final))
    print(json.dumps({'sent': sent, 'seconds': elapsed, 'rate': sent / elapsed,
                      'final': args.final, 'start_wall': start_wall,
                      'end_wall': start_wall + elapsed,
                      'acked': publisher.wait_for_all_acked(Duration(seconds=5.0))}), flush=True)
    rclpy.try_shutdown()
    return 0


def rss_mb(pid):
    with open(f'/proc/{pid}/status') as status:
        return next(int(line.split()[1]) / 1024 for line in status if line.startswith('VmRSS:'))


def stress(argv):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--rate', type=float, default=10000.0, help='cmd_vel rate [Hz]')
    parser.add_argument('--seconds', type=float, default=10.0, help='flood duration [s]')
    parser.add_argument('--odom-rate', type=float, default=50.0, help='simulator rate_hz')
    parser.add_argument('--idle', type=float, default=3.0,
                        help='idle time before the flood [s]; odometry rate over its last 2/3')
    args = parser.parse_args(argv)
    if args.seconds <= 2.0 * EDGE_S:
        parser.error(f'--seconds must be over {2.0 * EDGE_S:g}: the flood rate leaves out '
                     f'{EDGE_S:g} s at each end')
    from benchmark.core import Run
    from sim_diffdrive import harness

    graph, run = harness.SimGraph(), Run()  # a domain of its own, which the processes share
    try:
        sim = run.start('unicycle_sim', rate_hz=args.odom_rate, cmd_vel_timeout=0.0)
        odoms = graph.wait_for_odometry(20.0, process=sim) and graph.odometry.odoms
        graph.spin_for(args.idle)
        idle_end = time.time()
        rss, cpu = [(idle_end, rss_mb(sim.pid))], harness.cpu_seconds(sim.pid)
        flood_ = run.start(sys.executable, __file__, 'flood', '--rate', str(args.rate),
                           '--seconds', str(args.seconds), '--final', *map(str, FINAL))
        while flood_.poll() is None:
            graph.spin_for(0.05)
            if time.time() >= rss[-1][0] + 1.0:  # once a second while flooding
                rss.append((time.time(), rss_mb(sim.pid)))
        cpu = harness.cpu_seconds(sim.pid) - cpu
        graph.spin_for(1.0)
        rss.append((time.time(), rss_mb(sim.pid)))
        final, report = harness.twist_of(odoms[-1]), json.loads(
            flood_.output().strip().splitlines()[-1])
    finally:
        run.stop_all()
        graph.close()
    if 'error' in report:
        print(f'flood failed: {report}')
        return 1

    def odometry_rate(t0, t1):
        return sum(t0 <= harness.stamp_s(odom) < t1 for odom in odoms) / (t1 - t0)
    start, end = report['start_wall'], report['end_wall']
    flood_rate = odometry_rate(start + EDGE_S, end - EDGE_S)
    idle_rate = odometry_rate(idle_end - 2.0 * args.idle / 3.0, idle_end)
    # Growth from the first sample a second into the flood to the largest one after it.
    flooding = [mb for t, mb in rss[1:] if t >= start + 1.0] or [rss[0][1]]
    growth = max(flooding) - flooding[0]
    print(f'cmd_vel flood into unicycle_sim ({args.odom_rate:g} Hz odometry, wall time)\n'
          f'  commands sent        {report["sent"]} in {report["seconds"]:.2f} s = '
          f'{report["rate"]:.0f} Hz (target {f"{args.rate:g} Hz" if args.rate else "flat out"})'
          f', all acked: {report["acked"]}\n'
          f'  odometry rate        idle {idle_rate:.1f} Hz, during the flood {flood_rate:.1f} Hz '
          f'(nominal {args.odom_rate:g} Hz)\n'
          f'  simulator CPU        {100.0 * cpu / (end - start):.0f} % of a core during the flood'
          f'\n  simulator RSS [MB]   before {rss[0][1]:.1f}; into the flood '
          + ', '.join(f'{t - start:.1f} s {mb:.1f}' for t, mb in rss[1:-1] if t >= start)
          + f'; after {rss[-1][1]:.1f}\n'
          f'  RSS growth           {growth:+.2f} MB after the first second of flood\n'
          f'  final twist          {final}, last command {FINAL}')
    checks = {'odometry within 10 % of its rate':
              abs(flood_rate - args.odom_rate) <= 0.1 * args.odom_rate,
              'RSS did not grow (< 1 MB) under the flood': growth < 1.0,
              'the last command won': final == FINAL}
    for label, ok in checks.items():
        print(f'  {"ok  " if ok else "FAIL"} {label}')
    return 0 if all(checks.values()) else 1


if __name__ == '__main__':
    sys.exit(flood(sys.argv[2:]) if sys.argv[1:2] == ['flood'] else stress(sys.argv[1:]))
