"""The piecewise polynomials and splines of core/path/piecewise.py against scipy.interpolate's."""

import numpy as np
import pytest
from scipy.interpolate import CubicSpline, PPoly

from uav_global_planner.core.path.piecewise import (cubic_spline, PiecewisePolynomial,
                                                    stationary_points)


def knots(rng: np.random.Generator, n: int) -> np.ndarray:
    return np.cumsum(np.r_[rng.uniform(-5.0, 5.0), rng.uniform(0.05, 3.0, n - 1)])


@pytest.mark.parametrize('n', [2, 3, 4, 5, 17, 200])
@pytest.mark.parametrize('start', [False, True])
def test_cubic_spline_is_scipys(n, start):
    rng = np.random.default_rng(n + 1000 * start)
    t = knots(rng, n)
    y = rng.uniform(-50.0, 50.0, (n, 3))
    first = rng.uniform(-3.0, 3.0, 3)
    ours = cubic_spline(t, y, first if start else None)
    bc = ((1, first), 'not-a-knot') if start else 'not-a-knot'
    theirs = CubicSpline(t, y, bc_type=bc).c
    assert ours.shape == theirs.shape == (4, n - 1, 3)
    scale = np.abs(theirs).max(axis=(1, 2), keepdims=True) + 1.0
    assert np.all(np.abs(ours - theirs) <= 1e-11 * scale)
    # Through every knot, C2 inside, the start derivative held.
    curve = PiecewisePolynomial(ours, t)
    assert np.allclose(curve(t), y, rtol=0.0, atol=1e-9)
    for nu in (1, 2):
        left = curve(t[1:-1] - 1e-9, nu)
        assert np.allclose(left, curve(t[1:-1], nu), rtol=1e-5, atol=1e-5)
    if start:
        assert np.allclose(curve(t[0], 1), first, rtol=0.0, atol=1e-9)


def test_a_one_dimensional_spline_and_bad_knots():
    t = np.array([0.0, 1.0, 2.5, 4.0])
    y = np.array([0.0, 1.0, 0.0, 2.0])
    assert np.allclose(cubic_spline(t, y), CubicSpline(t, y).c, rtol=0.0, atol=1e-12)
    assert np.allclose(cubic_spline(t, y, np.zeros(())),
                       CubicSpline(t, y, bc_type=((1, 0.0), 'not-a-knot')).c, rtol=0.0,
                       atol=1e-12)
    with pytest.raises(ValueError, match='two or more'):
        cubic_spline(t[:1], y[:1])
    with pytest.raises(ValueError, match='do not fit'):
        PiecewisePolynomial(np.zeros((4, 3)), t[:3])


@pytest.mark.parametrize('order', [1, 3, 4])
def test_values_derivatives_and_antiderivative_are_scipys(order):
    rng = np.random.default_rng(order)
    x = knots(rng, 40)
    c = rng.uniform(-2.0, 2.0, (order, 39, 2))
    ours = PiecewisePolynomial(c, x)
    theirs = PPoly(c, x, extrapolate=True)
    # Inside, on the breaks, and beyond both ends (extrapolated by the end pieces).
    t = np.r_[np.linspace(x[0] - 1.0, x[-1] + 1.0, 3001), x]
    for nu in range(order + 1):
        assert np.array_equal(ours(t, nu), theirs(t, nu)), nu
    assert np.array_equal(ours.derivative()(t), theirs.derivative()(t))
    integral, reference = ours.antiderivative(), theirs.antiderivative()
    assert integral.c.shape == reference.c.shape
    assert np.allclose(integral(t), reference(t), rtol=1e-12, atol=1e-9)
    assert np.allclose(integral(x), reference(x), rtol=1e-12, atol=1e-9)
    assert ours(np.float64(x[3])).shape == (2,)


def test_stationary_points_are_every_extremum_inside_the_pieces():
    rng = np.random.default_rng(7)
    x = knots(rng, 30)
    c = rng.uniform(-2.0, 2.0, (4, 29, 3))
    c[0, 5] = 1e-19            # a parabola with rounding noise for its cubic term
    c[:3, 6, 1] = 0.0          # constant on a piece
    c[0, 7, 2] = 0.0           # a parabola
    c[:2, 8, 0] = 0.0          # a line
    roots, axes = stationary_points(c, x)
    chain = PiecewisePolynomial(c, x)
    slopes = chain(roots, 1)[np.arange(len(roots)), axes]
    scale = np.abs(c[2]).max()
    assert np.all(np.abs(slopes) <= 1e-9 * scale)
    theirs = PPoly(c, x).derivative().roots(discontinuity=False, extrapolate=False)
    for axis in range(3):
        expected = theirs[axis][np.isfinite(theirs[axis])]
        mine = np.sort(roots[axes == axis])
        # scipy lists the start of a constant piece; ours has no point there (a break).
        for root in expected:
            assert np.min(np.abs(mine - root)) <= 1e-9 or np.min(np.abs(x - root)) <= 1e-12
        assert len(mine) <= len(expected) + 1
    # The noisy parabola's vertex is found.
    vertex = x[5] - c[2, 5] / (2.0 * c[1, 5])
    inside = (vertex > x[5]) & (vertex < x[6])
    for axis in np.flatnonzero(inside):
        assert np.min(np.abs(roots[axes == axis] - vertex[axis])) <= 1e-9
