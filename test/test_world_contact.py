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

"""Contacts of disc robots with walls and with each other against closed forms (no ROS graph)."""

import math

from hypothesis import assume
from hypothesis import given
from hypothesis import settings
from hypothesis import strategies as st
import numpy as np
import pytest
from sim_diffdrive.kinematics import integrate
from sim_diffdrive.world.contact import overlaps_robot
from sim_diffdrive.world.contact import robot_contact
from sim_diffdrive.world.contact import Walls
from sim_diffdrive.world.grid import GridMap

R = 0.105          # the simulator's default robot radius
RES = 0.05
LO, HI = 0.75, 1.25  # the block of _block(): solid for x and y in [LO, HI] (grid axes)


def _block(origin=(0.0, 0.0, 0.0), size=40, lo=15, hi=25):
    """Return a size x size map, free but for the square of cells [lo, hi) x [lo, hi)."""
    rows = ['.' * lo + '#' * (hi - lo) + '.' * (size - hi) if lo <= size - 1 - k < hi
            else '.' * size for k in range(size)]
    return GridMap.from_rows(rows, resolution=RES, origin=origin)


BLOCK = _block()
ROOM = GridMap.from_rows([
    '##############################',
    '#............................#',
    '#....##..............#.......#',
    '#....##..............#.......#',
    '#....................#.......#',
    '#..........#.........#.......#',
    '#..........................###',
    '#............................#',
    '#.....######.................#',
    '#.....#......................#',
    '#.....#.............##.......#',
    '#...................##.......#',
    '#............................#',
    '#.........#..#...............#',
    '#............................#',
    '#............................#',
    '#....#.......................#',
    '#..............#######.......#',
    '#............................#',
    '##############################',
], resolution=RES)


def _distance(grid, x, y):
    """Return the distance from map points to the nearest solid square, by brute force."""
    rows, cols = np.nonzero(grid.solid)
    gx, gy = grid.to_grid(np.asarray(x, dtype=float)[..., None],
                          np.asarray(y, dtype=float)[..., None])
    dx = np.maximum(np.maximum(cols * RES - gx, gx - (cols + 1) * RES), 0.0)
    dy = np.maximum(np.maximum(rows * RES - gy, gy - (rows + 1) * RES), 0.0)
    return np.hypot(dx, dy).min(-1)


def _track(x, y, yaw, linear, angular, times):
    """Return the centre's x and y at each time along the exact arc."""
    points = [integrate(x, y, yaw, linear, angular, t)[:2] for t in times]
    return np.array([p[0] for p in points]), np.array([p[1] for p in points])


def _gap_at(grid, pose, command, s):
    x, y, _ = integrate(*pose, *command, s)
    return float(_distance(grid, x, y)) - R


def _first_touch(grid, pose, command, dt, samples=20001):
    """Return the first time the disc's gap to the walls is 0, by sampling and bisection."""
    times = np.linspace(0.0, dt, samples)
    gaps = _distance(grid, *_track(*pose, *command, times)) - R
    hits = np.nonzero(gaps <= 0.0)[0]
    if not hits.size:
        return None
    lo, hi = times[hits[0] - 1], times[hits[0]]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if _gap_at(grid, pose, command, mid) <= 0.0 else (mid, hi)
    return hi


@pytest.mark.parametrize('pose, command, face', [
    ((0.3, 1.0, 0.0), (0.5, 0.0), LO - R),                # at the left face
    ((1.6, 0.9, math.pi), (0.25, 0.0), HI + R),           # at the right face
    ((1.0, 0.2, 0.5 * math.pi), (1.0, 0.0), LO - R),      # from below
    ((0.8, 1.7, -0.5 * math.pi), (0.3, 0.0), HI + R),     # from above
    ((0.3, 1.2, math.pi), (-0.5, 0.0), LO - R),           # backwards into the left face
])
def test_straight_at_a_face_stops_radius_from_it(pose, command, face):
    along = 1 if abs(math.sin(pose[2])) > 0.5 else 0
    expected = abs(face - pose[along]) / abs(command[0])
    s = Walls(BLOCK, R).contact(*pose, *command, 2.0)
    assert s == pytest.approx(expected, abs=1e-12)
    end = integrate(*pose, *command, s)
    assert abs(abs(end[along] - (LO if face < LO else HI)) - R) <= 1e-9
    assert abs(_gap_at(BLOCK, pose, command, s)) <= 1e-9


