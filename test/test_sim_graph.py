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

from conftest import angle_error
from conftest import pose_of
import pytest

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
