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

import math

from hypothesis import given
from hypothesis import strategies as st
from motion_challenges.plans import approach_speed
from motion_challenges.plans import circle_plan
from motion_challenges.plans import final_pose
from motion_challenges.plans import out_and_back_plan
from motion_challenges.plans import pause
from motion_challenges.plans import PiecewisePlan
from motion_challenges.plans import rotation_plan
from motion_challenges.plans import Segment
from motion_challenges.plans import speed_ramp
from motion_challenges.plans import stopping_speed
import pytest
from sim_diffdrive.angles import normalize_angle


def run_ticks(plan, period, start=0.0):
    """Publish average(t, t + period) at t = start + k * period until the plan is finished."""
    commands = []
    k = 0
    while not plan.finished(start + k * period):
        t = start + k * period
        commands.append(plan.average(t, t + period))
        k += 1
        assert k < 10 ** 6
    return commands


def brute_force_integral(plan, t0, t1, step):
    """Midpoint sum of command_at; exact when every boundary lies on the step grid."""
    n = round((t1 - t0) / step)
    linear = angular = 0.0
    for k in range(n):
        v, w = plan.command_at(t0 + (k + 0.5) * step)
        linear += v * step
        angular += w * step
    return linear, angular


def distance(pose):
    return math.hypot(pose[0], pose[1])


# Segment and PiecewisePlan basics

@pytest.mark.parametrize('linear, angular, duration', [
    (0.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 0.0, math.nan), (0.0, 0.0, math.inf),
    (math.nan, 0.0, 1.0), (0.0, math.inf, 1.0), (-math.inf, 0.0, 1.0),
])
def test_segment_rejects_bad_values(linear, angular, duration):
    with pytest.raises(ValueError):
        Segment(linear, angular, duration)


def test_pause_stands_still():
    assert pause(2.5) == Segment(0.0, 0.0, 2.5)
    with pytest.raises(ValueError):
        pause(0.0)


def test_plan_rejects_empty_and_foreign_segments():
    with pytest.raises(ValueError):
        PiecewisePlan([])
    with pytest.raises(ValueError):
        PiecewisePlan([], repeat=True)
    with pytest.raises(TypeError):
        PiecewisePlan([(1.0, 0.0, 1.0)])


def test_command_at_picks_the_active_segment():
    plan = PiecewisePlan([Segment(1.0, 0.0, 1.0), Segment(0.0, 2.0, 0.5), pause(1.0)])
    assert plan.duration == 2.5
    assert plan.command_at(-0.1) == (0.0, 0.0)
    assert plan.command_at(0.0) == (1.0, 0.0)
    assert plan.command_at(0.999) == (1.0, 0.0)
    assert plan.command_at(1.0) == (0.0, 2.0)
    assert plan.command_at(1.4) == (0.0, 2.0)
    assert plan.command_at(1.5) == (0.0, 0.0)
    assert plan.command_at(2.5) == (0.0, 0.0)
    assert plan.command_at(100.0) == (0.0, 0.0)


def test_command_at_snaps_float_noise_to_boundaries():
    plan = PiecewisePlan([Segment(1.0, 0.0, 0.3), Segment(2.0, 0.0, 0.3)])
    # 0.1 + 0.2 = 0.30000000000000004 and 3 * 0.1 = 0.30000000000000004.
    assert plan.command_at(0.1 + 0.2) == (2.0, 0.0)
    assert plan.command_at(0.3 - 1e-12) == (2.0, 0.0)
    assert plan.command_at(0.6 - 1e-12) == (0.0, 0.0)
    assert plan.finished(0.6 - 1e-12)
    assert not plan.finished(0.6 - 1e-6)
    assert plan.average(0.6 - 1e-12, 0.7) == (0.0, 0.0)


def test_repeat_plan_wraps_around():
    plan = PiecewisePlan([Segment(1.0, 0.5, 2.0), Segment(-1.0, -0.5, 1.0)], repeat=True)
    assert plan.duration == math.inf
    assert plan.cycle_duration == 3.0
    assert not plan.finished(1e9)
    assert plan.command_at(2.5) == (-1.0, -0.5)
    assert plan.command_at(3.0) == (1.0, 0.5)
    assert plan.command_at(3.0 * 1000 + 2.2) == (-1.0, -0.5)
    assert plan.command_at(-1.0) == (0.0, 0.0)


