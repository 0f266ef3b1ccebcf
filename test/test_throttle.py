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

"""sim_diffdrive.throttle: a log line per key and period, decided on the monotonic clock."""

from sim_diffdrive.throttle import Throttle


def test_the_first_line_goes_out_then_one_per_period_and_key():
    now = [100.0]
    lines = Throttle(1.0, clock=lambda: now[0])
    assert lines.allows('stamp')
    assert not lines.allows('stamp')
    assert lines.allows('value')  # another key has its own period
    now[0] = 100.999
    assert not lines.allows('stamp')
    now[0] = 101.0
    assert lines.allows('stamp')
    assert not lines.allows('stamp')
    assert lines.allows()  # no key: a key of its own
    lines.reset()  # (a new Foxglove subscriber: every robot's scene at once)
    assert lines.allows('stamp') and lines.allows('value')


def test_a_refused_line_does_not_push_the_next_one_back():
    now = [0.0]
    lines = Throttle(2.0, clock=lambda: now[0])
    allowed = []
    for tick in range(100):  # every 50 ms for 5 s
        now[0] = tick * 0.05
        if lines.allows():
            allowed.append(round(now[0], 3))
    assert allowed == [0.0, 2.0, 4.0]
