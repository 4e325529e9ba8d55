"""The block-sparse inflated mask, built and re-inflated window by window.

The grid is cut into windows of :data:`_WINDOW` nodes a side; each obstacle is listed under the
windows its reach (the very index ranges of the dense passes) meets, and only windows with an
obstacle are stamped, into one reused dense scratch block, by the kernels of the dense layout
(:mod:`~uav_global_planner.core.map.stamping`) with the window's origin, and packed into the
bricks of a :class:`~uav_global_planner.core.map.sparse_grid.SparseMask`. Height fields file the
bricks wholly inside or outside their blocked range from their column limits alone, so their
cost follows the surfaces, not the volume under them. Both layouts block the same nodes, to the
bit.
"""

import threading
from typing import Optional

import numpy as np

from uav_global_planner.core.checks import check_integer, check_non_negative
from uav_global_planner.core.map.build_steps import (Checkpoint, cpu_count, run_tasks,
                                                     THREADS)
from uav_global_planner.core.map.dense_inflation import bin_points, bucket, bucket_spans
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.map.point_inflation import points_in_box, relevant_points
from uav_global_planner.core.map.sparse_grid import (BRICK, FROM_NODES, KNOWN_FREE, SparseBuilder,
                                                     SparseMask)
from uav_global_planner.core.map.spatial_index import shape_bounds
from uav_global_planner.core.map.stamping import (block_ranges, clear_ranges, fill_brick_columns,
                                                  fill_columns, reach_states, stamp_boxes_in,
                                                  stamp_shapes_in, stamp_spheres_in,
                                                  terrain_states)
from uav_global_planner.core.map.terrain import column_limits

# Edge of the windows of the block-sparse build [nodes]: 64^3 = 262 144 nodes (a 256 KiB
# scratch block, cache-sized), a multiple of the brick edge.
_WINDOW = 8 * BRICK


