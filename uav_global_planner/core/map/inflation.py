"""Safety-margin inflation of the voxel grid (paper eqs. 8-10).

A node is blocked (C(P) = 1) iff its Euclidean distance to the nearest obstacle is <= gamma. Each
obstacle only touches the nodes inside its reach, so the work follows the obstacles, never the
grid:

- a sphere or a box visits the rows of its bounding box grown by gamma; along each row the
  blocked nodes are one run, whose two ends the exact test finds;
- each occupied point of a point set stamps its ball of radius gamma into the grid, testing
  the nodes of the ball, about pi / 6 (2 gamma / delta + 3)^3 of them, so a cloud costs time
  proportional to points x (gamma / delta)^3 however large the grid. Dense clouds, whose
  balls would visit every node several times (a scan at a few centimetres: a dozen points a
  cell), go box by box through the exact distance transform of their cells
  (:mod:`~uav_global_planner.core.map.dense_inflation`, time close to linear in the grid), or,
  when gamma spans so many cells that its boxes would be huge, a nearest-point query of every
  node; each box takes the cheapest of the three, all of them exact;
- a height field (terrain, ground, an AGL floor or ceiling) blocks, in each grid column, the
  nodes below (above) one limit, found by bisection on the terrain's own distance function
  (:func:`~uav_global_planner.core.map.terrain.column_limits`): its solid is closed downwards
  (upwards), so the distance is monotone along a column. In the block-sparse layout the least
  and greatest limits of each 8 x 8 column of bricks file whole bricks full, or leave them
  free, without writing their nodes; only the bricks the limits cross are written.

The passes are compiled loops (numba, see :mod:`uav_global_planner.core.jit`) that write straight
into the mask, without temporaries; there is one implementation of each (with
``UAV_PLANNER_DISABLE_JIT=1`` the same source runs as plain Python, slowly, for debugging). They
evaluate the distance with one floating-point formula, the one of
:mod:`uav_global_planner.core.map.obstacles` (node coordinate ``min + i * delta``, differences
squared and summed x, y, z in that order, then the square root), so the masks agree with
``ObstacleSet.distance(node) <= gamma`` to the last bit, ties at exactly gamma included.

One module, though long (about 1200 lines): every stamping kernel (spheres, boxes, points,
zones) must use the one floating-point formula and the one window scheme of both layouts, so
they stay side by side.
"""

from concurrent.futures import FIRST_EXCEPTION, ThreadPoolExecutor, wait
import math
import os
import threading
from typing import Callable, Optional, Sequence, Union

import numpy as np
from scipy.spatial import cKDTree

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.jit import njit
from uav_global_planner.core.map.dense_inflation import (bin_points, bucket, bucket_spans,
                                                         CellBins, mark_box, transform_cost)
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.map.sparse_grid import (BRICK, BRICK_BITS, choose_layout, FROM_NODES,
                                                     KNOWN_FREE, KNOWN_FULL, SparseBuilder,
                                                     SparseMask)
from uav_global_planner.core.map.spatial_index import (_column_part, _finish, shape_bounds,
                                                       stamp_shapes)
from uav_global_planner.core.map.terrain import column_limits

# Largest number of nodes one nearest-point query of the KD-tree handles at once: bounds its
# temporary memory (about 100 bytes a node) whatever the window's size.
_PAIR_BUDGET = 1 << 18
# When the points' balls visit more than this many nodes per grid node (heavily overlapping
# balls: gamma many times delta in a dense cloud), a nearest-point query of every node is
# cheaper. A compiled visit costs about 1-3 ns and a KD-tree query of a node about 1 us.
_VISITS_PER_NODE_COMPILED = 300.0
# A cell of the distance transform of dense clouds (with its halo: sorting the points in,
# three passes, the bounds) costs about as much as this many compiled visits (measured on a
# 2 cm room scan and a voxel map: 10-15 ns a cell against about 2 ns a visit). The exact test of
# its shell is counted at one visit per cell it reads.
_CELL_COST = 8.0
# Largest box of the distance transform, halo included [cells]: 8 bytes a cell of scratch.
# Beyond it (gamma hundreds of cells wide) the stamping or the nearest-point query is used.
_MAX_TRANSFORM_CELLS = 1 << 23
# Edge of the boxes of the transform on a whole-grid mask [nodes]: some 0.1 s of work each,
# the most a build overruns its checkpoint by.
_DENSE_BOX = 8 * BRICK
# Compiled visits between two checkpoints of the stamping of a sparse cloud: some 30 ms.
_STAMP_CHUNK = 1 << 24
# How often a build on several threads calls its checkpoint [s].
_POLL_S = 0.01

