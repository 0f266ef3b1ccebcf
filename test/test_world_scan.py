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

"""The simulated laser scan against closed forms: faces, corners, discs, noise (no ROS)."""

import math

from benchmark.scan import cast_per_ray
import numpy as np
import pytest
from sim_diffdrive.world.grid import GridMap
from sim_diffdrive.world.scan import beam_angles
from sim_diffdrive.world.scan import cast
from sim_diffdrive.world.scan import Scanner

EXACT = 1e-9  # metres
RES = 0.1
# A 1.2 m x 1.0 m room, walls one cell thick, an inner wall x in [0.5, 0.6], y in [0.4, 0.7].
ROOM = ['############',
        '#..........#',
        '#..........#',
        '#....#.....#',
        '#....#.....#',
        '#....#.....#',
        '#..........#',
        '#..........#',
        '#..........#',
        '############']
# The same solid cells as closed boxes (x0, y0, x1, y1) in metres, for the slab oracle.
BOXES = [(0.0, 0.0, 1.2, 0.1), (0.0, 0.9, 1.2, 1.0), (0.0, 0.0, 0.1, 1.0),
         (1.1, 0.0, 1.2, 1.0), (0.5, 0.4, 0.6, 0.7)]


@pytest.fixture
def room():
    return GridMap.from_rows(ROOM, resolution=RES)


def slab(gx, gy, theta):
    """Return the exact distance along each ray to the first of BOXES it touches (or inf)."""
    gx, gy, theta = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (gx, gy, theta)))
    dx, dy = np.cos(theta), np.sin(theta)
    best = np.full(gx.shape, np.inf)
    with np.errstate(divide='ignore', invalid='ignore'):
        for x0, y0, x1, y1 in BOXES:
            tx0, tx1 = (x0 - gx) / dx, (x1 - gx) / dx
            ty0, ty1 = (y0 - gy) / dy, (y1 - gy) / dy
            enter = np.maximum(np.minimum(tx0, tx1), np.minimum(ty0, ty1))
            leave = np.minimum(np.maximum(tx0, tx1), np.maximum(ty0, ty1))
            hit = (enter <= leave) & (leave >= 0.0)
            best = np.where(hit, np.minimum(best, np.maximum(enter, 0.0)), best)
    return best


def free_poses(count, seed):
    """Return random poses in the room, clear of the walls by 1 cm."""
    rng = np.random.default_rng(seed)
    poses = []
    while len(poses) < count:
        x, y = rng.uniform(0.11, 1.09), rng.uniform(0.11, 0.89)
        if not (0.49 < x < 0.61 and 0.39 < y < 0.71):
            poses.append((x, y, rng.uniform(-math.pi, math.pi)))
    return np.array(poses).T


def test_beam_angles_turn_counter_clockwise_from_minus_pi():
    np.testing.assert_allclose(beam_angles(4), [-math.pi, -math.pi / 2, 0.0, math.pi / 2])
    angles = beam_angles(360)
    assert angles[0] == -math.pi and angles[180] == 0.0
    np.testing.assert_allclose(np.diff(angles), 2.0 * math.pi / 360, rtol=0, atol=1e-15)
    with pytest.raises(ValueError):
        beam_angles(0)


def test_beams_along_the_axes_end_on_the_cell_faces(room):
    ranges = cast(room, [0.23], [0.31], [0.0], [0.0, math.pi / 2, math.pi, -math.pi / 2], 5.0)
    # +x to the right wall's face x = 11 res, +y to the top wall's y = 9 res, then x = y = res.
    expected = [11 * RES - 0.23, 9 * RES - 0.31, 0.23 - RES, 0.31 - RES]
    np.testing.assert_allclose(ranges[0], expected, rtol=0, atol=EXACT)
    # The inner wall's faces from its left, right and top.
    ranges = cast(room, [0.37, 0.83, 0.55], [0.55, 0.55, 0.85], [0.0, math.pi, -math.pi / 2],
                  [0.0], 5.0)
    np.testing.assert_allclose(ranges[:, 0], [0.5 - 0.37, 0.83 - 0.6, 0.85 - 0.7], atol=EXACT)


def test_a_diagonal_beam_ends_on_the_first_face_it_crosses(room):
    # From (0.2, 0.15) along (0.8, 0.6): x = 0.5 is crossed at y = 0.375, below the inner wall;
    # its bottom face y = 0.4 at x = 0.2 + 0.25 / 0.6 * 0.8 = 0.533, within [0.5, 0.6].
    heading = math.atan2(0.6, 0.8)
    yaw = 0.3  # not a multiple of any beam increment
    ranges = cast(room, [0.2], [0.15], [yaw], [heading - yaw], 5.0)
    assert ranges[0, 0] == pytest.approx((0.4 - 0.15) / 0.6, abs=EXACT)


