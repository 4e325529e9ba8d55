"""Planner settings for a vehicle of some size: its radius and the room kept for tracking.

The planner certifies the reference curve at ``safety_margin + vehicle_radius +
tracking_margin``, so the body keeps ``safety_margin`` while the vehicle stays within
``tracking_margin`` of the reference.
"""

from uav_global_planner.core.config import PlannerConfig


def config_for_vehicle(config: PlannerConfig, vehicle_radius: float,
                       tracking_margin: float = 0.0) -> PlannerConfig:
    """``config`` planning for a body of ``vehicle_radius`` [m] with ``tracking_margin`` [m].

    Returns
    -------
    PlannerConfig
        Validated; ``safety_margin`` stays the body's margin.
    """
    return config.with_changes(vehicle_radius=float(vehicle_radius),
                               tracking_margin=float(tracking_margin))
