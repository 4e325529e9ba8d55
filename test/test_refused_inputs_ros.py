"""The ROS side of the bad-input catalogue: every refused or awkward input of the planner node.

:data:`CATALOGUE` is the table, one :class:`Case` per input, and doubles as documentation. Rows
with ``covered_by`` are run by the named test elsewhere (kept here so the table is complete;
:func:`test_catalogue_references_exist` keeps those references honest); the others run here,
against one node process in the good state of :func:`good_state`:

* ``refused``: the message is dropped. The node logs ``refused message on <topic>: <reason>``
  and publishes a WARN status with ``event: input_rejected``, the Nav2 ``status_code`` and the
  ``reason`` on ``/diagnostics``. Nothing is replanned, and the obstacles, start and goal in
  force stay as they were.
* ``plan fails``: the input is plausible, but no plan can be made from it. The node logs
  ``no plan (<why>): <status> (code <code>): <message>``, publishes an ERROR status with
  ``event: plan`` and no path; the last plan stays latched.
* ``parameter refused``: the ``SetParametersResult`` has ``successful = false`` and says why;
  the old value stays and nothing is replanned.
* ``map file refused``: the ``map_file`` read at start-up cannot be used (no usable points, all
  outside the bounds, a resolution finer than delta / 100, a non-finite header, unreadable).
  The node runs without it and logs ``refused map_file: <reason>``; its map status on
  ``/diagnostics`` is an ERROR with ``map_file_status: refused`` and ``map_file_refused:
  <reason>``, and every goal (topic or Nav2 action) is refused with the reason until the node is
  restarted with a usable file. These rows run in-process
  (:func:`test_map_file_refused_at_start_up`), one of them as a process
  (``test_node_map_restart.py``), each file written by its format's own library.
* ``accepted``: not an error; the row says what happens.

After every case the node must still plan the next valid request, in the state it had before.

One file, though long: the catalogue is one table that the docs build renders on
``docs/refused_inputs.md`` (``docs/gen_tables.py``), and its rows run against one shared node
process.
"""

from dataclasses import dataclass, field
import math
from pathlib import Path
import time
from typing import Any, Callable, Dict, Iterator, Mapping, Optional

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from helpers.map_files import BLOCK, bt, EMPTY, las, MapFile, NON_FINITE, npy, pcd, ply, UTM
import numpy as np
import pytest
from rclpy.parameter import Parameter
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Header
from visualization_msgs.msg import Marker, MarkerArray

from ros_harness import (assert_clean_exit, in_process_planner, LATCHED_QOS, marker,
                         marker_array, min_clearance, odom_msg, PlannerClient, pose_msg,
                         RosClient, RUN_NAMESPACE, start_planner, unique_domain_id)
from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.core.status import PlanStatus
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros import nav2_interfaces

pytestmark = pytest.mark.ros

HERE = Path(__file__).resolve().parent
NAMESPACE = f'{RUN_NAMESPACE}/refused'
SCENE = load_scene(find_scene('paper_medium'))
GAMMA = 0.2
START = np.array([0.0, -5.0, 0.0])  # the start parameter of config/planner.yaml
GOAL = np.array([8.0, 8.0, 8.0])
GOAL_ORIENTATION = conv.yaw_quaternion(0.3)
SPHERE_CENTER = SCENE.obstacles.sphere_centers[0].tolist()
TOL = 1e-6

REFUSED = 'refused'
PLAN_FAILS = 'plan fails'
PARAMETER_REFUSED = 'parameter refused'
MAP_FILE_REFUSED = 'map file refused'
ACCEPTED = 'accepted'

WARN = int.from_bytes(DiagnosticStatus.WARN, 'little')
ERROR = int.from_bytes(DiagnosticStatus.ERROR, 'little')

_NAN, _INF = math.nan, math.inf


@dataclass(frozen=True)
class Case:
    """One row of the catalogue.

    Attributes
    ----------
    case_id : str
    channel : str
        Topic (relative name) or ``parameter`` / ``parameters (atomic)``.
    given : str
        The input, in words.
    outcome : str
        :data:`REFUSED`, :data:`PLAN_FAILS`, :data:`PARAMETER_REFUSED`,
        :data:`MAP_FILE_REFUSED` or :data:`ACCEPTED`.
    code : int, optional
        Nav2 ``ComputePathToPose`` code in the diagnostics (None for parameters).
    reason : str
        Substring of the reason the user sees (diagnostics ``reason`` or ``message``, the log
        line, or ``SetParametersResult.reason``); for accepted inputs, what happens.
    send : callable or mapping, optional
        Message factory for topic rows, parameter values for parameter rows (start-up values
        for ``map_file`` rows, a :class:`MapFile` written first).
    with_parameters : mapping
        Parameters set for the duration of the case (restored afterwards).
    covered_by : str
        ``file::test`` that runs this case when it is not run by the generic tests here.
    """

    case_id: str
    channel: str
    given: str
    outcome: str
    code: Optional[int]
    reason: str
    send: Any = None
    with_parameters: Mapping[str, Any] = field(default_factory=dict)
    covered_by: str = ''


def _cloud(points, **changes: Any) -> PointCloud2:
    msg = conv.points_to_cloud(np.asarray(points, dtype=float).reshape(-1, 3), 'map', 0)
    for key, value in changes.items():
        setattr(msg, key, value)
    return msg


def _bad_sphere(center=(0.0, 0.0, 1.0), scale=(1.0, 1.0, 1.0), **options: Any) -> MarkerArray:
    return marker_array(marker('bad', 0, Marker.SPHERE, center, scale, **options))


def _unknown_action() -> MarkerArray:
    msg = _bad_sphere()
    msg.markers[0].action = 7
    return msg


def _good_then_bad() -> MarkerArray:
    return marker_array(marker('extra', 0, Marker.SPHERE, (-6.0, -6.0, 8.0), (1.0, 1.0, 1.0)),
                        marker('bad', 1, Marker.CUBE, (0.0, _NAN, 1.0), (1.0, 1.0, 1.0)))


PLANNING = 'test_node_planning.py::test_malformed_input_is_reported_and_refused'
LIVE_MAPS = 'test_node_live_maps.py::'
PLANNING_PARAMS = 'test_node_planning.py::test_invalid_parameter_is_rejected_and_old_value_kept'
THIS = 'test_refused_inputs_ros.py::'
MAP_FILE = 'map_file (start-up)'

