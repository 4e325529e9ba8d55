"""Conversions between ROS 2 messages and the planner's numpy types.

Small functions without side effects and without ``rclpy``: only message classes are imported, so
everything here is testable in a plain Python process. Positions are in metres in the planning
frame, times in seconds (``*_ns`` arguments in integer nanoseconds).

Inputs are validated here, and a refused input raises :class:`InputRejected`, whose ``code`` is the
Nav2 ``ComputePathToPose`` result code the node reports in its diagnostics.
"""

import math
from typing import Dict, Iterable, Mapping, Optional, Sequence, Tuple

from builtin_interfaces.msg import Duration, Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import (Point, Pose, PoseStamped, Quaternion, Transform, Twist,
                               Vector3)
from nav_msgs.msg import Odometry, Path
import numpy as np
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import ColorRGBA, Header
from trajectory_msgs.msg import MultiDOFJointTrajectory, MultiDOFJointTrajectoryPoint
from visualization_msgs.msg import Marker, MarkerArray

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.obstacles import Box, Obstacle, ObstacleSet, PointSet, Sphere
from uav_global_planner.core.result import PlanResult
from uav_global_planner.core.status import NAV2_CODE_BY_STATUS, NAV2_TF_ERROR, NAV2_UNKNOWN

#: Marker identity: (namespace, id), as RViz keys markers.
MarkerKey = Tuple[str, int]

#: Unit quaternion (x, y, z, w) of no rotation.
IDENTITY_QUATERNION = (0.0, 0.0, 0.0, 1.0)

# Below this horizontal step [m] the heading of a path segment is undefined (vertical climb), so
# the previous heading is kept instead of a yaw computed from rounding noise.
_HEADING_EPS = 1e-6

# Quaternions shorter than this are treated as "unset" (all zeros), which RViz shows unrotated.
_QUATERNION_EPS = 1e-9

_FLOAT_FIELD_TYPES = {PointField.FLOAT32: 'f4', PointField.FLOAT64: 'f8'}
_FIELD_TYPE_NAMES = {1: 'INT8', 2: 'UINT8', 3: 'INT16', 4: 'UINT16', 5: 'INT32', 6: 'UINT32',
                     7: 'FLOAT32', 8: 'FLOAT64'}


class InputRejected(InvalidInputError):
    """A message the node refuses, with the Nav2 result code to report.

    Parameters
    ----------
    message : str
        Human-readable reason, naming the offending field.
    code : int
        Nav2 ``ComputePathToPose`` result code (``NAV2_TF_ERROR`` for a wrong frame,
        ``NAV2_UNKNOWN`` for malformed content).
    """

    def __init__(self, message: str, code: int = NAV2_UNKNOWN) -> None:
        super().__init__(message)
        self.code = int(code)


# --------------------------------------------------------------------------------------------
# Time
# --------------------------------------------------------------------------------------------

def time_from_ns(stamp_ns: int) -> Time:
    """``builtin_interfaces/Time`` of a time in integer nanoseconds (>= 0)."""
    sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
    return Time(sec=sec, nanosec=nanosec)


