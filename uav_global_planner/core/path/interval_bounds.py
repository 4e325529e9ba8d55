"""The bounds of the time parameterisation per interval of the curve (its stations).

Step 1 of :mod:`uav_global_planner.core.path.timing`: between two stations (at first the curve's
samples), :class:`Stations` holds the largest tangent and curvature components, the largest
curvature and curvature rate, and the user's speed cap; :meth:`Stations.bounds` turns them into
the speed cap, the tangential acceleration bound and the tangential jerk allowance that prove
the limits for every speed below the cap.

An interval takes the bounds of the sharpest point in it. Where the curve turns back on itself
within micrometres (a near-cusp: a moving start whose goal lies behind it, the spline bending
back after the lead-in) that point's cap ``sqrt(A / |K|)``, a millimetre per second, would hold
over the whole 0.1 m interval, and the reference would crawl along it for minutes.
:meth:`Stations.refined` therefore cuts such intervals into quarters, each bounded on its own
(the proved curvature bounds of :meth:`~uav_global_planner.core.path.curve.PathCurve.
derivative_bounds` over the quarter), for as long as that shortens their crossing: the slow
part shrinks to the micrometres around the near-cusp, which the reference passes in one to
three seconds at the default limits, within every limit. (At a true cusp, where the curve's
parameter speed vanishes and no bound holds, quarters stop at :data:`_SPLIT_MIN_M` and the last
ones are crawled through in :data:`_CRAWL_CROSS_S` each.)

:meth:`Stations.bounds` is one compiled loop over the intervals
(:mod:`uav_global_planner.core.jit`; the same source is the pure-Python fallback): the
refinement asks for it after every cut.
"""

from dataclasses import dataclass
import math
from typing import Optional, Tuple

import numpy as np

from uav_global_planner.core.jit import njit
from uav_global_planner.core.path.curve import PathCurve
from uav_global_planner.core.path.motion_limits import MotionLimits
from uav_global_planner.core.path.smoothing import SmoothedPath

#: Share of an acceleration limit kept for tangential acceleration where the centripetal
#: term takes the rest, and the smallest share of its tangential acceleration bound that a
#: bend's jerk terms may take away before its speed is lowered [-].
MIN_ALPHA_SHARE = 0.35

#: Share of an acceleration limit that the centripetal term leaves to tangential
#: acceleration in the tightest bends [-].
TANGENTIAL_RESERVE = 0.35

#: The slowest speed cap [m/s]: only a cusp of the curve gets it ...
_CRAWL = 1e-3
#: ... or, on an interval too short to take this long at that speed, the speed that crosses it
#: in this time [s].
_CRAWL_CROSS_S = 0.5

#: Cutting of the intervals where the curve holds the speed down (:meth:`Stations.refined`):
#: an interval is cut into quarters when crossing it at its cap takes longer than this [s] ...
_SPLIT_TIME_S = 0.02
#: ... and its quarters cross in at most this share of its time [-] ...
_SPLIT_GAIN = 0.75
#: ... at most this many times in a row ...
_SPLIT_DEPTH = 40
#: ... into quarters no shorter than this [m] (at a true cusp, whose curvature has no bound,
#: the cutting would go on without end; the last quarters are crawled through, each in at most
#: _CRAWL_CROSS_S) ...
_SPLIT_MIN_M = 1e-6
#: ... adding at most this many stations.
_SPLIT_STATIONS = 4096


