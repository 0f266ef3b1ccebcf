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

"""Unicycle kinematics and angle maths against closed forms (no ROS graph)."""

from decimal import Decimal
from decimal import localcontext
import math

import pytest
from sim_diffdrive.angles import normalize_angle
from sim_diffdrive.angles import quaternion_from_yaw
from sim_diffdrive.angles import yaw_from_quaternion
from sim_diffdrive.angles import YawAccumulator
from sim_diffdrive.kinematics import _sinc
from sim_diffdrive.kinematics import integrate
from sim_diffdrive.kinematics import limit_command
from sim_diffdrive.kinematics import SMALL_ANGLE
from sim_diffdrive.kinematics import UnicycleModel

TWO_PI = 2.0 * math.pi


# -- a 50-digit reference, free of the cancellation in v/w * (sin(a + wt) - sin(a)) ----------

def _dsin(x):
    """Return sin(x) for a Decimal x by its Taylor series (the decimal module's recipe)."""
    with localcontext() as ctx:
        ctx.prec += 2
        i, lasts, s, fact, num, sign = 1, 0, x, 1, x, 1
        while s != lasts:
            lasts = s
            i += 2
            fact *= i * (i - 1)
            num *= x * x
            sign *= -1
            s += num / fact * sign
    return +s


def _dcos(x):
    """Return cos(x) for a Decimal x by its Taylor series (the decimal module's recipe)."""
    with localcontext() as ctx:
        ctx.prec += 2
        i, lasts, s, fact, num, sign = 0, 0, 1, 1, 1, 1
        while s != lasts:
            lasts = s
            i += 2
            fact *= i * (i - 1)
            num *= x * x
            sign *= -1
            s += num / fact * sign
    return +s


def exact_arc(x, y, yaw, v, w, t):
    """Return the end (x, y) of the arc (v, w) held for t seconds, to about 40 digits."""
    with localcontext() as ctx:
        ctx.prec = 50
        x, y, yaw, v, w, t = (Decimal(value) for value in (x, y, yaw, v, w, t))
        if w == 0:
            return float(x + v * t * _dcos(yaw)), float(y + v * t * _dsin(yaw))
        r = v / w
        end = yaw + w * t
        return (float(x + r * (_dsin(end) - _dsin(yaw))),
                float(y - r * (_dcos(end) - _dcos(yaw))))


def exact_sinc(x):
    with localcontext() as ctx:
        ctx.prec = 50
        return float(_dsin(Decimal(x)) / Decimal(x))


def angle_error(a, b):
    return abs(math.remainder(a - b, TWO_PI))


def in_yaw_range(yaw):
    return -math.pi < yaw <= math.pi


# -- integrate ---------------------------------------------------------------------------------

@pytest.mark.parametrize('yaw', [0.0, 0.3, -2.0, math.pi])
def test_straight_line(yaw):
    v, t = 0.7, 3.0
    x, y, new_yaw = integrate(1.0, -2.0, yaw, v, 0.0, t)
    assert x == pytest.approx(1.0 + v * t * math.cos(yaw), abs=1e-15)
    assert y == pytest.approx(-2.0 + v * t * math.sin(yaw), abs=1e-15)
    assert new_yaw == yaw


def test_backwards_straight_line():
    x, y, yaw = integrate(0.0, 0.0, math.pi / 2, -0.5, 0.0, 2.0)
    assert x == pytest.approx(0.0, abs=1e-15)
    assert y == pytest.approx(-1.0, abs=1e-15)
    assert yaw == math.pi / 2


@pytest.mark.parametrize('w', [1.0, -1.0, 2.5, -0.1])
def test_spin_in_place(w):
    t = 0.8
    x, y, yaw = integrate(1.5, -0.5, 0.2, 0.0, w, t)
    assert (x, y) == (1.5, -0.5)
    assert yaw == pytest.approx(normalize_angle(0.2 + w * t), abs=1e-15)


