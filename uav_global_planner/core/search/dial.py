"""Uniform-cost search in Dial's mode: the kernel of ``dijkstra`` on the 26-connected grid.

Every step costs at least ``c_min > 0`` [m] (the cheapest of the 26 step costs with the climb
and descent weights; unknown space only adds to them), and h is 0. The open list is a ring of
buckets a hair narrower than ``c_min``: a node's cost is final once its bucket is current, since
a path through another node of the same bucket costs at least ``c_min`` more and ends in a later
bucket (Dial, CACM 12(11), 1969). So the order inside a bucket does not matter for the costs,
and a bucket needs no heap: it is a list of chunks of node numbers, filled unordered (a push
is an append) and, once current, copied out and sorted by node number (:func:`take_bucket`),
so consecutive expansions touch neighbouring records and mask bytes. A large search is bound
by memory: at 6 M nodes, expanding each bucket in push order was no faster than ordering it in
a heap keyed by node number, while sorting it once measured 2.4 times faster than that heap.

No node is re-ordered in a heap: a better cost for an open node that moves it to an earlier
bucket adds an entry there (a better cost within its bucket only updates the record), and the
stale entry is skipped when reached (its node is closed by then). A cost beyond the ring (only
with very costly steps) waits in the ring's last bucket and is placed again when reached.

Costs are exact (the same optimum as the exact key order); among paths of equal cost another one
may be returned. The order of expansions (by bucket, then node number) depends only on the
inputs, not on the grid layout.
The records, the parent array, the state and the block-sparse bricks are those of
:mod:`uav_global_planner.core.search.grid_search` (its module notes): a record is 16 bytes,
float64 cost in slot 0, int32 generation stamp in slot 2 and, in slot 3, -1 once the node is
closed (>= 0 while open).

Queue layout
------------
``chunk_node`` and ``chunk_rec`` (int32, ``CHUNK`` entries a chunk) hold node and record
numbers (records only on the block-sparse layout); ``chunk_meta`` holds, per chunk, the next
chunk of its list and its entry count; ``ends`` the first and last chunk of each ring bucket
(-1 when empty); ``order`` (int64, as many entries as the chunks) the current bucket's
entries, sorted; ``qstate`` the slots ``Q_*``. Free chunks form a list; the caller grows the
chunk arrays (:func:`grown`) when the kernel returns ``GROW``.

:func:`node_place` (a node's brick, block-sparse) is inlined into this kernel and the heap
kernel of ``grid_search``; :func:`neighbour_record` is this kernel's neighbour step. The heap
kernel writes its neighbour step out: through the inlined function its searches ran 2.3x
slower at 20 M block-sparse nodes.
"""

from typing import Tuple

import numpy as np

from uav_global_planner.core.jit import njit
from uav_global_planner.core.map.sparse_grid import BRICK, BRICK_BITS, BRICK_NODES, FULL

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

#: Entries of a chunk.
CHUNK = 1024
#: Chunks a new queue holds before it grows.
FIRST_CHUNKS = 64

# Slots of the queue's int64 state array.
Q_CUR = 0      # current bucket number
Q_MASK = 1     # ring size - 1 (a power of two minus 1)
Q_FREE = 2     # first chunk of the free list, -1 for none
Q_TOP = 3      # chunks handed out so far (free ones included)
Q_AVAIL = 4    # chunks not in use (free list and never handed out)
Q_COUNT = 5    # entries of the current bucket (in ``order``)
Q_POS = 6      # next entry of it
Q_STATE_SIZE = 7

_BRICK_MASK = BRICK - 1
# A bucket entry of the block-sparse layout: node number << 31 | record number.
_REC_MASK = (1 << 31) - 1


def brick_steps(directions: np.ndarray) -> np.ndarray:
    """Offset of each move inside a brick of records: (di * BRICK + dj) * BRICK + dk."""
    return (directions @ np.array([BRICK * BRICK, BRICK, 1])).astype(np.int64)


def new_queue(chunks: int, ring: int) -> Tuple[np.ndarray, ...]:
    """Fresh queue arrays: chunk nodes, chunk records, chunk meta, bucket ends, the current
    bucket's sorted entries, state."""
    qstate = np.zeros(Q_STATE_SIZE, dtype=np.int64)
    qstate[Q_AVAIL] = chunks
    return (np.zeros(chunks * CHUNK, dtype=np.int32), np.zeros(chunks * CHUNK, dtype=np.int32),
            np.zeros(2 * chunks, dtype=np.int32), np.full(2 * ring, -1, dtype=np.int32),
            np.zeros(chunks * CHUNK, dtype=np.int64), qstate)


