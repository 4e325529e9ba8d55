"""The planner node in real processes: plans, latching, parameters, bad input, namespaces.

Two node processes serve the whole module (one in this run's namespace, one in ``second``
below it); the tests talk to them only through topics and parameter services. Every test starts
from the same state of the first node, whatever ran before it: the ``planner`` fixture changes
``frame_id`` away and back (the node then drops its goal, its start from start_pose or odom and
every obstacle), restores the parameters it started with, publishes the scene's obstacles and
plans to the scene's goal (that plan is ``planner.baseline``).
"""

import math
import signal
import time
from typing import Any, Dict, Optional, Sequence, Tuple

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from helpers.ros_messages import duration_to_seconds
from nav_msgs.msg import Odometry, Path
import numpy as np
import pytest
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Header
from trajectory_msgs.msg import MultiDOFJointTrajectory
from visualization_msgs.msg import Marker, MarkerArray

from ros_harness import (assert_clean_exit, CLOUD_QOS, LATCHED_QOS, marker, marker_array,
                         min_clearance, NODE_NAME, NodeProcess, OBSTACLES_QOS, odom_msg,
                         PlannerClient, pose_msg, READY_TEXT, Recorder, RosClient, RUN_NAMESPACE,
                         SENSOR_QOS, start_planner, STARTUP_TIMEOUT_S, unique_domain_id,
                         wait_until)
from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, PointSet, Sphere
from uav_global_planner.ros import conversions as conv

pytestmark = pytest.mark.ros

SCENE = load_scene(find_scene('paper_medium'))
GAMMA = 0.2
START = np.array([0.0, -5.0, 0.0])  # the start parameter of config/planner.yaml
GOAL = SCENE.goal
GOAL_ORIENTATION = conv.yaw_quaternion(0.7)
# An extra box beside the paper's spheres, away from start and goal.
BOX_CENTER, BOX_SIZE = (-5.0, -5.0, 3.0), (2.0, 2.0, 6.0)
PLAN_TIMEOUT_S = 20.0
TOL = 1e-6
SECOND_NAMESPACE = f'{RUN_NAMESPACE}/second'
# Every parameter a test sets (or tries to), restored to its start-up value before each test.
TOUCHED_PARAMETERS = ('safety_margin', 'bounds.min', 'bounds.max', 'resolution', 'max_voxels',
                      'algorithm', 'smoothing', 'start', 'frame_id', 'cloud_non_finite',
                      'use_sim_time')


def scene_markers() -> MarkerArray:
    """The paper_medium spheres plus one box, as the planner's input."""
    msg = conv.obstacle_input_markers(SCENE.obstacles, 'map', 0, ns='scene')
    msg.markers.append(marker('box', 0, Marker.CUBE, BOX_CENTER, BOX_SIZE))
    return msg


def scene_obstacles() -> ObstacleSet:
    lo = np.subtract(BOX_CENTER, np.divide(BOX_SIZE, 2))
    hi = np.add(BOX_CENTER, np.divide(BOX_SIZE, 2))
    return ObstacleSet(list(SCENE.obstacles.items) + [Box(lo, hi)])


