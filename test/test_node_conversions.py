"""Message conversions of the node, in-process (no rclpy, only the message classes)."""

import math

from diagnostic_msgs.msg import DiagnosticStatus
from helpers.ros_messages import duration_to_seconds
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from sensor_msgs.msg import PointField
from visualization_msgs.msg import Marker

from ros_harness import marker, marker_array, odom_msg, pose_msg
from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, Sphere
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.status import NAV2_TF_ERROR, NAV2_UNKNOWN, PlanStatus
from uav_global_planner.ros import conversions as conv

SMALL = PlannerConfig(bounds_min=(0.0, 0.0, 0.0), bounds_max=(6.0, 6.0, 4.0), resolution=0.25,
                      safety_margin=0.2)


@pytest.fixture(scope='module')
def plan_result():
    obstacles = ObstacleSet([Sphere([3.0, 3.0, 2.0], 1.0)])
    result = Planner(SMALL, obstacles).plan([0.5, 0.5, 1.0], [5.5, 5.5, 3.0])
    assert result.ok, result.message
    return result


# ------------------------------------------------------------------------------ poses, frames

def test_pose_in_planning_frame_gives_point_and_unit_quaternion():
    position, orientation = conv.pose_stamped_to_pose(
        pose_msg([1.0, 2.0, 3.0], 'map', (0.0, 0.0, 2.0, 0.0)), 'map', 'goal_pose')
    assert position.tolist() == [1.0, 2.0, 3.0]
    assert orientation.tolist() == [0.0, 0.0, 1.0, 0.0]


def test_leading_slash_frame_is_the_same_frame():
    assert conv.pose_stamped_to_point(pose_msg([1.0, 2.0, 3.0], '/map'), 'map', 'goal').size == 3


def test_zero_quaternion_counts_as_no_rotation():
    msg = pose_msg([0.0, 0.0, 0.0], 'map', (0.0, 0.0, 0.0, 0.0))
    _, orientation = conv.pose_stamped_to_pose(msg, 'map', 'goal_pose')
    assert orientation.tolist() == list(conv.IDENTITY_QUATERNION)


@pytest.mark.parametrize('position', [[math.nan, 0.0, 1.0], [0.0, math.inf, 1.0]])
def test_non_finite_pose_is_refused(position):
    with pytest.raises(conv.InputRejected, match='must be finite') as caught:
        conv.pose_stamped_to_point(pose_msg(position), 'map', 'goal_pose')
    assert caught.value.code == NAV2_UNKNOWN


def test_wrong_frame_is_refused_with_tf_error():
    with pytest.raises(conv.InputRejected, match="frame 'odom'") as caught:
        conv.pose_stamped_to_point(pose_msg([0.0, 0.0, 1.0], 'odom'), 'map', 'goal_pose')
    assert caught.value.code == NAV2_TF_ERROR


def test_odometry_uses_header_frame():
    assert conv.odometry_to_point(odom_msg([1.0, 2.0, 3.0]), 'map').tolist() == [1.0, 2.0, 3.0]
    with pytest.raises(conv.InputRejected):
        conv.odometry_to_point(odom_msg([1.0, 2.0, 3.0], 'odom'), 'map')
    assert isinstance(odom_msg([0, 0, 0]), Odometry)


def test_time_round_trip():
    stamp_ns = 1_700_000_000_123_456_789
    assert conv.time_to_ns(conv.time_from_ns(stamp_ns)) == stamp_ns
    assert duration_to_seconds(conv.duration_from_seconds(2.5)) == 2.5


# ------------------------------------------------------------------------------ markers

def test_sphere_marker_radius_is_half_the_largest_scale():
    obstacle = conv.marker_to_obstacle(marker('a', 1, Marker.SPHERE, [1, 2, 3], [1, 2, 4]), 100)
    assert isinstance(obstacle, Sphere)
    assert obstacle.radius == 2.0
    assert obstacle.center.tolist() == [1.0, 2.0, 3.0]


def test_cube_marker_is_an_axis_aligned_box():
    obstacle = conv.marker_to_obstacle(marker('a', 1, Marker.CUBE, [1, 2, 3], [2, 4, 6]), 100)
    assert isinstance(obstacle, Box)
    assert obstacle.min.tolist() == [0.0, 0.0, 0.0]
    assert obstacle.max.tolist() == [2.0, 4.0, 6.0]


