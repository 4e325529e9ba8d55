"""Conversions between ROS 2 messages and the planner's numpy types.

Small functions without side effects and without ``rclpy``: only message classes are imported, so
everything here is testable in a plain Python process. Positions are in metres in the planning
frame, times in seconds (``*_ns`` arguments in integer nanoseconds).

Inputs are validated here, and a refused input raises :class:`InputRejected`, whose ``code`` is the
Nav2 ``ComputePathToPose`` result code the node reports in its diagnostics.

This package is the import path (``from uav_global_planner.ros import conversions as conv``);
each function lives in the module of its job:

``stamps``            times and durations
``poses``             frames, positions, orientations, headings, the pose arrays of a path
``marker_obstacles``  obstacles from marker arrays
``clouds``            occupied points from point clouds, and clouds of points
``plans``             plans out (paths, trajectories)
``diagnostics``       diagnostic arrays
``markers``           obstacle drawings
"""

from uav_global_planner.ros.conversions.clouds import cloud_to_points, points_to_cloud
from uav_global_planner.ros.conversions.diagnostics import (diagnostic_array, diagnostic_values,
                                                            format_value,
                                                            plan_diagnostic_values)
from uav_global_planner.ros.conversions.errors import InputRejected
from uav_global_planner.ros.conversions.marker_obstacles import (apply_marker_array,
                                                                 combine_obstacles,
                                                                 marker_to_obstacle, MarkerKey,
                                                                 same_marker_obstacles,
                                                                 same_obstacle)
from uav_global_planner.ros.conversions.markers import obstacle_input_markers, obstacle_markers
from uav_global_planner.ros.conversions.plans import (empty_trajectory, path_to_points,
                                                      plan_to_path, plan_to_trajectory,
                                                      plan_to_unsmoothed_path, points_to_path,
                                                      pose_stamps_ns, require_trajectory)
from uav_global_planner.ros.conversions.poses import (check_frame, IDENTITY_QUATERNION,
                                                      normalize_frame, odometry_to_point,
                                                      path_orientations, path_yaws, point_to_array,
                                                      pose_array, pose_stamped,
                                                      pose_stamped_to_point,
                                                      pose_stamped_to_pose, quaternion_to_array,
                                                      quaternion_yaw, yaw_quaternion,
                                                      yaw_quaternions)
from uav_global_planner.ros.conversions.stamps import (duration_from_seconds, seconds_to_ns,
                                                       time_from_ns, time_to_ns)

__all__ = [
    'apply_marker_array', 'check_frame', 'cloud_to_points', 'combine_obstacles',
    'diagnostic_array', 'diagnostic_values', 'duration_from_seconds', 'empty_trajectory',
    'format_value', 'IDENTITY_QUATERNION', 'InputRejected', 'marker_to_obstacle', 'MarkerKey',
    'normalize_frame', 'obstacle_input_markers', 'obstacle_markers', 'odometry_to_point',
    'path_orientations', 'path_to_points', 'path_yaws', 'plan_diagnostic_values',
    'plan_to_path', 'plan_to_trajectory', 'plan_to_unsmoothed_path', 'point_to_array',
    'points_to_cloud', 'points_to_path', 'pose_array', 'pose_stamped', 'pose_stamped_to_point',
    'pose_stamped_to_pose', 'pose_stamps_ns', 'quaternion_to_array', 'quaternion_yaw',
    'require_trajectory', 'same_marker_obstacles', 'same_obstacle', 'seconds_to_ns',
    'time_from_ns', 'time_to_ns', 'yaw_quaternion', 'yaw_quaternions',
]