class PlannerUnderTest(PlannerClient):
    """The harness's client of one planner node, plus the outputs and inputs the tests here
    name (``BAD_INPUTS`` names the publishers)."""

    def __init__(self, process: NodeProcess, client: RosClient, namespace: str,
                 diagnostics: Recorder) -> None:
        super().__init__(client, namespace, diagnostics, process)
        prefix = self.prefix
        self.unsmoothed = client.record(Path, prefix + 'unsmoothed_plan', LATCHED_QOS)
        self.trajectories = client.record(MultiDOFJointTrajectory, prefix + 'trajectory',
                                          LATCHED_QOS)
        self.goal_pub = client.publisher(PoseStamped, prefix + 'goal_pose')
        self.start_pub = client.publisher(PoseStamped, prefix + 'start_pose')
        self.obstacles_pub = client.publisher(MarkerArray, prefix + 'obstacles', OBSTACLES_QOS)
        # Reliable, as the node's cloud subscription: a best-effort publisher does not
        # connect to it.
        self.cloud_pub = client.publisher(PointCloud2, prefix + 'obstacle_cloud', CLOUD_QOS)
        self.odom_pub = client.publisher(Odometry, prefix + 'odom', SENSOR_QOS)
        self.baseline: Optional[Tuple[Dict[str, str], Path]] = None

    def plan_to(self, goal: Sequence[float], orientation: Sequence[float] = GOAL_ORIENTATION,
                frame_id: str = 'map', timeout_s: float = PLAN_TIMEOUT_S
                ) -> Tuple[Dict[str, str], Optional[Path]]:
        """Send a goal (with the scene's goal heading); its plan diagnostics and plan."""
        return super().plan_to(goal, orientation, frame_id, timeout_s)

    def reset(self, initial: Dict[str, Any]) -> None:
        """Back to the start-up state, then the scene's obstacles and a plan to its goal."""
        # Leaving the frame drops the goal, the start from start_pose or odom and the map.
        for frame in (initial['frame_id'] + '_reset', initial['frame_id']):
            (result,) = self.params.set({'frame_id': frame})
            assert result.successful, result.reason
        current = self.params.get(list(initial))
        changed = {name: value for name, value in initial.items()
                   if not _same_value(current[name], value)}
        if changed:
            result = self.params.set_atomically(changed)
            assert result.successful, result.reason
        self.set_obstacles(scene_markers(), len(SCENE.obstacles) + 1)
        values, path = self.plan_to(GOAL)
        assert values['status'] == 'ok', values
        self.baseline = values, path


@pytest.fixture(scope='module')
def ros():
    domain_id = unique_domain_id()
    # Both in this run's namespace, which also shows that every topic name is relative.
    first = start_planner(domain_id, wait=False, namespace=RUN_NAMESPACE)
    second = start_planner(domain_id, wait=False, namespace=SECOND_NAMESPACE)
    client = None
    try:
        first.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        second.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        client = RosClient(domain_id)
        diagnostics = client.record(DiagnosticArray, '/diagnostics')
        yield {'first': PlannerUnderTest(first, client, RUN_NAMESPACE, diagnostics),
               'second': PlannerUnderTest(second, client, SECOND_NAMESPACE, diagnostics)}
    finally:
        if client is not None:
            client.close()
        try:
            # Both ways of being stopped end cleanly (test_node_lifecycle covers a busy node).
            assert_clean_exit(first, first.stop(signal.SIGINT))
            assert_clean_exit(second, second.stop(signal.SIGTERM))
        finally:
            first.kill()
            second.kill()


def _same_value(a: Any, b: Any) -> bool:
    if isinstance(a, (str, bool, int, float)) or isinstance(b, (str, bool, int, float)):
        return a == b
    return list(a) == list(b)


@pytest.fixture(scope='module')
def initial_parameters(ros) -> Dict[str, Any]:
    """The first node's start-up values of the parameters the tests touch."""
    return ros['first'].params.get(TOUCHED_PARAMETERS)


@pytest.fixture
def planner(ros, initial_parameters) -> PlannerUnderTest:
    """The first node, reset (see the module documentation); ``baseline`` is its plan."""
    first = ros['first']
    first.reset(initial_parameters)
    return first


def assert_safe(path: Path, obstacles: ObstacleSet, gamma: float) -> float:
    points = conv.path_to_points(path)
    assert len(points) >= 2
    clearance = min_clearance(points, obstacles)
    assert clearance >= gamma - TOL, f'clearance {clearance} m < gamma {gamma} m'
    return clearance


# ------------------------------------------------------------------------------ planning