CATALOGUE = (
    # ---------------------------------------------------------------- goal_pose
    Case('goal_nan', 'goal_pose', 'position x = NaN', REFUSED, 200,
         'goal_pose position must be finite', covered_by=PLANNING),
    Case('goal_inf', 'goal_pose', 'position y = +inf', REFUSED, 200,
         'goal_pose position must be finite', covered_by=PLANNING),
    Case('goal_orientation_nan', 'goal_pose', 'orientation z = NaN', REFUSED, 200,
         'goal_pose orientation must be finite',
         send=lambda: pose_msg(GOAL, orientation=(0.0, 0.0, _NAN, 1.0))),
    Case('goal_wrong_frame', 'goal_pose', "frame_id 'odom' (planner works in 'map')", REFUSED,
         202, "is in frame 'odom' but the planner works in frame 'map'", covered_by=PLANNING),
    Case('goal_outside_bounds', 'goal_pose', 'x = 50 m, bounds end at 10 m', REFUSED, 204,
         'is outside the bounds', covered_by=PLANNING),
    Case('goal_occupied', 'goal_pose', 'goal at the centre of a sphere obstacle', PLAN_FAILS,
         206, 'goal_occupied',
         covered_by='test_node_planning.py::'
         'test_goal_inside_an_obstacle_fails_with_goal_occupied'),
    Case('goal_sealed_in', 'goal_pose', 'goal inside a closed box of walls', PLAN_FAILS, 208,
         'no_valid_path', covered_by='test_node_lifecycle.py::'
         'test_long_plan_keeps_services_responsive_and_goals_coalesce_then_sigint'),
    Case('goal_occupied_by_new_obstacle', 'obstacles',
         'a sphere put on the active goal after it was planned', PLAN_FAILS, 206,
         'goal_occupied; the latched plan, which now collides, is withdrawn (empty path)',
         covered_by=THIS + 'test_plan_that_a_new_obstacle_invalidates_is_withdrawn'),
    Case('goal_equals_start', 'goal_pose', 'goal exactly at the start', ACCEPTED, 0,
         'ok: a one-pose plan at the goal, duration 0 s',
         covered_by=THIS + 'test_goal_equal_to_start_gives_a_one_pose_plan'),
    Case('goal_frame_leading_slash', 'goal_pose', "frame_id '/map'", ACCEPTED, 0,
         "ok: '/map' is the frame 'map', as in tf2",
         covered_by=THIS + 'test_leading_slash_names_the_same_frame'),
    Case('goal_before_map', 'goal_pose', 'a goal before any map source has delivered',
         PLAN_FAILS, 200, 'no map yet: none of the map sources (obstacles, obstacle_cloud, '
         'map_file) has delivered',
         covered_by=LIVE_MAPS + 'test_a_goal_before_any_map_is_refused_with_the_reason'),
    Case('goal_before_required_map', 'goal_pose',
         "required_map_sources ['obstacle_cloud'] and no cloud yet", PLAN_FAILS, 200,
         'no map yet: required_map_sources obstacle_cloud not delivered',
         covered_by=LIVE_MAPS + 'test_required_sources_are_waited_for'),
    # ---------------------------------------------------------------- start_pose and odom
    Case('start_pose_nan', 'start_pose', 'position x = NaN', REFUSED, 200,
         'start_pose position must be finite', covered_by=PLANNING),
    Case('start_pose_inf', 'start_pose', 'position z = -inf', REFUSED, 200,
         'start_pose position must be finite', send=lambda: pose_msg([0.0, -5.0, -_INF])),
    Case('start_pose_wrong_frame', 'start_pose', "frame_id 'base'", REFUSED, 202,
         "is in frame 'base'", covered_by=PLANNING),
    Case('start_outside_bounds', 'start_pose', 'start z = -1 m, below the bounds', PLAN_FAILS,
         203, 'is outside the bounds', send=lambda: pose_msg([0.0, -5.0, -1.0])),
    Case('start_occupied', 'start_pose', 'start at the centre of a sphere obstacle',
         PLAN_FAILS, 205, 'is within the safety margin', send=lambda: pose_msg(SPHERE_CENTER)),
    Case('start_outside_new_bounds', 'parameters (atomic)',
         'bounds moved so that the start is outside', PLAN_FAILS, 203, 'start_outside_map',
         covered_by='test_node_planning.py::test_bounds_move_atomically'),
    Case('odom_nan', 'odom', 'position y = NaN', REFUSED, 200, 'odom position must be finite',
         covered_by=PLANNING),
    Case('odom_inf', 'odom', 'position x = +inf', REFUSED, 200,
         'odom position must be finite', send=lambda: odom_msg([_INF, 0.0, 1.0])),
    Case('odom_wrong_frame', 'odom', "header.frame_id 'odom'", REFUSED, 202,
         "is in frame 'odom'", covered_by=PLANNING),
    # ---------------------------------------------------------------- obstacles (MarkerArray)
    Case('marker_nan', 'obstacles', 'SPHERE at x = NaN', REFUSED, 200,
         'position must be finite', covered_by=PLANNING),
    Case('marker_inf_position', 'obstacles', 'SPHERE at z = +inf', REFUSED, 200,
         "marker (ns 'bad', id 0) position must be finite",
         send=lambda: _bad_sphere(center=(0.0, 0.0, _INF))),
    Case('marker_nan_orientation', 'obstacles', 'CUBE with orientation x = NaN', REFUSED, 200,
         "marker (ns 'bad', id 0) orientation must be finite",
         send=lambda: marker_array(marker('bad', 0, Marker.CUBE, (0.0, 0.0, 1.0),
                                          (1.0, 1.0, 1.0), orientation=(_NAN, 0.0, 0.0, 1.0)))),
    Case('marker_nan_scale', 'obstacles', 'SPHERE with scale.y = NaN', REFUSED, 200,
         'scale must be finite and > 0 m', send=lambda: _bad_sphere(scale=(1.0, _NAN, 1.0))),
    Case('marker_inf_scale', 'obstacles', 'SPHERE with scale = +inf', REFUSED, 200,
         'scale must be finite and > 0 m', send=lambda: _bad_sphere(scale=(_INF,) * 3)),
    Case('marker_zero_scale', 'obstacles', 'SPHERE of scale 0 (zero radius)', REFUSED, 200,
         'scale must be finite and > 0 m', covered_by=PLANNING),
    Case('marker_flat', 'obstacles', 'SPHERE with scale.z = 0 (a flat disc)', REFUSED, 200,
         'scale must be finite and > 0 m, got [1.0, 1.0, 0.0]',
         send=lambda: _bad_sphere(scale=(1.0, 1.0, 0.0))),
    Case('marker_negative_scale', 'obstacles', 'CUBE with scale.y = -1 (negative size)',
         REFUSED, 200, 'scale must be finite and > 0 m', covered_by=PLANNING),
    Case('marker_huge', 'obstacles', 'SPHERE of diameter 1e9 m', REFUSED, 200,
         'exceeds max_obstacle_size', covered_by=PLANNING),
    Case('marker_unknown_type', 'obstacles', 'ARROW marker', REFUSED, 200,
         'has unsupported type 0; only SPHERE (2) and CUBE (1)', covered_by=PLANNING),
    Case('marker_unknown_action', 'obstacles', 'SPHERE with action = 7', REFUSED, 200,
         'has unknown action 7', send=_unknown_action),
    Case('marker_wrong_frame', 'obstacles', "SPHERE in frame 'odom'", REFUSED, 202,
         "is in frame 'odom'", covered_by=PLANNING),
    Case('marker_delete_all_then_bad', 'obstacles', 'DELETEALL, then a TEXT marker', REFUSED,
         200, 'unsupported type 9', covered_by=PLANNING),
    Case('marker_good_then_bad', 'obstacles', 'a valid SPHERE, then a CUBE at y = NaN',
         REFUSED, 200, "marker (ns 'bad', id 1) position must be finite", send=_good_then_bad),
    Case('markers_empty', 'obstacles', 'MarkerArray without markers', ACCEPTED, None,
         'nothing changes: no replan, the grid is kept',
         covered_by=THIS + 'test_marker_array_that_changes_nothing_is_a_no_op'),
    Case('markers_delete_unknown', 'obstacles', 'DELETE of an (ns, id) never added', ACCEPTED,
         None, 'nothing changes: no replan, the grid is kept',
         covered_by=THIS + 'test_marker_array_that_changes_nothing_is_a_no_op'),
    Case('markers_same_again', 'obstacles', 'the same obstacles republished', ACCEPTED, None,
         'nothing changes: no replan, the grid is kept',
         covered_by=THIS + 'test_marker_array_that_changes_nothing_is_a_no_op'),
    Case('markers_delete_all_ns', 'obstacles', "DELETEALL with ns 'extra'", ACCEPTED, None,
         "removes the markers of ns 'extra' only",
         covered_by=THIS + 'test_delete_all_of_one_namespace_keeps_the_others'),
    Case('markers_delete_all', 'obstacles', 'DELETEALL without ns', ACCEPTED, None,
         'removes every marker obstacle; the next plan flies straight',
         covered_by=THIS + 'test_delete_all_clears_every_marker_obstacle'),
    # ---------------------------------------------------------------- obstacle_cloud
    Case('cloud_missing_z', 'obstacle_cloud', 'fields x and y only', REFUSED, 200,
         "obstacle_cloud has no 'z' field", covered_by=PLANNING),
    Case('cloud_no_fields', 'obstacle_cloud', 'no fields at all', REFUSED, 200,
         "obstacle_cloud has no 'x' field (fields: [])",
         send=lambda: _cloud([[1.0, 1.0, 1.0]], fields=[])),
    Case('cloud_int_field', 'obstacle_cloud', 'z as INT32', REFUSED, 200,
         "field 'z' has type INT32; FLOAT32 or FLOAT64 needed", covered_by=PLANNING),
    Case('cloud_wrong_point_step', 'obstacle_cloud', 'point_step 8 for 12-byte points', REFUSED,
         200, 'does not fit in point_step = 8', covered_by=PLANNING),
    Case('cloud_row_step_short', 'obstacle_cloud', 'row_step 12 for two 12-byte points',
         REFUSED, 200, 'row_step = 12 is below width * point_step = 24',
         send=lambda: _cloud([[1.0, 1.0, 1.0], [2.0, 2.0, 2.0]], row_step=12)),
    Case('cloud_truncated', 'obstacle_cloud', '20 data bytes for two 12-byte points', REFUSED,
         200, 'truncated', covered_by=PLANNING),
    Case('cloud_too_many_points', 'obstacle_cloud', 'width 3,000,000 (max_cloud_points 2e6)',
         REFUSED, 200, 'more than max_cloud_points = 2000000',
         send=lambda: _cloud([[1.0, 1.0, 1.0]], width=3_000_000)),
    Case('cloud_nan_dropped', 'obstacle_cloud', "a NaN point, cloud_non_finite 'drop'",
         ACCEPTED, 0, 'the NaN point is dropped, the others are obstacles',
         covered_by='test_node_planning.py::test_point_cloud_obstacles_are_avoided'),
    Case('cloud_nan_refused', 'obstacle_cloud', "a NaN point, cloud_non_finite 'refuse'",
         REFUSED, 200, "1 points with NaN/inf coordinates and cloud_non_finite is 'refuse'",
         send=lambda: _cloud([[1.0, 1.0, 1.0], [_NAN, 0.0, 0.0]]),
         with_parameters={'cloud_non_finite': 'refuse'}),
    Case('cloud_wrong_frame', 'obstacle_cloud', "frame_id 'velodyne'", REFUSED, 202,
         "is in frame 'velodyne'", covered_by=PLANNING),
    # ---------------------------------------------------------------- parameters
    Case('param_resolution_negative', 'parameter', 'resolution = -1.0', PARAMETER_REFUSED,
         None, 'Parameter resolution out of range Min: 0.0, Max: 100.0',
         send={'resolution': -1.0}, covered_by=PLANNING_PARAMS),
    Case('param_resolution_zero', 'parameter', 'resolution = 0.0', PARAMETER_REFUSED, None,
         'resolution must be in (0.0, 100.0], got 0.0', send={'resolution': 0.0},
         covered_by=PLANNING_PARAMS),
    Case('param_resolution_voxel_cap', 'parameter', 'resolution = 0.001', PARAMETER_REFUSED,
         None, 'nodes exceeds max_voxels = 1200000000; raise the resolution or shrink the bounds',
         send={'resolution': 0.001}, covered_by=PLANNING_PARAMS),
    Case('param_max_voxels_small', 'parameter', 'max_voxels = 100', PARAMETER_REFUSED, None,
         'grid of 41 x 41 x 31 = 5.21e+04 nodes exceeds max_voxels = 100',
         send={'max_voxels': 100}, covered_by=PLANNING_PARAMS),
    Case('param_bounds_voxel_cap', 'parameters (atomic)', 'bounds +-10 km at delta 0.5 m',
         PARAMETER_REFUSED, None, 'nodes exceeds max_voxels = 1200000000',
         send={'bounds.min': [-1.0e4] * 3, 'bounds.max': [1.0e4] * 3}),
    Case('param_bounds_min_above_max', 'parameter', 'bounds.min = [10, 10, 10]',
         PARAMETER_REFUSED, None, 'bounds.min must be below bounds.max on every axis',
         send={'bounds.min': [10.0, 10.0, 10.0]}, covered_by=PLANNING_PARAMS),
    Case('param_bounds_empty_atomic', 'parameters (atomic)',
         'bounds.min = bounds.max on x, set together', PARAMETER_REFUSED, None,
         'bounds.min must be below bounds.max',
         send={'bounds.min': [5.0, -10.0, 0.0], 'bounds.max': [5.0, 10.0, 15.0]}),
    Case('param_bounds_two_numbers', 'parameter', 'bounds.max = [1.0, 2.0]',
         PARAMETER_REFUSED, None, 'bounds.max must be three numbers [x, y, z]',
         send={'bounds.max': [1.0, 2.0]}, covered_by=PLANNING_PARAMS),
    Case('param_bounds_nan', 'parameter', 'bounds.min = [NaN, -10, 0]', PARAMETER_REFUSED,
         None, 'bounds.min[0] must be finite', send={'bounds.min': [_NAN, -10.0, 0.0]}),
    Case('param_bounds_integers', 'parameter', 'bounds.max = [10, 10, 15] (integers)',
         PARAMETER_REFUSED, None, "expected 'Type.DOUBLE_ARRAY' got 'Type.INTEGER_ARRAY'",
         send={'bounds.max': [10, 10, 15]}),
    Case('param_safety_margin_nan', 'parameter', 'safety_margin = NaN', PARAMETER_REFUSED,
         None, 'Parameter safety_margin out of range', send={'safety_margin': _NAN},
         covered_by=PLANNING_PARAMS),
    Case('param_safety_margin_integer', 'parameter', 'safety_margin = 1 (an integer)',
         PARAMETER_REFUSED, None, "expected 'Type.DOUBLE' got 'Type.INTEGER'",
         send={'safety_margin': 1}),
    Case('param_resolution_string', 'parameter', "resolution = 'fine'", PARAMETER_REFUSED,
         None, "expected 'Type.DOUBLE' got 'Type.STRING'", send={'resolution': 'fine'},
         covered_by=PLANNING_PARAMS),
    Case('param_shortcut_string', 'parameter', "shortcut = 'yes'", PARAMETER_REFUSED, None,
         "expected 'Type.BOOL' got 'Type.STRING'", send={'shortcut': 'yes'}),
    Case('param_max_voxels_bool', 'parameter', 'max_voxels = true', PARAMETER_REFUSED, None,
         "expected 'Type.INTEGER' got 'Type.BOOL'", send={'max_voxels': True}),
    Case('param_max_expansions_negative', 'parameter', 'max_expansions = -1',
         PARAMETER_REFUSED, None, 'Parameter max_expansions out of range',
         send={'max_expansions': -1}),
    Case('param_max_speed_zero', 'parameter', 'max_speed_horizontal = 0.0', PARAMETER_REFUSED,
         None, 'max_speed_horizontal must be in (0.0, 1000.0], got 0.0',
         send={'max_speed_horizontal': 0.0}),
    Case('param_max_jerk_zero', 'parameter', 'max_jerk = 0.0', PARAMETER_REFUSED, None,
         'max_jerk must be in (0.0, 10000.0], got 0.0', send={'max_jerk': 0.0}),
    Case('param_max_jerk_negative', 'parameter', 'max_jerk = -5.0', PARAMETER_REFUSED, None,
         'Parameter max_jerk out of range', send={'max_jerk': -5.0}),
    Case('param_max_jerk_nan', 'parameter', 'max_jerk = NaN', PARAMETER_REFUSED, None,
         'Parameter max_jerk out of range', send={'max_jerk': _NAN}),
    Case('param_max_tilt_90', 'parameter', 'max_tilt = 90.0', PARAMETER_REFUSED, None,
         'Parameter max_tilt out of range', send={'max_tilt': 90.0}),
    Case('param_thrust_to_weight_one', 'parameter', 'max_thrust_to_weight = 1.0',
         PARAMETER_REFUSED, None, 'max_thrust_to_weight must be in (1.0, 100.0], got 1.0',
         send={'max_thrust_to_weight': 1.0}),
    Case('param_max_obstacle_size_zero', 'parameter', 'max_obstacle_size = 0.0',
         PARAMETER_REFUSED, None, 'max_obstacle_size must be in (0.0, 1000000.0], got 0.0',
         send={'max_obstacle_size': 0.0}),
    Case('param_algorithm_unknown', 'parameter', "algorithm = 'foo'", PARAMETER_REFUSED, None,
         'algorithm must be one of dijkstra, astar, adaptive, octile, weighted, bounded, '
         "got 'foo'",
         send={'algorithm': 'foo'}, covered_by=PLANNING_PARAMS),
    Case('param_smoothing_unknown', 'parameter', "smoothing = 'bezier'", PARAMETER_REFUSED,
         None, "smoothing must be one of chord, index, none, got 'bezier'",
         send={'smoothing': 'bezier'}, covered_by=PLANNING_PARAMS),
    Case('param_start_inf', 'parameter', 'start = [0, inf, 0]', PARAMETER_REFUSED, None,
         'start[1] must be finite, got inf', send={'start': [0.0, _INF, 0.0]},
         covered_by=PLANNING_PARAMS),
    Case('param_frame_id_empty', 'parameter', "frame_id = ''", PARAMETER_REFUSED, None,
         "frame_id must be a non-empty frame name, got ''", send={'frame_id': ''},
         covered_by=PLANNING_PARAMS),
    Case('param_cloud_non_finite_unknown', 'parameter', "cloud_non_finite = 'keep'",
         PARAMETER_REFUSED, None, "cloud_non_finite must be one of drop, refuse, got 'keep'",
         send={'cloud_non_finite': 'keep'}, covered_by=PLANNING_PARAMS),
    Case('param_undeclared', 'parameter', 'no_such_parameter = 1.0', PARAMETER_REFUSED, None,
         'undeclared parameter', send={'no_such_parameter': 1.0}),
    Case('param_cloud_qos_at_run_time', 'parameter', "cloud_qos_reliability = 'best_effort' "
         'on a running node', PARAMETER_REFUSED, None,
         'Trying to set a read-only parameter: cloud_qos_reliability',
         send={'cloud_qos_reliability': 'best_effort'}),
    Case('param_required_map_sources_unknown', 'parameter',
         "required_map_sources = ['lidar']", PARAMETER_REFUSED, None,
         "required_map_sources must be ['any'] or distinct names among obstacles, "
         'obstacle_cloud, map_file', send={'required_map_sources': ['lidar']}),
    Case('param_search_budget_tiny', 'parameter', 'max_expansions = 1 (valid, too small)',
         PLAN_FAILS, 207, 'search ran out of its expansion budget (max_expansions = 1)',
         send={'max_expansions': 1}),
    # ---------------------------------------------------------------- map_file (start-up)
    Case('map_file_ply_no_points', MAP_FILE, 'a PLY file with 0 vertices (plyfile)',
         MAP_FILE_REFUSED, 200, 'empty.ply: no points: the PLY file holds 0 points',
         send={'map_file': MapFile('empty.ply', ply(EMPTY))}),
    Case('map_file_bt_no_occupied_cells', MAP_FILE, 'an OctoMap .bt with no occupied cell',
         MAP_FILE_REFUSED, 200, 'empty.bt: no points: the OctoMap binary file holds 0 occupied '
         'cells', send={'map_file': MapFile('empty.bt', bt(EMPTY))}),
    Case('map_file_npy_all_non_finite', MAP_FILE, 'a .npy array of NaN and inf only',
         MAP_FILE_REFUSED, 200, 'nan.npy: no usable points: all 50 points of the NumPy .npy '
         'file have NaN or infinite coordinates',
         send={'map_file': MapFile('nan.npy', npy(NON_FINITE))}),
    Case('map_file_pcd_all_non_finite', MAP_FILE, 'a PCD file whose 50 points are NaN or inf',
         MAP_FILE_REFUSED, 200, 'nan.pcd: no usable points: all 50 points',
         send={'map_file': MapFile('nan.pcd', pcd(NON_FINITE))}),
    Case('map_file_las_all_outside', MAP_FILE, 'a LAS survey in UTM coordinates',
         MAP_FILE_REFUSED, 200, 'utm.las: all 50 usable points lie outside the planning bounds '
         '[-10.0, -10.0, 0.0] .. [10.0, 10.0, 15.0]',
         send={'map_file': MapFile('utm.las', las(UTM))}),
    Case('map_file_bt_resolution_too_fine', MAP_FILE, 'an OctoMap of 1 mm cells, delta 0.5 m',
         MAP_FILE_REFUSED, 200,
         'fine.bt: the OctoMap resolution 0.001 m is finer than delta / 100 = 0.005 m',
         send={'map_file': MapFile('fine.bt', bt(BLOCK, 0.001))}),
    Case('map_file_downsample_too_fine', MAP_FILE, 'map_downsample = 0.001 m, delta 0.5 m',
         MAP_FILE_REFUSED, 200,
         'block.npy: the downsampling cell 0.001 m is finer than delta / 100 = 0.005 m',
         send={'map_file': MapFile('block.npy', npy(BLOCK)), 'map_downsample': 0.001}),
    Case('map_file_pcd_non_finite_viewpoint', MAP_FILE, 'a PCD header with a NaN VIEWPOINT',
         MAP_FILE_REFUSED, 200, 'viewpoint.pcd: the PCD header holds a non-finite VIEWPOINT',
         send={'map_file': MapFile('viewpoint.pcd', pcd(BLOCK, (_NAN, 0, 0, 1, 0, 0, 0)))}),
    Case('map_file_las_non_finite_scale', MAP_FILE, 'a LAS header with an x scale of NaN',
         MAP_FILE_REFUSED, 200, 'scale.las: the LAS header holds a non-finite scale',
         send={'map_file': MapFile('scale.las', las(BLOCK, (_NAN, 0.001, 0.001)))}),
    Case('map_file_unreadable', MAP_FILE, 'a .npy file that is not one', MAP_FILE_REFUSED, 200,
         'broken.npy: not a valid NumPy .npy file, or truncated',
         covered_by='test_node_map_restart.py::test_a_prior_map_file_is_a_map_and_is_kept_off'),
    Case('map_file_some_non_finite_or_outside', MAP_FILE,
         'a .npy map with 2 NaN rows and 1 point 1 km away', ACCEPTED, None,
         'the NaN rows are dropped, the far point kept (the bounds may change), and the map '
         'status says so: map_file_points_read 53, map_file_dropped_non_finite 2, '
         'map_file_outside_bounds 1, map_file_points_kept 51',
         send={'map_file': MapFile('some.npy', npy(np.vstack(
             [BLOCK, NON_FINITE[:2], [[1000.0, 0.0, 0.0]]])))}),
)