@pytest.mark.parametrize('corner, heading', [
    ((LO, LO), 0.25 * math.pi), ((HI, LO), 0.75 * math.pi),
    ((HI, HI), -0.75 * math.pi), ((LO, HI), -0.25 * math.pi)])
def test_diagonal_at_a_corner_stops_radius_from_the_corner(corner, heading):
    a = 0.4
    pose = (corner[0] - a * math.cos(heading), corner[1] - a * math.sin(heading), heading)
    s = Walls(BLOCK, R).contact(*pose, 0.8, 0.0, 1.0)
    assert s == pytest.approx((a - R) / 0.8, abs=1e-12)
    x, y, _ = integrate(*pose, 0.8, 0.0, s)
    assert abs(math.hypot(x - corner[0], y - corner[1]) - R) <= 1e-9


@pytest.mark.parametrize('v, w', [(0.5, 0.5), (0.2, 0.4), (-0.3, -0.3), (1.0, 2.0)])
def test_arc_into_a_face_solves_the_closed_form(v, w):
    # Heading +x (or -x backwards), moving +x: x(t) = x0 + |v/w| sin(|w| t).
    x0, y0 = 0.4, 1.0
    yaw = 0.0 if v > 0 else math.pi
    rho = abs(v / w)
    expected = math.asin((LO - R - x0) / rho) / abs(w)
    s = Walls(BLOCK, R).contact(x0, y0, yaw, v, w, 2.0)
    assert s == pytest.approx(expected, abs=1e-11)
    x, y, _ = integrate(x0, y0, yaw, v, w, s)
    assert LO < y < HI and abs(x - (LO - R)) <= 1e-9
    assert abs(_gap_at(BLOCK, (x0, y0, yaw), (v, w), s)) <= 1e-9


@pytest.mark.parametrize('y0', [LO - R - 1e-6, LO - R - 0.02, LO - R])
@pytest.mark.parametrize('x0, yaw', [(0.2, 0.0), (1.8, math.pi), (1.0, 0.0)])
def test_grazing_along_a_face_is_no_contact(y0, x0, yaw):
    # Along the bottom face at or beyond the radius, past both corners or from beside it.
    assert Walls(BLOCK, R).contact(x0, y0, yaw, 0.7, 0.0, 3.0) is None
    assert Walls(BLOCK, R).contact(x0, y0, yaw, -0.7, 0.0, 3.0) is None


def test_resting_against_a_wall_may_leave_or_turn_but_not_push():
    walls = Walls(BLOCK, R)
    x0, y0 = LO - R, 1.0          # touching the left face
    assert walls.contact(x0, y0, 0.0, 0.3, 0.0, 1.0) == 0.0                # into it
    assert walls.contact(x0, y0, 0.0, -0.3, 0.0, 1.0) is None              # backing away
    assert walls.contact(x0, y0, math.pi, 0.3, 0.0, 1.0) is None           # driving away
    assert walls.contact(x0, y0, 0.0, 0.0, 1.0, 5.0) is None               # turning on the spot
    assert walls.contact(x0, y0, 0.5 * math.pi, 0.3, 0.0, 0.5) is None     # along it
    assert walls.contact(x0, y0, 0.5 * math.pi, 0.3, 1.0, 0.5) is None     # curving away
    assert walls.contact(x0, y0, 0.5 * math.pi, 0.3, -1.0, 0.5) == 0.0     # curving into it
    assert walls.contact(x0, y0, 0.3, 0.3, 0.0, 0.5) == 0.0                # slanting into it
    assert walls.contact(x0 + 1e-7, y0, 0.0, 0.3, 0.0, 1.0) == 0.0         # a hair inside
    assert walls.contact(x0 + 1e-7, y0, math.pi, 0.3, 0.0, 1.0) is None
    corner = LO - R / math.sqrt(2.0)   # touching the bottom-left corner diagonally
    assert walls.contact(corner, corner, 0.25 * math.pi, 0.3, 0.0, 1.0) == 0.0
    assert walls.contact(corner, corner, -0.75 * math.pi, 0.3, 0.0, 1.0) is None
    assert walls.contact(corner, corner, 0.75 * math.pi, 0.3, 0.0, 1.0) is None


def test_turning_on_the_spot_never_touches():
    walls = Walls(BLOCK, R)
    for x in (LO - R, LO - R + 1e-3, 1.0):
        assert walls.contact(x, 1.0, 0.0, 0.0, 3.0, 10.0) is None
    assert walls.contact(0.3, 1.0, 0.0, 0.5, 0.0, 0.0) is None   # no time, no motion


