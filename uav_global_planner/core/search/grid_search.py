"""Best-first search on the 26-connected voxel grid (paper section 3, eq. 12).

One A* routine serves every algorithm; only the heuristic h differs, chosen by an integer code:

``dijkstra``
    h = 0 (uniform-cost search).
``astar``
    Euclidean distance to the goal.
``adaptive``
    The paper's eq. 12: Manhattan (L1) distance while the Euclidean distance to the goal is above
    eta, Euclidean within eta. Manhattan overestimates diagonal moves, so the search is greedier
    and not optimal far from the goal; that trade of path length for speed is the point.
``octile``
    The exact obstacle-free 26-connected distance; admissible and consistent, and the tightest
    such bound, so it expands the fewest nodes of the optimal heuristics.
``weighted``
    Weighted A*: w times the octile distance, w >= 1. With a consistent heuristic and closed
    nodes never reopened, the path found costs at most w times the optimum (Likhachev, Gordon
    and Thrun, ARA*, NIPS 2003, theorem 1), for far fewer expansions on open grids.

Moving to one of the 26 neighbours costs ``resolution * sqrt(number of axes changed)`` [m].
Closed nodes are never reopened: with ``dijkstra``, ``astar`` and ``octile`` (consistent
heuristics) the first expansion of a node is already optimal; with ``adaptive`` reopening would
only undo the speed-up the paper asks for.

Energy-aware cost
-----------------
With a climb weight ``w_u`` and a descent weight ``w_d`` (each >= 0) a step ``d`` costs its
length plus ``(w - 1)`` times its vertical length, ``w`` the weight of its direction::

    c(d) = delta * (|d| + (w_u - 1) [d_z = +1] + (w_d - 1) [d_z = -1]),

which is >= 0 (a vertical step costs ``w * delta``) and, with both weights 1, the paper's length
(eq. 15). The heuristics become (in cells; ``a``, ``b`` the horizontal index differences to the
goal, ``z`` the signed vertical one, goal minus node, and ``oct(p, q, r)`` the octile distance
above):

``octile`` (and ``weighted``, w times it)
    ``h = omega * |z| + min over m in M of [oct(a, b, m) + S * (m - |z|) / 2]``, with
    ``omega = w_u - 1`` if the goal is above (``z > 0``), ``w_d - 1`` if below,
    ``S = w_u + w_d - 2`` and ``M = {|z|} u {a, b if above |z|}``; when
    ``S >= -2 (sqrt(3) - sqrt(2))`` only ``m = |z|`` counts and ``h = oct(a, b, |z|) +
    omega |z|``, the exact obstacle-free cost.

    *Derivation.* A path with ``U`` up and ``D`` down steps (``U - D = z``) has length at least
    ``oct(a, b, U + D)``: flipping its down steps to up steps keeps every step's length and gives
    a path to the displacement ``(a, b, U + D)``, whose shortest length is the octile distance.
    So its cost is at least ``G(U, D) = oct(a, b, U + D) + omega_u U + omega_d D``; for
    ``z >= 0`` put ``U = |z| + k``, ``D = k``: ``G = oct(a, b, |z| + 2k) + omega |z| + S k``.
    ``oct(a, b, m)`` is convex and piecewise linear in ``m`` (slopes ``sqrt(3) - sqrt(2)``,
    ``sqrt(2) - 1`` and 1, breaking at ``m = b`` and ``m = a``), so over real ``k >= 0`` the
    minimum is at ``m = |z|`` or at a breakpoint above it: that minimum is ``h``. Extra up-down
    pairs pay (a sawtooth) only when ``w_u + w_d < 2 + 2 sqrt(2) - 2 sqrt(3)`` (about 1.36);
    the formula covers it.

    *Admissible*: every path's cost is ``G(U, D)`` or more for its own integer ``U, D``, and
    ``h`` is the minimum of ``G`` over a superset.

    *Consistent*: let ``x' = x - d`` be the neighbour's displacement after step ``d`` and
    ``(U', D')`` the minimiser for ``x'``. Then ``U = U' + [d_z = 1]``, ``D = D' + [d_z = -1]``
    is feasible for ``x`` and ``h(x) <= G(U, D) = oct(a, b, U' + D' + |d_z|) + omega_u U'
    + omega_d D' + c(d) - |d|``. The octile distance is a norm, so
    ``oct(a, b, U' + D' + |d_z|) <= oct(a - d_x, b - d_y, U' + D') + oct(d) `` with
    ``oct(d) = |d|`` for a unit step; hence ``h(x) <= h(x') + c(d)``. Also ``h(goal) = 0``
    (``G(k, k) = (2 + S) k >= 0``) and ``h >= 0`` (``oct(a, b, m) >= m`` gives
    ``G >= w_u U + w_d D``). With both weights 1 it is the octile distance, bit for bit.
``astar``
    The Euclidean distance times ``kappa = min(1, w_u, w_d)``: a path's cost is at least
    ``kappa`` times its length (``c(d) >= kappa |d|`` for every step, the vertical step being
    the worst ratio), and its length at least the Euclidean distance; consistency follows from
    the triangle inequality the same way. ``kappa = 1`` (the paper's A*) whenever both weights
    are >= 1.
``adaptive``
    Unchanged: the paper's definition, on lengths.

Unknown-space cost
------------------
With a mask of the nodes that lie in unknown space (space the map never observed, see
:mod:`uav_global_planner.core.map.unknown_space`) and a rate ``c >= 0`` [m per m], a step also
costs ``c`` times its length for each of its two end nodes in unknown space, halved::

    c_u(d) = c(d) + c * |d| * delta * (u(a) + u(b)) / 2,

so a path pays ``c`` per metre it runs between unknown nodes. The extra cost is >= 0, so every
heuristic above keeps its guarantees (admissible and consistent where it was).

``dijkstra`` (h = 0) keeps its open list in Dial's buckets whenever every step costs more than 0
(:mod:`uav_global_planner.core.search.dial`): buckets as wide as the cheapest step, each
expanded in the order of its pushes, with no heap; the costs are the same optimum, the path one
of the optimal ones.

Implementation: a kernel compiled by numba (:mod:`uav_global_planner.core.jit`) works on flat
C-order node numbers. The per-node arrays (cost g, parent direction, heap position, generation
stamp) and the heap live in a :class:`SearchWorkspace` and are allocated once; a query bumps a
generation counter instead of clearing them, so a query costs nothing proportional to the grid
size. The open list is an indexed binary heap with decrease-key whose keys are ordered by
(f, h, node number), which makes the result independent of anything but the inputs. The kernel
runs at most a given number of expansions per call and can be resumed, so the time budget is
checked in Python between chunks (numba code cannot read the clock).

One module, though long (about 1000 lines): the compiled kernel, its heap, the heuristics and
the workspaces that hold its arrays for both grid layouts are compiled and tuned together;
Dial's kernel, its bucket queue and the neighbour loop both kernels share are the module
``dial``.
"""

