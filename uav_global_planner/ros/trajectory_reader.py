"""The follower's inputs read straight from their CDR bytes: ``trajectory`` and ``plan``.

rclpy builds a Python object per point, which takes a few hundred milliseconds for a plan of
thousands of points and holds the interpreter meanwhile; a setpoint thread in the same process
would wait. The planner's ``trajectory`` points have one transform, one velocity and one
acceleration each, a fixed-size record: :func:`read_trajectory` reads them as one numpy
structured array. Anything else (big-endian CDR, points with other counts) returns None and
the caller uses rclpy. Layout (plain CDR, alignment counted from after the 4-byte encapsulation
header): header (int32 sec, uint32 nanosec, string frame_id), ``joint_names`` (uint32 count,
strings), ``points`` (uint32 count, then per point: uint32 1, translation and rotation 7 float64,
uint32 1, twist 6 float64, uint32 1, twist 6 float64, int32 sec, uint32 nanosec).
"""

from typing import List, Optional, Tuple

import numpy as np

from uav_global_planner.core.follower import PlanSamples

_FIELDS: List[Tuple[str, str]] = (
    [('n_transforms', '<u4')]
    + [(name, '<f8') for name in ('tx', 'ty', 'tz', 'qx', 'qy', 'qz', 'qw')]
    + [('n_velocities', '<u4')]
    + [(name, '<f8') for name in ('vx', 'vy', 'vz', 'wx', 'wy', 'wz')]
    + [('n_accelerations', '<u4')]
    + [(name, '<f8') for name in ('ax', 'ay', 'az', 'bx', 'by', 'bz')]
    + [('sec', '<i4'), ('nanosec', '<u4')])


def _point_dtype(start: int) -> np.dtype:
    """One point's record at stream offset ``start``, CDR padding included."""
    names, formats, offsets = [], [], []
    offset = start
    for name, fmt in _FIELDS:
        size = np.dtype(fmt).itemsize
        offset += -offset % size
        names.append(name)
        formats.append(fmt)
        offsets.append(offset - start)
        offset += size
    return np.dtype({'names': names, 'formats': formats, 'offsets': offsets,
                     'itemsize': offset - start})


class _Stream:
    def __init__(self, data: bytes) -> None:
        self.data = data
        self.offset = 0          # from after the encapsulation header

    def u32(self, signed: bool = False) -> int:
        self.offset += -self.offset % 4
        start = 4 + self.offset
        if start + 4 > len(self.data):
            raise ValueError('truncated message')
        self.offset += 4
        return int.from_bytes(self.data[start:start + 4], 'little', signed=signed)

    def string(self) -> str:
        length = self.u32()
        start = 4 + self.offset
        if length < 1 or start + length > len(self.data):
            raise ValueError('bad string length')
        self.offset += length
        return self.data[start:start + length - 1].decode('utf-8')


def read_header(data: bytes) -> Tuple[_Stream, int, str]:
    """The stream after a ``std_msgs/Header``, with its stamp [ns] and frame id.

    Raises
    ------
    ValueError
        For big-endian or truncated data.
    """
    if len(data) < 4 or data[1] != 1:
        raise ValueError('not little-endian plain CDR')
    stream = _Stream(data)
    sec = stream.u32(signed=True)
    nanosec = stream.u32()
    frame_id = stream.string()
    return stream, sec * 1_000_000_000 + nanosec, frame_id


def read_path_header(data: bytes) -> Tuple[int, bool]:
    """``(stamp_ns, empty)`` of a serialised ``nav_msgs/Path``, without building it."""
    stream, stamp_ns, _ = read_header(data)
    return stamp_ns, stream.u32() == 0


def read_trajectory(data: bytes) -> Optional[PlanSamples]:
    """A serialised ``MultiDOFJointTrajectory`` as arrays (ENU), or None when empty.

    Raises
    ------
    ValueError
        When the bytes are not the fixed layout read here (the caller falls back to rclpy).
    InvalidInputError
        For non-finite or unordered values (from :class:`PlanSamples`).
    """
    stream, stamp_ns, frame_id = read_header(data)
    for _ in range(stream.u32()):
        stream.string()
    count = stream.u32()
    if count == 0:
        return None
    # The first record's padding depends on where it starts; from the second on (8-aligned,
    # records of a multiple of 8 bytes) every record is laid out alike.
    first = _point_dtype(stream.offset)
    second_offset = stream.offset + first.itemsize
    rest = _point_dtype(second_offset)
    if second_offset % 8 or rest.itemsize % 8:
        raise ValueError('point records of varying layout')
    start = 4 + stream.offset
    if start + first.itemsize + (count - 1) * rest.itemsize > len(data):
        raise ValueError('truncated points, or points with other than one transform, '
                         'velocity and acceleration')
    head = np.frombuffer(data, dtype=first, count=1, offset=start)
    tail = np.frombuffer(data, dtype=rest, count=count - 1, offset=start + first.itemsize)
    points = {name: np.concatenate([head[name], tail[name]]) for name, _ in _FIELDS}
    for name in ('n_transforms', 'n_velocities', 'n_accelerations'):
        if np.any(points[name] != 1):
            raise ValueError(f'points with {name} other than 1')

    def columns(*names: str) -> np.ndarray:
        return np.stack([points[name].astype(np.float64) for name in names], axis=1)

    qx, qy, qz, qw = (points[name] for name in ('qx', 'qy', 'qz', 'qw'))
    yaws = np.arctan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    times = points['sec'].astype(np.float64) + points['nanosec'].astype(np.float64) * 1e-9
    return PlanSamples(stamp_ns=stamp_ns, frame_id=frame_id, times=times,
                       positions=columns('tx', 'ty', 'tz'),
                       velocities=columns('vx', 'vy', 'vz'),
                       accelerations=columns('ax', 'ay', 'az'), yaws=yaws,
                       yaw_rates=points['wz'].astype(np.float64))
