"""Diagnostics and status publishing of the planner node.

A mixin of :class:`~uav_global_planner.ros.planner_node.PlannerNode`: every status goes out on
``/diagnostics`` through :meth:`StatusPublishing._publish_diagnostics` (any thread); the timers
publish the map status (1 Hz), the obstacle markers (only when someone subscribes) and report
another node of the same name.
"""

from dataclasses import replace
from typing import Dict, Mapping, Optional

from diagnostic_msgs.msg import DiagnosticStatus
import numpy as np

from uav_global_planner.core.map.live_map import LiveMap
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.geofence_source import describe
from uav_global_planner.ros.node_attributes import NodeAttributes
from uav_global_planner.ros.parameters import NodeSettings
from uav_global_planner.ros.terrain_source import terrain_values


class StatusPublishing(NodeAttributes):
    """Diagnostics, markers and map status; own ``_markers_published_key``."""

    def _settings_values(self, settings: NodeSettings) -> Dict[str, object]:
        config = settings.config
        return {'algorithm': config.algorithm, 'resolution_m': config.resolution,
                'safety_margin_m': config.safety_margin,
                'adaptive_threshold_m': config.adaptive_threshold,
                'climb_weight': config.climb_weight, 'descent_weight': config.descent_weight,
                'geofence': describe(self._airspace, settings.geofence_file),
                'frame_id': settings.frame_id}

    def _map_values(self, live: Optional[LiveMap] = None) -> Dict[str, object]:
        """What each map source delivered, which ones' newest message was refused, and the
        age of the newest map message [s] (any thread)."""
        with self._wake:
            sources = {name: replace(state) for name, state in self._sources.items()}
            map_stamp = self._map_stamp_ns
            live = self._map if live is None else live
        refused = [f'{name} ({state.last_refusal})' for name, state in sources.items()
                   if state.refused_last]
        values: Dict[str, object] = {
            'map_sources': '; '.join(f'{name}: {state.summary()}'
                                     for name, state in sources.items()
                                     if name != 'map_file' or state.received),
            'map_refused': '; '.join(refused),
            'map_version': live.version,
        }
        if map_stamp > 0:
            values['map_age_s'] = max(
                (self.node.get_clock().now().nanoseconds - map_stamp) * 1e-9, 0.0)
        return values

    def _prior_map_values(self) -> Dict[str, object]:
        """What the ``map_file`` load read, dropped (and why) and kept, and its extent; or why
        the file was refused (empty when there is no map_file)."""
        if self._prior_refusal:
            return {'map_file_status': 'refused', 'map_file_refused': self._prior_refusal}
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

    def _publish_diagnostics(self, stamp_ns: int, level: bytes, message: str,
                             values: Mapping[str, object]) -> None:
        msg = conv.diagnostic_array(stamp_ns, self._diag_name, 'uav_global_planner', level,
                                    message, values)
        # The executor thread (refusals), the intake (withdrawals) and the worker (plans)
        # publish here.
        with self._diagnostics_lock:
            self._diagnostics_pub.publish(msg)

    def publish_diagnostics(self, stamp_ns: int, level: bytes, message: str,
                            values: Mapping[str, object]) -> None:
        """Publish one status of this node on ``/diagnostics`` (any thread)."""
        self._publish_diagnostics(stamp_ns, level, message, values)

    def _publish_markers(self) -> None:
        """Timer: publish the obstacles in use when they changed and someone listens."""
        with self._wake:
            live, settings = self._map, self._settings
        key = (live.version, settings.config.safety_margin, settings.frame_id)
        if key == self._markers_published_key:
            return
        # Building a large marker array is wasted work when nobody looks.
        if self._markers_pub.get_subscription_count() == 0:
            return
        self._markers_pub.publish(conv.obstacle_markers(
            live.obstacles, settings.frame_id, self.node.get_clock().now().nanoseconds,
            settings.config.safety_margin))
        self._markers_published_key = key

    def _publish_map_status(self) -> None:
        """Timer: the map's state on /diagnostics (``event: map_status``), WARN while goals
        are refused for want of a map or a source's newest message was refused."""
        settings = self._current_settings()
        with self._wake:
            missing = self._map_missing(settings)
            sources = {name: replace(state) for name, state in self._sources.items()}
            live = self._map
            intake_s, index_s, mask_s = self._intake_times
            latencies, self._cloud_latencies = self._cloud_latencies, []
        values = self._map_values(live)
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
        values.update(self._settings_values(settings))
        values.update(self._prior_map_values())
        values.update(terrain_values(self._terrain_state))
        if self.map_refusal():
            level, text = DiagnosticStatus.ERROR, str(missing)
        elif missing:
            level, text = DiagnosticStatus.WARN, missing
        elif values['map_refused']:
            level, text = DiagnosticStatus.WARN, f'map incomplete: {values["map_refused"]}'
        else:
            level, text = DiagnosticStatus.OK, f'map version {live.version}'
        self._publish_diagnostics(self.node.get_clock().now().nanoseconds, level, text, values)

    def _check_duplicate_name(self) -> None:
        """Timer (and start-up): another node with this fully qualified name is an error: two
        planners would latch competing plans on the same topics."""
        node = self.node
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
        self._publish_diagnostics(node.get_clock().now().nanoseconds, DiagnosticStatus.ERROR,
                                  text, values)
