"""Live maps through real processes: map state, the plan in force under new maps, starts.

The planner nodes run as processes; the tests talk to them only through topics and parameter
services, as a mapping stack, a vehicle and a goal sender would.
"""

import threading
import time
from typing import Dict, Iterator

from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Path as PathMsg
import numpy as np
import pytest
from trajectory_msgs.msg import MultiDOFJointTrajectory
from visualization_msgs.msg import Marker, MarkerArray

from ros_harness import (LATCHED_QOS, marker, marker_array, min_clearance, odom_msg, PlannerClient,
                         plans_after_withdrawal, pose_msg, READY_TEXT, RosClient, RUN_NAMESPACE,
                         start_planner, STARTUP_TIMEOUT_S, unique_domain_id)
from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.core.map.obstacles import ObstacleSet, Sphere
from uav_global_planner.ros import conversions as conv

pytestmark = pytest.mark.ros

SCENE = load_scene(find_scene('paper_medium'))
GAMMA = 0.2
START = np.array([0.0, -5.0, 0.0])  # the start parameter of config/planner.yaml
GOAL = np.array(SCENE.goal)
TOL = 1e-6
ERROR = 2
WARN = 1

MAPPED = f'{RUN_NAMESPACE}/mapped'
OPEN_AIR = f'{RUN_NAMESPACE}/open_air'
BUSY = f'{RUN_NAMESPACE}/busy'


@pytest.fixture(scope='module')
def ros() -> Iterator[Dict[str, PlannerClient]]:
    """A planner with the defaults, one that may plan without a map, and a slow one (delta
    0.07 m, 17.7 M nodes, Dijkstra: plans of seconds)."""
    domain_id = unique_domain_id()
    processes = {}
    client = None
    try:
        processes['mapped'] = start_planner(domain_id, wait=False, namespace=MAPPED)
        processes['open_air'] = start_planner(domain_id, wait=False, namespace=OPEN_AIR,
                                              parameters={'plan_without_map': True})
        processes['busy'] = start_planner(domain_id, wait=False, namespace=BUSY, parameters={
            'resolution': 0.07, 'algorithm': 'dijkstra', 'max_planning_time': 120.0,
            'plan_without_map': True})
        for process in processes.values():
            process.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        client = RosClient(domain_id)
        diagnostics = client.record(DiagnosticArray, '/diagnostics')
        planners = {name: PlannerClient(client, {'mapped': MAPPED, 'open_air': OPEN_AIR,
                                                 'busy': BUSY}[name], diagnostics, process)
                    for name, process in processes.items()}
        for planner in planners.values():
            planner.trajectories = client.record(MultiDOFJointTrajectory,
                                                 planner.prefix + 'trajectory', LATCHED_QOS)
        yield planners
    finally:
        if client is not None:
            client.close()
        for process in processes.values():
            process.kill()


def scene_markers() -> MarkerArray:
    return conv.obstacle_input_markers(SCENE.obstacles, 'map', 0, ns='scene')


def points_of(path: PathMsg) -> np.ndarray:
    return conv.path_to_points(path)


def publish_scene(planner: PlannerClient) -> None:
    """Publish the scene's spheres; return once the node has taken them in (they may be in
    force already, and then nothing changes)."""
    before = planner.diag_events(0, 'map_status')
    accepted = int(before[-1]['obstacles_accepted']) if before else 0
    mark = planner.diagnostics.mark()
    planner.publish('obstacles', scene_markers())
    planner.wait_diag(mark, 'map_status',
                      check=lambda v: int(v['obstacles_accepted']) > accepted)


# ------------------------------------------------------------------------------ map state

