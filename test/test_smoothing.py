"""Shortcutting, spline smoothing and the clearance guarantee of core.smoothing.

Raw node paths come from a test-only shortest path (scipy.sparse.csgraph over the 26-connected
free nodes), independent of the project's search. Every clearance claim is re-checked here from
the returned curve, sampled by arc length at delta / 20.
"""

import math
from pathlib import Path

from helpers.scenes import csgraph_path, random_scene, SEEDS
import numpy as np
import pytest
from scipy.interpolate import CubicSpline, PPoly
import yaml

from uav_global_planner.core.errors import InvalidInputError, NoValidPathError
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, PointSet, Sphere
from uav_global_planner.core.path.repair import start_spline
from uav_global_planner.core.path.shortcut import shortcut_path
from uav_global_planner.core.path.smoothing import smooth_path, SmoothedPath
from uav_global_planner.core.result import polyline_length

SCENES = Path(__file__).resolve().parents[1] / 'config' / 'scenes'
LIPSCHITZ = math.sqrt(3.0) / 2.0


# ----------------------------------------------------------------------------------------------
# Scene files
# ----------------------------------------------------------------------------------------------

def load_scene(name: str):
    """(grid, obstacles, gamma, start, goal) of a shipped scene file."""
    data = yaml.safe_load((SCENES / f'{name}.yaml').read_text())
    obstacles = ObstacleSet([Sphere(o['center'], o['radius']) for o in data['obstacles']])
    grid = VoxelGrid.from_bounds(data['bounds']['min'], data['bounds']['max'],
                                 data['resolution'])
    return grid, obstacles, float(data['safety_margin']), np.array(data['start'], float), \
        np.array(data['goal'], float)


def dense_clearance(smoothed: SmoothedPath, obstacles: ObstacleSet, delta: float):
    """Clearance of the curve sampled every <= delta / 20 of arc length, and the samples."""
    count = max(int(math.ceil(smoothed.length_m / (delta / 20.0))), 1)
    s = np.linspace(0.0, smoothed.length_m, count + 1)
    points = smoothed.curve.evaluate(s)
    return obstacles.distance(points), points


def check_smoothed(smoothed: SmoothedPath, raw: np.ndarray, obstacles: ObstacleSet,
                   gamma: float, delta: float) -> None:
    """Every property a returned curve must have."""
    positions = smoothed.positions
    assert np.array_equal(positions[0], raw[0]) and np.array_equal(positions[-1], raw[-1])
    assert np.all(np.diff(smoothed.arc_length) > 0)
    assert smoothed.arc_length[0] == 0.0
    assert smoothed.arc_length[-1] == pytest.approx(smoothed.length_m, abs=1e-9)
    # The whole continuous curve, independently sampled at delta / 20, and the output samples.
    clearance, points = dense_clearance(smoothed, obstacles, delta)
    assert clearance.min() >= gamma, (clearance.min(), gamma)
    assert obstacles.distance(positions).min() >= gamma
    assert smoothed.certified_clearance_m >= gamma
    assert smoothed.min_clearance_m >= gamma
    # Both are samplings no coarser than delta / 20 of a 1-Lipschitz function.
    assert abs(smoothed.min_clearance_m - clearance.min()) <= delta / 40.0 + 1e-9
    assert smoothed.certified_clearance_m <= smoothed.min_clearance_m + 1e-12
    # Consecutive samples of the curve are no farther apart than their arc length.
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    assert steps.max() <= delta / 20.0 + 1e-9
    # The evaluator and the samples agree.
    assert np.allclose(smoothed.curve.evaluate(smoothed.arc_length), positions, atol=1e-7)
    check_continuity(smoothed)


