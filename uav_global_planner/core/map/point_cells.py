"""The point index of a live map's cloud: points bucketed into the cells of a grid.

:class:`PointCells` buckets one cloud's points into the cells of a
:class:`~uav_global_planner.core.map.tiles.CellGeometry` (the footprints of the tiles of grid
nodes), sorted by cell, in input order within a cell. Built in linear time (60-80 ms for 820 k
points on this project's machine; about 30 ms when the cloud is the previous one with a few rows
changed, the usual republished map), so every cloud gets its own; two clouds are compared cell
by cell, exactly (:func:`changed_cells`). Capped distance queries (what the clearance engine
asks) read the cells within the cap; wider and uncapped ones search outward over coarser blocks
of cells, skipping empty space.

The compiled kernels below serve :class:`PointCells` alone (numba, see
:mod:`uav_global_planner.core.jit`).
"""

import math
from typing import Optional, Tuple

import numpy as np
from scipy import ndimage

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.jit import njit
from uav_global_planner.core.map.obstacles import PointSet
from uav_global_planner.core.map.tiles import CellGeometry, COARSE_CELLS

# splitmix64 constants: a 64-bit fingerprint of each point's exact coordinates, with which two
# clouds holding the same points in another order compare equal.
_SEED = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_SHIFT30 = np.uint64(30)
_SHIFT27 = np.uint64(27)
_SHIFT31 = np.uint64(31)


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
