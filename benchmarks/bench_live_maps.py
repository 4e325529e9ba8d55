"""Prints how planner_node keeps up with a mapping stack, over real topics and processes.

Run inside the project's environment::

    source scripts/venv.sh && python benchmarks/bench_live_maps.py [--goals 12] [--json]

The scenario of the live-maps figures: a planner_node process plans on town400's grid (200 x
200 x 40 m at delta 0.5 m, 13 M nodes, gamma 0.5 m). A mapping-stack process publishes the
surface cloud of the town's 400 buildings (822 k points, 9.9 MB) at 10 Hz, reliable, each
cloud a little different from the last (a crane of 600 points swings across a street). This
process is the vehicle and the goal sender: it flies the plan in force at 3 m/s (odometry at
20 Hz; an empty plan means hold position), sends a goal every 5 s, polls a parameter every
100 ms, and now and then drops an obstacle on the plan in force 15 m ahead of the vehicle, as a
marker sphere or as a pole of points in the next clouds. Phases:

1. streaming only (10 s): node CPU and parameter round trips while the clouds stream;
2. goals, flight and drops while the clouds stream.

Printed: goal -> plan (first plan to the goal received), the age of the map each published
plan was computed on (plan stamp minus the stamp of the cloud that last changed it), cloud
stamp -> its map in the planner's hands (reported by the node), clouds published / reaching the
node / taken in / superseded, obstacle on the plan in force -> empty plan received (withdrawn)
and -> the next plan received (replaced), parameter round trips, node CPU [cores], and whether
the vehicle ever flew into a dropped obstacle. Figures only; nothing is asserted.

One script, though long: the mapping stack, the vehicle and the goal sender are three threads
of one scenario sharing its clock and records; its helpers are its own.
"""

import argparse
import json
import math
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import threading
import time
from typing import Any, Dict, List, Optional

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry, Path as PathMsg
import numpy as np
import psutil
from rclpy.parameter_client import AsyncParameterClient
from sensor_msgs.msg import PointCloud2
from visualization_msgs.msg import Marker, MarkerArray

from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.background_node import BackgroundNode
from uav_global_planner.ros.qos import (CLOUD_QOS, COMMAND_QOS, LATCHED_QOS, MONITOR_QOS,
                                        OBSTACLES_QOS, SENSOR_QOS)
from uav_global_planner_tools import outdoor_scenes
from uav_global_planner_tools.domains import choose_domain_id
from uav_global_planner_tools.processes import (NodeProcess, NodeProcessError, planner_command,
                                                ros_environment)


REPO = Path(__file__).resolve().parents[1]

NAMESPACE = '/live_maps_bench'
SPEED = 3.0          # vehicle speed [m/s]
ODOM_PERIOD = 0.05   # [s]
GOAL_PERIOD = 5.0    # [s]
DROP_AHEAD = 15.0    # [m]
DROP_RADIUS = 1.0    # [m]
CLOUD_RATE = 10.0    # [Hz]


# --------------------------------------------------------------------------------------------
# The mapping stack (a child process)
# --------------------------------------------------------------------------------------------