def check_continuity(smoothed: SmoothedPath) -> None:
    """Tangent and curvature vector continuous across every knot that is not a stop point."""
    curve = smoothed.curve
    stops = curve.stop_arc_length_m
    knots = curve.piece_start_m[1:-1]
    if len(stops):
        knots = knots[np.min(np.abs(knots[:, None] - stops[None, :]), axis=1) > 1e-9]
    if not len(knots):
        return
    # The jump J of a quantity f at a knot, with the smooth variation cancelled (Richardson):
    # f(s + e) - f(s - e) = J + 2 e f' + ..., f(s + 2e) - f(s - 2e) = J + 4 e f' + ...; e is
    # tiny because index splines may bend with millimetre radii next to a knot.
    eps = 1e-8
    (t1l, k1l), (t1r, k1r), (t2l, k2l), (t2r, k2r) = (
        curve.derivatives(knots + offset) for offset in (-eps, eps, -2 * eps, 2 * eps))
    jump_t = 2 * (t1r - t1l) - (t2r - t2l)
    jump_k = 2 * (k1r - k1l) - (k2r - k2l)
    assert np.max(np.linalg.norm(jump_t, axis=1)) < 1e-6
    scale = 1.0 + np.linalg.norm(k1l, axis=1)
    assert np.max(np.linalg.norm(jump_k, axis=1) / scale) < 1e-4
    # Finite differences of positions confirm the analytic derivatives between knots (a small
    # step: index splines through unevenly spaced knots can bend with radii of millimetres).
    s = 0.5 * (curve.piece_start_m[:-1] + curve.piece_start_m[1:])
    h = 1e-4
    points = curve.evaluate(np.concatenate([s - h, s, s + h]))
    before, mid, after = np.split(points, 3)
    tangent, curvature = curve.derivatives(s)
    assert np.allclose((after - before) / (2 * h), tangent, atol=1e-4)
    assert np.allclose((after - 2 * mid + before) / h ** 2, curvature,
                       atol=1e-2 * (1.0 + np.abs(curvature).max()))


def smooth_or_fallback(grid, obstacles, gamma, path, **options):
    """Emulate the planner facade: on NoValidPathError re-plan on the gamma + delta*sqrt(3)/2
    grid, whose polyline provably keeps gamma, and smooth that path (which must succeed)."""
    delta = grid.resolution
    try:
        return smooth_path(path, obstacles, gamma, delta, **options), path, None
    except NoValidPathError as error:
        assert 'safety margin' in str(error)
        conservative = blocked_mask(grid, obstacles, gamma + LIPSCHITZ * delta)
        fallback = csgraph_path(grid, conservative, path[0], path[-1])
        if fallback is None:
            return None, None, error
        return smooth_path(fallback, obstacles, gamma, delta, **options), fallback, error


# ----------------------------------------------------------------------------------------------
# Property tests on random scenes
# ----------------------------------------------------------------------------------------------

@pytest.fixture(scope='module')
def scenes():
    out = []
    for seed in SEEDS:
        scene = random_scene(seed)
        if scene is not None:
            out.append((seed,) + scene)
    return out


def test_enough_random_scenes(scenes):
    assert len(scenes) >= 200
    gammas = np.array([scene[3] for scene in scenes])
    assert gammas.max() == pytest.approx(0.6)
    assert sum(1 for seed, *_ in scenes if seed % 3 == 0) >= 40  # narrow passages


def test_random_scenes_keep_margin(scenes):
    outcomes = {'ok': 0, 'fallback': 0, 'failed': 0}
    modes = ('chord', 'index', 'none')
    for seed, grid, obstacles, gamma, path in scenes:
        delta = grid.resolution
        mode = modes[seed % 3] if seed % 2 else 'chord'
        shortcut = seed % 7 != 0
        smoothed, used, error = smooth_or_fallback(grid, obstacles, gamma, path, mode=mode,
                                                   shortcut=shortcut)
        if smoothed is None:
            outcomes['failed'] += 1
            continue
        outcomes['fallback' if error is not None else 'ok'] += 1
        check_smoothed(smoothed, used, obstacles, gamma, delta)
        if shortcut:
            assert smoothed.shortcut_length_m <= polyline_length(used) + 1e-9
    # Shortcut detours make a conservative re-plan rarely necessary; a few scenes have thin walls
    # between nodes that only the conservative grid sees.
    assert outcomes['ok'] >= 0.9 * len(scenes), outcomes


def test_conservative_grid_always_smooths(scenes):
    """On the gamma + delta*sqrt(3)/2 grid every mode succeeds, with and without shortcuts."""
    checked = 0
    for seed, grid, obstacles, gamma, path in scenes[::4]:
        delta = grid.resolution
        blocked = blocked_mask(grid, obstacles, gamma + LIPSCHITZ * delta)
        safe = csgraph_path(grid, blocked, path[0], path[-1])
        if safe is None:
            continue
        for mode in ('chord', 'index', 'none'):
            smoothed = smooth_path(safe, obstacles, gamma, delta, mode=mode,
                                   shortcut=bool(seed % 2))
            check_smoothed(smoothed, safe, obstacles, gamma, delta)
        checked += 1
    assert checked >= 30


