"""Tiles and cells of a live map's grid: which grid nodes a change can reach.

A tile is a block of T x T x T grid nodes (T from :meth:`CellGeometry.of_grid`: cells of about
:data:`CELL_TARGET_M`, at most :data:`MAX_CELLS` of them); the cells that bucket the points of a
cloud (:class:`~uav_global_planner.core.map.point_cells.PointCells`) are the tiles' footprints.
A node is blocked iff an obstacle lies within gamma of it, so a change can only affect the nodes
within gamma of a shape added or removed, or of a cell whose points differ: the tiles within
``ceil(gamma / (T delta)) + 1`` tiles of it (:func:`reach_tiles`). Points outside the grid are
counted in its border cells, which keeps the rule: clamping a point into the grid moves it
towards every node.

:func:`shape_tiles` and :func:`cell_tiles` turn a change (shapes, cells) into the tiles to
re-inflate (:mod:`~uav_global_planner.core.map.mask_buffers`).
"""

from dataclasses import dataclass
import math
from typing import Iterable, Optional, Sequence, Union

import numpy as np
from scipy import ndimage

from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.obstacles import Box, Obstacle, Sphere

#: Aimed-at cell edge [m]: about the distance cap of the clearance engine's queries (gamma plus
#: a metre), so a query reads a few cells per axis, and small enough that a local change
#: re-inflates little around it.
CELL_TARGET_M = 1.0
#: Most cells per grid (their index costs 8 bytes each per cloud).
MAX_CELLS = 2_000_000
#: Largest tile edge [nodes].
MAX_TILE_NODES = 64
#: Cells per edge of the coarse blocks that wide and uncapped queries search over.
COARSE_CELLS = 4
# Relative slack of the lower bounds that prune cells [m / m]: far above the rounding of cell
# boundaries, far below anything a clearance certificate resolves.
_SLACK = 1e-9


