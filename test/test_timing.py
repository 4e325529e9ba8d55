"""Time parameterisation of smoothed paths: limits, rest-to-rest, stops and kinematic sanity."""

from helpers.scenes import random_scene, SEEDS
import numpy as np
import pytest

from uav_global_planner.core.errors import InvalidInputError, NoValidPathError
from uav_global_planner.core.obstacles import ObstacleSet
from uav_global_planner.core.result import Trajectory
from uav_global_planner.core.smoothing import smooth_path, SmoothedPath
from uav_global_planner.core.timing import check_limits, time_parameterize

LIMITS = (2.0, 1.0, 1.0, 0.5)  # the PlannerConfig defaults [m/s, m/s, m/s^2, m/s^2]
# Relative tolerance of accelerations found by finite differences of the timed samples:
# rounding only (the measured worst over the random scenes is 1 + 1e-12).
ACCEL_RTOL = 1e-6


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
    check_motion_acceleration(trajectory, limits)
    # The reported accelerations agree with the change of speed: speed is linear in time on
    # each interval, so (speed[j+1] - speed[j]) / dt[j] is its tangential acceleration, and
    # away from stop points the reported value at a sample has the mean of its two intervals'.
    tangential = np.diff(speed) / dt
    inner = np.setdiff1d(np.arange(1, len(times) - 1), smoothed.stop_points)
    reported = np.sum(trajectory.accelerations[inner] * smoothed.tangents[inner], axis=1)
    expected = 0.5 * (tangential[inner - 1] + tangential[inner])
    scale = max(limits[2], limits[3])
    assert np.allclose(reported, expected, rtol=0.0, atol=ACCEL_RTOL * scale), (
        np.max(np.abs(reported - expected)))


def check_motion_acceleration(trajectory: Trajectory, limits) -> None:
    """The acceleration of the motion itself, from the timed samples alone, keeps the limits.

    The motion is C1 in time (the speed is continuous and zero where the tangent jumps), so
    twice the second divided difference of the positions over three consecutive samples is a
    weighted mean of its acceleration between them and keeps the (convex) limits, up to the
    rounding of the differences: ``ACCEL_RTOL`` of the limit. Independent of the reported
    accelerations, which :func:`check_limits` checks.
    """
    times, positions = trajectory.times, trajectory.positions
    if len(times) < 3:
        return
    dt = np.diff(times)
    chord_velocity = np.diff(positions, axis=0) / dt[:, None]
    motion = 2.0 * np.diff(chord_velocity, axis=0) / (dt[1:] + dt[:-1])[:, None]
    horizontal = np.hypot(motion[:, 0], motion[:, 1])
    vertical = np.abs(motion[:, 2])
    _, _, max_horizontal, max_vertical = limits
    assert horizontal.max() <= max_horizontal * (1.0 + ACCEL_RTOL), (
        f'horizontal acceleration {horizontal.max():.6g} m/s^2 > {max_horizontal:g} m/s^2')
    assert vertical.max() <= max_vertical * (1.0 + ACCEL_RTOL), (
        f'vertical acceleration {vertical.max():.6g} m/s^2 > {max_vertical:g} m/s^2')


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


def timed_line(start, end) -> Trajectory:
    """The checked timing, under :data:`LIMITS`, of the straight line from start to end [m]."""
    smoothed = smooth_path(np.array([start, end]), ObstacleSet(), 0.2, 0.5, sample_spacing=0.05)
    trajectory = time_parameterize(smoothed, *LIMITS)
    check_trajectory(trajectory, smoothed, LIMITS)
    return trajectory


def test_straight_horizontal_line_is_trapezoidal():
    trajectory = timed_line([0.0, 0.0, 1.0], [10.0, 0.0, 1.0])
    # Accelerate at 1 m/s^2 to 2 m/s (2 m), cruise 6 m, brake: 2 + 3 + 2 = 7 s.
    assert trajectory.duration_s == pytest.approx(7.0, rel=1e-3)
    assert np.linalg.norm(trajectory.velocities, axis=1).max() == pytest.approx(2.0)
    assert np.abs(trajectory.accelerations[:, 0]).max() == pytest.approx(1.0)


def test_vertical_line_uses_vertical_limits():
    trajectory = timed_line([0.0, 0.0, 0.0], [0.0, 0.0, 5.0])
    # Vertical: 0.5 m/s^2 to 1 m/s (1 m), cruise 3 m, brake: 2 + 3 + 2 = 7 s.
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
    trajectory = Trajectory(times=times, positions=positions,
                            velocities=np.array([[3.0, 0, 0], [0, 0, 2.0]]),
                            accelerations=np.array([[0, 0, 0], [0, 0, 0.0]]))
    problems = check_limits(trajectory, *LIMITS)
    assert len(problems) == 2
    assert 'horizontal speed' in problems[0] and 'vertical speed' in problems[1]