from dataclasses import dataclass
import math
import threading
import time
from typing import Callable, Dict, List, Optional, Tuple, Union

import numpy as np

from uav_global_planner.core.checks import check_non_negative, check_positive
from uav_global_planner.core.errors import (GoalOccupiedError, InvalidInputError, NoValidPathError,
                                            PlanningError, PlanningTimeoutError,
                                            StartOccupiedError)
from uav_global_planner.core.jit import njit
from uav_global_planner.core.map.sparse_grid import (BRICK, BRICK_BITS, BRICK_NODES, FULL,
                                                     SparseMask)
from uav_global_planner.core.search import dial
from uav_global_planner.core.search.bounded_kernel import lazy_zeros, octile as _octile_cells
from uav_global_planner.core.settings import check_setting

_H_ZERO = 0
_H_EUCLIDEAN = 1
_H_ADAPTIVE = 2
_H_OCTILE = 3
_H_WEIGHTED = 4

#: Heuristic code of each algorithm name accepted by :func:`search`.
ALGORITHM_CODES: Dict[str, int] = {'dijkstra': _H_ZERO, 'astar': _H_EUCLIDEAN,
                                   'adaptive': _H_ADAPTIVE, 'octile': _H_OCTILE,
                                   'weighted': _H_WEIGHTED}

#: Default suboptimality bound w of ``weighted``: its path costs at most w times the optimum.
DEFAULT_WEIGHT = 1.05

# Kernel return codes.
_FOUND = 0
_EXHAUSTED = 1
_PAUSED = 2
_GROW = 3

# Record bricks and heap entries a search on a block-sparse grid starts with; both double when
# a search needs more.
_FIRST_BRICKS = 1024
_FIRST_HEAP = 1 << 16
_BRICK_MASK = BRICK - 1
# Smallest page of the operating system [bytes].
_PAGE_BYTES = 4096

# Slots of the kernel's int64 state array, kept between resumed calls.
_S_GEN = 0        # current generation stamp
_S_SIZE = 1       # number of entries in the heap
_S_EXPANDED = 2   # nodes closed so far, goal included
_S_GOAL = 3       # flat node number of the goal
_S_CODE = 4       # heuristic code
_S_NX = 5         # grid shape
_S_NY = 6
_S_NZ = 7
_S_GI = 8         # goal index (i, j, k)
_S_GJ = 9
_S_GK = 10
_S_USED = 11     # brick slots of records in use (block-sparse grids)
_STATE_SIZE = 12

# Expansions per kernel call when a time budget must be checked between calls: about 4 to 8 ms
# of work, so the budget is overshot by at most that much, while the call overhead (~10 us)
# stays negligible.
_CHUNK = 20_000

# Parent code of the start node; 0..25 are directions into the node.
_NO_PARENT = 26

# Per-node arrays from this size up are memory maps without huge pages (see _lazy_zeros) [bytes].
_LAZY_BYTES = 1 << 24
# Dense per-node arrays and heap up to this size in all are committed when the workspace is
# made (a few hundred page faults there, not in the first search) [bytes].
_COMMIT_BYTES = 1 << 24

# Node numbers, heap positions and the heap itself are int32 (half the memory of int64).
_MAX_NODES = 2 ** 31 - 1

# Each node owns a 16-byte record, seen both as float64[2] (slot 0: cost g [m]) and as int32[4]
# (slot 2: generation stamp, slot 3: heap position, -1 once closed). Keeping the three together
# costs one cache line per neighbour instead of three: large searches are memory bound.
_STAMP_SLOT = 2
_HEAP_SLOT = 3

# Generation stamps are int32; past this many queries the stamps are cleared once.
_MAX_GENERATION = 2 ** 31 - 1

_SQRT2 = math.sqrt(2.0)
_SQRT3 = math.sqrt(3.0)
# Below this sum of (weight - 1) over climbing and descending, up-down pairs of steps can cost
# less than the level distance they cover (module notes): -2 (sqrt(3) - sqrt(2)).
_SAWTOOTH_PAYS = -2.0 * (_SQRT3 - _SQRT2)

# Stand-ins for the arrays of the layout a kernel call does not use: the dense mask, and the
# block-sparse mask (brick table, pool), brick counts and record slots.
_NO_MASK = np.zeros(0, dtype=np.bool_)
_NO_TABLE = np.zeros(0, dtype=np.int32)
_NO_POOL = np.zeros((0, BRICK_NODES), dtype=np.bool_)
_NO_BRICKS = np.zeros(3, dtype=np.int64)
_NO_SLOTS = np.zeros(0, dtype=np.int32)

# Slots of the kernel's float64 parameter array.
_P_RESOLUTION = 0    # delta [m]
_P_ETA = 1           # adaptive threshold [m]
_P_WEIGHT = 2        # w of weighted A*
_P_OMEGA_UP = 3      # climb weight - 1
_P_OMEGA_DOWN = 4    # descent weight - 1
_P_KAPPA = 5         # scale of the Euclidean heuristic
_P_INV_WIDTH = 6     # 1 / the bucket width of Dial's queue [1/m]
_PARAMS_SIZE = 7

# Dial's kernel for uniform-cost search when every step costs more than 0 (module notes);
# False keeps ``dijkstra`` on the heap of the other algorithms.
_DIAL = True
# Bucket width of Dial's kernel, relative to the cheapest step: a hair less, so rounding in
# the bucket number never puts a neighbour in its parent's bucket.
_DIAL_WIDTH = 1.0 - 1e-7
# Buckets of Dial's ring: more than the costliest step over the bucket width (a key beyond
# the ring waits in its last bucket, exact but slower).
_DIAL_RING = 64
# Most buckets of Dial's ring.
_DIAL_MAX_RING = 1 << 16

# Half the extra cost per step of a node in unknown space, none: the kernel's stand-in.
_NO_UNKNOWN_STEP = np.zeros(0, dtype=np.float64)


def _directions() -> np.ndarray:
    """The 26 neighbour offsets (di, dj, dk), shape (26, 3) int64, in lexicographic order."""
    steps = [(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)
             if (a, b, c) != (0, 0, 0)]
    return np.array(steps, dtype=np.int64)


_DIRECTIONS = _directions()
_DIRECTIONS.setflags(write=False)
_BRICK_STEP = dial.brick_steps(_DIRECTIONS)
_BRICK_STEP.setflags(write=False)
# Length of each move in cells: sqrt(number of axes changed), i.e. 1, sqrt(2) or sqrt(3).
_STEP_LENGTH = np.sqrt(np.abs(_DIRECTIONS).sum(axis=1).astype(np.float64))
_STEP_LENGTH.setflags(write=False)
# 1.0 where a move climbs (dk = +1), resp. descends (dk = -1), else 0.0.
_UP = (_DIRECTIONS[:, 2] > 0).astype(np.float64)
_DOWN = (_DIRECTIONS[:, 2] < 0).astype(np.float64)