CASES: Dict[str, Case] = {case.case_id: case for case in CATALOGUE}


def _run_here(outcome: str):
    return sorted(case.case_id for case in CATALOGUE
                  if case.outcome == outcome and not case.covered_by)


# ------------------------------------------------------------------------------ the node


def scene_markers() -> MarkerArray:
    """The paper_medium spheres, in ns 'scene'."""
    return conv.obstacle_input_markers(SCENE.obstacles, 'map', 0, ns='scene')


@pytest.fixture(scope='module')
def planner() -> Iterator[PlannerClient]:
    domain_id = unique_domain_id()
    process = start_planner(domain_id, namespace=NAMESPACE)
    client = None
    try:
        client = RosClient(domain_id)
        diagnostics = client.record(DiagnosticArray, '/diagnostics')
        planner = PlannerClient(client, NAMESPACE, diagnostics, process)
        planner.set_obstacles(scene_markers(), len(SCENE.obstacles))
        values, _ = planner.plan_to(GOAL, GOAL_ORIENTATION)
        assert values['status'] == 'ok', values
        yield planner
    finally:
        if client is not None:
            client.close()
        try:
            assert_clean_exit(process, process.stop())
        finally:
            process.kill()


def assert_good_plan(planner: PlannerClient, version: Optional[str] = None) -> Dict[str, str]:
    """The next valid request succeeds in the good state: the scene, the start, gamma.

    ``version`` is the ``obstacles_version`` that must still be in force, if given.
    """
    values = _plan_new_goal(planner, GOAL)
    assert values['status'] == 'ok', values
    path = planner.plan_for(values)
    assert values['obstacles'] == str(len(SCENE.obstacles)), values
    if version is not None:
        assert values['obstacles_version'] == version, 'the obstacles changed'
    assert values['start'] == conv.format_value(START), values
    assert float(values['safety_margin_m']) == pytest.approx(GAMMA)
    points = conv.path_to_points(path)
    assert np.allclose(points[0], START) and np.allclose(points[-1], GOAL)
    assert min_clearance(points, SCENE.obstacles) >= GAMMA - TOL
    return values


