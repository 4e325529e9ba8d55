"""Distance from points to solid shapes, exact and in time that follows what is near the query.

Shapes are kept as rows of a parameter table with a kind code, so one compiled loop serves them
all:

========================= ====================================================================
kind                      row (6 numbers) [m]
========================= ====================================================================
:data:`SPHERE`            centre x, y, z, radius, -, -
:data:`BOX`               min x, y, z, max x, y, z
:data:`PRISM`             bounding box min x, y, floor, max x, y, ceiling; polygon vertices
:data:`CYLINDER`          centre x, y, radius, floor, ceiling, -
:data:`FENCE`             as PRISM: the *outside* of a polygon prism (an inclusion fence)
:data:`CIRCLE_FENCE`      as CYLINDER: the outside of a vertical cylinder
========================= ====================================================================

Polygon vertices (x, y) of every row live in one flat array ``verts`` of shape (V, 2); row
``s`` owns ``verts[vstart[s]:vstart[s + 1]]`` (no vertices for the other kinds). Floors and
ceilings may be infinite.

Every gap is exact: a prism or a cylinder is the product of a plane region P and a height
interval I, so the distance to it is ``sqrt(d_P(x, y)**2 + d_I(z)**2)``; the outside of a fence
is the union of (outside P) x R and R^2 x (outside I), so inside the fence the distance to it is
``min(d(x, y; boundary of P), z - floor, ceiling - z)``, and 0 outside. Each gap is formed in two
steps, a part that depends on (x, y) only (:func:`_column_part`) and the rest
(:func:`_finish`): the grid inflation evaluates the first once per grid column and the second
per node with these very functions, so grid and clearance checks agree to the last bit.

Two ways to ask:

* :func:`min_gap_all` visits every shape: the exact distance whatever it is (used for reports
  and for a handful of shapes).
* :class:`ShapeIndex` answers a *capped* query: the exact distance where it is below ``cap``,
  and ``cap`` (a valid lower bound) where it is not. A uniform lattice of cells lists, for each
  cell, the shapes whose bounding box comes within ``reach >= cap`` of the cell, so a query reads
  one cell's short list, not every shape. A point outside the lattice (which covers every
  bounding box grown by ``reach``) is at least ``reach`` from every bounded shape. Fences are
  unbounded (their outside reaches infinity): they are not in the lattice but on an *always*
  list that every query evaluates exactly (one polygon each).

A lower bound is all a clearance certificate needs (:mod:`uav_global_planner.core.path.clearance`):
for a segment ``ab``, ``d(q) >= (d'(a) + d'(b) - |ab|) / 2`` holds for any ``d' <= d``, because
``d`` itself is 1-Lipschitz.
"""

import math
from typing import Optional, Tuple

import numpy as np

from uav_global_planner.core.jit import njit

#: Kind code of a sphere row: centre x, y, z, radius, unused, unused [m].
SPHERE = 0
#: Kind code of an axis-aligned box row: min x, y, z, max x, y, z [m].
BOX = 1
#: Kind code of a solid vertical prism: its bounding box (min x, y, floor, max x, y, ceiling)
#: [m] and its polygon's vertices.
PRISM = 2
#: Kind code of a solid vertical cylinder: centre x, y, radius, floor, ceiling, unused [m].
CYLINDER = 3
#: Kind code of the outside of a polygon inclusion fence (row as :data:`PRISM`).
FENCE = 4
#: Kind code of the outside of a circular inclusion fence (row as :data:`CYLINDER`).
CIRCLE_FENCE = 5
#: Kinds whose solid reaches infinity: never in a lattice, evaluated for every query.
UNBOUNDED_KINDS = (FENCE, CIRCLE_FENCE)

#: Most cells of the lattice: bounds its memory (8 bytes a cell) whatever the scene's extent.
MAX_CELLS = 1 << 22
#: Below this many shapes a query visits them all: a lattice would not pay for itself.
BRUTE_FORCE_SHAPES = 16
# Bounding boxes are clipped to this extent [m] before the lattice is laid out, so that a
# ground slab of +-1e30 m does not make every cell as large as the slab.
_EXTENT_LIMIT = 1e7

_NO_VERTICES = np.empty((0, 2))
_NO_VERTICES.setflags(write=False)


