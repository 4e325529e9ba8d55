"""Nav2's planner interfaces of the node, from a separate client process's point of view.

Three planner processes serve the module: ``paper`` (the paper_medium spheres plus a closed box
around an unreachable point), ``long`` (a fine 50 m x 50 m x 10 m grid, 25 M nodes, where
Dijkstra to an enclosed goal takes seconds: for cancel and preemption) and ``bare`` (started
with nav2_msgs made unimportable: no action servers, the rest works). The test side uses rclpy's
``ActionClient`` and a ``GetPlan`` client, as ``nav2_simple_commander`` does.
"""

from pathlib import Path
import sys
from typing import List, Sequence

from action_msgs.msg import GoalStatus
from diagnostic_msgs.msg import DiagnosticArray
from helpers.ros_messages import duration_to_seconds
from nav_msgs.srv import GetPlan
import numpy as np
import pytest
from rclpy.action import ActionClient, get_action_names_and_types
from trajectory_msgs.msg import MultiDOFJointTrajectory
from visualization_msgs.msg import Marker, MarkerArray

from ros_harness import (assert_clean_exit, LATCHED_QOS, marker, marker_array, min_clearance,
                         NodeProcess, planner_command, PlannerClient, pose_msg, READY_TEXT,
                         ros_environment, RosClient, RUN_NAMESPACE, start_planner,
                         STARTUP_TIMEOUT_S, unique_domain_id, wait_future)
from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.core.map.obstacles import Box, ObstacleSet
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.nav2_client import ExecutorCalls, get_result, send_goal
from uav_global_planner.ros.nav2_interfaces import PREEMPTED_TEXT

try:
    from nav2_msgs.action import ComputePathThroughPoses, ComputePathToPose
except ImportError as error:  # pragma: no cover - the message is the point
    raise ImportError(f'nav2_msgs is not importable ({error}); scripts/venv.sh builds it with '
                      'scripts/build_interfaces.sh') from None

pytestmark = pytest.mark.ros

SCENE = load_scene(find_scene('paper_medium'))
GAMMA = 0.2
START = np.array([0.0, -5.0, 0.0])  # the start parameter of config/planner.yaml
GOAL = np.array(SCENE.goal, dtype=float)
TOL = 1e-6
REPO_ROOT = Path(__file__).resolve().parents[1]
RESULT_TIMEOUT_S = 60.0

#: A closed box shell (walls 0.3 m) around an unreachable point of the paper scene.
SEALED_CENTER = np.array([-7.0, 7.0, 12.0])
#: The long-plan node: Dijkstra expands every node of a 501 x 501 x 101 grid before it finds
#: that the enclosed goal cannot be reached (3-5 s on a fast 2-core machine; 7.5 M nodes, as
#: before, took under a second: the plans ended before a test could act while they ran).
LONG_PARAMETERS = {'bounds.min': [0.0, 0.0, 0.0], 'bounds.max': [50.0, 50.0, 10.0],
                   'resolution': 0.1, 'algorithm': 'dijkstra', 'max_planning_time': 0.0,
                   'start': [1.0, 1.0, 1.0]}
LONG_GOAL = np.array([40.0, 40.0, 5.0])

# A module without nav2_msgs: the node must run without its action servers.
_WITHOUT_NAV2 = ("import runpy, sys; sys.modules['nav2_msgs'] = None; "
                 "runpy.run_module('uav_global_planner.ros.planner_node', run_name='__main__')")


def shell_boxes(center: Sequence[float], half: float = 1.5, wall: float = 0.3) -> List[Box]:
    """Six boxes forming a closed shell around ``center``."""
    center = np.asarray(center, dtype=float)
    boxes = []
    for axis in range(3):
        for side in (-1, 1):
            lo, hi = center - half, center + half
            if side < 0:
                hi[axis] = lo[axis] + wall
            else:
                lo[axis] = hi[axis] - wall
            boxes.append(Box(lo, hi))
    return boxes


