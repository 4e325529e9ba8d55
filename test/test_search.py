"""Tests of the grid search (uav_global_planner.core.search.grid_search).

Costs are checked against an independent shortest-path computation: the 26-connected graph over
the free nodes is built with numpy and solved with scipy.sparse.csgraph (test/helpers/scenes.py).
"""

import json
import math
import os
from pathlib import Path
import re
import subprocess
import sys
import time

from helpers.scenes import graph_distances
import numpy as np
import pytest

from uav_global_planner.core.config import ALGORITHMS as CONFIGURABLE
from uav_global_planner.core.errors import (GoalOccupiedError, InvalidInputError, NoValidPathError,
                                            PlanningTimeoutError, StartOccupiedError)
from uav_global_planner.core.jit import JIT_ENABLED
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, PointSet, Sphere
from uav_global_planner.core.map.sparse_grid import SparseMask
from uav_global_planner.core.search import grid_search as search_module
from uav_global_planner.core.search.grid_search import (ALGORITHM_CODES, DEFAULT_WEIGHT, search,
                                                        SearchResult, SearchWorkspace)

REPO = Path(__file__).resolve().parents[1]
#: The algorithms of the grid search itself ('bounded' is a search of its own, built on it,
#: that the planner runs: test_bounded_search.py).
ALGORITHMS = tuple(ALGORITHM_CODES)
OPTIMAL = ('dijkstra', 'astar', 'octile')
N_RANDOM_SCENES = 240
# Relative tolerance of cost comparisons: sums of a few hundred step costs in float64.
RTOL = 1e-9


def random_scene(seed: int):
    """A small random grid with spheres, boxes and point sets, and free start and goal nodes.

    Returns ``(blocked, resolution, eta, start, goal)`` with (i, j, k) start and goal indices.
    """
    rng = np.random.default_rng(seed)
    while True:
        resolution = float(rng.uniform(0.2, 0.5))
        lo = rng.uniform(-2.0, 2.0, 3)
        hi = lo + rng.uniform(0.5, 3.0, 3)
        grid = VoxelGrid.from_bounds(lo, hi, resolution)
        gamma = float(rng.uniform(0.0, 0.4))
        obstacles = []
        for _ in range(int(rng.integers(0, 6))):
            kind = rng.integers(3)
            if kind == 0:
                obstacles.append(Sphere(rng.uniform(lo, hi), rng.uniform(0.1, 0.8)))
            elif kind == 1:
                corner = rng.uniform(lo, hi)
                obstacles.append(Box(corner, corner + rng.uniform(0.05, 1.2, 3)))
            else:
                obstacles.append(PointSet(rng.uniform(lo, hi, (int(rng.integers(1, 40)), 3))))
        if rng.random() < 0.25:
            # A thin wall across the whole workspace, sometimes cutting it in two.
            axis = int(rng.integers(3))
            wall_lo, wall_hi = lo - 1.0, hi + 1.0
            wall_lo[axis] = rng.uniform(lo[axis], hi[axis])
            wall_hi[axis] = wall_lo[axis] + 0.05
            obstacles.append(Box(wall_lo, wall_hi))
        blocked = blocked_mask(grid, ObstacleSet(obstacles), gamma)
        free = np.flatnonzero(~blocked)
        if len(free):
            break
    start, goal = (grid.unravel(node) for node in rng.choice(free, 2))
    return blocked, resolution, float(rng.uniform(0.0, 2.0)), start, goal


def check_path(result: SearchResult, blocked: np.ndarray, resolution: float, start,
               goal, elapsed_s: float) -> None:
    """Every structural property a search result must have.

    ``elapsed_s`` is the wall-clock time [s] the test measured around the call: the search
    time reported must lie within it (in seconds, not another unit, and not 0 by default).
    """
    path = result.path_indices
    assert path.dtype == np.int64 and path.ndim == 2 and path.shape[1] == 3
    assert np.array_equal(path[0], start)
    assert np.array_equal(path[-1], goal)
    assert np.all(path >= 0) and np.all(path < blocked.shape)
    assert not np.any(blocked[tuple(path.T)]), 'path crosses a blocked node'
    steps = np.abs(np.diff(path, axis=0))
    assert np.all(steps <= 1), 'consecutive nodes are not 26-neighbours'
    axes = steps.sum(axis=1)
    assert np.all(axes >= 1), 'path repeats a node'
    assert result.cost_m == pytest.approx(float(np.sum(resolution * np.sqrt(axes))), rel=RTOL,
                                          abs=1e-12)
    assert result.expanded_nodes >= 1
    assert 0.0 < result.search_time_s <= elapsed_s


