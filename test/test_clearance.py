"""The clearance engine: exact capped distances, and certified segments, polylines and curves.

Property tests compare the engine with a brute force over every obstacle, and its "clear"
answers with dense sampling; regression tests place obstacles thinner than any sampling between
two samples.
"""

import math

import numpy as np
import pytest

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, PointSet, Sphere
from uav_global_planner.core.map.spatial_index import ShapeIndex
from uav_global_planner.core.path.clearance import (certify_pieces, certify_polyline,
                                                    certify_segments, line_pieces)
from uav_global_planner.core.planner import Planner


def random_obstacles(seed: int, shapes: int = 60, points: int = 300) -> ObstacleSet:
    """Spheres and boxes of very different sizes (1 mm to 8 m) and a point set, in 40 m."""
    rng = np.random.default_rng(seed)
    items = []
    for number in range(shapes):
        center = rng.uniform(-20.0, 20.0, 3)
        size = 10.0 ** rng.uniform(-3.0, 0.9)
        if number % 2:
            items.append(Sphere(center, size))
        else:
            half = size * rng.uniform(0.05, 1.0, 3)
            items.append(Box(center - half, center + half))
    if points:
        items.append(PointSet(rng.uniform(-20.0, 20.0, (points, 3))))
    return ObstacleSet(items)


def brute_force(obstacles: ObstacleSet, points: np.ndarray) -> np.ndarray:
    """Distance to the nearest obstacle by visiting every one of them, in plain numpy."""
    best = np.full(len(points), np.inf)
    for item in obstacles.items:
        if isinstance(item, Sphere):
            gap = np.linalg.norm(points - item.center, axis=1) - item.radius
        elif isinstance(item, Box):
            excess = np.maximum(np.maximum(item.min - points, points - item.max), 0.0)
            gap = np.linalg.norm(excess, axis=1)
        else:
            gap = np.min(np.linalg.norm(points[:, None, :] - item.points[None, :, :], axis=2),
                         axis=1)
        best = np.minimum(best, np.maximum(gap, 0.0))
    return best


@pytest.mark.parametrize('seed', range(8))
def test_distances_equal_a_brute_force(seed):
    obstacles = random_obstacles(seed)
    rng = np.random.default_rng(100 + seed)
    queries = np.vstack([rng.uniform(-25.0, 25.0, (3000, 3)),
                         # Far outside every obstacle, and on the surface of some.
                         rng.uniform(-1e4, 1e4, (50, 3)),
                         np.array([item.center for item in obstacles.items
                                   if isinstance(item, Sphere)])])
    expected = brute_force(obstacles, queries)
    assert np.allclose(obstacles.distance(queries), expected, rtol=0.0, atol=1e-9)
    for cap in (1e-3, 0.3, 1.7, 6.0, 40.0):
        capped = obstacles.distance(queries, cap)
        # Exact below the cap, the cap (a lower bound) at or above it.
        assert np.allclose(capped, np.minimum(expected, cap), rtol=0.0, atol=1e-9), cap
        assert np.all(capped <= expected + 1e-9)


def test_shape_index_lists_only_near_shapes_but_misses_none():
    """A lattice query reads one cell's list; with hundreds of shapes it still finds the
    nearest one wherever it is within the cap."""
    obstacles = random_obstacles(3, shapes=400, points=0)
    index = ShapeIndex(obstacles.shape_kind, obstacles.shape_params, 2.0)
    lists = np.diff(index._start)
    assert lists.max() < 400 / 4, 'a query reads most of the shapes'
    queries = np.random.default_rng(5).uniform(-22.0, 22.0, (20000, 3))
    expected = brute_force(obstacles, queries)
    assert np.allclose(index.query(queries, 2.0), np.minimum(expected, 2.0), atol=1e-12)
    with pytest.raises(ValueError, match='cap'):
        index.query(queries, 3.0)


def test_a_huge_ground_slab_does_not_break_the_lattice():
    slab = Box([-1e30, -1e30, -1.0], [1e30, 1e30, 0.0])
    spheres = [Sphere([x, 0.0, 3.0], 0.5) for x in np.linspace(-50.0, 50.0, 40)]
    obstacles = ObstacleSet([slab, *spheres])
    queries = np.random.default_rng(2).uniform([-60, -5, -2], [60, 5, 8], (5000, 3))
    expected = brute_force(obstacles, queries)
    assert np.allclose(obstacles.distance(queries, 1.0), np.minimum(expected, 1.0), atol=1e-9)


@pytest.mark.parametrize('seed', range(6))
def test_segments_declared_clear_are_clear_at_dense_samples(seed):
    obstacles = random_obstacles(seed)
    rng = np.random.default_rng(200 + seed)
    starts = rng.uniform(-20.0, 20.0, (300, 3))
    ends = starts + rng.normal(0.0, 6.0, (300, 3))
    gamma = [0.0, 0.1, 0.5][seed % 3]
    cert = certify_segments(obstacles, starts, ends, gamma, 0.5)
    assert cert.clear.any() and not cert.clear.all(), 'a scene that tests nothing'
    # Dense samples (every 5 mm at most) use the exact (uncapped) distance, equal to the brute
    # force above; all segments' samples in one call.
    lengths = np.linalg.norm(ends - starts, axis=1)
    count = int(np.ceil(lengths.max() / 0.005)) + 1
    t = np.linspace(0.0, 1.0, count)
    dense = starts[:, None, :] + t[None, :, None] * (ends - starts)[:, None, :]
    clearance = obstacles.distance(dense.reshape(-1, 3)).reshape(len(starts), count).min(axis=1)
    clear = cert.clear
    assert np.all(clearance[clear] >= gamma - 1e-9)
    assert np.all(clearance[clear] >= cert.bound[clear] - 1e-9)
    # A segment refused is one that really comes within the margin (up to the certificate's
    # resolution, delta * 1e-5).
    assert np.all(clearance[~clear] < gamma + 1e-2)


