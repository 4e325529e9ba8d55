"""Live maps: obstacles that change while the vehicle flies, indexed and inflated incrementally.

A mapping stack (octomap_server, voxblox, nvblox, a LiDAR SLAM) republishes the occupied space
at 1-10 Hz, and markers add or remove shapes in between. Rebuilding the inflated grid and the
point index of a large map for every message takes seconds; this module keeps both up to date
at a cost that follows what changed, and gives every consumer one consistent map at a time.

The pieces
----------
:class:`PointCells`
    A point index for one cloud: the points bucketed into cells (the footprints of the tiles
    of grid nodes, see below), sorted by cell, in input order within a cell. Built in linear
    time (60-80 ms for 820 k points on this project's machine; about 30 ms when the cloud is the
    previous one with a few rows changed, the usual republished map), so every cloud gets its
    own; two clouds are compared cell by cell, exactly (:func:`changed_cells`). Capped distance
    queries (what the clearance engine asks) read the cells within the cap; wider and uncapped
    ones search outward over coarser blocks of cells, skipping empty space.
:class:`LiveObstacles`
    An :class:`~uav_global_planner.core.map.obstacles.ObstacleSet` of shapes (markers) plus point
    layers (the newest cloud, a static prior map), each point layer indexed once: a marker
    update keeps the cloud's index, a cloud update the prior's.
:class:`MaskBuffers`
    Up to three inflated masks of one grid and margin. The planner reads one while the next is
    written, so a plan always runs on one consistent map (double buffering; a third buffer lets
    a new map be written while the newest one waits to be picked up). A buffer is brought up to
    date by re-inflating only the tiles changed since it was last written
    (:func:`~uav_global_planner.core.map.inflation.reinflate_tiles`), which gives the mask of a
    full rebuild to the bit.
:class:`LiveMapBuilder`
    Applies marker and cloud updates and produces :class:`LiveMap` objects: obstacles, their
    inflated mask and what the update cost.

Which tiles change
------------------
A tile is a block of T x T x T grid nodes (T from :meth:`CellGeometry.of_grid`: cells of about
:data:`CELL_TARGET_M`, at most :data:`MAX_CELLS` of them), and the cells of :class:`PointCells`
are the tiles' footprints. A node is blocked iff an obstacle lies within
gamma of it, so a change can only affect the nodes within gamma of a shape added or removed, or
of a cell whose points differ: the tiles within ``ceil(gamma / (T delta)) + 1`` tiles of it
(:func:`reach_tiles`). Points outside the grid are counted in its border cells, which keeps the
rule: clamping a point into the grid moves it towards every node.

One module, though long (about 1200 lines): the point-cell index, its compiled kernels and the
tile-wise mask writer share the cell geometry, the fingerprints and the tile numbering; each
kernel is private to the structure it serves.
"""

from dataclasses import dataclass
import math
import time
from typing import Any, Dict, Hashable, Iterable, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
from scipy import ndimage

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.jit import njit
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import (blocked_mask, Mask, reinflate_sparse,
                                                   reinflate_tiles)
from uav_global_planner.core.map.obstacles import Box, Obstacle, ObstacleSet, PointSet, Sphere
from uav_global_planner.core.map.sparse_grid import choose_layout, SparseMask
from uav_global_planner.core.map.terrain import HeightField
from uav_global_planner.core.planner import fallback_margin

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
#: Above this fraction of stale tiles a mask is rebuilt whole (cheaper than tile by tile).
FULL_REBUILD_FRACTION = 0.5
#: Masks kept per grid: the one the planner reads, the newest, and one being written.
MAX_BUFFERS = 3

# Relative slack of the lower bounds that prune cells [m / m]: far above the rounding of cell
# boundaries, far below anything a clearance certificate resolves.
_SLACK = 1e-9

# splitmix64 constants: a 64-bit fingerprint of each point's exact coordinates, with which two
# clouds holding the same points in another order compare equal.
_SEED = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_SHIFT30 = np.uint64(30)
_SHIFT27 = np.uint64(27)
_SHIFT31 = np.uint64(31)


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


# --------------------------------------------------------------------------------------------
# The point index
# --------------------------------------------------------------------------------------------

