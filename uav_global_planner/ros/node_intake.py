"""The map intake of the planner node: map messages to the map the worker plans on.

A part of :class:`~uav_global_planner.ros.planner_node.PlannerNode`. The executor only queues
the serialised map messages (markers in order, clouds latest-wins); the intake thread
deserialises, checks and indexes them, updates the inflated grid
(:class:`~uav_global_planner.core.map.live_map.LiveMapBuilder`), has the plan in force
re-checked against the new map before the worker sees it
(:meth:`~uav_global_planner.ros.node_in_force.PlanInForce.install_map`), and counts what each
source delivered.
"""

from dataclasses import replace
import threading
import time
import traceback
from typing import Any, Dict, Hashable, List, Mapping, Optional, Tuple

from rclpy.node import Node
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import PointCloud2
from visualization_msgs.msg import MarkerArray

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.airspace import Airspace
from uav_global_planner.core.map.live_map import LiveMap, LiveMapBuilder, UNCHANGED
from uav_global_planner.core.map.obstacles import Obstacle
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.conversions import MarkerKey
from uav_global_planner.ros.geofence_source import geofence_shapes
from uav_global_planner.ros.ground_source import ground_key, ground_shapes
from uav_global_planner.ros.node_diagnostics import NodeDiagnostics
from uav_global_planner.ros.node_in_force import PlanInForce
from uav_global_planner.ros.node_plan_inputs import PlanningInputs
from uav_global_planner.ros.node_state import Inbox, InForce, SourceState
from uav_global_planner.ros.parameters import MAP_SOURCES, NodeSettings
from uav_global_planner.ros.qos import CLOUD_QOS_BY_RELIABILITY, OBSTACLES_QOS

#: A source's outcome in one intake step: its header stamp [ns] or why it was refused.
_Outcome = Tuple[str, Any]


