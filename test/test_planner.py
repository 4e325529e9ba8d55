"""The planner facade: the paper's figures, every failure kind, and state kept across requests."""

from dataclasses import replace
import re

import numpy as np
import pytest

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, Sphere
from uav_global_planner.core.planner import densify, Planner
from uav_global_planner.core.status import PlanStatus

SMALL = PlannerConfig(bounds_min=(0.0, 0.0, 0.0), bounds_max=(6.0, 6.0, 4.0), resolution=0.25,
                      safety_margin=0.2)
SPHERE = Sphere([3.0, 3.0, 2.0], 1.0)


@pytest.fixture(scope='module')
def paper_medium_results():
    scene = load_scene(find_scene('paper_medium'))
    planner = Planner(scene.config, scene.obstacles)
    return {name: planner.plan(scene.start, scene.goal, name)
            for name in ('dijkstra', 'astar', 'adaptive', 'octile')}


@pytest.mark.parametrize('algorithm', ['dijkstra', 'astar', 'octile'])
def test_paper_medium_optimal_length(paper_medium_results, algorithm):
    result = paper_medium_results[algorithm]
    assert result.ok, result.message
    assert result.path_length_m == pytest.approx(19.367, abs=5e-4)


def test_paper_medium_adaptive_is_near_optimal_with_far_fewer_expansions(paper_medium_results):
    adaptive = paper_medium_results['adaptive']
    astar = paper_medium_results['astar']
    assert adaptive.ok
    assert adaptive.path_length_m <= 1.05 * astar.path_length_m
    assert adaptive.expanded_nodes * 5 < astar.expanded_nodes


def test_paper_medium_octile_expands_several_times_fewer_than_astar(paper_medium_results):
    octile = paper_medium_results['octile']
    astar = paper_medium_results['astar']
    dijkstra = paper_medium_results['dijkstra']
    assert octile.expanded_nodes * 3 < astar.expanded_nodes < dijkstra.expanded_nodes


def test_result_carries_settings_and_a_safe_smoothed_curve(paper_medium_results):
    result = paper_medium_results['adaptive']
    settings = (result.resolution, result.safety_margin, result.adaptive_threshold)
    assert settings == (0.5, 0.2, 1.5)
    assert np.array_equal(result.path[0], [0.0, -5.0, 0.0])
    assert np.array_equal(result.path[-1], [10.0, 5.0, 10.0])
    assert np.allclose(result.smoothed_path[0], result.start)
    assert np.allclose(result.smoothed_path[-1], result.goal)
    scene = load_scene(find_scene('paper_medium'))
    dense = densify(result.smoothed_path, 0.5 / 20)
    assert np.min(scene.obstacles.distance(dense)) >= 0.2
    assert result.min_clearance_m >= 0.2
    assert result.smoothed_length_m < result.path_length_m
    assert result.duration_s > 0


def _plan(start, goal, obstacles=(SPHERE,), **changes):
    planner = Planner(replace(SMALL, **changes), ObstacleSet(obstacles))
    return planner.plan(start, goal)


def _shell(center, half, wall=0.1):
    """Six boxes forming a closed hollow cube around ``center``."""
    c = np.asarray(center, dtype=float)
    boxes = []
    for axis in range(3):
        for side in (-1, 1):
            lo = c - half - wall
            hi = c + half + wall
            lo[axis] = c[axis] + side * half - wall
            hi[axis] = c[axis] + side * half + wall
            boxes.append(Box(lo, hi))
    return boxes


@pytest.mark.parametrize('start, goal, obstacles, changes, status, words', [
    ([0.5, 0.5, -1.0], [5.5, 5.5, 3.5], (SPHERE,), {}, PlanStatus.START_OUTSIDE_MAP,
     'start .* is outside the bounds'),
    ([0.5, 0.5, 0.5], [5.5, 7.0, 3.5], (SPHERE,), {}, PlanStatus.GOAL_OUTSIDE_MAP,
     'goal .* is outside the bounds'),
    ([3.0, 3.0, 2.0], [5.5, 5.5, 3.5], (SPHERE,), {}, PlanStatus.START_OCCUPIED,
     'start .* is within the safety margin'),
    ([0.5, 0.5, 0.5], [3.0, 3.0, 3.1], (SPHERE,), {}, PlanStatus.GOAL_OCCUPIED,
     'goal .* is within the safety margin: its clearance is 0.000 m'),
    ([0.5, 0.5, 0.5], [3.0, 3.0, 3.15], (SPHERE,), {}, PlanStatus.GOAL_OCCUPIED,
     'gamma is 0.2 m'),
    ([0.5, 0.5, 0.5], [5.0, 5.0, 2.0], _shell([5.0, 5.0, 2.0], 0.75), {},
     PlanStatus.NO_VALID_PATH, 'expanded'),
    ([0.5, 0.5, 0.5], [5.5, 5.5, 3.5], (SPHERE,), {'max_expansions': 5}, PlanStatus.TIMEOUT,
     'max_expansions'),
    ([0.5, 0.5, np.nan], [5.5, 5.5, 3.5], (SPHERE,), {}, PlanStatus.INVALID_INPUT,
     'start must be finite'),
    ([0.5, 0.5, 0.5], [5.5, np.inf, 3.5], (SPHERE,), {}, PlanStatus.INVALID_INPUT,
     'goal must be finite'),
    ([0.5, 0.5], [5.5, 5.5, 3.5], (SPHERE,), {}, PlanStatus.INVALID_INPUT,
     'start must be three numbers'),
])
def test_each_failure_kind_has_its_status_and_message(start, goal, obstacles, changes, status,
                                                      words):
    result = _plan(start, goal, obstacles, **changes)
    assert result.status is status
    assert not result.ok
    assert len(result.path) == 0 and result.trajectory is None
    assert re.search(words, result.message), result.message


