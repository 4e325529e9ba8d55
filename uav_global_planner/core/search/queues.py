"""The open list of the grid search: a ring of buckets over quantised keys and an exact heap.

An entry is a key (f, h) [m] with a node number and its record number. Entries are ordered by
f, then h, then node number, as a binary heap would order them; this queue pops them in exactly
that order, so the search it serves expands the same nodes in the same order as with one binary
heap, whatever the heuristic (consistent or not).

Layout
------
The key axis is cut into buckets of width ``W`` [m]: entry ``e`` belongs to bucket
``b(e) = floor(f / W)``, which is monotone in f. A current bucket number ``cur`` splits the
entries in two:

* every entry with ``b <= cur`` is in a binary heap (``heap_key``, ``heap_int``), ordered by
  (f, h, node);
* every other entry is in a singly linked list of a ring of ``B`` buckets (``heads``), at ring
  slot ``s & (B - 1)`` for a nominal bucket ``s = min(b, cur + B - 1)`` (a key beyond the ring
  waits in its last bucket and is placed again when that bucket is reached).

So every ring entry has a larger f than every heap entry and the heap's root is the least
entry. When the heap runs empty, ``cur`` advances to the next bucket of the ring that holds
entries and moves those with ``b <= cur`` into the heap. Bucket lists are unordered (a push is
a constant-time link), the heap only ever holds the entries of one bucket (plus those pushed
below it, which a consistent heuristic never does), so it stays small and in cache, and no
entry records its heap position: a better key for a node is a new entry, and the caller
skips the stale one when it pops (its node is closed by then).

Ring entries live in a pool (``pool_key``, ``pool_int``: node, record, next entry), recycled
through a free list. The heap and the pool hold at most ``capacity`` entries; the caller grows
both (see :func:`grown`) before a push could overflow them.

Dial's mode
-----------
When every step costs at least ``W`` and h is 0 (uniform-cost search), a node's cost is final
once its bucket is current: a path through another node of the same bucket costs at least ``W``
more, so it ends in a later bucket (Dial, CACM 12(11), 1969). The order within a bucket then
does not matter for the costs, and :func:`refill` can hand the bucket over in node-number order
(``by_node``): consecutive expansions touch neighbouring memory. Costs stay exact; among paths
of equal cost another one may be returned than in exact order.

The width and the ring size are chosen per query by the caller: with ``W`` at most a fraction
of the smallest step and ``B * W`` above the largest rise of the key from a node to a neighbour,
buckets rarely hold many keys and an entry is placed once.
"""

import numpy as np

from uav_global_planner.core.jit import njit

# Slots of the queue's int64 state array.
Q_CUR = 0     # current bucket number
Q_SIZE = 1    # entries in the heap
Q_RING = 2    # entries in the ring's lists
Q_FREE = 3    # first entry of the pool's free list, -1 for none
Q_TOP = 4     # pool entries handed out so far (free ones included)
Q_MASK = 5    # ring size B - 1 (B a power of two)
Q_STATE_SIZE = 6

#: Entries a new queue holds before it grows.
FIRST_CAPACITY = 1 << 14


def new_arrays(capacity: int, ring: int):
    """Fresh queue arrays: heap keys and ints, pool keys and ints, ring heads, state."""
    return (np.zeros(2 * capacity, dtype=np.float64), np.zeros(2 * capacity, dtype=np.int32),
            np.zeros(2 * capacity, dtype=np.float64), np.zeros(3 * capacity, dtype=np.int32),
            np.full(ring, -1, dtype=np.int32), np.zeros(Q_STATE_SIZE, dtype=np.int64))


