"""Faults around a running planner node: a dying map publisher, node restarts, late parameters.

* The obstacle publisher (a ``scene_publisher`` process, as a map server) is killed: the node
  keeps the map it had. A new publisher with another scene replaces it, delivered by the
  transient-local QoS without any resend.
* The node stopped with SIGTERM exits cleanly and, restarted with the same parameter file, gets
  the map from the still-running publisher and plans again; values set at run time are gone.
* A parameter set while a plan runs applies to the next plan, never to the one in flight.
* Obstacles that arrive while a plan is computed and collide with it: the plan is not published
  but made again on them (in-process, to time the arrival exactly).

The processes of the module start in parallel; the first two tests build on each other.
"""

import signal
import time
from typing import Dict, Iterator, List

from diagnostic_msgs.msg import DiagnosticArray
import numpy as np
import pytest
import rclpy
from rclpy.signals import SignalHandlerOptions
from visualization_msgs.msg import Marker

from ros_harness import (assert_clean_exit, marker, marker_array, min_clearance, NodeProcess,
                         PlannerClient, pose_msg, READY_TEXT, RosClient, RUN_NAMESPACE,
                         start_planner, start_scene_publisher, STARTUP_TIMEOUT_S, unique_domain_id)
from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, Sphere
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.planner_node import PlannerNode

pytestmark = [pytest.mark.ros, pytest.mark.slow]

MAPPED = f'{RUN_NAMESPACE}/faults'
BUSY = f'{RUN_NAMESPACE}/faults_busy'
PAPER = load_scene(find_scene('paper_medium'))
GAMMA = 0.2
START = np.array([0.0, -5.0, 0.0])  # the start parameter of config/planner.yaml
GOAL = [8.0, 8.0, 8.0]
# The centre of a paper_medium sphere: occupied on the paper map, free on the second one.
IN_PAPER_SPHERE = PAPER.obstacles.sphere_centers[3].tolist()
TOL = 1e-6

# The map of the restarted publisher: a wall between start and goal, and a small sphere.
SECOND_SCENE = """\
description: second map of test_node_faults
frame_id: map
bounds: {min: [-10.0, -10.0, 0.0], max: [10.0, 10.0, 15.0]}
resolution: 0.5
safety_margin: 0.2
adaptive_threshold: 1.5
start: [0.0, -5.0, 0.0]
goal: [8.0, 8.0, 8.0]
obstacles:
  - {type: box, min: [-4.0, -2.0, 0.0], max: [4.0, -1.0, 12.0]}
  - {type: sphere, center: [-6.0, 5.0, 5.0], radius: 1.0}
"""
SECOND_OBSTACLES = ObstacleSet([Box([-4.0, -2.0, 0.0], [4.0, -1.0, 12.0]),
                                Sphere([-6.0, 5.0, 5.0], 1.0)])


@pytest.fixture(scope='module')
def ros(tmp_path_factory) -> Iterator[Dict[str, object]]:
    """A planner with the shipped parameter file and a map publisher, and a busy planner
    (delta 0.07 m, Dijkstra: multi-second plans)."""
    domain_id = unique_domain_id()
    second_scene = tmp_path_factory.mktemp('faults') / 'second.yaml'
    second_scene.write_text(SECOND_SCENE)
    state: Dict[str, object] = {'domain_id': domain_id, 'second_scene': second_scene}
    processes = state['processes'] = []
    client = None
    try:
        processes.append(start_planner(domain_id, wait=False, namespace=MAPPED))
        processes.append(start_planner(domain_id, wait=False, namespace=BUSY, parameters={
            'resolution': 0.07, 'algorithm': 'dijkstra', 'max_planning_time': 60.0}))
        processes.append(start_scene_publisher(domain_id, 'paper_medium', MAPPED))
        state['planner'], state['busy'], state['publisher'] = processes
        for process in processes[:2]:
            process.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        client = RosClient(domain_id)
        diagnostics = client.record(DiagnosticArray, '/diagnostics')
        state['mapped'] = PlannerClient(client, MAPPED, diagnostics, processes[0])
        state['busy_client'] = PlannerClient(client, BUSY, diagnostics, processes[1])
        yield state
    finally:
        if client is not None:
            client.close()
        for process in processes:
            process.kill()


