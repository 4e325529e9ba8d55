"""The block-sparse grid layout against the dense one, and the search on large sparse grids.

- On random scenes (spheres, boxes, points, zones, a fence; points on the nodes, so that nodes
  tie at exactly gamma) both layouts block the same nodes, and the search finds the same paths
  and costs on both.
- On a large grid the optimal searches stay exactly optimal: compared with scipy's Dijkstra on
  the 26-connected graph of a walled-in crop.
- A grid of hundreds of millions of nodes plans, in a child process, without committing memory
  in proportion to its volume.
"""

import math
import subprocess
import sys
import textwrap
from typing import Dict, Hashable, List

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map import point_inflation, sparse_grid, sparse_inflation
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask
from uav_global_planner.core.map.live_map import LiveMapBuilder
from uav_global_planner.core.map.mask_buffers import MaskBuffers
from uav_global_planner.core.map.obstacles import Box, Obstacle, ObstacleSet, PointSet, Sphere
from uav_global_planner.core.map.sparse_grid import (choose_layout, first_free_node, FREE, FULL,
                                                     SparseMask)
from uav_global_planner.core.map.sparse_inflation import reinflate_sparse
from uav_global_planner.core.map.zones import Cylinder, InclusionCircle
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.search.grid_search import SearchWorkspace


def _scene(rng: np.random.Generator, grid: VoxelGrid, fence: bool) -> ObstacleSet:
    """Random spheres, boxes, points (half of them on nodes), a zone and maybe a fence."""
    lo = np.asarray(grid.bounds_min)
    hi = np.asarray(grid.upper_node)
    span = hi - lo
    items: List[Obstacle] = [
        Sphere(lo + rng.uniform(-0.1, 1.1, 3) * span, rng.uniform(0.05, 0.3) * span.min())
        for _ in range(rng.integers(1, 5))]
    for _ in range(rng.integers(1, 5)):
        corner = lo + rng.uniform(-0.1, 1.0, 3) * span
        items.append(Box(corner, corner + rng.uniform(0.01, 0.4, 3) * span))
    count = int(rng.integers(1, 400))
    on_nodes = grid.index_to_world(rng.integers(0, np.asarray(grid.shape), (count, 3)))
    anywhere = lo + rng.uniform(-0.05, 1.05, (count, 3)) * span
    items.append(PointSet(np.vstack([on_nodes, anywhere])))
    centre = lo + rng.uniform(0.2, 0.8, 3) * span
    items.append(Cylinder(centre[:2], 0.1 * span[:2].min(), centre[2] - 0.1 * span[2],
                          centre[2] + 0.1 * span[2]))
    if fence:
        items.append(InclusionCircle((lo[:2] + hi[:2]) / 2, 0.48 * span[:2].max()))
    return ObstacleSet(items)


def _dense(grid: VoxelGrid, obstacles: ObstacleSet, gamma: float) -> np.ndarray:
    """The dense-layout mask."""
    mask = blocked_mask(grid, obstacles, gamma, layout='dense')
    assert isinstance(mask, np.ndarray)
    return mask


# Shapes across several 64-node build windows and with partial bricks on every upper face.
GRIDS = [((0.0, 0.0, 0.0), (14.7, 6.3, 3.1), 0.1),
         ((-3.0, 2.0, -1.0), (3.3, 9.9, 20.0), 0.125),
         ((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), 0.25)]


@pytest.mark.parametrize('seed', range(12))
def test_sparse_and_dense_layouts_block_the_same_nodes(seed):
    rng = np.random.default_rng(seed)
    lo, hi, delta = GRIDS[seed % len(GRIDS)]
    grid = VoxelGrid.from_bounds(lo, hi, delta)
    obstacles = _scene(rng, grid, fence=seed % 4 == 3)
    # Margins that are whole multiples of delta make node-centred points tie at exactly gamma.
    gamma = float(rng.choice([0.0, delta, 2 * delta, rng.uniform(0.0, 4 * delta)]))
    dense = blocked_mask(grid, obstacles, gamma, layout='dense')
    sparse = blocked_mask(grid, obstacles, gamma, layout='sparse')
    assert isinstance(sparse, SparseMask) and isinstance(dense, np.ndarray)
    assert np.array_equal(sparse.to_dense(), dense)
    assert sparse.count_blocked() == int(dense.sum())
    assert first_free_node(sparse) == first_free_node(dense)
    nodes = rng.integers(0, np.asarray(grid.shape), (500, 3))
    assert np.array_equal(sparse.blocked_at(nodes), dense[tuple(nodes.T)])
    assert all(sparse[tuple(n)] == dense[tuple(n)] for n in nodes[:50])
    # Round trip through the dense form: the same free, full and mixed bricks.
    again = SparseMask.from_dense(dense)
    assert np.array_equal(np.minimum(again.table, 0), np.minimum(sparse.table, 0))
    assert again.brick_counts() == sparse.brick_counts()
    assert np.array_equal(again.to_dense(), dense)


