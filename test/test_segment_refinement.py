"""The compiled refinement of straight segments gives the certificate's verdicts and bounds.

``segments_clear`` refines the segments of a set of shapes in one compiled call
(:mod:`uav_global_planner.core.path.segment_refinement`) and those of any other set in rounds of
array operations (``certify_samples``). Both must agree to the bit, on clear, violating and
grazing segments, and both must find a wall thinner than the sample spacing.
"""

import numpy as np
import pytest

from uav_global_planner.core.jit import JIT_ENABLED
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, PointSet, Sphere
from uav_global_planner.core.path import clearance
from uav_global_planner.core.path.clearance import segments_clear
from uav_global_planner.core.path.segment_refinement import shape_tables

GAMMA = 0.2


def _scene(count: int) -> ObstacleSet:
    """``count`` spheres and boxes in a 20 x 20 x 15 m box; the lattice serves more than 16."""
    rng = np.random.default_rng(11)
    shapes: list = []
    for number in range(count):
        centre = rng.uniform([-10.0, -10.0, 0.0], [10.0, 10.0, 15.0])
        if number % 2:
            half = rng.uniform(0.3, 2.0, 3)
            shapes.append(Box(centre - half, centre + half))
        else:
            shapes.append(Sphere(centre, float(rng.uniform(0.5, 2.5))))
    return ObstacleSet(shapes)


def _segments(rng: np.random.Generator, obstacles: ObstacleSet, count: int):
    """Random segments, and segments that graze the first sphere at gamma plus a hair."""
    starts = rng.uniform([-10.0, -10.0, 0.0], [10.0, 10.0, 15.0], (count, 3))
    ends = starts + rng.normal(size=(count, 3)) * rng.choice([0.05, 0.5, 4.0], (count, 1))
    centre, radius = obstacles.sphere_centers[0], obstacles.sphere_radii[0]
    offsets = GAMMA + np.array([-1e-4, 0.0, 1e-6, 1e-4, 1e-3, 1e-2])
    graze_a = centre + np.array([-3.0, 0.0, 0.0]) + (radius + offsets)[:, None] * [0, 1.0, 0]
    graze_b = graze_a + [6.0, 0.0, 0.0]
    return np.vstack([starts, graze_a]), np.vstack([ends, graze_b])


def _in_rounds(monkeypatch, *args, **kwargs):
    """``segments_clear`` by rounds of array operations (the path of sets with points)."""
    with monkeypatch.context() as patch:
        patch.setattr(clearance, 'JIT_ENABLED', False)
        return segments_clear(*args, **kwargs)


@pytest.mark.skipif(not JIT_ENABLED, reason='the compiled refinement needs numba')
@pytest.mark.parametrize('shapes', [6, 80])
@pytest.mark.parametrize('max_pieces', [1024, 32])
def test_compiled_refinement_matches_the_rounds_to_the_bit(monkeypatch, shapes, max_pieces):
    obstacles = _scene(shapes)
    assert shape_tables(obstacles, 1.0) is not None
    rng = np.random.default_rng(shapes + max_pieces)
    starts, ends = _segments(rng, obstacles, 300)
    for gamma in (0.0, GAMMA):
        args = (starts, ends, obstacles, gamma, 0.25, 1e-6)
        clear, bound = segments_clear(*args, max_pieces=max_pieces)
        clear_rounds, bound_rounds = _in_rounds(monkeypatch, *args, max_pieces=max_pieces)
        assert np.array_equal(clear, clear_rounds)
        assert np.array_equal(bound[clear], bound_rounds[clear])
        # Both verdicts are certificates: every clear segment keeps gamma at dense samples.
        t = np.linspace(0.0, 1.0, 2001)[:, None]
        for a, b in zip(starts[clear], ends[clear]):
            assert obstacles.distance(a + t * (b - a)).min() >= gamma
        assert clear.any() and not clear.all()


def test_a_wall_thinner_than_the_samples_is_found():
    """A 2 mm slab between two first samples (0.25 m apart) blocks the segment."""
    wall = ObstacleSet([Box(np.array([0.124, -1.0, -1.0]), np.array([0.126, 1.0, 1.0])),
                        Sphere(np.array([5.0, 5.0, 5.0]), 1.0)])
    clear, _ = segments_clear(np.array([[0.0, 0.0, 0.0]]), np.array([[1.0, 0.0, 0.0]]), wall,
                              0.0, 0.25, 1e-6)
    assert not clear[0]
    beside, bound = segments_clear(np.array([[0.0, 0.5, 1.3]]), np.array([[1.0, 0.5, 1.3]]),
                                   wall, 0.2, 0.25, 1e-6)
    assert beside[0] and 0.2 <= bound[0] <= 0.3 + 1e-12


def test_sets_with_points_take_the_rounds():
    cloud = ObstacleSet([Sphere(np.zeros(3), 1.0), PointSet(np.array([[3.0, 0.0, 0.0]]))])
    assert shape_tables(cloud, 1.0) is None
    clear, _ = segments_clear(np.array([[-2.0, 2.0, 0.0], [2.0, -2.0, 0.0]]),
                              np.array([[2.0, 2.0, 0.0], [4.0, 2.0, 0.0]]), cloud, 0.2, 0.25,
                              1e-6)
    assert clear.tolist() == [True, False]
