"""Dense point sets: the distance-transform pass blocks exactly the nodes the stamping blocks,
and the plan's time budget covers the grid build (core and command line)."""

import json
import math
from pathlib import Path
import shutil
import subprocess

import numpy as np
import pytest

from uav_global_planner.core import budget as budget_module
from uav_global_planner.core.budget import PlanBudget, PlanStage
from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import PlanningTimeoutError
from uav_global_planner.core.map import dense_inflation
from uav_global_planner.core.map import point_inflation, stamping
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask, reinflate_tiles
from uav_global_planner.core.map.obstacles import ObstacleSet, PointSet
from uav_global_planner.core.map.sparse_inflation import reinflate_sparse
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.status import PlanStatus


def _stamped(grid: VoxelGrid, points: np.ndarray, gamma: float) -> np.ndarray:
    """The stamping of every point's ball alone: the reference."""
    blocked = np.zeros(grid.shape, dtype=bool)
    relevant = point_inflation.relevant_points(grid, points, gamma)
    stamping.stamp_points(blocked, np.asarray(grid.bounds_min), grid.resolution, relevant,
                          gamma)
    return blocked


def _by_transform(grid: VoxelGrid, points: np.ndarray, gamma: float, edge: int) -> np.ndarray:
    """The distance-transform pass alone, box by box (boxes of ``edge`` nodes), never giving
    up for a wide shell."""
    blocked = np.zeros(grid.shape, dtype=bool)
    relevant = point_inflation.relevant_points(grid, points, gamma)
    bins = dense_inflation.bin_points(relevant, grid.bounds_min, grid.resolution, gamma)
    shape = np.asarray(grid.shape, dtype=np.int64)
    start, items = dense_inflation.bucket(bins, shape, edge)
    boxes = tuple(-(-shape // edge))
    for box in np.flatnonzero(np.diff(start)):
        lo = np.asarray(np.unravel_index(box, boxes), dtype=np.int64) * edge
        hi = np.minimum(lo + edge - 1, shape - 1)
        dense_inflation.mark_box(blocked, np.zeros(3, dtype=np.int64), bins,
                                 items[start[box]:start[box + 1]], lo, hi, grid.bounds_min,
                                 grid.resolution, gamma, math.inf)
    return blocked


def _dense_cloud(rng, grid: VoxelGrid, gamma: float) -> np.ndarray:
    """Scanned-looking points: planes sampled far finer than delta, a blob, points on the
    half-node lattice (many exactly gamma from nodes when gamma is a multiple of delta / 2),
    some outside the bounds, and duplicates."""
    delta = grid.resolution
    lo = grid.bounds_min - gamma - 2.0 * delta
    hi = grid.bounds_max + gamma + 2.0 * delta
    parts = []
    for _ in range(int(rng.integers(1, 4))):
        axis = int(rng.integers(0, 3))
        level = rng.uniform(lo[axis], hi[axis])
        plane = rng.uniform(lo, hi, (int(rng.integers(1000, 5000)), 3))
        plane[:, axis] = level + rng.normal(0.0, 0.1 * delta, len(plane))
        parts.append(plane)
    center = rng.uniform(grid.bounds_min, grid.bounds_max)
    parts.append(center + rng.normal(0.0, 3.0 * delta, (int(rng.integers(200, 3000)), 3)))
    half = delta / 2.0
    lattice = rng.uniform(lo, hi, (int(rng.integers(100, 2000)), 3))
    parts.append(grid.bounds_min + np.round((lattice - grid.bounds_min) / half) * half)
    points = np.vstack(parts)
    return np.vstack([points, points[rng.integers(0, len(points), len(points) // 4)]])


def _nodes(grid: VoxelGrid) -> np.ndarray:
    return grid.index_to_world(grid.unravel(np.arange(grid.size)))


@pytest.mark.parametrize('seed', range(16))
def test_transform_pass_blocks_exactly_the_stamped_nodes(seed):
    rng = np.random.default_rng(500 + seed)
    delta = float(rng.choice([0.1, 0.25, rng.uniform(0.05, 0.4)]))
    lo = rng.uniform(-5.0, 5.0, 3)
    grid = VoxelGrid.from_bounds(lo, lo + rng.uniform(10, 30, 3) * delta, delta)
    gamma = float(rng.choice([0.0, 0.5, 1.0, 1.5, 3.0, rng.uniform(0.1, 4.0)])) * delta
    points = _dense_cloud(rng, grid, gamma)
    expected = _stamped(grid, points, gamma)
    for edge in (5, 16, 64):
        assert np.array_equal(_by_transform(grid, points, gamma, edge), expected), edge
    assert np.array_equal(blocked_mask(grid, ObstacleSet([PointSet(points)]), gamma), expected)
    distances = ObstacleSet([PointSet(points)]).distance(_nodes(grid))
    assert np.array_equal(expected.reshape(-1), distances <= gamma)


def test_points_exactly_gamma_from_nodes_and_duplicates():
    # Points on the half-node lattice with gamma a multiple of delta / 2: the distance of many
    # node-point pairs is exactly gamma (a tie, blocked), the nodes of the next shell are not.
    grid = VoxelGrid.from_bounds([0.0, 0.0, 0.0], [3.2, 2.4, 1.6], 0.1)
    rng = np.random.default_rng(3)
    cells = rng.integers(0, 65, (6000, 3)) * 0.05 - 0.2
    points = np.vstack([cells, cells[:3000], [[1.6, 1.2, 0.8]] * 50])
    for gamma in (0.0, 0.1, 0.15, 0.2, 0.25, 0.5):
        expected = _stamped(grid, points, gamma)
        distances = ObstacleSet([PointSet(points)]).distance(_nodes(grid))
        assert np.array_equal(expected.reshape(-1), distances <= gamma)
        assert gamma == 0.5 or np.any(distances == gamma), 'no tie in the test'
        assert np.array_equal(_by_transform(grid, points, gamma, 16), expected), gamma
        assert np.array_equal(blocked_mask(grid, ObstacleSet([PointSet(points)]), gamma),
                              expected)


def _wall_room(delta: float, spacing: float) -> np.ndarray:
    """The floor, two walls and a box of a room, sampled every ``spacing`` [m]."""
    u = np.arange(0.0, 3.0, spacing)
    a, b = np.meshgrid(u, u, indexing='ij')
    a, b = a.ravel(), b.ravel()
    floor = np.stack([a, b, np.zeros_like(a)], axis=1)
    wall_x = np.stack([np.zeros_like(a), a, b * 0.8], axis=1)
    wall_y = np.stack([a, np.full_like(a, 2.99), b * 0.8], axis=1)
    box = np.stack([1.0 + 0.3 * a / 3.0, 1.2 + 0.3 * b / 3.0, np.full_like(a, 0.7)], axis=1)
    return np.vstack([floor, wall_x, wall_y, box])


def test_dense_builds_use_the_transform_and_agree_in_every_layout(monkeypatch):
    grid = VoxelGrid.from_bounds([0.0, 0.0, 0.0], [3.0, 3.0, 2.4], 0.05)
    points = _wall_room(0.05, 0.01)
    gamma = 0.25
    obstacles = ObstacleSet([PointSet(points)])
    calls = []
    original = point_inflation.mark_box
    monkeypatch.setattr(point_inflation, 'mark_box',
                        lambda *args: calls.append(1) or original(*args))
    dense = blocked_mask(grid, obstacles, gamma, layout='dense')
    assert calls, 'the dense cloud did not take the distance transform'
    assert np.array_equal(dense, _stamped(grid, points, gamma))
    calls.clear()
    sparse = blocked_mask(grid, obstacles, gamma, layout='sparse')
    assert calls
    assert np.array_equal(sparse.to_dense(), dense)
    # Tiles of a live map: move part of the cloud, re-inflate the tiles it touched.
    moved = points.copy()
    moved[moved[:, 2] == 0.0] += [0.0, 0.0, 0.3]
    changed = ObstacleSet([PointSet(moved)])
    full = blocked_mask(grid, changed, gamma, layout='dense')
    tiles = np.stack(np.meshgrid(np.arange(4), np.arange(4), np.arange(2), indexing='ij'),
                     axis=-1).reshape(-1, 3)
    tile_nodes = 16
    calls.clear()
    mask = dense.copy()
    reinflate_tiles(grid, changed, gamma, mask, tiles, tile_nodes)
    assert calls
    assert np.array_equal(mask, full)
    again = reinflate_sparse(grid, changed, gamma, sparse, tiles, tile_nodes)
    assert np.array_equal(again.to_dense(), full)


def test_the_build_calls_its_checkpoint_and_stops_when_it_raises():
    grid = VoxelGrid.from_bounds([0.0, 0.0, 0.0], [3.0, 3.0, 2.4], 0.05)
    obstacles = ObstacleSet([PointSet(_wall_room(0.05, 0.01))])
    for layout in ('dense', 'sparse'):
        calls = []
        blocked_mask(grid, obstacles, 0.25, layout=layout, checkpoint=lambda: calls.append(1))
        assert calls, layout

        def spent():
            raise PlanningTimeoutError('grid build ran out')

        with pytest.raises(PlanningTimeoutError):
            blocked_mask(grid, obstacles, 0.25, layout=layout, checkpoint=spent)


def test_a_plan_reports_progress_and_runs_out_in_the_grid_build(monkeypatch):
    config = PlannerConfig(bounds_min=(0.0, 0.0, 0.0), bounds_max=(3.0, 3.0, 2.4),
                           resolution=0.05, safety_margin=0.25, max_planning_time=0.0)
    obstacles = ObstacleSet([PointSet(_wall_room(0.05, 0.01))])
    monkeypatch.setattr(budget_module, 'REPORT_AFTER_S', 0.0)
    monkeypatch.setattr(budget_module, 'REPORT_EVERY_S', 0.0)
    reports = []
    result = Planner(config, obstacles).plan([1.5, 0.5, 1.5], [2.5, 2.0, 1.5],
                                             progress=lambda *report: reports.append(report))
    assert result.ok, result.message
    assert sum(stage is PlanStage.GRID for stage, _, _ in reports) > 2
    # A budget that began before the build (the command line's): warm_up spends it.
    planner = Planner(config, obstacles)
    budget = PlanBudget(1e-3)
    with pytest.raises(PlanningTimeoutError, match='grid build ran out'):
        planner.warm_up(budget)
    result = planner.plan([1.5, 0.5, 1.5], [2.5, 2.0, 1.5], budget=budget)
    assert result.status is PlanStatus.TIMEOUT
    assert result.message.startswith('grid build ran out'), result.message


def test_command_line_budget_covers_the_grid_build(tmp_path):
    # A dense scan (2 M points 1 cm apart) whose grid build alone outlasts the budget.
    np.save(tmp_path / 'scan.npy', _wall_room(0.05, 0.004))
    scene = tmp_path / 'room.yaml'
    scene.write_text('bounds: {min: [0, 0, 0], max: [3, 3, 2.4]}\nresolution: 0.05\n'
                     'safety_margin: 0.25\nadaptive_threshold: 1\nstart: [1.5, 0.5, 1.5]\n'
                     'goal: [2.5, 2.0, 1.5]\nobstacles: []\n')
    executable = shutil.which('uav-plan')
    assert executable, 'uav-plan is not on PATH: run the tests through scripts/test.sh'
    run = subprocess.run([executable, 'plan', str(scene), '--map', str(tmp_path / 'scan.npy'),
                          '--max-planning-time', '0.01', '--json'], capture_output=True,
                         text=True, timeout=600, cwd=Path(tmp_path))
    assert run.returncode == 1, run.stderr  # a planning failure (cli/main.py)
    result = json.loads(run.stdout)
    assert result['status'] == 'timeout'
    assert result['message'].startswith('grid build ran out of the planning time budget'), (
        result['message'])
    assert 'Traceback' not in run.stderr