def _plan_new_goal(planner: PlannerClient, goal, frame_id: str = 'map') -> Dict[str, str]:
    """Send a goal; the diagnostics of its plan (not of a replan of an older goal)."""
    return planner.plan_to(goal, GOAL_ORIENTATION, frame_id)[0]


def last_plan_values(planner: PlannerClient) -> Dict[str, str]:
    """Diagnostics of the node's most recent plan attempt."""
    events = planner.diag_events(0, 'plan')
    assert events, 'no plan yet'
    return events[-1]


class _Parameters:
    """Set parameters for one case and restore them afterwards (a context manager)."""

    def __init__(self, planner: PlannerClient, values: Mapping[str, Any]) -> None:
        self.planner, self.values = planner, dict(values)
        self.before: Dict[str, Any] = {}

    def __enter__(self) -> None:
        if self.values:
            self.before = self.planner.params.get(list(self.values))
            result = self.planner.params.set_atomically(self.values)
            assert result.successful, result.reason

    def __exit__(self, *exc_info: Any) -> None:
        if self.values:
            result = self.planner.params.set_atomically(self.before)
            assert result.successful, result.reason


def _refusal_line(planner: PlannerClient, log_mark: int, case: Case) -> str:
    text = f'refused message on {planner.prefix}{case.channel}: '
    line = planner.process.wait_for_output(text, 5.0, log_mark)
    assert case.reason in line, line
    return line


