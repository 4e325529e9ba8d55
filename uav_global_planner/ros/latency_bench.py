"""ROS-side performance figures of ``planner_node``: goal-to-plan latency, start-up, memory.

``python -m uav_global_planner.ros.latency_bench [--json]`` starts ``planner_node`` as a child
process for each scene (``config/planner.yaml`` with the scene's bounds, delta, gamma, eta and
start given as ``-p`` overrides, as ``uav-demo`` does) and talks to it over DDS like any client:

start-up
    From just before the process is spawned until its ``planner ready`` log line (the node
    logs it after declaring its parameters, creating its topics, loading the compiled kernels
    and building the empty grid, right before it spins; the tests wait for the same line).
latency
    The scene's obstacles go out once as a transient-local ``MarkerArray``; after a few warm-up
    goals, ``--goals`` goals alternate between the scene's goal and another free point, so each
    one is a real replan. The latency of a goal runs from just before ``publish`` on
    ``goal_pose`` until the ``plan`` message ending at that goal has arrived in the client and
    been deserialised into a Python ``nav_msgs/Path``; the time until its bytes arrived is
    reported too (the difference is the Python client's own deserialisation, a few
    milliseconds for a few hundred poses, which a C++ client hardly pays). The next goal is
    sent once the node has also published the diagnostics of the plan, its last output, so
    goals never queue up behind each other.
memory
    For ``--memory-scene`` (default ``dense60_fine``), the node plans the scene with each
    algorithm in turn (switched with the ``algorithm`` parameter over the parameter services);
    the peak is ``VmHWM`` of ``/proc/<pid>/status``, the true high-water mark of the node
    process's resident memory.

Each node runs in its own namespace, and in the ROS domain given by ``--domain-id`` (default:
``$ROS_DOMAIN_ID``, else one derived from the process id) with discovery limited to this machine,
so the benchmark neither disturbs nor sees other ROS systems. Figures only: nothing here asserts
a speed. Exit code 0 when every goal got its plan, 1 otherwise, 2 for bad arguments.
"""

import argparse
import json
import os
from pathlib import Path
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from typing import Any, Callable, Dict, List, Optional, Sequence

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path as PathMsg
import numpy as np
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import PointCloud2
from visualization_msgs.msg import MarkerArray

from uav_global_planner.cli.bench import format_ros_report
from uav_global_planner.core.config import ALGORITHMS
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.scene import find_scene, load_scene, Scene
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.background_node import BackgroundNode, choose_domain_id
from uav_global_planner.ros.demo import _scene_overrides, find_config
from uav_global_planner.ros.qos import COMMAND_QOS, LATCHED_QOS, MONITOR_QOS

#: Scenes whose latency is measured when none are named.
DEFAULT_SCENES = ('paper_medium', 'paper_high')
#: Scene whose peak memory is measured by default.
DEFAULT_MEMORY_SCENE = 'dense60_fine'
#: Goals per latency scene by default.
DEFAULT_GOALS = 50

_READY_TEXT = 'planner ready'
# The node under test, run as ``python -m``.
_NODE_MODULE = 'uav_global_planner.ros.planner_node'
_NODE_NAME = 'global_planner'
# Goals sent (and not counted) before the measured ones: the first plans load code paths.
_WARM_UP_GOALS = 4
# Goals per algorithm on the memory scene (latency there is a by-product).
_MEMORY_GOALS = 2


# A plan must end within this distance of the goal it answers [m] (it ends exactly there).
_GOAL_MATCH_M = 1e-6
# Diagnostics print positions with 4 decimals [m].
_DIAG_MATCH_M = 2e-4


class BenchError(RuntimeError):
    """The node did not start or did not answer in time."""


# --------------------------------------------------------------------------------------------
# The node under test
# --------------------------------------------------------------------------------------------