def test_a_build_on_several_threads_blocks_the_same_nodes(monkeypatch):
    monkeypatch.setattr(sparse_inflation, 'cpu_count', lambda: 4)
    monkeypatch.setattr(point_inflation, 'cpu_count', lambda: 4)
    rng = np.random.default_rng(21)
    grid = VoxelGrid.from_bounds([0, 0, 0], [29.9, 29.9, 6.9], 0.1)  # 50 build windows
    obstacles = ObstacleSet([PointSet(rng.uniform(-0.5, 30.5, (20000, 3)) * [1, 1, 0.23]),
                             Box(np.array([3.0, 3, 0]), np.array([9.0, 25, 4])),
                             Sphere(np.array([20.0, 20, 3]), 2.5)])
    sparse = blocked_mask(grid, obstacles, 0.2, layout='sparse')
    assert isinstance(sparse, SparseMask)
    assert np.array_equal(sparse.to_dense(), _dense(grid, obstacles, 0.2))


def test_ties_at_exactly_gamma_are_blocked_in_both_layouts():
    grid = VoxelGrid.from_bounds([0, 0, 0], [9.5, 9.5, 9.5], 0.5)
    point = grid.index_to_world([[7, 9, 11]])
    for layout in ('dense', 'sparse'):
        mask = blocked_mask(grid, ObstacleSet([PointSet(point)]), 1.0, layout=layout)
        dense = mask.to_dense() if isinstance(mask, SparseMask) else mask
        # The node itself, the 6 at 0.5 m, the 12 at 0.71 m, the 8 at 0.87 m and the 6 at
        # exactly 1.0 m.
        assert dense.sum() == 33
        assert dense[9, 9, 11] and dense[7, 9, 13] and not dense[7, 9, 14]


@pytest.mark.parametrize('seed', range(6))
@pytest.mark.parametrize('algorithm', ['dijkstra', 'octile', 'astar', 'adaptive', 'weighted'])
def test_search_gives_the_same_paths_and_costs_on_both_layouts(seed, algorithm):
    rng = np.random.default_rng(100 + seed)
    lo, hi, delta = GRIDS[seed % 2]
    grid = VoxelGrid.from_bounds(lo, hi, delta)
    obstacles = _scene(rng, grid, fence=False)
    gamma = 2 * delta
    dense = blocked_mask(grid, obstacles, gamma, layout='dense')
    sparse = blocked_mask(grid, obstacles, gamma, layout='sparse')
    assert isinstance(dense, np.ndarray)
    free = np.argwhere(~dense)
    on_dense, on_sparse = SearchWorkspace(dense), SearchWorkspace(sparse)
    for _ in range(3):
        start, goal = free[rng.integers(0, len(free), 2)]
        try:
            expected = on_dense.search(start, goal, algorithm, delta, 1.5)
        except Exception as error:  # no path: both layouts must say so
            with pytest.raises(type(error)):
                on_sparse.search(start, goal, algorithm, delta, 1.5)
            continue
        found = on_sparse.search(start, goal, algorithm, delta, 1.5)
        assert found.cost_m == expected.cost_m
        assert found.expanded_nodes == expected.expanded_nodes
        assert np.array_equal(found.path_indices, expected.path_indices)