def box_markers(boxes: List[Box], ns: str) -> List[Marker]:
    return [marker(ns, index, Marker.CUBE, (box.min + box.max) / 2, box.max - box.min)
            for index, box in enumerate(boxes)]


def paper_obstacles() -> ObstacleSet:
    return ObstacleSet(list(SCENE.obstacles.items) + shell_boxes(SEALED_CENTER))


def paper_markers() -> MarkerArray:
    msg = conv.obstacle_input_markers(SCENE.obstacles, 'map', 0, ns='scene')
    msg.markers.extend(box_markers(shell_boxes(SEALED_CENTER), 'sealed'))
    return msg


class Nav2Client:
    """Action and GetPlan clients of one planner node.

    Action requests go out on the client's spin thread (:class:`ExecutorCalls`): rclpy's
    ActionClient drops an answer that arrives before it registered the request.
    """

    def __init__(self, planner: PlannerClient) -> None:
        node = planner.client.node
        self.planner = planner
        self.calls = ExecutorCalls(node)
        self.to_pose = ActionClient(node, ComputePathToPose,
                                    planner.prefix + 'compute_path_to_pose')
        self.through = ActionClient(node, ComputePathThroughPoses,
                                    planner.prefix + 'compute_path_through_poses')
        self.get_plan_client = node.create_client(GetPlan, planner.prefix + 'get_plan')
        assert self.to_pose.wait_for_server(timeout_sec=20.0)
        assert self.through.wait_for_server(timeout_sec=20.0)
        assert self.get_plan_client.wait_for_service(timeout_sec=20.0)

    def send(self, client: ActionClient, goal):
        """Send a goal; return its accepted handle."""
        handle = send_goal(self.calls, client, goal, 20.0)
        assert handle.accepted
        return handle

    def result(self, handle, timeout_s: float = RESULT_TIMEOUT_S):
        """(status, result) of an accepted goal."""
        response = get_result(self.calls, handle, timeout_s)
        return response.status, response.result

    def cancel(self, handle):
        """The cancel response of a goal."""
        return wait_future(self.calls(handle.cancel_goal_async), 20.0, 'the cancel response')

    def path_to(self, goal: Sequence[float], **fields):
        request = ComputePathToPose.Goal(goal=pose_msg(goal), **fields)
        return self.result(self.send(self.to_pose, request))

    def path_through(self, poses: Sequence[Sequence[float]], **fields):
        request = ComputePathThroughPoses.Goal(goals=[pose_msg(p) for p in poses], **fields)
        return self.result(self.send(self.through, request))

    def get_plan(self, goal: Sequence[float], tolerance: float = 0.0, start=None):
        request = GetPlan.Request(goal=pose_msg(goal), tolerance=float(tolerance))
        if start is not None:
            request.start = pose_msg(start)
        return wait_future(self.get_plan_client.call_async(request), RESULT_TIMEOUT_S,
                           'the GetPlan response').plan


