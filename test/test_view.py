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
view_port: the run in a real browser, as a user opens it.

Headless Chromium (Debian's package, driven by Playwright; WebGL2 through SwiftShader) opens
the address the simulator logs, and the screenshots must show the robot, drawn in its colour
where it is: nothing before the first step, then a track that grows upwards while it drives
along +y (ROS's frame the right way up).  The page must not send a request off this machine.
A client that leaves mid-run changes nothing in the simulation; a port in use, rerun-sdk
missing: the simulator says so and runs on; the rerun program never outlives the simulator.
"""

import http.client
import importlib.util
import io
import math
import os
from pathlib import Path
import re
import shutil
import signal
import socket
import struct
import time
import urllib.request

import numpy as np
import pytest
from sim_diffdrive import harness
from sim_diffdrive.taps.view import robot_colors
from sim_diffdrive.taps.view import scan_points
from sim_diffdrive.taps.view import solid_boxes
from sim_diffdrive.taps.view_page import confine
from sim_diffdrive.taps.view_page import ephemeral_ports
from sim_diffdrive.taps.view_page import free_port
from sim_diffdrive.world.grid import GridMap

# Asked of the import system rather than imported: rerun takes 0.6 CPU s to import, which each
# pytest worker would pay while collecting.
pytestmark = pytest.mark.skipif(importlib.util.find_spec('rerun') is None,
                                reason='no rerun-sdk (make venv installs it)')

CHROMIUM = shutil.which('chromium') or shutil.which('chromium-browser')
CHROMIUM_FLAGS = [
    '--no-sandbox', '--enable-unsafe-swiftshader', '--use-angle=swiftshader',
    '--ignore-gpu-blocklist', '--disable-background-networking', '--disable-component-update',
    '--disable-sync', '--no-first-run']
ROOM = str(Path(__file__).resolve().parents[1] / 'maps' / 'room.yaml')
PAGE_SIZE = {'width': 800, 'height': 500}
# The top view fills the left three fifths of the page, under the viewer's menu bar.
TOP_VIEW = (slice(60, 470), slice(0, 470))
ROBOT_RGB = robot_colors(1)[0].astype(int)
# How much of the robot's colour a drawn robot (box, arrow and label) shows, at least [px].
ROBOT_PIXELS = 150
# Between two screenshots while waiting for a picture [s]: every 0.6 s instead of 0.2, the test
# took 14.3 instead of 14.8 machine CPU s (four alternating pairs), and no longer.
SHOT_PERIOD = 0.6


@pytest.fixture(scope='module')
def browser():
    if CHROMIUM is None:
        pytest.skip('no chromium (make venv installs it: apt-get install chromium)')
    sync_api = pytest.importorskip('playwright.sync_api')
    with sync_api.sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_FLAGS)
        try:
            yield chromium
        finally:
            chromium.close()


class ViewerTab:
    """A browser tab on the view; every request it makes off this machine is refused and kept."""

    def __init__(self, browser, url):
        self.page = browser.new_page(viewport=PAGE_SIZE)
        # Rerun 0.41's web build logs at debug level: its shader compiler alone writes some
        # 11,000 console.debug lines in the viewer's first seconds, and the browser hands each
        # to Playwright's driver over its DevTools connection.  Dropped, the test costs the
        # machine 8.5 CPU s instead of 13.7 and the viewer settles 2 s sooner; what the page
        # draws is the same.
        self.page.add_init_script('console.debug = () => {};')
        self.outside = []
        self.page.route(re.compile(r'^(?!https?://(127\.0\.0\.1|localhost)[:/])'),
                        self._refuse)
        # Loaded, its WebAssembly started and streaming from the simulator's rerun program (its
        # picture is judged from screenshots, which wait for what they expect).
        with self.page.expect_request(lambda request: 'ReadMessages' in request.url,
                                      timeout=60_000):
            self.page.goto(url)

    def _refuse(self, route):
        self.outside.append(route.request.url)
        route.abort()

    def robot_pixels(self):
        """Return the (row, column) of every pixel of the top view in the robot's colour."""
        from PIL import Image
        image = Image.open(io.BytesIO(self.page.screenshot()))
        if os.environ.get('VIEW_SHOTS'):
            image.save(os.path.join(os.environ['VIEW_SHOTS'], f'{time.monotonic():.1f}.png'))
        shot = np.asarray(image.convert('RGB'))
        view = shot[TOP_VIEW].astype(int)
        near = np.abs(view - ROBOT_RGB).sum(axis=2) < 60
        return np.argwhere(near)

    def wait_for_robot(self, shown, timeout=30.0):
        """
        Return the robot's pixels once shown(pixels) holds.

        The viewer draws what arrived when it gets to it: on a busy machine (SwiftShader
        renders on the CPU) it can show the run seconds late, so a test waits for the picture
        it expects rather than for the first one with something in it.  A screenshot costs the
        browser about 0.06 CPU s and holds up its drawing, so it looks every SHOT_PERIOD.
        """
        deadline = time.monotonic() + timeout
        while not shown(pixels := self.robot_pixels()):
            assert time.monotonic() < deadline, (
                f'{len(pixels)} pixels of the robot after {timeout} s' + (
                    f', rows {pixels[:, 0].min()}..{pixels[:, 0].max()}' if len(pixels) else ''))
            time.sleep(SHOT_PERIOD)
        return pixels

    def close(self):
        self.page.close()


def test_the_browser_shows_the_robot_driving_up_the_screen(graph, browser):
    port = free_port()
    sim = graph.sim(view_port=port, initial_yaw=math.pi / 2, cmd_vel_timeout=0.0)
    url = sim.taps.named('view_port').url
    assert url.startswith(f'http://127.0.0.1:{port}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A')
    tab = ViewerTab(browser, url)
    try:
        # The robot at rest where it starts: a box in its colour, seen from above.
        start = tab.wait_for_robot(lambda pixels: len(pixels) > ROBOT_PIXELS // 5)
        assert len(start) < ROBOT_PIXELS  # no track yet
        probe = graph.probe(name='driver')
        graph.step()  # (the graph counts messages once its nodes have discovered each other)
        probe.send(0.5, 0.0)  # along +y: up the screen, if ROS's frame is drawn the right way
        graph.step(150)
        assert graph.pose() == pytest.approx((0.0, 1.5, math.pi / 2), abs=1e-9)
        # 1.5 m up the screen (about 100 pixels): the robot above where it stood, and its track.
        track = tab.wait_for_robot(lambda pixels: len(pixels) > ROBOT_PIXELS
                                   and pixels[:, 0].min() < start[:, 0].min() - 60)
        rows, columns = track[:, 0], track[:, 1]
        assert start[:, 0].min() < rows.max() < start[:, 0].max()  # from where it stood
        assert columns.max() - columns.min() < (rows.max() - rows.min()) / 2  # straight up
        # Above where it stood, judged in this one picture: where it stood is where its track
        # begins (the lowest rows).  Not against the first picture's columns: the viewer frames
        # the scene anew as the track grows, and between two pictures it once moved the robot
        # 16 pixels sideways, once 82, with nothing wrong in the run.
        top = columns[rows <= rows.min() + 10]  # the robot, now
        bottom = columns[rows >= rows.max() - 10]  # the track where it began
        assert abs(np.median(top) - np.median(bottom)) < (rows.max() - rows.min()) / 4
        assert tab.outside == []  # the page asked nothing of any other machine
    finally:
        tab.close()


def test_a_client_that_leaves_mid_run_disturbs_nothing(graph):
    port = free_port()
    sim = graph.sim(view_port=port, robots=['robot1', 'robot2'])
    view = sim.taps.named('view_port')
    one, two = graph.probe(name='one', namespace='robot1'), graph.probe(
        name='two', namespace='robot2')
    graph.step()  # (the graph counts messages once its nodes have discovered each other)
    one.send(0.5, 0.5)  # each drives until its command times out, 0.5 s later
    two.send(-0.2, 0.0)
    graph.step(5)
    read_the_stream_and_leave(view.grpc_url)  # gone while the viewer streams
    # A download cut off halfway (the viewer's 40 MB of WebAssembly).
    with urllib.request.urlopen(f'http://127.0.0.1:{port}/re_viewer_bg.wasm') as answer:
        assert len(answer.read(1 << 20)) == 1 << 20
    graph.step(45)
    x, y, yaw = graph.pose('robot1')
    assert (x, y, yaw) == pytest.approx((math.sin(0.25), 1.0 - math.cos(0.25), 0.25), abs=1e-12)
    assert graph.pose('robot2') == pytest.approx((-0.1, 0.0, 0.0), abs=1e-12)
    assert sim.taps  # the view is still there, and still serves the page
    with urllib.request.urlopen(f'http://127.0.0.1:{port}/') as answer:
        assert b're_viewer.js' in answer.read()


def test_a_scan_becomes_its_finite_hit_points_in_the_frame_of_the_poses():
    angles = np.array([-math.pi, -0.5 * math.pi, 0.0, 0.5 * math.pi])
    ranges = np.array([[1.0, np.inf, 2.0, -np.inf],   # at (0, 0) facing +x
                       [np.nan, 0.5, 1.5, 0.25]], np.float32)  # at (1, 2) facing +y
    points, owners = scan_points(ranges, angles, [0.0, 1.0], [0.0, 2.0], [0.0, 0.5 * math.pi])
    assert owners.tolist() == [0, 0, 1, 1, 1]
    assert points == pytest.approx(np.array(
        [[-1.0, 0.0], [2.0, 0.0], [1.5, 2.0], [1.0, 3.5], [0.75, 2.0]]), abs=1e-6)


def test_the_obstacle_cells_are_drawn_as_a_box_per_run_along_a_row():
    grid = GridMap.from_rows(['##.#', '....', '.###'], resolution=0.5, origin=(1.0, 2.0, 0.0))
    centers, half_sizes = solid_boxes(grid)
    # Row 0 (the bottom) holds cols 1-3; row 2 (the top) cols 0-1 and col 3.
    assert centers[:, :2].tolist() == [[2.25, 2.25], [1.5, 3.25], [2.75, 3.25]]
    assert half_sizes[:, :2].tolist() == [[0.75, 0.25], [0.5, 0.25], [0.25, 0.25]]


def test_a_run_in_a_map_is_drawn_without_failing(graph):
    sim = graph.sim(view_port=free_port(), map_file=ROOM, robots=['a', 'b'],
                    initial_poses=[0.0, 0.0, 0.0, 1.0, 1.0, 0.0])
    view = sim.taps.named('view_port')
    graph.step_for(0.5)  # five scans, drawn by the sending thread
    assert view._frames.in_map and view._ranges.shape == (2, 360)
    graph.remove(sim)  # closing draws the rest
    assert view._failure is None


def test_the_page_allows_this_machine_only(graph):
    port = free_port()
    sim = graph.sim(view_port=port)
    grpc_port = int(re.search(r':(\d+)/proxy', sim.taps.named('view_port').grpc_url).group(1))
    with urllib.request.urlopen(f'http://localhost:{port}/') as answer:  # redirected to ?url=
        assert answer.url == sim.taps.named('view_port').url
        page = answer.read()
        policy = answer.headers['Content-Security-Policy']
    assert b'fonts.googleapis.com' not in page and b'<canvas' in page
    assert b"fetch('/run')" in page  # the page follows the next run on this port
    with urllib.request.urlopen(f'http://127.0.0.1:{port}/run') as answer:
        run, grpc_url = answer.read().decode().split(' ')
    assert grpc_url == sim.taps.named('view_port').grpc_url and re.fullmatch('[0-9a-f]{32}', run)
    assert f"connect-src 'self' http://127.0.0.1:{grpc_port} http://localhost:{grpc_port};" \
        in policy
    assert "default-src 'self';" in policy
    request = urllib.request.Request(f'http://127.0.0.1:{port}/',
                                     headers={'Host': f'attacker.example:{port}'})
    with pytest.raises(urllib.error.HTTPError, match='403'):
        urllib.request.urlopen(request)


def test_the_font_links_are_taken_out_and_nothing_else():
    html = (b'<head>\n<link rel="preconnect" href="https://fonts.googleapis.com" />\n'
            b'<link\n  href="https://fonts.googleapis.com/css2?family=Inter"\n'
            b'  rel="stylesheet"\n/>\n<link rel="icon" href="favicon.ico" />\n</head>')
    assert confine(html) == b'<head>\n\n\n<link rel="icon" href="favicon.ico" />\n</head>'


def test_a_free_port_is_one_no_outgoing_connection_can_take_first():
    # The ports handed to the page and the rerun program are bound a while later; a port of
    # the ephemeral range could meanwhile become the local end of any connection on the
    # machine (once "Address already in use" in a full suite).
    for port in {free_port() for _ in range(8)}:
        assert 10000 <= port < ephemeral_ports().start
        with socket.socket() as server:
            # As the page's server and the rerun program bind: a connection to an earlier
            # server on that port, left in TIME_WAIT, does not keep it from them.
            server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            server.bind(('127.0.0.1', port))


# In process, the two ways the view cannot open: the simulator opens its view as it starts,
# the same in the executable, and fails before any rerun program is started.
def test_a_port_in_use_is_reported_and_the_simulator_runs(graph, capfd):
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        sim = graph.sim(view_port=port)
        graph.step_for(1.0)
    assert not sim.taps
    assert len(graph.odometry.odoms) >= 50  # it runs on
    output = capfd.readouterr().err
    assert 'view_port: [Errno 98] Address already in use. Running without it.' in output
    assert output.count('view_port') == 1, output


def test_the_rerun_program_ends_with_the_simulator(procs):
    # SIGTERM: sent to the simulator alone, as a service manager does (Ctrl-C in a terminal
    # reaches the rerun program too); SIGINT takes the same path in runtime.run.
    signum = signal.SIGTERM
    port = free_port()
    sim = procs('unicycle_sim', 'unicycle_sim', *harness.ros_params(f'view_port:={port}'))
    assert wait_for_line(sim, 'Browser view: open'), sim.describe()
    rerun = rerun_child(sim)
    sim.send(signum)
    assert sim.wait(10.0) == 0, sim.describe()
    assert_ends(rerun)
    with socket.socket() as again:  # and the port is free again
        again.bind(('127.0.0.1', port))


@pytest.mark.skipif(shutil.which('setpriv') is None,
                    reason='without setpriv (util-linux) a killed owner leaves rerun behind')
def test_the_rerun_program_ends_with_a_killed_owner(tmp_path):
    # Not a ROS node: one killed outright can leave DDS shared memory behind for other tests.
    code = ('import sys, time, types\n'
            'import numpy as np\n'
            'from sim_diffdrive.taps.view import BrowserView\n'
            "world = types.SimpleNamespace(x=np.zeros(1), y=np.zeros(1), names=[''])\n"
            'node = types.SimpleNamespace(\n'
            '    params=types.SimpleNamespace(publish_clock=True), world=world,\n'
            '    get_parameter=lambda name: types.SimpleNamespace(value=False),\n'
            '    get_logger=lambda: types.SimpleNamespace(info=print))\n'
            'BrowserView(0, node)\n'
            'sys.stdout.flush()\n'
            'time.sleep(60)\n')
    owner = harness.start_python(code, log_path=tmp_path / 'owner.log')
    try:
        assert wait_for_line(owner, 'Browser view: open'), owner.describe()
        rerun = rerun_child(owner)
        with open(f'/proc/{rerun}/environ', 'rb') as environ:  # the view's own directory
            home = dict(item.split(b'=', 1) for item in environ.read().split(b'\0') if item)
        owner.send(signal.SIGKILL)
        owner.wait(10.0)
        assert_ends(rerun)
    finally:
        owner.kill()
    # A killed owner cannot remove it: the test does.
    shutil.rmtree(os.path.dirname(home[b'XDG_CONFIG_HOME'].decode()))


def read_the_stream_and_leave(grpc_url):
    """
    Ask for the run as the page does, read the first message of the stream, and hang up.

    The page's own request (a gRPC-web ReadMessages call with an empty request, as Chromium
    sends it), without the browser: the driving test shows the page, a leaving client needs
    none, and a tab costs 3-5 CPU s to load (the machine's two cores for two seconds).
    """
    host, port = re.fullmatch(r'rerun\+http://([0-9.]+):(\d+)/proxy', grpc_url).groups()
    connection = http.client.HTTPConnection(host, int(port), timeout=10.0)
    try:
        connection.request(
            'POST', '/rerun.sdk_comms.v1alpha1.MessageProxyService/ReadMessages',
            body=bytes(5), headers={'Content-Type': 'application/grpc-web+proto',
                                    'Accept': 'application/grpc-web+proto', 'X-Grpc-Web': '1'})
        answer = connection.getresponse()
        assert answer.status == 200, answer.reason
        flag, length = struct.unpack('>BI', answer.read(5))  # a data frame of the stream
        assert flag == 0 and length > 0, (flag, length)
        assert len(answer.read(length)) == length
    finally:
        connection.close()


def rerun_child(process):
    """Return the pid of the one rerun program process started (its only child)."""
    pids = children(process.pid)
    assert len(pids) == 1 and '/rerun ' in command_line(pids[0]), pids
    return pids[0]


def assert_ends(pid, timeout=5.0):
    deadline = time.monotonic() + timeout
    while alive(pid):
        assert time.monotonic() < deadline, f'rerun ({pid}) outlived its owner'
        time.sleep(0.05)


def children(pid):
    """Return the pids whose parent is pid (Linux /proc)."""
    found = []
    for entry in os.listdir('/proc'):
        if entry.isdigit():
            try:
                with open(f'/proc/{entry}/stat') as stat:
                    fields = stat.read().rsplit(')', 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                found.append(int(entry))
    return found


def alive(pid):
    """Return whether pid runs (a zombie has ended: whoever adopted it reaps it)."""
    try:
        with open(f'/proc/{pid}/stat') as stat:
            return stat.read().rsplit(')', 1)[1].split()[0] != 'Z'
    except OSError:
        return False


def command_line(pid):
    with open(f'/proc/{pid}/cmdline', 'rb') as cmdline:
        return cmdline.read().replace(b'\0', b' ').decode()


def wait_for_line(process, text, timeout=20.0):
    deadline = time.monotonic() + timeout
    while text not in process.output():
        if time.monotonic() > deadline or process.poll() is not None:
            return False
        time.sleep(0.05)
    return True