#: ``checkpoint()``: called between bounded pieces of a build, milliseconds apart; whatever it
#: raises stops the build (a plan's time budget: :meth:`~uav_global_planner.core.budget.
#: PlanBudget.check`).
Checkpoint = Optional[Callable[[], None]]

#: A blocked mask in either layout.
Mask = Union[np.ndarray, SparseMask]
# Slack of the per-point index ranges, in cells and relative to the coordinates: far larger
# than any rounding of them, far smaller than a cell. The ranges only decide which nodes are
# tested; with the slack, every node outside them is certainly further than gamma.
_RANGE_SLACK_CELLS = 1e-6
_RANGE_SLACK_RELATIVE = 1e-12
# Relative slack on gamma^2 for skipping a row whose x-y distance alone exceeds gamma: the sum
# with a non-negative dz^2 can only grow, so the exact test could not pass anywhere on the row.
_ROW_SLACK = 1e-9
# Edge of the windows of the block-sparse build [nodes]: 64^3 = 262 144 nodes (a 256 KiB
# scratch block, cache-sized), a multiple of the brick edge.
_WINDOW = 8 * BRICK
# Most threads a block-sparse build stamps its windows on.
_THREADS = 4
# Window origin of a whole-grid mask.
_ZERO_BASE = np.zeros(3, dtype=np.int64)
_ZERO_BASE.setflags(write=False)


def blocked_mask(grid: VoxelGrid, obstacles: ObstacleSet, safety_margin: float,
                 out: Optional[np.ndarray] = None, layout: str = 'auto',
                 checkpoint: Checkpoint = None) -> Mask:
    """Boolean occupancy of every node: True where the distance to an obstacle is <= gamma.

    Parameters
    ----------
    grid : VoxelGrid
    obstacles : ObstacleSet
    safety_margin : float
        gamma [m], >= 0.
    out : numpy.ndarray of bool, shape ``grid.shape``, optional
        C-contiguous mask to overwrite instead of allocating a new one (a live map reuses its
        buffers); implies the dense layout.
    layout : str
        ``'auto'``, ``'dense'`` or ``'sparse'``
        (:func:`~uav_global_planner.core.map.sparse_grid.choose_layout`): by default grids from
        :data:`~uav_global_planner.core.map.sparse_grid.SPARSE_MIN_NODES` nodes up get the
        block-sparse mask. Both layouts block the same nodes, to the bit.
    checkpoint : callable, optional
        :data:`Checkpoint`, called between pieces of the build (windows, boxes, chunks of
        points), milliseconds apart; what it raises stops the build and is raised here.

    Returns
    -------
    numpy.ndarray of bool, shape ``grid.shape``, or SparseMask
        ``out`` when given.

    Raises
    ------
    InvalidInputError
        If ``safety_margin`` is negative or not finite, or ``layout`` is unknown.
    """
    gamma = _checked_margin(safety_margin)
    if out is None and choose_layout(grid.size, layout) == 'sparse':
        return _sparse_mask(grid, obstacles, gamma, checkpoint)
    if out is None:
        blocked = np.zeros(grid.shape, dtype=bool)
    else:
        blocked = _checked_out(grid, out)
        blocked[...] = False
    _mark_compiled(grid, obstacles, gamma, blocked, checkpoint)
    _mark_terrain(grid, obstacles, gamma, blocked, _ZERO_BASE, _ZERO_BASE,
                  np.asarray(grid.shape, dtype=np.int64) - 1, checkpoint)
    return blocked


