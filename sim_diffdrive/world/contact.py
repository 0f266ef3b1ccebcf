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
Contacts of disc robots with the map's walls and with each other (no ROS imports).

Walls: a solid square grown by the radius is bounded by its faces pushed out by the radius and
quarter circles at its corners.  The centre's exact arc (_Path) is intersected in closed form
with the exposed faces and convex corners near it, the earliest entry polished by Newton steps.
Robots: each robot's track through a step (``Track``), and where two first touch
(``earliest_touch``), by conservative advancement on the distance of the centres.
"""

import math

import numpy as np
from sim_diffdrive.kinematics import integrate

TOUCH = 1e-9          # m: an overlap up to this is touching; faces reach this beyond their ends
START_SLACK = 1e-6    # m: a disc up to this deep in a wall at s = 0 touches it there
ROBOT_TOL = 1e-7      # m: robot_contact stops once the centres are this close to 2 radius
_BEHIND = 1e-12       # m: a disc this far out of a wall at s = 0 touches it
_TWO_PI = 2.0 * math.pi
# Faces (0 left, 1 right, 2 bottom, 3 top), corners (bit 0 right, 1 top) by Walls._bits.
_FACES_OF = tuple(tuple(n for n in range(4) if bits >> n & 1) for bits in range(256))
_CORNERS_OF = tuple(tuple(n for n in range(4) if bits >> n + 4 & 1) for bits in range(256))


def _sat(mask):   # a summed-area table
    return np.pad(mask.cumsum(0, dtype=np.int64).cumsum(1), ((1, 0), (1, 0)))


def _entry(a, b, c, disc, v):
    """Return the root of a s^2 + b s + c (discriminant disc > 0) where it falls along v."""
    sign = 1.0 if b >= 0.0 else -1.0
    q = -0.5 * (b + sign * math.sqrt(disc))
    return (q / a if a else math.inf) if sign * v > 0.0 else c / q


class _Path:
    """
    The centre's motion in the grid's axes, seen from its start.

    At time t the centre is p0 + X e_t + Y e_n (e_t the start heading, e_n to its left) with
    tau = tan(w t / 2), sigma = 2 tau v / w (-> v t as w -> 0), X = sigma / (1 + tau^2) and
    Y = kappa sigma X / 2 (kappa = w / v).  A line or a circle meets the path where a quadratic
    in sigma vanishes whose coefficients are smooth in kappa: the line (w = 0) is no special case
    and a wide arc loses no precision to a far-away centre.
    """

    def __init__(self, px, py, th, v, w, dt):
        self.px, self.py, self.th, self.v, self.w, self.dt = px, py, th, v, w, dt
        self.speed, self.kappa, self.slow = abs(v), w / v, 1e-12 * abs(v)
        c, s = self.et = math.cos(th), math.sin(th)
        self.period = _TWO_PI / abs(w) if w else math.inf
        # A circle smaller than _BEHIND is turning on the spot (and kappa^2 would overflow).
        self.moves = self.speed * min(dt, self.period) > _BEHIND and abs(self.kappa) < 1e12
        self.en, self.box, self.cols = (-s, c), self.arc_box(0.0, min(dt, self.period)), [None] * 4

    def arc_box(self, t0, t1):
        """Return a bounding box (x0, x1, y0, y1) of the path over [t0, t1]."""
        w, turn, (c, s) = abs(self.w), abs(self.w) * (t1 - t0), self.et
        if turn >= math.pi:      # the circle's box, within reach of the start
            rho, reach = self.v / self.w, self.speed * t1
            cx, cy, big = self.px - rho * s, self.py + rho * c, abs(rho)
            return (max(cx - big, self.px - reach), min(cx + big, self.px + reach),
                    max(cy - big, self.py - reach), min(cy + big, self.py + reach))
        # The arc lies within its sagitta, 2 R sin^2(turn / 4), of its chord.
        sag = self.speed * 2.0 * math.sin(0.25 * turn) ** 2 / w if w else 0.0
        (x0, y0, _), (x1, y1, _) = (integrate(self.px, self.py, self.th, self.v, self.w, t)
                                    for t in (t0, t1))
        return min(x0, x1) - sag, max(x0, x1) + sag, min(y0, y1) - sag, max(y0, y1) + sag

    def column(self, col):
        """
        Return (and cache) what faces need in column col: 0 left, 1 right, 2 bottom, 3 top.

        The offsets and extents across at which a face can be met (the path's box; faced, on a
        line); axis, outward sign, the outward normal along e_t and e_n, whether the motion goes
        in at once, the start's coordinates along and across the axis, e_t and e_n across it.
        """
        axis, sgn = col >> 1, 2.0 * (col & 1) - 1.0
        (c, s), box, start = self.et, self.box, (self.px, self.py)
        a, b = sgn * (c, s)[axis], sgn * (-s, c)[axis]
        rate = -a * self.v            # the depth's rate, and its acceleration if that is 0
        into = rate > self.slow or (abs(rate) <= self.slow and self.w * self.v * b < 0.0)
        lo, hi = box[2 * axis] - START_SLACK, box[2 * axis + 1] + START_SLACK
        self.cols[col] = ((lo, hi) if into or self.w else (math.inf, -math.inf),
                          (box[2 - 2 * axis] - START_SLACK, box[3 - 2 * axis] + START_SLACK),
                          (axis, sgn, a, b, into, start[axis], start[1 - axis], (s, c)[axis],
                           (c, -s)[axis]))
        return self.cols[col]

    def pieces(self, length):
        """Return [(end time, bounding box)] of pieces of the path about length long, in order."""
        dt = min(self.dt, self.period)      # the path repeats after a full turn
        turn = abs(self.w) * dt
        count = max(math.ceil(self.speed * dt / length), math.ceil(2.0 * turn))
        if count <= 1 or (turn >= math.pi and 2.0 / abs(self.kappa) <= length):
            return [(self.dt, self.box)]    # a short path, or a small loop
        step = dt / count
        return [(self.dt if n == count else n * step, self.arc_box((n - 1) * step, n * step))
                for n in range(1, count + 1)]

    def time(self, sigma):
        """Return when the path is first at sigma (inf if never)."""
        if not math.isfinite(sigma):
            return math.inf
        tau = 0.5 * self.kappa * sigma     # atan(tau) / tau by its series near 0
        t = sigma * (1.0 - tau * tau / 3.0) / self.v if abs(tau) < 1e-4 else 2.0 * math.atan(
            tau) / self.w
        return t + self.period if t < 0.0 else t


class Walls:
    """What contacts of discs of one radius with one map's solid cells need (outside: free)."""

    def __init__(self, grid, radius):
        radius = float(radius)
        if not (math.isfinite(radius) and radius > 0.0):
            raise ValueError('radius must be a positive number, not %r' % (radius,))
        self.grid, self.radius, self._res = grid, radius, grid.resolution
        self._yaw0 = grid.origin[2]
        solid = self._solid = np.asarray(grid.solid, dtype=bool)
        free = ~np.pad(solid, 1)
        left, right = solid & free[1:-1, :-2], solid & free[1:-1, 2:]
        down, up = solid & free[:-2, 1:-1], solid & free[2:, 1:-1]
        # Per cell, bits 0-3: exposed faces (left, right, bottom, top); bits 4-7: convex
        # corners (bottom-left, bottom-right, top-left, top-right).
        bits = [left, right, down, up, left & down, right & down, left & up, right & up]
        self._bits = sum(mask.astype(np.uint8) << n for n, mask in enumerate(bits))
        self._edge_sat = _sat(self._bits > 0)

    def _window(self, x0, x1, y0, y1):
        """Return the cell ranges [i0, i1) x [j0, j1) meeting a box (grid axes), maybe empty."""
        res, (height, width) = self._res, self._solid.shape
        i0, i1 = (min(max(math.floor(y / res) + k, 0), height) for k, y in ((0, y0), (1, y1)))
        j0, j1 = (min(max(math.floor(x / res) + k, 0), width) for k, x in ((0, x0), (1, x1)))
        return i0, i1, j0, j1

    def _cells(self, x0, x1, y0, y1):
        """Return (rows, cols, bits) of the wall cells meeting a box (grid axes), or None."""
        (i0, i1, j0, j1), sat = self._window(x0, x1, y0, y1), self._edge_sat
        if not sat[i1, j1] - sat[i0, j1] - sat[i1, j0] + sat[i0, j0]:
            return None
        cells = self._bits[i0:i1, j0:j1]
        ci, cj = np.nonzero(cells)
        return (ci + i0).tolist(), (cj + j0).tolist(), cells[ci, cj].tolist()

    def contact(self, x, y, yaw, linear, angular, dt):
        """
        Return the earliest time in [0, dt] the disc touches a solid cell, or None.

        The centre follows the exact arc from (x, y, yaw) (map frame) under constant (linear,
        angular); then its distance to the nearest solid square is the radius to about 1e-13 m.
        Touching at s = 0 (out by up to 1e-12 m, in by up to START_SLACK) gives 0.0 only if the
        motion goes in; a path going in by no more than TOUCH (grazing) is no contact.
        """
        px, py = self.grid.to_grid(float(x), float(y))
        th, v, w, dt = float(yaw) - self._yaw0, float(linear), float(angular), float(dt)
        if not all(map(math.isfinite, (px, py, th, v, w, dt))):
            raise ValueError('contact needs a finite pose, command and dt')
        if not dt > 0.0 or v == 0.0:
            return None
        path = _Path(px, py, th, v, w, dt)
        r, res, grow = self.radius, self._res, self.radius + 2.0 * TOUCH
        near = tuple(side + grow * sign for side, sign in zip(path.box, (-1, 1, -1, 1)))
        found = self._cells(*near)
        if not found:
            return None
        best, feature, seen = math.inf, None, set()
        # Piece by piece along the path: a cell first met in a later piece is met later.
        pieces = path.pieces(max(2.0 * r, res))
        for end, (x0, x1, y0, y1) in pieces:
            if len(pieces) > 1:
                found = self._cells(x0 - grow, x1 + grow, y0 - grow, y1 + grow) or ((),)
            for i, j, bits in zip(*found):
                if (i, j) in seen:
                    continue
                seen.add((i, j))
                xa, xb, ya, yb = j * res, (j + 1) * res, i * res, (i + 1) * res
                for col in _FACES_OF[bits]:
                    (lo, hi), across, spec = path.cols[col] or path.column(col)
                    pos = (xa - r, xb + r, ya - r, yb + r)[col]
                    side = (ya, yb) if col < 2 else (xa, xb)
                    if lo <= pos <= hi and side[0] <= across[1] and side[1] >= across[0]:
                        t = self._face(path, spec, pos, *side)
                        if t < best:
                            best, feature = t, spec[:2] + (pos,)
                for n in _CORNERS_OF[bits]:
                    cx, cy = (xb if n & 1 else xa), (yb if n & 2 else ya)
                    if near[0] <= cx <= near[1] and near[2] <= cy <= near[3]:
                        t = self._corner(path, cx, cy)
                        if t < best:
                            best, feature = t, (cx, cy)
            if best <= end:
                break
        if best > dt:
            return None
        return 0.0 if best < 0.0 else self._refine(path, best, feature)

    def _face(self, path, col, pos, lo, hi):
        """Return the entry time through a face pushed out to pos (-1.0: at once; inf: never)."""
        axis, sgn, a, b, into, pn, pt, across_t, across_n = col
        depth0 = sgn * (pos - pn)              # how far the start is in past the face
        if into and -_BEHIND <= depth0 <= START_SLACK and lo - TOUCH <= pt <= hi + TOUCH:
            return -1.0
        if not path.moves:
            return math.inf
        k = path.kappa
        if k == 0.0:
            if not -a * path.v > path.slow:
                return math.inf
            sigma = depth0 / a
        else:
            # The whole circle must go in past the face by more than TOUCH (no cancellation).
            bend = b * math.copysign(1.0, k)
            deep = (a * a / (1.0 + bend) if bend > 0.0 else 1.0 - bend) / abs(k) + depth0
            disc = a * a + k * depth0 * (2.0 * b - k * depth0)
            if not (deep > TOUCH and disc > 0.0):
                return math.inf
            sigma = _entry(0.5 * b * k - 0.25 * k * k * depth0, a, -depth0, disc, path.v)
        t = path.time(sigma)
        if not 0.0 <= t <= path.dt:
            return math.inf
        x = sigma / (1.0 + (0.5 * k * sigma) ** 2)        # the crossing from the start: X, Y
        across = pt + x * across_t + 0.5 * k * sigma * x * across_n
        return t if lo - TOUCH <= across <= hi + TOUCH else math.inf

    def _corner(self, path, cx, cy):
        """Return the entry time into a corner's disc (-1.0: at once; inf: never)."""
        r, k, v = self.radius, path.kappa, path.v
        rx, ry = cx - path.px, cy - path.py
        d0 = math.hypot(rx, ry)
        x = rx * path.et[0] + ry * path.et[1]         # the corner along e_t and e_n
        y = rx * path.en[0] + ry * path.en[1]
        if r - START_SLACK <= d0 <= r + _BEHIND and d0 > 0.0:
            rate = -v * x / d0                         # of the distance, and its curvature
            if rate < -path.slow or (abs(rate) <= path.slow and v * v < path.w * v * y):
                return -1.0
        if not path.moves:
            return math.inf
        q = (d0 - r) * (d0 + r)
        # A quarter of the discriminant; r^2 - (d - R)^2 from it (d: the corner's distance from
        # the circle's centre, R its radius) is about 2 r times how deep the path goes.
        quarter = (r - y) * (r + y) + k * q * (y - 0.25 * k * q)
        den = (1.0 + math.hypot(1.0 - k * y, k * x)) ** 2 - (r * k) ** 2
        if not (quarter > 0.0 and den > 0.0 and 4.0 * quarter > 2.0 * r * TOUCH * den):
            return math.inf
        t = path.time(_entry(1.0 - k * y + 0.25 * k * k * q, -2.0 * x, q, 4.0 * quarter, path.v))
        return t if 0.0 <= t <= path.dt else math.inf

    def _refine(self, path, t, feature):
        """Newton steps on the exact distance to the feature hit first; t stays in [0, dt]."""
        for _ in range(4):
            x, y, heading = integrate(path.px, path.py, path.th, path.v, path.w, t)
            vx, vy = path.v * math.cos(heading), path.v * math.sin(heading)
            if len(feature) == 3:
                axis, sgn, pos = feature
                g, dg = sgn * (pos - (x, y)[axis]), -sgn * (vx, vy)[axis]
            else:
                dx, dy = x - feature[0], y - feature[1]
                d = math.hypot(dx, dy)
                g, dg = self.radius - d, -(dx * vx + dy * vy) / d
            if abs(g) <= 1e-14 or not dg > 0.0:
                break
            t = min(max(t - g / dg, 0.0), path.dt)
        return t

    def overlaps(self, x, y):
        """Whether a disc at (x, y) (map frame) overlaps a solid cell by more than TOUCH."""
        gx, gy = self.grid.to_grid(float(x), float(y))
        r, res = self.radius, self._res
        i0, i1, j0, j1 = self._window(gx - r, gx + r, gy - r, gy + r)
        ci, cj = np.nonzero(self._solid[i0:i1, j0:j1])
        dx = np.maximum(np.maximum((cj + j0) * res - gx, gx - (cj + j0 + 1) * res), 0.0)
        dy = np.maximum(np.maximum((ci + i0) * res - gy, gy - (ci + i0 + 1) * res), 0.0)
        return bool(np.any(np.hypot(dx, dy) < r - TOUCH))


