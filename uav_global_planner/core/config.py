"""Planner settings and their validation, shared by the ROS node, scene files and ``uav-plan``.

The settings themselves (types, units, ranges, defaults, words) are the table of
:mod:`uav_global_planner.core.settings`; this module holds the validated value object.
"""

from dataclasses import dataclass, fields, replace
from typing import Any, Dict, Mapping, Union

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.settings import (ALGORITHMS, PLANNER_SETTINGS, planner_settings,
                                              SETTINGS_BY_NAME, SMOOTHING_MODES)

__all__ = ['ALGORITHMS', 'SMOOTHING_MODES', 'MAX_COST_WEIGHT', 'PlannerConfig',
           'validate_config', 'config_from_mapping']

#: Largest climb or descent weight of the energy-aware cost [-]: larger is a typo, not a model.
MAX_COST_WEIGHT = float(SETTINGS_BY_NAME['climb_weight'].upper)

# The defaults of the table (core/settings.py), by PlannerConfig field.
_DEFAULT: Dict[str, Any] = {s.field: s.default for s in PLANNER_SETTINGS if s.field}


@dataclass(frozen=True)
class PlannerConfig:
    """Every setting of the planning core, one field per entry of the settings table.

    The fields, their units, accepted values, defaults and descriptions are those of
    :data:`uav_global_planner.core.settings.PLANNER_SETTINGS` (the entry whose ``field`` is the
    attribute name; ``bounds_min`` is the setting ``bounds.min``). Construction does not
    check anything; :func:`validate_config` does.
    """

    bounds_min: tuple = _DEFAULT['bounds_min']
    bounds_max: tuple = _DEFAULT['bounds_max']
    resolution: float = _DEFAULT['resolution']
    safety_margin: float = _DEFAULT['safety_margin']
    adaptive_threshold: float = _DEFAULT['adaptive_threshold']
    algorithm: str = _DEFAULT['algorithm']
    search_weight: float = _DEFAULT['search_weight']
    bound: float = _DEFAULT['bound']
    max_expansions: int = _DEFAULT['max_expansions']
    max_planning_time: float = _DEFAULT['max_planning_time']
    max_voxels: int = _DEFAULT['max_voxels']
    shortcut: bool = _DEFAULT['shortcut']
    smoothing: str = _DEFAULT['smoothing']
    sample_spacing: float = _DEFAULT['sample_spacing']
    index_step: float = _DEFAULT['index_step']
    max_speed_horizontal: float = _DEFAULT['max_speed_horizontal']
    max_speed_vertical: float = _DEFAULT['max_speed_vertical']
    max_accel_horizontal: float = _DEFAULT['max_accel_horizontal']
    max_accel_vertical: float = _DEFAULT['max_accel_vertical']
    max_jerk: float = _DEFAULT['max_jerk']
    max_tilt: float = _DEFAULT['max_tilt']
    max_thrust_to_weight: float = _DEFAULT['max_thrust_to_weight']
    max_yaw_rate: float = _DEFAULT['max_yaw_rate']
    yaw_mode: str = _DEFAULT['yaw_mode']
    vehicle_radius: float = _DEFAULT['vehicle_radius']
    tracking_margin: float = _DEFAULT['tracking_margin']
    start_tolerance: float = _DEFAULT['start_tolerance']
    climb_weight: float = _DEFAULT['climb_weight']
    descent_weight: float = _DEFAULT['descent_weight']
    unknown_space: str = _DEFAULT['unknown_space']
    unknown_cost: float = _DEFAULT['unknown_cost']
    vehicle_mass: float = _DEFAULT['vehicle_mass']
    hover_power: float = _DEFAULT['hover_power']
    ground: Union[str, float] = _DEFAULT['ground']
    min_agl: float = _DEFAULT['min_agl']
    max_agl: float = _DEFAULT['max_agl']

    def with_changes(self, **changes: Any) -> 'PlannerConfig':
        """Return a validated copy with some fields replaced."""
        return validate_config(replace(self, **changes))

    @property
    def planning_margin(self) -> float:
        """Clearance the reference curve keeps from every obstacle [m].

        ``safety_margin + vehicle_radius + tracking_margin``: obstacles are inflated and the
        curve certified by it, so the body keeps gamma while the vehicle flies within
        ``tracking_margin`` of the reference.
        """
        return float(self.safety_margin) + float(self.vehicle_radius) \
            + float(self.tracking_margin)

    def grid_key(self) -> tuple:
        """The fields that define the inflated grid; a change means a rebuild."""
        return (tuple(self.bounds_min), tuple(self.bounds_max), self.resolution,
                self.planning_margin)


def validate_config(config: PlannerConfig) -> PlannerConfig:
    """Check every field against the settings table and the cross-field rules.

    Each field is checked by its :class:`~uav_global_planner.core.settings.Setting`, in table
    order, then the bounds and the node count (:meth:`VoxelGrid.from_bounds`).

    Returns
    -------
    PlannerConfig
        A normalised copy (floats as float, points as tuples).

    Raises
    ------
    InvalidInputError
        Naming the first offending field and the accepted values.
    """
    if not isinstance(config, PlannerConfig):
        raise InvalidInputError(f'config must be a PlannerConfig, got {type(config).__name__}')
    values = {entry.field: entry.check(getattr(config, entry.field))
              for entry in planner_settings() if entry.field}
    if 0.0 < values['max_agl'] <= values['min_agl']:
        raise InvalidInputError(f'max_agl must be above min_agl when both are on (> 0), got '
                                f'min_agl {values["min_agl"]} m and max_agl '
                                f'{values["max_agl"]} m')
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
