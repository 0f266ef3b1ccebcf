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
The closed loops on plain numbers, against closed forms; no ROS graph (like Nav2's line_iterator).

A simulated perfect robot integrates each command over one control period, exactly as the
simulator would, and reports its pose as odometry.
"""

import math

from motion_challenges.controllers import Approach
from motion_challenges.controllers import CommandLog
from motion_challenges.controllers import odometry_fault
from motion_challenges.controllers import OutAndBack
from motion_challenges.controllers import Pose
from motion_challenges.controllers import SpinController
from motion_challenges.controllers import Standstill
from motion_challenges.controllers import Step
from motion_challenges.controllers import TOLERANCE
from motion_challenges.plans import speed_ramp
import pytest
from sim_diffdrive.angles import normalize_angle
from sim_diffdrive.angles import YawAccumulator
from sim_diffdrive.kinematics import integrate

NS = 1_000_000_000
MS = 1_000_000


def spin_law(remaining, max_speed, min_speed, accel, period):
    """Nav2 Spin's v = clamp(sqrt(2 a remaining), v_min, v_max), capped to end on the goal."""
    return min(max(math.sqrt(2.0 * accel * remaining), min_speed), max_speed, remaining / period)


def spin_on_a_perfect_robot(spin, period, max_ticks=100000):
    """Run spin until done; return the commands and the yaw turned."""
    turned = 0.0
    commands = []
    while True:
        angular = spin.command(turned)
        if angular is None:
            return commands, turned
        commands.append(angular)
        turned += angular * period
        assert len(commands) < max_ticks


# -- SpinController ---------------------------------------------------------------------------


@pytest.mark.parametrize('angle_deg', [0.5, 45.0, 90.0, 180.0, 359.0, 720.0, 1080.0])
@pytest.mark.parametrize('clockwise', [False, True])
@pytest.mark.parametrize('period', [0.1, 0.02])
def test_spin_ends_on_the_goal_and_never_exceeds_its_speed(angle_deg, clockwise, period):
    max_speed, min_speed, accel = math.radians(60.0), math.radians(2.0), math.radians(180.0)
    goal = math.radians(angle_deg)
    spin = SpinController(goal, clockwise, max_speed, min_speed, accel, period)
    commands, turned = spin_on_a_perfect_robot(spin, period)
    sign = -1.0 if clockwise else 1.0
    assert abs(turned - sign * goal) <= TOLERANCE
    assert all(sign * w > 0.0 for w in commands), 'always turns the asked way'
    assert max(abs(w) for w in commands) <= max_speed
    # It takes about as long as a trapezoid without the acceleration ramp: no dawdling.
    least = goal / max_speed
    assert least - period <= len(commands) * period <= least + max_speed / accel + 2 * period


def test_spin_slows_down_as_nav2_spin_does():
    max_speed, min_speed, accel, period = 1.0, 0.05, 2.0, 0.02
    goal = 3.0
    spin = SpinController(goal, False, max_speed, min_speed, accel, period)
    turned = 0.0
    speeds = []
    while (angular := spin.command(turned)) is not None:
        remaining = goal - turned
        assert angular == pytest.approx(spin_law(remaining, max_speed, min_speed, accel, period),
                                        rel=1e-12)
        speeds.append(angular)
        turned += angular * period
    # Full speed at first, then never faster again while approaching.
    assert speeds[0] == max_speed
    assert all(b <= a for a, b in zip(speeds, speeds[1:]))
    assert min(speeds[:-1]) >= min_speed


def test_spin_with_late_odometry_and_the_command_log_ends_on_the_goal():
    """Odometry one period old plus the commands since is where the robot is."""
    period_ns = 20 * MS
    spin = SpinController(math.pi, True, 1.0, 0.05, 2.0, period_ns / NS)
    log = CommandLog()
    robot_yaw = 0.0
    odom = Pose(0.0, 0.0, 0.0, stamp_ns=0)
    now_ns = 0
    while True:
        _, predicted = log.predict(odom.stamp_ns, now_ns)[0]
        angular = spin.command(odom.yaw, predicted)
        if angular is None:
            break
        log.add(now_ns, 0.0, angular)
        # The robot measured itself at now_ns; that odometry arrives one tick later.
        odom = Pose(0.0, 0.0, robot_yaw, stamp_ns=now_ns)
        robot_yaw += angular * period_ns / NS
        now_ns += period_ns
    assert robot_yaw == pytest.approx(-math.pi, abs=TOLERANCE)


@pytest.mark.parametrize('told', [True, False])
def test_spin_on_a_robot_that_ramps_stops_on_the_goal_when_told_its_limit(told):
    """
    A robot whose turn rate ramps at 2 rad/s^2, odometry one period late (its twist too).

    Told the limit, the loop predicts the ramp and ends on the goal; not told, it overshoots
    by degrees (docs/robustness.md, "A robot cannot stop at once").
    """
    period_ns, limit = 20 * MS, 2.0
    spin = SpinController(math.radians(135.0), False, math.radians(60.0), math.radians(2.0),
                          math.radians(180.0), period_ns / NS, robot_accel=limit if told else 0.0)
    accel = (0.0, limit if told else 0.0)
    log, robot_yaw, robot_rate, now_ns = CommandLog(), 0.0, 0.0, 0
    odom, odom_rate = Pose(0.0, 0.0, 0.0, stamp_ns=0), 0.0
    while True:
        (_, predicted), (_, rate) = log.predict(odom.stamp_ns, now_ns, (0.0, odom_rate), accel)
        angular = spin.command(odom.yaw, predicted, rate)
        if angular is None:
            break
        log.add(now_ns, 0.0, angular)
        odom, odom_rate = Pose(0.0, 0.0, robot_yaw, stamp_ns=now_ns), robot_rate
        turn, robot_rate = speed_ramp(robot_rate, angular, limit, period_ns / NS)
        robot_yaw += turn
        now_ns += period_ns
        assert now_ns < 60 * NS
    while robot_rate != 0.0:  # after the last command: the robot comes to rest
        turn, robot_rate = speed_ramp(robot_rate, 0.0, limit, period_ns / NS)
        robot_yaw += turn
    if told:
        assert robot_yaw == pytest.approx(math.radians(135.0), abs=1e-12)
    else:
        assert math.degrees(robot_yaw) > 136.0


def test_command_log_predicts_a_ramping_robot():
    log = CommandLog()
    log.add(0, 1.0, -1.0)
    log.add(NS, 0.0, 0.0)
    # From rest, limits 0.5 m/s^2 and 2 rad/s^2: 1 s of linear ramp (0.25 m, now 0.5 m/s), the
    # turn rate at -1 after 0.5 s (-0.25 - 0.5 rad); then down again for 0.5 s each.
    (metres, radians), speeds = log.predict(0, 3 * NS // 2, (0.0, 0.0), (0.5, 2.0))
    assert (metres, radians) == pytest.approx((0.25 + 0.1875, -0.75 - 0.25), abs=1e-15)
    assert speeds == pytest.approx((0.25, 0.0), abs=1e-15)
    # Without limits: the commands' integral, and the latest command's speeds.
    assert log.predict(0, 3 * NS // 2) == ((1.0, -1.0), (0.0, 0.0))


def test_spin_progress_is_counted_in_the_goal_direction():
    spin = SpinController(1.0, True, 1.0, 0.1, 1.0, 0.1)
    assert spin.progress(-0.25, -0.25) == 0.5
    assert spin.command(-1.0) is None
    assert spin.command(0.0) == -1.0


def test_approach_refuses_bad_values_at_once():
    with pytest.raises(ValueError):
        Approach(0.0, 0.1, 1.0, 0.1)
    with pytest.raises(ValueError):
        Approach(1.0, 0.1, 1.0, 0.0)
    # A min speed above the max speed is the max speed.
    assert Approach(0.5, 2.0, 100.0, 0.01).speed(1.0) == 0.5


# -- OutAndBack ---------------------------------------------------------------------------------


def out_and_back(legs=2, goal_distance=1.0, goal_angle=math.pi, pause=1.0, period=0.02):
    return OutAndBack(legs, goal_distance, goal_angle, pause,
                      drive=Approach(0.2, 0.01, 0.5, period),
                      turn=Approach(1.0, 0.05, 2.0, period))


def drive_legs(legs, x=0.0, y=0.0, yaw=0.0, period_ns=20 * MS):
    """Run the sequencer on a perfect robot; return the visited steps and the end pose."""
    turned = YawAccumulator(yaw)
    now_ns = 0
    legs.start(now_ns, Pose(x, y, yaw, now_ns), turned.total)
    visited = [(legs.leg, legs.step, now_ns)]
    while (command := legs.command(now_ns, Pose(x, y, yaw, now_ns), turned.total)) is not None:
        if (legs.leg, legs.step) != visited[-1][:2]:
            visited.append((legs.leg, legs.step, now_ns))
        x, y, yaw = integrate(x, y, yaw, *command, period_ns / NS)
        turned.update(yaw)
        now_ns += period_ns
        assert now_ns < 1000 * NS
    visited.append((None, None, now_ns))
    return visited, (x, y, yaw)


def test_out_and_back_visits_drive_pause_turn_pause_per_leg_then_ends():
    legs = out_and_back(legs=2)
    assert legs.step is None and not legs.finished
    visited, (x, y, yaw) = drive_legs(legs, 1.0, -2.0, 0.5)
    steps = [(leg, step) for leg, step, _ in visited]
    assert steps == [(1, Step.DRIVE), (1, Step.PAUSE), (1, Step.TURN), (1, Step.PAUSE),
                     (2, Step.DRIVE), (2, Step.PAUSE), (2, Step.TURN), (2, Step.PAUSE),
                     (None, None)]
    assert legs.finished
    # Out, turn around, back, turn around: where it started, facing the same way.
    assert math.hypot(x - 1.0, y + 2.0) < 1e-6
    assert abs(normalize_angle(yaw - 0.5)) < 1e-6
    # Each pause lasts its second (to the tick).
    starts = [t for _, _, t in visited]
    for i, (_, step, start) in enumerate(visited[:-1]):
        if step is Step.PAUSE:
            assert (starts[i + 1] - start) / NS == pytest.approx(1.0, abs=0.02 + 1e-9)


def test_out_and_back_drives_the_distance_and_turns_the_angle():
    legs = out_and_back(legs=1, goal_distance=0.7, goal_angle=math.pi / 2, pause=0.0)
    visited, (x, y, yaw) = drive_legs(legs)
    assert [step for _, step, _ in visited] == [Step.DRIVE, Step.TURN, None]
    assert (x, y) == pytest.approx((0.7, 0.0), abs=1e-6)
    assert yaw == pytest.approx(math.pi / 2, abs=1e-6)


def test_out_and_back_uses_the_predicted_progress():
    legs = out_and_back(legs=1, goal_distance=0.5, pause=0.0)
    start = Pose(0.0, 0.0, 0.0, 0)
    legs.start(0, start, 0.0)
    # Odometry still at the start, but the commands since have covered the distance: turn.
    assert legs.command(NS, start, 0.0, predicted=(0.5, 0.0)) == (0.0, 1.0)
    assert legs.step is Step.TURN


# -- CommandLog ---------------------------------------------------------------------------------


def test_command_log_integrates_each_command_until_the_next():
    log = CommandLog()
    log.add(0, 1.0, 0.5)
    log.add(1 * NS, 2.0, -1.0)
    log.add(3 * NS, 0.0, 0.0)
    # [0.5, 2]: half a second of (1, 0.5), one second of (2, -1).
    assert log.predict(NS // 2, 2 * NS)[0] == pytest.approx((2.5, -0.75), abs=1e-15)
    # [2.5, 4]: half a second of (2, -1), then the stop.
    assert log.predict(5 * NS // 2, 4 * NS)[0] == pytest.approx((1.0, -0.5), abs=1e-15)
    # Nothing was commanded before the first entry; the last holds until now.
    assert log.predict(-NS, NS // 4)[0] == pytest.approx((0.25, 0.125), abs=1e-15)
    log.add(5 * NS, 0.1, 0.0)
    assert log.predict(5 * NS, 7 * NS)[0] == pytest.approx((0.2, 0.0), abs=1e-15)
    assert log.predict(2 * NS, 2 * NS)[0] == (0.0, 0.0)


# -- odometry_fault -----------------------------------------------------------------------------


def driving_log(linear=0.2, angular=0.5):
    log = CommandLog()
    log.add(0, linear, angular)
    return log


def test_a_normal_step_is_no_fault():
    log = driving_log()
    last = Pose(0.0, 0.0, 0.0, 0)
    x, y, yaw = integrate(0.0, 0.0, 0.0, 0.2, 0.5, 0.02)
    assert odometry_fault(last, Pose(x, y, yaw, 20 * MS), log) == ''
    # Less than commanded (blocked, or a slower robot) is no fault either.
    assert odometry_fault(last, Pose(0.0, 0.0, 0.0, 20 * MS), log) == ''


def test_odometry_back_in_time_is_a_fault():
    fault = odometry_fault(Pose(0.0, 0.0, 0.0, 5 * NS), Pose(0.0, 0.0, 0.0, 4 * NS), driving_log())
    assert fault == 'Odometry went back in time from 5.000 s to 4.000 s'


@pytest.mark.parametrize('x, yaw', [(1.0, 0.0), (0.0, 0.5), (0.0, -0.05)])
def test_a_jump_or_a_turn_the_wrong_way_is_a_fault(x, yaw):
    fault = odometry_fault(Pose(0.0, 0.0, 0.0, 0), Pose(x, 0.0, yaw, 20 * MS), driving_log())
    assert fault.startswith('Odometry jumped')


def test_a_restarted_simulator_whose_clock_ran_ahead_is_a_fault():
    # 0.2 m into a drive at 0.2 m/s, the next odometry is 3 s later and back at the start:
    # closer than the 0.6 m commanded meanwhile, but behind the robot.
    last, pose = Pose(0.2, 0.0, 0.0, 1 * NS), Pose(0.0, 0.0, 0.0, 4 * NS)
    assert odometry_fault(last, pose, driving_log(0.2, 0.0)) == (
        'Odometry jumped 0.200 m (-0.200 m along the heading) and 0.0 deg between two messages')
    # The same step forward, and along an arc (the chord half the turn ahead), is no fault.
    assert odometry_fault(last, Pose(0.4, 0.0, 0.0, 4 * NS), driving_log(0.2, 0.0)) == ''
    x, y, yaw = integrate(0.2, 0.0, 0.0, 0.2, 0.5, 3.0)
    assert odometry_fault(last, Pose(x, y, yaw, 4 * NS), driving_log(0.2, 0.5)) == ''
    # Backing up as commanded is no fault; backing up when told to go forward is.
    assert odometry_fault(last, Pose(0.0, 0.0, 0.0, 4 * NS), driving_log(-0.2, 0.0)) == ''
    assert odometry_fault(last, Pose(0.4, 0.0, 0.0, 4 * NS), driving_log(-0.2, 0.0)) != ''


def test_a_robot_still_slowing_down_is_no_jump_when_its_limit_is_known():
    # At 2 m/s, commanded 0, slowing at 1 m/s^2: 0.0398 m in the next 20 ms.
    log = driving_log(0.0, 0.0)
    last, pose = Pose(0.0, 0.0, 0.0, 0), Pose(0.0398, 0.0, 0.0, 20 * MS)
    assert odometry_fault(last, pose, log, velocity=(2.0, 0.0), accel=(1.0, 0.0)) == ''
    assert odometry_fault(last, pose, log).startswith('Odometry jumped')


def test_command_log_keeps_every_command_since_the_last_odometry():
    """A 200 Hz controller on 10 Hz odometry: twenty commands lie between two odometry stamps."""
    log = CommandLog()
    period_ns = 5 * MS
    for k in range(40):
        log.add(k * period_ns, 0.01 * k, -0.02 * k)
    # Between the odometry stamped at 0 and the next at 0.1 s (the jump check) ...
    metres, radians = log.predict(0, 100 * MS)[0]
    assert metres == pytest.approx(sum(0.01 * k * 0.005 for k in range(20)), rel=1e-12)
    assert radians == pytest.approx(sum(-0.02 * k * 0.005 for k in range(20)), rel=1e-12)
    # ... and since the odometry at 0.1 s until now, 0.2 s (the lag compensation).
    metres, radians = log.predict(100 * MS, 200 * MS)[0]
    assert metres == pytest.approx(sum(0.01 * k * 0.005 for k in range(20, 40)), rel=1e-12)
    assert radians == pytest.approx(sum(-0.02 * k * 0.005 for k in range(20, 40)), rel=1e-12)


def test_command_log_forgets_what_ended_before_the_latest_odometry():
    log = CommandLog()
    for k in range(1000):  # 5 s at 200 Hz, odometry at 10 Hz
        log.add(k * 5 * MS, 1.0, 0.5)
        if k % 20 == 0:
            log.forget_before(k * 5 * MS)
    assert len(log) <= 21
    # What is still asked for is all there: since the latest odometry, at 4.9 s.
    assert log.predict(4900 * MS, 5000 * MS)[0] == pytest.approx((0.1, 0.05), rel=1e-12)
    # The command under way at t stays, even when it began before t.
    log.forget_before(4997 * MS)
    assert len(log) == 1
    assert log.predict(4997 * MS, 5000 * MS)[0] == pytest.approx((0.003, 0.0015), rel=1e-12)


def test_command_log_nobody_asks_keeps_only_its_horizon():
    log = CommandLog(horizon_ns=NS)
    for k in range(10000):  # 10 s at 1 kHz, no odometry
        log.add(k * MS, 1.0, 0.0)
    assert len(log) <= 1001
    assert log.predict(8999 * MS, 9999 * MS)[0] == pytest.approx((1.0, 0.0), rel=1e-12)


def _stand(watch, commands, stamps_s, moving=()):
    """Feed odometry at stamps_s (moving at the indices in moving); return the last answer."""
    pose, answer = Pose(1.0, 2.0, 0.5, 0), ''
    for i, stamp_s in enumerate(stamps_s):
        x = pose.x + (0.01 if i in moving else 0.0)
        nxt = Pose(x, pose.y, pose.yaw, round(stamp_s * NS))
        answer = watch.update(pose, nxt, commands)
        pose = nxt
    return answer


def test_a_robot_commanded_but_still_for_a_second_is_stuck():
    commands = CommandLog()
    commands.add(0, 0.2, 0.0)
    watch = Standstill()
    assert _stand(watch, commands, [0.02 * k for k in range(1, 50)]) == ''  # 0.98 s
    stuck = watch.update(Pose(1.0, 2.0, 0.5, round(0.98 * NS)),
                         Pose(1.0, 2.0, 0.5, round(1.0 * NS)), commands)
    assert stuck.startswith('The robot has stood still at (1.000, 2.000) for 1.0 s while '
                            'commanded to go 0.200 m and turn 0.0 deg'), stuck


def test_a_robot_that_moves_or_is_told_to_stay_is_not_stuck():
    commands = CommandLog()
    commands.add(0, 0.2, 0.0)
    # It moves once in the second: the count starts again from there.
    assert _stand(Standstill(), commands, [0.02 * k for k in range(1, 60)], moving={30}) == ''
    still = CommandLog()
    still.add(0, 0.0, 0.0)
    assert _stand(Standstill(), still, [0.02 * k for k in range(1, 200)]) == ''
    creep = CommandLog()  # commanded less than WAY_M in all
    creep.add(0, 0.01, 0.0)
    assert _stand(Standstill(), creep, [0.02 * k for k in range(1, 200)]) == ''
