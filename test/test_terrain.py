"""Terrain solids: exact distance to a triangulated height field, the grid inflation and the
clearance certificate over it."""

import math

from hypothesis import given, HealthCheck, settings, strategies as st
import numpy as np
import pytest

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask, reinflate_tiles
from uav_global_planner.core.map.live_map import LiveMapBuilder, same_shape
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, PointSet, Sphere
from uav_global_planner.core.map.sparse_grid import BRICK, FULL, SparseMask
from uav_global_planner.core.map.sparse_inflation import reinflate_sparse
from uav_global_planner.core.map.terrain import column_limits, flat_ground, HeightField
from uav_global_planner.core.planner import Planner

FAST = settings(max_examples=60, deadline=None,
                suppress_health_check=[HealthCheck.too_slow])


# --- an independent brute force: every column's top triangle and its three vertical faces ---

def _triangles(field: HeightField) -> np.ndarray:
    """Every top triangle, shape (T, 3 vertices, 3) [m]: each cell split along its diagonal
    (i, j)-(i + 1, j + 1)."""
    ny, nx = field.heights.shape
    out = []
    for j in range(ny - 1):
        for i in range(nx - 1):
            def vertex(a, b):
                return [field.origin[0] + a * field.spacing[0],
                        field.origin[1] + b * field.spacing[1], field.heights[b, a]]
            out.append([vertex(i, j), vertex(i + 1, j), vertex(i + 1, j + 1)])
            out.append([vertex(i, j), vertex(i + 1, j + 1), vertex(i, j + 1)])
    return np.array(out, dtype=np.float64)


