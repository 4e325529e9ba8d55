"""Obstacle distances (eq. 9) and the safety set (eqs. 8-10)."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map import inflation, point_inflation, stamping
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, PointSet, Sphere


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


# --- point clouds: stamping each point's ball ------------------------------------------------

def _nodes(grid: VoxelGrid) -> np.ndarray:
    return grid.index_to_world(grid.unravel(np.arange(grid.size)))


def _naive_cloud_mask(grid: VoxelGrid, points: np.ndarray, gamma: float) -> np.ndarray:
    """Every node against every point: the distance of eq. 9 written out, no pruning at all."""
    nodes = _nodes(grid)
    nearest = np.full(len(nodes), np.inf)
    for first in range(0, len(points), 64):
        chunk = points[first:first + 64]
        gaps = np.sqrt(np.sum((nodes[:, None, :] - chunk[None, :, :]) ** 2, axis=-1))
        nearest = np.minimum(nearest, gaps.min(axis=1))
    return (nearest <= gamma).reshape(grid.shape)


def _kd_cloud_mask(grid: VoxelGrid, points: np.ndarray, gamma: float) -> np.ndarray:
    """Each node's nearest point by scipy's KD-tree, without a distance bound."""
    nearest, _ = cKDTree(points).query(_nodes(grid))
    return (nearest <= gamma).reshape(grid.shape)


def _stamped(grid: VoxelGrid, points: np.ndarray, gamma: float) -> np.ndarray:
    """The stamping loop alone, whatever blocked_mask would pick for these sizes."""
    blocked = np.zeros(grid.shape, dtype=bool)
    relevant = point_inflation.relevant_points(grid, np.asarray(points, dtype=np.float64), gamma)
    stamping.stamp_points(blocked, np.asarray(grid.bounds_min), grid.resolution, relevant,
                          gamma)
    return blocked


def _cloud(rng, grid: VoxelGrid, count: int, gamma: float, on_lattice: bool) -> np.ndarray:
    """Random points over the bounds grown by gamma + 2 delta: some outside the grid."""
    grow = gamma + 2.0 * grid.resolution
    points = rng.uniform(grid.bounds_min - grow, grid.bounds_max + grow, (count, 3))
    if on_lattice:
        # On nodes and half-way between them: distances of exactly gamma (ties) everywhere.
        half = grid.resolution / 2.0
        points = grid.bounds_min + np.round((points - grid.bounds_min) / half) * half
    return points


@pytest.mark.parametrize('seed', range(24))
def test_stamped_cloud_equals_brute_force(seed):
    rng = np.random.default_rng(100 + seed)
    delta = float(rng.choice([0.1, 0.25, 0.5, rng.uniform(0.07, 0.6)]))
    lo = rng.uniform(-5.0, 5.0, 3)
    grid = VoxelGrid.from_bounds(lo, lo + rng.uniform(8, 16, 3) * delta, delta)
    ratio = float(rng.choice([0.0, 0.5, 1.0, 2.0, rng.uniform(0.1, 3.0)]))
    gamma = ratio * delta
    points = _cloud(rng, grid, int(rng.integers(1, 400)), gamma, on_lattice=seed % 2 == 0)
    expected = _naive_cloud_mask(grid, points, gamma)
    assert np.array_equal(_stamped(grid, points, gamma), expected)
    assert np.array_equal(blocked_mask(grid, ObstacleSet([PointSet(points)]), gamma), expected)


@pytest.mark.parametrize('ratio', [0.0, 0.3, 1.0, 1.5, 4.0])
def test_stamped_cloud_equals_kd_tree_on_a_larger_grid(ratio):
    rng = np.random.default_rng(int(ratio * 10))
    grid = VoxelGrid.from_bounds([-3.0, 2.0, 0.0], [3.0, 7.0, 4.0], 0.1)
    gamma = ratio * grid.resolution
    points = _cloud(rng, grid, 3000, gamma, on_lattice=False)
    lattice = _cloud(rng, grid, 3000, gamma, on_lattice=True)
    for cloud in (points, lattice):
        expected = _kd_cloud_mask(grid, cloud, gamma)
        assert np.array_equal(_stamped(grid, cloud, gamma), expected)
        assert np.array_equal(blocked_mask(grid, ObstacleSet([PointSet(cloud)]), gamma),
                              expected)


@pytest.mark.parametrize('gamma', [0.6, 1.3, 5.0, 40.0])
def test_gamma_large_against_delta_stamps_balls_wider_than_the_grid(gamma):
    # A ball many cells wide, up to one wider than the whole grid: the ranges are clipped to
    # the grid, and the answer is the rule of eqs. 8-10 still.
    rng = np.random.default_rng(7)
    grid = VoxelGrid.from_bounds([0.0, 0.0, 0.0], [2.0, 1.5, 1.0], 0.05)
    points = rng.uniform([-1.0, -1.0, -1.0], [3.0, 2.5, 2.0], (25, 3))
    expected = _naive_cloud_mask(grid, points, gamma)
    assert np.array_equal(_stamped(grid, points, gamma), expected)
    assert np.array_equal(blocked_mask(grid, ObstacleSet([PointSet(points)]), gamma), expected)


def test_overlapping_balls_switch_to_the_nearest_point_query_with_the_same_answer():
    # 4000 points with gamma 20 delta: the balls visit far more nodes than the grid has, so
    # blocked_mask asks the KD-tree of every node instead; both ways agree to the last bit.
    rng = np.random.default_rng(11)
    grid = VoxelGrid.from_bounds([0.0, 0.0, 0.0], [3.0, 3.0, 3.0], 0.1)
    gamma = 2.0
    points = rng.uniform(-2.5, 5.5, (4000, 3))
    assert (point_inflation.ball_visits(grid, len(points), gamma)
            > point_inflation.VISITS_PER_NODE_COMPILED * grid.size)
    via_tree = np.zeros(grid.shape, dtype=bool)
    point_inflation.mark_by_nearest_point_in(grid, points, gamma, via_tree, np.zeros(3, np.int64))
    assert np.array_equal(via_tree, _stamped(grid, points, gamma))
    assert np.array_equal(blocked_mask(grid, ObstacleSet([PointSet(points)]), gamma), via_tree)
    assert np.array_equal(via_tree, _kd_cloud_mask(grid, points, gamma))


def test_points_outside_the_grid_block_the_nodes_within_gamma_only():
    grid = VoxelGrid.from_bounds([0.0, 0.0, 0.0], [2.0, 2.0, 2.0], 0.25)
    gamma = 0.5
    # Beyond a face exactly gamma from its nearest node (a tie, so blocked), beyond a corner and
    # an edge within gamma, and beyond a face a hair further than gamma (nothing).
    corner = gamma / np.sqrt(3.0)
    points = np.array([[1.0, 1.0, 2.0 + gamma], [-corner, -corner, -corner],
                       [2.3, -0.3, 1.0], [1.0, -gamma - 1e-9, 1.0]])
    blocked = blocked_mask(grid, ObstacleSet([PointSet(points)]), gamma)
    assert blocked[4, 4, 8]
    assert blocked[0, 0, 0] == (np.sqrt(3 * corner ** 2) <= gamma)
    assert blocked[8, 0, 4]
    assert not blocked[4, 0, 4]
    assert np.array_equal(blocked, _naive_cloud_mask(grid, points, gamma))


def test_gamma_zero_blocks_exactly_the_nodes_a_point_sits_on():
    grid = VoxelGrid.from_bounds([-1.0, -1.0, 0.0], [1.0, 1.0, 1.0], 0.25)
    on_nodes = grid.index_to_world([[0, 0, 0], [3, 5, 2], [8, 8, 4]])
    between = on_nodes[1] + [0.125, 0.0, 0.0]
    blocked = blocked_mask(grid, ObstacleSet([PointSet(np.vstack([on_nodes, between]))]), 0.0)
    assert blocked.sum() == 3
    assert blocked[0, 0, 0] and blocked[3, 5, 2] and blocked[8, 8, 4]


def test_far_points_neither_overflow_nor_block():
    grid = VoxelGrid.from_bounds([0.0, 0.0, 0.0], [2.0, 2.0, 2.0], 0.5)
    points = np.array([[1e300, 0.0, 0.0], [-1e300, 1.0, 1.0], [1.0, 1.0, 1e18]])
    assert not _stamped(grid, points, 0.5).any()
    blocked = np.zeros(grid.shape, dtype=bool)
    stamping.stamp_points(blocked, np.asarray(grid.bounds_min), grid.resolution, points, 1.0)
    assert not blocked.any()


# --- compiled and vectorised passes: one rule, to the last bit --------------------------------

def _random_scene(rng, grid: VoxelGrid, delta: float):
    """Spheres, boxes and points, half of them placed on the node lattice (ties at gamma)."""
    lo, hi = grid.bounds_min, grid.upper_node

    def maybe_on_lattice(value):
        return np.round(value / delta) * delta if rng.random() < 0.5 else value

    items = []
    for _ in range(rng.integers(0, 5)):
        items.append(Sphere(maybe_on_lattice(rng.uniform(lo - 1.0, hi + 1.0)),
                            float(rng.choice([delta, 2.0 * delta, rng.uniform(0.05, 1.5)]))))
    for _ in range(rng.integers(0, 5)):
        corner = maybe_on_lattice(rng.uniform(lo - 1.5, hi))
        side = np.maximum(maybe_on_lattice(rng.uniform(0.05, 2.0, 3)), delta / 4.0)
        items.append(Box(corner, corner + side))
    count = int(rng.integers(1, 1500))
    points = rng.uniform(lo - 1.0, hi + 1.0, (count, 3))
    if rng.random() < 0.5:
        points = np.round(points / (delta / 2.0)) * (delta / 2.0)
    items.append(PointSet(points))
    return ObstacleSet(items)


@pytest.mark.parametrize('seed', range(40))
def test_the_compiled_passes_equal_the_distance_rule_on_random_scenes(seed):
    # The mask is eq. 10 on every node, ties at gamma included: ObstacleSet.distance forms the
    # distance with the same formula, so the comparison is exact.
    rng = np.random.default_rng(500 + seed)
    delta = float(rng.choice([0.1, 0.25, 0.5, rng.uniform(0.05, 0.6)]))
    lo = rng.uniform(-4.0, 4.0, 3)
    grid = VoxelGrid.from_bounds(lo, lo + rng.uniform(1.5, 4.0, 3), delta)
    obstacles = _random_scene(rng, grid, delta)
    gamma = float(rng.choice([0.0, delta, 0.5 * delta, 2.0 * delta, rng.uniform(0.0, 1.0),
                              rng.uniform(0.0, 4.0)]))
    compiled = np.zeros(grid.shape, dtype=bool)
    inflation._mark_compiled(grid, obstacles, gamma, compiled)
    expected = (obstacles.distance(_nodes(grid)) <= gamma).reshape(grid.shape)
    assert np.array_equal(compiled, expected)
    assert np.array_equal(blocked_mask(grid, obstacles, gamma), compiled)


def test_box_and_sphere_runs_keep_ties_and_far_reaching_boxes():
    # Faces on the node lattice and gamma a whole number of cells: many nodes sit at exactly
    # gamma, and a slab reaching +-1e30 m covers its rows to the grid's edge.
    grid = VoxelGrid.from_bounds([0.0, 0.0, 0.0], [4.0, 4.0, 3.0], 0.25)
    obstacles = ObstacleSet([Box([1.0, 1.0, 0.5], [2.0, 3.0, 1.5]), Sphere([3.0, 3.0, 2.0], 0.5),
                             Box([-1e30, -1e30, -1e30], [1e30, 1e30, 0.25])])
    gamma = 0.5
    expected = _brute_force_distance(obstacles, _nodes(grid)) <= gamma
    blocked = blocked_mask(grid, obstacles, gamma)
    assert np.array_equal(blocked.reshape(-1), expected)
    assert blocked[4, 4, 4] and blocked[4, 4, 8] and not blocked[4, 4, 9]
    assert blocked[:, :, :4].all() and not blocked[0, 0, 4]
