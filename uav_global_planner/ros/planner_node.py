"""The planner node: a thin rclpy layer around :class:`~uav_global_planner.core.planner.Planner`.

Topics (all relative, so namespaces work):

========================  ==============================  =======================================
name                      type                            notes
========================  ==============================  =======================================
``goal_pose`` (in)        geometry_msgs/PoseStamped       plan to it; latest goal wins
``obstacles`` (in)        visualization_msgs/MarkerArray  SPHERE/CUBE by (ns, id); transient local
``obstacle_cloud`` (in)   sensor_msgs/PointCloud2         occupied points, replaces the last cloud
``odom`` (in)             nav_msgs/Odometry               start position (latest of odom and
``start_pose`` (in)       geometry_msgs/PoseStamped       start_pose; else the ``start`` parameter)
``plan`` (out)            nav_msgs/Path                   smoothed, time-stamped; transient local
``unsmoothed_plan`` (out) nav_msgs/Path                   grid nodes; transient local
``trajectory`` (out)      MultiDOFJointTrajectory         positions, velocities, accelerations
``planner_markers`` (out) visualization_msgs/MarkerArray  obstacles and gamma-inflated obstacles
``/diagnostics`` (out)    diagnostic_msgs/DiagnosticArray after every plan and every refused input
========================  ==============================  =======================================

Planning runs on a worker thread (the search kernels release the GIL), so parameter services and
message intake stay responsive during a long plan. The worker takes a snapshot of the settings,
obstacles, start and goal when a plan begins; whatever arrives meanwhile is coalesced into at most
one follow-up plan. The diagnostics of a plan name the obstacle set it was computed on
(``obstacles_version``, and ``obstacles_stamp``: the header stamp of the obstacle message that last
changed the obstacles) and the newest set it was checked against before publishing
(``obstacles_checked_*``): a plan that collides with obstacles received while it was computed is
not published (``event: plan_discarded``) but made again on them. When new obstacles make the
latched plan collide and no new plan can replace it, empty ``plan``, ``unsmoothed_plan`` and
``trajectory`` messages withdraw it (``plan_withdrawn: true``).
"""

from dataclasses import dataclass
import math
import signal
import sys
import threading
import traceback
from typing import Any, Dict, List, Mapping, Optional, Tuple

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry, Path
import numpy as np
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import PointCloud2
from trajectory_msgs.msg import MultiDOFJointTrajectory
from visualization_msgs.msg import MarkerArray

from uav_global_planner.core.config import (ALGORITHMS, PlannerConfig, SMOOTHING_MODES,
                                            validate_config)
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.grid import as_point
from uav_global_planner.core.obstacles import ObstacleSet
from uav_global_planner.core.planner import densify, Planner
from uav_global_planner.core.result import PlanResult
from uav_global_planner.core.status import (NAV2_CODE_BY_STATUS, NAV2_GOAL_OUTSIDE_MAP,
                                            NAV2_UNKNOWN, PlanStatus)
from uav_global_planner.ros import cdr
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.qos import (COMMAND_QOS, DIAGNOSTICS_QOS, LATCHED_QOS, OBSTACLES_QOS,
                                        SENSOR_QOS)

#: Name of the node unless remapped with ``--ros-args -r __node:=...``.
NODE_NAME = 'global_planner'

#: Logged once the kernels are compiled and the node takes requests; tests wait for it.
READY_TEXT = 'planner ready'

#: Marker-publishing check period [s]: markers go out only when someone subscribes.
_MARKER_PERIOD_S = 0.5

#: Outcomes that may change when the obstacles change, so a failed goal is retried then.
_RETRY_ON_OBSTACLES = (PlanStatus.NO_VALID_PATH, PlanStatus.TIMEOUT, PlanStatus.START_OCCUPIED,
                       PlanStatus.GOAL_OCCUPIED)

#: Exit code for settings that are invalid at start-up.
EXIT_BAD_SETTINGS = 2

CLOUD_NON_FINITE_MODES = ('drop', 'refuse')