@pytest.fixture(scope='module')
def ros():
    domain_id = unique_domain_id()
    paper_ns = f'{RUN_NAMESPACE}/paper'
    long_ns = f'{RUN_NAMESPACE}/long'
    bare_ns = f'{RUN_NAMESPACE}/bare'
    paper = start_planner(domain_id, wait=False, namespace=paper_ns)
    long = start_planner(domain_id, wait=False, namespace=long_ns, parameters=LONG_PARAMETERS)
    bare_command = planner_command(namespace=bare_ns)
    bare_command[1:3] = ['-c', _WITHOUT_NAV2]
    bare = NodeProcess(bare_command, ros_environment(domain_id))
    client = None
    try:
        for process in (paper, long, bare):
            process.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        client = RosClient(domain_id, 'nav2_test_client')
        diagnostics = client.record(DiagnosticArray, '/diagnostics')
        planners = {'paper': PlannerClient(client, paper_ns, diagnostics, paper),
                    'long': PlannerClient(client, long_ns, diagnostics, long),
                    'bare': PlannerClient(client, bare_ns, diagnostics, bare)}
        planners['paper'].set_obstacles(paper_markers(), len(SCENE.obstacles) + 6)
        planners['long'].set_obstacles(
            marker_array(*box_markers(shell_boxes(LONG_GOAL), 'sealed')), 6)
        yield {'client': client, 'planners': planners, 'domain_id': domain_id,
               'trajectories': client.record(MultiDOFJointTrajectory, f'{paper_ns}/trajectory',
                                             LATCHED_QOS),
               'paper': Nav2Client(planners['paper']), 'long': Nav2Client(planners['long'])}
    finally:
        if client is not None:
            client.close()
        try:
            for process in (paper, long, bare):
                assert_clean_exit(process, process.stop())
        finally:
            for process in (paper, long, bare):
                process.kill()


@pytest.fixture(scope='module')
def paper(ros) -> Nav2Client:
    return ros['paper']


def path_points(path) -> np.ndarray:
    return conv.path_to_points(path)


def assert_safe_path(path, start: Sequence[float], goal: Sequence[float]) -> np.ndarray:
    points = path_points(path)
    assert len(points) >= 2
    assert np.linalg.norm(points[0] - start) <= TOL, points[0]
    assert np.linalg.norm(points[-1] - goal) <= TOL, points[-1]
    clearance = min_clearance(points, paper_obstacles())
    assert clearance >= GAMMA - TOL, f'clearance {clearance} m < gamma {GAMMA} m'
    return points


def distance_to_polyline(point: np.ndarray, points: np.ndarray) -> float:
    """Distance [m] from ``point`` to the polyline through ``points``."""
    a, b = points[:-1], points[1:]
    ab = b - a
    lengths = np.einsum('ij,ij->i', ab, ab)
    t = np.clip(np.einsum('ij,ij->i', point - a, ab) / np.where(lengths > 0, lengths, 1), 0, 1)
    return float(np.min(np.linalg.norm(a + t[:, None] * ab - point, axis=1)))


# ------------------------------------------------------------------------ ComputePathToPose

def test_path_to_pose_keeps_gamma_ends_at_the_goal_and_is_published(ros, paper):
    planner = ros['planners']['paper']
    mark = planner.plans.mark()
    status, result = paper.path_to(GOAL)
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_msg
    assert result.error_code == ComputePathToPose.Result.NONE and result.error_msg == ''
    assert result.path.header.frame_id == 'map'
    assert_safe_path(result.path, START, GOAL)
    assert duration_to_seconds(result.planning_time) > 0.0
    stamps = [conv.time_to_ns(pose.header.stamp) for pose in result.path.poses]
    assert np.all(np.diff(stamps) > 0), 'one timed trajectory: stamps increase'
    # The same plan is published on plan (latched), as Nav2's planner server does.
    published = planner.plans.wait_for(
        lambda msg: msg.header.stamp == result.path.header.stamp, 10.0, mark)
    assert np.array_equal(path_points(published), path_points(result.path))


def test_use_start_plans_from_the_given_start(paper):
    start = np.array([-6.0, -6.0, 2.0])
    status, result = paper.path_to(GOAL, start=pose_msg(start), use_start=True)
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_msg
    assert_safe_path(result.path, start, GOAL)