@dataclass(frozen=True, eq=False)
class SearchResult:
    """Outcome of a successful search.

    Attributes
    ----------
    path_indices : numpy.ndarray, shape (N, 3), int64
        Node indices (i, j, k) from the start node (first) to the goal node (last); consecutive
        nodes are 26-neighbours.
    cost_m : float
        Sum of the step costs along the path [m]: its length, or with climb and descent weights
        other than 1 the energy-aware cost (see the module notes).
    expanded_nodes : int
        Nodes closed (popped from the open list and expanded), the goal included.
    search_time_s : float
        Wall-clock time of the search [s].
    """

    path_indices: np.ndarray
    cost_m: float
    expanded_nodes: int
    search_time_s: float


@njit
def _energy_octile(di, dj, dk, omega_up, omega_down):
    """Lower bound of the energy-aware cost [cells] (module notes): ``di, dj`` absolute,
    ``dk`` signed (goal minus node, > 0: the goal is above)."""
    v = abs(dk)
    omega = omega_up if dk > 0 else omega_down
    best = _octile_cells(di, dj, v) + omega * v
    pair = omega_up + omega_down
    if pair < _SAWTOOTH_PAYS:
        for m in (di, dj):
            if m > v:
                best = min(best, _octile_cells(di, dj, m) + omega * v + 0.5 * pair * (m - v))
    return best


@njit
def _heuristic(code, di, dj, dk, resolution, eta, weight, omega_up=0.0, omega_down=0.0,
               kappa=1.0):
    """Heuristic h [m] for absolute index differences (di, dj) to the goal and the vertical one
    dk, signed (goal minus node; its sign only matters with climb and descent weights).

    ``omega_up``, ``omega_down`` are the climb and descent weights minus 1 and ``kappa`` the
    scale of the Euclidean heuristic (module notes); the defaults give the length heuristics.
    """
    if code == _H_ZERO:
        return 0.0
    if code == _H_OCTILE or code == _H_WEIGHTED:
        octile = resolution * _energy_octile(di, dj, dk, omega_up, omega_down)
        return octile * weight if code == _H_WEIGHTED else octile
    vertical = abs(dk)
    euclidean = resolution * math.sqrt(di * di + dj * dj + vertical * vertical)
    if code == _H_ADAPTIVE:
        if euclidean > eta:
            return resolution * (di + dj + vertical)
        return euclidean
    return euclidean * kappa


@njit
def _precedes(f_a, h_a, node_a, f_b, h_b, node_b):
    """Heap order: lower f first, then lower h (nearer the goal), then lower node number."""
    if f_a != f_b:
        return f_a < f_b
    if h_a != h_b:
        return h_a < h_b
    return node_a < node_b


@njit(inline='always')
def _move_entry(heap_node, heap_rec, heap_key, node_int, source, target):
    """Move the heap entry at slot ``source`` to slot ``target`` and record its new slot.

    Inlined into the sift loops by numba (``inline='always'``), so sharing it costs no call.
    """
    moved = heap_node[source]
    heap_node[target] = moved
    rec_moved = np.int64(moved)
    if heap_rec is not None:
        rec_moved = np.int64(heap_rec[source])
        heap_rec[target] = rec_moved
    heap_key[2 * target] = heap_key[2 * source]
    heap_key[2 * target + 1] = heap_key[2 * source + 1]
    node_int[4 * rec_moved + _HEAP_SLOT] = target


@njit
def _sift_up(heap_node, heap_rec, heap_key, node_int, pos, node, rec, f, h):
    """Place ``node`` (record number ``rec``) with key (f, h) at heap slot ``pos`` or above it.

    Each heap entry is a node number, its key and, on the block-sparse layout, its record
    number (``heap_rec``); on the dense layout ``heap_rec`` is None, a record number being the
    node number (numba compiles each layout's version without the test).
    """
    while pos > 0:
        up = (pos - 1) >> 1
        above = heap_node[up]
        if not _precedes(f, h, node, heap_key[2 * up], heap_key[2 * up + 1], above):
            break
        _move_entry(heap_node, heap_rec, heap_key, node_int, up, pos)
        pos = up
    heap_node[pos] = node
    if heap_rec is not None:
        heap_rec[pos] = rec
    heap_key[2 * pos] = f
    heap_key[2 * pos + 1] = h
    node_int[4 * np.int64(rec) + _HEAP_SLOT] = pos


@njit
def _pop_fill(heap_node, heap_rec, heap_key, node_int, size, node, rec, f, h):
    """Refill the root hole of a heap of ``size`` entries with ``node`` (record ``rec``) of key
    (f, h).

    Floyd's variant: the hole first walks down to a leaf along the preferred children (one
    comparison per level instead of two), then the element, which came from the bottom and so
    rarely climbs far, is sifted up from there. This is the most frequent heap operation.
    """
    pos = 0
    while True:
        child = 2 * pos + 1
        if child >= size:
            break
        right = child + 1
        if right < size and _precedes(heap_key[2 * right], heap_key[2 * right + 1],
                                      heap_node[right], heap_key[2 * child],
                                      heap_key[2 * child + 1], heap_node[child]):
            child = right
        _move_entry(heap_node, heap_rec, heap_key, node_int, child, pos)
        pos = child
    _sift_up(heap_node, heap_rec, heap_key, node_int, pos, node, rec, f, h)


