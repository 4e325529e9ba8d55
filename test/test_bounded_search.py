"""The certified bounded search (algorithm ``bounded``): cost <= w x optimum, proven per query."""

from dataclasses import replace
import json
import math
import shutil
import subprocess
from typing import List, Union

import numpy as np
import pytest
from rclpy.parameter import Parameter

from ros_harness import in_process_planner
from uav_global_planner.core.config import PlannerConfig, validate_config
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, Sphere
from uav_global_planner.core.map.sparse_grid import SparseMask
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.search.bounded import bounded_search
from uav_global_planner.core.search.bounded_kernel import kernel_masks
from uav_global_planner.core.search.coarse_guide import _cell_open
from uav_global_planner.core.search.grid_search import SearchWorkspace
from uav_global_planner.core.status import PlanStatus

DELTA = 0.25
ETA = 1.5
BOUNDS = (1.0, 1.05, 1.3)


def _scene(seed: int):
    """A cluttered random grid (spheres and boxes inflated by 0.2 m) with free ends."""
    rng = np.random.default_rng(seed)
    grid = VoxelGrid.from_bounds((0.0, 0.0, 0.0), (9.0, 8.0, 4.0), DELTA)
    shapes: List[Union[Sphere, Box]] = []
    for _ in range(int(rng.integers(6, 16))):
        shapes.append(Sphere(rng.uniform((1.0, 0.0, 0.0), (8.0, 8.0, 4.0)),
                             float(rng.uniform(0.4, 1.3))))
    for _ in range(int(rng.integers(2, 6))):
        low = rng.uniform((1.0, 0.0, 0.0), (7.5, 7.0, 2.0))
        shapes.append(Box(low, low + rng.uniform((0.3, 0.3, 1.0), (1.5, 3.0, 4.0))))
    blocked = blocked_mask(grid, ObstacleSet(shapes), 0.2, layout='dense')
    assert isinstance(blocked, np.ndarray)
    free = np.argwhere(~blocked)
    start = free[np.argmin(free @ np.array([1.0, 1.0, 0.1]))]
    goal = free[np.argmax(free @ np.array([1.0, 1.0, 0.1]))]
    return blocked, start, goal


def _path_cost(path: np.ndarray) -> float:
    steps = np.diff(path, axis=0)
    return float(DELTA * np.sqrt(np.abs(steps).sum(axis=1)).sum())


def _check_path(blocked: np.ndarray, path: np.ndarray, start, goal) -> None:
    assert np.array_equal(path[0], start) and np.array_equal(path[-1], goal)
    steps = np.abs(np.diff(path, axis=0))
    assert steps.max(initial=0) <= 1 and (steps.sum(axis=1) >= 1).all(), 'not 26-neighbours'
    assert not blocked[tuple(path.T)].any(), 'the path visits a blocked node'


@pytest.mark.parametrize('layout', ['dense', 'sparse'])
def test_cost_within_bound_of_the_optimum_on_random_scenes(layout: str) -> None:
    phases = set()
    for seed in range(12):
        dense, start, goal = _scene(seed)
        mask = dense if layout == 'dense' else SparseMask.from_dense(dense)
        workspace = SearchWorkspace(mask)
        try:
            optimum = workspace.search(start, goal, 'octile', DELTA, ETA).cost_m
        except Exception:  # no path: the bounded search must say so too
            with pytest.raises(Exception):
                bounded_search(workspace, start, goal, DELTA, ETA, 1.05)
            continue
        for w in BOUNDS:
            for corridor in (True, False):
                found = bounded_search(workspace, start, goal, DELTA, ETA, w,
                                       corridor=corridor)
                phases.add(found.phase)
                _check_path(dense, found.path_indices, start, goal)
                assert math.isclose(_path_cost(found.path_indices), found.cost_m,
                                    rel_tol=1e-9)
                # The certificate: L <= optimum and cost <= w L.
                assert found.lower_bound_m <= optimum * (1.0 + 1e-12)
                assert found.cost_m <= w * found.lower_bound_m * (1.0 + 1e-12)
                assert found.cost_m <= w * optimum * (1.0 + 1e-9)
                assert found.certified_ratio <= w * (1.0 + 1e-12)
                if w == 1.0:
                    assert math.isclose(found.cost_m, optimum, rel_tol=1e-7)
    # Every way of certifying was exercised.
    assert {'octile distance', 'corridor', 'lower-bound search', 'optimal'} <= phases, phases


def test_start_equal_to_goal_is_a_one_node_path() -> None:
    dense, start, _ = _scene(0)
    found = bounded_search(SearchWorkspace(dense), start, start, DELTA, ETA)
    assert found.path_indices.shape == (1, 3) and found.cost_m == 0.0
    assert found.certified_ratio == 1.0