def test_raw_polyline_bound_holds(scenes):
    """Between free nodes the raw polyline keeps clearance > gamma - delta*sqrt(3)/2."""
    below = 0
    for seed, grid, obstacles, gamma, path in scenes:
        delta = grid.resolution
        fractions = np.linspace(0.0, 1.0, 41)
        points = (path[:-1, None, :] + fractions[None, :, None]
                  * np.diff(path, axis=0)[:, None, :]).reshape(-1, 3)
        clearance = obstacles.distance(points)
        assert clearance.min() > gamma - LIPSCHITZ * delta
        below += int(clearance.min() < gamma)
    # The bound is not vacuous: plenty of random raw paths do dip below gamma.
    assert below >= 10


def test_raw_polyline_can_break_margin():
    """Two free neighbouring nodes whose diagonal edge passes within gamma of a point."""
    delta, gamma = 0.5, 0.4
    grid = VoxelGrid.from_bounds([0, 0, 0], [1, 1, 1], delta)
    obstacles = ObstacleSet([PointSet([[0.25, 0.25, 0.25]])])
    blocked = blocked_mask(grid, obstacles, gamma)
    a, b = np.zeros(3), np.full(3, delta)
    assert not blocked[0, 0, 0] and not blocked[1, 1, 1]
    mid = obstacles.distance(0.5 * (a + b))
    assert mid < gamma and mid > gamma - LIPSCHITZ * delta
    # Smoothing that edge alone is impossible: reported, not returned.
    with pytest.raises(NoValidPathError, match='safety margin'):
        smooth_path(np.array([a, b]), obstacles, gamma, delta, shortcut=False)


# ----------------------------------------------------------------------------------------------
# Constructed cases
# ----------------------------------------------------------------------------------------------

def _around_sphere(mode: str):
    """A path of nodes bending tightly around a sphere: sparse knots cut the corner.

    The radius is picked per mode so that the naive spline of that mode breaks the margin.
    """
    delta, gamma = 0.5, 0.3
    sphere = Sphere([2.0, 2.0, 1.0], 1.17 if mode == 'chord' else 1.3)
    obstacles = ObstacleSet([sphere])
    grid = VoxelGrid.from_bounds([0, 0, 0], [4, 4, 2], delta)
    blocked = blocked_mask(grid, obstacles, gamma)
    path = csgraph_path(grid, blocked, [0.0, 2.0, 1.0], [4.0, 2.0, 1.0])
    return path, obstacles, gamma, delta


@pytest.mark.parametrize('mode', ['chord', 'index'])
def test_naive_spline_breaks_margin_and_is_repaired(mode):
    path, obstacles, gamma, delta = _around_sphere(mode)
    smoothed = smooth_path(path, obstacles, gamma, delta, mode=mode, knot_spacing=10.0)
    # The unrepaired spline through the shortcut waypoints (what the paper would fly).
    waypoints = smoothed.shortcut_path
    if mode == 'index':
        t = np.arange(len(waypoints), dtype=float)
    else:
        t = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(waypoints, axis=0), axis=1))]
    naive = CubicSpline(t, waypoints)(np.linspace(0.0, t[-1], 4001))
    assert obstacles.distance(naive).min() < gamma
    assert smoothed.repaired_stretches
    for stretch in smoothed.repaired_stretches:
        assert 0.0 <= stretch.start_m < stretch.end_m <= smoothed.length_m + 1e-9
        assert stretch.method in ('knots', 'polyline')
        assert stretch.clearance_before_m < gamma + 1e-3
    check_smoothed(smoothed, path, obstacles, gamma, delta)


def test_box_corner_repair():
    """A path hugging the vertical edge of a box: the spline bulges into the margin."""
    delta, gamma = 0.5, 0.25
    obstacles = ObstacleSet([Box([1.0, 1.0, -1.0], [3.0, 3.0, 3.0])])
    path = np.array([[0.5, 0.0, 1.0], [0.5, 0.5, 1.0], [0.5, 3.5, 1.0], [3.5, 3.5, 1.0],
                     [3.5, 4.0, 1.0]])
    smoothed = smooth_path(path, obstacles, gamma, delta, shortcut=False, knot_spacing=10.0)
    naive = smooth_path(path, ObstacleSet(), gamma, delta, shortcut=False, knot_spacing=10.0)
    assert obstacles.distance(naive.curve.evaluate(
        np.linspace(0, naive.length_m, 2000))).min() < gamma
    assert smoothed.repaired_stretches
    check_smoothed(smoothed, path, obstacles, gamma, delta)


