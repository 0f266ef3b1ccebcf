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
The ``plot_file`` hook: a finished motion's path and time series, drawn by plotting.plot_run.

matplotlib is imported only when a plot is asked for.
"""


def write_plot(node, end_odom, achieved):
    """Write node's run to its plot_file (end_odom may be None); log what became of it."""
    from motion_challenges.plotting import plot_run
    from motion_challenges.plotting import time_series
    start = node.start_odom
    goal = node.goal_pose(start) if start else None
    # The odometry the motion started on comes first: the heading starts from its yaw.
    odometry = ([(start.stamp_ns, start.yaw, *start.twist)] if start else []) + [
        s for s in node.odometry_samples if not start or s[0] > start.stamp_ns]
    plot_file = node.params.plot_file
    try:
        plot_run(plot_file, node.trajectory,
                 start=(start.x, start.y, start.yaw) if start else None,
                 end=(end_odom.x, end_odom.y, end_odom.yaw) if end_odom else None,
                 goal=goal, title=f'{node.get_name()}: {achieved}',
                 series=time_series(odometry, node.sent_commands, node.start_ns,
                                    goal[2] if goal else None))
    except (ImportError, OSError) as error:
        node.get_logger().error(f'Could not write plot_file: {error}')
        return
    node.get_logger().info(f'Wrote {plot_file}')
