"""Helpers for tests that run ROS nodes in real processes and talk to them over DDS.

The processes are started by :mod:`uav_global_planner_tools.processes`, as the demo and the
benchmark start theirs: each gets a ROS domain of its own (:func:`unique_domain_id`),
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and a temporary ``ROS_LOG_DIR``, so concurrent test
runs on one machine do not see each other. The test side uses its own rclpy ``Context`` per
client, spun on a background thread, and never installs signal handlers (pytest keeps Ctrl-C).

Domain ids: ``ROS_DOMAIN_ID=N`` in the environment of pytest makes the tests take N, N+1, ...
(within the safe ids 1-101 and 215-232, wrapping); without it they start at a point derived
from the process id. Ids that another process on this machine is using are skipped, so two
checkouts tested side by side (best given bases far apart, e.g. 10 and 60) never share one.
"""

from contextlib import contextmanager
import itertools
import os
from pathlib import Path
import threading
import time
from typing import (Any, Callable, Dict, Iterator, List, Mapping, Optional, Sequence,
                    TYPE_CHECKING)

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Point, PoseStamped, Quaternion, Vector3
from nav_msgs.msg import Odometry, Path as PathMsg
import numpy as np
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import Header
from visualization_msgs.msg import Marker, MarkerArray

from uav_global_planner.core.planner import densify
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.background_node import BackgroundNode
# Re-exported for the tests, which import these from the harness.
from uav_global_planner.ros.names import NODE_NAME, READY_TEXT  # noqa: F401
from uav_global_planner.ros.qos import (CLOUD_QOS, LATCHED_QOS, MONITOR_QOS,  # noqa: F401
                                        OBSTACLES_QOS, SENSOR_QOS)
from uav_global_planner_tools import processes
from uav_global_planner_tools.domains import (candidate_domains, domain_in_use,
                                              environment_domain_id, SAFE_DOMAIN_IDS)
from uav_global_planner_tools.processes import (localhost_discovery, NodeProcess,  # noqa: F401
                                                NodeProcessError, ros_environment, wait_until)

if TYPE_CHECKING:
    from uav_global_planner.ros.planner_node import PlannerNode

REPO_ROOT = Path(__file__).resolve().parents[1]
PLANNER_YAML = REPO_ROOT / 'config' / 'planner.yaml'

# Start-up of a node: Python imports, loading the cached kernels, building the grid. Generous,
# because a cold numba cache compiles for tens of seconds on a slow machine.
STARTUP_TIMEOUT_S = 120.0

#: First domain id of this run's tests: ``$ROS_DOMAIN_ID`` or None (derived from the pid).
DOMAIN_BASE = environment_domain_id()


def _worker_share(domains: List[int]) -> List[int]:
    """The domain ids of this pytest-xdist worker: worker n of N takes the safe ids whose
    position is n modulo N, so that the test command's workers never start nodes in one
    domain, not even in the moment between checking an id and a node binding its ports."""
    worker = os.environ.get('PYTEST_XDIST_WORKER', '')
    count = int(os.environ.get('PYTEST_XDIST_WORKER_COUNT', '1') or 1)
    if not worker.startswith('gw') or not worker[2:].isdigit() or count < 2:
        return domains
    index = int(worker[2:]) % count
    return [d for d in domains if SAFE_DOMAIN_IDS.index(d) % count == index]


# Every safe id (of this worker) once from the base on, then around again; each call of
# unique_domain_id() takes the next one that no process on this machine is using.
_domains = itertools.cycle(_worker_share(list(candidate_domains(DOMAIN_BASE))))

#: Namespace of this test run's planner nodes. Should another test run on this machine draw the
#: same domain id at the same time, its topics still do not cross ours.
RUN_NAMESPACE = f'/uav_test_{os.getpid()}'


def unique_domain_id() -> int:
    """A ROS domain id for one test: the next one after the last call that is free (never 0).

    Raises
    ------
    RuntimeError
        When every safe domain id is in use on this machine.
    """
    for _ in range(len(SAFE_DOMAIN_IDS)):
        candidate = next(_domains)
        if not domain_in_use(candidate):
            return candidate
    raise RuntimeError('every safe ROS domain id is in use on this machine')


def planner_command(namespace: Optional[str] = None,
                    parameters: Optional[Mapping[str, Any]] = None,
                    params_file: Optional[Path] = PLANNER_YAML,
                    executable: Optional[str] = None) -> List[str]:
    """Command line of a planner node; the checkout's config/planner.yaml by default.

    See :func:`uav_global_planner_tools.processes.planner_command`.
    """
    return processes.planner_command(namespace, parameters, params_file, executable)