def test_polyline_fallback_stops_at_corners():
    """When only the polyline is safe, its corners become stop points."""
    delta, gamma = 0.5, 0.45
    obstacles = ObstacleSet([Box([1.0, 1.0, -1.0], [3.0, 3.0, 3.0])])
    # Waypoints exactly gamma + a hair from the box faces: no spline can bend at the corner.
    g = gamma + 1e-4
    path = np.array([[1.0 - g, 0.0, 1.0], [1.0 - g, 3.0 + g, 1.0], [3.5, 3.0 + g, 1.0]])
    smoothed = smooth_path(path, obstacles, gamma, delta, shortcut=False)
    assert any(s.method == 'polyline' for s in smoothed.repaired_stretches)
    corner = int(np.argmin(np.linalg.norm(smoothed.positions - path[1], axis=1)))
    assert np.array_equal(smoothed.positions[corner], path[1])
    assert corner in smoothed.stop_points
    assert not np.allclose(smoothed.tangents[corner], smoothed.incoming_tangents[corner])
    check_smoothed(smoothed, path, obstacles, gamma, delta)


def test_start_off_grid_and_tangent_segment():
    """A start off the nodes (as the facade adds it) and a path grazing gamma exactly."""
    delta, gamma = 0.5, 0.3
    obstacles = ObstacleSet([Sphere([2.0, 1.0, 1.0], 0.5)])
    # The segment from (0, 0.2, 1) to (4, 0.2, 1) stays exactly 0.8 - 0.5 = 0.3 from the sphere.
    path = np.array([[0.0, 0.2, 1.0], [4.0, 0.2, 1.0]])
    with pytest.raises(NoValidPathError):
        # Exactly tangent at gamma is not certifiable: reported, never returned.
        smooth_path(path, obstacles, gamma, delta, mode='none')
    path = np.array([[0.0, 0.19, 1.0], [4.0, 0.19, 1.0]])
    smoothed = smooth_path(path, obstacles, gamma, delta)
    assert smoothed.length_m == pytest.approx(4.0)
    check_smoothed(smoothed, path, obstacles, gamma, delta)


def test_detour_around_dipping_raw_edge():
    """A raw edge dipping below gamma is replaced by a certified detour vertex."""
    delta, gamma = 0.5, 0.4
    obstacles = ObstacleSet([PointSet([[0.3, 0.2, 0.25]])])
    path = np.array([[-1.0, 0.0, 0.0], [-0.5, 0.0, 0.0], [0.0, 0.0, 0.0], [0.5, 0.5, 0.5],
                     [1.0, 1.0, 1.0], [1.5, 1.0, 1.0]])
    assert obstacles.distance(path).min() > gamma
    assert obstacles.distance(0.5 * (path[2] + path[3])) < gamma
    smoothed = smooth_path(path, obstacles, gamma, delta)
    assert len(smoothed.shortcut_path) >= 3
    check_smoothed(smoothed, path, obstacles, gamma, delta)


def test_bounds_are_kept():
    """A path along the floor turning upwards: the spline would dip below z = 0."""
    delta, gamma = 0.5, 0.2
    obstacles = ObstacleSet([Sphere([3.0, 0.0, 3.0], 1.0)])
    path = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [3.0, 0.0, 0.0],
                     [4.0, 0.0, 1.0], [5.0, 0.0, 2.0], [6.0, 0.0, 3.0]])
    free = smooth_path(path, obstacles, gamma, delta, shortcut=False, knot_spacing=10.0)
    s = np.linspace(0, free.length_m, 4000)
    assert free.curve.evaluate(s)[:, 2].min() < -1e-3
    bounded = smooth_path(path, obstacles, gamma, delta, shortcut=False, knot_spacing=10.0,
                          bounds=([-1, -1, 0], [7, 1, 5]))
    assert bounded.curve.evaluate(np.linspace(0, bounded.length_m, 4000))[:, 2].min() >= -1e-9
    assert bounded.repaired_stretches
    check_smoothed(bounded, path, obstacles, gamma, delta)