# ------------------------------------------------------------------------------ generic cases

def _publish_until_refused(planner: PlannerClient, case: Case, mark: int) -> Dict[str, str]:
    """Publish the case's message; its input_rejected diagnostics.

    Best-effort topics (odom, obstacle_cloud) may lose the very first message of a new
    publisher while discovery completes, so those are sent again until the refusal shows.
    """
    # (obstacle_cloud is reliable, but a new publisher's first sample can still be lost before
    # both sides have matched.)
    best_effort = case.channel in ('odom', 'obstacle_cloud')
    deadline = time.monotonic() + 10.0
    while True:
        planner.publish(case.channel, case.send())
        try:
            return planner.wait_diag(mark, 'input_rejected', 1.0 if best_effort else 10.0)
        except AssertionError:
            if not best_effort or time.monotonic() > deadline:
                raise


@pytest.mark.parametrize('case_id', _run_here(REFUSED))
def test_refused_message(planner: PlannerClient, case_id: str) -> None:
    case = CASES[case_id]
    version = last_plan_values(planner)['obstacles_version']
    with _Parameters(planner, case.with_parameters):
        diag_mark, plans, log_mark = (planner.diagnostics.mark(), planner.plans.mark(),
                                      planner.process.mark())
        values = _publish_until_refused(planner, case, diag_mark)
        assert values['status_code'] == str(case.code), values
        assert case.reason in values['reason'], values
        assert values['topic'] == planner.prefix + case.channel, values
        assert values['_level'] == WARN, values
        _refusal_line(planner, log_mark, case)
        time.sleep(0.1)
        assert planner.process.process.poll() is None, planner.process.output
        assert planner.diag_events(diag_mark, 'plan') == [], 'a refused input caused a replan'
        assert planner.plans.mark() == plans, 'a refused input produced a plan'
    assert_good_plan(planner, version)


