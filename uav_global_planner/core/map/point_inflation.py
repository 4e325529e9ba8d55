"""Inflating point clouds: each box of the grid by its cheapest exact pass.

Each occupied point stamps its ball of radius gamma into the grid, testing the nodes of the
ball, about pi / 6 (2 gamma / delta + 3)^3 of them, so a cloud costs time proportional to
points x (gamma / delta)^3 however large the grid. Dense clouds, whose balls would visit every
node several times (a scan at a few centimetres: a dozen points a cell), go box by box through
the exact distance transform of their cells
(:mod:`~uav_global_planner.core.map.dense_inflation`, time close to linear in the grid), or,
when gamma spans so many cells that its boxes would be huge, a nearest-point query of every
node; each box takes the cheapest of the three (:func:`points_in_box`), all of them exact.
"""

import math

import numpy as np

from uav_global_planner.core.map.build_steps import (Checkpoint, cpu_count, run_tasks,
                                                     STAMP_CHUNK, THREADS)
from uav_global_planner.core.map.dense_inflation import (bin_points, bucket, CellBins, mark_box,
                                                         transform_cost)
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.sparse_grid import BRICK
from uav_global_planner.core.map.stamping import stamp_points_in, ZERO_BASE

# Largest number of nodes one nearest-point query of the KD-tree handles at once: bounds its
# temporary memory (about 100 bytes a node) whatever the window's size.
_PAIR_BUDGET = 1 << 18
#: When the points' balls visit more than this many nodes per grid node (heavily overlapping
#: balls: gamma many times delta in a dense cloud), a nearest-point query of every node is
#: cheaper. A compiled visit costs about 1-3 ns and a KD-tree query of a node about 1 us.
VISITS_PER_NODE_COMPILED = 300.0
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


def relevant_points(grid: VoxelGrid, points: np.ndarray, gamma: float) -> np.ndarray:
    """The points that can be within gamma of a node: inside the bounds grown by gamma + delta.

    Points outside the grid still block the nodes within gamma of them.
    """
    reach = gamma + grid.resolution
    inside = grid.contains(points) | np.all(
        (points > grid.bounds_min - reach) & (points < grid.bounds_max + reach), axis=-1)
    if inside.all():
        return np.ascontiguousarray(points, dtype=np.float64)  # no copy of a large map
    return np.ascontiguousarray(points[inside], dtype=np.float64)


def mark_points(grid: VoxelGrid, points: np.ndarray, gamma: float, blocked: np.ndarray,
                first: np.ndarray, last: np.ndarray, checkpoint: Checkpoint) -> None:
    """Block the nodes within gamma of ``points`` (relevant ones) on a whole-grid mask, in
    place: every such node of the box [first, last], and no node a full build leaves free.

    A sparse cloud, whose balls visit fewer nodes than :data:`_CELL_COST` times the box has,
    stamps them (in chunks of points between checkpoints). A denser one goes box by box
    (:data:`_DENSE_BOX` nodes a side), each by its cheapest exact pass (:func:`points_in_box`),
    on up to :data:`THREADS` threads.
    """
    origin = np.ascontiguousarray(grid.bounds_min, dtype=np.float64)
    delta = float(grid.resolution)
    first = np.asarray(first, dtype=np.int64)
    last = np.asarray(last, dtype=np.int64)
    if ball_visits(grid, len(points), gamma) <= _CELL_COST * float(np.prod(last - first + 1)):
        ordered = in_memory_order(grid, points)
        step = max(1, int(STAMP_CHUNK // ball_visits(grid, 1, gamma)))
        for begin in range(0, len(ordered), step):
            if checkpoint is not None:
                checkpoint()
            stamp_points_in(blocked, ZERO_BASE, origin, delta, ordered,
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
        points_in_box(blocked, ZERO_BASE, grid, bins, task[2], task[0], task[1], gamma)

    run_tasks(tasks, run, checkpoint, min(THREADS, cpu_count(), len(tasks)))


def points_in_box(block: np.ndarray, base: np.ndarray, grid: VoxelGrid, bins: CellBins,
                  items: np.ndarray, lo: np.ndarray, hi: np.ndarray, gamma: float) -> None:
    """Block the nodes of the box [lo, hi] within gamma of ``bins.points[items]`` (every point
    whose cell lies within the halo of the box), on the window ``block`` of the grid from node
    ``base`` on, by the cheapest exact pass, costs counted in compiled visits: stamping each
    point's ball, the distance transform of the cells
    (:func:`~uav_global_planner.core.map.dense_inflation.mark_box`: :data:`_CELL_COST` a cell,
    and it gives up when its shell would cost more than the others), or a nearest-point query
    of each node (:data:`VISITS_PER_NODE_COMPILED` a node).
    """
    origin = np.ascontiguousarray(grid.bounds_min, dtype=np.float64)
    delta = float(grid.resolution)
    extent = hi - lo + 1
    nodes = float(np.prod(extent))
    stamp = len(items) * min(ball_visits(grid, 1, gamma), nodes)
    query = VISITS_PER_NODE_COMPILED * nodes
    cells = transform_cost(extent, bins.halo)
    transform = _CELL_COST * cells
    if bins.boxes_allowed and cells <= _MAX_TRANSFORM_CELLS and transform < min(stamp, query):
        if mark_box(block, base, bins, items, lo, hi, origin, delta, gamma,
                    min(stamp, query) - transform) >= 0:
            return
    window = block[tuple(slice(int(a), int(b) + 1) for a, b in zip(lo - base, hi - base + 1))]
    part = window if window.flags.c_contiguous else np.zeros(window.shape, dtype=bool)
    if stamp <= query:
        stamp_points_in(part, lo, origin, delta, bins.points, items, gamma)
    else:
        mark_by_nearest_point_in(grid, bins.points[items], gamma, part, lo)
    if part is not window:
        window |= part


def mark_by_nearest_point_in(grid: VoxelGrid, points: np.ndarray, gamma: float,
                             block: np.ndarray, base: np.ndarray) -> None:
    """Block every node of one window (from node ``base`` on) whose nearest point is within
    gamma, in chunks of nodes, in place. scipy's KD-tree forms the Euclidean distance with the
    same formula as the stamping (differences squared and summed in axis order, then the
    square root); its query prunes beyond the bound strictly, so the bound gets a hair of room
    and the test applies the rule exactly."""
    from scipy.spatial import cKDTree  # a slow import, for point clouds only
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


def in_memory_order(grid: VoxelGrid, points: np.ndarray) -> np.ndarray:
    """The points sorted by the mask position of their nearest node.

    Consecutive points then stamp neighbouring rows of the mask, which stay in the cache: on a
    mask larger than the cache, points in random order miss it on nearly every row (a cloud of
    1 M scattered points on a 99 M-node grid stamped several times slower).
    """
    nearest = grid.world_to_index(points)
    order = np.argsort(grid.ravel(nearest), kind='stable')
    return np.ascontiguousarray(points[order])


def ball_visits(grid: VoxelGrid, count: int, gamma: float) -> float:
    """Nodes the stamping of ``count`` balls of radius gamma visits, about."""
    across = 2.0 * gamma / grid.resolution + 3.0
    per_point = min(across ** 3 * math.pi / 6.0 + across ** 2, float(grid.size))
    return count * per_point