@pytest.mark.parametrize('w', [1e-15, 1e-12, 7e-12, 9e-12, 1e-10, 1e-9, 1e-7, 1e-5, 1e-3, 0.1])
def test_small_turn_rates_join_the_straight_line(w):
    x0, v = 0.3, 1.0
    gap = LO - R - x0
    z = gap * w / v
    # The closed form asin(z)/w, written without its 0/0 as w -> 0.
    expected = gap / v * (1.0 + z * z / 6.0 if z < 1e-4 else math.asin(z) / z)
    walls = Walls(BLOCK, R)
    straight = walls.contact(x0, 1.0, 0.0, v, 0.0, 1.0)
    s = walls.contact(x0, 1.0, 0.0, v, w, 1.0)
    assert s == pytest.approx(expected, abs=1e-12)
    if w <= 1e-9:
        assert abs(s - straight) <= 1e-9
    assert abs(_gap_at(BLOCK, (x0, 1.0, 0.0), (v, w), s)) <= 1e-9


@pytest.mark.parametrize('gap', [1e-11, 1.5e-8, 1e-6, 0.2])
@pytest.mark.parametrize('w', [1e-9, -1e-7, 1e-5])
def test_wide_arcs_keep_their_precision(gap, w):
    # A circle of radius 1e5..1e9 m: solved about the start, not about its far-away centre.
    x0, yaw = LO - R - gap, 0.3
    s = Walls(BLOCK, R).contact(x0, 1.0, yaw, 0.8, w, 2.0)
    assert s > 0.0 and abs(_gap_at(BLOCK, (x0, 1.0, yaw), (0.8, w), s)) <= 1e-12
    assert s == pytest.approx(gap / (0.8 * math.cos(yaw)), rel=1e-4)


def test_a_small_loop_beside_a_wall():
    # A circle of 1 cm radius whose right side reaches 5 mm into the left face's offset.
    pose, command = (LO - R - 0.015, 1.0, 0.5 * math.pi), (0.05, -5.0)
    s = Walls(BLOCK, R).contact(*pose, *command, 2.0)
    assert s == pytest.approx(_first_touch(BLOCK, pose, command, 2.0), abs=1e-9)
    assert Walls(BLOCK, R).contact(LO - R - 0.021, 1.0, 0.5 * math.pi, 0.05, -5.0, 9.0) is None


@pytest.mark.parametrize('pose, command', [
    ((0.851, 0.289, 1.551), (0.504, 0.0)),     # straight up between the walls, 0.56 m
    ((0.84, 0.5, 0.777), (0.569, 2.376)),      # an arc
    ((0.884, 0.355, -1.454), (-0.78, -0.297)),  # backwards on an arc
    ((0.79, 0.65, 0.0), (0.4, -4.7)),          # three quarters of a loop first
])
def test_long_steps_cross_many_cells(pose, command):
    dt = 2.0
    assert not Walls(ROOM, R).overlaps(pose[0], pose[1])
    s = Walls(ROOM, R).contact(*pose, *command, dt)
    expected = _first_touch(ROOM, pose, command, dt)
    assert s > 0.5 and s == pytest.approx(expected, abs=1e-9)
    assert abs(_gap_at(ROOM, pose, command, s)) <= 1e-9


def test_a_rotated_origin_is_followed():
    yaw0 = 0.5
    grid = _block(origin=(1.0, -2.0, yaw0))
    walls = Walls(grid, R)
    # Start 0.4 m before the block's left face in the grid's axes, driving along grid x.
    x, y = grid.from_grid(0.4, 1.0)
    s = walls.contact(x, y, yaw0, 0.5, 0.0, 2.0)
    assert s == pytest.approx((LO - R - 0.4) / 0.5, abs=1e-12)
    assert abs(_gap_at(grid, (x, y, yaw0), (0.5, 0.0), s)) <= 1e-9
    # The same arc as in the grid's own frame.
    arc = walls.contact(x, y, yaw0 + 0.2, 0.5, 0.7, 2.0)
    assert arc == pytest.approx(Walls(BLOCK, R).contact(0.4, 1.0, 0.2, 0.5, 0.7, 2.0), abs=1e-12)
    # Straight along grid x beside the block, 1e-4 m clear of it: no contact.
    x, y = grid.from_grid(0.2, LO - R - 1e-4)
    assert walls.contact(x, y, yaw0, 0.5, 0.0, 4.0) is None
    assert walls.overlaps(*grid.from_grid(1.0, LO - R + 1e-6))
    assert not walls.overlaps(*grid.from_grid(1.0, LO - R - 1e-6))


