"""Starts and goals against the airspace: outside a fence, inside a zone, or too near one.

:func:`check_endpoint` refuses an endpoint by the zones and fences of an
:class:`~uav_global_planner.core.map.obstacles.ObstacleSet` (the planner's obstacles, fences and
zones included), with the error class of what is wrong, and :func:`zone_containing` names the
zone a point is in.
"""

from typing import Optional

import numpy as np

from uav_global_planner.core.errors import (GoalOccupiedError, GoalOutsideMapError,
                                            StartOccupiedError, StartOutsideMapError)
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.map.spatial_index import row_gaps, TableShape, UNBOUNDED_KINDS


def zone_gaps(obstacles: ObstacleSet, point) -> np.ndarray:
    """Exact distance from ``point`` to each zone and fence of ``obstacles.zones`` [m].

    For a fence it is the distance to its outside (0 outside the fence).
    """
    return row_gaps(np.asarray(point, dtype=np.float64), obstacles.zone_rows,
                    obstacles.shape_kind, obstacles.shape_params, obstacles.shape_vertices,
                    obstacles.shape_vstart)


def zone_containing(obstacles: ObstacleSet, point) -> Optional[TableShape]:
    """The first zone of ``obstacles`` that ``point`` [m] is inside, or whose fence it is
    outside of (on the boundary counts); None when the point is in free airspace."""
    gaps = zone_gaps(obstacles, point)
    inside = np.flatnonzero(gaps <= 0.0)
    return obstacles.zones[int(inside[0])] if len(inside) else None


def check_endpoint(obstacles: ObstacleSet, point, which: str, gamma: float,
                   slack: float = 0.0) -> None:
    """Refuse an endpoint that is outside a fence, inside a zone or within gamma of one.

    Parameters
    ----------
    obstacles : ObstacleSet
        Its :attr:`~ObstacleSet.zones` are checked (obstacles are not).
    point : array_like, shape (3,)
        [m]
    which : str
        ``'start'`` or ``'goal'``: the error class and the message's first word.
    gamma : float
        Safety margin [m].
    slack : float
        Extra room [m]: a clearance <= gamma + slack is refused (the planner keeps a little
        room for rounding), while the message states gamma.

    Raises
    ------
    StartOutsideMapError, GoalOutsideMapError
        Outside an inclusion fence: ``goal [..] is outside the inclusion fence``.
    StartOccupiedError, GoalOccupiedError
        Inside an exclusion zone (``goal [..] is inside exclusion zone 2 (cylinder)``) or
        within gamma of a zone or of a fence wall, floor or ceiling.
    """
    if which not in ('start', 'goal'):
        raise ValueError(f"which must be 'start' or 'goal', got {which!r}")
    if not len(obstacles.zones):
        return
    p = np.asarray(point, dtype=np.float64)
    gaps = zone_gaps(obstacles, p)
    near = np.flatnonzero(gaps <= gamma + slack)
    if not len(near):
        return
    # A point inside something is named by that; otherwise by the nearest zone.
    number = int(near[np.argmin(gaps[near])])
    zone = obstacles.zones[number]
    gap = float(gaps[number])
    fence = int(obstacles.shape_kind[obstacles.zone_rows[number]]) in UNBOUNDED_KINDS
    where = [round(float(v), 6) for v in p]
    if gap <= 0.0 and fence:
        outside = StartOutsideMapError if which == 'start' else GoalOutsideMapError
        raise outside(f'{which} {where} is outside {zone.label}')
    error = StartOccupiedError if which == 'start' else GoalOccupiedError
    if gap <= 0.0:
        raise error(f'{which} {where} is inside {zone.label}')
    boundary = f'the walls, floor or ceiling of {zone.label}' if fence else zone.label
    raise error(f'{which} {where} is within the safety margin of {boundary}: its clearance is '
                f'{gap:.3f} m, gamma is {gamma} m')
