"""The ground and the height band above it, as height-field obstacles.

From the settings ``ground``, ``min_agl`` and ``max_agl``
(:class:`~uav_global_planner.core.config.PlannerConfig`) and an optional terrain (a
:class:`~uav_global_planner.core.map.terrain.HeightField` read by
:mod:`uav_global_planner.core.map.dem`), :func:`ground_obstacles` makes the height fields the
planner keeps its margin ``m`` (:attr:`PlannerConfig.planning_margin`) from, like every other
obstacle:

* **the ground** ``h(x, y)``: the terrain when there is one, else flat ground at the bounds'
  floor (``ground: floor``) or at a height of the map frame (``ground: <z>``); ``ground: none``
  (the default, the paper's scenes) adds nothing: the bounds' floor is then only a wall of the
  grid. The solid is ``z <= h``, so clearance ``>= m`` keeps the curve ``m`` above it;
* **the AGL floor** (``min_agl > m``): the solid ``z <= h + min_agl - m``, label ``min_agl``;
* **the AGL ceiling** (``max_agl > 0``): the solid ``z >= h + max_agl + m``, label ``max_agl``.

A point at clearance ``>= m`` from the AGL floor has ``z >= h(x, y) + min_agl``: the point
``(x, y, h + min_agl - m)`` straight below it belongs to the solid, so a point lower than
``h + min_agl`` is closer than ``m`` to it; the same argument upwards bounds it by
``h + max_agl``. The clearance certificate of the planner therefore proves the band at every
point of the continuous curve, vertically, over the bounds' x/y extent the height fields cover.
A ``min_agl`` not above ``m`` needs no surface of its own: the ground's clearance already keeps
the curve ``m >= min_agl`` above it.
"""

from typing import Optional, Sequence, Tuple

import numpy as np

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.map.terrain import flat_ground, HeightField

#: Labels of the height fields :func:`ground_obstacles` makes.
GROUND_LABELS = ('terrain', 'ground', 'min_agl', 'max_agl')


def ground_surface(config: PlannerConfig,
                   terrain: Optional[HeightField] = None) -> Optional[HeightField]:
    """The ground ``h(x, y)`` (solid below): ``terrain``, else the flat ground of
    ``config.ground`` over the bounds' x/y extent, else None (``ground: none``).

    Raises
    ------
    InvalidInputError
        When a flat ground height is not below the bounds' top.
    """
    if terrain is not None:
        return terrain
    if config.ground == 'none':
        return None
    lo, hi = np.asarray(config.bounds_min, float), np.asarray(config.bounds_max, float)
    height = float(lo[2]) if config.ground == 'floor' else float(config.ground)
    if height >= hi[2]:
        raise InvalidInputError(f'ground must be below bounds.max z ({hi[2]:g} m), got '
                                f'{height:g} m: the whole workspace would be underground')
    return flat_ground(height, lo[:2], hi[:2], side='below', label='ground')


def ground_obstacles(config: PlannerConfig,
                     terrain: Optional[HeightField] = None) -> Tuple[HeightField, ...]:
    """The ground, the AGL floor and the AGL ceiling of ``config`` as height fields.

    Parameters
    ----------
    config : PlannerConfig
        ``ground``, ``min_agl``, ``max_agl``, the bounds and the planning margin.
    terrain : HeightField, optional
        The terrain (side ``'below'``), which is then the ground.

    Returns
    -------
    tuple of HeightField
        Empty for ``ground: none`` without a terrain and no band.

    Raises
    ------
    InvalidInputError
        For a height band without a ground (``min_agl`` or ``max_agl`` set, ``ground: none``
        and no terrain), or a flat ground above the bounds.
    """
    surface = ground_surface(config, terrain)
    min_agl, max_agl = float(config.min_agl), float(config.max_agl)
    if surface is None:
        if min_agl > 0.0 or max_agl > 0.0:
            raise InvalidInputError(
                'min_agl and max_agl are heights above the ground, and there is none: set '
                'ground (floor or a height [m]) or give a terrain')
        return ()
    if surface.side != 'below':
        raise InvalidInputError(f'the terrain must be a ground (side below), got side '
                                f'{surface.side!r}')
    margin = config.planning_margin
    shapes = [surface]
    if min_agl > margin:
        shapes.append(_offset(surface, min_agl - margin, 'below', 'min_agl'))
    if max_agl > 0.0:
        shapes.append(_offset(surface, max_agl + margin, 'above', 'max_agl'))
    return tuple(shapes)


def _offset(surface: HeightField, rise: float, side: str, label: str) -> HeightField:
    return HeightField(np.array(surface.origin, dtype=np.float64),
                       np.array(surface.spacing, dtype=np.float64),
                       np.asarray(surface.heights, dtype=np.float64) + rise, side, label)


def height_above_ground(surface: HeightField, points: np.ndarray) -> np.ndarray:
    """Height of map-frame points above the ground under them (AGL) [m].

    Parameters
    ----------
    surface : HeightField
        The ground (:func:`ground_surface`).
    points : numpy.ndarray, shape (N, 3)
        [m], map frame.
    """
    xyz = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return xyz[:, 2] - np.asarray(surface.height_at(xyz[:, :2]), dtype=np.float64)


def ground_fields(obstacles: ObstacleSet) -> Tuple[HeightField, ...]:
    """The ground among ``obstacles``: the height fields labelled ``terrain`` or ``ground``
    whose solid lies below them."""
    return tuple(field for field in obstacles.height_fields
                 if field.side == 'below' and field.label in ('terrain', 'ground'))


def ground_height(obstacles: ObstacleSet, xy: Sequence[float], floor: float) -> float:
    """Height of the ground under ``xy`` [m]: the highest of ``floor`` (the bounds' floor) and
    the ground height fields of ``obstacles`` that cover ``xy``."""
    point = np.asarray(xy, dtype=np.float64).reshape(1, 2)
    height = float(floor)
    for field in ground_fields(obstacles):
        lo, hi = field.extent
        if np.all(point[0] >= lo[:2]) and np.all(point[0] <= hi[:2]):
            height = max(height, float(field.height_at(point)[0]))
    return height


def without_ground(obstacles: ObstacleSet) -> ObstacleSet:
    """``obstacles`` without the solids below a surface (the ground and the AGL floor): what a
    take-off climb or a landing descent, straight up or down through them, is kept from."""
    kept = [item for item in obstacles.items
            if not (isinstance(item, HeightField) and item.side == 'below')]
    return obstacles if len(kept) == len(obstacles.items) else ObstacleSet(kept)