def test_gamma_zero_still_avoids_obstacles():
    delta = 0.5
    obstacles = ObstacleSet([Sphere([2.0, 0.0, 0.0], 1.0)])
    path = np.array([[0.0, 1.5, 0.0], [4.0, 1.5, 0.0]])
    smoothed = smooth_path(path, obstacles, 0.0, delta)
    check_smoothed(smoothed, path, obstacles, 0.0, delta)
    through = np.array([[0.0, 0.0, 0.0 + 1.5], [2.0, 0.0, 1.5 - 1.0], [4.0, 0.0, 1.5]])
    with pytest.raises(NoValidPathError):
        smooth_path(through, obstacles, 0.0, delta, mode='none', shortcut=False)


# ----------------------------------------------------------------------------------------------
# Parameterisations, shortcutting, shipped scenes
# ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize('mode', ['chord', 'index'])
def test_both_parameterisations_are_c2_through_endpoints(mode):
    path, obstacles, gamma, delta = _around_sphere(mode)
    smoothed = smooth_path(path, obstacles, gamma, delta, mode=mode)
    check_smoothed(smoothed, path, obstacles, gamma, delta)
    # Interior stops only where the polyline fallback was used.
    interior = smoothed.stop_points[1:-1]
    if not any(s.method == 'polyline' for s in smoothed.repaired_stretches):
        assert len(interior) == 0
    assert smoothed.stop_points[0] == 0 and smoothed.stop_points[-1] == len(smoothed.positions) - 1


def test_index_sampling_follows_parameter_and_chord_follows_arc_length():
    path = np.array([[0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [5.0, 1.0, 0.0], [5.5, 1.5, 0.0]])
    empty = ObstacleSet()
    index = smooth_path(path, empty, 0.1, 0.5, mode='index', shortcut=False, index_step=0.1)
    assert len(index.positions) == 3 * 10 + 1
    steps = np.diff(index.arc_length)
    assert steps.max() / steps.min() > 5.0  # uneven speed where the node spacing changes
    chord = smooth_path(path, empty, 0.1, 0.5, mode='chord', shortcut=False,
                        sample_spacing=0.1)
    steps = np.diff(chord.arc_length)
    assert np.all(steps <= 0.1 + 1e-9) and steps.min() > 0.09
    # The index spline overshoots beside the long segment, the chord spline does not.
    assert index.length_m > chord.length_m


def test_none_mode_is_the_sampled_polyline():
    path = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, 1.0, 1.0]])
    smoothed = smooth_path(path, ObstacleSet(), 0.1, 0.5, mode='none', shortcut=False,
                           sample_spacing=0.25)
    assert smoothed.length_m == pytest.approx(3.0)
    for vertex in path:
        assert np.min(np.linalg.norm(smoothed.positions - vertex, axis=1)) == 0.0
    assert list(smoothed.stop_points) == [0, 4, 8, 12]


def test_shortcut_path_keeps_endpoints_and_margin():
    path, obstacles, gamma, delta = _around_sphere('chord')
    short = shortcut_path(path, obstacles, gamma, delta)
    assert np.array_equal(short[0], path[0]) and np.array_equal(short[-1], path[-1])
    assert len(short) < len(path)
    fractions = np.linspace(0.0, 1.0, 2001)
    for a, b in zip(short[:-1], short[1:]):
        assert obstacles.distance(a + fractions[:, None] * (b - a)).min() >= gamma
    assert polyline_length(short) < polyline_length(path)


def test_single_point_and_duplicates():
    obstacles = ObstacleSet([Sphere([5.0, 5.0, 5.0], 1.0)])
    point = smooth_path([[0.0, 0.0, 0.0]], obstacles, 0.2, 0.5)
    assert point.positions.shape == (1, 3) and point.length_m == 0.0
    doubled = smooth_path([[0, 0, 0], [0, 0, 0], [1, 0, 0], [1, 0, 0]], obstacles, 0.2, 0.5)
    assert doubled.length_m == pytest.approx(1.0)