def run_mapper(domain_id: int, rate_hz: float) -> None:
    """Publish the town's surface cloud at ``rate_hz``; commands on stdin: ``pole x y z`` adds
    a pole of points to the next clouds (answering ``pole <stamp>`` for the first one),
    ``clear`` removes the poles, ``quit`` ends. Prints ``sent <n>`` when it ends."""
    base = outdoor_scenes.cloud_town()
    client = BackgroundNode('live_maps_bench_mapper', domain_id)
    publisher = client.node.create_publisher(PointCloud2, f'{NAMESPACE}/obstacle_cloud',
                                             CLOUD_QOS)
    commands: List[str] = []
    lock = threading.Lock()

    def read() -> None:
        for line in sys.stdin:
            with lock:
                commands.append(line.strip())
    threading.Thread(target=read, daemon=True).start()
    # A crane over a street: 600 points on a 12 m boom that swings a little every cloud.
    boom = np.linspace(0.0, 12.0, 600)
    poles: List[np.ndarray] = []
    announce: Optional[np.ndarray] = None
    sent = 0
    began = time.monotonic()
    while True:
        with lock:
            pending, commands[:] = list(commands), []
        for command in pending:
            words = command.split()
            if words and words[0] == 'quit':
                print(f'sent {sent}', flush=True)
                client.close()
                return
            if words and words[0] == 'pole':
                x, y, z = (float(v) for v in words[1:4])
                angle = np.linspace(0.0, 2.0 * math.pi, 24, endpoint=False)
                heights = np.arange(0.0, 12.0, 0.2)
                ring = np.stack([x + DROP_RADIUS * np.cos(angle),
                                 y + DROP_RADIUS * np.sin(angle)], axis=1)
                pole = np.array([[px, py, h] for px, py in ring for h in heights])
                pole[:, 2] += max(z - 6.0, 0.0)
                poles.append(pole)
                announce = pole
            if words and words[0] == 'clear':
                poles = []
        angle = 0.3 * math.sin(0.5 * (time.monotonic() - began))
        crane = np.stack([-45.0 + boom * math.cos(angle), 5.0 + boom * math.sin(angle),
                          np.full(len(boom), 25.0)], axis=1)
        points = np.vstack([base, crane] + poles)
        stamp_ns = client.node.get_clock().now().nanoseconds
        publisher.publish(conv.points_to_cloud(points, 'map', stamp_ns))
        sent += 1
        if announce is not None:
            print(f'pole {stamp_ns}', flush=True)
            announce = None
        next_time = began + sent / rate_hz
        time.sleep(max(next_time - time.monotonic(), 0.0))


# --------------------------------------------------------------------------------------------
# The vehicle, goal sender and observer (this process)
# --------------------------------------------------------------------------------------------