def reinflate_tiles(grid: VoxelGrid, obstacles: ObstacleSet, safety_margin: float,
                    blocked: np.ndarray, tiles: np.ndarray, tile_nodes: int,
                    points: Optional[np.ndarray] = None) -> None:
    """Recompute the nodes of some tiles of a mask, in place, as :func:`blocked_mask` would.

    A live map changes a little at a time; re-inflating only the tiles near what changed gives
    the mask of a full rebuild, to the bit, at a cost that follows the change. The nodes of the
    tiles are cleared and every obstacle within reach of them is stamped again by the very
    passes of :func:`blocked_mask`.

    Parameters
    ----------
    grid : VoxelGrid
    obstacles : ObstacleSet
        The obstacles now (spheres, boxes and zones are taken from here).
    safety_margin : float
        gamma [m], >= 0.
    blocked : numpy.ndarray of bool, shape ``grid.shape``
        C-contiguous mask, right for ``obstacles`` everywhere but in the tiles.
    tiles : numpy.ndarray of int, shape (K, 3)
        Tile indices; tile (a, b, c) holds the nodes ``[a T, (a + 1) T)`` x ... of each axis
        (T = ``tile_nodes``), clipped to the grid.
    tile_nodes : int
        Nodes per tile edge, >= 1.
    points : numpy.ndarray, shape (M, 3), optional
        The occupied points to stamp; they must include every point of ``obstacles`` within
        gamma of a node of the tiles. Default: ``obstacles.points``.

    Notes
    -----
    Stamping may also block nodes outside the tiles; it blocks only nodes that a full rebuild
    blocks too, so the result is exact when every obstacle within gamma of a node outside the
    tiles was the same when ``blocked`` was last right there. Without numba the whole mask is
    rebuilt (the same result, slower).
    """
    gamma = _checked_margin(safety_margin)
    blocked = _checked_out(grid, blocked)
    tiles = np.ascontiguousarray(np.asarray(tiles, dtype=np.int64).reshape(-1, 3))
    size = int(tile_nodes)
    if size < 1:
        raise InvalidInputError(f'tile_nodes must be >= 1, got {tile_nodes}')
    if len(tiles) == 0:
        return
    _clear_tiles(blocked, tiles, size)
    shape = np.asarray(grid.shape, dtype=np.int64)
    first = np.maximum(tiles.min(axis=0) * size, 0)
    last = np.minimum((tiles.max(axis=0) + 1) * size - 1, shape - 1)
    origin = np.ascontiguousarray(grid.bounds_min, dtype=np.float64)
    delta = float(grid.resolution)
    _mark_terrain(grid, obstacles, gamma, blocked, _ZERO_BASE, first, last)
    rows = obstacles.zone_rows
    if len(rows):
        lo, hi = shape_bounds(obstacles.shape_kind[rows], obstacles.shape_params[rows])
        ranges, keep = _within(_block_ranges(grid, lo - gamma, hi + gamma), first, last)
        if len(keep):
            stamp_shapes(blocked, origin, delta, ranges, np.ascontiguousarray(rows[keep]),
                         obstacles.shape_kind, obstacles.shape_params, obstacles.shape_vertices,
                         obstacles.shape_vstart, gamma)
    if len(obstacles.sphere_radii):
        centers = np.ascontiguousarray(obstacles.sphere_centers, dtype=np.float64)
        radii = np.ascontiguousarray(obstacles.sphere_radii, dtype=np.float64)
        reach = (radii + gamma)[:, None]
        ranges, keep = _within(_block_ranges(grid, centers - reach, centers + reach), first,
                               last)
        if len(keep):
            _stamp_spheres(blocked, origin, delta, ranges, np.ascontiguousarray(centers[keep]),
                           np.ascontiguousarray(radii[keep]), gamma)
    if len(obstacles.box_mins):
        mins = np.ascontiguousarray(obstacles.box_mins, dtype=np.float64)
        maxs = np.ascontiguousarray(obstacles.box_maxs, dtype=np.float64)
        ranges, keep = _within(_block_ranges(grid, mins - gamma, maxs + gamma), first, last)
        if len(keep):
            _stamp_boxes(blocked, origin, delta, ranges, np.ascontiguousarray(mins[keep]),
                         np.ascontiguousarray(maxs[keep]), gamma)
    cloud = obstacles.points if points is None else np.asarray(points, dtype=np.float64)
    if len(cloud):
        # Only points within gamma (and a cell of slack) of the tiles' nodes can block them.
        low = origin + first * delta - (gamma + delta)
        high = origin + last * delta + (gamma + delta)
        near = np.all((cloud >= low) & (cloud <= high), axis=1)
        cloud = _relevant_points(grid, cloud[near], gamma)
        if len(cloud):
            _mark_points(grid, cloud, gamma, blocked, first, last, None)