def sparse_mask(grid: VoxelGrid, obstacles: ObstacleSet, gamma: float,
                checkpoint: Checkpoint = None) -> SparseMask:
    """The block-sparse mask, window by window (module notes of
    :mod:`~uav_global_planner.core.map.sparse_grid`).

    The grid is cut into windows of :data:`_WINDOW` nodes a side; each obstacle is listed under
    the windows its reach (the very index ranges of the dense passes) meets, and only windows
    with an obstacle are stamped, into one reused dense scratch block, by the kernels of the
    dense layout with the window's origin: node coordinates are formed from the global indices,
    so every node's test is the dense layout's, to the bit. Time and memory follow the
    obstacles' reach; windows no obstacle reaches cost nothing. Height fields file the bricks
    wholly inside or outside their blocked range from their column limits alone
    (:meth:`_SparseWork._build_window`), so their cost follows the surfaces, not the volume
    under them.
    """
    shape = np.asarray(grid.shape, dtype=np.int64)
    work = _SparseWork(grid, obstacles, gamma, np.zeros(3, np.int64), shape - 1, None,
                       checkpoint)
    builder = SparseBuilder(grid.shape, capacity=len(work.busy) * (_WINDOW // BRICK) ** 3)
    work.stamp(builder, work.busy, None, checkpoint)
    return builder.finish()


def reinflate_sparse(grid: VoxelGrid, obstacles: ObstacleSet, safety_margin: float,
                     blocked: SparseMask, tiles: np.ndarray, tile_nodes: int,
                     points: Optional[np.ndarray] = None) -> SparseMask:
    """:func:`reinflate_tiles` for a block-sparse mask: a new mask (``blocked`` is not changed)
    equal to ``blocked`` but for the nodes of the tiles, recomputed (same parameters, same
    conditions for an exact result).

    Only the build windows that hold a node of a tile are unpacked, cleared on the tiles'
    nodes, stamped again and packed; the rest of the table is copied (4 bytes a brick) and so
    is the pool, compacted when most of its rows are no longer used.
    """
    gamma = check_non_negative('safety_margin', safety_margin, 'm')
    tiles = np.ascontiguousarray(np.asarray(tiles, dtype=np.int64).reshape(-1, 3))
    size = check_integer('tile_nodes', tile_nodes, 1)
    if len(tiles) == 0:
        return blocked
    shape = np.asarray(grid.shape, dtype=np.int64)
    # Node ranges of the tiles, clipped to the grid.
    spans = np.stack([np.maximum(tiles * size, 0),
                      np.minimum((tiles + 1) * size - 1, shape - 1)], axis=1)
    first = spans[:, 0].min(axis=0)
    last = spans[:, 1].max(axis=0)
    cloud = obstacles.points if points is None else np.asarray(points, dtype=np.float64)
    if len(cloud):
        origin = np.asarray(grid.bounds_min, dtype=np.float64)
        low = origin + first * grid.resolution - (gamma + grid.resolution)
        high = origin + last * grid.resolution + (gamma + grid.resolution)
        cloud = cloud[np.all((cloud >= low) & (cloud <= high), axis=1)]
    work = _SparseWork(grid, obstacles, gamma, first, last, cloud.reshape(-1, 3))
    tile_start, tile_items = _bucket_ranges(np.ascontiguousarray(spans), work.windows)
    chosen = np.flatnonzero(np.diff(tile_start))
    builder = SparseBuilder.editing(blocked, len(chosen) * (_WINDOW // BRICK) ** 3)
    work.stamp(builder, chosen, (spans, tile_start, tile_items))
    return builder.finish()


class _SparseWork:
    """The obstacles of a block-sparse build, listed under the windows their reach meets.

    Ranges are clipped to the node box [first, last] (the whole grid for a build; the tiles'
    bounding box for a re-inflation); ``points`` replaces the obstacles' points when given.
    """

    def __init__(self, grid: VoxelGrid, obstacles: ObstacleSet, gamma: float,
                 first: np.ndarray, last: np.ndarray, points: Optional[np.ndarray],
                 checkpoint: Checkpoint = None) -> None:
        self.grid = grid
        self.obstacles = obstacles
        self.gamma = gamma
        self.shape = np.asarray(grid.shape, dtype=np.int64)
        self.windows = -(-self.shape // _WINDOW)
        self.origin = np.ascontiguousarray(grid.bounds_min, dtype=np.float64)
        self.delta = float(grid.resolution)
        no_ranges = np.zeros((0, 2, 3), dtype=np.int64)
        rows = np.asarray(obstacles.zone_rows, dtype=np.int64)
        self.zone_ranges = no_ranges
        if len(rows):
            lo, hi = shape_bounds(obstacles.shape_kind[rows], obstacles.shape_params[rows])
            self.zone_ranges = _clipped(block_ranges(grid, lo - gamma, hi + gamma), first, last)
        self.rows = np.ascontiguousarray(rows)
        self.centers = np.ascontiguousarray(obstacles.sphere_centers,
                                            dtype=np.float64).reshape(-1, 3)
        self.radii = np.ascontiguousarray(obstacles.sphere_radii, dtype=np.float64).reshape(-1)
        self.sphere_ranges = no_ranges
        if len(self.radii):
            reach = (self.radii + gamma)[:, None]
            self.sphere_ranges = _clipped(
                block_ranges(grid, self.centers - reach, self.centers + reach), first, last)
        self.mins = np.ascontiguousarray(obstacles.box_mins, dtype=np.float64).reshape(-1, 3)
        self.maxs = np.ascontiguousarray(obstacles.box_maxs, dtype=np.float64).reshape(-1, 3)
        self.box_ranges = no_ranges
        if len(self.mins):
            self.box_ranges = _clipped(block_ranges(grid, self.mins - gamma, self.maxs + gamma),
                                       first, last)
        cloud = obstacles.points if points is None else points
        self.points = np.empty((0, 3))
        if len(cloud):
            self.points = relevant_points(grid, cloud, gamma)
        #: The points by their nearest node, listed under the windows within their halo.
        self.bins = bin_points(self.points, self.origin, self.delta, gamma)
        self.lists = [_bucket_ranges(self.zone_ranges, self.windows),
                      _bucket_ranges(self.sphere_ranges, self.windows),
                      _bucket_ranges(self.box_ranges, self.windows),
                      bucket(self.bins, self.shape, _WINDOW)]
        self.first = np.asarray(first, dtype=np.int64)
        self.last = np.asarray(last, dtype=np.int64)
        #: Per height field: its column limits over [first, last] and whether it is 'below'.
        self.terrain = [(column_limits(field, self.origin, self.delta, self.first, self.last,
                                       gamma, checkpoint), field.side == 'below')
                        for field in obstacles.height_fields]
        #: Per height field, on a whole-grid box (a full build): the least and the greatest
        #: column limit of each brick column (8 x 8 grid columns).
        whole = bool(np.all(self.first == 0) and np.all(self.last == self.shape - 1))
        self.brick_limits = [_brick_column_limits(limits) for limits, _ in self.terrain
                             if whole]
        reached = np.any(np.stack([np.diff(start) for start, _ in self.lists]), axis=0)
        for limits, below in self.terrain:
            reached |= _terrain_windows(limits, below, self.first, self.last, self.windows)
        #: Windows some obstacle reaches.
        self.busy = np.flatnonzero(reached)

    def stamp(self, builder: SparseBuilder, windows: np.ndarray, clear,
              checkpoint: Checkpoint = None) -> None:
        """Stamp and pack ``windows``; with ``clear`` = (tile node ranges, their window lists),
        each window starts from the builder's bricks with the tiles' nodes cleared, else from
        free nodes. ``checkpoint`` is called between windows.

        A full build stamps the windows on up to :data:`THREADS` threads (the kernels release
        the interpreter lock), each into its own scratch block; packing is serialised. The
        rows the mixed bricks get then depend on the threads' order, the mask does not.
        """
        workers = 1 if clear is not None else min(THREADS, cpu_count(), len(windows) // 4)
        lock = threading.Lock()
        scratches = threading.local()

        def run(window: int) -> None:
            if not hasattr(scratches, 'block'):
                scratches.block = self._scratch()
            if clear is None:
                block, base, states = self._build_window(int(window), scratches.block)
            else:
                block, base = self._stamp_window(int(window), scratches.block, builder, clear)
                states = None
            with lock:
                builder.pack(block, base, states)

        run_tasks(list(windows), run, checkpoint, workers)

    def _scratch(self) -> np.ndarray:
        return np.zeros(int(np.prod(np.minimum(self.shape, _WINDOW))), dtype=np.bool_)

    def _build_window(self, window: int, scratch: np.ndarray):
        """One window of a full build (the box [first, last] is the whole grid): the dense
        block, its first node and the states of its bricks
        (:meth:`~uav_global_planner.core.map.sparse_grid.SparseBuilder.pack`).

        The height fields decide most bricks from their brick columns' least and greatest
        limits alone: a brick under (over) every limit of a side-``'below'`` (``'above'``)
        field is full, one that no field's blocked nodes reach stays free unless another
        obstacle's index range meets it (all of them when points reach the window). Only the
        remaining bricks are written, by the very passes of :meth:`_stamp_window`, and read.
        """
        base, extent = self._window_box(window)
        block = scratch[:int(np.prod(extent))].reshape(extent)
        states = np.full(tuple(-(-np.asarray(extent) // BRICK)), KNOWN_FREE, dtype=np.int8)
        for (_, below), (least, greatest) in zip(self.terrain, self.brick_limits):
            terrain_states(states, base, self.shape[2], least, greatest, below)
        items = [found[start[window]:start[window + 1]] for start, found in self.lists]
        if len(items[3]):
            states[states == KNOWN_FREE] = FROM_NODES
        for ranges, chosen in zip((self.zone_ranges, self.sphere_ranges, self.box_ranges),
                                  items[:3]):
            if len(chosen):
                reach_states(states, block, base, ranges, chosen)
        if not np.any(states == FROM_NODES):
            return block, base, states
        block[...] = False
        for limits, below in self.terrain:
            fill_brick_columns(block, base, states, self.first, limits, below)
        self._stamp_items(block, base, items)
        return block, base, states

    def _window_box(self, window: int):
        """First node and node counts of a window."""
        base = np.asarray(np.unravel_index(window, tuple(self.windows)), np.int64) * _WINDOW
        extent = tuple(int(e) for e in np.minimum(self.shape - base, _WINDOW))
        return base, extent

    def _stamp_window(self, window: int, scratch: np.ndarray, builder: SparseBuilder, clear):
        """One window stamped into ``scratch``: the dense block and its first node."""
        base, extent = self._window_box(window)
        block = scratch[:int(np.prod(extent))].reshape(extent)
        if clear is None:
            block[...] = False
        else:
            spans, start, found = clear
            builder.unpack(block, base)
            clear_ranges(block, base, spans, found[start[window]:start[window + 1]])
        items = [found[start[window]:start[window + 1]] for start, found in self.lists]
        for limits, below in self.terrain:
            fill_columns(block, base, self.first, self.last, limits, below)
        self._stamp_items(block, base, items)
        return block, base

    def _stamp_items(self, block: np.ndarray, base: np.ndarray, items) -> None:
        """Stamp the zones, spheres, boxes and points listed in ``items`` (one array of item
        numbers each) into the window ``block`` of the grid from node ``base`` on."""
        obstacles = self.obstacles
        gamma = self.gamma
        if len(items[0]):
            stamp_shapes_in(block, base, self.origin, self.delta, self.zone_ranges, self.rows,
                            items[0], obstacles.shape_kind, obstacles.shape_params,
                            obstacles.shape_vertices, obstacles.shape_vstart, gamma)
        if len(items[1]):
            stamp_spheres_in(block, base, self.origin, self.delta, self.sphere_ranges,
                             items[1], self.centers, self.radii, gamma)
        if len(items[2]):
            stamp_boxes_in(block, base, self.origin, self.delta, self.box_ranges, items[2],
                           self.mins, self.maxs, gamma)
        if len(items[3]):
            lo = np.maximum(base, self.first)
            hi = np.minimum(base + np.asarray(block.shape) - 1, self.last)
            if np.all(lo <= hi):
                points_in_box(block, base, self.grid, self.bins, items[3], lo, hi, gamma)


def _brick_column_limits(limits: np.ndarray):
    """The least and the greatest of the column limits of each brick column (the columns
    ``[8 a, 8 a + 8) x [8 b, 8 b + 8)`` of ``limits``, clipped to it)."""
    pad = [(0, -n % BRICK) for n in limits.shape]
    full = np.pad(limits, pad, mode='edge')
    bricks = full.reshape(full.shape[0] // BRICK, BRICK, full.shape[1] // BRICK, BRICK)
    return (np.ascontiguousarray(bricks.min(axis=(1, 3))),
            np.ascontiguousarray(bricks.max(axis=(1, 3))))


def _terrain_windows(limits: np.ndarray, below: bool, first: np.ndarray, last: np.ndarray,
                     windows: np.ndarray) -> np.ndarray:
    """Which build windows (flat, C order) hold a node that the column limits block."""
    reached = np.zeros(tuple(int(w) for w in windows), dtype=bool)
    for a in range(int(first[0] // _WINDOW), int(last[0] // _WINDOW) + 1):
        i0 = max(a * _WINDOW, int(first[0])) - int(first[0])
        i1 = min((a + 1) * _WINDOW - 1, int(last[0])) - int(first[0])
        for b in range(int(first[1] // _WINDOW), int(last[1] // _WINDOW) + 1):
            j0 = max(b * _WINDOW, int(first[1])) - int(first[1])
            j1 = min((b + 1) * _WINDOW - 1, int(last[1])) - int(first[1])
            part = limits[i0:i1 + 1, j0:j1 + 1]
            for c in range(int(first[2] // _WINDOW), int(last[2] // _WINDOW) + 1):
                k0 = max(c * _WINDOW, int(first[2]))
                k1 = min((c + 1) * _WINDOW - 1, int(last[2]))
                reached[a, b, c] = (part.max() > k0) if below else (part.min() <= k1)
    return reached.reshape(-1)


def _clipped(ranges: np.ndarray, first: np.ndarray, last: np.ndarray) -> np.ndarray:
    """Index ranges clipped to the node box [first, last] (empty ones stay empty)."""
    out = ranges.copy()
    out[:, 0] = np.maximum(out[:, 0], first)
    out[:, 1] = np.minimum(out[:, 1], last)
    return np.ascontiguousarray(out)


def _bucket_ranges(ranges: np.ndarray, windows: np.ndarray):
    """Items listed under the windows their index ranges meet: ``start`` (one per window and one
    more) and ``items`` (C order over windows, items in order within a window)."""
    # C-contiguous lows and highs, as the dense layout passes them (one specialisation).
    return bucket_spans(np.ascontiguousarray(ranges[:, 0, :]),
                        np.ascontiguousarray(ranges[:, 1, :]), _WINDOW, windows)