class Observer:
    """Plans, diagnostics and the simulated vehicle, on the client's clock [s]."""

    def __init__(self, client: BackgroundNode, start: np.ndarray) -> None:
        self.client = client
        self.lock = threading.Condition()
        self.plans: List[Dict[str, Any]] = []       # each: arrived, stamp, points
        self.diagnostics: List[Dict[str, str]] = []
        self.position = np.array(start, dtype=np.float64)
        self.path: Optional[np.ndarray] = None
        self.hazards: List[np.ndarray] = []
        self.collisions = 0
        node = client.node
        node.create_subscription(PathMsg, f'{NAMESPACE}/plan', self._on_plan, LATCHED_QOS)
        node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics,
                                 MONITOR_QOS)
        self.odom_pub = node.create_publisher(Odometry, f'{NAMESPACE}/odom', SENSOR_QOS)
        self.goal_pub = node.create_publisher(PoseStamped, f'{NAMESPACE}/goal_pose',
                                              COMMAND_QOS)
        self.obstacles_pub = node.create_publisher(MarkerArray, f'{NAMESPACE}/obstacles',
                                                   OBSTACLES_QOS)
        self.stop = threading.Event()
        self.flying = threading.Thread(target=self._fly, daemon=True)

    def now_ns(self) -> int:
        return self.client.node.get_clock().now().nanoseconds

    def _on_plan(self, msg: PathMsg) -> None:
        arrived = time.monotonic()
        points = conv.path_to_points(msg)
        with self.lock:
            self.plans.append({'arrived': arrived, 'arrived_ns': self.now_ns(),
                               'stamp': conv.time_to_ns(msg.header.stamp), 'points': points})
            self.path = points if len(points) else None
            self.lock.notify_all()

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name.startswith(NAMESPACE):
                values = {kv.key: kv.value for kv in status.values}
                values['_stamp'] = str(conv.time_to_ns(msg.header.stamp))
                values['_arrived'] = str(time.monotonic())
                with self.lock:
                    self.diagnostics.append(values)
                    self.lock.notify_all()

    def _fly(self) -> None:
        """Follow the plan in force at SPEED; hold position without one."""
        while not self.stop.is_set():
            with self.lock:
                path = self.path
                hazards = list(self.hazards)
            if path is not None and len(path) > 1:
                nearest = int(np.argmin(np.linalg.norm(path - self.position, axis=1)))
                step = SPEED * ODOM_PERIOD
                ahead = path[nearest:]
                legs = np.linalg.norm(np.diff(ahead, axis=0), axis=1)
                reach = np.cumsum(legs)
                index = int(np.searchsorted(reach, step))
                if index < len(legs):
                    part = (step - (reach[index] - legs[index])) / max(legs[index], 1e-9)
                    self.position = ahead[index] + part * (ahead[index + 1] - ahead[index])
                else:
                    self.position = ahead[-1].copy()
            for center in hazards:
                if np.linalg.norm(self.position - center) < DROP_RADIUS:
                    self.collisions += 1
            msg = Odometry()
            msg.header.frame_id = 'map'
            msg.header.stamp = conv.time_from_ns(self.now_ns())
            msg.pose.pose.position.x, msg.pose.pose.position.y, msg.pose.pose.position.z = (
                float(v) for v in self.position)
            msg.pose.pose.orientation.w = 1.0
            self.odom_pub.publish(msg)
            time.sleep(ODOM_PERIOD)

    def wait_plan(self, after: int, predicate, timeout_s: float) -> Optional[Dict[str, Any]]:
        deadline = time.monotonic() + timeout_s
        with self.lock:
            while True:
                for plan in self.plans[after:]:
                    if predicate(plan):
                        return plan
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self.lock.wait(left)

    def wait_diag(self, after: int, predicate, timeout_s: float) -> Optional[Dict[str, str]]:
        deadline = time.monotonic() + timeout_s
        with self.lock:
            while True:
                for values in self.diagnostics[after:]:
                    if predicate(values):
                        return values
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self.lock.wait(left)

    def point_ahead(self, distance: float) -> Optional[np.ndarray]:
        with self.lock:
            path = self.path
        if path is None:
            return None
        nearest = int(np.argmin(np.linalg.norm(path - self.position, axis=1)))
        ahead = path[nearest:]
        reach = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(ahead, axis=0), axis=1))]
        if reach[-1] < distance + 3.0:
            return None
        return ahead[int(np.searchsorted(reach, distance))]


def street_goals(count: int, seed: int = 4) -> List[np.ndarray]:
    """Points of the town's streets at 2-8 m, 3 m from every building."""
    scene = outdoor_scenes.town400()
    obstacles = scene.obstacle_set()
    rng = np.random.default_rng(seed)
    goals: List[np.ndarray] = []
    while len(goals) < count:
        point = np.array([rng.uniform(-92.0, 92.0), rng.uniform(-92.0, 92.0),
                          rng.uniform(2.0, 8.0)])
        if float(obstacles.distance(point)) > 3.0:
            goals.append(point)
    return goals


def start_node(domain_id: int, log_dir: str) -> NodeProcess:
    scene = outdoor_scenes.town400()
    config = scene.config()
    parameters = {'bounds.min': [float(v) for v in config.bounds_min],
                  'bounds.max': [float(v) for v in config.bounds_max],
                  'resolution': float(config.resolution),
                  'safety_margin': float(config.safety_margin),
                  'adaptive_threshold': float(config.adaptive_threshold),
                  'start': [float(v) for v in scene.start], 'max_speed_horizontal': 3.0}
    node = NodeProcess(
        planner_command(namespace=NAMESPACE, parameters=parameters,
                        params_file=REPO / 'config' / 'planner.yaml'),
        ros_environment(domain_id, Path(log_dir)))
    try:
        node.wait_ready(180.0)
    except NodeProcessError as error:
        node.kill()
        raise RuntimeError(f'planner_node did not start: {error}') from None
    return node


def percentile(values: List[float], q: float) -> Optional[float]:
    return float(np.percentile(values, q)) if values else None