def test_every_beam_from_random_poses_equals_the_slab_oracle(room):
    x, y, yaw = free_poses(24, seed=1)
    angles = beam_angles(360)
    ranges = cast(room, x, y, yaw, angles, 5.0)
    expected = slab(x[:, None], y[:, None], yaw[:, None] + angles)
    assert np.isfinite(ranges).all()
    np.testing.assert_allclose(ranges, expected, rtol=0, atol=EXACT)


def test_a_rotated_map_origin_rotates_the_room(room):
    ox, oy, oyaw = 1.0, -2.0, 0.7
    rotated = GridMap.from_rows(ROOM, resolution=RES, origin=(ox, oy, oyaw))
    gx, gy, gyaw = free_poses(8, seed=2)
    x, y = rotated.from_grid(gx, gy)  # the poses in the map frame
    angles = beam_angles(90)
    ranges = cast(rotated, x, y, gyaw + oyaw, angles, 5.0)
    expected = slab(gx[:, None], gy[:, None], gyaw[:, None] + angles)
    np.testing.assert_allclose(ranges, expected, rtol=0, atol=EXACT)
    # And the unrotated room at the same grid poses agrees.
    np.testing.assert_allclose(cast(room, gx, gy, gyaw, angles, 5.0), ranges, atol=EXACT)


def test_corners_and_faces_are_touched_and_no_beam_leaks_through_a_diagonal_gap():
    stairs = GridMap.from_rows(['......',
                                '.#....',
                                '..#...',
                                '...#..',
                                '....#.',
                                '......'], resolution=RES)
    # y = x - 0.2 passes the corner (0.4, 0.2) where two solid cells touch, and no other.
    ranges = cast(stairs, [0.25, 0.55], [0.05, 0.35], [math.pi / 4, -3 * math.pi / 4], [0.0],
                  5.0)
    np.testing.assert_allclose(ranges[:, 0], 0.15 * math.sqrt(2.0), rtol=0, atol=EXACT)


def test_a_beam_grazing_a_wall_stops_at_its_corner(room):
    # Along the inner wall's bottom (y = 0.4) and top (y = 0.7) faces: its corner at x = 0.5;
    # 1 cm above the top it passes to the right wall; through its corner (0.5, 0.4) diagonally.
    ranges = cast(room, [0.2, 0.2, 0.2], [0.4, 0.7, 0.71], [0.0, 0.0, 0.0], [0.0], 5.0)
    np.testing.assert_allclose(ranges[:, 0], [0.3, 0.3, 0.9], rtol=0, atol=EXACT)
    ranges = cast(room, [0.3], [0.2], [0.0], [math.pi / 4], 5.0)
    assert ranges[0, 0] == pytest.approx(0.2 * math.sqrt(2.0), abs=EXACT)


@pytest.mark.parametrize('resolution', [0.03, 0.05, 0.1])
@pytest.mark.parametrize('origin', [(0.0, 0.0, 0.0), (0.013, -0.37, 0.0), (-2.3, 1.1, 0.0),
                                    (1.7, 0.9, 0.3), (-0.2, -5.4, -2.0)])
def test_grid_lines_and_corners_whatever_the_rounding(resolution, origin):
    # A wall of cells x in [2, 6], y in [1, 2] (in cells): beams along its bottom and top faces
    # stop at its ends, the diagonals through its corners at the corners.
    grid = GridMap.from_rows(['........', '..####..', '........'], resolution, origin)
    gx = np.array([0.5, 0.5, 7.5, 7.5, 1.0, 7.0, 1.0]) * resolution
    gy = np.array([1.0, 2.0, 1.0, 2.0, 0.0, 0.0, 3.0]) * resolution
    heading = np.array([0.0, 0.0, math.pi, math.pi, math.pi / 4, 3 * math.pi / 4, -math.pi / 4])
    x, y = grid.from_grid(gx, gy)
    ranges = cast(grid, x, y, heading + origin[2], [0.0], 5.0)
    expected = np.array([1.5, 1.5, 1.5, 1.5, math.sqrt(2.0), math.sqrt(2.0), math.sqrt(2.0)])
    np.testing.assert_allclose(ranges[:, 0], expected * resolution, rtol=0, atol=EXACT)


