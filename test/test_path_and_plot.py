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

"""What users look at: the driven path for RViz and the PNG a motion writes of its run."""

import math

from motion_challenges.rotate_robot import ask_missing
from motion_challenges.rotate_robot import RotateRobot
from motion_challenges.timed_out_and_back import TimedOutAndBack
from nav_msgs.msg import Path
import pytest
from rclpy.parameter import Parameter
from sim_diffdrive.harness import pose_of


def test_path_follows_the_odometry_and_keeps_its_length_bounded(graph):
    graph.sim(path_length=5, path_rate_hz=10.0)
    probe = graph.probe()
    paths = []
    probe.create_subscription(Path, 'path', paths.append, 10)
    probe.play([(0.5, 0.0, 20)])
    graph.step_until(lambda: not probe.playing, sim_timeout=10.0)
    graph.step_for(0.2)
    path = paths[-1]
    assert len(path.poses) == 5
    assert path.header.frame_id == 'odom'
    stamps = [p.header.stamp.sec + p.header.stamp.nanosec * 1e-9 for p in path.poses]
    assert stamps == sorted(stamps)
    assert [round(b - a, 9) for a, b in zip(stamps, stamps[1:])] == [0.1] * 4
    # The newest pose is where odometry says the robot is: 1 m along x.
    assert path.poses[-1].pose.position.x == pytest.approx(1.0, abs=1e-9)
    assert pose_of(probe.odom)[0] == pytest.approx(1.0, abs=1e-9)


def run_with_plot(graph, node_class, plot_file, **params):
    graph.sim()
    node = graph.add(node_class(context=graph.context, parameter_overrides=[
        Parameter(name, value=value) for name, value in
        dict(params, use_sim_time=True, plot_file=str(plot_file)).items()]))
    return node


def test_motion_writes_a_png_of_its_run(graph, tmp_path):
    pytest.importorskip('matplotlib')
    plot = tmp_path / 'run.png'
    node = run_with_plot(graph, TimedOutAndBack, plot, goal_distance=0.5, pause=0.2)
    graph.step_until(lambda: node.done, sim_timeout=30.0)
    assert node.exit_code == 0
    assert plot.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    # The trajectory drawn is the odometry of the run: out 0.5 m and back.
    xs = [x for x, _, _ in node.trajectory]
    assert max(xs) == pytest.approx(0.5, abs=1e-9)
    assert math.hypot(*node.trajectory[-1][:2]) < 1e-6


def test_unwritable_plot_file_is_reported_not_fatal(graph, tmp_path):
    pytest.importorskip('matplotlib')
    node = run_with_plot(graph, RotateRobot, tmp_path / 'missing' / 'run.png',
                         angular_speed_deg=90.0, angle_deg=45.0, clockwise=False)
    # Every answer is a parameter: nothing is read.
    ask_missing(node, read_line=lambda: '', write=lambda text: None)
    graph.step_until(lambda: node.done, sim_timeout=10.0)
    assert node.exit_code == 0
    assert not (tmp_path / 'missing').exists()
