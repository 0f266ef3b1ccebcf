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

from motion_challenges import motion_node
from motion_challenges.circle_back_and_forth import CircleBackAndForth
from motion_challenges.motion_node import MotionState
from motion_challenges.odom_out_and_back import OdomOutAndBack
from motion_challenges.plotting import plot_run
from motion_challenges.plotting import step_series
from motion_challenges.plotting import time_series
from motion_challenges.plotting import unwrap_deg
from motion_challenges.plotting import write_plot
from motion_challenges.prompts import RotationRequest
from motion_challenges.rotate_robot import ask_missing
from motion_challenges.rotate_robot import RotateRobot
from motion_challenges.timed_out_and_back import TimedOutAndBack
from nav_msgs.msg import Path
import pytest
from rclpy.parameter import Parameter
from sim_diffdrive.harness import pose_of
from sim_diffdrive.lockstep.participant import Participant
from sim_diffdrive.parameters import ParameterError
from sim_diffdrive.runtime import EXIT_FAILED


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


# plot_file's figure: 12.8 x 6.4 inches at 100 dpi (rows, columns, RGBA).
PLOT_SHAPE = (640, 1280, 4)
NS = 1_000_000_000


def assert_png(path, shape):
    image = pytest.importorskip('matplotlib.image')
    assert path.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    # Far more than an empty canvas: a path and three panels of curves and labels.
    assert path.stat().st_size > 30_000
    assert image.imread(path).shape == shape


def test_motion_writes_a_png_of_its_run(graph, tmp_path):
    pytest.importorskip('matplotlib')
    plot = tmp_path / 'run.png'
    node = run_with_plot(graph, TimedOutAndBack, plot, goal_distance=0.5, pause=0.2)
    graph.step_until(lambda: node.done, sim_timeout=30.0)
    assert node.exit_code == 0
    assert_png(plot, PLOT_SHAPE)  # in this graph, nobody waits for it: as it ended
    # The trajectory drawn is the odometry of the run: out 0.5 m and back.
    xs = [x for x, _, _ in node.trajectory]
    assert max(xs) == pytest.approx(0.5, abs=1e-9)
    assert math.hypot(*node.trajectory[-1][:2]) < 1e-6


def test_against_a_simulator_in_lockstep_it_plots_once_it_has_left(graph, tmp_path, monkeypatch):
    # Drawn as it ended (0.5 s, 4 s on a loaded machine), in a simulator's lockstep, the plot
    # held everyone's clock: a fleet's other robots failed, a lone motion was dropped.
    pytest.importorskip('matplotlib')
    plot = tmp_path / 'run.png'
    node = run_with_plot(graph, TimedOutAndBack, plot, goal_distance=0.5, pause=0.2)
    graph.step_until(lambda: node.state is MotionState.RUNNING, sim_timeout=5.0)
    monkeypatch.setattr(Participant, 'owner_present', property(lambda self: True))
    left_when_plotted = []
    monkeypatch.setattr(motion_node, 'write_plot', lambda node: (
        left_when_plotted.append(node.lockstep.left), write_plot(node)))
    graph.step_until(lambda: node.done, sim_timeout=30.0)
    assert node.exit_code == 0 and not plot.exists()
    node.shutdown_hook()
    assert left_when_plotted == [True]
    assert_png(plot, PLOT_SHAPE)


def test_a_run_cut_off_is_plotted_as_far_as_it_got(graph, tmp_path, capfd):
    # circle_back_and_forth drives until stopped: by default it could never plot (a user's
    # finding), nor could a motion that failed.  Ctrl-C ends a run through shutdown_hook.
    pytest.importorskip('matplotlib')
    plot = tmp_path / 'circle.png'
    node = run_with_plot(graph, CircleBackAndForth, plot, half_period=3.0)
    graph.step_for(4.0)
    assert not node.done and not plot.exists()
    node.shutdown_hook()
    assert_png(plot, PLOT_SHAPE)
    assert f'Wrote {plot}' in capfd.readouterr().err


