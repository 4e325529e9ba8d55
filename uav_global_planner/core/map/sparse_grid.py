"""Block-sparse occupancy of the voxel grid: memory that follows the obstacles, not the volume.

The grid's nodes are cut into *bricks* of ``8 x 8 x 8`` nodes (brick ``(a, b, c)`` holds the
nodes ``[8 a, 8 a + 8) x [8 b, 8 b + 8) x [8 c, 8 c + 8)``, clipped to the grid). A table with
one int32 per brick says what each brick is:

- :data:`FREE` (-1): no node of the brick is blocked; nothing else is stored;
- :data:`FULL` (-2): every node of the brick is blocked; nothing else is stored;
- ``s >= 0``: the brick is mixed and row ``s`` of the pool holds its 512 nodes, one bool each,
  in C order inside the brick.

So the mask costs 4 bytes a brick (1/128 byte a node) plus 512 bytes per brick that an
obstacle's surface crosses. The search keeps its per-node state in bricks of the same layout,
allocated when a search first reaches them (:mod:`uav_global_planner.core.search.grid_search`).

:func:`choose_layout` is the one rule that picks this layout or the dense one (a numpy bool
array of the grid's shape): dense below :data:`SPARSE_MIN_NODES` nodes, where it is slightly
faster and its memory is small anyway, block-sparse from there on. Both give the same blocked
nodes to the bit (:mod:`uav_global_planner.core.map.inflation` writes both with the same kernels)
and the search gives the same paths on both.
"""

from typing import Optional, Tuple

import numpy as np
import numpy.typing as npt

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.jit import njit

#: log2 of the brick edge [nodes].
BRICK_BITS = 3
#: Brick edge [nodes].
BRICK = 1 << BRICK_BITS
#: Nodes per brick.
BRICK_NODES = BRICK ** 3
#: Table code of a brick without a blocked node.
FREE = -1
#: Table code of a brick whose nodes are all blocked.
FULL = -2

#: What a build knows of a brick of a window before looking at its nodes
#: (:meth:`SparseBuilder.pack`): no node of it is blocked, ...
KNOWN_FREE = 0
#: ... its nodes decide (the window's nodes are read), ...
FROM_NODES = 1
#: ... or every node of it is blocked.
KNOWN_FULL = 2

#: From this many nodes up, :func:`choose_layout` picks the block-sparse layout.
SPARSE_MIN_NODES = 16_000_000

#: Names accepted by :func:`choose_layout`.
LAYOUTS = ('auto', 'dense', 'sparse')

_MASK = BRICK - 1


def choose_layout(nodes: int, layout: str = 'auto') -> str:
    """``'dense'`` or ``'sparse'``: the layout of a grid of ``nodes`` nodes.

    Parameters
    ----------
    nodes : int
        Grid size.
    layout : str
        ``'auto'`` (the rule: sparse from :data:`SPARSE_MIN_NODES` nodes up), or ``'dense'``
        or ``'sparse'`` to force one.

    Raises
    ------
    InvalidInputError
        For an unknown layout name.
    """
    if layout not in LAYOUTS:
        raise InvalidInputError(f'layout must be one of {", ".join(LAYOUTS)}, got {layout!r}')
    if layout != 'auto':
        return layout
    return 'sparse' if int(nodes) >= SPARSE_MIN_NODES else 'dense'


