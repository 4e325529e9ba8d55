"""The node's ground: the ``ground``, ``min_agl`` and ``max_agl`` parameters as map shapes.

The flat ground and the height band above it
(:func:`uav_global_planner.core.map.ground.ground_obstacles`) join the map as shapes of their own,
next to the marker obstacles and the geofence, so the planner, the certified check of the plan
in force and the endpoint checks see them as obstacles. They depend on the bounds and the
planning margin, so a change of any of those settings makes them again. A ``terrain_file``
(:mod:`uav_global_planner.ros.terrain_source`) is the ground when there is one, and the band
follows it; while that file is refused there are no ground shapes (goals are refused then).
"""

from typing import Dict, Hashable, Optional, Tuple

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.map.ground import ground_obstacles
from uav_global_planner.core.map.terrain import HeightField
from uav_global_planner.ros.terrain_source import TerrainState

#: Namespace of the ground's shapes among the map's shapes. Marker keys are (ns, id) with a ROS
#: string ns, which cannot hold a NUL character, so the two never collide.
_SHAPE_NS = '\x00ground'


def ground_key(config: PlannerConfig,
               terrain: Optional[TerrainState] = None) -> Tuple[Hashable, ...]:
    """The settings (and the terrain) the ground shapes are made from: a change means new
    shapes. The terrain compares by identity: a terrain read again is a new one."""
    return (config.ground, config.min_agl, config.max_agl, config.planning_margin,
            tuple(config.bounds_min), tuple(config.bounds_max),
            terrain)


def ground_shapes(config: PlannerConfig, terrain: Optional[TerrainState] = None
                  ) -> Dict[Tuple[str, int], HeightField]:
    """The ground and the AGL band of ``config`` as map shapes keyed by ``(namespace, n)``.

    Parameters
    ----------
    config : PlannerConfig
    terrain : TerrainState, optional
        The ``terrain_file`` in force: its height field is the ground; none while it is refused.

    Raises
    ------
    InvalidInputError
        For a height band without a ground, or a ground above the bounds.
    """
    if terrain is not None and terrain.refusal:
        return {}
    field = None if terrain is None else terrain.field
    return {(_SHAPE_NS, n): shape
            for n, shape in enumerate(ground_obstacles(config, field))}
