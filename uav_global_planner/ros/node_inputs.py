"""Goal and start inputs of the planner node, and the report of a refused message.

A mixin of :class:`~uav_global_planner.ros.planner_node.PlannerNode`, run on the executor:
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

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.status import NAV2_GOAL_OUTSIDE_MAP, NAV2_UNKNOWN
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.node_attributes import NodeAttributes
from uav_global_planner.ros.node_state import Goal
from uav_global_planner.ros.parameters import MAP_SOURCES, NodeSettings
from uav_global_planner.ros.start_source import StartSource
from uav_global_planner.ros.takeover import odometry_velocity

#: Diagnostics status of a goal refused because the map is missing.
NO_MAP_STATUS = 'no_map'


class CommandInputs(NodeAttributes):
    """Goal and start callbacks; write ``_goal`` and ``_start`` (under ``_wake``)."""

    def _map_missing(self, settings: NodeSettings) -> Optional[str]:
        """Why goals cannot be planned yet for want of a map, or None (caller holds _wake)."""
        refusal = self.map_refusal()
        if refusal:
            # Read once at start-up: planning without the map asked for would fly through it.
            return refusal
        if settings.plan_without_map:
            return None
        sources = self._sources
        if settings.required_map_sources == ('any',):
            if any(sources[name].delivered for name in MAP_SOURCES):
                return None
            refused = [f'{name} refused ({state.last_refusal})'
                       for name, state in sources.items() if state.refused]
            return ('no map yet: none of the map sources (obstacles, obstacle_cloud, map_file) '
                    'has delivered' + (': ' + '; '.join(refused) if refused else '')
                    + '; publish the map first, or set plan_without_map to plan in open air')
        missing = [name for name in settings.required_map_sources
                   if not sources[name].delivered]
        if not missing:
            return None
        return (f'no map yet: required_map_sources {", ".join(missing)} not delivered; publish '
                'them first, or set plan_without_map to plan in open air')

    def _on_goal(self, msg: PoseStamped) -> None:
        topic = self._goal_sub.topic_name
        settings = self._current_settings()
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
            self._refuse(topic, error)
            return
        with self._wake:
            missing = self._map_missing(settings)
            if missing is None:
                self._goal_serial += 1
                self._goal = Goal(position, orientation, self._goal_serial)
                self._goal_changed = True
                self._wake.notify_all()
        if missing is not None:
            self._refuse_goal(position, settings, missing)

    def _refuse_goal(self, position: np.ndarray, settings: NodeSettings, reason: str) -> None:
        """A goal the node will not plan (no map yet): an ERROR plan status with the reason."""
        text = f'goal {position.tolist()} refused: {reason}'
        self._log.warning(text)
        values = {'event': 'plan', 'status': NO_MAP_STATUS, 'status_code': NAV2_UNKNOWN,
                  'reason': 'new goal', 'message': text, 'goal': position}
        values.update(self._settings_values(settings))
        values.update(self._map_values())
        self._publish_diagnostics(self.node.get_clock().now().nanoseconds,
                                  DiagnosticStatus.ERROR, f'{NO_MAP_STATUS}: {text}', values)

    def _on_odom(self, msg: Odometry) -> None:
        topic = self._odom_sub.topic_name
        frame = self._current_settings().frame_id
        try:
            position = conv.odometry_to_point(msg, frame, topic)
        except InvalidInputError as error:
            self._refuse(topic, error, throttle=True)
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
        self._set_start(position, StartSource.ODOM)

    def _on_start_pose(self, msg: PoseStamped) -> None:
        topic = self._start_sub.topic_name
        try:
            position = conv.pose_stamped_to_point(msg, self._current_settings().frame_id,
                                                  topic)
        except InvalidInputError as error:
            self._refuse(topic, error)
            return
        self._set_start(position, StartSource.START_POSE)

    def _set_start(self, position: np.ndarray, source: StartSource) -> None:
        with self._wake:
            self._start, self._start_source = position, source
            if self._in_force_source == StartSource.PARAMETER and self._goal is not None:
                # The plan in force began at the start parameter, not where the vehicle is.
                self._in_force_source = None
                self._replan_request = (f'the vehicle position arrived on {source}; the plan '
                                        'in force started at the start parameter')
                self._wake.notify_all()

    def _refuse(self, topic: str, error: Exception, throttle: bool = False) -> None:
        """Log a refused message and report it on /diagnostics; the previous state stays."""
        code = getattr(error, 'code', NAV2_UNKNOWN)
        text = f'refused message on {topic}: {error}'
        if throttle:
            # Odometry arrives at sensor rate; one log line per second is enough.
            self._log.warning(text, throttle_duration_sec=1.0)
        else:
            self._log.warning(text)
        settings = self._current_settings()
        values = {'event': 'input_rejected', 'status': 'rejected', 'status_code': code,
                  'topic': topic, 'reason': str(error)}
        values.update(self._settings_values(settings))
        self._publish_diagnostics(self.node.get_clock().now().nanoseconds,
                                  DiagnosticStatus.WARN, text, values)