def start_planner(domain_id: int, wait: bool = True, **options: Any) -> NodeProcess:
    """Start a planner node process and (by default) wait for its ready line."""
    node = NodeProcess(planner_command(**options), ros_environment(domain_id))
    if wait:
        try:
            node.wait_for_output(READY_TEXT, STARTUP_TIMEOUT_S)
        except NodeProcessError:
            node.kill()
            raise
    return node


def scene_publisher_command(scene: str, namespace: Optional[str] = None,
                            options: Sequence[str] = ('--no-start', '--no-goal')) -> List[str]:
    """Command line of a ``scene_publisher`` for ``scene`` (file or shipped scene name).

    By default it publishes only the obstacles and keeps running, as a map server would.
    """
    return processes.scene_publisher_command(scene, namespace, options)


def start_scene_publisher(domain_id: int, scene: str, namespace: Optional[str] = None,
                          options: Sequence[str] = ('--no-start', '--no-goal')) -> NodeProcess:
    """Start a ``scene_publisher`` process; it logs its scene once the obstacles are out."""
    return NodeProcess(scene_publisher_command(scene, namespace, options),
                       ros_environment(domain_id))


def assert_clean_exit(node: NodeProcess, code: int) -> None:
    """Exit code 0 and no Python traceback in the output."""
    output = node.output
    assert code == 0, f'exit code {code}:\n{output}'
    assert 'Traceback' not in output, output


# --------------------------------------------------------------------------------------------
# The test side of the conversation
# --------------------------------------------------------------------------------------------


class Recorder:
    """Keeps every message of one subscription, for waiting and inspection."""

    def __init__(self) -> None:
        self._messages: List[Any] = []
        self._changed = threading.Condition()

    def __call__(self, msg: Any) -> None:
        with self._changed:
            self._messages.append(msg)
            self._changed.notify_all()

    @property
    def messages(self) -> List[Any]:
        """A copy of the messages received so far."""
        with self._changed:
            return list(self._messages)

    def mark(self) -> int:
        """Number of messages so far; pass it as ``after`` to wait only for newer ones."""
        with self._changed:
            return len(self._messages)

    def wait_for(self, predicate: Callable[[Any], bool] = lambda msg: True,
                 timeout_s: float = 10.0, after: int = 0, what: str = 'a message') -> Any:
        """First message at index >= ``after`` for which ``predicate`` holds."""
        deadline = time.monotonic() + timeout_s
        with self._changed:
            index = after
            while True:
                while index < len(self._messages):
                    if predicate(self._messages[index]):
                        return self._messages[index]
                    index += 1
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise AssertionError(f'timed out after {timeout_s} s waiting for {what}')
                self._changed.wait(remaining)


class RosClient:
    """A test-side rclpy node in its own context, spun on a background thread.

    Parameters
    ----------
    domain_id : int
    name : str
        Node name.
    """

    def __init__(self, domain_id: int, name: str = 'test_client') -> None:
        # The test process is not started through ros_environment(); set what DDS reads here.
        localhost_discovery()
        self._background = BackgroundNode(name, domain_id)
        self.context = self._background.context
        self.node = self._background.node

    def close(self) -> None:
        """Stop spinning, then release the node and the context."""
        self._background.close()

    def record(self, msg_type: Any, topic: str, qos: QoSProfile = MONITOR_QOS) -> Recorder:
        """Subscribe and keep every message."""
        recorder = Recorder()
        self.node.create_subscription(msg_type, topic, recorder, qos)
        return recorder

    def publisher(self, msg_type: Any, topic: str, qos: QoSProfile = MONITOR_QOS,
                  wait_for_subscribers: int = 1, timeout_s: float = 15.0):
        """A publisher, returned once ``wait_for_subscribers`` subscriptions matched."""
        publisher = self.node.create_publisher(msg_type, topic, qos)
        wait_until(lambda: publisher.get_subscription_count() >= wait_for_subscribers,
                   timeout_s, f'{wait_for_subscribers} subscriber(s) on {topic}')
        return publisher

    def parameters(self, remote_node: str) -> 'ParameterHelper':
        """Parameter services of ``remote_node`` (fully qualified name)."""
        return ParameterHelper(self.node, remote_node)

    def now_ns(self) -> int:
        """Current ROS time of the client [ns]."""
        return self.node.get_clock().now().nanoseconds


def wait_future(future, timeout_s: float, what: str) -> Any:
    """Result of an rclpy future completed by the background executor."""
    done = threading.Event()
    future.add_done_callback(lambda _: done.set())
    if not done.wait(timeout_s):
        raise AssertionError(f'timed out after {timeout_s} s waiting for {what}')
    return future.result()


