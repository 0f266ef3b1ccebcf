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
Run every motion against the simulator as separate processes over DDS; print a table and a figure.

For each motion in turn a fresh ``unicycle_sim`` owns time (``publish_clock``,
``real_time_factor`` = --rtf) and the motion's executable runs on it with ``use_sim_time`` and
its answers as parameters, so nothing prompts: the run of the benchmark's row 7
(``benchmark.processes.watch_motion``, on sim_diffdrive.harness).  Odometry, heard in this
process, gives the start pose, the resting pose once the motion has exited, and the simulated
and wall seconds from the robot's first to its last movement.  The simulator steps in lockstep
with the motion, so --rtf is only an upper bound and every row is exact on a loaded machine
too.  Each simulator records its run to ``out/<motion>.mcap`` (``--record-dir ''``: off), the
source of the commanded speeds in the figure.  The exit code is 1 when a motion failed.

Runs on its own ROS domain (random in 1..100, or SIM_GRAPH_DOMAIN_ID), discovery on this
machine only.  ``python tools/demo.py [--rtf 50]`` with the venv active (``make demo``).
"""

import argparse
import math
import os
from pathlib import Path
import re
import sys
import time

from benchmark.core import Run
from benchmark.core import tail
from benchmark.processes import MOTIONS
from benchmark.processes import watch_motion
from sim_diffdrive.harness import pose_of
from sim_diffdrive.harness import SimGraph
from sim_diffdrive.harness import stamp_s
from sim_diffdrive.harness import twist_of

DEMO = ('rotate', 'rotate_odom', 'circle_5s', 'out_and_back', 'odom_out_and_back')
RECORD_DIR = Path(__file__).resolve().parents[1] / 'out'  # as make bench's out/bench.json


def recording(motion, record_dir):
    """Return the MCAP file of a motion's run: its label as a file name."""
    name = re.sub(r'[^a-z0-9]+', '_', MOTIONS[motion][0].lower()).strip('_')
    return Path(record_dir) / f'{name}.mcap'


def recorded_commands(path):
    """Return (sim ns, linear, angular) of every command a recording holds, [] without one."""
    try:
        from geometry_msgs.msg import Twist
        from geometry_msgs.msg import TwistStamped
        from mcap.reader import make_reader
        from rclpy.serialization import deserialize_message
        with open(path, 'rb') as stream:
            heard = []
            for schema, _, message in make_reader(stream).iter_messages(topics=['/cmd_vel']):
                stamped = schema.name == 'geometry_msgs/msg/TwistStamped'
                msg = deserialize_message(message.data, TwistStamped if stamped else Twist)
                msg = msg.twist if stamped else msg
                heard.append((message.log_time, msg.linear.x, msg.angular.z))
            return heard
    except (ImportError, OSError, ValueError) as error:
        print(f'  could not read the commands from {path}: {error}')
        return []


def cells(motion, result):
    """Return the table cells of one run."""
    if 'end' not in result:
        return [MOTIONS[motion][0], '-', '-', '-', '-', '-', str(result['exit'])]
    (x, y, yaw), end = result['goal'], result['end']
    if MOTIONS[motion][4]:
        goal, achieved = f'yaw {math.degrees(yaw):.3f} deg', f'yaw {math.degrees(end[2]):.3f} deg'
    else:
        goal = f'({x:.4f}, {y:.4f}, {math.degrees(yaw):.3f} deg)'
        achieved = f'({end[0]:.4f}, {end[1]:.4f}, {math.degrees(end[2]):.3f} deg)'
    return [MOTIONS[motion][0], goal, achieved,
            f'{result["error_mm"]:.3f} mm, {result["error_deg"]:.4f} deg',
            *(f'{result[k]:.2f}' if k in result else '-' for k in ('sim_s', 'wall_s')),
            str(result['exit'])]


def run_series(result, commands):
    """
    Return the RunSeries of a run, from the motion's start to its rest; None if nothing moved.

    Time counts from the motion's start: the last odometry at rest before the robot moved, or
    the first moving command if earlier.  A little before stays in view, and half a second
    after the robot came to rest.
    """
    from motion_challenges.plotting import time_series

    odometry = [(int(stamp_s(odom) * 1e9), pose_of(odom)[2], *twist_of(odom))
                for odom in result['odoms']]
    moving = [t for t, v, w in commands if (v, w) != (0.0, 0.0)]
    driven = [i for i, (_, _, v, w) in enumerate(odometry) if (v, w) != (0.0, 0.0)]
    if not (moving or driven):
        return None
    start_ns = min(moving[:1] + ([odometry[max(driven[0] - 1, 0)][0]] if driven else []))
    stops = [t for t, *_ in commands if moving and t > moving[-1]]
    high = max(stops[:1] + [odometry[driven[-1]][0] if driven else start_ns]) + 500_000_000
    low = start_ns - 200_000_000
    return time_series([s for s in odometry if low <= s[0] <= high],
                       [c for c in commands if low <= c[0] <= high], start_ns,
                       result['goal'][2])