class TableShape:
    """Base of shapes that are one row of the shape table (zones and fences).

    Subclasses provide :meth:`table_row`;
    :class:`~uav_global_planner.core.map.obstacles.ObstacleSet` puts them in its table, and
    every distance query, the grid inflation and the clearance certificate then cover them.
    """

    #: What a message calls the shape, e.g. ``'exclusion zone 2 (cylinder)'``.
    label: str = ''

    def table_row(self) -> Tuple[int, np.ndarray, np.ndarray]:
        """``(kind, row of 6 numbers [m], polygon vertices of shape (V, 2) [m])``."""
        raise NotImplementedError


@njit
def _polygon_part(verts, first, stop, x, y):  # pragma: no cover - compiled
    """Squared distance from (x, y) to the boundary of a polygon [m^2], and whether (x, y) is
    inside it (even-odd rule; on the boundary either answer is right, the distance being 0)."""
    best = math.inf
    inside = False
    j = stop - 1
    for i in range(first, stop):
        ax = verts[j, 0]
        ay = verts[j, 1]
        ex = verts[i, 0] - ax
        ey = verts[i, 1] - ay
        wx = x - ax
        wy = y - ay
        # Edges have a positive length (validated), so the projection is defined.
        t = (wx * ex + wy * ey) / (ex * ex + ey * ey)
        t = min(max(t, 0.0), 1.0)
        dx = wx - t * ex
        dy = wy - t * ey
        gap = dx * dx + dy * dy
        if gap < best:
            best = gap
        if (ay > y) != (verts[i, 1] > y):
            if x < ax + (y - ay) / ey * ex:
                inside = not inside
        j = i
    return best, inside


@njit
def _column_part(kind, prm, verts, vstart, s, x, y):  # pragma: no cover - compiled
    """The part of shape ``s``'s gap that depends on (x, y) only (see :func:`_finish`)."""
    code = kind[s]
    if code == SPHERE:
        dx = x - prm[s, 0]
        dy = y - prm[s, 1]
        return dx * dx + dy * dy
    if code == BOX:
        ex = max(max(prm[s, 0] - x, x - prm[s, 3]), 0.0)
        ey = max(max(prm[s, 1] - y, y - prm[s, 4]), 0.0)
        return ex * ex + ey * ey
    if code == PRISM or code == FENCE:
        squared, inside = _polygon_part(verts, vstart[s], vstart[s + 1], x, y)
        if code == PRISM:
            return 0.0 if inside else squared
        return math.sqrt(squared) if inside else 0.0
    dx = x - prm[s, 0]
    dy = y - prm[s, 1]
    across = math.sqrt(dx * dx + dy * dy) - prm[s, 2]
    if code == CYLINDER:
        outside = max(across, 0.0)
        return outside * outside
    return max(-across, 0.0)    # CIRCLE_FENCE: distance to the circle from inside


@njit
def _finish(kind, prm, s, part, z):  # pragma: no cover - compiled
    """Gap from a point at height ``z`` to shape ``s`` [m], from its (x, y) part ``part``.

    Spheres: the squared plane distance to the centre; negative inside. Boxes, prisms and
    cylinders: the squared plane distance to the solid's footprint; 0 inside. Fences: the
    plane distance to the boundary from inside (0 outside); the gap is 0 outside the fence.
    """
    code = kind[s]
    if code == SPHERE:
        dz = z - prm[s, 2]
        return math.sqrt(part + dz * dz) - prm[s, 3]
    if code == BOX or code == PRISM:
        ez = max(max(prm[s, 2] - z, z - prm[s, 5]), 0.0)
        return math.sqrt(part + ez * ez)
    if code == CYLINDER:
        ez = max(max(prm[s, 3] - z, z - prm[s, 4]), 0.0)
        return math.sqrt(part + ez * ez)
    if code == FENCE:
        return max(min(part, min(z - prm[s, 2], prm[s, 5] - z)), 0.0)
    return max(min(part, min(z - prm[s, 3], prm[s, 4] - z)), 0.0)


@njit
def _gap(kind, prm, verts, vstart, s, x, y, z):  # pragma: no cover - compiled
    """Gap from (x, y, z) to shape ``s`` [m]: negative inside a sphere, 0 inside the others.

    The squares are summed in numpy's order over the last axis, so the values of spheres and
    boxes equal those of :func:`uav_global_planner.core.map.obstacles.sphere_distance` and
    ``box_distance`` to the bit.
    """
    return _finish(kind, prm, s, _column_part(kind, prm, verts, vstart, s, x, y), z)