def test_layout_rule_and_forcing():
    assert choose_layout(sparse_grid.SPARSE_MIN_NODES - 1) == 'dense'
    assert choose_layout(sparse_grid.SPARSE_MIN_NODES) == 'sparse'
    assert choose_layout(10, 'sparse') == 'sparse'
    assert choose_layout(10 ** 9, 'dense') == 'dense'
    with pytest.raises(InvalidInputError, match='layout must be one of'):
        choose_layout(10, 'bricks')
    grid = VoxelGrid.from_bounds([0, 0, 0], [2, 2, 2], 0.5)
    with pytest.raises(InvalidInputError, match='layout'):
        blocked_mask(grid, ObstacleSet(), 0.1, layout='bricks')
    everything = blocked_mask(grid, ObstacleSet([Box(np.full(3, -1.0), np.full(3, 3.0))]), 0.0,
                              layout='sparse')
    assert isinstance(everything, SparseMask)
    assert everything.first_free() is None and everything.brick_counts() == (0, 1, 0)
    empty = blocked_mask(grid, ObstacleSet(), 0.0, layout='sparse')
    assert isinstance(empty, SparseMask) and empty.table.tolist() == [FREE]
    assert FULL != FREE


def test_planner_gives_the_same_plan_with_either_layout(monkeypatch):
    config = PlannerConfig(bounds_min=(0.0, 0.0, 0.0), bounds_max=(12.0, 8.0, 5.0),
                           resolution=0.125, safety_margin=0.25, algorithm='octile')
    obstacles = ObstacleSet([Box(np.array([3.0, -1, -1]), np.array([4.0, 6, 6])),
                             Sphere(np.array([8.0, 4, 2]), 1.5),
                             PointSet(np.random.default_rng(3).uniform(0, 12, (200, 3)))])
    plans = []
    for threshold in (10 ** 12, 0):  # dense everywhere, then sparse everywhere
        monkeypatch.setattr(sparse_grid, 'SPARSE_MIN_NODES', threshold)
        planner = Planner(config, obstacles)
        planner.warm_up()
        plans.append((planner.plan((0.5, 0.5, 0.5), (11.5, 7.5, 4.5)), planner.blocked))
    (dense_plan, dense), (sparse_plan, sparse) = plans
    assert isinstance(dense, np.ndarray) and isinstance(sparse, SparseMask)
    assert dense_plan.status.value == 'ok' and sparse_plan.status.value == 'ok'
    assert np.array_equal(dense_plan.path, sparse_plan.path)
    assert dense_plan.cost == sparse_plan.cost


def test_live_map_masks_of_sparse_grids_match_a_dense_build(monkeypatch):
    monkeypatch.setattr(sparse_grid, 'SPARSE_MIN_NODES', 0)
    grid = VoxelGrid.from_bounds([0, 0, 0], [10, 10, 4], 0.1)
    obstacles = ObstacleSet([Box(np.array([2.0, 2, 0]), np.array([3.0, 5, 2])),
                             PointSet(np.random.default_rng(5).uniform(0, 10, (300, 3)))])
    buffers = MaskBuffers(grid, 0.3)
    mask, update = buffers.write(obstacles, 1, None)
    assert isinstance(mask, SparseMask) and update.full
    assert np.array_equal(mask.to_dense(), _dense(grid, obstacles, 0.3))


def test_live_maps_of_sparse_grids_feed_the_planner(monkeypatch):
    monkeypatch.setattr(sparse_grid, 'SPARSE_MIN_NODES', 0)
    config = PlannerConfig(bounds_min=(0.0, 0.0, 0.0), bounds_max=(12.0, 8.0, 5.0),
                           resolution=0.125, safety_margin=0.25)
    rng = np.random.default_rng(11)
    builder = LiveMapBuilder(config, prior=rng.uniform(0, 12, (100, 3)) * [1, 8 / 12, 5 / 12])
    builder.want_fallback = True
    planner = Planner(config)
    incremental = 0
    for step in range(4):
        shapes: Dict[Hashable, Obstacle] = {
            ('wall', 0): Box(np.array([3.0 + step, -1, -1]), np.array([4.0 + step, 6, 6])),
            ('ball', 1): Sphere(np.array([9.0, 4, 2 + 0.1 * step]), 0.5)}
        cloud = rng.uniform(5, 7, (50, 3)) if step < 2 else None
        live = builder.update(shapes=shapes, cloud=cloud)
        incremental += not live.update.full
        assert isinstance(live.blocked, SparseMask) and isinstance(live.fallback, SparseMask)
        expected = _dense(planner.grid, live.obstacles, config.safety_margin)
        assert np.array_equal(live.blocked.to_dense(), expected)
        assert planner.set_map(live.obstacles, live.blocked, live.grid_key, live.fallback)
        result = planner.plan((0.5, 0.5, 0.5), (11.5, 7.5, 4.5))
        assert result.status.value == 'ok'
        assert not live.blocked.blocked_at(planner.grid.world_to_index(result.path)).any()
    assert incremental >= 2