# average: the integral-exact timed motion

def test_average_of_rotation_90_deg_at_60_deg_per_s_takes_15_full_ticks():
    plan = rotation_plan(math.radians(60.0), math.radians(90.0), clockwise=False)
    commands = run_ticks(plan, 0.1)
    assert len(commands) == 15
    for linear, angular in commands:
        assert linear == 0.0
        assert angular == pytest.approx(math.radians(60.0), abs=1e-12)
    assert sum(w * 0.1 for _, w in commands) == pytest.approx(math.pi / 2.0, abs=1e-12)
    assert plan.average(1.5, 1.6) == (0.0, 0.0)


def test_average_of_pi_at_1_rad_per_s_at_50_hz_scales_the_last_tick():
    plan = rotation_plan(1.0, math.pi, clockwise=True)
    period = 1.0 / 50.0
    commands = run_ticks(plan, period)
    assert len(commands) == 158
    assert all(w == pytest.approx(-1.0, abs=1e-12) for _, w in commands[:-1])
    assert commands[-1][1] == pytest.approx(-(math.pi - 157 * period) / period, abs=1e-9)
    assert -1.0 < commands[-1][1] < 0.0
    assert sum(w * period for _, w in commands) == pytest.approx(-math.pi, abs=1e-12)


def test_average_is_exact_with_jittery_ticks():
    plan = out_and_back_plan(1.0, 0.2, math.pi, 1.0, 2, 1.0)
    t = 0.0
    linear = angular = 0.0
    k = 0
    while t < plan.duration + 0.1:
        # Deterministic jitter between 0.5 and 1.5 nominal periods, as a loaded timer might give.
        t_next = t + 0.02 * (1.0 + 0.5 * math.sin(12.9898 * k))
        v, w = plan.average(t, t_next)
        linear += v * (t_next - t)
        angular += w * (t_next - t)
        t = t_next
        k += 1
    assert linear == pytest.approx(2.0, abs=1e-12)
    assert angular == pytest.approx(2.0 * math.pi, abs=1e-12)


def test_average_over_windows_spanning_several_segments():
    plan = out_and_back_plan(1.0, 0.2, math.pi, 1.0, 2, 1.0)
    # Forward 0-5 s, pause 5-6 s, turn 6-(6 + pi) s, pause, second leg.
    assert plan.average(4.0, 8.0) == pytest.approx((0.2 / 4.0, 2.0 / 4.0), abs=1e-12)
    whole = plan.duration
    assert plan.average(0.0, whole) == pytest.approx((2.0 / whole, 2.0 * math.pi / whole))
    assert plan.average(-whole, 2.0 * whole) == pytest.approx(
        (2.0 / (3.0 * whole), 2.0 * math.pi / (3.0 * whole)))
    assert plan.integral(0.0, 1e6) == pytest.approx((2.0, 2.0 * math.pi), abs=1e-12)


def test_average_wraps_around_repeat_plans():
    plan = circle_plan(0.5, 0.5, 15.0, 0)
    # 2 s of (-v, -w) at the end of a cycle, then 1 s of (v, w) at the start of the next.
    assert plan.average(28.0, 31.0) == pytest.approx((-1.0 / 6.0, -1.0 / 6.0), abs=1e-12)
    # 25 s to 100 s: 2.5 m of the first cycle left, two whole cycles (zero), then 10 s forward.
    assert plan.average(25.0, 100.0) == pytest.approx((-2.5 / 75.0 + 5.0 / 75.0,) * 2, abs=1e-12)
    t0 = 30.0 * 1e5 + 14.5
    assert plan.average(t0, t0 + 1.0) == pytest.approx((0.0, 0.0), abs=1e-6)


@pytest.mark.parametrize('t0, t1', [
    (0.0, 0.25), (0.3, 1.9), (1.7, 5.2), (0.0, 2.0), (2.0, 4.0), (-1.0, 11.35), (7.125, 7.5),
])
def test_average_matches_brute_force_on_a_repeat_plan(t0, t1):
    plan = PiecewisePlan(
        [Segment(0.3, -1.0, 0.5), Segment(-0.1, 2.0, 1.25), Segment(1.0, 0.0, 0.25)],
        repeat=True)
    linear, angular = brute_force_integral(plan, t0, t1, 0.001)
    width = t1 - t0
    assert plan.average(t0, t1) == pytest.approx((linear / width, angular / width), abs=1e-9)


