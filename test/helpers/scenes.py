"""Random scenes and shortest paths computed independently of ``core.search``.

The 26-connected graph over the free nodes of a grid is built with numpy and solved with
``scipy.sparse.csgraph``, so the search, smoothing and timing tests compare the project's
results with a reference that shares none of its code.
"""

import itertools
import math
from typing import Callable, Tuple

import numpy as np
from scipy.sparse import coo_matrix, csr_matrix
from scipy.sparse.csgraph import dijkstra

from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, PointSet, Sphere

#: Seeds of :func:`random_scene` used by the smoothing and timing tests.
SEEDS = range(260)


def free_graph(blocked: np.ndarray, weight: Callable[[Tuple[int, int, int]], float],
               directed: bool = False) -> csr_matrix:
    """The 26-connected graph over the free nodes.

    Parameters
    ----------
    blocked : numpy.ndarray of bool, shape (nx, ny, nz)
    weight : callable
        Cost [m] of a step by an offset (di, dj, dk) in {-1, 0, 1}^3.
    directed : bool
        An edge for every offset; else each undirected edge once (the offsets whose first
        non-zero component is positive), for a symmetric ``weight``.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (N, N)
        Node ids are the C-order flat indices of ``blocked``. A step of cost 0 stays an edge
        (csgraph drops explicit zeros): it weighs the smallest positive float instead.
    """
    shape = blocked.shape
    ids = np.arange(blocked.size).reshape(shape)
    free = ~blocked
    rows, cols, weights = [], [], []
    for offset in itertools.product((-1, 0, 1), repeat=3):
        nonzero = [s for s in offset if s != 0]
        if not nonzero or (not directed and nonzero[0] < 0):
            continue
        src = tuple(slice(max(0, -s), n - max(0, s)) for s, n in zip(offset, shape))
        dst = tuple(slice(max(0, s), n - max(0, -s)) for s, n in zip(offset, shape))
        both = free[src] & free[dst]
        rows.append(ids[src][both])
        cols.append(ids[dst][both])
        weights.append(np.full(int(both.sum()), weight(offset)))
    values = np.maximum(np.concatenate(weights), 1e-300)
    return coo_matrix((values, (np.concatenate(rows), np.concatenate(cols))),
                      shape=(blocked.size, blocked.size)).tocsr()


def length_graph(blocked: np.ndarray, resolution: float) -> csr_matrix:
    """:func:`free_graph` with each edge weighing its length [m] (``resolution`` per axis)."""
    return free_graph(blocked, lambda offset: resolution * math.sqrt(sum(map(abs, offset))))


def graph_distances(blocked: np.ndarray, resolution: float, source: int) -> np.ndarray:
    """Shortest 26-connected distance [m] from flat node ``source`` to every node (inf if cut)."""
    return dijkstra(length_graph(blocked, resolution), directed=False, indices=source)


def csgraph_path(grid: VoxelGrid, blocked: np.ndarray, start, goal):
    """Shortest 26-connected path over free nodes [m] (M, 3) from ``start`` to ``goal``, or None.

    ``start`` and ``goal`` are points [m], snapped to their nodes; None when either node is
    blocked or no path joins them.
    """
    free = ~blocked.reshape(-1)
    source = int(grid.ravel(grid.world_to_index(np.asarray(start))))
    target = int(grid.ravel(grid.world_to_index(np.asarray(goal))))
    if not (free[source] and free[target]):
        return None
    dist, pred = dijkstra(length_graph(blocked, grid.resolution), directed=False,
                          indices=source, return_predecessors=True)
    if not np.isfinite(dist[target]):
        return None
    chain = [target]
    while chain[-1] != source:
        chain.append(int(pred[chain[-1]]))
    return grid.index_to_world(grid.unravel(np.array(chain[::-1])))


def random_scene(seed: int):
    """A random scene with a raw node path: (grid, obstacles, gamma, path) or None.

    Mixes spheres, boxes and point clouds; every third scene has a wall with a narrow opening
    (width between 2 gamma + delta / 2 and 2 gamma + 3 delta) that the path must squeeze through.
    """
    rng = np.random.default_rng(seed)
    delta = float(rng.choice([0.25, 0.3, 0.4, 0.5]))
    gamma = float(rng.uniform(0.0, 0.6)) if seed % 5 else 0.6
    extent = rng.uniform(3.0, 6.0, size=3)
    extent[2] = rng.uniform(2.0, 4.0)
    grid = VoxelGrid.from_bounds(np.zeros(3), extent, delta)
    top = grid.upper_node
    items = []
    if seed % 3 == 0:
        # A wall across x with a square opening; the ends of the path sit on either side.
        x0 = 0.5 * top[0] - 0.2
        width = 2.0 * gamma + rng.uniform(0.5, 3.0) * delta
        centre = rng.uniform([0.3 * top[1], 0.3 * top[2]], [0.7 * top[1], 0.7 * top[2]])
        lo, hi = centre - width / 2, centre + width / 2
        thick = rng.uniform(0.1, 0.6)
        panes = ((-1, lo[0], -1, top[2] + 1), (hi[0], top[1] + 1, -1, top[2] + 1),
                 (lo[0], hi[0], -1, lo[1]), (lo[0], hi[0], hi[1], top[2] + 1))
        for ymin, ymax, zmin, zmax in panes:
            if ymax > ymin and zmax > zmin:
                items.append(Box([x0, ymin, zmin], [x0 + thick, ymax, zmax]))
    for _ in range(int(rng.integers(1, 6))):
        items.append(Sphere(rng.uniform(0, top), rng.uniform(0.2, 1.2)))
    for _ in range(int(rng.integers(0, 3))):
        corner = rng.uniform(0, top)
        items.append(Box(corner, corner + rng.uniform(0.2, 1.5, size=3)))
    for _ in range(int(rng.integers(0, 2))):
        centre = rng.uniform(0, top)
        items.append(PointSet(centre + rng.normal(scale=0.4, size=(int(rng.integers(3, 40)), 3))))
    obstacles = ObstacleSet(items)
    blocked = blocked_mask(grid, obstacles, gamma)
    # Start and goal: random free nodes on the two end faces (x = 0 and x = max).
    ends = []
    for face in (blocked[0], blocked[-1]):
        free = np.argwhere(~face)
        if not len(free):
            return None
        ends.append(free[int(rng.integers(len(free)))])
    start = grid.index_to_world([0, *ends[0]])
    goal = grid.index_to_world([grid.shape[0] - 1, *ends[1]])
    path = csgraph_path(grid, blocked, start, goal)
    if path is None or len(path) < 2:
        return None
    return grid, obstacles, gamma, path