class ParameterPoller:
    """get_parameters round trips every 100 ms [s]."""

    def __init__(self, client: BackgroundNode) -> None:
        self.params = AsyncParameterClient(client.node, f'{NAMESPACE}/global_planner')
        deadline = time.monotonic() + 30.0
        while not self.params.services_are_ready() and time.monotonic() < deadline:
            time.sleep(0.1)
        self.samples: List[float] = []
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self.stop.is_set():
            started = time.monotonic()
            done = threading.Event()
            future = self.params.get_parameters(['safety_margin'])
            future.add_done_callback(lambda _: done.set())
            if done.wait(10.0):
                self.samples.append(time.monotonic() - started)
            time.sleep(max(0.1 - (time.monotonic() - started), 0.0))


def measure(goals: int, domain_id: int) -> Dict[str, Any]:
    scene = outdoor_scenes.town400()
    with tempfile.TemporaryDirectory() as log_dir:
        node = start_node(domain_id, log_dir)
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain_id), ROS_LOG_DIR=log_dir,
                   ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', PYTHONUNBUFFERED='1')
        mapper = subprocess.Popen([sys.executable, __file__, '--mapper', '--domain',
                                   str(domain_id)], env=env, stdin=subprocess.PIPE,
                                  stdout=subprocess.PIPE, text=True)
        mapper_lines: List[str] = []
        mapper_changed = threading.Condition()

        def read_mapper() -> None:
            for line in mapper.stdout:  # type: ignore[union-attr]
                with mapper_changed:
                    mapper_lines.append(line.strip())
                    mapper_changed.notify_all()
        threading.Thread(target=read_mapper, daemon=True).start()

        def mapper_reply(prefix: str, after: int, timeout_s: float) -> Optional[str]:
            deadline = time.monotonic() + timeout_s
            with mapper_changed:
                while True:
                    for line in mapper_lines[after:]:
                        if line.startswith(prefix):
                            return line
                    left = deadline - time.monotonic()
                    if left <= 0:
                        return None
                    mapper_changed.wait(left)

        def command(text: str) -> None:
            mapper.stdin.write(text + '\n')  # type: ignore[union-attr]
            mapper.stdin.flush()  # type: ignore[union-attr]

        client = BackgroundNode('live_maps_bench_client', domain_id)
        process = psutil.Process(node.process.pid)
        try:
            observer = Observer(client, np.asarray(scene.start))
            observer.flying.start()
            first = observer.wait_diag(0, lambda v: v.get('event') == 'map_status'
                                       and int(v.get('obstacle_cloud_accepted', '0')) > 0,
                                       120.0)
            if first is None:
                raise RuntimeError('no cloud reached the planner')
            poller = ParameterPoller(client)
            poller.thread.start()
            # Phase 1: streaming only.
            time.sleep(2.0)
            cpu0, wall0 = sum(process.cpu_times()[:2]), time.monotonic()
            samples0 = len(poller.samples)
            time.sleep(10.0)
            cpu_stream = (sum(process.cpu_times()[:2]) - cpu0) / (time.monotonic() - wall0)
            stream_rtt = list(poller.samples[samples0:])
            # Phase 2: goals, flight, drops.
            cpu1, wall1 = sum(process.cpu_times()[:2]), time.monotonic()
            samples1 = len(poller.samples)
            goal_latency: List[float] = []
            goals_unserved = 0
            drops: List[Dict[str, Any]] = []
            for number, goal in enumerate(street_goals(goals)):
                plan_mark = len(observer.plans)
                sent = time.monotonic()
                observer.goal_pub.publish(conv.pose_stamped(goal, 'map', 0))
                plan = observer.wait_plan(plan_mark, lambda p, g=goal: len(p['points']) > 1
                                          and np.linalg.norm(p['points'][-1] - g) < 1e-3,
                                          GOAL_PERIOD + 10.0)
                if plan is None:
                    goals_unserved += 1
                    continue
                goal_latency.append(plan['arrived'] - sent)
                time.sleep(1.0)
                if number % 2 == 1:
                    drops.append(drop(observer, command, mapper_reply, mapper_lines,
                                      'marker' if number % 4 == 1 else 'cloud', number))
                time.sleep(max(GOAL_PERIOD - (time.monotonic() - sent), 0.0))
            cpu_goals = (sum(process.cpu_times()[:2]) - cpu1) / (time.monotonic() - wall1)
            rss_mb = process.memory_info().rss / 2 ** 20
            goals_rtt = list(poller.samples[samples1:])
            poller.stop.set()
            marker_count = len(mapper_lines)
            command('quit')
            sent_line = mapper_reply('sent', marker_count, 20.0)
            clouds_sent = int(sent_line.split()[1]) if sent_line else None
            time.sleep(1.5)
            observer.stop.set()
            with observer.lock:
                diagnostics = list(observer.diagnostics)
                plans = list(observer.plans)
            figures = summarise(diagnostics, plans, goal_latency, goals_unserved, drops,
                                stream_rtt, goals_rtt, cpu_stream, cpu_goals, clouds_sent,
                                observer.collisions)
            figures['node_rss_mb'] = rss_mb
            return figures
        finally:
            client.close()
            if mapper.poll() is None:
                mapper.kill()
            try:
                node.stop()
            except NodeProcessError as error:
                print(f'bench_live_maps: {error}', file=sys.stderr)