def grown(chunk_node: np.ndarray, chunk_rec: np.ndarray, chunk_meta: np.ndarray,
          order: np.ndarray, qstate: np.ndarray) -> Tuple[np.ndarray, ...]:
    """The chunk arrays and ``order`` with twice the chunks, their entries kept (the new chunks
    available)."""
    chunks = chunk_meta.shape[0] // 2
    arrays = []
    for old, width in ((chunk_node, CHUNK), (chunk_rec, CHUNK), (chunk_meta, 2),
                       (order, CHUNK)):
        new = np.zeros(2 * chunks * width, dtype=old.dtype)
        new[:chunks * width] = old
        arrays.append(new)
    qstate[Q_AVAIL] += chunks
    return tuple(arrays)


@njit
def reset(ends, qstate, ring, chunks):
    """Empty the queue of ``chunks`` chunks, with ``ring`` buckets (a power of two,
    ``2 * ring <= len(ends)``) from bucket 0 (the current one is -1 until the first is
    taken)."""
    ends[:2 * ring] = -1
    qstate[Q_CUR] = -1
    qstate[Q_MASK] = ring - 1
    qstate[Q_FREE] = -1
    qstate[Q_TOP] = 0
    qstate[Q_AVAIL] = chunks
    qstate[Q_COUNT] = 0
    qstate[Q_POS] = 0


@njit(inline='always')
def push(chunk_node, chunk_rec, chunk_meta, ends, cur, mask, free, top, avail, bucket, node,
         rec, records):
    """Append ``node`` (record ``rec``, stored when ``records``) to bucket ``bucket``, clamped
    to the ring's last one (``cur + mask``); return the free list head, the chunks handed out
    and the chunks available (``free``, ``top``, ``avail`` before: the slots ``Q_*``). The
    caller makes sure a chunk is available."""
    last = cur + mask
    if bucket > last:
        bucket = last
    slot = 2 * (bucket & mask)
    tail = np.int64(ends[slot + 1])
    if tail < 0 or chunk_meta[2 * tail + 1] == CHUNK:
        chunk = free
        if chunk >= 0:
            free = np.int64(chunk_meta[2 * chunk])
        else:
            chunk = top
            top += 1
        avail -= 1
        chunk_meta[2 * chunk] = -1
        chunk_meta[2 * chunk + 1] = 0
        if tail < 0:
            ends[slot] = chunk
        else:
            chunk_meta[2 * tail] = chunk
        ends[slot + 1] = chunk
        tail = chunk
    count = chunk_meta[2 * tail + 1]
    chunk_node[tail * CHUNK + count] = node
    if records:
        chunk_rec[tail * CHUNK + count] = rec
    chunk_meta[2 * tail + 1] = count + 1
    return free, top, avail


@njit(inline='always')
def take_bucket(chunk_node, chunk_rec, chunk_meta, order, chunk, free, avail, records):
    """Move the entries of the bucket whose first chunk is ``chunk`` to ``order``, sorted (node
    numbers; with ``records`` node << 31 | record), and free its chunks; return the free list
    head, the chunks available and the number of entries."""
    count = 0
    while chunk >= 0:
        first = chunk * CHUNK
        entries = chunk_meta[2 * chunk + 1]
        for e in range(entries):
            key = np.int64(chunk_node[first + e])
            if records:
                key = (key << 31) | np.int64(chunk_rec[first + e])
            order[count] = key
            count += 1
        following = np.int64(chunk_meta[2 * chunk])
        chunk_meta[2 * chunk] = free
        free = chunk
        avail += 1
        chunk = following
    order[:count] = np.sort(order[:count])
    return free, avail, count


@njit
def push_start(chunk_node, chunk_rec, chunk_meta, ends, qstate, node, rec):
    """Put the start node (record ``rec``) in bucket 0 of a queue just :func:`reset`."""
    free, top, avail = push(chunk_node, chunk_rec, chunk_meta, ends, qstate[Q_CUR],
                            qstate[Q_MASK], qstate[Q_FREE], qstate[Q_TOP], qstate[Q_AVAIL], 0,
                            node, rec, True)
    qstate[Q_FREE] = free
    qstate[Q_TOP] = top
    qstate[Q_AVAIL] = avail