class PointCells:
    """Occupied points of one cloud, bucketed into the cells of a grid.

    Parameters
    ----------
    points : array_like, shape (M, 3)
        Finite positions [m] in the planning frame; M may be 0. Kept by reference: do not
        change the array afterwards.
    geometry : CellGeometry
    previous : PointCells, optional
        The previous cloud of the same source: when the new one holds the same number of
        points, nearly all of them the same rows bit for bit, only the differing rows are
        indexed anew (see :meth:`_update`); the result is the same.

    Attributes
    ----------
    points : numpy.ndarray, shape (M, 3)
        The points sorted by cell (read-only).
    geometry : CellGeometry
    start : numpy.ndarray of int64, shape (cells + 1,)
        The points of flat cell ``f`` are ``points[start[f]:start[f + 1]]``.
    changed_from_previous : numpy.ndarray of int64 or None
        Flat numbers of the cells whose points differ from ``previous`` (a superset of what
        :func:`changed_cells` finds), when the update path was taken; else None.

    Raises
    ------
    InvalidInputError
        If the points are not an (M, 3) array of finite numbers.
    """

    def __init__(self, points, geometry: CellGeometry,
                 previous: Optional['PointCells'] = None) -> None:
        raw = PointSet(points).points  # the same checks as any point obstacle
        raw = np.ascontiguousarray(raw)
        self.geometry = geometry
        self.changed_from_previous: Optional[np.ndarray] = None
        shape = tuple(int(d) for d in geometry.dims)
        coarse = tuple(d // COARSE_CELLS for d in shape)
        if not (previous is not None and self._update(raw, previous)):
            self._build(raw, shape, coarse)
        # The cloud as given, in its order, for comparing the next one with it (kept by
        # reference: the caller must not change the array afterwards).
        self._raw = raw
        self.points.setflags(write=False)
        self.start.setflags(write=False)
        # Chebyshev distance (in coarse blocks) to the nearest occupied block: the outward
        # search of a query starts there.
        if len(raw):
            self._coarse_ring = np.ascontiguousarray(ndimage.distance_transform_cdt(
                self._coarse_count == 0, metric='chessboard').astype(np.int64))
        else:
            self._coarse_ring = np.full(coarse, np.iinfo(np.int32).max, dtype=np.int64)

    def _build(self, raw: np.ndarray, shape: Tuple[int, ...],
               coarse: Tuple[int, ...]) -> None:
        """Index a cloud from scratch (linear time: a counting sort by cell)."""
        geometry = self.geometry
        count = geometry.count
        bits = raw.view(np.uint64).reshape(-1, 3)
        self._coarse_count = np.zeros(coarse, dtype=np.int64)
        # start[f + 1] counts the points of cell f, then the running sum makes it the end.
        start = np.zeros(count + 1, dtype=np.int64)
        cells = np.empty(len(raw), dtype=np.int64)
        fingerprint = np.empty(len(raw), dtype=np.uint64)
        _index_points(raw, bits, geometry.origin, geometry.cell, geometry.dims,
                      COARSE_CELLS, cells, fingerprint, self._coarse_count, start)
        np.cumsum(start, out=start)
        # A stable sort by cell: points keep their input order within a cell, so two clouds
        # from one producer usually compare equal point by point without further sorting.
        self.points = np.empty_like(raw)
        self._fingerprints = np.empty(len(raw), dtype=np.uint64)
        self._sorted_rows = np.empty(len(raw), dtype=np.int64)
        _sort_into_cells(raw, cells, fingerprint, start, self.points, self._fingerprints,
                         self._sorted_rows)
        self._row_cells = cells
        self.start = start

    def _update(self, raw: np.ndarray, previous: 'PointCells') -> bool:
        """Index a cloud as the previous one plus the rows that differ from it.

        A mapping stack republishes its map with small changes, mostly with the same points in
        the same order: then only the differing rows are indexed anew and the cells they leave
        or enter are rebuilt; the other cells' points are copied. The result is the index a
        full build gives, array for array. False (nothing done) when the clouds differ in size,
        were bucketed for other cells, or differ in more than a few rows.
        """
        if previous.geometry.key != self.geometry.key or len(previous._raw) != len(raw):
            return False
        rows = len(raw)
        bits = raw.view(np.uint64).reshape(-1, 3)
        old_bits = previous._raw.view(np.uint64).reshape(-1, 3)
        limit = max(rows // 20, 1)
        differ = np.empty(limit, dtype=np.int64)
        found = _differing_rows(bits, old_bits, differ)
        if found < 0:
            return False  # more than `limit` rows differ: a full build is as cheap
        differ = differ[:found]
        geometry = self.geometry
        new_cells = np.empty(found, dtype=np.int64)
        new_fingerprints = np.empty(found, dtype=np.uint64)
        _index_rows(raw[differ], bits[differ], geometry.origin, geometry.cell, geometry.dims,
                    new_cells, new_fingerprints)
        old_cells = previous._row_cells[differ]
        cells = previous._row_cells.copy()
        cells[differ] = new_cells
        self._row_cells = cells
        # Counts per cell and coarse block: the previous ones, minus the rows that left, plus
        # the rows that arrived.
        counts = np.diff(previous.start)
        np.subtract.at(counts, old_cells, 1)
        np.add.at(counts, new_cells, 1)
        start = np.zeros(geometry.count + 1, dtype=np.int64)
        np.cumsum(counts, out=start[1:])
        self.start = start
        self._coarse_count = previous._coarse_count.copy()
        dims = tuple(int(d) for d in geometry.dims)
        for moved, sign in ((old_cells, -1), (new_cells, 1)):
            blocks = np.stack(np.unravel_index(moved, dims), axis=-1) // COARSE_CELLS
            np.add.at(self._coarse_count, tuple(blocks.T), sign)
        changed = np.unique(np.concatenate([old_cells, new_cells]))
        # The arriving rows grouped by cell, in row order within a cell (a stable sort).
        order = np.lexsort((differ, new_cells))
        marked = np.zeros(rows, dtype=np.bool_)
        marked[differ] = True
        self.points = np.empty_like(raw)
        self._fingerprints = np.empty(rows, dtype=np.uint64)
        self._sorted_rows = np.empty(rows, dtype=np.int64)
        _patch_cells(previous.start, previous.points, previous._fingerprints,
                     previous._sorted_rows, start, changed, marked, raw,
                     np.ascontiguousarray(differ[order]), np.ascontiguousarray(new_cells[order]),
                     np.ascontiguousarray(new_fingerprints[order]), self.points,
                     self._fingerprints, self._sorted_rows)
        self.changed_from_previous = changed
        return True

    def __len__(self) -> int:
        return len(self.points)

    def occupied_cells(self) -> np.ndarray:
        """Flat numbers of the cells that hold points, ascending."""
        return np.flatnonzero(np.diff(self.start) > 0)

    def distance(self, queries, cap: float = math.inf) -> np.ndarray:
        """Distance from each query to the nearest point [m]; ``cap`` where it is >= cap.

        Parameters
        ----------
        queries : array_like, shape (M, 3)
            Positions [m].
        cap : float
            > 0, or +inf for exact distances everywhere.

        Returns
        -------
        numpy.ndarray, shape (M,)
            Exact below ``cap``; +inf for an empty cloud without a cap.
        """
        flat = np.ascontiguousarray(np.asarray(queries, dtype=np.float64).reshape(-1, 3))
        if len(self.points) == 0:
            return np.full(len(flat), cap)
        out = np.empty(len(flat))
        geometry = self.geometry
        _nearest_points(flat, self.points, self.start, self._coarse_count, self._coarse_ring,
                        geometry.origin, geometry.cell, geometry.dims, COARSE_CELLS,
                        float(cap), geometry.slack, out)
        return out

    def points_in(self, cells: np.ndarray) -> np.ndarray:
        """The points of some cells (flat cell numbers, each once), shape (K, 3)."""
        flat = np.ascontiguousarray(cells, dtype=np.int64)
        counts = self.start[flat + 1] - self.start[flat]
        out = np.empty((int(counts.sum()), 3))
        if len(out):
            _gather_cells(self.points, self.start, flat, out)
        return out


def changed_cells(first: Optional[PointCells], second: Optional[PointCells],
                  geometry: CellGeometry) -> np.ndarray:
    """Flat numbers of the cells whose points differ between two clouds, ascending.

    Exact: a cell counts as unchanged only when it holds the same points in both (as
    coordinates, bit for bit; the order of the points in the clouds does not matter). None
    stands for an empty cloud.

    Raises
    ------
    InvalidInputError
        If a cloud was bucketed for other cells.
    """
    for cloud in (first, second):
        if cloud is not None and cloud.geometry.key != geometry.key:
            raise InvalidInputError('the clouds were bucketed for different grids')
    if first is None or second is None:
        only = first if first is not None else second
        return np.empty(0, dtype=np.int64) if only is None else only.occupied_cells()
    out = np.empty(geometry.count, dtype=np.int64)
    found = _compare_cells(first.start, first._fingerprints, first.points, second.start,
                           second._fingerprints, second.points, out)
    return out[:found].copy()


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


@njit
def _index_points(points, bits, origin, cell, dims, factor, cells, fingerprints,
                  coarse_count, counts):  # pragma: no cover - compiled
    # The cell of each point (clamped into the border cells, in floating point before the
    # cast), the counts of its cell (at counts[cell + 1]) and coarse block, and a splitmix64
    # fingerprint of its exact coordinates.
    for n in range(points.shape[0]):
        i = _floor_index(points[n, 0], origin[0], cell, dims[0])
        j = _floor_index(points[n, 1], origin[1], cell, dims[1])
        k = _floor_index(points[n, 2], origin[2], cell, dims[2])
        c = (i * dims[1] + j) * dims[2] + k
        cells[n] = c
        counts[c + 1] += 1
        coarse_count[i // factor, j // factor, k // factor] += 1
        h = _mix_one(bits[n, 0] ^ _SEED)
        h = _mix_one(h ^ bits[n, 1])
        fingerprints[n] = _mix_one(h ^ bits[n, 2])


@njit
def _index_rows(points, bits, origin, cell, dims, cells, fingerprints):  # pragma: no cover
    # The cells and fingerprints of some rows, as _index_points computes them.
    for n in range(points.shape[0]):
        i = _floor_index(points[n, 0], origin[0], cell, dims[0])
        j = _floor_index(points[n, 1], origin[1], cell, dims[1])
        k = _floor_index(points[n, 2], origin[2], cell, dims[2])
        cells[n] = (i * dims[1] + j) * dims[2] + k
        h = _mix_one(bits[n, 0] ^ _SEED)
        h = _mix_one(h ^ bits[n, 1])
        fingerprints[n] = _mix_one(h ^ bits[n, 2])


@njit
def _mix_one(z):  # pragma: no cover - compiled
    z = (z ^ (z >> _SHIFT30)) * _MIX1
    z = (z ^ (z >> _SHIFT27)) * _MIX2
    return z ^ (z >> _SHIFT31)


@njit
def _sort_into_cells(points, cells, fingerprints, start, out_points, out_fingerprints,
                     out_rows):  # pragma: no cover - compiled
    # A stable counting sort by cell; out_rows keeps the input row of each sorted point.
    fill = start[:-1].copy()
    for n in range(points.shape[0]):
        m = fill[cells[n]]
        fill[cells[n]] = m + 1
        out_points[m, 0] = points[n, 0]
        out_points[m, 1] = points[n, 1]
        out_points[m, 2] = points[n, 2]
        out_fingerprints[m] = fingerprints[n]
        out_rows[m] = n


@njit
def _differing_rows(bits, old_bits, out):  # pragma: no cover - compiled
    # Rows whose coordinates differ bit for bit; -1 once more than len(out) do.
    found = 0
    for n in range(bits.shape[0]):
        if (bits[n, 0] != old_bits[n, 0] or bits[n, 1] != old_bits[n, 1]
                or bits[n, 2] != old_bits[n, 2]):
            if found == out.shape[0]:
                return -1
            out[found] = n
            found += 1
    return found


@njit
def _patch_cells(old_start, old_points, old_fingerprints, old_rows, start, changed, marked,
                 raw, new_rows, new_cells, new_fingerprints, out_points, out_fingerprints,
                 out_rows):  # pragma: no cover - compiled
    # The sorted arrays of the new cloud: unchanged cells copied from the old ones; a changed
    # cell merges its old points whose rows did not change with the rows that arrived in it,
    # by row number, which is the order of a stable sort of the new cloud.
    next_changed = 0
    arriving = 0
    for c in range(start.shape[0] - 1):
        out = start[c]
        if next_changed < changed.shape[0] and changed[next_changed] == c:
            next_changed += 1
            old = old_start[c]
            old_end = old_start[c + 1]
            while True:
                while old < old_end and marked[old_rows[old]]:
                    old += 1
                take_old = old < old_end
                take_new = arriving < new_rows.shape[0] and new_cells[arriving] == c
                if not take_old and not take_new:
                    break
                if take_old and (not take_new or old_rows[old] < new_rows[arriving]):
                    out_points[out, 0] = old_points[old, 0]
                    out_points[out, 1] = old_points[old, 1]
                    out_points[out, 2] = old_points[old, 2]
                    out_fingerprints[out] = old_fingerprints[old]
                    out_rows[out] = old_rows[old]
                    old += 1
                else:
                    row = new_rows[arriving]
                    out_points[out, 0] = raw[row, 0]
                    out_points[out, 1] = raw[row, 1]
                    out_points[out, 2] = raw[row, 2]
                    out_fingerprints[out] = new_fingerprints[arriving]
                    out_rows[out] = row
                    arriving += 1
                out += 1
        else:
            old = old_start[c]
            for t in range(old_start[c + 1] - old):
                out_points[out + t, 0] = old_points[old + t, 0]
                out_points[out + t, 1] = old_points[old + t, 1]
                out_points[out + t, 2] = old_points[old + t, 2]
                out_fingerprints[out + t] = old_fingerprints[old + t]
                out_rows[out + t] = old_rows[old + t]


@njit
def _compare_cells(start_a, keys_a, points_a, start_b, keys_b, points_b,
                   out):  # pragma: no cover - compiled
    # Writes the numbers of the differing cells to ``out``; returns how many.
    # Point by point in stored order first (the usual case: the same producer, the same
    # order). Where that differs, a cell is unchanged only if both hold the same points in
    # another order: equal fingerprint sums and xors, then equal after sorting both by
    # fingerprint (points of equal fingerprint compare in either order, so a collision can only
    # make a cell count as changed).
    found = 0
    for c in range(start_a.shape[0] - 1):
        first_a = start_a[c]
        first_b = start_b[c]
        size = start_a[c + 1] - first_a
        if size != start_b[c + 1] - first_b:
            out[found] = c
            found += 1
            continue
        same = True
        for t in range(size):
            if not _same_point(keys_a, points_a, first_a + t, keys_b, points_b, first_b + t):
                same = False
                break
        if same:
            continue
        total_a = np.uint64(0)
        total_b = np.uint64(0)
        xor_a = np.uint64(0)
        xor_b = np.uint64(0)
        for t in range(size):
            total_a += keys_a[first_a + t]
            total_b += keys_b[first_b + t]
            xor_a ^= keys_a[first_a + t]
            xor_b ^= keys_b[first_b + t]
        if total_a != total_b or xor_a != xor_b:
            out[found] = c
            found += 1
            continue
        rank_a = first_a + np.argsort(keys_a[first_a:first_a + size])
        rank_b = first_b + np.argsort(keys_b[first_b:first_b + size])
        for t in range(size):
            if not _same_point(keys_a, points_a, rank_a[t], keys_b, points_b, rank_b[t]):
                out[found] = c
                found += 1
                break
    return found


@njit
def _same_point(keys_a, points_a, a, keys_b, points_b, b):  # pragma: no cover - compiled
    return (keys_a[a] == keys_b[b] and points_a[a, 0] == points_b[b, 0]
            and points_a[a, 1] == points_b[b, 1] and points_a[a, 2] == points_b[b, 2])


@njit
def _gather_cells(points, start, cells, out):  # pragma: no cover - compiled
    m = 0
    for c in cells:
        for p in range(start[c], start[c + 1]):
            out[m, 0] = points[p, 0]
            out[m, 1] = points[p, 1]
            out[m, 2] = points[p, 2]
            m += 1


@njit
def _floor_index(value, origin, size, count):  # pragma: no cover - compiled
    """Cell index of a coordinate, clamped to [0, count - 1] (infinities included)."""
    scaled = (value - origin) / size
    if not scaled > 0.0:
        return 0
    if scaled >= count - 1:
        return count - 1
    return int(math.floor(scaled))


@njit
def _cell_gap(value, origin, size, index, count):  # pragma: no cover - compiled
    """Distance along one axis from a coordinate to a cell; border cells reach to infinity
    (they hold the points beyond the border)."""
    low = origin + index * size if index > 0 else -math.inf
    high = origin + (index + 1) * size if index < count - 1 else math.inf
    return max(max(low - value, value - high), 0.0)


@njit
def _nearest_points(queries, points, start, coarse_count, coarse_ring, origin, cell, dims,
                    factor, cap, slack, out):  # pragma: no cover - compiled
    # Rings of coarse blocks around the query's block, nearest first, from the first ring that
    # holds points; a block is read only when its box is closer than the best distance found
    # (and than the cap), and inside it only the cells within that distance. Every block of
    # ring R is at least (R - 1) block edges from the query, which ends the search.
    nx = dims[0]
    ny = dims[1]
    nz = dims[2]
    cx = nx // factor
    cy = ny // factor
    cz = nz // factor
    big = cell * factor
    rmax = max(cx, max(cy, cz))
    for n in range(queries.shape[0]):
        qx = queries[n, 0]
        qy = queries[n, 1]
        qz = queries[n, 2]
        best = cap
        ci = _floor_index(qx, origin[0], big, cx)
        cj = _floor_index(qy, origin[1], big, cy)
        ck = _floor_index(qz, origin[2], big, cz)
        ring = coarse_ring[ci, cj, ck]
        while ring <= rmax:
            if ring >= 1 and (ring - 1) * big - slack >= best:
                break
            for a in range(max(ci - ring, 0), min(ci + ring, cx - 1) + 1):
                edge_a = a == ci - ring or a == ci + ring
                gx = _cell_gap(qx, origin[0], big, a, cx)
                for b in range(max(cj - ring, 0), min(cj + ring, cy - 1) + 1):
                    edge_b = b == cj - ring or b == cj + ring
                    gy = _cell_gap(qy, origin[1], big, b, cy)
                    step = 1 if (edge_a or edge_b or ring == 0) else 2 * ring
                    for c in range(ck - ring, ck + ring + 1, step):
                        if c < 0 or c >= cz or coarse_count[a, b, c] == 0:
                            continue
                        gz = _cell_gap(qz, origin[2], big, c, cz)
                        if math.sqrt(gx * gx + gy * gy + gz * gz) - slack >= best:
                            continue
                        best = _scan_block(qx, qy, qz, a, b, c, best, points, start, origin,
                                           cell, nx, ny, nz, factor, slack)
            ring += 1
        out[n] = best


@njit
def _scan_block(qx, qy, qz, a, b, c, best, points, start, origin, cell, nx, ny, nz, factor,
                slack):  # pragma: no cover - compiled
    reach = best + slack
    i0 = max(a * factor, _floor_index(qx - reach, origin[0], cell, nx))
    i1 = min(a * factor + factor - 1, _floor_index(qx + reach, origin[0], cell, nx))
    j0 = max(b * factor, _floor_index(qy - reach, origin[1], cell, ny))
    j1 = min(b * factor + factor - 1, _floor_index(qy + reach, origin[1], cell, ny))
    k0 = max(c * factor, _floor_index(qz - reach, origin[2], cell, nz))
    k1 = min(c * factor + factor - 1, _floor_index(qz + reach, origin[2], cell, nz))
    for i in range(i0, i1 + 1):
        gx = _cell_gap(qx, origin[0], cell, i, nx)
        for j in range(j0, j1 + 1):
            gy = _cell_gap(qy, origin[1], cell, j, ny)
            base = (i * ny + j) * nz
            for k in range(k0, k1 + 1):
                f = base + k
                first = start[f]
                last = start[f + 1]
                if first == last:
                    continue
                gz = _cell_gap(qz, origin[2], cell, k, nz)
                if math.sqrt(gx * gx + gy * gy + gz * gz) - slack >= best:
                    continue
                for p in range(first, last):
                    # The formula of the grid inflation and of scipy's KD-tree: squares summed
                    # x, y, z, then the root.
                    dx = qx - points[p, 0]
                    dy = qy - points[p, 1]
                    dz = qz - points[p, 2]
                    d = math.sqrt(dx * dx + dy * dy + dz * dz)
                    if d < best:
                        best = d
    return best


# --------------------------------------------------------------------------------------------
# Obstacles of a live map
# --------------------------------------------------------------------------------------------

class LiveObstacles(ObstacleSet):
    """Shapes plus point layers, each point layer with its own index, built once.

    Behaves as the :class:`ObstacleSet` of all of them: ``points`` holds every layer's points,
    :meth:`distance` the nearest of shapes and points, ``items`` the shapes and one
    :class:`PointSet` per layer.

    Parameters
    ----------
    shapes : iterable of Sphere, Box, TableShape or HeightField
    layers : sequence of PointCells
        Empty layers are dropped.

    Raises
    ------
    InvalidInputError
        If a shape is a point set (points go in layers).
    """

    def __init__(self, shapes: Iterable[Obstacle] = (), layers: Sequence[PointCells] = ()):
        shapes = tuple(shapes)
        for number, shape in enumerate(shapes):
            if isinstance(shape, PointSet):
                raise InvalidInputError(f'shape {number} is a point set; points are layers')
        super().__init__(shapes)
        self.layers = tuple(layer for layer in layers if len(layer))
        self._shape_count = len(shapes)
        if not self.layers:
            points = np.empty((0, 3))
        elif len(self.layers) == 1:
            points = self.layers[0].points
        else:
            points = np.concatenate([layer.points for layer in self.layers])
        points.setflags(write=False)
        self.points = points
        self._layer_items: Optional[Tuple[PointSet, ...]] = None

    @property
    def items(self) -> Sequence[Obstacle]:
        """The shapes, then one point set per layer."""
        if self._layer_items is None:
            self._layer_items = tuple(PointSet(layer.points) for layer in self.layers)
        return tuple(super().items) + self._layer_items

    def __len__(self) -> int:
        return self._shape_count + len(self.layers)

    def distance(self, points, cap: float = math.inf) -> np.ndarray:
        """Euclidean distance to the nearest shape or point [m]; see
        :meth:`ObstacleSet.distance` for ``cap``."""
        p = np.asarray(points, dtype=np.float64)
        flat = np.ascontiguousarray(p.reshape(-1, 3))
        out = np.array(super().distance(flat, cap), dtype=np.float64).reshape(-1)
        for layer in self.layers:
            np.minimum(out, layer.distance(flat, cap), out=out)
        return out.reshape(p.shape[:-1])


# --------------------------------------------------------------------------------------------
# Inflated masks, written tile by tile
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class MaskUpdate:
    """What bringing one mask up to date cost.

    Attributes
    ----------
    full : bool
        The whole mask was rebuilt.
    tiles : int
        Tiles re-inflated (all of them when ``full``).
    points : int
        Points stamped again.
    time_s : float
        [s]
    """

    full: bool
    tiles: int
    points: int
    time_s: float


class _Buffer:
    def __init__(self, shape: Tuple[int, int, int]) -> None:
        self.mask = np.zeros(shape, dtype=bool)
        self.version = -1


class MaskBuffers:
    """Up to :data:`MAX_BUFFERS` inflated masks of one grid and margin.

    Each write goes to a buffer that neither a reader holds (``held``) nor is the newest one:
    the buffer takes a copy of the newest mask (a memory copy) and then the tiles of this
    change are re-inflated in it. The newest buffer is never written, so a reader always sees a
    complete mask.

    Parameters
    ----------
    grid : VoxelGrid
    safety_margin : float
        gamma [m].
    """

    def __init__(self, grid: VoxelGrid, safety_margin: float) -> None:
        self.grid = grid
        self.safety_margin = float(safety_margin)
        self.geometry = CellGeometry.of_grid(grid)
        self.reach = reach_tiles(self.safety_margin, self.geometry)
        self._buffers: List[_Buffer] = []
        self._newest: Optional[_Buffer] = None
        self._sparse_newest: Optional[SparseMask] = None

    def write(self, obstacles: ObstacleSet, version: int, changed: Optional[np.ndarray],
              layers: Sequence[PointCells] = (),
              held: Optional[Mask] = None) -> Tuple[Mask, MaskUpdate]:
        """Write the mask of ``obstacles`` (map ``version``) and make it the newest.

        Parameters
        ----------
        obstacles : ObstacleSet
        version : int
            Greater than every version written before.
        changed : numpy.ndarray of int, or None
            Flat numbers of the tiles (C order over ``geometry.tiles``) whose nodes may differ
            from the newest mask; None: any (a full rebuild).
        layers : sequence of PointCells
            The point layers of ``obstacles`` (their points are gathered tile by tile).
        held : numpy.ndarray or SparseMask, optional
            A mask a reader still uses; it is not written.

        Returns
        -------
        mask : numpy.ndarray of bool, shape ``grid.shape``
        update : MaskUpdate
        """
        started = time.perf_counter()
        if choose_layout(self.grid.size) == 'sparse':
            return self._write_sparse(obstacles, changed, layers, started)
        buffer = next((b for b in self._buffers
                       if b is not self._newest and b.mask is not held), None)
        if buffer is None:
            if len(self._buffers) >= MAX_BUFFERS:  # cannot happen: at most two are excluded
                raise RuntimeError('no free mask buffer')
            buffer = _Buffer(tuple(self.grid.shape))
            self._buffers.append(buffer)
        newest = self._newest
        tiles = int(np.prod(self.geometry.tiles))
        if newest is None or changed is None or len(changed) > FULL_REBUILD_FRACTION * tiles:
            blocked_mask(self.grid, obstacles, self.safety_margin, out=buffer.mask)
            update = MaskUpdate(True, tiles, len(obstacles.points), 0.0)
        else:
            if buffer.version != newest.version:
                np.copyto(buffer.mask, newest.mask)
            near = self._points_near(changed, layers)
            index = np.stack(np.unravel_index(
                np.asarray(changed, dtype=np.int64),
                tuple(int(t) for t in self.geometry.tiles)), axis=-1)
            reinflate_tiles(self.grid, obstacles, self.safety_margin, buffer.mask, index,
                            self.geometry.tile_nodes, near)
            update = MaskUpdate(False, len(changed), len(near), 0.0)
        buffer.version = version
        self._newest = buffer
        return buffer.mask, MaskUpdate(update.full, update.tiles, update.points,
                                       time.perf_counter() - started)

    def _write_sparse(self, obstacles: ObstacleSet, changed: Optional[np.ndarray],
                      layers: Sequence[PointCells],
                      started: float) -> Tuple[SparseMask, MaskUpdate]:
        """:meth:`write` on a block-sparse grid: each mask is a new object (no buffers; the
        old one stays intact for its readers), built whole or from the newest one with the
        changed tiles re-inflated."""
        newest = self._sparse_newest
        tiles = int(np.prod(self.geometry.tiles))
        if newest is None or changed is None or len(changed) > FULL_REBUILD_FRACTION * tiles:
            mask = blocked_mask(self.grid, obstacles, self.safety_margin)
            update = MaskUpdate(True, tiles, len(obstacles.points), 0.0)
        else:
            near = self._points_near(changed, layers)
            index = np.stack(np.unravel_index(
                np.asarray(changed, dtype=np.int64),
                tuple(int(t) for t in self.geometry.tiles)), axis=-1)
            mask = reinflate_sparse(self.grid, obstacles, self.safety_margin, newest, index,
                                    self.geometry.tile_nodes, near)
            update = MaskUpdate(False, len(changed), len(near), 0.0)
        assert isinstance(mask, SparseMask)
        self._sparse_newest = mask
        return mask, MaskUpdate(update.full, update.tiles, update.points,
                                time.perf_counter() - started)

    def _points_near(self, tiles: np.ndarray, layers: Sequence[PointCells]) -> np.ndarray:
        """Every layer point within gamma of a node of the tiles (and a few more)."""
        if not layers or len(tiles) == 0:
            return np.empty((0, 3))
        geometry = self.geometry
        index = np.unravel_index(np.asarray(tiles, dtype=np.int64),
                                 tuple(int(t) for t in geometry.tiles))
        cells = np.ravel_multi_index(index, tuple(int(d) for d in geometry.dims))
        near = dilate_cells(cells, geometry.dims, self.reach)
        parts = [layer.points_in(near) for layer in layers]
        return parts[0] if len(parts) == 1 else np.concatenate(parts)


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
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class LiveMap:
    """One consistent map: obstacles and, for one grid and margin, their inflated mask.

    Attributes
    ----------
    obstacles : LiveObstacles
    blocked : numpy.ndarray of bool, or SparseMask
        Inflated mask of ``grid_key`` (read-only by contract: the builder rewrites the buffer
        only once no reader holds it).
    grid_key : tuple
        :meth:`PlannerConfig.grid_key` the mask was built for.
    version : int
        Increases with every change of the obstacles.
    update : MaskUpdate
        What the mask cost.
    index_time_s : float
        Time spent indexing a new cloud and finding its changed cells [s].
    fallback : numpy.ndarray of bool, or SparseMask, optional
        Mask of the same obstacles for the planner's conservative fallback margin
        (:func:`~uav_global_planner.core.planner.fallback_margin`), once asked for
        (:attr:`LiveMapBuilder.want_fallback`).
    """

    obstacles: LiveObstacles
    blocked: Mask
    grid_key: tuple
    version: int
    update: MaskUpdate
    index_time_s: float
    fallback: Optional[Mask] = None


#: Pass as ``cloud`` to :meth:`LiveMapBuilder.update` to keep the cloud.
UNCHANGED = object()


def same_shape(first: Obstacle, second: Obstacle) -> bool:
    """True when two shapes are of one type with bit-identical parameters."""
    if type(first) is not type(second):
        return False
    if isinstance(first, Sphere) and isinstance(second, Sphere):
        return (bool(np.array_equal(first.center, second.center))
                and first.radius == second.radius)
    if isinstance(first, Box) and isinstance(second, Box):
        return (bool(np.array_equal(first.min, second.min))
                and bool(np.array_equal(first.max, second.max)))
    if isinstance(first, HeightField) and isinstance(second, HeightField):
        return (first is second or (
            first.side == second.side and first.label == second.label
            and bool(np.array_equal(first.origin, second.origin))
            and bool(np.array_equal(first.spacing, second.spacing))
            and bool(np.array_equal(first.heights, second.heights))))
    return first is second


class LiveMapBuilder:
    """Turns marker and cloud updates into :class:`LiveMap` objects (one thread at a time).

    Parameters
    ----------
    config : PlannerConfig
        The grid (bounds, delta) and margin gamma to inflate for.
    prior : array_like, shape (P, 3), optional
        Points of a static prior map [m]: indexed once per grid, and joined to every map.
    first_version : int
        Version of the first map.

    Attributes
    ----------
    want_fallback : bool
        Also keep the mask for the planner's fallback margin up to date (set it once a plan
        needed that grid: then it costs plans nothing more; a plain flag, so another thread may
        set it).
    """

    def __init__(self, config: PlannerConfig, prior=None, first_version: int = 1) -> None:
        self._prior_points = (None if prior is None or len(prior) == 0
                              else PointSet(prior).points)
        self._shapes: Dict[Hashable, Obstacle] = {}
        self._cloud_points: Optional[np.ndarray] = None
        self._cloud: Optional[PointCells] = None
        self._prior: Optional[PointCells] = None
        self._buffers: Optional[MaskBuffers] = None
        self._fallback_buffers: Optional[MaskBuffers] = None
        self.want_fallback = False
        self._grid_key: Optional[tuple] = None
        self._config = config
        self._version = int(first_version) - 1
        self._newest: Optional[LiveMap] = None

    @property
    def newest(self) -> Optional[LiveMap]:
        """The last map built (None before the first)."""
        return self._newest

    def update(self, shapes: Optional[Mapping[Any, Obstacle]] = None, cloud=UNCHANGED,
               config: Optional[PlannerConfig] = None, held: Optional[Mask] = None,
               give_cloud: bool = False, held_fallback: Optional[Mask] = None) -> LiveMap:
        """Apply an update and return the map it gives.

        Parameters
        ----------
        shapes : mapping of key to Sphere or Box, optional
            Every shape now, keyed by any hashable (for example by marker (ns, id)); None
            keeps them.
        cloud : numpy.ndarray of shape (M, 3), None or UNCHANGED
            The newest cloud (replacing the last one), None for no cloud, or UNCHANGED.
        config : PlannerConfig, optional
            New settings; a new grid or margin rebuilds the mask (and a new grid the indexes).
        held : numpy.ndarray or SparseMask, optional
            The mask a reader still uses (never written).
        give_cloud : bool
            The caller hands ``cloud`` over (a float64 array it will not touch again), so it
            is kept without a copy; by default it is copied.
        held_fallback : numpy.ndarray or SparseMask, optional
            The fallback mask a reader still uses (never written).

        Returns
        -------
        LiveMap
            A new version when the obstacles changed, else the same obstacles with a mask of
            the current settings.
        """
        if config is not None:
            self._config = config
        config = self._config
        grid_key = config.grid_key()
        regrid = self._buffers is None or grid_key != self._grid_key
        new_geometry = regrid and (self._buffers is None or self._grid_key is None or (
            grid_key[:3] != self._grid_key[:3]))
        if regrid:
            grid = VoxelGrid.from_bounds(config.bounds_min, config.bounds_max,
                                         config.resolution, config.max_voxels)
            self._buffers = MaskBuffers(grid, config.planning_margin)
            self._fallback_buffers = None
            self._grid_key = grid_key
        buffers = self._buffers
        assert buffers is not None  # made above when there were none
        geometry = buffers.geometry
        indexing_started = time.perf_counter()
        if new_geometry:
            self._prior = (None if self._prior_points is None
                           else PointCells(self._prior_points, geometry))
            self._cloud = (None if self._cloud_points is None
                           else PointCells(self._cloud_points, geometry))
        moved_shapes: List[Obstacle] = []
        moved_cells: List[np.ndarray] = []
        moved = False
        if shapes is not None:
            new_shapes = dict(shapes)
            differ = [shape for key, shape in self._shapes.items()
                      if key not in new_shapes or not same_shape(shape, new_shapes[key])]
            differ += [shape for key, shape in new_shapes.items()
                       if key not in self._shapes or not same_shape(shape, self._shapes[key])]
            if differ:
                moved_shapes = differ
                moved = True
            self._shapes = new_shapes
        if cloud is not UNCHANGED:
            points = None if cloud is None or len(cloud) == 0 else (
                np.asarray(cloud, dtype=np.float64) if give_cloud
                else np.array(cloud, dtype=np.float64))
            cells = None if points is None else PointCells(points, geometry, self._cloud)
            if cells is not None and cells.changed_from_previous is not None:
                differ_cells = cells.changed_from_previous
            else:
                differ_cells = changed_cells(self._cloud, cells, geometry)
            if len(differ_cells):
                moved_cells.append(differ_cells)
                moved = True
            self._cloud_points, self._cloud = (None if cells is None else cells.points), cells
        index_time = time.perf_counter() - indexing_started
        fallback_missing = self.want_fallback and self._fallback_buffers is None
        if not (moved or regrid or fallback_missing) and self._newest is not None:
            return self._newest
        if moved or self._newest is None:
            self._version += 1
            layers = [layer for layer in (self._prior, self._cloud) if layer is not None]
            # Keys are orderable as well as hashable (marker (ns, id) pairs, names).
            keys = sorted(self._shapes)  # type: ignore[type-var]
            obstacles = LiveObstacles([self._shapes[key] for key in keys], layers)
        else:
            obstacles = self._newest.obstacles
            layers = list(obstacles.layers)
        if regrid or moved or self._newest is None:
            tiles = None if regrid else _changed_tiles(buffers, moved_shapes, moved_cells)
            mask, update = buffers.write(obstacles, self._version, tiles, layers, held)
        else:
            mask, update = self._newest.blocked, MaskUpdate(False, 0, 0, 0.0)
        fallback = None
        if self.want_fallback:
            fallback = self._write_fallback(obstacles, layers, moved_shapes, moved_cells,
                                            moved, held_fallback)
        self._newest = LiveMap(obstacles, mask, grid_key, self._version, update, index_time,
                               fallback)
        return self._newest

    def _write_fallback(self, obstacles: LiveObstacles, layers: Sequence[PointCells],
                        moved_shapes: List[Obstacle], moved_cells: List[np.ndarray],
                        moved: bool, held: Optional[Mask]) -> Mask:
        """The mask for the planner's fallback margin, kept up to date like the other."""
        buffers = self._fallback_buffers
        if buffers is None:
            assert self._buffers is not None  # update() makes them first
            buffers = self._fallback_buffers = MaskBuffers(self._buffers.grid,
                                                           fallback_margin(self._config))
            return buffers.write(obstacles, self._version, None, layers, held)[0]
        if moved or self._newest is None or self._newest.fallback is None:
            tiles = _changed_tiles(buffers, moved_shapes, moved_cells) if moved else None
            return buffers.write(obstacles, self._version, tiles, layers, held)[0]
        return self._newest.fallback


def _changed_tiles(buffers: MaskBuffers, shapes: Sequence[Obstacle],
                   cells: Sequence[np.ndarray]) -> Optional[np.ndarray]:
    """Tiles of ``buffers`` that shapes added or removed and changed cells reach (with the
    buffers' own margin); None when anything may have changed."""
    parts = []
    if shapes:
        tiles = shape_tiles(buffers.grid, shapes, buffers.safety_margin, buffers.geometry)
        if tiles is None:
            return None
        parts.append(tiles)
    for changed in cells:
        parts.append(cell_tiles(changed, buffers.geometry, buffers.reach))
    return np.unique(np.concatenate(parts)) if parts else np.empty(0, dtype=np.int64)