def _plan_from(planner: PlannerClient, start, expected_start: str) -> Dict[str, str]:
    """Send ``start`` on start_pose, then the goal, until a plan uses that start."""
    def attempt() -> Optional[Dict[str, str]]:
        planner.publish('start_pose', start)
        values = _plan_new_goal(planner, GOAL)
        return values if values['start'] == expected_start else None
    deadline = time.monotonic() + 15.0
    while time.monotonic() < deadline:
        values = attempt()
        if values is not None:
            return values
        time.sleep(0.1)
    raise AssertionError(f'no plan from start {expected_start} within 15 s')


@pytest.mark.parametrize('case_id', _run_here(PLAN_FAILS))
def test_plan_fails_with_a_reason(planner: PlannerClient, case_id: str) -> None:
    case = CASES[case_id]
    version = last_plan_values(planner)['obstacles_version']
    plans, log_mark = planner.plans.mark(), planner.process.mark()
    parameters = case.send if case.channel == 'parameter' else case.with_parameters
    with _Parameters(planner, parameters):
        if case.channel == 'start_pose':
            msg = case.send()
            values = _plan_from(planner, msg, conv.format_value(
                conv.pose_stamped_to_point(msg, 'map', 'start')))
        else:
            values = _plan_new_goal(planner, GOAL)
        status_code = values['status_code']
        assert status_code == str(case.code), values
        assert case.reason in values['message'], values
        assert values['_level'] == ERROR, values
        line = planner.process.wait_for_output(f"{values['status']} (code {status_code})", 5.0,
                                               log_mark)
        assert case.reason in line and 'no plan (' in line, line
        time.sleep(0.1)
        stamps = [conv.time_to_ns(m.header.stamp) for m in planner.plans.messages[plans:]]
        assert values['_stamp'] not in stamps, 'a failed plan was published'
        assert planner.process.process.poll() is None, planner.process.output
    # Back to the good start; the next valid request succeeds.
    if case.channel == 'start_pose':
        _plan_from(planner, pose_msg(START), conv.format_value(START))
    assert_good_plan(planner, version)


