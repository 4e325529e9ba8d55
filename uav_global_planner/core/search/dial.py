"""Uniform-cost search in Dial's mode: the kernel of ``dijkstra`` on the 26-connected grid.

Every step costs at least ``c_min > 0`` [m] (the cheapest of the 26 step costs with the climb
and descent weights; unknown space only adds to them), and h is 0. The
open list is the bucket ring of :mod:`uav_global_planner.core.search.queues` with buckets a hair
narrower than ``c_min``: a node's cost is final once its bucket is current, since a path through
another node of the same bucket costs at least ``c_min`` more and ends in a later bucket (Dial,
CACM 12(11), 1969). The bucket is then expanded in node-number order (``by_node``), so
consecutive expansions touch neighbouring records and mask bytes, and no node is ever
re-ordered in a heap: a better cost for an open node adds an entry to a later bucket, and the
stale one is skipped when popped (its node is closed by then).

Costs are exact (the same optimum as the exact key order); among paths of equal cost another one
may be returned. The records, the parent array, the state and the block-sparse bricks are those
of :mod:`uav_global_planner.core.search.grid_search` (its module notes): a record is 16 bytes,
float64 cost in slot 0, int32 generation stamp in slot 2 and, in slot 3, -1 once the node is
closed (>= 0 while open).
"""

import numpy as np

from uav_global_planner.core.jit import njit
from uav_global_planner.core.map.sparse_grid import BRICK, BRICK_BITS, BRICK_NODES, FULL
from uav_global_planner.core.search import queues

# Slots of the search state array of grid_search (its _S_* constants).
S_GEN = 0
S_EXPANDED = 2
S_GOAL = 3
S_NX = 5
S_NY = 6
S_NZ = 7
S_USED = 11
# int32 slots of a record.
STAMP_SLOT = 2
OPEN_SLOT = 3

# Kernel return codes (grid_search's).
FOUND = 0
EXHAUSTED = 1
PAUSED = 2
GROW = 3

_BRICK_MASK = BRICK - 1


def brick_steps(directions: np.ndarray) -> np.ndarray:
    """Offset of each move inside a brick of records: (di * BRICK + dj) * BRICK + dk."""
    return (directions @ np.array([BRICK * BRICK, BRICK, 1])).astype(np.int64)


@njit(inline='always')
def _unknown_at(flat, table, pool, node, i, j, k, by, bz):  # pragma: no cover - compiled
    """1.0 when the node is in the unknown-space mask (dense ``flat``, else the block-sparse
    ``table`` and ``pool``), else 0.0."""
    if flat.shape[0] > 0:
        return 1.0 if flat[node] else 0.0
    brick = ((i >> BRICK_BITS) * by + (j >> BRICK_BITS)) * bz + (k >> BRICK_BITS)
    kind = table[brick]
    if kind == FULL:
        return 1.0
    if kind >= 0:
        local = (((i & _BRICK_MASK) * BRICK) + (j & _BRICK_MASK)) * BRICK + (k & _BRICK_MASK)
        return 1.0 if pool[kind, local] else 0.0
    return 0.0


