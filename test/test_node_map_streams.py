"""Clouds streamed to the planner node through real processes: every cloud arrives (reliable),
the latest wins, plans keep up and keep gamma from the map they were checked against, large
clouds and the documented size limit, and best-effort publishers.
"""

import time
from typing import Dict, Iterator, List

from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Path as PathMsg
import numpy as np
import pytest
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Header

from ros_harness import (CLOUD_QOS, min_clearance, PlannerClient, pose_msg, READY_TEXT, RosClient,
                         RUN_NAMESPACE, SENSOR_QOS, start_planner, STARTUP_TIMEOUT_S,
                         unique_domain_id, wait_until)
from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.core.map.obstacles import ObstacleSet, PointSet
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.qos import keep_last

pytestmark = pytest.mark.ros

SCENE = load_scene(find_scene('paper_medium'))
GAMMA = 0.2
TOL = 1e-6
STREAM = f'{RUN_NAMESPACE}/stream'
SENSOR = f'{RUN_NAMESPACE}/sensor'


@pytest.fixture(scope='module')
def ros() -> Iterator[Dict[str, object]]:
    domain_id = unique_domain_id()
    processes = {}
    client = None
    try:
        processes['stream'] = start_planner(domain_id, wait=False, namespace=STREAM)
        processes['sensor'] = start_planner(domain_id, wait=False, namespace=SENSOR, parameters={
            'cloud_qos_reliability': 'best_effort'})
        for process in processes.values():
            process.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        client = RosClient(domain_id)
        diagnostics = client.record(DiagnosticArray, '/diagnostics')
        yield {'client': client,
               'stream': PlannerClient(client, STREAM, diagnostics, processes['stream']),
               'sensor': PlannerClient(client, SENSOR, diagnostics, processes['sensor'])}
    finally:
        if client is not None:
            client.close()
        for process in processes.values():
            process.kill()


def map_status(planner: PlannerClient, after: int = 0, check=lambda values: True,
               timeout_s: float = 20.0) -> Dict[str, str]:
    """The first ``map_status`` of the node after ``after`` that passes ``check``."""
    try:
        return planner.wait_diag(after, 'map_status', timeout_s, check=check)
    except AssertionError:
        seen = planner.diag_events(after, 'map_status')
        raise AssertionError(f'no such map_status; the last: {seen[-1] if seen else None}')


def wall(offset: float, count: int = 4000) -> np.ndarray:
    """A wall of points across x = offset (y in [-4, 4], z in [0, 6]), seeded by offset."""
    rng = np.random.default_rng(int(offset * 1000) % 2 ** 32)
    points = np.empty((count, 3))
    points[:, 0] = offset
    points[:, 1] = rng.uniform(-4.0, 4.0, count)
    points[:, 2] = rng.uniform(0.0, 6.0, count)
    return points


def test_streamed_clouds_all_arrive_and_plans_keep_gamma_from_their_map(ros) -> None:
    planner: PlannerClient = ros['stream']
    # Plans come fast here: keep every one (the harness's latched recorder keeps the last).
    every_plan = planner.client.record(PathMsg, planner.prefix + 'plan',
                                       keep_last(200, latched=True))
    planner.set_obstacles(conv.obstacle_input_markers(SCENE.obstacles, 'map', 0, ns='scene'),
                          len(SCENE.obstacles))
    clouds: Dict[int, np.ndarray] = {}
    base = wall(-7.0, 20000)
    # A volatile subscription gets nothing its publisher sent before both sides matched
    # (discovery ends on each side at its own time), reliable or not: the first cloud is sent
    # until the node has it; from then on every cloud must arrive.
    warm_up = planner.client.now_ns()
    clouds[warm_up] = np.vstack([base, wall(-6.0)])

    def arrived() -> bool:
        mark = planner.diagnostics.mark()
        planner.publish('obstacle_cloud', conv.points_to_cloud(clouds[warm_up], 'map', warm_up))
        return map_status(planner, mark)['obstacle_cloud_stamp'] == str(warm_up)
    wait_until(arrived, 30.0, 'the first cloud', period_s=0.0)
    before = int(planner.diag_events(0, 'map_status')[-1]['obstacle_cloud_received'])
    mark = planner.diagnostics.mark()
    goals = [np.array([8.0, 8.0, 8.0]), np.array(SCENE.goal), np.array([-8.0, 8.0, 3.0])]
    sent_goals = 0
    for step in range(40):
        stamp_ns = planner.client.now_ns()
        # A wall that sweeps across the workspace: each cloud moves it a little.
        points = np.vstack([base, wall(-6.0 + 0.3 * step)])
        clouds[stamp_ns] = points
        planner.publish('obstacle_cloud', conv.points_to_cloud(points, 'map', stamp_ns))
        if step % 4 == 0:
            planner.publish('goal_pose', pose_msg(goals[sent_goals % len(goals)]))
            sent_goals += 1
        time.sleep(0.1)
    last_goal = goals[(sent_goals - 1) % len(goals)]

    sent = len(clouds) - 1

    # The newest cloud is in the map; each cloud that reached the node was taken in or, when
    # a newer one came first (the latest wins), superseded. (With keep-last 1, DDS itself also
    # replaces a cloud the node's executor had not taken yet: the benchmark counts those.)
    status = map_status(planner, mark, lambda v: v['obstacle_cloud_stamp'] == str(max(clouds)),
                        30.0)
    received = int(status['obstacle_cloud_received'])
    accepted = int(status['obstacle_cloud_accepted'])
    superseded = int(status['obstacle_cloud_superseded'])
    assert before < received <= before + sent, status
    assert accepted + superseded == received and accepted >= 1, status
    final = planner.wait_diag(mark, 'plan', 30.0, check=lambda v: v['goal'] == conv.format_value(
        last_goal) and v['reason'] == 'new goal')
    assert final['status'] == 'ok', final
    plans = [values for values in planner.diag_events(mark, 'plan') if values['status'] == 'ok']
    assert plans, 'no plan came out while the clouds streamed'
    for values in plans:
        # Stamp 0: checked against the markers alone, before the first cloud.
        checked = int(values['obstacles_checked_stamp'])
        assert checked == 0 or checked in clouds, values
        cloud = [PointSet(clouds[checked])] if checked else []
        obstacles = ObstacleSet(list(SCENE.obstacles.items) + cloud)
        path = conv.path_to_points(every_plan.wait_for(
            lambda m, stamp=values['_stamp']: conv.time_to_ns(m.header.stamp) == stamp, 5.0,
            what='the plan of the diagnostics'))
        assert min_clearance(path, obstacles) >= GAMMA - TOL, values
        assert int(values['obstacles_version']) <= int(values['obstacles_checked_version'])