@pytest.mark.parametrize('case_id', _run_here(PARAMETER_REFUSED))
def test_parameter_refused_with_a_reason(planner: PlannerClient, case_id: str) -> None:
    case = CASES[case_id]
    names = list(case.send)
    declared = [name for name in names if name != 'no_such_parameter']
    before = planner.params.get(declared) if declared else {}
    mark = planner.diagnostics.mark()
    if case.channel == 'parameters (atomic)':
        results = [planner.params.set_atomically(case.send)]
    else:
        results = planner.params.set(case.send)
    assert len(results) == 1 and not results[0].successful, results
    assert case.reason in results[0].reason, results[0].reason
    if declared:
        assert planner.params.get(declared) == before
    time.sleep(0.1)
    assert planner.diag_events(mark, 'plan') == [], 'a refused parameter caused a replan'
    assert_good_plan(planner)


# ------------------------------------------------------------------------------ accepted cases

def test_goal_equal_to_start_gives_a_one_pose_plan(planner: PlannerClient) -> None:
    values = _plan_new_goal(planner, START)
    assert values['status'] == 'ok' and values['status_code'] == '0', values
    path = planner.plan_for(values)
    assert float(values['duration_s']) == 0.0
    points = conv.path_to_points(path)
    assert len(points) == 1 and np.allclose(points[0], START)
    last = path.poses[-1].pose.orientation
    assert (last.x, last.y, last.z, last.w) == pytest.approx(GOAL_ORIENTATION)
    assert_good_plan(planner)


def test_leading_slash_names_the_same_frame(planner: PlannerClient) -> None:
    values = _plan_new_goal(planner, GOAL, frame_id='/map')
    assert values['status'] == 'ok', values
    path = planner.plan_for(values)
    assert path.header.frame_id == 'map'
    assert_good_plan(planner)


@pytest.mark.parametrize('make', [
    MarkerArray,
    lambda: marker_array(marker('never', 3, Marker.SPHERE, (0.0, 0.0, 1.0), (1.0, 1.0, 1.0),
                                action=Marker.DELETE)),
    scene_markers,
], ids=['empty', 'delete_unknown', 'same_again'])
def test_marker_array_that_changes_nothing_is_a_no_op(planner: PlannerClient,
                                                      make: Callable[[], MarkerArray]) -> None:
    version = assert_good_plan(planner)['obstacles_version']
    mark, markers = planner.diagnostics.mark(), planner.markers.mark()
    planner.publish('obstacles', make())
    time.sleep(0.7)  # longer than the node's marker period (0.5 s)
    assert planner.diag_events(mark, 'plan') == [], 'a no-op marker array caused a replan'
    assert planner.diag_events(mark, 'input_rejected') == []
    assert planner.markers.mark() == markers, 'planner_markers were republished'
    values = assert_good_plan(planner, version)
    assert float(values['grid_build_time_s']) == 0.0, 'the grid was rebuilt for nothing'


def test_delete_all_of_one_namespace_keeps_the_others(planner: PlannerClient) -> None:
    count = len(SCENE.obstacles)
    extra = marker('extra', 0, Marker.CUBE, (-6.0, -6.0, 8.0), (1.0, 1.0, 1.0))
    planner.set_obstacles(marker_array(extra), count + 1)
    clear = Marker(ns='extra', action=Marker.DELETEALL)
    clear.header = Header(frame_id='map')
    planner.set_obstacles(marker_array(clear), count)
    assert_good_plan(planner)


def test_delete_all_clears_every_marker_obstacle(planner: PlannerClient) -> None:
    clear = Marker(action=Marker.DELETEALL)
    clear.header = Header(frame_id='map')
    planner.set_obstacles(marker_array(clear), 0)
    values = _plan_new_goal(planner, GOAL)
    assert values['status'] == 'ok' and values['obstacles'] == '0', values
    # Nothing in the way: the smoothed path is the straight segment.
    assert float(values['smoothed_length_m']) == pytest.approx(
        float(np.linalg.norm(GOAL - START)), rel=1e-3)
    planner.set_obstacles(scene_markers(), len(SCENE.obstacles))
    assert_good_plan(planner)


def test_plan_that_a_new_obstacle_invalidates_is_withdrawn(planner: PlannerClient) -> None:
    count = len(SCENE.obstacles)
    assert_good_plan(planner)
    mark = planner.diagnostics.mark()
    planner.set_obstacles(marker_array(
        marker('block', 0, Marker.SPHERE, GOAL, (1.0, 1.0, 1.0))), count + 1)
    # The plan on the topic now collides: it is withdrawn as soon as the map arrives (an
    # ERROR saying where), replaced by an empty one, for late subscribers too (a controller
    # started now must not fly it); then its replacement is attempted, and fails.
    notice = planner.wait_diag(mark, 'plan_withdrawn')
    assert notice['_level'] == 2 and notice['plan_withdrawn'] == 'true', notice
    where = np.array([float(v) for v in notice['blocked_at'].strip('[]').split(',')])
    assert np.linalg.norm(where - GOAL) < 0.5 + GAMMA + 0.5, notice
    withdrawn = planner.plans.wait_for(
        lambda m: conv.time_to_ns(m.header.stamp) == notice['_stamp'], 5.0,
        what='the empty plan that withdraws the colliding one')
    assert len(withdrawn.poses) == 0 and withdrawn.header.frame_id == 'map'
    failed = planner.wait_diag(mark, 'plan')
    assert 'withdrawn' in failed['reason'], failed
    assert failed['status'] == 'goal_occupied' and failed['status_code'] == '206', failed
    late = planner.client.record(type(withdrawn), planner.prefix + 'plan', LATCHED_QOS)
    assert len(late.wait_for(timeout_s=10.0, what='the latched plan').poses) == 0

    # Without the obstacle the goal is retried at once.
    mark = planner.diagnostics.mark()
    planner.set_obstacles(marker_array(
        marker('block', 0, Marker.SPHERE, GOAL, (1.0, 1.0, 1.0), action=Marker.DELETE)), count)
    again = planner.wait_diag(mark, 'plan')
    assert again['status'] == 'ok' and again['reason'] == 'obstacles changed', again
    assert_good_plan(planner)


# ------------------------------------------------------------------------------ map_file

def _map_file_cases() -> list:
    return sorted(case.case_id for case in CATALOGUE
                  if case.channel == MAP_FILE and not case.covered_by)


