"""The planner node: a thin rclpy layer around :class:`~uav_global_planner.core.planner.Planner`.

Topics (all relative, so namespaces work):

========================  ==============================  =======================================
name                      type                            notes
========================  ==============================  =======================================
``goal_pose`` (in)        geometry_msgs/PoseStamped       plan to it; latest goal wins
``obstacles`` (in)        visualization_msgs/MarkerArray  SPHERE/CUBE by (ns, id); transient
                                                          local, depth 100
``obstacle_cloud`` (in)   sensor_msgs/PointCloud2         occupied points, replaces the last
                                                          cloud; reliable (or best effort)
``odom`` (in)             nav_msgs/Odometry               start position (latest of odom and
``start_pose`` (in)       geometry_msgs/PoseStamped       start_pose; else the ``start``
                                                          parameter); odom's twist for replans
                                                          in flight
``plan`` (out)            nav_msgs/Path                   smoothed, time-stamped; transient local
``unsmoothed_plan`` (out) nav_msgs/Path                   grid nodes; transient local
``trajectory`` (out)      MultiDOFJointTrajectory         positions, velocities, accelerations
``planner_markers`` (out) visualization_msgs/MarkerArray  obstacles and gamma-inflated obstacles
``/diagnostics`` (out)    diagnostic_msgs/DiagnosticArray after every plan and every refused input
========================  ==============================  =======================================

Three threads share the work:

- the executor serves topics, parameters, timers and the Nav2 interfaces; map messages are
  taken as serialised bytes and only queued there (markers in order, clouds latest-wins);
- the map intake (:meth:`PlannerNode._run_intake`) deserialises, checks and indexes them,
  updates the inflated grid tile by tile (:class:`~uav_global_planner.core.map.live_map.
  LiveMapBuilder`, double-buffered, so a plan always runs on one consistent map), publishes the
  new map to the planning worker and re-checks the plan in force against it at once with the
  certified check (ahead of the vehicle first). A plan the new map makes collide is withdrawn
  on the spot (empty ``plan``, ``unsmoothed_plan`` and ``trajectory``, an ERROR
  ``plan_withdrawn`` on /diagnostics saying where it is blocked) and a replacement is planned;
- the planning worker (the only thread that touches the :class:`Planner`) takes a snapshot of
  the settings, map, start and goal when a plan begins; whatever arrives meanwhile is coalesced
  into at most one follow-up plan. A newer goal or changed settings cancel a running plan; a
  new map does not: the finished plan is checked against the newest map before it is published
  (``event: plan_discarded`` when it collides, and it is made again on that map).

A plan made while the vehicle flies the plan in force continues it: it starts from the state
the plan in force will have when the new plan is published (planning latency predicted) and is
stamped with that time, so that a follower switches without a jump
(:mod:`~uav_global_planner.ros.takeover`).

The diagnostics of a plan name the map it was computed on (``obstacles_version``, and
``obstacles_stamp``: the header stamp of the map message that last changed the obstacles), the
newest map it was checked against before publishing (``obstacles_checked_*``) and the state of
every map source (``map_sources``, ``map_refused``: a plan made while a source's newest message
was refused says so, at WARN).

The node's jobs live in modules of their own, joined here as mixins of :class:`PlannerNode`
(one object, so the threads share its locks and state): the attributes they share, the lock
that guards each and the methods one calls on another are declared in their base
:class:`~uav_global_planner.ros.node_attributes.NodeAttributes`, shared records in
:mod:`~uav_global_planner.ros.node_state`, parameter changes in
:mod:`~uav_global_planner.ros.node_reconfigure`, goal and start inputs in
:mod:`~uav_global_planner.ros.node_inputs`, the map intake in
:mod:`~uav_global_planner.ros.node_intake`, the plan in force in
:mod:`~uav_global_planner.ros.node_in_force`, the planning worker in
:mod:`~uav_global_planner.ros.node_worker` and the diagnostics in
:mod:`~uav_global_planner.ros.node_status`. This module builds the node (publishers,
subscriptions, timers, threads) and runs it (:func:`main`).
"""