@njit
def _expand(blocked, mask_table, mask_pool, bricks, slots, node_g, node_int, parent, heap_node,
            heap_rec, heap_key, queue, directions, brick_step, delta, step_cost, unknown,
            unknown_table, unknown_pool, unknown_step, state, params, max_pops):
    """Run at most ``max_pops`` expansions of the search described by ``state``.

    One loop for every algorithm, two open lists and two record layouts; numba compiles one
    version for each combination in use, the tests of ``queue is None`` and ``slots is None``
    resolved at compile time, so each version holds only its own code:

    - The open list: the indexed binary heap (``queue`` None; ``heap_node``, ``heap_rec``,
      ``heap_key``) ordered by (f, h, node number), or Dial's buckets (``queue`` the arrays of
      :func:`~uav_global_planner.core.search.dial.new_queue`: chunk nodes, chunk records, chunk
      meta, bucket ends, queue state), which serve ``dijkstra`` when every step costs more
      than 0 (h = 0; ``params[_P_INV_WIDTH]`` is 1 over the bucket width [1/m]); the heap
      arrays are then unused.
    - The layout: dense (``slots`` None): ``blocked`` is the flat mask and a node's record number
      is its node number; ``heap_rec`` is None. Block-sparse (``blocked`` empty): the mask is
      ``mask_table`` and ``mask_pool`` and the records live in bricks of 8 x 8 x 8 nodes; a
      brick of records gets a slot (``slots[brick]``, in the order first reached) when the
      search first reaches one of its nodes; ``brick_step`` holds the record offset of each
      direction inside a brick. A node inside its brick (off its faces) has all 26 neighbours
      in that brick, which is looked up once.

    Returns ``_FOUND`` when the goal was closed, ``_EXHAUSTED`` when the open list is empty,
    ``_PAUSED`` when ``max_pops`` ran out and ``_GROW``, without expanding, when the record pool
    (block-sparse) might not hold the bricks of one more expansion (8), or the open list its 26
    neighbours (the heap of a block-sparse search; Dial's chunks); the caller grows them and
    resumes. ``state`` (and Dial's queue state) are updated so the call can be resumed. Node
    records are only meaningful when their stamp equals the current generation; slot 3 of a
    record is -1 once the node is closed (the heap position, or 0, while it is open).

    ``unknown_step`` (26 values, or None for none) is half the extra cost of each step per end
    node in unknown space (module notes); the mask is ``unknown`` (dense, flat) or
    ``unknown_table`` and ``unknown_pool`` (block-sparse, the bricks of ``bricks``).
    """
    generation = np.int32(state[_S_GEN])
    size = state[_S_SIZE]
    goal = state[_S_GOAL]
    code = state[_S_CODE]
    nx = state[_S_NX]
    ny = state[_S_NY]
    nz = state[_S_NZ]
    gi = state[_S_GI]
    gj = state[_S_GJ]
    gk = state[_S_GK]
    used = state[_S_USED]
    resolution = params[_P_RESOLUTION]
    eta = params[_P_ETA]
    weight = params[_P_WEIGHT]
    omega_up = params[_P_OMEGA_UP]
    omega_down = params[_P_OMEGA_DOWN]
    kappa = params[_P_KAPPA]
    inv_width = params[_P_INV_WIDTH]
    capacity = parent.shape[0] // BRICK_NODES
    heap_capacity = heap_node.shape[0]
    by = bricks[1]
    bz = bricks[2]
    nyz = ny * nz
    # Compiled without the unknown-space charges when there are none (``unknown_step`` None).
    charged = unknown_step is not None
    records = slots is not None
    # Dial's queue, kept in locals while the loop runs (unused with the heap).
    cur = mask = free = top = avail = reading = taken = chunks = np.int64(0)
    if queue is not None:
        qstate = queue[4]
        cur = qstate[dial.Q_CUR]
        mask = qstate[dial.Q_MASK]
        free = qstate[dial.Q_FREE]
        top = qstate[dial.Q_TOP]
        avail = qstate[dial.Q_AVAIL]
        reading = qstate[dial.Q_CHUNK]
        taken = qstate[dial.Q_POS]
        chunks = queue[2].shape[0] // 2
    pops = 0
    status = _PAUSED
    while True:
        if queue is None:
            if size == 0:
                status = _EXHAUSTED
                break
            if pops >= max_pops:
                break
            node = np.int64(heap_node[0])
            rec_node = node
            if slots is not None:
                if used + 8 > capacity or size + 26 > heap_capacity:
                    status = _GROW
                    break
                rec_node = np.int64(heap_rec[0])
            size -= 1
            if size > 0:
                last = heap_node[size]
                rec_last = np.int64(last)
                if slots is not None:
                    rec_last = np.int64(heap_rec[size])
                _pop_fill(heap_node, heap_rec, heap_key, node_int, size, last, rec_last,
                          heap_key[2 * size], heap_key[2 * size + 1])
        else:
            if pops >= max_pops:
                break
            if reading < 0 or taken == queue[2][2 * reading + 1]:
                # The chunk is read: the next one of the bucket, or of the next bucket.
                reading, cur, free, avail = dial.next_chunk(queue[2], queue[3], reading, cur,
                                                            mask, free, avail, chunks)
                taken = np.int64(0)
                if reading < 0:
                    status = _EXHAUSTED
                    break
                continue
            if avail < 27 or (slots is not None and used + 8 > capacity):
                status = _GROW
                break
            entry = reading * dial.CHUNK + taken
            taken += 1
            node = np.int64(queue[0][entry])
            rec_node = node
            if slots is not None:
                rec_node = np.int64(queue[1][entry])
            if node_int[4 * rec_node + _HEAP_SLOT] < 0:
                # A stale entry: the node was reached again at a lower cost and expanded since.
                continue
            bucket = np.int64(node_g[2 * rec_node] * inv_width)
            if bucket > cur:
                # A cost beyond the ring when it was pushed: place it again.
                free, top, avail = dial.push(queue[0], queue[1], queue[2], queue[3], cur, mask,
                                             free, top, avail, bucket, node, rec_node, records)
                continue
        node_int[4 * rec_node + _HEAP_SLOT] = -1
        pops += 1
        if node == goal:
            status = _FOUND
            break
        i = node // nyz
        rest = node - i * nyz
        j = rest // nz
        k = rest - j * nz
        g_node = node_g[2 * rec_node]
        u_node = 0.0
        if charged:
            u_node = dial.unknown_at(unknown, unknown_table, unknown_pool, node, i, j, k, by, bz)
        # Dense: a node off the grid's faces needs no bounds checks. Block-sparse: a node off
        # its brick's faces has its 26 neighbours in the same brick, whose mask and records are
        # looked up once.
        fast = False
        inside = False
        kind_node = 0
        base = np.int64(0)
        local_node = np.int64(0)
        if slots is None:
            fast = 0 < i < nx - 1 and 0 < j < ny - 1 and 0 < k < nz - 1
        else:
            li = i & _BRICK_MASK
            lj = j & _BRICK_MASK
            lk = k & _BRICK_MASK
            inside = (0 < li < _BRICK_MASK and 0 < lj < _BRICK_MASK and 0 < lk < _BRICK_MASK
                      and i + 1 < nx and j + 1 < ny and k + 1 < nz)
            if inside:
                local_node = (li * BRICK + lj) * BRICK + lk
                base = rec_node - local_node
                kind_node = mask_table[((i >> BRICK_BITS) * by + (j >> BRICK_BITS)) * bz
                                       + (k >> BRICK_BITS)]
        for d in range(26):
            ni = i + directions[d, 0]
            nj = j + directions[d, 1]
            nk = k + directions[d, 2]
            neighbour = node + delta[d]
            rec = neighbour
            if inside:
                local = local_node + brick_step[d]
                if kind_node >= 0 and mask_pool[kind_node, local]:
                    continue
                rec = base + local
            elif fast:
                if blocked[neighbour]:
                    continue
            elif ni < 0 or ni >= nx or nj < 0 or nj >= ny or nk < 0 or nk >= nz:
                continue
            elif slots is not None:
                brick = ((ni >> BRICK_BITS) * by + (nj >> BRICK_BITS)) * bz + (nk >> BRICK_BITS)
                local = (((ni & _BRICK_MASK) * BRICK) + (nj & _BRICK_MASK)) * BRICK + (
                    nk & _BRICK_MASK)
                kind = mask_table[brick]
                if kind == FULL:
                    continue
                if kind >= 0 and mask_pool[kind, local]:
                    continue
                slot = np.int64(slots[brick])
                if slot < 0:
                    slot = used
                    used += 1
                    slots[brick] = slot
                rec = slot * BRICK_NODES + local
            elif blocked[neighbour]:
                continue
            g_new = g_node + step_cost[d]
            if charged:
                u_next = dial.unknown_at(unknown, unknown_table, unknown_pool, neighbour, ni, nj,
                                         nk, by, bz)
                g_new += (u_node + u_next) * unknown_step[d]
            at = 4 * rec
            fresh = node_int[at + _STAMP_SLOT] != generation
            held = np.int64(0)
            g_old = 0.0
            if fresh:
                # First visit in this query: the record is stale, overwrite it.
                node_int[at + _STAMP_SLOT] = generation
            else:
                held = np.int64(node_int[at + _HEAP_SLOT])
                g_old = node_g[2 * rec]
                if held < 0 or g_new >= g_old:
                    continue
            node_g[2 * rec] = g_new
            parent[rec] = d
            if queue is None:
                if fresh:
                    h = _heuristic(code, abs(ni - gi), abs(nj - gj), gk - nk, resolution, eta,
                                   weight, omega_up, omega_down, kappa)
                    _sift_up(heap_node, heap_rec, heap_key, node_int, size, neighbour, rec,
                             g_new + h, h)
                    size += 1
                else:
                    # Decrease-key: h is kept in the heap, so it is not recomputed.
                    h = heap_key[2 * held + 1]
                    _sift_up(heap_node, heap_rec, heap_key, node_int, held, neighbour, rec,
                             g_new + h, h)
            else:
                bucket = np.int64(g_new * inv_width)
                if fresh:
                    node_int[at + _HEAP_SLOT] = 0
                elif bucket >= np.int64(g_old * inv_width):
                    # Still in the bucket of its entry.
                    continue
                free, top, avail = dial.push(queue[0], queue[1], queue[2], queue[3], cur, mask,
                                             free, top, avail, bucket, neighbour, rec, records)
    if queue is not None:
        qstate = queue[4]
        qstate[dial.Q_CUR] = cur
        qstate[dial.Q_FREE] = free
        qstate[dial.Q_TOP] = top
        qstate[dial.Q_AVAIL] = avail
        qstate[dial.Q_CHUNK] = reading
        qstate[dial.Q_POS] = taken
    state[_S_SIZE] = size
    state[_S_EXPANDED] += pops
    state[_S_USED] = used
    return status