@pytest.mark.parametrize('seed', range(N_RANDOM_SCENES))
def test_random_scene_matches_csgraph(seed):
    blocked, resolution, eta, start, goal = random_scene(seed)
    shape = blocked.shape
    distance = graph_distances(blocked, resolution,
                               int(np.ravel_multi_index(tuple(start), shape)))
    optimum = distance[np.ravel_multi_index(tuple(goal), shape)]
    workspace = SearchWorkspace(blocked)
    for algorithm in ALGORITHMS:
        if not np.isfinite(optimum):
            with pytest.raises(NoValidPathError, match='expanded'):
                workspace.search(start, goal, algorithm, resolution, eta)
            continue
        began = time.perf_counter()
        result = workspace.search(start, goal, algorithm, resolution, eta)
        check_path(result, blocked, resolution, start, goal, time.perf_counter() - began)
        if algorithm in OPTIMAL:
            assert result.cost_m == pytest.approx(optimum, rel=RTOL, abs=1e-12), algorithm
        else:
            assert result.cost_m >= optimum * (1.0 - RTOL)
        if algorithm == 'weighted':
            assert result.cost_m <= DEFAULT_WEIGHT * optimum * (1.0 + RTOL) + 1e-12


@pytest.mark.parametrize('weight', [1.0, 1.2, 2.0, 5.0])
@pytest.mark.parametrize('seed', range(0, N_RANDOM_SCENES, 3))
def test_weighted_search_keeps_its_bound(seed, weight):
    blocked, resolution, eta, start, goal = random_scene(seed)
    shape = blocked.shape
    distance = graph_distances(blocked, resolution,
                               int(np.ravel_multi_index(tuple(start), shape)))
    optimum = distance[np.ravel_multi_index(tuple(goal), shape)]
    if not np.isfinite(optimum):
        return
    workspace = SearchWorkspace(blocked)
    began = time.perf_counter()
    result = workspace.search(start, goal, 'weighted', resolution, eta, weight=weight)
    check_path(result, blocked, resolution, start, goal, time.perf_counter() - began)
    assert optimum * (1.0 - RTOL) <= result.cost_m <= weight * optimum * (1.0 + RTOL) + 1e-12
    if weight == 1.0:
        assert result.cost_m == pytest.approx(optimum, rel=RTOL, abs=1e-12)


def test_random_scenes_cover_the_interesting_cases():
    """The generator yields unreachable goals, start == goal and obstacle-free scenes."""
    unreachable = same = clear = 0
    for seed in range(N_RANDOM_SCENES):
        blocked, resolution, _, start, goal = random_scene(seed)
        source = int(np.ravel_multi_index(tuple(start), blocked.shape))
        target = int(np.ravel_multi_index(tuple(goal), blocked.shape))
        unreachable += not np.isfinite(graph_distances(blocked, resolution, source)[target])
        same += source == target
        clear += not blocked.any()
    assert unreachable >= 5 and same >= 1 and clear >= 5


def medium_scene():
    """paper_medium.yaml built as the planner does: spheres inflated by gamma, snapped ends."""
    import yaml
    data = yaml.safe_load((REPO / 'config' / 'scenes' / 'paper_medium.yaml').read_text())
    grid = VoxelGrid.from_bounds(data['bounds']['min'], data['bounds']['max'],
                                 data['resolution'])
    obstacles = ObstacleSet(Sphere(o['center'], o['radius']) for o in data['obstacles'])
    blocked = blocked_mask(grid, obstacles, data['safety_margin'])
    return (blocked, data['resolution'], data['adaptive_threshold'],
            grid.world_to_index(data['start']), grid.world_to_index(data['goal']))