def test_average_rejects_empty_or_bad_windows():
    plan = rotation_plan(1.0, 1.0, False)
    for t0, t1 in ((1.0, 1.0), (1.0, 0.5), (math.nan, 1.0), (0.0, math.nan), (0.0, math.inf)):
        with pytest.raises(ValueError):
            plan.average(t0, t1)


# Builders

def test_rotation_plan_signs_and_duration():
    ccw = rotation_plan(math.radians(30.0), math.radians(90.0), clockwise=False)
    cw = rotation_plan(math.radians(30.0), math.radians(90.0), clockwise=True)
    (segment,) = ccw.segments
    assert (segment.linear, segment.angular) == (0.0, math.radians(30.0))
    assert segment.duration == pytest.approx(3.0)
    assert cw.command_at(1.0) == (0.0, -math.radians(30.0))
    assert cw.duration == pytest.approx(3.0)
    for speed, angle in ((0.0, 1.0), (-1.0, 1.0), (1.0, 0.0), (1.0, -1.0), (math.inf, 1.0)):
        with pytest.raises(ValueError):
            rotation_plan(speed, angle, False)


def test_circle_plan_finite_and_forever():
    plan = circle_plan(0.5, 0.5, 15.0, 2)
    assert len(plan.segments) == 4
    assert plan.duration == 60.0
    assert plan.command_at(14.9) == (0.5, 0.5)
    assert plan.command_at(15.0) == (-0.5, -0.5)
    assert plan.command_at(45.0) == (-0.5, -0.5)
    assert plan.command_at(60.0) == (0.0, 0.0)
    forever = circle_plan(0.5, 0.5, 15.0, 0)
    assert forever.duration == math.inf
    assert forever.command_at(60.0 * 1000 + 16.0) == (-0.5, -0.5)
    for cycles in (-1, 1.5, True):
        with pytest.raises(ValueError):
            circle_plan(0.5, 0.5, 15.0, cycles)
    with pytest.raises(ValueError):
        circle_plan(0.5, 0.5, 0.0, 1)


def test_out_and_back_plan_segments():
    plan = out_and_back_plan(1.0, 0.2, math.pi, 1.0, 2, 1.0)
    leg = (Segment(0.2, 0.0, 5.0), pause(1.0), Segment(0.0, 1.0, math.pi), pause(1.0))
    assert plan.segments == leg * 2
    assert plan.duration == pytest.approx(2.0 * (7.0 + math.pi))
    no_pause = out_and_back_plan(1.0, 0.2, math.pi, 1.0, 3, 0.0)
    assert no_pause.segments == (leg[0], leg[2]) * 3
    for args in ((0.0, 0.2, math.pi, 1.0, 2, 1.0), (1.0, -0.2, math.pi, 1.0, 2, 1.0),
                 (1.0, 0.2, math.pi, 1.0, 0, 1.0), (1.0, 0.2, math.pi, 1.0, 2, -1.0),
                 (1.0, 0.2, math.pi, 0.0, 2, 1.0), (1.0, 0.2, math.pi, 1.0, 2, math.nan)):
        with pytest.raises(ValueError):
            out_and_back_plan(*args)


# approach_speed

def test_approach_speed_follows_the_spin_law():
    args = {'max_speed': 1.0, 'min_speed': 0.1, 'accel': 2.0, 'period': 0.02}
    assert approach_speed(0.0, **args) == 0.0
    assert approach_speed(-0.5, **args) == 0.0
    assert approach_speed(10.0, **args) == 1.0
    assert approach_speed(math.inf, **args) == 1.0
    # sqrt(2 * 2 * 0.04) = 0.4, between the limits and below remaining / period = 2.
    assert approach_speed(0.04, **args) == pytest.approx(0.4)
    # sqrt(2 * 2 * 0.0025) = 0.1 hits min_speed near the goal ...
    assert approach_speed(0.0025, **args) == pytest.approx(0.1)
    # ... but the last tick lands on the goal instead of overshooting.
    assert approach_speed(0.001, **args) == pytest.approx(0.05)
    assert approach_speed(0.001, **args) * 0.02 == pytest.approx(0.001)


