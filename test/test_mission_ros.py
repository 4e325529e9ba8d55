"""The ``export_mission`` service of the planner node, in real processes over DDS."""

import json
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticArray
import numpy as np
import pymap3d
import pytest
from std_srvs.srv import Trigger
from visualization_msgs.msg import Marker

from ros_harness import (assert_clean_exit, marker, marker_array, MONITOR_QOS, NodeProcess,
                         planner_command, PlannerClient, READY_TEXT, ros_environment, RosClient,
                         start_scene_publisher, STARTUP_TIMEOUT_S, unique_domain_id, wait_future,
                         wait_until)
from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.core.map.obstacles import ObstacleSet, Sphere
from uav_global_planner.ros import conversions as conv

pytestmark = pytest.mark.ros

ORIGIN = [47.397742, 8.545594, 488.0]
SCENE = load_scene(find_scene('paper_medium'))


def node_command(parameters):
    return planner_command(parameters=parameters)


@pytest.fixture
def world(tmp_path):
    domain = unique_domain_id()
    parameters = {'bounds.min': [-10.0, -10.0, 0.0], 'bounds.max': [10.0, 10.0, 15.0],
                  'start': [0.0, -5.0, 0.0], 'mission_file': str(tmp_path / 'node.plan')}
    node = NodeProcess(node_command(parameters), ros_environment(domain))
    publisher = client = None
    try:
        node.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        publisher = start_scene_publisher(domain, 'paper_medium')
        client = RosClient(domain)
        diagnostics = client.record(DiagnosticArray, '/diagnostics', MONITOR_QOS)
        planner = PlannerClient(client, '', diagnostics, node)
        service = client.node.create_client(Trigger, '/export_mission')
        wait_until(service.service_is_ready, 15.0, 'the export_mission service')
        yield node, planner, service, tmp_path
    finally:
        if client is not None:
            client.close()
        if publisher is not None:
            publisher.stop()
        if node.process.poll() is None:
            assert_clean_exit(node, node.stop())
        node.kill()


def export(service):
    response = wait_future(service.call_async(Trigger.Request()), 30.0, 'export_mission')
    return response.success, response.message


def mission_clearance(document, obstacles: ObstacleSet) -> float:
    """Smallest distance [m] from the legs of a ``.plan`` document (from the start parameter
    on) to ``obstacles``, at 500 points a leg."""
    items = document['mission']['items']
    home = document['mission']['plannedHomePosition']
    positions = np.array([pymap3d.geodetic2enu(i['params'][4], i['params'][5],
                                               home[2] + i['params'][6], *ORIGIN)
                          for i in items if i['command'] in (16, 17, 22)])
    path_points = np.vstack([[0.0, -5.0, 0.0], positions])
    samples = np.concatenate([a + np.linspace(0, 1, 500)[:, None] * (b - a)
                              for a, b in zip(path_points[:-1], path_points[1:])])
    return float(obstacles.distance(samples).min())


def test_export_mission_writes_the_plan_in_force(world):
    node, planner, service, folder = world
    # No origin yet, then no plan yet: refused, each by name.
    success, message = export(service)
    assert not success and 'geodetic_origin is not set' in message
    assert all(r.successful for r in planner.params.set({'geodetic_origin': ORIGIN}))
    success, message = export(service)
    assert not success and 'no plan in force' in message
    planner.wait_obstacle_count(len(SCENE.obstacles), 0, 20.0)
    values, plan = planner.plan_to(SCENE.goal.tolist())
    assert values['status'] == 'ok'
    success, message = export(service)
    assert success, message
    answer = json.loads(message)
    path = Path(answer['path'])
    assert path == folder / 'node.plan' and path.is_file()
    document = json.loads(path.read_text())
    items = document['mission']['items']
    assert answer['items'] == len(items)
    assert answer['waypoints'] == sum(item['command'] in (16, 17, 21, 22) for item in items)
    assert answer['required_clearance_m'] == pytest.approx(0.3)
    assert answer['plan_stamp_ns'] == values['_stamp']
    # The legs keep the clearance from the obstacles the node plans with.
    assert mission_clearance(document, SCENE.obstacles) >= 0.3
    # WPL through the parameters, and the end action.
    assert all(r.successful for r in planner.params.set(
        {'mission_file': str(folder / 'node.waypoints'), 'mission_end': 'land',
         'mission_firmware': 'ardupilot'}))
    success, message = export(service)
    assert success, message
    text = (folder / 'node.waypoints').read_text().splitlines()
    assert text[0] == 'QGC WPL 110'
    assert text[-1].split('\t')[3] == '21'
    assert 'Traceback' not in node.output


@pytest.mark.parametrize('name, value, reason', [
    ('mission_end', 'fly', 'mission_end must be one of'),
    ('geodetic_origin', [95.0, 8.0, 400.0], 'geodetic_origin.lat'),
    # The table's range is the parameter's: rclpy refuses below it, the table the open end.
    ('mission_acceptance_radius', -1.0, 'Parameter mission_acceptance_radius out of range'),
    ('mission_acceptance_radius', 0.0, 'mission_acceptance_radius must be in (0.0, 1000.0]'),
    ('mission_tracking_allowance', 101.0, 'Parameter mission_tracking_allowance out of range'),
    ('mission_format', 'kml', 'mission_format must be one of')])
def test_invalid_mission_parameters_are_refused(world, name, value, reason):
    node, planner, service, _ = world
    result, = planner.params.set({name: value})
    assert not result.successful and reason in result.reason
    assert all(r.successful for r in planner.params.set({'mission_end': 'rtl'}))


def test_an_export_racing_a_withdrawal_never_writes_the_withdrawn_plan(world):
    """An obstacle lands on the plan in force and a mission is asked for as soon as the
    withdrawal shows: the export reads the plan in force from the node's release gate, so it
    writes the replacement (certified against the newest map) or refuses, never the plan the
    map withdrew."""
    node, planner, service, folder = world
    assert all(r.successful for r in planner.params.set({'geodetic_origin': ORIGIN}))
    planner.wait_obstacle_count(len(SCENE.obstacles), 0, 20.0)
    values, plan = planner.plan_to(SCENE.goal.tolist())
    assert values['status'] == 'ok', values
    points = conv.path_to_points(plan)
    center = points[len(points) // 2]
    dropped = ObstacleSet(list(SCENE.obstacles.items) + [Sphere(center, 0.4)])
    mark = planner.diagnostics.mark()
    planner.publish('obstacles', marker_array(
        marker('dropped', 0, Marker.SPHERE, center, [0.8, 0.8, 0.8])))
    planner.wait_diag(mark, 'plan_withdrawn')
    success, message = export(service)
    if success:
        answer = json.loads(message)
        assert answer['plan_stamp_ns'] != values['_stamp'], 'the withdrawn plan was exported'
        document = json.loads(Path(answer['path']).read_text())
        assert mission_clearance(document, dropped) >= 0.3
    else:
        assert 'no plan in force' in message or 'withdrawn or replaced' in message, message
    replaced = planner.wait_diag(mark, 'plan', check=lambda v: 'withdrawn' in v['reason'])
    assert replaced['status'] == 'ok', replaced
    success, message = export(service)
    assert success, message
    answer = json.loads(message)
    assert answer['plan_stamp_ns'] == replaced['_stamp']
    assert mission_clearance(json.loads(Path(answer['path']).read_text()), dropped) >= 0.3
