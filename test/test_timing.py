"""Jerk-limited time parameterisation: limits on the continuous reference, continuity, clearance,
stops, the start from a moving state, and the heading."""

from helpers.scenes import random_scene, SEEDS
import numpy as np
import pytest

from uav_global_planner.core.errors import InvalidInputError, NoValidPathError
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.path.motion_limits import GRAVITY, MotionLimits
from uav_global_planner.core.path.smoothing import smooth_path, SmoothedPath
from uav_global_planner.core.path.timing import (_Stations, check_limits, longest_crawl,
                                                 StartMotion, time_parameterize)
from uav_global_planner.core.path.yaw import YAW_ACCELERATION

DEFAULTS = MotionLimits()
# Dense check step [s]: the reference is evaluated exactly at these times.
STEP = 0.004


def random_limits(rng: np.random.Generator) -> MotionLimits:
    speed_h, speed_z, accel_h, accel_z = rng.uniform([0.5, 0.2, 0.3, 0.1], [8.0, 3.0, 5.0, 3.0])
    return MotionLimits(speed_h, speed_z, accel_h, accel_z, jerk=float(rng.uniform(2.0, 30.0)),
                        tilt_deg=float(rng.uniform(5.0, 60.0)),
                        thrust_to_weight=float(rng.uniform(1.1, 3.0)),
                        yaw_rate=float(rng.uniform(0.2, 3.0)))


def random_curves(count: int, mode_of=lambda seed: 'chord'):
    """Certified curves of the first ``count`` random scenes that smooth: (seed, obstacles,
    gamma, smoothed)."""
    for seed in list(SEEDS)[:count]:
        scene = random_scene(seed)
        if scene is None:
            continue
        grid, obstacles, gamma, path = scene
        try:
            smoothed = smooth_path(path, obstacles, gamma, grid.resolution, mode=mode_of(seed))
        except NoValidPathError:
            continue
        yield seed, obstacles, gamma, smoothed


def check_reference(smoothed: SmoothedPath, limits: MotionLimits, obstacles: ObstacleSet,
                    gamma: float, trajectory, moving: bool = False) -> None:
    """Every limit at a dense grid of times, continuity, clearance and the samples."""
    assert check_limits(trajectory, limits, step_s=STEP) == []
    duration = trajectory.duration_s
    times = np.linspace(0.0, duration, max(3, int(duration / STEP) + 1))
    state = trajectory.state_at(times)
    dt = times[1] - times[0]
    # Acceleration is continuous: between two close times it changes by at most the jerk
    # limit times the step (jerk is bounded and acceleration its integral).
    step = np.linalg.norm(np.diff(state.acceleration, axis=0), axis=1)
    assert step.max() <= limits.jerk * dt * (1 + 1e-6) + 1e-9
    # Yaw continuous within the rate limit, and its rate continuous within the yaw
    # acceleration limit.
    turn = np.abs(np.angle(np.exp(1j * np.diff(state.yaw))))
    assert turn.max() <= limits.yaw_rate * dt * (1 + 1e-6) + 1e-12
    assert np.abs(np.diff(state.yaw_rate)).max() <= YAW_ACCELERATION * dt * (1 + 1e-6) + 1e-12
    # Rest at both ends (at the goal only, from a moving start).
    for k in ((-1,) if moving else (0, -1)):
        assert np.linalg.norm(state.velocity[k]) < 1e-9
        assert np.linalg.norm(state.acceleration[k]) < 1e-9
    # The reference stays on the certified curve: the clearance holds at every dense point.
    if not obstacles.is_empty():
        assert obstacles.distance(state.position).min() >= gamma - 1e-9
    # Samples: increasing times, the curve's samples, and the reference passes them then.
    assert trajectory.times[0] == 0.0 and np.all(np.diff(trajectory.times) > 0.0)
    assert np.array_equal(trajectory.positions, smoothed.positions)
    again = trajectory.state_at(trajectory.times)
    assert np.abs(again.position - smoothed.positions).max() < 1e-6
    speed = np.linalg.norm(trajectory.velocities, axis=1)
    stops = smoothed.stop_points[1:] if moving else smoothed.stop_points
    assert np.all(speed[stops] == 0.0)


def test_random_curves_and_limits_keep_every_limit_continuously():
    rng = np.random.default_rng(7)
    checked = 0
    for seed, obstacles, gamma, smoothed in random_curves(
            120, lambda seed: ('chord', 'index', 'none')[seed % 3]):
        limits = random_limits(rng)
        timing = time_parameterize(smoothed, limits, yaw_mode=('velocity', 'goal')[seed % 2])
        check_reference(smoothed, limits, obstacles, gamma, timing.trajectory)
        checked += 1
    assert checked >= 80