def test_invalid_inputs():
    obstacles = ObstacleSet()
    # Each refusal names the argument and what is wrong with it.
    with pytest.raises(InvalidInputError, match=r'path .*\(N, 3\).*\(3, 2\)'):
        smooth_path(np.zeros((3, 2)), obstacles, 0.2, 0.5)
    with pytest.raises(InvalidInputError, match=r'safety_margin .*>= 0.*-0\.1'):
        smooth_path(np.zeros((2, 3)), obstacles, -0.1, 0.5)
    with pytest.raises(InvalidInputError, match=r'mode .*chord, index, none.*bezier'):
        smooth_path(np.zeros((2, 3)), obstacles, 0.2, 0.5, mode='bezier')
    with pytest.raises(InvalidInputError, match=r'index_step must be in \(0\.0, 1\.0\], got 2\.0'):
        smooth_path(np.zeros((2, 3)), obstacles, 0.2, 0.5, index_step=2.0)
    with pytest.raises(InvalidInputError, match=r'path .*finite'):
        smooth_path([[0, 0, 0], [np.nan, 0, 0]], obstacles, 0.2, 0.5)
    occupied = ObstacleSet([Sphere([0.0, 0.0, 0.0], 1.0)])
    with pytest.raises(NoValidPathError, match='waypoint 0'):
        smooth_path([[0.0, 0.0, 1.1], [0.0, 0.0, 3.0]], occupied, 0.2, 0.5)


@pytest.mark.parametrize('name', ['paper_medium', 'paper_high'])
def test_paper_scenes_smoothed_shorter_than_raw(name):
    grid, obstacles, gamma, start, goal = load_scene(name)
    raw = csgraph_path(grid, blocked_mask(grid, obstacles, gamma), start, goal)
    delta = grid.resolution
    smoothed = smooth_path(raw, obstacles, gamma, delta)
    check_smoothed(smoothed, raw, obstacles, gamma, delta)
    assert smoothed.shortcut_length_m < polyline_length(raw)
    assert smoothed.length_m < polyline_length(raw)
    for mode in ('index', 'none'):
        check_smoothed(smooth_path(raw, obstacles, gamma, delta, mode=mode), raw, obstacles,
                       gamma, delta)


# ----------------------------------------------------------------------------------------------
# Continuing a motion: start tangent and curvature
# ----------------------------------------------------------------------------------------------

def random_start(rng: np.random.Generator, max_curvature: float = 0.5):
    """A random unit tangent and a random curvature vector normal to it [1/m]."""
    tangent = rng.normal(size=3)
    tangent /= np.linalg.norm(tangent)
    bend = rng.normal(size=3)
    bend -= np.dot(bend, tangent) * tangent
    bend *= rng.uniform(0.0, max_curvature) / np.linalg.norm(bend)
    return tangent, bend


def check_start(smoothed: SmoothedPath, tangent: np.ndarray, bend: np.ndarray) -> None:
    """The curve leaves the start with this tangent and curvature, without a stop."""
    assert smoothed.start_kept is True
    assert 0 not in smoothed.stop_points
    assert 0.0 not in smoothed.curve.stop_arc_length_m
    assert np.linalg.norm(smoothed.tangents[0] - tangent) <= 1e-9
    assert np.linalg.norm(smoothed.curvature_vectors[0] - bend) <= 1e-9 * (1.0 + np.linalg.norm(
        bend))
    t, k = smoothed.curve.derivatives(np.zeros(1))
    assert np.linalg.norm(t[0] - tangent) <= 1e-9
    assert np.linalg.norm(k[0] - bend) <= 1e-9 * (1.0 + np.linalg.norm(bend))
    # One-sided differences of positions agree (the curve, not only the samples); their
    # leading error terms cancelled (Richardson).
    h = 1e-3
    p = smoothed.curve.evaluate(h * np.arange(5.0))
    slope = (4.0 * (-3 * p[0] + 4 * p[1] - p[2]) / (2 * h)
             - (-3 * p[0] + 4 * p[2] - p[4]) / (4 * h)) / 3.0
    second = 2.0 * (p[0] - 2 * p[1] + p[2]) / h ** 2 - (p[0] - 2 * p[2] + p[4]) / (2 * h) ** 2
    assert np.allclose(slope, tangent, atol=1e-5)
    assert np.allclose(second, bend, atol=1e-3 * (1.0 + np.linalg.norm(bend))), (second, bend)


