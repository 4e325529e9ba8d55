"""Inflation of dense point sets in time close to linear in the grid.

Stamping each point's ball of radius gamma (:mod:`uav_global_planner.core.map.inflation`) costs
points x (gamma / delta)^3 node visits. A dense scan, such as a room scanned at 2 cm (a million
points, a dozen or more per grid cell), makes that billions of visits, most of them on nodes
that many other balls block too. This pass works on the grid's cells instead:

1. Every point p is assigned its nearest node c(p); ``r`` is the largest offset ``|p - c(p)|``
   (at most delta sqrt(3) / 2, plus rounding).
2. An exact Euclidean distance transform of the occupied nodes (the lower envelope of
   parabolas of Felzenszwalb and Huttenlocher, axis by axis, on integer squared distances in
   cells, so without rounding) gives every node X the distance d(X) to the nearest occupied
   node.
3. By the triangle inequality the distance D(X) to the nearest point lies in [d - r, d + r]:
   nodes with d + r <= gamma are blocked and nodes with d - r > gamma are free (with a slack
   :data:`SLACK_RELATIVE`, far above any rounding, taken off both).
4. Only the nodes in between, a shell about 2 r thick around the inflated surface, are
   decided by the exact test: against the points of the occupied cells whose node lies between
   d and gamma + r from them (any point within gamma lies in such a cell; none is nearer than
   d), nearest cells first, stopping at the first point within gamma.

The exact test is the formula of the stamping kernels: node coordinate ``min + i * delta``,
differences squared and summed x, y, z in that order, then the square root, compared with
``<= gamma``; so a node is blocked here iff the stamping blocks it, to the bit (ties at exactly
gamma included). Steps 2 and 3 decide only nodes whose verdict the bounds prove.

The work is done box by box (the build windows of the inflation), each with a halo of
:attr:`CellBins.halo` cells so that every occupied cell within gamma + r of a node of the box is
seen. A box costs time proportional to its cells with their halo, plus its points, plus its
shell nodes times the cells of a spherical shell of radius gamma and thickness 2 r. That last
term is large for isolated points (each one's shell is a sphere of its own): the caller
compares the cost with the stamping's and picks (:func:`transform_cost`, ``max_work`` of
:func:`mark_box`).

One implementation: compiled loops (with ``UAV_PLANNER_DISABLE_JIT=1`` the same source runs as
plain Python, slowly, for debugging).
"""

from dataclasses import dataclass
import math
from typing import Tuple

import numpy as np

from uav_global_planner.core.jit import njit

#: Slack of the bounds of step 3, relative to gamma + delta [m / m]; a further 1e-12 of the
#: largest coordinate covers the rounding of the node coordinates and offsets (about 1e-16 of
#: them). Any slack only widens the shell of exactly tested nodes.
SLACK_RELATIVE = 1e-9
_SLACK_SCALE = 1e-12
#: Squared distance [cells^2] of a node with no occupied node in its row (and box).
_FAR = 1 << 30
#: Widest (gamma + r) / delta [cells] for which :func:`mark_box` is offered: its exact test
#: reads about 4 pi (that)^2 cells a shell node, beyond which stamping or a nearest-point query
#: is cheaper anyway (and the offset table stays small).
MAX_REACH_CELLS = 40


@dataclass(frozen=True, eq=False)
class CellBins:
    """Points assigned to their nearest grid node, and the bounds of the pass (module notes).

    Attributes
    ----------
    points : numpy.ndarray, shape (N, 3)
        The points [m], float64, C-contiguous.
    cells : numpy.ndarray of int64, shape (N, 3)
        Index of each point's nearest node; it may lie outside the grid (points near the
        bounds outside them).
    offset : float
        r: the largest distance from a point to its node, slack included [m].
    slack : float
        Slack of the bounds [m].
    halo : int
        Cells a box is widened by on every side: ``ceil((gamma + r + slack) / delta) + 1``.
    inner2 : float
        Nodes whose squared distance to the nearest occupied node [cells^2] is at most this
        are blocked without a test; -1 when none is.
    outer2 : float
        ... and those beyond this are free.
    offsets : numpy.ndarray of int64, shape (K, 3)
        Every cell offset whose squared length is at most ``outer2``, shortest first; none
        when ``outer2`` exceeds :data:`MAX_REACH_CELLS` squared (:attr:`boxes_allowed`).
    first_at : numpy.ndarray of int64, shape (floor(outer2) + 2,) or (0,)
        ``first_at[q]``: the first offset whose squared length is at least q.
    """

    points: np.ndarray
    cells: np.ndarray
    offset: float
    slack: float
    halo: int
    inner2: float
    outer2: float
    offsets: np.ndarray
    first_at: np.ndarray

    @property
    def boxes_allowed(self) -> bool:
        """Whether :func:`mark_box` may be used (gamma at most :data:`MAX_REACH_CELLS`)."""
        return len(self.first_at) > 0


