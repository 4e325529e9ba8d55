"""Obstacle shapes and the exact Euclidean distance to them (paper eq. 9).

Three shapes: spheres (centre, radius), axis-aligned boxes (min and max corners) and point sets
(occupied points, for example a point cloud or an octomap's occupied-cell centres). Distances are
to the obstacle's surface, 0 inside it, in metres. The same distance functions drive the grid
inflation (:mod:`uav_global_planner.core.inflation`) and the clearance check of smoothed paths, so
the two can never disagree.
"""

from dataclasses import dataclass
import math
from typing import Iterable, Sequence, Union

import numpy as np
from scipy.spatial import cKDTree

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.grid import as_point
from uav_global_planner.core.jit import njit


@dataclass(frozen=True, eq=False)
class Sphere:
    """Sphere obstacle.

    Attributes
    ----------
    center : numpy.ndarray, shape (3,)
        Centre [m].
    radius : float
        Radius [m], > 0.
    """

    center: np.ndarray
    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, 'center', as_point(self.center, 'sphere center'))
        radius = _finite_float(self.radius, 'sphere radius')
        if radius <= 0.0:
            raise InvalidInputError(f'sphere radius must be > 0 m, got {radius}')
        object.__setattr__(self, 'radius', radius)


@dataclass(frozen=True, eq=False)
class Box:
    """Axis-aligned box obstacle.

    Attributes
    ----------
    min, max : numpy.ndarray, shape (3,)
        Opposite corners [m], ``min < max`` on every axis.
    """

    min: np.ndarray
    max: np.ndarray

    def __post_init__(self) -> None:
        lo = as_point(self.min, 'box min')
        hi = as_point(self.max, 'box max')
        if np.any(lo >= hi):
            raise InvalidInputError(
                f'box min must be below box max on every axis, got {lo.tolist()} and '
                f'{hi.tolist()}')
        object.__setattr__(self, 'min', lo)
        object.__setattr__(self, 'max', hi)


@dataclass(frozen=True, eq=False)
class PointSet:
    """Set of occupied points.

    Attributes
    ----------
    points : numpy.ndarray, shape (M, 3)
        Occupied positions [m], all finite; M may be 0.
    """

    points: np.ndarray

    def __post_init__(self) -> None:
        try:
            pts = np.asarray(self.points, dtype=np.float64)
        except (TypeError, ValueError):
            raise InvalidInputError('points must be a list of [x, y, z] triples') from None
        if pts.size == 0:
            pts = pts.reshape(0, 3)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise InvalidInputError(
                f'points must have shape (M, 3), got shape {tuple(pts.shape)}')
        if not np.all(np.isfinite(pts)):
            raise InvalidInputError('points must be finite; found NaN or inf')
        object.__setattr__(self, 'points', pts)


Obstacle = Union[Sphere, Box, PointSet]


def _finite_float(value, name: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f'{name} must be a number, got {value!r}') from None
    if not np.isfinite(number):
        raise InvalidInputError(f'{name} must be finite, got {number}')
    return number


def sphere_distance(points: np.ndarray, centers: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Distance from each point to the nearest of several spheres [m], 0 inside.

    Parameters
    ----------
    points : numpy.ndarray, shape (..., 3)
    centers : numpy.ndarray, shape (S, 3)
    radii : numpy.ndarray, shape (S,)

    Returns
    -------
    numpy.ndarray, shape (...), +inf when S = 0.
    """
    flat = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.full(len(flat), np.inf)
    if len(radii):
        _nearest_sphere_gap(flat, np.ascontiguousarray(centers, dtype=np.float64),
                            np.ascontiguousarray(radii, dtype=np.float64), out)
    return np.maximum(out, 0.0).reshape(np.shape(points)[:-1])


@njit
def _nearest_sphere_gap(points, centers, radii, out):  # pragma: no cover - compiled
    # One pass per point over every sphere, no temporaries: this runs on every clearance check
    # of smoothing, on thousands of samples. The sum is formed in the same order as numpy's
    # sum over the last axis, so inflation and clearance checks agree to the last bit.
    for n in range(points.shape[0]):
        best = out[n]
        for s in range(radii.shape[0]):
            dx = points[n, 0] - centers[s, 0]
            dy = points[n, 1] - centers[s, 1]
            dz = points[n, 2] - centers[s, 2]
            gap = math.sqrt(dx * dx + dy * dy + dz * dz) - radii[s]
            if gap < best:
                best = gap
        out[n] = best


def box_distance(points: np.ndarray, mins: np.ndarray, maxs: np.ndarray) -> np.ndarray:
    """Distance from each point to the nearest of several axis-aligned boxes [m], 0 inside.

    Parameters
    ----------
    points : numpy.ndarray, shape (..., 3)
    mins, maxs : numpy.ndarray, shape (B, 3)
    """
    out = np.full(points.shape[:-1], np.inf)
    for lo, hi in zip(mins, maxs):
        excess = np.maximum(np.maximum(lo - points, points - hi), 0.0)
        np.minimum(out, np.sqrt(np.sum(excess ** 2, axis=-1)), out=out)
    return out


class ObstacleSet:
    """Immutable collection of obstacles with vectorised distance queries.

    Parameters
    ----------
    obstacles : iterable of Sphere, Box or PointSet
    """

    def __init__(self, obstacles: Iterable[Obstacle] = ()) -> None:
        items = tuple(obstacles)
        for number, item in enumerate(items):
            if not isinstance(item, (Sphere, Box, PointSet)):
                raise InvalidInputError(
                    f'obstacle {number} has unsupported type {type(item).__name__}')
        self._items = items
        spheres = [o for o in items if isinstance(o, Sphere)]
        boxes = [o for o in items if isinstance(o, Box)]
        clouds = [o.points for o in items if isinstance(o, PointSet)]
        self.sphere_centers = np.array([s.center for s in spheres]).reshape(-1, 3)
        self.sphere_radii = np.array([s.radius for s in spheres], dtype=np.float64)
        self.box_mins = np.array([b.min for b in boxes]).reshape(-1, 3)
        self.box_maxs = np.array([b.max for b in boxes]).reshape(-1, 3)
        self.points = (np.concatenate(clouds) if clouds else np.empty((0, 3)))
        self._tree = cKDTree(self.points) if len(self.points) else None
        for array in (self.sphere_centers, self.sphere_radii, self.box_mins, self.box_maxs,
                      self.points):
            array.setflags(write=False)

    @property
    def items(self) -> Sequence[Obstacle]:
        """The obstacles as given."""
        return self._items

    def __len__(self) -> int:
        return len(self._items)

    def is_empty(self) -> bool:
        """True when there is nothing to avoid."""
        return not (len(self.sphere_radii) or len(self.box_mins) or len(self.points))

    def distance(self, points) -> np.ndarray:
        """Euclidean distance from each point to the nearest obstacle [m] (eq. 9).

        Parameters
        ----------
        points : array_like, shape (3,) or (M, 3)
            Query positions [m].

        Returns
        -------
        numpy.ndarray, shape () or (M,)
            Distance to the nearest obstacle surface, 0 inside an obstacle, +inf when the set is
            empty.
        """
        p = np.asarray(points, dtype=np.float64)
        out = np.minimum(sphere_distance(p, self.sphere_centers, self.sphere_radii),
                         box_distance(p, self.box_mins, self.box_maxs))
        if self._tree is not None:
            nearest, _ = self._tree.query(p.reshape(-1, 3))
            out = np.minimum(out, nearest.reshape(p.shape[:-1]))
        return out