def test_paper_medium_figures():
    blocked, resolution, eta, start, goal = medium_scene()
    workspace = SearchWorkspace(blocked)
    results = {a: workspace.search(start, goal, a, resolution, eta) for a in ALGORITHMS}
    for algorithm in OPTIMAL:
        assert results[algorithm].cost_m == pytest.approx(19.367, abs=5e-4)
    adaptive = results['adaptive']
    assert 19.367 < adaptive.cost_m < 1.1 * 19.367
    assert adaptive.expanded_nodes * 10 < results['astar'].expanded_nodes
    assert results['octile'].expanded_nodes * 3 < results['astar'].expanded_nodes
    assert results['astar'].expanded_nodes < results['dijkstra'].expanded_nodes


def test_start_equals_goal_is_a_single_node():
    blocked = np.zeros((4, 5, 6), dtype=bool)
    for algorithm in ALGORITHMS:
        result = search(blocked, (1, 2, 3), (1, 2, 3), algorithm, 0.5, 1.5)
        assert result.path_indices.tolist() == [[1, 2, 3]]
        assert result.cost_m == 0.0
        assert result.expanded_nodes == 1


def test_straight_and_diagonal_costs_on_an_empty_grid():
    blocked = np.zeros((6, 6, 6), dtype=bool)
    assert search(blocked, (0, 0, 0), (5, 0, 0), 'astar', 0.5, 1.5).cost_m == pytest.approx(2.5)
    diagonal = search(blocked, (0, 0, 0), (5, 5, 5), 'octile', 0.5, 1.5)
    assert diagonal.cost_m == pytest.approx(2.5 * math.sqrt(3.0))
    assert len(diagonal.path_indices) == 6


def test_expansion_budget():
    blocked, resolution, eta, start, goal = medium_scene()
    workspace = SearchWorkspace(blocked)
    with pytest.raises(PlanningTimeoutError, match=r'max_expansions = 5\b.*expanding 5 nodes'):
        workspace.search(start, goal, 'astar', resolution, eta, max_expansions=5)
    needed = workspace.search(start, goal, 'astar', resolution, eta).expanded_nodes
    exact = workspace.search(start, goal, 'astar', resolution, eta, max_expansions=needed)
    assert exact.expanded_nodes == needed
    with pytest.raises(PlanningTimeoutError, match=f'expanding {needed - 1} nodes'):
        workspace.search(start, goal, 'astar', resolution, eta, max_expansions=needed - 1)


def test_time_budget_on_a_large_grid():
    blocked = np.zeros((100, 100, 100), dtype=bool)
    with pytest.raises(PlanningTimeoutError, match='max_time_s') as caught:
        search(blocked, (0, 0, 0), (99, 99, 99), 'dijkstra', 0.1, 1.5, max_time_s=1e-4)
    expanded = int(re.search(r'expanding (\d+) nodes', str(caught.value)).group(1))
    assert 0 < expanded < blocked.size


def test_timeout_and_no_path_carry_their_status():
    assert PlanningTimeoutError.status.value == 'timeout'
    blocked = np.zeros((5, 5, 5), dtype=bool)
    blocked[2] = True
    with pytest.raises(NoValidPathError) as caught:
        search(blocked, (0, 0, 0), (4, 4, 4), 'adaptive', 0.5, 1.5)
    assert caught.value.status.value == 'no_valid_path'
    assert 'all 50 nodes' in str(caught.value)


def test_chunked_search_equals_one_call():
    """A time budget splits the search into resumed chunks; the result must not change."""
    blocked, resolution, eta, start, goal = medium_scene()
    workspace = SearchWorkspace(blocked)
    whole = workspace.search(start, goal, 'dijkstra', resolution, eta)
    assert whole.expanded_nodes > 2 * search_module._CHUNK
    chunked = workspace.search(start, goal, 'dijkstra', resolution, eta, max_time_s=600.0)
    assert np.array_equal(whole.path_indices, chunked.path_indices)
    assert whole.expanded_nodes == chunked.expanded_nodes
    assert whole.cost_m == chunked.cost_m