def drop(observer: Observer, command, mapper_reply, mapper_lines: List[str], kind: str,
         number: int) -> Dict[str, Any]:
    """Drop an obstacle on the plan in force 15 m ahead of the vehicle; time its withdrawal
    and replacement (None when they did not come within 10 s)."""
    center = observer.point_ahead(DROP_AHEAD)
    if center is None:
        return {'kind': kind, 'skipped': 'the plan in force ends within 15 m'}
    plan_mark = len(observer.plans)
    with observer.lock:
        observer.hazards.append(center)
    if kind == 'marker':
        sphere = Marker()
        sphere.header.frame_id = 'map'
        sphere.ns, sphere.id, sphere.type, sphere.action = 'dropped', number, Marker.SPHERE, 0
        sphere.pose.position.x, sphere.pose.position.y, sphere.pose.position.z = (
            float(v) for v in center)
        sphere.pose.orientation.w = 1.0
        sphere.scale.x = sphere.scale.y = sphere.scale.z = 2.0 * DROP_RADIUS
        msg = MarkerArray()
        msg.markers = [sphere]
        sent_ns = observer.now_ns()
        observer.obstacles_pub.publish(msg)
    else:
        mark = len(mapper_lines)
        command(f'pole {center[0]} {center[1]} {center[2]}')
        reply = mapper_reply('pole', mark, 5.0)
        if reply is None:
            return {'kind': kind, 'skipped': 'the mapper did not answer'}
        sent_ns = int(reply.split()[1])
    withdrawn = observer.wait_plan(plan_mark, lambda p: len(p['points']) == 0, 10.0)
    replaced = observer.wait_plan(plan_mark, lambda p: len(p['points']) > 1
                                  and p['arrived_ns'] > sent_ns, 10.0)
    result = {'kind': kind,
              'withdrawn_s': None if withdrawn is None
              else (withdrawn['arrived_ns'] - sent_ns) * 1e-9,
              'replaced_s': None if replaced is None
              else (replaced['arrived_ns'] - sent_ns) * 1e-9}
    if replaced is not None:
        result['replacement_clear_m'] = float(
            np.min(np.linalg.norm(replaced['points'] - center, axis=1)) - DROP_RADIUS)
    time.sleep(1.0)
    # Take it away again, so the streets stay open for the next goals.
    with observer.lock:
        observer.hazards.remove(center) if any(h is center for h in observer.hazards) else None
    if kind == 'marker':
        clear = Marker()
        clear.header.frame_id = 'map'
        clear.ns, clear.action = 'dropped', Marker.DELETEALL
        msg = MarkerArray()
        msg.markers = [clear]
        observer.obstacles_pub.publish(msg)
    else:
        command('clear')
    return result