def test_a_run_that_failed_is_plotted_as_far_as_it_got(graph, tmp_path):
    pytest.importorskip('matplotlib')
    failed = tmp_path / 'failed.png'
    node = run_with_plot(graph, TimedOutAndBack, failed, goal_distance=0.5, pause=0.2)
    graph.step_for(1.0)
    node.finish(EXIT_FAILED, 'No odometry for 1.2 s mid-motion')  # as its watchdog says it
    node.shutdown_hook()
    assert_png(failed, PLOT_SHAPE)


def test_a_plot_file_that_cannot_be_written_is_refused_at_start_and_live(graph, tmp_path):
    # Found out as the run ended, after the motion: 'Could not write plot_file', exit 0.
    pytest.importorskip('matplotlib')

    def circle(plot_file):
        return CircleBackAndForth(context=graph.context, parameter_overrides=[
            Parameter('plot_file', value=str(plot_file))])
    with pytest.raises(ParameterError, match=r"'plot_file' names a directory that does not "
                                             rf'exist \({tmp_path}/missing\)'):
        circle(tmp_path / 'missing' / 'run.png')
    with pytest.raises(ParameterError, match="'plot_file' must end in a format matplotlib "
                                             'writes: .*pdf, .*png, .*svg'):
        circle(tmp_path / 'run.txt')
    with pytest.raises(ParameterError, match="'plot_file' names a directory, not a file"):
        circle(tmp_path)
    node = graph.add(circle(tmp_path / 'run'))  # no format named: matplotlib writes a PNG
    result, = node.set_parameters([Parameter('plot_file', value=str(tmp_path / 'run.txt'))])
    assert not result.successful and 'format matplotlib writes' in result.reason


def test_a_plot_file_gone_by_the_end_is_reported_not_fatal(graph, tmp_path, capfd):
    # A savefig that raises (its directory removed meanwhile) made a Ctrl-C exit 1 from
    # shutdown_hook and said the robot may not have been told to stop.
    pytest.importorskip('matplotlib')
    (tmp_path / 'gone').mkdir()
    node = run_with_plot(graph, RotateRobot, tmp_path / 'gone' / 'run.png',
                         angular_speed_deg=90.0, angle_deg=45.0, clockwise=False)
    (tmp_path / 'gone').rmdir()
    # Every answer is a parameter: nothing is read.
    ask_missing(node, read_line=lambda: '', write=lambda text: None)
    graph.step_until(lambda: node.done, sim_timeout=10.0)
    node.shutdown_hook()
    assert node.exit_code == 0
    assert 'Could not write plot_file: [Errno 2]' in capfd.readouterr().err


@pytest.mark.parametrize('node_class,params', [
    (RotateRobot, {'mode': 'odom'}),
    (OdomOutAndBack, {'goal_distance': 0.5}),
    (CircleBackAndForth, {'cycles': 1, 'half_period': 3.0}),
], ids=['rotate_720_clockwise', 'odom_out_and_back', 'circle'])
def test_every_motion_plots_path_heading_and_speeds(graph, tmp_path, node_class, params):
    pytest.importorskip('matplotlib')
    plot = tmp_path / f'{node_class.__name__}.png'
    node = run_with_plot(graph, node_class, plot, **params)
    if node_class is RotateRobot:
        node.start(RotationRequest(90.0, 720.0, True))
    graph.step_until(lambda: node.done, sim_timeout=40.0)
    assert node.exit_code == 0
    assert_png(plot, PLOT_SHAPE)
    # What was recorded for it: odometry (stamp, yaw, twist) and the commands, all on sim time
    # from the start on, the last command the stop.
    assert len(node.odometry_samples) == len(node.trajectory) > 10
    assert all(t >= node.start_ns for t, *_ in node.odometry_samples + node.sent_commands)
    assert node.sent_commands[0][0] == node.start_ns
    assert node.sent_commands[-1][1:] == (0.0, 0.0)
    series = time_series([(node.start_odom.stamp_ns, node.start_odom.yaw, 0.0, 0.0)]
                         + node.odometry_samples, node.sent_commands, node.start_ns)
    if node_class is RotateRobot:
        assert series.heading_deg[-1] == pytest.approx(-720.0, abs=0.01)
        assert min(series.command_angular[1]) == pytest.approx(-90.0)
        assert max(series.linear) == 0.0
    else:
        assert max(series.command_linear[1]) > 0.0