def test_a_start_a_little_below_the_floor_is_lifted_as_the_node_does(ros, paper):
    """The node's own start admission serves Nav2 too: 0.2 m below the floor (within
    start_tolerance 0.5 m) the path starts on the floor, and the diagnostics say so."""
    planner = ros['planners']['paper']
    mark = planner.diagnostics.mark()
    landed = np.array([-6.0, -6.0, -0.2])
    status, result = paper.path_to(GOAL, start=pose_msg(landed), use_start=True)
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_msg
    assert_safe_path(result.path, [-6.0, -6.0, 0.0], GOAL)
    values = planner.wait_diag(mark, 'plan', check=lambda v: v['reason'] == (
        'compute_path_to_pose request'))
    assert 'below the floor' in values['note'] and 'lifted' in values['note'], values
    # Beyond the tolerance the start is refused, with the fix.
    status, result = paper.path_to(GOAL, start=pose_msg([-6.0, -6.0, -1.0]), use_start=True)
    assert result.error_code == ComputePathToPose.Result.START_OUTSIDE_MAP, result.error_msg
    assert 'start_tolerance' in result.error_msg, result.error_msg


def test_planner_id_selects_the_algorithm(ros, paper):
    planner = ros['planners']['paper']
    mark = planner.diagnostics.mark()
    status, result = paper.path_to(GOAL, planner_id='octile')
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_msg
    values = planner.wait_diag(mark, 'plan',
                               check=lambda v: v['reason'] == 'compute_path_to_pose request')
    assert values['algorithm'] == 'octile'


INSIDE_SPHERE = np.array(SCENE.obstacles.items[3].center)


@pytest.mark.parametrize('goal, fields, code, text', [
    ([10.0, 5.0, 10.0], {'start': pose_msg([0.0, -50.0, 0.0]), 'use_start': True},
     ComputePathToPose.Result.START_OUTSIDE_MAP, 'start [0.0, -50.0, 0.0] is outside the bounds'),
    ([30.0, 5.0, 10.0], {}, ComputePathToPose.Result.GOAL_OUTSIDE_MAP,
     'goal [30.0, 5.0, 10.0] is outside the bounds'),
    ([10.0, 5.0, 10.0], {'start': pose_msg(INSIDE_SPHERE), 'use_start': True},
     ComputePathToPose.Result.START_OCCUPIED, 'is within the safety margin'),
    (INSIDE_SPHERE, {}, ComputePathToPose.Result.GOAL_OCCUPIED, 'is within the safety margin'),
    (SEALED_CENTER, {}, ComputePathToPose.Result.NO_VALID_PATH, 'no path'),
    ([10.0, 5.0, 10.0], {'planner_id': 'GridBased'}, ComputePathToPose.Result.INVALID_PLANNER,
     "planner_id 'GridBased' is not a planner of this node"),
])
def test_path_to_pose_failure_codes(paper, goal, fields, code, text):
    status, result = paper.path_to(goal, **fields)
    assert status == GoalStatus.STATUS_ABORTED
    assert result.error_code == code, result.error_msg
    assert text in result.error_msg
    assert len(result.path.poses) == 0


def test_wrong_frame_is_tf_error(paper):
    request = ComputePathToPose.Goal(goal=pose_msg(GOAL, frame_id='odom'))
    status, result = paper.result(paper.send(paper.to_pose, request))
    assert status == GoalStatus.STATUS_ABORTED
    assert result.error_code == ComputePathToPose.Result.TF_ERROR
    assert "in frame 'odom'" in result.error_msg


def test_exhausted_budget_is_timeout(ros, paper):
    params = ros['planners']['paper'].params
    assert all(r.successful for r in params.set({'max_expansions': 3}))
    try:
        status, result = paper.path_to(GOAL, planner_id='dijkstra')
    finally:
        assert all(r.successful for r in params.set({'max_expansions': 0}))
    assert status == GoalStatus.STATUS_ABORTED
    assert result.error_code == ComputePathToPose.Result.TIMEOUT, result.error_msg
    assert 'budget' in result.error_msg or 'expansions' in result.error_msg


# --------------------------------------------------------------------------- cancel, preempt

def wait_until_planning(ros, after: int) -> None:
    """Wait for the long node's progress report: its plan of the goal is running."""
    ros['planners']['long'].wait_diag(
        after, 'progress', 60.0, check=lambda v: v.get('reason') == 'compute_path_to_pose request')


