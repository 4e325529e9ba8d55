"""The zones and fences of the airspace, as rows of the shape table.

Exclusion zones (no-fly volumes): vertical prisms (:class:`Prism`: polygon, floor, ceiling),
vertical cylinders (:class:`Cylinder`: centre, radius, floor, ceiling) and axis-aligned boxes
(:class:`BoxZone`). Inclusion fences (operating areas, the vehicle stays inside): a polygon
(:class:`InclusionFence`) or a circle (:class:`InclusionCircle`) between a floor and a ceiling.
Every one is a row of the shape table of :mod:`uav_global_planner.core.map.spatial_index`, with
an exact distance (to a zone's solid, 0 inside it; to the *outside* of a fence, 0 outside it),
and is validated on construction; messages name the field (``radius: must be > 0 m, got
-1.0``), and the file readers put the key path before it.

Coordinates are in the planning frame [m], z up. Floors and ceilings may be left out: a zone
without a floor reaches down without end, one without a ceiling up without end.
"""

from dataclasses import dataclass
import math
from typing import Any, Tuple, Union

import numpy as np

from uav_global_planner.core.checks import check_number, check_point
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.polygons import checked_polygon
from uav_global_planner.core.map.spatial_index import (BOX, CIRCLE_FENCE, CYLINDER, FENCE, PRISM,
                                                       TableShape)

#: No floor: a zone reaches down without end [m].
LOWEST = -math.inf
#: No ceiling: a zone reaches up without end [m].
HIGHEST = math.inf


def check_band(floor: Any, ceiling: Any) -> Tuple[float, float]:
    """Validated (floor, ceiling) [m]; either may be infinite (no limit)."""
    low = check_number('floor:', floor, finite=False)
    high = check_number('ceiling:', ceiling, finite=False)
    if low == HIGHEST:
        raise InvalidInputError('floor: must be below +inf')
    if high == LOWEST:
        raise InvalidInputError('ceiling: must be above -inf')
    if not low < high:
        raise InvalidInputError(f'floor: must be below the ceiling, got floor {low} m and '
                                f'ceiling {high} m')
    return low, high


def _plane_point(value: Any, name: str) -> np.ndarray:
    return check_point(f'{name}:', value, 'xy')


def _radius(value: Any) -> float:
    return check_number('radius:', value, 0.0, low_open=True, unit='m')


def _polygon_row(polygon: np.ndarray, floor: float, ceiling: float) -> np.ndarray:
    lo = polygon.min(axis=0)
    hi = polygon.max(axis=0)
    return np.array([lo[0], lo[1], floor, hi[0], hi[1], ceiling])


@dataclass(frozen=True, eq=False)
class PolygonBand(TableShape):
    """A polygon in x-y between a floor and a ceiling, validated on construction.

    Attributes
    ----------
    polygon : numpy.ndarray, shape (V, 2)
        Simple polygon [m], either orientation, convex or not.
    floor, ceiling : float
        Height interval [m], floor < ceiling; -inf / +inf for no limit.
    label : str
        What messages call it.
    """

    polygon: np.ndarray
    floor: float = LOWEST
    ceiling: float = HIGHEST
    label: str = ''

    def __post_init__(self) -> None:
        object.__setattr__(self, 'polygon', checked_polygon(self.polygon))
        floor, ceiling = check_band(self.floor, self.ceiling)
        object.__setattr__(self, 'floor', floor)
        object.__setattr__(self, 'ceiling', ceiling)


