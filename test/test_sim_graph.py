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

"""The simulator over DDS in one process, on its own simulated time."""

import math

from geometry_msgs.msg import TwistStamped
from nav_msgs.msg import Odometry
import pytest
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from rclpy.qos import ReliabilityPolicy
from rclpy.time import Time
from rosgraph_msgs.msg import Clock as ClockMsg
from sim_diffdrive.harness import angle_error
from sim_diffdrive.harness import is_moving
from sim_diffdrive.harness import pose_of
from sim_diffdrive.harness import Probe
from sim_diffdrive.harness import SimGraph
from sim_diffdrive.harness import stamp_s
from sim_diffdrive.harness import twist_of
from std_srvs.srv import Empty

NS = 1_000_000_000


def play_and_wait(graph, probe, script, period=0.1):
    probe.play(script, period)
    graph.step_until(lambda: not probe.playing, sim_timeout=1000.0)
    graph.step_for(0.1)
    return pose_of(probe.odom)


def test_straight_line_matches_distance(graph):
    graph.sim()
    probe = graph.probe()
    x, y, yaw = play_and_wait(graph, probe, [(0.5, 0.0, 20)])
    assert x == pytest.approx(1.0, abs=1e-9)
    assert y == pytest.approx(0.0, abs=1e-9)
    assert yaw == pytest.approx(0.0, abs=1e-12)


def test_arc_matches_closed_form(graph):
    graph.sim(initial_yaw=0.3)
    probe = graph.probe()
    v, w, t = 0.4, 0.7, 2.3
    x, y, yaw = play_and_wait(graph, probe, [(v, w, 23)])
    r = v / w
    assert x == pytest.approx(r * (math.sin(0.3 + w * t) - math.sin(0.3)), abs=1e-9)
    assert y == pytest.approx(-r * (math.cos(0.3 + w * t) - math.cos(0.3)), abs=1e-9)
    assert angle_error(yaw, 0.3 + w * t) < 1e-12


# -- helpers for single commands ---------------------------------------------------------------

def stamp_ns(odom):
    return odom.header.stamp.sec * NS + odom.header.stamp.nanosec


def arc(x0, y0, yaw0, v, w, t):
    """Return the closed-form end pose of (v, w) held for t seconds from (x0, y0, yaw0)."""
    if w == 0.0:
        return x0 + v * t * math.cos(yaw0), y0 + v * t * math.sin(yaw0), yaw0
    return (x0 + v / w * (math.sin(yaw0 + w * t) - math.sin(yaw0)),
            y0 - v / w * (math.cos(yaw0 + w * t) - math.cos(yaw0)),
            yaw0 + w * t)


def assert_pose(odom, expected, tol=1e-12):
    x, y, yaw = pose_of(odom)
    assert x == pytest.approx(expected[0], abs=tol)
    assert y == pytest.approx(expected[1], abs=tol)
    assert angle_error(yaw, expected[2]) <= tol


def settle(graph):
    """Spin until every message sent so far has been handled, without stepping time."""
    now_ns = graph.now_ns
    assert graph.spin_until(lambda: graph.settled(now_ns), timeout=5.0, poll=0.001)


def command(graph, probe, v, w):
    """Send one Twist now and return the simulated time at which the simulator applied it."""
    probe.send(v, w)
    settle(graph)
    return graph.now_ns


# -- what a probe reads from the bytes ----------------------------------------------------------

def test_a_probes_latest_twist_stamp_and_motion_read_from_bytes_equal_the_message(graph):
    graph.sim(rate_hz=30.0, initial_x=1.5, initial_yaw=-0.7)  # stamps 1/30 s apart
    probe = graph.probe()
    assert (probe.twist, probe.stamp_s, probe.moving) == (None, None, False)
    seen = set()
    for v, w in ((0.0, 0.0), (0.25, -1.3), (-0.5, 0.0), (0.0, 2.0), (0.0, 0.0)):
        command(graph, probe, v, w)
        for _ in range(3):
            graph.step_for(0.04)
            odom = probe.odom
            assert probe.twist == twist_of(odom) == (v, w)
            assert probe.stamp_s == stamp_s(odom) and stamp_s(odom) not in seen
            assert probe.moving == is_moving(odom) == ((v, w) != (0.0, 0.0))
            seen.add(stamp_s(odom))