def time_to_ns(stamp: Time) -> int:
    """Integer nanoseconds of a ``builtin_interfaces/Time``."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def duration_from_seconds(seconds: float) -> Duration:
    """``builtin_interfaces/Duration`` of a non-negative time span [s]."""
    sec, nanosec = divmod(int(round(float(seconds) * 1e9)), 1_000_000_000)
    return Duration(sec=sec, nanosec=nanosec)


def duration_to_seconds(duration: Duration) -> float:
    """Seconds of a ``builtin_interfaces/Duration``."""
    return float(duration.sec) + float(duration.nanosec) * 1e-9


# --------------------------------------------------------------------------------------------
# Poses and frames
# --------------------------------------------------------------------------------------------

def normalize_frame(frame_id: str) -> str:
    """Frame name without the leading '/' that tf2 ignores too."""
    return frame_id.lstrip('/')


def check_frame(frame_id: str, expected: str, what: str) -> None:
    """Refuse data stamped in another frame than the planning frame.

    The node has no tf2, so it cannot transform; it says so instead of planning in a wrong frame.

    Raises
    ------
    InputRejected
        With ``code = NAV2_TF_ERROR``.
    """
    if normalize_frame(frame_id) != normalize_frame(expected):
        raise InputRejected(
            f'{what} is in frame {frame_id!r} but the planner works in frame {expected!r} '
            '(no transforms are done; publish in the planning frame or set frame_id)',
            NAV2_TF_ERROR)


def point_to_array(point, what: str) -> np.ndarray:
    """Position (x, y, z) [m] of a ``Point``/``Vector3`` as a finite float64 array (3,).

    Raises
    ------
    InputRejected
        If a coordinate is NaN or infinite.
    """
    xyz = np.array([point.x, point.y, point.z], dtype=np.float64)
    if not np.all(np.isfinite(xyz)):
        raise InputRejected(f'{what} must be finite, got {xyz.tolist()}')
    return xyz


def quaternion_to_array(quaternion: Quaternion, what: str) -> np.ndarray:
    """Unit quaternion (x, y, z, w) of a ``Quaternion`` message.

    An all-zero quaternion counts as "no rotation", as in RViz; others are normalised.

    Raises
    ------
    InputRejected
        If a component is NaN or infinite.
    """
    q = np.array([quaternion.x, quaternion.y, quaternion.z, quaternion.w], dtype=np.float64)
    if not np.all(np.isfinite(q)):
        raise InputRejected(f'{what} orientation must be finite, got {q.tolist()}')
    norm = float(np.linalg.norm(q))
    if norm < _QUATERNION_EPS:
        return np.array(IDENTITY_QUATERNION)
    return q / norm


def pose_stamped_to_pose(msg: PoseStamped, expected_frame: str,
                         what: str) -> Tuple[np.ndarray, np.ndarray]:
    """Position [m] and unit quaternion (x, y, z, w) of a ``PoseStamped`` in the planning frame.

    Raises
    ------
    InputRejected
        For a wrong frame (``NAV2_TF_ERROR``) or non-finite numbers.
    """
    check_frame(msg.header.frame_id, expected_frame, what)
    return (point_to_array(msg.pose.position, f'{what} position'),
            quaternion_to_array(msg.pose.orientation, what))


def pose_stamped_to_point(msg: PoseStamped, expected_frame: str, what: str) -> np.ndarray:
    """Position (3,) [m] of a ``PoseStamped`` in the planning frame."""
    return pose_stamped_to_pose(msg, expected_frame, what)[0]


def odometry_to_point(msg: Odometry, expected_frame: str, what: str = 'odom') -> np.ndarray:
    """Position (3,) [m] of an ``Odometry`` message whose header frame is the planning frame.

    The pose of ``nav_msgs/Odometry`` is given in ``header.frame_id``; ``child_frame_id`` only
    concerns the twist, which the planner does not use.
    """
    check_frame(msg.header.frame_id, expected_frame, what)
    return point_to_array(msg.pose.pose.position, f'{what} position')


def pose_stamped(position: Sequence[float], frame_id: str, stamp_ns: int,
                 orientation: Sequence[float] = IDENTITY_QUATERNION) -> PoseStamped:
    """``PoseStamped`` of a position [m] and a quaternion (x, y, z, w)."""
    msg = PoseStamped()
    msg.header = Header(frame_id=frame_id, stamp=time_from_ns(stamp_ns))
    msg.pose = _pose(position, orientation)
    return msg


def _pose(position: Sequence[float], orientation: Sequence[float]) -> Pose:
    x, y, z = (float(v) for v in position)
    qx, qy, qz, qw = (float(v) for v in orientation)
    return Pose(position=Point(x=x, y=y, z=z), orientation=Quaternion(x=qx, y=qy, z=qz, w=qw))


def yaw_quaternion(yaw: float) -> Tuple[float, float, float, float]:
    """Unit quaternion (x, y, z, w) of a rotation by ``yaw`` [rad] about +z."""
    half = 0.5 * float(yaw)
    return (0.0, 0.0, math.sin(half), math.cos(half))


def quaternion_yaw(quaternion: Sequence[float]) -> float:
    """Yaw [rad] (rotation about +z) of a quaternion (x, y, z, w)."""
    x, y, z, w = (float(v) for v in quaternion)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def path_yaws(positions: np.ndarray, fallback_yaw: float = 0.0) -> np.ndarray:
    """Heading [rad] of each point of a polyline: the direction of the next horizontal step.

    Vertical stretches keep the heading they were entered with (a quadcopter climbs without
    turning); a path without any horizontal motion gets ``fallback_yaw`` everywhere.

    Parameters
    ----------
    positions : numpy.ndarray, shape (M, 3)
        Path points [m].
    fallback_yaw : float
        Heading [rad] used before the first horizontal step and when there is none.

    Returns
    -------
    numpy.ndarray, shape (M,)
    """
    pts = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    count = len(pts)
    yaws = np.full(count, float(fallback_yaw))
    if count < 2:
        return yaws
    steps = np.diff(pts[:, :2], axis=0)
    # Point i heads along step i; the last point continues along the last step.
    steps = np.vstack([steps, steps[-1:]])
    horizontal = np.hypot(steps[:, 0], steps[:, 1]) > _HEADING_EPS
    if not np.any(horizontal):
        return yaws
    raw = np.arctan2(steps[:, 1], steps[:, 0])
    # Forward-fill headings over vertical stretches, back-fill before the first horizontal step.
    index = np.where(horizontal, np.arange(count), -1)
    np.maximum.accumulate(index, out=index)
    first = int(np.argmax(horizontal))
    index[index < 0] = first
    return raw[index]


# --------------------------------------------------------------------------------------------
# Obstacles from markers
# --------------------------------------------------------------------------------------------

def _rotation_matrix(q: np.ndarray) -> np.ndarray:
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def marker_to_obstacle(marker: Marker, max_size: float) -> Obstacle:
    """Obstacle enclosing one ``SPHERE`` or ``CUBE`` marker (action ADD).

    A ``SPHERE`` becomes the sphere of radius ``max(scale) / 2``, which encloses the ellipsoid
    RViz draws; a ``CUBE`` becomes its axis-aligned bounding box, exact when unrotated.
    Enclosing shapes keep the safety guarantee for every marker the planner accepts.

    Parameters
    ----------
    marker : visualization_msgs.msg.Marker
    max_size : float
        Largest accepted scale component [m]; bigger markers are refused as implausible.

    Raises
    ------
    InputRejected
        For an unsupported type, non-finite pose, or a scale component that is not in
        (0, max_size].
    """
    what = f'marker (ns {marker.ns!r}, id {marker.id})'
    if marker.type not in (Marker.SPHERE, Marker.CUBE):
        raise InputRejected(
            f'{what} has unsupported type {marker.type}; only SPHERE ({Marker.SPHERE}) and '
            f'CUBE ({Marker.CUBE}) describe obstacles')
    center = point_to_array(marker.pose.position, f'{what} position')
    rotation = quaternion_to_array(marker.pose.orientation, what)
    scale = np.array([marker.scale.x, marker.scale.y, marker.scale.z], dtype=np.float64)
    if not np.all(np.isfinite(scale)) or np.any(scale <= 0.0):
        raise InputRejected(f'{what} scale must be finite and > 0 m, got {scale.tolist()}')
    if np.any(scale > max_size):
        raise InputRejected(
            f'{what} scale {scale.tolist()} exceeds max_obstacle_size = {max_size} m')
    if marker.type == Marker.SPHERE:
        return Sphere(center, 0.5 * float(np.max(scale)))
    half = np.abs(_rotation_matrix(rotation)) @ (0.5 * scale)
    return Box(center - half, center + half)


def apply_marker_array(current: Mapping[MarkerKey, Obstacle], msg: MarkerArray,
                       expected_frame: str, max_size: float) -> Dict[MarkerKey, Obstacle]:
    """Apply a ``MarkerArray`` to the obstacles keyed by (ns, id), all or nothing.

    Markers are applied in order: ADD/MODIFY insert or replace, DELETE removes (a missing key is
    not an error), DELETEALL removes every marker, or only those of its namespace when ``ns`` is
    set. Frames are checked for ADD only, because deletions carry no geometry. ``lifetime`` and
    ``frame_locked`` are ignored: an obstacle stays until it is deleted.

    Returns
    -------
    dict
        A new mapping; ``current`` is never modified, so a refused message leaves the previous
        obstacles in force.

    Raises
    ------
    InputRejected
        At the first bad marker, naming it; nothing is applied then.
    """
    updated = dict(current)
    for marker in msg.markers:
        key = (str(marker.ns), int(marker.id))
        if marker.action == Marker.ADD:
            check_frame(marker.header.frame_id, expected_frame,
                        f'marker (ns {marker.ns!r}, id {marker.id})')
            updated[key] = marker_to_obstacle(marker, max_size)
        elif marker.action == Marker.DELETE:
            updated.pop(key, None)
        elif marker.action == Marker.DELETEALL:
            if marker.ns:
                updated = {k: v for k, v in updated.items() if k[0] != marker.ns}
            else:
                updated = {}
        else:
            raise InputRejected(
                f'marker (ns {marker.ns!r}, id {marker.id}) has unknown action {marker.action}')
    return updated


def same_obstacle(first: Obstacle, second: Obstacle) -> bool:
    """True when two obstacles have the same shape and the same numbers."""
    if first is second:
        return True
    if type(first) is not type(second):
        return False
    if isinstance(first, Sphere):
        return (first.radius == second.radius
                and bool(np.array_equal(first.center, second.center)))
    if isinstance(first, Box):
        return (bool(np.array_equal(first.min, second.min))
                and bool(np.array_equal(first.max, second.max)))
    return bool(np.array_equal(first.points, second.points))


def same_marker_obstacles(first: Mapping[MarkerKey, Obstacle],
                          second: Mapping[MarkerKey, Obstacle]) -> bool:
    """True when two (ns, id)-keyed obstacle maps hold the same keys and the same shapes.

    An empty ``MarkerArray``, a DELETE of an unknown marker or a republished map change nothing.
    """
    return (first.keys() == second.keys()
            and all(same_obstacle(first[key], second[key]) for key in first))


# --------------------------------------------------------------------------------------------
# Obstacles from point clouds
# --------------------------------------------------------------------------------------------

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


def combine_obstacles(markers: Mapping[MarkerKey, Obstacle],
                      cloud: Optional[np.ndarray]) -> ObstacleSet:
    """One :class:`ObstacleSet` of the marker obstacles (in key order) and the cloud points."""
    items = [markers[key] for key in sorted(markers)]
    if cloud is not None and len(cloud):
        items.append(PointSet(cloud))
    return ObstacleSet(items)


# --------------------------------------------------------------------------------------------
# Plans out
# --------------------------------------------------------------------------------------------

def points_to_path(points: np.ndarray, frame_id: str, stamp_ns: int,
                   times: Optional[np.ndarray] = None,
                   goal_orientation: Optional[Sequence[float]] = None) -> Path:
    """``nav_msgs/Path`` of a polyline, heading along the path, goal orientation at the end.

    Parameters
    ----------
    points : numpy.ndarray, shape (M, 3)
        Path positions [m].
    frame_id : str
    stamp_ns : int
        Plan time [ns]: the header stamp and, with ``times``, the start of the pose stamps.
    times : numpy.ndarray, shape (M,), optional
        Time from start of each pose [s]; pose stamps are ``stamp + times``. Without it every
        pose carries the header stamp.
    goal_orientation : sequence of 4 float, optional
        Quaternion (x, y, z, w) of the last pose; default: the heading of the last step.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    fallback = quaternion_yaw(goal_orientation) if goal_orientation is not None else 0.0
    yaws = path_yaws(pts, fallback)
    msg = Path()
    msg.header = Header(frame_id=frame_id, stamp=time_from_ns(stamp_ns))
    poses = []
    for index, (position, yaw) in enumerate(zip(pts, yaws)):
        offset_ns = 0 if times is None else int(round(float(times[index]) * 1e9))
        orientation = yaw_quaternion(yaw)
        if index == len(pts) - 1 and goal_orientation is not None:
            orientation = tuple(goal_orientation)
        poses.append(pose_stamped(position, frame_id, stamp_ns + offset_ns, orientation))
    msg.poses = poses
    return msg


