"""The status timers of the planner node: a part of the node.

:class:`NodeStatus` runs the timers: the map status on ``/diagnostics`` (1 Hz, through
:class:`~uav_global_planner.ros.node_diagnostics.NodeDiagnostics`), the obstacle markers on
``planner_markers`` (only when someone subscribes) and the report of another node of the same
name.
"""

from typing import Dict, Optional, Tuple

from diagnostic_msgs.msg import DiagnosticStatus
import numpy as np
from rclpy.node import Node
from visualization_msgs.msg import MarkerArray

from uav_global_planner.core.io.mapfiles import MapPoints
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.node_diagnostics import NodeDiagnostics
from uav_global_planner.ros.node_intake import MapIntake
from uav_global_planner.ros.node_plan_inputs import PlanningInputs
from uav_global_planner.ros.qos import LATCHED_QOS
from uav_global_planner.ros.terrain_source import terrain_values

#: Marker-publishing check period [s]: markers go out only when someone subscribes.
_MARKER_PERIOD_S = 0.5

#: Period of the ``map_status`` diagnostics [s] (as diagnostic_updater's 1 Hz).
_MAP_STATUS_PERIOD_S = 1.0

#: Period of the check for another node of the same fully qualified name [s].
_DUPLICATE_CHECK_PERIOD_S = 2.0