import sys
import threading
from typing import Any, List, Optional

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry, Path
import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import PointCloud2
from trajectory_msgs.msg import MultiDOFJointTrajectory
from visualization_msgs.msg import MarkerArray

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.mapfiles import load_prior_map
from uav_global_planner.core.map.airspace import Airspace
from uav_global_planner.core.map.live_map import LiveMapBuilder
from uav_global_planner.core.map.unknown_space import unknown_from_map_files, UnknownSpace
from uav_global_planner.core.planner import Planner
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.geofence_source import (airspace_from_values, geofence_key,
                                                    geofence_shapes)
from uav_global_planner.ros.ground_source import ground_key, ground_shapes
from uav_global_planner.ros.mission_service import MissionExportService, ORIGIN_PARAMETER
from uav_global_planner.ros.names import NODE_NAME, READY_TEXT
from uav_global_planner.ros.nav2_interfaces import PlannerInterfaces
from uav_global_planner.ros.node_in_force import PlanInForce
from uav_global_planner.ros.node_inputs import CommandInputs
from uav_global_planner.ros.node_intake import MapIntake
from uav_global_planner.ros.node_main import (  # noqa: F401 - importable from the node
    EXIT_BAD_SETTINGS, run_node)
from uav_global_planner.ros.node_reconfigure import ParameterHandling
from uav_global_planner.ros.node_state import Inbox, SourceState
from uav_global_planner.ros.node_status import StatusPublishing
from uav_global_planner.ros.node_worker import PlanningWorker
from uav_global_planner.ros.parameters import (  # noqa: F401 - importable from the node
    CLOUD_NON_FINITE_MODES, declare_parameters, MAP_SOURCES, NodeSettings, PARAMETER_SPECS,
    plain as _plain, settings_from_parameters, SPECS_BY_NAME, STARTUP_ONLY)
from uav_global_planner.ros.plan_writer import startup_plan_writer
from uav_global_planner.ros.qos import (CLOUD_QOS_BY_RELIABILITY, COMMAND_QOS, DIAGNOSTICS_QOS,
                                        LATCHED_QOS, OBSTACLES_QOS, SENSOR_QOS)
from uav_global_planner.ros.start_source import StartSource
from uav_global_planner.ros.takeover import TakeoverPredictor
from uav_global_planner.ros.terrain_source import (describe_terrain, read_terrain,
                                                   TerrainState)

#: Marker-publishing check period [s]: markers go out only when someone subscribes.
_MARKER_PERIOD_S = 0.5

#: Period of the ``map_status`` diagnostics [s] (as diagnostic_updater's 1 Hz).
_MAP_STATUS_PERIOD_S = 1.0

#: Period of the check for another node of the same fully qualified name [s].
_DUPLICATE_CHECK_PERIOD_S = 2.0


