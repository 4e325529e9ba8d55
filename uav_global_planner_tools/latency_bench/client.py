"""The benchmark's side of the conversation: an rclpy node that talks to the planner over DDS.

Its own context, spun on a background thread (:class:`~uav_global_planner.ros.background_node.
BackgroundNode`), so that the main thread can wait on the answers while the messages come in;
each message is kept with its arrival time.
"""

import threading
import time
from typing import Any, Callable, Dict, List, Optional

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path as PathMsg
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import PointCloud2
from visualization_msgs.msg import MarkerArray

from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.background_node import BackgroundNode
from uav_global_planner.ros.names import NODE_NAME
from uav_global_planner.ros.qos import COMMAND_QOS, LATCHED_QOS, MONITOR_QOS


class BenchError(RuntimeError):
    """The node did not start or did not answer in time."""


class Inbox:
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


class BenchClient:
    """The benchmark's rclpy node, in its own context, spun on a background thread.

    Parameters
    ----------
    domain_id : int
    namespace : str
        Namespace of the planner node; the client's topics are resolved in it.
    """

    def __init__(self, domain_id: int, namespace: str) -> None:
        self.namespace = namespace
        self.node_fqn = f'{namespace}/{NODE_NAME}'
        self._background = BackgroundNode('uav_latency_bench', domain_id, namespace)
        self.node = self._background.node
        self.changed = threading.Condition()
        # Raw, to time the arrival of the bytes and the Python deserialisation apart.
        self.plans = Inbox(self.changed, PathMsg)
        self.diagnostics = Inbox(self.changed)
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
