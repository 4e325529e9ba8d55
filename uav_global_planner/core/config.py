"""Planner settings and their validation, shared by the ROS node and the command-line tool."""

from dataclasses import dataclass, fields, replace
import math
from typing import Any, Mapping

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.grid import DEFAULT_MAX_VOXELS, VoxelGrid

#: Search heuristics, by the names users type.
ALGORITHMS = ('dijkstra', 'astar', 'adaptive', 'octile', 'weighted')

#: Spline parameterisations: chord length sampled in metres, or the paper's node index.
SMOOTHING_MODES = ('chord', 'index', 'none')

#: Largest climb or descent weight of the energy-aware cost [-]: larger is a typo, not a model.
MAX_COST_WEIGHT = 100.0


@dataclass(frozen=True)
class PlannerConfig:
    """Every setting of the planner, with units.

    Attributes
    ----------
    bounds_min, bounds_max : tuple of float
        Workspace corners (x, y, z) [m] (eq. 4).
    resolution : float
        Grid spacing delta [m] (eq. 5).
    safety_margin : float
        Obstacle inflation gamma [m] (eqs. 8-10).
    adaptive_threshold : float
        eta [m]: the adaptive heuristic is Manhattan beyond it, Euclidean within it (eq. 12).
    algorithm : str
        One of :data:`ALGORITHMS`.
    search_weight : float
        Suboptimality bound w of ``weighted`` [-], in [1, 10]: its path costs at most w times
        the optimum.
    max_expansions : int
        Search budget in expanded nodes; 0 means no limit.
    max_planning_time : float
        Budget of a whole plan [s] (grid build, search, smoothing, timing); 0 means no limit.
    max_voxels : int
        Largest accepted grid node count.
    shortcut : bool
        Drop intermediate nodes where the straight segment keeps clearance >= gamma.
    smoothing : str
        One of :data:`SMOOTHING_MODES`.
    sample_spacing : float
        Spacing of smoothed samples along the curve for ``chord`` smoothing [m].
    index_step : float
        Parameter step of the paper's node-index spline for ``index`` smoothing [-].
    max_speed_horizontal, max_speed_vertical : float
        Speed limits [m/s].
    max_accel_horizontal, max_accel_vertical : float
        Acceleration limits [m/s^2].
    vehicle_mass, hover_power : float
        Take-off mass [kg] and hover power [W] of the energy estimate of every plan
        (:mod:`uav_global_planner.core.energy`).
    climb_weight, descent_weight : float
        Energy-aware step cost [-], each in [0, 100]: a grid step costs its length plus
        (weight - 1) times its vertical length, with the weight of its direction; 1 and 1 give
        the paper's geometric length (eq. 15), a descent weight below 1 makes descending
        cheaper (:mod:`uav_global_planner.core.search`).
    """

    bounds_min: tuple = (-10.0, -10.0, 0.0)
    bounds_max: tuple = (10.0, 10.0, 15.0)
    resolution: float = 0.5
    safety_margin: float = 0.2
    adaptive_threshold: float = 1.5
    algorithm: str = 'adaptive'
    search_weight: float = 1.05
    max_expansions: int = 0
    max_planning_time: float = 5.0
    max_voxels: int = DEFAULT_MAX_VOXELS
    shortcut: bool = True
    smoothing: str = 'chord'
    sample_spacing: float = 0.1
    index_step: float = 0.1
    max_speed_horizontal: float = 2.0
    max_speed_vertical: float = 1.0
    max_accel_horizontal: float = 1.0
    max_accel_vertical: float = 0.5
    climb_weight: float = 1.0
    descent_weight: float = 1.0
    vehicle_mass: float = 1.5
    hover_power: float = 180.0

    def with_changes(self, **changes: Any) -> 'PlannerConfig':
        """Return a validated copy with some fields replaced."""
        return validate_config(replace(self, **changes))

    def grid_key(self) -> tuple:
        """The fields that define the inflated grid; a change means a rebuild."""
        return (tuple(self.bounds_min), tuple(self.bounds_max), self.resolution,
                self.safety_margin)