def _queries():
    """Queries on paper_medium, including failures that leave a half-finished search behind."""
    blocked, resolution, eta, start, goal = medium_scene()
    free = np.argwhere(~blocked)
    rng = np.random.default_rng(7)
    queries = [(start, goal, a, 0) for a in ALGORITHMS]
    queries.append((start, goal, 'astar', 3))
    queries += [(free[a], free[b], ALGORITHMS[n % len(ALGORITHMS)], 0)
                for n, (a, b) in enumerate(rng.integers(len(free), size=(12, 2)))]
    return blocked, resolution, eta, queries


def _outcome(workspace, blocked, resolution, eta, query):
    start, goal, algorithm, budget = query
    try:
        result = workspace.search(start, goal, algorithm, resolution, eta, max_expansions=budget)
    except (PlanningTimeoutError, NoValidPathError) as error:
        return type(error).__name__, str(error).split(' in ')[0]
    return result.path_indices.tolist(), result.cost_m, result.expanded_nodes


def test_same_query_twice_is_identical():
    blocked, resolution, eta, start, goal = medium_scene()
    workspace = SearchWorkspace(blocked)
    for algorithm in ALGORITHMS:
        first = workspace.search(start, goal, algorithm, resolution, eta)
        second = workspace.search(start, goal, algorithm, resolution, eta)
        assert np.array_equal(first.path_indices, second.path_indices)
        assert first.expanded_nodes == second.expanded_nodes
        assert first.cost_m == second.cost_m


def test_reused_workspace_equals_fresh_workspaces():
    blocked, resolution, eta, queries = _queries()
    shared = SearchWorkspace(blocked)
    for query in queries:
        fresh = _outcome(SearchWorkspace(blocked), blocked, resolution, eta, query)
        assert _outcome(shared, blocked, resolution, eta, query) == fresh


def test_set_blocked_swaps_the_grid():
    blocked, resolution, eta, queries = _queries()
    other = blocked.copy()
    other[:, :, 4] = True
    other[20, 20, 4] = False
    workspace = SearchWorkspace(blocked)
    for grid in (other, blocked, other):
        workspace.set_blocked(grid)
        for query in queries[:4]:
            assert (_outcome(workspace, grid, resolution, eta, query)
                    == _outcome(SearchWorkspace(grid), grid, resolution, eta, query))
    with pytest.raises(InvalidInputError, match='shape'):
        workspace.set_blocked(blocked[1:])


def test_generation_counter_wraps_around():
    blocked, resolution, eta, queries = _queries()
    workspace = SearchWorkspace(blocked)
    expected = [_outcome(workspace, blocked, resolution, eta, q) for q in queries[:4]]
    workspace._generation = search_module._MAX_GENERATION - 2
    again = [_outcome(workspace, blocked, resolution, eta, q) for q in queries[:4]]
    assert again == expected
    assert workspace._generation < 10


_SUBPROCESS_SCRIPT = """
import json
import numpy as np
from uav_global_planner.core.jit import JIT_ENABLED
from uav_global_planner.core.search.grid_search import ALGORITHM_CODES, search
blocked = np.zeros((9, 8, 7), dtype=bool)
blocked[3:6, 1:8, 0:6] = True
blocked[6, 0:3, 2] = True
out = {'jit': JIT_ENABLED}
for algorithm in ALGORITHM_CODES:
    r = search(blocked, (0, 7, 0), (8, 0, 6), algorithm, 0.3, 0.8)
    out[algorithm] = [r.path_indices.tolist(), r.cost_m, r.expanded_nodes]
print(json.dumps(out))
"""


def _run_subprocess(disable_jit: bool) -> dict:
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(REPO), env.get('PYTHONPATH')]))
    env['UAV_PLANNER_DISABLE_JIT'] = '1' if disable_jit else '0'
    done = subprocess.run([sys.executable, '-c', _SUBPROCESS_SCRIPT], env=env, check=True,
                          capture_output=True, text=True, timeout=120)
    return json.loads(done.stdout)