class ParameterHelper:
    """Synchronous wrappers around :class:`AsyncParameterClient` for tests."""

    def __init__(self, node, remote_node: str) -> None:
        self.remote_node = remote_node
        self.client = AsyncParameterClient(node, remote_node)
        wait_until(lambda: self.client.services_are_ready(), 15.0,
                   f'parameter services of {remote_node}')

    def set(self, values: Mapping[str, Any], timeout_s: float = 5.0) -> List[SetParametersResult]:
        """Set parameters one by one (as ``ros2 param set``); one result per parameter."""
        parameters = [Parameter(name, value=value) for name, value in values.items()]
        response = wait_future(self.client.set_parameters(parameters), timeout_s,
                               f'set_parameters {list(values)}')
        return list(response.results)

    def set_atomically(self, values: Mapping[str, Any],
                       timeout_s: float = 5.0) -> SetParametersResult:
        """Set several parameters all at once."""
        parameters = [Parameter(name, value=value) for name, value in values.items()]
        response = wait_future(self.client.set_parameters_atomically(parameters), timeout_s,
                               f'set_parameters_atomically {list(values)}')
        return response.result

    def get(self, names: Sequence[str], timeout_s: float = 5.0) -> Dict[str, Any]:
        """Current values, as plain Python."""
        response = wait_future(self.client.get_parameters(list(names)), timeout_s,
                               f'get_parameters {list(names)}')
        return {name: parameter_value_to_python(value)
                for name, value in zip(names, response.values)}


# --------------------------------------------------------------------------------------------
# Messages and checks
# --------------------------------------------------------------------------------------------

def stamp(ns: int = 0) -> Time:
    """``builtin_interfaces/Time`` of integer nanoseconds."""
    return conv.time_from_ns(ns)


def pose_msg(position: Sequence[float], frame_id: str = 'map',
             orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0)) -> PoseStamped:
    """A ``PoseStamped`` (stamp 0: the planner uses the latest message anyway)."""
    msg = PoseStamped()
    msg.header = Header(frame_id=frame_id)
    msg.pose.position = Point(x=float(position[0]), y=float(position[1]),
                              z=float(position[2]))
    msg.pose.orientation = Quaternion(x=float(orientation[0]), y=float(orientation[1]),
                                      z=float(orientation[2]), w=float(orientation[3]))
    return msg


def odom_msg(position: Sequence[float], frame_id: str = 'map') -> Odometry:
    """An ``Odometry`` at ``position``."""
    msg = Odometry()
    msg.header = Header(frame_id=frame_id)
    msg.child_frame_id = 'base_link'
    msg.pose.pose = pose_msg(position, frame_id).pose
    return msg


def marker(ns: str, marker_id: int, marker_type: int, center: Sequence[float],
           scale: Sequence[float], frame_id: str = 'map', action: int = Marker.ADD,
           orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0)) -> Marker:
    """One marker (SPHERE: scale = diameter; CUBE: edge lengths)."""
    msg = Marker()
    msg.header = Header(frame_id=frame_id)
    msg.ns, msg.id, msg.type, msg.action = ns, marker_id, marker_type, action
    msg.pose = pose_msg(center, frame_id, orientation).pose
    msg.scale = Vector3(x=float(scale[0]), y=float(scale[1]), z=float(scale[2]))
    msg.color.a = 1.0
    return msg


def marker_array(*markers: Marker) -> MarkerArray:
    """A ``MarkerArray`` of the given markers."""
    msg = MarkerArray()
    msg.markers = list(markers)
    return msg


def diagnostics_of(node_fqn: str, msg: DiagnosticArray) -> Optional[Dict[str, str]]:
    """Key values of the planner status of ``node_fqn`` in ``msg`` (None when absent).

    The status message and level are added under ``_message`` and ``_level``.
    """
    for status, values in conv.diagnostic_values(msg):
        if status.name.startswith(f'{node_fqn}: '):
            values = dict(values)
            values['_message'] = status.message
            values['_level'] = int.from_bytes(status.level, 'little')
            return values
    return None