def test_outside_the_map_is_free():
    walls = Walls(BLOCK, R)
    assert walls.contact(-1.0, -1.0, 0.0, 1.0, 0.0, 1.0) is None      # all outside
    assert walls.contact(1.0, 1.9, 0.5 * math.pi, 1.0, 0.0, 1.0) is None   # driving off it
    assert walls.contact(-0.5, 1.0, 0.0, 1.0, 0.0, 2.0) == pytest.approx(LO - R + 0.5, abs=1e-12)


def test_placements():
    walls = Walls(BLOCK, R)
    assert not walls.overlaps(LO - R, 1.0)                 # touching
    assert not walls.overlaps(LO - R + 0.5e-9, 1.0)        # within the tolerance
    assert walls.overlaps(LO - R + 1e-6, 1.0)
    assert not walls.overlaps(LO - R - 1e-6, 1.0)
    assert walls.overlaps(1.0, 1.0)                        # inside the block
    corner = LO - R / math.sqrt(2.0)
    assert walls.overlaps(corner + 1e-6, corner + 1e-6)
    assert not walls.overlaps(corner - 1e-6, corner - 1e-6)
    assert not walls.overlaps(-5.0, 3.0)                   # far outside the map
    edge = Walls(GridMap.from_rows(['#.', '..']), R)       # a wall cell at the map's edge
    assert edge.overlaps(-R + 1e-6, 0.07) and not edge.overlaps(-R - 1e-6, 0.07)


def test_robots_head_on():
    for v1, v2 in ((0.5, 0.5), (1.0, 0.25), (0.3, 0.0)):
        a, b = (0.0, 0.0, 0.0, v1, 0.0), (1.0, 0.0, math.pi, v2, 0.0)
        s = robot_contact(R, a, b, 5.0)
        assert s == pytest.approx((1.0 - 2.0 * R) / (v1 + v2), abs=1e-6 / (v1 + v2))
        gap = math.dist(integrate(*a, s)[:2], integrate(*b, s)[:2]) - 2.0 * R
        assert -1e-12 <= gap <= 1e-6
    assert robot_contact(R, (0.0, 0.0, 0.0, 0.5, 0.0), (1.0, 0.0, math.pi, 0.5, 0.0), 0.5) is None


def test_one_robot_standing():
    a, b = (0.0, 0.0, 0.3, 0.4, 0.0), (math.cos(0.3), math.sin(0.3), 2.0, 0.0, 1.0)
    assert robot_contact(R, a, b, 5.0) == pytest.approx((1.0 - 2.0 * R) / 0.4, abs=1e-5)
    assert robot_contact(R, b, a, 5.0) == pytest.approx((1.0 - 2.0 * R) / 0.4, abs=1e-5)


def _robot_gaps(a, b, times):
    xa, ya = _track(*a, times)
    xb, yb = _track(*b, times)
    return np.hypot(xa - xb, ya - yb) - 2.0 * R


@pytest.mark.parametrize('a, b', [
    ((0.0, 0.0, 1.0, 0.9, -1.8), (0.3, -0.4, 1.5, 0.4, -1.7)),
    ((0.0, 0.0, -0.8, 0.9, -2.4), (-0.7, -0.9, 0.0, 0.2, 0.2)),
    ((0.0, 0.0, -0.1, 0.7, 1.8), (-0.7, 0.9, 2.2, -0.5, 0.8)),  # one backwards
    ((0.0, 0.0, 2.6, 0.3, 0.6), (0.0, 0.5, -2.7, 0.3, 0.7)),
])
def test_robots_on_arcs(a, b):
    dt = 4.0
    times = np.linspace(0.0, dt, 40001)
    gaps = _robot_gaps(a, b, times)
    first = np.nonzero(gaps <= 0.0)[0][0]
    lo, hi = times[first - 1], times[first]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if _robot_gaps(a, b, [mid])[0] <= 0.0 else (mid, hi)
    s = robot_contact(R, a, b, dt)
    assert 0.0 <= _robot_gaps(a, b, [s])[0] <= 1e-6
    assert s > 0.8 and s == pytest.approx(hi, abs=1e-5)