def write_figure(runs, filename):
    """
    Draw every run into one PNG, a column each; return False without matplotlib.

    In each column: the path, then over simulated time the heading and the linear and angular
    speeds, commanded (cmd_vel as the simulator recorded it) and achieved (odometry).
    """
    try:
        import matplotlib
    except ImportError:
        return False
    matplotlib.use('Agg')
    from matplotlib import pyplot
    from motion_challenges.plotting import draw_run
    from motion_challenges.plotting import draw_series

    figure, axes = pyplot.subplots(4, len(runs), figsize=(4.4 * len(runs), 12.5), squeeze=False,
                                   gridspec_kw={'height_ratios': (2.2, 1.0, 1.0, 1.0)})
    for column, (motion, result, commands) in enumerate(runs):
        path, heading, linear, angular = axes[:, column]
        for ax in (linear, angular):
            ax.sharex(heading)
        if 'end' not in result:
            path.set_title(f'{MOTIONS[motion][0]}: no odometry', fontsize='small')
            for ax in axes[1:, column]:
                ax.set_axis_off()
            continue
        row = cells(motion, result)
        draw_run(path, [pose_of(odom) for odom in result['odoms']],
                 start=pose_of(result['odoms'][0]), end=result['end'], goal=result['goal'],
                 title=f'{row[0]}\nerror {row[3]}', legend=column == 0)
        series = run_series(result, commands)
        if series is None:
            heading.set_title('no command heard', fontsize='small')
            continue
        draw_series(heading, linear, angular, series, legend=column == 0)
    figure.tight_layout()
    figure.savefig(filename, dpi=80)
    pyplot.close(figure)
    return True


def print_table(runs):
    rows = [['motion', 'goal', 'achieved', 'error', 'sim s', 'wall s', 'exit']]
    rows += [cells(motion, result) for motion, result, _ in runs]
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for i, row in enumerate(rows):
        print('  '.join(c.ljust(w) if j < 4 else c.rjust(w)
                        for j, (c, w) in enumerate(zip(row, widths))))
        if i == 0:
            print('  '.join('-' * w for w in widths))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--rtf', type=float, default=50.0,
                        help='upper bound of simulated seconds per wall second (default: '
                             '%(default)s)')
    parser.add_argument('--figure', default='demo.png', help='PNG of every run (default: '
                        '%(default)s)')
    parser.add_argument('--record-dir', default=str(RECORD_DIR), help='record each run to an '
                        "MCAP file here ('': no recording; default: %(default)s)")
    options = parser.parse_args()
    record_dir = Path(options.record_dir).resolve() if options.record_dir else None
    if record_dir:
        record_dir.mkdir(parents=True, exist_ok=True)
    graph, run, runs = SimGraph(), Run(), []  # children inherit the graph's domain
    print(f'ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}, localhost only, real-time factor '
          f'{options.rtf:g}', flush=True)
    wall_start = time.monotonic()
    try:
        for i, motion in enumerate(DEMO, 1):
            print(f'[{i}/{len(DEMO)}] {MOTIONS[motion][0]} ...', flush=True)
            record = {'record_file': str(recording(motion, record_dir))} if record_dir else {}
            result = watch_motion(graph, run.start, run.stop, motion, options.rtf, **record)
            if result['exit'] != 0:
                print(f'  {MOTIONS[motion][1]}: {result["exit"]}; the last lines of its output:'
                      f'\n{tail(result["log"], 8)}')
            runs.append((motion, result, recorded_commands(record['record_file'])
                         if record else []))
    except (KeyboardInterrupt, FileNotFoundError) as error:
        print(error or 'Interrupted', file=sys.stderr)
        return 130 if isinstance(error, KeyboardInterrupt) else 2
    finally:
        run.stop_all()
        graph.close()
    print()
    print_table(runs)
    print('\nsim s / wall s: from the first to the last movement seen on odometry. Total wall '
          f'time {time.monotonic() - wall_start:.1f} s.')
    if write_figure(runs, options.figure):
        print(f'Figure (path, heading, speeds): {os.path.abspath(options.figure)}')
    else:
        print('No figure: matplotlib is not installed (pip install matplotlib).')
    files = [f for f in (recording(m, record_dir) for m in DEMO) if f.exists()] if record_dir \
        else []
    if files:
        print(f'Recordings (MCAP) in {record_dir}: '
              + ', '.join(f'{f.name} ({f.stat().st_size / 1e6:.1f} MB)' for f in files)
              + '.\nOpen in Foxglove (File \N{RIGHTWARDS ARROW} Open) or `ros2 bag info <file>` '
              'on a ROS machine.')
    failed = [MOTIONS[motion][0] for motion, result, _ in runs if result['exit'] != 0]
    if failed:
        print('Failed: ' + ', '.join(failed))
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
