"""Safety-margin inflation of the voxel grid (paper eqs. 8-10).

A node is blocked (C(P) = 1) iff its Euclidean distance to the nearest obstacle is <= gamma. Each
obstacle only touches the nodes inside its reach, so the work follows the obstacles, never the
grid:

- a sphere or a box visits the rows of its bounding box grown by gamma; along each row the
  blocked nodes are one run, whose two ends the exact test finds;
- each occupied point of a point set stamps its ball of radius gamma into the grid, testing
  the nodes of the ball, about pi / 6 (2 gamma / delta + 3)^3 of them, so a cloud costs time
  proportional to points x (gamma / delta)^3 however large the grid. Only when the balls
  overlap so much that they would visit every node hundreds of times does each node ask a
  KD-tree of the points for its nearest one instead (time proportional to the nodes).

The passes are compiled loops (numba, see :mod:`uav_global_planner.core.jit`) that write straight
into the mask, without temporaries. Without numba the same rule runs as vectorised numpy passes
over the same sub-blocks. Both evaluate the distance with one floating-point formula, the one of
:mod:`uav_global_planner.core.obstacles` (node coordinate ``min + i * delta``, differences
squared and summed x, y, z in that order, then the square root), so they give identical masks
to the last bit, ties at exactly gamma included.
"""

import math
from typing import Optional

import numpy as np
from scipy.spatial import cKDTree

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.grid import VoxelGrid
from uav_global_planner.core.jit import JIT_ENABLED, njit
from uav_global_planner.core.obstacles import box_distance, ObstacleSet, sphere_distance
from uav_global_planner.core.spatial_index import shape_bounds, stamp_shapes

# Largest number of (point, nearby node) pairs, or of nodes, handled at once by the vectorised
# passes: bounds their temporary memory (about 100 bytes each) whatever gamma / delta and the
# number of points.
_PAIR_BUDGET = 1 << 18
# When the points' balls visit more than this many nodes per grid node (heavily overlapping
# balls: gamma many times delta in a dense cloud), a nearest-point query of every node is
# cheaper. A compiled visit costs about 1-3 ns and a KD-tree query of a node about 1 us; the
# vectorised visits cost about 100 ns.
_VISITS_PER_NODE_COMPILED = 300.0
_VISITS_PER_NODE_VECTORISED = 8.0
# Slack of the per-point index ranges, in cells and relative to the coordinates: far larger
# than any rounding of them, far smaller than a cell. The ranges only decide which nodes are
# tested; with the slack, every node outside them is certainly further than gamma.
_RANGE_SLACK_CELLS = 1e-6
_RANGE_SLACK_RELATIVE = 1e-12
# Relative slack on gamma^2 for skipping a row whose x-y distance alone exceeds gamma: the sum
# with a non-negative dz^2 can only grow, so the exact test could not pass anywhere on the row.
_ROW_SLACK = 1e-9