def big_cloud(count: int, stamp_ns: int, point_step: int = 16) -> PointCloud2:
    """A cloud of ``count`` points high above the workspace: x, y, z float32 and padding."""
    rng = np.random.default_rng(count)
    record = np.zeros(count, dtype=np.dtype({'names': ['x', 'y', 'z'],
                                             'formats': ['<f4', '<f4', '<f4'],
                                             'offsets': [0, 4, 8], 'itemsize': point_step}))
    record['x'] = rng.uniform(-10.0, 10.0, count)
    record['y'] = rng.uniform(-10.0, 10.0, count)
    record['z'] = rng.uniform(14.5, 15.0, count)
    msg = PointCloud2()
    msg.header = Header(frame_id='map', stamp=conv.time_from_ns(stamp_ns))
    msg.height, msg.width = 1, count
    msg.fields = [PointField(name=axis, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, axis in enumerate('xyz')]
    msg.point_step, msg.row_step = point_step, point_step * count
    msg.data = record.tobytes()
    msg.is_dense = True
    return msg


def test_25_mb_clouds_at_1_hz_arrive_and_too_large_ones_are_refused(ros) -> None:
    planner: PlannerClient = ros['stream']
    before = map_status(planner, planner.diagnostics.mark())
    received = int(before['obstacle_cloud_received'])
    stamps: List[int] = []
    for _ in range(3):
        stamps.append(planner.client.now_ns())
        msg = big_cloud(1_600_000, stamps[-1])
        assert len(msg.data) >= 25_000_000
        planner.publish('obstacle_cloud', msg)
        time.sleep(1.0)
    status = map_status(planner, planner.diagnostics.mark(),
                        lambda v: int(v['obstacle_cloud_received']) == received + 3
                        and v['obstacle_cloud_stamp'] == str(stamps[-1]), 60.0)
    assert status['status'] == 'ok' and int(status['points']) == 1_600_000, status
    # The documented limit: 2.1 M points (25 MB of x, y, z) exceed max_cloud_points.
    mark = planner.diagnostics.mark()
    planner.publish('obstacle_cloud', big_cloud(2_100_000, planner.client.now_ns(), 12))
    refused = planner.wait_diag(mark, 'input_rejected', 60.0)
    assert 'more than max_cloud_points = 2000000' in refused['reason'], refused
    values, _ = planner.plan_to([8.0, 8.0, 8.0])
    assert values['status'] == 'ok' and 'max_cloud_points' in values['map_refused'], values


def test_best_effort_publishers_need_the_best_effort_parameter(ros) -> None:
    client: RosClient = ros['client']
    stream: PlannerClient = ros['stream']
    sensor: PlannerClient = ros['sensor']
    # The default (reliable) subscription does not connect to a best-effort publisher...
    reliable = client.publisher(PointCloud2, stream.prefix + 'obstacle_cloud', CLOUD_QOS)
    best_effort = client.node.create_publisher(PointCloud2, stream.prefix + 'obstacle_cloud',
                                               SENSOR_QOS)
    assert reliable.get_subscription_count() == 1
    time.sleep(1.0)
    assert best_effort.get_subscription_count() == 0, 'an incompatible QoS pair connected'
    # ... while with cloud_qos_reliability: best_effort it does, and the cloud is taken in.
    to_sensor = client.node.create_publisher(PointCloud2, sensor.prefix + 'obstacle_cloud',
                                             SENSOR_QOS)
    wait_until(lambda: to_sensor.get_subscription_count() == 1, 15.0, 'the sensor node')

    def taken() -> bool:
        mark = sensor.diagnostics.mark()
        to_sensor.publish(conv.points_to_cloud(wall(5.0), 'map', client.now_ns()))
        status = sensor.wait_diag(mark, 'map_status', 5.0)
        return int(status['obstacle_cloud_accepted']) >= 1
    wait_until(taken, 30.0, 'a best-effort cloud taken in', period_s=0.1)
