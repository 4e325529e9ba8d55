"""Obstacle shapes and the exact Euclidean distance to them (paper eq. 9).

Three shapes: spheres (centre, radius), axis-aligned boxes (min and max corners) and point sets
(occupied points, for example a point cloud or an octomap's occupied-cell centres). Terrain and
ground surfaces (:class:`~uav_global_planner.core.map.terrain.HeightField`, the solid below or
above a triangulated height field) join as they are, with their own exact distance. Airspace
zones and fences (:mod:`uav_global_planner.core.map.airspace`: prisms, cylinders, the outside of an
inclusion fence) join the same shape table, so every distance query covers them. Distances are
to the obstacle's surface, 0 inside it, in metres. The same distance functions drive the grid
inflation (:mod:`uav_global_planner.core.map.inflation`) and the clearance check of smoothed paths,
so the two can never disagree.
"""

from dataclasses import dataclass
import math
import threading
from typing import Dict, Iterable, Sequence, Union

import numpy as np

from uav_global_planner.core.checks import check_point, check_positive
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.jit import njit
from uav_global_planner.core.map.spatial_index import (BOX, BRUTE_FORCE_SHAPES, min_gap_all,
                                                       ShapeIndex, SPHERE, TableShape)
from uav_global_planner.core.map.terrain import HeightField

# Smallest reach of a shape lattice [m]: caps below it share one lattice.
_SMALLEST_REACH = 0.25
# Lattices kept per obstacle set (one per power-of-two reach in use).
_MAX_INDEXES = 4


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
        object.__setattr__(self, 'center', check_point('sphere center', self.center))
        object.__setattr__(self, 'radius', check_positive('sphere radius', self.radius, 'm'))


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
        lo = check_point('box min', self.min)
        hi = check_point('box max', self.max)
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


