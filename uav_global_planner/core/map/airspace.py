"""Airspace: an inclusion fence and exclusion zones (no-fly volumes) in the planning model.

The vehicle must stay inside the *inclusion fence* (a polygon in x-y with a floor and a
ceiling, or a circle) and outside every *exclusion zone*: vertical prisms (polygon, floor,
ceiling), vertical cylinders (centre, radius, floor, ceiling) and axis-aligned boxes. Without an
inclusion fence the planning bounds are the fence. Every zone and fence is a row of the shape
table of :mod:`uav_global_planner.core.map.spatial_index`, with an exact distance (to a zone's
solid, 0 inside it; to the *outside* of a fence, 0 outside it): put them into the
:class:`~uav_global_planner.core.map.obstacles.ObstacleSet` (:meth:`Airspace.with_obstacles`) and
the grid inflation and every clearance certificate keep gamma from fence walls as from
obstacles. Several inclusion fences are all enforced (the vehicle stays inside each of them),
which is the reading that satisfies both PX4 (inside at least one) and ArduPilot (inside all).

Coordinates are in the planning frame [m], z up. Floors and ceilings may be left out: a zone
without a floor reaches down without end, one without a ceiling up without end.

Fences come from a scene file's ``geofence`` key, a YAML geofence file or a QGroundControl
``.plan`` file (:mod:`~uav_global_planner.core.io.geofence`). Errors name
the key path, as for obstacles: ``geofence.exclusion[2].radius: must be > 0 m, got -1.0``;
polygons must be simple (no two edges cross or touch), with at least three distinct vertices and
a non-zero area.

Where the pieces are: the zone and fence shapes in :mod:`~uav_global_planner.core.map.zones`
(polygons checked by :mod:`~uav_global_planner.core.map.polygons`), the file readers in
:mod:`~uav_global_planner.core.io.geofence`, the start and goal checks in
:mod:`~uav_global_planner.core.map.zone_checks`; this module holds the :class:`Airspace` of one
planning frame.
"""

from dataclasses import dataclass
from typing import Optional, Tuple

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.map.spatial_index import TableShape
from uav_global_planner.core.map.zones import (BoxZone, Cylinder, Exclusion, Inclusion,
                                               InclusionCircle, InclusionFence, Prism)


@dataclass(frozen=True, eq=False)
class Airspace:
    """Inclusion fences and exclusion zones of one planning frame.

    Attributes
    ----------
    inclusions : tuple of InclusionFence or InclusionCircle
        Every one is enforced; none: the planning bounds are the fence.
    exclusions : tuple of Prism, Cylinder or BoxZone
    """

    inclusions: Tuple[Inclusion, ...] = ()
    exclusions: Tuple[Exclusion, ...] = ()

    def __post_init__(self) -> None:
        inclusions = tuple(self.inclusions)
        exclusions = tuple(self.exclusions)
        for item in inclusions:
            if not isinstance(item, (InclusionFence, InclusionCircle)):
                raise InvalidInputError(f'inclusions: {type(item).__name__} is not an '
                                        'inclusion fence')
        for zone in exclusions:
            if not isinstance(zone, (Prism, Cylinder, BoxZone)):
                raise InvalidInputError(f'exclusions: {type(zone).__name__} is not an '
                                        'exclusion zone')
        object.__setattr__(self, 'inclusions', inclusions)
        object.__setattr__(self, 'exclusions', exclusions)

    def __len__(self) -> int:
        return len(self.inclusions) + len(self.exclusions)

    def shapes(self) -> Tuple[TableShape, ...]:
        """Every fence and zone, fences first."""
        return self.inclusions + self.exclusions

    def with_obstacles(self, obstacles: Optional[ObstacleSet] = None) -> ObstacleSet:
        """An obstacle set holding ``obstacles`` and every fence and zone of this airspace."""
        items = list(obstacles.items) if obstacles is not None else []
        return ObstacleSet(items + list(self.shapes()))

    def merged(self, other: 'Airspace') -> 'Airspace':
        """Both airspaces' fences and zones together."""
        return Airspace(self.inclusions + other.inclusions, self.exclusions + other.exclusions)