def _segment_distance(p, a, b):
    """Distance from p (3,) to segments a-b (T, 3)."""
    ab = b - a
    t = np.clip(np.einsum('ij,ij->i', p - a, ab) / np.einsum('ij,ij->i', ab, ab), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


def _triangle_distance(p, tri):
    """Distance from p to each triangle: the plane's foot when inside (barycentric
    coordinates), else the nearest edge."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    normal = np.cross(b - a, c - a)
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    height = np.einsum('ij,ij->i', p - a, normal)
    foot = p - height[:, None] * normal
    v0, v1, v2 = b - a, c - a, foot - a
    d00 = np.einsum('ij,ij->i', v0, v0)
    d01 = np.einsum('ij,ij->i', v0, v1)
    d11 = np.einsum('ij,ij->i', v1, v1)
    d20 = np.einsum('ij,ij->i', v2, v0)
    d21 = np.einsum('ij,ij->i', v2, v1)
    det = d00 * d11 - d01 * d01
    beta = (d11 * d20 - d01 * d21) / det
    gamma = (d00 * d21 - d01 * d20) / det
    inside = (beta >= 0) & (gamma >= 0) & (beta + gamma <= 1)
    edges = np.min([_segment_distance(p, a, b), _segment_distance(p, b, c),
                    _segment_distance(p, c, a)], axis=0)
    return np.where(inside, np.abs(height), edges)


def _face_distance(p, a, b):
    """Distance from p to the vertical faces under edges a-b (each face: the points below the
    edge, down to -inf): in the face's own plane, the 2D distance to the region under a
    segment, combined with the offset from the plane."""
    along = b[:, :2] - a[:, :2]
    length = np.linalg.norm(along, axis=1)
    unit = along / length[:, None]
    rel = p[:2] - a[:, :2]
    t = np.einsum('ij,ij->i', rel, unit)
    perp = np.abs(rel[:, 0] * unit[:, 1] - rel[:, 1] * unit[:, 0])
    z = p[2]
    top = a[:, 2] + (b[:, 2] - a[:, 2]) * np.clip(t / length, 0.0, 1.0)
    inside = (t >= 0) & (t <= length) & (z <= top)
    # Outside: the nearest of the top segment and the two vertical rays.
    seg_a = np.stack([np.zeros_like(t), a[:, 2]], axis=1)
    seg_b = np.stack([length, b[:, 2]], axis=1)
    q = np.stack([t, np.full_like(t, z)], axis=1)
    ab = seg_b - seg_a
    s = np.clip(np.einsum('ij,ij->i', q - seg_a, ab) / np.einsum('ij,ij->i', ab, ab), 0, 1)
    to_segment = np.linalg.norm(q - (seg_a + s[:, None] * ab), axis=1)
    to_ray_a = np.hypot(t, np.maximum(z - a[:, 2], 0.0))
    to_ray_b = np.hypot(t - length, np.maximum(z - b[:, 2], 0.0))
    planar = np.where(inside, 0.0, np.min([to_segment, to_ray_a, to_ray_b], axis=0))
    return np.hypot(perp, planar)


def brute_distance(field: HeightField, points: np.ndarray) -> np.ndarray:
    """Distance to the union of triangular columns, each: 0 inside, else the nearest of its
    top triangle and its three vertical faces."""
    tri = _triangles(field)
    sign = 1.0 if field.side == 'below' else -1.0
    tri[:, :, 2] *= sign
    out = []
    for point in np.asarray(points, dtype=np.float64).reshape(-1, 3):
        p = point * [1.0, 1.0, sign]
        a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
        # Inside a column: (x, y) in the triangle and z under its plane.
        v0, v1, v2 = b[:, :2] - a[:, :2], c[:, :2] - a[:, :2], p[:2] - a[:, :2]
        det = v0[:, 0] * v1[:, 1] - v0[:, 1] * v1[:, 0]
        beta = (v2[:, 0] * v1[:, 1] - v2[:, 1] * v1[:, 0]) / det
        gamma = (v0[:, 0] * v2[:, 1] - v0[:, 1] * v2[:, 0]) / det
        plane = a[:, 2] + beta * (b[:, 2] - a[:, 2]) + gamma * (c[:, 2] - a[:, 2])
        inside = (beta >= -1e-15) & (gamma >= -1e-15) & (beta + gamma <= 1 + 1e-15) & (
            p[2] <= plane)
        if inside.any():
            out.append(0.0)
            continue
        best = np.min(_triangle_distance(p, tri))
        for first, second in ((a, b), (b, c), (c, a)):
            best = min(best, np.min(_face_distance(p, first, second)))
        out.append(best)
    return np.array(out)


@st.composite
def lattices(draw, side=None):
    nx = draw(st.integers(2, 5))
    ny = draw(st.integers(2, 5))
    heights = np.array(draw(st.lists(st.floats(-3.0, 3.0), min_size=nx * ny,
                                     max_size=nx * ny))).reshape(ny, nx)
    origin = [draw(st.floats(-5.0, 5.0)), draw(st.floats(-5.0, 5.0))]
    spacing = [draw(st.floats(0.3, 3.0)), draw(st.floats(0.3, 3.0))]
    chosen = side if side is not None else draw(st.sampled_from(['below', 'above']))
    return HeightField(origin, spacing, heights, side=chosen)


def _points_around(field: HeightField, seed: int, count: int = 25) -> np.ndarray:
    lo, hi = field.extent
    span = hi - lo
    rng = np.random.default_rng(seed)
    xy = rng.uniform(lo - 0.5 * span - 1.0, hi + 0.5 * span + 1.0, (count, 2))
    z = rng.uniform(field.heights.min() - 3.0, field.heights.max() + 3.0, count)
    return np.column_stack([xy, z])


# --- the distance -----------------------------------------------------------------------------

@FAST
@given(lattices(), st.integers(0, 2 ** 31))
def test_distance_equals_brute_force_over_triangles_and_faces(field, seed):
    points = _points_around(field, seed)
    assert np.allclose(field.distance(points), brute_distance(field, points), rtol=0.0,
                       atol=1e-9)


@FAST
@given(lattices(), st.integers(0, 2 ** 31), st.floats(0.05, 4.0))
def test_capped_distance_is_the_exact_one_capped(field, seed, cap):
    points = _points_around(field, seed, 40)
    exact = field.distance(points)
    assert np.array_equal(field.distance(points, cap), np.minimum(exact, cap))


def test_distance_on_the_surface_and_inside_is_zero():
    rng = np.random.default_rng(3)
    field = HeightField([0.0, 0.0], [1.0, 1.5], rng.uniform(0.0, 2.0, (4, 5)))
    xy = rng.uniform([0.0, 0.0], [4.0, 4.5], (200, 2))
    h = field.height_at(xy)
    assert np.all(field.distance(np.column_stack([xy, h - 0.5])) == 0.0)
    assert np.all(field.distance(np.column_stack([xy, h])) <= 1e-12)
    above = HeightField(field.origin, field.spacing, field.heights, side='above')
    assert np.all(above.distance(np.column_stack([xy, h + 0.5])) == 0.0)
    # Side 'above' is the mirror image in z of side 'below'.
    mirror = HeightField(field.origin, field.spacing, -field.heights, side='above')
    points = _points_around(field, 9, 100)
    assert np.array_equal(mirror.distance(points * [1.0, 1.0, -1.0]), field.distance(points))


def test_far_points_and_large_lattices_stay_exact():
    rng = np.random.default_rng(5)
    field = HeightField([-40.0, 10.0], [7.0, 5.0], rng.uniform(0.0, 30.0, (9, 12)))
    points = np.column_stack([rng.uniform(-200, 200, 60), rng.uniform(-200, 200, 60),
                              rng.uniform(-50, 150, 60)])
    assert np.allclose(field.distance(points), brute_distance(field, points), atol=1e-9)


def test_flat_ground_distance_is_height_above_it():
    ground = flat_ground(1.25, [-10.0, -5.0], [20.0, 15.0])
    rng = np.random.default_rng(7)
    points = np.column_stack([rng.uniform(-10, 20, 500), rng.uniform(-5, 15, 500),
                              rng.uniform(-3, 30, 500)])
    expected = np.maximum(0.0, points[:, 2] - 1.25)
    assert np.allclose(ground.distance(points), expected, rtol=0.0, atol=1e-12)
    ceiling = flat_ground(20.0, [-10.0, -5.0], [20.0, 15.0], side='above', label='ceiling')
    assert np.allclose(ceiling.distance(points), np.maximum(0.0, 20.0 - points[:, 2]),
                       rtol=0.0, atol=1e-12)
    # Beyond the extent the solid ends: the distance is to its walls.
    assert ground.distance([-13.0, 0.0, 0.0]) == pytest.approx(3.0)
    assert ground.distance([-13.0, -9.0, 5.25]) == pytest.approx(math.sqrt(9 + 16 + 16))


def test_height_at_interpolates_the_triangles():
    heights = np.array([[0.0, 1.0], [2.0, 4.0]])
    field = HeightField([0.0, 0.0], [2.0, 2.0], heights)
    # Lower triangle (0,0),(1,0),(1,1) and upper (0,0),(0,1),(1,1) in cell units.
    got = field.height_at([[0.0, 0.0], [2.0, 2.0], [1.5, 0.5], [0.5, 1.5], [1.0, 1.0],
                           [3.0, 1.0]])
    assert np.allclose(got[:5], [0.0, 4.0, 0.75 + 0.75, 1.5 + 0.5, 2.0])
    assert np.isnan(got[5])


@pytest.mark.parametrize('kwargs, words', [
    (dict(origin=[0.0, np.nan], spacing=[1.0, 1.0], heights=np.zeros((2, 2))), 'finite'),
    (dict(origin=[0.0, 0.0], spacing=[1.0, 0.0], heights=np.zeros((2, 2))), '> 0'),
    (dict(origin=[0.0, 0.0], spacing=[1.0, 1.0], heights=np.zeros((1, 5))), '2 x 2'),
    (dict(origin=[0.0, 0.0], spacing=[1.0, 1.0], heights=[[0.0, np.inf], [0.0, 0.0]]),
     'finite'),
    (dict(origin=[0.0, 0.0, 0.0], spacing=[1.0, 1.0], heights=np.zeros((2, 2))), 'origin'),
    (dict(origin=[0.0, 0.0], spacing=[1.0, 1.0], heights=np.zeros((2, 2)), side='up'),
     'side'),
])
def test_invalid_height_fields_are_refused(kwargs, words):
    with pytest.raises(InvalidInputError, match=words):
        HeightField(**kwargs)


def test_invalid_queries_and_ground_are_refused():
    ground = flat_ground(0.0, [0.0, 0.0], [1.0, 1.0])
    with pytest.raises(InvalidInputError):
        ground.distance([[0.0, 0.0, 1.0]], cap=0.0)
    with pytest.raises(InvalidInputError):
        ground.distance([[0.0, 0.0]])
    with pytest.raises(InvalidInputError):
        flat_ground(0.0, [1.0, 0.0], [1.0, 1.0])
    with pytest.raises(InvalidInputError):
        flat_ground(math.nan, [0.0, 0.0], [1.0, 1.0])


# --- the obstacle set ---------------------------------------------------------------------------

def test_obstacle_set_holds_height_fields_in_every_query():
    field = HeightField([0.0, 0.0], [2.0, 2.0], [[0.0, 1.0, 0.5], [0.2, 0.8, 0.1]])
    sphere = Sphere([1.0, 1.0, 6.0], 1.0)
    alone = ObstacleSet([field])
    assert not alone.is_empty()
    assert alone.height_fields == (field,)
    both = ObstacleSet([sphere, field])
    points = _points_around(field, 11, 50)
    expected = np.minimum(field.distance(points), ObstacleSet([sphere]).distance(points))
    assert np.array_equal(both.distance(points), expected)
    assert np.array_equal(both.distance(points, 0.7), np.minimum(expected, 0.7))
    # Everything but the ground, as the contract says to build it.
    rest = ObstacleSet([o for o in both.items if not isinstance(o, HeightField)])
    assert rest.height_fields == () and len(rest) == 1


# --- the inflation ------------------------------------------------------------------------------

def _node_distances(grid: VoxelGrid, obstacles: ObstacleSet) -> np.ndarray:
    nodes = grid.index_to_world(np.stack(np.indices(grid.shape), axis=-1).reshape(-1, 3))
    return obstacles.distance(nodes).reshape(grid.shape)


def _dense(mask) -> np.ndarray:
    return mask.to_dense() if isinstance(mask, SparseMask) else mask


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(lattices(), st.sampled_from([0.0, 0.2, 0.45, 1.0]), st.integers(0, 2 ** 31))
def test_inflation_blocks_exactly_the_nodes_within_gamma(field, gamma, seed):
    lo, hi = field.extent
    rng = np.random.default_rng(seed)
    delta = float(rng.choice([0.2, 0.25, 0.3]))
    grid = VoxelGrid.from_bounds([lo[0] - 1.0, lo[1] - 1.0, -4.0],
                                 [hi[0] + 1.0, hi[1] + 1.0, 4.0], delta)
    obstacles = ObstacleSet([field, Sphere(rng.uniform(lo, hi).tolist() + [0.0], 0.4)])
    expected = _node_distances(grid, obstacles) <= gamma
    for layout in ('dense', 'sparse'):
        assert np.array_equal(_dense(blocked_mask(grid, obstacles, gamma, layout=layout)),
                              expected), layout


def test_inflation_of_a_floor_and_a_ceiling_and_ties_at_gamma():
    rng = np.random.default_rng(2)
    floor = HeightField([0.0, 0.0], [1.5, 1.0], rng.uniform(0.0, 2.0, (6, 5)))
    ceiling = HeightField([1.0, -1.0], [1.0, 2.0], rng.uniform(4.0, 6.0, (5, 5)),
                          side='above')
    # A level ground at a node height: the nodes exactly gamma above it are blocked.
    ground = flat_ground(-1.0, [-2.0, -2.0], [8.0, 8.0])
    obstacles = ObstacleSet([floor, ceiling, ground])
    grid = VoxelGrid.from_bounds([-3.0, -3.0, -3.0], [9.0, 9.0, 8.0], 0.25)
    gamma = 0.5
    distances = _node_distances(grid, obstacles)
    expected = distances <= gamma
    assert np.any(distances == gamma)
    for layout in ('dense', 'sparse'):
        mask = _dense(blocked_mask(grid, obstacles, gamma, layout=layout))
        assert np.array_equal(mask, expected), layout
    k_tie = int(round((-1.0 + gamma + 3.0) / 0.25))
    assert expected[42, 42, k_tie] and not expected[42, 42, k_tie + 1]


def test_sparse_terrain_band_files_whole_bricks_as_the_dense_mask_does():
    # Hills, an AGL floor and ceiling over them and obstacles in the band, on a grid of several
    # build windows with partial bricks on its upper faces: most bricks lie wholly under the
    # floor or over the ceiling (full) or wholly in the band (free).
    rng = np.random.default_rng(11)
    x = np.arange(0.0, 37.0, 3.0)
    y = np.arange(0.0, 34.0, 3.0)
    xx, yy = np.meshgrid(x, y)
    heights = (2.0 + 1.5 * np.sin(xx / 4.0) * np.cos(yy / 5.0)
               + 3.0 * np.exp(-((xx - 18.0) ** 2 + (yy - 15.0) ** 2) / 40.0)
               + rng.uniform(-0.3, 0.3, xx.shape))
    terrain = HeightField([0.0, 0.0], [3.0, 3.0], heights)
    floor = HeightField([0.0, 0.0], [3.0, 3.0], heights + 3.0, label='floor')
    ceiling = HeightField([0.0, 0.0], [3.0, 3.0], heights + 11.0, side='above',
                          label='ceiling')
    items = [terrain, floor, ceiling,
             Sphere([10.0, 12.0, 9.0], 1.2), Sphere([30.0, 5.0, 14.0], 2.0),
             Box([20.0, 20.0, 0.0], [23.0, 24.0, 12.0]),  # from the ground into the band
             Box([2.0, 28.0, 9.0], [5.5, 30.0, 10.0]),
             PointSet(rng.uniform([25.0, 25.0, 7.0], [32.0, 31.0, 11.0], (40, 3)))]
    obstacles = ObstacleSet(items)
    # The lattice ends inside the grid on the upper x and y faces: columns off it as well.
    grid = VoxelGrid.from_bounds([-1.0, -1.0, -2.0], [38.1, 35.3, 22.0], 0.25)
    assert all(n % BRICK for n in grid.shape) and min(grid.shape) > 64
    gamma = 0.5
    dense = blocked_mask(grid, obstacles, gamma, layout='dense')
    sparse = blocked_mask(grid, obstacles, gamma, layout='sparse')
    assert isinstance(sparse, SparseMask) and isinstance(dense, np.ndarray)
    free, full, mixed = sparse.brick_counts()
    assert full > 0.3 * len(sparse.table) and free > 0.2 * len(sparse.table) and mixed > 0
    assert np.array_equal(sparse.to_dense(), dense)
    # The same free, full and mixed bricks as filing the dense mask brick by brick.
    again = SparseMask.from_dense(dense)
    assert np.array_equal(np.minimum(again.table, 0), np.minimum(sparse.table, 0))
    # The rule itself, on the nodes of the bricks filed full without their nodes being read,
    # and on a sample of the others.
    bricks = np.stack(np.unravel_index(np.flatnonzero(sparse.table == FULL), sparse.bricks),
                      axis=-1)
    corners = np.minimum(bricks[rng.choice(len(bricks), 40, replace=False)] * BRICK,
                         np.asarray(grid.shape) - 1)
    nodes = np.concatenate([corners, rng.integers(0, np.asarray(grid.shape), (4000, 3))])
    distances = obstacles.distance(grid.index_to_world(nodes))
    assert np.array_equal(sparse.blocked_at(nodes), distances <= gamma)


def test_reinflated_tiles_keep_the_terrain():
    rng = np.random.default_rng(4)
    field = HeightField([0.0, 0.0], [1.0, 1.0], rng.uniform(0.0, 3.0, (7, 7)))
    obstacles = ObstacleSet([field])
    grid = VoxelGrid.from_bounds([-1.0, -1.0, -1.0], [7.0, 7.0, 5.0], 0.2)
    gamma = 0.35
    expected = _node_distances(grid, obstacles) <= gamma
    tiles = np.array([[0, 0, 0], [1, 2, 0], [2, 1, 1]])
    stale = expected.copy()
    stale[:16, :16, :16] = ~stale[:16, :16, :16]
    stale[16:32, 32:, :16] = True
    stale[32:, 16:32, 16:32] = False
    reinflate_tiles(grid, obstacles, gamma, stale, tiles, 16)
    assert np.array_equal(stale, expected)
    sparse = blocked_mask(grid, ObstacleSet(), gamma, layout='sparse')
    assert isinstance(sparse, SparseMask)
    every = np.stack(np.indices((3, 3, 2)), axis=-1).reshape(-1, 3)
    rebuilt = reinflate_sparse(grid, obstacles, gamma, sparse, every, 16)
    assert np.array_equal(rebuilt.to_dense(), expected)


# --- the certificate over hills -----------------------------------------------------------------

def test_smoothed_path_over_hills_keeps_gamma_at_dense_samples():
    x = np.arange(0.0, 41.0, 4.0)
    y = np.arange(-4.0, 25.0, 4.0)
    xx, yy = np.meshgrid(x, y)
    heights = (3.0 + 2.5 * np.sin(xx / 5.0) * np.cos(yy / 6.0)
               + 4.0 * np.exp(-((xx - 20.0) ** 2 + (yy - 10.0) ** 2) / 30.0))
    hills = HeightField([0.0, -4.0], [4.0, 4.0], heights)
    config = PlannerConfig(bounds_min=(0.0, 0.0, 0.0), bounds_max=(40.0, 20.0, 14.0),
                           resolution=0.5, safety_margin=1.0, max_planning_time=120.0)
    obstacles = ObstacleSet([hills])
    start = np.array([1.0, 2.0, float(hills.height_at([1.0, 2.0])) + 1.5])
    goal = np.array([39.0, 18.0, float(hills.height_at([39.0, 18.0])) + 1.5])
    planner = Planner(config, obstacles)
    planner.warm_up()  # compiles the kernels (a cold cache) outside the plan's time budget
    result = planner.plan(start, goal, 'octile')
    assert result.ok, result.message
    margin = result.planning_margin
    assert margin >= 1.0
    s = np.linspace(0.0, result.curve.length_m, 10_000)
    clearance = obstacles.distance(result.curve.evaluate(s))
    assert clearance.min() >= margin, (clearance.min(), margin)
    # The path crosses the hill's flank: it does not simply fly far above everything.
    assert clearance.min() <= margin + 1.0


def test_column_limits_stop_at_the_checkpoint():
    field = flat_ground(0.0, [0.0, 0.0], [100.0, 100.0])
    calls = []

    def checkpoint():
        calls.append(1)
        if len(calls) > 2:
            raise TimeoutError('out of time')

    box = (np.zeros(3, dtype=np.int64), np.array([399, 399, 20]))
    with pytest.raises(TimeoutError):
        column_limits(field, np.zeros(3), 0.25, *box, 0.5, checkpoint)
    limits = column_limits(field, np.zeros(3), 0.25, *box, 0.5, lambda: None)
    assert np.all(limits == 3)  # nodes z = 0, 0.25, 0.5 are within 0.5 m of the ground


def test_a_live_map_keeps_the_terrain_through_cloud_updates():
    rng = np.random.default_rng(8)
    field = HeightField([0.0, 0.0], [2.0, 2.0], rng.uniform(0.0, 2.0, (5, 6)))
    config = PlannerConfig(bounds_min=(0.0, 0.0, 0.0), bounds_max=(10.0, 8.0, 5.0),
                           resolution=0.25, safety_margin=0.3)
    builder = LiveMapBuilder(config)
    first = builder.update(shapes={'terrain': field}, cloud=None)
    gamma = config.planning_margin
    grid = VoxelGrid.from_bounds(config.bounds_min, config.bounds_max, config.resolution)
    assert np.array_equal(_dense(first.blocked),
                          _node_distances(grid, first.obstacles) <= gamma)
    # A cloud arrives: only the tiles near it are re-inflated, the terrain stays in them.
    cloud = np.column_stack([rng.uniform(1.0, 3.0, 30), rng.uniform(1.0, 3.0, 30),
                             rng.uniform(3.0, 4.5, 30)])
    second = builder.update(cloud=cloud)
    assert not second.update.full
    assert np.array_equal(_dense(second.blocked),
                          _node_distances(grid, second.obstacles) <= gamma)
    # The same terrain again (a new object with the same samples) is no change.
    again = HeightField(field.origin.copy(), field.spacing.copy(), field.heights.copy())
    assert same_shape(field, again)
    assert builder.update(shapes={'terrain': again}) is second
