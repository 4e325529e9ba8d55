"""The planner node's parameters: declared, described and validated from the settings tables.

Every parameter is a :class:`~uav_global_planner.core.settings.Setting`: the planning core's
settings (:data:`~uav_global_planner.core.settings.PLANNER_SETTINGS`, the same table that
checks scene files, ``uav-plan`` flags and :func:`validate_config`) followed by the settings of
the node alone, :data:`NODE_SETTINGS`. Those name ROS things (frames, topics, QoS, the map
sources of the node), which the core must not know, so they live here; being of the same type
they are described, ranged and refused in the same words.

From a setting come the parameter's type (its default), its ``ParameterDescriptor``
(:func:`descriptor`: description with unit, accepted values, read-only flag and the
``FloatingPointRange`` or ``IntegerRange`` rclpy checks first) and its validation
(:func:`settings_from_parameters`, which the node calls on start-up and for every set request).

rclpy's ranges are closed intervals: where a setting excludes its lower end (``resolution``
> 0) rclpy lets that value through and :func:`settings_from_parameters` refuses it, in the
words of the table.
"""

from dataclasses import dataclass
import sys
from typing import Any, Dict, Mapping, Tuple

import numpy as np
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node

from uav_global_planner.core.config import PlannerConfig, validate_config
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.ground import ground_obstacles
from uav_global_planner.core.settings import (by_name, INT64_MAX, Kind, planner_settings,
                                              Setting)
from uav_global_planner.ros.qos import CLOUD_QOS_BY_RELIABILITY

#: What to do with NaN/inf points of obstacle_cloud.
CLOUD_NON_FINITE_MODES = ('drop', 'refuse')

#: The map sources of the node, as named in ``required_map_sources`` and the diagnostics.
MAP_SOURCES = ('obstacles', 'obstacle_cloud', 'map_file')

_PATH_OR_NONE = "a path (a string), '' for none"

# The upper end of a float range without one (the table's floats all have one today).
_DOUBLE_MAX = sys.float_info.max

#: The settings of the node alone, in the order they are declared after the core's.
NODE_SETTINGS: Tuple[Setting, ...] = (
    Setting('frame_id', Kind.TEXT, 'map', 'planning frame',
            'Every input must be stamped in it (the node does no tf2 transforms; other frames '
            'are refused with code TF_ERROR 202). Changing it drops the obstacles, start and '
            'goal received in the old frame.', accepts='a non-empty frame name',
            non_empty=True),
    Setting('start', Kind.POINT, (0.0, 0.0, 0.0), 'start position',
            'Start (x, y, z) in frame_id, used until a message arrives on odom or '
            'start_pose.', 'm'),
    Setting('max_obstacle_size', Kind.FLOAT, 100.0, 'largest marker size',
            'Largest accepted marker scale component; bigger markers are refused as '
            'implausible.', 'm', 0.0, 1.0e6, low_open=True),
    Setting('max_cloud_points', Kind.INT, 2_000_000, 'largest obstacle cloud',
            'Largest accepted obstacle_cloud size (width x height) in points.', '', 1),
    Setting('cloud_non_finite', Kind.CHOICE, 'drop', 'non-finite cloud points',
            'What to do with NaN/inf points of obstacle_cloud: drop them (usual for sensor '
            'clouds) or refuse the whole cloud.',
            choices=CLOUD_NON_FINITE_MODES),
    Setting('replan_on_obstacle_change', Kind.BOOL, True, 'replanning on obstacle changes',
            'Replan the active goal by itself when the obstacles change and the current path '
            'no longer keeps clearance >= gamma.'),
    Setting('map_file', Kind.TEXT, '', 'static prior map',
            'A .pcd, .ply, .las, .laz, .bt or .npy file of occupied points in frame_id [m], '
            'combined with the obstacles and obstacle_cloud topics. Read at start-up; a file '
            'that cannot be used (unreadable, no usable points, all outside the bounds) is '
            'refused: goals are refused and the map status says why.',
            accepts=_PATH_OR_NONE, read_only=True),
    Setting('terrain_file', Kind.TEXT, '', 'terrain',
            'A digital elevation model: a GeoTIFF (placed with geodetic_origin when it is set, '
            'else its CRS must be projected in metres and is frame_id) or an ESRI ASCII grid '
            '(.asc, in frame_id); .npy is refused. It is the ground (instead of ground), and '
            'min_agl and max_agl follow it. Read at start-up and again when the bounds or '
            'geodetic_origin change; a file that cannot be used is refused: goals are refused '
            'and the map status says why.', accepts=_PATH_OR_NONE, read_only=True),
    Setting('cloud_qos_reliability', Kind.CHOICE, 'reliable', 'reliability of obstacle_cloud',
            'Either reliable (large clouds arrive whole; needs a reliable publisher) or '
            'best_effort (for best-effort sensor publishers; clouds may be lost). Read at '
            'start-up.',
            choices=tuple(CLOUD_QOS_BY_RELIABILITY), read_only=True),
    Setting('trajectory_sample_period', Kind.FLOAT, 0.05, 'trajectory sample period',
            'Time between the points of the trajectory message, sampled from the continuous '
            'reference.', 's', 0.0, 10.0, low_open=True),
    Setting('plan_without_map', Kind.BOOL, False, 'planning without a map',
            'Plan goals before any map source has delivered (open air). By default such a '
            'goal is refused with the reason, as planning through an unknown map would be '
            'reported as safe.'),
    Setting('required_map_sources', Kind.NAMES, ('any',), 'required map sources',
            'Map sources that must have delivered before goals are planned: any (at least one '
            'of them) or a list of obstacles, obstacle_cloud, map_file (each of them).',
            accepts="['any'] or distinct names among " + ', '.join(MAP_SOURCES)),
    Setting('start_replan_distance', Kind.FLOAT, 2.0, 'start replan distance',
            "A plan whose start is farther than this from the vehicle's newest position (odom "
            'or start_pose) when it is ready is made again from there; 0 = never.', 'm', 0.0,
            1.0e6),
    Setting('geofence_file', Kind.TEXT, '', 'geofence',
            'A YAML file (inclusion fence, exclusion prisms, cylinders, boxes) or a '
            'QGroundControl .plan (its geoFence, placed with geodetic_origin). The flown curve '
            'keeps gamma inside the fence and outside every zone; a change replans the active '
            'goal.', accepts=_PATH_OR_NONE),
    Setting('geofence_floor', Kind.FLOAT, 0.0, 'geofence floor',
            'Floor of the inclusion fences of a .plan geofence_file, map frame z (.plan fences '
            'are 2D; YAML fences carry their own).', 'm', -1.0e4, 1.0e5,
            rule='below geofence_ceiling'),
    Setting('geofence_ceiling', Kind.FLOAT, 120.0, 'geofence ceiling',
            'Ceiling of the inclusion fences of a .plan geofence_file, map frame z.', 'm',
            -1.0e4, 1.0e5, rule='above geofence_floor'),
)

