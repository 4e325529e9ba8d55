"""The energy-aware cost (climb and descent weights) and the flight time and energy estimate.

Costs are checked against an independent shortest-path computation on the weighted, directed
26-connected graph (scipy.sparse.csgraph), the adapted octile heuristic against the exact
obstacle-free cost and its own consistency inequality, and the energy model against closed
forms on trajectories built here.
"""

from dataclasses import replace
import itertools
import math

from helpers.scenes import free_graph
import numpy as np
import pytest
from scipy.sparse.csgraph import shortest_path

from uav_global_planner.core.config import PlannerConfig, validate_config
from uav_global_planner.core.errors import InvalidInputError, NoValidPathError
from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, Sphere
from uav_global_planner.core.path.energy import (estimate_energy, GRAVITY, parse_vehicle,
                                                 VehicleModel)
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.result import Trajectory
from uav_global_planner.core.search import grid_search as search_module
from uav_global_planner.core.search.grid_search import (ALGORITHM_CODES, DEFAULT_WEIGHT,
                                                        SearchWorkspace)

#: The grid search's own algorithms ('bounded' runs them: test_bounded_search.py).
ALGORITHMS = tuple(ALGORITHM_CODES)
RTOL = 1e-9
# Weight pairs: the paper's length, costly climbs, cheap descents, free vertical moves, and
# pairs cheap enough that up-down sawtooths pay.
WEIGHT_PAIRS = [(1.0, 1.0), (3.0, 1.0), (1.0, 0.2), (2.0, 0.0), (0.0, 0.0), (0.5, 0.6),
                (0.1, 1.5), (5.0, 5.0), (0.7, 0.7)]


def step_cost(offset, resolution: float, climb: float, descent: float) -> float:
    """Cost of one move, straight from the definition."""
    length = math.sqrt(sum(abs(v) for v in offset))
    weight = climb if offset[2] > 0 else descent if offset[2] < 0 else 1.0
    return resolution * (length + (weight - 1.0) * abs(offset[2]))


def weighted_graph_distances(blocked: np.ndarray, resolution: float, climb: float,
                             descent: float, source: int) -> np.ndarray:
    """Cheapest directed 26-connected cost [m] from flat node ``source`` to every node."""
    graph = free_graph(blocked, lambda offset: step_cost(offset, resolution, climb, descent),
                       directed=True)
    return shortest_path(graph, method='D', directed=True, indices=source)


def random_blocked(seed: int):
    rng = np.random.default_rng(seed)
    resolution = float(rng.uniform(0.2, 0.5))
    lo = rng.uniform(-2.0, 2.0, 3)
    hi = lo + rng.uniform([1.0, 1.0, 0.6], [3.0, 3.0, 2.5])
    grid = VoxelGrid.from_bounds(lo, hi, resolution)
    obstacles = [Sphere(rng.uniform(lo, hi), rng.uniform(0.1, 0.7))
                 for _ in range(int(rng.integers(0, 4)))]
    for _ in range(int(rng.integers(0, 3))):
        corner = rng.uniform(lo, hi)
        obstacles.append(Box(corner, corner + rng.uniform(0.05, 1.0, 3)))
    blocked = blocked_mask(grid, ObstacleSet(obstacles), float(rng.uniform(0.0, 0.3)))
    free = np.flatnonzero(~blocked)
    start, goal = (grid.unravel(node) for node in rng.choice(free, 2))
    return blocked, resolution, start, goal, rng


def path_cost(path: np.ndarray, resolution: float, climb: float, descent: float) -> float:
    return sum(step_cost(tuple(step), resolution, climb, descent)
               for step in np.diff(path, axis=0))


@pytest.mark.parametrize('seed', range(60))
def test_weighted_costs_match_an_independent_shortest_path(seed):
    blocked, resolution, start, goal, rng = random_blocked(seed)
    climb, descent = WEIGHT_PAIRS[seed % len(WEIGHT_PAIRS)]
    shape = blocked.shape
    distance = weighted_graph_distances(blocked, resolution, climb, descent,
                                        int(np.ravel_multi_index(tuple(start), shape)))
    optimum = distance[np.ravel_multi_index(tuple(goal), shape)]
    workspace = SearchWorkspace(blocked)
    for algorithm in ALGORITHMS:
        kwargs = dict(climb_weight=climb, descent_weight=descent)
        if not np.isfinite(optimum):
            with pytest.raises(NoValidPathError):
                workspace.search(start, goal, algorithm, resolution, 1.0, **kwargs)
            continue
        result = workspace.search(start, goal, algorithm, resolution, 1.0, **kwargs)
        assert result.cost_m == pytest.approx(path_cost(result.path_indices, resolution, climb,
                                                        descent), rel=RTOL, abs=1e-12)
        if algorithm in ('dijkstra', 'octile', 'astar'):
            assert result.cost_m == pytest.approx(optimum, rel=RTOL, abs=1e-9), algorithm
        else:
            assert result.cost_m >= optimum * (1.0 - RTOL) - 1e-9
        if algorithm == 'weighted':
            assert result.cost_m <= DEFAULT_WEIGHT * optimum * (1.0 + RTOL) + 1e-9