def blocked_mask(grid: VoxelGrid, obstacles: ObstacleSet, safety_margin: float,
                 out: Optional[np.ndarray] = None) -> np.ndarray:
    """Boolean occupancy of every node: True where the distance to an obstacle is <= gamma.

    Parameters
    ----------
    grid : VoxelGrid
    obstacles : ObstacleSet
    safety_margin : float
        gamma [m], >= 0.
    out : numpy.ndarray of bool, shape ``grid.shape``, optional
        C-contiguous mask to overwrite instead of allocating a new one (a live map reuses its
        buffers).

    Returns
    -------
    numpy.ndarray of bool, shape ``grid.shape``
        ``out`` when given.

    Raises
    ------
    InvalidInputError
        If ``safety_margin`` is negative or not finite.
    """
    gamma = _checked_margin(safety_margin)
    if out is None:
        blocked = np.zeros(grid.shape, dtype=bool)
    else:
        blocked = _checked_out(grid, out)
        blocked[...] = False
    if JIT_ENABLED:
        _mark_compiled(grid, obstacles, gamma, blocked)
    else:
        _mark_vectorised(grid, obstacles, gamma, blocked)
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
    if not JIT_ENABLED:
        blocked_mask(grid, obstacles, gamma, out=blocked)
        return
    _clear_tiles(blocked, tiles, size)
    shape = np.asarray(grid.shape, dtype=np.int64)
    first = np.maximum(tiles.min(axis=0) * size, 0)
    last = np.minimum((tiles.max(axis=0) + 1) * size - 1, shape - 1)
    origin = np.ascontiguousarray(grid.bounds_min, dtype=np.float64)
    delta = float(grid.resolution)
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
            _stamp_points(blocked, origin, delta, _in_memory_order(grid, cloud), gamma)


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
                   blocked: np.ndarray) -> None:
    """Every obstacle's nodes within gamma, by the compiled loops, in place."""
    _mark_zones(grid, obstacles, gamma, blocked)
    origin = np.ascontiguousarray(grid.bounds_min, dtype=np.float64)
    delta = float(grid.resolution)
    if len(obstacles.sphere_radii):
        centers = np.ascontiguousarray(obstacles.sphere_centers, dtype=np.float64)
        radii = np.ascontiguousarray(obstacles.sphere_radii, dtype=np.float64)
        reach = (radii + gamma)[:, None]
        ranges = _block_ranges(grid, centers - reach, centers + reach)
        _stamp_spheres(blocked, origin, delta, ranges, centers, radii, gamma)
    if len(obstacles.box_mins):
        mins = np.ascontiguousarray(obstacles.box_mins, dtype=np.float64)
        maxs = np.ascontiguousarray(obstacles.box_maxs, dtype=np.float64)
        ranges = _block_ranges(grid, mins - gamma, maxs + gamma)
        _stamp_boxes(blocked, origin, delta, ranges, mins, maxs, gamma)
    if len(obstacles.points):
        points = _relevant_points(grid, obstacles.points, gamma)
        if len(points) == 0:
            return
        if _ball_visits(grid, len(points), gamma) > _VISITS_PER_NODE_COMPILED * grid.size:
            _mark_by_nearest_point(grid, points, gamma, blocked)
        else:
            _stamp_points(blocked, origin, delta, _in_memory_order(grid, points), gamma)


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
def _stamp_spheres(blocked, origin, delta, ranges, centers, radii, gamma):  # pragma: no cover
    # The distance is formed exactly as in obstacles._nearest_sphere_gap, dx, dy, dz being the
    # node minus the centre; the node is blocked iff max(gap, 0) <= gamma, i.e. gap <= gamma.
    # Along a z row the computed dz is monotone in k (rounding is monotone), so the computed
    # distance falls and then rises: the blocked nodes of a row are one run. Its two ends are
    # found with the exact test and the nodes between them are blocked without one.
    for s in range(radii.shape[0]):
        for i in range(ranges[s, 0, 0], ranges[s, 1, 0] + 1):
            dx = (origin[0] + i * delta) - centers[s, 0]
            for j in range(ranges[s, 0, 1], ranges[s, 1, 1] + 1):
                dy = (origin[1] + j * delta) - centers[s, 1]
                row = dx * dx + dy * dy
                first = ranges[s, 0, 2]
                last = ranges[s, 1, 2]
                while first <= last and not _sphere_hit(origin[2] + first * delta, row,
                                                        centers[s, 2], radii[s], gamma):
                    first += 1
                while last > first and not _sphere_hit(origin[2] + last * delta, row,
                                                       centers[s, 2], radii[s], gamma):
                    last -= 1
                for k in range(first, last + 1):
                    blocked[i, j, k] = True


@njit
def _sphere_hit(z, row, center_z, radius, gamma):  # pragma: no cover - compiled
    dz = z - center_z
    return math.sqrt(row + dz * dz) - radius <= gamma