def test_rotated_cube_is_enclosed_by_its_bounding_box():
    yaw45 = conv.yaw_quaternion(math.pi / 4)
    obstacle = conv.marker_to_obstacle(
        marker('a', 1, Marker.CUBE, [0, 0, 0], [2, 2, 2], orientation=yaw45), 100)
    half = math.sqrt(2.0)
    assert obstacle.max[:2] == pytest.approx([half, half])
    assert obstacle.max[2] == pytest.approx(1.0)
    # Every corner of the rotated cube lies inside the box.
    c = s = math.sqrt(0.5)
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])    # 45 deg about +z
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    rotated = corners @ rotation.T
    assert np.all(rotated <= obstacle.max + 1e-12) and np.all(rotated >= obstacle.min - 1e-12)


@pytest.mark.parametrize('bad, match', [
    (dict(scale=[0.0, 1.0, 1.0]), 'scale must be finite and > 0'),
    (dict(scale=[-1.0, 1.0, 1.0]), 'scale must be finite and > 0'),
    (dict(scale=[1.0, math.nan, 1.0]), 'scale must be finite and > 0'),
    (dict(scale=[1e6, 1.0, 1.0]), 'exceeds max_obstacle_size'),
    (dict(center=[math.nan, 0.0, 0.0]), 'must be finite'),
    (dict(marker_type=Marker.ARROW), 'unsupported type'),
    (dict(marker_type=Marker.TEXT_VIEW_FACING), 'unsupported type'),
])
def test_bad_markers_are_refused(bad, match):
    fields = dict(marker_type=Marker.SPHERE, center=[1.0, 1.0, 1.0], scale=[1.0, 1.0, 1.0])
    fields.update(bad)
    with pytest.raises(conv.InputRejected, match=match):
        conv.marker_to_obstacle(marker('ns', 7, **fields), 100.0)


def test_marker_actions_by_namespace_and_id():
    sphere = marker('a', 1, Marker.SPHERE, [1, 1, 1], [1, 1, 1])
    cube = marker('b', 1, Marker.CUBE, [3, 3, 3], [1, 1, 1])
    state = conv.apply_marker_array({}, marker_array(sphere, cube), 'map', 100.0)
    assert sorted(state) == [('a', 1), ('b', 1)]
    moved = marker('a', 1, Marker.SPHERE, [2, 2, 2], [1, 1, 1])
    state = conv.apply_marker_array(state, marker_array(moved), 'map', 100.0)
    assert state[('a', 1)].center.tolist() == [2.0, 2.0, 2.0]
    delete = marker('a', 1, Marker.SPHERE, [0, 0, 0], [0, 0, 0], action=Marker.DELETE)
    state = conv.apply_marker_array(state, marker_array(delete), 'map', 100.0)
    assert sorted(state) == [('b', 1)]
    state = conv.apply_marker_array(state, marker_array(sphere), 'map', 100.0)
    clear_b = Marker(ns='b', action=Marker.DELETEALL)
    assert sorted(conv.apply_marker_array(state, marker_array(clear_b), 'map', 100.0)) == [
        ('a', 1)]
    clear_all = Marker(action=Marker.DELETEALL)
    assert conv.apply_marker_array(state, marker_array(clear_all, cube), 'map', 100.0).keys() \
        == {('b', 1)}


def test_bad_marker_array_changes_nothing():
    state = conv.apply_marker_array(
        {}, marker_array(marker('a', 1, Marker.SPHERE, [1, 1, 1], [1, 1, 1])), 'map', 100.0)
    bad = marker_array(Marker(action=Marker.DELETEALL),
                       marker('a', 2, Marker.SPHERE, [1, 1, 1], [1, 1, 1], frame_id='odom'))
    with pytest.raises(conv.InputRejected) as caught:
        conv.apply_marker_array(state, bad, 'map', 100.0)
    assert caught.value.code == NAV2_TF_ERROR
    assert sorted(state) == [('a', 1)]


def test_unknown_marker_action_is_refused():
    with pytest.raises(conv.InputRejected, match='unknown action'):
        conv.apply_marker_array({}, marker_array(
            marker('a', 1, Marker.SPHERE, [1, 1, 1], [1, 1, 1], action=1)), 'map', 100.0)


def test_scene_markers_round_trip():
    obstacles = ObstacleSet([Sphere([1, 2, 3], 0.5), Box([0, 0, 0], [1, 2, 3])])
    msg = conv.obstacle_input_markers(obstacles, 'map', 0)
    state = conv.apply_marker_array({}, msg, 'map', 100.0)
    again = conv.combine_obstacles(state, None)
    points = np.random.default_rng(1).uniform(-2, 5, size=(200, 3))
    assert np.allclose(again.distance(points), obstacles.distance(points))


# ------------------------------------------------------------------------------ point clouds

def _cloud(points, **changes):
    msg = conv.points_to_cloud(np.asarray(points, dtype=float), 'map', 0)
    for key, value in changes.items():
        setattr(msg, key, value)
    return msg