def test_a_goal_before_any_map_is_refused_with_the_reason(ros) -> None:
    planner = ros['mapped']
    plans = planner.plans.mark()
    values, path = planner.plan_to(GOAL)
    assert values['status'] == 'no_map', values
    assert values['_level'] == ERROR
    assert values['status_code'] == '200'
    assert ('no map yet: none of the map sources (obstacles, obstacle_cloud, map_file) has '
            'delivered' in values['message']), values
    assert 'set plan_without_map to plan in open air' in values['message'], values
    assert path is None and planner.plans.mark() == plans, 'a plan went out without a map'
    status = planner.wait_diag(0, 'map_status', check=lambda v: v['status'] == 'no_map')
    assert status['_level'] == WARN and status['obstacles_accepted'] == '0', status
    # An empty array is a map: "nothing here" from a map server that has delivered.
    mark = planner.diagnostics.mark()
    planner.publish('obstacles', marker_array())
    planner.wait_diag(mark, 'map_status', check=lambda v: v['obstacles_accepted'] == '1')
    values, path = planner.plan_to(GOAL)
    assert values['status'] == 'ok', values
    assert 'obstacles: 1 accepted' in values['map_sources'], values


def test_without_a_map_open_air_is_planned_when_asked_for(ros) -> None:
    values, path = ros['open_air'].plan_to(GOAL)
    assert values['status'] == 'ok', values
    assert values['map_refused'] == '' and values['obstacles'] == '0'
    assert np.allclose(points_of(path)[-1], GOAL)


def test_refused_obstacles_are_named_in_the_plan(ros) -> None:
    planner = ros['mapped']
    planner.set_obstacles(scene_markers(), len(SCENE.obstacles))
    mark = planner.diagnostics.mark()
    planner.publish('obstacles', marker_array(
        marker('late', 0, Marker.SPHERE, [5.0, 0.0, 5.0], [1.0, 1.0, 1.0], frame_id='odom')))
    planner.wait_diag(mark, 'input_rejected')
    values, path = planner.plan_to(GOAL)
    assert values['status'] == 'ok', values
    assert values['_level'] == WARN, 'a plan on an incomplete map was reported OK'
    assert values['map_refused'].startswith('obstacles ('), values
    assert "in frame 'odom'" in values['map_refused'], values
    assert 'map incomplete' in values['message'], values
    # The scene itself is still in force, and is kept.
    assert min_clearance(points_of(path), SCENE.obstacles) >= GAMMA - TOL
    # A good array again (the same map): the source is complete again.
    mark = planner.diagnostics.mark()
    planner.publish('obstacles', scene_markers())
    planner.wait_diag(mark, 'map_status', check=lambda v: v['map_refused'] == '')
    values, _ = planner.plan_to([8.0, 8.0, 8.0])
    assert values['status'] == 'ok' and values['map_refused'] == '', values
    assert values['_level'] == 0


def test_required_sources_are_waited_for(ros) -> None:
    planner = ros['mapped']
    (result,) = planner.params.set({'required_map_sources': ['obstacle_cloud']})
    assert result.successful, result.reason
    try:
        values, _ = planner.plan_to(GOAL)
        assert values['status'] == 'no_map', values
        assert ('no map yet: required_map_sources obstacle_cloud not delivered'
                in values['message']), values
        mark = planner.diagnostics.mark()
        planner.publish('obstacle_cloud', conv.points_to_cloud(
            np.array([[9.0, -9.0, 14.0]]), 'map', 1))
        planner.wait_diag(mark, 'map_status', check=lambda v: v['obstacle_cloud_accepted'] == '1')
        values, _ = planner.plan_to(GOAL)
        assert values['status'] == 'ok', values
    finally:
        planner.params.set({'required_map_sources': ['any']})
    (result,) = planner.params.set({'required_map_sources': ['lidar']})
    assert not result.successful and 'required_map_sources' in result.reason
    (result,) = planner.params.set({'required_map_sources': ['map_file']})
    assert not result.successful and 'no map_file is set' in result.reason
    (result,) = planner.params.set({'cloud_qos_reliability': 'best_effort'})
    # Read at start-up: a read-only parameter, refused by rclpy on a running node.
    assert not result.successful and 'read-only parameter' in result.reason, result.reason
    assert planner.params.get(['cloud_qos_reliability']) == {'cloud_qos_reliability': 'reliable'}


# ------------------------------------------------------------------------------ plan in force

def _sphere_on(points: np.ndarray, fraction: float) -> np.ndarray:
    """A point of the path, ``fraction`` along its samples."""
    return points[int(fraction * (len(points) - 1))]