#: :data:`NODE_SETTINGS` by name; read when the node runs, as the core's table is.
NODE_SETTINGS_BY_NAME: Dict[str, Setting] = by_name(NODE_SETTINGS)


def parameter_specs() -> Tuple[Setting, ...]:
    """Every parameter of the node, from the tables in force: the core's, then the node's."""
    core = tuple(entry for entry in planner_settings() if entry.node)
    return core + tuple(NODE_SETTINGS_BY_NAME.values())


#: The node's parameters (as :func:`parameter_specs` gives them at import).
PARAMETER_SPECS: Tuple[Setting, ...] = parameter_specs()

#: :data:`PARAMETER_SPECS` by parameter name.
SPECS_BY_NAME: Dict[str, Setting] = by_name(PARAMETER_SPECS)

#: Parameters read once at start-up (read-only): changing them needs a restart.
STARTUP_ONLY: Tuple[str, ...] = tuple(spec.name for spec in PARAMETER_SPECS if spec.read_only)


def parameter_default(spec: Setting) -> Any:
    """The default as a parameter value: lists for points and names (rclpy arrays)."""
    if isinstance(spec.default, tuple):
        return list(spec.default)
    return spec.default


def descriptor(spec: Setting) -> ParameterDescriptor:
    """The rclpy descriptor of a setting: description with unit, accepted values, read-only
    flag and, for numbers, the range rclpy checks before the node's own validation."""
    result = ParameterDescriptor(name=spec.name, description=spec.summary,
                                 additional_constraints=spec.constraints,
                                 read_only=spec.read_only)
    if spec.kind is Kind.FLOAT:
        result.floating_point_range = [FloatingPointRange(
            from_value=float(spec.low), to_value=min(spec.upper, _DOUBLE_MAX), step=0.0)]
    elif spec.kind is Kind.INT:
        result.integer_range = [IntegerRange(from_value=int(spec.low),
                                             to_value=min(int(spec.upper), INT64_MAX), step=1)]
    elif spec.kind is Kind.WORD_OR_NUMBER:
        # A word or a number (ground: floor, ground:=2.5): the table checks which.
        result.dynamic_typing = True
    return result


