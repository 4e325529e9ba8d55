"""The compiled stamping kernels of the inflation: each obstacle's nodes within gamma.

Every kernel writes straight into a mask window (a whole-grid mask, or the scratch block of one
window of the block-sparse build, from node ``base`` on; indices stay global), without
temporaries, and evaluates the distance with one floating-point formula, the one of
:mod:`uav_global_planner.core.map.obstacles` (node coordinate ``min + i * delta``, differences
squared and summed x, y, z in that order, then the square root), so the masks agree with
``ObstacleSet.distance(node) <= gamma`` to the last bit, ties at exactly gamma included. The
kernels share that formula and the window scheme, which is why they stay side by side here.
With ``UAV_PLANNER_DISABLE_JIT=1`` the same source runs as plain Python, slowly.

:func:`block_ranges` gives the index ranges the kernels visit.
"""

import math

import numpy as np

from uav_global_planner.core.jit import njit
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.sparse_grid import (BRICK, BRICK_BITS, FROM_NODES, KNOWN_FREE,
                                                     KNOWN_FULL)
from uav_global_planner.core.map.spatial_index import _column_part, _finish

# Slack of the per-point index ranges, in cells and relative to the coordinates: far larger
# than any rounding of them, far smaller than a cell. The ranges only decide which nodes are
# tested; with the slack, every node outside them is certainly further than gamma.
_RANGE_SLACK_CELLS = 1e-6
_RANGE_SLACK_RELATIVE = 1e-12
# Relative slack on gamma^2 for skipping a row whose x-y distance alone exceeds gamma: the sum
# with a non-negative dz^2 can only grow, so the exact test could not pass anywhere on the row.
_ROW_SLACK = 1e-9
#: Window origin of a whole-grid mask.
ZERO_BASE = np.zeros(3, dtype=np.int64)
ZERO_BASE.setflags(write=False)


def block_ranges(grid: VoxelGrid, lows: np.ndarray, highs: np.ndarray) -> np.ndarray:
    """First and last node index per axis of the sub-blocks covering world boxes [lo, hi].

    Parameters
    ----------
    lows, highs : numpy.ndarray, shape (B, 3)
        Box corners [m].

    Returns
    -------
    numpy.ndarray of int64, shape (B, 2, 3)
        ``[b, 0]`` the first and ``[b, 1]`` the last index; first > last on some axis when the
        box misses the grid.
    """
    # Clip to [-2, N + 1] cells in floating point before the cast (the same block results):
    # far-reaching obstacles (a ground slab of +-1e30 m) would overflow int64 and wrap to a
    # block that misses the grid.
    top = np.asarray(grid.shape, dtype=np.float64) + 1.0
    first = np.floor(np.clip((lows - grid.bounds_min) / grid.resolution, -2.0, top)).astype(
        np.int64) - 1
    last = np.ceil(np.clip((highs - grid.bounds_min) / grid.resolution, -2.0, top)).astype(
        np.int64) + 1
    first = np.maximum(first, 0)
    last = np.minimum(last, np.asarray(grid.shape, dtype=np.int64) - 1)
    return np.ascontiguousarray(np.stack([first, last], axis=1))


@njit
def _window(ranges, s, base, blocked):  # pragma: no cover - compiled
    """Index range of item ``s`` clipped to the window ``blocked`` of the grid at ``base``."""
    return (max(ranges[s, 0, 0], base[0]), min(ranges[s, 1, 0], base[0] + blocked.shape[0] - 1),
            max(ranges[s, 0, 1], base[1]), min(ranges[s, 1, 1], base[1] + blocked.shape[1] - 1),
            max(ranges[s, 0, 2], base[2]), min(ranges[s, 1, 2], base[2] + blocked.shape[2] - 1))


def stamp_spheres(blocked, origin, delta, ranges, centers, radii, gamma) -> None:
    """Every sphere's nodes within gamma, on a whole-grid mask."""
    stamp_spheres_in(blocked, ZERO_BASE, origin, delta, ranges,
                     np.arange(len(radii), dtype=np.int64), centers, radii, gamma)


@njit
def stamp_spheres_in(blocked, base, origin, delta, ranges, items, centers, radii,
                     gamma):  # pragma: no cover - compiled
    """The nodes within gamma of the spheres ``items``, on the window ``blocked`` of the grid
    from node ``base`` on (:func:`_stamp_in` with each sphere's centre as its extent)."""
    _stamp_in(blocked, base, origin, delta, ranges, items, centers, centers, centers[:, 2],
              radii, False, gamma)


