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
The CDR bytes of the few messages the package sends and reads, with numpy and struct (no ROS).

The hot path builds no message objects: odometry and /tf are patched into layouts made once
per set of frames, commands are read where their fields lie.  XCDR1: a 4-byte encapsulation
header, then the body, each value aligned to its size from the body's start; another
encapsulation raises UnsupportedEncoding, for the caller to decode it the slow way.
"""

import struct

import numpy as np

_NS = 1_000_000_000
# Encapsulation header of what is written here: CDR, little endian, no options.
ENCAPSULATION = b'\x00\x01\x00\x00'
_BODY = len(ENCAPSULATION)
# Encapsulation kinds read here (the second byte; the first is 0): byte order of each.
_BYTE_ORDER = {0: '>', 1: '<'}
_TWIST = 'd32xd'  # linear.x, (linear.y, .z, angular.x, .y), angular.z
# Odometry after its frames (8-byte aligned): pose (position 3, orientation 4, covariance 36
# doubles), twist (linear 3, angular 3, covariance 36 doubles).
_POSE_DOUBLES = 7
_TWIST_DOUBLES = 6
_COVARIANCE_DOUBLES = 36
_ODOMETRY_DOUBLES = 2 * _COVARIANCE_DOUBLES + _POSE_DOUBLES + _TWIST_DOUBLES
# Where each patched value lies, in doubles from the start of the pose.
_X, _Y, _QZ, _QW = 0, 1, 5, 6
_LINEAR_X = _POSE_DOUBLES + _COVARIANCE_DOUBLES
_ANGULAR_Z = _LINEAR_X + 5


class UnsupportedEncoding(ValueError):
    """The bytes are not in the plain CDR encapsulation read here (XCDR2, say)."""


def cdr_string(text):
    """Return text as a CDR string: uint32 length with the NUL (little endian), bytes, NUL."""
    data = text.encode() + b'\0'
    return struct.pack('<I', len(data)) + data


def pad(body, alignment):
    """Append zeros to the bytearray body until its length is a multiple of alignment."""
    body += bytes(-len(body) % alignment)


def _header(body, frame_id, child_frame_id):
    """Append a zero stamp and the two frames to body, padded for the doubles; return body."""
    body += bytes(8)
    body += cdr_string(frame_id)
    pad(body, 4)
    body += cdr_string(child_frame_id)
    pad(body, 8)
    return body


def _byte_order(data):
    order = _BYTE_ORDER.get(data[1]) if len(data) >= _BODY and data[0] == 0 else None
    if order is None:
        raise UnsupportedEncoding(f'encapsulation {bytes(data[:2]).hex()} is not plain CDR')
    return order


def clock_message(stamp_ns):
    """Return the CDR bytes of a rosgraph_msgs/Clock at stamp_ns (floor seconds, nanoseconds)."""
    return ENCAPSULATION + struct.pack('<iI', *divmod(stamp_ns, _NS))


def header_stamp_ns(data):
    """Return the stamp [ns] of a message whose first field is a std_msgs/Header."""
    sec, nanosec = struct.unpack_from(_byte_order(data) + 'iI', data, _BODY)
    return sec * _NS + nanosec


def string_message(text):
    """Return the CDR bytes of a std_msgs/String holding text."""
    return ENCAPSULATION + cdr_string(text)


def read_string(data):
    """Return the text of a std_msgs/String's bytes (ValueError: not one, or cut short)."""
    order = _byte_order(data)
    if len(data) < _BODY + 4:
        raise ValueError('no string length')
    (length,) = struct.unpack_from(order + 'I', data, _BODY)
    if length < 1 or len(data) < _BODY + 4 + length:
        raise ValueError('a string longer than its message')
    return bytes(data[_BODY + 4:_BODY + 3 + length]).decode()


def twist_message(linear, angular):
    """Return the CDR bytes of a geometry_msgs/Twist of linear.x and angular.z."""
    return ENCAPSULATION + struct.pack('<' + _TWIST, linear, angular)


def read_twist(data):
    """Return (linear.x, angular.z) of a geometry_msgs/Twist's bytes."""
    return struct.unpack_from(_byte_order(data) + _TWIST, data, _BODY)


def read_twist_stamped(data):
    """Return (stamp [ns], linear.x, angular.z) of a geometry_msgs/TwistStamped's bytes."""
    order = _byte_order(data)
    sec, nanosec, length = struct.unpack_from(order + 'iII', data, _BODY)
    # The twist follows the frame_id string, its doubles aligned to 8 within the body.
    twist = _BODY + ((12 + length + 7) & ~7)
    linear, angular = struct.unpack_from(order + _TWIST, data, twist)
    return sec * _NS + nanosec, linear, angular