class _NodeProcess:
    """``planner_node`` as a child process; its output is read (and time-stamped) on a thread.

    Parameters
    ----------
    command : sequence of str
    env : dict
        Full environment of the child.
    """

    def __init__(self, command: Sequence[str], env: Dict[str, str]) -> None:
        self._lines: List[str] = []
        self._changed = threading.Condition()
        self.ready_at: Optional[float] = None
        self.launched_at = time.monotonic()
        self.process = subprocess.Popen(
            list(command), env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL, text=True, bufsize=1, start_new_session=True)
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            now = time.monotonic()
            with self._changed:
                if self.ready_at is None and _READY_TEXT in line:
                    self.ready_at = now
                self._lines.append(line.rstrip('\n'))
                self._changed.notify_all()
        with self._changed:
            self._changed.notify_all()

    def tail(self, count: int = 20) -> str:
        """The last ``count`` output lines, indented."""
        with self._changed:
            return '\n'.join(f'    {line}' for line in self._lines[-count:])

    def wait_ready(self, timeout_s: float) -> float:
        """Seconds from spawning to the ready line.

        Raises
        ------
        BenchError
            When the process exits first or the line does not come within ``timeout_s``.
        """
        deadline = time.monotonic() + timeout_s
        with self._changed:
            while self.ready_at is None:
                if self.process.poll() is not None and not self._reader.is_alive():
                    raise BenchError(f'planner_node exited with {self.process.returncode} '
                                     f'before it was ready:\n{self.tail_unlocked()}')
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise BenchError(f'planner_node not ready within {timeout_s} s:\n'
                                     f'{self.tail_unlocked()}')
                self._changed.wait(min(remaining, 0.2))
            return self.ready_at - self.launched_at

    def tail_unlocked(self, count: int = 20) -> str:
        """:meth:`tail` for callers that hold the lock."""
        return '\n'.join(f'    {line}' for line in self._lines[-count:])

    def status_kb(self) -> Dict[str, int]:
        """Memory lines of ``/proc/<pid>/status`` (``VmHWM``, ``VmRSS``, ...) [kB]."""
        values = {}
        try:
            text = Path(f'/proc/{self.process.pid}/status').read_text(encoding='ascii')
        except OSError:
            return values
        for line in text.splitlines():
            key, _, rest = line.partition(':')
            parts = rest.split()
            if key.startswith('Vm') and len(parts) == 2 and parts[1] == 'kB':
                values[key] = int(parts[0])
        return values

    def stop(self, timeout_s: float = 10.0) -> Optional[int]:
        """SIGINT, then SIGKILL after ``timeout_s``; the exit code."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._reader.join(5.0)
        return self.process.returncode


# --------------------------------------------------------------------------------------------
# The client side
# --------------------------------------------------------------------------------------------

class _Inbox:
    """Messages of one subscription with their arrival times (``time.perf_counter``).

    Parameters
    ----------
    changed : threading.Condition
        Notified after each message.
    msg_type : type, optional
        For a raw subscription: the items are (arrival of the bytes, message deserialised in
        the callback, end of that deserialisation). Otherwise (arrival, message).
    """

    def __init__(self, changed: threading.Condition, msg_type: Optional[type] = None) -> None:
        self._changed = changed
        self._msg_type = msg_type
        self.items: List[tuple] = []

    def __call__(self, msg: Any) -> None:
        arrived = time.perf_counter()
        if self._msg_type is None:
            item: tuple = (arrived, msg)
        else:
            item = (arrived, deserialize_message(msg, self._msg_type), time.perf_counter())
        with self._changed:
            self.items.append(item)
            self._changed.notify_all()


class _Client:
    """The benchmark's rclpy node, in its own context, spun on a background thread.

    Parameters
    ----------
    domain_id : int
    namespace : str
        Namespace of the planner node; the client's topics are resolved in it.
    """

    def __init__(self, domain_id: int, namespace: str) -> None:
        self.namespace = namespace
        self.node_fqn = f'{namespace}/{_NODE_NAME}'
        self._background = BackgroundNode('uav_latency_bench', domain_id, namespace)
        self.node = self._background.node
        self.changed = threading.Condition()
        # Raw, to time the arrival of the bytes and the Python deserialisation apart.
        self.plans = _Inbox(self.changed, PathMsg)
        self.diagnostics = _Inbox(self.changed)
        node = self.node
        node.create_subscription(PathMsg, 'plan', self.plans, LATCHED_QOS, raw=True)
        node.create_subscription(DiagnosticArray, '/diagnostics', self.diagnostics,
                                 MONITOR_QOS)
        self.goal_pub = node.create_publisher(PoseStamped, 'goal_pose', COMMAND_QOS)
        self.obstacles_pub = node.create_publisher(MarkerArray, 'obstacles', LATCHED_QOS)
        self.cloud_pub = node.create_publisher(PointCloud2, 'obstacle_cloud', COMMAND_QOS)
        self.parameters = AsyncParameterClient(node, self.node_fqn)

    def close(self) -> None:
        """Stop spinning and release the context."""
        self._background.close()

    def mark(self) -> tuple:
        """Message counts so far, to wait only for newer messages."""
        with self.changed:
            return len(self.plans.items), len(self.diagnostics.items)

    def wait(self, predicate: Callable[[], Any], timeout_s: float) -> Any:
        """Wait under the message lock until ``predicate()`` is truthy; return it (or None)."""
        deadline = time.monotonic() + timeout_s
        with self.changed:
            while True:
                value = predicate()
                if value:
                    return value
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                self.changed.wait(min(remaining, 0.1))

    def plan_diagnostics(self, after: int) -> List[Dict[str, str]]:
        """Key values of the planner's ``plan`` diagnostics received since ``after``.

        Call with :attr:`changed` held.
        """
        found = []
        for _, msg in self.diagnostics.items[after:]:
            for status, values in conv.diagnostic_values(msg):
                if (status.name.startswith(f'{self.node_fqn}: ')
                        and values.get('event') == 'plan'):
                    found.append(values)
        return found

    def set_parameter(self, name: str, value: Any, timeout_s: float) -> None:
        """Set one parameter of the planner.

        Raises
        ------
        BenchError
            When the services do not answer or the node refuses the value.
        """
        if not self.parameters.wait_for_services(timeout_sec=timeout_s):
            raise BenchError(f'parameter services of {self.node_fqn} not available')
        done = threading.Event()
        future = self.parameters.set_parameters([Parameter(name, value=value)])
        future.add_done_callback(lambda _: done.set())
        if not done.wait(timeout_s):
            raise BenchError(f'setting {name} timed out after {timeout_s} s')
        result = future.result().results[0]
        if not result.successful:
            raise BenchError(f'{name} = {value!r} refused: {result.reason}')

    def wait_matched(self, timeout_s: float) -> bool:
        """True once the planner's subscriptions and publishers are known on both sides."""
        def matched() -> bool:
            return (self.goal_pub.get_subscription_count() > 0
                    and self.obstacles_pub.get_subscription_count() > 0
                    and self.node.count_publishers(f'{self.namespace}/plan') > 0
                    and self.node.count_publishers('/diagnostics') > 0)
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if matched():
                return True
            time.sleep(0.02)
        return matched()