def test_approach_speed_never_overshoots_when_iterated():
    remaining = math.pi
    for _ in range(1000):
        speed = approach_speed(remaining, 1.0, 0.05, 1.0, 0.02)
        if speed == 0.0:
            break
        remaining -= speed * 0.02
        assert remaining >= -1e-12
    assert remaining == pytest.approx(0.0, abs=1e-12)


def test_ramp_is_the_closed_form_of_a_speed_that_changes_at_accel():
    # From 0.2 towards 1.0 at 2 per s: 0.4 s to get there, so 0.1 s is all ramp ...
    assert speed_ramp(0.2, 1.0, 2.0, 0.1) == pytest.approx((0.2 * 0.1 + 0.5 * 2.0 * 0.01, 0.4))
    # ... and 1 s is 0.4 s of ramp (0.24), then 0.6 s at 1.0.
    assert speed_ramp(0.2, 1.0, 2.0, 1.0) == pytest.approx((0.24 + 0.6, 1.0))
    # Slowing down, and through zero: from 1.0 to -1.0 at 4 per s, 0.5 s, ends where it began.
    assert speed_ramp(1.0, -1.0, 4.0, 0.5) == pytest.approx((0.0, -1.0), abs=1e-15)
    # A robot without a limit takes the command at once (bit for bit the command's integral).
    assert speed_ramp(0.3, 0.7, 0.0, 0.02) == (0.7 * 0.02, 0.7)


def stopping_distance(command, velocity, accel, period):
    """How far a ramping robot goes commanded command for period, then 0 until it stands."""
    distance, speed = speed_ramp(velocity, command, accel, period)
    more, rest = speed_ramp(speed, 0.0, accel, abs(speed) / accel + 1.0)
    assert rest == 0.0
    return distance + more


@given(remaining=st.floats(1e-9, 10.0), velocity=st.floats(-2.0, 3.0),
       accel=st.floats(0.05, 50.0), period=st.sampled_from([0.005, 0.02, 0.1, 0.5]))
def test_stopping_speed_stops_a_ramping_robot_on_the_goal(remaining, velocity, accel, period):
    command = stopping_speed(remaining, velocity, accel, period)
    if command == math.inf:  # nothing the robot reaches within the period goes that far
        assert stopping_distance(velocity + accel * period, velocity, accel, period) <= remaining
    elif command == 0.0:  # it cannot stop in time: brake
        assert stopping_distance(0.0, velocity, accel, period) >= remaining * (1.0 - 1e-12)
    else:
        assert command > 0.0
        gone = stopping_distance(command, velocity, accel, period)
        assert gone == pytest.approx(remaining, rel=1e-9, abs=1e-15)


def test_approach_speed_for_a_ramping_robot_stops_it_on_the_goal_when_iterated():
    # A robot with a 1 rad/s^2 limit, turned by the law with a 3 rad/s^2 slow-down: it is
    # commanded what lets it stop, and it does, on the goal.
    remaining, velocity, period = math.pi, 0.0, 0.02
    for _ in range(1000):
        speed = approach_speed(remaining, 1.0, 0.05, 3.0, period, 1.0, velocity)
        distance, velocity = speed_ramp(velocity, speed, 1.0, period)
        remaining -= distance
        assert remaining >= -1e-12
        if speed == velocity == 0.0:
            break
    assert remaining == pytest.approx(0.0, abs=1e-12)
    # The same law for a robot that takes each command at once, as before: remaining / period.
    assert approach_speed(0.001, 1.0, 0.1, 2.0, 0.02) == pytest.approx(0.05)


@pytest.mark.parametrize('args', [
    (1.0, 0.0, 0.1, 1.0, 0.1), (1.0, 1.0, 0.0, 1.0, 0.1), (1.0, 1.0, 0.1, -1.0, 0.1),
    (1.0, 1.0, 0.1, 1.0, 0.0), (1.0, 0.1, 1.0, 1.0, 0.1), (math.nan, 1.0, 0.1, 1.0, 0.1),
    (1.0, math.inf, 0.1, 1.0, 0.1),
])
def test_approach_speed_rejects_bad_arguments(args):
    with pytest.raises(ValueError):
        approach_speed(*args)


# final_pose