def robot_contact(radius, a, b, dt):
    """
    Return the earliest time in [0, dt] two discs of radius touch while approaching, or None.

    a, b: (x, y, yaw, linear, angular), each on its exact arc.  A step goes to the first root of
    a lower bound of the distance (its value, rate, and |va wa| + |vb wb|), never past a touch;
    it stops within ROBOT_TOL.  Touching (or overlapping) at s = 0 counts only if approaching.
    """
    a, b = tuple(map(float, a)), tuple(map(float, b))
    (_, _, tha, va, wa), (_, _, thb, vb, wb) = a, b
    acc, t = abs(va * wa) + abs(vb * wb), 0.0
    for _ in range(100000):
        pa, pb = integrate(*a, t), integrate(*b, t)
        qx, qy = pa[0] - pb[0], pa[1] - pb[1]
        dqx = va * math.cos(tha + wa * t) - vb * math.cos(thb + wb * t)
        dqy = va * math.sin(tha + wa * t) - vb * math.sin(thb + wb * t)
        d = math.hypot(qx, qy)
        f = d - 2.0 * radius
        rate = (qx * dqx + qy * dqy) / d if d > 0.0 else -math.hypot(dqx, dqy)
        if f <= ROBOT_TOL and rate < 0.0:
            return t
        f = max(f, ROBOT_TOL)       # touching, not approaching: step on as if just apart
        if rate >= 0.0 and acc == 0.0:
            return None             # parting on straight lines, for good
        root = math.sqrt(rate * rate + 2.0 * acc * f)
        t += 2.0 * f / (root - rate) if rate < 0.0 else (rate + root) / acc
        if t > dt:
            return None
    return None


def overlaps_robot(radius, x1, y1, x2, y2):
    """Whether two discs of radius centred at (x1, y1), (x2, y2) overlap by more than TOUCH."""
    return math.hypot(x1 - x2, y1 - y2) < 2.0 * radius - TOUCH


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