def test_energy_cost_falls_back_to_weighted_with_the_same_bound() -> None:
    dense, start, goal = _scene(3)
    workspace = SearchWorkspace(dense)
    optimum = workspace.search(start, goal, 'octile', DELTA, ETA, climb_weight=3.0).cost_m
    found = bounded_search(workspace, start, goal, DELTA, ETA, 1.05, climb_weight=3.0)
    assert found.phase == 'weighted'
    assert optimum <= found.cost_m <= 1.05 * optimum * (1.0 + 1e-9)
    _check_path(dense, found.path_indices, start, goal)


@pytest.mark.parametrize('bound, words', [(0.99, 'bound must be in [1.0, 10.0], got 0.99'),
                                          (math.nan, 'bound must be finite, got nan'),
                                          (math.inf, 'bound must be finite, got inf'),
                                          ('1.05', "bound must be a number, got '1.05'")])
def test_bad_bound_is_refused_naming_the_setting(bound, words: str) -> None:
    dense, start, goal = _scene(0)
    with pytest.raises(InvalidInputError, match=words.replace('[', r'\[').replace(']', r'\]')):
        bounded_search(SearchWorkspace(dense), start, goal, DELTA, ETA, bound)
    with pytest.raises(InvalidInputError, match='^bound must be'):
        validate_config(PlannerConfig(algorithm='bounded', bound=bound))


def test_bad_bound_in_a_scene_file_names_its_key(tmp_path) -> None:
    text = find_scene('paper_medium').read_text(encoding='utf-8')
    assert 'planner:' not in text
    scene = tmp_path / 'scene.yaml'
    scene.write_text(text + '\nplanner:\n  bound: 0.5\n', encoding='utf-8')
    with pytest.raises(InvalidInputError, match='planner.bound: must be in'):
        load_scene(scene)
    scene.write_text(text + '\nplanner:\n  bound: 1.2\n', encoding='utf-8')
    assert load_scene(scene).config.bound == 1.2


def test_planner_plan_with_bounded_keeps_its_certificates() -> None:
    scene = load_scene(find_scene('paper_medium'))
    planner = Planner(replace(scene.config, algorithm='bounded', bound=1.05), scene.obstacles)
    optimal = Planner(replace(scene.config, algorithm='octile'), scene.obstacles)
    result = planner.plan(scene.start, scene.goal)
    best = optimal.plan(scene.start, scene.goal)
    assert result.status is PlanStatus.OK, result.message
    assert result.algorithm == 'bounded'
    assert result.cost <= 1.05 * best.cost * (1.0 + 1e-9)
    blocked = planner.blocked
    nodes = planner.grid.world_to_index(result.path)
    assert not np.asarray(blocked)[tuple(np.asarray(nodes).T)].any()
    assert planner.plan_is_clear(result).clear


@pytest.mark.ros
def test_node_accepts_bounded_and_refuses_a_bad_bound_keeping_the_last_good() -> None:
    with in_process_planner() as node:
        ros = node.node
        (result,) = ros.set_parameters([Parameter('algorithm', value='bounded')])
        assert result.successful, result.reason
        (result,) = ros.set_parameters([Parameter('bound', value=1.2)])
        assert result.successful, result.reason
        for bad in (0.5, math.nan, math.inf):
            (result,) = ros.set_parameters([Parameter('bound', value=bad)])
            assert not result.successful
            assert 'bound' in result.reason, result.reason
            assert ros.get_parameter('bound').value == 1.2
        assert ros.get_parameter('algorithm').value == 'bounded'


def test_uav_plan_takes_bounded_and_refuses_a_bad_bound() -> None:
    executable = shutil.which('uav-plan')
    assert executable, 'uav-plan is not on PATH: run the tests through scripts/test.sh'
    run = subprocess.run([executable, 'plan', 'paper_medium', '--algorithm', 'bounded',
                          '--bound', '1.05', '--json'], capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)['algorithm'] == 'bounded'
    for bad, words in (('0.9', 'bound must be in [1.0, 10.0], got 0.9'),
                       ('nan', 'bound must be finite, got nan')):
        run = subprocess.run([executable, 'plan', 'paper_medium', '--algorithm', 'bounded',
                              '--bound', bad], capture_output=True, text=True, timeout=600)
        assert run.returncode == 2
        assert words in run.stderr, run.stderr


def test_coarse_cells_read_alike_from_dense_and_sparse_masks() -> None:
    rng = np.random.default_rng(1)
    for trial in range(6):
        shape = tuple(int(n) for n in rng.integers(5, 30, 3))
        dense = rng.random(shape) < rng.uniform(0.3, 0.999)
        if trial % 2:
            dense[:16, :16, :16] = True  # whole full bricks
        masks = kernel_masks(dense), kernel_masks(SparseMask.from_dense(dense))
        for size in (2, 4, 8, 16):
            cells = [-(-n // size) for n in shape]
            for cell in np.ndindex(*cells):
                opened = [_cell_open(*m, *shape, size, *cell) for m in masks]
                block = dense[tuple(slice(c * size, (c + 1) * size) for c in cell)]
                assert opened == [not block.all()] * 2, (shape, size, cell)