def test_plan_keeps_gamma_from_every_obstacle(planner):
    values, path = planner.baseline
    assert values['status'] == 'ok', values
    assert values['status_code'] == '0'
    assert values['start_source'] == 'parameter'
    assert values['obstacles'] == str(len(SCENE.obstacles) + 1)
    for key in ('algorithm', 'planning_time_s', 'expanded_nodes', 'path_length_m',
                'min_clearance_m', 'safety_margin_m', 'adaptive_threshold_m', 'resolution_m'):
        assert key in values, key
    assert float(values['safety_margin_m']) == pytest.approx(GAMMA)
    assert values['algorithm'] == 'adaptive'
    assert int(values['expanded_nodes']) > 0

    assert path.header.frame_id == 'map'
    assert_safe(path, scene_obstacles(), GAMMA)
    points = conv.path_to_points(path)
    assert np.allclose(points[0], START) and np.allclose(points[-1], GOAL)
    # Stamps: plan time + trajectory time, increasing, ending at the flight time.
    offsets = np.array([conv.time_to_ns(p.header.stamp) for p in path.poses]) - values['_stamp']
    assert offsets[0] == 0 and np.all(np.diff(offsets) > 0)
    assert offsets[-1] * 1e-9 == pytest.approx(float(values['duration_s']), abs=1e-3)
    last = path.poses[-1].pose.orientation
    assert (last.x, last.y, last.z, last.w) == pytest.approx(GOAL_ORIENTATION)

    stamp = values['_stamp']
    unsmoothed = planner.unsmoothed.wait_for(
        lambda m: conv.time_to_ns(m.header.stamp) == stamp, 5.0)
    trajectory = planner.trajectories.wait_for(
        lambda m: conv.time_to_ns(m.header.stamp) == stamp, 5.0)
    assert len(unsmoothed.poses) >= 2
    # The trajectory: a point every trajectory_sample_period (0.05 s) of the same flight, from
    # the start at rest to the goal at rest, keeping gamma too.
    times = np.array([duration_to_seconds(p.time_from_start) for p in trajectory.points])
    assert times[0] == 0.0 and np.allclose(np.diff(times)[:-1], 0.05, atol=1e-9)
    assert times[-1] == pytest.approx(float(values['duration_s']), abs=1e-3)
    positions = np.array([[p.transforms[0].translation.x, p.transforms[0].translation.y,
                           p.transforms[0].translation.z] for p in trajectory.points])
    assert np.allclose(positions[0], START) and np.allclose(positions[-1], GOAL)
    assert scene_obstacles().distance(positions).min() >= GAMMA - 1e-9
    for end in (trajectory.points[0], trajectory.points[-1]):
        velocity = end.velocities[0].linear
        assert (velocity.x, velocity.y, velocity.z) == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)


def test_late_subscriber_gets_the_last_plan(planner):
    _, last = planner.baseline
    late = planner.client.record(Path, f'{RUN_NAMESPACE}/plan', LATCHED_QOS)
    received = late.wait_for(timeout_s=10.0, what='the latched plan')
    assert received.header.stamp == last.header.stamp
    assert len(received.poses) == len(last.poses)


def test_raised_safety_margin_applies_to_the_next_plan(planner):
    mark = planner.diagnostics.mark()
    (result,) = planner.params.set({'safety_margin': 0.6})
    assert result.successful, result.reason
    # The active goal is replanned with the new gamma, without a restart.
    values = planner.wait_diag(mark, 'plan')
    assert values['reason'] == 'parameters changed'
    assert values['status'] == 'ok', values
    assert float(values['safety_margin_m']) == pytest.approx(0.6)
    clearance = assert_safe(planner.plan_for(values), scene_obstacles(), 0.6)
    assert clearance >= 0.6 - TOL
    assert planner.params.get(['safety_margin'])['safety_margin'] == pytest.approx(0.6)

    mark = planner.diagnostics.mark()
    (result,) = planner.params.set({'safety_margin': GAMMA})
    assert result.successful, result.reason
    values = planner.wait_diag(mark, 'plan')
    assert float(values['safety_margin_m']) == pytest.approx(GAMMA)


@pytest.mark.parametrize('values, reason', [
    ({'resolution': -1.0}, 'resolution'),
    ({'resolution': 0.0}, 'resolution must be in (0.0'),
    ({'resolution': 0.001}, 'exceeds max_voxels'),
    ({'max_voxels': 100}, 'exceeds max_voxels'),
    ({'algorithm': 'foo'}, 'algorithm must be one of'),
    ({'smoothing': 'bezier'}, 'smoothing must be one of'),
    ({'bounds.min': [10.0, 10.0, 10.0]}, 'bounds.min must be below bounds.max'),
    ({'bounds.max': [1.0, 2.0]}, 'bounds.max must be three numbers'),
    ({'safety_margin': math.nan}, 'safety_margin'),
    ({'start': [0.0, math.inf, 0.0]}, 'start[1] must be finite'),
    ({'frame_id': ''}, 'frame_id must be a non-empty'),
    ({'cloud_non_finite': 'keep'}, 'cloud_non_finite must be one of'),
    ({'resolution': 'fine'}, 'type'),
])
def test_invalid_parameter_is_rejected_and_old_value_kept(planner, values, reason):
    names = list(values)
    before = planner.params.get(names)
    mark = planner.diagnostics.mark()
    results = planner.params.set(values)
    assert len(results) == 1
    assert not results[0].successful
    assert reason in results[0].reason, results[0].reason
    after = planner.params.get(names)
    for name in names:
        assert after[name] == before[name] or (
            isinstance(before[name], float) and math.isnan(before[name]))
    time.sleep(0.2)
    assert planner.diag_events(mark, 'plan') == [], 'a refused parameter caused a replan'