@dataclass(frozen=True, eq=False)
class CellGeometry:
    """The cells (tile footprints) of one grid.

    Attributes
    ----------
    origin : numpy.ndarray, shape (3,)
        World position of the corner of cell (0, 0, 0): the grid's first node [m].
    cell : float
        Cell edge ``tile_nodes * delta`` [m].
    tiles : numpy.ndarray of int64, shape (3,)
        Tiles per axis, covering every node: ``ceil(N / tile_nodes)``.
    dims : numpy.ndarray of int64, shape (3,)
        Cells per axis: ``tiles`` rounded up to a multiple of :data:`COARSE_CELLS`. Cells on
        the border hold the points beyond it as well.
    """

    origin: np.ndarray
    cell: float
    tiles: np.ndarray
    dims: np.ndarray
    tile_nodes: int

    @classmethod
    def of_grid(cls, grid: VoxelGrid) -> 'CellGeometry':
        """The cells of ``grid``: edges of about :data:`CELL_TARGET_M`, at most
        :data:`MAX_CELLS` of them."""
        delta = float(grid.resolution)
        size = max(int(round(CELL_TARGET_M / delta)),
                   int(math.ceil((grid.size / MAX_CELLS) ** (1.0 / 3.0))), 1)
        size = min(size, MAX_TILE_NODES)
        tiles = -(-np.asarray(grid.shape, dtype=np.int64) // size)
        dims = -(-tiles // COARSE_CELLS) * COARSE_CELLS
        origin = np.array(grid.bounds_min, dtype=np.float64)
        origin.setflags(write=False)
        return cls(origin, delta * size, tiles, dims, size)

    @property
    def key(self) -> tuple:
        """Equal for equal geometries."""
        return (tuple(self.origin.tolist()), self.cell, tuple(self.dims.tolist()),
                tuple(self.tiles.tolist()))

    @property
    def count(self) -> int:
        """Number of cells."""
        return int(np.prod(self.dims))

    @property
    def slack(self) -> float:
        """Pruning slack [m] (see :data:`_SLACK`)."""
        return _SLACK * (self.cell + float(np.max(np.abs(self.origin))))


def reach_tiles(gamma: float, geometry: CellGeometry) -> int:
    """How many tiles from a changed cell the nodes within gamma of its points can lie.

    A point of cell a lies within the nodes [a T, (a + 1) T) of each axis, so the nodes within
    gamma of it lie in the tiles a - ceil(x) .. a + ceil(x), x = gamma / (T delta); floor(x) + 1
    is that, or one more when x is a whole number (room for a point rounded into the next cell).
    """
    return int(math.floor(float(gamma) / geometry.cell)) + 1


def dilate_cells(flat: np.ndarray, dims: Union[Sequence[int], np.ndarray],
                 reach: int) -> np.ndarray:
    """Flat numbers of the cells within ``reach`` cells (Chebyshev) of the given ones.

    Parameters
    ----------
    flat : numpy.ndarray of int
        Flat cell numbers of a C-ordered array of shape ``dims``.
    dims : sequence of 3 int
    reach : int
        >= 0.

    Returns
    -------
    numpy.ndarray of int64
        Ascending, each once.
    """
    shape = tuple(int(d) for d in dims)
    count = int(np.prod(shape))
    flat = np.asarray(flat, dtype=np.int64)
    if len(flat) == 0 or reach == 0:
        return np.unique(flat)
    side = 2 * int(reach) + 1
    if len(flat) * side ** 3 > count // 4:
        mask = np.zeros(count, dtype=bool)
        mask[flat] = True
        grown = ndimage.maximum_filter(mask.reshape(shape), size=side, mode='constant')
        return np.flatnonzero(grown)
    steps = np.arange(-int(reach), int(reach) + 1)
    offsets = np.stack(np.meshgrid(steps, steps, steps, indexing='ij'), axis=-1).reshape(-1, 3)
    index = np.stack(np.unravel_index(flat, shape), axis=-1)
    near = (index[:, None, :] + offsets[None, :, :]).reshape(-1, 3)
    inside = np.all((near >= 0) & (near < np.asarray(shape)), axis=1)
    return np.unique(np.ravel_multi_index(tuple(near[inside].T), shape))


def shape_tiles(grid: VoxelGrid, shapes: Iterable[Obstacle], safety_margin: float,
                geometry: CellGeometry) -> Optional[np.ndarray]:
    """Flat numbers of the tiles with a node within gamma of any of the shapes, ascending.

    None when a shape has no cheap bound (zones, fences, height fields): anything may have
    changed.
    """
    size = geometry.tile_nodes
    gamma = float(safety_margin)
    delta = float(grid.resolution)
    tiles = tuple(int(t) for t in geometry.tiles)
    last = np.asarray(tiles, dtype=np.int64) - 1
    top = np.asarray(grid.shape, dtype=np.float64) + 1.0
    parts = []
    for shape in shapes:
        if isinstance(shape, Sphere):
            lo, hi = shape.center - shape.radius, shape.center + shape.radius
        elif isinstance(shape, Box):
            lo, hi = shape.min, shape.max
        else:
            return None
        # One node of slack beyond gamma on each side, as the inflation's own blocks.
        first = np.floor(np.clip((lo - gamma - grid.bounds_min) / delta, -2.0, top)) - 1
        final = np.ceil(np.clip((hi + gamma - grid.bounds_min) / delta, -2.0, top)) + 1
        first = np.maximum(first.astype(np.int64), 0) // size
        final = np.minimum(np.maximum(final.astype(np.int64), 0) // size, last)
        if np.all(first <= final):
            axes = [np.arange(first[a], final[a] + 1) for a in range(3)]
            index = np.stack(np.meshgrid(*axes, indexing='ij'), axis=-1).reshape(-1, 3)
            parts.append(np.ravel_multi_index(tuple(index.T), tiles))
    if not parts:
        return np.empty(0, dtype=np.int64)
    return np.unique(np.concatenate(parts))


def cell_tiles(cells: np.ndarray, geometry: CellGeometry, reach: int) -> np.ndarray:
    """Flat numbers of the tiles with a node within gamma of a point of the given cells
    (``reach`` from :func:`reach_tiles`), ascending."""
    grown = dilate_cells(cells, geometry.dims, reach)
    index = np.stack(np.unravel_index(grown, tuple(int(d) for d in geometry.dims)), axis=-1)
    # Cells beyond the last tile hold points beyond the grid; they reach into the last tiles.
    index = np.minimum(index, geometry.tiles - 1)
    return np.unique(np.ravel_multi_index(tuple(index.T), tuple(int(t) for t in geometry.tiles)))


# --------------------------------------------------------------------------------------------
# The map builder
