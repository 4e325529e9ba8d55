"""The smoothed curve as a function of arc length, and its output samples.

:class:`PathCurve` is the accepted chain of cubic pieces (splines and straight segments) that
:mod:`uav_global_planner.core.path.smoothing` returns, evaluated by arc length. The functions below
place the output samples on it (by arc length, or by knot parameter in ``'index'`` mode), give
arc lengths of points on it, and the unit tangents and curvature vectors (derivatives with
respect to arc length) at them.
"""

import math
from typing import List, Tuple

import numpy as np

from uav_global_planner.core.path.clearance import Pieces, SampleGrid
from uav_global_planner.core.path.piecewise import PiecewisePolynomial
from uav_global_planner.core.path.repair import Chain

# Output samples closer than this to a via-point are dropped in its favour [m].
_VIA_SAMPLE_GAP = 1e-6


class PathCurve:
    """The final continuous curve: a chain of cubic pieces, evaluated by arc length.

    An arc length is turned into a piece and a parameter on it (Newton steps on the same
    Gauss-Legendre arc lengths that label the samples); the point and its derivatives are then
    those of the chain as one :class:`~uav_global_planner.core.path.piecewise.PiecewisePolynomial`
    over the cumulative parameter.

    Attributes
    ----------
    length_m : float
        Arc length [m].
    piece_start_m : numpy.ndarray, shape (P + 1,)
        Arc length at the start of each piece, then the total length [m].
    stop_arc_length_m : numpy.ndarray
        Arc lengths of the points where the curve is not C2 (polyline corners, junctions) and
        the time parameterisation stops, the goal included, and the start unless the curve
        continues a motion [m].
    """

    def __init__(self, pieces: Pieces, iv_piece: np.ndarray, iv_ta: np.ndarray,
                 iv_tb: np.ndarray, iv_sa: np.ndarray, iv_sb: np.ndarray,
                 piece_start_m: np.ndarray, stop_arc_length_m: np.ndarray) -> None:
        self._pieces = pieces
        self._breaks = np.r_[0.0, np.cumsum(pieces.h)]
        self._chain = PiecewisePolynomial(pieces.coef, self._breaks)
        self._iv = (iv_piece, iv_ta, iv_tb, iv_sa, iv_sb)
        self.piece_start_m = piece_start_m
        self.length_m = float(piece_start_m[-1])
        self.stop_arc_length_m = stop_arc_length_m

    def _locate(self, s) -> Tuple[np.ndarray, np.ndarray]:
        iv_piece, iv_ta, iv_tb, iv_sa, iv_sb = self._iv
        target = np.clip(np.asarray(s, dtype=np.float64).ravel(), 0.0, self.length_m)
        j = np.clip(np.searchsorted(iv_sa, target, side='right') - 1, 0, len(iv_sa) - 1)
        span = iv_sb[j] - iv_sa[j]
        with np.errstate(divide='ignore', invalid='ignore'):
            frac = np.where(span > 0, (target - iv_sa[j]) / span, 0.0)
        frac = np.clip(frac, 0.0, 1.0)
        piece = iv_piece[j]
        tau = iv_ta[j] + (iv_tb[j] - iv_ta[j]) * frac
        # Newton steps on the arc length (the parameter speed may vary within an interval).
        for _ in range(4):
            reached = iv_sa[j] + self._pieces.speed_integral(piece, iv_ta[j], tau)
            speed = np.linalg.norm(self._pieces.first(piece, tau), axis=1)
            with np.errstate(divide='ignore', invalid='ignore'):
                correction = np.where(speed > 0, (target - reached) / speed, 0.0)
            tau = np.clip(tau + correction, iv_ta[j], iv_tb[j])
            if np.all(np.abs(correction) * speed <= 1e-13 * max(self.length_m, 1.0)):
                break
        return piece, tau

    def pieces_after(self, s: float) -> Pieces:
        """The cubic pieces that reach beyond arc length ``s`` [m] (all of them for s <= 0)."""
        keep = np.flatnonzero(self.piece_start_m[1:] >= s)
        if not len(keep):
            keep = np.array([len(self.piece_start_m) - 2])
        return Pieces(self._pieces.coef[:, keep, :], self._pieces.h[keep],
                      linear=self._pieces.linear)

    def _parameter(self, s) -> np.ndarray:
        """Chain parameter of the points at arc lengths ``s`` [m]."""
        piece, tau = self._locate(s)
        return self._breaks[piece] + tau

    def evaluate(self, s) -> np.ndarray:
        """Points of the curve at arc lengths ``s`` [m], shape (M, 3).

        The points lie exactly on the curve, at arc length ``s`` to rounding.
        """
        return self._chain(self._parameter(s))

    def derivatives(self, s) -> Tuple[np.ndarray, np.ndarray]:
        """Unit tangent dc/ds and curvature vector d2c/ds2 [1/m] at arc lengths ``s``.

        At a stop point the piece after it is used.
        """
        x = self._parameter(s)
        return arc_derivatives(self._chain(x, 1), self._chain(x, 2))

    def derivatives3(self, s) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Points and the first three derivatives with respect to arc length at ``s`` [m].

        Returns the point [m], the unit tangent dc/ds [-], the curvature vector d2c/ds2 [1/m]
        and its derivative d3c/ds3 [1/m^2], each shape (M, 3). At a stop point the piece after
        it is used.
        """
        x = self._parameter(s)
        d1, d2, d3 = self._chain(x, 1), self._chain(x, 2), self._chain(x, 3)
        sigma = np.linalg.norm(d1, axis=1)
        sigma = np.where(sigma > 0, sigma, np.nan)[:, None]
        # d/ds = (1/sigma) d/dx; sigma' and sigma'' are derivatives of |c'| in the parameter.
        dot12 = np.sum(d1 * d2, axis=1)[:, None]
        sigma1 = dot12 / sigma
        sigma2 = (np.sum(d2 * d2, axis=1)[:, None] + np.sum(d1 * d3, axis=1)[:, None]) / sigma \
            - dot12 ** 2 / sigma ** 3
        tangent = d1 / sigma
        normal = d2 / sigma ** 2 - d1 * sigma1 / sigma ** 3
        third = (d3 / sigma ** 3 - 3.0 * d2 * sigma1 / sigma ** 4 - d1 * sigma2 / sigma ** 4
                 + 3.0 * d1 * sigma1 ** 2 / sigma ** 5)
        return self._chain(x), tangent, normal, third

    def derivative_bounds(self, s_start: np.ndarray,
                          s_end: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """Upper bounds of ``|d2c/ds2|`` [1/m] and ``|d3c/ds3|`` [1/m^2] over each arc-length
        interval ``[s_start[i], s_end[i]]``, proved on the cubic pieces it covers.

        On a parameter range of a piece, ``|c'''|`` is constant, ``|c''|`` is largest at an end
        (it is linear) and ``|c'|`` is bounded below by its value at the middle less
        ``max|c''|`` times the half-width; with ``sigma = |c'|`` these bound every term of
        ``d2c/ds2 = c''/sigma^2 - c' sigma'/sigma^3`` and of its derivative
        (:meth:`derivatives3`). Ranges whose lower bound of ``sigma`` is poor are halved, up to
        :data:`_BOUND_SPLITS` times.
        """
        start = np.asarray(s_start, dtype=np.float64)
        end = np.asarray(s_end, dtype=np.float64)
        piece_a, tau_a = self._locate(start)
        piece_b, tau_b = self._locate(end)
        h = self._pieces.h
        rows = [np.arange(len(start))]
        pieces = [piece_a]
        t0 = [tau_a]
        t1 = [np.where(piece_b == piece_a, tau_b, h[piece_a])]
        # Intervals over a knot: the rest of the first piece above, then the pieces after it.
        for row in np.flatnonzero(piece_b > piece_a).tolist():
            for piece in range(int(piece_a[row]) + 1, int(piece_b[row]) + 1):
                rows.append(np.array([row]))
                pieces.append(np.array([piece]))
                t0.append(np.zeros(1))
                t1.append(np.array([tau_b[row] if piece == piece_b[row] else h[piece]]))
        owner = np.concatenate(rows)
        curvature, rate = _range_bounds(self._pieces.coef, np.concatenate(pieces),
                                        np.concatenate(t0), np.concatenate(t1), _BOUND_SPLITS)
        out_k = np.zeros(len(start))
        out_r = np.zeros(len(start))
        np.maximum.at(out_k, owner, curvature)
        np.maximum.at(out_r, owner, rate)
        return out_k, out_r


#: Halvings of a parameter range whose speed bound is poor (:meth:`PathCurve.derivative_bounds`).
_BOUND_SPLITS = 24
#: A range's speed bound is poor below this share of the speed at its middle.
_GOOD_SPEED_BOUND = 0.9


def _range_bounds(coef: np.ndarray, piece: np.ndarray, t0: np.ndarray, t1: np.ndarray,
                  splits: int) -> Tuple[np.ndarray, np.ndarray]:
    """Bounds of ``|d2c/ds2|`` and ``|d3c/ds3|`` on parameter ranges ``[t0, t1]`` of pieces."""
    c0, c1, c2 = coef[0, piece], coef[1, piece], coef[2, piece]
    third = np.linalg.norm(6.0 * c0, axis=1)
    second = np.maximum(np.linalg.norm(6.0 * c0 * t0[:, None] + 2.0 * c1, axis=1),
                        np.linalg.norm(6.0 * c0 * t1[:, None] + 2.0 * c1, axis=1))
    middle = 0.5 * (t0 + t1)
    half = 0.5 * np.abs(t1 - t0)
    speed = np.linalg.norm((3.0 * c0 * middle[:, None] + 2.0 * c1) * middle[:, None] + c2,
                           axis=1)
    low = speed - second * half
    poor = low <= _GOOD_SPEED_BOUND * speed
    if splits > 0 and poor.any():
        rows = np.flatnonzero(poor)
        count = len(rows)
        # Both halves in one call: the calls grow with the splits, not with 2^splits.
        halves = _range_bounds(coef, np.r_[piece[rows], piece[rows]],
                               np.r_[t0[rows], middle[rows]], np.r_[middle[rows], t1[rows]],
                               splits - 1)
        good_k, good_r = _bounds_of(second, third, np.where(poor, 1.0, low))
        good_k[rows] = np.maximum(halves[0][:count], halves[0][count:])
        good_r[rows] = np.maximum(halves[1][:count], halves[1][count:])
        return good_k, good_r
    # No better bound of the speed: the tiniest positive one (a cusp has no finite bound).
    return _bounds_of(second, third, np.maximum(low, 1e-9 * np.maximum(speed, 1e-9)))


def _bounds_of(second: np.ndarray, third: np.ndarray,
               low: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Bounds of ``|d2c/ds2|`` and ``|d3c/ds3|`` from the bounds of the parameter derivatives.

    ``second`` bounds ``|c''|``, ``third`` is ``|c'''|`` and ``low`` bounds ``sigma = |c'|``
    from below. With ``P`` the projection normal to the tangent ``T``,
    ``d2c/ds2 = P c'' / sigma^2``, so its norm is at most ``|c''| / sigma^2``; its derivative in
    the parameter is ``P' c'' / sigma^2 + P c''' / sigma^2 - 2 P c'' sigma' / sigma^3`` with
    ``|P'| <= 2 |dT/dt| <= 2 |c''| / sigma`` and ``|sigma'| <= |c''|``, and ``d/ds`` is
    ``1 / sigma`` times that: ``|d3c/ds3| <= |c'''| / sigma^3 + 4 |c''|^2 / sigma^4``.
    """
    with np.errstate(over='ignore'):
        curvature = second / low ** 2
        curvature_rate = third / low ** 3 + 4.0 * second ** 2 / low ** 4
    return curvature, curvature_rate


def arc_derivatives(d1: np.ndarray, d2: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Tangent and curvature vector w.r.t. arc length from parameter derivatives."""
    speed = np.linalg.norm(d1, axis=1)
    speed = np.where(speed > 0, speed, np.nan)
    tangent = d1 / speed[:, None]
    along = np.sum(d2 * tangent, axis=1)
    normal = (d2 - along[:, None] * tangent) / (speed ** 2)[:, None]
    return tangent, normal


def span_samples(chain: Chain, grid: SampleGrid, mode: str, spacing: float, step: float,
                 via_sigma: np.ndarray) -> Tuple[List[np.ndarray], List[np.ndarray]]:
    """Output samples of every span as (piece, tau) arrays, both span ends included.

    Knots at ``via_sigma`` (polyline arc lengths of via-points) are samples too, so the sampled
    path passes through every via-point exactly.
    """
    pieces = chain.pieces
    out_piece, out_tau = [], []
    ia = np.flatnonzero(grid.first)
    bounds = np.flatnonzero(np.r_[True, chain.span[1:] != chain.span[:-1], True])
    for first, stop in zip(bounds[:-1], bounds[1:]):
        p0, p1 = int(first), int(stop) - 1
        if mode == 'index' and not chain.line[p0]:
            knots = p1 - p0 + 2
            # Parameter = knot number, in steps of index_step, the last knot exactly.
            count = int(math.ceil((knots - 1) / step - 1e-9))
            t = np.minimum(np.arange(count + 1) * step, knots - 1.0)
            t[-1] = knots - 1.0
            local = np.minimum(np.floor(t), knots - 2).astype(np.int64)
            piece = p0 + local
            tau = (t - local) * pieces.h[piece]
        elif mode == 'index':
            count = max(2, int(math.ceil(1.0 / step - 1e-9)))
            piece = np.full(count + 1, p0)
            tau = pieces.h[p0] * np.arange(count + 1) / count
        else:
            # Arc length: evenly spaced targets located in the span's verification intervals.
            span_iv = ia[(grid.piece[ia] >= p0) & (grid.piece[ia] <= p1)]
            sa, sb = grid.s[span_iv], grid.s[span_iv + 1]
            start, end = sa[0], sb[-1]
            count = max(2, int(math.ceil((end - start) / spacing - 1e-9)))
            target = start + (end - start) * np.arange(1, count) / count
            j = np.clip(np.searchsorted(sa, target, side='right') - 1, 0, len(sa) - 1)
            frac = np.clip((target - sa[j]) / (sb[j] - sa[j]), 0.0, 1.0)
            ta, tb = grid.tau[span_iv[j]], grid.tau[span_iv[j] + 1]
            piece = np.r_[p0, grid.piece[span_iv[j]], p1]
            tau = np.r_[0.0, ta + (tb - ta) * frac, pieces.h[p1]]
            vias = np.arange(p0 + 1, p1 + 1)
            vias = vias[np.isin(chain.sig[vias, 0], via_sigma)]
            if len(vias):
                # Targets within a micrometre of a via-point would make a zero-length step.
                via_s = grid.s[np.flatnonzero(grid.first & (grid.tau == 0.0))][vias]
                near = np.any(np.abs(target[:, None] - via_s[None, :]) < _VIA_SAMPLE_GAP, axis=1)
                keep = np.r_[True, ~near, True]
                piece = np.r_[piece[keep], vias]
                tau = np.r_[tau[keep], np.zeros(len(vias))]
                order = np.lexsort((tau, piece))
                piece, tau = piece[order], tau[order]
        out_piece.append(piece)
        out_tau.append(tau)
    return out_piece, out_tau


def arc_length_at(pieces: Pieces, grid: SampleGrid, piece: np.ndarray,
                  tau: np.ndarray) -> np.ndarray:
    """Arc length of points (piece, tau) [m], from the nearest verification sample below."""
    ia = np.flatnonzero(grid.first)
    key_grid = grid.piece[ia] + grid.tau[ia] / pieces.h[grid.piece[ia]]
    key = piece + tau / pieces.h[piece]
    j = np.clip(np.searchsorted(key_grid, key, side='right') - 1, 0, len(ia) - 1)
    # A point at tau = h of its piece must integrate on its own piece, not the next one.
    own = grid.piece[ia[j]] != piece
    while own.any():
        j[own] -= 1
        own = grid.piece[ia[j]] != piece
    base = ia[j]
    return grid.s[base] + pieces.speed_integral(piece, grid.tau[base], tau)


def _components(vectors: np.ndarray) -> np.ndarray:
    """Horizontal norm and vertical magnitude of each row, shape (M, 2)."""
    return np.stack([np.hypot(vectors[:, 0], vectors[:, 1]), np.abs(vectors[:, 2])], axis=1)


def interval_maxima(pieces: Pieces, grid: SampleGrid, arc: np.ndarray, tangent_in: np.ndarray,
                    tangent_out: np.ndarray,
                    curvature: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Largest horizontal and vertical tangent and curvature components over each interval.

    Taken over the interval's two ends (one-sided at stop points) and every verification sample
    strictly inside it (spacing <= max(delta / 20, 5 mm)).
    """
    tangent_max = np.maximum(_components(tangent_out[:-1]), _components(tangent_in[1:]))
    curvature_max = np.maximum(_components(curvature[:-1]), _components(curvature[1:]))
    j = np.searchsorted(arc, grid.s, side='right') - 1
    inside = (j >= 0) & (j < len(arc) - 1)
    inside[inside] &= (grid.s[inside] > arc[j[inside]]) & (grid.s[inside] < arc[j[inside] + 1])
    if inside.any():
        t, k = arc_derivatives(pieces.first(grid.piece[inside], grid.tau[inside]),
                               pieces.second(grid.piece[inside], grid.tau[inside]))
        np.maximum.at(tangent_max, j[inside], _components(t))
        np.maximum.at(curvature_max, j[inside], _components(k))
    return tangent_max, curvature_max