def _h(code: str, di, dj, dk, climb, descent, resolution=1.0, weight=1.0):
    return search_module._heuristic(ALGORITHM_CODES[code], di, dj, dk, resolution, 0.0, weight,
                                    climb - 1.0, descent - 1.0, min(1.0, climb, descent))


@pytest.mark.parametrize('climb, descent', WEIGHT_PAIRS)
def test_the_adapted_octile_is_admissible_and_consistent(climb, descent):
    """h <= the exact obstacle-free cost everywhere, and h(x) <= c(d) + h(x - d) for every
    step d (consistency), on every displacement of a 9 x 8 x 11 block."""
    shape = (9, 8, 11)
    source = (4, 3, 5)      # the goal
    exact = weighted_graph_distances(np.zeros(shape, dtype=bool), 1.0, climb, descent,
                                     int(np.ravel_multi_index(source, shape)))
    # exact[n] is the cost from the goal to n; h needs node -> goal: reverse the weights.
    back = weighted_graph_distances(np.zeros(shape, dtype=bool), 1.0, descent, climb,
                                    int(np.ravel_multi_index(source, shape)))
    assert exact.shape == back.shape
    steps = [d for d in itertools.product((-1, 0, 1), repeat=3) if d != (0, 0, 0)]
    tight = 0
    for node in np.ndindex(*shape):
        di, dj = abs(source[0] - node[0]), abs(source[1] - node[1])
        dk = source[2] - node[2]
        for code in ('octile', 'astar'):
            h = _h(code, di, dj, dk, climb, descent)
            assert h <= back[np.ravel_multi_index(node, shape)] + 1e-12, (code, node)
        h = _h('octile', di, dj, dk, climb, descent)
        tight += h >= back[np.ravel_multi_index(node, shape)] - 1e-12
        for d in steps:
            after = [source[a] - (node[a] + d[a]) for a in range(3)]
            h_after = _h('octile', abs(after[0]), abs(after[1]), after[2], climb, descent)
            assert h <= step_cost(d, 1.0, climb, descent) + h_after + 1e-12, (node, d)
        assert h >= 0.0
    assert _h('octile', 0, 0, 0, climb, descent) == 0.0
    if climb + descent >= 2.0 + 2.0 * math.sqrt(2.0) - 2.0 * math.sqrt(3.0):
        # No sawtooth pays: the heuristic is the exact obstacle-free cost everywhere.
        assert tight == np.prod(shape)


def test_unit_weights_give_the_length_heuristics_bit_for_bit():
    for code in ALGORITHM_CODES.values():
        for di, dj, dk in itertools.product(range(0, 7, 2), range(0, 5), range(-4, 5)):
            plain = search_module._heuristic(code, di, dj, abs(dk), 0.3, 1.1, 1.07)
            weighted = search_module._heuristic(code, di, dj, dk, 0.3, 1.1, 1.07, 0.0, 0.0,
                                                1.0)
            assert plain == weighted


def test_a_climb_weight_trades_length_for_less_climbing():
    """With climbing three times as dear the optimum flies round a tall obstacle instead of
    over it: longer, cheaper in the weighted cost, and with less total climb."""
    config = PlannerConfig(bounds_min=(0.0, 0.0, 0.0), bounds_max=(20.0, 10.0, 10.0),
                           resolution=0.5, safety_margin=0.2, algorithm='octile',
                           max_planning_time=0.0)
    wall = ObstacleSet([Box([9.0, 0.0, 0.0], [11.0, 8.0, 5.0])])
    start, goal = [2.0, 4.0, 1.0], [18.0, 4.0, 1.0]
    level = Planner(config, wall).plan(start, goal)
    costly = Planner(replace(config, climb_weight=3.0), wall).plan(start, goal)
    assert level.ok and costly.ok
    assert level.cost == pytest.approx(level.path_length_m, rel=1e-12)

    def climb(path):
        return float(np.sum(np.maximum(np.diff(path[:, 2]), 0.0)))

    def weighted(path, climb_weight):
        steps = np.diff(path, axis=0)
        length = np.linalg.norm(steps, axis=1)
        return float(np.sum(length + (climb_weight - 1.0) * np.maximum(steps[:, 2], 0.0)))

    assert costly.cost == pytest.approx(weighted(costly.path, 3.0), rel=1e-9)
    assert costly.cost <= weighted(level.path, 3.0) + 1e-9
    assert costly.path_length_m >= level.path_length_m - 1e-9
    assert climb(costly.path) < climb(level.path)
    assert costly.legs[0].cost == pytest.approx(costly.cost)