def test_start_spline_meets_its_conditions():
    """The clamped run: start point, both derivatives, every later knot but the first, C2."""
    rng = np.random.default_rng(7)
    for count in (2, 3, 4, 9):
        t = np.r_[0.0, np.cumsum(rng.uniform(0.3, 2.0, count - 1))]
        points = rng.uniform(-50.0, 50.0, size=(count, 3)) + 1e4
        first, second = rng.normal(size=3), rng.normal(size=3)
        coef = start_spline(t, points, first, second)
        spline = PPoly(coef, t)
        assert np.allclose(spline(t[0], 1), first, rtol=0, atol=1e-10)
        assert np.allclose(spline(t[0], 2), second, rtol=0, atol=1e-9)
        assert np.allclose(spline(t[0]), points[0], rtol=0, atol=1e-9)
        later = np.r_[0, np.arange(2, count)] if count > 2 else np.array([0, 1])
        assert np.allclose(spline(t[later]), points[later], rtol=0, atol=1e-8)
        # C2 at every interior knot: each piece's end meets the next piece's start.
        h = np.diff(t)[:-1]
        for order in (0, 1, 2):
            ends = np.array([np.polyval(np.polyder(coef[:, j, axis], order), h[j])
                             for j in range(count - 2) for axis in range(3)])
            starts = np.array([np.polyval(np.polyder(coef[:, j + 1, axis], order), 0.0)
                               for j in range(count - 2) for axis in range(3)])
            assert np.allclose(ends, starts, rtol=0, atol=1e-8 * 10 ** order), (count, order)


def test_random_scenes_continue_the_start_motion(scenes):
    """Random certified curves from random moving starts keep the start state and the margin."""
    rng = np.random.default_rng(19)
    kept = total = 0
    for seed, grid, obstacles, gamma, path in scenes[::3]:
        delta = grid.resolution
        mode = ('chord', 'index')[seed % 2]
        tangent, bend = random_start(rng)
        if seed % 5:
            # Mostly into the box: a start heading out of it near a face cannot be kept.
            near_low = path[0] - grid.bounds_min < 1.5
            near_high = grid.bounds_max - path[0] < 1.5
            flip = (near_low & (tangent < 0)) | (near_high & (tangent > 0))
            tangent[flip] *= -1.0
            bend[flip] *= -1.0
            bend -= np.dot(bend, tangent) * tangent
        options = dict(mode=mode, bounds=(grid.bounds_min, grid.bounds_max),
                       start_tangent=tangent, start_curvature=bend)
        if seed % 4 == 0:
            options['start_lead_in'] = float(rng.uniform(0.5, 4.0))
        try:
            smoothed = smooth_path(path, obstacles, gamma, delta, **options)
        except NoValidPathError:
            continue
        total += 1
        check_smoothed(smoothed, path, obstacles, gamma, delta)
        if smoothed.start_kept:
            kept += 1
            check_start(smoothed, tangent, bend)
        else:
            assert smoothed.start_kept is False and smoothed.stop_points[0] == 0
    # Starts near a face of the box heading out of it cannot be kept; most others can.
    assert total >= 60 and kept >= 0.75 * total, (kept, total)


def test_a_start_heading_away_from_the_goal_turns_without_stopping():
    delta, gamma = 0.5, 0.3
    obstacles = ObstacleSet([Sphere([5.0, 0.0, 2.0], 1.0)])
    path = np.array([[0.0, 0.0, 2.0], [2.0, 1.0, 2.0], [4.0, 2.0, 2.0], [6.0, 2.0, 2.0],
                     [8.0, 1.0, 2.0], [10.0, 0.0, 2.0]])
    box = (np.array([-20.0, -20.0, 0.0]), np.array([20.0, 20.0, 10.0]))
    for mode in ('chord', 'index'):
        for tangent, bend in (([-1.0, 0.0, 0.0], [0.0, 0.3, 0.0]), ([0.0, 0.0, 1.0], [0.0] * 3),
                              ([0.6, 0.8, 0.0], [-0.16, 0.12, 0.0])):
            tangent, bend = np.array(tangent), np.array(bend)
            smoothed = smooth_path(path, obstacles, gamma, delta, mode=mode, bounds=box,
                                   start_tangent=tangent, start_curvature=bend,
                                   start_lead_in=3.0)
            check_smoothed(smoothed, path, obstacles, gamma, delta)
            check_start(smoothed, tangent, bend)
            # It follows the start's osculating circle over the lead-in (within centimetres in
            # chord mode; index splines swing wider).
            kappa = float(np.linalg.norm(bend))
            s = np.array([0.5, 1.0, 2.0])
            if kappa > 0.0:
                circle = (path[0] + np.outer(np.sin(kappa * s) / kappa, tangent)
                          + np.outer((1.0 - np.cos(kappa * s)) / kappa, bend / kappa))
            else:
                circle = path[0] + np.outer(s, tangent)
            apart = np.linalg.norm(smoothed.curve.evaluate(s) - circle, axis=1)
            assert apart.max() < (0.03 if mode == 'chord' else 0.1), apart