@njit(inline='always')
def _gap_inline(kind, prm, verts, vstart, s, x, y, z):  # pragma: no cover - compiled
    """:func:`_gap`, with spheres and boxes worked out in place.

    Inlined into the loops by numba (``inline='always'``); spheres and boxes use the very
    operations of :func:`_column_part` and :func:`_finish` (same bits), since a call of
    :func:`_gap` per shape, passing the whole table, costs several times their arithmetic.
    """
    code = kind[s]
    if code == SPHERE:
        dx = x - prm[s, 0]
        dy = y - prm[s, 1]
        dz = z - prm[s, 2]
        return math.sqrt((dx * dx + dy * dy) + dz * dz) - prm[s, 3]
    if code == BOX:
        ex = max(max(prm[s, 0] - x, x - prm[s, 3]), 0.0)
        ey = max(max(prm[s, 1] - y, y - prm[s, 4]), 0.0)
        ez = max(max(prm[s, 2] - z, z - prm[s, 5]), 0.0)
        return math.sqrt((ex * ex + ey * ey) + ez * ez)
    return _gap(kind, prm, verts, vstart, s, x, y, z)


@njit
def _min_gap_all(points, kind, prm, verts, vstart, out):  # pragma: no cover - compiled
    for n in range(points.shape[0]):
        best = out[n]
        x = points[n, 0]
        y = points[n, 1]
        z = points[n, 2]
        for s in range(kind.shape[0]):
            gap = _gap_inline(kind, prm, verts, vstart, s, x, y, z)
            if gap < best:
                best = gap
        out[n] = max(best, 0.0)


@njit
def _min_gap_indexed(points, kind, prm, verts, vstart, always, origin, cell, dims, start, items,
                     cap, out):  # pragma: no cover - compiled
    nx, ny, nz = dims[0], dims[1], dims[2]
    for n in range(points.shape[0]):
        x = points[n, 0]
        y = points[n, 1]
        z = points[n, 2]
        best = cap
        for e in range(always.shape[0]):
            gap = _gap(kind, prm, verts, vstart, always[e], x, y, z)
            if gap < best:
                best = gap
        # Compared as floats before the cast: a far point (or NaN) must not wrap an integer.
        fi = (x - origin[0]) / cell
        fj = (y - origin[1]) / cell
        fk = (z - origin[2]) / cell
        if 0.0 <= fi < nx and 0.0 <= fj < ny and 0.0 <= fk < nz:
            c = (int(fi) * ny + int(fj)) * nz + int(fk)
            for e in range(start[c], start[c + 1]):
                gap = _gap_inline(kind, prm, verts, vstart, items[e], x, y, z)
                if gap < best:
                    best = gap
        out[n] = max(best, 0.0)


@njit
def _fill_lattice(lo_cells, hi_cells, dims, start, items):  # pragma: no cover - compiled
    """Count (first pass, ``items`` empty) or list (second pass) the shapes of every cell."""
    ny, nz = dims[1], dims[2]
    fill = start[:-1].copy()
    counting = items.shape[0] == 0
    for s in range(lo_cells.shape[0]):
        for i in range(lo_cells[s, 0], hi_cells[s, 0] + 1):
            for j in range(lo_cells[s, 1], hi_cells[s, 1] + 1):
                base = (i * ny + j) * nz
                for k in range(lo_cells[s, 2], hi_cells[s, 2] + 1):
                    if counting:
                        start[base + k + 1] += 1
                    else:
                        items[fill[base + k]] = s
                        fill[base + k] += 1


@njit
def stamp_shapes(blocked, origin, delta, ranges, rows, kind, prm, verts, vstart,
                 gamma):  # pragma: no cover - compiled
    """Block every node within ``gamma`` of the shapes ``rows``, in place.

    Parameters
    ----------
    blocked : numpy.ndarray of bool, shape (Nx, Ny, Nz)
    origin : numpy.ndarray, shape (3,)
        Position of node (0, 0, 0) [m]; node (i, j, k) is at ``origin + (i, j, k) * delta``.
    delta : float
        Node spacing [m].
    ranges : numpy.ndarray of int64, shape (R, 2, 3)
        First and last node index per axis to visit for each shape (first > last: none).
    rows : numpy.ndarray of int64, shape (R,)
        Rows of the shape table.
    kind, prm, verts, vstart
        The shape table.
    gamma : float
        Margin [m]: a node is blocked iff its gap (:func:`_gap`, clipped at 0) is <= gamma.

    Notes
    -----
    The (x, y) part of each gap is evaluated once per column and finished per node by the same
    two functions as every distance query, so a node is blocked iff ``ObstacleSet.distance``
    of its position is <= gamma, to the bit.
    """
    for r in range(rows.shape[0]):
        s = rows[r]
        for i in range(ranges[r, 0, 0], ranges[r, 1, 0] + 1):
            x = origin[0] + i * delta
            for j in range(ranges[r, 0, 1], ranges[r, 1, 1] + 1):
                y = origin[1] + j * delta
                part = _column_part(kind, prm, verts, vstart, s, x, y)
                for k in range(ranges[r, 0, 2], ranges[r, 1, 2] + 1):
                    if max(_finish(kind, prm, s, part, origin[2] + k * delta), 0.0) <= gamma:
                        blocked[i, j, k] = True