# --------------------------------------------------------------------------------------------
# Measurements
# --------------------------------------------------------------------------------------------

def _parse_point(text: Optional[str]) -> Optional[np.ndarray]:
    """``[x, y, z]`` of a diagnostics value, or None."""
    if not text:
        return None
    try:
        values = [float(v) for v in text.strip('[] ').split(',')]
    except ValueError:
        return None
    return np.array(values) if len(values) == 3 else None


def _float(values: Dict[str, str], key: str) -> Optional[float]:
    try:
        number = float(values[key])
    except (KeyError, ValueError):
        return None
    return number if np.isfinite(number) else None


def alternate_goal(scene: Scene) -> np.ndarray:
    """A second free goal of ``scene``, far from its start and goal, to alternate with.

    The first of a fixed list of points (as fractions of the workspace) that keeps a clearance
    of gamma + 2 delta and lies at least a third of the workspace diagonal from the start and
    the goal; deterministic for a given scene.

    Raises
    ------
    BenchError
        When no candidate is free.
    """
    config = scene.config
    lo = np.asarray(config.bounds_min, dtype=np.float64)
    hi = np.asarray(config.bounds_max, dtype=np.float64)
    fractions = [(a, b, c) for c in (0.5, 0.3, 0.7, 0.15, 0.85)
                 for a, b in ((0.15, 0.85), (0.85, 0.15), (0.15, 0.15), (0.85, 0.85),
                              (0.5, 0.9), (0.9, 0.5), (0.1, 0.5), (0.5, 0.1))]
    candidates = lo + np.array(fractions) * (hi - lo)
    clearance = scene.obstacles.distance(candidates)
    far = np.linalg.norm(hi - lo) / 3.0
    for point, free in zip(candidates, clearance):
        if (free >= config.safety_margin + 2.0 * config.resolution
                and np.linalg.norm(point - scene.start) >= far
                and np.linalg.norm(point - scene.goal) >= far):
            return point
    raise BenchError(f'no free alternate goal found in scene {scene.name!r}')


