"""The voxel grid of the workspace (paper eqs. 4-7).

Node ``(i, j, k)`` sits at ``bounds_min + (i, j, k) * resolution`` and there are
``floor((max - min) / resolution) + 1`` nodes per axis, which is the paper's eq. 7 whenever the
resolution divides the extent. Coordinates are in metres in the planning frame.
"""

from dataclasses import dataclass
import math

import numpy as np

from uav_global_planner.core.checks import check_point, check_positive
from uav_global_planner.core.errors import InvalidInputError

#: Distance from the centre of a cube of side 1 to its corners, sqrt(3) / 2: a point of a segment
#: between two 26-neighbour nodes, of a cell, or of a cube of side ``s`` lies within this times
#: delta (or ``s``) of a node (or the centre). The one name of the factor wherever a cell's reach
#: bounds a distance (the fallback grid, the raw polyline's deficit, a map cell's margin).
HALF_CELL_DIAGONAL = math.sqrt(3.0) / 2.0

#: Default cap on the number of grid nodes; a typo such as ``resolution = 0.001`` fails at once.
#: From 16 M nodes up the grid is block-sparse (:mod:`uav_global_planner.core.map.sparse_grid`):
#: the blocked mask takes 4 bytes per brick of 512 nodes (1/128 byte a node) plus one byte a
#: node only in the bricks an obstacle's surface crosses, and the search 17 bytes a node only
#: in the bricks it reaches (24 more per open-list entry). A 1 km x 1 km x 120 m city at
#: delta = 0.5 m (965 M nodes, 300 buildings) measured 0.075 bytes a node of mask and 0.02 of
#: search state for a 1.3 km crossing, peaking near 0.5 GB of resident memory; 1.2 G nodes
#: keep the brick tables and a mask of that kind well inside 2 GB. Set ``max_voxels`` (scene
#: files, ``uav-plan --max-voxels``, the node's parameter) to go beyond.
DEFAULT_MAX_VOXELS = 1_200_000_000

#: How a refusal tells the user to lift the cap.
_RAISE_CAP = ('or raise max_voxels (scene key max_voxels, uav-plan --max-voxels N or the node '
              'parameter max_voxels; memory follows the obstacle surfaces and the '
              'search, about 1/128 byte a node of volume plus 1 byte a node near surfaces '
              'and 17-41 bytes a node the search reaches)')

# Tolerance, in cells, for floating-point extents such as 15.0 / 0.1 = 149.99999999999997.
_CELL_EPS = 1e-9


def as_point(value, name: str) -> np.ndarray:
    """Return ``value`` as a finite float64 array of shape (3,)
    (:func:`~uav_global_planner.core.checks.check_point`, value first).

    Raises
    ------
    InvalidInputError
        ``<name> must be three numbers [x, y, z], got ...`` or ``<name> must be finite, got
        [...]``.
    """
    return check_point(name, value)


def positive_number(name: str, value, unit: str = '') -> float:
    """Return ``value`` as a finite float > 0
    (:func:`~uav_global_planner.core.checks.check_positive`).

    Raises
    ------
    InvalidInputError
        ``<name> must be a number, got ...``, ``<name> must be finite, got ...`` or ``<name>
        must be > 0 <unit>, got ...``.
    """
    return check_positive(name, value, unit)