@dataclass
class Stations:
    """Arc lengths of the profile's stations and the curve's maxima over each interval."""

    s: np.ndarray            # (n,) [m]
    stop: np.ndarray         # (n,) bool: the speed is zero there
    tangent: np.ndarray      # (n - 1, 2) largest |T_h|, |T_z|
    curvature: np.ndarray    # (n - 1, 2) largest |K_h|, |K_z| [1/m]
    curvature_norm: np.ndarray   # (n - 1,) largest |K| [1/m]
    curvature_rate: np.ndarray   # (n - 1,) largest |K'| [1/m^2]
    user_cap: np.ndarray     # (n - 1,) [m/s]

    @classmethod
    def of(cls, smoothed: SmoothedPath, speed_cap: Optional[np.ndarray]) -> 'Stations':
        s = np.asarray(smoothed.arc_length, dtype=np.float64)
        stop = np.zeros(len(s), dtype=bool)
        stop[np.asarray(smoothed.stop_points, dtype=np.int64)] = True
        tangent = np.asarray(smoothed.interval_tangent_max, dtype=np.float64)
        curvature = np.asarray(smoothed.interval_curvature_max, dtype=np.float64)
        if speed_cap is None:
            user = np.full(len(s) - 1, np.inf)
        else:
            at = np.asarray(speed_cap, dtype=np.float64).reshape(-1)
            user = np.minimum(at[:-1], at[1:])
        # An interval between two stops gets a station in its middle, where the profile
        # turns from accelerating to braking.
        both = np.flatnonzero(stop[:-1] & stop[1:])
        if len(both):
            s = np.insert(s, both + 1, 0.5 * (s[both] + s[both + 1]))
            stop = np.insert(stop, both + 1, False)
            tangent = np.insert(tangent, both, tangent[both], axis=0)
            curvature = np.insert(curvature, both, curvature[both], axis=0)
            user = np.insert(user, both, user[both])
        ds = np.diff(s)
        # |K'| is proved per interval on the cubic pieces; |K| and its components are the
        # curve's verification-sample maxima widened by |K'| times half the interval (every
        # point of it is that close to a sample), within the proved |K|; the tangent
        # components likewise by |K|.
        proved_k, rate_max = smoothed.curve.derivative_bounds(s[:-1], s[1:])
        half = 0.5 * ds
        curvature_norm = np.minimum(np.hypot(curvature[:, 0], curvature[:, 1])
                                    + rate_max * half, proved_k)
        curvature = np.minimum(curvature + (rate_max * half)[:, None], proved_k[:, None])
        tangent = np.minimum(tangent + (curvature_norm * half)[:, None], 1.0)
        return cls(s=s, stop=stop, tangent=tangent, curvature=curvature,
                   curvature_norm=curvature_norm, curvature_rate=rate_max,
                   user_cap=user)

    def refined(self, curve: PathCurve, limits: MotionLimits, accel_h: float,
                accel_z: float) -> 'Stations':
        """These stations, with the intervals where the curve holds the speed down cut into
        quarters as long as that pays.

        An interval takes the bounds of the sharpest point in it: at a near-cusp (a turn of a
        radius far below the interval's length, where the spline bends back on itself) its
        cap ``sqrt(A / |K|)`` would hold over the whole interval, and the reference would
        crawl along it at millimetres per second. An interval that takes longer than
        :data:`_SPLIT_TIME_S` to cross at its cap, which the curvature or the jerk holds
        below the speed limits, is cut into quarters when they (each bounded on its own,
        :meth:`_quarters`) cross in at most :data:`_SPLIT_GAIN` of its time; the quarters
        are tried again, up to :data:`_SPLIT_DEPTH` times and :data:`_SPLIT_STATIONS` new
        stations. (Quarters, not halves: the sharpest point may sit at the middle.) The
        bounds of the result are those of :meth:`bounds`, proved as before.
        """
        shortest = self.bounds(limits, accel_h, accel_z)[3]
        per_alpha = 1.0 / shortest
        cap = self.bounds(limits, accel_h, accel_z, per_alpha, crawl=False)[0]
        current = self
        rows = current._slow(cap, limits)
        added = 0
        for _ in range(_SPLIT_DEPTH):
            rows = rows[:max((_SPLIT_STATIONS - added) // 3, 0)]
            if not len(rows):
                break
            quarters = current._quarters(rows, curve)
            quarter_cap = quarters.bounds(limits, accel_h, accel_z, per_alpha, crawl=False)[0]
            # (A cap of zero, at a cusp no bound holds, takes forever: +inf; a quarter too
            # short to tell from its neighbours takes no time.)
            with np.errstate(divide='ignore', invalid='ignore', over='ignore'):
                after = np.nan_to_num(np.diff(quarters.s)[0::2] / quarter_cap[0::2], nan=0.0)
                after = np.sum(after.reshape(-1, 4), axis=1)
                before = (current.s[rows + 1] - current.s[rows]) / cap[rows]
            better = after <= _SPLIT_GAIN * before
            if not better.any():
                break
            keep = np.repeat(better, 4)
            current = current._cut(rows[better], quarters.s[1::2].reshape(-1, 4)[better, :3],
                                   quarters, keep)
            rows = rows[better]
            added += 3 * len(rows)
            cap = current.bounds(limits, accel_h, accel_z, per_alpha, crawl=False)[0]
            # Only the quarters just made can pay again: row k is now k + 3 j (j rows before).
            first = rows + 3 * np.arange(len(rows))
            rows = np.intersect1d(current._slow(cap, limits),
                                  (first[:, None] + np.arange(4)).ravel())
        return current

    def _slow(self, cap: np.ndarray, limits: MotionLimits) -> np.ndarray:
        """Intervals whose cap the curve holds below their speed limits, that take longer than
        :data:`_SPLIT_TIME_S` to cross at it and whose quarters would be no shorter than
        :data:`_SPLIT_MIN_M`."""
        free = np.minimum.reduce([_ratio(limits.speed_horizontal, self.tangent[:, 0]),
                                  _ratio(limits.speed_vertical, self.tangent[:, 1]),
                                  self.user_cap])
        ds = np.diff(self.s)
        slow = (cap < free * (1.0 - 1e-9)) & (ds > _SPLIT_TIME_S * cap) & (ds >= 4 * _SPLIT_MIN_M)
        return np.flatnonzero(slow)

    def _quarters(self, rows: np.ndarray, curve: PathCurve) -> 'Stations':
        """The four quarters of each interval of ``rows``, as the intervals ``4 k`` to
        ``4 k + 3`` of stations of their own (``s`` is the quarters' ends in a row, so the
        quarters of consecutive rows are joined by intervals of length zero, never used).

        A quarter keeps the bounds of its interval and takes tighter ones where it has them:
        the proved ``|K|`` and ``|K'|`` over the quarter (:meth:`PathCurve.derivative_bounds`),
        and the tangent and curvature components at its middle widened by ``|K|`` and ``|K'|``
        times half its length. Its middle is inside the interval, never a stop.
        """
        lo, hi = self.s[rows], self.s[rows + 1]
        ends = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, 5)[None, :]
        starts, stops = ends[:, :-1].ravel(), ends[:, 1:].ravel()
        parent = np.repeat(rows, 4)
        proved_k, rate = curve.derivative_bounds(starts, stops)
        rate = np.minimum(rate, self.curvature_rate[parent])
        half = 0.5 * (stops - starts)
        tangent, curvature = curve.derivatives(0.5 * (starts + stops))
        # (A parameter speed of zero at the middle leaves NaN: no bound from there.)
        tangent = np.nan_to_num(tangent, nan=1.0)
        curvature = np.nan_to_num(curvature, nan=np.inf)
        norm = np.minimum.reduce([np.linalg.norm(curvature, axis=1) + rate * half, proved_k,
                                  self.curvature_norm[parent]])
        components = np.minimum.reduce([_components(curvature) + (rate * half)[:, None],
                                        np.repeat(proved_k[:, None], 2, axis=1),
                                        self.curvature[parent]])
        tangents = np.minimum.reduce([_components(tangent) + (norm * half)[:, None],
                                      np.ones((len(parent), 2)), self.tangent[parent]])
        s = np.r_[starts[:1], np.ravel(np.stack([stops, np.r_[starts[1:], stops[-1]]],
                                                axis=1))[:-1]]

        def spread(values: np.ndarray) -> np.ndarray:
            return np.repeat(values, 2, axis=0)[:-1]

        return Stations(s=s, stop=np.zeros(len(s), dtype=bool), tangent=spread(tangents),
                        curvature=spread(components), curvature_norm=spread(norm),
                        curvature_rate=spread(rate), user_cap=spread(self.user_cap[parent]))

    def _cut(self, rows: np.ndarray, inner: np.ndarray, quarters: 'Stations',
             keep: np.ndarray) -> 'Stations':
        """These stations with the intervals ``rows`` (increasing) cut at the arc lengths
        ``inner`` (three per row) into the quarters ``keep`` of :meth:`_quarters`."""
        every = np.arange(0, 2 * len(keep) - 1, 2)[keep]

        def merged(old: np.ndarray, new: np.ndarray) -> np.ndarray:
            parts = new[every].reshape((len(rows), 4) + new.shape[1:])
            out = old.copy()
            out[rows] = parts[:, 0]
            at = np.repeat(rows + 1, 3)
            return np.insert(out, at, parts[:, 1:].reshape((-1,) + new.shape[1:]), axis=0)

        at = np.repeat(rows + 1, 3)
        return Stations(s=np.insert(self.s, at, inner.ravel()),
                        stop=np.insert(self.stop, at, False),
                        tangent=merged(self.tangent, quarters.tangent),
                        curvature=merged(self.curvature, quarters.curvature),
                        curvature_norm=merged(self.curvature_norm, quarters.curvature_norm),
                        curvature_rate=merged(self.curvature_rate, quarters.curvature_rate),
                        user_cap=merged(self.user_cap, quarters.user_cap))

    def bounds(self, limits: MotionLimits, accel_h: float, accel_z: float,
               per_alpha: Optional[float] = None,
               crawl: bool = True) -> Tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """Speed cap ``w`` [m/s], tangential acceleration bound ``alpha`` [m/s^2] and
        tangential jerk allowance ``zeta`` [m/s^3] per interval (module docstring, step 1),
        and the shortest window ``tau`` [s].

        ``per_alpha`` is ``J / max(alpha)`` (``1 / tau``), by default that of these intervals;
        ``crawl`` False leaves the caps below the crawling speed as they are.
        ``zeta = J - 3 w alpha |K| - w^3 |K'|`` is at least ``alpha / tau``: what a jump of
        ``alpha`` over the window asks.
        """
        count = len(self.s) - 1
        cap, alpha, zeta = np.empty(count), np.empty(count), np.empty(count)
        dense = [np.ascontiguousarray(values, dtype=np.float64)
                 for values in (self.tangent, self.curvature, self.curvature_norm,
                                self.curvature_rate, self.user_cap)]
        per = _bounds_kernel(
            *dense, np.diff(self.s), float(limits.speed_horizontal), float(limits.speed_vertical),
            float(accel_h), float(accel_z), float(limits.jerk),
            -1.0 if per_alpha is None else float(per_alpha), crawl, cap, alpha, zeta)
        return cap, alpha, zeta, 1.0 / per


def _components(vectors: np.ndarray) -> np.ndarray:
    """Horizontal norm and vertical magnitude of each row, shape (M, 2)."""
    return np.stack([np.hypot(vectors[:, 0], vectors[:, 1]), np.abs(vectors[:, 2])], axis=1)


def _ratio(limit: float, component: np.ndarray) -> np.ndarray:
    """``limit / component`` with +inf where the component vanishes."""
    safe = np.where(component > 0.0, component, 1.0)
    return np.where(component > 0.0, limit / safe, np.inf)


@njit
def _over(limit, component):  # pragma: no cover - compiled
    """``limit / component``, +inf where the component vanishes."""
    return limit / component if component > 0.0 else np.inf


@njit
def _least(a, b):  # pragma: no cover - compiled
    """The smaller of two numbers, NaN if either is (as numpy.minimum)."""
    if a != a or b != b:
        return a + b
    return a if a <= b else b


@njit
def _cubic_cap(linear, cubic, room):  # pragma: no cover - compiled
    """Largest ``w >= 0`` with ``linear * w + cubic * w^3 <= room`` (coefficients >= 0).

    Newton's method from an upper bound decreases monotonically to the root (the left side is
    convex and increasing); the result is rounded down.
    """
    room = max(room, 0.0)
    w = _least(_over(room, linear), np.cbrt(_over(room, cubic)))
    if not math.isfinite(w):
        return w
    x = w
    for _ in range(60):
        value = linear * x + cubic * x ** 3 - room
        slope = linear + 3.0 * cubic * x ** 2
        step = value / slope if slope > 0.0 else 0.0
        x = x - max(step, 0.0)
        if step <= 1e-14 * max(x, 1e-12):
            break
    return x * (1.0 - 1e-12)


@njit
def _bounds_kernel(tangent, curvature, knorm, rate, user, ds, speed_h, speed_z, accel_h,
                   accel_z, jerk, per_alpha, crawl, cap, alpha, zeta):  # pragma: no cover
    """:meth:`Stations.bounds` per interval into ``cap``, ``alpha``, ``zeta``; returns
    ``J / max(alpha)`` when ``per_alpha`` is negative, else ``per_alpha``."""
    keep = 1.0 - TANGENTIAL_RESERVE
    count = cap.shape[0]
    top = -np.inf
    for i in range(count):
        th, tz = tangent[i, 0], tangent[i, 1]
        kh, kz = curvature[i, 0], curvature[i, 1]
        w = _least(_least(_least(_least(_over(speed_h, th), _over(speed_z, tz)),
                                 math.sqrt(_over(keep * accel_h, kh))),
                          math.sqrt(_over(keep * accel_z, kz))), user[i])
        cap[i] = w
        a = _least(_over(1.0, th) * (accel_h - w ** 2 * kh),
                   _over(1.0, tz) * (accel_z - w ** 2 * kz))
        alpha[i] = a
        if a > top or a != a:
            top = a
    if per_alpha < 0.0:
        per_alpha = jerk / top
    for i in range(count):
        w, a = cap[i], alpha[i]
        # Jerk: alpha (J / max(alpha)) + 3 w alpha |K| + w^3 |K'| <= J. On a straight the
        # tangential jerk takes all of J; in a bend speed matters more than tangential
        # acceleration, so alpha gives way first (down to MIN_ALPHA_SHARE of itself), and
        # only then the speed cap.
        spare = jerk - w ** 3 * rate[i]
        wanted = spare / (per_alpha + 3.0 * w * knorm[i])
        a = _least(max(wanted, MIN_ALPHA_SHARE * a), a)
        # (Within rounding: alpha was just fitted to this very sum.)
        if not a * (per_alpha + 3.0 * w * knorm[i]) + w ** 3 * rate[i] <= jerk * (1.0 + 1e-12):
            w = _least(w, _cubic_cap(3.0 * a * knorm[i], rate[i], jerk - a * per_alpha))
        z = jerk - 3.0 * w * a * knorm[i] - w ** 3 * rate[i]
        # A cusp, whose curvature no bound can hold, is crawled through rather than stopped
        # at for good: at _CRAWL, or in _CRAWL_CROSS_S on an interval shorter than that
        # takes (:meth:`Stations.refined` makes them around a near-cusp).
        if crawl:
            w = max(w, min(_CRAWL, ds[i] / _CRAWL_CROSS_S))
        cap[i] = w
        alpha[i] = a
        zeta[i] = max(z, a * per_alpha)
    return per_alpha
