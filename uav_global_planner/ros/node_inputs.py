"""Goal and start inputs of the planner node: a part of the node, run on the executor.

``goal_pose`` sets the active goal (refused while the map is missing), ``odom`` and
``start_pose`` the start (the twist and heading of ``odom`` also go to the takeover predictor,
for replans in flight); a refused message keeps the previous state and is reported on the
log and ``/diagnostics``.
"""

from typing import Optional

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
import numpy as np
from rclpy.node import Node

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.status import NAV2_GOAL_OUTSIDE_MAP, NAV2_UNKNOWN
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.node_diagnostics import NodeDiagnostics
from uav_global_planner.ros.node_intake import MapIntake
from uav_global_planner.ros.node_plan_inputs import PlanningInputs
from uav_global_planner.ros.parameters import NodeSettings
from uav_global_planner.ros.qos import COMMAND_QOS, SENSOR_QOS
from uav_global_planner.ros.start_source import StartSource
from uav_global_planner.ros.takeover import odometry_velocity, TakeoverPredictor

#: Diagnostics status of a goal refused because the map is missing.
NO_MAP_STATUS = 'no_map'

#: How long a goal waits for map messages received before it to be applied (at start-up the
#: intake may still be building the first map) [s].
_PENDING_MAP_WAIT_S = 5.0


class CommandInputs:
    """The ``goal_pose``, ``odom`` and ``start_pose`` subscriptions.

    No state and no lock of its own: an accepted goal or position goes to the planning inputs
    (their condition guards it), odometry's motion to the takeover predictor (its own lock).

    Parameters
    ----------
    node : rclpy.node.Node
        Gets the subscriptions.
    inputs : PlanningInputs
    intake : MapIntake
        Whether the map goals need has arrived.
    diagnostics : NodeDiagnostics
    takeover : TakeoverPredictor
    """

    def __init__(self, node: Node, inputs: PlanningInputs, intake: MapIntake,
                 diagnostics: NodeDiagnostics, takeover: TakeoverPredictor) -> None:
        self._node = node
        self._log = node.get_logger()
        self._inputs = inputs
        self._intake = intake
        self._diagnostics = diagnostics
        self._takeover = takeover
        self._goal_sub = node.create_subscription(PoseStamped, 'goal_pose', self.on_goal,
                                                  COMMAND_QOS)
        self._odom_sub = node.create_subscription(Odometry, 'odom', self._on_odom, SENSOR_QOS)
        self._start_sub = node.create_subscription(PoseStamped, 'start_pose',
                                                   self._on_start_pose, COMMAND_QOS)

    @property
    def goal_topic(self) -> str:
        """The resolved name of the goal topic."""
        return self._goal_sub.topic_name

    def on_goal(self, msg: PoseStamped) -> None:
        """A goal (executor; in-process use and tests may call it directly)."""
        topic = self._goal_sub.topic_name
        settings = self._inputs.current_settings()
        try:
            position, orientation = conv.pose_stamped_to_pose(msg, settings.frame_id, topic)
            config = settings.config
            tol = 1e-9 * config.resolution
            if (np.any(position < np.asarray(config.bounds_min) - tol)
                    or np.any(position > np.asarray(config.bounds_max) + tol)):
                raise conv.InputRejected(
                    f'goal {position.tolist()} is outside the bounds '
                    f'{list(config.bounds_min)} .. {list(config.bounds_max)}',
                    NAV2_GOAL_OUTSIDE_MAP)
        except InvalidInputError as error:
            self._diagnostics.refuse(topic, error)
            return
        # The sources count as delivered only once the map holding them is installed, so an
        # accepted goal is planned on that map. A map received just before the goal (both
        # queued while the node started) is waited for, not taken for no map.
        missing = self._intake.map_missing(settings)
        if missing is not None:
            self._intake.wait_for_pending_maps(_PENDING_MAP_WAIT_S)
            missing = self._intake.map_missing(settings)
        if missing is None:
            self._inputs.new_goal(position, orientation)
        else:
            self._refuse_goal(position, settings, missing)

    def _refuse_goal(self, position: np.ndarray, settings: NodeSettings, reason: str) -> None:
        """A goal the node will not plan (no map yet): an ERROR plan status with the reason."""
        text = f'goal {position.tolist()} refused: {reason}'
        self._log.warning(text)
        values = {'event': 'plan', 'status': NO_MAP_STATUS, 'status_code': NAV2_UNKNOWN,
                  'reason': 'new goal', 'message': text, 'goal': position}
        values.update(self._diagnostics.settings_values(settings))
        values.update(self._intake.map_values())
        self._diagnostics.publish(self._node.get_clock().now().nanoseconds,
                                  DiagnosticStatus.ERROR, f'{NO_MAP_STATUS}: {text}', values)

    def _on_odom(self, msg: Odometry) -> None:
        topic = self._odom_sub.topic_name
        frame = self._inputs.current_settings().frame_id
        try:
            position = conv.odometry_to_point(msg, frame, topic)
        except InvalidInputError as error:
            self._diagnostics.refuse(topic, error, throttle=True)
            return
        # The twist and heading feed replans in flight (ros/takeover.py); a non-finite twist
        # only leaves the velocity unknown.
        try:
            velocity: Optional[np.ndarray] = odometry_velocity(msg, frame, topic)
        except InvalidInputError:
            velocity = None
        try:
            yaw = conv.quaternion_yaw(conv.quaternion_to_array(msg.pose.pose.orientation, topic))
        except InvalidInputError:
            yaw = 0.0
        self._takeover.on_odometry(position, velocity, yaw)
        self._inputs.set_vehicle(position, StartSource.ODOM)

    def _on_start_pose(self, msg: PoseStamped) -> None:
        topic = self._start_sub.topic_name
        try:
            position = conv.pose_stamped_to_point(msg, self._inputs.current_settings().frame_id,
                                                  topic)
        except InvalidInputError as error:
            self._diagnostics.refuse(topic, error)
            return
        self._inputs.set_vehicle(position, StartSource.START_POSE)
