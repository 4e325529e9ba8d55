"""Planner node processes under load and at the edges of their life.

* A multi-second plan (a goal sealed in a hollow box on a 6-million-node grid, so the search has
  to exhaust the grid) must not block the parameter services; goals arriving meanwhile cancel
  it, and the latest of them is planned.
* SIGINT during such a plan and SIGTERM on an idle node exit with code 0 and no traceback.
* Invalid parameters at start-up stop the node with a clear message and exit code 2.

The three processes start in parallel to keep the wall time down.
"""

import signal
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
import numpy as np
import pytest
from visualization_msgs.msg import Marker, MarkerArray

from ros_harness import (assert_clean_exit, diagnostics_of, LATCHED_QOS, marker,
                         marker_array, NODE_NAME, OBSTACLES_QOS, pose_msg, READY_TEXT,
                         RosClient, RUN_NAMESPACE, start_planner, STARTUP_TIMEOUT_S,
                         unique_domain_id)
from uav_global_planner.ros import conversions as conv

pytestmark = [pytest.mark.ros, pytest.mark.slow]

BUSY = f'{RUN_NAMESPACE}/busy'
NODE = f'{BUSY}/{NODE_NAME}'
SEALED_GOAL = [5.0, 5.0, 5.0]
# Reachable goals sent while the long plan runs; only the last should be planned.
FOLLOW_UP_GOALS = [[-8.0, 8.0, float(z)] for z in range(2, 7)]
# A parameter call that gets no answer for this long has hung (not a speed target) [s].
PARAM_TIMEOUT_S = 15.0


def sealed_box_markers() -> MarkerArray:
    """Six 0.4 m walls forming a closed box from 3 m to 7 m around the sealed goal."""
    lo, hi, wall = np.array([3.0, 3.0, 3.0]), np.array([7.0, 7.0, 7.0]), 0.4
    markers = []
    for axis in range(3):
        for side in (lo[axis] + wall / 2, hi[axis] - wall / 2):
            center = (lo + hi) / 2
            center[axis] = side
            size = hi - lo
            size[axis] = wall
            markers.append(marker('walls', len(markers), Marker.CUBE, center, size))
    return marker_array(*markers)


def node_events(recorder, after: int = 0):
    """Diagnostics values of the busy node, in order of arrival."""
    return [values for values in (diagnostics_of(NODE, msg) for msg in recorder.messages[after:])
            if values is not None]


def plan_events(recorder, after: int = 0):
    events = []
    for msg in recorder.messages[after:]:
        values = diagnostics_of(NODE, msg)
        if values is not None and values.get('event') == 'plan':
            events.append(values)
    return events


def test_long_plan_keeps_services_responsive_and_goals_coalesce_then_sigint():
    domain_id = unique_domain_id()
    busy = start_planner(domain_id, wait=False, namespace=BUSY,
                         parameters={'resolution': 0.07, 'max_planning_time': 60.0})
    idle = start_planner(domain_id, wait=False, namespace=f'{RUN_NAMESPACE}/idle')
    bad = start_planner(domain_id, wait=False, namespace=f'{RUN_NAMESPACE}/bad',
                        parameters={'algorithm': 'foo'})
    client = None
    try:
        # Invalid start-up parameters: a clear message and exit code 2, no traceback.
        assert bad.process.wait(STARTUP_TIMEOUT_S) == 2, bad.output
        assert 'algorithm must be one of' in bad.output
        assert 'Traceback' not in bad.output

        busy.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        client = RosClient(domain_id)
        diagnostics = client.record(DiagnosticArray, '/diagnostics')
        shown = client.record(MarkerArray, f'{BUSY}/planner_markers', LATCHED_QOS)
        obstacles = client.publisher(MarkerArray, f'{BUSY}/obstacles', OBSTACLES_QOS)
        goals = client.publisher(PoseStamped, f'{BUSY}/goal_pose')
        params = client.parameters(NODE)
        obstacles.publish(sealed_box_markers())
        shown.wait_for(lambda m: sum(x.ns == 'obstacles' for x in m.markers) == 6, 15.0,
                       what='the walls in use')

        goals.publish(pose_msg(SEALED_GOAL))
        # Behaviour, not speed: the parameter services answer while the long plan runs. The
        # plan reports progress every second; a report after the answer shows that the plan
        # was still running when the answer came (a node that answered only once the plan had
        # ended could not produce it).
        sealed = conv.format_value(np.array(SEALED_GOAL))

        def sealed_progress(msg: DiagnosticArray) -> bool:
            values = diagnostics_of(NODE, msg) or {}
            return values.get('event') == 'progress' and values.get('goal') == sealed
        diagnostics.wait_for(sealed_progress, 30.0, what='the long plan under way')
        assert params.get(['safety_margin'], timeout_s=PARAM_TIMEOUT_S)['safety_margin'] == 0.2
        answered = diagnostics.mark()
        diagnostics.wait_for(sealed_progress, 30.0, answered,
                             what='progress of the long plan after the parameter answer')
        assert 'plan_cancelled' not in [e.get('event') for e in node_events(diagnostics)]
        assert plan_events(diagnostics) == [], 'the long plan ended before the answer'
        for number in range(4):
            assert params.get(['safety_margin'],
                              timeout_s=PARAM_TIMEOUT_S)['safety_margin'] == 0.2
            (result,) = params.set({'max_speed_horizontal': 2.0 + 0.1 * number},
                                   timeout_s=PARAM_TIMEOUT_S)
            assert result.successful, result.reason
            goals.publish(pose_msg(FOLLOW_UP_GOALS[number]))
        goals.publish(pose_msg(FOLLOW_UP_GOALS[-1]))
        # The newer goals and settings preempt the long plan: it is cancelled, never published,
        # and the latest goal is planned (goals coalesce: the worker takes the newest).
        cancelled = diagnostics.wait_for(
            lambda m: (diagnostics_of(NODE, m) or {}).get('event') == 'plan_cancelled', 20.0,
            what='the long plan cancelled')
        cancelled_values = diagnostics_of(NODE, cancelled)
        assert cancelled_values['goal'] == conv.format_value(np.array(SEALED_GOAL))
        assert 'no_valid_path' not in [e['status'] for e in plan_events(diagnostics)]
        latest = conv.format_value(np.array(FOLLOW_UP_GOALS[-1]))
        diagnostics.wait_for(lambda m: (diagnostics_of(NODE, m) or {}).get('goal') == latest
                             and plan_events_in(m), 20.0, what='the plan of the latest goal')
        time.sleep(1.0)
        events = plan_events(diagnostics)
        assert events[-1]['status'] == 'ok' and events[-1]['goal'] == latest, events
        followers = {conv.format_value(np.array(goal)) for goal in FOLLOW_UP_GOALS}
        assert all(e['status'] == 'ok' and e['goal'] in followers for e in events), events
        count = len(events)

        # SIGINT while the next long plan runs: clean exit.
        goals.publish(pose_msg(SEALED_GOAL))
        time.sleep(0.5)
        assert len(plan_events(diagnostics)) == count, 'the long plan should still be running'
        assert_clean_exit(busy, busy.stop(signal.SIGINT, timeout_s=15.0))

        idle.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        assert_clean_exit(idle, idle.stop(signal.SIGTERM, timeout_s=15.0))
    finally:
        if client is not None:
            client.close()
        for process in (busy, idle, bad):
            process.kill()


def plan_events_in(msg: DiagnosticArray) -> bool:
    values = diagnostics_of(NODE, msg)
    return values is not None and values.get('event') == 'plan'