def halo_cells(gamma: float, delta: float) -> int:
    """Halo [cells] of the boxes of points assigned to their nearest node: the bound on r of
    any such assignment (delta sqrt(3) / 2, with room for rounding)."""
    return int(math.ceil((gamma + 0.87 * delta) * (1.0 + SLACK_RELATIVE) / delta)) + 1


def bin_points(points: np.ndarray, origin: np.ndarray, delta: float,
               gamma: float) -> CellBins:
    """Assign ``points`` to their nearest nodes of the grid from ``origin`` [m] with spacing
    ``delta`` [m], for the margin ``gamma`` [m]; see :class:`CellBins`."""
    pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    start = np.ascontiguousarray(origin, dtype=np.float64)
    cells = np.empty(pts.shape, dtype=np.int64)
    largest, scale = _assign(pts, start, float(delta), cells)
    slack = SLACK_RELATIVE * (gamma + delta) + _SLACK_SCALE * scale
    offset = largest + slack
    outer = (gamma + offset + slack) / delta
    inner = (gamma - offset - slack) / delta
    outer2 = outer * outer
    inner2 = inner * inner if inner >= 0.0 else -1.0
    reach = int(math.floor(outer))
    if reach > MAX_REACH_CELLS:
        return CellBins(pts, cells, offset, slack, int(math.ceil(outer)) + 1, inner2, outer2,
                        np.zeros((0, 3), dtype=np.int64), np.zeros(0, dtype=np.int64))
    steps = np.arange(-reach, reach + 1, dtype=np.int64)
    grid = np.stack(np.meshgrid(steps, steps, steps, indexing='ij'), axis=-1).reshape(-1, 3)
    lengths = np.sum(grid * grid, axis=1)
    inside = lengths <= outer2
    order = np.argsort(lengths[inside], kind='stable')
    offsets = np.ascontiguousarray(grid[inside][order])
    first_at = np.searchsorted(lengths[inside][order],
                               np.arange(int(math.floor(outer2)) + 2)).astype(np.int64)
    return CellBins(pts, cells, offset, slack, int(math.ceil(outer)) + 1, inner2, outer2,
                    offsets, first_at)


@njit
def _assign(points, origin, delta, cells):  # pragma: no cover - compiled
    """Nearest node of each point into ``cells``; the largest offset and coordinate [m]."""
    inverse = 1.0 / delta
    largest = 0.0
    scale = abs(origin[0]) + abs(origin[1]) + abs(origin[2])
    for n in range(points.shape[0]):
        total = 0.0
        size = 0.0
        for axis in range(3):
            index = np.rint((points[n, axis] - origin[axis]) * inverse)
            cells[n, axis] = np.int64(index)
            gap = points[n, axis] - (origin[axis] + cells[n, axis] * delta)
            total += gap * gap
            size += abs(points[n, axis]) + abs(origin[axis] + cells[n, axis] * delta)
        largest = max(largest, math.sqrt(total))
        scale = max(scale, size)
    return largest, scale


