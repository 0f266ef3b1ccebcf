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

"""What the browser view draws, as numpy arrays (no ROS, no Rerun): paths, scans, walls."""

import numpy as np

# The map's obstacle cells as drawn: flat slabs just under the robots; the scan's hit points.
MAP_HALF_HEIGHT = 0.02
# A step longer than its robot can have driven is a jump (a reset): no path segment joins it.
_JUMP_MARGIN_M = 1e-3
_GOLDEN = 0.618033988749895


def path_strips(stamps, xs, ys, linear):
    """
    Return each robot's path through xs, ys (count, points) as strips (count, points, 3).

    Points before a jump are moved onto the point after it, so no segment joins the jump.
    """
    if xs.shape[1] < 2:
        return None
    reach = (np.maximum(np.abs(linear[:, 1:]), np.abs(linear[:, :-1])) * (np.diff(stamps) * 1e-9)
             + _JUMP_MARGIN_M)
    jumps = np.hypot(np.diff(xs), np.diff(ys)) > reach
    xs, ys = xs.copy(), ys.copy()
    for robot, after in zip(*np.nonzero(jumps)):  # rare: one loop turn per jump
        xs[robot, :after + 1] = xs[robot, after + 1]
        ys[robot, :after + 1] = ys[robot, after + 1]
    return np.stack([xs, ys, np.zeros_like(xs)], axis=2)


def scan_points(ranges, angles, x, y, yaw):
    """Return the finite hits of scans (robots, beams) from poses x, y, yaw: (points, owners)."""
    ranges = np.asarray(ranges, dtype=float)
    owners, beams = np.nonzero(np.isfinite(ranges))
    hit = ranges[owners, beams]
    heading = np.asarray(yaw, dtype=float)[owners] + np.asarray(angles, dtype=float)[beams]
    points = np.empty((len(hit), 2))
    points[:, 0] = np.asarray(x, dtype=float)[owners] + hit * np.cos(heading)
    points[:, 1] = np.asarray(y, dtype=float)[owners] + hit * np.sin(heading)
    return points, owners


def solid_boxes(grid):
    """Return a map's obstacle cells as boxes, one per run along a row: (centers, half_sizes)."""
    solid = np.asarray(grid.solid, dtype=np.int8)
    edges = np.diff(np.pad(solid, ((0, 0), (1, 1))), axis=1)
    rows, starts = np.nonzero(edges == 1)
    _, ends = np.nonzero(edges == -1)  # row by row, in the same order as the starts
    res = grid.resolution
    gx, gy = 0.5 * (starts + ends) * res, (rows + 0.5) * res
    mx, my = grid.from_grid(gx, gy)
    centers = np.zeros((len(rows), 3))
    centers[:, 0], centers[:, 1] = mx, my
    half_sizes = np.empty((len(rows), 3))
    half_sizes[:, 0] = 0.5 * (ends - starts) * res
    half_sizes[:, 1] = 0.5 * res
    half_sizes[:, 2] = MAP_HALF_HEIGHT
    return centers, half_sizes


def robot_colors(count):
    """Return count distinct RGB colours (uint8), the same for the same index in every run."""
    hues = (0.07 + _GOLDEN * np.arange(count)) % 1.0  # orange first: not Rerun's own blue
    return (np.stack([_hsv_channel(hues, shift) for shift in (5.0, 3.0, 1.0)], axis=1)
            * 255).round().astype(np.uint8)


def _hsv_channel(hues, shift, saturation=0.75, value=0.9):
    k = (shift + hues * 6.0) % 6.0
    return value - value * saturation * np.clip(np.minimum(k, 4.0 - k), 0.0, 1.0)