# --------------------------------------------------------------------------------------------
# Parameters
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ParameterSpec:
    """One parameter of the node: name, default, documentation and range.

    Attributes
    ----------
    name : str
    default : Any
        Also fixes the parameter type (float, int, str, bool, list of float).
    description : str
        With units and the paper's symbol.
    constraints : str
        Free-text constraints shown by ``ros2 param describe``.
    float_range, int_range : tuple, optional
        Inclusive (from, to) range checked by rclpy before the node's own validation.
    field : str, optional
        The :class:`PlannerConfig` field it sets; None for node-only parameters.
    """

    name: str
    default: Any
    description: str
    constraints: str = ''
    float_range: Optional[Tuple[float, float]] = None
    int_range: Optional[Tuple[int, int]] = None
    field: Optional[str] = None

    def descriptor(self) -> ParameterDescriptor:
        """The rclpy descriptor of this parameter."""
        descriptor = ParameterDescriptor(name=self.name, description=self.description,
                                         additional_constraints=self.constraints)
        if self.float_range is not None:
            descriptor.floating_point_range = [FloatingPointRange(
                from_value=float(self.float_range[0]), to_value=float(self.float_range[1]),
                step=0.0)]
        if self.int_range is not None:
            descriptor.integer_range = [IntegerRange(
                from_value=int(self.int_range[0]), to_value=int(self.int_range[1]), step=1)]
        return descriptor


_DEFAULTS = PlannerConfig()
_INT_MAX = 2 ** 62

#: Every parameter the node owns. Ranges mirror :func:`validate_config`, which stays the one
#: authority: rclpy's range check only gives ``ros2 param describe`` something to show.
PARAMETER_SPECS: Tuple[ParameterSpec, ...] = (
    ParameterSpec('resolution', _DEFAULTS.resolution,
                  'Grid spacing delta [m] (paper eq. 5). Smaller is finer and slower.',
                  '0 < delta <= 100 m; the node count must stay <= max_voxels',
                  float_range=(0.0, 100.0), field='resolution'),
    ParameterSpec('safety_margin', _DEFAULTS.safety_margin,
                  'Safety margin gamma [m] (paper eqs. 8-10): nodes within gamma of an obstacle '
                  'are blocked and the smoothed path keeps clearance >= gamma.',
                  '0 <= gamma <= 100 m', float_range=(0.0, 100.0), field='safety_margin'),
    ParameterSpec('adaptive_threshold', _DEFAULTS.adaptive_threshold,
                  'Heuristic switch distance eta [m] (paper eq. 12): the adaptive heuristic is '
                  'Manhattan beyond eta and Euclidean within it.',
                  'eta >= 0 m', float_range=(0.0, 1.0e6), field='adaptive_threshold'),
    ParameterSpec('bounds.min', list(_DEFAULTS.bounds_min),
                  'Workspace minimum corner [x, y, z] [m] (paper eq. 4), in frame_id.',
                  'three finite numbers, below bounds.max on every axis', field='bounds_min'),
    ParameterSpec('bounds.max', list(_DEFAULTS.bounds_max),
                  'Workspace maximum corner [x, y, z] [m] (paper eq. 4), in frame_id.',
                  'three finite numbers, above bounds.min on every axis', field='bounds_max'),
    ParameterSpec('algorithm', _DEFAULTS.algorithm,
                  'Search heuristic: dijkstra (none), astar (Euclidean), adaptive (paper eq. 12, '
                  'Manhattan beyond eta) or octile.',
                  'one of: ' + ', '.join(ALGORITHMS), field='algorithm'),
    ParameterSpec('max_expansions', _DEFAULTS.max_expansions,
                  'Search budget in expanded nodes [-]; 0 = no limit. Exceeding it reports '
                  'TIMEOUT (207).', '>= 0', int_range=(0, _INT_MAX), field='max_expansions'),
    ParameterSpec('max_planning_time', _DEFAULTS.max_planning_time,
                  'Search time budget [s] (paper eq. 14 measures this time); 0 = no limit. '
                  'Exceeding it reports TIMEOUT (207).', '>= 0 s',
                  float_range=(0.0, 1.0e6), field='max_planning_time'),
    ParameterSpec('max_voxels', _DEFAULTS.max_voxels,
                  'Largest accepted grid node count [-] (paper eq. 7), so that a typo in '
                  'resolution or bounds cannot exhaust memory.', '>= 1',
                  int_range=(1, _INT_MAX), field='max_voxels'),
    ParameterSpec('shortcut', _DEFAULTS.shortcut,
                  'Drop grid nodes where the straight segment keeps clearance >= gamma before '
                  'smoothing.', field='shortcut'),
    ParameterSpec('smoothing', _DEFAULTS.smoothing,
                  'Cubic-spline parameterisation: chord (arc length, sampled every '
                  "sample_spacing metres), index (the paper's node index, step index_step) or "
                  'none.', 'one of: ' + ', '.join(SMOOTHING_MODES), field='smoothing'),
    ParameterSpec('sample_spacing', _DEFAULTS.sample_spacing,
                  'Spacing of the smoothed samples for chord smoothing [m].', '0 < s <= 10 m',
                  float_range=(0.0, 10.0), field='sample_spacing'),
    ParameterSpec('index_step', _DEFAULTS.index_step,
                  'Parameter step of the node-index spline for index smoothing [-].',
                  '0 < step <= 1', float_range=(0.0, 1.0), field='index_step'),
    ParameterSpec('max_speed_horizontal', _DEFAULTS.max_speed_horizontal,
                  'Horizontal speed limit of the time parameterisation [m/s].', '> 0 m/s',
                  float_range=(0.0, 1000.0), field='max_speed_horizontal'),
    ParameterSpec('max_speed_vertical', _DEFAULTS.max_speed_vertical,
                  'Vertical speed limit of the time parameterisation [m/s].', '> 0 m/s',
                  float_range=(0.0, 1000.0), field='max_speed_vertical'),
    ParameterSpec('max_accel_horizontal', _DEFAULTS.max_accel_horizontal,
                  'Horizontal acceleration limit of the time parameterisation [m/s^2].',
                  '> 0 m/s^2', float_range=(0.0, 1000.0), field='max_accel_horizontal'),
    ParameterSpec('max_accel_vertical', _DEFAULTS.max_accel_vertical,
                  'Vertical acceleration limit of the time parameterisation [m/s^2].',
                  '> 0 m/s^2', float_range=(0.0, 1000.0), field='max_accel_vertical'),
    ParameterSpec('frame_id', 'map',
                  'Planning frame. Every input must be stamped in it (the node does no tf2 '
                  'transforms; other frames are refused with code TF_ERROR 202). Changing it '
                  'drops the obstacles, start and goal received in the old frame.',
                  'non-empty'),
    ParameterSpec('start', [0.0, 0.0, 0.0],
                  'Start position [x, y, z] [m] in frame_id, used until a message arrives on '
                  'odom or start_pose.', 'three finite numbers'),
    ParameterSpec('max_obstacle_size', 100.0,
                  'Largest accepted marker scale component [m]; bigger markers are refused as '
                  'implausible.', '> 0 m', float_range=(0.0, 1.0e6)),
    ParameterSpec('max_cloud_points', 2_000_000,
                  'Largest accepted obstacle_cloud size (width x height) [points].', '>= 1',
                  int_range=(1, _INT_MAX)),
    ParameterSpec('cloud_non_finite', 'drop',
                  'What to do with NaN/inf points in obstacle_cloud: drop them (usual for '
                  'sensor clouds) or refuse the whole cloud.',
                  'one of: ' + ', '.join(CLOUD_NON_FINITE_MODES)),
    ParameterSpec('replan_on_obstacle_change', True,
                  'Replan the active goal by itself when the obstacles change and the current '
                  'path no longer keeps clearance >= gamma.'),
)

