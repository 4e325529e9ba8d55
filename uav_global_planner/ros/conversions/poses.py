"""Frames, positions, orientations and headings of poses, and the pose arrays of a path.

The headings of a published path are computed here once (:func:`path_orientations`), for the
message builders of :mod:`~uav_global_planner.ros.conversions.plans` and for the bytes written
by :mod:`~uav_global_planner.ros.cdr` alike. Rotations are scipy's
:class:`~scipy.spatial.transform.Rotation`; quaternions are (x, y, z, w), as in ROS messages.
"""

from typing import Optional, Sequence, Tuple, Union

from geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion, Vector3
from nav_msgs.msg import Odometry
import numpy as np
from scipy.spatial.transform import Rotation
from std_msgs.msg import Header

from uav_global_planner.core.status import NAV2_TF_ERROR
from uav_global_planner.ros.conversions.errors import InputRejected
from uav_global_planner.ros.conversions.stamps import time_from_ns

#: Unit quaternion (x, y, z, w) of no rotation.
IDENTITY_QUATERNION = (0.0, 0.0, 0.0, 1.0)

# Below this horizontal step [m] the heading of a path segment is undefined (vertical climb), so
# the previous heading is kept instead of a yaw computed from rounding noise.
_HEADING_EPS = 1e-6

# Quaternions shorter than this are treated as "unset" (all zeros), which RViz shows unrotated.
_QUATERNION_EPS = 1e-9

#: A few numbers: a point [m], a vector or a quaternion, as a sequence or a numpy array.
Numbers = Union[Sequence[float], np.ndarray]


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


def pose_stamped(position: Numbers, frame_id: str, stamp_ns: int,
                 orientation: Numbers = IDENTITY_QUATERNION) -> PoseStamped:
    """``PoseStamped`` of a position [m] and a quaternion (x, y, z, w)."""
    msg = PoseStamped()
    msg.header = Header(frame_id=frame_id, stamp=time_from_ns(stamp_ns))
    msg.pose = pose(position, orientation)
    return msg


def pose(position: Numbers, orientation: Numbers) -> Pose:
    """``Pose`` of a position [m] and a quaternion (x, y, z, w)."""
    x, y, z = (float(v) for v in position)
    qx, qy, qz, qw = (float(v) for v in orientation)
    return Pose(position=Point(x=x, y=y, z=z), orientation=Quaternion(x=qx, y=qy, z=qz, w=qw))


def vector3(values: Numbers) -> Vector3:
    """``Vector3`` of three numbers."""
    x, y, z = (float(v) for v in values)
    return Vector3(x=x, y=y, z=z)


def rotation_matrix(quaternion: Numbers) -> np.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion (x, y, z, w)."""
    return Rotation.from_quat(np.asarray(quaternion, dtype=np.float64)).as_matrix()


def yaw_quaternions(yaws) -> np.ndarray:
    """Unit quaternions (M, 4), (x, y, z, w), of rotations by ``yaws`` [rad] about +z."""
    angles = np.asarray(yaws, dtype=np.float64).reshape(-1, 1)
    return Rotation.from_euler('z', angles).as_quat()


def yaw_quaternion(yaw: float) -> Tuple[float, float, float, float]:
    """Unit quaternion (x, y, z, w) of a rotation by ``yaw`` [rad] about +z."""
    x, y, z, w = (float(v) for v in yaw_quaternions([yaw])[0])
    return (x, y, z, w)


def quaternion_yaw(quaternion: Numbers) -> float:
    """Yaw [rad] of a quaternion (x, y, z, w): the heading of the rotated +x axis.

    That is the first angle of the z-y'-x'' (yaw, pitch, roll) decomposition; a zero quaternion
    counts as no rotation.
    """
    q = np.asarray(quaternion, dtype=np.float64)
    if float(np.linalg.norm(q)) < _QUATERNION_EPS:
        return 0.0
    x_axis = Rotation.from_quat(q).as_matrix()[:, 0]
    return float(np.arctan2(x_axis[1], x_axis[0]))


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


def path_orientations(positions: np.ndarray,
                      goal_orientation: Optional[Sequence[float]] = None) -> np.ndarray:
    """Orientations (M, 4), (x, y, z, w), of the poses of a published path.

    Each pose heads along the path (:func:`path_yaws`); the last one takes
    ``goal_orientation`` when given, whose yaw also heads a path without horizontal motion.
    """
    pts = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    fallback = quaternion_yaw(goal_orientation) if goal_orientation is not None else 0.0
    quaternions = yaw_quaternions(path_yaws(pts, fallback))
    if goal_orientation is not None and len(pts):
        quaternions[-1] = [float(v) for v in goal_orientation]
    return quaternions


def pose_array(positions: np.ndarray,
               goal_orientation: Optional[Sequence[float]] = None) -> np.ndarray:
    """Poses (M, 7) of a published path: x, y, z [m] and the quaternion x, y, z, w."""
    pts = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    return np.hstack([pts, path_orientations(pts, goal_orientation)])