class _Session:
    """One planner node with one scene, and the client talking to it."""

    def __init__(self, scene: Scene, domain_id: int, namespace: str, log_dir: Path,
                 timeout_s: float) -> None:
        self.scene = scene
        self.timeout_s = timeout_s
        self.client = _Client(domain_id, namespace)
        env = dict(os.environ)
        env.update({'ROS_DOMAIN_ID': str(domain_id),
                    'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST', 'PYTHONUNBUFFERED': '1',
                    'RCUTILS_COLORIZED_OUTPUT': '0', 'ROS_LOG_DIR': str(log_dir)})
        env.pop('ROS_STATIC_PEERS', None)
        start = '[' + ', '.join(repr(float(v)) for v in scene.start) + ']'
        command = [sys.executable, '-m', _NODE_MODULE, '--ros-args',
                   '-r', f'__ns:={namespace}', '--params-file', str(find_config()),
                   *_scene_overrides(scene), '-p', f'start:={start}']
        self.node = _NodeProcess(command, env)
        self.startup_s: Optional[float] = None
        self.goal_index = 0
        self.algorithm: Optional[str] = None  # as last reported by the node
        self.goals = (np.asarray(scene.goal, dtype=np.float64), alternate_goal(scene))

    def close(self) -> Optional[int]:
        """Stop the node and the client; the node's exit code."""
        code = self.node.stop()
        self.client.close()
        return code

    def start(self) -> float:
        """Wait for the node, send the obstacles and warm up; return the start-up time [s]."""
        self.startup_s = self.node.wait_ready(self.timeout_s)
        if not self.client.wait_matched(self.timeout_s):
            raise BenchError(f'planner topics not matched within {self.timeout_s} s:\n'
                             f'{self.node.tail()}')
        scene = self.scene
        stamp_ns = self.client.node.get_clock().now().nanoseconds
        markers = conv.obstacle_input_markers(scene.obstacles, scene.frame_id, stamp_ns)
        cloud = scene.obstacles.points if len(scene.obstacles.points) else None
        expected = len(conv.combine_obstacles(
            conv.apply_marker_array({}, markers, scene.frame_id, float('inf')), cloud))
        self.client.obstacles_pub.publish(markers)
        if cloud is not None:
            self.client.cloud_pub.publish(conv.points_to_cloud(cloud, scene.frame_id, stamp_ns))
        # Until a plan reports every obstacle, the obstacles may still be on their way.
        for _ in range(20):
            outcome = self.send_goal()
            if outcome['obstacles'] == expected:
                break
            time.sleep(0.1)
        else:
            raise BenchError(f'the node never planned with all {expected} obstacles')
        for _ in range(_WARM_UP_GOALS - 1):
            self.send_goal()
        return self.startup_s

    def set_algorithm(self, algorithm: str) -> None:
        """Switch the ``algorithm`` parameter and wait for the replan it causes."""
        client = self.client
        _, diags_before = client.mark()
        client.set_parameter('algorithm', algorithm, self.timeout_s)
        if algorithm == self.algorithm:
            return  # no change, no replan
        self.algorithm = algorithm
        # The node replans its active goal by itself; let that finish before timing goals.
        if client.wait(lambda: any(values.get('algorithm') == algorithm for values in
                                   client.plan_diagnostics(diags_before)),
                       self.timeout_s) is None:
            raise BenchError(f'no replan after switching to {algorithm}:\n{self.node.tail()}')

    def send_goal(self) -> Dict[str, Any]:
        """Publish the next goal; wait for its plan and diagnostics.

        Returns
        -------
        dict
            ``latency_s`` until the plan was deserialised (None when no plan came),
            ``bytes_s`` until its bytes arrived, ``status``, ``algorithm``, ``obstacles`` (count
            the node planned with), ``node_search_s``, ``node_smoothing_s``, ``poses`` and
            ``kind`` (0 for the scene's goal, 1 for the alternate one).
        """
        kind = self.goal_index % 2
        goal = self.goals[kind]
        self.goal_index += 1
        client = self.client
        frame = self.scene.frame_id
        msg = conv.pose_stamped(goal, frame, client.node.get_clock().now().nanoseconds)
        plans_before, diags_before = client.mark()
        sent = time.perf_counter()
        client.goal_pub.publish(msg)

        def answered() -> Optional[Dict[str, str]]:
            for values in client.plan_diagnostics(diags_before):
                point = _parse_point(values.get('goal'))
                if point is not None and np.linalg.norm(point - goal) <= _DIAG_MATCH_M:
                    return values
            return None

        values = client.wait(answered, self.timeout_s)
        if values is None:
            raise BenchError(f'no answer to goal {goal.tolist()} within {self.timeout_s} s:\n'
                             f'{self.node.tail()}')
        self.algorithm = values.get('algorithm')
        outcome = {'status': values.get('status'), 'latency_s': None, 'bytes_s': None,
                   'poses': None, 'kind': kind,
                   'obstacles': int(_float(values, 'obstacles') or 0),
                   'node_search_s': _float(values, 'planning_time_s'),
                   'node_smoothing_s': _float(values, 'smoothing_time_s'),
                   'algorithm': values.get('algorithm')}
        if outcome['status'] != 'ok':
            return outcome

        def received() -> Optional[tuple]:
            for arrived, path, decoded in client.plans.items[plans_before:]:
                if len(path.poses) and np.linalg.norm(
                        conv.path_to_points(path)[-1] - goal) <= _GOAL_MATCH_M:
                    return arrived, decoded, len(path.poses)
            return None

        # The plan goes out before the diagnostics, but topics are not ordered with each other.
        arrival = client.wait(received, 5.0)
        if arrival is not None:
            outcome['bytes_s'] = arrival[0] - sent
            outcome['latency_s'] = arrival[1] - sent
            outcome['poses'] = arrival[2]
        return outcome


