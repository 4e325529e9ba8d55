"""Live maps (core/map/live_map.py, point_cells.py, tiles.py, mask_buffers.py): the point index,
exact cloud comparison, tile-by-tile inflation.

Every incremental answer is checked against the plain computation it replaces: distances
against scipy's KD-tree, masks against a full :func:`blocked_mask` of the same obstacles.
"""

import json
import math
import os
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial import cKDTree

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask, reinflate_tiles
from uav_global_planner.core.map.live_map import LiveMapBuilder, LiveObstacles, UNCHANGED
from uav_global_planner.core.map.mask_buffers import MaskBuffers
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, PointSet, Sphere
from uav_global_planner.core.map.point_cells import changed_cells, PointCells
from uav_global_planner.core.map.tiles import CellGeometry
from uav_global_planner.core.planner import certify_plan, fallback_margin, Planner

REPO = Path(__file__).resolve().parents[1]
CONFIG = PlannerConfig(bounds_min=(-10.0, -10.0, 0.0), bounds_max=(10.0, 10.0, 8.0),
                       resolution=0.5, safety_margin=0.7)


def _grid(config: PlannerConfig = CONFIG) -> VoxelGrid:
    return VoxelGrid.from_bounds(config.bounds_min, config.bounds_max, config.resolution)


def _cloud(rng, count: int) -> np.ndarray:
    """Points inside and around the bounds, a few far away (they land in border cells)."""
    points = rng.uniform([-12.0, -12.0, -2.0], [12.0, 12.0, 10.0], (count, 3))
    points[:3] = rng.uniform(-1e4, 1e4, (3, 3))
    return points


# ------------------------------------------------------------------------------ point index

@pytest.mark.parametrize('seed', range(4))
@pytest.mark.parametrize('cap', [0.3, 1.5, 6.0, 40.0, math.inf])
def test_cell_distances_equal_a_kd_tree(seed: int, cap: float) -> None:
    rng = np.random.default_rng(seed)
    geometry = CellGeometry.of_grid(_grid())
    # A spread cloud and a tight cluster: empty blocks, crowded cells, far queries.
    for points in (_cloud(rng, 1500), rng.normal(0.0, 0.3, (800, 3)) + [3.0, -2.0, 4.0]):
        cells = PointCells(points, geometry)
        queries = rng.uniform([-30.0, -30.0, -20.0], [30.0, 30.0, 30.0], (3000, 3))
        queries = np.vstack([queries, points[:50] + rng.normal(0.0, 1e-3, (50, 3)),
                             points[:5]])
        expected = np.minimum(cKDTree(points).query(queries)[0], cap)
        assert np.array_equal(cells.distance(queries, cap), expected)


def test_an_empty_cloud_is_at_the_cap() -> None:
    cells = PointCells(np.empty((0, 3)), CellGeometry.of_grid(_grid()))
    assert np.all(cells.distance(np.zeros((4, 3)), 2.0) == 2.0)
    assert np.all(np.isinf(cells.distance(np.zeros((2, 3)))))


def test_bad_points_are_refused() -> None:
    with pytest.raises(InvalidInputError, match='finite'):
        PointCells([[0.0, np.nan, 1.0]], CellGeometry.of_grid(_grid()))


def test_cells_are_sized_to_the_grid() -> None:
    fine = CellGeometry.of_grid(VoxelGrid.from_bounds([0, 0, 0], [10, 10, 10], 0.1))
    assert fine.cell == pytest.approx(1.0)
    coarse = CellGeometry.of_grid(VoxelGrid.from_bounds([0, 0, 0], [200, 200, 40], 2.0))
    assert coarse.tile_nodes == 1
    # A huge grid gets larger cells: the index stays a few million cells.
    huge = CellGeometry.of_grid(VoxelGrid.from_bounds([0, 0, 0], [1000, 1000, 100], 0.5,
                                                      max_voxels=10 ** 9))
    assert huge.count <= 2_100_000 and huge.tile_nodes > 2


# ------------------------------------------------------------------------------ comparison

def test_the_same_points_in_another_order_are_unchanged() -> None:
    rng = np.random.default_rng(7)
    geometry = CellGeometry.of_grid(_grid())
    points = _cloud(rng, 2000)
    first = PointCells(points, geometry)
    assert len(changed_cells(first, PointCells(rng.permutation(points), geometry),
                             geometry)) == 0


