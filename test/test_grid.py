"""The voxel grid: node counts (eq. 7), index conversion (eq. 5) and input errors."""

import numpy as np
import pytest

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.grid import VoxelGrid


def test_paper_grid_has_41_41_31_nodes():
    grid = VoxelGrid.from_bounds([-10, -10, 0], [10, 10, 15], 0.5)
    assert grid.shape == (41, 41, 31)
    assert grid.size == 41 * 41 * 31


def test_fine_grid_counts_survive_floating_point_extents():
    # 15 / 0.1 is 149.99999999999997 in floating point: eq. 7 still gives 151 nodes.
    grid = VoxelGrid.from_bounds([-10, -10, 0], [10, 10, 15], 0.1)
    assert grid.shape == (201, 201, 151)


def test_extent_not_divisible_floors_the_count():
    grid = VoxelGrid.from_bounds([0, 0, 0], [1.0, 1.3, 2.0], 0.5)
    assert grid.shape == (3, 3, 5)
    assert np.allclose(grid.upper_node, [1.0, 1.0, 2.0])


@pytest.mark.parametrize('seed', range(20))
def test_index_world_round_trip(seed):
    rng = np.random.default_rng(seed)
    lo = rng.uniform(-5, 5, 3)
    grid = VoxelGrid.from_bounds(lo, lo + rng.uniform(1, 6, 3), rng.uniform(0.1, 0.7))
    idx = np.stack([rng.integers(0, n, 50) for n in grid.shape], axis=1)
    assert np.array_equal(grid.world_to_index(grid.index_to_world(idx)), idx)
    flat = grid.ravel(idx)
    assert np.array_equal(grid.unravel(flat), idx)
    # Points within half a cell snap to the node.
    jitter = rng.uniform(-0.49, 0.49, idx.shape) * grid.resolution
    assert np.array_equal(grid.world_to_index(grid.index_to_world(idx) + jitter), idx)


def test_contains_includes_the_boundary():
    grid = VoxelGrid.from_bounds([0, 0, 0], [1, 1, 1], 0.25)
    assert grid.contains([1.0, 1.0, 1.0])
    assert grid.contains([0.0, 0.5, 0.0])
    assert not grid.contains([1.01, 0.5, 0.5])
    assert not grid.contains([0.5, -0.01, 0.5])


@pytest.mark.parametrize('lo, hi, resolution, words', [
    ([0, 0, 0], [1, 1, 1], 0.0, 'resolution must be > 0 m, got 0.0'),
    ([0, 0, 0], [1, 1, 1], -0.5, 'resolution must be > 0 m, got -0.5'),
    ([0, 0, 0], [1, 1, 1], float('nan'), 'resolution must be finite, got nan'),
    ([0, 0, 0], [1, 1, 1], 'fine', 'resolution must be a number'),
    ([0, 0, 1], [1, 1, 1], 0.1, 'bounds.min must be below bounds.max'),
    ([2, 0, 0], [1, 1, 1], 0.1, 'bounds.min must be below bounds.max'),
    ([0, 0, float('inf')], [1, 1, 1], 0.1, 'bounds.min must be finite'),
    ([0, 0], [1, 1, 1], 0.1, 'bounds.min must be three numbers'),
])
def test_invalid_grids_are_refused_with_the_reason(lo, hi, resolution, words):
    with pytest.raises(InvalidInputError, match=words):
        VoxelGrid.from_bounds(lo, hi, resolution)


def test_voxel_cap_fails_before_allocating():
    # A typo of 0.001 m would be 8e12 nodes: refused at once, naming the cap.
    with pytest.raises(InvalidInputError, match='exceeds max_voxels = 1200000000'):
        VoxelGrid.from_bounds([-10, -10, 0], [10, 10, 15], 0.001)
    with pytest.raises(InvalidInputError, match='exceeds max_voxels = 1000'):
        VoxelGrid.from_bounds([0, 0, 0], [10, 10, 10], 0.5, max_voxels=1000)