def plan_to_path(result: PlanResult, frame_id: str, stamp_ns: int,
                 goal_orientation: Optional[Sequence[float]] = None) -> Path:
    """Smoothed, time-stamped path of a successful plan (pose stamps = plan time + times)."""
    trajectory = _require_trajectory(result)
    return points_to_path(trajectory.positions, frame_id, stamp_ns, trajectory.times,
                          goal_orientation)


def plan_to_unsmoothed_path(result: PlanResult, frame_id: str, stamp_ns: int,
                            goal_orientation: Optional[Sequence[float]] = None) -> Path:
    """Grid-node path of a plan (all poses stamped with the plan time)."""
    return points_to_path(result.path, frame_id, stamp_ns, None, goal_orientation)


def plan_to_trajectory(result: PlanResult, frame_id: str, stamp_ns: int,
                       goal_orientation: Optional[Sequence[float]] = None,
                       joint_name: str = 'base_link') -> MultiDOFJointTrajectory:
    """``MultiDOFJointTrajectory`` with one joint: positions, yaw, velocities, accelerations.

    Angular velocities and accelerations are zero: the planner does not time the heading.
    """
    trajectory = _require_trajectory(result)
    positions = trajectory.positions
    fallback = quaternion_yaw(goal_orientation) if goal_orientation is not None else 0.0
    yaws = path_yaws(positions, fallback)
    msg = MultiDOFJointTrajectory()
    msg.header = Header(frame_id=frame_id, stamp=time_from_ns(stamp_ns))
    msg.joint_names = [joint_name]
    points = []
    last = len(positions) - 1
    for index in range(len(positions)):
        x, y, z = (float(v) for v in positions[index])
        q = yaw_quaternion(yaws[index])
        if index == last and goal_orientation is not None:
            q = tuple(goal_orientation)
        point = MultiDOFJointTrajectoryPoint()
        point.transforms = [Transform(translation=Vector3(x=x, y=y, z=z),
                                      rotation=Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]))]
        point.velocities = [Twist(linear=_vector3(trajectory.velocities[index]))]
        point.accelerations = [Twist(linear=_vector3(trajectory.accelerations[index]))]
        point.time_from_start = duration_from_seconds(trajectory.times[index])
        points.append(point)
    msg.points = points
    return msg