def plan_ok(planner: PlannerClient, goal, obstacles: ObstacleSet, count: int,
            gamma: float = GAMMA) -> Dict[str, str]:
    """Plan to ``goal``: ok, ``count`` obstacles in use, clearance >= gamma from ``obstacles``."""
    values, path = planner.plan_to(goal)
    assert values['status'] == 'ok', values
    assert values['obstacles'] == str(count), values
    points = conv.path_to_points(path)
    assert np.allclose(points[0], START) and np.allclose(points[-1], goal)
    assert min_clearance(points, obstacles) >= gamma - TOL
    return values


def test_map_outlives_its_publisher_and_follows_the_restarted_one(ros) -> None:
    planner: PlannerClient = ros['mapped']
    first: NodeProcess = ros['publisher']
    planner.wait_obstacle_count(len(PAPER.obstacles), timeout_s=15.0)
    before = plan_ok(planner, GOAL, PAPER.obstacles, len(PAPER.obstacles))

    # The map publisher dies without a goodbye.
    first.process.kill()
    first.process.wait()
    time.sleep(0.5)
    after = plan_ok(planner, GOAL, PAPER.obstacles, len(PAPER.obstacles))
    assert after['obstacles_version'] == before['obstacles_version'], 'the map changed'
    mark = planner.diagnostics.mark()
    planner.publish('goal_pose', pose_msg(IN_PAPER_SPHERE))
    occupied = planner.wait_diag(mark, 'plan')
    assert occupied['status'] == 'goal_occupied', occupied

    # A new publisher with another map: the node gets it through transient local durability,
    # and its DELETEALL of ns 'scene' leaves nothing of the old map.
    markers = planner.markers.mark()
    second = start_scene_publisher(ros['domain_id'], str(ros['second_scene']), MAPPED)
    ros['processes'].append(second)
    ros['publisher'] = second
    planner.wait_obstacle_count(len(SECOND_OBSTACLES), markers, timeout_s=STARTUP_TIMEOUT_S)
    plan_ok(planner, GOAL, SECOND_OBSTACLES, len(SECOND_OBSTACLES))
    plan_ok(planner, IN_PAPER_SPHERE, SECOND_OBSTACLES, len(SECOND_OBSTACLES))


def test_restart_with_the_same_parameter_file_gets_the_map_and_plans(ros) -> None:
    planner: PlannerClient = ros['mapped']
    (result,) = planner.params.set({'safety_margin': 0.4})
    assert result.successful, result.reason
    plan_ok(planner, GOAL, SECOND_OBSTACLES, len(SECOND_OBSTACLES), gamma=0.4)

    old: NodeProcess = ros['planner']
    assert_clean_exit(old, old.stop(signal.SIGTERM))
    markers = planner.markers.mark()
    new = start_planner(ros['domain_id'], namespace=MAPPED)  # the same config/planner.yaml
    ros['processes'].append(new)
    planner.process = new
    # The map comes from the publisher that kept running; nothing was resent.
    planner.wait_obstacle_count(len(SECOND_OBSTACLES), markers, timeout_s=15.0)
    assert planner.params.get(['safety_margin'])['safety_margin'] == GAMMA
    values = plan_ok(planner, GOAL, SECOND_OBSTACLES, len(SECOND_OBSTACLES))
    assert float(values['safety_margin_m']) == pytest.approx(GAMMA)
    assert_clean_exit(new, new.stop(signal.SIGINT))
    publisher: NodeProcess = ros['publisher']
    assert_clean_exit(publisher, publisher.stop(signal.SIGINT))


