"""Dial's bucket queue: the open list of ``dijkstra`` on the 26-connected grid.

Every step costs at least ``c_min > 0`` [m] (the cheapest of the 26 step costs with the climb
and descent weights; unknown space only adds to them), and h is 0. The open list is a ring of
buckets a hair narrower than ``c_min``: a node's cost is final once its bucket is current, since
a path through another node of the same bucket costs at least ``c_min`` more and ends in a later
bucket (Dial, CACM 12(11), 1969). So the order inside a bucket does not matter for the costs,
and a bucket needs no heap: it is a list of chunks of node numbers, filled unordered (a push
is an append) and read in the order of its pushes. No push reaches the current bucket, so it is
read where it lies, each chunk freed once read. Sorting each bucket by node number, so that
consecutive expansions touch neighbouring memory, was measured too: 3 % slower on the dense
6 M grid and 5-10 % slower on the block-sparse 20 M grid of ``bench_search_peers``.

No node is re-ordered in a heap: a better cost for an open node that moves it to an earlier
bucket adds an entry there (a better cost within its bucket only updates the record), and the
stale entry is skipped when reached (its node is closed by then). A cost beyond the ring (only
with very costly steps) waits in the ring's last bucket and is placed again when reached.

Costs are exact (the same optimum as the exact key order); among paths of equal cost another one
may be returned. The order of expansions (by bucket, then by push) depends only on the inputs,
not on the grid layout.
The records, the parent array, the state and the block-sparse bricks are those of
:mod:`uav_global_planner.core.search.grid_search` (its module notes): a record is 16 bytes,
float64 cost in slot 0, int32 generation stamp in slot 2 and, in slot 3, -1 once the node is
closed (>= 0 while open).

Queue layout
------------
``chunk_node`` and ``chunk_rec`` (int32, ``CHUNK`` entries a chunk) hold node and record
numbers (records only on the block-sparse layout); ``chunk_meta`` holds, per chunk, the next
chunk of its list and its entry count; ``ends`` the first and last chunk of each ring bucket
(-1 when empty); ``qstate`` the slots ``Q_*``. Free chunks form a list; the caller grows the
chunk arrays (:func:`grown`) when the kernel asks for more.

The search loop is ``grid_search``'s kernel, compiled for this queue (its ``queue`` argument
holds these arrays) or for its heap: the neighbour step, the hot part of every search, is
written once, in the loop itself. This module's :func:`push` and :func:`next_chunk` are
inlined into it. An earlier version ran its own loop, whose neighbour step called an inlined
function: at 20 M block-sparse nodes its searches ran 6 times slower than with the step
written out in the loop.
"""

from typing import Tuple

import numpy as np

from uav_global_planner.core.jit import njit
from uav_global_planner.core.map.sparse_grid import BRICK, BRICK_BITS, FULL

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
Q_CHUNK = 5    # the current bucket's chunk being read, -1 before the first
Q_POS = 6      # next entry of it
Q_STATE_SIZE = 7

_BRICK_MASK = BRICK - 1


def brick_steps(directions: np.ndarray) -> np.ndarray:
    """Offset of each move inside a brick of records: (di * BRICK + dj) * BRICK + dk."""
    return (directions @ np.array([BRICK * BRICK, BRICK, 1])).astype(np.int64)


def new_queue(chunks: int, ring: int) -> Tuple[np.ndarray, ...]:
    """Fresh queue arrays: chunk nodes, chunk records, chunk meta, bucket ends, state."""
    qstate = np.zeros(Q_STATE_SIZE, dtype=np.int64)
    qstate[Q_AVAIL] = chunks
    qstate[Q_CHUNK] = -1
    return (np.zeros(chunks * CHUNK, dtype=np.int32), np.zeros(chunks * CHUNK, dtype=np.int32),
            np.zeros(2 * chunks, dtype=np.int32), np.full(2 * ring, -1, dtype=np.int32), qstate)


def grown(chunk_node: np.ndarray, chunk_rec: np.ndarray, chunk_meta: np.ndarray,
          qstate: np.ndarray) -> Tuple[np.ndarray, ...]:
    """The chunk arrays with twice the chunks, their entries kept (the new chunks
    available)."""
    chunks = chunk_meta.shape[0] // 2
    arrays = []
    for old, width in ((chunk_node, CHUNK), (chunk_rec, CHUNK), (chunk_meta, 2)):
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
    qstate[Q_CHUNK] = -1
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
def next_chunk(chunk_meta, ends, chunk, cur, mask, free, avail, chunks):
    """The chunk to read after ``chunk`` (-1 before the first), which is freed: the next one of
    its bucket, else the first of the next non-empty bucket of the ring, which becomes the
    current one and leaves the ring. Returns that chunk (-1 when the queue of ``chunks`` chunks
    is empty), the current bucket, the free list head and the chunks available."""
    following = np.int64(-1)
    if chunk >= 0:
        following = np.int64(chunk_meta[2 * chunk])
        chunk_meta[2 * chunk] = free
        free = chunk
        avail += 1
    if following < 0 and avail < chunks:
        end = 0
        while following < 0:
            cur += 1
            end = 2 * (cur & mask)
            following = np.int64(ends[end])
        ends[end] = -1
        ends[end + 1] = -1
    return following, cur, free, avail


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