@dataclass(frozen=True, eq=False)
class NodeSettings:
    """The validated values of every parameter of the node (units as in the tables).

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
        One of :data:`CLOUD_NON_FINITE_MODES`.
    replan_on_obstacle_change : bool
    map_file : str
    terrain_file : str
        '' = no terrain.
    map_downsample : float
        [m], 0 = none.
    cloud_qos_reliability : str
        ``'reliable'`` or ``'best_effort'``.
    trajectory_sample_period : float
        [s]
    plan_without_map : bool
    required_map_sources : tuple of str
        ``('any',)`` or a subset of :data:`MAP_SOURCES`.
    start_replan_distance : float
        [m], 0 = off.
    geofence_file : str
        '' = no geofence.
    geofence_floor, geofence_ceiling : float
        Height band of a ``.plan`` geofence's inclusion fences [m].
    """

    config: PlannerConfig
    frame_id: str
    start: np.ndarray
    max_obstacle_size: float
    max_cloud_points: int
    cloud_non_finite: str
    replan_on_obstacle_change: bool
    map_file: str = ''
    terrain_file: str = ''
    map_downsample: float = 0.0
    cloud_qos_reliability: str = 'reliable'
    trajectory_sample_period: float = 0.05
    plan_without_map: bool = False
    required_map_sources: Tuple[str, ...] = ('any',)
    start_replan_distance: float = 2.0
    geofence_file: str = ''
    geofence_floor: float = 0.0
    geofence_ceiling: float = 120.0

    @property
    def start_tolerance(self) -> float:
        """How far a start or goal is moved to free space at most [m] (``config.start_tolerance``,
        a setting of the core's table: :mod:`uav_global_planner.core.search.start_admission`)."""
        return float(self.config.start_tolerance)


def plain(value: Any) -> Any:
    """Parameter value as plain Python (rclpy gives arrays as ``array.array``)."""
    if isinstance(value, (list, tuple)) or hasattr(value, 'tolist'):
        items = list(value.tolist() if hasattr(value, 'tolist') else value)
        if items and all(isinstance(item, str) for item in items):
            return items
        return [float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else v
                for v in items]
    return value


def settings_from_parameters(values: Mapping[str, Any],
                             map_margin_m: float = 0.0) -> NodeSettings:
    """Build and validate the settings from parameter values keyed by parameter name.

    The planner settings go through :func:`validate_config`, the node's own through their
    :meth:`Setting.check`, then the node's cross-parameter rules.

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
    specs = parameter_specs()
    fields = {spec.field: plain(values[spec.name]) for spec in specs if spec.field}
    config = validate_config(PlannerConfig(**fields))
    if map_margin_m:
        config = config.with_changes(safety_margin=config.safety_margin + map_margin_m)
    # A height band needs a ground, and a flat ground lies below the bounds' top; a
    # terrain_file is the ground (read by the node, which reports it when refused).
    terrain = values.get('terrain_file', '')
    if not (isinstance(terrain, str) and terrain.strip()):
        ground_obstacles(config)
    node = {spec.name: spec.check(plain(values[spec.name])) for spec in specs
            if not spec.field}
    required = node['required_map_sources']
    if required != ('any',):
        unknown = [name for name in required if name not in MAP_SOURCES]
        if not required or unknown or len(set(required)) != len(required):
            raise InvalidInputError(
                f'required_map_sources must be {SPECS_BY_NAME["required_map_sources"].accepted}'
                f', got {list(required)!r}')
        if 'map_file' in required and not node['map_file'].strip():
            raise InvalidInputError(
                'required_map_sources lists map_file, but no map_file is set')
    if not node['geofence_floor'] < node['geofence_ceiling']:
        raise InvalidInputError(
            f'geofence_floor must be below geofence_ceiling, got {node["geofence_floor"]} and '
            f'{node["geofence_ceiling"]}')
    node['start'] = np.array(node['start'])
    node['frame_id'] = str(node['frame_id'])
    return NodeSettings(config=config, **node)


def declare_parameters(node: Node) -> Dict[str, Any]:
    """Declare every parameter of :func:`parameter_specs`; return the values in force
    (defaults overridden by ``--params-file``/``-p``)."""
    declared = node.declare_parameters('', [(spec.name, parameter_default(spec),
                                             descriptor(spec))
                                            for spec in parameter_specs()])
    return {parameter.name: parameter.value for parameter in declared}
