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

Each motion runs against a fresh ``unicycle_sim`` owning time (real_time_factor --rtf, a bound:
they step in lockstep, so every row is exact on a loaded machine too), as in the benchmark's
row 7 (``watch_motion``).  The figure draws each path, heading and speeds, the commands from
the simulator's recording (``out/<motion>.mcap``).  Exit code 1 when a motion failed.
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
from sim_diffdrive import harness

DEMO = ('rotate', 'rotate_odom', 'circle_5s', 'out_and_back', 'odom_out_and_back')
RECORD_DIR = Path(__file__).resolve().parents[1] / 'out'


def recording(motion, record_dir):  # the MCAP file of a motion's run
    name = re.sub(r'[^a-z0-9]+', '_', MOTIONS[motion][0].lower()).strip('_')
    return Path(record_dir) / f'{name}.mcap'


def recorded_commands(path):  # (sim ns, linear, angular) of every Twist(Stamped) recorded
    from mcap_ros2.reader import read_ros2_messages
    twists = ((m.log_time_ns, getattr(m.ros_msg, 'twist', m.ros_msg))
              for m in read_ros2_messages(str(path), topics=['/cmd_vel']))
    return [(t, twist.linear.x, twist.angular.z) for t, twist in twists]


def cells(motion, result):
    def fmt(pose):
        return f'({pose[0]:.4f}, {pose[1]:.4f}, {math.degrees(pose[2]):.3f} deg)'
    if 'end' not in result:
        return [MOTIONS[motion][0], '-', '-', '-', '-', '-', str(result['exit'])]
    return [MOTIONS[motion][0], fmt(result['goal']), fmt(result['end']),
            f'{result["error_mm"]:.3f} mm, {result["error_deg"]:.4f} deg',
            *(f'{result[k]:.2f}' if k in result else '-' for k in ('sim_s', 'wall_s')),
            str(result['exit'])]


def run_series(result, commands):
    """Return the RunSeries from 0.2 s before the motion's start to 0.5 s after its rest."""
    from motion_challenges.plotting import time_series

    odometry = [(int(harness.stamp_s(odom) * 1e9), harness.pose_of(odom)[2],
                 *harness.twist_of(odom)) for odom in result['odoms']]
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
    """Draw each run in a column: its path, then its heading and speeds over simulated time."""
    import matplotlib
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
            continue
        draw_run(path, [harness.pose_of(odom) for odom in result['odoms']],
                 start=harness.pose_of(result['odoms'][0]), end=result['end'], goal=result['goal'],
                 title=f'{MOTIONS[motion][0]}\nerror {cells(motion, result)[3]}',
                 legend=column == 0)
        series = run_series(result, commands)
        if series is None:
            heading.set_title('no command heard', fontsize='small')
        else:
            draw_series(heading, linear, angular, series, legend=column == 0)
    figure.tight_layout()
    figure.savefig(filename, dpi=80)
    pyplot.close(figure)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--rtf', type=float, help='upper bound of simulated seconds per '
                        'wall second (default: 50; 2 with --view)')
    parser.add_argument('--view', type=int, default=0, metavar='PORT', help='watch every run '
                        'live in a browser at http://127.0.0.1:PORT/ (needs rerun-sdk)')
    parser.add_argument('--figure', default='demo.png', help='default: %(default)s')
    parser.add_argument('--record-dir', default=str(RECORD_DIR), help='default: %(default)s')
    options = parser.parse_args()
    options.rtf = options.rtf or (2.0 if options.view else 50.0)
    record_dir = Path(options.record_dir).resolve() if options.record_dir else None
    if record_dir:
        record_dir.mkdir(parents=True, exist_ok=True)
    graph, run, runs = harness.SimGraph(), Run(), []  # the processes share its domain
    print(f'ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}, localhost only, real-time factor '
          f'{options.rtf:g}', flush=True)
    if options.view:  # each motion's simulator serves it; the page follows from one to the next
        print(f'Watch it live: open http://127.0.0.1:{options.view}/ in a browser', flush=True)
    wall_start = time.monotonic()
    try:
        for i, motion in enumerate(DEMO, 1):
            print(f'[{i}/{len(DEMO)}] {MOTIONS[motion][0]} ...', flush=True)
            record = {'record_file': str(recording(motion, record_dir))} if record_dir else {}
            view = {'view_port': options.view} if options.view else {}
            result = watch_motion(graph, run.start, run.stop, motion, options.rtf,
                                  **record, **view)
            if result['exit'] != 0:
                print(f'  exit {result["exit"]}; its last lines:\n{tail(result["log"], 8)}')
            runs.append((motion, result, recorded_commands(record['record_file'])
                         if record and Path(record['record_file']).exists() else []))
    except (KeyboardInterrupt, FileNotFoundError) as error:  # not on PATH: make venv
        print(error or 'Interrupted', file=sys.stderr)
        return 130 if isinstance(error, KeyboardInterrupt) else 2
    finally:
        run.stop_all()
        graph.close()
    table = [['motion', 'goal', 'achieved', 'error', 'sim s', 'wall s', 'exit']]
    table += [cells(motion, result) for motion, result, _ in runs]
    widths = [max(len(r[i]) for r in table) for i in range(len(table[0]))]
    table.insert(1, ['-' * w for w in widths])
    print('\n' + '\n'.join('  '.join(c.ljust(w) if j < 4 else c.rjust(w) for j, (c, w) in
                                     enumerate(zip(line, widths))) for line in table))
    print('\nsim s / wall s: from the first to the last movement seen on odometry. Total wall '
          f'time {time.monotonic() - wall_start:.1f} s.')
    try:
        write_figure(runs, options.figure)
        print(f'Figure (path, heading, speeds): {os.path.abspath(options.figure)}')
    except ImportError as error:
        print(f'No figure: {error} (pip install matplotlib).')
    files = [recording(m, record_dir) for m in DEMO] if record_dir else []
    if files:
        print(f'Recordings (MCAP) in {record_dir}: ' + ', '.join(f.name for f in files if
                                                                 f.exists())
              + '. Open in Foxglove (File \N{RIGHTWARDS ARROW} Open) or `ros2 bag info`.')
    failed = [MOTIONS[motion][0] for motion, result, _ in runs if result['exit'] != 0]
    print('Failed: ' + ', '.join(failed) if failed else 'All motions done.')
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