class PlannerNode(ParameterHandling, CommandInputs, MapIntake, PlanInForce, PlanningWorker,
                  StatusPublishing):
    """The planner node: parameters, map intake, planning worker and outputs.

    Composition rather than a ``Node`` subclass: :attr:`node` is the rclpy node, the
    :class:`Planner` is touched only by the worker thread.

    Parameters
    ----------
    node_name : str
    **node_options
        Passed to :class:`rclpy.node.Node` (for example ``namespace``, ``context``,
        ``parameter_overrides``).

    Raises
    ------
    InvalidInputError
        When the parameters given at start-up are invalid. A ``map_file`` that cannot be read,
        or cannot be right (no usable points, all outside the bounds, see
        :mod:`~uav_global_planner.core.io.mapfiles`), is refused instead: the node runs without it,
        reports why in the log and the map status, and refuses goals.
    """

    def __init__(self, node_name: str = NODE_NAME, **node_options: Any) -> None:
        self.node = Node(node_name, **node_options)
        self._log = self.node.get_logger()
        # Latency estimate, newest odometry motion and takeover predictions (own lock).
        self._takeover = TakeoverPredictor(lambda: self.node.get_clock().now().nanoseconds)
        # Checked once per process: CDR bytes only when rclpy reads them back right.
        self._plan_writer = startup_plan_writer(self._log)
        self._param_values = declare_parameters(self.node)
        # Validated before the map file is read: a typo elsewhere is reported first.
        first = settings_from_parameters(self._param_values)
        self._prior = None
        # Why map_file was refused ('': it was not); map_file is read once, at start-up.
        self._prior_refusal = ''
        # Space an OctoMap map_file never observed, within the bounds (see _follow_bounds).
        unknown: Optional[UnknownSpace] = None
        try:
            self._prior = load_prior_map(
                first.map_file, first.map_downsample,
                bounds=(first.config.bounds_min, first.config.bounds_max),
                reach=first.config.safety_margin, resolution=first.config.resolution)
            if self._prior is not None:
                unknown = unknown_from_map_files([first.map_file.strip()],
                                                 first.config.bounds_min,
                                                 first.config.bounds_max)
        except InvalidInputError as error:
            self._prior = None
            self._prior_refusal = str(error)
            self._log.error(f'refused map_file: {error}; goals are refused until the node is '
                            'restarted with a map file that can be used (or none)')
        self._map_margin_m = self._prior.margin_m if self._prior is not None else 0.0
        settings = settings_from_parameters(self._param_values, self._map_margin_m)
        # Registered after declaring, so start-up values are checked once above, not per item.
        self.node.add_on_set_parameters_callback(self._validate_parameters)
        self.node.add_post_set_parameters_callback(self._apply_parameters)

        self._planner = Planner(settings.config, unknown=unknown)
        self._unknown_file = first.map_file.strip() if unknown is not None else ''
        self._unknown_bounds = (tuple(first.config.bounds_min), tuple(first.config.bounds_max))
        # The prior map is indexed once (per grid) and joined to every map of the intake.
        self._builder = LiveMapBuilder(
            settings.config, None if self._prior is None else self._prior.points,
            first_version=0)
        self._wake = threading.Condition()
        self._diagnostics_lock = threading.Lock()
        # Serialises publishing a plan, withdrawing it and checking it against a new map, so
        # that no plan goes out unchecked against a map published meanwhile.
        self._publish_lock = threading.RLock()
        # State below is guarded by self._wake.
        self._settings = settings
        self._settings_changed = False
        self._map = self._builder.update()
        self._map_changed = False
        # Header stamp of the map message that last changed the obstacles (0: none yet), and
        # of the newest map message taken in; reported with every plan.
        self._obstacles_stamp_ns = 0
        self._map_stamp_ns = 0
        self._sources = {name: SourceState() for name in MAP_SOURCES}
        if self._prior is not None:
            self._sources['map_file'] = SourceState(received=1, accepted=1)
        elif self._prior_refusal:
            self._sources['map_file'] = SourceState(received=1, refused=1, refused_last=True,
                                                    last_refusal=self._prior_refusal)
        self._goal = None
        self._goal_serial = 0
        self._goal_changed = False
        self._start = None
        self._start_source = StartSource.PARAMETER
        self._stopping = False
        # A replan the worker owes the active goal (the plan in force was withdrawn, or it
        # started at the start parameter and the vehicle's position arrived): the reason.
        self._replan_request = None
        # The map the worker plans on (its mask is never rewritten while held).
        self._worker_map = None
        # Start source of the plan in force; None: none in force.
        self._in_force_source = None
        self._intake_times = (0.0, 0.0, 0.0)
        # Seconds from a cloud's header stamp to its map being handed to the worker, since the
        # last map_status (the stamp is the publisher's clock: meaningful on one machine).
        self._cloud_latencies = []
        # Worker-only state: outcome of the last plan attempt.
        self._last_result = None
        self._last_goal_serial = -1
        # Worker-only: why the active goal must be planned again although nothing flagged it.
        self._replan_reason = None
        # Worker-only: the map applied to the planner, and plans dropped in a row because the
        # vehicle moved away from their start while they were computed.
        self._applied_map = None
        self._grid_from_map = False
        self._drift_replans = 0
        # Guarded by _publish_lock: the plan latched on ``plan`` (None: none, or withdrawn).
        self._latched = None
        self._in_force = None
        self._markers_published_key = None
        # Intake: its inbox (guarded by _intake_cv) and its own state.
        self._intake_cv = threading.Condition()
        self._inbox = Inbox()
        self._intake_markers = {}
        # The geofence in force and its shapes in the intake's map (read below).
        self._airspace = Airspace()
        self._intake_geofence = {}
        # Serial numbers of the geofence asked for and of the one the map holds (_wake).
        self._geofence_requested = 0
        self._geofence_applied = 0
        # The geofence parameters the geofence in force was read from (None: not read yet).
        self._geofence_key = None
        # The terrain_file in force (None: not read yet; written under _wake).
        self._terrain_state = None
        # A terrain read by the on-set callback for values about to be set (see node_reconfigure).
        self._terrain_candidate = None
        self._intake_frame = conv.normalize_frame(settings.frame_id)
        self._duplicates_reported = 0

        node = self.node
        self._plan_pub = node.create_publisher(Path, 'plan', LATCHED_QOS)
        self._unsmoothed_pub = node.create_publisher(Path, 'unsmoothed_plan', LATCHED_QOS)
        self._trajectory_pub = node.create_publisher(MultiDOFJointTrajectory, 'trajectory',
                                                     LATCHED_QOS)
        self._markers_pub = node.create_publisher(MarkerArray, 'planner_markers', LATCHED_QOS)
        self._diagnostics_pub = node.create_publisher(DiagnosticArray, '/diagnostics',
                                                      DIAGNOSTICS_QOS)
        self._goal_sub = node.create_subscription(PoseStamped, 'goal_pose', self._on_goal,
                                                  COMMAND_QOS)
        # Map topics arrive serialised: the executor only queues the bytes, the intake thread
        # deserialises and indexes them, so a 25 MB cloud never stalls parameter services.
        self._obstacles_sub = node.create_subscription(
            MarkerArray, 'obstacles', self._on_obstacles_raw, OBSTACLES_QOS, raw=True)
        self._cloud_sub = node.create_subscription(
            PointCloud2, 'obstacle_cloud', self._on_cloud_raw,
            CLOUD_QOS_BY_RELIABILITY[settings.cloud_qos_reliability], raw=True)
        self._odom_sub = node.create_subscription(Odometry, 'odom', self._on_odom, SENSOR_QOS)
        self._start_sub = node.create_subscription(PoseStamped, 'start_pose',
                                                   self._on_start_pose, COMMAND_QOS)
        self._marker_timer = node.create_timer(_MARKER_PERIOD_S, self._publish_markers)
        self._status_timer = node.create_timer(_MAP_STATUS_PERIOD_S, self._publish_map_status)
        self._duplicate_timer = node.create_timer(_DUPLICATE_CHECK_PERIOD_S,
                                                  self._check_duplicate_name)
        self._worker = threading.Thread(target=self._run_worker, name='planner-worker',
                                        daemon=True)
        self._intake = threading.Thread(target=self._run_intake, name='map-intake',
                                        daemon=True)
        self._diag_name = f'{node.get_fully_qualified_name()}: global planner'
        # Requests of the Nav2 interfaces, run by the worker after _step (guarded by _wake).
        self._jobs = []
        self._nav2 = PlannerInterfaces(self)
        self._mission_export = MissionExportService(self)
        # The geofence is read once geodetic_origin (declared by the mission export) exists;
        # its zones join the map as shapes of their own.
        geofence = self._geofence_values()
        self._airspace = airspace_from_values(geofence)
        self._geofence_key = geofence_key(geofence)
        self._intake_geofence = geofence_shapes(self._airspace)
        # The terrain_file (placed with geodetic_origin too) is the ground when there is one.
        self._terrain_state = read_terrain(settings.terrain_file, settings.config,
                                           geofence[ORIGIN_PARAMETER])
        if self._terrain_state.refusal:  # a terrain read is in the ready line
            self._log_terrain(self._terrain_state)
        # The ground and the height band above it (ground, min_agl, max_agl) join it alike.
        self._intake_ground = ground_shapes(settings.config, self._terrain_state)
        self._ground_key = ground_key(settings.config, self._terrain_state)
        if self._intake_geofence or self._intake_ground:
            self._map = self._builder.update(shapes={**self._intake_geofence,
                                                     **self._intake_ground})

    def _follow_bounds(self, config: PlannerConfig) -> None:
        """The unknown space of an OctoMap ``map_file`` within new bounds (read again from the
        file; all of the bounds when it can no longer be read)."""
        bounds = (tuple(config.bounds_min), tuple(config.bounds_max))
        if not self._unknown_file or bounds == self._unknown_bounds:
            return
        try:
            unknown = unknown_from_map_files([self._unknown_file], *bounds)
        except InvalidInputError as error:
            self._log.error(f'map_file: unknown space for the new bounds: {error}; all of the '
                            'bounds count as unknown')
            unknown = UnknownSpace(np.array(bounds[0])[None, :], np.array(bounds[1])[None, :],
                                   self._unknown_file)
        self._unknown_bounds = bounds
        self._planner.set_unknown(unknown)

    def start(self) -> None:
        """Compile the kernels and build the grid, then start the threads and log readiness."""
        self._grid_from_map = self._planner.set_map(self._map.obstacles, self._map.blocked,
                                                    self._map.grid_key)
        self._applied_map = self._map
        self._planner.warm_up()
        self._worker.start()
        self._intake.start()
        settings = self._settings
        config = settings.config
        grid = self._planner.grid
        prior = ''
        if self._prior is not None:
            prior = ''.join(f'; prior map {report.summary()}' for report in self._prior.reports)
            prior += f' (margin {self._prior.margin_m:.3f} m added to gamma)'
        terrain = self._terrain_state
        if terrain is not None and terrain.field is not None:
            prior += f'; {describe_terrain(terrain)}'
        self._log.info(
            f'{READY_TEXT}: frame {settings.frame_id!r}, grid {grid.shape[0]}x{grid.shape[1]}x'
            f'{grid.shape[2]} (delta {config.resolution} m, gamma {config.safety_margin} m, '
            f'eta {config.adaptive_threshold} m), algorithm {config.algorithm}; goals on '
            f'{self._goal_sub.topic_name}{prior}')
        self._check_duplicate_name()

    def close(self, timeout_s: float = 2.0) -> None:
        """Stop the threads (a running plan is cancelled within milliseconds) and destroy the
        node."""
        self._nav2.destroy()
        with self._wake:
            self._stopping = True
            self._wake.notify_all()
        with self._intake_cv:
            self._inbox.stopping = True
            self._intake_cv.notify_all()
        for thread in (self._worker, self._intake):
            if thread.is_alive():
                thread.join(timeout_s)
        self.node.destroy_node()

    def _current_settings(self) -> NodeSettings:
        with self._wake:
            return self._settings

    def current_settings(self) -> NodeSettings:
        """The settings in force (any thread)."""
        return self._current_settings()

    def map_refusal(self) -> str:
        """Why ``map_file`` or ``terrain_file`` was refused, with what to do ('' when neither
        was): no request is planned without the map or the terrain asked for (any thread)."""
        if self._prior_refusal:
            return (f'map_file refused: {self._prior_refusal}; restart the node with a map '
                    'file that can be used, or with map_file empty')
        terrain = self._terrain_state
        if terrain is not None and terrain.refusal:
            return (f'terrain_file refused: {terrain.refusal}; restart the node with a terrain '
                    'file that can be used (or set bounds or geodetic_origin it covers), or '
                    'with terrain_file empty')
        return ''

    def _log_terrain(self, state: TerrainState) -> None:
        """Log the terrain read, or why it was refused."""
        if state.refusal:
            self._log.error(f'refused terrain_file: {state.refusal}; goals are refused until '
                            'a terrain that can be used is in force')
        elif state.field is not None:
            self._log.info(f'{describe_terrain(state)}: the ground from the next plan')


def main(args: Optional[List[str]] = None) -> int:
    """Entry point of ``planner_node``: run until SIGINT/SIGTERM, then exit with 0.

    Returns
    -------
    int
        0 after a clean shutdown, :data:`EXIT_BAD_SETTINGS` for invalid start-up parameters
        (a ``map_file`` that cannot be used is reported by the running node instead).
    """
    return run_node('planner_node', PlannerNode, args)


if __name__ == '__main__':
    sys.exit(main())