def test_pure_python_fallback_matches_compiled():
    plain = _run_subprocess(disable_jit=True)
    assert plain.pop('jit') is False
    # The child ran every algorithm its search accepts: the configurable ones but 'bounded'.
    assert sorted(plain) == sorted(ALGORITHMS)
    assert sorted(set(CONFIGURABLE) - set(ALGORITHMS)) == ['bounded']
    compiled = _run_subprocess(disable_jit=False) if not JIT_ENABLED else None
    blocked = np.zeros((9, 8, 7), dtype=bool)
    blocked[3:6, 1:8, 0:6] = True
    blocked[6, 0:3, 2] = True
    for algorithm in ALGORITHMS:
        r = search(blocked, (0, 7, 0), (8, 0, 6), algorithm, 0.3, 0.8)
        here = [r.path_indices.tolist(), r.cost_m, r.expanded_nodes]
        assert plain[algorithm] == here, algorithm
        if compiled is not None:
            assert compiled[algorithm] == here, algorithm


def test_octile_heuristic_is_the_free_space_distance():
    shape, resolution = (7, 6, 5), 0.3
    blocked = np.zeros(shape, dtype=bool)
    for source in [(0, 0, 0), (3, 2, 4), (6, 5, 2)]:
        distance = graph_distances(blocked, resolution, int(np.ravel_multi_index(source, shape)))
        for node in np.ndindex(*shape):
            di, dj, dk = (abs(a - b) for a, b in zip(node, source))
            h = search_module._heuristic(ALGORITHM_CODES['octile'], di, dj, dk, resolution, 0.0,
                                         1.0)
            assert h == pytest.approx(distance[np.ravel_multi_index(node, shape)], rel=1e-12,
                                      abs=1e-12)


def test_heuristic_definitions():
    def h(code, di, dj, dk, resolution, eta, weight=1.0):
        return search_module._heuristic(code, di, dj, dk, resolution, eta, weight)

    codes = ALGORITHM_CODES
    assert h(codes['dijkstra'], 3, 4, 12, 0.5, 1.0) == 0.0
    assert h(codes['astar'], 3, 4, 12, 0.5, 1.0) == pytest.approx(6.5)
    # Euclidean 6.5 m > eta = 1 m: Manhattan 0.5 * 19; within eta = 7 m: Euclidean.
    assert h(codes['adaptive'], 3, 4, 12, 0.5, 1.0) == pytest.approx(9.5)
    assert h(codes['adaptive'], 3, 4, 12, 0.5, 7.0) == pytest.approx(6.5)
    assert h(codes['adaptive'], 3, 4, 12, 0.5, 6.5) == pytest.approx(6.5)
    expected = 0.5 * (math.sqrt(3) * 3 + math.sqrt(2) * 1 + 8)
    assert h(codes['octile'], 12, 3, 4, 0.5, 1.0) == pytest.approx(expected)
    assert h(codes['octile'], 3, 4, 12, 0.5, 1.0) == pytest.approx(expected)
    # The weight scales the octile distance for 'weighted' only.
    assert h(codes['weighted'], 3, 4, 12, 0.5, 1.0, 1.25) == pytest.approx(1.25 * expected)
    assert h(codes['octile'], 3, 4, 12, 0.5, 1.0, 1.25) == pytest.approx(expected)


