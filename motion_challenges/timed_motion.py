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

"""The open-loop motions' base: follow a PiecewisePlan (plans.py) on the node clock."""

from motion_challenges.controllers import NS
from motion_challenges.motion_node import MotionNode
from motion_challenges.robot_watch import MotionState


class TimedMotion(MotionNode):
    """
    An open-loop motion: follows the PiecewisePlan its subclass returns from ``plan()``.

    Each tick publishes the plan's mean command until the next tick, so the commanded integral
    equals the plan's.  On sim time the next tick is known (the first clock step at or after it
    is due); on wall time ticks land late, so the last tick arms a one-shot timer for the plan's
    end and the final stop is sent then.
    """

    def plan(self):
        raise NotImplementedError

    def begin(self, now_ns):
        self._plan = self.plan()
        self._end_timer = None

    def elapsed(self, now_ns):
        return (now_ns - self.start_ns) / NS

    def control(self, now_ns):
        t = self.elapsed(now_ns)
        if self._plan.finished(t):
            return None
        end = self._plan.duration
        if not self.sim_time and t + self.period >= end:
            if self._end_timer is None:
                self._end_timer = self.create_timer(end - t, self._on_plan_end)
            return self._plan.average(t, end)
        return self._plan.average(t, t + self._until_next_tick_s())

    def _until_next_tick_s(self):
        """Return how long this tick's command holds [s]: until the next tick fires."""
        if self.lockstep is None:
            return self.period
        step_ns = self.lockstep.clock_step_ns
        due_ns = self.lockstep.until_next_call_ns(self._tick_timer)
        if not step_ns or due_ns is None:
            return self.period
        # The clock reaches the next tick's time in whole steps of its last step's size.
        return -(-due_ns // step_ns) * step_ns / NS

    def _on_plan_end(self):
        self._end_timer.cancel()
        if self.state == MotionState.RUNNING:
            self.stop_robot()