Obstacle = Union[Sphere, Box, PointSet, TableShape, HeightField]


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

    Spheres, boxes and table shapes (airspace zones and fences) form one shape table
    (:mod:`uav_global_planner.core.map.spatial_index`), point sets one KD-tree. A query with a
    ``cap`` looks only at what lies within ``cap`` of each query point (fences, which are
    unbounded, are evaluated exactly for every query), so its cost follows the obstacles near
    the query, not their number. Height fields (terrain, ground, AGL floors and ceilings) are
    kept in :attr:`height_fields` and queried each with its own exact, capped distance.

    Parameters
    ----------
    obstacles : iterable of Sphere, Box, PointSet, TableShape or HeightField
        Table shapes (:class:`~uav_global_planner.core.map.spatial_index.TableShape`, for example
        the zones of :mod:`uav_global_planner.core.map.airspace`) keep their order in
        :attr:`zones`; their rows follow the spheres' and boxes' (:attr:`zone_rows`).
    """

    def __init__(self, obstacles: Iterable[Obstacle] = ()) -> None:
        items = tuple(obstacles)
        for number, item in enumerate(items):
            if not isinstance(item, (Sphere, Box, PointSet, TableShape, HeightField)):
                raise InvalidInputError(
                    f'obstacle {number} has unsupported type {type(item).__name__}')
        self._items = items
        spheres = [o for o in items if isinstance(o, Sphere)]
        boxes = [o for o in items if isinstance(o, Box)]
        clouds = [o.points for o in items if isinstance(o, PointSet)]
        zones = [o for o in items if isinstance(o, TableShape)]
        #: The height fields (terrain, ground, AGL floors and ceilings), in the order given.
        self.height_fields = tuple(o for o in items if isinstance(o, HeightField))
        self.sphere_centers = np.array([s.center for s in spheres]).reshape(-1, 3)
        self.sphere_radii = np.array([s.radius for s in spheres], dtype=np.float64)
        self.box_mins = np.array([b.min for b in boxes]).reshape(-1, 3)
        self.box_maxs = np.array([b.max for b in boxes]).reshape(-1, 3)
        # One cloud (a map file) is kept as it is: a copy of millions of points would double
        # their memory.
        self.points = (clouds[0] if len(clouds) == 1
                       else np.concatenate(clouds) if clouds else np.empty((0, 3)))
        self._tree = None
        if len(self.points):
            from scipy.spatial import cKDTree  # only for point clouds: a slow import
            self._tree = cKDTree(self.points)
        sphere_rows = np.zeros((len(spheres), 6))
        sphere_rows[:, :3] = self.sphere_centers
        sphere_rows[:, 3] = self.sphere_radii
        zone_rows = [zone.table_row() for zone in zones]
        self.zones = tuple(zones)
        self.zone_rows = np.arange(len(spheres) + len(boxes),
                                   len(spheres) + len(boxes) + len(zones), dtype=np.int64)
        self.shape_kind = np.r_[np.full(len(spheres), SPHERE, dtype=np.int64),
                                np.full(len(boxes), BOX, dtype=np.int64),
                                np.array([row[0] for row in zone_rows], dtype=np.int64)]
        self.shape_params = np.ascontiguousarray(
            np.vstack([sphere_rows, np.hstack([self.box_mins, self.box_maxs]),
                       np.array([row[1] for row in zone_rows]).reshape(-1, 6)]))
        # Polygon vertices of the zone rows, flat; row s owns vertices[vstart[s]:vstart[s + 1]].
        counts = np.zeros(len(self.shape_kind), dtype=np.int64)
        counts[self.zone_rows] = [len(row[2]) for row in zone_rows]
        self.shape_vstart = np.r_[0, np.cumsum(counts)].astype(np.int64)
        self.shape_vertices = np.ascontiguousarray(
            np.vstack([np.empty((0, 2))] + [row[2] for row in zone_rows]), dtype=np.float64)
        for array in (self.sphere_centers, self.sphere_radii, self.box_mins, self.box_maxs,
                      self.points, self.shape_kind, self.shape_params, self.zone_rows,
                      self.shape_vstart, self.shape_vertices):
            array.setflags(write=False)
        self._indexes: Dict[float, ShapeIndex] = {}
        self._index_lock = threading.Lock()

    @property
    def items(self) -> Sequence[Obstacle]:
        """The obstacles as given."""
        return self._items

    def __len__(self) -> int:
        return len(self._items)

    def is_empty(self) -> bool:
        """True when there is nothing to avoid."""
        return not (len(self.shape_kind) or len(self.points) or self.height_fields)

    def distance(self, points, cap: float = math.inf) -> np.ndarray:
        """Euclidean distance from each point to the nearest obstacle [m] (eq. 9).

        Parameters
        ----------
        points : array_like, shape (3,) or (M, 3)
            Query positions [m].
        cap : float
            Distances at or above this are reported as ``cap`` [m], > 0; +inf (the default)
            gives every distance exactly. A capped distance is a lower bound of the true one
            everywhere and equal to it below ``cap``, which is all a clearance certificate
            needs, at a cost that follows the obstacles within ``cap`` of the query only.

        Returns
        -------
        numpy.ndarray, shape () or (M,)
            Distance to the nearest obstacle surface, 0 inside an obstacle, +inf when the set is
            empty and no cap is given.
        """
        p = np.asarray(points, dtype=np.float64)
        flat = np.ascontiguousarray(p.reshape(-1, 3))
        capped = math.isfinite(cap)
        if capped and not cap > 0.0:
            raise InvalidInputError(f'distance cap must be > 0 m, got {cap}')
        if capped and len(self.shape_kind) > BRUTE_FORCE_SHAPES:
            out = self._index(cap).query(flat, cap)
        else:
            out = min_gap_all(flat, self.shape_kind, self.shape_params, self.shape_vertices,
                              self.shape_vstart)
        if self._tree is not None:
            nearest, _ = self._tree.query(flat, distance_upper_bound=cap)
            np.minimum(out, nearest, out=out)
        for field in self.height_fields:
            np.minimum(out, field.distance(flat, cap), out=out)
        if capped:
            np.minimum(out, cap, out=out)
        return out.reshape(p.shape[:-1])

    def _index(self, cap: float) -> ShapeIndex:
        """The shape lattice for caps up to the next power of two of ``cap`` (built once)."""
        reach = 2.0 ** math.ceil(math.log2(max(cap, _SMALLEST_REACH)))
        index = self._indexes.get(reach)
        if index is None:
            with self._index_lock:
                index = self._indexes.get(reach)
                if index is None:
                    index = ShapeIndex(self.shape_kind, self.shape_params, reach,
                                       self.shape_vertices, self.shape_vstart)
                    if len(self._indexes) >= _MAX_INDEXES:
                        self._indexes.pop(next(iter(self._indexes)))
                    self._indexes[reach] = index
        return index