def empty_trajectory(frame_id: str, stamp_ns: int,
                     joint_name: str = 'base_link') -> MultiDOFJointTrajectory:
    """A trajectory without points: withdraws a latched one."""
    msg = MultiDOFJointTrajectory()
    msg.header = Header(frame_id=frame_id, stamp=time_from_ns(stamp_ns))
    msg.joint_names = [joint_name]
    return msg


def path_to_points(msg: Path) -> np.ndarray:
    """Positions (M, 3) [m] of the poses of a ``nav_msgs/Path``."""
    return np.array([[p.pose.position.x, p.pose.position.y, p.pose.position.z]
                     for p in msg.poses], dtype=np.float64).reshape(-1, 3)


def _vector3(values: Sequence[float]) -> Vector3:
    x, y, z = (float(v) for v in values)
    return Vector3(x=x, y=y, z=z)


def _require_trajectory(result: PlanResult):
    if result.trajectory is None:
        raise ValueError(f'plan has no trajectory (status {result.status.value})')
    return result.trajectory


# --------------------------------------------------------------------------------------------
# Diagnostics
# --------------------------------------------------------------------------------------------

def format_value(value) -> str:
    """Diagnostics text of a value: floats with 4 decimals, arrays as [x, y, z]."""
    if isinstance(value, (bool, np.bool_)):
        return 'true' if value else 'false'
    if isinstance(value, (float, np.floating)):
        return f'{float(value):.4f}'
    if isinstance(value, np.ndarray):
        return '[' + ', '.join(f'{float(v):.4f}' for v in value.ravel()) + ']'
    return str(value)