def test_exactly_the_cells_that_changed_are_found() -> None:
    rng = np.random.default_rng(8)
    grid = _grid()
    geometry = CellGeometry.of_grid(grid)
    points = _cloud(rng, 2000)
    first = PointCells(points, geometry)
    moved = points.copy()
    moved[10] += [1e-9, 0.0, 0.0]      # below any rounding of the cell boundaries
    moved[20] = [3.0, 3.0, 3.0]        # to a new cell
    added = np.vstack([moved, [[-5.0, -5.0, 5.0]]])
    second = PointCells(rng.permutation(added), geometry)

    def cell_of(point):
        return int(np.ravel_multi_index(tuple(np.clip(np.floor(
            (point - geometry.origin) / geometry.cell), 0, geometry.dims - 1).astype(int)),
            tuple(geometry.dims)))
    expected = {cell_of(points[10]), cell_of(points[20]), cell_of(np.array([3.0, 3.0, 3.0])),
                cell_of(np.array([-5.0, -5.0, 5.0]))}
    assert set(changed_cells(first, second, geometry).tolist()) == expected
    assert len(changed_cells(None, first, geometry)) == len(first.occupied_cells())


def test_clouds_of_other_grids_are_not_compared() -> None:
    points = np.zeros((1, 3))
    with pytest.raises(InvalidInputError, match='different grids'):
        changed_cells(PointCells(points, CellGeometry.of_grid(_grid())),
                      PointCells(points, CellGeometry.of_grid(
                          VoxelGrid.from_bounds([-5, -5, 0], [5, 5, 5], 0.5))),
                      CellGeometry.of_grid(_grid()))


def _same_index(first: PointCells, second: PointCells) -> bool:
    return all(np.array_equal(getattr(first, name), getattr(second, name)) for name in (
        'points', 'start', '_fingerprints', '_sorted_rows', '_row_cells', '_coarse_count',
        '_coarse_ring'))


def test_a_cloud_indexed_from_the_previous_one_equals_a_fresh_index() -> None:
    """The update path (the same rows but a few) gives the arrays of a full build, and its
    changed cells include every cell whose points differ."""
    rng = np.random.default_rng(21)
    geometry = CellGeometry.of_grid(_grid())
    previous = PointCells(_cloud(rng, 5000), geometry)
    updates = 0
    for _ in range(150):
        cloud = previous._raw.copy()
        count = int(rng.integers(0, 60))
        rows = rng.integers(0, len(cloud), count)
        roll = rng.random()
        if roll < 0.4:
            cloud[rows] += rng.normal(0.0, 0.5, (count, 3))
        elif roll < 0.6:
            cloud[rows] = cloud[rng.integers(0, len(cloud), count)]   # duplicates
        elif roll < 0.7:
            cloud[rows] = -0.0 * cloud[rows]                           # -0.0 and 0.0
        else:
            cloud[rows] = rng.uniform(-12.0, 12.0, (count, 3))
        updated, fresh = PointCells(cloud, geometry, previous), PointCells(cloud, geometry)
        assert _same_index(updated, fresh)
        if updated.changed_from_previous is not None:
            updates += 1
            assert set(changed_cells(previous, fresh, geometry).tolist()) <= set(
                updated.changed_from_previous.tolist())
        previous = updated
    assert updates > 100, 'the update path was not taken'
    # Another size, or many rows changed: a full build (and nothing claimed as changed).
    assert PointCells(previous._raw[1:], geometry, previous).changed_from_previous is None
    shuffled = rng.permutation(previous._raw)
    assert PointCells(shuffled, geometry, previous).changed_from_previous is None


# ------------------------------------------------------------------------------ obstacles

def test_live_obstacles_answer_as_one_obstacle_set() -> None:
    rng = np.random.default_rng(3)
    geometry = CellGeometry.of_grid(_grid())
    shapes = [Sphere([1.0, 2.0, 3.0], 1.5), Box([-4.0, -4.0, 0.0], [-2.0, -1.0, 5.0])]
    cloud, prior = _cloud(rng, 500), _cloud(rng, 300)
    live = LiveObstacles(shapes, [PointCells(prior, geometry), PointCells(cloud, geometry)])
    plain = ObstacleSet(shapes + [PointSet(np.vstack([prior, cloud]))])
    queries = rng.uniform(-15.0, 15.0, (2000, 3))
    for cap in (1.0, 5.0, math.inf):
        assert np.array_equal(live.distance(queries, cap), plain.distance(queries, cap))
    assert len(live) == 4 and len(live.items) == 4 and len(live.points) == 800
    assert np.array_equal(blocked_mask(_grid(), live, 0.7), blocked_mask(_grid(), plain, 0.7))
    with pytest.raises(InvalidInputError, match='layers'):
        LiveObstacles([PointSet(cloud)])


# ------------------------------------------------------------------------------ masks