def test_invalid_inputs_are_rejected():
    blocked = np.zeros((4, 4, 4), dtype=bool)
    blocked[1, 1, 1] = True
    workspace = SearchWorkspace(blocked)
    ok = dict(algorithm='astar', resolution=0.5, adaptive_threshold=1.0)
    with pytest.raises(InvalidInputError, match='algorithm'):
        workspace.search((0, 0, 0), (3, 3, 3), 'bfs', 0.5, 1.0)
    for bad in [(0, 0), (0, 0, 4), (-1, 0, 0), (0.0, 1.0, 2.0), 'abc']:
        with pytest.raises(InvalidInputError, match='start_index'):
            workspace.search(bad, (3, 3, 3), **ok)
        with pytest.raises(InvalidInputError, match='goal_index'):
            workspace.search((3, 3, 3), bad, **ok)
    for name, value in [('resolution', 0.0), ('resolution', math.nan),
                        ('adaptive_threshold', -1.0), ('max_time_s', -1.0),
                        ('max_expansions', -1), ('max_expansions', 2.5)]:
        with pytest.raises(InvalidInputError, match=name):
            workspace.search((0, 0, 0), (3, 3, 3), **{**ok, name: value})
    with pytest.raises(StartOccupiedError):
        workspace.search((1, 1, 1), (3, 3, 3), **ok)
    with pytest.raises(GoalOccupiedError):
        workspace.search((0, 0, 0), (1, 1, 1), **ok)
    for bad_grid in [np.zeros((4, 4), dtype=bool), np.zeros((4, 4, 4), dtype=np.uint8),
                     np.zeros((0, 4, 4), dtype=bool), [[[False]]]]:
        with pytest.raises(InvalidInputError, match='blocked'):
            SearchWorkspace(bad_grid)


def test_non_contiguous_grid_is_accepted():
    blocked = np.zeros((6, 5, 4), dtype=bool)
    blocked[2, :, 1:] = True
    reference = search(blocked, (0, 0, 3), (5, 4, 3), 'dijkstra', 0.5, 1.0)
    transposed = np.ascontiguousarray(blocked.transpose(2, 1, 0)).transpose(2, 1, 0)
    assert not transposed.flags.c_contiguous
    result = search(transposed, (0, 0, 3), (5, 4, 3), 'dijkstra', 0.5, 1.0)
    assert result.cost_m == reference.cost_m
    assert np.array_equal(result.path_indices, reference.path_indices)


def test_jit_flag_tells_whether_the_kernels_are_compiled():
    # numba's dispatchers have the compiled signatures; the plain functions have none.
    kernels = [value for name, value in vars(search_module).items()
               if name.startswith('_') and callable(value) and hasattr(value, 'py_func')]
    assert isinstance(JIT_ENABLED, bool)
    assert bool(kernels) == JIT_ENABLED
    if os.environ.get('UAV_PLANNER_DISABLE_JIT') == '1':
        assert not JIT_ENABLED


def test_every_algorithm_name_selects_its_own_heuristic():
    """Each configurable name reaches the search, with a heuristic no other name has."""
    blocked = np.zeros((4, 4, 4), dtype=bool)
    for algorithm in ALGORITHMS:
        assert search(blocked, (0, 0, 0), (3, 2, 1), algorithm, 0.5, 1.0).cost_m > 0.0
    # At a displacement where the formulas differ (see test_heuristic_definitions).
    values = {name: search_module._heuristic(ALGORITHM_CODES[name], 3, 4, 12, 0.5, 1.0, 1.25)
              for name in ALGORITHMS}
    assert len(set(values.values())) == len(ALGORITHMS), values
    with pytest.raises(InvalidInputError, match='algorithm must be one of'):
        search(blocked, (0, 0, 0), (3, 2, 1), 'theta*', 0.5, 1.0)