@dataclass(frozen=True, eq=False)
class CircleBand(TableShape):
    """A circle in x-y between a floor and a ceiling, validated on construction.

    Attributes
    ----------
    center : numpy.ndarray, shape (2,)
        Axis position (x, y) [m].
    radius : float
        [m], > 0.
    floor, ceiling : float
        Height interval [m], floor < ceiling; -inf / +inf for no limit.
    label : str
        What messages call it.
    """

    center: np.ndarray
    radius: float
    floor: float = LOWEST
    ceiling: float = HIGHEST
    label: str = ''

    def __post_init__(self) -> None:
        object.__setattr__(self, 'center', _plane_point(self.center, 'center'))
        object.__setattr__(self, 'radius', _radius(self.radius))
        floor, ceiling = check_band(self.floor, self.ceiling)
        object.__setattr__(self, 'floor', floor)
        object.__setattr__(self, 'ceiling', ceiling)

    def _row(self) -> np.ndarray:
        return np.array([self.center[0], self.center[1], self.radius, self.floor, self.ceiling,
                         0.0])


@dataclass(frozen=True, eq=False)
class Prism(PolygonBand):
    """Solid vertical prism: a polygon in x-y between a floor and a ceiling (a no-fly volume).

    Built from ``polygon`` [m] (V, 2), ``floor`` and ``ceiling`` [m] and ``label`` (default
    ``'prism'``), checked as :class:`PolygonBand` says.
    """

    label: str = 'prism'

    def table_row(self) -> Tuple[int, np.ndarray, np.ndarray]:
        return PRISM, _polygon_row(self.polygon, self.floor, self.ceiling), self.polygon


@dataclass(frozen=True, eq=False)
class Cylinder(CircleBand):
    """Solid vertical cylinder (a no-fly volume).

    Built from ``center`` (x, y) [m], ``radius`` [m], ``floor`` and ``ceiling`` [m] and
    ``label`` (default ``'cylinder'``), checked as :class:`CircleBand` says.
    """

    label: str = 'cylinder'

    def table_row(self) -> Tuple[int, np.ndarray, np.ndarray]:
        return CYLINDER, self._row(), np.empty((0, 2))


@dataclass(frozen=True, eq=False)
class BoxZone(TableShape):
    """Axis-aligned box no-fly volume.

    Attributes
    ----------
    min, max : numpy.ndarray, shape (3,)
        Opposite corners [m], min < max on every axis.
    label : str
    """

    min: np.ndarray
    max: np.ndarray
    label: str = 'box'

    def __post_init__(self) -> None:
        lo = check_point('min:', self.min)
        hi = check_point('max:', self.max)
        if np.any(lo >= hi):
            raise InvalidInputError(f'min: must be below max on every axis, got min '
                                    f'{lo.tolist()} and max {hi.tolist()}')
        object.__setattr__(self, 'min', lo)
        object.__setattr__(self, 'max', hi)

    def table_row(self) -> Tuple[int, np.ndarray, np.ndarray]:
        return BOX, np.r_[self.min, self.max], np.empty((0, 2))


@dataclass(frozen=True, eq=False)
class InclusionFence(PolygonBand):
    """Operating area: a polygon in x-y between a floor and a ceiling; the vehicle stays inside.

    As a shape it is the *outside* of that prism: its distance is the distance to the nearest
    wall, floor or ceiling from inside, 0 outside. Built like :class:`Prism` (fields of
    :class:`PolygonBand`); without floor or ceiling the planning bounds still apply.
    """

    label: str = 'the inclusion fence'

    def table_row(self) -> Tuple[int, np.ndarray, np.ndarray]:
        return FENCE, _polygon_row(self.polygon, self.floor, self.ceiling), self.polygon


@dataclass(frozen=True, eq=False)
class InclusionCircle(CircleBand):
    """Circular operating area (a QGroundControl inclusion circle): stay inside the cylinder.

    Built like :class:`Cylinder` (fields of :class:`CircleBand`).
    """

    label: str = 'the inclusion fence'

    def table_row(self) -> Tuple[int, np.ndarray, np.ndarray]:
        return CIRCLE_FENCE, self._row(), np.empty((0, 2))


Inclusion = Union[InclusionFence, InclusionCircle]
Exclusion = Union[Prism, Cylinder, BoxZone]
