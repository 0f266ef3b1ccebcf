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

"""The benchmark (tools/benchmark/): its originals against hand-computed answers, a quick run."""

import json
import math
import os
import signal
import subprocess
import sys

from benchmark import core
from benchmark import one_process
from benchmark import originals
import pytest
from sim_diffdrive.harness import isolated_domain_id

BENCH_PATH = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), 'tools',
                          'bench.py')

# Every row the table prints, in order: README.md and docs refer to them by number.
ROW_KEYS = (
    'rotate_timed', 'rotate_odom', 'out_and_back_closure', 'circle_closure',
    'integration_error', 'rtf_in_process', 'rtf_processes', 'latency', 'cpu_idle',
    'cpu_commands', 'scaling_one_process', 'scaling_processes', 'fleet_cpu', 'fleet_real_time',
    'fleet_rtf', 'fleet_per_robot', 'fleet_motions', 'fleet_idle_large', 'suite', 'scan_cast',
)

# The original's speed: 60 deg/s converted with 3.14/180 [rad/s].
ORIGINAL_SPEED = 60.0 * 3.14 / 180.0
DOMAIN_ID = isolated_domain_id()


def original_turn(start_s):
    """Return the yaw after the original rotate_robot.py started at start_s [s] (90 deg cw)."""
    robot = originals.ModelRobot(start_ns=round(start_s * core.NS))
    (_, _, yaw), seconds = robot.play(originals.original_rotate(robot, 60.0, 90.0, True), 10.0)
    return yaw, seconds


def test_original_rotate_from_a_whole_second_turns_two_seconds():
    # t0 = 5 and the estimate moves in whole seconds: 1.047 rad after 1 s is short of the
    # goal 1.57, 2.093 after 2 s is past it, so the turn lasts 2 s: 119.94 deg, not 90.
    yaw, seconds = original_turn(5.0)
    assert seconds == pytest.approx(2.0)
    assert yaw == pytest.approx(-2.0 * ORIGINAL_SPEED, abs=1e-12)
    error = originals.yaw_error_deg(0.0, yaw, -math.pi / 2)
    assert error == pytest.approx(2.0 * 60.0 * 3.14 / math.pi - 90.0, abs=1e-9)
    assert error == pytest.approx(29.939, abs=1e-3)


@pytest.mark.parametrize('offset,ticks', [(0.25, 18), (0.5, 15), (0.95, 11)])
def test_original_rotate_stops_on_the_first_tick_two_whole_seconds_later(offset, ticks):
    # Ticks at 5 + offset + 0.1 k; the first with whole seconds 7 stops the turn.
    yaw, seconds = original_turn(5.0 + offset)
    assert seconds == pytest.approx(ticks * 0.1)
    assert yaw == pytest.approx(-ticks * 0.1 * ORIGINAL_SPEED, abs=1e-12)
    assert originals.yaw_error_deg(0.0, yaw, -math.pi / 2) > 0.04


def test_start_times_are_spread_over_one_second_on_the_step():
    times = originals.start_times(20, 0.05, 1.0)
    offsets = [t % core.NS / core.NS for t in times]
    assert offsets == pytest.approx([0.05 * i for i in range(20)])
    assert all(b - a >= 2 * core.NS for a, b in zip(times, times[1:]))


def test_original_rotate_against_the_simulator_matches_the_hand_computed_error():
    errors = one_process.rotations(core.Run(quick=True), 'original')[:1]
    assert errors == [pytest.approx(29.939, abs=1e-3)]


def test_rbx1_ticks_truncate_the_turn_to_3_14_rad():
    drive, turn, turned = originals.rbx1_ticks()
    assert (drive, turn) == (250, 157)
    assert turned == pytest.approx(3.14)
    # The ticks come from the angle, not the duration: half the speed, half the turn.
    assert originals.rbx1_ticks(angular_speed=0.5)[2] == pytest.approx(1.57)