def textbook_search(blocked: np.ndarray, start, goal, algorithm: str, resolution: float,
                    eta: float):
    """Plain A* with Python's binary heap, keyed (f, h, node number), stale entries skipped.

    Returns ``(path, cost, expanded)`` like the search, or None when the goal is unreachable.
    """
    import heapq
    shape = blocked.shape
    code = ALGORITHM_CODES[algorithm]
    goal_t = tuple(int(v) for v in goal)

    def h(node):
        a, b, c = np.unravel_index(node, shape)
        return search_module._heuristic(code, abs(int(a) - goal_t[0]), abs(int(b) - goal_t[1]),
                                        goal_t[2] - int(c), resolution, eta, DEFAULT_WEIGHT)

    source = int(np.ravel_multi_index(tuple(start), shape))
    target = int(np.ravel_multi_index(goal_t, shape))
    g = {source: 0.0}
    parent = {source: -1}
    closed = set()
    heap = [(h(source), h(source), source)]
    steps = [(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)
             if (a, b, c) != (0, 0, 0)]
    while heap:
        _, _, node = heapq.heappop(heap)
        if node in closed:
            continue
        closed.add(node)
        if node == target:
            chain = [node]
            while parent[chain[-1]] >= 0:
                chain.append(parent[chain[-1]])
            path = np.stack(np.unravel_index(chain[::-1], shape), axis=-1)
            return path.tolist(), g[node], len(closed)
        i, j, k = (int(v) for v in np.unravel_index(node, shape))
        for a, b, c in steps:
            n = (i + a, j + b, k + c)
            if not all(0 <= n[m] < shape[m] for m in range(3)) or blocked[n]:
                continue
            neighbour = int(np.ravel_multi_index(n, shape))
            cost = g[node] + resolution * math.sqrt(abs(a) + abs(b) + abs(c))
            if neighbour in closed or cost >= g.get(neighbour, math.inf):
                continue
            g[neighbour] = cost
            parent[neighbour] = node
            heapq.heappush(heap, (cost + h(neighbour), h(neighbour), neighbour))
    return None


@pytest.mark.parametrize('seed', range(0, N_RANDOM_SCENES, 8))
@pytest.mark.parametrize('dial', [True, False])
def test_open_list_pops_in_binary_heap_order(monkeypatch, seed, dial):
    """The bucketed open list expands exactly the nodes, in the order, of one binary heap: same
    path, cost and number of expansions as a textbook A*, on both grid layouts. Dial's mode of
    ``dijkstra`` (each bucket in push order) keeps the cost, not the order."""
    monkeypatch.setattr(search_module, '_DIAL', dial)
    blocked, resolution, eta, start, goal = random_scene(seed)
    for mask in (blocked, SparseMask.from_dense(blocked)):
        workspace = SearchWorkspace(mask)
        for algorithm in ALGORITHM_CODES:
            expected = textbook_search(blocked, start, goal, algorithm, resolution, eta)
            if expected is None:
                with pytest.raises(NoValidPathError):
                    workspace.search(start, goal, algorithm, resolution, eta)
                continue
            result = workspace.search(start, goal, algorithm, resolution, eta)
            if dial and algorithm == 'dijkstra':
                assert result.cost_m == pytest.approx(expected[1], rel=RTOL, abs=1e-12)
                continue
            assert result.path_indices.tolist() == expected[0], algorithm
            assert result.cost_m == pytest.approx(expected[1], rel=RTOL, abs=1e-12)
            assert result.expanded_nodes == expected[2], algorithm


@pytest.mark.parametrize('width, ring', [(0.5, 1 << 16), (0.01, 4), (1.0 - 1e-7, 1),
                                         (1.0 - 1e-7, 2)])
def test_dial_bucket_width_and_ring_size_keep_the_cost(monkeypatch, width, ring):
    """Dial's buckets narrower than the cheapest step, and rings too short for the costliest
    step (keys then wait in the ring's last bucket), keep the uniform-cost optimum."""
    blocked, resolution, eta, queries = _queries()
    queries = [(q[0], q[1], 'dijkstra', 0) for q in queries[::2]]
    monkeypatch.setattr(search_module, '_DIAL', False)
    expected = [_outcome(SearchWorkspace(blocked), blocked, resolution, eta, q) for q in queries]
    monkeypatch.setattr(search_module, '_DIAL', True)
    monkeypatch.setattr(search_module, '_DIAL_WIDTH', width)
    monkeypatch.setattr(search_module, '_DIAL_MAX_RING', ring)
    workspace = SearchWorkspace(blocked)
    for query, before in zip(queries, expected):
        after = _outcome(workspace, blocked, resolution, eta, query)
        if isinstance(before[0], str):
            assert after == before
        else:
            assert after[1] == pytest.approx(before[1], rel=RTOL, abs=1e-12)