def _sparse_mask(grid: VoxelGrid, obstacles: ObstacleSet, gamma: float,
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
    gamma = _checked_margin(safety_margin)
    tiles = np.ascontiguousarray(np.asarray(tiles, dtype=np.int64).reshape(-1, 3))
    size = int(tile_nodes)
    if size < 1:
        raise InvalidInputError(f'tile_nodes must be >= 1, got {tile_nodes}')
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
            self.zone_ranges = _clipped(_block_ranges(grid, lo - gamma, hi + gamma), first, last)
        self.rows = np.ascontiguousarray(rows)
        self.centers = np.ascontiguousarray(obstacles.sphere_centers,
                                            dtype=np.float64).reshape(-1, 3)
        self.radii = np.ascontiguousarray(obstacles.sphere_radii, dtype=np.float64).reshape(-1)
        self.sphere_ranges = no_ranges
        if len(self.radii):
            reach = (self.radii + gamma)[:, None]
            self.sphere_ranges = _clipped(
                _block_ranges(grid, self.centers - reach, self.centers + reach), first, last)
        self.mins = np.ascontiguousarray(obstacles.box_mins, dtype=np.float64).reshape(-1, 3)
        self.maxs = np.ascontiguousarray(obstacles.box_maxs, dtype=np.float64).reshape(-1, 3)
        self.box_ranges = no_ranges
        if len(self.mins):
            self.box_ranges = _clipped(_block_ranges(grid, self.mins - gamma, self.maxs + gamma),
                                       first, last)
        cloud = obstacles.points if points is None else points
        self.points = np.empty((0, 3))
        if len(cloud):
            self.points = _relevant_points(grid, cloud, gamma)
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

        A full build stamps the windows on up to :data:`_THREADS` threads (the kernels release
        the interpreter lock), each into its own scratch block; packing is serialised. The
        rows the mixed bricks get then depend on the threads' order, the mask does not.
        """
        workers = 1 if clear is not None else min(_THREADS, _cpu_count(), len(windows) // 4)
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

        _run_tasks(list(windows), run, checkpoint, workers)

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
            _terrain_states(states, base, self.shape[2], least, greatest, below)
        items = [found[start[window]:start[window + 1]] for start, found in self.lists]
        if len(items[3]):
            states[states == KNOWN_FREE] = FROM_NODES
        for ranges, chosen in zip((self.zone_ranges, self.sphere_ranges, self.box_ranges),
                                  items[:3]):
            if len(chosen):
                _reach_states(states, block, base, ranges, chosen)
        if not np.any(states == FROM_NODES):
            return block, base, states
        block[...] = False
        for limits, below in self.terrain:
            _fill_brick_columns(block, base, states, self.first, limits, below)
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
            _clear_ranges(block, base, spans, found[start[window]:start[window + 1]])
        items = [found[start[window]:start[window + 1]] for start, found in self.lists]
        for limits, below in self.terrain:
            _fill_columns(block, base, self.first, self.last, limits, below)
        self._stamp_items(block, base, items)
        return block, base

    def _stamp_items(self, block: np.ndarray, base: np.ndarray, items) -> None:
        """Stamp the zones, spheres, boxes and points listed in ``items`` (one array of item
        numbers each) into the window ``block`` of the grid from node ``base`` on."""
        obstacles = self.obstacles
        gamma = self.gamma
        if len(items[0]):
            _stamp_shapes_in(block, base, self.origin, self.delta, self.zone_ranges, self.rows,
                             items[0], obstacles.shape_kind, obstacles.shape_params,
                             obstacles.shape_vertices, obstacles.shape_vstart, gamma)
        if len(items[1]):
            _stamp_spheres_in(block, base, self.origin, self.delta, self.sphere_ranges,
                              items[1], self.centers, self.radii, gamma)
        if len(items[2]):
            _stamp_boxes_in(block, base, self.origin, self.delta, self.box_ranges, items[2],
                            self.mins, self.maxs, gamma)
        if len(items[3]):
            lo = np.maximum(base, self.first)
            hi = np.minimum(base + np.asarray(block.shape) - 1, self.last)
            if np.all(lo <= hi):
                _points_in_box(block, base, self.grid, self.bins, items[3], lo, hi, gamma)


def _mark_terrain(grid: VoxelGrid, obstacles: ObstacleSet, gamma: float, block: np.ndarray,
                  base: np.ndarray, first: np.ndarray, last: np.ndarray,
                  checkpoint: Checkpoint = None) -> None:
    """Every height field's nodes within gamma in the node box [first, last] (inclusive), on
    the window ``block`` of the grid from node ``base`` on, in place (``checkpoint`` between
    pieces of the work).

    Each column's limit comes from :func:`~uav_global_planner.core.map.terrain.column_limits`,
    which decides every node it tests with the terrain's own distance function, so the mask
    agrees with ``ObstacleSet.distance`` to the bit.
    """
    if not obstacles.height_fields:
        return
    first = np.maximum(np.asarray(first, dtype=np.int64), 0)
    last = np.minimum(np.asarray(last, dtype=np.int64), np.asarray(grid.shape) - 1)
    if np.any(first > last):
        return
    origin = np.ascontiguousarray(grid.bounds_min, dtype=np.float64)
    for field in obstacles.height_fields:
        limits = column_limits(field, origin, float(grid.resolution), first, last, gamma,
                               checkpoint)
        _fill_columns(block, base, first, last, limits, field.side == 'below')


@njit
def _fill_columns(block, base, first, last, limits, below):  # pragma: no cover - compiled
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


def _brick_column_limits(limits: np.ndarray):
    """The least and the greatest of the column limits of each brick column (the columns
    ``[8 a, 8 a + 8) x [8 b, 8 b + 8)`` of ``limits``, clipped to it)."""
    pad = [(0, -n % BRICK) for n in limits.shape]
    full = np.pad(limits, pad, mode='edge')
    bricks = full.reshape(full.shape[0] // BRICK, BRICK, full.shape[1] // BRICK, BRICK)
    return (np.ascontiguousarray(bricks.min(axis=(1, 3))),
            np.ascontiguousarray(bricks.max(axis=(1, 3))))


@njit
def _terrain_states(states, base, nz, least, greatest, below):  # pragma: no cover - compiled
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
def _reach_states(states, block, base, ranges, items):  # pragma: no cover - compiled
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
def _fill_brick_columns(block, base, states, first, limits,
                        below):  # pragma: no cover - compiled
    """:func:`_fill_columns` on the :data:`FROM_NODES` bricks of the window ``block`` (from
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


def _cpu_count() -> int:
    """Processors this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _run_tasks(tasks: Sequence, run: Callable, checkpoint: Checkpoint, workers: int) -> None:
    """``run(task)`` for every task, on ``workers`` threads (the kernels release the
    interpreter lock) when it is 2 or more, calling ``checkpoint()`` between tasks (every
    :data:`_POLL_S` from this thread when there are workers). What a task or the checkpoint
    raises is raised here, once the other threads have finished the task in hand.
    """
    if workers < 2:
        for task in tasks:
            if checkpoint is not None:
                checkpoint()
            run(task)
        return
    stop = threading.Event()

    def part(chosen: Sequence) -> None:
        for task in chosen:
            if stop.is_set():
                return
            run(task)

    with ThreadPoolExecutor(max_workers=workers) as pool:
        futures = [pool.submit(part, tasks[w::workers]) for w in range(workers)]
        try:
            while True:
                done, pending = wait(futures, timeout=_POLL_S, return_when=FIRST_EXCEPTION)
                for future in done:
                    future.result()
                if not pending:
                    return
                if checkpoint is not None:
                    checkpoint()
        except BaseException:
            stop.set()
            raise


def _clipped(ranges: np.ndarray, first: np.ndarray, last: np.ndarray) -> np.ndarray:
    """Index ranges clipped to the node box [first, last] (empty ones stay empty)."""
    out = ranges.copy()
    out[:, 0] = np.maximum(out[:, 0], first)
    out[:, 1] = np.minimum(out[:, 1], last)
    return np.ascontiguousarray(out)


@njit
def _clear_ranges(block, base, spans, items):  # pragma: no cover - compiled
    """Clear the nodes of the ranges ``spans[items]`` inside the window ``block`` (from node
    ``base`` on)."""
    for n in range(items.shape[0]):
        i0, i1, j0, j1, k0, k1 = _window(spans, items[n], base, block)
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                for k in range(k0, k1 + 1):
                    block[i - base[0], j - base[1], k - base[2]] = False


def _bucket_ranges(ranges: np.ndarray, windows: np.ndarray):
    """Items listed under the windows their index ranges meet: ``start`` (one per window and one
    more) and ``items`` (C order over windows, items in order within a window)."""
    return bucket_spans(ranges[:, 0, :], ranges[:, 1, :], _WINDOW, windows)


@njit
def _stamp_shapes_in(blocked, base, origin, delta, ranges, rows, items, kind, prm, verts,
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


def _mark_by_nearest_point_in(grid: VoxelGrid, points: np.ndarray, gamma: float,
                              block: np.ndarray, base: np.ndarray) -> None:
    """Block every node of one window (from node ``base`` on) whose nearest point is within
    gamma, in chunks of nodes, in place. scipy's KD-tree forms the Euclidean distance with the
    same formula as the stamping (differences squared and summed in axis order, then the
    square root); its query prunes beyond the bound strictly, so the bound gets a hair of room
    and the test applies the rule exactly."""
    tree = cKDTree(points)
    upper = gamma + 1e-9 * (1.0 + gamma)
    axes = [np.arange(base[a], base[a] + block.shape[a]) for a in range(3)]
    flat = block.reshape(-1)
    local = np.stack(np.unravel_index(np.arange(block.size), block.shape), axis=-1)
    for first in range(0, block.size, _PAIR_BUDGET):
        part = local[first:first + _PAIR_BUDGET]
        indices = np.stack([axes[a][part[:, a]] for a in range(3)], axis=-1)
        nearest, _ = tree.query(grid.index_to_world(indices), distance_upper_bound=upper)
        flat[first:first + len(part)] |= nearest <= gamma


def _checked_margin(safety_margin: float) -> float:
    gamma = float(safety_margin)
    if not np.isfinite(gamma) or gamma < 0.0:
        raise InvalidInputError(f'safety_margin must be a finite number >= 0 m, got {gamma}')
    return gamma


def _checked_out(grid: VoxelGrid, out: np.ndarray) -> np.ndarray:
    """A mask to write into: bool, the grid's shape, C-contiguous (the kernels index it)."""
    if (not isinstance(out, np.ndarray) or out.dtype != np.bool_
            or tuple(out.shape) != tuple(grid.shape) or not out.flags.c_contiguous
            or not out.flags.writeable):
        raise InvalidInputError(
            f'the mask must be a writeable C-contiguous bool array of shape {tuple(grid.shape)}')
    return out


def _within(ranges: np.ndarray, first: np.ndarray, last: np.ndarray):
    """Index ranges clipped to the node window [first, last]; and which ones are not empty."""
    clipped = ranges.copy()
    clipped[:, 0] = np.maximum(clipped[:, 0], first)
    clipped[:, 1] = np.minimum(clipped[:, 1], last)
    keep = np.flatnonzero(np.all(clipped[:, 0] <= clipped[:, 1], axis=1))
    return np.ascontiguousarray(clipped[keep]), keep


@njit
def _clear_tiles(blocked, tiles, size):  # pragma: no cover - compiled
    nx, ny, nz = blocked.shape
    for t in range(tiles.shape[0]):
        i1 = min((tiles[t, 0] + 1) * size, nx)
        j1 = min((tiles[t, 1] + 1) * size, ny)
        k1 = min((tiles[t, 2] + 1) * size, nz)
        for i in range(max(tiles[t, 0] * size, 0), i1):
            for j in range(max(tiles[t, 1] * size, 0), j1):
                for k in range(max(tiles[t, 2] * size, 0), k1):
                    blocked[i, j, k] = False


def _block_ranges(grid: VoxelGrid, lows: np.ndarray, highs: np.ndarray) -> np.ndarray:
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


def _relevant_points(grid: VoxelGrid, points: np.ndarray, gamma: float) -> np.ndarray:
    """The points that can be within gamma of a node: inside the bounds grown by gamma + delta.

    Points outside the grid still block the nodes within gamma of them.
    """
    reach = gamma + grid.resolution
    inside = grid.contains(points) | np.all(
        (points > grid.bounds_min - reach) & (points < grid.bounds_max + reach), axis=-1)
    if inside.all():
        return np.ascontiguousarray(points, dtype=np.float64)  # no copy of a large map
    return np.ascontiguousarray(points[inside], dtype=np.float64)


def _mark_zones(grid: VoxelGrid, obstacles: ObstacleSet, gamma: float,
                blocked: np.ndarray) -> None:
    """Airspace zones and fences (the table rows of ``obstacles.zone_rows``), in place.

    One pass for both builds: it evaluates the shape table's own gap functions per node (the
    (x, y) part once per column), so the mask agrees with ``ObstacleSet.distance`` to the bit.
    A fence's block is the whole grid, its solid (the outside) being unbounded.
    """
    rows = obstacles.zone_rows
    if not len(rows):
        return
    lo, hi = shape_bounds(obstacles.shape_kind[rows], obstacles.shape_params[rows])
    stamp_shapes(blocked, np.ascontiguousarray(grid.bounds_min, dtype=np.float64),
                 float(grid.resolution), _block_ranges(grid, lo - gamma, hi + gamma), rows,
                 obstacles.shape_kind, obstacles.shape_params, obstacles.shape_vertices,
                 obstacles.shape_vstart, gamma)


# --- compiled passes ------------------------------------------------------------------------

def _mark_compiled(grid: VoxelGrid, obstacles: ObstacleSet, gamma: float,
                   blocked: np.ndarray, checkpoint: Checkpoint = None) -> None:
    """Every obstacle's nodes within gamma, by the compiled loops, in place."""
    _mark_zones(grid, obstacles, gamma, blocked)
    origin = np.ascontiguousarray(grid.bounds_min, dtype=np.float64)
    delta = float(grid.resolution)
    if len(obstacles.sphere_radii):
        centers = np.ascontiguousarray(obstacles.sphere_centers, dtype=np.float64)
        radii = np.ascontiguousarray(obstacles.sphere_radii, dtype=np.float64)
        reach = (radii + gamma)[:, None]
        ranges = _block_ranges(grid, centers - reach, centers + reach)
        for items in _in_chunks(ranges, checkpoint):
            _stamp_spheres_in(blocked, _ZERO_BASE, origin, delta, ranges, items, centers, radii,
                              gamma)
    if len(obstacles.box_mins):
        mins = np.ascontiguousarray(obstacles.box_mins, dtype=np.float64)
        maxs = np.ascontiguousarray(obstacles.box_maxs, dtype=np.float64)
        ranges = _block_ranges(grid, mins - gamma, maxs + gamma)
        for items in _in_chunks(ranges, checkpoint):
            _stamp_boxes_in(blocked, _ZERO_BASE, origin, delta, ranges, items, mins, maxs, gamma)
    if len(obstacles.points):
        if checkpoint is not None:
            checkpoint()
        points = _relevant_points(grid, obstacles.points, gamma)
        if len(points):
            _mark_points(grid, points, gamma, blocked, _ZERO_BASE,
                         np.asarray(grid.shape, dtype=np.int64) - 1, checkpoint)


def _in_chunks(ranges: np.ndarray, checkpoint: Checkpoint):
    """The item numbers of ``ranges`` (B, 2, 3 index ranges) in runs whose ranges hold about
    :data:`_STAMP_CHUNK` nodes together (one item at least), ``checkpoint()`` before each;
    all at once without a checkpoint."""
    if checkpoint is None:
        yield np.arange(len(ranges), dtype=np.int64)
        return
    sides = np.maximum(ranges[:, 1] - ranges[:, 0] + 1, 0).astype(np.float64)
    total = np.cumsum(np.prod(sides, axis=1))
    begin = 0
    while begin < len(ranges):
        checkpoint()
        done = float(total[begin - 1]) if begin else 0.0
        end = max(int(np.searchsorted(total, done + _STAMP_CHUNK, side='right')), begin + 1)
        yield np.arange(begin, end, dtype=np.int64)
        begin = end


def _mark_points(grid: VoxelGrid, points: np.ndarray, gamma: float, blocked: np.ndarray,
                 first: np.ndarray, last: np.ndarray, checkpoint: Checkpoint) -> None:
    """Block the nodes within gamma of ``points`` (relevant ones) on a whole-grid mask, in
    place: every such node of the box [first, last], and no node a full build leaves free.

    A sparse cloud, whose balls visit fewer nodes than :data:`_CELL_COST` times the box has,
    stamps them (in chunks of points between checkpoints). A denser one goes box by box
    (:data:`_DENSE_BOX` nodes a side), each by its cheapest exact pass (:func:`_points_in_box`),
    on up to :data:`_THREADS` threads.
    """
    origin = np.ascontiguousarray(grid.bounds_min, dtype=np.float64)
    delta = float(grid.resolution)
    first = np.asarray(first, dtype=np.int64)
    last = np.asarray(last, dtype=np.int64)
    if _ball_visits(grid, len(points), gamma) <= _CELL_COST * float(np.prod(last - first + 1)):
        ordered = _in_memory_order(grid, points)
        step = max(1, int(_STAMP_CHUNK // _ball_visits(grid, 1, gamma)))
        for begin in range(0, len(ordered), step):
            if checkpoint is not None:
                checkpoint()
            _stamp_points_in(blocked, _ZERO_BASE, origin, delta, ordered,
                             np.arange(begin, min(begin + step, len(ordered)), dtype=np.int64),
                             gamma)
        return
    bins = bin_points(points, origin, delta, gamma)
    shape = np.asarray(grid.shape, dtype=np.int64)
    start, items = bucket(bins, shape, _DENSE_BOX)
    tasks = []
    for box in np.flatnonzero(np.diff(start)):
        corner = np.asarray(np.unravel_index(box, tuple(-(-shape // _DENSE_BOX))),
                            dtype=np.int64) * _DENSE_BOX
        lo = np.maximum(corner, first)
        hi = np.minimum(corner + _DENSE_BOX - 1, last)
        if np.all(lo <= hi):
            tasks.append((lo, hi, items[start[box]:start[box + 1]]))

    def run(task) -> None:
        _points_in_box(blocked, _ZERO_BASE, grid, bins, task[2], task[0], task[1], gamma)

    _run_tasks(tasks, run, checkpoint, min(_THREADS, _cpu_count(), len(tasks)))


def _points_in_box(block: np.ndarray, base: np.ndarray, grid: VoxelGrid, bins: CellBins,
                   items: np.ndarray, lo: np.ndarray, hi: np.ndarray, gamma: float) -> None:
    """Block the nodes of the box [lo, hi] within gamma of ``bins.points[items]`` (every point
    whose cell lies within the halo of the box), on the window ``block`` of the grid from node
    ``base`` on, by the cheapest exact pass, costs counted in compiled visits: stamping each
    point's ball, the distance transform of the cells
    (:func:`~uav_global_planner.core.map.dense_inflation.mark_box`: :data:`_CELL_COST` a cell,
    and it gives up when its shell would cost more than the others), or a nearest-point query
    of each node (:data:`_VISITS_PER_NODE_COMPILED` a node).
    """
    origin = np.ascontiguousarray(grid.bounds_min, dtype=np.float64)
    delta = float(grid.resolution)
    extent = hi - lo + 1
    nodes = float(np.prod(extent))
    stamp = len(items) * min(_ball_visits(grid, 1, gamma), nodes)
    query = _VISITS_PER_NODE_COMPILED * nodes
    cells = transform_cost(extent, bins.halo)
    transform = _CELL_COST * cells
    if bins.boxes_allowed and cells <= _MAX_TRANSFORM_CELLS and transform < min(stamp, query):
        if mark_box(block, base, bins, items, lo, hi, origin, delta, gamma,
                    min(stamp, query) - transform) >= 0:
            return
    window = block[tuple(slice(int(a), int(b) + 1) for a, b in zip(lo - base, hi - base + 1))]
    part = window if window.flags.c_contiguous else np.zeros(window.shape, dtype=bool)
    if stamp <= query:
        _stamp_points_in(part, lo, origin, delta, bins.points, items, gamma)
    else:
        _mark_by_nearest_point_in(grid, bins.points[items], gamma, part, lo)
    if part is not window:
        window |= part


def _in_memory_order(grid: VoxelGrid, points: np.ndarray) -> np.ndarray:
    """The points sorted by the mask position of their nearest node.

    Consecutive points then stamp neighbouring rows of the mask, which stay in the cache: on a
    mask larger than the cache, points in random order miss it on nearly every row (a cloud of
    1 M scattered points on a 99 M-node grid stamped several times slower).
    """
    nearest = grid.world_to_index(points)
    order = np.argsort(grid.ravel(nearest), kind='stable')
    return np.ascontiguousarray(points[order])


def _ball_visits(grid: VoxelGrid, count: int, gamma: float) -> float:
    """Nodes the stamping of ``count`` balls of radius gamma visits, about."""
    across = 2.0 * gamma / grid.resolution + 3.0
    per_point = min(across ** 3 * math.pi / 6.0 + across ** 2, float(grid.size))
    return count * per_point


@njit
def _window(ranges, s, base, blocked):  # pragma: no cover - compiled
    """Index range of item ``s`` clipped to the window ``blocked`` of the grid at ``base``."""
    return (max(ranges[s, 0, 0], base[0]), min(ranges[s, 1, 0], base[0] + blocked.shape[0] - 1),
            max(ranges[s, 0, 1], base[1]), min(ranges[s, 1, 1], base[1] + blocked.shape[1] - 1),
            max(ranges[s, 0, 2], base[2]), min(ranges[s, 1, 2], base[2] + blocked.shape[2] - 1))


def _stamp_spheres(blocked, origin, delta, ranges, centers, radii, gamma) -> None:
    """Every sphere's nodes within gamma, on a whole-grid mask."""
    _stamp_spheres_in(blocked, _ZERO_BASE, origin, delta, ranges,
                      np.arange(len(radii), dtype=np.int64), centers, radii, gamma)


@njit
def _stamp_spheres_in(blocked, base, origin, delta, ranges, items, centers, radii,
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


def _stamp_boxes(blocked, origin, delta, ranges, mins, maxs, gamma) -> None:
    """Every box's nodes within gamma, on a whole-grid mask."""
    _stamp_boxes_in(blocked, _ZERO_BASE, origin, delta, ranges,
                    np.arange(len(mins), dtype=np.int64), mins, maxs, gamma)


@njit
def _stamp_boxes_in(blocked, base, origin, delta, ranges, items, mins, maxs,
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


def _stamp_points(blocked, origin, delta, points, gamma) -> None:
    """Every node within gamma of one of ``points``, on a whole-grid mask."""
    _stamp_points_in(blocked, _ZERO_BASE, origin, delta, points,
                     np.arange(len(points), dtype=np.int64), gamma)


@njit
def _stamp_points_in(blocked, base, origin, delta, points, items,
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