@pytest.mark.parametrize('v,w', [(0.4, 0.7), (0.4, -0.7), (-0.3, 1.9), (1.0, 1e-3)])
def test_arc_matches_closed_form(v, w):
    x0, y0, yaw0, t = 0.5, -1.0, 0.3, 2.3
    x, y, yaw = integrate(x0, y0, yaw0, v, w, t)
    x_ref, y_ref = exact_arc(x0, y0, yaw0, v, w, t)
    assert x == pytest.approx(x_ref, abs=1e-14)
    assert y == pytest.approx(y_ref, abs=1e-14)
    assert angle_error(yaw, yaw0 + w * t) < 1e-15
    # The robot stays on its circle of radius v/w about the centre left of its start.
    cx, cy = x0 - v / w * math.sin(yaw0), y0 + v / w * math.cos(yaw0)
    assert math.hypot(x - cx, y - cy) == pytest.approx(abs(v / w), rel=1e-12)


@pytest.mark.parametrize('v,w', [(0.5, 0.7), (1.0, -2.0), (-0.2, 0.3)])
def test_full_circle_in_one_call_closes(v, w):
    x0, y0, yaw0 = 1.0, 2.0, 0.3
    x, y, yaw = integrate(x0, y0, yaw0, v, w, TWO_PI / abs(w))
    assert math.hypot(x - x0, y - y0) < 1e-12
    assert angle_error(yaw, yaw0) < 1e-12


@pytest.mark.parametrize('v,w', [(0.5, 0.7), (1.0, -2.0)])
def test_full_circle_in_small_steps_closes(v, w):
    x, y, yaw = x0, y0, yaw0 = 1.0, 2.0, 0.3
    steps = 1000
    dt = TWO_PI / abs(w) / steps
    for k in range(steps):
        x, y, yaw = integrate(x, y, yaw, v, w, dt)
        if k == steps // 2 - 1:
            # Half way round the robot is a diameter away, heading the other way.
            assert math.hypot(x - x0, y - y0) == pytest.approx(2 * abs(v / w), rel=1e-12)
            assert angle_error(yaw, yaw0 + math.pi) < 1e-12
    assert math.hypot(x - x0, y - y0) < 1e-12
    assert angle_error(yaw, yaw0) < 1e-12


def test_hundred_laps_in_fixed_steps_do_not_drift():
    v, w, dt = 0.8, 1.3, 0.02
    x0, y0, yaw0 = 0.2, -0.1, 1.0
    model = UnicycleModel(x0, y0, yaw0)
    model.command(v, w)
    total = 100 * TWO_PI / w
    steps = int(total / dt)
    for _ in range(steps):
        model.advance(dt)
    model.advance(total - steps * dt)
    assert math.hypot(model.x - x0, model.y - y0) < 1e-9
    assert angle_error(model.yaw, yaw0) < 1e-9


# -- continuity as w -> 0 ----------------------------------------------------------------------

@pytest.mark.parametrize('w', [1e-3, 1e-5, 1e-7, 1e-9, 0.0, -1e-9, -1e-5])
def test_small_turn_rate_is_continuous(w):
    x0, y0, yaw0, v, t = 0.1, 0.2, 0.7, 1.2, 2.0
    x, y, yaw = integrate(x0, y0, yaw0, v, w, t)
    x_ref, y_ref = exact_arc(x0, y0, yaw0, v, w, t)
    assert x == pytest.approx(x_ref, abs=2e-15)
    assert y == pytest.approx(y_ref, abs=2e-15)
    assert yaw == pytest.approx(yaw0 + w * t, abs=1e-15)
    # Off the straight line by no more than the arc's sagitta, v * |w| * t^2 / 2.
    x_line, y_line = x0 + v * t * math.cos(yaw0), y0 + v * t * math.sin(yaw0)
    assert math.hypot(x - x_line, y - y_line) <= 0.5 * v * abs(w) * t * t + 1e-15