@dataclass(frozen=True, eq=False)
class VoxelGrid:
    """Regular 3D grid of nodes inside axis-aligned bounds.

    Attributes
    ----------
    bounds_min : numpy.ndarray
        Minimum corner (x, y, z) [m]; node (0, 0, 0) lies here.
    bounds_max : numpy.ndarray
        Maximum corner (x, y, z) [m] as requested; the last node is at or just below it.
    resolution : float
        Node spacing delta [m].
    shape : tuple of int
        Nodes per axis (Nx, Ny, Nz).
    """

    bounds_min: np.ndarray
    bounds_max: np.ndarray
    resolution: float
    shape: tuple

    @classmethod
    def from_bounds(cls, bounds_min, bounds_max, resolution: float,
                    max_voxels: int = DEFAULT_MAX_VOXELS) -> 'VoxelGrid':
        """Build a grid, checking every input before allocating anything.

        Parameters
        ----------
        bounds_min, bounds_max : array_like, shape (3,)
            Corners of the workspace [m]; ``bounds_min < bounds_max`` on every axis.
        resolution : float
            Node spacing delta [m], > 0.
        max_voxels : int
            Largest accepted node count.

        Raises
        ------
        InvalidInputError
            For a non-positive or non-finite resolution, non-finite or inverted bounds, or a node
            count above ``max_voxels``.
        """
        lo = as_point(bounds_min, 'bounds.min')
        hi = as_point(bounds_max, 'bounds.max')
        delta = positive_number('resolution', resolution, 'm')
        if np.any(lo >= hi):
            raise InvalidInputError(
                f'bounds.min must be below bounds.max on every axis, got min {lo.tolist()} '
                f'and max {hi.tolist()}')
        counts = np.floor((hi - lo) / delta + _CELL_EPS) + 1.0
        total = float(np.prod(counts))
        if total > max_voxels:
            raise InvalidInputError(
                f'grid of {int(counts[0])} x {int(counts[1])} x {int(counts[2])} = {total:.3g} '
                f'nodes exceeds max_voxels = {max_voxels}; raise the resolution or shrink the '
                f'bounds, {_RAISE_CAP}')
        lo.setflags(write=False)
        hi.setflags(write=False)
        return cls(lo, hi, delta, tuple(int(c) for c in counts))

    @property
    def size(self) -> int:
        """Total number of nodes."""
        return self.shape[0] * self.shape[1] * self.shape[2]

    @property
    def upper_node(self) -> np.ndarray:
        """Position of the last node (Nx-1, Ny-1, Nz-1) [m]."""
        return self.bounds_min + (np.asarray(self.shape) - 1) * self.resolution

    def axis_coordinates(self, axis: int) -> np.ndarray:
        """Node coordinates along one axis [m], shape (N_axis,)."""
        return self.bounds_min[axis] + np.arange(self.shape[axis]) * self.resolution

    def contains(self, points) -> np.ndarray:
        """True where a point lies inside the bounds (eq. 4), boundary included.

        Parameters
        ----------
        points : array_like, shape (3,) or (M, 3)
            Positions [m].
        """
        p = np.asarray(points, dtype=np.float64)
        tol = _CELL_EPS * self.resolution
        return np.all((p >= self.bounds_min - tol) & (p <= self.bounds_max + tol), axis=-1)

    def world_to_index(self, points) -> np.ndarray:
        """Nearest node index of each point, clipped to the grid.

        Parameters
        ----------
        points : array_like, shape (3,) or (M, 3)
            Positions [m]; callers check :meth:`contains` first.

        Returns
        -------
        numpy.ndarray of int64, same leading shape, last axis (i, j, k).
        """
        p = np.asarray(points, dtype=np.float64)
        idx = np.rint((p - self.bounds_min) / self.resolution).astype(np.int64)
        return np.clip(idx, 0, np.asarray(self.shape, dtype=np.int64) - 1)

    def index_to_world(self, indices) -> np.ndarray:
        """Position of node indices [m] (eq. 5).

        Parameters
        ----------
        indices : array_like of int, shape (3,) or (M, 3)
        """
        return self.bounds_min + np.asarray(indices, dtype=np.float64) * self.resolution

    def ravel(self, indices) -> np.ndarray:
        """Flat (C-order) node number of (i, j, k) indices."""
        idx = np.asarray(indices, dtype=np.int64)
        return np.ravel_multi_index(tuple(np.moveaxis(idx, -1, 0)), self.shape)

    def unravel(self, flat) -> np.ndarray:
        """(i, j, k) indices of flat node numbers, last axis of length 3."""
        return np.stack(np.unravel_index(np.asarray(flat, dtype=np.int64), self.shape), axis=-1)