def grown(heap_key: np.ndarray, heap_int: np.ndarray, pool_key: np.ndarray,
          pool_int: np.ndarray, qstate: np.ndarray):
    """The heap and pool arrays with twice the capacity, their entries kept."""
    capacity = 2 * (heap_int.shape[0] // 2)
    size = int(qstate[Q_SIZE])
    top = int(qstate[Q_TOP])
    arrays = []
    for old, width, used in ((heap_key, 2, size), (heap_int, 2, size), (pool_key, 2, top),
                             (pool_int, 3, top)):
        new = np.zeros(width * capacity, dtype=old.dtype)
        new[:width * used] = old[:width * used]
        arrays.append(new)
    return tuple(arrays)


@njit
def reset(heads, qstate, ring, cur):
    """Empty the queue, with ``ring`` buckets (a power of two <= len(heads)) from ``cur``."""
    heads[:ring] = -1
    qstate[Q_CUR] = cur
    qstate[Q_SIZE] = 0
    qstate[Q_RING] = 0
    qstate[Q_FREE] = -1
    qstate[Q_TOP] = 0
    qstate[Q_MASK] = ring - 1


@njit(inline='always')
def heap_push(heap_key, heap_int, size, f, h, node, rec):
    """Place an entry in a heap of ``size`` entries (the caller counts it)."""
    pos = size
    while pos > 0:
        up = (pos - 1) >> 1
        f_up = heap_key[2 * up]
        if f > f_up:
            break
        if f == f_up:
            h_up = heap_key[2 * up + 1]
            if h > h_up or (h == h_up and node >= heap_int[2 * up]):
                break
        heap_key[2 * pos] = f_up
        heap_key[2 * pos + 1] = heap_key[2 * up + 1]
        heap_int[2 * pos] = heap_int[2 * up]
        heap_int[2 * pos + 1] = heap_int[2 * up + 1]
        pos = up
    heap_key[2 * pos] = f
    heap_key[2 * pos + 1] = h
    heap_int[2 * pos] = node
    heap_int[2 * pos + 1] = rec


@njit(inline='always')
def heap_drop_root(heap_key, heap_int, size):
    """Remove the root of a heap that holds ``size`` entries after the removal (the last one,
    at slot ``size``, takes its place).

    Floyd's variant: the hole walks down to a leaf along the preferred children (one comparison
    per level), then the last entry is sifted up from there.
    """
    f = heap_key[2 * size]
    h = heap_key[2 * size + 1]
    node = heap_int[2 * size]
    rec = heap_int[2 * size + 1]
    pos = 0
    while True:
        child = 2 * pos + 1
        if child >= size:
            break
        right = child + 1
        if right < size:
            f_c = heap_key[2 * child]
            f_r = heap_key[2 * right]
            if f_r < f_c or (f_r == f_c and (
                    heap_key[2 * right + 1] < heap_key[2 * child + 1]
                    or (heap_key[2 * right + 1] == heap_key[2 * child + 1]
                        and heap_int[2 * right] < heap_int[2 * child]))):
                child = right
        heap_key[2 * pos] = heap_key[2 * child]
        heap_key[2 * pos + 1] = heap_key[2 * child + 1]
        heap_int[2 * pos] = heap_int[2 * child]
        heap_int[2 * pos + 1] = heap_int[2 * child + 1]
        pos = child
    heap_push(heap_key, heap_int, pos, f, h, node, rec)


@njit(inline='always')
def _link(pool_int, heads, qstate, entry, bucket):
    """Put a pool entry in the list of nominal bucket ``bucket`` (clamped to the ring)."""
    last = qstate[Q_CUR] + qstate[Q_MASK]
    if bucket > last:
        bucket = last
    slot = bucket & qstate[Q_MASK]
    pool_int[3 * entry + 2] = heads[slot]
    heads[slot] = entry


@njit(inline='always')
def push(heap_key, heap_int, pool_key, pool_int, heads, qstate, inv_width, f, h, node, rec):
    """Add an entry of key (f, h) [m], f >= 0, for ``node`` and its record ``rec``."""
    bucket = np.int64(f * inv_width)
    if bucket <= qstate[Q_CUR]:
        size = qstate[Q_SIZE]
        heap_push(heap_key, heap_int, size, f, h, node, rec)
        qstate[Q_SIZE] = size + 1
        return
    entry = qstate[Q_FREE]
    if entry >= 0:
        qstate[Q_FREE] = pool_int[3 * entry + 2]
    else:
        entry = qstate[Q_TOP]
        qstate[Q_TOP] = entry + 1
    pool_key[2 * entry] = f
    pool_key[2 * entry + 1] = h
    pool_int[3 * entry] = node
    pool_int[3 * entry + 1] = rec
    _link(pool_int, heads, qstate, entry, bucket)
    qstate[Q_RING] += 1


@njit
def refill(heap_key, heap_int, pool_key, pool_int, heads, qstate, inv_width, by_node):
    """Advance the current bucket until the heap holds entries; the ring must hold some.

    With ``by_node`` the bucket's entries enter the heap with key (0, 0): it then pops them in
    the order of their node numbers (Dial's mode, see the module notes).
    """
    mask = qstate[Q_MASK]
    while qstate[Q_SIZE] == 0:
        cur = qstate[Q_CUR] + 1
        qstate[Q_CUR] = cur
        slot = cur & mask
        entry = np.int64(heads[slot])
        if entry < 0:
            continue
        heads[slot] = -1
        size = qstate[Q_SIZE]
        moved = 0
        while entry >= 0:
            following = np.int64(pool_int[3 * entry + 2])
            f = pool_key[2 * entry]
            bucket = np.int64(f * inv_width)
            if bucket <= cur:
                h = pool_key[2 * entry + 1]
                if by_node:
                    f = 0.0
                    h = 0.0
                heap_push(heap_key, heap_int, size, f, h, pool_int[3 * entry],
                          pool_int[3 * entry + 1])
                size += 1
                moved += 1
                pool_int[3 * entry + 2] = qstate[Q_FREE]
                qstate[Q_FREE] = entry
            else:
                _link(pool_int, heads, qstate, entry, bucket)
            entry = following
        qstate[Q_SIZE] = size
        qstate[Q_RING] -= moved