def test_moving_starts_keep_every_limit_and_start_as_asked():
    rng = np.random.default_rng(11)
    checked = kept = 0
    for _, obstacles, gamma, smoothed in random_curves(80):
        limits = random_limits(rng)
        box = limits.acceleration_box()
        speed = float(rng.uniform(0.1, 1.0)) * min(limits.speed_horizontal,
                                                   limits.speed_vertical)
        accel = float(rng.uniform(-0.8, 0.8)) * min(box.horizontal, box.vertical)
        timing = time_parameterize(smoothed, limits, start=StartMotion(speed, accel))
        check_reference(smoothed, limits, obstacles, gamma, timing.trajectory, moving=True)
        state = timing.trajectory.state_at(0.0)
        tangent = smoothed.tangents[0]
        # Speed and tangential acceleration as kept (lowered only to brake for the curve).
        assert 0.0 <= timing.start_speed <= speed
        assert float(state.velocity[0] @ tangent) == pytest.approx(timing.start_speed,
                                                                   abs=1e-9)
        if timing.start_speed == speed:
            assert float(state.acceleration[0] @ tangent) == pytest.approx(timing.start_accel,
                                                                           abs=1e-9)
            kept += 1
        checked += 1
    assert checked >= 50 and kept >= checked // 2


def assert_maxima_hold_inside(smoothed: SmoothedPath, stations: _Stations,
                              rng: np.random.Generator) -> None:
    """The maxima of every interval of ``stations`` (tangent components, curvature norm and
    horizontal part, curvature rate) bound the curve's own values at four random points
    inside it."""
    s = stations.s
    th, tz = stations.tangent.T
    for _ in range(4):
        inside = s[:-1] + rng.uniform(0.0, 1.0, len(s) - 1) * np.diff(s)
        _, tangent, curvature, rate = smoothed.curve.derivatives3(inside)
        assert np.all(np.hypot(tangent[:, 0], tangent[:, 1]) <= th + 1e-9)
        assert np.all(np.abs(tangent[:, 2]) <= tz + 1e-9)
        assert np.all(np.linalg.norm(curvature, axis=1)
                      <= stations.curvature_norm * (1 + 1e-9) + 1e-9)
        assert np.all(np.hypot(curvature[:, 0], curvature[:, 1])
                      <= stations.curvature[:, 0] * (1 + 1e-9) + 1e-9)
        assert np.all(np.linalg.norm(rate, axis=1)
                      <= stations.curvature_rate * (1 + 1e-9) + 1e-9)


def test_per_interval_bounds_prove_the_limits():
    """The speed cap w and tangential bound alpha of every interval satisfy the three
    sufficient conditions of the timing module, with the interval's maxima."""
    rng = np.random.default_rng(3)
    checked = 0
    for _, _, _, smoothed in random_curves(60):
        limits = random_limits(rng)
        box = limits.acceleration_box()
        stations = _Stations.of(smoothed, None)
        cap, alpha, zeta, window = stations.bounds(limits, box.horizontal, box.vertical)
        th, tz = stations.tangent.T
        kh, kz = stations.curvature.T
        assert np.all(cap > 0.0) and np.all(alpha > 0.0)
        assert np.all(cap * th <= limits.speed_horizontal * (1 + 1e-12))
        assert np.all(cap * tz <= limits.speed_vertical * (1 + 1e-12))
        assert np.all(alpha * th + cap ** 2 * kh <= box.horizontal * (1 + 1e-9))
        assert np.all(alpha * tz + cap ** 2 * kz <= box.vertical * (1 + 1e-9))
        # The tangential jerk a jump of alpha over the shortest window asks fits the
        # allowance zeta, and zeta leaves the curvature terms within the limit.
        bends = 3 * cap * alpha * stations.curvature_norm + cap ** 3 * stations.curvature_rate
        assert np.all(alpha / window <= zeta * (1 + 1e-9))
        assert alpha.max() <= window * limits.jerk * (1 + 1e-12)
        assert np.all(zeta + bends <= limits.jerk * (1 + 1e-9))
        # The maxima bound the curve's own values at points inside each interval.
        assert_maxima_hold_inside(smoothed, stations, rng)
        checked += 1
    assert checked >= 40


