"""Piecewise polynomials and the not-a-knot cubic splines of the smoothing.

The curve, the time parameterisation and the repair need a few operations on piecewise
polynomials: evaluation with derivatives, the derivative and the antiderivative of a chain, the
stationary points of cubic pieces, and the C2 cubic spline through knots (not-a-knot ends, or a
given first derivative at the start). ``scipy.interpolate`` has them all, but importing it pulls
in ``scipy.special``, ``scipy.optimize`` and ``scipy.linalg``: about 0.7 s of every command that
plans. This module holds the same operations on the same layout, in numpy and one compiled
tridiagonal solve.

The layout is that of :class:`scipy.interpolate.PPoly`: coefficients ``c`` of shape
``(k + 1, m, ...)``, highest power first, over the breaks ``x`` of shape ``(m + 1,)``; piece
``i`` is a polynomial in ``t - x[i]`` and holds on ``[x[i], x[i + 1])`` (the last piece also at
its end, and the end pieces extend beyond the breaks). A point is evaluated term by term in
increasing powers, as scipy sums it, so that the values agree with scipy's to the last bit
(``test/test_piecewise.py`` checks both against scipy).
"""

from typing import Any, Optional, Tuple

import numpy as np

from uav_global_planner.core.jit import njit


class PiecewisePolynomial:
    """A piecewise polynomial over increasing breaks, extrapolated by its end pieces.

    Parameters
    ----------
    c : numpy.ndarray, shape (k + 1, m, ...)
        Coefficients, highest power first; trailing axes are the value's (for example the
        three axes of a curve point).
    x : numpy.ndarray, shape (m + 1,)
        Breaks, increasing.
    """

    def __init__(self, c: np.ndarray, x: np.ndarray) -> None:
        self.c = np.asarray(c, dtype=np.float64)
        self.x = np.asarray(x, dtype=np.float64)
        if self.c.ndim < 2 or self.x.ndim != 1 or self.c.shape[1] + 1 != self.x.shape[0]:
            raise ValueError(f'coefficients of shape {self.c.shape} do not fit '
                             f'{self.x.shape[0]} breaks')

    def __call__(self, t: Any, nu: int = 0) -> np.ndarray:
        """The ``nu``-th derivative at ``t``: shape ``t.shape + c.shape[2:]``.

        Parameters
        ----------
        t : array_like
            Where [units of the breaks].
        nu : int
            Order of the derivative, >= 0.
        """
        t = np.asarray(t, dtype=np.float64)
        flat = t.reshape(-1)
        trailing = self.c.shape[2:]
        piece = np.clip(np.searchsorted(self.x, flat, side='right') - 1, 0,
                        self.c.shape[1] - 1)
        local = (flat - self.x[piece]).reshape((-1,) + (1,) * len(trailing))
        order = self.c.shape[0]
        total = np.zeros((flat.shape[0],) + trailing)
        power = np.ones_like(local)
        for kp in range(nu, order):
            factor = 1.0
            for k in range(kp, kp - nu, -1):
                factor *= k
            total = total + self.c[order - kp - 1, piece] * power * factor
            if kp < order - 1:
                power = power * local
        return total.reshape(t.shape + trailing)

    def derivative(self) -> 'PiecewisePolynomial':
        """The first derivative (one order lower; a constant's is zero)."""
        order = self.c.shape[0]
        if order == 1:
            return PiecewisePolynomial(np.zeros_like(self.c), self.x)
        factors = np.arange(order - 1, 0, -1, dtype=np.float64)
        return PiecewisePolynomial(
            self.c[:-1] * factors.reshape((-1,) + (1,) * (self.c.ndim - 1)), self.x)

    def antiderivative(self) -> 'PiecewisePolynomial':
        """The antiderivative that is 0 at ``x[0]`` and continuous at every break."""
        order = self.c.shape[0]
        c = np.zeros((order + 1,) + self.c.shape[1:])
        factors = np.arange(order, 0, -1, dtype=np.float64)
        c[:-1] = self.c / factors.reshape((-1,) + (1,) * (self.c.ndim - 1))
        # Each piece starts where the one before ends: the rise of every piece over its
        # length, summed.
        h = np.diff(self.x).reshape((-1,) + (1,) * (self.c.ndim - 2))
        rise = np.zeros(c.shape[1:])
        power = np.ones_like(h)
        for kp in range(1, order + 1):
            power = power * h
            rise = rise + c[order - kp] * power
        c[-1, 1:] = np.cumsum(rise[:-1], axis=0)
        return PiecewisePolynomial(c, self.x)


