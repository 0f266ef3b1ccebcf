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
The laser scan's cost: cast() for all robots at once against nav2_loopback_sim's per-ray loop.

``python tools/benchmark/scan.py [repeats]`` prints the table; measure() returns its figures.
On maps/room.yaml, 360 beams of 3.5 m,
robots of radius 0.105 m at seeded random poses on the free floor.
"""

import math
from pathlib import Path
import sys
import time

import numpy as np
from sim_diffdrive.world.grid import load_map
from sim_diffdrive.world.scan import beam_angles
from sim_diffdrive.world.scan import cast
from sim_diffdrive.world.scan import Scanner

ROOM_YAML = Path(__file__).resolve().parents[2] / 'maps' / 'room.yaml'
BEAMS, RANGE_MAX, RADIUS, RATE_HZ = 360, 3.5, 0.105, 10.0
ROBOTS = 64


def room():
    """Return the example room, maps/room.yaml."""
    return load_map(ROOM_YAML)


def poses(grid, count, seed=0):
    """Return count poses on the free floor, a radius clear of walls and of each other."""
    rng = np.random.default_rng(seed)
    placed = []
    while len(placed) < count:
        gx = rng.uniform(0.0, grid.width * grid.resolution)
        gy = rng.uniform(0.0, grid.height * grid.resolution)
        span = math.ceil(RADIUS / grid.resolution)
        col, row = int(gx / grid.resolution), int(gy / grid.resolution)
        if grid.solid[max(row - span, 0):row + span + 1, max(col - span, 0):col + span + 1].any():
            continue
        if all(math.hypot(gx - px, gy - py) > 2.0 * RADIUS for px, py, _ in placed):
            placed.append((gx, gy, rng.uniform(-math.pi, math.pi)))
    gx, gy, yaw = (np.array(v) for v in zip(*placed))
    x, y = grid.from_grid(gx, gy)
    return x, y, yaw + grid.origin[2]


def seconds(call, repeats):
    """Return the median wall time of call() over repeats runs, after one warm-up."""
    call()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def measure(repeats=5, loop_robots=ROBOTS):
    """
    Return the figures: seconds per beam and per scan of each method, and the agreement.

    The per-ray loop runs over the first loop_robots robots; its fleet time is that times
    ROBOTS / loop_robots (the loop's cost is the same for every robot: a loop per ray).
    """
    grid = room()
    angles = beam_angles(BEAMS)
    x, y, yaw = poses(grid, ROBOTS)
    one = (x[:1], y[:1], yaw[:1])
    scanner = Scanner(grid, beams=BEAMS, range_max=RANGE_MAX, noise_std=0.01, radius=RADIUS)
    exact = cast(grid, x, y, yaw, angles, RANGE_MAX)
    # The per-ray loop over every robot (but with --quick), timed once: the run that is
    # compared (half a second of pure Python a run, no warm-up to speak of; twice more cost a
    # second of every run).
    start, exact = time.perf_counter(), exact[:loop_robots]
    loop = cast_per_ray(grid, x[:loop_robots], y[:loop_robots], yaw[:loop_robots], angles,
                        RANGE_MAX)
    fleet_loop_s = (time.perf_counter() - start) * ROBOTS / loop_robots
    both = np.isfinite(exact) & np.isfinite(loop)
    return {
        'one_robot_cast_s': seconds(lambda: cast(grid, *one, angles, RANGE_MAX), repeats),
        'one_robot_loop_s': seconds(lambda: cast_per_ray(grid, *one, angles, RANGE_MAX),
                                    repeats),
        'fleet_cast_s': seconds(lambda: cast(grid, x, y, yaw, angles, RANGE_MAX), repeats),
        'fleet_scan_s': seconds(lambda: scanner.scan(x, y, yaw), repeats),
        'fleet_loop_s': fleet_loop_s,
        'loop_error_max_m': float(np.abs(loop[both] - exact[both]).max()),
        'resolution_m': grid.resolution,
    }


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    figures = measure(int(argv[0]) if argv else 5)
    beams = ROBOTS * BEAMS
    rows = [
        ('measure', 'cast (numpy, exact)', 'nav2_loopback_sim loop', 'ratio'),
        ('1 robot x %d beams, per beam' % BEAMS, '%.2f us' % (figures['one_robot_cast_s']
                                                              / BEAMS * 1e6),
         '%.2f us' % (figures['one_robot_loop_s'] / BEAMS * 1e6),
         '%.0fx' % (figures['one_robot_loop_s'] / figures['one_robot_cast_s'])),
        ('%d robots x %d beams, per beam' % (ROBOTS, BEAMS),
         '%.2f us' % (figures['fleet_cast_s'] / beams * 1e6),
         '%.2f us' % (figures['fleet_loop_s'] / beams * 1e6), ''),
        ('%d x %d, per scan' % (ROBOTS, BEAMS),
         '%.1f ms (%.1f ms with discs, noise)' % (figures['fleet_cast_s'] * 1e3,
                                                  figures['fleet_scan_s'] * 1e3),
         '%.0f ms' % (figures['fleet_loop_s'] * 1e3),
         '%.0fx' % (figures['fleet_loop_s'] / figures['fleet_cast_s'])),
        ('%d x %d at %g Hz, share of a core' % (ROBOTS, BEAMS, RATE_HZ),
         '%.0f %%' % (figures['fleet_scan_s'] * RATE_HZ * 100),
         '%.0f %%' % (figures['fleet_loop_s'] * RATE_HZ * 100), ''),
    ]
    widths = [max(len(r[i]) for r in rows) for i in range(4)]
    for i, cells in enumerate(rows):
        print(' | '.join(cell.ljust(w) for cell, w in zip(cells, widths)).rstrip())
        if i == 0:
            print('-+-'.join('-' * w for w in widths))
    print("cast: the walls only; the share of a core is Scanner.scan's (the walls, the other"
          " robots' discs, noise).")
    print('The loop steps cell to cell and returns cell indices apart: off the exact ranges by up'
          ' to %.3f m (%.1f cells).'
          % (figures['loop_error_max_m'], figures['loop_error_max_m'] / figures['resolution_m']))


def cast_per_ray(grid, x, y, yaw, angles, range_max, step=None):
    """
    Return the ranges as nav2_loopback_sim casts them, one ray at a time in Python (benchmark).

    step None: its findMapRange, Amanatides & Woo's traversal from cell to cell, the range
    being the distance between the start cell's and the hit cell's indices times the
    resolution (within sqrt(2) cells of the exact one; the start cell is not looked at); a
    step [m]: its earlier walk along the ray in steps from its origin (nav2_simple_commander's
    LineIterator), the range of the first point in a solid cell.  grid.solid is the occupancy
    (nav2: a value >= 60); no return, out of the map or beyond range_max, is +inf here (nav2:
    range_max - 0.01).
    """
    cells = (grid.solid.ravel().tolist(), grid.resolution, grid.width, grid.height)
    ranges = np.full((len(x), len(angles)), math.inf)
    for i in range(len(x)):
        gx, gy = grid.to_grid(float(x[i]), float(y[i]))
        for j in range(len(angles)):
            theta = float(yaw[i]) + float(angles[j]) - grid.origin[2]
            ranges[i, j] = (_traverse(*cells, gx, gy, theta, range_max) if step is None else
                            _walk(*cells, gx, gy, theta, range_max, step))
    return ranges


def _traverse(solid, res, width, height, gx, gy, theta, range_max):
    origin, direction = (gx, gy), (math.cos(theta), math.sin(theta))
    start = [math.floor(gx / res), math.floor(gy / res)]
    cell = list(start)
    step, t_max, t_delta = [0, 0], [math.inf, math.inf], [math.inf, math.inf]
    for axis in range(2):
        if direction[axis] != 0.0:
            step[axis] = 1 if direction[axis] > 0.0 else -1
            border = (cell[axis] + (step[axis] > 0)) * res
            t_max[axis] = (border - origin[axis]) / direction[axis]
            t_delta[axis] = res / abs(direction[axis])
    while True:
        axis = 0 if t_max[0] < t_max[1] else 1
        cell[axis] += step[axis]
        t_max[axis] += t_delta[axis]
        if not (0 <= cell[0] < width and 0 <= cell[1] < height):
            return math.inf
        distance = math.hypot(cell[0] - start[0], cell[1] - start[1]) * res
        if distance > range_max:
            return math.inf
        if solid[cell[1] * width + cell[0]]:
            return distance


def _walk(solid, res, width, height, gx, gy, theta, range_max, step):
    dx, dy = math.cos(theta), math.sin(theta)
    for k in range(int(range_max / step) + 1):
        col, row = math.floor((gx + k * step * dx) / res), math.floor((gy + k * step * dy) / res)
        if not (0 <= col < width and 0 <= row < height):
            return math.inf
        if solid[row * width + col]:
            return k * step
    return math.inf


if __name__ == '__main__':
    main()