SPECS_BY_NAME: Dict[str, ParameterSpec] = {spec.name: spec for spec in PARAMETER_SPECS}


@dataclass(frozen=True, eq=False)
class NodeSettings:
    """The validated values of every parameter of the node.

    Attributes
    ----------
    config : PlannerConfig
        Planner settings, validated by :func:`validate_config` (as in the command-line tool).
    frame_id : str
    start : numpy.ndarray, shape (3,)
        Start from the parameter [m].
    max_obstacle_size : float
        [m]
    max_cloud_points : int
    cloud_non_finite : str
        ``'drop'`` or ``'refuse'``.
    replan_on_obstacle_change : bool
    """

    config: PlannerConfig
    frame_id: str
    start: np.ndarray
    max_obstacle_size: float
    max_cloud_points: int
    cloud_non_finite: str
    replan_on_obstacle_change: bool


def _plain(value: Any) -> Any:
    """Parameter value as plain Python (rclpy gives arrays as ``array.array``)."""
    if isinstance(value, (list, tuple)) or hasattr(value, 'tolist'):
        return [float(v) for v in value]
    return value


def settings_from_parameters(values: Mapping[str, Any]) -> NodeSettings:
    """Build and validate the settings from parameter values keyed by parameter name.

    Raises
    ------
    InvalidInputError
        Naming the offending parameter and the accepted values.
    """
    fields = {spec.field: _plain(values[spec.name]) for spec in PARAMETER_SPECS if spec.field}
    for key in ('bounds_min', 'bounds_max'):
        if isinstance(fields[key], list):
            fields[key] = tuple(fields[key])
    config = validate_config(PlannerConfig(**fields))
    frame_id = values['frame_id']
    if not isinstance(frame_id, str) or not frame_id.strip('/ '):
        raise InvalidInputError(f'frame_id must be a non-empty frame name, got {frame_id!r}')
    try:
        start = as_point(_plain(values['start']), 'start')
    except InvalidInputError as error:
        raise InvalidInputError(f'{error}') from None
    size = float(values['max_obstacle_size'])
    if not math.isfinite(size) or size <= 0.0:
        raise InvalidInputError(f'max_obstacle_size must be a finite number > 0 m, got {size}')
    points = int(values['max_cloud_points'])
    if points < 1:
        raise InvalidInputError(f'max_cloud_points must be >= 1, got {points}')
    mode = values['cloud_non_finite']
    if mode not in CLOUD_NON_FINITE_MODES:
        raise InvalidInputError(
            f'cloud_non_finite must be one of {", ".join(CLOUD_NON_FINITE_MODES)}, got {mode!r}')
    return NodeSettings(config=config, frame_id=str(frame_id), start=start,
                        max_obstacle_size=size, max_cloud_points=points,
                        cloud_non_finite=mode,
                        replan_on_obstacle_change=bool(values['replan_on_obstacle_change']))


