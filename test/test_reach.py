"""Minima over the reach of each interval (the timing's window): the compiled loops against
the definitions, written out pair by pair."""

import numpy as np

from uav_global_planner.core.path.reach import (MinTable, REACH_LEVELS, reach_min,
                                                REACH_RATIO, self_reach_min)


def stations(rng: np.random.Generator, count: int) -> np.ndarray:
    """Arc lengths [m] with intervals from micrometres to decimetres."""
    return np.r_[0.0, np.cumsum(10.0 ** rng.uniform(-6.0, -1.0, count))]


def gaps(s: np.ndarray) -> np.ndarray:
    """Arc length between every two intervals (0 for an interval and itself) [m]."""
    lo, hi = s[:-1], s[1:]
    return np.maximum(np.maximum(lo[:, None] - hi[None, :], lo[None, :] - hi[:, None]), 0.0)


def test_self_reach_keeps_every_cap_within_its_reach_and_is_nearly_the_largest():
    rng = np.random.default_rng(5)
    for count in (1, 2, 7, 60, 300):
        s = stations(rng, count)
        caps = rng.uniform(0.01, 3.0, count)
        tau = float(rng.uniform(0.01, 0.5))
        c = self_reach_min(s, caps, tau)
        between = gaps(s)
        for i in range(count):
            reach = between[i] < tau * c[i]
            assert reach[i] and c[i] <= caps[reach].min()
            # A slightly larger cap would break it (the bisection ends within 2^-24 of the
            # interval's own cap).
            larger = c[i] + caps[i] * 2.0 ** -23
            assert larger > caps[between[i] < tau * larger].min() or c[i] == caps[i]


def test_reach_takes_the_smallest_value_of_every_interval_that_reaches():
    rng = np.random.default_rng(6)
    for count in (1, 3, 40, 250):
        s = stations(rng, count)
        values = rng.uniform(0.1, 5.0, count)
        radius = rng.uniform(0.0, 0.3, count) * rng.integers(0, 2, count)
        out = reach_min(s, values, radius)
        between = gaps(s)
        # Every interval j that reaches i counts (exactly, or rounded up one level: the
        # lowest level for the shortest radii).
        lowest = radius.max() * REACH_RATIO ** (REACH_LEVELS - 1)
        for i in range(count):
            exact = (between[:, i] < radius) | (np.arange(count) == i)
            wider = ((between[:, i] < np.maximum(radius / REACH_RATIO, lowest))
                     | (np.arange(count) == i))
            assert out[i] <= values[exact].min()
            assert out[i] >= values[wider].min()


def test_min_table_answers_every_range():
    rng = np.random.default_rng(7)
    values = rng.normal(size=37)
    table = MinTable(values)
    lo, hi = np.triu_indices(len(values))
    assert np.array_equal(table.query(lo, hi),
                          [values[a:b + 1].min() for a, b in zip(lo, hi)])