@pytest.mark.parametrize('case_id', _map_file_cases())
def test_map_file_refused_at_start_up(case_id: str, tmp_path: Path) -> None:
    """In-process (no DDS traffic): the node starts, and its map status, its goals and its Nav2
    requests say why the map file was refused; an accepted file's figures are in the status."""
    case = CASES[case_id]
    overrides = [Parameter(name, value=str(value.at(tmp_path)) if isinstance(value, MapFile)
                           else value) for name, value in case.send.items()]
    with in_process_planner(overrides) as node:
        published = []
        node.diagnostics.publish = (
            lambda stamp_ns, level, text, values: published.append((level, text, dict(values))))
        node.status.publish_map_status()
        level, text, values = published[-1]
        assert values['event'] == 'map_status', values
        if case.outcome == ACCEPTED:
            assert node.map_refusal() == '' and values['map_file_status'] == 'ok', values
            for figure in case.reason.partition('says so: ')[2].split(', '):
                key, _, number = figure.partition(' ')
                assert str(values[key]) == number, (key, values)
            assert 'map_file: 1 accepted' in values['map_sources'], values
            return
        assert case.outcome == MAP_FILE_REFUSED
        reason = node.map_refusal()
        assert reason.startswith('map_file refused: ') and case.reason in reason, reason
        assert level == DiagnosticStatus.ERROR and text == reason, (level, text)
        assert values['status'] == 'no_map' and values['map_file_status'] == 'refused', values
        assert case.reason in values['map_file_refused'], values
        assert case.reason in values['map_refused'], values
        assert 'map_file: 0 accepted, 1 refused' in values['map_sources'], values
        # A goal is refused with the reason, as if no map had arrived: code 200.
        node.commands.on_goal(pose_msg(GOAL))
        level, text, values = published[-1]
        assert values['event'] == 'plan' and values['status'] == 'no_map', values
        assert values['status_code'] == case.code and case.reason in values['message'], values
        assert level == DiagnosticStatus.ERROR
        assert node.inputs.active_goal() is None
        # So is a Nav2 request, before it reaches the planner.
        request = nav2_interfaces._Request('ComputePathToPose', GOAL, GOAL_ORIENTATION, 'map',
                                           'adaptive')
        outcome = node.nav2._plan(request, None, None)
        assert outcome.status is PlanStatus.INVALID_INPUT and outcome.message == reason


# ------------------------------------------------------------------------------ the table itself

def test_catalogue_references_exist() -> None:
    """Every ``covered_by`` names a test that exists; the rows of test_node_planning's
    parametrised cases match them."""
    for case in CATALOGUE:
        assert case.send is not None or case.covered_by, case.case_id
        if not case.covered_by:
            continue
        filename, _, test_name = case.covered_by.partition('::')
        text = (HERE / filename).read_text()
        assert f'def {test_name}(' in text, case.covered_by
        if case.covered_by == PLANNING:
            assert f"'{case.case_id}'" in text, case.case_id
        elif case.covered_by == PLANNING_PARAMS:
            # The same values are in that test's parameter list.
            name, value = next(iter(case.send.items()))
            shown = 'math.nan' if value is _NAN else repr(value).replace('inf', 'math.inf')
            assert f"{{'{name}': {shown}}}" in text, (case.case_id, shown)


# How each publisher of test_node_planning's BAD_INPUTS is read by the node (pure functions).
_READERS = {
    'goal_pub': lambda msg: conv.pose_stamped_to_pose(msg, 'map', '/ns/goal_pose'),
    'start_pub': lambda msg: conv.pose_stamped_to_pose(msg, 'map', '/ns/start_pose'),
    'odom_pub': lambda msg: conv.odometry_to_point(msg, 'map', '/ns/odom'),
    'obstacles_pub': lambda msg: conv.apply_marker_array({}, msg, 'map', 100.0),
    'cloud_pub': lambda msg: conv.cloud_to_points(msg, 'map', True, 2_000_000),
}


@pytest.mark.parametrize('case_id', sorted(case.case_id for case in CATALOGUE
                                           if case.covered_by == PLANNING))
def test_documented_reason_of_a_case_run_elsewhere(case_id: str) -> None:
    """The code and reason in the table are what test_node_planning's message gets."""
    from test_node_planning import BAD_INPUTS
    case = CASES[case_id]
    publisher, make, code = BAD_INPUTS[case_id]
    assert code == case.code
    if case_id == 'goal_outside_bounds':
        return  # the node checks the bounds itself, with the settings in force
    with pytest.raises(conv.InputRejected) as refused:
        _READERS[publisher](make())
    assert refused.value.code == case.code
    assert case.reason in str(refused.value)


def test_documented_reason_of_a_parameter_case_run_elsewhere() -> None:
    """The reasons in the parameter rows of test_node_planning's cases are what rclpy and the
    node say (in-process: no DDS traffic, no duplicate of that test)."""
    with in_process_planner() as node:
        for case in CATALOGUE:
            if case.covered_by != PLANNING_PARAMS:
                continue
            (result,) = node.node.set_parameters(
                [Parameter(name, value=value) for name, value in case.send.items()])
            assert not result.successful, case.case_id
            assert case.reason in result.reason, (case.case_id, result.reason)


def test_catalogue_is_complete() -> None:
    """The inputs the issue names all have a row (ids are unique by construction)."""
    assert len(CASES) == len(CATALOGUE)
    needed = {'goal_nan', 'goal_inf', 'start_pose_nan', 'start_pose_inf', 'odom_nan',
              'odom_inf', 'goal_outside_bounds', 'start_outside_bounds', 'goal_occupied',
              'start_occupied', 'goal_equals_start', 'goal_wrong_frame', 'marker_wrong_frame',
              'cloud_wrong_frame', 'odom_wrong_frame', 'marker_nan', 'marker_inf_scale',
              'marker_zero_scale', 'marker_negative_scale', 'marker_huge', 'markers_empty',
              'markers_delete_all', 'marker_unknown_type', 'cloud_missing_z',
              'cloud_nan_refused', 'cloud_wrong_point_step', 'cloud_truncated',
              'param_resolution_string', 'param_resolution_zero',
              'param_bounds_min_above_max', 'param_bounds_voxel_cap'}
    assert needed <= set(CASES), sorted(needed - set(CASES))