@pytest.mark.parametrize('seed', range(6))
def test_reinflating_tiles_of_a_sparse_mask_gives_a_full_rebuild(seed):
    rng = np.random.default_rng(300 + seed)
    grid = VoxelGrid.from_bounds([0, 0, 0], [18.7, 11.2, 5.1], 0.1)
    before = _scene(rng, grid, fence=seed % 3 == 2)
    gamma = float(rng.choice([0.1, 0.2, 0.33]))
    old = blocked_mask(grid, before, gamma, layout='sparse')
    assert isinstance(old, SparseMask)
    # Move a box and a sphere, change the points near a spot.
    spot = np.asarray(grid.bounds_min) + rng.uniform(0.2, 0.8, 3) * (grid.upper_node
                                                                     - grid.bounds_min)
    moved: List[Obstacle] = [Box(spot - 0.5, spot + rng.uniform(0.1, 1.0, 3)),
                             Sphere(spot + 1.0, 0.4)]
    kept: List[Obstacle] = [o for o in before.items if not isinstance(o, PointSet)]
    old_points = before.points[np.linalg.norm(before.points - spot, axis=1) > 2.5]
    new_points = spot + rng.uniform(-1.5, 1.5, (40, 3))
    after = ObstacleSet(kept + moved + [PointSet(np.vstack([old_points, new_points]))])
    # Tiles of 12 nodes over everything within 2.5 m + gamma + a cell of the spot.
    size = 12
    reach = 2.5 + 1.0 + gamma + grid.resolution
    lo = np.maximum(grid.world_to_index(spot - reach) // size, 0)
    hi = grid.world_to_index(spot + reach) // size
    axes = [np.arange(a, b + 1) for a, b in zip(lo, hi)]
    tiles = np.stack(np.meshgrid(*axes, indexing='ij'), axis=-1).reshape(-1, 3)
    new = reinflate_sparse(grid, after, gamma, old, tiles, size)
    assert np.array_equal(new.to_dense(), _dense(grid, after, gamma))
    assert np.array_equal(old.to_dense(), _dense(grid, before, gamma))


def _crop_costs(mask: np.ndarray, delta: float, start: int) -> np.ndarray:
    """Shortest step-length sums from ``start`` over the free nodes of a 26-connected crop."""
    shape = mask.shape
    numbers = np.arange(mask.size).reshape(shape)
    rows, cols, weights = [], [], []
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            for dk in (-1, 0, 1):
                if (di, dj, dk) == (0, 0, 0):
                    continue
                src = tuple(slice(max(0, -d), n - max(0, d)) for d, n in zip((di, dj, dk), shape))
                dst = tuple(slice(max(0, d), n - max(0, -d)) for d, n in zip((di, dj, dk), shape))
                both = ~mask[src] & ~mask[dst]
                rows.append(numbers[src][both])
                cols.append(numbers[dst][both])
                step = delta * math.sqrt(abs(di) + abs(dj) + abs(dk))
                weights.append(np.full(int(both.sum()), step))
    graph = coo_matrix((np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))),
                       shape=(mask.size, mask.size)).tocsr()
    return dijkstra(graph, indices=start)  # type: ignore[call-overload]


