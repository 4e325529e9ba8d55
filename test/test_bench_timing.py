"""The timing benchmark's pieces on small curves: copp's reference is itself within the limits,
and ours is not faster than the optimum that copp finds (which would mean a broken limit)."""

import importlib.util
import math
import sys
from types import ModuleType

import numpy as np
import pytest

from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.path.smoothing import smooth_path

pytest.importorskip('copp_py')

# Discretisation: copp keeps its rows at its stations only, and the flight times of two
# discretisations of the same problem differ by a little [-].
TOLERANCE = 0.02


@pytest.fixture(scope='module')
def bench(repo_root) -> ModuleType:
    """benchmarks/bench_timing.py as a module (benchmarks/ is not a package)."""
    spec = importlib.util.spec_from_file_location('bench_timing',
                                                  repo_root / 'benchmarks' / 'bench_timing.py')
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules['bench_timing'] = module
    spec.loader.exec_module(module)
    return module


def within(peaks, limits, jerk_factor: float = 1.0, accel_factor: float = 1.0) -> None:
    """Peaks within the limits (the norm ones times a factor) up to the tolerance."""
    slack = 1.0 + TOLERANCE
    assert peaks.speed_horizontal <= limits.speed_horizontal * slack, peaks
    assert peaks.speed_vertical <= limits.speed_vertical * slack, peaks
    assert peaks.accel_horizontal <= limits.accel_horizontal * accel_factor * slack, peaks
    assert peaks.accel_vertical <= limits.accel_vertical * slack, peaks
    assert peaks.jerk <= limits.jerk * jerk_factor * slack, peaks


def test_copp_matches_the_closed_form_on_a_straight_line(bench):
    # Rest to rest over L with v, A, J (v >= A^2 / J, L long enough to cruise): the optimum is
    # L / v + v / A + A / J. The line runs along x, a facet direction of both polytopes.
    limits = bench.DEFAULT_LIMITS
    line = smooth_path(np.array([[0.0, 0.0, 2.0], [20.0, 0.0, 2.0]]), ObstacleSet(), 0.2, 0.5)
    expected = (20.0 / limits.speed_horizontal + limits.speed_horizontal
                / limits.accel_horizontal + limits.accel_horizontal / limits.jerk)
    reference = bench.copp_reference(line.curve, limits, bench.make_facets(), False, 0.1)
    assert reference.duration_s == pytest.approx(expected, rel=2e-3)
    within(bench.copp_peaks(line.curve, reference), limits)
    # Without the jerk limit the ramps take no time.
    assert reference.second_order_s == pytest.approx(expected - limits.accel_horizontal
                                                     / limits.jerk, rel=2e-3)


@pytest.mark.parametrize('limits_name', ['default', '8 m/s'])
def test_copp_reference_keeps_the_limits_and_ours_is_not_faster(bench, limits_name):
    limits = {entry.name: entry for entry in bench.LIMIT_SETS}[limits_name]
    smoothed = bench.random_curve(8, seed=3)
    assert bench.piece_count(smoothed.curve) == 8
    curve = smoothed.curve
    facets = bench.make_facets()
    outer = bench.copp_reference(curve, limits, facets, False, 0.1)
    inner = bench.copp_reference(curve, limits, facets, True, 0.1)
    assert outer.exceed <= 1e-6 and inner.exceed <= 1e-6
    # The inner polytopes lie inside the norm limits: copp's profile keeps them between its
    # stations too. The outer ones reach 1 / inner factor beyond them.
    within(bench.copp_peaks(curve, inner), limits)
    within(bench.copp_peaks(curve, outer), limits, 1.0 / facets.jerk_inner,
           1.0 / facets.horizontal_inner)
    assert inner.duration_s >= outer.duration_s * (1.0 - 1e-3)
    feasible = bench.feasible_duration(curve, outer, limits)
    assert outer.duration_s <= feasible <= outer.duration_s * (1.0 + 3.0 * TOLERANCE)

    trajectory = bench.timing_call(limits)(smoothed)
    # The jerk-limited optimum bounds a jerk-limited reference; the optimum without the jerk
    # limit bounds any reference within the speed and acceleration limits.
    bound = outer.duration_s if bench.jerk_limited() else outer.second_order_s
    assert trajectory.duration_s >= bound * (1.0 - TOLERANCE)
    peaks, exact = bench.trajectory_peaks(trajectory)
    assert math.isfinite(peaks.jerk) and peaks.accel_horizontal > 0.0
    if exact:
        within(peaks, limits)


def test_random_curves_have_the_piece_count_asked_for(bench):
    for pieces in (1, 5, 12):
        smoothed = bench.random_curve(pieces, seed=pieces)
        assert bench.piece_count(smoothed.curve) == pieces
        assert smoothed.certified_clearance_m >= 0.2


def test_the_timing_call_takes_the_limits_asked_for(bench):
    smoothed = bench.random_curve(3, seed=1)
    slow = bench.timing_call(bench.DEFAULT_LIMITS)(smoothed)
    fast = bench.timing_call(bench.FAST_LIMITS)(smoothed)
    assert fast.duration_s < slow.duration_s
    peaks, _ = bench.trajectory_peaks(fast)
    assert peaks.accel_horizontal > bench.DEFAULT_LIMITS.accel_horizontal
    first, median, runs = bench.wall_time(smoothed, bench.timing_call(bench.DEFAULT_LIMITS),
                                          budget_s=0.05)
    assert first > 0.0 and median > 0.0 and runs >= 3