def summarise(diagnostics, plans, goal_latency, goals_unserved, drops, stream_rtt, goals_rtt,
              cpu_stream, cpu_goals, clouds_sent, collisions) -> Dict[str, Any]:
    ages = []
    for values in diagnostics:
        if values.get('event') == 'plan' and values.get('status') == 'ok':
            stamp = int(values.get('obstacles_stamp', '0'))
            if stamp > 0:
                ages.append((int(values['_stamp']) - stamp) * 1e-9)
    discards: Dict[str, int] = {}
    for values in diagnostics:
        if values.get('event') == 'plan_discarded':
            why = 'vehicle moved' if 'vehicle moved' in values.get('reason', '') else 'new map'
            discards[why] = discards.get(why, 0) + 1
    compute = [sum(float(v[key]) for key in ('planning_time_s', 'smoothing_time_s',
                                             'grid_build_time_s'))
               for v in diagnostics if v.get('event') == 'plan' and v.get('status') == 'ok']
    statuses = [v for v in diagnostics if v.get('event') == 'map_status']
    latencies = [float(x) for v in statuses for x in v.get('cloud_latencies_s', '').split()]
    last = statuses[-1] if statuses else {}
    withdrawn = {kind: [d['withdrawn_s'] for d in drops if d.get('kind') == kind
                        and d.get('withdrawn_s') is not None] for kind in ('marker', 'cloud')}
    replaced = {kind: [d['replaced_s'] for d in drops if d.get('kind') == kind
                       and d.get('replaced_s') is not None] for kind in ('marker', 'cloud')}
    return {
        'goals_served': len(goal_latency), 'goals_unserved': goals_unserved,
        'goal_to_plan_p50_s': percentile(goal_latency, 50),
        'goal_to_plan_p90_s': percentile(goal_latency, 90),
        'goal_to_plan_max_s': max(goal_latency) if goal_latency else None,
        'goal_to_plan_s': [round(v, 3) for v in goal_latency],
        'plans_discarded': discards,
        'plans_cancelled': sum(1 for v in diagnostics if v.get('event') == 'plan_cancelled'),
        'plans_failed': [f"{v['status']}: {v.get('message', '')[:160]}" for v in diagnostics
                         if v.get('event') == 'plan' and v.get('status') != 'ok'],
        'plan_compute_p50_s': percentile(compute, 50),
        'plan_compute_max_s': max(compute) if compute else None,
        'plans_published': sum(1 for p in plans if len(p['points']) > 1),
        'map_age_median_s': percentile(ages, 50), 'map_age_max_s': max(ages) if ages else None,
        'cloud_in_map_p50_s': percentile(latencies, 50),
        'cloud_in_map_p90_s': percentile(latencies, 90),
        'cloud_in_map_max_s': max(latencies) if latencies else None,
        'clouds_sent': clouds_sent,
        'clouds_reached_node': int(last.get('obstacle_cloud_received', 0)),
        'clouds_taken_in': int(last.get('obstacle_cloud_accepted', 0)),
        'clouds_superseded_at_node': int(last.get('obstacle_cloud_superseded', 0)),
        'drops': drops,
        'withdrawn_marker_max_s': max(withdrawn['marker']) if withdrawn['marker'] else None,
        'withdrawn_cloud_max_s': max(withdrawn['cloud']) if withdrawn['cloud'] else None,
        'replaced_marker_max_s': max(replaced['marker']) if replaced['marker'] else None,
        'replaced_cloud_max_s': max(replaced['cloud']) if replaced['cloud'] else None,
        'param_rtt_streaming_p50_s': percentile(stream_rtt, 50),
        'param_rtt_streaming_p99_s': percentile(stream_rtt, 99),
        'param_rtt_streaming_max_s': max(stream_rtt) if stream_rtt else None,
        'param_rtt_goals_p99_s': percentile(goals_rtt, 99),
        'param_rtt_goals_max_s': max(goals_rtt) if goals_rtt else None,
        'node_cpu_streaming_cores': cpu_stream, 'node_cpu_goals_cores': cpu_goals,
        'vehicle_in_a_dropped_obstacle_ticks': collisions,
    }