def _number(name: str, value: Any, low: float, high: float = math.inf,
            low_open: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidInputError(f'{name} must be a number, got {value!r}')
    number = float(value)
    if not math.isfinite(number):
        raise InvalidInputError(f'{name} must be finite, got {number}')
    too_low = number <= low if low_open else number < low
    if too_low or number > high:
        bracket = '(' if low_open else '['
        raise InvalidInputError(f'{name} must be in {bracket}{low}, {high}], got {number}')
    return number


def _integer(name: str, value: Any, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise InvalidInputError(f'{name} must be an integer, got {value!r}')
    if value < low:
        raise InvalidInputError(f'{name} must be >= {low}, got {value}')
    return int(value)


def _triple(name: str, value: Any) -> tuple:
    if isinstance(value, (str, bytes)) or not hasattr(value, '__len__') or len(value) != 3:
        raise InvalidInputError(f'{name} must be three numbers [x, y, z], got {value!r}')
    return tuple(_number(f'{name}[{axis}]', item, -math.inf) for axis, item in enumerate(value))


def validate_config(config: PlannerConfig) -> PlannerConfig:
    """Check every field and the cross-field rules; return a normalised copy.

    Raises
    ------
    InvalidInputError
        Naming the first offending field and the accepted range.
    """
    if not isinstance(config, PlannerConfig):
        raise InvalidInputError(f'config must be a PlannerConfig, got {type(config).__name__}')
    values = {
        'bounds_min': _triple('bounds.min', config.bounds_min),
        'bounds_max': _triple('bounds.max', config.bounds_max),
        'resolution': _number('resolution', config.resolution, 0.0, 100.0, low_open=True),
        'safety_margin': _number('safety_margin', config.safety_margin, 0.0, 100.0),
        'adaptive_threshold': _number('adaptive_threshold', config.adaptive_threshold, 0.0),
        'search_weight': _number('search_weight', config.search_weight, 1.0, 10.0),
        'max_expansions': _integer('max_expansions', config.max_expansions, 0),
        'max_planning_time': _number('max_planning_time', config.max_planning_time, 0.0),
        'max_voxels': _integer('max_voxels', config.max_voxels, 1),
        'sample_spacing': _number('sample_spacing', config.sample_spacing, 0.0, 10.0,
                                  low_open=True),
        'index_step': _number('index_step', config.index_step, 0.0, 1.0, low_open=True),
        'vehicle_mass': _number('vehicle_mass', config.vehicle_mass, 0.0, 1000.0,
                                low_open=True),
        'hover_power': _number('hover_power', config.hover_power, 0.0, 1e6, low_open=True),
        'climb_weight': _number('climb_weight', config.climb_weight, 0.0, MAX_COST_WEIGHT),
        'descent_weight': _number('descent_weight', config.descent_weight, 0.0,
                                  MAX_COST_WEIGHT),
    }
    for name in ('max_speed_horizontal', 'max_speed_vertical', 'max_accel_horizontal',
                 'max_accel_vertical'):
        values[name] = _number(name, getattr(config, name), 0.0, 1000.0, low_open=True)
    if config.algorithm not in ALGORITHMS:
        raise InvalidInputError(
            f'algorithm must be one of {", ".join(ALGORITHMS)}, got {config.algorithm!r}')
    if config.smoothing not in SMOOTHING_MODES:
        raise InvalidInputError(
            f'smoothing must be one of {", ".join(SMOOTHING_MODES)}, got {config.smoothing!r}')
    if not isinstance(config.shortcut, bool):
        raise InvalidInputError(f'shortcut must be true or false, got {config.shortcut!r}')
    # Cross-field rules: consistent bounds and a grid below the voxel cap.
    VoxelGrid.from_bounds(values['bounds_min'], values['bounds_max'], values['resolution'],
                          values['max_voxels'])
    return replace(config, **values)


def config_from_mapping(values: Mapping[str, Any],
                        base: PlannerConfig = PlannerConfig()) -> PlannerConfig:
    """Build a validated config from a flat mapping of field names, rejecting unknown keys."""
    known = {f.name for f in fields(PlannerConfig)}
    unknown = sorted(set(values) - known)
    if unknown:
        raise InvalidInputError(f'unknown setting(s): {", ".join(unknown)}')
    return validate_config(replace(base, **dict(values)))
