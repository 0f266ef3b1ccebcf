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
Draw a motion's run to a PNG: its path beside heading and speeds (matplotlib, imported lazily).

``time_series`` prepares the series from the recorded samples and is plain code.
"""

from collections import namedtuple
import math
import os

import numpy as np

_NS = 1e9
# Arrows of poses: a fraction of the path's extent, but never shorter than _MIN_ARROW [m], so
# that a turn in place (a path that is a dot) still shows where the robot pointed.
_ARROW = 0.08
_MIN_ARROW = 0.1
# The path panel spans at least this much [m] in each direction.
_MIN_VIEW = 0.35
_MARKER_SIZE = {'D': 7, 's': 15, 'o': 10}
# Poses that coincide (the end on the goal, a turn in place) keep every arrow visible: the
# first drawn are the widest.
_ARROW_STYLE = {'goal': {'lw': 6.0, 'alpha': 0.45, 'mutation_scale': 26},
                'start': {'lw': 3.5, 'alpha': 0.9, 'mutation_scale': 20},
                'end': {'lw': 1.5, 'alpha': 1.0, 'mutation_scale': 13}}
# Commanded wide and light under the achieved line: where they agree, both show.
_ACHIEVED = {'color': 'tab:blue', 'lw': 1.4, 'label': 'achieved (odometry)'}
_COMMANDED = {'color': 'tab:gray', 'lw': 4.0, 'alpha': 0.5, 'label': 'commanded'}
_GOAL = {'color': 'tab:orange', 'lw': 1.6, 'ls': '--', 'label': 'goal'}
# Heading ticks: the smallest of these steps that gives at most 7 intervals [deg].
_HEADING_STEPS = (15.0, 30.0, 45.0, 90.0, 180.0, 360.0, 720.0, 1440.0)

RunSeries = namedtuple('RunSeries', [
    't',  # odometry times [s from the motion's start]
    'heading_deg',  # odometry yaw, unwrapped [deg]
    'linear',  # odometry's twist, linear.x [m/s]
    'angular_deg',  # odometry's twist, angular.z [deg/s]
    'command_linear',  # (times [s], values [m/s]) of the commanded linear.x as a step series
    'command_angular',  # (times [s], values [deg/s]) of the commanded angular.z, likewise
    'goal_heading_deg',  # the goal yaw on the unwrapped heading's branch [deg], or None
])


def unwrap_deg(yaws):
    """Return yaws [rad] as continuous degrees: no jump of 360 where the angle wraps."""
    return np.degrees(np.unwrap(yaws)).tolist()


def step_series(times, values, end=None):
    """
    Return (times, values) that draw values[i] held from times[i] until times[i + 1].

    The last value holds until end (when later than its time).  A repeated value adds no step.
    """
    xs, ys = [], []
    for t, value in zip(times, values):
        if not ys:
            xs, ys = [t], [value]
        elif value != ys[-1]:
            xs += [t, t]
            ys += [ys[-1], value]
    if ys and end is not None and end > xs[-1]:
        xs, ys = xs + [end], ys + [ys[-1]]
    return xs, ys


def time_series(odometry, commands=(), start_ns=None, goal_yaw=None):
    """
    Turn the samples of a run into the RunSeries to draw.

    odometry: [(stamp_ns, yaw [rad], linear [m/s], angular [rad/s])]; commands: [(time_ns,
    linear, angular)] as sent; both on the same (simulated) clock.  Times count from start_ns
    (default: the first sample).  goal_yaw [rad] goes on the heading's branch nearest the last
    heading, so that a goal of turning twice round is drawn at -720 deg, not at 0.
    """
    odometry = sorted(odometry, key=lambda sample: sample[0])
    commands = sorted(commands, key=lambda command: command[0])
    if start_ns is None:
        start_ns = min((samples[0][0] for samples in (odometry, commands) if samples), default=0)
    t = [(stamp - start_ns) / _NS for stamp, *_ in odometry]
    heading = unwrap_deg([yaw for _, yaw, _, _ in odometry])
    command_t = [(stamp - start_ns) / _NS for stamp, *_ in commands]
    end = max(t[-1:] + command_t[-1:]) if t or command_t else None
    goal_deg = None if goal_yaw is None else unwrap_deg(
        [math.radians(last) for last in heading[-1:]] + [goal_yaw])[-1]
    return RunSeries(t, heading, [v for _, _, v, _ in odometry],
                     [math.degrees(w) for _, _, _, w in odometry],
                     step_series(command_t, [v for _, v, _ in commands], end),
                     step_series(command_t, [math.degrees(w) for _, _, w in commands], end),
                     goal_deg)


def draw_run(axes, trajectory, start=None, end=None, goal=None, title='', legend=True):
    """Draw a trajectory [(x, y, yaw), ...] with start, end and goal poses on axes."""
    xs, ys = [p[0] for p in trajectory], [p[1] for p in trajectory]
    axes.plot(xs, ys, '-', color='tab:blue', lw=1.5, label='driven (odometry)')
    poses = [p for p in ((goal, 'tab:orange', 'goal', 's'), (start, 'tab:green', 'start', 'D'),
                         (end, 'tab:red', 'end', 'o')) if p[0] is not None]
    px = xs + [pose[0] for pose, *_ in poses] or [0.0]
    py = ys + [pose[1] for pose, *_ in poses] or [0.0]
    span = max(max(px) - min(px), max(py) - min(py))
    size = max(_ARROW * span, _MIN_ARROW)
    for (x, y, yaw), color, label, marker in poses:
        axes.annotate('', xy=(x + size * math.cos(yaw), y + size * math.sin(yaw)), xytext=(x, y),
                      arrowprops=dict(_ARROW_STYLE[label], arrowstyle='-|>', color=color,
                                      shrinkA=0, shrinkB=0))
        # Hollow markers of different sizes keep a goal visible under an end that hit it.
        axes.plot([x], [y], marker, color=color, markerfacecolor='none',
                  markersize=_MARKER_SIZE[marker], markeredgewidth=2, label=label)
    # Arrows do not count in matplotlib's limits: the view holds their tips, and a minimum.
    px += [x + size * math.cos(yaw) for (x, _, yaw), *_ in poses]
    py += [y + size * math.sin(yaw) for (_, y, yaw), *_ in poses]
    corners = []
    for low, high in ((min(px), max(px)), (min(py), max(py))):
        half = max(0.55 * (high - low), 0.5 * _MIN_VIEW)
        corners.append((0.5 * (low + high) - half, 0.5 * (low + high) + half))
    axes.update_datalim(list(zip(*corners)))
    axes.autoscale_view()
    axes.set_aspect('equal', adjustable='datalim')
    axes.set(xlabel='x [m]', ylabel='y [m]')
    axes.grid(True, alpha=0.3)
    if legend:
        axes.legend(loc='best', fontsize='small')
    if title:
        axes.set_title(title, fontsize='small', wrap=True)


def draw_series(heading_axes, linear_axes, angular_axes, series, legend=True):
    """Draw a RunSeries: heading, linear and angular speed over time on three axes."""
    from matplotlib.ticker import MultipleLocator

    heading_axes.plot(series.t, series.heading_deg, **_ACHIEVED)
    if series.goal_heading_deg is not None:
        heading_axes.axhline(series.goal_heading_deg, **_GOAL)
    heading_axes.set_ylabel('heading [deg]')
    # Multiples of 45 or 90 deg for turns; matplotlib's choice for a small wobble.
    values = series.heading_deg + [series.goal_heading_deg] * (series.goal_heading_deg is not None)
    if values and max(values) - min(values) > 30.0:
        step = next((s for s in _HEADING_STEPS if (max(values) - min(values)) / s <= 7.0),
                    _HEADING_STEPS[-1])
        heading_axes.yaxis.set_major_locator(MultipleLocator(step))
    for axes, (times, values), achieved, unit in (
            (linear_axes, series.command_linear, series.linear, 'linear [m/s]'),
            (angular_axes, series.command_angular, series.angular_deg, 'angular [deg/s]')):
        axes.plot(times, values, solid_joinstyle='miter', **_COMMANDED)
        axes.plot(series.t, achieved, **_ACHIEVED)
        axes.set_ylabel(unit)
    angular_axes.set_xlabel('time since the start [s, simulated]')
    for axes in (heading_axes, linear_axes, angular_axes):
        axes.grid(True, alpha=0.3)
        axes.margins(x=0.02, y=0.12)
        if legend:
            axes.legend(loc='best', fontsize='x-small')
    for axes in (heading_axes, linear_axes):
        axes.tick_params(labelbottom=False)


def plot_run(filename, trajectory, start=None, end=None, goal=None, title='', series=None):
    """Write one run to filename as a PNG (with series: heading and speeds beside the path)."""
    try:
        import matplotlib
    except ImportError:
        raise ImportError('plot_file needs matplotlib: pip install matplotlib '
                          '(or apt install python3-matplotlib)') from None
    matplotlib.use('Agg')
    from matplotlib import pyplot

    figure = pyplot.figure(figsize=(6.4, 6.4) if series is None else (12.8, 6.4))
    try:
        if series is None:
            draw_run(figure.add_subplot(), trajectory, start, end, goal, title)
        else:
            grid = figure.add_gridspec(3, 2, width_ratios=(1.0, 1.15))
            path_axes = figure.add_subplot(grid[:, 0])
            heading_axes = figure.add_subplot(grid[0, 1])
            draw_run(path_axes, trajectory, start, end, goal)
            draw_series(heading_axes, figure.add_subplot(grid[1, 1], sharex=heading_axes),
                        figure.add_subplot(grid[2, 1], sharex=heading_axes), series)
            figure.suptitle(title, fontsize='medium', wrap=True)
        figure.tight_layout()
        figure.savefig(filename, dpi=100)
    finally:
        pyplot.close(figure)


def plot_file_problem(path):
    """Return why a plot cannot be written to path, or None ('' asks for none)."""
    folder = os.path.dirname(os.path.abspath(path))
    if path and not os.path.isdir(folder):
        return f'names a directory that does not exist ({folder})'
    if path and (os.path.isdir(path) or path.endswith('/')):
        return 'names a directory, not a file'
    suffix = os.path.splitext(path)[1][1:]
    if not suffix:  # nothing asked, or no format named (matplotlib writes a PNG)
        return None
    try:
        from matplotlib.backend_bases import FigureCanvasBase
    except ImportError:
        return 'needs matplotlib: pip install matplotlib (or apt install python3-matplotlib)'
    formats = FigureCanvasBase.get_supported_filetypes()
    if suffix.lower() not in formats:
        return 'must end in a format matplotlib writes: ' + ', '.join(sorted(formats))
    return None


def write_plot(node, plot_file=None):
    """
    Write a motion node's run to its plot_file, if it has one and the motion began; log it.

    However the run ended: its closing line's goal against the achieved pose (``node.plot_end``:
    the odometry at rest and that text) once it settled, else ``node.ending`` (why it stopped).
    """
    # A fleet's robot: a file of its own.  (params.plot_file is checked as it is read, and
    # its directory may be gone by now: savefig below says so.)
    plot_file = node.get_parameter('plot_file').value if plot_file is None else plot_file
    if not plot_file or node.start_ns is None:
        return
    end_odom, achieved = node.plot_end or (None, node.ending)
    start = node.start_odom
    goal = node.goal_pose(start) if start else None
    # The odometry the motion started on comes first: the heading starts from its yaw.
    odometry = ([(start.stamp_ns, start.yaw, *start.twist)] if start else []) + [
        s for s in node.odometry_samples if not start or s[0] > start.stamp_ns]
    try:
        plot_run(plot_file, node.trajectory,
                 start=(start.x, start.y, start.yaw) if start else None,
                 end=(end_odom.x, end_odom.y, end_odom.yaw) if end_odom else None, goal=goal,
                 title=f'{node.get_name()}: {achieved}', series=time_series(
                     odometry, node.sent_commands, node.start_ns, goal[2] if goal else None))
    except Exception as error:  # no matplotlib, no such directory, a format it has not ...
        # ... never ends a run that was ending anyway, nor its final stop, in a traceback
        node.get_logger().error(f'Could not write plot_file: {error}')
        return
    node.get_logger().info(f'Wrote {plot_file}')