class MapIntake:
    """Map topics, the intake thread and what each map source delivered.

    Its condition, ``_inbox_lock``, guards the messages waiting for the intake (``_inbox``),
    the state of each map source (``_sources``) and the intake's figures (``_intake_times``,
    ``_cloud_latencies``); no other lock is taken while it is held. The map builder, the
    marker obstacles and the map's own shapes belong to the intake thread (and to the caller of
    :meth:`on_obstacles` and :meth:`on_cloud`, which run a step in-process).

    Parameters
    ----------
    node : rclpy.node.Node
        Gets the ``obstacles`` and ``obstacle_cloud`` subscriptions.
    inputs : PlanningInputs
        Where the new maps go, with the settings in force.
    in_force : PlanInForce
        Checks the plan in force against every new map before it is installed.
    diagnostics : NodeDiagnostics
    builder : LiveMapBuilder
        The map builder (the prior map file joined to every map); the intake's from now on.
    prior_refusal : str
        Why ``map_file`` was refused at start-up ('' when it was not, or there is none).
    prior_loaded : bool
        A ``map_file`` was read at start-up.
    """

    def __init__(self, node: Node, inputs: PlanningInputs, in_force: PlanInForce,
                 diagnostics: NodeDiagnostics, builder: LiveMapBuilder, prior_refusal: str,
                 prior_loaded: bool) -> None:
        self._node = node
        self._log = node.get_logger()
        self._inputs = inputs
        self._in_force = in_force
        self._diagnostics = diagnostics
        self._prior_refusal = prior_refusal
        settings = inputs.current_settings()
        self._inbox_lock = threading.Condition()
        self._inbox = Inbox()
        self._sources = {name: SourceState() for name in MAP_SOURCES}
        if prior_loaded:
            self._sources['map_file'] = SourceState(received=1, accepted=1)
        elif prior_refusal:
            self._sources['map_file'] = SourceState(received=1, refused=1, refused_last=True,
                                                    last_refusal=prior_refusal)
        # Seconds of the intake's last map update: whole step, index, mask.
        self._intake_times = (0.0, 0.0, 0.0)
        # Seconds from a cloud's header stamp to its map being handed to the worker, since the
        # last map status (the stamp is the publisher's clock: meaningful on one machine).
        self._cloud_latencies: List[float] = []
        # The intake thread is applying map messages it took from the inbox.
        self._maps_in_step = False
        # The intake thread's.
        self._builder = builder
        self._markers: Dict[MarkerKey, Obstacle] = {}
        self._geofence: Mapping[MarkerKey, Obstacle] = {}
        self._ground: Mapping[MarkerKey, Obstacle] = {}
        self._ground_key: Tuple[Hashable, ...] = ()
        self._frame = conv.normalize_frame(settings.frame_id)
        # Map topics arrive serialised: the executor only queues the bytes, the intake thread
        # deserialises and indexes them, so a 25 MB cloud never stalls parameter services.
        self._obstacles_sub = node.create_subscription(
            MarkerArray, 'obstacles', self._on_obstacles_raw, OBSTACLES_QOS, raw=True)
        self._cloud_sub = node.create_subscription(
            PointCloud2, 'obstacle_cloud', self._on_cloud_raw,
            CLOUD_QOS_BY_RELIABILITY[settings.cloud_qos_reliability], raw=True)
        self._thread = threading.Thread(target=self._run, name='map-intake', daemon=True)

    @property
    def prior_refusal(self) -> str:
        """Why ``map_file`` was refused at start-up ('' when it was not)."""
        return self._prior_refusal

    # ------------------------------------------------------------------------- life cycle

    def start_shapes(self, airspace: Airspace) -> None:
        """Join the geofence and the ground (with its height band) of the settings in force to
        the map at start-up (before :meth:`start`)."""
        settings = self._inputs.current_settings()
        terrain = self._inputs.terrain()
        self._geofence = geofence_shapes(airspace)
        self._ground = ground_shapes(settings.config, terrain)
        self._ground_key = ground_key(settings.config, terrain)
        if self._geofence or self._ground:
            shapes: Dict[MarkerKey, Obstacle] = {**self._geofence, **self._ground}
            self._inputs.set_start_map(self._builder.update(shapes=shapes))

    def start(self) -> None:
        """Start the intake thread."""
        self._thread.start()

    def stop(self, timeout_s: float) -> None:
        """Stop the intake thread (waiting at most ``timeout_s`` [s])."""
        with self._inbox_lock:
            self._inbox.stopping = True
            self._inbox_lock.notify_all()
        if self._thread.is_alive():
            self._thread.join(timeout_s)

    # ------------------------------------------------------------- requests of other parts

    def queue_reconfigure(self, frame_reset: bool = False, shapes_serial: int = 0) -> None:
        """Build the map again for the settings in force (``frame_reset``: the frame changed,
        drop the markers and the cloud); ``shapes_serial``: the shapes request it answers."""
        with self._inbox_lock:
            self._inbox.reconfigure = True
            self._inbox.frame_reset = self._inbox.frame_reset or frame_reset
            self._inbox.airspace_serial = max(self._inbox.airspace_serial, shapes_serial)
            self._inbox_lock.notify_all()

    def queue_airspace(self, airspace: Airspace, shapes_serial: int) -> None:
        """Join a new geofence to the map (it replans the active goal)."""
        with self._inbox_lock:
            self._inbox.airspace = airspace
            self._inbox.airspace_serial = max(self._inbox.airspace_serial, shapes_serial)
            self._inbox_lock.notify_all()

    def forget_sources(self) -> None:
        """The frame changed: the markers and clouds delivered so far count no more."""
        with self._inbox_lock:
            for name in ('obstacles', 'obstacle_cloud'):
                self._sources[name] = SourceState()

    def keep_fallback_grid(self) -> None:
        """Keep the conservative grid up to date in every map from now on (the worker needed
        it: later plans then do not inflate it themselves)."""
        self._builder.want_fallback = True

    def wait_for_pending_maps(self, timeout_s: float) -> None:
        """Wait at most ``timeout_s`` [s] while map messages received so far are still being
        applied and no map source has delivered yet (a goal that arrives just after the map's
        first message, before the intake has built it, is then judged on that map)."""
        def settled() -> bool:
            pending = (bool(self._inbox.markers) or self._inbox.cloud is not None
                       or self._maps_in_step)
            delivered = any(self._sources[name].delivered for name in MAP_SOURCES)
            return self._inbox.stopping or delivered or not pending

        with self._inbox_lock:
            self._inbox_lock.wait_for(settled, timeout_s)

    # --------------------------------------------------------------------------- reports

    def sources(self) -> Dict[str, SourceState]:
        """A copy of what each map source delivered."""
        with self._inbox_lock:
            return {name: replace(state) for name, state in self._sources.items()}

    def take_statistics(self) -> Tuple[Tuple[float, float, float], List[float]]:
        """Seconds of the last map update (step, index, mask), and the cloud latencies [s]
        since the last call."""
        with self._inbox_lock:
            latencies, self._cloud_latencies = self._cloud_latencies, []
            return self._intake_times, latencies

    def map_missing(self, settings: NodeSettings) -> Optional[str]:
        """Why goals cannot be planned yet for want of a map, or None."""
        refusal = self._inputs.map_refusal()
        if refusal:
            # Read once at start-up: planning without the map asked for would fly through it.
            return refusal
        if settings.plan_without_map:
            return None
        sources = self.sources()
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

    def map_values(self, live: Optional[LiveMap] = None) -> Dict[str, object]:
        """What each map source delivered, which ones' newest message was refused, and the
        age of the newest map message [s] (any thread)."""
        sources = self.sources()
        map_stamp = self._inputs.map_stamps()[1]
        live = self._inputs.newest_map() if live is None else live
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
                (self._node.get_clock().now().nanoseconds - map_stamp) * 1e-9, 0.0)
        return values

    # ----------------------------------------------------------------------- the executor's

    def _on_obstacles_raw(self, data: bytes) -> None:
        """Executor: queue a serialised MarkerArray for the intake (all of them, in order:
        incremental arrays build the map together)."""
        with self._inbox_lock:
            self._sources['obstacles'].received += 1
            self._inbox.markers.append((data, time.monotonic_ns()))
            self._inbox_lock.notify_all()

    def _on_cloud_raw(self, data: bytes) -> None:
        """Executor: keep the newest serialised cloud for the intake; an older one it had no
        time for is dropped (the latest cloud wins)."""
        with self._inbox_lock:
            dropped = self._inbox.cloud is not None
            self._inbox.cloud = (data, time.monotonic_ns())
            state = self._sources['obstacle_cloud']
            state.received += 1
            state.superseded += int(dropped)
            self._inbox_lock.notify_all()

    def on_obstacles(self, msg: MarkerArray) -> None:
        """Apply one MarkerArray at once, on the calling thread (in-process use and tests; the
        subscription goes through the intake thread)."""
        self._step([msg], None, False)

    def on_cloud(self, msg: PointCloud2) -> None:
        """Apply one cloud at once, on the calling thread (see :meth:`on_obstacles`)."""
        self._step([], msg, False)

    # ------------------------------------------------------------------- the intake thread

    def _run(self) -> None:
        """Map intake thread: deserialise, check, index and inflate; publish; re-check."""
        while True:
            with self._inbox_lock:
                self._inbox_lock.wait_for(
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
                self._maps_in_step = bool(markers) or cloud is not None
            try:
                messages = [self._deserialize(data, MarkerArray, 'obstacles')
                            for data, _ in markers]
                cloud_msg = (None if cloud is None
                             else self._deserialize(cloud[0], PointCloud2, 'obstacle_cloud'))
                self._step([m for m in messages if m is not None], cloud_msg, reconfigure,
                           airspace, frame_reset)
            except Exception as error:  # noqa: BLE001 - a bug must not stop the intake
                if self._inputs.is_stopping():
                    return
                self._log.error(f'map intake failed: {error!r}\n{traceback.format_exc()}')
            finally:
                if airspace is not None or reconfigure:
                    # The step built the map from the settings and geofence in force, so
                    # every shapes request up to this serial is in it.
                    self._inputs.shapes_applied(airspace_serial)
                with self._inbox_lock:
                    self._maps_in_step = False
                    self._inbox_lock.notify_all()

    def _deserialize(self, data: bytes, msg_type: Any, source: str) -> Optional[Any]:
        try:
            return deserialize_message(data, msg_type)
        except Exception as error:  # noqa: BLE001 - a malformed message is refused
            topic = (self._obstacles_sub if source == 'obstacles' else self._cloud_sub).topic_name
            self._refuse_map(source, topic, InvalidInputError(
                f'{source} message could not be deserialised ({error})'))
            return None

    def _step(self, marker_msgs: List[MarkerArray], cloud_msg: Optional[PointCloud2],
              reconfigure: bool, airspace: Optional[Airspace] = None,
              frame_reset: bool = False) -> None:
        """Apply marker arrays (in order), a cloud, new settings and a new geofence; publish
        the map they give and re-check the plan in force against it. ``frame_reset``: the
        frame changed since the last step (perhaps back again): the map is dropped."""
        settings = self._inputs.current_settings()
        frame = conv.normalize_frame(settings.frame_id)
        cloud: Any = UNCHANGED
        shapes_before = self._markers
        if frame != self._frame or frame_reset:
            # Markers and cloud of the old frame are gone (the executor reset the sources).
            self._frame = frame
            self._markers, cloud = {}, None
        markers = self._markers
        stamp_ns = 0
        # Sources count as delivered only together with the map that holds their data, so a
        # goal is never accepted while the worker still has the map from before.
        accepted: List[_Outcome] = []
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
        self._markers = markers
        if airspace is not None:
            self._geofence = geofence_shapes(airspace)
            shapes_changed = True
        terrain = self._inputs.terrain()
        if ground_key(settings.config, terrain) != self._ground_key:
            self._ground = ground_shapes(settings.config, terrain)
            self._ground_key = ground_key(settings.config, terrain)
            shapes_changed = True
        if not (shapes_changed or cloud is not UNCHANGED or reconfigure):
            self._accept_map(accepted)
            return
        held_map = self._inputs.held_map()
        held = held_map.blocked if held_map is not None else None
        held_fallback = held_map.fallback if held_map is not None else None
        started = time.perf_counter()
        try:
            # The cloud array is fresh from the message: handed over without a copy.
            live = self._builder.update(shapes={**markers, **self._geofence, **self._ground}
                                        if shapes_changed else None,
                                        cloud=cloud, config=settings.config, held=held,
                                        give_cloud=True, held_fallback=held_fallback)
        except InvalidInputError as error:  # settings that cannot make a grid (never valid)
            self._log.error(f'map update failed: {error}')
            return
        elapsed = time.perf_counter() - started
        previous = self._inputs.newest_map()
        if live is previous:
            self._accept_map(accepted)
            return
        now_ns = self._node.get_clock().now().nanoseconds

        def install(withdrawn: Optional[InForce]) -> None:
            # Under the plan in force's release lock, after the check of the plan in force:
            # a withdrawal and the request for its replacement reach the worker with the map.
            self._inputs.install_map(live, stamp_ns, withdrawn,
                                     settings.replan_on_obstacle_change, airspace is not None)
            latency = ((now_ns - cloud_stamp) * 1e-9 if cloud is not UNCHANGED
                       and cloud_msg is not None and cloud_stamp > 0 else None)
            self._accept_map(accepted, (elapsed, live.index_time_s, live.update.time_s),
                             latency)

        self._in_force.install_map(live, live.version != previous.version, install)

    def _accept_map(self, outcomes: List[_Outcome],
                    times: Optional[Tuple[float, float, float]] = None,
                    cloud_latency: Optional[float] = None) -> None:
        """Replay the map messages of one intake step in order: (source, header stamp [ns])
        for an accepted one, counted now; (source, the error) for a refused one, counted when
        it was refused (so that the refusal shows at once), replayed here only for the order
        of "the newest message was refused". ``times``: the seconds of the map update that
        holds them, ``cloud_latency``: its cloud's stamp to now [s]."""
        with self._inbox_lock:
            for source, outcome in outcomes:
                state = self._sources[source]
                if isinstance(outcome, Exception):
                    state.refused_last = True
                    state.last_refusal = str(outcome)
                else:
                    state.accepted += 1
                    state.refused_last = False
                    state.last_stamp_ns = int(outcome)
            if times is not None:
                self._intake_times = times
            if cloud_latency is not None:
                self._cloud_latencies.append(cloud_latency)

    def _refuse_map(self, source: str, topic: str, error: Exception) -> None:
        with self._inbox_lock:
            state = self._sources[source]
            state.refused += 1
            state.refused_last = True
            state.last_refusal = str(error)
        self._diagnostics.refuse(topic, error)