def test_beams_along_grid_lines_from_grid_points_give_no_nan(room):
    headings = [0.0, -0.0, math.pi / 2, math.pi, -math.pi / 2, math.pi / 4, -3 * math.pi / 4]
    ranges = cast(room, [0.3, 0.4, 1.0], [0.3, 0.8, 0.2], [0.0, 0.0, 0.0], headings, 5.0)
    assert not np.isnan(ranges).any()
    diagonal = 0.2 * math.sqrt(2.0)  # to (0.5, 0.5) on the inner wall, to the corner (0.1, 0.1)
    np.testing.assert_allclose(ranges[0], [0.8, 0.8, 0.6, 0.2, 0.2, diagonal, diagonal],
                               rtol=0, atol=EXACT)
    assert ranges[1, 2] == pytest.approx(0.1, abs=EXACT)  # to the top wall's face y = 0.9
    assert ranges[2, 4] == pytest.approx(0.1, abs=EXACT)  # to the bottom wall's face y = 0.1


def test_beams_along_a_grid_line_from_a_rounding_error_off_it_equal_the_slab_oracle(room):
    # 0.3 / 0.1 is 2.9999999999999996: a scanner there is on the line y = 0.3 within SNAP, and
    # its beam at -pi has a y component of -1.2e-16.  The crossing of that line came out 0.45 m
    # behind it, where the right wall is: the beam read 0 (-inf in a scan), with nothing near.
    # Scanners along the lines y = 0.3 and 0.8, then x = 0.3, 0.7 and 0.8 (k * 0.1 / 0.1 is a
    # rounding error below k or above it), between cell faces (a beam along a face stops at
    # its corner, where the oracle's slab misses it), none in a wall.
    along = np.arange(0.15, 1.1, 0.1)
    gx = np.concatenate([np.tile(along, 2), np.repeat([0.3, 0.7, 0.8], along.size)])
    gy = np.concatenate([np.repeat([0.3, 0.8], along.size), np.tile(along, 3)])
    clear = ~((gx > 0.45) & (gx < 0.65) & (gy > 0.35) & (gy < 0.75)) & (gy < 0.9)
    gx, gy = gx[clear], gy[clear]
    angles = np.array([-math.pi, math.pi, -math.pi / 2, math.pi / 2, 0.0])
    ranges = cast(room, gx, gy, np.zeros(gx.size), angles, 5.0)
    expected = slab(gx[:, None], gy[:, None], angles[None, :])
    np.testing.assert_allclose(ranges, expected, rtol=0, atol=EXACT)


def test_a_users_corridor_reads_its_wall_not_minus_inf():
    # As a user met it: (0.05 + 2.0) / 0.05 is 40.99999999999999, and the beam behind the
    # robot read 0 (-inf in its scan) instead of the wall 1.3 m behind it.
    grid = GridMap.from_rows(['####' + '.' * 96 + '#' * 20] * 100, resolution=0.05,
                             origin=(-1.0, -2.0, 0.0))  # free from x = -0.8 to 4.0
    ranges = cast(grid, [0.5, 0.5], [0.05, 0.05], [0.0, math.pi], [-math.pi, 0.0], 5.0)
    np.testing.assert_allclose(ranges, [[1.3, 3.5], [3.5, 1.3]], rtol=0, atol=EXACT)


def test_inside_a_wall_is_zero_and_outside_the_map_is_free(room):
    assert (cast(room, [0.05], [0.5], [0.3], beam_angles(36), 5.0) == 0.0).all()
    # From outside the map: towards it, the left wall's outer face x = 0; away, nothing.
    ranges = cast(room, [-0.5], [0.5], [0.0], [0.0, math.pi], 5.0)
    np.testing.assert_allclose(ranges[0], [0.5, math.inf], atol=EXACT)
    assert (cast(GridMap.from_rows(['....', '....']), [0.1], [0.1], [0.0], beam_angles(8),
                 5.0) == math.inf).all()


def test_beyond_range_max_is_inf(room):
    x, y, yaw = free_poses(6, seed=3)
    angles = beam_angles(72)
    far = cast(room, x, y, yaw, angles, 5.0)
    near = cast(room, x, y, yaw, angles, 0.3)
    assert np.array_equal(near, np.where(far > 0.3, math.inf, far))
    assert np.isinf(near).any() and np.isfinite(near).any()


