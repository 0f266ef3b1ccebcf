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
The map of the simulator's world: GridMap, load_map and the example room (no ROS).

Pixel rules are those of nav2_map_server's map_io.cpp (Jazzy); the expected cells below are
worked out by hand from them.  maps/room.yaml's comment gives the room's wall boundaries.
"""

import math
import os

import numpy as np
from PIL import Image
import pytest
from sim_diffdrive.world.grid import GridMap
from sim_diffdrive.world.grid import load_map
from sim_diffdrive.world.grid import MapError

ROOM_YAML = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                         'maps', 'room.yaml')


def room_rows():
    """Return the room of maps/room.yaml as text rows, top row first (from its comment)."""
    grid = [['.'] * 80 for _ in range(60)]  # grid[row][col], row 0 at the origin (bottom)
    for row in range(60):
        for col in range(80):
            border = row in (0, 59) or col in (0, 79)
            inner = 10 <= row <= 45 and col in (50, 51)
            if border or inner:
                grid[row][col] = '#'
    return [''.join(row) for row in reversed(grid)]


def write_map(tmp_path, pixels, image_name='map.pgm', **keys):
    """
    Write an image of pixels (rows top first) and a YAML naming it; return the YAML's path.

    The image's mode follows the pixels' shape: grey values, (grey, alpha), RGB or RGBA.
    """
    Image.fromarray(np.array(pixels, dtype=np.uint8)).save(tmp_path / image_name)
    doc = {'image': image_name, 'resolution': 0.1, 'origin': '[0.0, 0.0, 0.0]'}
    doc.update(keys)
    text = ''.join('%s: %s\n' % (key, value) for key, value in doc.items())
    (tmp_path / 'map.yaml').write_text(text)
    return tmp_path / 'map.yaml'


def cells(tmp_path, pixels, image_name='map.pgm', **keys):
    return load_map(write_map(tmp_path, pixels, image_name, **keys)).data


def test_from_rows_top_row_first():
    grid = GridMap.from_rows(['#..', '.?.'], resolution=0.5)
    assert grid.width == 3 and grid.height == 2
    assert grid.data.dtype == np.int8
    # The top row of the text is the last row of data: row 0 is the row at the origin.
    assert grid.data.tolist() == [[0, -1, 0], [100, 0, 0]]
    assert grid.data.ravel().tolist() == [0, -1, 0, 100, 0, 0]
    assert grid.solid.tolist() == [[False, False, False], [True, False, False]]
    assert grid.cell_of(0.25, 0.75) == (1, 0)
    assert grid.solid[grid.cell_of(0.25, 0.75)]
    assert grid.origin == (0.0, 0.0, 0.0) and grid.resolution == 0.5


def test_grid_map_is_read_only():
    grid = GridMap.from_rows(['#.'])
    with pytest.raises(ValueError):
        grid.data[0, 0] = 0
    with pytest.raises(ValueError):
        grid.solid[0, 0] = False
    with pytest.raises(AttributeError):
        grid.resolution = 1.0


def test_from_rows_refuses_bad_rows():
    for rows in ([], [''], ['#.', '#'], ['#x']):
        with pytest.raises(ValueError):
            GridMap.from_rows(rows)


def test_to_grid_exact_without_yaw():
    grid = GridMap.from_rows(['..'], origin=(-0.5, -0.3, 0.0))
    assert grid.to_grid(0.0, 0.0) == (0.5, 0.3)
    assert grid.to_grid(1.25, -2.0) == (1.25 + 0.5, -2.0 + 0.3)
    assert grid.from_grid(0.5, 0.3) == (0.0, 0.0)


def test_to_grid_from_grid_round_trip_with_rotated_origin():
    grid = GridMap.from_rows(['....'] * 3, resolution=0.25, origin=(1.0, 2.0, math.pi / 2))
    # Rotated a quarter turn: the grid's x axis is the map's +y, its y axis the map's -x.
    gx, gy = grid.to_grid(1.0, 3.0)
    assert gx == pytest.approx(1.0) and gy == pytest.approx(0.0, abs=1e-12)
    gx, gy = grid.to_grid(0.0, 2.0)
    assert gx == pytest.approx(0.0, abs=1e-12) and gy == pytest.approx(1.0)
    assert grid.cell_of(0.9, 2.1) == (0, 0)
    assert grid.cell_of(1.1, 2.1) is None
    xs = np.linspace(-3.0, 3.0, 13)
    ys = np.linspace(5.0, -1.0, 13)
    for yaw in (0.0, 0.3, -2.5, math.pi):
        grid = GridMap.from_rows(['.'], origin=(0.7, -1.2, yaw))
        back_x, back_y = grid.from_grid(*grid.to_grid(xs, ys))
        np.testing.assert_allclose(back_x, xs, atol=1e-12)
        np.testing.assert_allclose(back_y, ys, atol=1e-12)
        x, y = grid.from_grid(*grid.to_grid(0.25, -0.5))
        assert (x, y) == (pytest.approx(0.25), pytest.approx(-0.5))


def test_cell_of_at_borders():
    grid = GridMap.from_rows(['...', '...'], resolution=0.5, origin=(-1.0, 1.0, 0.0))
    assert grid.cell_of(-1.0, 1.0) == (0, 0)        # the origin corner is inside
    assert grid.cell_of(-0.5, 1.0) == (0, 1)        # a border belongs to the higher cell
    assert grid.cell_of(-0.5000001, 1.4999999) == (0, 0)
    assert grid.cell_of(0.4999999, 1.9999999) == (1, 2)
    assert grid.cell_of(0.5, 1.5) is None           # the far edges are outside
    assert grid.cell_of(0.0, 2.0) is None
    assert grid.cell_of(-1.0000001, 1.2) is None
    assert grid.cell_of(-0.7, 0.9999999) is None
    assert grid.cell_of(math.nan, 1.2) is None
    assert grid.cell_of(math.inf, 1.2) is None


def test_load_room():
    room = load_map(ROOM_YAML)
    assert (room.width, room.height) == (80, 60)
    assert room.resolution == 0.05
    assert room.origin == (-0.5, -0.5, 0.0)
    # The shipped picture is the one the comment in room.yaml describes.
    expected = GridMap.from_rows(room_rows(), resolution=0.05, origin=(-0.5, -0.5, 0.0))
    np.testing.assert_array_equal(room.data, expected.data)
    assert set(np.unique(room.data).tolist()) == {0, 100}
    with Image.open(os.path.join(os.path.dirname(ROOM_YAML), 'room.pgm')) as img:
        assert img.mode == 'L' and img.size == (80, 60)
        assert set(np.unique(np.asarray(img)).tolist()) == {0, 254}


def test_room_walls_where_the_yaml_says():
    room = load_map(ROOM_YAML)
    solid = lambda x, y: room.solid[room.cell_of(x, y)]  # noqa: E731
    # The robot at the map's origin is on the floor, at least 0.3 m from every wall.
    assert room.cell_of(0.0, 0.0) == (10, 10)
    for dx, dy in ((0.0, 0.0), (-0.3, 0.0), (0.0, -0.3), (0.3, 0.3), (-0.3, -0.3)):
        assert not solid(dx, dy)
    # Border walls, one cell thick, mid-cell points.
    for x, y in ((-0.475, 1.0), (3.475, 1.0), (1.0, -0.475), (1.0, 2.475)):
        assert solid(x, y)
    for x, y in ((-0.425, 1.0), (3.425, 1.0), (1.0, -0.425), (1.0, 2.425)):
        assert not solid(x, y)
    # The inner wall: x 2.00 .. 2.10, y 0.00 .. 1.80, standing free of the bottom and top walls.
    for x in (2.025, 2.075):
        for y in (0.025, 0.9, 1.775):
            assert solid(x, y)
        assert not solid(x, -0.025) and not solid(x, 1.825)
    assert not solid(1.975, 0.9) and not solid(2.125, 0.9)
    # Frame flip: the bottom of the image (its last row) is data's row 0, at the origin.
    assert room.cell_of(-0.5, -0.5) == (0, 0)
    assert room.data[0].tolist() == [100] * 80
    assert room.data[10, 50] == 100 and room.data[9, 50] == 0
    assert room.data[45, 51] == 100 and room.data[46, 51] == 0
    assert room.cell_of(3.5, 1.0) is None and room.cell_of(1.0, 2.5) is None


def test_trinary_default_thresholds(tmp_path):
    # occ = 1 - v / 255: > 0.65 occupied, < 0.25 free, between unknown (the thresholds strict).
    data = cells(tmp_path, [[0, 89, 90, 191, 192, 254, 255]])
    assert data.tolist() == [[100, 100, -1, -1, 0, 0, 0]]


def test_trinary_negate_and_own_thresholds(tmp_path):
    # negate: occ = v / 255, so white is occupied.
    data = cells(tmp_path, [[255, 166, 165, 64, 63, 0]], negate=1)
    assert data.tolist() == [[100, 100, -1, -1, 0, 0]]
    data = cells(tmp_path, [[0, 25, 26, 229, 230, 255]], occupied_thresh=0.9, free_thresh=0.1)
    # occ: 1, 0.902, 0.898, 0.102, 0.098, 0
    assert data.tolist() == [[100, 100, -1, -1, 0, 0]]
    assert cells(tmp_path, [[0, 255]], negate='true').tolist() == [[0, 100]]
    assert cells(tmp_path, [[0, 255]], negate='false').tolist() == [[100, 0]]


def test_image_rows_are_flipped(tmp_path):
    data = cells(tmp_path, [[0, 0, 0], [254, 254, 0]])
    assert data.tolist() == [[0, 0, 100], [100, 100, 100]]


def test_scale_mode(tmp_path):
    # Between the thresholds: rint((occ - free) / (occupied - free) * 100).
    # v 90: occ 0.64706 -> 99.26 -> 99; v 127: occ 0.50196 -> 62.99 -> 63;
    # v 150: occ 0.41176 -> 40.44 -> 40; v 191: occ 0.25098 -> 0.25 -> 0.
    data = cells(tmp_path, [[0, 89, 90, 127, 150, 191, 192, 255]], mode='scale')
    assert data.tolist() == [[100, 100, 99, 63, 40, 0, 0, 0]]
    data = cells(tmp_path, [[127, 255]], mode='scale', negate=1)
    assert data.tolist() == [[62, 100]]  # occ 0.49804 -> 62.01


def test_scale_and_trinary_with_alpha(tmp_path):
    pixels = [[[0, 0, 0, 255], [0, 0, 0, 254], [255, 255, 255, 0], [0, 0, 0, 128],
               [127, 127, 127, 255], [255, 0, 0, 255]]]
    data = cells(tmp_path, pixels, 'map.png', mode='scale')
    # Any pixel that is not fully opaque is unknown in scale mode; colour is the channels' mean.
    assert data.tolist() == [[100, -1, -1, -1, 63, 100]]
    # Trinary averages the alpha in with the colour: (0,0,0,254) has shade 0.249, occ 0.751;
    # transparent white 0.75 -> occ 0.25, not below free_thresh; (0,0,0,128) -> occ 0.875;
    # (127,127,127,255) -> shade 0.6235, occ 0.3765; opaque red -> shade 0.5, occ 0.5.
    data = cells(tmp_path, pixels, 'map.png')
    assert data.tolist() == [[100, 100, -1, 100, -1, -1]]
    grey_alpha = [[[254, 255], [254, 0]]]
    assert cells(tmp_path, grey_alpha, 'map.png', mode='scale').tolist() == [[0, -1]]
    assert cells(tmp_path, grey_alpha, 'map.png').tolist() == [[0, -1]]  # shade 0.996, 0.747


def test_raw_mode(tmp_path):
    # The grey value itself; above 100 is unknown.  negate does not apply in raw mode.
    data = cells(tmp_path, [[0, 37, 100, 101, 255]], mode='raw')
    assert data.tolist() == [[0, 37, 100, -1, -1]]
    data = cells(tmp_path, [[0, 37, 100, 101, 255]], mode='raw', negate=1)
    assert data.tolist() == [[0, 37, 100, -1, -1]]
    rgb = [[[30, 60, 90], [100, 100, 101]]]  # means 60 and 100.33
    assert cells(tmp_path, rgb, 'map.png', mode='raw').tolist() == [[60, 100]]


def test_image_path_absolute_and_relative(tmp_path):
    (tmp_path / 'maps').mkdir()
    Image.fromarray(np.zeros((2, 2), dtype=np.uint8), 'L').save(tmp_path / 'maps' / 'a.pgm')
    (tmp_path / 'maps' / 'rel.yaml').write_text(
        'image: a.pgm\nresolution: 1\norigin: [0, 0, 0]\n')
    (tmp_path / 'abs.yaml').write_text(
        'image: %s\nresolution: 0.5\norigin: [1, 2, 0.5]\n' % (tmp_path / 'maps' / 'a.pgm'))
    assert load_map(str(tmp_path / 'maps' / 'rel.yaml')).data.tolist() == [[100, 100]] * 2
    grid = load_map(tmp_path / 'abs.yaml')
    assert grid.origin == (1.0, 2.0, 0.5) and grid.resolution == 0.5


def test_numbers_are_read_as_map_servers_yaml_cpp_reads_them(tmp_path):
    # PyYAML (YAML 1.1) takes 5e-2 (no dot) for a string; yaml-cpp reads it, and a quoted
    # number, as a number.
    Image.fromarray(np.zeros((2, 2), dtype=np.uint8), 'L').save(tmp_path / 'a.pgm')
    (tmp_path / 'a.yaml').write_text(
        "image: a.pgm\nresolution: 5e-2\norigin: [1e1, '2', -5e-1]\nfree_thresh: '0.2'\n")
    grid = load_map(tmp_path / 'a.yaml')
    assert grid.resolution == 0.05 and grid.origin == (10.0, 2.0, -0.5)


def assert_refused(yaml_path, *words):
    with pytest.raises(MapError) as caught:
        load_map(yaml_path)
    message = str(caught.value)
    assert str(yaml_path) in message
    for word in words:
        assert word in message, message
    return message


def test_refuses_missing_or_unreadable_yaml(tmp_path):
    assert_refused(tmp_path / 'nowhere.yaml', 'no such file')
    assert_refused(tmp_path, 'is a folder')
    (tmp_path / 'bad.yaml').write_text('image: [unclosed\n')
    assert_refused(tmp_path / 'bad.yaml', 'YAML')
    (tmp_path / 'binary.yaml').write_bytes(b'\xff\xfe\x00\x01')
    assert_refused(tmp_path / 'binary.yaml', 'YAML')
    for text in ('', '- image: a.pgm\n', 'just text\n'):
        (tmp_path / 'list.yaml').write_text(text)
        assert_refused(tmp_path / 'list.yaml', 'mapping')
    assert issubclass(MapError, ValueError)


@pytest.mark.parametrize('key, value, words', [
    ('image', None, ["missing 'image'"]),
    ('image', "''", ["'image'"]),
    ('image', '[a.pgm]', ["'image'"]),
    ('resolution', None, ["missing 'resolution'"]),
    ('resolution', '0', ["'resolution'", 'positive']),
    ('resolution', '-0.05', ["'resolution'", 'positive']),
    ('resolution', 'fine', ["'resolution'", 'number']),
    ('resolution', '.nan', ["'resolution'"]),
    ('resolution', 'true', ["'resolution'"]),
    ('resolution', "'inf'", ["'resolution'"]),
    ('resolution', '1e400', ["'resolution'"]),
    ('origin', None, ["missing 'origin'"]),
    ('origin', '[0, 0]', ["'origin'", '3 numbers']),
    ('origin', '[0, 0, 0, 0]', ["'origin'", '3 numbers']),
    ('origin', '[0, zero, 0]', ["'origin'", '3 numbers']),
    ('origin', '0', ["'origin'", '3 numbers']),
    ('negate', '2', ["'negate'"]),
    ('negate', 'maybe', ["'negate'"]),
    ('negate', '0.5', ["'negate'"]),
    ('mode', 'Trinary', ["'mode'", 'trinary, scale, raw']),
    ('mode', 'binary', ["'mode'"]),
    ('occupied_thresh', '1.5', ["'occupied_thresh'"]),
    ('occupied_thresh', '0.2', ["'free_thresh'", "'occupied_thresh'"]),
    ('occupied_thresh', '0.25', ["'free_thresh'", "'occupied_thresh'"]),
    ('free_thresh', '-0.1', ["'free_thresh'"]),
    ('free_thresh', 'low', ["'free_thresh'", 'number']),
])
def test_refuses_bad_key(tmp_path, key, value, words):
    yaml_path = write_map(tmp_path, [[0]])
    lines = [line for line in yaml_path.read_text().splitlines()
             if not line.startswith(key + ':')]
    if value is not None:
        lines.append('%s: %s' % (key, value))
    yaml_path.write_text('\n'.join(lines) + '\n')
    assert_refused(yaml_path, *words)


def test_accepts_threshold_edges(tmp_path):
    data = cells(tmp_path, [[0, 255]], free_thresh=0, occupied_thresh=1)
    assert data.tolist() == [[-1, -1]]  # occ 1 is not above 1, occ 0 is not below 0


def test_refuses_missing_or_bad_image(tmp_path):
    (tmp_path / 'map.yaml').write_text('image: gone.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n')
    message = assert_refused(tmp_path / 'map.yaml', "'image'", 'does not exist')
    assert str(tmp_path / 'gone.pgm') in message
    for text in ('P5 this is not an image\n', 'image: gone.pgm\n'):
        (tmp_path / 'gone.pgm').write_text(text)
        message = assert_refused(tmp_path / 'map.yaml', "'image'", 'not a readable image')
        assert str(tmp_path / 'gone.pgm') in message
    (tmp_path / 'gone.pgm').unlink()
    (tmp_path / 'gone.pgm').mkdir()
    assert_refused(tmp_path / 'map.yaml', "'image'", 'does not exist')


def test_sixteen_bit_and_palette_images(tmp_path):
    # A 16-bit PGM's values are GraphicsMagick's quanta: 22873 / 65535 = 89 / 255.
    Image.fromarray(np.array([[0, 22873, 23130, 65535]], dtype=np.uint16)).save(
        tmp_path / 'deep.pgm')
    yaml_path = write_map(tmp_path, [[0]], image='deep.pgm')
    assert load_map(yaml_path).data.tolist() == [[100, 100, -1, 0]]
    palette = Image.fromarray(np.array([[0, 254]], dtype=np.uint8)).convert('P')
    palette.save(tmp_path / 'palette.png')
    yaml_path = write_map(tmp_path, [[0]], image='palette.png')
    assert load_map(yaml_path).data.tolist() == [[100, 0]]