def _summary(values: List[float]) -> Dict[str, Optional[float]]:
    """median, p90 and max of ``values`` [s] in milliseconds (None when empty)."""
    if not values:
        return {'median_ms': None, 'p90_ms': None, 'max_ms': None, 'min_ms': None}
    array = np.asarray(values) * 1e3
    return {'median_ms': float(np.median(array)), 'p90_ms': float(np.percentile(array, 90)),
            'max_ms': float(np.max(array)), 'min_ms': float(np.min(array))}


def _median_ms(values: List[Optional[float]]) -> Optional[float]:
    known = [v for v in values if v is not None]
    return 1e3 * statistics.median(known) if known else None


def measure_latency(scene_name: str, goals: int, domain_id: int, log_dir: Path,
                    timeout_s: float, index: int = 0) -> Dict[str, Any]:
    """Start-up time and goal-to-plan latency of one scene (see the module documentation).

    Returns
    -------
    dict
        ``scene``, ``startup_s``, ``goals``, ``plans_received``, ``failures`` (statuses other
        than ok), ``latency`` (``median_ms``, ``p90_ms``, ``max_ms``, ``min_ms``; until the
        plan was deserialised), ``bytes_latency`` (the same until its bytes arrived),
        ``node_search_ms`` and ``node_smoothing_ms`` (medians the node reports),
        ``poses`` (median plan size), ``peak_rss_mb``, ``exit_code`` and ``by_goal``: for the
        scene's goal and the alternate goal, ``goal``, ``goals``, ``latency`` and
        ``node_plan_ms`` (median search + smoothing), since the two often differ in cost and
        the median of all goals then falls between them.
    """
    scene = load_scene(find_scene(scene_name))
    session = _Session(scene, domain_id, _namespace(index), log_dir, timeout_s)
    outcomes: List[Dict[str, Any]] = []
    try:
        startup = session.start()
        for _ in range(goals):
            outcomes.append(session.send_goal())
        memory = session.node.status_kb()
    finally:
        code = session.close()
    latencies = [o['latency_s'] for o in outcomes if o['latency_s'] is not None]
    return {
        'scene': scene.name, 'startup_s': startup, 'goals': goals,
        'plans_received': len(latencies),
        'failures': sorted({o['status'] for o in outcomes if o['status'] != 'ok'}),
        'latency': _summary(latencies),
        'bytes_latency': _summary([o['bytes_s'] for o in outcomes if o['bytes_s'] is not None]),
        'node_search_ms': _median_ms([o['node_search_s'] for o in outcomes]),
        'node_smoothing_ms': _median_ms([o['node_smoothing_s'] for o in outcomes]),
        'poses': (int(statistics.median(o['poses'] for o in outcomes if o['poses']))
                  if latencies else None),
        'peak_rss_mb': memory.get('VmHWM', 0) / 1024.0 or None, 'exit_code': code,
        'by_goal': [_goal_figures(session.goals[kind], [o for o in outcomes if o['kind'] == kind])
                    for kind in (0, 1)],
    }


