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
``start_pose`` (in)       geometry_msgs/PoseStamped       start_pose; else the ``start`` parameter)
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
  updates the inflated grid tile by tile (:class:`~uav_global_planner.core.live_map.
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

The diagnostics of a plan name the map it was computed on (``obstacles_version``, and
``obstacles_stamp``: the header stamp of the map message that last changed the obstacles), the
newest map it was checked against before publishing (``obstacles_checked_*``) and the state of
every map source (``map_sources``, ``map_refused``: a plan made while a source's newest message
was refused says so, at WARN).
"""

from collections import deque
from dataclasses import dataclass, field, replace
import math
import signal
import sys
import threading
import time
import traceback
from typing import Any, Callable, Deque, Dict, List, Mapping, Optional, Tuple

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
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import PointCloud2
from trajectory_msgs.msg import MultiDOFJointTrajectory
from visualization_msgs.msg import MarkerArray

from uav_global_planner.core.budget import PlanStage
from uav_global_planner.core.config import (ALGORITHMS, PlannerConfig, SMOOTHING_MODES,
                                            validate_config)
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.grid import as_point
from uav_global_planner.core.live_map import LiveMap, LiveMapBuilder, UNCHANGED
from uav_global_planner.core.mapfiles import load_prior_map, MapPoints
from uav_global_planner.core.planner import certify_plan, ClearanceVerdict, Planner
from uav_global_planner.core.result import PlanResult
from uav_global_planner.core.status import (NAV2_CODE_BY_STATUS, NAV2_GOAL_OUTSIDE_MAP,
                                            NAV2_UNKNOWN, PlanStatus)
from uav_global_planner.ros import cdr
from uav_global_planner.ros import conversions as conv
from uav_global_planner.ros.mission_service import MissionExportService
from uav_global_planner.ros.nav2_interfaces import nearest_free_node, PlannerInterfaces
from uav_global_planner.ros.qos import (CLOUD_QOS_BY_RELIABILITY, COMMAND_QOS, DIAGNOSTICS_QOS,
                                        LATCHED_QOS, OBSTACLES_QOS, SENSOR_QOS)

#: Name of the node unless remapped with ``--ros-args -r __node:=...``.
NODE_NAME = 'global_planner'

#: Logged once the kernels are compiled and the node takes requests; tests wait for it.
READY_TEXT = 'planner ready'

#: Marker-publishing check period [s]: markers go out only when someone subscribes.
_MARKER_PERIOD_S = 0.5

#: Period of the ``map_status`` diagnostics [s] (as diagnostic_updater's 1 Hz).
_MAP_STATUS_PERIOD_S = 1.0

#: Period of the check for another node of the same fully qualified name [s].
_DUPLICATE_CHECK_PERIOD_S = 2.0

#: Length of the curve ahead of the vehicle certified first when a map arrives [m].
_CHECK_AHEAD_M = 30.0

#: Consecutive plans dropped because the vehicle moved away from their start while they were
#: computed; after that many the plan is published anyway (with a note), so a slow plan behind
#: a fast vehicle still gives one.
_MAX_DRIFT_REPLANS = 3

#: Outcomes that may change when the obstacles change, so a failed goal is retried then.
_RETRY_ON_OBSTACLES = (PlanStatus.NO_VALID_PATH, PlanStatus.TIMEOUT, PlanStatus.START_OCCUPIED,
                       PlanStatus.GOAL_OCCUPIED)

#: Exit code for settings that are invalid at start-up.
EXIT_BAD_SETTINGS = 2

CLOUD_NON_FINITE_MODES = ('drop', 'refuse')

#: The map sources of the node, as named in ``required_map_sources`` and the diagnostics.
MAP_SOURCES = ('obstacles', 'obstacle_cloud', 'map_file')

#: Parameters read once at start-up: changing them needs a restart.
STARTUP_ONLY = ('cloud_qos_reliability', 'map_file', 'map_downsample')

#: Diagnostics status of a goal refused because the map is missing.
NO_MAP_STATUS = 'no_map'


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
                  'Manhattan beyond eta), octile (optimal, fewest expansions) or weighted '
                  '(cost <= search_weight x optimum).',
                  'one of: ' + ', '.join(ALGORITHMS), field='algorithm'),
    ParameterSpec('search_weight', _DEFAULTS.search_weight,
                  'Suboptimality bound w of the weighted algorithm [-]: its path costs at most '
                  'w times the optimum.', '1 <= w <= 10', float_range=(1.0, 10.0),
                  field='search_weight'),
    ParameterSpec('max_expansions', _DEFAULTS.max_expansions,
                  'Search budget in expanded nodes [-]; 0 = no limit. Exceeding it reports '
                  'TIMEOUT (207).', '>= 0', int_range=(0, _INT_MAX), field='max_expansions'),
    ParameterSpec('max_planning_time', _DEFAULTS.max_planning_time,
                  'Time budget of a whole plan [s]: grid build, search, smoothing and timing; '
                  '0 = no limit. Exceeding it reports TIMEOUT (207) naming the stage.', '>= 0 s',
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
    ParameterSpec('map_file', '',
                  'Static prior map: a .pcd, .ply, .las, .laz, .bt or .npy file of occupied '
                  'points in frame_id [m], combined with the obstacles and obstacle_cloud '
                  'topics; empty for none. Read at start-up.', 'a readable map file, or empty'),
    ParameterSpec('map_downsample', 0.0,
                  'Voxel downsampling cell of map_file [m]: one point (the cell centre) per '
                  'occupied cell; 0 = none. gamma grows by the map margin (cell*sqrt(3)/2, plus '
                  "an OctoMap's cell half-diagonal) so paths keep gamma from the map as read.",
                  '0 or > 0 m', float_range=(0.0, 100.0)),
    ParameterSpec('cloud_qos_reliability', 'reliable',
                  'Reliability of the obstacle_cloud subscription: reliable (large clouds '
                  'arrive whole; needs a reliable publisher) or best_effort (for best-effort '
                  'sensor publishers; clouds may be lost). Read at start-up.',
                  'one of: ' + ', '.join(CLOUD_QOS_BY_RELIABILITY)),
    ParameterSpec('plan_without_map', False,
                  'Plan goals before any map source has delivered (open air). By default such '
                  'a goal is refused with the reason, as planning through an unknown map '
                  'would be reported as safe.'),
    ParameterSpec('required_map_sources', ['any'],
                  'Map sources that must have delivered before goals are planned: any (at least '
                  'one of them) or a list of obstacles, obstacle_cloud, map_file (each of '
                  'them).', "['any'] or a subset of obstacles, obstacle_cloud, map_file"),
    ParameterSpec('start_tolerance', 0.5,
                  'A start outside the bounds (below the floor: a landed vehicle) or within the '
                  'safety margin by at most this distance [m] is moved to the nearest free '
                  'point, and the plan says so; about delta. 0 = never.', '>= 0 m',
                  float_range=(0.0, 100.0)),
    ParameterSpec('start_replan_distance', 2.0,
                  "A plan whose start is farther than this from the vehicle's newest position "
                  '(odom or start_pose) when it is ready is made again from there [m]; 0 = '
                  'never.', '>= 0 m', float_range=(0.0, 1.0e6)),
)


SPECS_BY_NAME: Dict[str, ParameterSpec] = {spec.name: spec for spec in PARAMETER_SPECS}


@dataclass(frozen=True, eq=False)
class NodeSettings:
    """The validated values of every parameter of the node.

    Attributes
    ----------
    config : PlannerConfig
        Planner settings, validated by :func:`validate_config` (as in the command-line tool);
        gamma includes the prior map's margin.
    frame_id : str
    start : numpy.ndarray, shape (3,)
        Start from the parameter [m].
    max_obstacle_size : float
        [m]
    max_cloud_points : int
    cloud_non_finite : str
        ``'drop'`` or ``'refuse'``.
    replan_on_obstacle_change : bool
    map_file : str
    map_downsample : float
        [m]
    cloud_qos_reliability : str
        ``'reliable'`` or ``'best_effort'``.
    plan_without_map : bool
    required_map_sources : tuple of str
        ``('any',)`` or a subset of :data:`MAP_SOURCES`.
    start_tolerance : float
        [m]
    start_replan_distance : float
        [m], 0 = off.
    """

    config: PlannerConfig
    frame_id: str
    start: np.ndarray
    max_obstacle_size: float
    max_cloud_points: int
    cloud_non_finite: str
    replan_on_obstacle_change: bool
    map_file: str = ''
    map_downsample: float = 0.0
    cloud_qos_reliability: str = 'reliable'
    plan_without_map: bool = False
    required_map_sources: Tuple[str, ...] = ('any',)
    start_tolerance: float = 0.5
    start_replan_distance: float = 2.0


def _plain(value: Any) -> Any:
    """Parameter value as plain Python (rclpy gives arrays as ``array.array``)."""
    if isinstance(value, (list, tuple)) or hasattr(value, 'tolist'):
        items = list(value.tolist() if hasattr(value, 'tolist') else value)
        if items and all(isinstance(item, str) for item in items):
            return items
        return [float(v) for v in items]
    return value


def _finite_at_least_zero(values: Mapping[str, Any], name: str) -> float:
    number = float(values[name])
    if not math.isfinite(number) or number < 0.0:
        raise InvalidInputError(f'{name} must be a finite number >= 0 m, got {number}')
    return number


def settings_from_parameters(values: Mapping[str, Any],
                             map_margin_m: float = 0.0) -> NodeSettings:
    """Build and validate the settings from parameter values keyed by parameter name.

    Parameters
    ----------
    values : mapping
    map_margin_m : float
        Margin of the prior map [m] (:attr:`MapPoints.margin_m`), added to gamma so paths keep
        gamma from the map as it was read.

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
    if map_margin_m:
        config = config.with_changes(safety_margin=config.safety_margin + map_margin_m)
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
    reliability = values['cloud_qos_reliability']
    if reliability not in CLOUD_QOS_BY_RELIABILITY:
        raise InvalidInputError(
            f'cloud_qos_reliability must be one of {", ".join(CLOUD_QOS_BY_RELIABILITY)}, got '
            f'{reliability!r}')
    map_file = values['map_file']
    if not isinstance(map_file, str):
        raise InvalidInputError(f'map_file must be a path (a string), got {map_file!r}')
    required = tuple(_plain(values['required_map_sources']))
    if required != ('any',):
        unknown = [name for name in required if name not in MAP_SOURCES]
        if not required or unknown or len(set(required)) != len(required):
            raise InvalidInputError(
                "required_map_sources must be ['any'] or distinct names among "
                f'{", ".join(MAP_SOURCES)}, got {list(required)!r}')
        if 'map_file' in required and not map_file.strip():
            raise InvalidInputError(
                'required_map_sources lists map_file, but no map_file is set')
    return NodeSettings(config=config, frame_id=str(frame_id), start=start,
                        max_obstacle_size=size, max_cloud_points=points,
                        cloud_non_finite=mode,
                        replan_on_obstacle_change=bool(values['replan_on_obstacle_change']),
                        map_file=map_file,
                        map_downsample=_finite_at_least_zero(values, 'map_downsample'),
                        cloud_qos_reliability=reliability,
                        plan_without_map=bool(values['plan_without_map']),
                        required_map_sources=required,
                        start_tolerance=_finite_at_least_zero(values, 'start_tolerance'),
                        start_replan_distance=_finite_at_least_zero(values,
                                                                    'start_replan_distance'))


def declare_parameters(node: Node) -> Dict[str, Any]:
    """Declare every parameter of :data:`PARAMETER_SPECS`; return the values in force
    (defaults overridden by ``--params-file``/``-p``)."""
    declared = node.declare_parameters('', [(spec.name, spec.default, spec.descriptor())
                                            for spec in PARAMETER_SPECS])
    return {parameter.name: parameter.value for parameter in declared}


# --------------------------------------------------------------------------------------------
# Shared state between the executor thread, the map intake and the planning worker
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
    """Everything one plan uses, copied under the lock when the plan begins.

    ``obstacles`` and ``obstacles_version`` are those of ``map``, the consistent map (obstacles
    and inflated grid) the plan runs on.
    """

    settings: NodeSettings
    settings_changed: bool
    obstacles: Any
    obstacles_changed: bool
    obstacles_version: int
    obstacles_stamp_ns: int
    goal: Optional[Goal]
    goal_changed: bool
    start: np.ndarray
    start_source: str
    map: Optional[LiveMap] = None
    replan_reason: Optional[str] = None


@dataclass
class SourceState:
    """What one map source has delivered (guarded by the node's lock).

    Attributes
    ----------
    received : int
        Messages that arrived (clouds the intake had no time for included).
    accepted, refused, superseded : int
        Messages taken into the map, refused (with ``last_refusal``), or dropped unread for a
        newer cloud.
    refused_last : bool
        The newest message was refused: the map holds older data of this source (or none).
    last_refusal : str
    last_stamp_ns : int
        Header stamp of the newest accepted message.
    """

    received: int = 0
    accepted: int = 0
    refused: int = 0
    superseded: int = 0
    refused_last: bool = False
    last_refusal: str = ''
    last_stamp_ns: int = 0

    @property
    def delivered(self) -> bool:
        return self.accepted > 0

    def summary(self) -> str:
        if not self.delivered and not self.refused:
            return 'nothing received'
        text = f'{self.accepted} accepted'
        if self.refused:
            text += f', {self.refused} refused'
        if self.superseded:
            text += f', {self.superseded} superseded by newer'
        return text


@dataclass
class _InForce:
    """The plan latched on ``plan`` (guarded by the publish lock)."""

    result: PlanResult
    frame_id: str
    stamp_ns: int
    start_source: str
    checked_version: int
    goal_serial: Optional[int] = None     # None: a Nav2 request's plan


@dataclass
class _Inbox:
    """Map messages waiting for the intake (guarded by the intake's condition)."""

    markers: Deque[Tuple[bytes, int]] = field(default_factory=deque)
    cloud: Optional[Tuple[bytes, int]] = None
    reconfigure: bool = False
    stopping: bool = False


class PlannerNode:
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
        When the parameters given at start-up are invalid, or ``map_file`` cannot be read.
    """

    def __init__(self, node_name: str = NODE_NAME, **node_options: Any) -> None:
        self.node = Node(node_name, **node_options)
        self._log = self.node.get_logger()
        self._param_values = declare_parameters(self.node)
        # Validated before the map file is read: a typo elsewhere is reported first.
        first = settings_from_parameters(self._param_values)
        self._prior: Optional[MapPoints] = load_prior_map(first.map_file, first.map_downsample)
        self._map_margin_m = self._prior.margin_m if self._prior is not None else 0.0
        settings = settings_from_parameters(self._param_values, self._map_margin_m)
        # Registered after declaring, so start-up values are checked once above, not per item.
        self.node.add_on_set_parameters_callback(self._validate_parameters)
        self.node.add_post_set_parameters_callback(self._apply_parameters)

        self._planner = Planner(settings.config)
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
        self._map: LiveMap = self._builder.update()
        self._map_changed = False
        # Header stamp of the map message that last changed the obstacles (0: none yet), and
        # of the newest map message taken in; reported with every plan.
        self._obstacles_stamp_ns = 0
        self._map_stamp_ns = 0
        self._sources: Dict[str, SourceState] = {name: SourceState() for name in MAP_SOURCES}
        if self._prior is not None:
            self._sources['map_file'] = SourceState(received=1, accepted=1)
        self._goal: Optional[Goal] = None
        self._goal_serial = 0
        self._goal_changed = False
        self._start: Optional[np.ndarray] = None
        self._start_source = 'parameter'
        self._stopping = False
        # A replan the worker owes the active goal (the plan in force was withdrawn, or it
        # started at the start parameter and the vehicle's position arrived): the reason.
        self._replan_request: Optional[str] = None
        # The map the worker plans on (its mask is never rewritten while held).
        self._worker_map: Optional[LiveMap] = None
        # Start source of the plan in force ('parameter', 'odom', ...); None: none in force.
        self._in_force_source: Optional[str] = None
        self._intake_times: Tuple[float, float, float] = (0.0, 0.0, 0.0)
        # Seconds from a cloud's header stamp to its map being handed to the worker, since the
        # last map_status (the stamp is the publisher's clock: meaningful on one machine).
        self._cloud_latencies: List[float] = []
        # Worker-only state: outcome of the last plan attempt.
        self._last_result: Optional[PlanResult] = None
        self._last_goal_serial = -1
        # Worker-only: why the active goal must be planned again although nothing flagged it.
        self._replan_reason: Optional[str] = None
        # Worker-only: the map applied to the planner, and plans dropped in a row because the
        # vehicle moved away from their start while they were computed.
        self._applied_map: Optional[LiveMap] = None
        self._grid_from_map = False
        self._drift_replans = 0
        # Guarded by _publish_lock: the plan latched on ``plan`` (None: none, or withdrawn).
        self._latched: Optional[PlanResult] = None
        self._in_force: Optional[_InForce] = None
        self._markers_published_key: Optional[tuple] = None
        # Intake: its inbox (guarded by _intake_cv) and its own state.
        self._intake_cv = threading.Condition()
        self._inbox = _Inbox()
        self._intake_markers: Dict[conv.MarkerKey, Any] = {}
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
        self._jobs: List[Callable[[Planner, Snapshot], None]] = []
        self._nav2 = PlannerInterfaces(self)
        self._mission_export = MissionExportService(self)

    # ---------------------------------------------------------------------------- lifecycle

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
            prior = (f'; prior map {self._prior.source}: {len(self._prior.points)} points '
                     f'(margin {self._prior.margin_m:.3f} m added to gamma)')
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
            if (parameter.name in STARTUP_ONLY
                    and _plain(parameter.value) != _plain(self._param_values[parameter.name])):
                reason = (f'{parameter.name} is read at start-up; restart the node to change '
                          'it')
                self._log.warning(f'parameter change refused: {reason}')
                return SetParametersResult(successful=False, reason=reason)
            values[parameter.name] = parameter.value
            owned = True
        if owned:
            try:
                settings_from_parameters(values, self._map_margin_m)
            except InvalidInputError as error:
                self._log.warning(f'parameter change refused: {error}')
                return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters: List[Parameter]) -> None:
        """Post-set callback: the new settings take effect at the next plan; a running plan
        with other settings is cancelled and made again."""
        changed = {p.name: p.value for p in parameters if p.name in SPECS_BY_NAME}
        if not changed:
            return
        self._param_values.update(changed)
        settings = settings_from_parameters(self._param_values, self._map_margin_m)
        frame_changed = False
        with self._wake:
            previous = self._settings
            self._settings = settings
            if conv.normalize_frame(settings.frame_id) != conv.normalize_frame(
                    previous.frame_id):
                # Data stamped in the old frame means nothing in the new one; the intake
                # drops the map (the prior map file stays: it is in the planning frame).
                frame_changed = True
                self._goal, self._start, self._start_source = None, None, 'parameter'
                for name in ('obstacles', 'obstacle_cloud'):
                    self._sources[name] = SourceState()
            start_matters = (self._start is None
                             and not np.array_equal(settings.start, previous.start))
            if settings.config != previous.config or start_matters:
                self._settings_changed = True
            self._wake.notify_all()
        with self._intake_cv:
            self._inbox.reconfigure = True
            self._intake_cv.notify_all()
        if frame_changed:
            self._log.warning(f'frame_id changed to {settings.frame_id!r}: obstacles, '
                              'start and goal cleared; republish them in the new frame')
            # A plan in the old frame must not stay in force.
            self._withdraw_in_force(settings.frame_id,
                                    f'frame_id changed to {settings.frame_id!r}', None)
        shown = ', '.join(f'{name} = {conv.format_value(_plain(value))}'
                          for name, value in changed.items())
        self._log.info(f'parameters set: {shown}; in force from the next plan')

    # ---------------------------------------------------------------------------- intake

    def _current_settings(self) -> NodeSettings:
        with self._wake:
            return self._settings

    def _map_missing(self, settings: NodeSettings) -> Optional[str]:
        """Why goals cannot be planned yet for want of a map, or None (caller holds _wake)."""
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
                    or self._inbox.cloud is not None or self._inbox.reconfigure)
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
            try:
                messages = [self._deserialize(data, MarkerArray, 'obstacles')
                            for data, _ in markers]
                cloud_msg = (None if cloud is None
                             else self._deserialize(cloud[0], PointCloud2, 'obstacle_cloud'))
                self._intake_step([m for m in messages if m is not None], cloud_msg,
                                  reconfigure)
            except Exception as error:  # noqa: BLE001 - a bug must not stop the intake
                if self._is_stopping():
                    return
                self._log.error(f'map intake failed: {error!r}\n{traceback.format_exc()}')

    def _deserialize(self, data: bytes, msg_type: Any, source: str) -> Optional[Any]:
        try:
            return deserialize_message(data, msg_type)
        except Exception as error:  # noqa: BLE001 - a malformed message is refused
            topic = (self._obstacles_sub if source == 'obstacles' else self._cloud_sub).topic_name
            self._refuse_map(source, topic, InvalidInputError(
                f'{source} message could not be deserialised ({error})'))
            return None

    def _intake_step(self, marker_msgs: List[MarkerArray], cloud_msg: Optional[PointCloud2],
                     reconfigure: bool) -> None:
        """Apply marker arrays (in order), a cloud and new settings; publish the map they give
        and re-check the plan in force against it."""
        settings = self._current_settings()
        frame = conv.normalize_frame(settings.frame_id)
        cloud: Any = UNCHANGED
        shapes_before = self._intake_markers
        if frame != self._intake_frame:
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
            live = self._builder.update(shapes=markers if shapes_changed else None,
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
        # request for its replacement reach the worker together with the map.
        withdrawn = self._recheck_in_force(live) if live.version != previous.version else None
        now_ns = self.node.get_clock().now().nanoseconds
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
            self._wake.notify_all()
        # A plan published meanwhile was checked against the previous map: check it too.
        if live.version != previous.version:
            withdrawn = self._recheck_in_force(live)
            with self._wake:
                self._request_replacement(withdrawn, settings)
                self._wake.notify_all()

    def _request_replacement(self, withdrawn: Optional[_InForce],
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

    def _recheck_in_force(self, live: LiveMap) -> Optional[_InForce]:
        """Certify the plan in force against a new map at once (ahead of the vehicle first);
        withdraw it there and then if the map makes it collide. Returns the withdrawn plan."""
        with self._publish_lock:
            in_force = self._in_force
            if in_force is None or in_force.checked_version >= live.version:
                return None
            with self._wake:
                position = self._start if self._start_source != 'parameter' else None
            result = in_force.result
            verdict = certify_plan(result, live.obstacles, result.safety_margin,
                                   result.resolution, position, ahead_m=_CHECK_AHEAD_M)
            in_force.checked_version = live.version
            if verdict.clear:
                return None
            self._withdraw_in_force(in_force.frame_id, 'the new map makes it collide', verdict,
                                    live)
            return in_force

    def _withdraw_in_force(self, frame: str, why: str, verdict: Optional[ClearanceVerdict],
                           live: Optional[LiveMap] = None) -> None:
        """Withdraw the plan in force (if any) with empty messages and an ERROR status."""
        with self._publish_lock:
            if self._in_force is None:
                return
            in_force = self._in_force
            stamp_ns = self.node.get_clock().now().nanoseconds
            self._withdraw_plan(frame, stamp_ns, log=False)  # logged below, with the reason
        where = ''
        values: Dict[str, object] = {'event': 'plan_withdrawn', 'status': 'withdrawn',
                                     'plan_withdrawn': True, 'reason': why,
                                     'plan_stamp': in_force.stamp_ns}
        if verdict is not None and verdict.blocked_at is not None:
            where = (f' near {np.round(verdict.blocked_at, 3).tolist()}, '
                     f'{verdict.blocked_ahead_m:.1f} m ahead')
            values['blocked_at'] = verdict.blocked_at
            values['blocked_ahead_m'] = verdict.blocked_ahead_m
        if live is not None:
            values['obstacles_version'] = live.version
        text = (f'plan in force withdrawn (empty plan and trajectory published: hold position): '
                f'{why}{where}')
        self._log.error(text)
        values.update(self._settings_values(self._current_settings()))
        values['message'] = text
        self._publish_diagnostics(stamp_ns, DiagnosticStatus.ERROR, text, values)

    def _on_odom(self, msg: Odometry) -> None:
        topic = self._odom_sub.topic_name
        try:
            position = conv.odometry_to_point(msg, self._current_settings().frame_id, topic)
        except InvalidInputError as error:
            self._refuse(topic, error, throttle=True)
            return
        self._set_start(position, 'odom')

    def _on_start_pose(self, msg: PoseStamped) -> None:
        topic = self._start_sub.topic_name
        try:
            position = conv.pose_stamped_to_point(msg, self._current_settings().frame_id,
                                                  topic)
        except InvalidInputError as error:
            self._refuse(topic, error)
            return
        self._set_start(position, 'start_pose')

    def _set_start(self, position: np.ndarray, source: str) -> None:
        with self._wake:
            self._start, self._start_source = position, source
            if self._in_force_source == 'parameter' and self._goal is not None:
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

    # ---------------------------------------------------------------------------- worker

    def _take_snapshot(self) -> Optional[Snapshot]:
        """Wait for work; copy what the next step needs and clear the change flags."""
        with self._wake:
            self._wake.wait_for(lambda: self._stopping or self._goal_changed
                                or self._settings_changed or self._map_changed
                                or self._replan_request is not None or bool(self._jobs))
            if self._stopping:
                return None
            settings = self._settings
            if self._start is not None:
                start, source = self._start, self._start_source
            else:
                start, source = settings.start, 'parameter'
            live = self._map
            previous = self._worker_map if self._worker_map is not None else self._applied_map
            changed = previous is None or live.version != previous.version
            snapshot = Snapshot(
                settings=settings, settings_changed=self._settings_changed,
                obstacles=live.obstacles, obstacles_changed=changed,
                obstacles_version=live.version, obstacles_stamp_ns=self._obstacles_stamp_ns,
                goal=self._goal, goal_changed=self._goal_changed, start=start,
                start_source=source, map=live, replan_reason=self._replan_request)
            # From here on the worker reads this map's mask: the intake writes others.
            self._worker_map = live
            self._settings_changed = self._map_changed = self._goal_changed = False
            self._replan_request = None
            return snapshot

    def _run_worker(self) -> None:
        """Planning thread: the only thread that touches the Planner."""
        while True:
            snapshot = self._take_snapshot()
            if snapshot is None:
                return
            try:
                self._step(snapshot)
                self._run_jobs(snapshot)
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

    def _apply_map(self, snap: Snapshot) -> None:
        """Give the planner the snapshot's settings and map (its mask when it fits them)."""
        config_changed = snap.settings_changed and snap.settings.config != self._planner.config
        grid_changed = config_changed and (snap.settings.config.grid_key()
                                           != self._planner.config.grid_key())
        if config_changed:
            self._planner.set_config(snap.settings.config)
        live = snap.map
        if live is not None and (live is not self._applied_map or grid_changed):
            # The map's mask when it fits the settings; else the planner inflates its own at
            # the next plan (the intake is still building the one for the new settings).
            self._grid_from_map = self._planner.set_map(live.obstacles, live.blocked,
                                                        live.grid_key, live.fallback)
            self._applied_map = live

    def _step(self, snap: Snapshot) -> None:
        """Apply changed settings/map to the planner, then plan if something requires it."""
        self._apply_map(snap)
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
        elif snap.replan_reason is not None:
            reason = snap.replan_reason
        elif snap.obstacles_changed and snap.settings.replan_on_obstacle_change:
            reason = self._obstacle_replan_reason(snap)
            if reason is None:
                return
        else:
            return
        self._plan(snap, goal, reason)

    def _obstacle_replan_reason(self, snap: Snapshot) -> Optional[str]:
        """Why new obstacles require a replan of the active goal, or None if they do not.

        The plan in force is re-checked by the intake as each map arrives (and withdrawn and
        replanned from there if it collides); here only a failed goal is retried.
        """
        last = self._last_result
        if last is None:
            return None
        if not last.ok:
            return 'obstacles changed' if last.status in _RETRY_ON_OBSTACLES else None
        with self._publish_lock:
            in_force = self._in_force
        if in_force is not None and in_force.result is last:
            return None
        if self._clear_ahead(last, snap):
            return None
        return 'obstacles changed and the current path is no longer clear'

    def _clear_ahead(self, result: PlanResult, snap: Snapshot,
                     obstacles: Optional[Any] = None) -> bool:
        """True when the curve of ``result`` still ahead of the vehicle is certified to keep
        gamma from ``obstacles`` (default: the planner's), by the clearance engine."""
        return self._verdict_ahead(result, snap, obstacles).clear

    def _verdict_ahead(self, result: PlanResult, snap: Snapshot,
                       obstacles: Optional[Any] = None) -> ClearanceVerdict:
        # Only the part still ahead of the vehicle matters.
        position = snap.start if snap.start_source != 'parameter' else None
        verdict = self._planner.plan_is_clear(result, position, obstacles)
        if not verdict.clear and verdict.blocked_at is not None:
            self._log.warning('the plan is blocked near '
                              f'{np.round(verdict.blocked_at, 3).tolist()}')
        return verdict

    def _cancel_test(self, goal: Goal, settings: NodeSettings) -> Callable[[], bool]:
        """A cancel test for the plan of ``goal``: true once a newer goal, changed settings or
        shutdown makes the plan pointless (checked every few milliseconds by the planner)."""
        def cancelled() -> bool:
            with self._wake:
                return (self._stopping or self._goal is None
                        or self._goal.serial != goal.serial
                        or (self._settings_changed and self._settings.config != settings.config))
        return cancelled

    def _report_progress(self, goal: Goal, settings: NodeSettings, stage: PlanStage,
                         elapsed_s: float, budget_s: float) -> None:
        """Progress callback of a long plan: which stage it is in, on the log and /diagnostics."""
        limit = f' of {budget_s:g} s' if budget_s > 0 else ''
        text = f'planning: {stage.value} after {elapsed_s:.1f} s{limit}'
        self._log.info(text)
        values = {'event': 'progress', 'status': 'planning', 'stage': stage.value,
                  'elapsed_s': elapsed_s, 'budget_s': budget_s, 'goal': goal.position}
        values.update(self._settings_values(settings))
        self._publish_diagnostics(self.node.get_clock().now().nanoseconds,
                                  DiagnosticStatus.OK, text, values)

    def _admissible_start(self, start: np.ndarray,
                          settings: NodeSettings) -> Tuple[np.ndarray, str]:
        """The start to plan from, and a note when it was moved.

        A vehicle on the ground reads a little below the floor (odometry noise), or sits
        within the safety margin of the ground it stands on: a start outside the bounds or
        within gamma by at most ``start_tolerance`` is moved to the nearest free point (the
        start projected into the bounds, or else the nearest free node), so the plan is a
        take-off from there.
        """
        tolerance = settings.start_tolerance
        if tolerance <= 0.0:
            return start, ''
        planner = self._planner
        grid = planner.grid
        config = planner.config
        gamma = config.safety_margin
        inside = bool(grid.contains(start))
        clamped = np.clip(start, grid.bounds_min, grid.bounds_max)
        outside_by = float(np.linalg.norm(start - clamped))
        if inside and self._start_is_free(start, gamma):
            return start, ''
        if outside_by > tolerance:
            return start, ''
        room = 1e-4 * config.resolution
        if self._start_is_free(clamped, gamma):
            moved = clamped
        else:
            moved = nearest_free_node(grid, planner.obstacles, gamma, clamped,
                                      max(tolerance - outside_by, 0.0) + room)
            if moved is None or float(np.linalg.norm(moved - start)) > tolerance + room:
                return start, ''
        what = 'outside the bounds' if not inside else 'within the safety margin'
        note = (f'start {np.round(start, 4).tolist()} is {what}; moved '
                f'{float(np.linalg.norm(moved - start)):.3f} m to {np.round(moved, 4).tolist()} '
                f'(start_tolerance {tolerance} m)')
        return moved, note

    def _start_is_free(self, point: np.ndarray, gamma: float) -> bool:
        planner = self._planner
        grid = planner.grid
        if not bool(grid.contains(point)):
            return False
        node = tuple(grid.world_to_index(point))
        if planner.blocked[node]:
            return False
        if planner.obstacles.is_empty():
            return True
        room = 1e-4 * planner.config.resolution
        return float(planner.obstacles.distance(point)) > gamma + room

    def _plan(self, snap: Snapshot, goal: Goal, reason: str) -> None:
        settings = snap.settings
        self._replan_reason = None
        start, start_note = self._admissible_start(snap.start, settings)
        if start_note:
            self._log.info(start_note)
        fallback_builds = self._planner.fallback_builds
        result = self._planner.plan(
            start, goal.position, cancel=self._cancel_test(goal, settings),
            progress=lambda *report: self._report_progress(goal, settings, *report))
        if self._planner.fallback_builds != fallback_builds and self._grid_from_map:
            # This map needed the conservative grid: from now on the intake keeps it up to
            # date too, so later plans do not inflate it (a second or so on a large map).
            self._builder.want_fallback = True
        if result.status is PlanStatus.CANCELED:
            self._cancelled(snap, goal, result)
            return
        checked = (snap.obstacles_version, snap.obstacles_stamp_ns)
        frame = settings.frame_id
        drift_note = ''
        with self._publish_lock:
            with self._wake:
                newest = (self._map, self._obstacles_stamp_ns)
                vehicle = self._start if self._start_source != 'parameter' else None
                goal_current = self._goal is not None and self._goal.serial == goal.serial
            if result.ok and newest[0].version != checked[0]:
                # A map arrived while planning: publish only a plan that keeps gamma from it
                # too; otherwise plan again on it at once.
                if not self._clear_ahead(result, snap, newest[0].obstacles):
                    self._discard(snap, goal, newest[0].version, newest[1])
                    return
                checked = (newest[0].version, newest[1])
            if result.ok and vehicle is not None and snap.start_source != 'parameter':
                moved = float(np.linalg.norm(vehicle - snap.start))
                limit = settings.start_replan_distance
                if limit > 0.0 and moved > limit and goal_current:
                    if self._drift_replans < _MAX_DRIFT_REPLANS:
                        self._drift_replans += 1
                        self._drifted(snap, goal, moved)
                        return
                    drift_note = (f'the vehicle moved {moved:.2f} m from the start while '
                                  f'planning ({_MAX_DRIFT_REPLANS} replans in a row); published')
            stamp_ns = self.node.get_clock().now().nanoseconds
            self._last_result, self._last_goal_serial = result, goal.serial
            if result.ok:
                self._drift_replans = 0
                orientation = tuple(float(v) for v in goal.orientation)
                self._latch(result, frame, stamp_ns, orientation, snap.start_source, checked[0],
                            goal.serial)
            withdrawn = False
            if (not result.ok and self._latched is not None
                    and not self._clear_ahead(self._latched, snap)):
                # The latched plan now collides and nothing replaces it: a controller, even one
                # that subscribes later, must not fly it. Empty messages withdraw it.
                self._withdraw_plan(frame, stamp_ns)
                withdrawn = True
        if result.ok:
            level = DiagnosticStatus.OK
            self._log.info(
                f'plan ({reason}): {result.smoothed_length_m:.2f} m smoothed, '
                f'{result.expanded_nodes} nodes expanded in {result.planning_time_s:.3f} s, '
                f'min clearance {result.min_clearance_m:.3f} m, start from {snap.start_source}')
        else:
            level = DiagnosticStatus.ERROR
            self._log.warning(f'no plan ({reason}): {result.status.value} '
                              f'(code {NAV2_CODE_BY_STATUS[result.status]}): {result.message}')
        map_values = self._map_values(snap.map)
        message = result.message
        if result.ok and map_values['map_refused']:
            # The map holds older data of a source whose newest message was refused: say so.
            level = DiagnosticStatus.WARN
            message += f'; map incomplete: {map_values["map_refused"]}'
        values = conv.plan_diagnostic_values(result, snap.start_source, {
            'reason': reason, 'plan_withdrawn': withdrawn, 'obstacles': len(snap.obstacles),
            'obstacles_version': snap.obstacles_version,
            'obstacles_stamp': snap.obstacles_stamp_ns, 'obstacles_checked_version': checked[0],
            'obstacles_checked_stamp': checked[1], 'frame_id': frame,
            'message': message, 'start_adjusted': bool(start_note),
            'requested_start': snap.start})
        if start_note:
            values['start_note'] = start_note
        if snap.map is not None:
            # Whether the plan searched the intake's mask (built off the planning thread, for
            # the gamma below) or inflated its own (grid_build_time_s).
            values['grid_from_map'] = self._grid_from_map
            values['map_grid_gamma_m'] = float(snap.map.grid_key[3])
            values['map_mask_full'] = snap.map.update.full
            values['map_mask_time_s'] = snap.map.update.time_s
        if drift_note:
            values['note'] = drift_note
        values.update(map_values)
        self._publish_diagnostics(stamp_ns, level, f'{result.status.value}: {message}',
                                  values)

    def _latch(self, result: PlanResult, frame: str, stamp_ns: int,
               orientation: Tuple[float, ...], start_source: str, checked_version: int,
               goal_serial: Optional[int] = None) -> bytes:
        """Publish and latch a plan checked against map ``checked_version``; return the
        serialised ``plan``. A newer map published meanwhile is re-checked by the intake as
        soon as the publish lock is free."""
        # Serialised from the arrays: the messages of conv.plan_to_path and friends, without
        # building hundreds of message objects (milliseconds per plan).
        with self._publish_lock:
            plan = cdr.serialized_plan_path(result, frame, stamp_ns, orientation)
            self._plan_pub.publish(plan)
            self._unsmoothed_pub.publish(
                cdr.serialized_unsmoothed_path(result, frame, stamp_ns, orientation))
            self._trajectory_pub.publish(
                cdr.serialized_trajectory(result, frame, stamp_ns, orientation))
            self._latched = result
            self._in_force = _InForce(result, frame, stamp_ns, start_source, checked_version,
                                      goal_serial)
        with self._wake:
            # Only a plan for the active goal is replanned once the vehicle's position arrives.
            self._in_force_source = start_source if goal_serial is not None else None
        return plan

    def _cancelled(self, snap: Snapshot, goal: Goal, result: PlanResult) -> None:
        """A plan stopped by a newer goal, new settings or shutdown: nothing is published but
        an OK status (``event: plan_cancelled``); the newer request is served next."""
        if self._is_stopping():
            return
        if self._goal_is(goal):
            # Same goal, new settings: plan it again with them.
            self._replan_reason = 'parameters changed while planning'
        self._log.info(f'plan cancelled: {result.message}')
        values = {'event': 'plan_cancelled', 'status': result.status.value,
                  'reason': result.message, 'goal': goal.position}
        values.update(self._settings_values(snap.settings))
        self._publish_diagnostics(self.node.get_clock().now().nanoseconds,
                                  DiagnosticStatus.OK, f'plan cancelled: {result.message}',
                                  values)

    def _goal_is(self, goal: Goal) -> bool:
        with self._wake:
            return self._goal is not None and self._goal.serial == goal.serial

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

    def _drifted(self, snap: Snapshot, goal: Goal, moved_m: float) -> None:
        """Drop a plan whose start the vehicle left while it was computed; plan again from
        where the vehicle is now (``event: plan_discarded``, WARN)."""
        self._last_result, self._last_goal_serial = None, goal.serial
        self._replan_reason = 'the vehicle moved away from the start while planning'
        text = (f'plan discarded: the vehicle moved {moved_m:.2f} m from its start while it was '
                f'computed (start_replan_distance {snap.settings.start_replan_distance} m); '
                'planning again from the newest position')
        self._log.info(text)
        values = {'event': 'plan_discarded', 'status': 'discarded', 'reason': text,
                  'goal': goal.position, 'start': snap.start}
        values.update(self._settings_values(snap.settings))
        self._publish_diagnostics(self.node.get_clock().now().nanoseconds,
                                  DiagnosticStatus.WARN, text, values)
        with self._wake:
            # Nothing else may wake the worker: ask for the replan explicitly.
            self._replan_request = self._replan_reason
            self._wake.notify_all()
        self._replan_reason = None

    def _withdraw_plan(self, frame: str, stamp_ns: int, log: bool = True) -> None:
        """Replace the latched plan, unsmoothed plan and trajectory by empty ones."""
        with self._publish_lock:
            empty = np.empty((0, 3))
            self._plan_pub.publish(conv.points_to_path(empty, frame, stamp_ns))
            self._unsmoothed_pub.publish(conv.points_to_path(empty, frame, stamp_ns))
            self._trajectory_pub.publish(conv.empty_trajectory(frame, stamp_ns))
            self._latched = None
            self._in_force = None
        with self._wake:
            self._in_force_source = None
        if log:
            self._log.warning('withdrew the plan in force (published an empty plan and '
                              'trajectory): it no longer keeps gamma from the obstacles')

    # ---------------------------------------------------------------------------- Nav2 host

    def submit(self, job: Callable[[Planner, Snapshot], None]) -> None:
        """Run ``job(planner, snapshot)`` on the worker after the pending settings and map
        are applied (:class:`PlannerInterfaces` plans its requests so); returns at once."""
        with self._wake:
            self._jobs.append(job)
            self._wake.notify_all()

    def _run_jobs(self, snapshot: Snapshot) -> None:
        with self._wake:
            jobs, self._jobs = self._jobs, []
        for job in jobs:
            job(self._planner, snapshot)

    def publish_plan(self, result: PlanResult, frame_id: str, stamp_ns: int,
                     orientation: Tuple[float, ...]) -> bytes:
        """Worker only: publish and latch a successful plan on ``plan``, ``unsmoothed_plan`` and
        ``trajectory``; return the serialised ``plan`` message. The plan is the plan in force
        from then on: re-checked against every new map, and against a map newer than the
        planner's right away."""
        applied = self._applied_map.version if self._applied_map is not None else -1
        with self._publish_lock:
            plan = self._latch(result, frame_id, stamp_ns, orientation, 'request', applied)
            with self._wake:
                newest = self._map
            if newest.version > applied:
                self._recheck_in_force(newest)
        return plan

    def publish_diagnostics(self, stamp_ns: int, level: bytes, message: str,
                            values: Mapping[str, object]) -> None:
        """Publish one status of this node on ``/diagnostics`` (any thread)."""
        self._publish_diagnostics(stamp_ns, level, message, values)

    def current_settings(self) -> NodeSettings:
        """The settings in force (any thread)."""
        return self._current_settings()

    # ---------------------------------------------------------------------------- outputs

    def _settings_values(self, settings: NodeSettings) -> Dict[str, object]:
        config = settings.config
        return {'algorithm': config.algorithm, 'resolution_m': config.resolution,
                'safety_margin_m': config.safety_margin,
                'adaptive_threshold_m': config.adaptive_threshold,
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
                                     if name != 'map_file' or state.delivered),
            'map_refused': '; '.join(refused),
            'map_version': live.version,
        }
        if map_stamp > 0:
            values['map_age_s'] = max(
                (self.node.get_clock().now().nanoseconds - map_stamp) * 1e-9, 0.0)
        return values

    def _publish_diagnostics(self, stamp_ns: int, level: bytes, message: str,
                             values: Mapping[str, object]) -> None:
        msg = conv.diagnostic_array(stamp_ns, self._diag_name, 'uav_global_planner', level,
                                    message, values)
        # The executor thread (refusals), the intake (withdrawals) and the worker (plans)
        # publish here.
        with self._diagnostics_lock:
            self._diagnostics_pub.publish(msg)

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
        if missing:
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


def main(args: Optional[List[str]] = None) -> int:
    """Entry point of ``planner_node``: run until SIGINT/SIGTERM, then exit with 0.

    Returns
    -------
    int
        0 after a clean shutdown, :data:`EXIT_BAD_SETTINGS` for invalid start-up parameters
        (or a ``map_file`` that cannot be read).
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
        # Invalid --params-file or -p values (out of range, wrong type, failing validation),
        # or an unreadable map file: say which, and do not start.
        print(f'planner_node: invalid parameters: {error}', file=sys.stderr)
        code = EXIT_BAD_SETTINGS
    except RuntimeError:
        # A message taken while SIGINT/SIGTERM shuts the context down can fail to convert;
        # that is the shutdown, not an error. Anything else still shows its traceback.
        if rclpy.ok():
            raise
    finally:
        # A second Ctrl-C during clean-up must not print a traceback.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        if planner is not None:
            planner.close()
        rclpy.try_shutdown()
    return code


if __name__ == '__main__':
    sys.exit(main())