@pytest.mark.parametrize('field', ['climb_weight', 'descent_weight'])
@pytest.mark.parametrize('value, message', [(-0.5, r'must be in \[0\.0, 100\.0\]'),
                                            (101.0, r'must be in'), ('1', 'must be a number'),
                                            (math.nan, 'must be finite')])
def test_config_refuses_bad_weights(field, value, message):
    with pytest.raises(InvalidInputError, match=f'^{field} ' + message):
        validate_config(replace(PlannerConfig(), **{field: value}))


def test_search_refuses_negative_weights():
    workspace = SearchWorkspace(np.zeros((3, 3, 3), dtype=bool))
    with pytest.raises(InvalidInputError,
                       match=r'climb_weight must be in \[0\.0, 100\.0\], got -1\.0'):
        workspace.search((0, 0, 0), (2, 2, 2), 'octile', 0.5, 1.0, climb_weight=-1.0)


# --- energy ---------------------------------------------------------------------------------

def _trajectory(times, positions) -> Trajectory:
    times = np.asarray(times, dtype=np.float64)
    positions = np.asarray(positions, dtype=np.float64)
    velocities = np.gradient(positions, times, axis=0)
    return Trajectory(times=times, positions=positions, velocities=velocities,
                      accelerations=np.gradient(velocities, times, axis=0))


def test_level_flight_costs_hover_power_times_flight_time():
    t = np.linspace(0.0, 40.0, 401)
    path = np.column_stack([2.0 * t, np.sin(t), np.full_like(t, 7.0)])
    estimate = estimate_energy(_trajectory(t, path), VehicleModel(2.0, 250.0))
    assert estimate.flight_time_s == 40.0
    assert estimate.energy_j == pytest.approx(250.0 * 40.0, rel=1e-15)
    assert estimate.climb_energy_j == 0.0 and estimate.climb_m == 0.0
    assert estimate.mean_power_w == pytest.approx(250.0)


def test_climbing_adds_m_g_h_of_every_rise_and_descending_recovers_nothing():
    t = np.linspace(0.0, 30.0, 3001)
    z = 5.0 + 3.0 * np.sin(2.0 * np.pi * t / 10.0)       # three full up-down cycles
    path = np.column_stack([t, np.zeros_like(t), z])
    vehicle = VehicleModel(1.5, 180.0)
    estimate = estimate_energy(_trajectory(t, path), vehicle)
    rises = 3 * 6.0                                       # each cycle climbs 2 x 3 m
    assert estimate.climb_m == pytest.approx(rises, rel=1e-6)
    assert estimate.climb_energy_j == pytest.approx(1.5 * GRAVITY * rises, rel=1e-6)
    assert estimate.energy_j == pytest.approx(180.0 * 30.0 + 1.5 * GRAVITY * rises, rel=1e-9)
    assert estimate.energy_wh == pytest.approx(estimate.energy_j / 3600.0)


def test_a_planned_trajectory_has_an_energy_estimate():
    scene = load_scene(find_scene('paper_medium'))
    result = Planner(replace(scene.config, algorithm='octile'), scene.obstacles).plan(
        scene.start, scene.goal)
    estimate = estimate_energy(result.trajectory, scene.vehicle)
    assert estimate.flight_time_s == pytest.approx(result.duration_s)
    assert estimate.climb_m >= scene.goal[2] - scene.start[2] - 1e-9
    assert estimate.energy_j == pytest.approx(
        scene.vehicle.hover_power * result.duration_s
        + scene.vehicle.mass * GRAVITY * estimate.climb_m)


@pytest.mark.parametrize('data, message', [
    ({'mass': -1.0}, r'^vehicle\.mass: must be in \(0\.0, 1000\.0\], got -1\.0'),
    ({'hover_power': math.inf}, r'^vehicle\.hover_power: must be finite, got inf'),
    ({'mass': True}, r'^vehicle\.mass: must be a number'),
    ({'weight': 2.0}, r'^vehicle: unknown key\(s\) weight'),
    ([1.5, 180.0], r'^vehicle: must be a mapping'),
])
def test_bad_vehicles_are_refused(data, message):
    with pytest.raises(InvalidInputError, match=message):
        parse_vehicle(data)


def test_energy_needs_a_trajectory_and_a_vehicle():
    with pytest.raises(InvalidInputError, match='Trajectory'):
        estimate_energy(np.zeros((3, 3)))
    assert parse_vehicle(None) == VehicleModel()
    t = _trajectory([0.0, 1.0], [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    with pytest.raises(InvalidInputError, match='VehicleModel'):
        estimate_energy(t, {'mass': 1.0})