@njit(inline='always')
def unknown_at(flat, table, pool, node, i, j, k, by, bz):  # pragma: no cover - compiled
    """1.0 when the node is in the unknown-space mask (dense ``flat``, else the block-sparse
    ``table`` and ``pool``), else 0.0 (both grid kernels' unknown-space charge)."""
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


@njit(inline='always')
def neighbour_record(blocked, mask_table, mask_pool, bricks, slots, node, i, j, k, nx, ny, nz,
                     d, directions, brick_step, delta, inside, fast, kind, base, local_node,
                     used):
    """Record number of neighbour ``d`` of ``node`` (i, j, k), or -1 when it is outside the
    grid or blocked; and the brick slots in use (a new slot when its brick is first reached).

    The neighbour loop of the grid kernels (:mod:`uav_global_planner.core.search.grid_search`
    and this one), inlined into each. Dense (``slots`` None): ``fast`` when ``node`` is off the
    grid's faces (no bounds to check). Block-sparse: ``inside`` when it is off its brick's
    faces, its brick of kind ``kind`` (mask) at record ``base``, ``local_node`` its place in
    it; otherwise the neighbour's brick is looked up.
    """
    if slots is None:
        neighbour = node + delta[d]
        if not fast:
            ni = i + directions[d, 0]
            nj = j + directions[d, 1]
            nk = k + directions[d, 2]
            if ni < 0 or ni >= nx or nj < 0 or nj >= ny or nk < 0 or nk >= nz:
                return np.int64(-1), used
        if blocked[neighbour]:
            return np.int64(-1), used
        return np.int64(neighbour), used
    if inside:
        local = local_node + brick_step[d]
        if kind >= 0 and mask_pool[kind, local]:
            return np.int64(-1), used
        return np.int64(base + local), used
    ni = i + directions[d, 0]
    nj = j + directions[d, 1]
    nk = k + directions[d, 2]
    if ni < 0 or ni >= nx or nj < 0 or nj >= ny or nk < 0 or nk >= nz:
        return np.int64(-1), used
    brick = ((ni >> BRICK_BITS) * bricks[1] + (nj >> BRICK_BITS)) * bricks[2] + (
        nk >> BRICK_BITS)
    local = (((ni & _BRICK_MASK) * BRICK) + (nj & _BRICK_MASK)) * BRICK + (nk & _BRICK_MASK)
    kind_n = mask_table[brick]
    if kind_n == FULL:
        return np.int64(-1), used
    if kind_n >= 0 and mask_pool[kind_n, local]:
        return np.int64(-1), used
    slot = np.int64(slots[brick])
    if slot < 0:
        slot = used
        used += 1
        slots[brick] = slot
    return slot * BRICK_NODES + local, used


@njit(inline='always')
def node_place(mask_table, bricks, slots, rec_node, i, j, k, nx, ny, nz):
    """Where the neighbour loop of a node starts, block-sparse (``slots`` given): ``inside``
    when the node is off its brick's faces (its 26 neighbours are in that brick), the brick's
    mask kind, its first record and the node's place in it (both grid kernels' prelude)."""
    inside = False
    kind = 0
    base = 0
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
            kind = mask_table[((i >> BRICK_BITS) * bricks[1] + (j >> BRICK_BITS)) * bricks[2]
                              + (k >> BRICK_BITS)]
    return inside, kind, base, local_node