def declare_parameters(node: Node) -> Dict[str, Any]:
    """Declare every parameter of :data:`PARAMETER_SPECS`; return the values in force
    (defaults overridden by ``--params-file``/``-p``)."""
    declared = node.declare_parameters('', [(spec.name, spec.default, spec.descriptor())
                                            for spec in PARAMETER_SPECS])
    return {parameter.name: parameter.value for parameter in declared}


# --------------------------------------------------------------------------------------------
# Shared state between the executor thread (intake) and the planning worker
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class Goal:
    """A goal accepted from ``goal_pose``.

    Attributes
    ----------
    position : numpy.ndarray, shape (3,)
        [m] in the planning frame.
    orientation : numpy.ndarray, shape (4,)
        Unit quaternion (x, y, z, w), kept for the last pose of the plan.
    serial : int
        Increases with every accepted goal.
    """

    position: np.ndarray
    orientation: np.ndarray
    serial: int


@dataclass(frozen=True, eq=False)
class Snapshot:
    """Everything one plan uses, copied under the lock when the plan begins."""

    settings: NodeSettings
    settings_changed: bool
    obstacles: ObstacleSet
    obstacles_changed: bool
    obstacles_version: int
    obstacles_stamp_ns: int
    goal: Optional[Goal]
    goal_changed: bool
    start: np.ndarray
    start_source: str


