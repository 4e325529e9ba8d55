"""Time parameterisation of smoothed paths: limits, rest-to-rest, stops and kinematic sanity."""

import numpy as np
import pytest
from test_smoothing import random_scene, SEEDS

from uav_global_planner.core.errors import InvalidInputError, NoValidPathError
from uav_global_planner.core.obstacles import ObstacleSet
from uav_global_planner.core.result import Trajectory
from uav_global_planner.core.smoothing import smooth_path, SmoothedPath
from uav_global_planner.core.timing import check_limits, time_parameterize

LIMITS = (2.0, 1.0, 1.0, 0.5)  # the PlannerConfig defaults [m/s, m/s, m/s^2, m/s^2]


def check_trajectory(trajectory: Trajectory, smoothed: SmoothedPath, limits) -> None:
    """Limits, rest at start, goal and stops, and consistency of positions, speeds, times."""
    assert check_limits(trajectory, *limits) == []
    times = trajectory.times
    assert times[0] == 0.0 and np.all(np.diff(times) > 0)
    assert np.array_equal(trajectory.positions, smoothed.positions)
    speed = np.linalg.norm(trajectory.velocities, axis=1)
    assert np.all(speed[smoothed.stop_points] == 0.0)
    assert speed[0] == 0.0 and speed[-1] == 0.0
    # Velocities are tangent to the curve.
    along = np.sum(trajectory.velocities * smoothed.tangents, axis=1)
    assert np.allclose(along, speed, atol=1e-9)
    # Mean speed over each interval times its duration is its arc length (exact for constant
    # tangential acceleration); the chord over the time step matches the mean velocity.
    ds = np.diff(smoothed.arc_length)
    dt = np.diff(times)
    assert np.allclose(0.5 * (speed[1:] + speed[:-1]) * dt, ds, rtol=1e-9, atol=1e-12)
    chord_velocity = np.diff(trajectory.positions, axis=0) / dt[:, None]
    mean_velocity = 0.5 * (speed[1:, None] * smoothed.incoming_tangents[1:]
                           + speed[:-1, None] * smoothed.tangents[:-1])
    error = np.linalg.norm(chord_velocity - mean_velocity, axis=1)
    # On an arc turning by theta they differ by about speed * theta^2 / 12 + |dv| * theta / 4.
    turn = ds * np.linalg.norm(smoothed.interval_curvature_max, axis=1)
    top = np.maximum(speed[1:], speed[:-1])
    # (Generous: the curvature also varies along the interval.)
    bound = top * turn ** 2 / 2.0 + np.abs(np.diff(speed)) * turn + 0.01 * top + 1e-9
    assert np.all(error <= bound), np.max(error - bound)
    # Accelerations agree with the change of velocity away from stop points.
    assert np.all(np.isfinite(trajectory.accelerations))


def test_random_scenes_within_limits():
    rng = np.random.default_rng(7)
    checked = 0
    for seed in SEEDS:
        scene = random_scene(seed)
        if scene is None:
            continue
        grid, obstacles, gamma, path = scene
        mode = ('chord', 'index', 'none')[seed % 3]
        try:
            smoothed = smooth_path(path, obstacles, gamma, grid.resolution, mode=mode)
        except NoValidPathError:
            continue
        limits = tuple(rng.uniform([0.5, 0.2, 0.3, 0.1], [5.0, 3.0, 4.0, 2.0]))
        trajectory = time_parameterize(smoothed, *limits)
        check_trajectory(trajectory, smoothed, limits)
        checked += 1
    assert checked >= 200


def test_straight_horizontal_line_is_trapezoidal():
    path = np.array([[0.0, 0.0, 1.0], [10.0, 0.0, 1.0]])
    smoothed = smooth_path(path, ObstacleSet(), 0.2, 0.5, sample_spacing=0.05)
    trajectory = time_parameterize(smoothed, *LIMITS)
    check_trajectory(trajectory, smoothed, LIMITS)
    # Accelerate at 1 m/s^2 to 2 m/s (2 m), cruise 6 m, brake: 2 + 3 + 2 = 7 s.
    assert trajectory.duration_s == pytest.approx(7.0, rel=1e-3)
    assert np.linalg.norm(trajectory.velocities, axis=1).max() == pytest.approx(2.0)
    assert np.abs(trajectory.accelerations[:, 0]).max() == pytest.approx(1.0)