def test_reinflating_tiles_equals_a_full_rebuild() -> None:
    rng = np.random.default_rng(11)
    grid = _grid()
    before = ObstacleSet([Sphere([0.0, 0.0, 3.0], 2.0), PointSet(_cloud(rng, 400))])
    after = ObstacleSet([Sphere([1.3, 0.0, 3.0], 2.0), PointSet(_cloud(rng, 400))])
    mask = blocked_mask(grid, before, 0.7)
    every = np.argwhere(np.ones(tuple(-(-np.asarray(grid.shape) // 2)), dtype=bool))
    reinflate_tiles(grid, after, 0.7, mask, every, 2)  # every tile of 2 nodes
    assert np.array_equal(mask, blocked_mask(grid, after, 0.7))
    # Only the tiles near what changed, with the points near them.
    mask = blocked_mask(grid, before, 0.7)
    moved = ObstacleSet([Sphere([1.3, 0.0, 3.0], 2.0), PointSet(before.points)])
    near = every[np.all(np.abs(every * 2 * 0.5 + grid.bounds_min - [0.65, 0.0, 3.0])
                        <= [2.0 + 0.65 + 0.7 + 2.0, 2.7 + 2.0, 2.7 + 2.0], axis=1)]
    reinflate_tiles(grid, moved, 0.7, mask, near, 2)
    assert np.array_equal(mask, blocked_mask(grid, moved, 0.7))
    with pytest.raises(InvalidInputError, match='C-contiguous bool'):
        reinflate_tiles(grid, after, 0.7, mask.astype(np.uint8), every, 2)


def _updates(rng, builder: LiveMapBuilder, steps: int):
    """Random marker and cloud updates; yields each map with the obstacles it must hold."""
    shapes = {}
    cloud = _cloud(rng, 600)
    sent = np.empty((0, 3))
    held = None
    for step in range(steps):
        roll = rng.random()
        config = None
        if roll < 0.35:
            key = ('m', int(rng.integers(0, 12)))
            if key in shapes and rng.random() < 0.4:
                del shapes[key]
            elif rng.random() < 0.5:
                shapes[key] = Sphere(rng.uniform(-12.0, 12.0, 3), rng.uniform(0.1, 2.0))
            else:
                corner = rng.uniform(-12.0, 12.0, 3)
                shapes[key] = Box(corner, corner + rng.uniform(0.1, 3.0, 3))
            live = builder.update(shapes=shapes, held=held)
        elif roll < 0.85:
            cloud = cloud.copy()
            index = rng.integers(0, len(cloud), rng.integers(1, 15))
            cloud[index] += rng.normal(0.0, 0.6, (len(index), 3))
            if rng.random() < 0.2:
                cloud = np.vstack([cloud, rng.uniform(-11.0, 11.0, (20, 3))])
            if rng.random() < 0.2:
                cloud = cloud[int(rng.integers(1, 10)):]
            live = builder.update(cloud=rng.permutation(cloud), held=held)
            sent = cloud
        elif roll < 0.93:
            config = CONFIG.with_changes(safety_margin=float(rng.choice([0.3, 0.7, 1.2])))
            live = builder.update(config=config, held=held)
        else:
            live = builder.update(shapes=shapes, cloud=UNCHANGED, held=held)
        if rng.random() < 0.6:
            held = live.blocked
        yield live, [shapes[key] for key in sorted(shapes)], sent


@pytest.mark.parametrize('seed', range(3))
def test_every_map_equals_a_full_rebuild_of_its_obstacles(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    prior = _cloud(rng, 200)
    builder = LiveMapBuilder(CONFIG, prior)
    grid = _grid()
    versions = []
    held_copy = None
    for step, (live, shapes, cloud) in enumerate(_updates(rng, builder, 120)):
        gamma = live.grid_key[3]
        expected = ObstacleSet(shapes + [PointSet(np.vstack([prior, cloud]))])
        assert np.array_equal(live.blocked, blocked_mask(grid, expected, gamma))
        if live.fallback is not None:
            # The planner's conservative grid, kept up to date alongside, once asked for.
            margin = fallback_margin(CONFIG.with_changes(safety_margin=gamma))
            assert np.array_equal(live.fallback, blocked_mask(grid, expected, margin))
        if step == 30:
            builder.want_fallback = True
        probe = rng.uniform(-12.0, 12.0, (200, 3))
        assert np.array_equal(live.obstacles.distance(probe, 2.0), expected.distance(probe, 2.0))
        versions.append(live.version)
        if held_copy is not None:
            # The mask a reader held was not written while it was held.
            assert np.array_equal(held_copy[0], held_copy[1])
        held_copy = (live.blocked, live.blocked.copy())
    assert versions == sorted(versions)
    assert live.fallback is not None


def test_a_small_change_reinflates_little() -> None:
    rng = np.random.default_rng(5)
    builder = LiveMapBuilder(CONFIG)
    cloud = _cloud(rng, 3000)
    first = builder.update(cloud=cloud)
    assert first.update.full
    moved = cloud.copy()
    moved[100] += 0.3
    second = builder.update(cloud=moved, held=first.blocked)
    assert not second.update.full and 0 < second.update.tiles < 200
    assert second.update.points < 300
    marker = builder.update(shapes={('a', 0): Sphere([0.0, 0.0, 3.0], 0.5)}, held=second.blocked)
    assert not marker.update.full and marker.update.tiles < 200
    # The cloud's index is kept across the marker update.
    assert marker.obstacles.layers[0] is second.obstacles.layers[0]
    same = builder.update(cloud=moved, held=marker.blocked)
    assert same is marker, 'an unchanged cloud made a new map'


def test_buffers_never_write_the_newest_or_the_held_mask() -> None:
    grid = _grid()
    buffers = MaskBuffers(grid, 0.5)
    obstacles = ObstacleSet([Sphere([0.0, 0.0, 3.0], 1.0)])
    first, _ = buffers.write(obstacles, 1, None)
    second, _ = buffers.write(obstacles, 2, np.array([0]), held=first)
    third, _ = buffers.write(obstacles, 3, np.array([0]), held=first)
    assert len({id(first), id(second), id(third)}) == 3
    fourth, _ = buffers.write(obstacles, 4, np.array([0]), held=third)
    assert fourth is not third and fourth is not second and fourth is first


def test_without_numba_the_same_maps_come_out(tmp_path) -> None:
    """The pure-Python fallback (KD-tree distances, full rebuilds) gives the same masks."""
    script = tmp_path / 'fallback.py'
    script.write_text(
        'import numpy as np\n'
        'from uav_global_planner.core.jit import JIT_ENABLED\n'
        'from uav_global_planner.core.map.live_map import LiveMapBuilder\n'
        'from uav_global_planner.core.config import PlannerConfig\n'
        'from uav_global_planner.core.map.obstacles import Sphere\n'
        'assert not JIT_ENABLED\n'
        'rng = np.random.default_rng(1)\n'
        'config = PlannerConfig(bounds_min=(-3.0, -3.0, 0.0), bounds_max=(3.0, 3.0, 3.0),\n'
        '                       resolution=0.5, safety_margin=0.5)\n'
        'builder = LiveMapBuilder(config)\n'
        'cloud = rng.uniform(-4.0, 4.0, (300, 3))\n'
        'builder.update(cloud=cloud)\n'
        'cloud[5] += 0.4\n'
        'live = builder.update(cloud=cloud, shapes={"a": Sphere([0.0, 0.0, 1.0], 0.5)})\n'
        'np.save(%r, live.blocked)\n'
        'np.save(%r, live.obstacles.distance(rng.uniform(-4, 4, (100, 3)), 1.5))\n'
        % (str(tmp_path / 'slow.npy'), str(tmp_path / 'slow_d.npy')))
    env = dict(os.environ, UAV_PLANNER_DISABLE_JIT='1', PYTHONPATH=str(REPO))
    subprocess.run([sys.executable, str(script)], check=True, env=env, timeout=300)
    rng = np.random.default_rng(1)
    config = PlannerConfig(bounds_min=(-3.0, -3.0, 0.0), bounds_max=(3.0, 3.0, 3.0),
                           resolution=0.5, safety_margin=0.5)
    builder = LiveMapBuilder(config)
    cloud = rng.uniform(-4.0, 4.0, (300, 3))
    builder.update(cloud=cloud)
    cloud[5] += 0.4
    live = builder.update(cloud=cloud, shapes={'a': Sphere([0.0, 0.0, 1.0], 0.5)})
    assert np.array_equal(np.load(tmp_path / 'slow.npy'), live.blocked)
    assert np.array_equal(np.load(tmp_path / 'slow_d.npy'),
                          live.obstacles.distance(rng.uniform(-4, 4, (100, 3)), 1.5))


# ------------------------------------------------------------------------------ the planner

def test_a_prepared_mask_is_planned_on_as_its_own() -> None:
    rng = np.random.default_rng(9)
    builder = LiveMapBuilder(CONFIG)
    cloud = _cloud(rng, 400)
    cloud = cloud[np.linalg.norm(cloud - [-8.0, -8.0, 1.0], axis=1) > 2.0]
    cloud = cloud[np.linalg.norm(cloud - [8.0, 8.0, 6.0], axis=1) > 2.0]
    live = builder.update(cloud=cloud, shapes={'s': Sphere([0.0, 0.0, 3.0], 2.0)})
    prepared = Planner(CONFIG)
    assert prepared.set_map(live.obstacles, live.blocked, live.grid_key)
    own = Planner(CONFIG, live.obstacles)
    start, goal = [-8.0, -8.0, 1.0], [8.0, 8.0, 6.0]
    ours, theirs = prepared.plan(start, goal), own.plan(start, goal)
    assert ours.ok and theirs.ok
    assert np.array_equal(ours.path, theirs.path)
    assert ours.grid_build_time_s == 0.0 and theirs.grid_build_time_s > 0.0
    assert prepared.blocked is live.blocked
    # A mask of other settings is not used.
    assert not prepared.set_map(live.obstacles, live.blocked,
                                CONFIG.with_changes(safety_margin=0.2).grid_key())


def test_a_plan_is_certified_ahead_of_the_vehicle_first() -> None:
    planner = Planner(CONFIG)
    result = planner.plan([-8.0, 0.0, 2.0], [8.0, 0.0, 2.0])
    assert result.ok
    samples = result.trajectory.positions
    assert certify_plan(result, ObstacleSet(), 0.7, 0.5).clear
    far = ObstacleSet([Sphere(samples[-20], 0.3)])
    verdict = certify_plan(result, far, 0.7, 0.5, samples[0], ahead_m=3.0)
    assert not verdict.clear
    assert np.linalg.norm(verdict.blocked_at - samples[-20]) < 1.5
    assert verdict.blocked_ahead_m > 5.0
    near = ObstacleSet([Sphere(samples[15], 0.3)])
    verdict = certify_plan(result, near, 0.7, 0.5, samples[0], ahead_m=3.0)
    assert not verdict.clear and verdict.blocked_ahead_m < 3.0
    # Behind the vehicle: no longer in the way.
    behind = ObstacleSet([Sphere(samples[5], 0.2)])
    assert certify_plan(result, behind, 0.7, 0.5, samples[len(samples) // 2]).clear


# A process that builds a map, changes it (a box dropped, a new cloud) and certifies a plan
# against the change from a position, as the node does when an obstacle arrives; prints the
# kernels compiled or loaded by the change and the check (argv[1]: '1' warms up first).
_FIRST_CHANGE = """
import json, sys
import numpy as np
from uav_global_planner.core import jit
from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.map.live_map import LiveMapBuilder, warm_up_changes
from uav_global_planner.core.map.obstacles import Box, ObstacleSet
from uav_global_planner.core.planner import certify_plan, Planner
config = PlannerConfig(bounds_min=(0.0, 0.0, 0.0), bounds_max=(20.0, 20.0, 10.0),
                       resolution=0.25, safety_margin=0.3)
wall = Box([9.0, 0.0, 0.0], [10.0, 14.0, 10.0])
result = Planner(config, ObstacleSet([wall])).plan([2.0, 2.0, 3.0], [18.0, 2.0, 3.0])
if sys.argv[1] == '1':
    warm_up_changes(config)
builder = LiveMapBuilder(config)
builder.update({'wall': wall})
before = sum(jit.kernel_counts())
dropped = Box([10.0, 6.0, 0.0], [20.0, 7.0, 10.0])  # across the way to the goal
live = builder.update({'wall': wall, 'dropped': dropped}, cloud=np.array([[5.0, 18.0, 5.0]]))
verdict = certify_plan(result, live.obstacles, result.planning_margin, result.resolution,
                       result.path[0], ahead_m=30.0)
print(json.dumps({'ok': result.ok, 'clear': verdict.clear,
                  'kernels': sum(jit.kernel_counts()) - before}))
"""


@pytest.mark.parametrize('warm', [False, True])
def test_after_the_warm_up_a_first_map_change_loads_no_kernel(warm: bool) -> None:
    """The node loads the kernels of a map change at start-up: the first obstacle that blocks
    the plan in force is then checked, and the plan withdrawn, without waiting for them."""
    run = subprocess.run([sys.executable, '-c', _FIRST_CHANGE, '1' if warm else '0'],
                         capture_output=True, text=True, timeout=900, env=dict(os.environ))
    assert run.returncode == 0, run.stderr[-3000:]
    outcome = json.loads(run.stdout.strip().splitlines()[-1])
    assert outcome['ok'] and not outcome['clear']  # the dropped box blocks the plan
    if warm:
        assert outcome['kernels'] == 0
    else:
        assert outcome['kernels'] > 0