@pytest.mark.parametrize('h', [SMALL_ANGLE, -SMALL_ANGLE])
def test_sinc_has_no_jump_at_the_series_threshold(h):
    below = h * (1.0 - 1e-9)
    above = h * (1.0 + 1e-9)
    assert abs(below) < SMALL_ANGLE <= abs(above)
    for x in (below, math.nextafter(h, 0.0), h, above):
        assert _sinc(x) == pytest.approx(exact_sinc(x), abs=2.3e-16)
    # sinc'(1e-4) is about -3.3e-5, so 2e-13 apart in x means ~1e-17 apart in value.
    assert abs(_sinc(below) - _sinc(above)) <= 2.3e-16
    assert _sinc(0.0) == 1.0


def test_integrate_has_no_jump_at_the_series_threshold():
    # The series applies to half the turn, so the threshold is at w * dt = 2e-4.
    v, dt, yaw0 = 3.0, 0.5, -0.4
    w_threshold = 2.0 * SMALL_ANGLE / dt
    for w in (w_threshold * (1.0 - 1e-9), w_threshold * (1.0 + 1e-9)):
        x, y, _ = integrate(0.0, 0.0, yaw0, v, w, dt)
        x_ref, y_ref = exact_arc(0.0, 0.0, yaw0, v, w, dt)
        assert x == pytest.approx(x_ref, abs=1e-15)
        assert y == pytest.approx(y_ref, abs=1e-15)


# -- yaw normalisation -------------------------------------------------------------------------

def test_yaw_is_wrapped_to_minus_pi_exclusive_pi_inclusive():
    assert integrate(0.0, 0.0, 0.0, 0.0, math.pi, 1.0)[2] == math.pi
    assert integrate(0.0, 0.0, 0.0, 0.0, -math.pi, 1.0)[2] == math.pi
    assert integrate(0.0, 0.0, 3.0, 0.0, 1.0, 0.5)[2] == pytest.approx(3.5 - TWO_PI, abs=1e-15)
    assert integrate(0.0, 0.0, -3.0, 0.0, -1.0, 0.5)[2] == pytest.approx(TWO_PI - 3.5, abs=1e-15)
    # Ten turns and a quarter in one call.
    assert integrate(0.0, 0.0, 0.25, 0.0, 1.0, 10 * TWO_PI)[2] == pytest.approx(0.25, abs=1e-12)
    model = UnicycleModel(yaw=7.0)
    assert model.yaw == pytest.approx(7.0 - TWO_PI, abs=1e-15)
    yaw = 0.0
    for _ in range(200):
        _, _, yaw = integrate(0.0, 0.0, yaw, 0.0, 1.1, 0.37)
        assert in_yaw_range(yaw)


# -- command limits ----------------------------------------------------------------------------

def test_limit_command_zero_means_unlimited():
    assert limit_command(123.0, 0.0, 0.0, 0.0, 0.1) == 123.0
    assert limit_command(2.0, 0.0, 0.5, 0.0, 0.1) == 0.5
    assert limit_command(-2.0, 0.0, 0.5, 0.0, 0.1) == -0.5
    assert limit_command(2.0, 0.3, 0.0, 1.0, 0.1) == pytest.approx(0.4)
    assert limit_command(-2.0, 0.3, 0.0, 1.0, 0.1) == pytest.approx(0.2)


def test_speed_limits_clamp_the_command():
    model = UnicycleModel(max_linear_speed=0.5, max_angular_speed=1.0)
    model.command(2.0, -3.0)
    assert (model.linear, model.angular) == (0.5, -1.0)
    model.advance(2.0)
    x_ref, y_ref = exact_arc(0.0, 0.0, 0.0, 0.5, -1.0, 2.0)
    assert (model.x, model.y) == pytest.approx((x_ref, y_ref), abs=1e-14)
    assert model.yaw == pytest.approx(-2.0, abs=1e-15)
    model.command(-2.0, 0.25)
    assert (model.linear, model.angular) == (-0.5, 0.25)