def _goal_figures(goal: np.ndarray, outcomes: List[Dict[str, Any]]) -> Dict[str, Any]:
    """Latency of the goals sent to one of the two goal positions."""
    return {'goal': [float(v) for v in goal], 'goals': len(outcomes),
            'latency': _summary([o['latency_s'] for o in outcomes if o['latency_s'] is not None]),
            'node_plan_ms': _median_ms([o['node_search_s'] + o['node_smoothing_s']
                                        for o in outcomes if o['node_search_s'] is not None
                                        and o['node_smoothing_s'] is not None])}


def measure_memory(scene_name: str, domain_id: int, log_dir: Path, timeout_s: float,
                   index: int = 0) -> Dict[str, Any]:
    """Peak resident memory of the node after planning ``scene_name`` with every algorithm.

    Returns
    -------
    dict
        ``scene``, ``startup_s``, ``peak_rss_mb`` (``VmHWM`` at the end), ``rss_mb`` (``VmRSS``
        at the end), ``exit_code`` and ``algorithms``: per algorithm its ``status``, median
        ``latency_ms`` of a few goals, ``node_search_ms`` and ``peak_rss_mb`` after it.
    """
    scene = load_scene(find_scene(scene_name))
    session = _Session(scene, domain_id, _namespace(index), log_dir, timeout_s)
    rows = []
    try:
        startup = session.start()
        for algorithm in ALGORITHMS:
            session.set_algorithm(algorithm)
            outcomes = [session.send_goal() for _ in range(_MEMORY_GOALS)]
            rows.append({
                'algorithm': algorithm,
                'status': ','.join(sorted({o['status'] for o in outcomes})),
                'latency_ms': _median_ms([o['latency_s'] for o in outcomes]),
                'node_search_ms': _median_ms([o['node_search_s'] for o in outcomes]),
                'peak_rss_mb': session.node.status_kb().get('VmHWM', 0) / 1024.0 or None})
        memory = session.node.status_kb()
    finally:
        code = session.close()
    return {'scene': scene.name, 'startup_s': startup,
            'peak_rss_mb': memory.get('VmHWM', 0) / 1024.0 or None,
            'rss_mb': memory.get('VmRSS', 0) / 1024.0 or None, 'exit_code': code,
            'algorithms': rows}


def _namespace(index: int) -> str:
    return f'/uav_latency_bench_{os.getpid()}_{index}'