def test_rbx1_closure_is_off_by_the_truncated_turns():
    robot = originals.ModelRobot()
    (x, y, yaw), seconds = robot.play(originals.rbx1_timed_out_and_back(robot), 50.0)
    short = math.pi - 3.14
    # Out 1 m, turn 3.14, back 1 m: 2 sin(short / 2) from the start; two turns short.
    mm, deg = originals.closure((0.0, 0.0, 0.0), (x, y, yaw))
    assert mm == pytest.approx(2000.0 * math.sin(short / 2.0), abs=1e-6)
    assert mm == pytest.approx(1.593, abs=1e-3)
    assert deg == pytest.approx(math.degrees(2.0 * short), abs=1e-9)
    assert seconds == pytest.approx(2 * (5.0 + 1.0 + 3.14 + 1.0))


def test_move_rob_model_does_not_return_but_a_single_publish_per_flip_does():
    robot = originals.ModelRobot()
    (x, y, _), _ = robot.play(originals.move_rob(robot, cycles=1, half_period=3.0), 10.0)
    assert math.hypot(x, y) > 0.01
    # The same loop with one complete Twist per flip retraces the arc exactly.

    def single_publish(robot):
        for tick in range(60):
            sign = 1.0 if tick < 30 else -1.0
            robot.publish(sign * 0.5, sign * 0.5)
            yield
        robot.publish(0.0, 0.0)
    robot = originals.ModelRobot()
    (x, y, yaw), _ = robot.play(single_publish(robot), 10.0)
    assert math.hypot(x, y) < 1e-12 and abs(yaw) < 1e-12


def test_euler_error_is_orders_of_magnitude_above_the_exact_arc():
    errors = originals.integration_errors(laps=100)
    assert errors['arc_max_m'] < 1e-8
    # Euler's phase lag on a constant circle peaks at about v * dt = 1 cm.
    assert 0.005 < errors['euler_max_m'] <= 0.0101
    assert errors['euler_max_m'] > 1e5 * errors['arc_max_m']


