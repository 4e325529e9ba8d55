"""Occupied points from ``sensor_msgs/PointCloud2`` messages, and clouds of points.

The layout of a cloud is checked before its data is read, and the common layout (x, y, z side
by side) is read in one strided pass: a large cloud at sensor rate is mostly that copy.
"""

import numpy as np
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Header

from uav_global_planner.ros.conversions.errors import InputRejected
from uav_global_planner.ros.conversions.poses import check_frame
from uav_global_planner.ros.conversions.stamps import time_from_ns

_FLOAT_FIELD_TYPES = {PointField.FLOAT32: 'f4', PointField.FLOAT64: 'f8'}
_FIELD_TYPE_NAMES = {1: 'INT8', 2: 'UINT8', 3: 'INT16', 4: 'UINT16', 5: 'INT32', 6: 'UINT32',
                     7: 'FLOAT32', 8: 'FLOAT64'}


def cloud_to_points(msg: PointCloud2, expected_frame: str, drop_non_finite: bool = True,
                    max_points: int = 2_000_000) -> np.ndarray:
    """Occupied points (M, 3) [m] of a ``PointCloud2`` with float x, y, z fields.

    Checks the layout before touching the data: x, y and z present as FLOAT32 or FLOAT64, each
    inside ``point_step``, ``row_step >= width * point_step`` and enough bytes in ``data``.

    Parameters
    ----------
    msg : sensor_msgs.msg.PointCloud2
    expected_frame : str
        Planning frame; the cloud must be stamped in it.
    drop_non_finite : bool
        Drop points with a NaN/inf coordinate (unorganised "no return" points); when False such
        a cloud is refused.
    max_points : int
        Largest accepted ``width * height``.

    Raises
    ------
    InputRejected
        Naming the problem; ``NAV2_TF_ERROR`` for a wrong frame.
    """
    check_frame(msg.header.frame_id, expected_frame, 'obstacle_cloud')
    width, height = int(msg.width), int(msg.height)
    count = width * height
    if count > max_points:
        raise InputRejected(
            f'obstacle_cloud has {count} points, more than max_cloud_points = {max_points}')
    fields = {f.name: f for f in msg.fields}
    point_step, row_step = int(msg.point_step), int(msg.row_step)
    formats, offsets = [], []
    for axis in 'xyz':
        field = fields.get(axis)
        if field is None:
            raise InputRejected(
                f'obstacle_cloud has no {axis!r} field (fields: {sorted(fields)})')
        if field.datatype not in _FLOAT_FIELD_TYPES:
            name = _FIELD_TYPE_NAMES.get(field.datatype, str(field.datatype))
            raise InputRejected(
                f'obstacle_cloud field {axis!r} has type {name}; FLOAT32 or FLOAT64 needed')
        size = 4 if field.datatype == PointField.FLOAT32 else 8
        if field.offset < 0 or field.offset + size > point_step:
            raise InputRejected(
                f'obstacle_cloud field {axis!r} (offset {field.offset}, {size} bytes) does '
                f'not fit in point_step = {point_step}')
        formats.append(('>' if msg.is_bigendian else '<') + _FLOAT_FIELD_TYPES[field.datatype])
        offsets.append(int(field.offset))
    if count == 0:
        return np.empty((0, 3))
    if row_step < width * point_step:
        raise InputRejected(
            f'obstacle_cloud row_step = {row_step} is below width * point_step = '
            f'{width * point_step}')
    needed = (height - 1) * row_step + width * point_step
    data = np.frombuffer(msg.data, dtype=np.uint8)
    if len(data) < needed:
        raise InputRejected(
            f'obstacle_cloud data has {len(data)} bytes, {needed} needed for {height} x '
            f'{width} points (truncated?)')
    points = np.empty((height * width, 3))
    size = np.dtype(formats[0]).itemsize
    if (formats[0] == formats[1] == formats[2] and offsets[1] == offsets[0] + size
            and offsets[2] == offsets[0] + 2 * size):
        # x, y, z side by side (the usual layout): one strided view per row of points, read in
        # a single pass (a large cloud at sensor rate is mostly this copy).
        view = np.ndarray(shape=(height, width, 3), dtype=formats[0], buffer=data,
                          offset=offsets[0], strides=(row_step, point_step, size))
        points.reshape(height, width, 3)[...] = view
    else:
        layout = np.dtype({'names': ['x', 'y', 'z'], 'formats': formats, 'offsets': offsets,
                           'itemsize': point_step})
        # A strided view of the rows, so padding at row ends is skipped without copying.
        records = np.ndarray(shape=(height, width), dtype=layout, buffer=data,
                             strides=(row_step, point_step))
        for column, axis in enumerate('xyz'):
            points[:, column] = records[axis].ravel()
    if np.isfinite(points.reshape(-1)).all():  # the usual case, without a per-row pass
        return points
    finite = np.isfinite(points).all(axis=1)
    if not finite.all():
        if not drop_non_finite:
            raise InputRejected(
                f'obstacle_cloud has {int(np.sum(~finite))} points with NaN/inf coordinates '
                "and cloud_non_finite is 'refuse'")
        points = points[finite]
    return points


def points_to_cloud(points: np.ndarray, frame_id: str, stamp_ns: int) -> PointCloud2:
    """Unorganised FLOAT32 x, y, z ``PointCloud2`` of an (M, 3) array [m]."""
    pts = np.ascontiguousarray(np.asarray(points, dtype='<f4').reshape(-1, 3))
    msg = PointCloud2()
    msg.header = Header(frame_id=frame_id, stamp=time_from_ns(stamp_ns))
    msg.height, msg.width = 1, len(pts)
    msg.fields = [PointField(name=axis, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, axis in enumerate('xyz')]
    msg.is_bigendian = False
    msg.point_step, msg.row_step = 12, 12 * len(pts)
    msg.data = pts.tobytes()
    msg.is_dense = True
    return msg