def test_another_robot_is_seen_at_its_disc_and_a_robot_never_sees_its_own(room):
    radius, bearing = 0.1, 0.3
    x = [0.3, 0.3 + 0.5 * math.cos(bearing)]
    y = [0.25, 0.25 + 0.5 * math.sin(bearing)]
    yaw = [bearing, 0.0]
    angles = [0.0, math.pi + bearing, 0.25]
    ranges = cast(room, x, y, yaw, angles, 5.0, radius=radius)
    walls = cast(room, x, y, yaw, angles, 5.0)
    # On the line of centres: centre distance minus radius, both ways.
    assert ranges[0, 0] == pytest.approx(0.5 - radius, abs=EXACT)
    assert ranges[1, 1] == pytest.approx(0.5 - radius, abs=EXACT)
    # 0.25 rad off the line of centres passes the disc by 0.5 sin(0.25) > radius.
    assert ranges[0, 2] == walls[0, 2]
    # Off the line of centres but through the disc: the nearer root of |p + t d - c| = r.
    offset = 0.1
    ranges = cast(room, x, y, [bearing + offset, 0.0], [0.0], 5.0, radius=radius)
    b, c = 0.5 * math.cos(offset), 0.25 - radius ** 2
    assert ranges[0, 0] == pytest.approx(b - math.sqrt(b * b - c), abs=EXACT)
    # A robot alone, or discs off: the walls only.
    alone = cast(room, x[:1], y[:1], yaw[:1], beam_angles(360), 5.0, radius=radius)
    assert np.array_equal(alone, cast(room, x[:1], y[:1], yaw[:1], beam_angles(360), 5.0))
    assert np.array_equal(cast(room, x, y, yaw, angles, 5.0, radius=radius, discs=False), walls)
    # A scanner inside another robot's disc sees nothing else.
    inside = cast(room, [0.3, 0.35], [0.25, 0.25], [0.0, 0.0], beam_angles(8), 5.0, radius=0.1)
    assert (inside == 0.0).all()


def test_discs_on_the_empty_plane():
    ranges = cast(None, [0.0, 1.0, 0.0], [0.0, 0.0, -2.0], [0.0, 0.0, 0.0],
                  [0.0, math.pi / 2, math.pi], 3.5, radius=0.2)
    np.testing.assert_allclose(ranges[0], [0.8, math.inf, math.inf], atol=EXACT)
    np.testing.assert_allclose(ranges[1], [math.inf, math.inf, 0.8], atol=EXACT)
    np.testing.assert_allclose(ranges[2], [math.inf, 1.8, math.inf], atol=EXACT)


def test_discs_equal_every_ray_against_every_disc_for_any_beam_angles():
    rng = np.random.default_rng(9)
    x, y, yaw = rng.uniform(-2.0, 2.0, 12), rng.uniform(-2.0, 2.0, 12), rng.uniform(-9, 9, 12)
    radius = 0.3
    for angles in (beam_angles(720), rng.uniform(-7.0, 7.0, 50)):  # unsorted, over a turn
        ranges = cast(None, x, y, yaw, angles, 3.0, radius=radius)
        theta = (yaw[:, None] + angles)[:, :, None]
        wx, wy = x - x[:, None], y - y[:, None]
        b = wx[:, None, :] * np.cos(theta) + wy[:, None, :] * np.sin(theta)
        c = (wx * wx + wy * wy - radius ** 2)[:, None, :]
        with np.errstate(invalid='ignore'):
            t = np.where((b * b >= c) & (b > 0.0), b - np.sqrt(b * b - c), np.inf)
        t[np.broadcast_to(c <= 0.0, t.shape)] = 0.0  # inside another disc
        t[np.arange(12), :, np.arange(12)] = np.inf  # not its own disc
        expected = t.min(axis=2)
        expected[expected > 3.0] = np.inf
        assert np.array_equal(np.isinf(ranges), np.isinf(expected))
        assert np.isfinite(ranges).sum() > 20
        np.testing.assert_allclose(ranges[np.isfinite(ranges)],
                                   expected[np.isfinite(expected)], rtol=0, atol=EXACT)


def test_scanner_fields_and_rep_117_infinities(room):
    scanner = Scanner(room, beams=360, range_min=0.12, range_max=0.5)
    assert scanner.angle_min == -math.pi
    assert scanner.angle_increment == 2.0 * math.pi / 360
    assert scanner.angle_max == -math.pi + 359 * scanner.angle_increment
    assert (scanner.range_min, scanner.range_max) == (0.12, 0.5)
    ranges = scanner.scan([0.17, 0.05], [0.5, 0.5], [0.0, 0.0])
    assert ranges.dtype == np.float32 and ranges.shape == (2, 360)
    assert ranges[0, 0] == -math.inf  # 7 cm to the left wall's face: too close
    assert ranges[0, 180] == np.float32(0.5 - 0.17)  # to the inner wall's face
    assert ranges[0, 225] == math.inf  # at pi/4: the top wall 0.57 m away, beyond range_max
    assert (ranges[1] == -math.inf).all()  # inside the wall