def plans_after_withdrawal(plans: 'Recorder', after: int, withdrawn: Mapping[str, Any],
                           keeps_clear: Callable[[np.ndarray], bool]) -> List[PathMsg]:
    """Check the ``plan`` messages (index >= ``after``) that followed an obstacle landing on
    the plan in force, whose ``plan_withdrawn`` diagnostics are ``withdrawn``; return them.

    ``plan`` is latched state of depth 1 (:data:`LATCHED_QOS`): a subscription that keeps one
    message, as a controller's does, may get the replacement in place of the empty plan that
    withdrew the colliding one when the replacement follows within milliseconds (writer and
    reader each keep only the newest). So the order of messages is not the property; this is:
    every message after the drop is either the empty withdrawal (stamped as its diagnostics) or
    a plan stamped after it whose points satisfy ``keeps_clear``; the withdrawn plan never
    comes back.
    """
    withdrawn_stamp = int(withdrawn['_stamp'])
    messages = plans.messages[after:]
    for message in messages:
        stamp = conv.time_to_ns(message.header.stamp)
        if len(message.poses) == 0:
            assert stamp == withdrawn_stamp, 'an empty plan that is not the withdrawal'
        else:
            assert stamp > withdrawn_stamp, 'a plan from before the withdrawal was published'
            assert keeps_clear(conv.path_to_points(message)), 'a colliding plan was published'
    return messages


def min_clearance(points: np.ndarray, obstacles, spacing_m: float = 0.01) -> float:
    """Smallest distance [m] from the polyline through ``points`` to the obstacles."""
    dense = densify(np.asarray(points, dtype=np.float64).reshape(-1, 3), spacing_m)
    return float(np.min(obstacles.distance(dense)))


# --------------------------------------------------------------------------------------------
# One planner node as seen from the test
# --------------------------------------------------------------------------------------------

#: QoS of the test-side publishers of each planner input topic.
INPUT_QOS = {'goal_pose': MONITOR_QOS, 'start_pose': MONITOR_QOS, 'odom': SENSOR_QOS,
             'obstacles': OBSTACLES_QOS, 'obstacle_cloud': CLOUD_QOS}


class PlannerClient:
    """The test side of one planner node: its outputs, diagnostics, inputs and parameters.

    Publishers are created on first use, so a test that leaves an input to another process
    (for example the obstacles to a ``scene_publisher``) does not latch its own.

    Parameters
    ----------
    client : RosClient
    namespace : str
        Namespace of the planner node ('' or '/' for the root).
    diagnostics : Recorder
        The client's recording of ``/diagnostics`` (shared by every planner of a test).
    process : NodeProcess, optional
        The node's process, for its log lines.
    """

    def __init__(self, client: RosClient, namespace: str, diagnostics: Recorder,
                 process: Optional[NodeProcess] = None) -> None:
        self.client = client
        self.process = process
        self.prefix = namespace.rstrip('/') + '/'
        self.fqn = self.prefix + NODE_NAME
        self.diagnostics = diagnostics
        self.plans = client.record(PathMsg, self.prefix + 'plan', LATCHED_QOS)
        self.markers = client.record(MarkerArray, self.prefix + 'planner_markers', LATCHED_QOS)
        self._publishers: Dict[str, Any] = {}
        self._params: Optional[ParameterHelper] = None

    @property
    def params(self) -> 'ParameterHelper':
        """Parameter services of the node (waits for them on first use)."""
        if self._params is None:
            self._params = self.client.parameters(self.fqn)
        return self._params

    def publish(self, topic: str, msg: Any) -> None:
        """Publish ``msg`` on the planner input ``topic`` (relative name, e.g. 'goal_pose')."""
        publisher = self._publishers.get(topic)
        if publisher is None:
            publisher = self.client.publisher(type(msg), self.prefix + topic, INPUT_QOS[topic])
            self._publishers[topic] = publisher
        publisher.publish(msg)

    def diag(self, msg: DiagnosticArray) -> Optional[Dict[str, str]]:
        """This node's key values in ``msg`` plus ``_stamp`` [ns], or None."""
        values = diagnostics_of(self.fqn, msg)
        if values is not None:
            values['_stamp'] = conv.time_to_ns(msg.header.stamp)
        return values

    def wait_diag(self, after: int, event: str, timeout_s: float = 20.0,
                  check: Callable[[Dict[str, str]], bool] = lambda values: True,
                  what: str = '') -> Dict[str, str]:
        """First diagnostics entry of this node after ``after`` with the given event."""
        def matches(msg: DiagnosticArray) -> bool:
            values = self.diag(msg)
            return values is not None and values.get('event') == event and check(values)
        msg = self.diagnostics.wait_for(matches, timeout_s, after,
                                        what or f'{event} diagnostics of {self.fqn}')
        return self.diag(msg)

    def diag_events(self, after: int, event: str) -> List[Dict[str, str]]:
        """Every diagnostics entry of this node after ``after`` with the given event."""
        found = []
        for msg in self.diagnostics.messages[after:]:
            values = self.diag(msg)
            if values is not None and values.get('event') == event:
                found.append(values)
        return found

    def plan_to(self, goal: Sequence[float],
                orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0),
                frame_id: str = 'map', timeout_s: float = 20.0):
        """Send a goal; return the diagnostics of its plan and the plan (None on failure).

        Replans of an older goal (for new parameters or obstacles) that end meanwhile are
        skipped: only a plan with reason 'new goal' answers the goal.
        """
        mark = self.diagnostics.mark()
        self.publish('goal_pose', pose_msg(goal, frame_id, orientation))
        values = self.wait_diag(mark, 'plan', timeout_s,
                                check=lambda values: values['reason'] == 'new goal')
        return values, self.plan_for(values)

    def plan_for(self, values: Mapping[str, Any]) -> Optional[PathMsg]:
        """The plan published with these diagnostics (same stamp), or None on failure."""
        if values['status'] != 'ok':
            return None
        stamp_ns = values['_stamp']
        return self.plans.wait_for(lambda m: conv.time_to_ns(m.header.stamp) == stamp_ns,
                                   5.0, what='the plan of the diagnostics')

    def wait_obstacle_count(self, count: int, after: int = 0,
                            timeout_s: float = 10.0) -> MarkerArray:
        """Wait until ``planner_markers`` (after ``after``) shows ``count`` obstacles."""
        def shown(markers: MarkerArray) -> bool:
            return sum(m.ns == 'obstacles' for m in markers.markers) == count
        return self.markers.wait_for(shown, timeout_s, after, f'{count} obstacles in use')

    def set_obstacles(self, msg: MarkerArray, expected_obstacles: int) -> None:
        """Publish markers; return once the node shows that many obstacles."""
        mark = self.markers.mark()
        self.publish('obstacles', msg)
        self.wait_obstacle_count(expected_obstacles, mark)


