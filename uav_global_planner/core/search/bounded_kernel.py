"""The compiled A* of the bounded search (:mod:`.bounded`): an octile A* over lengths in
cells, optionally confined to a corridor, that stops at a threshold on its key and reports the
last key it popped (a lower bound of the optimum).

The open list is a binary heap with lazy deletion (a node may be queued more than once; the
entries of a closed node are skipped), ordered by (f, h). The per-node arrays (:class:`Memory`:
cost 8 bytes, parent direction 1, mark 4, corridor stamp 4) are lazily committed zero pages,
kept for the last grid shape searched and reused without clearing (each run has its own marks),
so memory follows the nodes the runs touch and a repeated query commits no new pages.
"""

from contextlib import contextmanager
import math
import mmap
import threading
from typing import Callable, Dict, Iterator, Optional, Tuple, Union

import numpy as np

from uav_global_planner.core.errors import PlanningError, PlanningTimeoutError
from uav_global_planner.core.jit import njit
from uav_global_planner.core.map.sparse_grid import BRICK, BRICK_BITS, FREE, FULL, SparseMask

# Kernel return codes (public: :mod:`.bounded` reads them).
FOUND = 0
EXHAUSTED = 1
PAUSED = 2
GROW = 3
CERTIFIED = 4

# Slots of the kernel's int64 state: heap entries, pops so far, goal, shape, the mark of an
# open node in this run (closed: one more; any smaller mark is a node not seen yet) and the
# stamp of the corridor's nodes.
_K_SIZE = 0
_K_POPS = 1
_K_GOAL = 2
_K_NX = 3
_K_NY = 4
_K_NZ = 5
_K_OPEN = 6
_K_STAMP = 7
# Marks and stamps are int32; the memory is replaced before they would overflow.
_MAX_MARK = 2 ** 31 - 4

# Expansions per kernel call between budget checks (a few milliseconds).
_CHUNK = 20_000
_FIRST_HEAP = 1 << 14
# Per-node arrays from this size up are memory maps without huge pages [bytes].
_LAZY_BYTES = 1 << 20
# Relative margin taken off every lower bound against floating-point rounding.
ROUNDING = 1e-9
_BRICK_MASK = BRICK - 1
_SQRT2 = math.sqrt(2.0)
_SQRT3 = math.sqrt(3.0)
_NO_FLAT = np.zeros(0, dtype=np.bool_)
_NO_TABLE = np.zeros(0, dtype=np.int32)
_NO_POOL = np.zeros((0, BRICK ** 3), dtype=np.bool_)
_NO_BRICKS = np.zeros(3, dtype=np.int64)
NO_CORRIDOR = np.zeros(0, dtype=np.int32)

#: The 26 neighbour offsets (di, dj, dk) and the length of each step [cells].
DIRECTIONS = np.array([(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)
                       if (a, b, c) != (0, 0, 0)], dtype=np.int64)
STEP = np.sqrt(np.abs(DIRECTIONS).sum(axis=1).astype(np.float64))


@njit
def octile(di, dj, dk):
    """Obstacle-free 26-connected distance [cells] for absolute index differences."""
    # Sort so that d1 >= d2 >= d3: move diagonally in 3D d3 times, in 2D d2 - d3 times and
    # straight d1 - d2 times.
    d1, d2, d3 = di, dj, dk
    if d1 < d2:
        d1, d2 = d2, d1
    if d2 < d3:
        d2, d3 = d3, d2
    if d1 < d2:
        d1, d2 = d2, d1
    return _SQRT3 * d3 + _SQRT2 * (d2 - d3) + (d1 - d2)


@njit
def is_free(flat, table, pool, bricks, node, i, j, k):  # pragma: no cover - compiled
    """True when the node is free in the dense ``flat`` mask, else the block-sparse one."""
    if flat.shape[0] > 0:
        return not flat[node]
    code = table[((i >> BRICK_BITS) * bricks[1] + (j >> BRICK_BITS)) * bricks[2]
                 + (k >> BRICK_BITS)]
    if code == FREE:
        return True
    if code == FULL:
        return False
    local = (((i & _BRICK_MASK) * BRICK) + (j & _BRICK_MASK)) * BRICK + (k & _BRICK_MASK)
    return not pool[code, local]