@njit
def expand(blocked, mask_table, mask_pool, bricks, slots, node_g, node_int, parent, chunk_node,
           chunk_rec, chunk_meta, ends, order, qstate, directions, brick_step, delta, step_cost,
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
    ``PAUSED`` when ``max_pops`` ran out and ``GROW``, without expanding, when the queue might
    not have the chunks of 26 more entries or, block-sparse, the record pool the bricks of one
    more expansion (8) (the caller grows them and resumes); ``state`` and ``qstate`` are updated
    so the call can be resumed. Node records are only meaningful when their stamp equals the
    current generation.

    ``directions`` are the 26 moves (di, dj, dk), ``brick_step`` their record offsets inside a
    brick (:func:`brick_steps`) and ``delta`` their node number offsets; ``inv_width`` is 1
    over the bucket width [1/m]. ``unknown_step`` (26 values, or None for none) is
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
    by = bricks[1]
    bz = bricks[2]
    nyz = ny * nz
    charged = unknown_step is not None
    records = slots is not None
    mask = qstate[Q_MASK]
    cur = qstate[Q_CUR]
    pos = qstate[Q_POS]
    count = qstate[Q_COUNT]
    free = qstate[Q_FREE]
    top = qstate[Q_TOP]
    chunks = chunk_meta.shape[0] // 2
    avail = qstate[Q_AVAIL]
    pops = 0
    status = PAUSED
    while pops < max_pops:
        if pos >= count:
            # The bucket is done: take the next one of the ring, its entries in node order.
            if avail == chunks:
                status = EXHAUSTED
                break
            chunk = np.int64(-1)
            while chunk < 0:
                cur += 1
                slot = 2 * (cur & mask)
                chunk = np.int64(ends[slot])
            ends[slot] = -1
            ends[slot + 1] = -1
            free, avail, count = take_bucket(chunk_node, chunk_rec, chunk_meta, order, chunk,
                                             free, avail, records)
            pos = 0
            continue
        if avail < 27 or (slots is not None and used + 8 > capacity):
            status = GROW
            break
        key = order[pos]
        pos += 1
        node = key
        rec_node = key
        if slots is not None:
            node = key >> 31
            rec_node = key & _REC_MASK
        if node_int[4 * rec_node + OPEN_SLOT] < 0:
            # A stale entry: the node was reached again at a lower cost and expanded since.
            continue
        g_node = node_g[2 * rec_node]
        bucket = np.int64(g_node * inv_width)
        if bucket > cur:
            # A cost beyond the ring when it was pushed: place it again.
            free, top, avail = push(chunk_node, chunk_rec, chunk_meta, ends, cur, mask, free,
                                    top, avail, bucket, node, rec_node, records)
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
        u_node = 0.0
        if charged:
            u_node = unknown_at(unknown, unknown_table, unknown_pool, node, i, j, k, by, bz)
        fast = 0 < i < nx - 1 and 0 < j < ny - 1 and 0 < k < nz - 1
        inside, kind, base, local_node = node_place(mask_table, bricks, slots, rec_node, i, j, k,
                                                    nx, ny, nz)
        for d in range(26):
            if slots is None and fast:
                rec = node + delta[d]
                if blocked[rec]:
                    continue
            else:
                rec, used = neighbour_record(blocked, mask_table, mask_pool, bricks, slots,
                                             node, i, j, k, nx, ny, nz, d, directions,
                                             brick_step, delta, inside, fast, kind, base,
                                             local_node, used)
                if rec < 0:
                    continue
            g_new = g_node + step_cost[d]
            neighbour = node + delta[d]
            if charged:
                g_new += (u_node + unknown_at(
                    unknown, unknown_table, unknown_pool, neighbour, i + directions[d, 0],
                    j + directions[d, 1], k + directions[d, 2], by, bz)) * unknown_step[d]
            at = 4 * rec
            bucket = np.int64(g_new * inv_width)
            if node_int[at + STAMP_SLOT] == generation:
                if node_int[at + OPEN_SLOT] < 0:
                    continue
                g_old = node_g[2 * rec]
                if g_new >= g_old:
                    continue
                node_g[2 * rec] = g_new
                parent[rec] = d
                if bucket >= np.int64(g_old * inv_width):
                    # Still in the bucket of its entry.
                    continue
            else:
                # First visit in this query: the record is stale, overwrite it.
                node_int[at + STAMP_SLOT] = generation
                node_int[at + OPEN_SLOT] = 0
                node_g[2 * rec] = g_new
                parent[rec] = d
            free, top, avail = push(chunk_node, chunk_rec, chunk_meta, ends, cur, mask, free,
                                    top, avail, bucket, neighbour, rec, records)
    qstate[Q_CUR] = cur
    qstate[Q_FREE] = free
    qstate[Q_TOP] = top
    qstate[Q_AVAIL] = avail
    qstate[Q_COUNT] = count
    qstate[Q_POS] = pos
    state[S_EXPANDED] += pops
    state[S_USED] = used
    return status