def test_an_obstacle_dropped_on_the_plan_in_force_withdraws_it_at_once(ros) -> None:
    planner = ros['mapped']
    publish_scene(planner)
    values, path = planner.plan_to(GOAL)
    assert values['status'] == 'ok', values
    center = _sphere_on(points_of(path), 0.5)
    diag_mark, plan_mark = planner.diagnostics.mark(), planner.plans.mark()
    trajectory_mark = planner.trajectories.mark()
    planner.publish('obstacles', marker_array(
        marker('dropped', 0, Marker.SPHERE, center, [0.8, 0.8, 0.8])))
    withdrawn = planner.wait_diag(diag_mark, 'plan_withdrawn')
    assert withdrawn['_level'] == ERROR, withdrawn
    assert 'hold position' in withdrawn['message'], withdrawn
    where = np.array([float(v) for v in withdrawn['blocked_at'].strip('[]').split(',')])
    assert np.linalg.norm(where - center) < 0.4 + GAMMA + 0.5, (where, center)
    assert float(withdrawn['blocked_ahead_m']) >= 0.0
    replaced = planner.wait_diag(diag_mark, 'plan')
    assert replaced['status'] == 'ok', replaced
    assert 'withdrawn' in replaced['reason'], replaced
    assert int(replaced['_stamp']) > int(withdrawn['_stamp']), 'replaced before withdrawn'
    after = points_of(planner.plan_for(replaced))
    obstacles = ObstacleSet(list(SCENE.obstacles.items) + [Sphere(center, 0.4)])
    assert min_clearance(after, obstacles) >= GAMMA - TOL
    assert np.allclose(after[-1], GOAL)
    # Nothing published after the drop collides with it: the empty withdrawal, then the
    # replacement (a subscription keeping one message may see only the replacement).
    plans_after_withdrawal(planner.plans, plan_mark, withdrawn,
                           lambda points: min_clearance(points, obstacles) >= GAMMA - TOL)
    newest = planner.trajectories.wait_for(
        lambda m: conv.time_to_ns(m.header.stamp) == int(replaced['_stamp']),
        after=trajectory_mark, what='the trajectory of the replacement')
    assert len(newest.points) > 0


def test_the_withdrawal_does_not_wait_for_a_running_plan(ros) -> None:
    """A long plan for a newer goal runs while an obstacle lands on the plan in force: the
    plan in force is withdrawn before the long plan ends."""
    busy = ros['busy']
    values, path = busy.plan_to([2.0, -4.0, 1.0], timeout_s=120.0)
    assert values['status'] == 'ok', values
    center = _sphere_on(points_of(path), 0.5)
    mark = busy.diagnostics.mark()
    busy.publish('goal_pose', pose_msg([9.0, 9.0, 14.0]))
    busy.wait_diag(mark, 'progress', 60.0, what='the long plan to be running')
    busy.publish('obstacles', marker_array(
        marker('dropped', 0, Marker.SPHERE, center, [0.4, 0.4, 0.4])))
    busy.wait_diag(mark, 'plan_withdrawn', 60.0)
    assert busy.diag_events(mark, 'plan') == [], 'the withdrawal waited for the running plan'
    served = busy.wait_diag(mark, 'plan', 120.0)
    assert served['status'] == 'ok', served
    assert served['goal'] == conv.format_value(np.array([9.0, 9.0, 14.0]))
    assert int(served['obstacles_checked_version']) >= 1


# ------------------------------------------------------------------------------ starts