def test_unwrap_deg_follows_the_turn_across_the_wrap():
    yaws = [math.radians(d) for d in (170.0, -170.0, -10.0, 10.0)]
    assert unwrap_deg(yaws) == pytest.approx([170.0, 190.0, 350.0, 370.0])
    assert unwrap_deg([]) == []


def test_step_series_holds_each_command_until_the_next():
    xs, ys = step_series([0.0, 0.02, 0.04, 0.06], [0.5, 0.5, 0.0, 0.0], end=0.1)
    # A repeated value adds no step; the last value holds until the end.
    assert xs == [0.0, 0.04, 0.04, 0.1]
    assert ys == [0.5, 0.5, 0.0, 0.0]
    assert step_series([], [], end=1.0) == ([], [])
    assert step_series([1.0], [2.0]) == ([1.0], [2.0])


def test_time_series_of_a_720_deg_clockwise_turn():
    """Hand-made samples: turn -720 deg at -90 deg/s in 8 s, odometry every 0.5 s."""
    start_ns = 5 * NS
    rate = math.radians(-90.0)
    odometry = []
    for i in range(19):
        t = 0.5 * i
        turning = 0.0 < t <= 8.0
        yaw = math.remainder(rate * min(t, 8.0), 2.0 * math.pi)  # as odometry wraps it
        odometry.append((start_ns + int(t * NS), yaw, 0.0, rate if turning else 0.0))
    commands = [(start_ns + int(0.02 * i * NS), 0.0, rate) for i in range(400)]
    commands.append((start_ns + 8 * NS, 0.0, 0.0))
    # The goal as the motion gives it (start yaw - 4 pi) or wrapped: the same line.
    for goal_yaw in (-4.0 * math.pi, 0.0):
        series = time_series(odometry, commands, start_ns, goal_yaw)
        assert series.t[0] == 0.0 and series.t[-1] == 9.0
        assert series.heading_deg == pytest.approx(
            [-90.0 * min(0.5 * i, 8.0) for i in range(19)], abs=1e-9)
        assert series.heading_deg[-1] == pytest.approx(-720.0)
        assert series.goal_heading_deg == pytest.approx(-720.0)
        assert series.angular_deg[1] == pytest.approx(-90.0)
        # Commanded: -90 deg/s from 0 to 8 s, then 0 until the last odometry (9 s).
        assert series.command_angular[0] == pytest.approx([0.0, 8.0, 8.0, 9.0])
        assert series.command_angular[1] == pytest.approx([-90.0, -90.0, 0.0, 0.0])
        assert series.command_linear == ([0.0, 9.0], [0.0, 0.0])


def test_time_series_without_a_start_counts_from_the_first_sample():
    series = time_series([(2 * NS, 0.0, 0.1, 0.0), (3 * NS, 0.0, 0.2, 0.0)],
                         [(NS, 0.3, 0.0)])
    assert series.t == [1.0, 2.0]
    assert series.command_linear == ([0.0, 2.0], [0.3, 0.3])
    assert series.goal_heading_deg is None
    empty = time_series([], [])
    assert empty.t == [] and empty.command_linear == ([], [])


def test_plot_run_without_series_draws_the_path_alone(tmp_path):
    pytest.importorskip('matplotlib')
    plot = tmp_path / 'path.png'
    plot_run(str(plot), [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0)], start=(0.0, 0.0, 0.0),
             end=(1.0, 0.0, 0.0), goal=(1.0, 0.0, 0.0), title='path only')
    image = pytest.importorskip('matplotlib.image')
    assert image.imread(plot).shape == (640, 640, 4)