@njit
def _stamp_boxes(blocked, origin, delta, ranges, mins, maxs, gamma):  # pragma: no cover
    # obstacles.box_distance per node: the excess beyond the box along each axis,
    # max(lo - p, p - hi, 0), squared and summed x, y, z, then the square root. The excess
    # along z falls and then rises with k, so, as for spheres, each row's blocked nodes are one
    # run between two ends found by the exact test.
    for b in range(mins.shape[0]):
        for i in range(ranges[b, 0, 0], ranges[b, 1, 0] + 1):
            x = origin[0] + i * delta
            ex = max(max(mins[b, 0] - x, x - maxs[b, 0]), 0.0)
            for j in range(ranges[b, 0, 1], ranges[b, 1, 1] + 1):
                y = origin[1] + j * delta
                ey = max(max(mins[b, 1] - y, y - maxs[b, 1]), 0.0)
                row = ex * ex + ey * ey
                first = ranges[b, 0, 2]
                last = ranges[b, 1, 2]
                while first <= last and not _box_hit(origin[2] + first * delta, row,
                                                     mins[b, 2], maxs[b, 2], gamma):
                    first += 1
                while last > first and not _box_hit(origin[2] + last * delta, row,
                                                    mins[b, 2], maxs[b, 2], gamma):
                    last -= 1
                for k in range(first, last + 1):
                    blocked[i, j, k] = True


@njit
def _box_hit(z, row, low, high, gamma):  # pragma: no cover - compiled
    ez = max(max(low - z, z - high), 0.0)
    return math.sqrt(row + ez * ez) <= gamma


@njit
def _index_range(center, origin, delta, half, slack, count):  # pragma: no cover - compiled
    """First and last node index within ``half`` metres of ``center`` on one axis, widened by
    ``slack`` cells and clipped to [0, count - 1] (first > last when empty)."""
    low = (center - origin - half) / delta - slack
    high = (center - origin + half) / delta + slack
    # Clipped before the cast, so that far points cannot overflow it.
    low = min(max(low, -2.0), count + 1.0)
    high = min(max(high, -2.0), count + 1.0)
    first = max(int(math.floor(low)), 0)
    last = min(int(math.ceil(high)), count - 1)
    return first, last


@njit
def _stamp_points(blocked, origin, delta, points, gamma):  # pragma: no cover - compiled
    # Each point visits the nodes of its ball: the x range within gamma, for each x the y range
    # within sqrt(gamma^2 - dx^2), for each (x, y) the z range within sqrt(gamma^2 - dx^2 - dy^2),
    # every range widened by a slack far above rounding. Which nodes are blocked is decided by
    # the exact rule on the same formula as the vectorised pass, so the ranges only save work.
    # Rows are a few nodes long: each node is tested, without a branch (which, in a dense
    # cloud whose balls overlap, would be mispredicted about as often as not).
    nx, ny, nz = blocked.shape
    squared = gamma * gamma * (1.0 + _ROW_SLACK)
    for n in range(points.shape[0]):
        px = points[n, 0]
        py = points[n, 1]
        pz = points[n, 2]
        scale = abs(px) + abs(py) + abs(pz) + abs(origin[0]) + abs(origin[1]) + abs(origin[2])
        slack = _RANGE_SLACK_CELLS + _RANGE_SLACK_RELATIVE * (scale + gamma) / delta
        i0, i1 = _index_range(px, origin[0], delta, gamma, slack, nx)
        for i in range(i0, i1 + 1):
            dx = (origin[0] + i * delta) - px
            across = squared - dx * dx
            if across < 0.0:
                continue
            j0, j1 = _index_range(py, origin[1], delta, math.sqrt(across), slack, ny)
            for j in range(j0, j1 + 1):
                dy = (origin[1] + j * delta) - py
                row = dx * dx + dy * dy
                if row > squared:
                    continue
                first, last = _index_range(pz, origin[2], delta, math.sqrt(squared - row),
                                           slack, nz)
                for k in range(first, last + 1):
                    blocked[i, j, k] |= _point_hit(origin[2] + k * delta, row, pz, gamma)


