"""A corridor for the bounded search from an optimal path on a coarse, optimistic grid.

The fine grid is cut into cells of ``s x s x s`` nodes; a cell is *open* when at least one of
its nodes is free (optimistic: a cell may be open although no fine path crosses it). An
octile A* over the open cells (steps of ``s * sqrt(axes changed)`` cells, the ``26``-connected
step costs scaled) finds the coarse path; the fine nodes of the cells within one cell
(Chebyshev) of it make the corridor in which the bounded search looks for a fine path. The
coarse path picks the way around the obstacles (the side of each), which a greedy fine search
often gets wrong; the corridor search then finds the best fine path that way.

Nothing here is a proof: the corridor only proposes a path (an upper bound), which
:mod:`.bounded` certifies with its own lower bound, and a corridor without a fine path only
costs the time of its search.

A cell's state is computed when the coarse search first meets it (a scan of its nodes that
stops at the first free one), so the work follows the search, never the grid. The coarse path
is refined through a pyramid of cell sizes (halved from the coarsest down to 2 nodes): each
level searches only under the corridor of the level above, so no level's search is large and
the final corridor is a few nodes wide.
"""

from typing import List, Optional, Sequence, Tuple

import numpy as np

from uav_global_planner.core.jit import njit
from uav_global_planner.core.map.sparse_grid import BRICK, BRICK_BITS, FREE, FULL
from uav_global_planner.core.search.bounded_kernel import (DIRECTIONS, is_free, lazy_zeros,
                                                           neighbour_of, octile, pop, push,
                                                           STEP, trace_path)

#: Largest number of cells of the coarsest level: its cell size s is the smallest power of two
#: from 2 up that keeps it at most this large.
MAX_CELLS = 1 << 18

_BRICK_MASK = BRICK - 1

#: Cell size of the finest level, whose cells make the corridor [nodes].
FINEST = 2

# Cell states (0: not looked at yet).
_OPEN_CELL = 1
_SHUT_CELL = 2
# Cell marks of the coarse search.
_QUEUED = 1
_DONE = 2


def cell_size(shape: Tuple[int, int, int]) -> int:
    """Nodes per cell edge s for a fine grid of ``shape`` (a power of two, >= 2)."""
    nodes = int(np.prod(shape))
    size = 2
    while nodes / size ** 3 > MAX_CELLS:
        size *= 2
    return size


@njit
def _cell_open(flat, table, pool, bricks, nx, ny, nz, size, ci, cj, ck):  # pragma: no cover
    """True when a node of the cell (ci, cj, ck) is free."""
    if flat.shape[0] == 0:
        return _cell_open_sparse(table, pool, bricks, nx, ny, nz, size, ci, cj, ck)
    for i in range(ci * size, min((ci + 1) * size, nx)):
        for j in range(cj * size, min((cj + 1) * size, ny)):
            base = (i * ny + j) * nz
            for k in range(ck * size, min((ck + 1) * size, nz)):
                if is_free(flat, table, pool, bricks, base + k, i, j, k):
                    return True
    return False


@njit
def _cell_open_sparse(table, pool, bricks, nx, ny, nz, size, ci, cj, ck):  # pragma: no cover
    """:func:`_cell_open` on a block-sparse mask, brick by brick: a free brick answers at
    once, a full one is skipped without reading its nodes."""
    i0, i1 = ci * size, min((ci + 1) * size, nx)
    j0, j1 = cj * size, min((cj + 1) * size, ny)
    k0, k1 = ck * size, min((ck + 1) * size, nz)
    for bi in range(i0 >> BRICK_BITS, ((i1 - 1) >> BRICK_BITS) + 1):
        for bj in range(j0 >> BRICK_BITS, ((j1 - 1) >> BRICK_BITS) + 1):
            for bk in range(k0 >> BRICK_BITS, ((k1 - 1) >> BRICK_BITS) + 1):
                code = table[(bi * bricks[1] + bj) * bricks[2] + bk]
                if code == FULL:
                    continue
                if code == FREE:
                    return True
                for i in range(max(i0, bi * BRICK), min(i1, (bi + 1) * BRICK)):
                    for j in range(max(j0, bj * BRICK), min(j1, (bj + 1) * BRICK)):
                        row = ((i & _BRICK_MASK) * BRICK + (j & _BRICK_MASK)) * BRICK
                        for k in range(max(k0, bk * BRICK), min(k1, (bk + 1) * BRICK)):
                            if not pool[code, row + (k & _BRICK_MASK)]:
                                return True
    return False


@njit
def _grown(array, capacity):  # pragma: no cover - compiled
    """``array`` copied into a new array of ``capacity`` entries."""
    out = np.empty(capacity, dtype=array.dtype)
    out[:array.shape[0]] = array
    return out


