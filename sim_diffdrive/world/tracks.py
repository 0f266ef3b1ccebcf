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

"""Robots solid to each other: each robot's track through a step, and where two first touch."""

import numpy as np
from sim_diffdrive.kinematics import integrate
from sim_diffdrive.world.contact import robot_contact


class Track:
    """A robot's way through a step in the map: its pose at the start and its timed arcs."""

    def __init__(self, x, y, yaw, arcs_):
        self.start = (x, y, yaw)
        self.arcs = arcs_  # (begin [s into the step], seconds, linear, angular), in order
        self.length = sum(abs(linear) * seconds for _, seconds, linear, _ in arcs_)

    def at(self, t):
        """Return (x, y, yaw, linear, angular): the pose at t [s] and the arc held from there."""
        x, y, yaw = self.start
        for begin, seconds, linear, angular in self.arcs:
            if t < begin + seconds:
                if t > begin:
                    x, y, yaw = integrate(x, y, yaw, linear, angular, t - begin)
                return (x, y, yaw, linear, angular) if t >= begin else (x, y, yaw, 0.0, 0.0)
            x, y, yaw = integrate(x, y, yaw, linear, angular, seconds)
        return x, y, yaw, 0.0, 0.0

    def bounds(self):
        return [edge for begin, seconds, _, _ in self.arcs for edge in (begin, begin + seconds)]

    def cut(self, t):
        """Return this track, standing still from t on."""
        kept = [(begin, min(seconds, t - begin), linear, angular)
                for begin, seconds, linear, angular in self.arcs if begin < t]
        return Track(*self.start, kept)


def earliest_touch(tracks, radius, touched):
    """Return (t [s], i, j) of the first two tracks that touch, or None."""
    moved = np.array([track.length for track in tracks])
    if not moved.any():
        return None
    x = np.array([track.start[0] for track in tracks])
    y = np.array([track.start[1] for track in tracks])
    apart = np.hypot(x[:, None] - x[None, :], y[:, None] - y[None, :])
    near = apart - (moved[:, None] + moved[None, :]) <= 2.0 * radius + 1e-9
    near &= (moved[:, None] + moved[None, :]) > 0.0
    rows, columns = np.nonzero(np.triu(near, 1))  # (i, j) in order: a tie goes to the first
    touches = ((touch(tracks[i], tracks[j], radius), i, j)
               for i, j in zip(rows.tolist(), columns.tolist()) if (i, j) not in touched)
    return min((found for found in touches if found[0] is not None), default=None)


def touch(a, b, radius):
    """Return the first time [s] tracks a and b come two radii apart, closing in, or None."""
    edges = sorted({0.0, *a.bounds(), *b.bounds()})  # distinct: each span is longer than 0
    for begin, end in zip(edges, edges[1:]):
        at = robot_contact(radius, a.at(begin), b.at(begin), end - begin)
        if at is not None:
            return begin + at
    return None