def bucket(bins: CellBins, shape: np.ndarray, edge: int) -> Tuple[np.ndarray, np.ndarray]:
    """The points listed under the boxes of ``edge`` nodes a side (box (a, b, c) holds the
    nodes ``[a edge, (a + 1) edge)`` x ..., clipped to the grid of ``shape`` nodes) whose
    cells with their halo hold the point's cell.

    Returns
    -------
    start : numpy.ndarray of int64, shape (boxes + 1,)
    items : numpy.ndarray of int32
        Box ``w`` (C order) lists ``items[start[w]:start[w + 1]]``.
    """
    sides = np.asarray(shape, dtype=np.int64)
    boxes = -(-sides // edge)
    lows = np.maximum(bins.cells - bins.halo, 0)
    highs = np.minimum(bins.cells + bins.halo, sides - 1)
    return bucket_spans(lows, highs, int(edge), boxes)


@njit
def list_item(start, fill, items, step, item, lo, hi, windows):  # pragma: no cover - compiled
    """One item's part of a two-pass window listing: pass 0 (``step`` 0) counts it under each
    window from ``lo`` to ``hi`` (window indices, inclusive, per axis) in ``start[w + 1]``;
    pass 1 writes it at ``fill[w]`` of ``items``."""
    for a in range(lo[0], hi[0] + 1):
        for b in range(lo[1], hi[1] + 1):
            for c in range(lo[2], hi[2] + 1):
                w = (a * windows[1] + b) * windows[2] + c
                if step:
                    items[fill[w]] = item
                    fill[w] += 1
                else:
                    start[w + 1] += 1


@njit
def bucket_spans(lows, highs, edge, windows):  # pragma: no cover - compiled
    """Items listed under the windows (``edge`` nodes a side, ``windows`` per axis) that their
    inclusive node-index spans ``lows[s]`` .. ``highs[s]`` meet; an item whose span is empty on
    some axis is listed nowhere. Returns ``start`` (one per window and one more) and ``items``
    (C order over windows, items in order within a window)."""
    count = windows[0] * windows[1] * windows[2]
    start = np.zeros(count + 1, dtype=np.int64)
    lo = np.empty(3, dtype=np.int64)
    hi = np.empty(3, dtype=np.int64)
    for step in range(2):
        fill = start[:-1].copy()
        items = np.empty(start[count] if step else 0, dtype=np.int32)
        for s in range(lows.shape[0]):
            empty = False
            for axis in range(3):
                if lows[s, axis] > highs[s, axis]:
                    empty = True
                lo[axis] = lows[s, axis] // edge
                hi[axis] = highs[s, axis] // edge
            if empty:
                continue
            list_item(start, fill, items, step, s, lo, hi, windows)
        if not step:
            for w in range(count):
                start[w + 1] += start[w]
    return start, items


def transform_cost(extent, halo: int) -> int:
    """Cells the transform of a box of ``extent`` nodes (3 ints) with its halo visits."""
    return int(np.prod(np.asarray(extent, dtype=np.int64) + 2 * int(halo)))


def mark_box(block: np.ndarray, base: np.ndarray, bins: CellBins, items: np.ndarray,
             lo: np.ndarray, hi: np.ndarray, origin: np.ndarray, delta: float, gamma: float,
             max_work: float) -> int:
    """Block the nodes of the box [lo, hi] (global node indices, inclusive) within gamma of a
    point, in the window ``block`` of the grid from node ``base`` on (it holds the box).

    Parameters
    ----------
    block : numpy.ndarray of bool, 3-D
        Written where a node is blocked, never cleared.
    base : numpy.ndarray of int64, shape (3,)
    bins : CellBins
    items : numpy.ndarray of int
        Indices of ``bins.points`` that include every point whose cell lies within the halo of
        the box (others are ignored).
    lo, hi : numpy.ndarray of int64, shape (3,)
    origin : numpy.ndarray, shape (3,)
        Position of node (0, 0, 0) [m].
    delta, gamma : float
        Node spacing and margin [m].
    max_work : float
        Most cell visits the exact test of the shell may take.

    Returns
    -------
    int
        Nodes decided by the exact test; -1 when that would take more than ``max_work``
        visits: the nodes the bounds prove blocked are then written, the shell is not.

    Raises
    ------
    ValueError
        When ``bins`` do not allow boxes (:attr:`CellBins.boxes_allowed`).
    """
    if not bins.boxes_allowed:
        raise ValueError('gamma spans too many cells for the boxes of the distance transform')
    return int(_mark_box(block, np.asarray(base, dtype=np.int64),
                         np.asarray(lo, dtype=np.int64), np.asarray(hi, dtype=np.int64),
                         bins.points, bins.cells, np.asarray(items), bins.halo,
                         np.ascontiguousarray(origin, dtype=np.float64), float(delta),
                         float(gamma), bins.inner2, bins.outer2, bins.offsets, bins.first_at,
                         float(max_work)))


@njit(inline='always')
def _box_cell(cells, n, lo, halo, sa, sb, sc):  # pragma: no cover - compiled
    """Flat index ``(a sb + b) sc + c`` of point ``n``'s cell in the box with its halo, or -1
    when the cell lies outside (inlined into :func:`_mark_box` by numba)."""
    a = cells[n, 0] - lo[0] + halo
    b = cells[n, 1] - lo[1] + halo
    c = cells[n, 2] - lo[2] + halo
    if 0 <= a < sa and 0 <= b < sb and 0 <= c < sc:
        return (a * sb + b) * sc + c
    return -1


@njit
def _mark_box(block, base, lo, hi, points, cells, items, halo, origin, delta, gamma, inner2,
              outer2, offsets, first_at, max_work):  # pragma: no cover - compiled
    nx = hi[0] - lo[0] + 1
    ny = hi[1] - lo[1] + 1
    nz = hi[2] - lo[2] + 1
    sa = nx + 2 * halo
    sb = ny + 2 * halo
    sc = nz + 2 * halo
    # The box's points sorted by cell (a counting sort): cell f = (a sb + b) sc + c holds
    # local[start[f]:start[f + 1]].
    start = np.zeros(sa * sb * sc + 1, dtype=np.int32)
    for m in range(items.shape[0]):
        f = _box_cell(cells, items[m], lo, halo, sa, sb, sc)
        if f >= 0:
            start[f + 1] += 1
    for f in range(sa * sb * sc):
        start[f + 1] += start[f]
    fill = start[:-1].copy()
    local = np.empty((start[sa * sb * sc], 3))
    for m in range(items.shape[0]):
        n = items[m]
        f = _box_cell(cells, n, lo, halo, sa, sb, sc)
        if f >= 0:
            local[fill[f], 0] = points[n, 0]
            local[fill[f], 1] = points[n, 1]
            local[fill[f], 2] = points[n, 2]
            fill[f] += 1
    squared = _squared_distances(start, sa, sb, sc, halo, int(math.floor(outer2)))
    # One byte a cell for the exact test's scan, and each offset as a step of the flat index.
    occupied = np.empty(sa * sb * sc, dtype=np.uint8)
    for f in range(sa * sb * sc):
        occupied[f] = start[f + 1] > start[f]
    steps = np.empty(offsets.shape[0], dtype=np.int64)
    for o in range(offsets.shape[0]):
        steps[o] = (offsets[o, 0] * sb + offsets[o, 1]) * sc + offsets[o, 2]
    # The bounds: blocked, free, or left to the exact test (its work counted first: the
    # caller's other passes may be cheaper than a wide shell).
    work = 0.0
    shell = 0
    last = offsets.shape[0]
    for a in range(nx):
        for b in range(ny):
            for c in range(nz):
                q = squared[a, b, c]
                if q > outer2:
                    continue
                i = lo[0] + a - base[0]
                j = lo[1] + b - base[1]
                k = lo[2] + c - base[2]
                if q <= inner2:
                    block[i, j, k] = True
                elif not block[i, j, k]:
                    work += last - first_at[q]
                    shell += 1
    if work > max_work:
        return -1
    for a in range(nx):
        x = origin[0] + (lo[0] + a) * delta
        for b in range(ny):
            y = origin[1] + (lo[1] + b) * delta
            for c in range(nz):
                q = squared[a, b, c]
                if q > outer2 or q <= inner2:
                    continue
                i = lo[0] + a - base[0]
                j = lo[1] + b - base[1]
                k = lo[2] + c - base[2]
                if block[i, j, k]:
                    continue
                z = origin[2] + (lo[2] + c) * delta
                here = ((a + halo) * sb + b + halo) * sc + c + halo
                if _any_within(x, y, z, here, start, local, occupied, steps, first_at[q],
                               gamma):
                    block[i, j, k] = True
    return shell


@njit
def _any_within(x, y, z, here, start, local, occupied, steps, first,
                gamma):  # pragma: no cover - compiled
    """Whether a point of the cells ``here + steps[first:]`` (flat indices of the haloed box)
    lies within gamma of the node at (x, y, z) [m], by the stamping kernels' formula."""
    for o in range(first, steps.shape[0]):
        f = here + steps[o]
        if not occupied[f]:
            continue
        for m in range(start[f], start[f + 1]):
            dx = x - local[m, 0]
            dy = y - local[m, 1]
            row = dx * dx + dy * dy
            dz = z - local[m, 2]
            if math.sqrt(row + dz * dz) <= gamma:
                return True
    return False


@njit
def _squared_distances(start, sa, sb, sc, halo, cap):  # pragma: no cover - compiled
    """Squared distance [cells^2] from each node of the box (the cells without their halo) to
    the nearest occupied cell of the haloed box where it is at most ``cap``, :data:`_FAR`
    elsewhere: the exact transform, separable along z, y, then x (a value beyond ``cap`` can
    only grow in the later passes, so it is dropped at once)."""
    far = _FAR
    columns = np.empty(sa * sb * sc, dtype=np.int32)
    # Along z: the distance to the nearest occupied cell of the same (x, y) column, squared.
    for ab in range(sa * sb):
        row = ab * sc
        last = -1
        for c in range(sc):
            if start[row + c + 1] > start[row + c]:
                last = c
            columns[row + c] = far if last < 0 else c - last
        last = -1
        for c in range(sc - 1, -1, -1):
            if start[row + c + 1] > start[row + c]:
                last = c
            if last >= 0 and last - c < columns[row + c]:
                columns[row + c] = last - c
        for c in range(sc):
            gap = np.int64(columns[row + c])
            columns[row + c] = gap * gap if gap * gap <= cap else far
    size = max(sa, sb)
    values = np.empty(size, dtype=np.int32)
    out = np.empty(size, dtype=np.int32)
    where = np.empty(size, dtype=np.int32)
    bounds = np.empty(size + 1)
    # Along y, for the box's heights only (the halo's are not needed any more).
    for a in range(sa):
        for c in range(halo, sc - halo):
            for b in range(sb):
                values[b] = columns[(a * sb + b) * sc + c]
            _envelope(values, sb, out, where, bounds, cap)
            for b in range(sb):
                columns[(a * sb + b) * sc + c] = out[b]
    squared = np.empty((sa - 2 * halo, sb - 2 * halo, sc - 2 * halo), dtype=np.int32)
    # Along x, for the box's (y, z) only.
    for b in range(halo, sb - halo):
        for c in range(halo, sc - halo):
            for a in range(sa):
                values[a] = columns[(a * sb + b) * sc + c]
            _envelope(values, sa, out, where, bounds, cap)
            for a in range(halo, sa - halo):
                squared[a - halo, b - halo, c - halo] = out[a]
    return squared


@njit
def _envelope(values, n, out, where, bounds, cap):  # pragma: no cover - compiled
    """``out[q] = min over p of (q - p)^2 + values[p]`` for q, p < n where that is at most
    ``cap``, else :data:`_FAR`; :data:`_FAR` values are skipped (the lower envelope of
    parabolas of Felzenszwalb and Huttenlocher, in integers but for the crossings)."""
    k = -1
    for q in range(n):
        value = values[q]
        if value >= _FAR:
            continue
        s = -math.inf
        while k >= 0:
            p = where[k]
            s = ((value + q * q) - (values[p] + p * p)) / (2.0 * (q - p))
            if s <= bounds[k]:
                k -= 1
            else:
                break
        k += 1
        where[k] = q
        bounds[k] = s if k > 0 else -math.inf
        bounds[k + 1] = math.inf
    if k < 0:
        for q in range(n):
            out[q] = _FAR
        return
    j = 0
    for q in range(n):
        while bounds[j + 1] < q:
            j += 1
        p = where[j]
        total = (q - p) * (q - p) + values[p]
        out[q] = total if total <= cap else _FAR
