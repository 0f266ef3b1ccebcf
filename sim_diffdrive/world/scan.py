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

"""The simulated laser scan: every beam of every robot cast at once, exactly (no ROS imports)."""

import math

import numpy as np

# A crossing within SNAP cells of another grid line is on it (a corner, a beam along a line):
# it then touches the cells on both sides of that line, so no beam leaks through a diagonal gap.
SNAP = 1e-9
RAYS, BATCH = 16384, 16  # rays cast together, crossings of each axis looked at together


def beam_angles(beams):
    """Return the beams' angles to the heading: -pi + k * 2pi/beams, k = 0..beams-1."""
    beams = int(beams)
    if beams < 1:
        raise ValueError('beams must be at least 1, not %d' % beams)
    return -math.pi + np.arange(beams) * (2.0 * math.pi / beams)


def pad_solid(grid):
    """Return grid.solid with a free border, flat: cast()'s indices are clipped onto it."""
    return np.pad(grid.solid, 1).ravel()


def cast(grid, x, y, yaw, angles, range_max, radius=0.0, discs=True, padded=None):
    """
    Return the range [m] of every beam of every robot: float64 of shape (robots, beams).

    A beam ends where it first touches a solid cell of grid (None: no map; outside it is free;
    the exact crossing of its boundary, a corner counts) or another robot's disc of radius
    (with discs).  A scanner inside either sees 0.0; no return within range_max is +inf (REP
    117).  padded: pad_solid(grid), if the caller keeps it.
    """
    x, y, yaw = (np.atleast_1d(np.asarray(v, dtype=np.float64)) for v in (x, y, yaw))
    angles = np.atleast_1d(np.asarray(angles, dtype=np.float64))
    if not 0.0 < range_max < math.inf:
        raise ValueError('range_max must be a positive finite number, not %r' % (range_max,))
    ranges = np.full((x.size, angles.size), np.inf)
    if grid is not None and ranges.size:
        gx, gy = grid.to_grid(x, y)
        gx, gy = np.repeat(gx, angles.size), np.repeat(gy, angles.size)
        theta = ((yaw[:, np.newaxis] + angles) - grid.origin[2]).ravel()
        padded = pad_solid(grid) if padded is None else padded
        crossings = math.ceil(range_max / grid.resolution) + 2
        cells = ranges.reshape(-1)
        size = BATCH * min(RAYS, cells.size)
        work = (np.empty((3, size)), np.empty(size, np.intp), np.empty((2, size), bool))
        for start in range(0, cells.size, RAYS):
            rays = slice(start, start + RAYS)
            cells[rays] = _cast_cells(grid, padded, work, gx[rays], gy[rays], theta[rays],
                                      crossings, range_max)
    if discs and radius > 0.0 and x.size > 1:
        _cast_discs(ranges, x, y, yaw, angles, float(radius), range_max)
    ranges[ranges > range_max] = np.inf
    return ranges


def _cast_cells(grid, padded, work, gx, gy, theta, crossings, range_max):
    """Return each ray's distance to its first solid cell: crossings looked at BATCH by BATCH."""
    res, width, height = grid.resolution, grid.width, grid.height
    dx, dy = np.cos(theta), np.sin(theta)
    col0 = np.clip(np.floor(gx / res + SNAP), -1, width)
    row0 = np.clip(np.floor(gy / res + SNAP), -1, height)
    inside = padded[((row0 + 1) * (width + 2) + col0 + 1).astype(np.intp)]
    axes = (_Lines(work, padded, res, gx, gy, dx, dy, width, height, 1, width + 2),
            _Lines(work, padded, res, gy, gx, dy, dx, height, width, width + 2, 1))
    best = np.where(inside, 0.0, np.inf)
    last = [np.where(inside, np.inf, -np.inf) for _ in axes]
    for k0 in range(0, crossings, BATCH):
        k = np.arange(k0, min(k0 + BATCH, crossings), dtype=np.float64)
        busy = False
        for lines, seen in zip(axes, last):
            rays = np.flatnonzero(seen < np.minimum(best, range_max))  # may see nearer yet
            if rays.size:
                busy = True
                hit, seen[rays] = lines.first_hit(rays, k)
                best[rays] = np.minimum(best[rays], hit)
        if not busy:
            break
    return best