def test_noise_repeats_bit_for_bit_with_a_seed(room):
    x, y, yaw = free_poses(4, seed=4)

    def scans(seed):
        scanner = Scanner(room, beams=90, range_max=0.6, noise_std=0.01, seed=seed)
        return [scanner.scan(x, y, yaw, stamp_ns) for stamp_ns in (0, 100_000_000, 0)]

    first, again, other = scans(7), scans(7), scans(8)
    for a, b, c in zip(first, again, other):
        assert a.tobytes() == b.tobytes()
        assert not np.array_equal(a, c)
    assert not np.array_equal(first[0], first[1])  # another time, other noise
    # The same time, the same noise, whatever came before: a node that joins a running
    # simulator (a separate process, at any time) sees the scans of any other run.
    assert first[0].tobytes() == first[2].tobytes()
    clean = cast(room, x, y, yaw, beam_angles(90), 0.6)
    assert np.isposinf(first[0][np.isinf(clean)]).all()  # no return stays no return
    middle = (clean > 0.2) & (clean < 0.5)
    error = first[0][middle] - clean[middle]
    assert middle.sum() > 50 and np.abs(error).max() < 0.06 and error.std() > 0.005


def test_no_noise_gives_exactly_the_cast_ranges(room):
    x, y, yaw = free_poses(5, seed=5)
    scanner = Scanner(room, beams=360, range_min=0.12, range_max=3.5)
    expected = cast(room, x, y, yaw, beam_angles(360), 3.5)
    expected = np.where(expected < 0.12, -math.inf, expected).astype(np.float32)
    assert np.array_equal(scanner.scan(x, y, yaw), expected)


def test_the_per_ray_loop_agrees_within_its_step(room):
    x, y, yaw = free_poses(4, seed=6)
    angles = beam_angles(360)
    exact = cast(room, x, y, yaw, angles, 5.0)
    # nav2_loopback_sim's traversal: cell indices apart, within sqrt(2) cells.
    traversal = cast_per_ray(room, x, y, yaw, angles, 5.0)
    assert np.abs(traversal - exact).max() <= math.sqrt(2.0) * RES + EXACT
    # Its earlier walk in steps: never before the face, and within a step after it.
    step = RES / 50
    walk = cast_per_ray(room, x, y, yaw, angles, 5.0, step=step)
    assert -EXACT <= (walk - exact).min() and (walk - exact).max() <= step + EXACT


def test_64_robots_by_360_beams():
    size = 80  # a 4 m room of 5 cm cells
    rows = ['#' * size] + ['#' + '.' * (size - 2) + '#'] * (size - 2) + ['#' * size]
    grid = GridMap.from_rows(rows, resolution=0.05)
    col, row = np.arange(64) % 8, np.arange(64) // 8
    x, y, yaw = 0.5 + 0.4 * col, 0.5 + 0.4 * row, np.zeros(64)
    radius = 0.105
    ranges = cast(grid, x, y, yaw, beam_angles(360), 3.5, radius=radius)
    assert ranges.shape == (64, 360) and ranges.dtype == np.float64
    ahead, right = ranges[:, 180], ranges[:, 90]  # angles 0 and -pi/2
    # Ahead: the next robot's disc, or the right wall's face x = 3.95 for the last column.
    np.testing.assert_allclose(ahead[col < 7], 0.4 - radius, rtol=0, atol=EXACT)
    np.testing.assert_allclose(ahead[col == 7], 3.95 - 3.3, rtol=0, atol=EXACT)
    # To the right (-y): the robot below, or the bottom wall's face y = 0.05 for the first row.
    np.testing.assert_allclose(right[row > 0], 0.4 - radius, rtol=0, atol=EXACT)
    np.testing.assert_allclose(right[row == 0], 0.5 - 0.05, rtol=0, atol=EXACT)
    # The Scanner (its grid kept padded, the discs, range_min) gives the same, as float32.
    scans = Scanner(grid, radius=radius).scan(x, y, yaw)
    expected = np.where(ranges < 0.12, -math.inf, ranges).astype(np.float32)
    assert np.array_equal(scans, expected)
