"""State that survives a restart, a second node of the same name, and a prior map file, with
the planner node as a real process.
"""

import signal
import time

from helpers.map_files import EMPTY, ply
import numpy as np
import pytest
from visualization_msgs.msg import Marker, MarkerArray

from ros_harness import (assert_clean_exit, assert_start_file_refused, marker, marker_array,
                         min_clearance, NodeProcess, OBSTACLES_QOS, planner_command,
                         planner_session, PlannerClient, READY_TEXT, ros_environment, RosClient,
                         RUN_NAMESPACE, start_planner, STARTUP_TIMEOUT_S, unique_domain_id)
from uav_global_planner.core.map.obstacles import ObstacleSet, PointSet
from uav_global_planner.ros import conversions as conv

pytestmark = pytest.mark.ros

GAMMA = 0.2
TOL = 1e-6
ERROR = 2


def test_a_map_of_30_incremental_arrays_is_rebuilt_whole_after_a_restart() -> None:
    """The publisher keeps its last 100 arrays (transient local, depth 100), as the node's
    subscription does: a restarted node gets all of them, in order."""
    domain_id = unique_domain_id()
    namespace = f'{RUN_NAMESPACE}/restart'
    second = None
    with planner_session(namespace, domain_id=domain_id) as planner:
        client, diagnostics, first = planner.client, planner.diagnostics, planner.process
        try:
            publisher = client.publisher(MarkerArray, planner.prefix + 'obstacles',
                                         OBSTACLES_QOS)
            for number in range(30):
                # Each array adds one sphere; the 10th also deletes the 5th and adds it back
                # moved.
                markers = [marker('incremental', number, Marker.SPHERE,
                                  [-9.0 + 0.6 * number, 9.0, 2.0], [0.4, 0.4, 0.4])]
                if number == 10:
                    markers += [marker('incremental', 5, Marker.SPHERE, [0, 0, 0], [1, 1, 1],
                                       action=Marker.DELETE),
                                marker('incremental', 5, Marker.SPHERE, [-6.0, 8.0, 2.0],
                                       [0.4, 0.4, 0.4])]
                publisher.publish(marker_array(*markers))
            planner.wait_obstacle_count(30, timeout_s=20.0)
            assert_clean_exit(first, first.stop(signal.SIGINT))
            second = start_planner(domain_id, namespace=namespace)
            restarted = PlannerClient(client, namespace, diagnostics, second)
            shown = restarted.wait_obstacle_count(30, restarted.markers.mark(), 20.0)
            centers = sorted(tuple(round(v, 3) for v in (m.pose.position.x, m.pose.position.y))
                             for m in shown.markers if m.ns == 'obstacles')
            expected = sorted([(round(-9.0 + 0.6 * n, 3), 9.0) for n in range(30) if n != 5]
                              + [(-6.0, 8.0)])
            assert centers == expected
            status = restarted.wait_diag(0, 'map_status',
                                         check=lambda v: v['obstacles'] == '30')
            assert int(status['obstacles_accepted']) == 30, status
        finally:
            if second is not None:
                second.kill()


def test_a_second_node_with_the_same_name_is_reported_by_both() -> None:
    domain_id = unique_domain_id()
    namespace = f'{RUN_NAMESPACE}/twins'
    second = None
    with planner_session(namespace, domain_id=domain_id) as planner:
        diagnostics, first = planner.diagnostics, planner.process
        try:
            mark, log_mark = diagnostics.mark(), first.mark()
            second = start_planner(domain_id, namespace=namespace)
            found = planner.wait_diag(mark, 'duplicate_node', 20.0)
            assert found['_level'] == ERROR and found['nodes_with_this_name'] == '2', found
            assert 'stop them or start this one in another namespace' in found['message']
            line = first.wait_for_output('other node(s) named', 20.0, log_mark)
            assert f'{namespace}/global_planner' in line
            second.wait_for_output('other node(s) named', 20.0)
            # Gone again: the remaining node says so.
            assert_clean_exit(second, second.stop(signal.SIGINT))
            first.wait_for_output('is gone', 20.0, log_mark)
        finally:
            if second is not None:
                second.kill()