def shape_bounds(kind: np.ndarray, prm: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounding box of every shape row, shapes (S, 3) each [m].

    Fences (:data:`UNBOUNDED_KINDS`) get -inf .. +inf: their solid, the outside, is unbounded.
    """
    lo = np.array(prm[:, :3], dtype=np.float64)
    hi = np.array(prm[:, 3:6], dtype=np.float64)
    sphere = kind == SPHERE
    lo[sphere] = prm[sphere, :3] - prm[sphere, 3:4]
    hi[sphere] = prm[sphere, :3] + prm[sphere, 3:4]
    cylinder = kind == CYLINDER
    radius = prm[cylinder, 2:3]
    lo[cylinder] = np.hstack([prm[cylinder, :2] - radius, prm[cylinder, 3:4]])
    hi[cylinder] = np.hstack([prm[cylinder, :2] + radius, prm[cylinder, 4:5]])
    unbounded = np.isin(kind, UNBOUNDED_KINDS)
    lo[unbounded] = -np.inf
    hi[unbounded] = np.inf
    return lo, hi


def _table(kind: np.ndarray, prm: np.ndarray, verts: Optional[np.ndarray],
           vstart: Optional[np.ndarray]) -> Tuple[np.ndarray, np.ndarray]:
    """The vertex arrays of a table, empty ones for tables without polygons."""
    if verts is None:
        verts = _NO_VERTICES
    if vstart is None:
        if np.any((kind == PRISM) | (kind == FENCE)):
            raise ValueError('polygon rows (PRISM, FENCE) need verts and vstart')
        vstart = np.zeros(len(kind) + 1, dtype=np.int64)
    return verts, vstart


def min_gap_all(points: np.ndarray, kind: np.ndarray, prm: np.ndarray,
                verts: Optional[np.ndarray] = None,
                vstart: Optional[np.ndarray] = None) -> np.ndarray:
    """Exact distance from each point to the nearest shape [m], 0 inside, +inf without shapes.

    Parameters
    ----------
    points : numpy.ndarray, shape (M, 3)
        Query positions [m].
    kind : numpy.ndarray of int64, shape (S,)
        Kind code per row (see the module notes).
    prm : numpy.ndarray, shape (S, 6)
        Shape parameters [m] (see the kind codes).
    verts : numpy.ndarray, shape (V, 2), optional
        Polygon vertices [m] of the PRISM and FENCE rows.
    vstart : numpy.ndarray of int64, shape (S + 1,), optional
        Row ``s`` owns ``verts[vstart[s]:vstart[s + 1]]``.
    """
    verts, vstart = _table(kind, prm, verts, vstart)
    out = np.full(len(points), np.inf)
    if len(kind):
        _min_gap_all(points, kind, prm, verts, vstart, out)
    return out


class ShapeIndex:
    """Uniform lattice over shapes for capped distance queries.

    Parameters
    ----------
    kind : numpy.ndarray of int64, shape (S,)
    prm : numpy.ndarray, shape (S, 6)
    verts, vstart : numpy.ndarray, optional
        Shape table, as for :func:`min_gap_all`; kept by reference (read-only).
    reach : float
        Largest ``cap`` the index answers exactly below [m], > 0.

    Notes
    -----
    The cell edge is chosen so that there is about one shape per cell over the bounded shapes'
    joint bounding box (at least ``reach / 2``, and at most :data:`MAX_CELLS` cells); each cell
    lists the shapes whose bounding box grown by ``reach`` meets it, with one cell of slack
    against rounding. Memory is 8 bytes a cell plus 8 bytes a (cell, shape) pair. Unbounded
    shapes (fences) are evaluated for every query instead.
    """

    def __init__(self, kind: np.ndarray, prm: np.ndarray, reach: float,
                 verts: Optional[np.ndarray] = None,
                 vstart: Optional[np.ndarray] = None) -> None:
        self.kind = kind
        self.prm = prm
        self.verts, self.vstart = _table(kind, prm, verts, vstart)
        self.reach = float(reach)
        unbounded = np.isin(kind, UNBOUNDED_KINDS)
        self.always = np.flatnonzero(unbounded).astype(np.int64)
        bounded = np.flatnonzero(~unbounded).astype(np.int64)
        if len(bounded) == 0:
            origin = np.zeros(3)
            cell = 1.0
            dims = np.ones(3, dtype=np.int64)
            start = np.zeros(2, dtype=np.int64)
            items = np.empty(0, dtype=np.int64)
        else:
            origin, cell, dims, start, items = self._lattice(bounded)
        self.origin = origin
        self.cell = float(cell)
        self.dims = dims
        self._start = start
        self._items = items

    def _lattice(self, bounded: np.ndarray):
        lo, hi = shape_bounds(self.kind[bounded], self.prm[bounded])
        lo = np.clip(lo, -_EXTENT_LIMIT, _EXTENT_LIMIT) - self.reach
        hi = np.clip(hi, -_EXTENT_LIMIT, _EXTENT_LIMIT) + self.reach
        origin = lo.min(axis=0)
        extent = np.maximum(hi.max(axis=0) - origin, 1e-9)
        volume = float(np.prod(extent))
        # About one shape per cell, but no coarser than half a typical shape: large shapes
        # would otherwise share every cell with many others.
        sizes = np.prod(np.maximum(hi - lo - 2.0 * self.reach, 1e-9), axis=1) ** (1.0 / 3.0)
        typical = 0.5 * float(np.median(sizes))
        cell = max(min((volume / max(len(bounded), 1)) ** (1.0 / 3.0), typical),
                   0.5 * self.reach, (volume / MAX_CELLS) ** (1.0 / 3.0))
        dims = np.maximum(np.ceil(extent / cell).astype(np.int64), 1)
        while int(np.prod(dims)) > MAX_CELLS:  # rounding up on three axes can overshoot
            cell *= 1.1
            dims = np.maximum(np.ceil(extent / cell).astype(np.int64), 1)
        top = dims - 1
        lo_cells = np.clip(np.floor((lo - origin) / cell).astype(np.int64) - 1, 0, top)
        hi_cells = np.clip(np.floor((hi - origin) / cell).astype(np.int64) + 1, 0, top)
        start = np.zeros(int(np.prod(dims)) + 1, dtype=np.int64)
        _fill_lattice(lo_cells, hi_cells, dims, start, np.empty(0, dtype=np.int64))
        np.cumsum(start, out=start)
        items = np.empty(int(start[-1]), dtype=np.int64)
        _fill_lattice(lo_cells, hi_cells, dims, start, items)
        # The lattice numbers the bounded shapes 0..B-1: map back to table rows.
        return origin, cell, dims, start, bounded[items]

    @property
    def nbytes(self) -> int:
        """Memory of the lattice [bytes]."""
        return int(self._start.nbytes + self._items.nbytes)

    def query(self, points: np.ndarray, cap: float) -> np.ndarray:
        """Distance to the nearest shape where it is below ``cap``, else ``cap`` [m].

        Parameters
        ----------
        points : numpy.ndarray, shape (M, 3), C-contiguous float64
        cap : float
            [m], 0 < cap <= :attr:`reach`.
        """
        if not 0.0 < cap <= self.reach:
            raise ValueError(f'cap must be in (0, {self.reach}] m, got {cap}')
        out = np.empty(len(points))
        _min_gap_indexed(points, self.kind, self.prm, self.verts, self.vstart, self.always,
                         self.origin, self.cell, self.dims, self._start, self._items,
                         float(cap), out)
        return out


@njit
def _row_gaps(point, rows, kind, prm, verts, vstart, out):  # pragma: no cover - compiled
    for r in range(rows.shape[0]):
        out[r] = max(_gap(kind, prm, verts, vstart, rows[r], point[0], point[1], point[2]), 0.0)


def row_gaps(point: np.ndarray, rows: np.ndarray, kind: np.ndarray, prm: np.ndarray,
             verts: Optional[np.ndarray] = None,
             vstart: Optional[np.ndarray] = None) -> np.ndarray:
    """Exact distance from one point to each of the shape rows ``rows`` [m], 0 inside.

    Parameters
    ----------
    point : numpy.ndarray, shape (3,)
    rows : numpy.ndarray of int64, shape (R,)
    kind, prm, verts, vstart
        The shape table, as for :func:`min_gap_all`.
    """
    verts, vstart = _table(kind, prm, verts, vstart)
    out = np.empty(len(rows))
    _row_gaps(np.ascontiguousarray(point, dtype=np.float64), np.asarray(rows, dtype=np.int64),
              kind, prm, verts, vstart, out)
    return out