class NodeStatus:
    """The status timers: map status, obstacle markers, another node of the same name.

    No lock: its state (the markers last published, the duplicates last reported) belongs to
    the executor, which runs the timers (and :meth:`check_duplicate_name` at start-up, before
    spinning).

    Parameters
    ----------
    node : rclpy.node.Node
        Gets the ``planner_markers`` publisher and the timers.
    inputs : PlanningInputs
    intake : MapIntake
    diagnostics : NodeDiagnostics
    prior : MapPoints, optional
        The map_file read at start-up (None: none, or refused).
    """

    def __init__(self, node: Node, inputs: PlanningInputs, intake: MapIntake,
                 diagnostics: NodeDiagnostics, prior: Optional[MapPoints]) -> None:
        self._node = node
        self._log = node.get_logger()
        self._inputs = inputs
        self._intake = intake
        self._diagnostics = diagnostics
        self._prior = prior
        self._markers_published_key: Optional[Tuple[object, ...]] = None
        self._duplicates_reported = 0
        self._markers_pub = node.create_publisher(MarkerArray, 'planner_markers', LATCHED_QOS)
        self._marker_timer = node.create_timer(_MARKER_PERIOD_S, self._publish_markers)
        self._status_timer = node.create_timer(_MAP_STATUS_PERIOD_S, self.publish_map_status)
        self._duplicate_timer = node.create_timer(_DUPLICATE_CHECK_PERIOD_S,
                                                  self.check_duplicate_name)

    def _prior_map_values(self) -> Dict[str, object]:
        """What the ``map_file`` load read, dropped (and why) and kept, and its extent; or why
        the file was refused (empty when there is no map_file)."""
        if self._intake.prior_refusal:
            return {'map_file_status': 'refused', 'map_file_refused': self._intake.prior_refusal}
        if self._prior is None:
            return {}
        values: Dict[str, object] = {'map_file_status': 'ok'}
        for report in self._prior.reports:
            values.update({
                'map_file': report.file, 'map_file_format': report.format,
                'map_file_points_read': report.points_read,
                'map_file_dropped_non_finite': report.dropped_non_finite,
                'map_file_dropped_downsampled': report.dropped_downsampled,
                'map_file_outside_bounds': report.outside_bounds,
                'map_file_points_kept': report.points_kept,
                'map_file_extent_min': np.array(report.extent_min or (np.nan,) * 3),
                'map_file_extent_max': np.array(report.extent_max or (np.nan,) * 3),
                'map_file_resolution_m': (np.nan if report.resolution_m is None
                                          else report.resolution_m),
                'map_file_downsample_m': report.downsample_m or 0.0,
                'map_file_margin_m': report.margin_m,
                'map_file_report': report.summary()})
        return values

    def _publish_markers(self) -> None:
        """Timer: publish the obstacles in use when they changed and someone listens."""
        live, settings = self._inputs.newest_map(), self._inputs.current_settings()
        key = (live.version, settings.config.safety_margin, settings.frame_id)
        if key == self._markers_published_key:
            return
        # Building a large marker array is wasted work when nobody looks.
        if self._markers_pub.get_subscription_count() == 0:
            return
        self._markers_pub.publish(conv.obstacle_markers(
            live.obstacles, settings.frame_id, self._diagnostics.now_ns(),
            settings.config.safety_margin))
        self._markers_published_key = key

    def publish_map_status(self) -> None:
        """Timer: the map's state on /diagnostics (``event: map_status``), WARN while goals
        are refused for want of a map or a source's newest message was refused."""
        settings = self._inputs.current_settings()
        missing = self._intake.map_missing(settings)
        sources = self._intake.sources()
        live = self._inputs.newest_map()
        (intake_s, index_s, mask_s), latencies = self._intake.take_statistics()
        values = self._intake.map_values(live)
        if latencies:
            # Cloud stamp to its map in the planner's hands, over the last period [s].
            values['cloud_latency_count'] = len(latencies)
            values['cloud_latency_p50_s'] = float(np.percentile(latencies, 50))
            values['cloud_latency_max_s'] = float(np.max(latencies))
            values['cloud_latencies_s'] = ' '.join(f'{v:.4f}' for v in latencies)
        for name, state in sources.items():
            values[f'{name}_received'] = state.received
            values[f'{name}_accepted'] = state.accepted
            values[f'{name}_refused'] = state.refused
            values[f'{name}_stamp'] = state.last_stamp_ns
        values['obstacle_cloud_superseded'] = sources['obstacle_cloud'].superseded
        values.update({'event': 'map_status', 'status': 'no_map' if missing else 'ok',
                       'obstacles': len(live.obstacles), 'points': len(live.obstacles.points),
                       'last_update_s': intake_s, 'last_index_s': index_s,
                       'last_mask_s': mask_s, 'last_mask_full': live.update.full,
                       'last_mask_tiles': live.update.tiles,
                       'fallback_grid_kept': live.fallback is not None})
        values.update(self._diagnostics.settings_values(settings))
        values.update(self._prior_map_values())
        values.update(terrain_values(self._inputs.terrain()))
        if self._inputs.map_refusal():
            level, text = DiagnosticStatus.ERROR, str(missing)
        elif missing:
            level, text = DiagnosticStatus.WARN, missing
        elif values['map_refused']:
            level, text = DiagnosticStatus.WARN, f'map incomplete: {values["map_refused"]}'
        else:
            level, text = DiagnosticStatus.OK, f'map version {live.version}'
        self._diagnostics.publish(self._diagnostics.now_ns(), level, text, values)

    def check_duplicate_name(self) -> None:
        """Timer (and start-up): another node with this fully qualified name is an error: two
        planners would latch competing plans on the same topics."""
        node = self._node
        name, namespace = node.get_name(), node.get_namespace()
        try:
            count = sum(1 for other, space in node.get_node_names_and_namespaces()
                        if other == name and space == namespace)
        except Exception:  # noqa: BLE001 - the graph is gone during shutdown
            return
        if count <= 1:
            if self._duplicates_reported:
                self._log.info(f'the other node named {node.get_fully_qualified_name()} is '
                               'gone')
                self._duplicates_reported = 0
            return
        text = (f'{count - 1} other node(s) named {node.get_fully_qualified_name()} are '
                'running: their plans, trajectories and diagnostics mix with these on the same '
                'topics; stop them or start this one in another namespace '
                '(--ros-args -r __ns:=/uav2) or under another name (-r __node:=...)')
        self._log.error(text)
        self._duplicates_reported = count
        values = {'event': 'duplicate_node', 'status': 'duplicate', 'nodes_with_this_name': count,
                  'node': node.get_fully_qualified_name(), 'message': text}
        self._diagnostics.publish(node.get_clock().now().nanoseconds, DiagnosticStatus.ERROR,
                                  text, values)