def test_a_start_toward_an_obstacle_is_repaired_and_kept():
    """Heading past a sphere that the spline would cut: repaired with knots, start kept."""
    delta, gamma = 0.5, 0.3
    obstacles = ObstacleSet([Sphere([2.0, 1.4, 1.0], 1.0)])
    path = np.array([[0.0, 0.0, 1.0], [4.0, 0.0, 1.0], [4.0, 4.0, 1.0]])
    tangent, bend = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.2, 0.0])
    smoothed = smooth_path(path, obstacles, gamma, delta, start_tangent=tangent,
                           start_curvature=bend, start_lead_in=2.0)
    check_smoothed(smoothed, path, obstacles, gamma, delta)
    check_start(smoothed, tangent, bend)


def test_a_start_that_cannot_be_continued_is_reported_and_starts_from_rest():
    """Flying into a wall half a millimetre beyond the margin: no certified curve keeps the
    motion (further away, a sharp enough turn would, however fast it would have to be flown)."""
    delta, gamma = 0.5, 0.3
    obstacles = ObstacleSet([Box([0.3005, -5.0, -5.0], [1.0, 5.0, 5.0])])
    path = np.array([[0.0, 0.0, 1.0], [0.0, 2.0, 1.0]])
    tangent = np.array([1.0, 0.0, 0.0])
    smoothed = smooth_path(path, obstacles, gamma, delta, start_tangent=tangent,
                           start_curvature=np.array([0.0, 0.0, 0.0]))
    assert smoothed.start_kept is False
    assert smoothed.stop_points[0] == 0
    check_smoothed(smoothed, path, obstacles, gamma, delta)
    plain = smooth_path(path, obstacles, gamma, delta)
    assert plain.start_kept is None
    assert np.array_equal(plain.positions, smoothed.positions)


def test_start_conditions_in_none_mode_and_without_them():
    obstacles = ObstacleSet([Sphere([5.0, 5.0, 5.0], 1.0)])
    path = np.array([[0.0, 0.0, 1.0], [3.0, 0.0, 1.0], [3.0, 3.0, 1.0]])
    straight = smooth_path(path, obstacles, 0.2, 0.5, mode='none',
                           start_tangent=[0.0, 2.0, 0.0])
    check_start(straight, np.array([0.0, 1.0, 0.0]), np.zeros(3))
    assert len(straight.stop_points) >= 2    # the corners stay stop points
    bent = smooth_path(path, obstacles, 0.2, 0.5, mode='none', start_tangent=[0.0, 1.0, 0.0],
                       start_curvature=[0.1, 0.0, 0.0])
    assert bent.start_kept is False and bent.stop_points[0] == 0
    rest = smooth_path(path, obstacles, 0.2, 0.5)
    assert rest.start_kept is None and rest.stop_points[0] == 0
    # The curvature's part along the tangent is dropped; the tangent is normalised.
    tilted = smooth_path(path, obstacles, 0.2, 0.5, start_tangent=[0.0, 3.0, 0.0],
                         start_curvature=[0.2, 5.0, 0.0])
    check_start(tilted, np.array([0.0, 1.0, 0.0]), np.array([0.2, 0.0, 0.0]))
    assert smooth_path(path[:1], obstacles, 0.2, 0.5, start_tangent=[1, 0, 0]).start_kept is False


def test_invalid_start_conditions():
    obstacles = ObstacleSet()
    path = np.array([[0.0, 0.0, 1.0], [3.0, 0.0, 1.0]])
    with pytest.raises(InvalidInputError, match='start_curvature needs start_tangent'):
        smooth_path(path, obstacles, 0.2, 0.5, start_curvature=[0.0, 0.1, 0.0])
    with pytest.raises(InvalidInputError, match='start_lead_in needs start_tangent'):
        smooth_path(path, obstacles, 0.2, 0.5, start_lead_in=2.0)
    with pytest.raises(InvalidInputError, match='start_tangent must be a nonzero vector'):
        smooth_path(path, obstacles, 0.2, 0.5, start_tangent=[0.0, 0.0, 0.0])
    with pytest.raises(InvalidInputError, match='start_tangent'):
        smooth_path(path, obstacles, 0.2, 0.5, start_tangent=[np.nan, 0.0, 0.0])
    with pytest.raises(InvalidInputError, match='start_lead_in'):
        smooth_path(path, obstacles, 0.2, 0.5, start_tangent=[1, 0, 0], start_lead_in=-1.0)
