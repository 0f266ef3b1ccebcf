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
The run, live in a browser (view_port): Rerun's web viewer, fed on simulated time.

How and why (the rerun program, the frames, privacy): docs/visualization.md, "In the browser".
``BrowserView`` logs ``world/robots``, ``world/heading``, ``world/map``, ``world/scan``,
``world/paths`` (broken at a jump) and ``speed/linear``, ``speed/angular`` (achieved and
commanded) as numpy arrays, shaped by the plain functions at the end.
"""

import atexit
import collections
import colorsys
import contextlib
import os
import shutil
import socket
import subprocess
import tempfile
import threading
import time
import uuid

import numpy as np
from sim_diffdrive.angles import quaternion_from_yaw
from sim_diffdrive.taps.view_page import ephemeral_ports
from sim_diffdrive.taps.view_page import free_port
from sim_diffdrive.taps.view_page import page_url
from sim_diffdrive.taps.view_page import port_is_free
from sim_diffdrive.taps.view_page import ViewerPage

DEFAULT_HOST = '127.0.0.1'
TIMELINE = 'sim_time'
# At most this many frames per wall second (a screen shows no more); the steps between two
# frames go with the next one.
FRAME_PERIOD_S = 1.0 / 30.0
# The steps one frame can hold: fewer with more robots, so memory stays a few MB.
_MAX_VALUES_PER_FRAME = 1 << 18
# How long the rerun program may take to listen [s], and to stop before it is killed.
START_TIMEOUT_S = 15.0
STOP_TIMEOUT_S = 3.0
# The robot as drawn, in its base frame [m]: a box on the ground and an arrow along +x.
BODY_HALF_SIZE = (0.15, 0.12, 0.05)
ARROW_LENGTH = 0.35
PATH_RADIUS = 0.01
MAP_RGB = (150, 150, 150)
SCAN_RADIUS = 0.015
SCAN_Z = 0.03
# More robots than these: no name labels in the view, no legend in the plots (they pile up).
_LABELLED_ROBOTS = 16
_LEGEND_ROBOTS = 1
# The map's obstacle cells as drawn: flat slabs just under the robots; the scan's hit points.
MAP_HALF_HEIGHT = 0.02
# A step longer than its robot can have driven is a jump (a reset): no path segment joins it.
_JUMP_MARGIN_M = 1e-3
_GOLDEN = 0.618033988749895


class BrowserView:
    """A tap drawing every robot in Rerun's web viewer."""

    name = 'view_port'
    wants_path = False

    def __init__(self, port, node, host=DEFAULT_HOST):
        """Serve the viewer on host:port, fed by a new rerun program (ImportError, OSError)."""
        import rerun as rr
        program = rerun_program()
        self._rr = rr
        self._thread = None
        self._closing = contextlib.ExitStack()  # what close() stops, the last made first
        self._home = self._closing.enter_context(tempfile.TemporaryDirectory(
            prefix='unicycle_sim_view_', ignore_cleanup_errors=True))
        self._sim_clock = node.params.publish_clock or node.get_parameter('use_sim_time').value
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._failure = None  # why the view stopped, for the simulator to report
        surroundings = getattr(node, 'surroundings', None)
        grid = surroundings.grid if surroundings is not None else None
        # With a map: each robot's scan topic -> its row, this step's ranges, the newest scan.
        self._scan_rows = ({pub.topic_name: i for i, pub in enumerate(surroundings.scan_pubs)}
                           if surroundings is not None else {})
        self._ranges = self._angles = self._scan = None
        self._scan_fresh = False
        self._colors = robot_colors(len(node.world.names))
        try:
            grpc_port, files_port = _grpc_port(host, port), free_port(host)
            run = uuid.uuid4()
            self.grpc_url = f'rerun+http://{host}:{grpc_port}/proxy'
            self._page = ViewerPage(host, port, files_port, [
                f'http://{name}:{grpc_port}' for name in (host, 'localhost')],
                (run.hex, self.grpc_url))
            self._closing.callback(self._page.close)
            self._process = self._start_rerun(program, host, grpc_port, files_port)
            self._closing.callback(_stop, self._process)
            self.url = page_url(self._page.port, self.grpc_url)
            self._rec = rr.RecordingStream('unicycle_sim', recording_id=run)
            self._closing.callback(self._rec.disconnect)
            self._closing.callback(self._rec.flush, timeout_sec=1.0)
            # Simulated time only: a wall-clock timeline would only show the frames' latency.
            rr.set_log_time_enabled(False, recording=self._rec)
            self._rec.connect_grpc(self.grpc_url, default_blueprint=_blueprint(node.world, grid))
            self._log_static(node.world.names, grid)
        except BaseException:
            self.close()
            raise
        self._frames = _Frames(len(node.world.names), in_map=grid is not None)
        self._thread = threading.Thread(target=self._send_frames, name='browser_view', daemon=True)
        self._thread.start()
        atexit.register(self.close)
        node.get_logger().info(f'Browser view: open {self.url}')

    def _start_rerun(self, program, host, grpc_port, files_port):
        env = dict(os.environ, XDG_CONFIG_HOME=os.path.join(self._home, 'config'),
                   XDG_DATA_HOME=os.path.join(self._home, 'data'), TELEMETRY_ENABLED='false')
        try:  # Rerun's documented opt-out, written to this run's own configuration directory
            subprocess.run([program, 'analytics', 'disable'], env=env, timeout=30, check=True,
                           stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                           stderr=subprocess.DEVNULL)
        except subprocess.SubprocessError as error:
            raise OSError(f'{program} analytics disable failed: {error}') from error
        command = [program, '--serve-web', '--bind', host, '--port', str(grpc_port),
                   '--web-viewer-port', str(files_port)]
        setpriv = shutil.which('setpriv')
        if setpriv is not None:  # util-linux: the kernel stops it should this process die
            command = [setpriv, '--pdeathsig', 'TERM', '--'] + command
        self._log_path = os.path.join(self._home, 'rerun.log')
        with open(self._log_path, 'wb') as log:
            # Its own session: a Ctrl-C in the terminal reaches the simulator, which stops it.
            process = subprocess.Popen(command, env=env, stdin=subprocess.DEVNULL, stdout=log,
                                       stderr=subprocess.STDOUT, start_new_session=True)
        deadline = time.monotonic() + START_TIMEOUT_S
        while not (_listening(host, grpc_port) and _listening(host, files_port)):
            if process.poll() is not None or time.monotonic() > deadline:
                _stop(process)
                raise OSError(f'the rerun program did not start ({self._log_tail()})')
            time.sleep(0.02)
        return process

    def _log_tail(self):
        lines = []
        with contextlib.suppress(OSError), open(self._log_path, 'rb') as log:
            lines = log.read().decode(errors='replace').strip().splitlines()
        return lines[-1] if lines else 'no output'

    def write(self, topic, msg, stamp_ns):
        """Keep a robot's scan for step() to draw from the pose of the step it precedes."""
        row = self._scan_rows.get(topic)
        if row is None or isinstance(msg, bytes):
            return
        ranges = np.frombuffer(msg.ranges, dtype=np.float32)
        if self._ranges is None or self._ranges.shape[1] != len(ranges):
            self._ranges = np.full((len(self._scan_rows), len(ranges)), np.inf, np.float32)
            self._angles = msg.angle_min + msg.angle_increment * np.arange(len(ranges))
        self._ranges[row] = ranges
        self._scan_fresh = True

    def step(self, stamp_ns, fleet):
        """Keep every robot's state at stamp_ns (and the step's scans) for the next frame."""
        if self._failure is not None:
            raise OSError(self._failure)
        with self._lock:
            frames = self._frames
            if frames.full:  # the sending thread is starved: send from here
                self._log(frames.take(), self._take_scan())
            frames.add(stamp_ns, fleet)
            if self._scan_fresh:  # drawn from the poses just kept (the map frame's)
                self._scan_fresh = False
                last = frames.steps - 1
                self._scan = (stamp_ns, self._ranges.copy(), self._angles,
                              frames.x[last].copy(), frames.y[last].copy(),
                              frames.yaw[last].copy())

    def _take_scan(self):
        """Return the newest scan not drawn yet, or None (with the lock held)."""
        scan, self._scan = self._scan, None
        return scan

    def _send_frames(self):
        while not self._stop.wait(FRAME_PERIOD_S):
            try:
                if self._process.poll() is not None:
                    raise OSError(f'the rerun program stopped ({self._log_tail()})')
                with self._lock:
                    frame, scan = self._frames.take(), self._take_scan()
                self._log(frame, scan)
            except Exception as error:  # reported by the next step(), which drops the view
                self._failure = f'{type(error).__name__}: {error}'
                return

    def _log(self, frame, scan=None):
        """Log the frame's newest poses, its paths and speeds, and scan (or None) at its stamp."""
        if frame is None:
            return
        rr, rec = self._rr, self._rec
        stamps, x, y, yaw = frame.stamps, frame.x[-1], frame.y[-1], frame.yaw[-1]
        self._set_time(stamps[-1])
        times = rr.TimeColumn(TIMELINE, **self._when(stamps))
        count, zeros = len(x), np.zeros(len(x))
        positions = np.column_stack([x, y, zeros])
        quaternions = np.column_stack([zeros, zeros, np.sin(0.5 * yaw), np.cos(0.5 * yaw)])
        rec.log('world/robots', rr.Boxes3D.from_fields(centers=positions, quaternions=quaternions))
        heading = np.column_stack([ARROW_LENGTH * np.cos(yaw), ARROW_LENGTH * np.sin(yaw), zeros])
        rec.log('world/heading', rr.Arrows3D.from_fields(origins=positions, vectors=heading))
        if frame.strips is not None:
            rec.log('world/paths', rr.LineStrips3D.from_fields(strips=frame.strips))
        rows = [2 * count] * len(stamps)
        for name, achieved, commanded in (('linear', frame.linear, frame.target_linear),
                                          ('angular', frame.angular, frame.target_angular)):
            values = np.concatenate([achieved, commanded], axis=1).ravel()
            rec.send_columns(f'speed/{name}', indexes=[times],
                             columns=rr.Scalars.columns(scalars=values).partition(rows))
        if scan is not None:
            stamp, ranges, angles, scan_x, scan_y, scan_yaw = scan
            points, owners = scan_points(ranges, angles, scan_x, scan_y, scan_yaw)
            positions = np.full((len(points), 3), SCAN_Z)
            positions[:, :2] = points
            self._set_time(stamp)
            rec.log('world/scan', rr.Points3D.from_fields(
                positions=positions, colors=self._colors[owners]))

    def _set_time(self, stamp_ns):
        self._rec.set_time(TIMELINE, **self._when(np.int64(stamp_ns)))

    def _when(self, stamps_ns):
        """Return the timeline's value of stamps [ns]: seconds on sim time, else dates."""
        return ({'duration': stamps_ns * 1e-9} if self._sim_clock
                else {'timestamp': stamps_ns.astype('datetime64[ns]')})

    def _log_static(self, names, grid=None):
        """Log what does not change during the run: axes, colours, names, line styles, map."""
        rr, rec, count = self._rr, self._rec, len(names)
        colors = self._colors
        labels = [name or 'robot' for name in names]
        rec.log('world', rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        if grid is not None:
            centers, half_sizes = solid_boxes(grid)
            rec.log('world/map', rr.Boxes3D(
                centers=centers, half_sizes=half_sizes,
                quaternions=[quaternion_from_yaw(grid.origin[2])], colors=[MAP_RGB],
                fill_mode=rr.components.FillMode.Solid), static=True)
            rec.log('world/scan', rr.Points3D.from_fields(radii=[SCAN_RADIUS]), static=True)
        rec.log('world/robots', rr.Boxes3D.from_fields(
            half_sizes=[BODY_HALF_SIZE], colors=colors, labels=labels,
            show_labels=any(names) and count <= _LABELLED_ROBOTS), static=True)
        rec.log('world/heading', rr.Arrows3D.from_fields(colors=colors), static=True)
        rec.log('world/paths', rr.LineStrips3D.from_fields(
            colors=colors, radii=[PATH_RADIUS]), static=True)
        dimmed = (colors * 0.5 + 127.5).astype(np.uint8)
        for kind in ('linear', 'angular'):
            rec.log(f'speed/{kind}', rr.SeriesLines(
                names=[f'{name} achieved' for name in labels]
                + [f'{name} commanded' for name in labels],
                colors=np.concatenate([colors, dimmed]),
                widths=[2.0] * count + [1.0] * count), static=True)

    def close(self):
        """Send the last frame, stop the rerun program and the page (idempotent)."""
        self._stop.set()
        thread, self._thread = self._thread, None
        try:
            if thread is not None:
                thread.join()
                if self._failure is None:
                    with self._lock:
                        # the steps (and the scan) since the last frame
                        self._log(self._frames.take(), self._take_scan())
        finally:
            self._closing.close()
            atexit.unregister(self.close)


def _blueprint(fleet, grid=None):
    """Return the layout: the robots from above (around their start or the map), speeds."""
    import rerun.blueprint as rrb
    if grid is None:
        center = [float(np.mean(fleet.x)), float(np.mean(fleet.y)), 0.0]
        span = float(max(np.ptp(fleet.x), np.ptp(fleet.y)))
    else:
        size = (grid.width * grid.resolution, grid.height * grid.resolution)
        center = [*(float(v) for v in grid.from_grid(0.5 * size[0], 0.5 * size[1])), 0.0]
        span = float(max(size))
    whole_run = rrb.VisibleTimeRanges(rrb.VisibleTimeRange(
        TIMELINE, start=rrb.TimeRangeBoundary.infinite(),
        end=rrb.TimeRangeBoundary.cursor_relative()))
    top_view = rrb.Spatial3DView(
        origin='world', name='Robots from above (x right, y up)',
        eye_controls=rrb.EyeControls3D(
            position=[center[0], center[1], max(6.0, 1.5 * span + 4.0)], look_target=center,
            eye_up=[0, 1, 0]),
        overrides={'world/paths': whole_run})
    legend = rrb.PlotLegend(visible=len(fleet.x) <= _LEGEND_ROBOTS)
    speeds = rrb.Vertical(
        rrb.TimeSeriesView(origin='speed/linear', name='linear.x [m/s]', plot_legend=legend),
        rrb.TimeSeriesView(origin='speed/angular', name='angular.z [rad/s]', plot_legend=legend))
    return rrb.Blueprint(
        rrb.Horizontal(top_view, speeds, column_shares=[3, 2]),
        rrb.BlueprintPanel(state='collapsed'), rrb.SelectionPanel(state='collapsed'),
        rrb.TimePanel(state='collapsed'))


Frame = collections.namedtuple(
    'Frame', 'stamps x y yaw linear angular target_linear target_angular strips')


class _Frames:
    """Every robot's state at each step since the last frame, and where each path left off."""

    FIELDS = ('x', 'y', 'yaw', 'linear', 'angular', 'target_linear', 'target_angular')

    def __init__(self, count, in_map=False):
        self.in_map = in_map  # the poses kept are the map frame's (world.map_poses())
        self.capacity = min(8192, max(64, _MAX_VALUES_PER_FRAME // count))
        self.stamps = np.zeros(self.capacity, dtype=np.int64)
        for name in self.FIELDS:
            setattr(self, name, np.zeros((self.capacity, count)))
        self.steps = 0
        self._path_end = None  # (stamp_ns, x, y, linear) of the newest step already sent

    @property
    def full(self):
        return self.steps == self.capacity

    def add(self, stamp_ns, fleet):
        i = self.steps
        self.stamps[i] = stamp_ns
        for name in self.FIELDS:
            getattr(self, name)[i] = getattr(fleet, name)
        if self.in_map:
            self.x[i], self.y[i], self.yaw[i] = fleet.map_poses()
        self.steps = i + 1

    def take(self):
        """Return the steps since the last frame as a Frame (None if none) and forget them."""
        steps = self.steps
        if steps == 0:
            return None
        stamps, xs, ys, linear = (
            self.stamps[:steps], self.x[:steps].T, self.y[:steps].T, self.linear[:steps].T)
        if self._path_end is not None:  # the paths go on from where they left off
            stamps, xs, ys, linear = (np.concatenate([np.asarray(start)[..., None], now], axis=-1)
                                      for start, now in zip(self._path_end, (
                                          stamps, xs, ys, linear)))
        frame = Frame(self.stamps[:steps].copy(), *(
            getattr(self, name)[:steps].copy() for name in self.FIELDS),
            path_strips(stamps, xs, ys, linear))
        self._path_end = tuple(value[..., -1].copy() for value in (stamps, xs, ys, linear))
        self.steps = 0
        return frame


def rerun_program():
    """Return the path of the rerun program the rerun-sdk wheel installed."""
    with contextlib.suppress(ImportError):
        import rerun_cli
        program = os.path.join(os.path.dirname(rerun_cli.__file__), 'rerun')
        if os.access(program, os.X_OK):
            return program
    program = shutil.which('rerun')
    if program is None:
        raise ImportError('the rerun program of rerun-sdk is not installed')
    return program


def _grpc_port(host, view_port):
    """Return view_port + 1 when free (the same address to open, run after run), else any."""
    grpc_port = view_port + 1
    # Not from the ephemeral range, where an outgoing connection may take it first (free_port).
    if 0 < view_port < 65535 and grpc_port not in ephemeral_ports() and port_is_free(
            host, grpc_port):
        return grpc_port
    return free_port(host)


def _listening(host, port):
    try:
        with socket.create_connection((host, port), timeout=0.5):
            return True
    except OSError:
        return False


def _stop(process):
    """Stop a child politely (SIGTERM), then for sure (SIGKILL), and reap it."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout=STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            process.kill()
    process.wait()


def path_strips(stamps, xs, ys, linear):
    """Return each robot's path through xs, ys (count, points) as strips, unjoined at jumps."""
    if xs.shape[1] < 2:
        return None
    reach = (np.maximum(np.abs(linear[:, 1:]), np.abs(linear[:, :-1])) * (np.diff(stamps) * 1e-9)
             + _JUMP_MARGIN_M)
    jumps = np.hypot(np.diff(xs), np.diff(ys)) > reach
    xs, ys = xs.copy(), ys.copy()
    for robot, after in zip(*np.nonzero(jumps)):  # rare: one loop turn per jump
        xs[robot, :after + 1] = xs[robot, after + 1]
        ys[robot, :after + 1] = ys[robot, after + 1]
    return np.stack([xs, ys, np.zeros_like(xs)], axis=2)


def scan_points(ranges, angles, x, y, yaw):
    """Return the finite hits of scans (robots, beams) from poses x, y, yaw: (points, owners)."""
    ranges = np.asarray(ranges, dtype=float)
    owners, beams = np.nonzero(np.isfinite(ranges))
    hit = ranges[owners, beams]
    heading = np.asarray(yaw, dtype=float)[owners] + np.asarray(angles, dtype=float)[beams]
    return np.column_stack([np.asarray(x, dtype=float)[owners] + hit * np.cos(heading),
                            np.asarray(y, dtype=float)[owners] + hit * np.sin(heading)]), owners


def solid_boxes(grid):
    """Return a map's obstacle cells as boxes, one per run along a row: (centers, half_sizes)."""
    solid = np.asarray(grid.solid, dtype=np.int8)
    edges = np.diff(np.pad(solid, ((0, 0), (1, 1))), axis=1)
    rows, starts = np.nonzero(edges == 1)
    _, ends = np.nonzero(edges == -1)  # row by row, in the same order as the starts
    res = grid.resolution
    gx, gy = 0.5 * (starts + ends) * res, (rows + 0.5) * res
    mx, my = grid.from_grid(gx, gy)
    ones = np.ones(len(rows))
    half_sizes = [0.5 * (ends - starts) * res, 0.5 * res * ones, MAP_HALF_HEIGHT * ones]
    return np.column_stack([mx, my, 0.0 * ones]), np.column_stack(half_sizes)


def robot_colors(count):
    """Return count distinct RGB colours (uint8), the same for the same index in every run."""
    hues = (0.07 + _GOLDEN * np.arange(count)) % 1.0  # orange first: not Rerun's own blue
    rgb = [colorsys.hsv_to_rgb(hue, 0.75, 0.9) for hue in hues]
    return (np.array(rgb).reshape(-1, 3) * 255).round().astype(np.uint8)