def test_catching_up_on_one_circle():
    # Both on the circle of radius 0.25 about (0, 0.25), b a quarter turn ahead and half as fast:
    # they touch when the chord between them, 2 (0.25) sin(gap / 2), is 2 R.
    a, b = (0.0, 0.0, 0.0, 0.6, 2.4), (0.25, 0.25, 0.5 * math.pi, 0.3, 1.2)
    expected = (0.5 * math.pi - 2.0 * math.asin(R / 0.25)) / 1.2
    assert robot_contact(R, a, b, 2.0) == pytest.approx(expected, abs=1e-6)
    assert robot_contact(R, b, a, 2.0) == pytest.approx(expected, abs=1e-6)


def test_separating_and_touching_robots():
    apart = (2.0 * R, 0.0, 0.0, 0.3, 0.0)
    assert robot_contact(R, (0.0, 0.0, math.pi, 0.5, 0.0), (3.0, 0.0, 0.0, 0.5, 0.0), 9.0) is None
    assert robot_contact(R, (0.0, 0.0, 0.0, 0.0, 0.0), apart, 9.0) is None     # touching, leaving
    assert robot_contact(R, (0.0, 0.0, 0.0, 0.5, 0.0), apart, 9.0) == 0.0      # caught up with
    assert robot_contact(R, (0.0, 0.0, 0.0, 0.0, 2.0), apart, 9.0) is None     # turning only
    assert robot_contact(R, (0.0, 0.0, 0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0, 0.0), 9.0) is None
    assert overlaps_robot(R, 0.0, 0.0, 2.0 * R - 1e-6, 0.0)
    assert not overlaps_robot(R, 0.0, 0.0, 2.0 * R, 0.0)
    assert not overlaps_robot(R, 0.0, 0.0, 0.0, 2.0 * R + 1e-6)


# Free places in and around ROOM, every 2 cm: a start is one of them plus up to 2 cm.
# (The distances at once, not one call a place: collection, in every pytest worker, took 0.4
# CPU s for them.)
_LATTICE = [(x, y) for x in np.arange(-0.2, 1.7, 0.02) for y in np.arange(-0.2, 1.2, 0.02)]
_CLEARANCE = _distance(ROOM, [x for x, _ in _LATTICE], [y for _, y in _LATTICE])
FREE = [p for p, clearance in zip(_LATTICE, _CLEARANCE) if clearance > R + 0.03]


@settings(max_examples=150, deadline=None)
@given(start=st.sampled_from(FREE), dx=st.floats(0.0, 0.02), dy=st.floats(0.0, 0.02),
       yaw=st.floats(-math.pi, math.pi),
       v=st.one_of(st.floats(-1.0, 1.0), st.sampled_from([0.0, 1e-3])),
       w=st.one_of(st.floats(-4.0, 4.0), st.sampled_from([0.0, 1e-9, -1e-6])),
       dt=st.floats(0.001, 2.0))
def test_contact_is_the_first_touch(start, dx, dy, yaw, v, w, dt):
    x, y = start[0] + dx, start[1] + dy
    walls = Walls(ROOM, R)
    assert not walls.overlaps(x, y)
    s = walls.contact(x, y, yaw, v, w, dt)
    end = dt if s is None else s
    gaps = _distance(ROOM, *_track(x, y, yaw, v, w, np.linspace(0.0, end, 400)[:-1])) - R
    assert np.all(gaps > -1e-9)
    if s is not None:
        assert 0.0 <= s <= dt
        assert abs(_gap_at(ROOM, (x, y, yaw), (v, w), s)) <= 1e-9


@settings(max_examples=100, deadline=None)
@given(a=st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-4, 4), st.floats(-1, 1),
                   st.floats(-3, 3)),
       b=st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-4, 4), st.floats(-1, 1),
                   st.floats(-3, 3)),
       dt=st.floats(0.01, 3.0))
def test_robot_contact_is_the_first_touch(a, b, dt):
    assume(not overlaps_robot(R, a[0], a[1], b[0], b[1]))
    s = robot_contact(R, a, b, dt)
    end = dt if s is None else s
    assert np.all(_robot_gaps(a, b, np.linspace(0.0, end, 400)[:-1]) > -1e-6)
    if s is not None:
        assert abs(_robot_gaps(a, b, [s])[0]) <= 1e-6