@contextmanager
def planner_session(namespace: str, parameters: Optional[Mapping[str, Any]] = None,
                    domain_id: Optional[int] = None) -> Iterator[PlannerClient]:
    """One planner node (waited for) and a client of it recording ``/diagnostics``.

    The client is closed and the node killed on leaving.

    Parameters
    ----------
    namespace : str
    parameters : mapping, optional
        The node's ``-p`` values.
    domain_id : int, optional
        Its ROS domain; a free one by default.
    """
    domain_id = unique_domain_id() if domain_id is None else domain_id
    process = start_planner(domain_id, namespace=namespace, parameters=parameters)
    client = RosClient(domain_id)
    try:
        yield PlannerClient(client, namespace, client.record(DiagnosticArray, '/diagnostics'),
                            process)
    finally:
        client.close()
        process.kill()


@contextmanager
def in_process_planner(parameter_overrides: Optional[List[Parameter]] = None
                       ) -> Iterator['PlannerNode']:
    """A planner node in this process, in a context of its own on a free domain (no signal
    handlers); closed, and the context shut down, on leaving.

    Parameters
    ----------
    parameter_overrides : list of rclpy.parameter.Parameter, optional
        Values the node starts with instead of its defaults.
    """
    from uav_global_planner.ros.planner_node import PlannerNode
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=unique_domain_id(),
               signal_handler_options=SignalHandlerOptions.NO)
    node = None
    try:
        node = PlannerNode(context=context, parameter_overrides=parameter_overrides)
        yield node
    finally:
        if node is not None:
            node.close()
        rclpy.try_shutdown(context=context)


def assert_start_file_refused(planner: PlannerClient, setting: str, file: Path,
                              reason: str) -> None:
    """A node started with an unusable file in ``setting`` (``map_file``, ``terrain_file``)
    runs on without it: its log and map status name the file and the reason, it has no map,
    and a goal is refused with the same words."""
    line = planner.process.wait_for_output(f'refused {setting}: ', 1.0)
    assert f'{file}: {reason}' in line, line
    status = planner.wait_diag(0, 'map_status')
    error = int.from_bytes(DiagnosticStatus.ERROR, 'little')
    assert status['_level'] == error and status['status'] == 'no_map', status
    assert status[f'{setting}_status'] == 'refused', status
    assert f'{file}: {reason}' in status[f'{setting}_refused'], status
    mark = planner.diagnostics.mark()
    planner.publish('goal_pose', conv.pose_stamped([0.0, 5.0, 2.0], 'map', 0))
    refused = planner.wait_diag(mark, 'plan')
    assert refused['status'] == 'no_map' and refused['_level'] == error, refused
    assert f'{setting} refused: ' in refused['message'], refused
    assert reason in refused['message'], refused