def cubic_spline(t: np.ndarray, y: np.ndarray,
                 start_derivative: Optional[np.ndarray] = None) -> np.ndarray:
    """Coefficients of the C2 cubic spline through ``y`` at ``t``.

    Both ends are not-a-knot (the first two and the last two pieces are one cubic each), or the
    start has the first derivative ``start_derivative``: :class:`scipy.interpolate.CubicSpline`
    with ``bc_type='not-a-knot'`` or ``((1, start_derivative), 'not-a-knot')``. Two knots give
    the straight line (or, with a start derivative, the parabola), three not-a-knot knots the
    parabola through them.

    Parameters
    ----------
    t : numpy.ndarray, shape (n,)
        Strictly increasing knot parameters, n >= 2.
    y : numpy.ndarray, shape (n,) or (n, d)
        Values at the knots.
    start_derivative : numpy.ndarray, shape () or (d,), optional
        dy/dt at ``t[0]``.

    Returns
    -------
    numpy.ndarray, shape (4, n - 1) or (4, n - 1, d)
        Coefficients in the layout of :class:`PiecewisePolynomial` (highest power first).
    """
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n = t.shape[0]
    if n < 2 or y.shape[0] != n:
        raise ValueError(f'{n} knots and {y.shape[0]} values: a spline needs two or more of each')
    values = y.reshape(n, -1)
    dx = np.diff(t)
    dxr = dx[:, None]
    slope = np.diff(values, axis=0) / dxr
    start = (None if start_derivative is None
             else np.broadcast_to(np.asarray(start_derivative, dtype=np.float64),
                                  values.shape[1:]))
    lower = np.zeros(n)
    diag = np.zeros(n)
    upper = np.zeros(n)
    rhs = np.empty_like(values)
    if n == 2:
        # Not-a-knot on two knots is a convention: the end derivative is the chord's.
        diag[:] = 1.0
        rhs[0] = slope[0] if start is None else start
        rhs[1] = slope[0]
    elif n == 3 and start is None:
        # Both ends not-a-knot on three knots: the parabola through them.
        diag[0], upper[0] = 1.0, 1.0
        lower[1], diag[1], upper[1] = dx[1], 2.0 * (dx[0] + dx[1]), dx[0]
        lower[2], diag[2] = 1.0, 1.0
        rhs[0] = 2.0 * slope[0]
        rhs[1] = 3.0 * (dxr[0] * slope[1] + dxr[1] * slope[0])
        rhs[2] = 2.0 * slope[1]
    else:
        diag[1:-1] = 2.0 * (dx[:-1] + dx[1:])
        upper[1:-1] = dx[:-1]
        lower[1:-1] = dx[1:]
        rhs[1:-1] = 3.0 * (dxr[1:] * slope[:-1] + dxr[:-1] * slope[1:])
        if start is None:
            d = t[2] - t[0]
            diag[0], upper[0] = dx[1], d
            rhs[0] = ((dxr[0] + 2.0 * d) * dxr[1] * slope[0] + dxr[0] ** 2 * slope[1]) / d
        else:
            diag[0] = 1.0
            rhs[0] = start
        d = t[-1] - t[-3]
        diag[-1], lower[-1] = dx[-2], d
        rhs[-1] = (dxr[-1] ** 2 * slope[-2] + (2.0 * d + dxr[-1]) * dxr[-2] * slope[-1]) / d
    derivatives = np.empty_like(values)
    _tridiagonal_solve(lower, diag, upper, np.ascontiguousarray(rhs), derivatives)
    return _hermite_coefficients(dxr, values, slope, derivatives).reshape(
        (4, n - 1) + y.shape[1:])


def _hermite_coefficients(dxr: np.ndarray, values: np.ndarray, slope: np.ndarray,
                          derivatives: np.ndarray) -> np.ndarray:
    """The cubic pieces with the given values and first derivatives at the knots."""
    t = (derivatives[:-1] + derivatives[1:] - 2.0 * slope) / dxr
    c = np.empty((4,) + slope.shape)
    c[0] = t / dxr
    c[1] = (slope - derivatives[:-1]) / dxr - t
    c[2] = derivatives[:-1]
    c[3] = values[:-1]
    return c


@njit
def _tridiagonal_solve(lower, diag, upper, rhs, out):  # pragma: no cover - compiled
    """Solve the tridiagonal system (row i: lower[i] x[i-1] + diag[i] x[i] + upper[i] x[i+1])
    for each column of ``rhs``, into ``out`` (Gaussian elimination down, substitution up)."""
    n = diag.shape[0]
    pivot = np.empty(n)
    work = rhs.copy()
    pivot[0] = diag[0]
    for i in range(1, n):
        m = lower[i] / pivot[i - 1]
        pivot[i] = diag[i] - m * upper[i - 1]
        for j in range(work.shape[1]):
            work[i, j] -= m * work[i - 1, j]
    for j in range(work.shape[1]):
        out[n - 1, j] = work[n - 1, j] / pivot[n - 1]
    for i in range(n - 2, -1, -1):
        for j in range(work.shape[1]):
            out[i, j] = (work[i, j] - upper[i] * out[i + 1, j]) / pivot[i]


def stationary_points(coef: np.ndarray, breaks: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Where cubic pieces have a zero first derivative, per axis, inside their pieces.

    Parameters
    ----------
    coef : numpy.ndarray, shape (4, m, d)
        Cubic pieces (highest power first) over ``breaks``.
    breaks : numpy.ndarray, shape (m + 1,)

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        The parameters (on the chain, within the pieces' spans) and the axis of each. The
        roots of each piece's quadratic derivative come from the cancellation-free formula, so
        the stationary point of a parabola whose cubic coefficient is rounding noise is found.
        An axis constant on a piece has none (its ends are its extrema).
    """
    a = 3.0 * coef[0]
    b = 2.0 * coef[1]
    c = coef[2]
    h = np.diff(breaks)[:, None]
    found_t, found_axis = [], []
    with np.errstate(divide='ignore', invalid='ignore'):
        disc = b * b - 4.0 * a * c
        root = np.sqrt(np.where(disc >= 0.0, disc, 0.0))
        q = -0.5 * (b + np.where(b >= 0.0, root, -root))
        quadratic = (a != 0.0) & (disc >= 0.0)
        candidates = [np.where(quadratic, q / a, np.nan), np.where(quadratic, c / q, np.nan),
                      np.where((a == 0.0) & (b != 0.0), -c / b, np.nan)]
    for local in candidates:
        inside = np.isfinite(local) & (local >= 0.0) & (local <= h)
        piece, axis = np.nonzero(inside)
        found_t.append(breaks[piece] + local[piece, axis])
        found_axis.append(axis)
    return np.concatenate(found_t), np.concatenate(found_axis)