def test_bounds_move_atomically(planner):
    far = {'bounds.min': [11.0, -10.0, 0.0], 'bounds.max': [31.0, 10.0, 15.0]}
    # One at a time, the new minimum is refused against the old maximum ...
    (alone,) = planner.params.set({'bounds.min': far['bounds.min']})
    assert not alone.successful
    assert 'bounds.min must be below bounds.max' in alone.reason
    # ... together they are accepted, and the active goal is replanned at once: the start
    # [0, -5, 0] now lies outside the map.
    mark = planner.diagnostics.mark()
    result = planner.params.set_atomically(far)
    assert result.successful, result.reason
    values = planner.wait_diag(mark, 'plan')
    assert values['reason'] == 'parameters changed'
    assert values['status'] == 'start_outside_map' and values['status_code'] == '203'

    mark = planner.diagnostics.mark()
    home = {'bounds.min': [-10.0, -10.0, 0.0], 'bounds.max': [10.0, 10.0, 15.0]}
    result = planner.params.set_atomically(home)
    assert result.successful, result.reason
    values = planner.wait_diag(mark, 'plan')
    assert values['status'] == 'ok', values
    assert list(planner.params.get(['bounds.max'])['bounds.max']) == home['bounds.max']


def test_parameters_of_rclpy_are_not_refused(planner):
    (result,) = planner.params.set({'use_sim_time': False})
    assert result.successful, result.reason


# ------------------------------------------------------------------------------ bad input

def _cloud(points, **changes) -> PointCloud2:
    msg = conv.points_to_cloud(np.asarray(points, dtype=float).reshape(-1, 3), 'map', 0)
    for key, value in changes.items():
        setattr(msg, key, value)
    return msg


def _cloud_missing_z() -> PointCloud2:
    msg = _cloud([[1.0, 1.0, 1.0]])
    msg.fields = msg.fields[:2]
    return msg


def _cloud_int_field() -> PointCloud2:
    msg = _cloud([[1.0, 1.0, 1.0]])
    msg.fields[2] = PointField(name='z', offset=8, datatype=PointField.INT32, count=1)
    return msg


