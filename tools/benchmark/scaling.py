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

"""Rows 11 and 12: N robots (simulator + odom_out_and_back) in one process, as 2N processes."""

import math
import re
import time

from benchmark.config import NS
from benchmark.config import SCALING_TIMEOUT_S
from benchmark.graph import BenchGraph
from benchmark.processes import tail
from benchmark.table import fmt_x
from benchmark.table import row
from motion_challenges.odom_out_and_back import OdomOutAndBack
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from sim_diffdrive.harness import closing_line
from sim_diffdrive.sim.node import UnicycleSim

DONE_LINE = re.compile(r'Done in ([0-9.]+) s \(([0-9.]+) s wall\)')
ERROR_LINE = re.compile(r'error ([0-9.]+) mm, ([0-9.]+) deg')


def scaling_one_process(robots, window_s, motion, domain_id):
    """Return the real-time factor of `robots` simulator+motion pairs in one executor."""
    with BenchGraph(EventsExecutor, domain_id) as graph:
        graph.add_sim(namespace='/robot0')
        for k in range(1, robots):
            graph.add_node(UnicycleSim, namespace=f'/robot{k}')
        for k in range(robots):
            graph.add_node(OdomOutAndBack, namespace=f'/robot{k}', **motion)
        graph.wait_for_discovery()
        graph.step(10)  # the motions prime their connection and start
        steps = round(window_s * NS / graph.step_ns)
        wall = time.perf_counter()
        graph.step(steps)
        wall = time.perf_counter() - wall
        return steps * graph.step_ns / NS / wall


def scaling_processes(children, domain_id, robots, motion, rtf):
    """
    Run `robots` odom_out_and_back + unicycle_sim pairs as separate processes.

    Robot 0's simulator owns /clock (publish_clock at rtf, in lockstep with every other process,
    all of which take part: the motions and the simulators on sim time) and starts last, once
    every other process is up and connected.  Commands are TwistStamped (stamped:=true on every
    node), so a robot's simulator applies each at the step it was sent for even when it arrives
    before that step's /clock.  Returns the slowest motion's sim s / wall s, the largest
    closure error (both from the motions' closing lines) and how many motions did not finish.
    """
    processes = []
    with BenchGraph(domain_id=domain_id, offline=False) as session:
        probe = session.add(Node('bench_probe', context=session.context, enable_rosout=False))
        try:
            for k in range(1, robots):
                processes.append(children.start('unicycle_sim', namespace=f'/robot{k}',
                                                use_sim_time=True, stamped=True))
            motions = [children.start('odom_out_and_back', namespace=f'/robot{k}',
                                      use_sim_time=True, start_timeout=120.0, stamped=True,
                                      **motion)
                       for k in range(robots)]
            processes += motions

            def ready():
                return all(probe.count_publishers(f'/robot{k}/cmd_vel') >= 1
                           and (k == 0 or probe.count_subscribers(f'/robot{k}/cmd_vel') >= 1)
                           for k in range(robots))
            if not session.spin_until(ready, 30.0 + 2.0 * robots, poll=0.05):
                raise RuntimeError(f'{robots} robots did not come up')
            # 2N Python processes on a small machine: a participant can be off the CPU for
            # seconds, which is no reason to go on without it.
            started = time.monotonic()
            processes.append(children.start('unicycle_sim', namespace='/robot0',
                                            publish_clock=True, real_time_factor=rtf,
                                            lockstep_timeout=SCALING_TIMEOUT_S, stamped=True))
            session.spin_until(lambda: all(m.poll() is not None for m in motions),
                               SCALING_TIMEOUT_S + 4.0 * robots, poll=0.05)
            # Wall seconds from the clock owner's start to the last motion's exit.
            wall_s = (max(m.exited_at for m in motions) - started
                      if all(m.poll() is not None for m in motions) else math.nan)
        finally:
            for process in processes:
                children.stop(process)
    finished = [closing(closing_line(children.stop(motion))) if motion.returncode == 0 else None
                for motion in motions]
    result = summary(finished, wall_s)
    result['failure_logs'] = [tail(children.stop(motion)) for motion, done
                              in zip(motions, finished) if done is None]
    return result


def closing(line):
    """Return (sim s, wall s, error mm, error deg) from a motion's closing line, or None."""
    done, error = DONE_LINE.search(line), ERROR_LINE.search(line)
    if not done or not error:
        return None
    return (float(done.group(1)), float(done.group(2)), float(error.group(1)),
            float(error.group(2)))


def summary(finished, wall_s):
    """
    Sum up the motions' closings (None: not finished) and the run's wall seconds.

    rtf: the slowest motion's sim s / wall s; worst_mm, worst_deg: the largest closure error;
    failed: how many did not finish.
    """
    done = [f for f in finished if f is not None]
    return {'rtf': min((sim_s / wall if wall > 0 else math.inf for sim_s, wall, _, _ in done),
                       default=math.nan),
            'worst_mm': max((mm for _, _, mm, _ in done), default=math.nan),
            'worst_deg': max((deg for _, _, _, deg in done), default=math.nan),
            'failed': len(finished) - len(done), 'robots': len(finished), 'wall_s': wall_s}


def rows_scaling(sizes, children, domain_id, rtf):
    motion = sizes.scaling_motion
    one = {n: scaling_one_process(n, sizes.scaling_window_s, motion, domain_id)
           for n in sizes.robots}
    many = {n: scaling_processes(children, domain_id, n, motion, rtf)
            for n in sizes.robots_processes}
    drive = 'odom_out_and_back (' + ', '.join(f'{k} {v:g}' for k, v in motion.items()) + ')'
    one_text = ', '.join(f'N={n}: {v:.1f}x' for n, v in one.items())
    many_text = ', '.join(
        f'N={n}: {fmt_x(m["rtf"])} ({m["worst_mm"]:.3f} mm'
        + (f', {m["failed"]} not done)' if m['failed'] else ')') for n, m in many.items())
    return {
        'scaling_one_process': row(
            'N robots in one process, real-time factor', one_text,
            'as 2N processes: ' + many_text, '-', '-',
            f'Simulator + {drive} pairs in namespaces /robotK, all nodes in one '
            "EventsExecutor; robot 0's simulator owns /clock and is stepped in lockstep, the "
            f'others run on sim time. Measured over {sizes.scaling_window_s:g} s of simulated '
            'time, exact.', rtf={str(n): v for n, v in one.items()}),
        'scaling_processes': row(
            'N robots as 2N processes, real-time factor (worst closure)', many_text,
            'one process: ' + one_text, '-', '-',
            f'unicycle_sim and {drive} executables per robot (-r __ns:=/robotK). '
            f"Robot 0's simulator owns /clock (real_time_factor {rtf:g} as an upper bound) "
            'and starts once all others are connected; the rest use_sim_time and take part in '
            'its lockstep, so it waits for all 2N-1 of them at every step. Commands are '
            'TwistStamped, so each simulator applies a command at the step it was sent for. '
            "Factor: slowest motion's sim s / wall s; error: "
            "largest closure error; both from the motions' closing lines of the robots that "
            f'finished (not done: no closing line within {SCALING_TIMEOUT_S:g} s + 4 s per '
            'robot of wall time).',
            rtf={str(n): m['rtf'] for n, m in many.items()},
            worst_error_mm={str(n): m['worst_mm'] for n, m in many.items()},
            not_done={str(n): m['failed'] for n, m in many.items()},
            runs={str(n): m for n, m in many.items()}),
    }