def test_cancel_stops_a_long_plan(ros):
    long = ros['long']
    mark = ros['planners']['long'].diagnostics.mark()
    handle = long.send(long.to_pose, ComputePathToPose.Goal(goal=pose_msg(LONG_GOAL)))
    wait_until_planning(ros, mark)
    cancel = long.cancel(handle)
    assert len(cancel.goals_canceling) == 1
    status, result = long.result(handle)
    assert status == GoalStatus.STATUS_CANCELED
    assert len(result.path.poses) == 0


def test_new_goal_preempts_the_running_one(ros):
    long = ros['long']
    mark = ros['planners']['long'].diagnostics.mark()
    first = long.send(long.to_pose, ComputePathToPose.Goal(goal=pose_msg(LONG_GOAL)))
    wait_until_planning(ros, mark)
    near = np.array([5.0, 5.0, 2.0])
    second = long.send(long.to_pose, ComputePathToPose.Goal(goal=pose_msg(near)))
    status, result = long.result(first)
    assert status == GoalStatus.STATUS_ABORTED
    assert result.error_code == ComputePathToPose.Result.NONE
    assert result.error_msg == PREEMPTED_TEXT
    status, result = long.result(second)
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_msg
    assert np.linalg.norm(path_points(result.path)[-1] - near) <= TOL


#: The wall race, per interface: the request's kind (its diagnostics' reason) and whether it
#: publishes the plan it answers with.
RACED_INTERFACES = {'compute_path_to_pose': True, 'compute_path_through_poses': True,
                    'get_plan': False}


@pytest.mark.parametrize('kind', list(RACED_INTERFACES))
def test_a_map_that_blocks_the_path_while_it_is_planned_refuses_it(ros, kind):
    """A wall across the whole workspace lands while the long node plans: the path planned on
    the map before it crosses the wall, so the client gets no path and nothing is published,
    through every interface (the node's one release gate, PlanInForce.release)."""
    long, planner = ros['long'], ros['planners']['long']
    mark, plans = planner.diagnostics.mark(), planner.plans.mark()
    goal = pose_msg([48.0, 45.0, 5.0])
    if kind == 'compute_path_to_pose':
        request = long.calls(lambda: long.to_pose.send_goal_async(
            ComputePathToPose.Goal(goal=goal)))
    elif kind == 'compute_path_through_poses':
        request = long.calls(lambda: long.through.send_goal_async(ComputePathThroughPoses.Goal(
            goals=[pose_msg([30.0, 5.0, 5.0]), goal])))
    else:
        request = long.get_plan_client.call_async(GetPlan.Request(goal=goal))
    planner.wait_diag(mark, 'progress', 60.0, check=lambda v: v.get('reason') == f'{kind} request')
    # Every path from x = 1 m to x = 48 m crosses x = 20 m within the bounds (0-50 x 0-10 m).
    wall = [20.0, 25.0, 5.0], [0.5, 50.0, 10.0]
    planner.publish('obstacles', marker_array(marker('wall', 0, Marker.CUBE, *wall)))
    try:
        if kind == 'get_plan':
            path = wait_future(request, RESULT_TIMEOUT_S, 'the GetPlan response').plan
        else:
            handle = wait_future(request, 20.0, 'the goal response')
            assert handle.accepted
            status, result = long.result(handle)
            assert status == GoalStatus.STATUS_ABORTED, result.error_msg
            action = (ComputePathToPose if kind == 'compute_path_to_pose'
                      else ComputePathThroughPoses)
            assert result.error_code == action.Result.NO_VALID_PATH, result.error_msg
            assert 'arrived while planning' in result.error_msg, result.error_msg
            path = result.path
        assert len(path.poses) == 0
        refused = planner.wait_diag(mark, 'plan', check=lambda v: v['reason'] == f'{kind} request')
        assert refused['status'] == 'no_valid_path', refused
        assert 'arrived while planning' in refused['message'], refused
        assert planner.plans.mark() == plans, 'a plan crossing the wall was published'
    finally:
        # The next request must start on the map without the wall.
        shown = planner.markers.mark()
        planner.publish('obstacles', marker_array(
            marker('wall', 0, Marker.CUBE, *wall, action=Marker.DELETE)))
        planner.wait_obstacle_count(6, shown, timeout_s=60.0)