_NAN = math.nan
BAD_INPUTS = {
    'goal_nan': ('goal_pub', lambda: pose_msg([_NAN, 0.0, 5.0]), 200),
    'goal_inf': ('goal_pub', lambda: pose_msg([0.0, math.inf, 5.0]), 200),
    'goal_wrong_frame': ('goal_pub', lambda: pose_msg([1.0, 1.0, 5.0], 'odom'), 202),
    'goal_outside_bounds': ('goal_pub', lambda: pose_msg([50.0, 0.0, 5.0]), 204),
    'start_pose_nan': ('start_pub', lambda: pose_msg([_NAN, 0.0, 1.0]), 200),
    'start_pose_wrong_frame': ('start_pub', lambda: pose_msg([0.0, 0.0, 1.0], 'base'), 202),
    'odom_wrong_frame': ('odom_pub', lambda: odom_msg([0.0, 0.0, 1.0], 'odom'), 202),
    'odom_nan': ('odom_pub', lambda: odom_msg([0.0, _NAN, 1.0]), 200),
    'marker_nan': ('obstacles_pub', lambda: marker_array(
        marker('bad', 0, Marker.SPHERE, [_NAN, 0.0, 1.0], [1.0, 1.0, 1.0])), 200),
    'marker_zero_scale': ('obstacles_pub', lambda: marker_array(
        marker('bad', 0, Marker.SPHERE, [0.0, 0.0, 1.0], [0.0, 0.0, 0.0])), 200),
    'marker_negative_scale': ('obstacles_pub', lambda: marker_array(
        marker('bad', 0, Marker.CUBE, [0.0, 0.0, 1.0], [1.0, -1.0, 1.0])), 200),
    'marker_huge': ('obstacles_pub', lambda: marker_array(
        marker('bad', 0, Marker.SPHERE, [0.0, 0.0, 1.0], [1e9, 1e9, 1e9])), 200),
    'marker_unknown_type': ('obstacles_pub', lambda: marker_array(
        marker('bad', 0, Marker.ARROW, [0.0, 0.0, 1.0], [1.0, 1.0, 1.0])), 200),
    'marker_wrong_frame': ('obstacles_pub', lambda: marker_array(
        marker('bad', 0, Marker.SPHERE, [0.0, 0.0, 1.0], [1.0, 1.0, 1.0], 'odom')), 202),
    'marker_delete_all_then_bad': ('obstacles_pub', lambda: marker_array(
        Marker(action=Marker.DELETEALL),
        marker('bad', 0, Marker.TEXT_VIEW_FACING, [0.0, 0.0, 1.0], [1.0, 1.0, 1.0])), 200),
    'cloud_missing_z': ('cloud_pub', _cloud_missing_z, 200),
    'cloud_int_field': ('cloud_pub', _cloud_int_field, 200),
    'cloud_wrong_point_step': ('cloud_pub', lambda: _cloud(
        [[1.0, 1.0, 1.0], [2.0, 2.0, 2.0]], point_step=8, row_step=16), 200),
    'cloud_truncated': ('cloud_pub', lambda: _cloud(
        [[1.0, 1.0, 1.0], [2.0, 2.0, 2.0]], data=bytes(20)), 200),
    'cloud_wrong_frame': ('cloud_pub', lambda: _cloud([[1.0, 1.0, 1.0]], header=Header(
        frame_id='velodyne')), 202),
}


@pytest.mark.parametrize('case', sorted(BAD_INPUTS))
def test_malformed_input_is_reported_and_refused(planner, case):
    publisher, make, code = BAD_INPUTS[case]
    mark = planner.diagnostics.mark()
    plans = planner.plans.mark()
    markers = planner.markers.mark()
    getattr(planner, publisher).publish(make())
    values = planner.wait_diag(mark, 'input_rejected', 10.0)
    assert values['status_code'] == str(code), values
    assert values['reason'], values
    assert values['_level'] == 1  # WARN
    assert planner.process.process.poll() is None, planner.process.output
    time.sleep(0.1)
    assert planner.plans.mark() == plans, 'a refused input produced a plan'
    assert planner.diag_events(mark, 'plan') == []
    assert planner.markers.mark() == markers, 'a refused input changed the obstacles'


def test_goal_inside_an_obstacle_fails_with_goal_occupied(planner):
    plans = planner.plans.mark()
    center = SCENE.obstacles.sphere_centers[0]
    values, path = planner.plan_to(center)
    assert values['status'] == 'goal_occupied'
    assert values['status_code'] == '206'
    assert values['_level'] == 2  # ERROR
    assert path is None
    assert planner.plans.mark() == plans


def test_node_still_plans_safely_after_bad_input(planner):
    for case in ('marker_nan', 'cloud_truncated', 'goal_nan', 'odom_wrong_frame'):
        publisher, make, _ = BAD_INPUTS[case]
        mark = planner.diagnostics.mark()
        getattr(planner, publisher).publish(make())
        planner.wait_diag(mark, 'input_rejected', 10.0)
    values, path = planner.plan_to(GOAL)
    assert values['status'] == 'ok', values
    assert values['obstacles'] == str(len(SCENE.obstacles) + 1)
    assert_safe(path, scene_obstacles(), GAMMA)


# ------------------------------------------------------------------------------ obstacle changes