def test_a_landed_vehicle_gets_a_take_off_plan(ros) -> None:
    planner = ros['open_air']
    landed = [1.0, 2.0, -0.02]
    goal = [1.0, 2.0, 6.0]

    def planned():
        # Odometry is streamed, as a flight stack does: one message on this volatile topic is
        # lost when it goes out before the node's subscription has matched the publisher.
        # A plan made meanwhile without it climbs from near the landed vehicle: while that
        # plan is young the still vehicle counts as flying it and the next plan continues it
        # (a moving takeover). The landed start is the one taken from rest.
        planner.publish('odom', odom_msg(landed))
        values, path = planner.plan_to(goal)
        from_rest = values['start_source'] == 'odom' and values.get('takeover') == 'rest'
        return (values, path) if from_rest else None
    values, path = _retry(planned, 'a plan from the landed odometry', timeout_s=60.0)
    assert values['status'] == 'ok', values
    assert values['start_adjusted'] == 'true', values
    assert 'outside the bounds' in values['start_note'], values
    points = points_of(path)
    assert np.allclose(points[0], [1.0, 2.0, 0.0]), points[0]
    assert np.all(points[:, 2] >= -TOL) and np.allclose(points[-1], goal)
    assert values['requested_start'] == conv.format_value(np.array(landed))
    # Farther below than start_tolerance is still refused.
    planner.publish('odom', odom_msg([1.0, 2.0, -1.0]))
    values = _retry(lambda: (lambda v: v if v[0]['status'] != 'ok' else None)(
        planner.plan_to([1.0, 3.0, 6.0])), 'the start far below the floor')[0]
    assert values['status'] == 'start_outside_map', values


def test_odometry_after_a_plan_from_the_start_parameter_replans(ros) -> None:
    planner = ros['mapped']
    publish_scene(planner)
    values, _ = planner.plan_to([8.0, 8.0, 8.0])
    # The mapped node has had no odometry: its plan starts at the start parameter.
    assert values['status'] == 'ok' and values['start_source'] == 'parameter', values
    mark = planner.diagnostics.mark()
    vehicle = [-7.0, -5.0, 1.0]

    def replanned_from_odometry():
        # Odometry is a best-effort stream, as a vehicle's: sent until it gets through.
        planner.publish('odom', odom_msg(vehicle))
        found = [v for v in planner.diag_events(mark, 'plan') if v['start_source'] == 'odom']
        return found[0] if found else None
    replanned = _retry(replanned_from_odometry, 'a plan from the odometry')
    assert 'vehicle position arrived' in replanned['reason'], replanned
    assert len(planner.diag_events(mark, 'plan')) == 1, 'more than one replan'
    assert np.allclose(points_of(planner.plan_for(replanned))[0], vehicle)
    # Further odometry does not replan by itself.
    time.sleep(0.5)
    later = planner.diagnostics.mark()
    planner.publish('odom', odom_msg([-7.0, -5.0, 1.1]))
    time.sleep(1.0)
    assert planner.diag_events(later, 'plan') == []


def test_a_plan_the_vehicle_left_behind_is_made_again_from_where_it_is(ros) -> None:
    busy = ros['busy']
    # The vehicle streams its odometry at 20 Hz, as a flight stack does.
    position = {'now': [-8.0, -8.0, 1.0]}
    streaming = threading.Event()

    def stream() -> None:
        while not streaming.is_set():
            busy.publish('odom', odom_msg(position['now']))
            time.sleep(0.05)
    sender = threading.Thread(target=stream, daemon=True)
    sender.start()
    try:
        time.sleep(1.5)
        mark = busy.diagnostics.mark()
        goal = np.array([8.0, 8.0, 12.0])
        busy.publish('goal_pose', pose_msg(goal))
        busy.wait_diag(mark, 'progress', 60.0, what='the plan to be running',
                       check=lambda v: v['goal'] == conv.format_value(goal))
        moved = [-4.0, -8.0, 1.0]
        position['now'] = moved
        dropped = busy.wait_diag(mark, 'plan_discarded', 120.0)
        assert 'vehicle moved' in dropped['reason'], dropped
        served = busy.wait_diag(mark, 'plan', 120.0)
        assert served['status'] == 'ok', served
        assert np.allclose(points_of(busy.plan_for(served))[0], moved)
    finally:
        streaming.set()
        sender.join(5.0)


def _retry(attempt, what: str, timeout_s: float = 20.0):
    deadline = time.monotonic() + timeout_s
    while True:
        found = attempt()
        if found:
            return found
        if time.monotonic() > deadline:
            raise AssertionError(f'timed out waiting for {what}')
        time.sleep(0.2)