def test_quick_run_writes_every_row(tmp_path):
    # The same command as make bench, at the small sizes of --quick (core.SIZES).
    path = tmp_path / 'bench.json'
    # In a process group of its own: should the run hang, the group goes, the simulators and
    # motions it started too (killed alone, the bench left them publishing on its domain).
    bench = subprocess.Popen(
        [sys.executable, BENCH_PATH, '--quick', '--json', str(path),
         '--domain-id', str(DOMAIN_ID)],
        env=dict(os.environ), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True)
    out = None
    try:
        out, err = bench.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        pass
    finally:  # however it ended (a hang, a failure, Ctrl-C): nothing it started lives on
        try:
            os.killpg(bench.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass  # the group is empty: all its processes ended
    if out is None:
        out, err = bench.communicate()
        pytest.fail('the quick bench did not end within 120 s:\n' + out[-3000:] + err[-3000:])
    assert bench.returncode == 0, out[-3000:] + err[-3000:]
    report = json.loads(path.read_text())
    assert report['quick'] is True
    assert tuple(report['rows']) == ROW_KEYS
    for key, row in report['rows'].items():
        for field in ('measure', 'project', 'reference', 'target', 'result', 'note'):
            assert isinstance(row[field], str) and row[field], (key, field)
        assert row['result'] in ('met', 'missed', '-'), key
        assert (row['target'] == '-') == (row['result'] == '-'), key
    rows = {key: row['data'] for key, row in report['rows'].items()}
    sizes = core.Run(quick=True).sizes
    original = rows['rotate_timed']['original_errors_deg']
    assert len(original) == sizes.starts
    assert original[0] == pytest.approx(29.939, abs=1e-3)
    assert max(rows['rotate_odom']['project_errors_deg']) < 1e-6
    assert rows['rtf_in_process']['events_identical'] is True
    assert rows['rtf_in_process']['step_package_calls'] > 0  # counted, not NaN
    assert rows['rtf_in_process']['step_calls'] > rows['rtf_in_process']['step_package_calls']
    assert rows['out_and_back_closure']['rbx1_mm'] == pytest.approx(1.593, abs=1e-3)
    assert rows['integration_error']['arc_max_m'] < 1e-8
    assert rows['scan_cast']['fleet_cast_s'] < rows['scan_cast']['fleet_loop_s']
    assert tuple(rows['rtf_processes']['rtf']) == sizes.process_motions
    assert rows['rtf_processes']['round_trip_us'] > 0.0
    assert rows['rtf_processes']['bare_step_us'] > 0.0  # (NaN, from no bare steps, is not)
    ratio = rows['rtf_processes']['step_over_round_trip']
    assert ratio is not None and ratio > 0.0, rows['rtf_processes']['untimed']
    assert rows['latency']['samples'] + rows['latency']['lost'] == sizes.latency_samples
    # Measured (a number, not NaN); a quick window of 0.2 s on a loaded machine may see a
    # process not run at all (0.0 once for the publish floor, in a suite beside two others).
    for key in ('idle_percent', 'rclpy_floor_percent', 'publish_floor_percent',
                'sleep_floor_percent'):
        assert rows['cpu_idle'][key] >= 0.0, key
    # Wakes per step by thread: how many is the load's (a simulator behind on a busy machine
    # runs several steps a wake), but some thread of it was seen to wake.
    assert rows['cpu_idle']['wakes_per_step'], 'no wake of the simulator was counted'
    assert tuple(rows['scaling_one_process']['rtf']) == tuple(map(str, sizes.robots))
    assert tuple(rows['scaling_processes']['rtf']) == tuple(map(str, sizes.robots_processes))
    # Many robots in one simulator (rows 13-18): every count measured, sane, motions exact.
    fleet = rows['fleet_cpu']
    for key in ('idle_cores', 'commands_cores'):
        assert tuple(fleet[key]) == tuple(map(str, sizes.fleet_robots)), key
        assert all(0.0 < cores < 2.0 for cores in fleet[key].values()), (key, fleet[key])
    assert rows['fleet_real_time']['robots'] == sizes.fleet_robots[-1]
    assert rows['fleet_real_time']['steps_per_s'] > 0.0
    free = rows['fleet_rtf']
    for key in ('idle_rtf', 'commands_rtf'):
        assert tuple(free[key]) == tuple(map(str, sizes.fleet_free_robots)), key
        assert all(factor > 0.0 for factor in free[key].values()), (key, free[key])
    assert all(0.0 < commands for commands in free['commands_per_robot_step'].values())
    per_message = rows['fleet_per_robot']['per_message_s']
    assert 0.0 < per_message['no_subscriber_s'] < 1e-3
    assert 0.0 < per_message['one_subscriber_s'] < 1e-3
    assert math.isfinite(rows['fleet_per_robot']['ratio'])
    motions = rows['fleet_motions']
    for run in (motions['one_simulator'], motions['pairs']):
        assert run['robots'] == sizes.fleet_motion_robots
        assert run['failed'] == 0, json.dumps(run, indent=1)
        assert run['rtf'] > 0.0 and run['wall_s'] > 0.0
    # The closing lines print 3 decimals of mm and 4 of deg: exact prints zeros.
    assert motions['one_simulator']['worst_mm'] == 0.0
    assert motions['one_simulator']['worst_deg'] == 0.0
    assert motions['one_simulator']['exit_codes'] == [0]
    large = rows['fleet_idle_large']
    assert large['robots'] == sizes.fleet_idle_robots
    # --quick starts no simulator of its own for row 18: row 13's largest, idle, is measured.
    assert large['from_row_13'] is True
    assert large['window'] == fleet['windows'][str(sizes.fleet_idle_robots)]['idle']
    assert 0.0 < large['cores'] < 2.0 and large['steps_per_s'] > 0.0
    # Row 19 times a pytest run as it times make test, here on one module of pure tests.
    suite = rows['suite']
    assert suite['command'].endswith(' test/test_throttle.py')
    assert suite['returncode'] == 0 and suite['counts']['passed'] > 0, suite
    assert 0.0 < suite['wall_s'] and 0.0 < suite['cpu_s'], suite
    # The table is printed too, with the commit it measured.
    assert 'this project' in out and 'reference' in out
    assert report['machine']['commit'] != '?'
    assert f'commit {report["machine"]["commit"]}' in out