class _Lines:
    """
    The crossings of one axis' grid lines a = n * res by rays, n = first + step * k.

    At a crossing a ray enters the cell n (n - 1 going back) along a, and the one or two cells
    along b whose closed span holds the crossing point (two on a line: a corner, or a beam
    along a line).  Cells are indexed in the padded grid (a free border of one cell).
    """

    def __init__(self, work, padded, res, ga, gb, da, db, size_a, size_b, stride_a, stride_b):
        self.work, self.padded, self.res, self.ga = work, padded, res, ga
        self.sizes, self.strides = (size_a, size_b), (stride_a, stride_b)
        forward = da > 0.0
        self.step = np.where(forward, 1.0, -1.0)
        self.first = np.where(forward, np.ceil(ga / res - SNAP), np.floor(ga / res + SNAP))
        # The padded index of the cell entered at crossing 0 along a, and per crossing.
        self.cell = (self.first + np.where(forward, 1.0, 0.0)) * stride_a
        self.inc = self.step * stride_a
        self.along = np.where(da == 0.0, 1.0, da)
        self.never = da == 0.0
        # A line within SNAP behind the ray (snapped to, as the one it starts on) is crossed
        # where it starts: divided by a component as small as 1e-16 (a beam along the line),
        # that rounding error would put the crossing metres behind it.
        t0 = np.maximum((self.first * res - ga) / self.along, 0.0)
        self.b0 = (gb + t0 * db) / res + (1.0 + SNAP)  # padded b at crossing 0, plus SNAP
        self.db = np.where(self.never, 0.0, db) * self.step / self.along  # b per crossing

    def first_hit(self, rays, k):
        """Return the distance to the first solid crossing in k and to the last one in k."""
        (size_a, size_b), (stride_a, stride_b) = self.sizes, self.strides
        size, shape = k.size * rays.size, (k.size, rays.size)  # no fresh pages every batch
        cell, b, whole = (buffer[:size].reshape(shape) for buffer in self.work[0])
        index = self.work[1][:size].reshape(shape)
        hit, on_line = (buffer[:size].reshape(shape) for buffer in self.work[2])
        np.multiply(k[:, None], self.inc[rays], out=cell)
        cell += self.cell[rays]
        np.clip(cell, 0.0, (size_a + 1.0) * stride_a, out=cell)
        np.multiply(k[:, None], self.db[rays], out=b)
        b += self.b0[rays]
        np.clip(b, 0.5, size_b + 1.5, out=b)  # beyond the map: the border's middle
        np.floor(b, out=whole)
        b -= whole
        np.less(b, 2.0 * SNAP, out=on_line)  # then the cell on the other side of the line too
        whole *= stride_b
        cell += whole
        np.copyto(index, cell, casting='unsafe')
        np.take(self.padded, index, out=hit, mode='clip')
        if on_line.any():
            where = np.nonzero(on_line)
            hit[where] |= self.padded[index[where] - stride_b]
        # The first hit's k, k.size if none: hits weighted k.size .. 1, the largest (no argmax).
        weighted = on_line.view(np.uint8)
        np.multiply(hit, np.arange(k.size, 0, -1, dtype=np.uint8)[:, None], out=weighted)
        j = k.size - weighted.max(axis=0).astype(np.intp)
        found = (j < k.size) & ~self.never[rays]
        first, step, along, ga = self.first[rays], self.step[rays], self.along[rays], self.ga[rays]
        t = np.maximum(((first + step * (k[0] + j)) * self.res - ga) / along, 0.0)
        last = ((first + step * k[-1]) * self.res - ga) / along
        return np.where(found, t, np.inf), np.where(self.never[rays], np.inf, last)