# --------------------------------------------------------------------------------------------
# Entry point
# --------------------------------------------------------------------------------------------

def run(scenes: Sequence[str], goals: int, memory_scene: Optional[str], domain_id: int,
        timeout_s: float) -> Dict[str, Any]:
    """Every figure: latency and start-up per scene, then the memory scene.

    Returns
    -------
    dict
        ``domain_id``, ``goals``, ``scenes`` (see :func:`measure_latency`), ``memory``
        (see :func:`measure_memory`, None when skipped), ``cpus``, ``load_average`` and
        ``load_average_after`` (1-minute load before and after), ``log_dir``.
    """
    log_dir = Path(tempfile.mkdtemp(prefix='uav_latency_bench_'))
    figures: Dict[str, Any] = {'domain_id': domain_id, 'goals': goals, 'scenes': [],
                               'memory': None, 'log_dir': str(log_dir),
                               'cpus': os.cpu_count(), 'load_average': _load_average()}
    for index, name in enumerate(scenes):
        figures['scenes'].append(measure_latency(name, goals, domain_id, log_dir, timeout_s,
                                                 index))
    if memory_scene:
        figures['memory'] = measure_memory(memory_scene, domain_id, log_dir, timeout_s,
                                           len(scenes))
    figures['load_average_after'] = _load_average()
    return figures


def _load_average() -> Optional[float]:
    """The 1-minute load average (other work on the machine skews every figure)."""
    try:
        return os.getloadavg()[0]
    except OSError:
        return None


def _parse(argv: Optional[List[str]]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='python -m uav_global_planner.ros.latency_bench',
        description='ROS-side figures of planner_node: goal-to-plan latency, start-up time '
                    'and peak memory.')
    parser.add_argument('scenes', nargs='*', default=list(DEFAULT_SCENES),
                        help='scenes whose latency is measured (default: '
                             f'{" ".join(DEFAULT_SCENES)})')
    parser.add_argument('--goals', type=int, default=DEFAULT_GOALS,
                        help=f'measured goals per scene (default {DEFAULT_GOALS})')
    parser.add_argument('--memory-scene', default=DEFAULT_MEMORY_SCENE,
                        help=f'scene of the peak-memory figure (default {DEFAULT_MEMORY_SCENE})')
    parser.add_argument('--no-memory', action='store_true', help='skip the memory figure')
    parser.add_argument('--domain-id', type=int, default=None,
                        help='ROS domain (default: $ROS_DOMAIN_ID, else derived from the '
                             'process id)')
    parser.add_argument('--timeout', type=float, default=180.0, metavar='S',
                        help='give up after S seconds without an answer (default 180; the '
                             'first run compiles the search kernels)')
    parser.add_argument('--json', action='store_true', help='print one JSON document')
    return parser.parse_args(argv)


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point: measure, then print a table (or JSON with ``--json``).

    Returns
    -------
    int
        0 when every goal got its plan, 1 otherwise or when the node failed, 2 for bad
        arguments.
    """
    options = _parse(argv)
    if options.goals < 1:
        print('latency_bench: --goals must be >= 1', file=sys.stderr)
        return 2
    domain_id = choose_domain_id(options.domain_id)
    # The client in this process reads it from the environment.
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    memory_scene = None if options.no_memory else options.memory_scene
    try:
        for name in [*options.scenes, *([memory_scene] if memory_scene else [])]:
            find_scene(name)
        figures = run(options.scenes, options.goals, memory_scene, domain_id, options.timeout)
    except InvalidInputError as error:
        print(f'latency_bench: {error}', file=sys.stderr)
        return 2
    except BenchError as error:
        print(f'latency_bench: {error}', file=sys.stderr)
        return 1
    if options.json:
        print(json.dumps(figures))
    else:
        print(format_ros_report(figures))
    complete = all(s['plans_received'] == s['goals'] for s in figures['scenes'])
    if figures['memory'] is not None:
        complete = complete and all(r['status'] == 'ok' for r in figures['memory']['algorithms'])
    return 0 if complete else 1


if __name__ == '__main__':
    sys.exit(main())
