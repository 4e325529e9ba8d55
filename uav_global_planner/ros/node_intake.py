"""The map intake of the planner node: map messages to the map the worker plans on.

A mixin of :class:`~uav_global_planner.ros.planner_node.PlannerNode`. The executor only queues
the serialised map messages (markers in order, clouds latest-wins); the intake thread
(:meth:`MapIntake._run_intake`) deserialises, checks and indexes them, updates the inflated
grid (:class:`~uav_global_planner.core.map.live_map.LiveMapBuilder`), has the plan in force
re-checked against the new map before the worker sees it, and counts what each source
delivered.
"""

import time
import traceback
from typing import Any, List, Optional, Tuple

from rclpy.serialization import deserialize_message
from sensor_msgs.msg import PointCloud2
from visualization_msgs.msg import MarkerArray

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.airspace import Airspace
from uav_global_planner.core.map.live_map import UNCHANGED
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.geofence_source import geofence_shapes
from uav_global_planner.ros.ground_source import ground_key, ground_shapes
from uav_global_planner.ros.node_attributes import NodeAttributes
from uav_global_planner.ros.node_state import InForce
from uav_global_planner.ros.parameters import NodeSettings


class MapIntake(NodeAttributes):
    """Map topics and the intake thread; own ``_inbox`` and ``_intake_*``, write ``_map``."""

    def _on_obstacles_raw(self, data: bytes) -> None:
        """Executor: queue a serialised MarkerArray for the intake (all of them, in order:
        incremental arrays build the map together)."""
        with self._wake:
            self._sources['obstacles'].received += 1
        with self._intake_cv:
            self._inbox.markers.append((data, time.monotonic_ns()))
            self._intake_cv.notify_all()

    def _on_cloud_raw(self, data: bytes) -> None:
        """Executor: keep the newest serialised cloud for the intake; an older one it had no
        time for is dropped (the latest cloud wins)."""
        with self._intake_cv:
            dropped = self._inbox.cloud is not None
            self._inbox.cloud = (data, time.monotonic_ns())
            self._intake_cv.notify_all()
        with self._wake:
            state = self._sources['obstacle_cloud']
            state.received += 1
            state.superseded += int(dropped)

    def _on_obstacles(self, msg: MarkerArray) -> None:
        """Apply one MarkerArray at once, on the calling thread (in-process use and tests; the
        subscription goes through the intake thread)."""
        self._intake_step([msg], None, False)

    def _on_cloud(self, msg: PointCloud2) -> None:
        """Apply one cloud at once, on the calling thread (see :meth:`_on_obstacles`)."""
        self._intake_step([], msg, False)

    def _run_intake(self) -> None:
        """Map intake thread: deserialise, check, index and inflate; publish; re-check."""
        while True:
            with self._intake_cv:
                self._intake_cv.wait_for(
                    lambda: self._inbox.stopping or bool(self._inbox.markers)
                    or self._inbox.cloud is not None or self._inbox.reconfigure
                    or self._inbox.airspace is not None)
                if self._inbox.stopping:
                    return
                markers = list(self._inbox.markers)
                self._inbox.markers.clear()
                # Markers first, on their own: a shape dropped on the plan in force must not
                # wait for a large cloud to be indexed (the cloud is taken next time round,
                # unless a newer one has replaced it by then).
                cloud = None
                if not markers:
                    cloud, self._inbox.cloud = self._inbox.cloud, None
                reconfigure, self._inbox.reconfigure = self._inbox.reconfigure, False
                frame_reset, self._inbox.frame_reset = self._inbox.frame_reset, False
                airspace, self._inbox.airspace = self._inbox.airspace, None
                airspace_serial = self._inbox.airspace_serial
            try:
                messages = [self._deserialize(data, MarkerArray, 'obstacles')
                            for data, _ in markers]
                cloud_msg = (None if cloud is None
                             else self._deserialize(cloud[0], PointCloud2, 'obstacle_cloud'))
                self._intake_step([m for m in messages if m is not None], cloud_msg,
                                  reconfigure, airspace, frame_reset)
            except Exception as error:  # noqa: BLE001 - a bug must not stop the intake
                if self._is_stopping():
                    return
                self._log.error(f'map intake failed: {error!r}\n{traceback.format_exc()}')
            finally:
                if airspace is not None or reconfigure:
                    # The step built the map from the settings and geofence in force, so
                    # every shapes request up to this serial is in it.
                    with self._wake:
                        self._geofence_applied = max(self._geofence_applied, airspace_serial)
                        self._wake.notify_all()

    def _deserialize(self, data: bytes, msg_type: Any, source: str) -> Optional[Any]:
        try:
            return deserialize_message(data, msg_type)
        except Exception as error:  # noqa: BLE001 - a malformed message is refused
            topic = (self._obstacles_sub if source == 'obstacles' else self._cloud_sub).topic_name
            self._refuse_map(source, topic, InvalidInputError(
                f'{source} message could not be deserialised ({error})'))
            return None

    def _intake_step(self, marker_msgs: List[MarkerArray], cloud_msg: Optional[PointCloud2],
                     reconfigure: bool, airspace: Optional[Airspace] = None,
                     frame_reset: bool = False) -> None:
        """Apply marker arrays (in order), a cloud, new settings and a new geofence; publish
        the map they give and re-check the plan in force against it. ``frame_reset``: the
        frame changed since the last step (perhaps back again): the map is dropped."""
        settings = self._current_settings()
        frame = conv.normalize_frame(settings.frame_id)
        cloud: Any = UNCHANGED
        shapes_before = self._intake_markers
        if frame != self._intake_frame or frame_reset:
            # Markers and cloud of the old frame are gone (the executor reset the sources).
            self._intake_frame = frame
            self._intake_markers, cloud = {}, None
        markers = self._intake_markers
        stamp_ns = 0
        # Sources count as delivered only together with the map that holds their data, so a
        # goal is never accepted while the worker still has the map from before.
        accepted: List[Tuple[str, Any]] = []
        markers_topic = self._obstacles_sub.topic_name
        for msg in marker_msgs:
            try:
                updated = conv.apply_marker_array(markers, msg, settings.frame_id,
                                                  settings.max_obstacle_size)
            except InvalidInputError as error:
                self._refuse_map('obstacles', markers_topic, error)
                accepted.append(('obstacles', error))
                continue
            message_stamp = max((conv.time_to_ns(m.header.stamp) for m in msg.markers),
                                default=0)
            accepted.append(('obstacles', message_stamp))
            if not conv.same_marker_obstacles(markers, updated):
                markers = updated
                stamp_ns = max(stamp_ns, message_stamp)
        cloud_stamp = 0
        if cloud_msg is not None:
            try:
                points = conv.cloud_to_points(cloud_msg, settings.frame_id,
                                              settings.cloud_non_finite == 'drop',
                                              settings.max_cloud_points)
            except InvalidInputError as error:
                self._refuse_map('obstacle_cloud', self._cloud_sub.topic_name, error)
                accepted.append(('obstacle_cloud', error))
            else:
                cloud = points
                cloud_stamp = conv.time_to_ns(cloud_msg.header.stamp)
                accepted.append(('obstacle_cloud', cloud_stamp))
                stamp_ns = max(stamp_ns, cloud_stamp)
        shapes_changed = markers is not shapes_before
        self._intake_markers = markers
        if airspace is not None:
            self._intake_geofence = geofence_shapes(airspace)
            shapes_changed = True
        terrain = self._terrain_state
        if ground_key(settings.config, terrain) != self._ground_key:
            self._intake_ground = ground_shapes(settings.config, terrain)
            self._ground_key = ground_key(settings.config, terrain)
            shapes_changed = True
        if not (shapes_changed or cloud is not UNCHANGED or reconfigure):
            self._accept_map(accepted)
            return
        with self._wake:
            held = self._worker_map.blocked if self._worker_map is not None else None
            held_fallback = (self._worker_map.fallback if self._worker_map is not None
                             else None)
        started = time.perf_counter()
        try:
            # The cloud array is fresh from the message: handed over without a copy.
            live = self._builder.update(shapes={**markers, **self._intake_geofence,
                                                **self._intake_ground}
                                        if shapes_changed else None,
                                        cloud=cloud, config=settings.config, held=held,
                                        give_cloud=True, held_fallback=held_fallback)
        except InvalidInputError as error:  # settings that cannot make a grid (never valid)
            self._log.error(f'map update failed: {error}')
            return
        elapsed = time.perf_counter() - started
        with self._wake:
            previous = self._map
        if live is previous:
            self._accept_map(accepted)
            return
        # The plan in force is checked before the worker sees the map, so a withdrawal and the
        # request for its replacement reach the worker together with the map; the map is
        # installed under the publish lock, so no plan is released between the check and the
        # installation (PlanInForce.release certifies against the map installed).
        now_ns = self.node.get_clock().now().nanoseconds
        with self._publish_lock:
            withdrawn = (self._recheck_in_force(live) if live.version != previous.version
                         else None)
            with self._wake:
                self._map = live
                self._accept_map(accepted)
                if live.version != previous.version:
                    self._obstacles_stamp_ns = stamp_ns
                    self._map_stamp_ns = max(self._map_stamp_ns, stamp_ns)
                self._map_changed = True
                self._intake_times = (elapsed, live.index_time_s, live.update.time_s)
                if cloud is not UNCHANGED and cloud_msg is not None and cloud_stamp > 0:
                    self._cloud_latencies.append((now_ns - cloud_stamp) * 1e-9)
                self._request_replacement(withdrawn, settings)
                if airspace is not None and self._goal is not None:
                    # A new geofence replans the active goal on the map that holds it.
                    self._replan_request = self._replan_request or 'the geofence changed'
                self._wake.notify_all()

    def _request_replacement(self, withdrawn: Optional[InForce],
                             settings: NodeSettings) -> None:
        """Ask the worker to replan the active goal whose plan was withdrawn (caller holds
        _wake). A withdrawn Nav2 request's plan is not replanned: its client asks again."""
        if (withdrawn is not None and settings.replan_on_obstacle_change
                and self._goal is not None and withdrawn.goal_serial == self._goal.serial):
            self._replan_request = 'the plan in force was withdrawn: the new map makes it collide'

    def _accept_map(self, outcomes: List[Tuple[str, Any]]) -> None:
        """Replay the map messages of one intake step in order: (source, header stamp [ns])
        for an accepted one, counted now; (source, the error) for a refused one, counted when
        it was refused (so that the refusal shows at once), replayed here only for the order
        of "the newest message was refused". Re-entrant under _wake."""
        with self._wake:
            for source, outcome in outcomes:
                state = self._sources[source]
                if isinstance(outcome, Exception):
                    state.refused_last = True
                    state.last_refusal = str(outcome)
                else:
                    state.accepted += 1
                    state.refused_last = False
                    state.last_stamp_ns = int(outcome)

    def _refuse_map(self, source: str, topic: str, error: Exception) -> None:
        with self._wake:
            state = self._sources[source]
            state.refused += 1
            state.refused_last = True
            state.last_refusal = str(error)
        self._refuse(topic, error)