@njit(inline='always')
def neighbour_of(i, j, k, d, directions, nx, ny, nz):  # pragma: no cover - compiled
    """``(ni, nj, nk, node)``: the indices of the neighbour of node (i, j, k) along direction
    ``d`` (a row of ``directions``) of an ``nx x ny x nz`` grid and its flat number, -1 when it
    lies outside the grid. Inlined in the kernels (no call)."""
    ni = i + directions[d, 0]
    nj = j + directions[d, 1]
    nk = k + directions[d, 2]
    if ni < 0 or ni >= nx or nj < 0 or nj >= ny or nk < 0 or nk >= nz:
        return ni, nj, nk, -1
    return ni, nj, nk, (ni * ny + nj) * nz + nk


@njit
def _before(f_a, h_a, f_b, h_b):
    return f_a < f_b or (f_a == f_b and h_a < h_b)


@njit(inline='always')
def _put(heap_f, heap_h, heap_n, pos, f, h, node):  # pragma: no cover - compiled
    """Write the entry of key (f, h) for ``node`` at heap slot ``pos`` (inlined, no call)."""
    heap_f[pos] = f
    heap_h[pos] = h
    heap_n[pos] = node


@njit
def push(heap_f, heap_h, heap_n, size, f, h, node):  # pragma: no cover - compiled
    pos = size
    while pos > 0:
        up = (pos - 1) >> 1
        if not _before(f, h, heap_f[up], heap_h[up]):
            break
        _put(heap_f, heap_h, heap_n, pos, heap_f[up], heap_h[up], heap_n[up])
        pos = up
    _put(heap_f, heap_h, heap_n, pos, f, h, node)


@njit
def pop(heap_f, heap_h, heap_n, size):  # pragma: no cover - compiled
    """Remove the root of a heap of ``size`` entries (``size`` >= 1)."""
    size -= 1
    f = heap_f[size]
    h = heap_h[size]
    node = heap_n[size]
    pos = 0
    while True:
        child = 2 * pos + 1
        if child >= size:
            break
        if child + 1 < size and _before(heap_f[child + 1], heap_h[child + 1], heap_f[child],
                                        heap_h[child]):
            child += 1
        if not _before(heap_f[child], heap_h[child], f, h):
            break
        _put(heap_f, heap_h, heap_n, pos, heap_f[child], heap_h[child], heap_n[child])
        pos = child
    _put(heap_f, heap_h, heap_n, pos, f, h, node)


