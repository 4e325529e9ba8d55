"""An rclpy node in a context of its own, spun on a background thread.

The planner's clients (the demo and the ROS benchmark of ``uav_global_planner_tools``) and the
tests talk to ``planner_node`` from a process that also does other work: each holds one of these,
so its subscriptions and parameter calls are served while the main thread waits on results. A
context of its own fixes the ROS domain per client and leaves the global context alone.
"""

import threading
from typing import Optional

import rclpy
from rclpy.executors import ExternalShutdownException, ShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions


class BackgroundNode:
    """Owns a context, a node in it, and a thread that spins the node until :meth:`close`.

    Parameters
    ----------
    name : str
        Node name.
    domain_id : int
        ROS domain of the context.
    namespace : str, optional
        Namespace of the node; relative topic names resolve in it.

    Attributes
    ----------
    node : rclpy.node.Node
        Create subscriptions, publishers and clients on it, before or after construction.
    """

    def __init__(self, name: str, domain_id: int, namespace: Optional[str] = None) -> None:
        self.context = rclpy.Context()
        # No signal handlers: the owner decides what SIGINT means for its process.
        rclpy.init(context=self.context, domain_id=domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        self.node: Node = rclpy.create_node(name, namespace=namespace, context=self.context)
        self._executor = SingleThreadedExecutor(context=self.context)
        self._executor.add_node(self.node)
        self._closing = False
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        try:
            self._executor.spin()
        except (ExternalShutdownException, ShutdownException):
            pass
        except Exception:  # noqa: BLE001 - handles released while closing
            if not self._closing:
                raise

    def close(self) -> None:
        """Stop spinning, then release the node and the context.

        The spin thread is joined before the node is destroyed: destroying it while the executor
        still waits on its guard conditions raises ``InvalidHandle`` in that thread.
        """
        self._closing = True
        self._executor.shutdown(timeout_sec=2.0)
        self._thread.join(5.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self._thread.join(5.0)