def _cast_discs(ranges, x, y, yaw, angles, radius, reach):
    """Lower ranges to each beam's distance to another robot's disc (only beams that span it)."""
    robots, beams = ranges.shape
    turn, wrapped = 2.0 * math.pi, np.mod(angles, 2.0 * math.pi)  # in one turn: around sorted
    order = np.argsort(wrapped, kind='stable')
    ordered = wrapped[order]
    around = np.concatenate([ordered - turn, ordered, ordered + turn])
    i, j = np.nonzero(~np.eye(robots, dtype=bool))  # scanner i, disc j
    wx, wy = x[j] - x[i], y[j] - y[i]
    c = wx * wx + wy * wy - radius * radius
    ranges[i[c <= 0.0]] = 0.0
    distance = np.hypot(wx, wy)
    near = (c > 0.0) & (distance <= reach + radius)
    i, wx, wy, c, distance = i[near], wx[near], wy[near], c[near], distance[near]
    half = np.arcsin(np.minimum(radius / distance, 1.0)) + SNAP
    bearing = np.arctan2(wy, wx) - yaw[i]
    bearing = ordered[0] + np.mod(bearing - ordered[0], turn)
    low = np.searchsorted(around, bearing - half, 'left')
    count = np.searchsorted(around, bearing + half, 'right') - low
    pair = np.repeat(np.arange(count.size), count)
    beam = order[(low[pair] + np.arange(pair.size) - np.repeat(np.cumsum(count) - count, count))
                 % beams]
    scanner, theta, c = i[pair], yaw[i[pair]] + angles[beam], c[pair]
    b = wx[pair] * np.cos(theta) + wy[pair] * np.sin(theta)
    disc = b * b - c
    with np.errstate(invalid='ignore', divide='ignore'):
        # The nearer root b - sqrt(disc), as c / (b + sqrt(disc)): no cancellation.
        t = np.where((disc >= 0.0) & (b > 0.0), c / (b + np.sqrt(np.abs(disc))), np.inf)
    np.minimum.at(ranges, (scanner, beam), t)


class Scanner:
    """A 2-D laser scanner over a GridMap for all robots, LaserScan's fields; seeded noise."""

    def __init__(self, grid, beams=360, range_min=0.12, range_max=3.5, noise_std=0.0, seed=0,
                 radius=0.0):
        if not (0.0 <= range_min < range_max and noise_std >= 0.0 and radius >= 0.0):
            raise ValueError('need 0 <= range_min < range_max, noise_std >= 0, radius >= 0; not '
                             '%r, %r, %r, %r' % (range_min, range_max, noise_std, radius))
        self.grid = grid
        self.angles = beam_angles(beams)
        self.angle_min, self.angle_increment = -math.pi, 2.0 * math.pi / len(self.angles)
        self.angle_max = self.angle_min + (len(self.angles) - 1) * self.angle_increment
        self.range_min, self.range_max = float(range_min), float(range_max)
        self.noise_std, self.radius = float(noise_std), float(radius)
        self.seed = seed
        self._padded = pad_solid(grid) if grid is not None else None

    def scan(self, x, y, yaw, stamp_ns=0):
        """
        Return cast() plus noise: float32 (robots, beams), -inf/+inf out of range (REP 117).

        The noise is drawn from (seed, stamp_ns): a scan's is the same whenever it is asked for,
        however many scans went before (a simulator that ran before a node joined).
        """
        ranges = cast(self.grid, x, y, yaw, self.angles, self.range_max, self.radius,
                      padded=self._padded)
        if self.noise_std > 0.0:
            rng = np.random.default_rng((self.seed, stamp_ns))
            noise = rng.normal(0.0, self.noise_std, ranges.shape)
            finite = np.isfinite(ranges)
            ranges[finite] += noise[finite]
        ranges[ranges < self.range_min] = -np.inf
        ranges[ranges > self.range_max] = np.inf
        return ranges.astype(np.float32)