@njit
def _record(node, ny, nz, bricks, slots):
    """Record number of a node: the node number on the dense layout (``slots`` empty), else its
    place in its brick's slot, which it must have."""
    if slots.shape[0] == 0:
        return np.int64(node)
    nyz = ny * nz
    i = node // nyz
    rest = node - i * nyz
    j = rest // nz
    k = rest - j * nz
    brick = ((i >> BRICK_BITS) * bricks[1] + (j >> BRICK_BITS)) * bricks[2] + (k >> BRICK_BITS)
    local = (((i & _BRICK_MASK) * BRICK) + (j & _BRICK_MASK)) * BRICK + (k & _BRICK_MASK)
    return np.int64(slots[brick]) * BRICK_NODES + local


@njit
def _trace(goal, parent, node_g, delta, ny, nz, bricks, slots):
    """The path from the start to ``goal``, following the parent directions, as node indices
    (i, j, k), shape (N, 3), and the goal's cost [m]."""
    length = 1
    node = goal
    while parent[_record(node, ny, nz, bricks, slots)] != _NO_PARENT:
        node -= delta[parent[_record(node, ny, nz, bricks, slots)]]
        length += 1
    path = np.empty((length, 3), dtype=np.int64)
    nyz = ny * nz
    node = goal
    for slot in range(length - 1, -1, -1):
        i = node // nyz
        rest = node - i * nyz
        path[slot, 0] = i
        path[slot, 1] = rest // nz
        path[slot, 2] = rest - (rest // nz) * nz
        if slot > 0:
            node -= delta[parent[_record(node, ny, nz, bricks, slots)]]
    return path, node_g[2 * _record(goal, ny, nz, bricks, slots)]


class SearchWorkspace:
    """Reusable search memory for one occupancy grid.

    On a dense mask (a numpy bool array) the per-node arrays (17 bytes per node: a 16-byte
    record of cost, stamp and heap position, and a parent byte) and the heap (20 bytes per
    entry, committed by the operating system only as far as the heap grows) are allocated once
    here and reused by every :meth:`search`; expect the per-node arrays to be fully resident
    after a few queries (about 105 MB at 6.1 million nodes).

    On a block-sparse mask (:class:`~uav_global_planner.core.map.sparse_grid.SparseMask`) the same
    17-byte records live in bricks of 8 x 8 x 8 nodes, given a slot of a pool when a search
    first reaches the brick; each query starts with an empty brick table (4 bytes a brick) and
    reuses the pool, which, like the heap (24 bytes an entry there), doubles when a search needs
    more. Memory then follows what the searches touch (about 8.7 kB per brick reached), not
    the grid's volume, and a first query commits only the pages it writes.

    Dial's queue (``dijkstra``) keeps its open list apart (8 bytes an entry, in chunks of
    1024; about the frontier of a search, not the grid), doubling when a search needs more.

    Searches on one workspace are serialised by a lock; use one workspace per thread to search
    in parallel.

    Parameters
    ----------
    blocked : numpy.ndarray of bool, shape (Nx, Ny, Nz), or SparseMask
        True where a node is unsafe. The workspace keeps a reference (a copy only if the array is
        not C-contiguous), so in-place edits of a C-contiguous array are seen by later searches.

    Attributes
    ----------
    shape : tuple of int
        (Nx, Ny, Nz), fixed for the life of the workspace.

    Raises
    ------
    InvalidInputError
        If ``blocked`` is not a 3D bool array (or a SparseMask) with at least one node per axis
        and fewer than 2**31 nodes.
    """

    def __init__(self, blocked: Union[np.ndarray, SparseMask]) -> None:
        self._blocked = _checked_grid(blocked)
        self.shape = tuple(int(n) for n in self._blocked.shape)
        nx, ny, nz = self.shape
        strides = np.array([ny * nz, nz, 1], dtype=np.int64)
        self._delta = _DIRECTIONS @ strides
        self._state = np.zeros(_STATE_SIZE, dtype=np.int64)
        self._state[_S_NX:_S_NZ + 1] = self.shape
        self._params = np.zeros(_PARAMS_SIZE, dtype=np.float64)
        self._step_cost_key: Tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._step_cost = _STEP_LENGTH
        self._generation = 0
        self._lock = threading.Lock()
        self._sparse = False
        # Record number of each heap entry (block-sparse layout; None on the dense one).
        self._heap_rec: Optional[np.ndarray] = None
        # Dial's queue (dial module), the open list of dijkstra; it grows as a search needs.
        (self._q_node, self._q_rec, self._q_meta, self._q_ends,
         self._qstate) = dial.new_queue(dial.FIRST_CHUNKS, _DIAL_RING)
        self._use(self._blocked)

    def _use(self, blocked: Union[np.ndarray, SparseMask]) -> None:
        """Search ``blocked``, (re)allocating the records when the layout changes."""
        sparse = isinstance(blocked, SparseMask)
        first = not hasattr(self, '_node_g')
        self._blocked = blocked
        if sparse:
            self._flat_blocked = None
        else:
            self._flat_blocked = blocked.reshape(-1)  # type: ignore[union-attr]
        if not first and sparse == self._sparse:
            return
        self._sparse = sparse
        size = int(np.prod(self.shape))
        if sparse:
            self._bricks = np.asarray(blocked.bricks, dtype=np.int64)  # type: ignore
            self._slots = np.full(int(np.prod(self._bricks)), -1, dtype=np.int32)
            self._node_g = np.zeros(2 * _FIRST_BRICKS * BRICK_NODES, dtype=np.float64)
            self._parent = np.zeros(_FIRST_BRICKS * BRICK_NODES, dtype=np.int8)
            self._heap_node = np.zeros(_FIRST_HEAP, dtype=np.int32)
            self._heap_rec = np.zeros(_FIRST_HEAP, dtype=np.int32)
            self._heap_key = np.zeros(2 * _FIRST_HEAP, dtype=np.float64)
            # Commit the first pool now (about 10 MB), so that a first query does not pay the
            # page faults of its records.
            _commit_pages(self._node_g, self._parent, self._heap_node, self._heap_rec,
                          self._heap_key)
        else:
            # Large np.zeros / np.empty arrays are fresh zero pages: memory is only committed
            # where a search touches it. Zeroed records carry stamp 0, which no query uses.
            self._node_g = _lazy_zeros(2 * size, np.float64)
            self._parent = _lazy_zeros(size, np.int8)
            # The heap holds each node at most once, so `size` entries always suffice; an entry
            # is a node number and its key (f, h).
            self._heap_node = _lazy_zeros(size, np.int32)
            self._heap_key = _lazy_zeros(2 * size, np.float64)
            self._heap_rec = None
            self._bricks = _NO_BRICKS
            self._slots = _NO_SLOTS
            arrays = (self._node_g, self._parent, self._heap_node, self._heap_key)
            if sum(array.nbytes for array in arrays) <= _COMMIT_BYTES:
                _commit_pages(*arrays)
        self._node_int = self._node_g.view(np.int32)

    @property
    def blocked(self) -> Union[np.ndarray, SparseMask]:
        """The occupancy grid searched, shape (Nx, Ny, Nz)."""
        return self._blocked

    @property
    def record_bytes(self) -> int:
        """Memory of the search records, heap and brick table as allocated [bytes]."""
        arrays: List[np.ndarray] = [self._node_g, self._parent, self._heap_node, self._heap_key]
        if self._heap_rec is not None:
            arrays += [self._heap_rec, self._slots]
        arrays += [self._q_node, self._q_rec, self._q_meta, self._q_ends]
        return int(sum(a.nbytes for a in arrays))

    def _kernel_masks(self) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The mask as :func:`_expand` takes it: (flat dense mask, brick table, brick pool),
        the arrays of the other layout empty."""
        if self._flat_blocked is not None:
            return self._flat_blocked, _NO_TABLE, _NO_POOL
        mask = self._blocked
        return _NO_MASK, mask.table, mask.pool  # type: ignore[union-attr]

    def _is_blocked(self, node: int) -> bool:
        if self._sparse:
            return self._blocked[tuple(self._unravel(node))]
        return bool(self._flat_blocked[node])  # type: ignore[index]

    def _grow(self, dial_queue: bool = False) -> None:
        """Double the record pool and / or the heap of a block-sparse search, and the chunks
        of Dial's queue when ``dial_queue`` (its kernel runs) and it might run short."""
        used = int(self._state[_S_USED])
        if (used + 8) * BRICK_NODES > len(self._parent):
            bricks = 2 * len(self._parent) // BRICK_NODES
            node_g = np.zeros(2 * bricks * BRICK_NODES, dtype=np.float64)
            node_g[:2 * used * BRICK_NODES] = self._node_g[:2 * used * BRICK_NODES]
            parent = np.zeros(bricks * BRICK_NODES, dtype=np.int8)
            parent[:used * BRICK_NODES] = self._parent[:used * BRICK_NODES]
            self._node_g, self._parent = node_g, parent
            self._node_int = node_g.view(np.int32)
        size = int(self._state[_S_SIZE])
        if self._heap_rec is not None and size + 26 > len(self._heap_node):
            entries = 2 * len(self._heap_node)
            heap_node = np.zeros(entries, dtype=np.int32)
            heap_node[:size] = self._heap_node[:size]
            heap_rec = np.zeros(entries, dtype=np.int32)
            heap_rec[:size] = self._heap_rec[:size]
            heap_key = np.zeros(2 * entries, dtype=np.float64)
            heap_key[:2 * size] = self._heap_key[:2 * size]
            self._heap_node, self._heap_rec, self._heap_key = heap_node, heap_rec, heap_key
        if dial_queue and self._qstate[dial.Q_AVAIL] < 27:
            (self._q_node, self._q_rec, self._q_meta) = dial.grown(
                self._q_node, self._q_rec, self._q_meta, self._qstate)

    def set_blocked(self, blocked: Union[np.ndarray, SparseMask]) -> None:
        """Search another occupancy grid of the same shape, keeping the allocated memory.

        Raises
        ------
        InvalidInputError
            If ``blocked`` is not a valid grid (see the class) of shape :attr:`shape`.
        """
        grid = _checked_grid(blocked)
        if tuple(grid.shape) != self.shape:
            raise InvalidInputError(
                f'blocked must keep the workspace shape {self.shape}, got {grid.shape}')
        with self._lock:
            self._use(grid)

    def _node(self, index, name: str) -> int:
        """Flat node number of a (i, j, k) index, checked against the grid."""
        array = np.asarray(index)
        if array.shape != (3,) or array.dtype.kind not in 'iu':
            raise InvalidInputError(f'{name} must be three integers (i, j, k), got {index!r}')
        i, j, k = (int(v) for v in array)
        nx, ny, nz = self.shape
        if not (0 <= i < nx and 0 <= j < ny and 0 <= k < nz):
            raise InvalidInputError(
                f'{name} {[i, j, k]} lies outside the grid of shape {self.shape}')
        return (i * ny + j) * nz + k

    def search(self, start_index, goal_index, algorithm: str, resolution: float,
               adaptive_threshold: float, max_expansions: int = 0,
               max_time_s: float = 0.0, *, weight: float = DEFAULT_WEIGHT,
               climb_weight: float = 1.0, descent_weight: float = 1.0,
               checkpoint: Optional[Callable[[], None]] = None,
               unknown: Optional[Union[np.ndarray, SparseMask]] = None,
               unknown_cost: float = 0.0) -> SearchResult:
        """Find a path between two free nodes.

        Parameters
        ----------
        start_index, goal_index : array_like of int, shape (3,)
            Node indices (i, j, k).
        algorithm : str
            One of ``dijkstra``, ``astar``, ``adaptive``, ``octile`` (:data:`ALGORITHM_CODES`).
        resolution : float
            Node spacing delta [m], > 0; step costs and heuristics are in metres.
        adaptive_threshold : float
            eta [m], >= 0; only used by ``adaptive``.
        max_expansions : int
            Budget of expanded nodes; 0 means unlimited.
        max_time_s : float
            Budget of wall-clock time [s], checked every 20000 expansions; 0 means unlimited.
        weight : float
            Suboptimality bound w >= 1 of ``weighted`` (ignored by the others).
        climb_weight, descent_weight : float
            Energy-aware step cost [-], each >= 0: a step costs its length plus (weight - 1)
            times its vertical length (module notes); 1 and 1 give lengths.
        checkpoint : callable, optional
            Called every 20000 expansions (a few milliseconds); it raises a
            :class:`~uav_global_planner.core.errors.PlanningError` to stop the search (a
            cancelled request, a plan-wide time budget), which is re-raised with the number of
            expanded nodes.
        unknown : numpy.ndarray of bool or SparseMask, optional
            Nodes in unknown space, in the layout and shape of the searched mask.
        unknown_cost : float
            Extra cost per metre between nodes in unknown space [m/m], >= 0 (module notes);
            ignored without ``unknown``.

        Returns
        -------
        SearchResult

        Raises
        ------
        InvalidInputError
            Unknown algorithm, indices that are not three integers inside the grid, or a bad
            resolution, threshold or budget.
        StartOccupiedError, GoalOccupiedError
            If the start or goal node is blocked.
        NoValidPathError
            If every node reachable from the start was expanded without reaching the goal.
        PlanningTimeoutError
            If the expansion or time budget ran out first.
        """
        code = ALGORITHM_CODES.get(algorithm) if isinstance(algorithm, str) else None
        if code is None:
            raise InvalidInputError(
                f'algorithm must be one of {", ".join(ALGORITHM_CODES)}, got {algorithm!r}')
        start = self._node(start_index, 'start_index')
        goal = self._node(goal_index, 'goal_index')
        delta_m = check_positive('resolution', resolution, 'm', convert=False)
        budget_s = check_non_negative('max_time_s', max_time_s, 's', convert=False)
        # The settings are checked by their table entries (core/settings.py).
        eta = check_setting('adaptive_threshold', adaptive_threshold)
        budget_n = check_setting('max_expansions', max_expansions)
        w = check_setting('search_weight', weight, 'weight')
        climb = check_setting('climb_weight', climb_weight)
        descent = check_setting('descent_weight', descent_weight)
        rate = check_setting('unknown_cost', unknown_cost)

        with self._lock:
            if self._is_blocked(start):
                raise StartOccupiedError(f'start node {self._unravel(start)} is blocked')
            if self._is_blocked(goal):
                raise GoalOccupiedError(f'goal node {self._unravel(goal)} is blocked')
            began = time.perf_counter()
            self._begin(start, goal, code, delta_m, eta, w, climb, descent)
            step_cost = self._step_costs(delta_m, climb, descent)
            state = self._state
            flat, table, pool = self._kernel_masks()
            u_flat, u_table, u_pool, u_step = self._unknown_arrays(unknown, rate, delta_m)
            dial_queue = self._begin_dial(start, code, step_cost, u_step)
            while True:
                if budget_s > 0.0 or checkpoint is not None:
                    pops = _CHUNK
                else:
                    pops = _MAX_NODES
                if budget_n > 0:
                    pops = min(pops, budget_n - int(state[_S_EXPANDED]))
                # Dial's queue for the kernel, or None for the heap (its arrays may have grown).
                queue = None
                if dial_queue:
                    queue = (self._q_node, self._q_rec, self._q_meta, self._q_ends,
                             self._qstate)
                status = _expand(flat, table, pool, self._bricks,
                                 self._slots if self._sparse else None, self._node_g,
                                 self._node_int, self._parent, self._heap_node, self._heap_rec,
                                 self._heap_key, queue, _DIRECTIONS, _BRICK_STEP, self._delta,
                                 step_cost, u_flat, u_table, u_pool,
                                 u_step if len(u_step) else None, state, self._params, pops)
                if status == _GROW:
                    self._grow(dial_queue)
                    continue
                expanded = int(state[_S_EXPANDED])
                if status == _FOUND:
                    break
                if status == _EXHAUSTED:
                    raise NoValidPathError(
                        f'no path from start to goal: all {expanded} nodes reachable from the '
                        'start were expanded', expanded_nodes=expanded)
                if checkpoint is not None:
                    try:
                        checkpoint()
                    except PlanningError as error:
                        error.expanded_nodes = expanded
                        raise
                elapsed = time.perf_counter() - began
                if budget_n > 0 and expanded >= budget_n:
                    raise PlanningTimeoutError(
                        f'search ran out of its expansion budget (max_expansions = {budget_n}) '
                        f'after expanding {expanded} nodes in {elapsed:.3f} s',
                        expanded_nodes=expanded)
                if budget_s > 0.0 and elapsed >= budget_s:
                    raise PlanningTimeoutError(
                        f'search ran out of its time budget (max_time_s = {budget_s:g} s) after '
                        f'expanding {expanded} nodes in {elapsed:.3f} s', expanded_nodes=expanded)
            _, ny, nz = self.shape
            path, cost = _trace(goal, self._parent, self._node_g, self._delta, ny, nz,
                                self._bricks, self._slots)
            elapsed = time.perf_counter() - began
        return SearchResult(path_indices=path, cost_m=float(cost), expanded_nodes=expanded,
                            search_time_s=elapsed)

    def _step_costs(self, resolution: float, climb: float, descent: float) -> np.ndarray:
        """The cost of each of the 26 steps [m] (module notes), kept for the next query."""
        key = (resolution, climb, descent)
        if self._step_cost_key != key:
            cost = resolution * (_STEP_LENGTH + (climb - 1.0) * _UP + (descent - 1.0) * _DOWN)
            cost.setflags(write=False)
            self._step_cost_key, self._step_cost = key, cost
        return self._step_cost

    def _unknown_arrays(self, unknown: Optional[Union[np.ndarray, SparseMask]], rate: float,
                        resolution: float) -> Tuple[np.ndarray, np.ndarray, np.ndarray,
                                                    np.ndarray]:
        """The unknown-space mask and step charges as :func:`_expand` takes them."""
        if unknown is None or not rate > 0.0:
            return _NO_MASK, _NO_TABLE, _NO_POOL, _NO_UNKNOWN_STEP
        if isinstance(unknown, SparseMask) != self._sparse or tuple(unknown.shape) != self.shape:
            raise InvalidInputError(
                f'the unknown-space mask must have the layout and shape {self.shape} of the '
                f'searched mask, got a {type(unknown).__name__} of shape {unknown.shape}')
        step = 0.5 * rate * resolution * _STEP_LENGTH
        if isinstance(unknown, SparseMask):
            return _NO_MASK, unknown.table, unknown.pool, step
        if unknown.dtype != np.bool_:
            raise InvalidInputError('the unknown-space mask must be a bool array')
        return np.ascontiguousarray(unknown).reshape(-1), _NO_TABLE, _NO_POOL, step

    def _begin_dial(self, start: int, code: int, step_cost: np.ndarray,
                    unknown_step: np.ndarray) -> bool:
        """Put the start node on Dial's queue when it serves this query (``dijkstra``, every
        step costing more than 0) and set the bucket width; False when the heap serves it.
        Call after :meth:`_begin`."""
        if code != _H_ZERO or not _DIAL:
            return False
        cheapest = float(step_cost.min())
        if not cheapest > 0.0:
            return False
        width = cheapest * _DIAL_WIDTH
        costliest = float(step_cost.max()) + 2.0 * float(unknown_step.max(initial=0.0))
        buckets = min(math.ceil(costliest / width) + 4, _DIAL_MAX_RING)
        ring = 1 << (buckets - 1).bit_length()
        if 2 * ring > len(self._q_ends):
            self._q_ends = np.full(2 * ring, -1, dtype=np.int32)
        record = start
        if self._sparse:
            _, ny, nz = self.shape
            record = int(_record(start, ny, nz, self._bricks, self._slots))
        dial.reset(self._q_ends, self._qstate, ring, len(self._q_meta) // 2)
        dial.push_start(self._q_node, self._q_rec, self._q_meta, self._q_ends, self._qstate,
                        start, record)
        self._params[_P_INV_WIDTH] = 1.0 / width
        return True

    def _begin(self, start: int, goal: int, code: int, resolution: float, eta: float,
               weight: float, climb: float = 1.0, descent: float = 1.0) -> None:
        """Start a new generation and put the start node on the open list."""
        self._generation += 1
        if self._generation > _MAX_GENERATION:
            # Once in 2 billion queries: forget every stamp rather than let them alias.
            self._node_int[_STAMP_SLOT::4] = 0
            self._generation = 1
        gi, gj, gk = self._unravel(goal)
        si, sj, sk = self._unravel(start)
        params = self._params
        params[_P_RESOLUTION] = resolution
        params[_P_ETA] = eta
        params[_P_WEIGHT] = weight
        params[_P_OMEGA_UP] = climb - 1.0
        params[_P_OMEGA_DOWN] = descent - 1.0
        params[_P_KAPPA] = min(1.0, climb, descent)
        h = float(_heuristic(code, abs(si - gi), abs(sj - gj), gk - sk, resolution, eta,
                             weight, climb - 1.0, descent - 1.0, params[_P_KAPPA]))
        state = self._state
        state[_S_GEN] = self._generation
        state[_S_SIZE] = 1
        state[_S_EXPANDED] = 0
        state[_S_GOAL] = goal
        state[_S_CODE] = code
        state[_S_GI:_S_GK + 1] = (gi, gj, gk)
        record = start
        if self._sparse:
            # A new brick table each query; the pool's old records carry older stamps.
            self._slots.fill(-1)
            _, ny, nz = self.shape
            brick = ((si >> BRICK_BITS) * self._bricks[1] + (sj >> BRICK_BITS)) * self._bricks[2]
            self._slots[brick + (sk >> BRICK_BITS)] = 0
            state[_S_USED] = 1
            record = int(_record(start, ny, nz, self._bricks, self._slots))
        if self._heap_rec is not None:
            self._heap_rec[0] = record
        self._node_g[2 * record] = 0.0
        self._node_int[4 * record + _STAMP_SLOT] = self._generation
        self._node_int[4 * record + _HEAP_SLOT] = 0
        self._parent[record] = _NO_PARENT
        self._heap_node[0] = start
        self._heap_key[0] = h
        self._heap_key[1] = h

    def _unravel(self, node: int) -> list:
        """(i, j, k) of a flat node number, as Python ints."""
        _, ny, nz = self.shape
        return [node // (ny * nz), node // nz % ny, node % nz]


def _lazy_zeros(count: int, dtype) -> np.ndarray:
    """A zeroed array whose memory is committed page by page as it is first written.

    Large arrays come from an anonymous memory map advised against transparent huge pages:
    numpy's own allocator asks for huge pages, so the first touch of a node record would commit
    2 MiB instead of 4 KiB, and a first search on a 100 M-node grid spent seconds committing
    gigabytes it never used.
    """
    return lazy_zeros(count, dtype, _LAZY_BYTES)


def _commit_pages(*arrays: np.ndarray) -> None:
    """Write a zero into every page of the arrays (zeros already), so that the operating system
    commits their memory now rather than at a search's first touches."""
    for array in arrays:
        array.view(np.uint8)[::_PAGE_BYTES] = 0


def _checked_grid(blocked) -> Union[np.ndarray, SparseMask]:
    """``blocked`` as a C-contiguous 3D bool array (copied only if not contiguous), or the
    SparseMask itself."""
    if isinstance(blocked, SparseMask):
        if blocked.size > _MAX_NODES:
            raise InvalidInputError(
                f'blocked has {blocked.size} nodes; the search supports at most {_MAX_NODES}')
        return blocked
    if not isinstance(blocked, np.ndarray) or blocked.dtype != np.bool_:
        raise InvalidInputError('blocked must be a numpy bool array')
    if blocked.ndim != 3 or min(blocked.shape) < 1:
        raise InvalidInputError(
            f'blocked must have shape (Nx, Ny, Nz) with every axis >= 1, got {blocked.shape}')
    if blocked.size > _MAX_NODES:
        raise InvalidInputError(
            f'blocked has {blocked.size} nodes; the search supports at most {_MAX_NODES}')
    return np.ascontiguousarray(blocked)


def search(blocked: Union[np.ndarray, SparseMask], start_index, goal_index, algorithm: str,
           resolution: float, adaptive_threshold: float, max_expansions: int = 0,
           max_time_s: float = 0.0, *, weight: float = DEFAULT_WEIGHT,
           climb_weight: float = 1.0, descent_weight: float = 1.0,
           unknown: Optional[Union[np.ndarray, SparseMask]] = None,
           unknown_cost: float = 0.0) -> SearchResult:
    """One-off search on a fresh :class:`SearchWorkspace`; see :meth:`SearchWorkspace.search`.

    Prefer a workspace kept alive between queries on the same grid: this allocates (lazily) the
    per-node arrays each call.
    """
    return SearchWorkspace(blocked).search(start_index, goal_index, algorithm, resolution,
                                           adaptive_threshold, max_expansions, max_time_s,
                                           weight=weight, climb_weight=climb_weight,
                                           descent_weight=descent_weight, unknown=unknown,
                                           unknown_cost=unknown_cost)
