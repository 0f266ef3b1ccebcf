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

"""Draw a motion's run to a PNG (matplotlib is optional and imported only here)."""

import math

# Arrow length for poses, as a fraction of the plot's extent.
_ARROW = 0.06
_MARKER_SIZE = {'D': 6, 's': 14, 'o': 9}


def _arrow(axes, pose, size, color, label, marker):
    x, y, yaw = pose
    axes.annotate('', xy=(x + size * math.cos(yaw), y + size * math.sin(yaw)), xytext=(x, y),
                  arrowprops={'arrowstyle': '->', 'color': color, 'lw': 2})
    # Hollow markers of different sizes keep a goal visible under an end that hit it.
    axes.plot([x], [y], marker, color=color, markerfacecolor='none',
              markersize=_MARKER_SIZE[marker], markeredgewidth=2, label=label)


def draw_run(axes, trajectory, start=None, end=None, goal=None, title=''):
    """Draw a trajectory [(x, y, yaw), ...] with start, end and goal poses on axes."""
    xs = [p[0] for p in trajectory]
    ys = [p[1] for p in trajectory]
    axes.plot(xs, ys, '-', color='tab:blue', lw=1.5, label='driven (odometry)')
    extent = max([1e-3] + [abs(v) for v in xs + ys]) if trajectory else 1.0
    size = _ARROW * 2.0 * extent
    for pose, color, label, marker in ((start, 'tab:green', 'start', 'D'),
                                       (goal, 'tab:orange', 'goal', 's'),
                                       (end, 'tab:red', 'end', 'o')):
        if pose is not None:
            _arrow(axes, pose, size, color, label, marker)
    axes.set_aspect('equal', adjustable='datalim')
    axes.set_xlabel('x [m]')
    axes.set_ylabel('y [m]')
    axes.grid(True, alpha=0.3)
    axes.legend(loc='best', fontsize='small')
    axes.set_title(title, fontsize='small', wrap=True)


def plot_run(filename, trajectory, start=None, end=None, goal=None, title=''):
    """Write one run to filename as a PNG; raises ImportError without matplotlib."""
    try:
        import matplotlib
    except ImportError:
        raise ImportError('plot_file needs matplotlib: pip install matplotlib '
                          '(or apt install python3-matplotlib)') from None
    matplotlib.use('Agg')
    from matplotlib import pyplot

    figure, axes = pyplot.subplots(figsize=(6.4, 6.4))
    try:
        draw_run(axes, trajectory, start, end, goal, title)
        figure.tight_layout()
        figure.savefig(filename, dpi=100)
    finally:
        pyplot.close(figure)