def test_linear_acceleration_limit_ramps_and_decelerates():
    a, v_goal = 0.5, 2.0
    model = UnicycleModel(max_linear_accel=a)
    model.command(v_goal, 0.0)
    assert model.linear == 0.0
    t = 0.0
    for dt in (0.3, 0.25, 0.7, 0.02, 1.13):
        model.advance(dt)
        t += dt
        assert model.linear == pytest.approx(a * t, abs=1e-12)
        assert model.x == pytest.approx(0.5 * a * t * t, abs=1e-6)
        assert model.y == 0.0
    model.advance(4.0 - t)
    assert model.linear == pytest.approx(v_goal, abs=1e-12)
    assert model.x == pytest.approx(0.5 * v_goal ** 2 / a, abs=1e-6)
    model.advance(1.0)
    assert model.linear == v_goal
    assert not model.ramping
    assert model.x == pytest.approx(0.5 * v_goal ** 2 / a + v_goal, abs=1e-6)
    x_stop = model.x

    # Told to stop, it decelerates at the limit: v_goal / a seconds, v_goal^2 / (2a) metres.
    model.command(0.0, 0.0)
    model.advance(1.5)
    assert model.linear == pytest.approx(v_goal - a * 1.5, abs=1e-12)
    assert model.x == pytest.approx(x_stop + v_goal * 1.5 - 0.5 * a * 1.5 ** 2, abs=1e-6)
    model.advance(10.0)
    assert model.linear == 0.0
    assert not model.ramping
    assert model.x == pytest.approx(x_stop + 0.5 * v_goal ** 2 / a, abs=1e-6)


def test_angular_acceleration_limit_ramps():
    alpha = 2.0
    model = UnicycleModel(max_angular_accel=alpha, max_angular_speed=1.0)
    model.command(0.0, -5.0)
    model.advance(0.4)
    assert model.angular == pytest.approx(-alpha * 0.4, abs=1e-12)
    assert model.yaw == pytest.approx(-0.5 * alpha * 0.4 ** 2, abs=1e-6)
    model.advance(0.6)
    # Capped at max_angular_speed after 0.5 s.
    assert model.angular == -1.0
    assert model.yaw == pytest.approx(-(0.25 + 0.5), abs=1e-6)
    assert (model.x, model.y) == (0.0, 0.0)


def test_both_acceleration_limits_follow_the_closed_form():
    # v = a t and w = alpha t give yaw = alpha t^2 / 2 and
    # x = (a / alpha) sin(alpha t^2 / 2), y = (a / alpha) (1 - cos(alpha t^2 / 2)).
    a, alpha = 0.5, 1.0
    model = UnicycleModel(max_linear_accel=a, max_angular_accel=alpha)
    model.command(10.0, 10.0)
    for t in (0.5, 1.0, 1.5, 2.0):
        model.advance(0.5)
        phi = 0.5 * alpha * t * t
        assert (model.linear, model.angular) == pytest.approx((a * t, alpha * t), abs=1e-12)
        assert model.yaw == pytest.approx(phi, abs=1e-9)
        assert model.x == pytest.approx(a / alpha * math.sin(phi), abs=1e-6)
        assert model.y == pytest.approx(a / alpha * (1.0 - math.cos(phi)), abs=1e-6)


def test_reset_puts_the_model_at_rest():
    model = UnicycleModel(max_linear_accel=1.0)
    model.command(1.0, 0.5)
    model.advance(0.5)
    model.reset(1.0, 2.0, 4.0)
    assert (model.x, model.y) == (1.0, 2.0)
    assert model.yaw == pytest.approx(4.0 - TWO_PI)
    assert (model.linear, model.angular, model.target_linear, model.target_angular) == (0, 0, 0, 0)
    model.advance(1.0)
    assert (model.x, model.y) == (1.0, 2.0)


# -- angles ------------------------------------------------------------------------------------

