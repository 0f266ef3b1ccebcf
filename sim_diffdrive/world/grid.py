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
The simulator's map: an occupancy grid read from a map_server YAML (no ROS imports).

load_map() follows Nav2's map_server (map_io.cpp, Jazzy), so ``map`` is what map_server would
publish for the same file.
"""

from dataclasses import dataclass
from dataclasses import field
import math
import os

import numpy as np
import yaml

OCCUPIED = 100
FREE = 0
UNKNOWN = -1
MODES = ('trinary', 'scale', 'raw')
# map_server reads images with GraphicsMagick built with 16-bit quanta: an 8-bit value v is the
# quantum v * 257 of MAX_QUANTUM.  Computing shades from quanta keeps its rounding.
MAX_QUANTUM = 65535
_ROW_CHARS = {'#': OCCUPIED, '.': FREE, '?': UNKNOWN}


class MapError(ValueError):
    """An unusable map file; the message names the file and, where it applies, the key."""


@dataclass(frozen=True, eq=False)
class GridMap:
    """
    An occupancy grid in the map frame, as nav_msgs/OccupancyGrid lays it out (read-only).

    origin is the (x, y, yaw) of cell (0, 0)'s lower-left corner; data is int8 (height, width),
    row 0 at the origin; solid marks the obstacle cells (100).
    """

    resolution: float
    origin: tuple
    data: np.ndarray
    solid: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        resolution = float(self.resolution)
        if not (math.isfinite(resolution) and resolution > 0.0):
            raise ValueError('resolution must be a positive number, not %r' % (self.resolution,))
        origin = tuple(float(value) for value in self.origin)
        if len(origin) != 3 or not all(math.isfinite(value) for value in origin):
            raise ValueError('origin must be 3 finite numbers (x, y, yaw), not %r' % (origin,))
        data = np.array(self.data, dtype=np.int8, order='C')
        if data.ndim != 2:
            raise ValueError('data must be 2-D (height, width), not of shape %r' % (data.shape,))
        solid = data == OCCUPIED
        data.setflags(write=False)
        solid.setflags(write=False)
        object.__setattr__(self, 'resolution', resolution)
        object.__setattr__(self, 'origin', origin)
        object.__setattr__(self, 'data', data)
        object.__setattr__(self, 'solid', solid)

    @property
    def width(self):
        """Return the number of columns."""
        return self.data.shape[1]

    @property
    def height(self):
        """Return the number of rows."""
        return self.data.shape[0]

    def to_grid(self, x, y):
        """Return a map-frame point (floats or arrays) in the grid's axes [m] (exact for yaw 0)."""
        ox, oy, yaw = self.origin
        dx, dy = x - ox, y - oy
        if yaw == 0.0:
            return dx, dy
        c, s = math.cos(yaw), math.sin(yaw)
        return c * dx + s * dy, c * dy - s * dx

    def from_grid(self, gx, gy):
        """Return the map-frame point of a point in the grid's axes (the inverse of to_grid)."""
        ox, oy, yaw = self.origin
        if yaw == 0.0:
            return gx + ox, gy + oy
        c, s = math.cos(yaw), math.sin(yaw)
        return ox + c * gx - s * gy, oy + s * gx + c * gy

    def outside(self, x, y):
        """Return why a map-frame point is not on the map (in words), or None when it is."""
        if self.cell_of(x, y) is not None:
            return None
        return (f'outside the map ({self.width} x {self.height} cells from its origin): no wall '
                'or scan return out there')

    def cell_of(self, x, y):
        """Return the (row, col) of the half-open cell that holds a map-frame point, or None."""
        gx, gy = self.to_grid(x, y)
        col = math.floor(gx / self.resolution) if math.isfinite(gx) else -1
        row = math.floor(gy / self.resolution) if math.isfinite(gy) else -1
        return (row, col) if 0 <= row < self.height and 0 <= col < self.width else None

    @classmethod
    def from_rows(cls, rows, resolution=0.05, origin=(0.0, 0.0, 0.0)):
        """
        Build a map from rows of text, the TOP row first, as in an image.

        '#' is occupied (100), '.' free (0), '?' unknown (-1); all rows have the same length.
        """
        rows = [str(row) for row in rows]
        if not rows or not rows[0] or any(len(row) != len(rows[0]) for row in rows):
            raise ValueError('rows must be non-empty and all of the same length')
        bad = sorted(set(''.join(rows)) - set(_ROW_CHARS))
        if bad:
            raise ValueError('rows may hold only #, . and ?, not %s' % ', '.join(map(repr, bad)))
        data = [[_ROW_CHARS[char] for char in row] for row in reversed(rows)]
        return cls(resolution, origin, np.array(data, dtype=np.int8))