@njit
def _row_hit(z, row, box, a, b, gamma):  # pragma: no cover - compiled
    """Exact test of the node at height ``z`` [m] of a row whose horizontal part of the squared
    distance is ``row`` [m^2]: a sphere of centre height ``a`` and radius ``b`` or, ``box``
    True, a box from height ``a`` to ``b`` [m]."""
    if box:
        ez = max(max(a - z, z - b), 0.0)
        return math.sqrt(row + ez * ez) <= gamma
    dz = z - a
    return math.sqrt(row + dz * dz) - b <= gamma


@njit
def _stamp_row(blocked, base, i, j, k0, k1, origin_z, delta, row, box, a, b,
               gamma):  # pragma: no cover - compiled
    """Block the run of hit nodes of row (i, j) within k0..k1 (:func:`_row_hit` of ``box``,
    ``a``, ``b``): its two ends found with the exact test, the nodes between them blocked."""
    first = k0
    last = k1
    while first <= last and not _row_hit(origin_z + first * delta, row, box, a, b, gamma):
        first += 1
    while last > first and not _row_hit(origin_z + last * delta, row, box, a, b, gamma):
        last -= 1
    for k in range(first, last + 1):
        blocked[i - base[0], j - base[1], k - base[2]] = True


def stamp_boxes(blocked, origin, delta, ranges, mins, maxs, gamma) -> None:
    """Every box's nodes within gamma, on a whole-grid mask."""
    stamp_boxes_in(blocked, ZERO_BASE, origin, delta, ranges,
                   np.arange(len(mins), dtype=np.int64), mins, maxs, gamma)


@njit
def stamp_boxes_in(blocked, base, origin, delta, ranges, items, mins, maxs,
                   gamma):  # pragma: no cover - compiled
    """The nodes within gamma of the boxes ``items``, on the window ``blocked`` of the grid
    from node ``base`` on (:func:`_stamp_in`)."""
    _stamp_in(blocked, base, origin, delta, ranges, items, mins, maxs, mins[:, 2], maxs[:, 2],
              True, gamma)


@njit(inline='always')
def _stamp_in(blocked, base, origin, delta, ranges, items, lows, highs, a, b, box,
              gamma):  # pragma: no cover - compiled
    # Inlined by numba into the sphere and the box kernel, each compiled with its own ``box``.
    # Item s spans lows[s] to highs[s] horizontally (a sphere: its centre, both times): the
    # horizontal part of a node's squared distance is the squared excess beyond that span
    # along x and y, max(lo - p, p - hi, 0) (for a sphere |p - c|, whose square is that of
    # p - c to the bit), as in obstacles._nearest_sphere_gap and obstacles.box_distance. The
    # vertical part (box: the excess beyond a[s]..b[s]; sphere: centre height a[s], radius
    # b[s]) falls and then rises along a z row (rounding is monotone), so each row's blocked
    # nodes are one run whose two ends :func:`_stamp_row` finds with the exact test. The mask
    # ``blocked`` is the window of the grid from node ``base`` on (indices stay global).
    for n in range(items.shape[0]):
        s = items[n]
        i0, i1, j0, j1, k0, k1 = _window(ranges, s, base, blocked)
        for i in range(i0, i1 + 1):
            x = origin[0] + i * delta
            ex = max(max(lows[s, 0] - x, x - highs[s, 0]), 0.0)
            for j in range(j0, j1 + 1):
                y = origin[1] + j * delta
                ey = max(max(lows[s, 1] - y, y - highs[s, 1]), 0.0)
                _stamp_row(blocked, base, i, j, k0, k1, origin[2], delta, ex * ex + ey * ey,
                           box, a[s], b[s], gamma)


@njit
def _index_range(cell, reach, start, count):  # pragma: no cover - compiled
    """First and last node index within ``reach`` cells of position ``cell`` [cells] on one
    axis, clipped to [start, start + count - 1] (first > last when empty)."""
    low = cell - reach
    high = cell + reach
    # Clipped before the cast, so that far points cannot overflow it.
    low = min(max(low, start - 2.0), start + count + 1.0)
    high = min(max(high, start - 2.0), start + count + 1.0)
    first = max(int(math.floor(low)), start)
    last = min(int(math.ceil(high)), start + count - 1)
    return first, last


def stamp_points(blocked, origin, delta, points, gamma) -> None:
    """Every node within gamma of one of ``points``, on a whole-grid mask."""
    stamp_points_in(blocked, ZERO_BASE, origin, delta, points,
                    np.arange(len(points), dtype=np.int64), gamma)