@njit
def expand(blocked, mask_table, mask_pool, bricks, slots, node_g, node_int, parent, heap_key,
           heap_int, pool_key, pool_int, heads, qstate, directions, brick_step, delta, step_cost,
           unknown, unknown_table, unknown_pool, unknown_step, state, inv_width, max_pops):
    """Run at most ``max_pops`` expansions of the search described by ``state``.

    Two record layouts share this loop; numba compiles one version of it for each, the tests
    of ``slots is not None`` resolved at compile time. Dense (``slots`` None): ``blocked`` is
    the flat mask and a node's record number is its node number. Block-sparse (``blocked``
    empty): the mask is ``mask_table`` and ``mask_pool`` and the records live in bricks of
    8 x 8 x 8 nodes; a brick of records gets a slot (``slots[brick]``, in the order first
    reached) when the search first reaches one of its nodes. A node inside its brick (not on
    its faces) has all 26 neighbours in that brick, which is looked up once.

    Returns ``FOUND`` when the goal was closed, ``EXHAUSTED`` when the open list is empty,
    ``PAUSED`` when ``max_pops`` ran out and ``GROW``, without expanding, when the open list
    might not hold 26 more entries or, block-sparse, the record pool the bricks of one more
    expansion (8) (the caller grows them and resumes); ``state`` and ``qstate`` are updated so
    the call can be resumed. Node records are only meaningful when their stamp equals the
    current generation.

    ``directions`` are the 26 moves (di, dj, dk), ``brick_step`` their record offsets inside a
    brick (:func:`brick_steps`) and ``delta`` their node number offsets; ``inv_width`` is 1
    over the bucket width [1/m]. ``unknown_step`` (26 values, or empty for none) is
    half the extra cost of each step per end node in unknown space (module notes); the mask is
    ``unknown`` (dense, flat) or ``unknown_table`` and ``unknown_pool`` (block-sparse, the
    bricks of ``bricks``).
    """
    generation = np.int32(state[S_GEN])
    goal = state[S_GOAL]
    nx = state[S_NX]
    ny = state[S_NY]
    nz = state[S_NZ]
    used = state[S_USED]
    capacity = node_g.shape[0] // (2 * BRICK_NODES)
    queue_capacity = heap_int.shape[0] // 2 - 26
    by = bricks[1]
    bz = bricks[2]
    nyz = ny * nz
    charged = unknown_step.shape[0] > 0
    pops = 0
    status = PAUSED
    while pops < max_pops:
        if qstate[queues.Q_SIZE] == 0:
            if qstate[queues.Q_RING] == 0:
                status = EXHAUSTED
                break
            queues.refill(heap_key, heap_int, pool_key, pool_int, heads, qstate, inv_width,
                          True)
        size = qstate[queues.Q_SIZE]
        if size + qstate[queues.Q_RING] > queue_capacity:
            status = GROW
            break
        if slots is not None and used + 8 > capacity:
            status = GROW
            break
        node = np.int64(heap_int[0])
        rec_node = np.int64(heap_int[1])
        size -= 1
        qstate[queues.Q_SIZE] = size
        if size > 0:
            queues.heap_drop_root(heap_key, heap_int, size)
        if node_int[4 * rec_node + OPEN_SLOT] < 0:
            # A stale entry: the node was reached again at a lower cost and expanded since.
            continue
        node_int[4 * rec_node + OPEN_SLOT] = -1
        pops += 1
        if node == goal:
            status = FOUND
            break
        i = node // nyz
        rest = node - i * nyz
        j = rest // nz
        k = rest - j * nz
        g_node = node_g[2 * rec_node]
        u_node = 0.0
        if charged:
            u_node = _unknown_at(unknown, unknown_table, unknown_pool, node, i, j, k, by, bz)
        # A node inside its brick (block-sparse): every neighbour is in the same brick.
        inside = False
        base = 0
        kind = 0
        local_node = 0
        if slots is not None:
            li = i & _BRICK_MASK
            lj = j & _BRICK_MASK
            lk = k & _BRICK_MASK
            inside = (0 < li < _BRICK_MASK and 0 < lj < _BRICK_MASK and 0 < lk < _BRICK_MASK
                      and i + 1 < nx and j + 1 < ny and k + 1 < nz)
            if inside:
                local_node = (li * BRICK + lj) * BRICK + lk
                base = rec_node - local_node
                kind = mask_table[((i >> BRICK_BITS) * by + (j >> BRICK_BITS)) * bz
                                  + (k >> BRICK_BITS)]
        for d in range(26):
            ni = i + directions[d, 0]
            nj = j + directions[d, 1]
            nk = k + directions[d, 2]
            neighbour = node + delta[d]
            if inside:
                local = local_node + brick_step[d]
                if kind >= 0 and mask_pool[kind, local]:
                    continue
                rec = base + local
            else:
                if ni < 0 or ni >= nx or nj < 0 or nj >= ny or nk < 0 or nk >= nz:
                    continue
                rec = neighbour
                if slots is not None:
                    brick = (((ni >> BRICK_BITS) * by + (nj >> BRICK_BITS)) * bz
                             + (nk >> BRICK_BITS))
                    local = (((ni & _BRICK_MASK) * BRICK) + (nj & _BRICK_MASK)) * BRICK + (
                        nk & _BRICK_MASK)
                    kind_n = mask_table[brick]
                    if kind_n == FULL:
                        continue
                    if kind_n >= 0 and mask_pool[kind_n, local]:
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
                g_new += (u_node + _unknown_at(unknown, unknown_table, unknown_pool, neighbour,
                                               ni, nj, nk, by, bz)) * unknown_step[d]
            at = 4 * rec
            if node_int[at + STAMP_SLOT] == generation:
                if node_int[at + OPEN_SLOT] < 0 or g_new >= node_g[2 * rec]:
                    continue
            else:
                # First visit in this query: the record is stale, overwrite it.
                node_int[at + STAMP_SLOT] = generation
                node_int[at + OPEN_SLOT] = 0
            node_g[2 * rec] = g_new
            parent[rec] = d
            queues.push(heap_key, heap_int, pool_key, pool_int, heads, qstate, inv_width, g_new,
                        0.0, neighbour, rec)
    state[S_EXPANDED] += pops
    state[S_USED] = used
    return status