def test_unknown_algorithm_is_invalid_input():
    planner = Planner(SMALL, ObstacleSet([SPHERE]))
    result = planner.plan([0.5, 0.5, 0.5], [5.5, 5.5, 3.5], 'bfs')
    assert result.status is PlanStatus.INVALID_INPUT
    assert "got 'bfs'" in result.message


def test_failures_keep_the_planner_usable():
    planner = Planner(SMALL, ObstacleSet([SPHERE]))
    for start, goal in (([np.nan, 0, 0], [1, 1, 1]), ([3, 3, 2], [5, 5, 3]),
                        ([0.5, 0.5, 0.5], [50, 5, 3])):
        assert not planner.plan(start, goal).ok
    assert planner.plan([0.5, 0.5, 0.5], [5.5, 5.5, 3.5]).ok


def test_start_equal_to_goal_gives_a_single_point_plan():
    result = _plan([0.5, 0.5, 0.5], [0.5, 0.5, 0.5])
    assert result.ok, result.message
    assert result.path_length_m == 0.0
    assert np.allclose(result.smoothed_path[0], result.smoothed_path[-1])


def test_off_node_endpoints_are_kept_exactly():
    start, goal = np.array([0.43, 0.61, 0.37]), np.array([5.38, 5.52, 3.21])
    result = _plan(start, goal)
    assert result.ok, result.message
    assert np.allclose(result.smoothed_path[0], start, atol=1e-9)
    assert np.allclose(result.smoothed_path[-1], goal, atol=1e-9)


def test_larger_gamma_gives_larger_clearance():
    obstacles = ObstacleSet([Sphere([3.0, 3.0, 2.0], 1.2), Box([1.0, 4.0, 0.0], [2.0, 5.0, 4.0])])
    planner = Planner(SMALL, obstacles)
    start, goal = [0.5, 0.5, 2.0], [5.5, 5.5, 2.0]
    low = planner.plan(start, goal)
    planner.set_config(replace(SMALL, safety_margin=0.6))
    high = planner.plan(start, goal)
    assert low.ok and high.ok
    assert high.min_clearance_m >= 0.6 > low.min_clearance_m >= 0.2


def test_obstacle_change_is_seen_by_path_is_clear():
    planner = Planner(SMALL, ObstacleSet([SPHERE]))
    result = planner.plan([0.5, 0.5, 2.0], [5.5, 5.5, 2.0])
    assert planner.path_is_clear(result.smoothed_path)
    # A small obstacle exactly halfway along the longest edge of the shortcut polyline: every
    # vertex keeps far more than gamma from it, so a check of the vertices sees nothing, but
    # the edge runs through it.
    polyline = result.shortcut_path
    assert planner.path_is_clear(polyline)
    longest = int(np.argmax(np.linalg.norm(np.diff(polyline, axis=0), axis=1)))
    between = Sphere(polyline[longest:longest + 2].mean(axis=0), 0.1)
    assert ObstacleSet([between]).distance(polyline).min() >= 3 * SMALL.safety_margin
    changed = ObstacleSet([SPHERE, between])
    assert changed.distance(polyline).min() >= SMALL.safety_margin
    planner.set_obstacles(changed)
    assert not planner.path_is_clear(polyline)
    assert not planner.path_is_clear(result.smoothed_path)
    replanned = planner.plan([0.5, 0.5, 2.0], [5.5, 5.5, 2.0])
    assert replanned.ok and planner.path_is_clear(replanned.smoothed_path)


def test_invalid_config_keeps_the_previous_one():
    planner = Planner(SMALL, ObstacleSet([SPHERE]))
    with pytest.raises(ValueError, match='resolution'):
        planner.set_config(replace(SMALL, resolution=-1.0))
    assert planner.config.resolution == 0.25
    assert planner.plan([0.5, 0.5, 0.5], [5.5, 5.5, 3.5]).ok