@njit
def stamp_points_in(blocked, base, origin, delta, points, items,
                    gamma):  # pragma: no cover - compiled
    # Each point visits the nodes of its ball: the x range within gamma, for each x the y range
    # within sqrt(gamma^2 - dx^2), for each (x, y) the z range within sqrt(gamma^2 - dx^2 - dy^2),
    # every range widened by a slack far above rounding. Which nodes are blocked is decided by
    # the exact rule on the formula of ObstacleSet.distance, so the ranges only save work.
    # Rows are a few nodes long: each node is tested, without a branch (which, in a dense
    # cloud whose balls overlap, would be mispredicted about as often as not).
    nx, ny, nz = blocked.shape
    squared = gamma * gamma * (1.0 + _ROW_SLACK)
    inverse = 1.0 / delta
    for m in range(items.shape[0]):
        n = items[m]
        px = points[n, 0]
        py = points[n, 1]
        pz = points[n, 2]
        scale = abs(px) + abs(py) + abs(pz) + abs(origin[0]) + abs(origin[1]) + abs(origin[2])
        slack = _RANGE_SLACK_CELLS + _RANGE_SLACK_RELATIVE * (scale + gamma) * inverse
        # Positions in cells; a product by 1 / delta instead of a quotient errs by far less
        # than the slack, and only decides which nodes are tested.
        cx = (px - origin[0]) * inverse
        cy = (py - origin[1]) * inverse
        cz = (pz - origin[2]) * inverse
        i0, i1 = _index_range(cx, gamma * inverse + slack, base[0], nx)
        for i in range(i0, i1 + 1):
            dx = (origin[0] + i * delta) - px
            across = squared - dx * dx
            if across < 0.0:
                continue
            j0, j1 = _index_range(cy, math.sqrt(across) * inverse + slack, base[1], ny)
            for j in range(j0, j1 + 1):
                dy = (origin[1] + j * delta) - py
                row = dx * dx + dy * dy
                if row > squared:
                    continue
                first, last = _index_range(cz, math.sqrt(squared - row) * inverse + slack,
                                           base[2], nz)
                for k in range(first, last + 1):
                    blocked[i - base[0], j - base[1], k - base[2]] |= _point_hit(
                        origin[2] + k * delta, row, pz, gamma)


@njit
def _point_hit(z, row, point_z, gamma):  # pragma: no cover - compiled
    dz = z - point_z
    return math.sqrt(row + dz * dz) <= gamma


@njit
def stamp_shapes_in(blocked, base, origin, delta, ranges, rows, items, kind, prm, verts,
                    vstart, gamma):  # pragma: no cover - compiled
    """:func:`~uav_global_planner.core.map.spatial_index.stamp_shapes` on the window ``blocked`` of
    the grid from node ``base`` on, for the table rows ``rows[items]`` (their index ranges
    ``ranges[items]``); the very same per-node test."""
    for n in range(items.shape[0]):
        r = items[n]
        s = rows[r]
        i0, i1, j0, j1, k0, k1 = _window(ranges, r, base, blocked)
        for i in range(i0, i1 + 1):
            x = origin[0] + i * delta
            for j in range(j0, j1 + 1):
                y = origin[1] + j * delta
                part = _column_part(kind, prm, verts, vstart, s, x, y)
                for k in range(k0, k1 + 1):
                    if max(_finish(kind, prm, s, part, origin[2] + k * delta), 0.0) <= gamma:
                        blocked[i - base[0], j - base[1], k - base[2]] = True


@njit
def clear_tiles(blocked, tiles, size):  # pragma: no cover - compiled
    nx, ny, nz = blocked.shape
    for t in range(tiles.shape[0]):
        i1 = min((tiles[t, 0] + 1) * size, nx)
        j1 = min((tiles[t, 1] + 1) * size, ny)
        k1 = min((tiles[t, 2] + 1) * size, nz)
        for i in range(max(tiles[t, 0] * size, 0), i1):
            for j in range(max(tiles[t, 1] * size, 0), j1):
                for k in range(max(tiles[t, 2] * size, 0), k1):
                    blocked[i, j, k] = False


@njit
def clear_ranges(block, base, spans, items):  # pragma: no cover - compiled
    """Clear the nodes of the ranges ``spans[items]`` inside the window ``block`` (from node
    ``base`` on)."""
    for n in range(items.shape[0]):
        i0, i1, j0, j1, k0, k1 = _window(spans, items[n], base, block)
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                for k in range(k0, k1 + 1):
                    block[i - base[0], j - base[1], k - base[2]] = False