# ---------------------------------------------------------------- ComputePathThroughPoses

VIA_POINTS = np.array([[-5.0, -6.0, 3.0], [-5.0, 4.0, 8.0], [2.0, 8.0, 11.0], [8.0, -6.0, 11.0],
                       [6.0, -1.0, 13.0]])


def test_via_points_are_free():
    clearances = paper_obstacles().distance(VIA_POINTS)
    assert np.all(clearances > GAMMA + 0.5), clearances


@pytest.mark.parametrize('count', [3, 4, 5])
def test_path_through_poses_passes_every_via_point(ros, paper, count):
    via = VIA_POINTS[:count]
    planner = ros['planners']['paper']
    mark, trajectories_mark = planner.plans.mark(), ros['trajectories'].mark()
    status, result = paper.path_through([*via, GOAL])
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_msg
    assert result.error_code == ComputePathThroughPoses.Result.NONE
    points = assert_safe_path(result.path, START, GOAL)
    for number, point in enumerate(via):
        assert distance_to_polyline(point, points) <= TOL, f'via-point {number} missed'
    # One timed trajectory through all of them: stamps increase over the whole path.
    stamps = np.array([conv.time_to_ns(pose.header.stamp) for pose in result.path.poses])
    assert np.all(np.diff(stamps) > 0)
    planner.plans.wait_for(lambda msg: msg.header.stamp == result.path.header.stamp, 10.0, mark)
    # The published trajectory flies through the via-points without stopping there.
    trajectory = ros['trajectories'].wait_for(
        lambda msg: msg.header.stamp == result.path.header.stamp, 10.0, trajectories_mark)
    positions = np.array([[p.transforms[0].translation.x, p.transforms[0].translation.y,
                           p.transforms[0].translation.z] for p in trajectory.points])
    for point in via:
        sample = trajectory.points[int(np.argmin(np.linalg.norm(positions - point, axis=1)))]
        velocity = sample.velocities[0].linear
        assert np.linalg.norm([velocity.x, velocity.y, velocity.z]) > 0.0


def test_empty_pose_list_is_no_viapoints_given(paper):
    status, result = paper.result(paper.send(paper.through, ComputePathThroughPoses.Goal()))
    assert status == GoalStatus.STATUS_ABORTED
    assert result.error_code == ComputePathThroughPoses.Result.NO_VIAPOINTS_GIVEN == 309
    assert result.error_msg


def test_via_point_inside_an_obstacle_names_its_leg(paper):
    status, result = paper.path_through([VIA_POINTS[0], INSIDE_SPHERE, VIA_POINTS[2], GOAL])
    assert status == GoalStatus.STATUS_ABORTED
    assert result.error_code == ComputePathThroughPoses.Result.GOAL_OCCUPIED == 306
    assert 'leg 1' in result.error_msg, result.error_msg


def test_through_poses_codes_are_offset(paper):
    status, result = paper.path_through([GOAL], planner_id='nope')
    assert status == GoalStatus.STATUS_ABORTED
    assert result.error_code == ComputePathThroughPoses.Result.INVALID_PLANNER == 301
    status, result = paper.path_through([[0.0, 50.0, 1.0], GOAL])
    assert result.error_code == ComputePathThroughPoses.Result.GOAL_OUTSIDE_MAP == 304


# ------------------------------------------------------------------------------- GetPlan