@njit
def _astar(flat, table, pool, bricks, corridor, g, parent, mark, heap_f, heap_h, heap_n,
           directions, step, state, bounds, max_pops):  # pragma: no cover - compiled
    """Run at most ``max_pops`` expansions of an octile A* (lengths in cells).

    Only nodes with ``corridor[node]`` equal to the run's stamp are searched when
    ``corridor`` is not empty; ``mark`` holds the run's open mark, the closed mark (one more)
    or an older value (a node not seen in this run).
    ``bounds[0]`` is the threshold: popping a node with ``f >= bounds[0]`` stops the search
    with ``CERTIFIED``; ``bounds[1]`` receives the key of the last node popped (a lower bound
    of the optimum when ``bounds[2]``, the weight of the heuristic in the key, is 1).
    Returns ``FOUND`` (goal popped), ``EXHAUSTED``, ``PAUSED``, ``GROW`` (the heap might not
    hold 26 more entries) or ``CERTIFIED``.
    """
    size = state[_K_SIZE]
    goal = state[_K_GOAL]
    nx = state[_K_NX]
    ny = state[_K_NY]
    nz = state[_K_NZ]
    nyz = ny * nz
    gi = goal // nyz
    gj = (goal // nz) % ny
    gk = goal % nz
    threshold = bounds[0]
    weight = bounds[2]
    limited = corridor.shape[0] > 0
    stamp = state[_K_STAMP]
    is_open = state[_K_OPEN]
    is_closed = is_open + 1
    capacity = heap_n.shape[0]
    pops = 0
    status = PAUSED
    while True:
        if size == 0:
            status = EXHAUSTED
            break
        if pops >= max_pops:
            break
        if size + 26 > capacity:
            status = GROW
            break
        f = heap_f[0]
        node = heap_n[0]
        pop(heap_f, heap_h, heap_n, size)
        size -= 1
        if mark[node] == is_closed:
            continue  # a stale entry: the node was closed with a lower key
        bounds[1] = f
        if f >= threshold:
            status = CERTIFIED
            break
        mark[node] = is_closed
        pops += 1
        if node == goal:
            status = FOUND
            break
        i = node // nyz
        j = (node // nz) % ny
        k = node % nz
        g_node = g[node]
        for d in range(26):
            ni, nj, nk, neighbour = neighbour_of(i, j, k, d, directions, nx, ny, nz)
            if neighbour < 0:
                continue
            seen = mark[neighbour]
            if seen == is_closed:
                continue
            if limited and corridor[neighbour] != stamp:
                continue
            g_new = g_node + step[d]
            if seen == is_open and g_new >= g[neighbour]:
                continue
            if seen < is_open and not is_free(flat, table, pool, bricks, neighbour, ni, nj, nk):
                mark[neighbour] = is_closed  # blocked: never looked at again
                continue
            g[neighbour] = g_new
            parent[neighbour] = d
            mark[neighbour] = is_open
            h = octile(abs(ni - gi), abs(nj - gj), abs(nk - gk))
            push(heap_f, heap_h, heap_n, size, g_new + weight * h, h, neighbour)
            size += 1
    state[_K_SIZE] = size
    state[_K_POPS] += pops
    return status


@njit
def trace_path(goal, parent, directions, ny, nz, start):  # pragma: no cover - compiled
    """(i, j, k) of the path from ``start`` to ``goal`` following the parent directions."""
    nyz = ny * nz
    length = 1
    node = goal
    while node != start:
        d = parent[node]
        node -= (directions[d, 0] * ny + directions[d, 1]) * nz + directions[d, 2]
        length += 1
    path = np.empty((length, 3), dtype=np.int64)
    node = goal
    for slot in range(length - 1, -1, -1):
        path[slot, 0] = node // nyz
        path[slot, 1] = (node // nz) % ny
        path[slot, 2] = node % nz
        if slot > 0:
            d = parent[node]
            node -= (directions[d, 0] * ny + directions[d, 1]) * nz + directions[d, 2]
    return path


def lazy_zeros(count: int, dtype, min_bytes: int = _LAZY_BYTES) -> np.ndarray:
    """Zeros whose pages are committed when first written (no huge pages): a memory map from
    ``min_bytes`` [bytes] up, plain numpy zeros below."""
    nbytes = int(count) * np.dtype(dtype).itemsize
    if nbytes < min_bytes or not hasattr(mmap, 'MADV_NOHUGEPAGE'):
        return np.zeros(count, dtype=dtype)
    region = mmap.mmap(-1, nbytes)
    region.madvise(mmap.MADV_NOHUGEPAGE)
    return np.frombuffer(region, dtype=dtype, count=count)


def kernel_masks(blocked: Union[np.ndarray, SparseMask]) -> Tuple[np.ndarray, ...]:
    """The mask as the kernels take it: (flat dense mask, brick table, pool, bricks), the
    arrays of the other layout empty."""
    if isinstance(blocked, SparseMask):
        return (_NO_FLAT, blocked.table, blocked.pool, np.asarray(blocked.bricks, np.int64))
    return (np.ascontiguousarray(blocked).reshape(-1), _NO_TABLE, _NO_POOL, _NO_BRICKS)


class Memory:
    """The per-node arrays of the kernel for one grid shape, kept between runs.

    ``g`` (cost [cells]), ``parent`` (direction into the node), ``mark`` (int32: open or
    closed in a run, older values mean not seen) and ``corridor`` (int32 stamps) are lazily
    committed zeros; a run takes a new mark and a corridor a new stamp, so nothing is cleared
    between runs and a run only touches the pages of the nodes it reaches.
    """

    def __init__(self, shape: Tuple[int, int, int]) -> None:
        size = int(np.prod(shape))
        self.shape = shape
        self.g = lazy_zeros(size, np.float64)
        self.parent = lazy_zeros(size, np.int8)
        self.mark = lazy_zeros(size, np.int32)
        self.corridor = lazy_zeros(size, np.int32)
        self.last_mark = 0
        self.last_stamp = 0
        self.lock = threading.Lock()

    def new_mark(self) -> int:
        """The open mark of a new run (its closed mark is one more)."""
        self.last_mark += 2
        return self.last_mark

    def new_stamp(self) -> int:
        """The stamp of a new corridor."""
        self.last_stamp += 1
        return self.last_stamp

    @property
    def worn(self) -> bool:
        """True when marks or stamps are near their int32 limit: use new memory."""
        return max(self.last_mark, self.last_stamp) >= _MAX_MARK


_MEMORY: Dict[Tuple[int, int, int], Memory] = {}
_MEMORY_LOCK = threading.Lock()


@contextmanager
def memory_for(shape: Tuple[int, int, int]) -> Iterator[Memory]:
    """The kept :class:`Memory` of ``shape`` (the last shape asked for is kept), or new memory
    while another thread uses it."""
    with _MEMORY_LOCK:
        memory = _MEMORY.get(shape)
        if memory is None or memory.worn:
            _MEMORY.clear()
            memory = _MEMORY[shape] = Memory(shape)
    if not memory.lock.acquire(blocking=False):
        yield Memory(shape)
        return
    try:
        yield memory
    finally:
        memory.lock.release()


class Phase:
    """One run of :func:`_astar` from ``start`` to ``goal`` (flat node numbers) on ``memory``
    (its per-node arrays) with its own heap; a ``stamp`` above 0 confines it to the nodes of
    ``memory.corridor`` that carry it. A later run on the same memory overwrites this one."""

    def __init__(self, blocked: Union[np.ndarray, SparseMask], start: int, goal: int,
                 memory: Memory, stamp: int = 0) -> None:
        shape = tuple(int(n) for n in blocked.shape)
        self.masks = kernel_masks(blocked)
        self.shape = shape
        self.start = start
        self.corridor = memory.corridor if stamp > 0 else NO_CORRIDOR
        self.g = memory.g
        self.parent = memory.parent
        self.mark = memory.mark
        is_open = memory.new_mark()
        self.heap_f = np.empty(_FIRST_HEAP, dtype=np.float64)
        self.heap_h = np.empty(_FIRST_HEAP, dtype=np.float64)
        self.heap_n = np.empty(_FIRST_HEAP, dtype=np.int64)
        nyz = shape[1] * shape[2]
        gi, gj, gk = goal // nyz, goal // shape[2] % shape[1], goal % shape[2]
        si, sj, sk = start // nyz, start // shape[2] % shape[1], start % shape[2]
        h = float(octile(abs(si - gi), abs(sj - gj), abs(sk - gk)))
        self.heap_f[0], self.heap_h[0], self.heap_n[0] = h, h, start
        self.mark[start] = is_open
        self.g[start] = 0.0
        self.state = np.array([1, 0, goal, *shape, is_open, stamp], dtype=np.int64)
        self.bounds = np.array([math.inf, 0.0, 1.0])

    @property
    def pops(self) -> int:
        """Nodes expanded so far."""
        return int(self.state[_K_POPS])

    def run(self, threshold: float, budget: int, checkpoint: Optional[Callable[[], None]],
            spent: int, weight: float = 1.0) -> int:
        """Search until the goal, the threshold [cells] or the end; returns the status.

        ``budget`` (0: none) counts expansions with the ``spent`` ones of earlier phases;
        ``weight`` multiplies the heuristic in the key (1: optimal, and a lower bound).
        """
        self.bounds[0] = threshold
        self.bounds[2] = weight
        while True:
            pops = _CHUNK if checkpoint is not None or budget > 0 else 2 ** 62
            if budget > 0:
                pops = min(pops, budget - spent - self.pops)
            status = _astar(*self.masks, self.corridor, self.g, self.parent, self.mark,
                            self.heap_f, self.heap_h, self.heap_n, DIRECTIONS, STEP,
                            self.state, self.bounds, pops)
            if status == GROW:
                size = int(self.state[_K_SIZE])
                self.heap_f = np.concatenate([self.heap_f, np.empty_like(self.heap_f)])
                self.heap_h = np.concatenate([self.heap_h, np.empty_like(self.heap_h)])
                self.heap_n = np.concatenate([self.heap_n, np.empty_like(self.heap_n)])
                assert size + 26 <= len(self.heap_n)
                continue
            if status != PAUSED:
                return status
            if checkpoint is not None:
                try:
                    checkpoint()
                except PlanningError as error:
                    error.expanded_nodes = spent + self.pops
                    raise
            if budget > 0 and spent + self.pops >= budget:
                raise PlanningTimeoutError(
                    f'search ran out of its expansion budget (max_expansions = {budget}) '
                    f'after expanding {spent + self.pops} nodes', expanded_nodes=spent + self.pops)

    def path(self, goal: int) -> np.ndarray:
        """(i, j, k) of the path found to ``goal``, shape (N, 3) int64."""
        return trace_path(goal, self.parent, DIRECTIONS, self.shape[1], self.shape[2], self.start)
