"""The ROS-free helpers of the Nav2 interfaces, without ``rclpy.init()``."""

from hypothesis import given, settings, strategies as st
import numpy as np
import pytest

from uav_global_planner.core.config import ALGORITHMS
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, Sphere
from uav_global_planner.core.status import PlanStatus
from uav_global_planner.ros.nav2_interfaces import (InvalidPlannerIdError, nearest_free_node,
                                                    resolve_planner_id, result_code)


def test_empty_planner_id_is_the_algorithm_parameter():
    assert resolve_planner_id('', 'octile') == 'octile'


@pytest.mark.parametrize('name', ALGORITHMS)
def test_algorithm_names_are_planner_ids(name):
    assert resolve_planner_id(name, 'adaptive') == name


@pytest.mark.parametrize('planner_id', ['GridBased', 'ASTAR', ' astar', 'a*'])
def test_other_planner_ids_are_refused_naming_the_valid_ones(planner_id):
    with pytest.raises(InvalidPlannerIdError) as raised:
        resolve_planner_id(planner_id, 'adaptive')
    text = str(raised.value)
    assert repr(planner_id) in text
    assert all(name in text for name in ALGORITHMS)


@pytest.mark.parametrize('status, to_pose, through', [
    (PlanStatus.OK, 0, 0),
    (PlanStatus.START_OUTSIDE_MAP, 203, 303),
    (PlanStatus.GOAL_OUTSIDE_MAP, 204, 304),
    (PlanStatus.START_OCCUPIED, 205, 305),
    (PlanStatus.GOAL_OCCUPIED, 206, 306),
    (PlanStatus.TIMEOUT, 207, 307),
    (PlanStatus.NO_VALID_PATH, 208, 308),
    (PlanStatus.INVALID_INPUT, 200, 300),
])
def test_result_codes_are_nav2s(status, to_pose, through):
    assert result_code(status, False) == to_pose
    assert result_code(status, True) == through


def brute_force_nearest(grid, obstacles, gamma, goal, tolerance):
    nodes = np.stack(np.meshgrid(*[np.arange(n) for n in grid.shape], indexing='ij'),
                     -1).reshape(-1, 3)
    points = grid.index_to_world(nodes)
    distances = np.linalg.norm(points - goal, axis=1)
    free = (distances <= tolerance) & (obstacles.distance(points) > gamma + 1e-4 * grid.resolution)
    if not np.any(free):
        return None
    return float(np.min(distances[free]))


@settings(max_examples=60, deadline=None)
@given(center=st.tuples(*[st.floats(1.0, 5.0)] * 3), radius=st.floats(0.3, 2.0),
       offset=st.tuples(*[st.floats(-1.0, 1.0)] * 3), tolerance=st.floats(0.0, 3.0),
       resolution=st.sampled_from([0.25, 0.4, 0.5]))
def test_nearest_free_node_is_the_nearest(center, radius, offset, tolerance, resolution):
    grid = VoxelGrid.from_bounds((0.0, 0.0, 0.0), (6.0, 6.0, 6.0), resolution)
    obstacles = ObstacleSet([Sphere(np.array(center), radius),
                             Box(np.array([0.0, 0.0, 0.0]), np.array([1.0, 6.0, 1.0]))])
    goal = np.clip(np.add(center, np.multiply(offset, radius)), 0.0, 6.0)
    gamma = 0.2
    found = nearest_free_node(grid, obstacles, gamma, goal, tolerance)
    expected = brute_force_nearest(grid, obstacles, gamma, goal, tolerance)
    if expected is None:
        assert found is None
        return
    assert found is not None
    assert np.linalg.norm(found - goal) == pytest.approx(expected, abs=1e-12)
    assert float(obstacles.distance(found)) > gamma
    # It is a grid node.
    assert np.allclose(grid.index_to_world(grid.world_to_index(found)), found)


def test_free_goal_is_its_own_nearest_node_when_on_the_grid():
    grid = VoxelGrid.from_bounds((0.0, 0.0, 0.0), (4.0, 4.0, 4.0), 0.5)
    goal = np.array([2.0, 2.0, 2.0])
    assert np.array_equal(nearest_free_node(grid, ObstacleSet(), 0.2, goal, 1.0), goal)