def test_new_obstacle_on_the_path_triggers_a_replan(planner):
    path = conv.path_to_points(planner.baseline[1])
    blocker = path[len(path) // 2]
    mark = planner.diagnostics.mark()
    planner.set_obstacles(marker_array(
        marker('test', 1, Marker.SPHERE, blocker, [1.6, 1.6, 1.6])), len(SCENE.obstacles) + 2)
    # The plan in force is withdrawn as the map arrives (ERROR), then replaced.
    withdrawn = planner.wait_diag(mark, 'plan_withdrawn')
    assert withdrawn['_level'] == 2 and withdrawn['plan_withdrawn'] == 'true', withdrawn
    values = planner.wait_diag(mark, 'plan')
    assert 'withdrawn' in values['reason'], values
    assert values['status'] == 'ok', values
    obstacles = ObstacleSet(list(scene_obstacles().items) + [Sphere(blocker, 0.8)])
    assert_safe(planner.plan_for(values), obstacles, GAMMA)

    # Removing it leaves the new path clear: no replan.
    mark = planner.diagnostics.mark()
    planner.set_obstacles(marker_array(
        marker('test', 1, Marker.SPHERE, blocker, [1.0, 1.0, 1.0], action=Marker.DELETE)),
        len(SCENE.obstacles) + 1)
    time.sleep(0.5)
    assert planner.diag_events(mark, 'plan') == []


def test_point_cloud_obstacles_are_avoided(planner):
    path = conv.path_to_points(planner.baseline[1])
    center = path[len(path) // 3]
    rng = np.random.default_rng(3)
    blob = center + rng.uniform(-0.5, 0.5, size=(400, 3))
    # NaN points (no sensor return) are dropped, not a reason to refuse the cloud.
    cloud = np.vstack([blob, [[math.nan, 0.0, 0.0]]])
    mark = planner.diagnostics.mark()
    planner.cloud_pub.publish(_cloud(cloud))
    values = planner.wait_diag(mark, 'plan')
    assert values['status'] == 'ok', values
    obstacles = ObstacleSet(list(scene_obstacles().items) + [PointSet(blob)])
    assert_safe(planner.plan_for(values), obstacles, GAMMA)
    # An empty cloud clears the points again.
    planner.cloud_pub.publish(_cloud(np.zeros((0, 3))))
    planner.markers.wait_for(
        lambda m: not any(marker.type == Marker.CUBE_LIST for marker in m.markers), 10.0,
        what='cloud removed')


# ------------------------------------------------------------------------------ start sources

def test_start_comes_from_start_pose_then_odom(planner):
    planner.start_pub.publish(pose_msg([-2.0, -7.0, 1.0]))
    time.sleep(0.3)
    values, path = planner.plan_to(GOAL)
    assert values['status'] == 'ok' and values['start_source'] == 'start_pose', values
    assert np.allclose(conv.path_to_points(path)[0], [-2.0, -7.0, 1.0])

    odom = [1.0, -8.0, 2.0]

    def odom_used() -> bool:
        planner.odom_pub.publish(odom_msg(odom))
        mark = planner.diagnostics.mark()
        planner.goal_pub.publish(pose_msg(GOAL, 'map', GOAL_ORIENTATION))
        values = planner.wait_diag(mark, 'plan')
        return values if values['start_source'] == 'odom' else None
    values = wait_until(odom_used, 15.0, 'a plan from odom', period_s=0.1)
    path = planner.plan_for(values)
    assert np.allclose(conv.path_to_points(path)[0], odom)


# ------------------------------------------------------------------------------ namespaces

def test_namespaced_instance_plans_beside_the_first(ros, planner):
    first, second = ros['first'], ros['second']
    assert second.fqn == f'{SECOND_NAMESPACE}/{NODE_NAME}'
    assert first.fqn == f'{RUN_NAMESPACE}/{NODE_NAME}'
    wait_until(lambda: second.params.get(['safety_margin']), 5.0, 'second node parameters')
    mark = first.diagnostics.mark()
    first_plans = first.plans.mark()
    only_box = marker_array(marker('box', 0, Marker.CUBE, (5.0, 0.0, 5.0), (2.0, 8.0, 10.0)))
    second.set_obstacles(only_box, 1)
    values, path = second.plan_to([9.0, 0.0, 5.0])
    assert values['status'] == 'ok', values
    box = ObstacleSet([Box([4.0, -4.0, 0.0], [6.0, 4.0, 10.0])])
    assert_safe(path, box, GAMMA)
    assert np.allclose(conv.path_to_points(path)[-1], [9.0, 0.0, 5.0])
    # The first instance saw none of it.
    assert first.diag_events(mark, 'plan') == []
    assert first.plans.mark() == first_plans