@pytest.mark.parametrize('algorithm', ['dijkstra', 'octile'])
def test_optimal_searches_stay_optimal_on_a_large_sparse_grid(algorithm):
    # 1201 x 1201 x 161 = 232 M nodes; a walled room of 40 x 40 x 25 nodes with obstacles in it.
    delta = 0.5
    grid = VoxelGrid.from_bounds([0, 0, 0], [600, 600, 80], delta)
    room_lo, room_hi = np.array([300.0, 200.0, 20.0]), np.array([320.0, 220.0, 32.5])
    wall, gamma = 1.0, 0.5
    walls: List[Obstacle] = []
    for axis in range(3):
        for side in (0, 1):
            lo, hi = room_lo - wall - gamma, room_hi + wall + gamma
            if side == 0:
                hi = hi.copy()
                hi[axis] = room_lo[axis] - gamma - 0.25
            else:
                lo = lo.copy()
                lo[axis] = room_hi[axis] + gamma + 0.25
            walls.append(Box(lo, hi))
    rng = np.random.default_rng(7)
    inside: List[Obstacle] = [
        Sphere(room_lo + rng.uniform(0.2, 0.8, 3) * (room_hi - room_lo), 1.5) for _ in range(3)]
    inside.append(Box(room_lo + [5.0, -1.0, -1.0], room_lo + [6.0, 15.0, 20.0]))
    inside.append(PointSet(room_lo + rng.uniform(0, 1, (60, 3)) * (room_hi - room_lo)))
    mask = blocked_mask(grid, ObstacleSet(walls + inside), gamma)
    assert isinstance(mask, SparseMask)
    first = grid.world_to_index(room_lo) - 3
    last = grid.world_to_index(room_hi) + 3
    axes = [np.arange(a, b + 1) for a, b in zip(first, last)]
    crop_idx = np.stack(np.meshgrid(*axes, indexing='ij'), axis=-1).reshape(-1, 3)
    crop = mask.blocked_at(crop_idx).reshape([len(a) for a in axes])
    # The crop's outer shell is blocked: no path leaves it.
    for axis in range(3):
        assert crop.take(0, axis).all() and crop.take(-1, axis).all()
    free = np.argwhere(~crop)
    start, goal = free[0], free[-1]
    costs = _crop_costs(crop, delta, int(np.ravel_multi_index(tuple(start), crop.shape)))
    expected = costs[np.ravel_multi_index(tuple(goal), crop.shape)]
    found = SearchWorkspace(mask).search(start + first, goal + first, algorithm, delta, 1.5)
    assert np.isfinite(expected)
    assert found.cost_m == pytest.approx(expected, rel=1e-12, abs=1e-9)
    steps = np.diff(found.path_indices, axis=0)
    assert np.abs(steps).max() == 1
    assert not mask.blocked_at(found.path_indices).any()


_CHILD = textwrap.dedent("""
    import json, os
    import numpy as np
    from uav_global_planner.core.config import PlannerConfig
    from uav_global_planner.core.map.obstacles import Box, ObstacleSet, Sphere
    from uav_global_planner.core.planner import Planner
    from uav_global_planner.core.map.sparse_grid import SparseMask

    def rss():
        with open('/proc/self/statm') as handle:
            return int(handle.read().split()[1]) * os.sysconf('SC_PAGE_SIZE')

    config = PlannerConfig(bounds_min=(0.0, 0.0, 0.0), bounds_max=(1000.0, 1000.0, 60.0),
                           resolution=0.5, safety_margin=0.5, algorithm='adaptive')
    obstacles = ObstacleSet([Box([100, 80, 0], [140, 160, 40]), Sphere([200, 200, 20], 8)])
    planner = Planner(config, obstacles)
    planner.warm_up()
    # A short plan first: it compiles (or loads) every kernel the long one runs, so that what
    # is measured is the long plan's memory, not the compiler's.
    assert planner.plan((50.0, 50.0, 10.0), (52.0, 50.0, 10.0)).status.value == 'ok'
    before = rss()
    result = planner.plan((50.0, 50.0, 10.0), (260.0, 240.0, 12.0))
    print(json.dumps(dict(nodes=planner.grid.size, grown=rss() - before,
                          status=result.status.value,
                          sparse=isinstance(planner.blocked, SparseMask))))
""")


def test_a_huge_grid_plans_without_memory_in_proportion_to_its_volume():
    done = subprocess.run([sys.executable, '-c', _CHILD], capture_output=True, text=True,
                          timeout=300, check=True)
    figures = eval(done.stdout.strip().splitlines()[-1], {'true': True, 'false': False})
    assert figures['nodes'] > 480_000_000 and figures['sparse']
    assert figures['status'] == 'ok'
    # A dense mask alone would be one byte a node (480 MB), the search records 17 more.
    assert figures['grown'] < 150_000_000