class PlannerNode:
    """The planner node: parameters, intake, planning worker and outputs.

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
        When the parameters given at start-up are invalid.
    """

    def __init__(self, node_name: str = NODE_NAME, **node_options: Any) -> None:
        self.node = Node(node_name, **node_options)
        self._log = self.node.get_logger()
        self._param_values = declare_parameters(self.node)
        settings = settings_from_parameters(self._param_values)
        # Registered after declaring, so start-up values are checked once above, not per item.
        self.node.add_on_set_parameters_callback(self._validate_parameters)
        self.node.add_post_set_parameters_callback(self._apply_parameters)

        self._planner = Planner(settings.config)
        self._wake = threading.Condition()
        self._diagnostics_lock = threading.Lock()
        # State below is guarded by self._wake.
        self._settings = settings
        self._settings_changed = False
        self._markers: Dict[conv.MarkerKey, Any] = {}
        self._cloud: Optional[np.ndarray] = None
        self._obstacles = ObstacleSet()
        self._obstacles_serial = 0
        # Header stamp of the obstacle message that last changed the obstacles (0: none yet);
        # reported with every plan, so a reader can tell which map a plan was computed on.
        self._obstacles_stamp_ns = 0
        self._obstacles_changed = False
        self._goal: Optional[Goal] = None
        self._goal_serial = 0
        self._goal_changed = False
        self._start: Optional[np.ndarray] = None
        self._start_source = 'parameter'
        self._stopping = False
        # Worker-only state: outcome of the last plan attempt.
        self._last_result: Optional[PlanResult] = None
        self._last_goal_serial = -1
        # Worker-only: positions of the plan latched on ``plan`` (None: none, or withdrawn).
        self._latched_path: Optional[np.ndarray] = None
        # Worker-only: why the active goal must be planned again although nothing flagged it.
        self._replan_reason: Optional[str] = None
        self._markers_published_key: Optional[tuple] = None

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
        self._obstacles_sub = node.create_subscription(MarkerArray, 'obstacles',
                                                       self._on_obstacles, OBSTACLES_QOS)
        self._cloud_sub = node.create_subscription(PointCloud2, 'obstacle_cloud',
                                                   self._on_cloud, SENSOR_QOS)
        self._odom_sub = node.create_subscription(Odometry, 'odom', self._on_odom, SENSOR_QOS)
        self._start_sub = node.create_subscription(PoseStamped, 'start_pose',
                                                   self._on_start_pose, COMMAND_QOS)
        self._marker_timer = node.create_timer(_MARKER_PERIOD_S, self._publish_markers)
        self._worker = threading.Thread(target=self._run_worker, name='planner-worker',
                                        daemon=True)
        self._diag_name = f'{node.get_fully_qualified_name()}: global planner'

    # ---------------------------------------------------------------------------- lifecycle

    def start(self) -> None:
        """Compile the kernels and build the grid, then start the worker and log readiness."""
        self._planner.warm_up()
        self._worker.start()
        settings = self._settings
        config = settings.config
        grid = self._planner.grid
        self._log.info(
            f'{READY_TEXT}: frame {settings.frame_id!r}, grid {grid.shape[0]}x{grid.shape[1]}x'
            f'{grid.shape[2]} (delta {config.resolution} m, gamma {config.safety_margin} m, '
            f'eta {config.adaptive_threshold} m), algorithm {config.algorithm}; goals on '
            f'{self._goal_sub.topic_name}')

    def close(self, timeout_s: float = 2.0) -> None:
        """Stop the worker (a running plan finishes in the background) and destroy the node."""
        with self._wake:
            self._stopping = True
            self._wake.notify_all()
        if self._worker.is_alive():
            self._worker.join(timeout_s)
        self.node.destroy_node()

    # ---------------------------------------------------------------------------- parameters

    def _validate_parameters(self, parameters: List[Parameter]) -> SetParametersResult:
        """On-set callback: accept only a set of values that validates as a whole."""
        values = dict(self._param_values)
        owned = False
        for parameter in parameters:
            if parameter.name not in SPECS_BY_NAME:
                continue  # use_sim_time and friends belong to rclpy
            if parameter.type_ == Parameter.Type.NOT_SET:
                return SetParametersResult(
                    successful=False, reason=f'{parameter.name} cannot be undeclared')
            values[parameter.name] = parameter.value
            owned = True
        if owned:
            try:
                settings_from_parameters(values)
            except InvalidInputError as error:
                self._log.warning(f'parameter change refused: {error}')
                return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters: List[Parameter]) -> None:
        """Post-set callback: the new settings take effect at the next plan."""
        changed = {p.name: p.value for p in parameters if p.name in SPECS_BY_NAME}
        if not changed:
            return
        self._param_values.update(changed)
        settings = settings_from_parameters(self._param_values)
        with self._wake:
            previous = self._settings
            self._settings = settings
            if conv.normalize_frame(settings.frame_id) != conv.normalize_frame(
                    previous.frame_id):
                # Data stamped in the old frame means nothing in the new one.
                self._markers, self._cloud = {}, None
                self._obstacles = ObstacleSet()
                self._obstacles_serial += 1
                self._obstacles_stamp_ns = 0
                self._obstacles_changed = True
                self._goal, self._start, self._start_source = None, None, 'parameter'
                self._log.warning(f'frame_id changed to {settings.frame_id!r}: obstacles, '
                                  'start and goal cleared; republish them in the new frame')
            start_matters = (self._start is None
                             and not np.array_equal(settings.start, previous.start))
            if settings.config != previous.config or start_matters:
                self._settings_changed = True
            self._wake.notify_all()
        shown = ', '.join(f'{name} = {conv.format_value(_plain(value))}'
                          for name, value in changed.items())
        self._log.info(f'parameters set: {shown}; in force from the next plan')

    # ---------------------------------------------------------------------------- intake

    def _current_settings(self) -> NodeSettings:
        with self._wake:
            return self._settings

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
            self._goal_serial += 1
            self._goal = Goal(position, orientation, self._goal_serial)
            self._goal_changed = True
            self._wake.notify_all()

    def _on_obstacles(self, msg: MarkerArray) -> None:
        topic = self._obstacles_sub.topic_name
        settings = self._current_settings()
        with self._wake:
            markers, cloud = self._markers, self._cloud
        try:
            updated = conv.apply_marker_array(markers, msg, settings.frame_id,
                                              settings.max_obstacle_size)
            obstacles = conv.combine_obstacles(updated, cloud)
        except InvalidInputError as error:
            self._refuse(topic, error)
            return
        if conv.same_marker_obstacles(markers, updated):
            # An empty array, a DELETE of an unknown marker or the same map republished: keep
            # the inflated grid instead of rebuilding it for nothing.
            return
        with self._wake:
            # Only this (executor) thread writes markers and cloud, so nothing changed since.
            self._markers, self._obstacles = updated, obstacles
            self._obstacles_serial += 1
            self._obstacles_stamp_ns = max(
                (conv.time_to_ns(marker.header.stamp) for marker in msg.markers), default=0)
            self._obstacles_changed = True
            self._wake.notify_all()

    def _on_cloud(self, msg: PointCloud2) -> None:
        topic = self._cloud_sub.topic_name
        settings = self._current_settings()
        with self._wake:
            markers = self._markers
        try:
            points = conv.cloud_to_points(msg, settings.frame_id,
                                          settings.cloud_non_finite == 'drop',
                                          settings.max_cloud_points)
            obstacles = conv.combine_obstacles(markers, points)
        except InvalidInputError as error:
            self._refuse(topic, error)
            return
        with self._wake:
            self._cloud, self._obstacles = points, obstacles
            self._obstacles_serial += 1
            self._obstacles_stamp_ns = conv.time_to_ns(msg.header.stamp)
            self._obstacles_changed = True
            self._wake.notify_all()

    def _on_odom(self, msg: Odometry) -> None:
        topic = self._odom_sub.topic_name
        try:
            position = conv.odometry_to_point(msg, self._current_settings().frame_id, topic)
        except InvalidInputError as error:
            self._refuse(topic, error, throttle=True)
            return
        with self._wake:
            self._start, self._start_source = position, 'odom'

    def _on_start_pose(self, msg: PoseStamped) -> None:
        topic = self._start_sub.topic_name
        try:
            position = conv.pose_stamped_to_point(msg, self._current_settings().frame_id,
                                                  topic)
        except InvalidInputError as error:
            self._refuse(topic, error)
            return
        with self._wake:
            self._start, self._start_source = position, 'start_pose'

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

    # ---------------------------------------------------------------------------- worker

    def _take_snapshot(self) -> Optional[Snapshot]:
        """Wait for work; copy what the next step needs and clear the change flags."""
        with self._wake:
            self._wake.wait_for(lambda: self._stopping or self._goal_changed
                                or self._settings_changed or self._obstacles_changed)
            if self._stopping:
                return None
            settings = self._settings
            if self._start is not None:
                start, source = self._start, self._start_source
            else:
                start, source = settings.start, 'parameter'
            snapshot = Snapshot(
                settings=settings, settings_changed=self._settings_changed,
                obstacles=self._obstacles, obstacles_changed=self._obstacles_changed,
                obstacles_version=self._obstacles_serial,
                obstacles_stamp_ns=self._obstacles_stamp_ns,
                goal=self._goal, goal_changed=self._goal_changed, start=start,
                start_source=source)
            self._settings_changed = self._obstacles_changed = self._goal_changed = False
            return snapshot

    def _run_worker(self) -> None:
        """Planning thread: the only thread that touches the Planner."""
        while True:
            snapshot = self._take_snapshot()
            if snapshot is None:
                return
            try:
                self._step(snapshot)
            except Exception as error:  # noqa: BLE001 - a bug must not kill the planner
                if self._is_stopping():
                    return  # publishers are gone during shutdown; nothing left to report
                self._log.error(f'planning step failed: {error!r}\n{traceback.format_exc()}')
                values = {'event': 'plan', 'status': 'error', 'status_code': NAV2_UNKNOWN,
                          'reason': repr(error)}
                values.update(self._settings_values(snapshot.settings))
                try:
                    self._publish_diagnostics(self.node.get_clock().now().nanoseconds,
                                              DiagnosticStatus.ERROR,
                                              f'planning failed: {error!r}', values)
                except Exception:  # noqa: BLE001 - shutting down
                    return

    def _is_stopping(self) -> bool:
        with self._wake:
            return self._stopping

    def _step(self, snap: Snapshot) -> None:
        """Apply changed settings/obstacles to the planner, then plan if something requires it."""
        if snap.settings_changed and snap.settings.config != self._planner.config:
            self._planner.set_config(snap.settings.config)
        if snap.obstacles_changed and snap.obstacles is not self._planner.obstacles:
            self._planner.set_obstacles(snap.obstacles)
        goal = snap.goal
        if goal is None:
            return
        # A goal not attempted yet (normally goal_changed; also after a failed step).
        if goal.serial != self._last_goal_serial:
            reason = 'new goal'
        elif self._replan_reason is not None:
            reason = self._replan_reason
        elif snap.settings_changed:
            reason = 'parameters changed'
        elif snap.obstacles_changed and snap.settings.replan_on_obstacle_change:
            reason = self._obstacle_replan_reason(snap)
            if reason is None:
                return
        else:
            return
        self._plan(snap, goal, reason)

    def _obstacle_replan_reason(self, snap: Snapshot) -> Optional[str]:
        """Why new obstacles require a replan of the active goal, or None if they do not."""
        last = self._last_result
        if last is None:
            return None
        if not last.ok:
            return 'obstacles changed' if last.status in _RETRY_ON_OBSTACLES else None
        if self._clear_ahead(last.smoothed_path, snap):
            return None
        return 'obstacles changed and the current path is no longer clear'

    def _clear_ahead(self, path: np.ndarray, snap: Snapshot,
                     obstacles: Optional[ObstacleSet] = None) -> bool:
        """True when the part of ``path`` still ahead of the vehicle keeps gamma from
        ``obstacles`` (default: the planner's)."""
        if snap.start_source != 'parameter' and len(path) > 1:
            # Only the part still ahead of the vehicle matters.
            nearest = int(np.argmin(np.linalg.norm(path - snap.start, axis=1)))
            path = path[nearest:]
        if obstacles is None:
            return self._planner.path_is_clear(path)
        if len(path) == 0 or obstacles.is_empty():
            return True
        config = snap.settings.config
        dense = densify(np.asarray(path, dtype=np.float64), config.resolution / 20.0)
        return bool(np.min(obstacles.distance(dense)) >= config.safety_margin)

    def _plan(self, snap: Snapshot, goal: Goal, reason: str) -> None:
        settings = snap.settings
        self._replan_reason = None
        result = self._planner.plan(snap.start, goal.position)
        checked = (snap.obstacles_version, snap.obstacles_stamp_ns)
        if result.ok:
            with self._wake:
                newest = (self._obstacles, self._obstacles_serial, self._obstacles_stamp_ns)
            if newest[1] != checked[0]:
                # Obstacles arrived while planning: publish only a plan that keeps gamma from
                # them too; otherwise plan again on them at once.
                if not self._clear_ahead(result.smoothed_path, snap, newest[0]):
                    self._discard(snap, goal, newest[1], newest[2])
                    return
                checked = newest[1:]
        stamp_ns = self.node.get_clock().now().nanoseconds
        self._last_result, self._last_goal_serial = result, goal.serial
        frame = settings.frame_id
        if result.ok:
            orientation = tuple(float(v) for v in goal.orientation)
            # Serialised from the arrays: the messages of conv.plan_to_path and friends, without
            # building hundreds of message objects (milliseconds per plan).
            self._plan_pub.publish(cdr.serialized_plan_path(result, frame, stamp_ns, orientation))
            self._unsmoothed_pub.publish(
                cdr.serialized_unsmoothed_path(result, frame, stamp_ns, orientation))
            self._trajectory_pub.publish(
                cdr.serialized_trajectory(result, frame, stamp_ns, orientation))
            self._latched_path = result.smoothed_path
            level = DiagnosticStatus.OK
            self._log.info(
                f'plan ({reason}): {result.smoothed_length_m:.2f} m smoothed, '
                f'{result.expanded_nodes} nodes expanded in {result.planning_time_s:.3f} s, '
                f'min clearance {result.min_clearance_m:.3f} m, start from {snap.start_source}')
        else:
            level = DiagnosticStatus.ERROR
            self._log.warning(f'no plan ({reason}): {result.status.value} '
                              f'(code {NAV2_CODE_BY_STATUS[result.status]}): {result.message}')
        withdrawn = False
        if (not result.ok and self._latched_path is not None
                and not self._clear_ahead(self._latched_path, snap)):
            # The latched plan now collides and nothing replaces it: a controller, even one
            # that subscribes later, must not fly it. Empty messages withdraw it.
            self._withdraw_plan(frame, stamp_ns)
            withdrawn = True
        values = conv.plan_diagnostic_values(result, snap.start_source, {
            'reason': reason, 'plan_withdrawn': withdrawn, 'obstacles': len(snap.obstacles),
            'obstacles_version': snap.obstacles_version,
            'obstacles_stamp': snap.obstacles_stamp_ns, 'obstacles_checked_version': checked[0],
            'obstacles_checked_stamp': checked[1], 'frame_id': frame,
            'message': result.message})
        self._publish_diagnostics(stamp_ns, level, f'{result.status.value}: {result.message}',
                                  values)

    def _discard(self, snap: Snapshot, goal: Goal, version: int, stamp_ns: int) -> None:
        """Drop a plan that collides with obstacles received while it was computed.

        Nothing is published but a WARN status (``event: plan_discarded``); the goal is planned
        again on the new obstacles right away (their arrival has woken the worker already).
        """
        self._last_result, self._last_goal_serial = None, goal.serial
        self._replan_reason = 'obstacles changed while planning and collided with the plan'
        text = (f'plan discarded: obstacles (version {version}) arrived while planning '
                f'(on version {snap.obstacles_version}) and the new plan does not keep gamma '
                'from them; planning again')
        self._log.info(text)
        values = {'event': 'plan_discarded', 'status': 'discarded', 'reason': text,
                  'obstacles_version': snap.obstacles_version,
                  'obstacles_stamp': snap.obstacles_stamp_ns,
                  'obstacles_checked_version': version, 'obstacles_checked_stamp': stamp_ns,
                  'goal': goal.position}
        values.update(self._settings_values(snap.settings))
        self._publish_diagnostics(self.node.get_clock().now().nanoseconds,
                                  DiagnosticStatus.WARN, text, values)

    def _withdraw_plan(self, frame: str, stamp_ns: int) -> None:
        """Replace the latched plan, unsmoothed plan and trajectory by empty ones."""
        empty = np.empty((0, 3))
        self._plan_pub.publish(conv.points_to_path(empty, frame, stamp_ns))
        self._unsmoothed_pub.publish(conv.points_to_path(empty, frame, stamp_ns))
        self._trajectory_pub.publish(conv.empty_trajectory(frame, stamp_ns))
        self._latched_path = None
        self._log.warning('withdrew the last plan (published empty ones): it is no longer '
                          'clear of the obstacles by gamma and no new plan replaces it')

    # ---------------------------------------------------------------------------- outputs

    def _settings_values(self, settings: NodeSettings) -> Dict[str, object]:
        config = settings.config
        return {'algorithm': config.algorithm, 'resolution_m': config.resolution,
                'safety_margin_m': config.safety_margin,
                'adaptive_threshold_m': config.adaptive_threshold,
                'frame_id': settings.frame_id}

    def _publish_diagnostics(self, stamp_ns: int, level: bytes, message: str,
                             values: Mapping[str, object]) -> None:
        msg = conv.diagnostic_array(stamp_ns, self._diag_name, 'uav_global_planner', level,
                                    message, values)
        # Both the executor thread (refusals) and the worker (plans) publish here.
        with self._diagnostics_lock:
            self._diagnostics_pub.publish(msg)

    def _publish_markers(self) -> None:
        """Timer: publish the obstacles in use when they changed and someone listens."""
        with self._wake:
            obstacles, serial, settings = (self._obstacles, self._obstacles_serial,
                                           self._settings)
        key = (serial, settings.config.safety_margin, settings.frame_id)
        if key == self._markers_published_key:
            return
        # Building a large marker array is wasted work when nobody looks.
        if self._markers_pub.get_subscription_count() == 0:
            return
        self._markers_pub.publish(conv.obstacle_markers(
            obstacles, settings.frame_id, self.node.get_clock().now().nanoseconds,
            settings.config.safety_margin))
        self._markers_published_key = key


def main(args: Optional[List[str]] = None) -> int:
    """Entry point of ``planner_node``: run until SIGINT/SIGTERM, then exit with 0.

    Returns
    -------
    int
        0 after a clean shutdown, :data:`EXIT_BAD_SETTINGS` for invalid start-up parameters.
    """
    rclpy.init(args=args)
    planner: Optional[PlannerNode] = None
    code = 0
    try:
        planner = PlannerNode()
        executor = SingleThreadedExecutor()
        executor.add_node(planner.node)
        planner.start()
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (InvalidInputError, ParameterException) as error:
        # Invalid --params-file or -p values (out of range, wrong type, failing validation):
        # say which, and do not start.
        print(f'planner_node: invalid parameters: {error}', file=sys.stderr)
        code = EXIT_BAD_SETTINGS
    finally:
        # A second Ctrl-C during clean-up must not print a traceback.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        if planner is not None:
            planner.close()
        rclpy.try_shutdown()
    return code


if __name__ == '__main__':
    sys.exit(main())
