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
Run every motion against the simulator, as separate processes over DDS, and print a table.

For each motion in turn this starts a fresh ``unicycle_sim`` that owns time (``publish_clock``,
``real_time_factor`` = --rtf) and the motion's executable with ``use_sim_time`` and all its
answers given as parameters, so nothing prompts (started and stopped by sim_diffdrive.harness).
A probe in this process records ``odom``; once the motion process has exited, the robot's
resting pose is compared with the analytic goal (rotations: start yaw - 90 deg; the others:
back at the start pose).

The table shows goal, achieved pose, error (mm, deg), and the simulated and wall seconds from
the robot's first to its last movement (their ratio is the real-time factor the processes
actually kept up with).  The simulator steps in lockstep with the motion (it waits for the
motion's answer to every clock step), so --rtf is only an upper bound and every row is exact
on a loaded machine too.  The exit code is 1 when a motion process failed or timed out, 0
otherwise.

Each simulator records its run to ``out/<motion>.mcap`` under the repository (record_file:
odometry, /tf, /clock, path and the commands it heard; needs the mcap package), to open in
Foxglove or with ``ros2 bag info``; --record-dir '' turns that off.

The demo runs on its own ROS domain (random in 1..100, or SIM_GRAPH_DOMAIN_ID) with
localhost-only discovery, so it never drives anyone else's robot.  Usage:
``python tools/demo.py [--rtf 50]`` with the venv active (``make demo``).
"""

import argparse
from collections import namedtuple
from dataclasses import dataclass
import math
import os
from pathlib import Path
import re
import shutil
import sys
import tempfile
import time

from geometry_msgs.msg import Twist
from sim_diffdrive import harness
from sim_diffdrive.harness import is_moving
from sim_diffdrive.harness import pose_of
from sim_diffdrive.harness import SimGraph
from sim_diffdrive.harness import stamp_s
from sim_diffdrive.harness import twist_of

Pose = namedtuple('Pose', 'x y yaw')


@dataclass(frozen=True)
class Motion:
    """One row of the demo: what to run and what it should achieve."""

    label: str
    executable: str
    params: tuple  # 'name:=value' strings, given with -p
    sim_seconds: float  # about how long it runs in simulated time, to bound the wait
    turn_deg: float = None  # goal yaw relative to the start; None: back at the start pose


ROTATION = ('angular_speed_deg:=60.0', 'angle_deg:=90.0', 'clockwise:=true')
MOTIONS = (
    Motion('rotate_robot (timed)', 'rotate_robot', ROTATION + ('mode:=timed',), 1.5, -90.0),
    Motion('rotate_robot (odom)', 'rotate_robot', ROTATION + ('mode:=odom',), 1.5, -90.0),
    Motion('circle_back_and_forth (1 cycle, 5 s half period)', 'circle_back_and_forth',
           ('cycles:=1', 'half_period:=5.0'), 10.0),
    Motion('timed_out_and_back', 'timed_out_and_back', (), 20.3),
    Motion('odom_out_and_back', 'odom_out_and_back', (), 21.0),
)

# Wall seconds allowed on top of a motion's simulated duration (process start, discovery).
_START_ALLOWANCE = 15.0
# Where the runs are recorded, like make bench's out/bench.json (git ignores out/).
RECORD_DIR = Path(__file__).resolve().parents[1] / 'out'


def recording_path(motion, record_dir):
    """Return the MCAP file of a motion's run: its label as a file name."""
    return Path(record_dir) / (re.sub(r'[^a-z0-9]+', '_', motion.label.lower()).strip('_')
                               + '.mcap')


@dataclass
class Result:
    motion: Motion
    exit_code: object  # int, or 'timeout'
    start: Pose = None
    end: Pose = None
    sim_s: float = None
    wall_s: float = None
    trajectory: list = None
    # For the figure, on simulated time [ns]: (stamp, yaw, linear, angular) of each odometry
    # and (time heard, linear, angular) of each command on cmd_vel.
    odometry: list = None
    commands: list = None


def print_tail(what, log_path, lines=8):
    print(f'  {what}; last lines of its output:')
    for line in log_path.read_text().splitlines()[-lines:]:
        print('    ' + line)


def movement(probe):
    """
    Return ((sim s, wall s) at rest before the robot moved, (sim s, wall s) at rest after).

    None where odometry does not show it: the robot never moved, or never came to rest.
    """
    samples = list(zip(probe.odoms, probe.odom_walls))
    moving = [i for i, (odom, _) in enumerate(samples) if is_moving(odom)]
    if not moving:
        return None, None
    first, last = moving[0], moving[-1]
    start = samples[first - 1] if first > 0 else samples[first]
    end = samples[last + 1] if last + 1 < len(samples) else None
    return ((stamp_s(start[0]), start[1]),
            (stamp_s(end[0]), end[1]) if end else None)


def record_commands(probe):
    """Return the list probe will fill with (sim ns, linear, angular) of each cmd_vel heard."""
    heard = []
    # On the probe's clock (sim time): the commanded speeds line up with odometry's stamps.
    probe.create_subscription(Twist, 'cmd_vel', lambda msg: heard.append(
        (probe.get_clock().now().nanoseconds, msg.linear.x, msg.angular.z)), 200)
    return heard


def run_motion(motion, graph, rtf, log_dir, record_dir=None):
    """Run one motion against a fresh simulator and return what odometry showed."""
    probe = graph.probe('demo_observer', listen_only=True)
    commands = record_commands(probe)
    sim_log = Path(log_dir) / 'unicycle_sim.log'
    motion_log = Path(log_dir) / f'{motion.executable}.log'
    sim = process = None
    try:
        recording = (f'record_file:={recording_path(motion, record_dir)}',) if record_dir else ()
        sim = harness.start('unicycle_sim', *harness.ros_params(
            'publish_clock:=true', f'real_time_factor:={rtf}', *recording), log_path=sim_log)
        # Start the motion only once the start pose is known.
        if not graph.spin_until(lambda: probe.odom is not None, _START_ALLOWANCE):
            print_tail('no odometry from unicycle_sim', sim_log)
            return Result(motion, 'no sim')
        process = harness.start(motion.executable, *harness.ros_params(
            'use_sim_time:=true', *motion.params), log_path=motion_log)
        # In lockstep the pace is the graph's, not rtf's: allow down to real time.
        timeout = _START_ALLOWANCE + motion.sim_seconds / min(rtf, 1.0)
        if graph.spin_until(lambda: process.poll() is not None, timeout):
            exit_code = process.returncode
        else:
            harness.stop(process)
            exit_code = 'timeout'
        if exit_code != 0:
            print_tail(f'{motion.executable} exited with {exit_code}', motion_log)
        # The resting pose: odometry received after the motion process has gone.
        seen = len(probe.odoms)
        graph.spin_until(lambda: len(probe.odoms) > seen + 2 and not is_moving(probe.odom), 2.0)
        result = Result(motion, exit_code, Pose(*pose_of(probe.odoms[0])),
                        Pose(*pose_of(probe.odom)),
                        trajectory=[pose_of(odom) for odom in probe.odoms],
                        odometry=[(int(stamp_s(odom) * 1e9), pose_of(odom)[2], *twist_of(odom))
                                  for odom in probe.odoms],
                        commands=commands)
        move_start, move_end = movement(probe)
        if move_start and move_end:
            result.sim_s = move_end[0] - move_start[0]
            result.wall_s = move_end[1] - move_start[1]
        return result
    finally:
        for child in (process, sim):
            if child is not None:
                harness.stop(child)
        graph.remove(probe)
        if record_dir and sim is not None:
            # The simulator heard every command, on its own clock, from the first one on; this
            # process hears cmd_vel only once it has discovered the motion's process, which can
            # be late in a short run.  The recording (closed when the simulator stopped) wins.
            commands[:] = recorded_commands(recording_path(motion, record_dir)) or commands


def recorded_commands(path):
    """Return (sim ns, linear, angular) of every command a recording holds, [] without one."""
    try:
        from geometry_msgs.msg import TwistStamped
        from mcap.reader import make_reader
        from rclpy.serialization import deserialize_message
        with open(path, 'rb') as stream:
            heard = []
            for schema, _, message in make_reader(stream).iter_messages(topics=['/cmd_vel']):
                stamped = schema.name == 'geometry_msgs/msg/TwistStamped'
                msg = deserialize_message(message.data, TwistStamped if stamped else Twist)
                twist = msg.twist if stamped else msg
                heard.append((message.log_time, twist.linear.x, twist.angular.z))
            return heard
    except (ImportError, OSError, ValueError) as error:
        print(f'  could not read the commands from {path}: {error}')
        return []


def goal_pose(result):
    """Return the analytic goal (x, y, yaw) from the start pose."""
    start = result.start
    turn = math.radians(result.motion.turn_deg or 0.0)
    return start.x, start.y, math.remainder(start.yaw + turn, 2.0 * math.pi)


def row(result):
    """Return the table cells of one result."""
    exit_code = str(result.exit_code)
    if result.start is None or result.end is None:
        return [result.motion.label, '-', '-', '-', '-', '-', exit_code]
    x, y, yaw = goal_pose(result)
    end = result.end
    if result.motion.turn_deg is not None:
        goal = f'yaw {math.degrees(yaw):.3f} deg'
        achieved = f'yaw {math.degrees(end.yaw):.3f} deg'
    else:
        goal = f'({x:.4f}, {y:.4f}, {math.degrees(yaw):.3f} deg)'
        achieved = f'({end.x:.4f}, {end.y:.4f}, {math.degrees(end.yaw):.3f} deg)'
    error_mm = 1000.0 * math.hypot(end.x - x, end.y - y)
    error_deg = math.degrees(abs(math.remainder(end.yaw - yaw, 2.0 * math.pi)))
    seconds = [f'{s:.2f}' if s is not None else '-' for s in (result.sim_s, result.wall_s)]
    return [result.motion.label, goal, achieved, f'{error_mm:.3f} mm, {error_deg:.4f} deg',
            *seconds, exit_code]


def run_series(result):
    """
    Return the RunSeries of a result, from the motion's start to its rest; None without odometry.

    Time counts from the motion's start: the last odometry at rest before the robot moved, or
    the first moving command if heard before (commands are those heard once this process has
    discovered the motion's publisher, which can be late: the commanded steps may begin late).
    A little before the start stays in view, and half a second after the robot came to rest.
    """
    from motion_challenges.plotting import time_series

    commands = result.commands or []
    odometry = result.odometry or []
    moving = [t for t, v, w in commands if (v, w) != (0.0, 0.0)]
    driven = [i for i, (_, _, v, w) in enumerate(odometry) if (v, w) != (0.0, 0.0)]
    if not odometry or not (moving or driven):
        return None
    # The rest before moving on odometry, or the first moving command if heard before it.
    starts = moving[:1] + ([odometry[max(driven[0] - 1, 0)][0]] if driven else [])
    start_ns = min(starts)
    stops = [t for t, *_ in commands if moving and t > moving[-1]]
    high = max(stops[:1] + [odometry[driven[-1]][0] if driven else start_ns]) + 500_000_000
    low = start_ns - 200_000_000
    return time_series([s for s in odometry if low <= s[0] <= high],
                       [c for c in commands if low <= c[0] <= high],
                       start_ns, goal_pose(result)[2])


def write_figure(results, filename):
    """
    Draw every run into one PNG, a column each; return False without matplotlib.

    In each column: the path, then over simulated time the heading and the linear and angular
    speeds, commanded (cmd_vel as heard) and achieved (odometry).
    """
    try:
        import matplotlib
    except ImportError:
        return False
    matplotlib.use('Agg')
    from matplotlib import pyplot

    from motion_challenges.plotting import draw_run
    from motion_challenges.plotting import draw_series

    figure, axes = pyplot.subplots(
        4, len(results), figsize=(4.4 * len(results), 12.5), squeeze=False,
        gridspec_kw={'height_ratios': (2.2, 1.0, 1.0, 1.0)})
    for column, result in enumerate(results):
        path, heading, linear, angular = axes[:, column]
        for ax in (linear, angular):
            ax.sharex(heading)
        if result.start is None or result.end is None:
            path.set_title(f'{result.motion.label}: no odometry', fontsize='small')
            for ax in axes[1:, column]:
                ax.set_axis_off()
            continue
        cells = row(result)
        start, end = result.start, result.end
        draw_run(path, result.trajectory, start=(start.x, start.y, start.yaw),
                 end=(end.x, end.y, end.yaw), goal=goal_pose(result),
                 title=f'{cells[0]}\nerror {cells[3]}', legend=column == 0)
        series = run_series(result)
        if series is None:
            heading.set_title('no command heard', fontsize='small')
            continue
        draw_series(heading, linear, angular, series, legend=column == 0)
    figure.tight_layout()
    figure.savefig(filename, dpi=80)
    pyplot.close(figure)
    return True


def print_table(results):
    header = ['motion', 'goal', 'achieved', 'error', 'sim s', 'wall s', 'exit']
    rows = [header] + [row(r) for r in results]
    widths = [max(len(r[i]) for r in rows) for i in range(len(header))]
    for i, cells in enumerate(rows):
        print('  '.join(c.ljust(w) if j < 4 else c.rjust(w)
                        for j, (c, w) in enumerate(zip(cells, widths))))
        if i == 0:
            print('  '.join('-' * w for w in widths))


def record_dir_for(option):
    """Return the directory to record to (created), or None: turned off or no mcap package."""
    if not option:
        return None
    try:
        import mcap  # noqa: F401  (the simulator's record_file needs it)
    except ImportError:
        print('No recordings: the mcap package is not installed (pip install mcap).')
        return None
    record_dir = Path(option).resolve()
    record_dir.mkdir(parents=True, exist_ok=True)
    return record_dir


def print_recordings(record_dir):
    """Say where this run's MCAP files are and how to open them."""
    files = [recording_path(motion, record_dir) for motion in MOTIONS]
    files = [f for f in files if f.exists()]
    if not files:
        return
    sizes = ', '.join(f'{f.name} ({f.stat().st_size / 1e6:.1f} MB)' for f in files)
    print(f'Recordings (MCAP) in {record_dir}: {sizes}.')
    print('Open in Foxglove (File \N{RIGHTWARDS ARROW} Open) or `ros2 bag info <file>` on a ROS '
          'machine.')


def main():
    parser = argparse.ArgumentParser(
        description='Run every motion against unicycle_sim over DDS on simulated time and '
                    'print goal versus achieved pose.')
    parser.add_argument('--rtf', type=float, default=50.0,
                        help='upper bound of simulated seconds per wall second '
                             '(default: %(default)s)')
    parser.add_argument('--figure', default='demo.png',
                        help='PNG with every trajectory (default: %(default)s)')
    parser.add_argument('--record-dir', default=str(RECORD_DIR),
                        help="record each run to an MCAP file here ('': no recording; "
                             'default: %(default)s)')
    options = parser.parse_args()
    missing = [e for e in {'unicycle_sim'} | {m.executable for m in MOTIONS}
               if shutil.which(e) is None]
    if missing:
        print(f'Not on PATH: {", ".join(sorted(missing))}; run `. .venv/bin/activate` first '
              '(or `make demo`).', file=sys.stderr)
        return 2

    # Children inherit the domain: one of our own, discovery on this machine only.
    graph = SimGraph()
    print(f'ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}, localhost only, real-time factor '
          f'{options.rtf:g}', flush=True)
    record_dir = record_dir_for(options.record_dir)
    wall_start = time.monotonic()
    results = []
    try:
        with tempfile.TemporaryDirectory(prefix='motion_demo_') as log_dir:
            for i, motion in enumerate(MOTIONS, 1):
                print(f'[{i}/{len(MOTIONS)}] {motion.label} ...', flush=True)
                results.append(run_motion(motion, graph, options.rtf, log_dir, record_dir))
    except KeyboardInterrupt:
        print('Interrupted')
        return 130
    finally:
        graph.close()

    print()
    print_table(results)
    print(f'\nsim s / wall s: from the first to the last movement seen on odometry. '
          f'Total wall time {time.monotonic() - wall_start:.1f} s.')
    if write_figure(results, options.figure):
        print(f'Figure (path, heading, speeds): {os.path.abspath(options.figure)}')
    else:
        print('No figure: matplotlib is not installed (pip install matplotlib).')
    if record_dir is not None:
        print_recordings(record_dir)
    failed = [r.motion.label for r in results if r.exit_code != 0]
    if failed:
        print('Failed: ' + ', '.join(failed))
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