def test_normalize_angle_edge_cases():
    assert normalize_angle(0.0) == 0.0
    assert normalize_angle(math.pi) == math.pi
    assert normalize_angle(-math.pi) == math.pi
    assert normalize_angle(3 * math.pi) == math.pi
    assert normalize_angle(-3 * math.pi) == math.pi
    assert normalize_angle(TWO_PI) == 0.0
    assert normalize_angle(-TWO_PI) == 0.0
    below_pi = math.nextafter(math.pi, 0.0)
    assert normalize_angle(below_pi) == below_pi
    assert normalize_angle(-below_pi) == -below_pi
    assert normalize_angle(math.nextafter(math.pi, 4.0)) == pytest.approx(-math.pi)
    assert normalize_angle(1e-300) == 1e-300
    assert normalize_angle(0.5 + 7 * TWO_PI) == pytest.approx(0.5, abs=1e-14)
    assert normalize_angle(-0.5 - 7 * TWO_PI) == pytest.approx(-0.5, abs=1e-14)
    with localcontext() as ctx:
        ctx.prec = 50
        two_pi = 2 * Decimal('3.14159265358979323846264338327950288419716939937510')
        big = Decimal(1e6)
        reference = float(big - two_pi * (big / two_pi).to_integral_value())
    assert normalize_angle(1e6) == pytest.approx(reference, abs=1e-9)
    for k in range(-50, 51):
        assert in_yaw_range(normalize_angle(k * 0.77))


@pytest.mark.parametrize('yaw', [0.0, 0.1, -0.1, 1.0, -2.5, math.pi / 2, -math.pi / 2, math.pi,
                                 math.nextafter(-math.pi, 0.0)])
def test_quaternion_round_trip(yaw):
    q = quaternion_from_yaw(yaw)
    assert q[0] == 0.0 and q[1] == 0.0
    assert math.fsum(c * c for c in q) == pytest.approx(1.0, abs=1e-15)
    assert yaw_from_quaternion(*q) == pytest.approx(yaw, abs=1e-15)
    # -q is the same rotation.
    assert angle_error(yaw_from_quaternion(*(-c for c in q)), yaw) < 1e-15


def test_yaw_from_quaternion_stays_in_range():
    # (0, 0, -1, 0) and (0, 0, 1, 0) are both a half turn.
    assert yaw_from_quaternion(0.0, 0.0, 1.0, 0.0) == math.pi
    assert yaw_from_quaternion(0.0, 0.0, -1.0, 0.0) == math.pi
    assert yaw_from_quaternion(*quaternion_from_yaw(-math.pi)) == math.pi
    # A non-unit quaternion gives the same yaw.
    assert yaw_from_quaternion(0.0, 0.0, 2 * math.sin(0.35), 2 * math.cos(0.35)) == (
        pytest.approx(0.7, abs=1e-15))


@pytest.mark.parametrize('scale', [1e200, 1e-200, 1e-320, 1.7e308])
def test_yaw_from_quaternion_of_any_finite_size(scale):
    # Its products would overflow (a NaN yaw) or underflow (atan2(0, 0) = 0) unscaled.
    assert yaw_from_quaternion(0.0, 0.0, scale, scale) == pytest.approx(math.pi / 2, abs=1e-15)
    if scale > 1e-300:  # a subnormal number holds too few digits for more
        assert yaw_from_quaternion(0.0, 0.0, scale * math.sin(0.35), scale * math.cos(0.35)) == (
            pytest.approx(0.7, abs=1e-15))


def test_yaw_accumulator_counts_whole_turns():
    acc = YawAccumulator()
    assert acc.update(0.3) == 0.0
    yaw = 0.3
    # Two and a half turns counter-clockwise in wrapped readings 0.1 rad apart ...
    for _ in range(round(5 * math.pi / 0.1)):
        yaw += 0.1
        acc.update(normalize_angle(yaw))
    assert acc.total == pytest.approx(yaw - 0.3, abs=1e-9)
    # ... then three turns clockwise in steps of 3 rad (less than pi each).
    start_total = acc.total
    for _ in range(round(6 * math.pi / 3.0)):
        yaw -= 3.0
        acc.update(normalize_angle(yaw))
    assert acc.total == pytest.approx(start_total - 3.0 * round(6 * math.pi / 3.0), abs=1e-9)
    acc.reset(1.0)
    assert acc.total == 0.0
    assert acc.update(-3.0) == pytest.approx(TWO_PI - 4.0, abs=1e-15)
    assert YawAccumulator(0.5).update(0.25) == pytest.approx(-0.25)