def test_cloud_round_trip_and_nan_removal():
    points = np.array([[1.0, 2.0, 3.0], [math.nan, 0.0, 0.0], [4.0, 5.0, 6.0]])
    out = conv.cloud_to_points(_cloud(points), 'map')
    assert out.tolist() == [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]
    with pytest.raises(conv.InputRejected, match='NaN/inf'):
        conv.cloud_to_points(_cloud(points), 'map', drop_non_finite=False)


def test_cloud_with_padding_float64_and_row_step():
    # Two rows of two points, x/y/z float64 plus an intensity, 8 padding bytes per row.
    layout = np.dtype({'names': ['x', 'y', 'z', 'i'], 'formats': ['<f8', '<f8', '<f8', '<f4'],
                       'offsets': [0, 8, 16, 24], 'itemsize': 32})
    rows = np.zeros((2, 2), dtype=layout)
    rows['x'] = [[1, 2], [3, 4]]
    rows['y'] = 10
    rows['z'] = 20
    data = b''.join(row.tobytes() + bytes(8) for row in rows)
    msg = _cloud(np.zeros((0, 3)), height=2, width=2, point_step=32, row_step=72, data=data)
    msg.fields = [PointField(name=n, offset=o, datatype=PointField.FLOAT64, count=1)
                  for n, o in (('x', 0), ('y', 8), ('z', 16))]
    out = conv.cloud_to_points(msg, 'map')
    assert out[:, 0].tolist() == [1.0, 2.0, 3.0, 4.0]
    assert np.all(out[:, 1] == 10.0) and np.all(out[:, 2] == 20.0)


def test_big_endian_cloud():
    points = np.array([[1.5, -2.0, 3.25]], dtype='>f4')
    msg = _cloud(np.zeros((0, 3)), width=1, point_step=12, row_step=12, is_bigendian=True,
                 data=points.tobytes())
    assert conv.cloud_to_points(msg, 'map').tolist() == [[1.5, -2.0, 3.25]]