@njit
def _coarse_astar(flat, table, pool, bricks, nx, ny, nz, size, start, goal, allowed, state,
                  mark, g, parent):  # pragma: no cover - compiled
    """Cells (ci, cj, ck) of an optimal coarse path from the cell of fine node ``start`` to
    that of ``goal``; an empty array when the cells do not connect.

    Only cells with ``allowed[cell] != 0`` are searched when ``allowed`` is not empty;
    ``state``, ``mark``, ``g`` and ``parent`` are zeroed arrays of one entry per cell.
    """
    cx = (nx + size - 1) // size
    cy = (ny + size - 1) // size
    cz = (nz + size - 1) // size
    confined = allowed.shape[0] > 0
    capacity = 1024
    heap_f = np.empty(capacity, dtype=np.float64)
    heap_h = np.empty(capacity, dtype=np.float64)
    heap_n = np.empty(capacity, dtype=np.int64)
    nyz = ny * nz
    si = start // nyz // size
    sj = (start // nz) % ny // size
    sk = start % nz // size
    ti = goal // nyz // size
    tj = (goal // nz) % ny // size
    tk = goal % nz // size
    first = (si * cy + sj) * cz + sk
    last = (ti * cy + tj) * cz + tk
    h0 = octile(abs(si - ti), abs(sj - tj), abs(sk - tk))
    heap_f[0] = h0
    heap_h[0] = h0
    heap_n[0] = first
    heap_size = 1
    mark[first] = _QUEUED
    state[first] = _OPEN_CELL
    state[last] = _OPEN_CELL
    found = False
    while heap_size > 0:
        cell = heap_n[0]
        pop(heap_f, heap_h, heap_n, heap_size)
        heap_size -= 1
        if mark[cell] == _DONE:
            continue
        mark[cell] = _DONE
        if cell == last:
            found = True
            break
        ci = cell // (cy * cz)
        cj = (cell // cz) % cy
        ck = cell % cz
        for d in range(26):
            ni, nj, nk, other = neighbour_of(ci, cj, ck, d, DIRECTIONS, cx, cy, cz)
            if other < 0:
                continue
            if mark[other] == _DONE:
                continue
            if confined and allowed[other] == 0:
                continue
            if state[other] == 0:
                state[other] = (_OPEN_CELL if _cell_open(flat, table, pool, bricks, nx, ny, nz,
                                                         size, ni, nj, nk) else _SHUT_CELL)
            if state[other] == _SHUT_CELL:
                continue
            g_new = g[cell] + STEP[d]
            if mark[other] == _QUEUED and g_new >= g[other]:
                continue
            g[other] = g_new
            parent[other] = d
            mark[other] = _QUEUED
            if heap_size == capacity:
                capacity *= 2
                heap_f = _grown(heap_f, capacity)
                heap_h = _grown(heap_h, capacity)
                heap_n = _grown(heap_n, capacity)
            h = octile(abs(ni - ti), abs(nj - tj), abs(nk - tk))
            push(heap_f, heap_h, heap_n, heap_size, g_new + h, h, other)
            heap_size += 1
    if not found:
        return np.zeros((0, 3), dtype=np.int64)
    return trace_path(last, parent, DIRECTIONS, cy, cz, first)


@njit
def _mark_around(out, cells, ratio, reach, fx, fy, fz, value):  # pragma: no cover - compiled
    """Write ``value`` in ``out`` (cells ``ratio`` times finer than ``cells``, ``fx, fy, fz``
    per axis) under every cell within ``reach`` cells (Chebyshev) of a path cell."""
    for p in range(cells.shape[0]):
        i0 = max((cells[p, 0] - reach) * ratio, 0)
        i1 = min((cells[p, 0] + reach + 1) * ratio, fx)
        j0 = max((cells[p, 1] - reach) * ratio, 0)
        j1 = min((cells[p, 1] + reach + 1) * ratio, fy)
        k0 = max((cells[p, 2] - reach) * ratio, 0)
        k1 = min((cells[p, 2] + reach + 1) * ratio, fz)
        for i in range(i0, i1):
            for j in range(j0, j1):
                base = (i * fy + j) * fz
                for k in range(k0, k1):
                    out[base + k] = value


def levels(shape: Tuple[int, int, int]) -> List[int]:
    """Cell sizes of the pyramid, coarsest first: :func:`cell_size`, halved down to
    :data:`FINEST`."""
    sizes = [max(cell_size(shape), FINEST)]
    while sizes[-1] // 2 >= FINEST:
        sizes.append(sizes[-1] // 2)
    return sizes


def _cells(shape: Tuple[int, int, int], size: int) -> Tuple[int, int, int]:
    return tuple(-(-n // size) for n in shape)  # type: ignore[return-value]


def coarse_corridor(masks, shape: Tuple[int, int, int], start: int, goal: int,
                    corridor: np.ndarray, reach: int = 1,
                    sizes: Optional[Sequence[int]] = None, stamp: int = 1) -> int:
    """Write ``stamp`` in ``corridor`` (one entry per fine node) at the nodes of the cells
    within ``reach`` cells of an optimal coarse path from ``start`` to ``goal`` (flat fine
    node numbers); returns the number of path cells of the finest level, 0 when the coarse
    cells do not connect (nothing written).

    The coarse path is found level by level (``sizes``, coarsest first, each a divisor of the
    one before; :func:`levels` by default): each level searches only the cells under the
    cells within ``reach`` of the path of the level above, so every level's search stays
    small. ``masks`` is the mask as the kernels take it (dense flat mask, brick table, pool,
    bricks).
    """
    chain = levels(shape) if sizes is None else [int(s) for s in sizes]
    nx, ny, nz = shape
    allowed = np.zeros(0, dtype=np.uint8)
    path = np.zeros((0, 3), dtype=np.int64)
    last = chain[0]
    for number, size in enumerate(chain):
        count = int(np.prod(_cells(shape, size)))
        found = _coarse_astar(*masks, nx, ny, nz, size, start, goal, allowed,
                              lazy_zeros(count, np.uint8), lazy_zeros(count, np.uint8),
                              lazy_zeros(count, np.float64), lazy_zeros(count, np.int8))
        if len(found) == 0:
            break  # the corridor of the level above has no path at this level: use that one
        path, last = found, size
        if number + 1 < len(chain):
            finer = _cells(shape, chain[number + 1])
            allowed = lazy_zeros(int(np.prod(finer)), np.uint8)
            _mark_around(allowed, path, size // chain[number + 1], int(reach), *finer, 1)
    if len(path) == 0:
        return 0
    _mark_around(corridor, path, last, int(reach), nx, ny, nz, stamp)
    return int(len(path))
