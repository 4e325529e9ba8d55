"""Plans out: ``nav_msgs/Path`` and ``trajectory_msgs/MultiDOFJointTrajectory`` of a plan.

Each pose heads along the path and the last one takes the goal orientation
(:func:`~uav_global_planner.ros.conversions.poses.pose_array`); pose stamps are the plan time
plus the pose's time from the start (:func:`pose_stamps_ns`). :mod:`uav_global_planner.ros.cdr`
writes the same messages as bytes from the same arrays.
"""

from typing import Dict, Optional, Sequence, Tuple

from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Quaternion, Transform, Twist
from nav_msgs.msg import Path
import numpy as np
from std_msgs.msg import Header
from trajectory_msgs.msg import MultiDOFJointTrajectory, MultiDOFJointTrajectoryPoint

from uav_global_planner.core.result import PlanResult, Trajectory
from uav_global_planner.ros.conversions.poses import pose_array, pose_stamped, vector3
from uav_global_planner.ros.conversions.stamps import seconds_to_ns, time_from_ns


def pose_stamps_ns(stamp_ns: int, count: int, times: Optional[np.ndarray] = None) -> np.ndarray:
    """Stamps (int64 [ns]) of ``count`` poses: ``stamp_ns`` plus each time from start [s].

    Without ``times`` every pose carries ``stamp_ns``.
    """
    if times is None:
        return np.full(count, int(stamp_ns), dtype=np.int64)
    return int(stamp_ns) + seconds_to_ns(times)


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
    poses = pose_array(points, goal_orientation)
    stamps = pose_stamps_ns(stamp_ns, len(poses), times)
    msg = Path()
    msg.header = Header(frame_id=frame_id, stamp=time_from_ns(stamp_ns))
    msg.poses = [pose_stamped(row[:3], frame_id, stamp, row[3:])
                 for row, stamp in zip(poses.tolist(), stamps.tolist())]
    return msg


def plan_to_path(result: PlanResult, frame_id: str, stamp_ns: int,
                 goal_orientation: Optional[Sequence[float]] = None) -> Path:
    """Smoothed, time-stamped path of a successful plan (pose stamps = plan time + times)."""
    points, times = path_samples(result, True)
    return points_to_path(points, frame_id, stamp_ns, times, goal_orientation)


def plan_to_unsmoothed_path(result: PlanResult, frame_id: str, stamp_ns: int,
                            goal_orientation: Optional[Sequence[float]] = None) -> Path:
    """Grid-node path of a plan (all poses stamped with the plan time)."""
    points, times = path_samples(result, False)
    return points_to_path(points, frame_id, stamp_ns, times, goal_orientation)


def path_samples(result: PlanResult,
                 smoothed: bool) -> Tuple[np.ndarray, Optional[np.ndarray]]:
    """Positions and times of a plan's ``Path`` message.

    Parameters
    ----------
    result : PlanResult
    smoothed : bool
        The smoothed trajectory's samples (its positions [m] and times from start [s]), else
        the grid-node path with no times (every pose stamped with the plan time).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray or None)
        Positions, shape (M, 3) [m, map frame], and times, shape (M,) [s], or None.

    Raises
    ------
    ValueError
        For the smoothed path of a failed plan, which has none.
    """
    if not smoothed:
        return result.path, None
    trajectory = require_trajectory(result)
    return trajectory.positions, trajectory.times


#: Default time step of the ``trajectory`` message's points [s].
TRAJECTORY_SAMPLE_PERIOD = 0.05


def trajectory_points(trajectory: Trajectory, period: float,
                      goal_orientation: Optional[Sequence[float]] = None) -> Dict[str, np.ndarray]:
    """The ``trajectory`` message's points as arrays, one row per point.

    A trajectory with a continuous reference is sampled every ``period`` seconds (the last
    point at its end); one rebuilt from samples keeps its own samples. The rotation is the
    reference's heading (yaw about +z, ENU) where the trajectory has one, else the heading
    along the path as in the ``plan`` message.

    Returns
    -------
    dict of numpy.ndarray
        ``times`` (N,) [s], ``positions`` (N, 3) [m], ``quaternions`` (N, 4) (x, y, z, w),
        ``velocities`` (N, 3) [m/s], ``yaw_rates`` (N,) [rad/s], ``accelerations`` (N, 3)
        [m/s^2].
    """
    if trajectory.reference is not None:
        trajectory = trajectory.sampled(period)
    count = len(trajectory.times)
    if trajectory.yaws is not None:
        half = 0.5 * np.asarray(trajectory.yaws, dtype=np.float64)
        quaternions = np.zeros((count, 4))
        quaternions[:, 2] = np.sin(half)
        quaternions[:, 3] = np.cos(half)
    else:
        quaternions = pose_array(trajectory.positions, goal_orientation)[:, 3:]
    rates = (np.zeros(count) if trajectory.yaw_rates is None
             else np.asarray(trajectory.yaw_rates, dtype=np.float64))
    return {'times': np.asarray(trajectory.times, dtype=np.float64),
            'positions': np.asarray(trajectory.positions, dtype=np.float64).reshape(-1, 3),
            'quaternions': quaternions,
            'velocities': np.asarray(trajectory.velocities, dtype=np.float64).reshape(-1, 3),
            'yaw_rates': rates,
            'accelerations': np.asarray(trajectory.accelerations,
                                        dtype=np.float64).reshape(-1, 3)}


def plan_to_trajectory(result: PlanResult, frame_id: str, stamp_ns: int,
                       goal_orientation: Optional[Sequence[float]] = None,
                       joint_name: str = 'base_link',
                       sample_period: float = TRAJECTORY_SAMPLE_PERIOD) -> MultiDOFJointTrajectory:
    """``MultiDOFJointTrajectory`` with one joint, a point every ``sample_period`` seconds.

    Each point has the position and heading (transform), the velocity and yaw rate (twist:
    linear, angular z) and the acceleration (linear; angular zero) of the continuous
    reference, in the planning frame (ENU), at ``time_from_start``.
    """
    points_of = trajectory_points(require_trajectory(result), sample_period, goal_orientation)
    msg = MultiDOFJointTrajectory()
    msg.header = Header(frame_id=frame_id, stamp=time_from_ns(stamp_ns))
    msg.joint_names = [joint_name]
    points = []
    durations = seconds_to_ns(points_of['times']).tolist()
    rows = zip(points_of['positions'].tolist(), points_of['quaternions'].tolist(),
               points_of['velocities'].tolist(), points_of['yaw_rates'].tolist(),
               points_of['accelerations'].tolist(), durations)
    for position, (qx, qy, qz, qw), velocity, yaw_rate, acceleration, duration in rows:
        point = MultiDOFJointTrajectoryPoint()
        point.transforms = [Transform(translation=vector3(position),
                                      rotation=Quaternion(x=qx, y=qy, z=qz, w=qw))]
        twist = Twist(linear=vector3(velocity))
        twist.angular.z = yaw_rate
        point.velocities = [twist]
        point.accelerations = [Twist(linear=vector3(acceleration))]
        sec, nanosec = divmod(duration, 1_000_000_000)
        point.time_from_start = Duration(sec=sec, nanosec=nanosec)
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


def require_trajectory(result: PlanResult) -> Trajectory:
    """The trajectory of a plan.

    Raises
    ------
    ValueError
        For a failed plan, which has none.
    """
    if result.trajectory is None:
        raise ValueError(f'plan has no trajectory (status {result.status.value})')
    return result.trajectory