def test_get_plan_answers_with_the_path(paper):
    plan = paper.get_plan(GOAL)
    assert_safe_path(plan, START, GOAL)
    start = np.array([-6.0, -6.0, 2.0])
    assert_safe_path(paper.get_plan(GOAL, start=start), start, GOAL)


def test_get_plan_failure_is_an_empty_path_with_the_reason(ros, paper):
    planner = ros['planners']['paper']
    mark, lines = planner.diagnostics.mark(), planner.process.mark()
    plan = paper.get_plan(SEALED_CENTER)
    assert len(plan.poses) == 0
    values = planner.wait_diag(mark, 'plan', check=lambda v: v['reason'] == 'get_plan request')
    assert values['status'] == 'no_valid_path'
    assert 'no path' in values['message']
    planner.process.wait_for_output('get_plan request failed: no_valid_path', 10.0, lines)


def test_get_plan_tolerance_uses_the_nearest_free_node(ros, paper):
    planner = ros['planners']['paper']
    occupied = np.array(SCENE.obstacles.items[1].center)  # sphere of radius 1.16 m
    assert len(paper.get_plan(occupied, tolerance=0.0).poses) == 0
    assert len(paper.get_plan(occupied, tolerance=0.5).poses) == 0  # still inside
    lines = planner.process.mark()
    plan = paper.get_plan(occupied, tolerance=2.0)
    points = path_points(plan)
    assert len(points) >= 2
    end = points[-1]
    assert np.linalg.norm(end - occupied) <= 2.0
    assert float(paper_obstacles().distance(end)) > GAMMA
    assert min_clearance(points, paper_obstacles()) >= GAMMA - TOL
    line = planner.process.wait_for_output('nearest free node', 10.0, lines)
    assert 'is occupied' in line


def test_readme_example_gets_both_paths(ros):
    planner = ros['planners']['paper']
    command = [sys.executable, str(REPO_ROOT / 'docs' / 'nav2_example.py'), '--ros-args', '-r',
               f'__ns:={planner.prefix.rstrip("/")}']
    example = NodeProcess(command, ros_environment(ros['domain_id']))
    try:
        code = example.process.wait(RESULT_TIMEOUT_S)
    finally:
        example.kill()
    example.stop()
    assert code == 0, example.output
    assert 'direct: ' in example.output and 'through 2 via-points: ' in example.output
    assert 'failed' not in example.output, example.output


# ---------------------------------------------------------------------- without nav2_msgs

def test_without_nav2_msgs_the_node_serves_topics_and_get_plan(ros):
    bare = ros['planners']['bare']
    node = ros['client'].node
    output = bare.process.output
    assert output.count('Nav2 action servers compute_path_to_pose and '
                        'compute_path_through_poses are off') == 1, output
    assert 'nav2_msgs is not importable' in output
    actions = dict(get_action_names_and_types(node))
    assert bare.prefix + 'compute_path_to_pose' not in actions
    assert ros['planners']['paper'].prefix + 'compute_path_to_pose' in actions
    client = node.create_client(GetPlan, bare.prefix + 'get_plan')
    assert client.wait_for_service(timeout_sec=20.0)
    response = wait_future(client.call_async(GetPlan.Request(goal=pose_msg(GOAL))), 60.0,
                           'GetPlan of the node without nav2_msgs')
    assert np.linalg.norm(path_points(response.plan)[-1] - GOAL) <= TOL
    # No map source has delivered: a goal on the topic is refused with the reason, and is
    # planned once a (here empty) map is in.
    values, path = bare.plan_to(GOAL)
    assert values['status'] == 'no_map' and path is None, values
    mark = bare.diagnostics.mark()
    bare.publish('obstacles', marker_array())
    bare.wait_diag(mark, 'map_status', check=lambda v: v['obstacles_accepted'] == '1')
    values, path = bare.plan_to(GOAL)
    assert values['status'] == 'ok' and path is not None