@pytest.mark.parametrize('change, match', [
    ('missing_z', "no 'z' field"),
    ('int_field', 'FLOAT32 or FLOAT64'),
    ('small_point_step', 'does not fit in point_step'),
    ('truncated', 'truncated'),
    ('small_row_step', 'row_step'),
    ('too_many', 'max_cloud_points'),
    ('frame', 'frame'),
])
def test_bad_clouds_are_refused(change, match):
    msg = _cloud([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    limit = 1000
    if change == 'missing_z':
        msg.fields = msg.fields[:2]
    elif change == 'int_field':
        msg.fields[2].datatype = PointField.INT32
    elif change == 'small_point_step':
        msg.point_step, msg.row_step = 8, 16
    elif change == 'truncated':
        msg.data = bytes(msg.data)[:-4]
    elif change == 'small_row_step':
        msg.row_step = 12
    elif change == 'too_many':
        limit = 1
    elif change == 'frame':
        msg.header.frame_id = 'base_link'
    with pytest.raises(conv.InputRejected, match=match):
        conv.cloud_to_points(msg, 'map', max_points=limit)


def test_empty_cloud_is_no_points():
    assert conv.cloud_to_points(_cloud(np.zeros((0, 3))), 'map').shape == (0, 3)


# ------------------------------------------------------------------------------ plans out

def test_path_stamps_follow_the_trajectory_times(plan_result):
    goal_q = conv.yaw_quaternion(1.0)
    stamp_ns = 5_000_000_000
    path = conv.plan_to_path(plan_result, 'map', stamp_ns, goal_q)
    times = plan_result.trajectory.times
    assert len(path.poses) == len(times)
    assert conv.time_to_ns(path.header.stamp) == stamp_ns
    offsets = [conv.time_to_ns(p.header.stamp) - stamp_ns for p in path.poses]
    assert np.allclose(np.array(offsets) * 1e-9, times, atol=1e-9)
    last = path.poses[-1].pose.orientation
    assert (last.x, last.y, last.z, last.w) == pytest.approx(goal_q)
    assert np.allclose(conv.path_to_points(path), plan_result.trajectory.positions)


def test_path_heading_follows_the_motion(plan_result):
    path = conv.plan_to_path(plan_result, 'map', 0, None)
    points = conv.path_to_points(path)
    for index in (0, len(points) // 2):
        step = points[index + 1] - points[index]
        q = path.poses[index].pose.orientation
        yaw = conv.quaternion_yaw((q.x, q.y, q.z, q.w))
        assert yaw == pytest.approx(math.atan2(step[1], step[0]), abs=1e-9)


def test_vertical_stretches_keep_the_heading():
    points = np.array([[0, 0, 0], [1, 1, 0], [1, 1, 1], [1, 1, 2], [1, 2, 2]], dtype=float)
    yaws = conv.path_yaws(points)
    # Points 1 and 2 climb straight up: they keep the heading of point 0.
    assert yaws[:3] == pytest.approx([math.pi / 4] * 3)
    assert yaws[3:] == pytest.approx([math.pi / 2] * 2)
    assert conv.path_yaws(np.array([[0, 0, 0], [0, 0, 1.0]]), 0.7).tolist() == [0.7, 0.7]


def test_unsmoothed_path_is_the_grid_path(plan_result):
    path = conv.plan_to_unsmoothed_path(plan_result, 'map', 7, None)
    assert np.allclose(conv.path_to_points(path), plan_result.path)
    assert all(conv.time_to_ns(p.header.stamp) == 7 for p in path.poses)


def test_trajectory_message(plan_result):
    """Points every 0.05 s of the continuous reference: state, heading and yaw rate."""
    msg = conv.plan_to_trajectory(plan_result, 'map', 0, conv.yaw_quaternion(0.5))
    trajectory = plan_result.trajectory
    assert msg.joint_names == ['base_link']
    times = np.array([duration_to_seconds(p.time_from_start) for p in msg.points])
    assert times[0] == 0.0 and times[-1] == pytest.approx(trajectory.duration_s, abs=1e-9)
    assert np.allclose(np.diff(times)[:-1], 0.05, atol=1e-9)
    assert 0.0 < times[-1] - times[-2] <= 0.05 + 1e-9
    middle = len(msg.points) // 2
    point = msg.points[middle]
    state = trajectory.state_at(times[middle])
    position = point.transforms[0].translation
    assert [position.x, position.y, position.z] == pytest.approx(state.position[0].tolist())
    assert point.velocities[0].linear.x == pytest.approx(state.velocity[0][0])
    assert point.velocities[0].angular.z == pytest.approx(state.yaw_rate[0])
    assert point.accelerations[0].linear.z == pytest.approx(state.acceleration[0][2])
    rotation = point.transforms[0].rotation
    assert 2.0 * np.arctan2(rotation.z, rotation.w) == pytest.approx(
        np.angle(np.exp(1j * state.yaw[0])))
    # A longer period gives fewer points of the same reference.
    coarse = conv.plan_to_trajectory(plan_result, 'map', 0, sample_period=0.5)
    assert len(coarse.points) < len(msg.points) / 5


def test_plan_diagnostics_carry_code_and_key_values(plan_result):
    values = conv.plan_diagnostic_values(plan_result, 'odom')
    msg = conv.diagnostic_array(0, '/n: global planner', 'hw', DiagnosticStatus.OK,
                                'ok', values)
    (status, read), = conv.diagnostic_values(msg)
    assert read['status_code'] == '0' and read['status'] == 'ok'
    assert read['start_source'] == 'odom'
    for key in ('algorithm', 'planning_time_s', 'expanded_nodes', 'path_length_m',
                'min_clearance_m', 'safety_margin_m', 'adaptive_threshold_m', 'resolution_m'):
        assert key in read
    assert float(read['safety_margin_m']) == pytest.approx(0.2)


def test_failed_plan_maps_to_nav2_code():
    result = Planner(SMALL, ObstacleSet()).plan([0.5, 0.5, 1.0], [50.0, 0.5, 1.0])
    assert result.status is PlanStatus.GOAL_OUTSIDE_MAP
    assert conv.plan_diagnostic_values(result, 'parameter')['status_code'] == 204
    with pytest.raises(ValueError):
        conv.plan_to_path(result, 'map', 0)


def test_planner_markers_show_the_inflated_margin():
    obstacles = ObstacleSet([Sphere([1, 2, 3], 0.5), Box([0, 0, 0], [1, 2, 3])])
    cloud = conv.combine_obstacles({}, np.random.default_rng(0).uniform(size=(50, 3)))
    msg = conv.obstacle_markers(ObstacleSet(list(obstacles.items) + list(cloud.items)), 'map',
                                0, 0.25)
    assert msg.markers[0].action == Marker.DELETEALL
    inflated = [m for m in msg.markers if m.ns == 'inflated']
    sphere = next(m for m in inflated if m.type == Marker.SPHERE)
    assert sphere.scale.x == pytest.approx(2 * (0.5 + 0.25))
    cube = next(m for m in inflated if m.type == Marker.CUBE)
    assert (cube.scale.x, cube.scale.y, cube.scale.z) == pytest.approx((1.5, 2.5, 3.5))
    spheres = next(m for m in inflated if m.type == Marker.SPHERE_LIST)
    assert len(spheres.points) == 50 and spheres.scale.x == pytest.approx(0.5)