def _ms(value: Optional[float]) -> str:
    return '-' if value is None else f'{1000.0 * value:.0f} ms'


def print_table(figures: Dict[str, Any]) -> None:
    f = figures
    rows = [
        ('goal -> plan, p50 / p90 / max',
         f'{_ms(f["goal_to_plan_p50_s"])} / {_ms(f["goal_to_plan_p90_s"])} / '
         f'{_ms(f["goal_to_plan_max_s"])} ({f["goals_served"]} goals served, '
         f'{f["goals_unserved"]} not)'),
        ('age of the map a published plan was built on, median / max',
         f'{_ms(f["map_age_median_s"])} / {_ms(f["map_age_max_s"])}'),
        ("a cloud's stamp -> its map in the planner's hands, p50 / p90 / max",
         f'{_ms(f["cloud_in_map_p50_s"])} / {_ms(f["cloud_in_map_p90_s"])} / '
         f'{_ms(f["cloud_in_map_max_s"])}'),
        ('clouds published / reaching the node / taken in / superseded at the node',
         f'{f["clouds_sent"]} / {f["clouds_reached_node"]} / {f["clouds_taken_in"]} / '
         f'{f["clouds_superseded_at_node"]}'),
        ('obstacle on the plan in force -> withdrawn, max (marker / cloud)',
         f'{_ms(f["withdrawn_marker_max_s"])} / {_ms(f["withdrawn_cloud_max_s"])}'),
        ('obstacle on the plan in force -> replaced, max (marker / cloud)',
         f'{_ms(f["replaced_marker_max_s"])} / {_ms(f["replaced_cloud_max_s"])}'),
        ('parameter round trip while streaming, p50 / p99 / max',
         f'{_ms(f["param_rtt_streaming_p50_s"])} / {_ms(f["param_rtt_streaming_p99_s"])} / '
         f'{_ms(f["param_rtt_streaming_max_s"])}'),
        ('parameter round trip with goals and drops too, p99 / max',
         f'{_ms(f["param_rtt_goals_p99_s"])} / {_ms(f["param_rtt_goals_max_s"])}'),
        ('node CPU: streaming only / with goals [cores]',
         f'{f["node_cpu_streaming_cores"]:.2f} / {f["node_cpu_goals_cores"]:.2f}'),
        ('vehicle ticks inside a dropped obstacle', f'{f["vehicle_in_a_dropped_obstacle_ticks"]}'),
        ('node resident memory at the end', f'{f["node_rss_mb"]:.0f} MB'),
        ('plans discarded (vehicle moved / new map) and failed',
         f'{f["plans_discarded"]}, {len(f["plans_failed"])} failed'),
    ]
    width = max(len(name) for name, _ in rows)
    for name, value in rows:
        print(f'{name:<{width}}  {value}')
    for d in f['drops']:
        print('  drop:', {k: (round(v, 3) if isinstance(v, float) else v) for k, v in d.items()})
    for failure in f['plans_failed']:
        print('  failed plan:', failure)
    print('  goal -> plan [s]:', f['goal_to_plan_s'])


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--goals', type=int, default=12, help='goals sent, one every 5 s')
    parser.add_argument('--domain', type=int, default=None, help='ROS domain id')
    parser.add_argument('--json', action='store_true', help='print the figures as JSON')
    parser.add_argument('--mapper', action='store_true', help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    domain_id = choose_domain_id(args.domain)
    if args.mapper:
        run_mapper(domain_id, CLOUD_RATE)
        return 0
    figures = measure(args.goals, domain_id)
    if args.json:
        print(json.dumps(figures, indent=2))
    else:
        print(f'load average at the end: {os.getloadavg()[0]:.2f} (2 cores)')
        print_table(figures)
    return 0


if __name__ == '__main__':
    sys.exit(main())