def test_parameter_set_during_a_plan_preempts_it(ros) -> None:
    """A parameter change that affects the running plan cancels it; the newer request (the
    next goal, with the new margin) is served next, and a long plan reports its stage."""
    busy: PlannerClient = ros['busy_client']
    busy.set_obstacles(conv.obstacle_input_markers(PAPER.obstacles, 'map', 0),
                       len(PAPER.obstacles))
    far, near = [9.0, 9.0, 14.0], [-2.0, -7.0, 1.0]
    assert busy.params.get(['safety_margin'])['safety_margin'] == GAMMA
    mark = busy.diagnostics.mark()
    busy.publish('goal_pose', pose_msg(far))
    progress = busy.wait_diag(mark, 'progress', 30.0)
    assert progress['stage'] == 'search', progress
    assert float(progress['elapsed_s']) >= 1.0, progress
    began = time.monotonic()
    (result,) = busy.params.set({'safety_margin': 0.5}, timeout_s=1.0)
    assert result.successful, result.reason
    assert busy.params.get(['safety_margin'], timeout_s=1.0)['safety_margin'] == 0.5
    round_trip = time.monotonic() - began
    busy.publish('goal_pose', pose_msg(near))
    assert busy.diag_events(mark, 'plan') == [], (
        'the long plan ended before the parameter was set; the test proved nothing')

    cancelled = busy.wait_diag(mark, 'plan_cancelled', 30.0)
    assert cancelled['status'] == 'canceled', cancelled
    assert 'cancelled during search' in cancelled['reason'], cancelled
    assert cancelled['goal'] == conv.format_value(np.array(far))
    following = busy.wait_diag(mark, 'plan', 60.0)
    assert following['status'] == 'ok', following
    assert following['goal'] == conv.format_value(np.array(near))
    assert float(following['safety_margin_m']) == pytest.approx(0.5), following
    # The grid was inflated for the new gamma: by the plan itself, or by the map intake off the
    # planning thread (then the plan searched that mask, built for gamma 0.5).
    assert float(following['grid_build_time_s']) > 0.0 or (
        following['grid_from_map'] == 'true'
        and float(following['map_grid_gamma_m']) == pytest.approx(0.5)), following
    path = conv.path_to_points(busy.plan_for(following))
    assert min_clearance(path, PAPER.obstacles) >= 0.5 - TOL
    time.sleep(0.5)
    assert len(busy.diag_events(mark, 'plan')) == 1, busy.diag_events(mark, 'plan')
    assert round_trip < 1.0, f'parameter services took {round_trip:.2f} s during the plan'
    process: NodeProcess = ros['busy']
    assert_clean_exit(process, process.stop(signal.SIGINT))


def test_plan_that_collides_with_obstacles_received_meanwhile_is_not_published() -> None:
    """In-process, so that obstacles arrive exactly while a plan is computed: the plan collides
    with them, is dropped with a ``plan_discarded`` status, and the goal is planned again on
    them at once."""
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=unique_domain_id(),
               signal_handler_options=SignalHandlerOptions.NO)
    planner = None
    try:
        planner = PlannerNode(context=context)
        published: List[object] = []
        diagnostics: List[Dict[str, object]] = []
        planner.in_force._plan_pub.publish = published.append
        planner.diagnostics.publish = (
            lambda stamp_ns, level, message, values: diagnostics.append(dict(values)))
        planner.intake.on_obstacles(conv.obstacle_input_markers(PAPER.obstacles, 'map', 1))
        planner.commands.on_goal(pose_msg(GOAL))
        worker = planner.worker
        plan = worker._planner.plan
        late: List[np.ndarray] = []

        def plan_while_obstacles_arrive(start, goal, **options):
            result = plan(start, goal, **options)
            if not late:
                late.append(result.smoothed_path[len(result.smoothed_path) // 2])
                planner.intake.on_obstacles(marker_array(
                    marker('late', 0, Marker.SPHERE, late[0], (1.0, 1.0, 1.0))))
            return result
        worker._planner.plan = plan_while_obstacles_arrive

        worker._step(worker._take_snapshot())
        assert published == [], 'a plan that collides with the newest obstacles went out'
        assert diagnostics[-1]['event'] == 'plan_discarded', diagnostics[-1]
        worker._step(worker._take_snapshot())
        assert len(published) == 1
        values = diagnostics[-1]
        assert values['event'] == 'plan' and values['status'] == 'ok', values
        assert 'while planning' in values['reason'], values
        assert values['obstacles_version'] == values['obstacles_checked_version'] == 2
        obstacles = ObstacleSet(list(PAPER.obstacles.items) + [Sphere(late[0], 0.5)])
        assert min_clearance(planner.in_force.latched().smoothed_path, obstacles) >= GAMMA - TOL
    finally:
        if planner is not None:
            planner.close()
        rclpy.try_shutdown(context=context)