def test_out_and_back_returns_home():
    x, y, yaw = final_pose(out_and_back_plan(1.0, 0.2, math.pi, 1.0, 2, 1.0))
    assert abs(x) < 1e-9 and abs(y) < 1e-9 and abs(yaw) < 1e-9
    # Halfway it is 1 m out, facing back.
    plan = out_and_back_plan(1.0, 0.2, math.pi, 1.0, 1, 1.0)
    x, y, yaw = final_pose(plan)
    assert (x, y) == pytest.approx((1.0, 0.0), abs=1e-12)
    assert abs(yaw) == pytest.approx(math.pi, abs=1e-12)


def test_circle_returns_to_start_after_a_cycle():
    for plan, t_end in ((circle_plan(0.5, 0.5, 15.0, 1), None),
                        (circle_plan(0.5, 0.5, 15.0, 0), 30.0 * 10)):
        x, y, yaw = final_pose(plan, 1.0, -2.0, 0.3, t_end=t_end)
        assert (x, y, yaw) == pytest.approx((1.0, -2.0, 0.3), abs=1e-9)


def test_circle_half_cycle_reaches_one_diameter_and_retraces():
    v, w = 0.5, 0.5
    plan = circle_plan(v, w, 15.0, 1)
    samples = [final_pose(plan, t_end=0.01 * k) for k in range(1501)]
    farthest = max(distance(pose) for pose in samples)
    assert farthest <= 2.0 * v / w + 1e-12
    assert farthest == pytest.approx(2.0 * v / w, abs=1e-4)
    assert distance(final_pose(plan, t_end=math.pi / w)) == pytest.approx(2.0 * v / w, abs=1e-12)
    forward = final_pose(plan, t_end=15.0 - 4.0)
    back = final_pose(plan, t_end=15.0 + 4.0)
    assert back == pytest.approx(forward, abs=1e-12)


def test_rotation_clockwise_90_deg_ends_at_minus_half_pi():
    plan = rotation_plan(math.radians(60.0), math.radians(90.0), clockwise=True)
    assert final_pose(plan) == pytest.approx((0.0, 0.0, -math.pi / 2.0), abs=1e-12)
    # Multi-turn rotations keep their remainder: 450 deg counter-clockwise ends at +90 deg.
    plan = rotation_plan(1.0, math.radians(450.0), clockwise=False)
    assert final_pose(plan) == pytest.approx((0.0, 0.0, math.pi / 2.0), abs=1e-12)


def test_final_pose_matches_the_arc_formula_and_is_continuous_at_zero_turn():
    x0, y0, th = 0.5, -1.0, 0.7
    v, dt = 0.8, 2.0
    for w in (1.3, -0.4, 1e-3):
        x, y, yaw = final_pose(PiecewisePlan([Segment(v, w, dt)]), x0, y0, th)
        assert x == pytest.approx(x0 + v / w * (math.sin(th + w * dt) - math.sin(th)), abs=1e-12)
        assert y == pytest.approx(y0 - v / w * (math.cos(th + w * dt) - math.cos(th)), abs=1e-12)
        assert yaw == pytest.approx(normalize_angle(th + w * dt), abs=1e-12)
    straight = final_pose(PiecewisePlan([Segment(v, 0.0, dt)]), x0, y0, th)
    assert straight == pytest.approx(
        (x0 + v * dt * math.cos(th), y0 + v * dt * math.sin(th), th), abs=1e-15)
    for w in (1e-12, 1e-9, 1e-6, 1e-5, 1e-4, 2e-4):
        nearly = final_pose(PiecewisePlan([Segment(v, w, dt)]), x0, y0, th)
        # The chord moves by about v * dt**2 * w / 2 sideways: no jump at any threshold.
        assert nearly == pytest.approx(straight, abs=v * dt * dt * w)


def test_final_pose_stops_at_t_end():
    plan = PiecewisePlan([Segment(1.0, 0.0, 2.0), Segment(0.0, 1.0, 1.0)])
    assert final_pose(plan, t_end=0.5) == pytest.approx((0.5, 0.0, 0.0))
    assert final_pose(plan, t_end=2.5) == pytest.approx((2.0, 0.0, 0.5))
    assert final_pose(plan, t_end=100.0) == pytest.approx((2.0, 0.0, 1.0))
    assert final_pose(plan, t_end=0.0) == (0.0, 0.0, 0.0)
    with pytest.raises(ValueError):
        final_pose(circle_plan(0.5, 0.5, 15.0, 0))
    with pytest.raises(ValueError):
        final_pose(plan, t_end=-1.0)