def test_tilt_and_thrust_limits_bound_the_acceleration():
    smoothed = smooth_path(np.array([[0.0, 0.0, 1.0], [60.0, 0.0, 1.0], [60.0, 40.0, 20.0]]),
                           ObstacleSet(), 0.2, 0.5)
    fast = MotionLimits(12.0, 5.0, 8.0, 4.0, jerk=20.0, tilt_deg=10.0, thrust_to_weight=1.2)
    timing = time_parameterize(smoothed, fast)
    peaks = timing.trajectory.peaks(STEP)
    assert peaks.tilt_deg <= 10.0 * (1 + 1e-9)
    assert peaks.thrust_to_weight <= 1.2 * (1 + 1e-9)
    box = fast.acceleration_box()
    assert box.horizontal <= (GRAVITY - box.vertical) * np.tan(np.radians(10.0)) + 1e-12
    assert box.horizontal_by == 'tilt' and box.vertical_by == 'thrust'
    # The tilt limit binds: the reference uses most of it on the long straight.
    assert peaks.tilt_deg > 8.0
    assert check_limits(timing.trajectory, fast, step_s=STEP) == []


def test_straight_line_meets_the_jerk_limited_optimum_closely():
    """Rest to rest on 30 m: the time-optimal jerk-limited profile takes L/v + v/a + a/J."""
    smoothed = smooth_path(np.array([[0.0, 0.0, 1.0], [30.0, 0.0, 1.0]]), ObstacleSet(), 0.2,
                           0.5, sample_spacing=0.05)
    limits = MotionLimits(3.0, 1.0, 1.5, 0.5, jerk=10.0)
    trajectory = time_parameterize(smoothed, limits).trajectory
    optimum = 30.0 / 3.0 + 3.0 / 1.5 + 1.5 / 10.0
    assert optimum <= trajectory.duration_s <= 1.1 * optimum
    peaks = trajectory.peaks(STEP)
    assert peaks.speed_horizontal == pytest.approx(3.0, rel=1e-6)
    assert peaks.accel_horizontal == pytest.approx(1.5, rel=1e-3)
    assert peaks.jerk <= 10.0 * (1 + 1e-9)


def test_polyline_corners_stop_smoothly_and_the_rest_does_not():
    path = np.array([[0.0, 0.0, 1.0], [3.0, 0.0, 1.0], [3.0, 3.0, 2.0], [0.0, 3.0, 2.0]])
    smoothed = smooth_path(path, ObstacleSet(), 0.1, 0.5, mode='none', shortcut=False)
    assert len(smoothed.stop_points) == 4
    trajectory = time_parameterize(smoothed, DEFAULTS).trajectory
    check_reference(smoothed, DEFAULTS, ObstacleSet(), 0.1, trajectory)
    speed = np.linalg.norm(trajectory.velocities, axis=1)
    interior = np.setdiff1d(np.arange(1, len(speed) - 1), smoothed.stop_points)
    assert np.all(speed[interior] > 0.0)
    # A smooth bend does not stop.
    angles = np.linspace(0.0, np.pi, 40)
    arc = np.stack([5 * np.cos(angles), 5 * np.sin(angles), np.ones_like(angles)], axis=1)
    bend = smooth_path(arc, ObstacleSet(), 0.1, 0.5, shortcut=False)
    bent = time_parameterize(bend, DEFAULTS).trajectory
    quarter = len(bent.times) // 4
    assert np.linalg.norm(bent.velocities[quarter:-quarter], axis=1).min() > 0.9


@pytest.mark.parametrize('speed, accel', [(5.0, 0.0), (5.0, -2.0), (2.0, 1.5), (0.3, -0.5)])
def test_a_moving_start_is_continued_exactly(speed, accel):
    smoothed = smooth_path(np.array([[0.0, 0.0, 5.0], [80.0, 10.0, 5.0]]), ObstacleSet(), 0.2,
                           0.5)
    limits = MotionLimits(8.0, 3.0, 4.0, 2.0, jerk=10.0)
    timing = time_parameterize(smoothed, limits, start=StartMotion(speed, accel))
    state = timing.trajectory.state_at(0.0)
    tangent = smoothed.tangents[0]
    assert np.linalg.norm(state.velocity[0] - speed * tangent) < 1e-9
    assert np.linalg.norm(state.acceleration[0] - accel * tangent) < 1e-9
    assert (timing.start_speed, timing.start_accel) == (speed, accel)
    assert check_limits(timing.trajectory, limits, step_s=STEP) == []


@pytest.mark.parametrize('back, side, lead_in', [(5.0, 0.3, 8.0), (6.0, 0.5, 10.0),
                                                 (8.0, 0.1, 12.0)])