def diagnostic_array(stamp_ns: int, name: str, hardware_id: str, level: bytes, message: str,
                     values: Mapping[str, object]) -> DiagnosticArray:
    """A ``DiagnosticArray`` with a single status.

    Parameters
    ----------
    level : bytes
        ``DiagnosticStatus.OK``, ``WARN`` or ``ERROR``.
    values : mapping
        Key values, formatted with :func:`format_value`.
    """
    status = DiagnosticStatus(level=level, name=name, message=message, hardware_id=hardware_id)
    status.values = [KeyValue(key=str(k), value=format_value(v)) for k, v in values.items()]
    msg = DiagnosticArray()
    msg.header = Header(stamp=time_from_ns(stamp_ns))
    msg.status = [status]
    return msg


def plan_diagnostic_values(result: PlanResult, start_source: str,
                           extra: Optional[Mapping[str, object]] = None) -> Dict[str, object]:
    """Key values of one plan attempt: outcome, Nav2 code, timing, lengths, delta/gamma/eta."""
    values: Dict[str, object] = {
        'event': 'plan',
        'status': result.status.value,
        'status_code': NAV2_CODE_BY_STATUS[result.status],
        'algorithm': result.algorithm,
        'planning_time_s': result.planning_time_s,
        'grid_build_time_s': result.grid_build_time_s,
        'smoothing_time_s': result.smoothing_time_s,
        'expanded_nodes': result.expanded_nodes,
        'path_length_m': result.path_length_m,
        'smoothed_length_m': result.smoothed_length_m,
        'duration_s': result.duration_s,
        'energy_wh': result.energy.energy_wh if result.energy is not None else float('nan'),
        'min_clearance_m': result.min_clearance_m,
        'resolution_m': result.resolution,
        'safety_margin_m': result.safety_margin,
        'adaptive_threshold_m': result.adaptive_threshold,
        'start_source': start_source,
        'start': result.start,
        'goal': result.goal,
    }
    values.update(extra or {})
    return values


