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

The work is split by job: the compiled kernels and their index ranges
(:mod:`~uav_global_planner.core.map.stamping`), the passes over point clouds
(:mod:`~uav_global_planner.core.map.point_inflation`), the block-sparse layout
(:mod:`~uav_global_planner.core.map.sparse_inflation`) and the pieces, checkpoints and threads
of a build (:mod:`~uav_global_planner.core.map.build_steps`); this module builds and re-inflates
whole-grid masks.
"""

from typing import Optional, Union

import numpy as np

from uav_global_planner.core.checks import check_integer, check_non_negative
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.build_steps import Checkpoint, in_chunks
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.map.point_inflation import mark_points, relevant_points
from uav_global_planner.core.map.sparse_grid import choose_layout, SparseMask
from uav_global_planner.core.map.sparse_inflation import sparse_mask
from uav_global_planner.core.map.spatial_index import shape_bounds, stamp_shapes
from uav_global_planner.core.map.stamping import (block_ranges, clear_tiles, fill_columns,
                                                  stamp_boxes, stamp_boxes_in, stamp_spheres,
                                                  stamp_spheres_in, ZERO_BASE)
from uav_global_planner.core.map.terrain import column_limits

#: A blocked mask in either layout.
Mask = Union[np.ndarray, SparseMask]


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
    gamma = check_non_negative('safety_margin', safety_margin, 'm')
    if out is None and choose_layout(grid.size, layout) == 'sparse':
        return sparse_mask(grid, obstacles, gamma, checkpoint)
    if out is None:
        blocked = np.zeros(grid.shape, dtype=bool)
    else:
        blocked = _checked_out(grid, out)
        blocked[...] = False
    _mark_compiled(grid, obstacles, gamma, blocked, checkpoint)
    _mark_terrain(grid, obstacles, gamma, blocked, ZERO_BASE, ZERO_BASE,
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
    gamma = check_non_negative('safety_margin', safety_margin, 'm')
    blocked = _checked_out(grid, blocked)
    tiles = np.ascontiguousarray(np.asarray(tiles, dtype=np.int64).reshape(-1, 3))
    size = check_integer('tile_nodes', tile_nodes, 1)
    if len(tiles) == 0:
        return
    clear_tiles(blocked, tiles, size)
    shape = np.asarray(grid.shape, dtype=np.int64)
    first = np.maximum(tiles.min(axis=0) * size, 0)
    last = np.minimum((tiles.max(axis=0) + 1) * size - 1, shape - 1)
    origin = np.ascontiguousarray(grid.bounds_min, dtype=np.float64)
    delta = float(grid.resolution)
    _mark_terrain(grid, obstacles, gamma, blocked, ZERO_BASE, first, last)
    rows = obstacles.zone_rows
    if len(rows):
        lo, hi = shape_bounds(obstacles.shape_kind[rows], obstacles.shape_params[rows])
        ranges, keep = _within(block_ranges(grid, lo - gamma, hi + gamma), first, last)
        if len(keep):
            stamp_shapes(blocked, origin, delta, ranges, np.ascontiguousarray(rows[keep]),
                         obstacles.shape_kind, obstacles.shape_params, obstacles.shape_vertices,
                         obstacles.shape_vstart, gamma)
    if len(obstacles.sphere_radii):
        centers = np.ascontiguousarray(obstacles.sphere_centers, dtype=np.float64)
        radii = np.ascontiguousarray(obstacles.sphere_radii, dtype=np.float64)
        reach = (radii + gamma)[:, None]
        ranges, keep = _within(block_ranges(grid, centers - reach, centers + reach), first,
                               last)
        if len(keep):
            stamp_spheres(blocked, origin, delta, ranges, np.ascontiguousarray(centers[keep]),
                          np.ascontiguousarray(radii[keep]), gamma)
    if len(obstacles.box_mins):
        mins = np.ascontiguousarray(obstacles.box_mins, dtype=np.float64)
        maxs = np.ascontiguousarray(obstacles.box_maxs, dtype=np.float64)
        ranges, keep = _within(block_ranges(grid, mins - gamma, maxs + gamma), first, last)
        if len(keep):
            stamp_boxes(blocked, origin, delta, ranges, np.ascontiguousarray(mins[keep]),
                        np.ascontiguousarray(maxs[keep]), gamma)
    cloud = obstacles.points if points is None else np.asarray(points, dtype=np.float64)
    if len(cloud):
        # Only points within gamma (and a cell of slack) of the tiles' nodes can block them.
        low = origin + first * delta - (gamma + delta)
        high = origin + last * delta + (gamma + delta)
        near = np.all((cloud >= low) & (cloud <= high), axis=1)
        cloud = relevant_points(grid, cloud[near], gamma)
        if len(cloud):
            mark_points(grid, cloud, gamma, blocked, first, last, None)


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
        fill_columns(block, base, first, last, limits, field.side == 'below')


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
                 float(grid.resolution), block_ranges(grid, lo - gamma, hi + gamma), rows,
                 obstacles.shape_kind, obstacles.shape_params, obstacles.shape_vertices,
                 obstacles.shape_vstart, gamma)


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
        ranges = block_ranges(grid, centers - reach, centers + reach)
        for items in in_chunks(ranges, checkpoint):
            stamp_spheres_in(blocked, ZERO_BASE, origin, delta, ranges, items, centers, radii,
                             gamma)
    if len(obstacles.box_mins):
        mins = np.ascontiguousarray(obstacles.box_mins, dtype=np.float64)
        maxs = np.ascontiguousarray(obstacles.box_maxs, dtype=np.float64)
        ranges = block_ranges(grid, mins - gamma, maxs + gamma)
        for items in in_chunks(ranges, checkpoint):
            stamp_boxes_in(blocked, ZERO_BASE, origin, delta, ranges, items, mins, maxs, gamma)
    if len(obstacles.points):
        if checkpoint is not None:
            checkpoint()
        points = relevant_points(grid, obstacles.points, gamma)
        if len(points):
            mark_points(grid, points, gamma, blocked, ZERO_BASE,
                        np.asarray(grid.shape, dtype=np.int64) - 1, checkpoint)