def test_a_prior_map_file_is_a_map_and_is_kept_off(tmp_path) -> None:
    """A .npy wall across the workspace: goals are planned on it without any topic, around it
    by gamma plus the downsampling margin, and the map status says what the file held; the file
    is fixed for the node's life. A file that cannot be used is refused: the node runs without
    it, says why in the log and the map status, and refuses goals."""
    wall = np.array([[x, 0.0, z] for x in np.arange(-10.0, 6.01, 0.1)
                     for z in np.arange(0.0, 15.01, 0.1)])
    path = tmp_path / 'wall.npy'
    np.save(path, wall)
    domain_id = unique_domain_id()
    namespace = f'{RUN_NAMESPACE}/prior'
    with planner_session(namespace, {'map_file': str(path), 'map_downsample': 0.2},
                         domain_id) as planner:
        assert 'prior map' in planner.process.wait_for_output(READY_TEXT, 1.0)
        values, plan = planner.plan_to([0.0, 5.0, 2.0])
        assert values['status'] == 'ok', values
        assert 'map_file: 1 accepted' in values['map_sources'], values
        margin = 0.2 * np.sqrt(3.0) / 2.0
        assert float(values['safety_margin_m']) == pytest.approx(GAMMA + margin, abs=1e-4)
        points = conv.path_to_points(plan)
        assert min_clearance(points, ObstacleSet([PointSet(wall)])) >= GAMMA - TOL
        assert np.max(points[:, 0]) > 6.0, 'the path does not go round the wall'
        # What the file held: read, merged by downsampling, kept, and the extent.
        status = planner.wait_diag(0, 'map_status')
        assert status['map_file_status'] == 'ok' and status['map_file'] == str(path), status
        kept = int(status['map_file_points_kept'])
        assert int(status['map_file_points_read']) == len(wall), status
        assert int(status['map_file_dropped_downsampled']) == len(wall) - kept > 0, status
        assert status['map_file_dropped_non_finite'] == '0', status
        extent_min = np.array(status['map_file_extent_min'].strip('[]').split(', '), float)
        extent_max = np.array(status['map_file_extent_max'].strip('[]').split(', '), float)
        assert np.all(np.abs(extent_min - wall.min(axis=0)) <= margin + 1e-4), status
        assert np.all(np.abs(extent_max - wall.max(axis=0)) <= margin + 1e-4), status
        (result,) = planner.params.set({'map_file': ''})
        # A read-only parameter (read at start-up): rclpy refuses it on a running node.
        assert not result.successful and 'read-only parameter: map_file' in result.reason
    # A file that cannot be read, then one with no points: the node runs without it, says why,
    # and refuses goals until it is restarted with a usable file.
    broken = tmp_path / 'broken.npy'
    broken.write_bytes(b'not a numpy file')
    empty = tmp_path / 'empty.ply'
    ply(EMPTY)(empty)
    for bad, reason in ((broken, 'not a valid NumPy .npy file, or truncated'),
                        (empty, 'no points: the PLY file holds 0 points')):
        with planner_session(namespace, {'map_file': str(bad)}, domain_id) as planner:
            assert_start_file_refused(planner, 'map_file', bad, reason)
            assert planner.process.process.poll() is None, planner.process.output


def test_a_frame_switch_during_a_long_plan_cancels_it_and_withdraws_the_old_plan() -> None:
    with planner_session(f'{RUN_NAMESPACE}/frames', {
            'resolution': 0.07, 'algorithm': 'dijkstra', 'max_planning_time': 120.0,
            'plan_without_map': True}) as planner:
        values, _ = planner.plan_to([1.0, -4.0, 1.0], timeout_s=60.0)
        assert values['status'] == 'ok', values
        mark, plans = planner.diagnostics.mark(), planner.plans.mark()
        planner.publish('goal_pose', conv.pose_stamped([9.0, 9.0, 14.0], 'map', 0))
        planner.wait_diag(mark, 'progress', 60.0)
        (result,) = planner.params.set({'frame_id': 'world'})
        assert result.successful, result.reason
        cancelled = planner.wait_diag(mark, 'plan_cancelled', 30.0)
        assert cancelled['status'] == 'canceled', cancelled
        withdrawn = planner.wait_diag(mark, 'plan_withdrawn', 30.0)
        assert "frame_id changed to 'world'" in withdrawn['reason'], withdrawn
        empty = planner.plans.wait_for(after=plans, what='the withdrawal')
        assert len(empty.poses) == 0 and empty.header.frame_id == 'world'
        time.sleep(1.0)
        assert planner.diag_events(mark, 'plan') == [], 'the old-frame goal was planned'
        # The new frame plans: goals in it are taken (open air here).
        values, plan = planner.plan_to([1.0, -4.0, 1.0], frame_id='world', timeout_s=60.0)
        assert values['status'] == 'ok' and plan.header.frame_id == 'world', values


def test_the_node_starts_with_the_shipped_defaults_from_the_console_script() -> None:
    """The parameters added for live maps are declared with their documented defaults."""
    domain_id = unique_domain_id()
    process = NodeProcess(planner_command(namespace=f'{RUN_NAMESPACE}/defaults'),
                          ros_environment(domain_id))
    client = RosClient(domain_id)
    try:
        process.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        params = client.parameters(f'{RUN_NAMESPACE}/defaults/global_planner')
        values = params.get(['cloud_qos_reliability', 'plan_without_map', 'required_map_sources',
                             'start_tolerance', 'start_replan_distance', 'map_file'])
        assert values == {'cloud_qos_reliability': 'reliable', 'plan_without_map': False,
                          'required_map_sources': ['any'], 'start_tolerance': 0.5,
                          'start_replan_distance': 2.0, 'map_file': ''}
    finally:
        client.close()
        process.kill()
