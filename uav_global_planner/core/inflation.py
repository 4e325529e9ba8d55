"""Safety-margin inflation of the voxel grid (paper eqs. 8-10).

A node is blocked (C(P) = 1) iff its Euclidean distance to the nearest obstacle is <= gamma. Each
obstacle only touches the nodes inside its bounding box grown by gamma, so the work is a few
vectorised passes over small sub-blocks, never a Python loop over voxels.
"""

import numpy as np
from scipy.spatial import cKDTree

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.grid import VoxelGrid
from uav_global_planner.core.obstacles import box_distance, ObstacleSet, sphere_distance

# Largest number of (point, nearby node) pairs, or of nodes, handled at once when inflating
# point sets: bounds the temporary memory (about 100 bytes each) whatever gamma / delta and the
# number of points.
_PAIR_BUDGET = 1 << 18
# Above this many (point, nearby node) pairs per grid node, point sets are inflated by a
# nearest-point query of every node instead.
_PAIRS_PER_NODE = 8


def _node_block(grid: VoxelGrid, lo: np.ndarray, hi: np.ndarray):
    """Index slices and node positions of the sub-block covering world box [lo, hi].

    Returns ``None`` when the box misses the grid.
    """
    # Clip to [-2, N + 1] cells in floating point before the cast (the same block results):
    # far-reaching obstacles (a ground slab of +-1e30 m) would overflow int64 and wrap to a
    # block that misses the grid.
    top = np.asarray(grid.shape, dtype=np.float64) + 1.0
    first = np.floor(np.clip((lo - grid.bounds_min) / grid.resolution, -2.0, top)).astype(
        np.int64) - 1
    last = np.ceil(np.clip((hi - grid.bounds_min) / grid.resolution, -2.0, top)).astype(
        np.int64) + 1
    first = np.maximum(first, 0)
    last = np.minimum(last, np.asarray(grid.shape) - 1)
    if np.any(first > last):
        return None
    slices = tuple(slice(int(a), int(b) + 1) for a, b in zip(first, last))
    axes = [grid.axis_coordinates(axis)[slices[axis]] for axis in range(3)]
    positions = np.stack(np.meshgrid(*axes, indexing='ij'), axis=-1)
    return slices, positions


def blocked_mask(grid: VoxelGrid, obstacles: ObstacleSet, safety_margin: float) -> np.ndarray:
    """Boolean occupancy of every node: True where the distance to an obstacle is <= gamma.

    Parameters
    ----------
    grid : VoxelGrid
    obstacles : ObstacleSet
    safety_margin : float
        gamma [m], >= 0.

    Returns
    -------
    numpy.ndarray of bool, shape ``grid.shape``
    """
    gamma = float(safety_margin)
    if not np.isfinite(gamma) or gamma < 0.0:
        raise InvalidInputError(f'safety_margin must be a finite number >= 0 m, got {gamma}')
    blocked = np.zeros(grid.shape, dtype=bool)
    for center, radius in zip(obstacles.sphere_centers, obstacles.sphere_radii):
        reach = radius + gamma
        block = _node_block(grid, center - reach, center + reach)
        if block is not None:
            slices, positions = block
            near = sphere_distance(positions, center[None, :], np.array([radius])) <= gamma
            blocked[slices] |= near
    for lo, hi in zip(obstacles.box_mins, obstacles.box_maxs):
        block = _node_block(grid, lo - gamma, hi + gamma)
        if block is not None:
            slices, positions = block
            blocked[slices] |= box_distance(positions, lo[None, :], hi[None, :]) <= gamma
    if len(obstacles.points):
        _mark_near_points(grid, obstacles.points, gamma, blocked)
    return blocked


def _mark_near_points(grid: VoxelGrid, points: np.ndarray, gamma: float,
                      blocked: np.ndarray) -> None:
    """Block every node within gamma of any occupied point, exactly, in place.

    Each point visits the cube of nodes within gamma / delta cells of it. That cube grows as
    (gamma / delta)^3 whatever the grid's size (gamma = 100 m at delta = 0.25 m: 5e8 nodes, a
    MemoryError), so when the points' cubes hold more nodes than the grid, every node asks a
    KD-tree of the points for its nearest one instead.
    """
    reach = int(np.ceil(gamma / grid.resolution)) + 1
    inside = grid.contains(points) | np.all(
        (points > grid.bounds_min - gamma - grid.resolution)
        & (points < grid.bounds_max + gamma + grid.resolution), axis=-1)
    relevant = points[inside]
    if len(relevant) * (2 * reach + 1) ** 3 > _PAIRS_PER_NODE * grid.size:
        _mark_by_nearest_point(grid, relevant, gamma, blocked)
        return
    steps = np.arange(-reach, reach + 1)
    offsets = np.stack(np.meshgrid(steps, steps, steps, indexing='ij'), axis=-1).reshape(-1, 3)
    shape = np.asarray(grid.shape)
    step = max(1, _PAIR_BUDGET // len(offsets))
    for start in range(0, len(relevant), step):
        chunk = relevant[start:start + step]
        base = np.rint((chunk - grid.bounds_min) / grid.resolution).astype(np.int64)
        candidates = base[:, None, :] + offsets[None, :, :]
        valid = np.all((candidates >= 0) & (candidates < shape), axis=-1)
        node_positions = grid.bounds_min + candidates * grid.resolution
        gap = np.sqrt(np.sum((node_positions - chunk[:, None, :]) ** 2, axis=-1))
        hit = candidates[valid & (gap <= gamma)]
        blocked[hit[:, 0], hit[:, 1], hit[:, 2]] = True


def _mark_by_nearest_point(grid: VoxelGrid, points: np.ndarray, gamma: float,
                           blocked: np.ndarray) -> None:
    """Block every node whose nearest point is within gamma, in chunks of nodes, in place."""
    tree = cKDTree(points)
    flat = blocked.reshape(-1)
    # The query prunes beyond the bound (strictly); the test below applies the rule exactly.
    upper = gamma + 1e-9 * (1.0 + gamma)
    for first in range(0, grid.size, _PAIR_BUDGET):
        number = np.arange(first, min(first + _PAIR_BUDGET, grid.size))
        nearest, _ = tree.query(grid.index_to_world(grid.unravel(number)),
                                distance_upper_bound=upper)
        flat[number] |= nearest <= gamma
