"""Obstacle distances (eq. 9) and the safety set (eqs. 8-10)."""

import numpy as np
import pytest

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.grid import VoxelGrid
from uav_global_planner.core.inflation import blocked_mask
from uav_global_planner.core.obstacles import Box, ObstacleSet, PointSet, Sphere


def _random_obstacles(rng, lo, hi):
    items = []
    for _ in range(rng.integers(1, 4)):
        items.append(Sphere(rng.uniform(lo, hi), rng.uniform(0.2, 1.5)))
    for _ in range(rng.integers(0, 3)):
        corner = rng.uniform(lo, hi)
        items.append(Box(corner, corner + rng.uniform(0.1, 1.5, 3)))
    if rng.random() < 0.7:
        items.append(PointSet(rng.uniform(lo - 0.5, hi + 0.5, (rng.integers(1, 40), 3))))
    return ObstacleSet(items)


def _brute_force_distance(obstacles: ObstacleSet, points: np.ndarray) -> np.ndarray:
    """Independent distance: sample each obstacle's surface densely would be approximate, so
    use the closed forms written out one obstacle and one point at a time."""
    out = np.full(len(points), np.inf)
    for n, p in enumerate(points):
        for item in obstacles.items:
            if isinstance(item, Sphere):
                d = max(float(np.linalg.norm(p - item.center)) - item.radius, 0.0)
            elif isinstance(item, Box):
                nearest = np.minimum(np.maximum(p, item.min), item.max)
                d = float(np.linalg.norm(p - nearest))
            else:
                d = min(float(np.linalg.norm(p - q)) for q in item.points)
            out[n] = min(out[n], d)
    return out


@pytest.mark.parametrize('seed', range(40))
def test_blocked_iff_distance_at_most_gamma(seed):
    rng = np.random.default_rng(seed)
    lo = rng.uniform(-3, 3, 3)
    hi = lo + rng.uniform(1.5, 4, 3)
    grid = VoxelGrid.from_bounds(lo, hi, rng.uniform(0.15, 0.5))
    obstacles = _random_obstacles(rng, lo, hi)
    gamma = rng.uniform(0.0, 0.6)
    blocked = blocked_mask(grid, obstacles, gamma)
    nodes = grid.index_to_world(grid.unravel(np.arange(grid.size)))
    expected = _brute_force_distance(obstacles, nodes) <= gamma
    assert np.array_equal(blocked.reshape(-1), expected)


def test_paper_sphere_rule():
    # Remark 2: blocked iff ||P - O|| <= R + gamma.
    grid = VoxelGrid.from_bounds([-2, -2, -2], [2, 2, 2], 0.5)
    blocked = blocked_mask(grid, ObstacleSet([Sphere([0, 0, 0], 1.0)]), 0.5)
    nodes = grid.index_to_world(grid.unravel(np.arange(grid.size)))
    assert np.array_equal(blocked.reshape(-1), np.linalg.norm(nodes, axis=1) <= 1.5)


def test_distance_is_zero_inside_and_inf_without_obstacles():
    obstacles = ObstacleSet([Sphere([0, 0, 0], 1.0), Box([5, 5, 5], [6, 6, 6])])
    assert obstacles.distance([0.2, 0.0, 0.0]) == 0.0
    assert obstacles.distance([5.5, 5.5, 5.5]) == 0.0
    assert obstacles.distance([0, 0, 3]) == pytest.approx(2.0)
    assert obstacles.distance([6.0, 6.0, 9.0]) == pytest.approx(3.0)
    assert np.isinf(ObstacleSet().distance(np.zeros((4, 3)))).all()


def test_obstacles_outside_the_grid_block_nothing_far_away():
    grid = VoxelGrid.from_bounds([0, 0, 0], [2, 2, 2], 0.5)
    far = ObstacleSet([Sphere([10, 10, 10], 1.0), Box([-9, -9, -9], [-8, -8, -8]),
                       PointSet([[20.0, 0.0, 0.0]])])
    assert not blocked_mask(grid, far, 0.5).any()


@pytest.mark.parametrize('make, words', [
    (lambda: Sphere([0, 0, 0], 0.0), 'sphere radius must be > 0'),
    (lambda: Sphere([0, 0, 0], -1.0), 'sphere radius must be > 0'),
    (lambda: Sphere([0, float('nan'), 0], 1.0), 'sphere center must be finite'),
    (lambda: Sphere([0, 0, 0], float('inf')), 'sphere radius must be finite'),
    (lambda: Box([0, 0, 0], [1, 0, 1]), 'box min must be below box max'),
    (lambda: Box([0, 0], [1, 1, 1]), 'box min must be three numbers'),
    (lambda: PointSet([[0, 0, float('nan')]]), 'points must be finite'),
    (lambda: PointSet([[0, 0]]), r'points must have shape \(M, 3\)'),
    (lambda: ObstacleSet(['sphere']), 'unsupported type str'),
])
def test_malformed_obstacles_are_refused(make, words):
    with pytest.raises(InvalidInputError, match=words):
        make()


def test_negative_gamma_is_refused():
    grid = VoxelGrid.from_bounds([0, 0, 0], [1, 1, 1], 0.5)
    with pytest.raises(InvalidInputError, match='safety_margin'):
        blocked_mask(grid, ObstacleSet(), -0.1)