def read_odometry(data):
    """
    Return (stamp [ns], frame_id, child_frame_id, position, orientation, twist) of Odometry bytes.

    position is (x, y, z), orientation (x, y, z, w), twist (linear.x, angular.z).
    """
    order = _byte_order(data)
    sec, nanosec = struct.unpack_from(order + 'iI', data, _BODY)
    offset = _BODY + 8
    frames = []
    for _ in range(2):
        offset += -(offset - _BODY) % 4
        (length,) = struct.unpack_from(order + 'I', data, offset)
        frames.append(bytes(data[offset + 4:offset + 3 + length]).decode())
        offset += 4 + length
    offset += -(offset - _BODY) % 8
    pose = struct.unpack_from(order + '7d', data, offset)
    twist = struct.unpack_from(order + _TWIST, data, offset + 8 * _LINEAR_X)
    return sec * _NS + nanosec, frames[0], frames[1], pose[:3], pose[3:], twist


def covariance(diagonal):
    """Return the flat, row-major 6x6 matrix with the given diagonal and zeros elsewhere."""
    values = [0.0] * 36
    values[::7] = map(float, diagonal)
    return values


class _Layout:
    """CDR bytes in a buffer whose stamps and doubles ``_write`` patches in place."""

    def _lay_out(self, buffer, stamps, fields):
        # stamps: the byte offset of each stamp; fields: the float64 elements of each value,
        # one row a value, one column a stamp.
        self._buffer = np.frombuffer(buffer, dtype=np.uint8).copy()
        self._i32, self._f64 = self._buffer.view('<i4'), self._buffer.view('<f8')
        self._stamps = np.array(stamps, dtype=np.intp).reshape(-1, 1) // 4 + np.arange(2)
        self._fields = np.stack(fields)

    def _write(self, sec, nanosec, values):
        self._i32[self._stamps] = sec, nanosec  # nanosec (< 1e9): the same bytes as uint32
        self._f64[self._fields] = values


class OdometryLayout(_Layout):
    """
    Every robot's nav_msgs/Odometry as CDR bytes in one buffer, patched per step with numpy.

    ``frames`` holds (frame_id, child_frame_id) per robot; what a unicycle does not have stays
    0.  Each message starts 4 bytes past a multiple of 8, so that its body is 8-aligned and
    every double is one element of a float64 view.
    """

    def __init__(self, frames, pose_covariance, twist_covariance):
        covariances = (np.asarray(pose_covariance, dtype='<f8'),
                       np.asarray(twist_covariance, dtype='<f8'))
        if any(c.shape != (_COVARIANCE_DOUBLES,) for c in covariances):
            raise ValueError('a covariance has 36 values (6x6, row-major)')
        buffer = bytearray()
        stamps, poses, self._spans = [], [], []
        for frame_id, child_frame_id in frames:
            buffer += bytes(-(len(buffer) + _BODY) % 8)
            start = len(buffer)
            body = _header(bytearray(), frame_id, child_frame_id)
            pose = len(body)
            doubles = np.zeros(_ODOMETRY_DOUBLES, dtype='<f8')
            doubles[_POSE_DOUBLES:_LINEAR_X] = covariances[0]
            doubles[_LINEAR_X + _TWIST_DOUBLES:] = covariances[1]
            body += doubles.tobytes()
            buffer += ENCAPSULATION + body
            stamps.append(start + _BODY)
            poses.append(start + _BODY + pose)
            self._spans.append((start, len(buffer)))
        buffer += bytes(-len(buffer) % 8)
        pose = np.array(poses, dtype=np.intp) // 8
        self._lay_out(buffer, stamps,
                      [pose + i for i in (_X, _Y, _QZ, _QW, _LINEAR_X, _ANGULAR_Z)])

    def __len__(self):
        return len(self._spans)

    def serialize(self, sec, nanosec, x, y, qz, qw, linear, angular):
        """Return every robot's message (a list of bytes); x to angular hold one value each."""
        self._write(sec, nanosec, (x, y, qz, qw, linear, angular))
        data = self._buffer.tobytes()
        return [data[start:end] for start, end in self._spans]


class TransformLayout(_Layout):
    """The CDR bytes of a TFMessage of fixed (frame_id, child_frame_id) frames, turned about z."""

    def __init__(self, frames):
        body = bytearray(struct.pack('<I', len(frames)))
        stamps, translations = [], []
        for frame_id, child_frame_id in frames:
            pad(body, 4)
            stamps.append(2 * _BODY + len(body))
            _header(body, frame_id, child_frame_id)
            translations.append(2 * _BODY + len(body))
            body += bytes(56)
        # Four bytes ahead of the message, so that the body's 8-aligned doubles are aligned
        # in the buffer too and every field is one element of a typed view.
        xy = np.array(translations, dtype=np.intp) // 8
        # x, y, then rotation z, w: after translation (3) and rotation x, y.
        self._lay_out(bytes(_BODY) + ENCAPSULATION + body, stamps, [xy, xy + 1, xy + 5, xy + 6])

    def serialize(self, sec, nanosec, x, y, qz, qw):
        """Return the message's bytes; x to qw hold one value per transform."""
        self._write(sec, nanosec, (x, y, qz, qw))
        return self._buffer[_BODY:].tobytes()
