"""The ``/diagnostics`` publisher of the planner node: a part every other part reports through.

Every status of the node (plans, refusals, withdrawals, the map status) goes out through
:meth:`NodeDiagnostics.publish`, from any thread; a refused message is logged and reported by
:meth:`NodeDiagnostics.refuse`.
"""

import threading
from typing import Dict, Mapping

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.node import Node

from uav_global_planner.core.status import NAV2_UNKNOWN
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.geofence_source import describe
from uav_global_planner.ros.node_plan_inputs import PlanningInputs
from uav_global_planner.ros.parameters import NodeSettings
from uav_global_planner.ros.qos import DIAGNOSTICS_QOS


class NodeDiagnostics:
    """The node's ``/diagnostics`` publisher: every part reports through it (any thread).

    Its lock, ``_publisher_lock``, guards the publisher (the executor, the intake and the worker
    publish); no other lock is taken while it is held.

    Parameters
    ----------
    node : rclpy.node.Node
        Gets the ``/diagnostics`` publisher.
    inputs : PlanningInputs
        The geofence in force and the settings, reported with a status.
    """

    def __init__(self, node: Node, inputs: PlanningInputs) -> None:
        self._node = node
        self._log = node.get_logger()
        self._inputs = inputs
        self._name = f'{node.get_fully_qualified_name()}: global planner'
        self._publisher_lock = threading.Lock()
        self._publisher = node.create_publisher(DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)

    def now_ns(self) -> int:
        """The node's clock [ns]."""
        return self._node.get_clock().now().nanoseconds

    def publish(self, stamp_ns: int, level: bytes, message: str,
                values: Mapping[str, object]) -> None:
        """Publish one status of this node on ``/diagnostics`` (any thread)."""
        msg = conv.diagnostic_array(stamp_ns, self._name, 'uav_global_planner', level,
                                    message, values)
        with self._publisher_lock:
            self._publisher.publish(msg)

    def settings_values(self, settings: NodeSettings) -> Dict[str, object]:
        """The settings reported with a status."""
        config = settings.config
        return {'algorithm': config.algorithm, 'resolution_m': config.resolution,
                'safety_margin_m': config.safety_margin,
                'adaptive_threshold_m': config.adaptive_threshold,
                'climb_weight': config.climb_weight, 'descent_weight': config.descent_weight,
                'geofence': describe(self._inputs.airspace(), settings.geofence_file),
                'frame_id': settings.frame_id}

    def refuse(self, topic: str, error: Exception, throttle: bool = False) -> None:
        """Log a refused message and report it on /diagnostics; the previous state stays."""
        code = getattr(error, 'code', NAV2_UNKNOWN)
        text = f'refused message on {topic}: {error}'
        if throttle:
            # Odometry arrives at sensor rate; one log line per second is enough.
            self._log.warning(text, throttle_duration_sec=1.0)
        else:
            self._log.warning(text)
        settings = self._inputs.current_settings()
        values = {'event': 'input_rejected', 'status': 'rejected', 'status_code': code,
                  'topic': topic, 'reason': str(error)}
        values.update(self.settings_values(settings))
        self.publish(self.now_ns(), DiagnosticStatus.WARN, text, values)