@njit
def fill_columns(block, base, first, last, limits, below):  # pragma: no cover - compiled
    """Block, in each column of the node box [first, last], the nodes under its limit
    (``below``) or from it on (:func:`~uav_global_planner.core.map.terrain.column_limits`), within
    the window ``block`` of the grid from node ``base`` on."""
    i0 = max(first[0], base[0])
    i1 = min(last[0], base[0] + block.shape[0] - 1)
    j0 = max(first[1], base[1])
    j1 = min(last[1], base[1] + block.shape[1] - 1)
    k0 = max(first[2], base[2])
    k1 = min(last[2], base[2] + block.shape[2] - 1)
    for i in range(i0, i1 + 1):
        for j in range(j0, j1 + 1):
            limit = limits[i - first[0], j - first[1]]
            a = k0 if below else max(limit, k0)
            b = min(limit - 1, k1) if below else k1
            for k in range(a, b + 1):
                block[i - base[0], j - base[1], k - base[2]] = True


@njit
def terrain_states(states, base, nz, least, greatest, below):  # pragma: no cover - compiled
    """Fold one height field into the brick states of the window from node ``base`` on, from
    its brick columns' least and greatest limits (:func:`_brick_column_limits` of a whole-grid
    box; ``nz`` nodes along z): a brick all of whose nodes the field blocks becomes
    :data:`KNOWN_FULL`, one some of whose nodes it blocks :data:`FROM_NODES` unless known full.
    """
    a0 = base[0] >> BRICK_BITS
    b0 = base[1] >> BRICK_BITS
    for a in range(states.shape[0]):
        for b in range(states.shape[1]):
            low = least[a0 + a, b0 + b]
            high = greatest[a0 + a, b0 + b]
            for c in range(states.shape[2]):
                k0 = base[2] + c * BRICK
                k1 = min(k0 + BRICK - 1, nz - 1)
                if below:  # nodes k < limit blocked
                    full = low > k1
                    some = high > k0
                else:  # nodes k >= limit blocked
                    full = high <= k0
                    some = low <= k1
                if full:
                    states[a, b, c] = KNOWN_FULL
                elif some and states[a, b, c] == KNOWN_FREE:
                    states[a, b, c] = FROM_NODES


@njit
def reach_states(states, block, base, ranges, items):  # pragma: no cover - compiled
    """Mark :data:`FROM_NODES` the bricks of the window ``block`` (from node ``base`` on) that
    the index ranges ``ranges[items]`` meet, unless known full."""
    for n in range(items.shape[0]):
        i0, i1, j0, j1, k0, k1 = _window(ranges, items[n], base, block)
        if i0 > i1 or j0 > j1 or k0 > k1:
            continue
        for a in range((i0 - base[0]) >> BRICK_BITS, ((i1 - base[0]) >> BRICK_BITS) + 1):
            for b in range((j0 - base[1]) >> BRICK_BITS, ((j1 - base[1]) >> BRICK_BITS) + 1):
                for c in range((k0 - base[2]) >> BRICK_BITS,
                               ((k1 - base[2]) >> BRICK_BITS) + 1):
                    if states[a, b, c] == KNOWN_FREE:
                        states[a, b, c] = FROM_NODES


@njit
def fill_brick_columns(block, base, states, first, limits,
                       below):  # pragma: no cover - compiled
    """:func:`fill_columns` on the :data:`FROM_NODES` bricks of the window ``block`` (from
    node ``base`` on) only; the columns' limits are those of the box from node ``first`` on,
    which holds the window."""
    wi, wj, wk = block.shape
    for a in range(states.shape[0]):
        for b in range(states.shape[1]):
            for c in range(states.shape[2]):
                if states[a, b, c] != FROM_NODES:
                    continue
                k0 = c * BRICK
                k1 = min(k0 + BRICK, wk) - 1
                for i in range(a * BRICK, min(a * BRICK + BRICK, wi)):
                    for j in range(b * BRICK, min(b * BRICK + BRICK, wj)):
                        limit = limits[base[0] + i - first[0], base[1] + j - first[1]] - base[2]
                        lo = k0 if below else max(limit, k0)
                        hi = min(limit - 1, k1) if below else k1
                        for k in range(lo, hi + 1):
                            block[i, j, k] = True