@njit
def _point_hit(z, row, point_z, gamma):  # pragma: no cover - compiled
    dz = z - point_z
    return math.sqrt(row + dz * dz) <= gamma


# --- vectorised passes (numba missing or disabled) ------------------------------------------

def _node_block(grid: VoxelGrid, lo: np.ndarray, hi: np.ndarray):
    """Index slices and node positions of the sub-block covering world box [lo, hi].

    Returns ``None`` when the box misses the grid.
    """
    (first, last), = _block_ranges(grid, lo[None, :], hi[None, :])
    if np.any(first > last):
        return None
    slices = tuple(slice(int(a), int(b) + 1) for a, b in zip(first, last))
    axes = [grid.axis_coordinates(axis)[slices[axis]] for axis in range(3)]
    positions = np.stack(np.meshgrid(*axes, indexing='ij'), axis=-1)
    return slices, positions


def _mark_vectorised(grid: VoxelGrid, obstacles: ObstacleSet, gamma: float,
                     blocked: np.ndarray) -> None:
    """Every obstacle's nodes within gamma, by numpy passes over sub-blocks, in place."""
    _mark_zones(grid, obstacles, gamma, blocked)
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
        _mark_near_points(grid, _relevant_points(grid, obstacles.points, gamma), gamma, blocked)


def _mark_near_points(grid: VoxelGrid, points: np.ndarray, gamma: float,
                      blocked: np.ndarray) -> None:
    """Block every node within gamma of any of ``points``, exactly, in place, vectorised.

    Each point visits the cube of nodes within gamma / delta cells of it, in chunks of bounded
    memory; when the cubes hold many more nodes than the grid, every node asks a KD-tree of the
    points for its nearest one instead.
    """
    if len(points) == 0:
        return
    reach = int(np.ceil(gamma / grid.resolution)) + 1
    if len(points) * (2 * reach + 1) ** 3 > _VISITS_PER_NODE_VECTORISED * grid.size:
        _mark_by_nearest_point(grid, points, gamma, blocked)
        return
    steps = np.arange(-reach, reach + 1)
    offsets = np.stack(np.meshgrid(steps, steps, steps, indexing='ij'), axis=-1).reshape(-1, 3)
    shape = np.asarray(grid.shape)
    step = max(1, _PAIR_BUDGET // len(offsets))
    for start in range(0, len(points), step):
        chunk = points[start:start + step]
        base = np.rint((chunk - grid.bounds_min) / grid.resolution).astype(np.int64)
        candidates = base[:, None, :] + offsets[None, :, :]
        valid = np.all((candidates >= 0) & (candidates < shape), axis=-1)
        node_positions = grid.bounds_min + candidates * grid.resolution
        gap = np.sqrt(np.sum((node_positions - chunk[:, None, :]) ** 2, axis=-1))
        hit = candidates[valid & (gap <= gamma)]
        blocked[hit[:, 0], hit[:, 1], hit[:, 2]] = True


def _mark_by_nearest_point(grid: VoxelGrid, points: np.ndarray, gamma: float,
                           blocked: np.ndarray) -> None:
    """Block every node whose nearest point is within gamma, in chunks of nodes, in place.

    scipy's KD-tree forms the Euclidean distance with the same formula (differences squared
    and summed in axis order, then the square root), so this agrees with the stamping passes.
    """
    tree = cKDTree(points)
    flat = blocked.reshape(-1)
    # The query prunes beyond the bound (strictly); the test below applies the rule exactly.
    upper = gamma + 1e-9 * (1.0 + gamma)
    for first in range(0, grid.size, _PAIR_BUDGET):
        number = np.arange(first, min(first + _PAIR_BUDGET, grid.size))
        nearest, _ = tree.query(grid.index_to_world(grid.unravel(number)),
                                distance_upper_bound=upper)
        flat[number] |= nearest <= gamma