def test_a_probe_keeps_its_depth_of_odometry_while_its_process_does_not_spin(graph):
    # A process busy elsewhere (a benchmark on a loaded machine) takes its odometry later:
    # a probe keeps the newest `depth` of it, 200 unless told.
    node = graph.add(Node('flood', context=graph.context))
    flood = node.create_publisher(Odometry, 'odom', 1000)
    short, deep = graph.probe('short', listen_only=True), graph.probe('deep', depth=500)
    graph.wait_for_discovery()
    for i in range(300):
        odom = Odometry()
        odom.header.stamp.sec = i
        flood.publish(odom)
    assert flood.wait_for_all_acked(Duration(seconds=10.0))  # in both probes' queues
    assert graph.spin_until(lambda: len(deep.odoms) == 300 and len(short.odoms) >= 200)
    assert [deep.odoms.stamp_ns(i) // NS for i in range(300)] == list(range(300))
    assert [short.odoms.stamp_ns(i) // NS for i in range(200)] == list(range(100, 300))


# -- cmd_vel timeout ---------------------------------------------------------------------------

def test_cmd_vel_timeout_stops_the_robot_exactly(graph):
    graph.sim(cmd_vel_timeout=0.3)
    probe = graph.probe()
    v, w, timeout_ns = 0.5, 0.4, 300_000_000
    graph.step_for(0.1)
    t0 = command(graph, probe, v, w)
    graph.step_for(0.6)
    regions = set()
    for odom in probe.odoms:
        t = stamp_ns(odom)
        twist = odom.twist.twist
        if t <= t0:
            regions.add('before')
            assert_pose(odom, (0.0, 0.0, 0.0))
            assert (twist.linear.x, twist.angular.z) == (0.0, 0.0)
        elif t < t0 + timeout_ns:
            regions.add('moving')
            assert_pose(odom, arc(0.0, 0.0, 0.0, v, w, (t - t0) / NS))
            assert (twist.linear.x, twist.angular.z) == (v, w)
        else:
            regions.add('stopped')
            assert_pose(odom, arc(0.0, 0.0, 0.0, v, w, 0.3))
            assert (twist.linear.x, twist.angular.z) == (0.0, 0.0)
    assert regions == {'before', 'moving', 'stopped'}
    assert stamp_ns(probe.odom) >= t0 + 2 * timeout_ns


def test_cmd_vel_timeout_is_measured_from_the_last_command(graph):
    graph.sim(cmd_vel_timeout=0.3)
    probe = graph.probe()
    graph.step_for(0.1)
    command(graph, probe, 0.5, 0.0)
    graph.step_for(0.2)
    t1 = command(graph, probe, 0.5, 0.0)
    graph.step_for(0.6)
    # 0.2 s after the first command plus 0.3 s after the second.
    assert_pose(probe.odom, (0.25, 0.0, 0.0))
    assert probe.odom.twist.twist.linear.x == 0.0
    assert probe.odom_after(t1 + 280_000_000).twist.twist.linear.x == 0.5


def test_zero_cmd_vel_timeout_keeps_the_last_command(graph):
    graph.sim(cmd_vel_timeout=0.0)
    probe = graph.probe()
    graph.step_for(0.1)
    t0 = command(graph, probe, 0.5, 0.0)
    graph.step_for(2.0)
    assert stamp_ns(probe.odom) == t0 + 2 * NS
    assert_pose(probe.odom, (1.0, 0.0, 0.0))
    assert probe.odom.twist.twist.linear.x == 0.5


# -- limits ------------------------------------------------------------------------------------

@pytest.mark.parametrize('sign', [1.0, -1.0])
def test_speed_limits_clamp(graph, sign):
    graph.sim(max_linear_speed=0.3, max_angular_speed=0.5)
    probe = graph.probe()
    probe.play([(sign * 1.0, sign * 2.0, 10)])
    graph.step_until(lambda: probe.script_started_at is not None, sim_timeout=1.0)
    graph.step_for(0.5)
    twist = probe.odom.twist.twist
    assert (twist.linear.x, twist.angular.z) == (sign * 0.3, sign * 0.5)
    graph.step_until(lambda: not probe.playing, sim_timeout=2.0)
    graph.step_for(0.1)
    assert_pose(probe.odom, arc(0.0, 0.0, 0.0, sign * 0.3, sign * 0.5, 1.0))


def test_acceleration_limits_ramp(graph):
    # v = a t, w = alpha t: yaw = alpha t^2 / 2, x = a / alpha sin(yaw), y = a / alpha (1 - cos).
    a, alpha = 0.5, 1.0
    graph.sim(max_linear_accel=a, max_angular_accel=alpha)
    probe = graph.probe()
    probe.play([(1.0, 2.0, 10)])
    graph.step_until(lambda: not probe.playing, sim_timeout=2.0)
    t0, t1 = probe.script_started_at, probe.script_done_at
    assert t1 - t0 == NS
    graph.step_for(1.2)
    ramp = [o for o in probe.odoms if t0 < stamp_ns(o) <= t1]
    assert len(ramp) == 50
    for odom in ramp:
        t = (stamp_ns(odom) - t0) / NS
        twist = odom.twist.twist
        assert twist.linear.x == pytest.approx(a * t, abs=1e-12)
        assert twist.angular.z == pytest.approx(alpha * t, abs=1e-12)
        yaw = 0.5 * alpha * t * t
        assert_pose(odom, (a / alpha * math.sin(yaw), a / alpha * (1.0 - math.cos(yaw)), yaw),
                    tol=1e-6)
    # Told to stop at 0.5 m/s and 1 rad/s, it decelerates at the limit.
    braking = probe.odom_after(t1 + 400_000_000).twist.twist
    assert braking.linear.x == pytest.approx(0.5 - a * 0.4, abs=1e-12)
    assert braking.angular.z == pytest.approx(1.0 - alpha * 0.4, abs=1e-12)
    stopped = probe.odom_after(t1 + NS).twist.twist
    assert (stopped.linear.x, stopped.angular.z) == (0.0, 0.0)


# -- reset service -----------------------------------------------------------------------------

def test_reset_service_returns_to_the_initial_pose_at_rest(graph):
    start = (1.0, -2.0, 0.5)
    graph.sim(initial_x=start[0], initial_y=start[1], initial_yaw=start[2], cmd_vel_timeout=0.0)
    probe = graph.probe()
    client = probe.create_client(Empty, '/unicycle_sim/reset')
    try:
        assert graph.spin_until(client.service_is_ready, timeout=10.0)
        graph.step_for(0.1)
        assert_pose(probe.odom, start)
        t0 = command(graph, probe, 0.4, 0.6)
        graph.step_for(0.5)
        assert_pose(probe.odom, arc(*start, 0.4, 0.6, 0.5))

        settle(graph)
        seen = len(probe.odoms)
        future = client.call_async(Empty.Request())
        assert graph.spin_until(future.done, timeout=5.0, poll=0.001)
        assert future.result() is not None
        t_reset = graph.now_ns
        assert t_reset == t0 + NS // 2
        graph.step_for(0.3)
        after = probe.odoms[seen:]
        # The next step's odometry shows the reset (none at t_reset, which is out already with
        # the pose before it): 15 steps.
        assert [stamp_ns(o) for o in after] == [t_reset + k * NS // 50 for k in range(1, 16)]
        for odom in after:
            assert_pose(odom, start, tol=0.0)
            twist = odom.twist.twist
            assert (twist.linear.x, twist.angular.z) == (0.0, 0.0)
    finally:
        probe.destroy_client(client)


# -- bad commands ------------------------------------------------------------------------------

def test_non_finite_commands_are_refused(graph):
    graph.sim(cmd_vel_timeout=0.0, initial_yaw=-0.2)
    probe = graph.probe()
    graph.step_for(0.1)
    t0 = command(graph, probe, 0.4, 0.3)
    for bad in [(math.nan, 0.3), (0.4, math.inf), (-math.inf, math.nan), (math.nan, 0.0),
                (0.0, -math.inf)]:
        graph.step_for(0.1)
        command(graph, probe, *bad)
    graph.step_for(0.3)
    t = (stamp_ns(probe.odom) - t0) / NS
    assert t == pytest.approx(0.8)
    for odom in probe.odoms:
        p = odom.pose.pose
        values = (p.position.x, p.position.y, p.orientation.z, p.orientation.w,
                  odom.twist.twist.linear.x, odom.twist.twist.angular.z)
        assert all(math.isfinite(value) for value in values)
    assert_pose(probe.odom, arc(0.0, 0.0, -0.2, 0.4, 0.3, t))
    assert (probe.odom.twist.twist.linear.x, probe.odom.twist.twist.angular.z) == (0.4, 0.3)


# -- odometry ----------------------------------------------------------------------------------

@pytest.mark.parametrize('rate_hz,seconds', [(40.0, 2.0), (200.0, 0.5)])
def test_odometry_keeps_its_rate_while_idle(graph, rate_hz, seconds):
    graph.sim(rate_hz=rate_hz, initial_x=0.5, initial_yaw=1.0)
    probe = graph.probe()
    graph.step_for(seconds)
    period_ns = NS // int(rate_hz)
    assert len(probe.odoms) == round(seconds * rate_hz)
    assert [stamp_ns(o) for o in probe.odoms] == [
        k * period_ns for k in range(1, len(probe.odoms) + 1)]
    for odom in probe.odoms:
        assert_pose(odom, (0.5, 0.0, 1.0), tol=0.0)
        assert (odom.twist.twist.linear.x, odom.twist.twist.angular.z) == (0.0, 0.0)


def _diagonal(covariance):
    return [covariance[7 * i] for i in range(6)]


def _off_diagonal(covariance):
    return [c for i, c in enumerate(covariance) if i % 7]


@pytest.mark.parametrize('frames,covariances', [
    ({}, {}),
    ({'odom_frame_id': 'world', 'base_frame_id': 'base_link'},
     {'pose_covariance_diagonal': [0.1, 0.2, 0.3, 0.4, 0.5, 0.6],
      'twist_covariance_diagonal': [1.0, 2.0, 0.0, 0.0, 0.0, 3.0]}),
])
def test_odometry_fields(graph, frames, covariances):
    yaw0, v, w = 2.0, 0.4, -0.7
    graph.sim(initial_yaw=yaw0, cmd_vel_timeout=0.0, **frames, **covariances)
    probe = graph.probe()
    graph.step_for(0.1)
    t0 = command(graph, probe, v, w)
    graph.step_for(0.5)
    odom = probe.odom
    assert odom.header.frame_id == frames.get('odom_frame_id', 'odom')
    assert odom.child_frame_id == frames.get('base_frame_id', 'base_footprint')
    q = odom.pose.pose.orientation
    assert (q.x, q.y) == (0.0, 0.0)
    assert q.x ** 2 + q.y ** 2 + q.z ** 2 + q.w ** 2 == pytest.approx(1.0, abs=1e-15)
    assert odom.pose.pose.position.z == 0.0
    assert_pose(odom, arc(0.0, 0.0, yaw0, v, w, (stamp_ns(odom) - t0) / NS))
    # The twist is in the child (base) frame: forward speed along x whatever the heading.
    twist = odom.twist.twist
    assert (twist.linear.x, twist.linear.y, twist.linear.z) == (v, 0.0, 0.0)
    assert (twist.angular.x, twist.angular.y, twist.angular.z) == (0.0, 0.0, w)
    default = [0.001, 0.001, 0.001, 0.001, 0.001, 0.01]
    for field, covariance in (('pose_covariance_diagonal', odom.pose.covariance),
                              ('twist_covariance_diagonal', odom.twist.covariance)):
        assert len(covariance) == 36
        assert _diagonal(covariance) == covariances.get(field, default)
        assert not any(_off_diagonal(covariance))


# -- TwistStamped ------------------------------------------------------------------------------

def test_stamped_cmd_vel_drives_the_robot(graph):
    v, w = 0.4, 0.7
    graph.sim(stamped=True, cmd_vel_timeout=0.0)
    # One process is one DDS participant, which cannot hold Twist and TwistStamped on one topic:
    # the probe's Twist publisher goes elsewhere, a node of its own sends TwistStamped.
    probe = graph.add(Probe(context=graph.context, cli_args=[
        '--ros-args', '-r', 'cmd_vel:=unused_cmd_vel'],
        parameter_overrides=[Parameter('use_sim_time', value=True)]))
    sender = graph.add(Node('stamped_sender', context=graph.context, parameter_overrides=[
        Parameter('use_sim_time', value=True)]))
    stamped_pub = sender.create_publisher(TwistStamped, 'cmd_vel', 10)
    graph.step_for(0.1)
    msg = TwistStamped()
    msg.header.stamp = sender.get_clock().now().to_msg()
    msg.header.frame_id = 'base_footprint'
    msg.twist.linear.x = v
    msg.twist.angular.z = w
    stamped_pub.publish(msg)
    settle(graph)
    t0 = graph.now_ns
    graph.step_for(1.0)
    assert stamp_ns(probe.odom) == t0 + NS
    assert_pose(probe.odom, arc(0.0, 0.0, 0.0, v, w, 1.0))
    assert (probe.odom.twist.twist.linear.x, probe.odom.twist.twist.angular.z) == (v, w)


# -- publish rate does not change the result ---------------------------------------------------

def test_result_does_not_depend_on_rate_hz(ros_context):
    yaw0, v, w = 0.3, 0.4, 0.7
    poses = {}
    for rate_hz in (10.0, 50.0, 200.0):
        graph = SimGraph(ros_context)
        try:
            graph.sim(rate_hz=rate_hz, initial_yaw=yaw0)
            probe = graph.probe()
            # The probe's 0.1 s ticks land on simulator steps at each of these rates.
            poses[rate_hz] = play_and_wait(graph, probe, [(v, w, 23)], period=0.1)
            assert probe.script_done_at - probe.script_started_at == 23 * NS // 10
        finally:
            graph.close()
    expected = arc(0.0, 0.0, yaw0, v, w, 2.3)
    for rate_hz, (x, y, yaw) in poses.items():
        assert x == pytest.approx(poses[10.0][0], abs=1e-12), rate_hz
        assert y == pytest.approx(poses[10.0][1], abs=1e-12), rate_hz
        assert angle_error(yaw, poses[10.0][2]) < 1e-12, rate_hz
        assert x == pytest.approx(expected[0], abs=1e-9)
        assert y == pytest.approx(expected[1], abs=1e-9)
        assert angle_error(yaw, expected[2]) < 1e-12


class ExternalClock:
    """A simulator on someone else's /clock, which the test sets to any time it likes."""

    def __init__(self, graph, **params):
        self.graph = graph
        self.sim = graph.sim(stepped=False, publish_clock=False, use_sim_time=True, **params)
        self.probe = graph.probe()
        source = graph.add(Node('clock_source', context=graph.context))
        self.clock_pub = source.create_publisher(
            ClockMsg, '/clock', QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
        assert graph.spin_until(lambda: self.clock_pub.get_subscription_count() >= 2
                                and self.probe.cmd_pub.get_subscription_count() >= 1
                                and all(pub.get_subscription_count() >= 1
                                        for pub in self.sim.publishers
                                        if pub.topic_name == '/odom'))

    def set_time(self, t_ns):
        msg = ClockMsg()
        msg.clock = Time(nanoseconds=t_ns).to_msg()
        self.clock_pub.publish(msg)
        assert self.graph.spin_until(
            lambda: self.sim.get_clock().now().nanoseconds == t_ns, poll=0.001)

    def send_at(self, t_ns, v, w):
        self.set_time(t_ns)
        world = self.sim.world
        received = world.commanded[0]
        self.probe.send(v, w)
        assert self.graph.spin_until(lambda: world.commanded[0] != received, poll=0.001)

    def odom_at(self, t_ns):
        self.set_time(t_ns)
        probe = self.probe
        assert self.graph.spin_until(
            lambda: probe.odom is not None and stamp_ns(probe.odom) == t_ns,
            poll=0.001), f'no odometry stamped {t_ns} ns'
        return probe.odom


def test_commands_between_odometry_ticks_are_integrated_piecewise(graph):
    # On someone else's /clock, commands land between the simulator's odometry ticks: the pose
    # must be brought up to each command's arrival before the command takes effect.
    clock = ExternalClock(graph, rate_hz=10.0, cmd_vel_timeout=0.0)
    ms = NS // 1000
    clock.odom_at(1000 * ms)
    clock.send_at(1050 * ms, 0.5, 0.0)
    assert_pose(clock.odom_at(1100 * ms), (0.5 * 0.05, 0.0, 0.0))
    clock.send_at(1130 * ms, 0.5, 1.0)
    x0 = 0.5 * 0.08
    assert_pose(clock.odom_at(1200 * ms), arc(x0, 0.0, 0.0, 0.5, 1.0, 0.07))
    clock.send_at(1270 * ms, 0.0, 0.0)
    assert_pose(clock.odom_at(1300 * ms), arc(x0, 0.0, 0.0, 0.5, 1.0, 0.14))


def test_cmd_vel_timeout_still_brakes_after_the_clock_jumps_back(graph):
    # A replayed or restarted /clock goes back in time: the last command's time must not stay
    # in the future, or the timeout would not brake until the clock caught up with it.
    clock = ExternalClock(graph, rate_hz=10.0, cmd_vel_timeout=0.5)
    ms = NS // 1000
    clock.odom_at(100_000 * ms)
    clock.send_at(100_000 * ms, 0.5, 0.0)
    assert clock.odom_at(100_100 * ms).twist.twist.linear.x == 0.5
    clock.set_time(10_000 * ms)  # the clock jumps back 90.1 s; the odometry timer restarts
    x_back = clock.odom_at(10_100 * ms).pose.pose.position.x
    odom = clock.odom_at(10_700 * ms)
    assert odom.twist.twist.linear.x == 0.0, 'still driving 0.7 s after the jump'
    # Driven for the timeout from the first time the simulator saw after the jump, then
    # stopped: 0.5 s at 0.5 m/s.
    assert odom.pose.pose.position.x == pytest.approx(x_back + 0.25, abs=1e-9)