def diagnostic_values(msg: DiagnosticArray) -> Iterable[Tuple[DiagnosticStatus, Dict[str, str]]]:
    """(status, {key: value}) of each status in a ``DiagnosticArray`` (for readers and tests)."""
    return [(status, {kv.key: kv.value for kv in status.values}) for status in msg.status]


# --------------------------------------------------------------------------------------------
# Markers out
# --------------------------------------------------------------------------------------------

_OBSTACLE_COLOR = ColorRGBA(r=0.8, g=0.2, b=0.2, a=0.9)
_INFLATED_COLOR = ColorRGBA(r=1.0, g=0.6, b=0.1, a=0.25)


def _marker(frame_id: str, stamp_ns: int, ns: str, marker_id: int, marker_type: int,
            color: ColorRGBA) -> Marker:
    marker = Marker()
    marker.header = Header(frame_id=frame_id, stamp=time_from_ns(stamp_ns))
    marker.ns, marker.id, marker.type, marker.action = ns, marker_id, marker_type, Marker.ADD
    marker.pose.orientation.w = 1.0
    marker.color = color
    return marker


def _set_scale(marker: Marker, size: Sequence[float]) -> None:
    marker.scale = _vector3(size)


def obstacle_markers(obstacles: ObstacleSet, frame_id: str, stamp_ns: int,
                     safety_margin: float, max_points: int = 20_000) -> MarkerArray:
    """Obstacles as used by the planner, for RViz, after a DELETEALL that clears stale ones.

    Namespace ``obstacles`` draws the obstacles themselves, ``inflated`` each grown by the
    safety margin gamma (boxes as their grown bounding box; the true inflated box has rounded
    edges, so the drawing is slightly conservative), and point sets as sphere lists (at most
    ``max_points`` points, evenly subsampled, so a large cloud cannot flood RViz).
    """
    gamma = float(safety_margin)
    clear = Marker(action=Marker.DELETEALL)
    clear.header = Header(frame_id=frame_id, stamp=time_from_ns(stamp_ns))
    markers = [clear]
    next_id = {'obstacles': 0, 'inflated': 0}

    def add(ns: str, marker_type: int, color: ColorRGBA, center, size) -> Marker:
        marker = _marker(frame_id, stamp_ns, ns, next_id[ns], marker_type, color)
        next_id[ns] += 1
        marker.pose.position = Point(x=float(center[0]), y=float(center[1]),
                                     z=float(center[2]))
        _set_scale(marker, size)
        markers.append(marker)
        return marker

    for center, radius in zip(obstacles.sphere_centers, obstacles.sphere_radii):
        add('obstacles', Marker.SPHERE, _OBSTACLE_COLOR, center, [2 * radius] * 3)
        add('inflated', Marker.SPHERE, _INFLATED_COLOR, center, [2 * (radius + gamma)] * 3)
    for lo, hi in zip(obstacles.box_mins, obstacles.box_maxs):
        center = 0.5 * (lo + hi)
        add('obstacles', Marker.CUBE, _OBSTACLE_COLOR, center, hi - lo)
        add('inflated', Marker.CUBE, _INFLATED_COLOR, center, hi - lo + 2 * gamma)
    points = obstacles.points
    if len(points):
        stride = max(1, int(math.ceil(len(points) / max_points)))
        shown = [Point(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in points[::stride]]
        raw = add('obstacles', Marker.CUBE_LIST, _OBSTACLE_COLOR, (0.0, 0.0, 0.0),
                  [0.05] * 3)
        raw.points = shown
        if gamma > 0.0:
            grown = add('inflated', Marker.SPHERE_LIST, _INFLATED_COLOR, (0.0, 0.0, 0.0),
                        [2 * gamma] * 3)
            grown.points = shown
    msg = MarkerArray()
    msg.markers = markers
    return msg


def obstacle_input_markers(obstacles: ObstacleSet, frame_id: str, stamp_ns: int,
                           ns: str = 'scene') -> MarkerArray:
    """Spheres and boxes of an obstacle set as the planner's ``obstacles`` input.

    Starts with a DELETEALL of ``ns``, so republishing replaces the previous scene. Point sets
    are not included; send them as a cloud (:func:`points_to_cloud`).
    """
    clear = Marker(ns=ns, action=Marker.DELETEALL)
    clear.header = Header(frame_id=frame_id, stamp=time_from_ns(stamp_ns))
    markers = [clear]
    for center, radius in zip(obstacles.sphere_centers, obstacles.sphere_radii):
        marker = _marker(frame_id, stamp_ns, ns, len(markers) - 1, Marker.SPHERE,
                         _OBSTACLE_COLOR)
        marker.pose.position = Point(x=float(center[0]), y=float(center[1]),
                                     z=float(center[2]))
        _set_scale(marker, [2.0 * float(radius)] * 3)
        markers.append(marker)
    for lo, hi in zip(obstacles.box_mins, obstacles.box_maxs):
        marker = _marker(frame_id, stamp_ns, ns, len(markers) - 1, Marker.CUBE,
                         _OBSTACLE_COLOR)
        center = 0.5 * (lo + hi)
        marker.pose.position = Point(x=float(center[0]), y=float(center[1]),
                                     z=float(center[2]))
        _set_scale(marker, hi - lo)
        markers.append(marker)
    msg = MarkerArray()
    msg.markers = markers
    return msg