def test_a_curve_that_turns_back_passes_its_near_cusp_without_crawling(back, side, lead_in):
    """A moving start whose goal lies behind it: the curve leaves along the motion for the
    lead-in and then turns back on itself within micrometres (a near-cusp). The reference slows
    down to turn there, within every limit, and goes on: it does not crawl (it used to creep
    along at 1 mm/s for minutes, the cap of the sharpest point held over the whole sample
    interval)."""
    smoothed = smooth_path(np.array([[0.0, 0.0, 2.0], [-back, side, 2.0]]), ObstacleSet(), 0.2,
                           0.5, start_tangent=[1.0, 0.0, 0.0], start_lead_in=lead_in)
    assert smoothed.start_kept
    timing = time_parameterize(smoothed, DEFAULTS, start=StartMotion(2.0, 0.0))
    trajectory = timing.trajectory
    assert longest_crawl(trajectory) < 5.0
    # Out at 2 m/s for the lead-in, back to the goal: well under twice the time at full speed.
    assert trajectory.duration_s < 2.0 * (smoothed.length_m / 2.0 + 2 * 2.0 / 0.35)
    check_reference(smoothed, DEFAULTS, ObstacleSet(), 0.2, trajectory, moving=True)
    box = DEFAULTS.acceleration_box()
    stations = _Stations.of(smoothed, None).refined(smoothed.curve, DEFAULTS, box.horizontal,
                                                    box.vertical)
    # The near-cusp: a radius below a millimetre, where the stations were cut finer.
    _, _, curvature, _ = smoothed.curve.derivatives3(stations.s)
    assert np.nanmax(np.linalg.norm(curvature, axis=1)) > 1e3
    assert len(stations.s) > len(smoothed.arc_length)
    # The bounds of the cut stations hold inside each of their intervals.
    assert_maxima_hold_inside(smoothed, stations, np.random.default_rng(7))


def test_a_start_too_fast_to_stop_is_slowed_and_says_so():
    smoothed = smooth_path(np.array([[0.0, 0.0, 5.0], [4.0, 0.0, 5.0]]), ObstacleSet(), 0.2,
                           0.5)
    limits = MotionLimits(8.0, 3.0, 1.0, 0.5, jerk=10.0)
    timing = time_parameterize(smoothed, limits, start=StartMotion(6.0, 0.0))
    assert timing.start_speed < 6.0
    speed = np.linalg.norm(timing.trajectory.state_at(0.0).velocity[0])
    assert speed == pytest.approx(timing.start_speed, abs=1e-9)


def test_heading_follows_travel_within_the_yaw_rate():
    smoothed = smooth_path(np.array([[0.0, 0.0, 1.0], [0.0, 30.0, 1.0]]), ObstacleSet(), 0.2,
                           0.5)
    limits = MotionLimits(yaw_rate=0.5)
    trajectory = time_parameterize(smoothed, limits, initial_yaw=0.0).trajectory
    state = trajectory.state_at(np.linspace(0.0, trajectory.duration_s, 4000))
    # Flying along +y the heading turns from 0 to pi/2 at 0.5 rad/s, then holds.
    assert np.abs(state.yaw_rate).max() <= 0.5 + 1e-12
    assert state.yaw[-1] == pytest.approx(np.pi / 2, abs=1e-9)
    assert state.yaw[0] == 0.0
    fixed = time_parameterize(smoothed, limits, yaw_mode='fixed', initial_yaw=1.0).trajectory
    assert np.allclose(fixed.state_at([0.0, 5.0, fixed.duration_s]).yaw, 1.0)


def test_single_point_and_invalid_limits_name_the_setting():
    smoothed = smooth_path([[1.0, 2.0, 3.0]], ObstacleSet(), 0.2, 0.5)
    trajectory = time_parameterize(smoothed, DEFAULTS).trajectory
    assert trajectory.times.tolist() == [0.0] and trajectory.duration_s == 0.0
    bad = (({'jerk': 0.0}, 'max_jerk'), ({'jerk': -1.0}, 'max_jerk'),
           ({'jerk': float('nan')}, 'max_jerk'), ({'tilt_deg': 90.0}, 'max_tilt'),
           ({'thrust_to_weight': 1.0}, 'max_thrust_to_weight'),
           ({'speed_horizontal': 0.0}, 'max_speed_horizontal'),
           ({'yaw_rate': float('inf')}, 'max_yaw_rate'))
    for change, name in bad:
        with pytest.raises(InvalidInputError, match=name):
            MotionLimits(**change)


def test_check_limits_reports_violations():
    smoothed = smooth_path(np.array([[0.0, 0.0, 1.0], [20.0, 0.0, 1.0]]), ObstacleSet(), 0.2,
                           0.5)
    trajectory = time_parameterize(smoothed, MotionLimits(4.0, 1.0, 2.0, 0.5)).trajectory
    problems = check_limits(trajectory, MotionLimits(3.0, 1.0, 1.0, 0.5, jerk=1.0))
    assert any('horizontal speed' in p for p in problems)
    assert any('horizontal acceleration' in p for p in problems)
    assert any(p.startswith('jerk') for p in problems)