def load_map(yaml_path):
    """Read a map_server YAML and its image into a GridMap (MapError names the file and key)."""
    path = os.path.expanduser(os.fspath(yaml_path))
    where = 'map file %s' % path
    if not os.path.isabs(path):  # relative to where the process was started: say where that is
        where += ' (%s)' % os.path.abspath(path)
    if os.path.isdir(path):
        raise MapError('%s: is a folder, not a map_server YAML' % where)
    if not os.path.isfile(path):
        raise MapError('%s: no such file' % where)
    try:
        with open(path, encoding='utf-8') as stream:
            doc = yaml.safe_load(stream)
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as error:
        raise MapError('%s: cannot be read as YAML: %s' % (where, error)) from None
    if not isinstance(doc, dict):
        raise MapError('%s: must be a YAML mapping of map_server keys, not %s'
                       % (where, type(doc).__name__))

    for key in ('image', 'resolution', 'origin'):
        if key not in doc:
            raise MapError("%s: missing '%s'" % (where, key))
    image = doc['image']
    if not isinstance(image, str) or not image:
        raise MapError("%s: 'image' must name the image file, not %r" % (where, image))
    resolution = _number(doc, 'resolution', where)
    if not resolution > 0.0:
        raise MapError("%s: 'resolution' must be a positive number (metres per cell), not %r"
                       % (where, doc['resolution']))
    origin = doc['origin']
    if (not isinstance(origin, (list, tuple)) or len(origin) != 3
            or None in map(_as_number, origin)):
        raise MapError("%s: 'origin' must be 3 numbers [x, y, yaw], not %r" % (where, origin))
    negate = doc.get('negate', 0)
    if negate not in (0, 1) or not isinstance(negate, (int, bool)):
        raise MapError("%s: 'negate' must be 0 or 1 (or true/false), not %r" % (where, negate))
    occupied = _number(doc, 'occupied_thresh', where, 0.65)
    free = _number(doc, 'free_thresh', where, 0.25)
    if not 0.0 <= free < occupied <= 1.0:
        raise MapError("%s: thresholds must satisfy 0 <= 'free_thresh' < 'occupied_thresh' <= 1,"
                       ' not free_thresh %r, occupied_thresh %r' % (where, free, occupied))
    mode = doc.get('mode', 'trinary')
    if mode not in MODES:
        raise MapError("%s: 'mode' must be one of %s, not %r" % (where, ', '.join(MODES), mode))

    image_path = image if os.path.isabs(image) else os.path.join(os.path.dirname(path), image)
    if not os.path.isfile(image_path):
        raise MapError("%s: 'image' file %s does not exist" % (where, image_path))
    # Pillow only to read a map: a simulator without one starts without loading it.
    from PIL import Image
    from PIL import UnidentifiedImageError
    try:
        with Image.open(image_path) as img:
            grey, alpha = _quanta(img)
    except (OSError, UnidentifiedImageError, ValueError, Image.DecompressionBombError) as error:
        raise MapError("%s: 'image' file %s is not a readable image: %s"
                       % (where, image_path, error)) from None
    cells = _cells(grey, alpha, mode, bool(negate), free, occupied)
    # Image row 0 is the top; map_server stores it last: data[width * (height - y - 1) + x].
    return GridMap(resolution, tuple(map(_as_number, origin)), cells[::-1])


def _as_number(value):
    """
    Return value as a finite float, or None.

    As map_server's yaml-cpp reads a number: YAML 1.1 (PyYAML) takes 5e-2 for a string, and a
    quoted '0.05' is one; yaml-cpp reads both as numbers.
    """
    if isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            return None
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    return None


def _number(doc, key, where, default=None):
    if key not in doc:
        return default
    number = _as_number(doc[key])
    if number is None:
        raise MapError("%s: '%s' must be a number, not %r" % (where, key, doc[key]))
    return number


def _quanta(img):
    """Return the image's channels (height, width, 1 or 3) and alpha (or None), 16-bit quanta."""
    if img.mode in ('I;16', 'I;16B', 'I;16L', 'I'):
        grey = np.clip(np.asarray(img, dtype=np.int64), 0, MAX_QUANTUM)
        return grey[:, :, np.newaxis].astype(np.float64), None
    has_alpha = 'A' in img.getbands() or 'transparency' in img.info
    if img.mode not in (('LA', 'RGBA') if has_alpha else ('L', 'RGB')):
        img = img.convert('RGBA' if has_alpha else 'RGB')
    pixels = np.asarray(img, dtype=np.float64) * (MAX_QUANTUM / 255.0)
    if pixels.ndim == 2:
        pixels = pixels[:, :, np.newaxis]
    return (pixels[:, :, :-1], pixels[:, :, -1]) if has_alpha else (pixels, None)


def _cells(channels, alpha, mode, negate, free, occupied):
    """Apply map_server's per-pixel rule to one image; returns int8 rows, top row first."""
    if channels.shape[2] == 1:
        channels = np.repeat(channels, 3, axis=2)
    if mode == 'trinary' and alpha is not None:
        # map_server averages the alpha (opaque = full) in with the colour channels here.
        channels = np.concatenate([channels, alpha[:, :, np.newaxis]], axis=2)
    shade = channels.mean(axis=2) / MAX_QUANTUM
    if mode == 'raw':
        value = np.round(shade * 255.0)
        return np.where((value >= FREE) & (value <= OCCUPIED), value, UNKNOWN).astype(np.int8)
    occ = shade if negate else 1.0 - shade
    cells = np.full(occ.shape, UNKNOWN, dtype=np.int8)
    if mode == 'scale':
        between = np.rint((occ - free) / (occupied - free) * 100.0)
        cells[:] = np.clip(between, FREE, OCCUPIED).astype(np.int8)
    cells[occ < free] = FREE
    cells[occupied < occ] = OCCUPIED
    if mode == 'scale' and alpha is not None:
        cells[alpha != MAX_QUANTUM] = UNKNOWN
    return cells