def larger_scene(seed: int):
    """A random box-and-sphere grid of 9 to 30 nodes an axis (partial bricks of 8 nodes
    included), with free start and goal nodes: ``(blocked, resolution, start, goal)``."""
    rng = np.random.default_rng(1000 + seed)
    shape = tuple(int(n) for n in rng.integers(9, 31, 3))
    resolution = float(rng.uniform(0.1, 1.0))
    index = np.indices(shape).transpose(1, 2, 3, 0)
    blocked = np.zeros(shape, dtype=bool)
    for _ in range(int(rng.integers(1, 12))):
        low = rng.integers(0, shape)
        if rng.random() < 0.5:
            blocked |= np.all((index >= low) & (index <= low + rng.integers(1, 8, 3)), axis=-1)
        else:
            blocked |= np.sum((index - low) ** 2, axis=-1) <= rng.integers(1, 30)
    free = np.argwhere(~blocked)
    start, goal = free[rng.choice(len(free), 2)]
    return blocked, resolution, start, goal


@pytest.mark.parametrize('seed', range(40))
def test_both_layouts_match_csgraph_on_larger_grids(seed):
    """Optimal costs against scipy's Dijkstra on the same graph, dense and block-sparse masks
    (nodes inside bricks take the one-lookup path), and the bound of ``weighted``."""
    blocked, resolution, start, goal = larger_scene(seed)
    distance = graph_distances(blocked, resolution,
                               int(np.ravel_multi_index(tuple(start), blocked.shape)))
    optimum = distance[np.ravel_multi_index(tuple(goal), blocked.shape)]
    outcomes = []
    for mask in (blocked, SparseMask.from_dense(blocked)):
        workspace = SearchWorkspace(mask)
        for algorithm in ALGORITHM_CODES:
            if not np.isfinite(optimum):
                with pytest.raises(NoValidPathError):
                    workspace.search(start, goal, algorithm, resolution, 1.0)
                continue
            result = workspace.search(start, goal, algorithm, resolution, 1.0)
            outcomes.append((result.path_indices.tolist(), result.cost_m,
                             result.expanded_nodes))
            assert not np.any(blocked[tuple(result.path_indices.T)])
            if algorithm in OPTIMAL:
                assert result.cost_m == pytest.approx(optimum, rel=RTOL, abs=1e-12), algorithm
            else:
                assert result.cost_m >= optimum * (1.0 - RTOL)
            if algorithm == 'weighted':
                assert result.cost_m <= DEFAULT_WEIGHT * optimum * (1.0 + RTOL)
    half = len(outcomes) // 2
    assert outcomes[:half] == outcomes[half:]


@pytest.mark.parametrize('seed', range(0, N_RANDOM_SCENES, 12))
@pytest.mark.parametrize('climb, descent', [(1.0, 1.0), (2.5, 0.4), (1.0, 0.0), (0.0, 3.0)])
def test_dial_mode_keeps_the_uniform_cost_optimum(monkeypatch, seed, climb, descent):
    """``dijkstra`` in Dial's mode (buckets as wide as the cheapest step, popped in push order)
    costs what the exact order costs, with climb and descent weights too; a free vertical step
    (a weight of 0) leaves it in the exact order."""
    blocked, resolution, eta, start, goal = random_scene(seed)
    for mask in (blocked, SparseMask.from_dense(blocked)):
        outcomes = []
        for dial in (True, False):
            monkeypatch.setattr(search_module, '_DIAL', dial)
            try:
                result = SearchWorkspace(mask).search(start, goal, 'dijkstra', resolution, eta,
                                                      climb_weight=climb, descent_weight=descent)
            except NoValidPathError as error:
                outcomes.append(('no path', error.expanded_nodes))
                continue
            outcomes.append(result)
        if isinstance(outcomes[0], tuple):
            assert outcomes[0] == outcomes[1]
            continue
        assert outcomes[0].cost_m == pytest.approx(outcomes[1].cost_m, rel=RTOL, abs=1e-12)
        if min(climb, descent) == 0.0:
            assert outcomes[0].path_indices.tolist() == outcomes[1].path_indices.tolist()
