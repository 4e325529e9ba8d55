"""Safety and bounded time of the node, through real processes and topics.

* With gamma = 0, an 8 mm wall dropped across the plan in force, between two of its samples:
  the certified re-check sees it, and the node replaces the plan by a clear one (or withdraws
  it when none exists).
* A newer goal cancels a long plan: the old one is reported ``plan_cancelled`` and never
  published, and the newer goal is planned next.
* The whole-plan budget: out of time in the search gives TIMEOUT (207) naming the stage.
"""

import time
from typing import Dict, Iterator

from diagnostic_msgs.msg import DiagnosticArray
import numpy as np
import pytest
from visualization_msgs.msg import Marker

from ros_harness import (marker, marker_array, min_clearance, PlannerClient,
                         plans_after_withdrawal, pose_msg, READY_TEXT, RosClient, RUN_NAMESPACE,
                         start_planner, STARTUP_TIMEOUT_S, unique_domain_id)
from uav_global_planner.core.map.obstacles import Box, ObstacleSet
from uav_global_planner.ros import conversions as conv

pytestmark = [pytest.mark.ros, pytest.mark.slow]

THIN = f'{RUN_NAMESPACE}/bounded_thin'
BUSY = f'{RUN_NAMESPACE}/bounded_busy'
START = np.array([0.0, -5.0, 0.0])  # the start parameter of config/planner.yaml


@pytest.fixture(scope='module')
def ros() -> Iterator[Dict[str, object]]:
    """A planner with gamma = 0, and a busy one (delta 0.07 m, Dijkstra: multi-second plans)."""
    domain_id = unique_domain_id()
    processes = []
    client = None
    try:
        # Both plan in open air first (no map source has delivered yet).
        processes.append(start_planner(domain_id, wait=False, namespace=THIN, parameters={
            'safety_margin': 0.0, 'plan_without_map': True}))
        processes.append(start_planner(domain_id, wait=False, namespace=BUSY, parameters={
            'resolution': 0.07, 'algorithm': 'dijkstra', 'max_planning_time': 60.0,
            'plan_without_map': True}))
        for process in processes:
            process.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        client = RosClient(domain_id)
        diagnostics = client.record(DiagnosticArray, '/diagnostics')
        yield {'thin': PlannerClient(client, THIN, diagnostics, processes[0]),
               'busy': PlannerClient(client, BUSY, diagnostics, processes[1])}
    finally:
        if client is not None:
            client.close()
        for process in processes:
            process.kill()


def test_a_thin_wall_across_the_plan_in_force_replaces_it(ros) -> None:
    thin: PlannerClient = ros['thin']
    goal = [0.0, 8.0, 0.0]
    values, path = thin.plan_to(goal)
    assert values['status'] == 'ok', values
    points = conv.path_to_points(path)
    # An 8 mm wall across the path, centred between two published samples, 2 m high.
    middle = int(np.argmin(np.abs(points[:, 1] - 1.5)))
    y = 0.5 * (points[middle, 1] + points[middle + 1, 1])
    wall = Box([-3.0, y - 0.004, 0.0], [3.0, y + 0.004, 2.0])
    assert min_clearance(points, ObstacleSet([wall]), spacing_m=10.0) > 0.0, (
        'the wall should fall between two samples, where sampling misses it')
    mark = thin.diagnostics.mark()
    plan_mark = thin.plans.mark()
    thin.publish('obstacles', marker_array(
        marker('wall', 0, Marker.CUBE, [0.0, y, 1.0], (6.0, 0.008, 2.0))))
    # The certified check finds the wall between the samples: the plan is withdrawn at once,
    # then replaced; nothing published after the wall crosses it.
    withdrawn = thin.wait_diag(mark, 'plan_withdrawn', 20.0)
    assert abs(float(withdrawn['blocked_at'].strip('[]').split(',')[1]) - y) < 0.5, withdrawn
    replanned = thin.wait_diag(mark, 'plan', 20.0)
    assert 'withdrawn' in replanned['reason'], replanned
    if replanned['status'] == 'ok':
        after = conv.path_to_points(thin.plan_for(replanned))
        assert min_clearance(after, ObstacleSet([wall]), spacing_m=1e-4) > 0.0
        assert np.allclose(after[-1], goal)
    else:
        thin.plans.wait_for(lambda msg: len(msg.poses) == 0, 5.0, plan_mark, 'the withdrawal')
    plans_after_withdrawal(
        thin.plans, plan_mark, withdrawn,
        lambda points: min_clearance(points, ObstacleSet([wall]), spacing_m=1e-4) > 0.0)


def test_a_newer_goal_cancels_a_long_plan(ros) -> None:
    busy: PlannerClient = ros['busy']
    far, near = [9.0, 9.0, 14.0], [-2.0, -7.0, 1.0]
    mark = busy.diagnostics.mark()
    busy.publish('goal_pose', pose_msg(far))
    time.sleep(0.5)
    sent = time.monotonic()
    busy.publish('goal_pose', pose_msg(near))
    cancelled = busy.wait_diag(mark, 'plan_cancelled', 20.0)
    assert cancelled['goal'] == conv.format_value(np.array(far)), cancelled
    assert cancelled['status'] == 'canceled'
    served = busy.wait_diag(mark, 'plan', 60.0)
    assert served['status'] == 'ok', served
    assert served['goal'] == conv.format_value(np.array(near)), 'the old goal was planned'
    assert served['reason'] == 'new goal'
    assert len(busy.diag_events(mark, 'plan')) == 1
    assert time.monotonic() - sent < 60.0


def test_the_plan_budget_names_the_stage_that_ran_out(ros) -> None:
    busy: PlannerClient = ros['busy']
    (result,) = busy.params.set({'max_planning_time': 0.3})
    assert result.successful, result.reason
    try:
        values, path = busy.plan_to([9.0, -9.0, 14.0], timeout_s=30.0)
        assert values['status'] == 'timeout', values
        assert values['status_code'] == '207', values
        assert 'search ran out of the planning time budget' in values['message'], values
        assert path is None
    finally:
        busy.params.set({'max_planning_time': 60.0})