def brick_dims(shape: Tuple[int, int, int]) -> Tuple[int, int, int]:
    """Bricks per axis of a grid of ``shape`` nodes."""
    return tuple(-(-int(n) // BRICK) for n in shape)  # type: ignore[return-value]


class SparseMask:
    """Blocked nodes of a grid in bricks (module notes); read-only once built.

    Parameters
    ----------
    shape : tuple of int
        Nodes per axis (Nx, Ny, Nz).
    table : numpy.ndarray of int32, shape (Bx * By * Bz,)
        Brick codes in C order over the bricks (:data:`FREE`, :data:`FULL` or a pool row).
    pool : numpy.ndarray of bool, shape (S, 512)
        Nodes of the mixed bricks.

    Attributes
    ----------
    shape : tuple of int
    bricks : tuple of int
        Bricks per axis (Bx, By, Bz).
    """

    dtype = np.dtype(np.bool_)
    ndim = 3

    def __init__(self, shape: Tuple[int, int, int], table: npt.NDArray[np.int32],
                 pool: npt.NDArray[np.bool_]) -> None:
        self.shape = tuple(int(n) for n in shape)
        self.bricks = brick_dims(self.shape)  # type: ignore[arg-type]
        table = np.ascontiguousarray(table, dtype=np.int32)
        pool = np.ascontiguousarray(pool, dtype=np.bool_).reshape(-1, BRICK_NODES)
        if table.shape != (int(np.prod(self.bricks)),):
            raise InvalidInputError(f'the brick table must have {int(np.prod(self.bricks))} '
                                    f'entries, got {table.shape}')
        table.setflags(write=False)
        pool.setflags(write=False)
        self.table = table
        self.pool = pool

    @property
    def size(self) -> int:
        """Number of nodes."""
        return self.shape[0] * self.shape[1] * self.shape[2]

    @property
    def nbytes(self) -> int:
        """Memory of the table and the pool [bytes]."""
        return int(self.table.nbytes + self.pool.nbytes)

    def brick_counts(self) -> Tuple[int, int, int]:
        """Numbers of free, full and mixed bricks."""
        free = int(np.count_nonzero(self.table == FREE))
        full = int(np.count_nonzero(self.table == FULL))
        return free, full, len(self.table) - free - full

    def __getitem__(self, index) -> bool:
        """Whether node ``(i, j, k)`` is blocked (three integers inside the grid)."""
        if not isinstance(index, tuple):
            index = tuple(np.asarray(index).tolist())
        if len(index) != 3:
            raise InvalidInputError(f'a node index is three integers, got {index!r}')
        i, j, k = (int(v) for v in index)
        nx, ny, nz = self.shape
        if not (0 <= i < nx and 0 <= j < ny and 0 <= k < nz):
            raise IndexError(f'node {[i, j, k]} lies outside the grid of shape {self.shape}')
        return bool(_node_blocked(self.table, self.pool, np.asarray(self.bricks, np.int64),
                                  i, j, k))

    def blocked_at(self, indices) -> npt.NDArray[np.bool_]:
        """Whether each node of ``indices`` (shape (M, 3), inside the grid) is blocked."""
        idx = np.ascontiguousarray(np.asarray(indices, dtype=np.int64).reshape(-1, 3))
        out = np.empty(len(idx), dtype=np.bool_)
        _nodes_blocked(self.table, self.pool, np.asarray(self.bricks, np.int64), idx, out)
        return out

    def count_blocked(self) -> int:
        """Number of blocked nodes (work in the number of bricks, not of nodes)."""
        return int(_count_blocked(self.table, self.pool, np.asarray(self.shape, np.int64),
                                  np.asarray(self.bricks, np.int64)))

    def first_free(self) -> Optional[int]:
        """Smallest flat (C-order) number of a free node, or None when every node is blocked."""
        found = int(_first_free(self.table, self.pool, np.asarray(self.shape, np.int64),
                                np.asarray(self.bricks, np.int64)))
        return None if found < 0 else found

    def to_dense(self) -> npt.NDArray[np.bool_]:
        """The mask as a bool array of :attr:`shape` (memory: one byte a node)."""
        out = np.zeros(self.shape, dtype=np.bool_)
        _unpack(self.table, self.pool, np.asarray(self.bricks, np.int64), out)
        return out

    @classmethod
    def from_dense(cls, mask: npt.NDArray[np.bool_]) -> 'SparseMask':
        """The block-sparse form of a dense bool mask."""
        mask = np.ascontiguousarray(mask, dtype=np.bool_)
        shape = mask.shape
        builder = SparseBuilder((int(shape[0]), int(shape[1]), int(shape[2])))
        builder.pack(mask, np.zeros(3, dtype=np.int64))
        return builder.finish()


def first_free_node(blocked) -> Optional[int]:
    """Smallest flat number of a free node of a dense or sparse mask; None if all are blocked."""
    if isinstance(blocked, SparseMask):
        return blocked.first_free()
    flat = blocked.reshape(-1)
    first = int(np.argmin(flat))  # without a copy of the grid
    return None if flat[first] else first


class SparseBuilder:
    """Writes a :class:`SparseMask` window by window.

    Each window is a dense bool block of the grid (at most a few million nodes, aligned to
    bricks except at the grid's upper faces); :meth:`pack` files its bricks as free, full or
    mixed. Bricks that no window covers stay free.

    Parameters
    ----------
    shape : tuple of int
        Nodes per axis of the grid.
    capacity : int, optional
        Most mixed bricks the windows can hold (for example 512 per window to pack). The pool
        is then reserved once: fresh zero pages, committed only as rows are written, so
        neither growing it nor trimming it copies anything. Without it the pool doubles as
        needed.
    """

    def __init__(self, shape: Tuple[int, int, int], capacity: Optional[int] = None) -> None:
        self.shape = tuple(int(n) for n in shape)
        self.bricks = np.asarray(brick_dims(self.shape), dtype=np.int64)  # type: ignore
        self._table = np.full(int(np.prod(self.bricks)), FREE, dtype=np.int32)
        rows = 64 if capacity is None else max(1, min(int(capacity), len(self._table)))
        self._pool = np.zeros((rows, BRICK_NODES), dtype=np.bool_)
        self._reserved = capacity is not None
        self._used = 0
        self._shape = np.asarray(self.shape, dtype=np.int64)

    def pack(self, window: npt.NDArray[np.bool_], base: npt.NDArray[np.int64],
             states: Optional[npt.NDArray[np.int8]] = None) -> None:
        """File the bricks of ``window``, the nodes from ``base`` (multiples of 8) on.

        Parameters
        ----------
        window : numpy.ndarray of bool
            The nodes of the window.
        base : numpy.ndarray of int64, shape (3,)
            Its first node.
        states : numpy.ndarray of int8, shape (bricks of the window per axis), optional
            What is known of each brick of the window: :data:`KNOWN_FREE` and
            :data:`KNOWN_FULL` bricks are filed as such without reading their nodes (which
            ``window`` then need not hold), :data:`FROM_NODES` bricks from their nodes. Without
            it every brick is filed from its nodes.
        """
        spans = -(-np.asarray(window.shape, dtype=np.int64) // BRICK)
        if states is None:
            states = np.full(tuple(int(n) for n in spans), FROM_NODES, dtype=np.int8)
        if states.shape != tuple(spans):
            raise InvalidInputError(f'states must have the shape {tuple(spans.tolist())} of the '
                                    f'bricks of the window, got {states.shape}')
        need = self._used + int(np.count_nonzero(states == FROM_NODES))
        if need > len(self._pool):
            grown = np.zeros((max(need, 2 * len(self._pool)), BRICK_NODES), dtype=np.bool_)
            grown[:self._used] = self._pool[:self._used]
            self._pool = grown
        self._used = int(_pack(window, np.asarray(base, dtype=np.int64), self._shape,
                               self.bricks, self._table, self._pool, self._used,
                               np.ascontiguousarray(states, dtype=np.int8)))

    @classmethod
    def editing(cls, mask: SparseMask, capacity: int) -> 'SparseBuilder':
        """A builder that starts from ``mask`` (a copy of its table and pool) with room for
        ``capacity`` more mixed bricks; bricks it packs again get new pool rows. When more than
        half of the rows would then be orphaned, the pool is compacted first."""
        builder = cls((int(mask.shape[0]), int(mask.shape[1]), int(mask.shape[2])), capacity=1)
        table = mask.table.copy()
        pool = mask.pool
        live = table >= 0
        if 2 * int(np.count_nonzero(live)) < len(pool):
            pool = pool[table[live]]
            table[live] = np.arange(int(np.count_nonzero(live)), dtype=np.int32)
        builder._table = table
        builder._pool = np.zeros((len(pool) + max(1, int(capacity)), BRICK_NODES),
                                 dtype=np.bool_)
        builder._pool[:len(pool)] = pool
        builder._used = len(pool)
        return builder

    def unpack(self, window: npt.NDArray[np.bool_], base: npt.NDArray[np.int64]) -> None:
        """Write the nodes of the bricks already filed into ``window`` (the nodes from
        ``base`` on)."""
        _unpack_window(self._table, self._pool, self.bricks, np.asarray(base, dtype=np.int64),
                       window)

    def finish(self) -> SparseMask:
        """The mask (the pool trimmed to the mixed bricks)."""
        pool = self._pool[:self._used]
        if not self._reserved and self._used < len(self._pool):
            pool = pool.copy()
        return SparseMask(self.shape, self._table, pool)  # type: ignore[arg-type]


@njit
def _brick_of(bricks, i, j, k):  # pragma: no cover - compiled
    return ((i >> BRICK_BITS) * bricks[1] + (j >> BRICK_BITS)) * bricks[2] + (k >> BRICK_BITS)


@njit
def _local(i, j, k):  # pragma: no cover - compiled
    return ((i & _MASK) * BRICK + (j & _MASK)) * BRICK + (k & _MASK)


@njit
def _node_blocked(table, pool, bricks, i, j, k):  # pragma: no cover - compiled
    code = table[_brick_of(bricks, i, j, k)]
    if code == FREE:
        return False
    if code == FULL:
        return True
    return pool[code, _local(i, j, k)]


@njit
def _nodes_blocked(table, pool, bricks, idx, out):  # pragma: no cover - compiled
    for n in range(idx.shape[0]):
        out[n] = _node_blocked(table, pool, bricks, idx[n, 0], idx[n, 1], idx[n, 2])


@njit
def _brick_extent(shape, bricks, brick):  # pragma: no cover - compiled
    """First node and node counts per axis of a brick (clipped to the grid)."""
    c = brick % bricks[2]
    rest = brick // bricks[2]
    b = rest % bricks[1]
    a = rest // bricks[1]
    i0 = a * BRICK
    j0 = b * BRICK
    k0 = c * BRICK
    return (i0, j0, k0, min(BRICK, shape[0] - i0), min(BRICK, shape[1] - j0),
            min(BRICK, shape[2] - k0))


@njit
def _count_blocked(table, pool, shape, bricks):  # pragma: no cover - compiled
    total = 0
    for brick in range(table.shape[0]):
        code = table[brick]
        if code == FREE:
            continue
        i0, j0, k0, si, sj, sk = _brick_extent(shape, bricks, brick)
        if code == FULL:
            total += si * sj * sk
            continue
        for a in range(si):
            for b in range(sj):
                for c in range(sk):
                    if pool[code, (a * BRICK + b) * BRICK + c]:
                        total += 1
    return total


@njit
def _first_free(table, pool, shape, bricks):  # pragma: no cover - compiled
    # Bricks are not in node order: scan them all and keep the smallest free node number.
    best = -1
    nyz = shape[1] * shape[2]
    for brick in range(table.shape[0]):
        code = table[brick]
        if code == FULL:
            continue
        i0, j0, k0, si, sj, sk = _brick_extent(shape, bricks, brick)
        first = -1
        for a in range(si):
            for b in range(sj):
                for c in range(sk):
                    if code == FREE or not pool[code, (a * BRICK + b) * BRICK + c]:
                        first = (i0 + a) * nyz + (j0 + b) * shape[2] + k0 + c
                        break
                if first >= 0:
                    break
            if first >= 0:
                break
        if first >= 0 and (best < 0 or first < best):
            best = first
    return best


@njit
def _unpack(table, pool, bricks, out):  # pragma: no cover - compiled
    shape = np.array(out.shape, dtype=np.int64)
    for brick in range(table.shape[0]):
        code = table[brick]
        if code == FREE:
            continue
        i0, j0, k0, si, sj, sk = _brick_extent(shape, bricks, brick)
        for a in range(si):
            for b in range(sj):
                for c in range(sk):
                    out[i0 + a, j0 + b, k0 + c] = (
                        code == FULL or pool[code, (a * BRICK + b) * BRICK + c])


@njit
def _unpack_window(table, pool, bricks, base, window):  # pragma: no cover - compiled
    """The nodes of a brick-aligned window (from node ``base`` on), from the bricks."""
    wi, wj, wk = window.shape
    for a in range(wi):
        i = base[0] + a
        for b in range(wj):
            j = base[1] + b
            for c in range(wk):
                window[a, b, c] = _node_blocked(table, pool, bricks, i, j, base[2] + c)


@njit
def _pack(window, base, shape, bricks, table, pool, used,
          states):  # pragma: no cover - compiled
    """File the bricks of a dense window (origin ``base``, brick-aligned) by their ``states``
    (:meth:`SparseBuilder.pack`); returns the pool rows in use. The pool has room for every
    brick filed from its nodes."""
    wi, wj, wk = window.shape
    for a0 in range(0, wi, BRICK):
        for b0 in range(0, wj, BRICK):
            for c0 in range(0, wk, BRICK):
                brick = _brick_of(bricks, base[0] + a0, base[1] + b0, base[2] + c0)
                state = states[a0 >> BRICK_BITS, b0 >> BRICK_BITS, c0 >> BRICK_BITS]
                if state == KNOWN_FREE:
                    table[brick] = FREE
                    continue
                if state == KNOWN_FULL:
                    table[brick] = FULL
                    continue
                si = min(BRICK, wi - a0)
                sj = min(BRICK, wj - b0)
                sk = min(BRICK, wk - c0)
                count = 0
                for a in range(si):
                    for b in range(sj):
                        for c in range(sk):
                            if window[a0 + a, b0 + b, c0 + c]:
                                count += 1
                if count == 0:
                    table[brick] = FREE
                elif count == si * sj * sk:
                    table[brick] = FULL
                else:
                    row = used
                    used += 1
                    for a in range(BRICK):
                        for b in range(BRICK):
                            for c in range(BRICK):
                                pool[row, (a * BRICK + b) * BRICK + c] = (
                                    a < si and b < sj and c < sk
                                    and window[a0 + a, b0 + b, c0 + c])
                    table[brick] = row
    return used