def test_vertical_line_uses_vertical_limits():
    path = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 5.0]])
    smoothed = smooth_path(path, ObstacleSet(), 0.2, 0.5, sample_spacing=0.05)
    trajectory = time_parameterize(smoothed, *LIMITS)
    check_trajectory(trajectory, smoothed, LIMITS)
    # 1 m/s^2 ... no: vertical 0.5 m/s^2 to 1 m/s (1 m), cruise 3 m, brake: 2 + 3 + 2 = 7 s.
    assert trajectory.duration_s == pytest.approx(7.0, rel=1e-3)
    assert np.abs(trajectory.velocities[:, 2]).max() == pytest.approx(1.0)


def test_curvature_limits_speed_on_a_circle():
    radius = 2.0
    angles = np.linspace(0.0, 1.5 * np.pi, 200)
    path = np.stack([radius * np.cos(angles), radius * np.sin(angles), np.ones_like(angles)], 1)
    smoothed = smooth_path(path, ObstacleSet(), 0.1, 0.5, shortcut=False)
    limits = (5.0, 1.0, 1.0, 0.5)
    trajectory = time_parameterize(smoothed, *limits)
    check_trajectory(trajectory, smoothed, limits)
    # Centripetal acceleration v^2 / R within 1 m/s^2: v <= sqrt(2) m/s.
    speed = np.linalg.norm(trajectory.velocities, axis=1)
    assert speed.max() <= np.sqrt(1.0 * radius) * (1 + 1e-3)
    assert speed.max() >= 0.9 * np.sqrt(1.0 * radius)


def test_polyline_corners_stop():
    path = np.array([[0.0, 0.0, 1.0], [3.0, 0.0, 1.0], [3.0, 3.0, 2.0], [0.0, 3.0, 2.0]])
    smoothed = smooth_path(path, ObstacleSet(), 0.1, 0.5, mode='none', shortcut=False)
    assert len(smoothed.stop_points) == 4
    trajectory = time_parameterize(smoothed, *LIMITS)
    check_trajectory(trajectory, smoothed, LIMITS)
    speed = np.linalg.norm(trajectory.velocities, axis=1)
    interior = [i for i in range(1, len(speed) - 1) if i not in smoothed.stop_points]
    assert np.all(speed[interior] > 0.0)


def test_limits_hold_between_samples():
    """At interval midpoints the continuous motion stays within a few per cent of the limits."""
    checked = 0
    for seed in list(SEEDS)[:60]:
        scene = random_scene(seed)
        if scene is None:
            continue
        grid, obstacles, gamma, path = scene
        try:
            smoothed = smooth_path(path, obstacles, gamma, grid.resolution)
        except NoValidPathError:
            continue
        trajectory = time_parameterize(smoothed, *LIMITS)
        s = smoothed.arc_length
        u = np.linalg.norm(trajectory.velocities, axis=1) ** 2
        tangential = np.diff(u) / (2 * np.diff(s))
        mid = 0.5 * (s[1:] + s[:-1])
        tangent, curvature = smoothed.curve.derivatives(mid)
        accel = tangential[:, None] * tangent + (0.5 * (u[1:] + u[:-1]))[:, None] * curvature
        horizontal = np.hypot(accel[:, 0], accel[:, 1])
        assert horizontal.max() <= LIMITS[2] * 1.05
        assert np.abs(accel[:, 2]).max() <= LIMITS[3] * 1.05
        checked += 1
    assert checked >= 40


def test_single_sample_and_invalid_limits():
    smoothed = smooth_path([[1.0, 2.0, 3.0]], ObstacleSet(), 0.2, 0.5)
    trajectory = time_parameterize(smoothed, *LIMITS)
    assert trajectory.times.tolist() == [0.0] and trajectory.duration_s == 0.0
    line = smooth_path([[0, 0, 0], [1, 0, 0]], ObstacleSet(), 0.2, 0.5)
    for bad in ((0.0, 1, 1, 1), (1, -1, 1, 1), (1, 1, np.inf, 1), (1, 1, 1, np.nan)):
        with pytest.raises(InvalidInputError):
            time_parameterize(line, *bad)


def test_check_limits_reports_violations():
    times = np.array([0.0, 1.0])
    positions = np.zeros((2, 3))
    trajectory = Trajectory(times, positions, np.array([[3.0, 0, 0], [0, 0, 2.0]]),
                            np.array([[0, 0, 0], [0, 0, 0.0]]))
    problems = check_limits(trajectory, *LIMITS)
    assert len(problems) == 2
    assert 'horizontal speed' in problems[0] and 'vertical speed' in problems[1]