@pytest.mark.parametrize('gamma', [0.0, 0.2])
def test_a_one_millimetre_wall_between_samples_is_found(gamma):
    """A wall 1 mm thick across a 20 m segment, between any two of its 0.25 m samples."""
    wall = Box([3.1234, -5.0, -5.0], [3.1244, 5.0, 5.0])
    obstacles = ObstacleSet([wall, Sphere([50.0, 50.0, 50.0], 1.0)])
    start, end = np.array([[-10.0, 0.0, 0.0]]), np.array([[10.0, 0.0, 0.0]])
    assert not certify_segments(obstacles, start, end, gamma, 0.5).clear[0]
    assert not certify_polyline(obstacles, [start[0], [0.0, 0.0, 0.0], end[0]], gamma,
                                0.5).clear
    # The same wall beside the segment, 1 mm farther than gamma, leaves it clear.
    beside = ObstacleSet([Box([-5.0, gamma + 1e-3, -5.0], [5.0, gamma + 2e-3, 5.0])])
    assert certify_segments(beside, start, end, gamma, 0.5).clear[0]


def test_a_tiny_sphere_between_samples_is_found():
    others = [Sphere([x, 9.0, 0.0], 0.2) for x in range(40)]
    tiny = ObstacleSet([Sphere([0.37, 0.0, 0.0], 1e-4), *others])
    assert not certify_segments(tiny, [[-5.0, 0.0, 0.0]], [[5.0, 0.0, 0.0]], 0.0, 0.5).clear[0]
    offset = ObstacleSet([Sphere([0.37, 0.0, 2e-4], 1e-4)])
    verdict = certify_segments(offset, [[-5.0, 0.0, 0.0]], [[5.0, 0.0, 0.0]], 0.0, 0.5)
    assert verdict.clear[0] and 0.0 < verdict.bound[0] <= 1e-4 + 1e-9


def test_curve_pieces_declared_clear_are_clear_at_dense_samples():
    obstacles = random_obstacles(11)
    rng = np.random.default_rng(9)
    p0 = rng.uniform(-20.0, 20.0, (60, 3))
    p1 = p0 + rng.normal(0.0, 3.0, (60, 3))
    pieces = line_pieces(p0, p1)
    pieces.coef[1] = rng.normal(0.0, 0.5, (60, 3))    # bend the lines into parabolas
    pieces = type(pieces)(pieces.coef, pieces.h)
    _, cert = certify_pieces(pieces, obstacles, 0.2, 0.5)
    assert cert.violated.any() and not cert.violated.all()
    tau = np.linspace(0.0, 1.0, 10_000)
    for p in np.flatnonzero(~cert.violated):
        dense = pieces.position(np.full(len(tau), p), tau)
        assert obstacles.distance(dense).min() >= 0.2 - 1e-9


def test_bad_arguments_are_refused():
    obstacles = random_obstacles(0)
    with pytest.raises(InvalidInputError, match='margin'):
        certify_segments(obstacles, [[0, 0, 0]], [[1, 0, 0]], -1.0, 0.5)
    with pytest.raises(InvalidInputError, match='resolution'):
        certify_segments(obstacles, [[0, 0, 0]], [[1, 0, 0]], 0.1, 0.0)
    with pytest.raises(InvalidInputError, match='same shape'):
        certify_segments(obstacles, [[0, 0, 0]], [[1, 0, 0], [2, 0, 0]], 0.1, 0.5)
    with pytest.raises(InvalidInputError, match='finite'):
        certify_polyline(obstacles, [[0, 0, math.nan]], 0.1, 0.5)
    with pytest.raises(InvalidInputError, match='cap'):
        obstacles.distance([0.0, 0.0, 0.0], cap=0.0)


def test_planner_safety_checks_are_certified_not_sampled():
    """The regression behind this engine: with gamma = 0, a path through an 8 mm wall was
    reported clear because the check sampled it delta / 20 apart."""
    config = PlannerConfig(safety_margin=0.0, resolution=0.5)
    planner = Planner(config, ObstacleSet([Sphere([5.0, 5.0, 5.0], 1.0)]))
    result = planner.plan([-8.0, 0.0, 3.0], [8.0, 0.0, 3.0])
    assert result.ok, result.message
    assert planner.plan_is_clear(result).clear
    # An 8 mm wall across the plan, placed between two of its samples.
    samples = result.smoothed_path
    middle = len(samples) // 2
    x = 0.5 * (samples[middle, 0] + samples[middle + 1, 0])
    wall = ObstacleSet([Sphere([5.0, 5.0, 5.0], 1.0),
                        Box([x - 0.004, -10.0, 0.0], [x + 0.004, 10.0, 15.0])])
    assert np.all(wall.distance(samples) > 0.0), 'the wall should fall between the samples'
    verdict = planner.plan_is_clear(result, obstacles=wall)
    assert not verdict.clear
    assert abs(verdict.blocked_at[0] - x) < 0.05
    assert not planner.path_is_clear(samples, obstacles=wall)
    # Ahead of a vehicle already past the wall, the rest of the plan is still clear.
    assert planner.plan_is_clear(result, position=samples[-3], obstacles=wall).clear
