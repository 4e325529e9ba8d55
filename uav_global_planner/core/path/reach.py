"""Minima over the arc-length reach of each interval, for the averaging window of the timing.

Step 2 of :mod:`uav_global_planner.core.path.timing`: with the averaging window ``tau``, the
moving average at an arc length mixes speeds and accelerations of ``s0`` from up to ``tau``
times its speed away, so each interval of the stations takes the smallest cap
(:func:`self_reach_min`) and the smallest acceleration bound (:func:`reach_min`) within that
reach. Interval ``j`` lies within ``r`` of interval ``i`` when the gap between them (arc
length) is below ``r``; an interval is always within reach of itself.

Both are compiled loops over the intervals (:mod:`uav_global_planner.core.jit`; the same source
is the pure-Python fallback), with range minima from a sparse table: a few hundred to a few
thousand intervals per plan, each answered in microseconds.
"""

import numpy as np

from uav_global_planner.core.jit import njit

#: Geometric levels of reach radii in :func:`reach_min`, each this ratio of the next.
REACH_LEVELS = 24
REACH_RATIO = 0.8

#: Bisection steps of :func:`self_reach_min`: the cap it finds is within 2^-24 of the
#: largest that fits, and always one that fits.
REACH_BISECTIONS = 24


@njit
def _table(values):  # pragma: no cover - compiled
    """Sparse table of range minima: row ``k`` holds the minima of ``2^k`` values."""
    n = values.shape[0]
    depth = 1
    while (2 << (depth - 1)) <= n:
        depth += 1
    table = np.full((depth, max(n, 1)), np.inf)
    for i in range(n):
        table[0, i] = values[i]
    width = 1
    for k in range(1, depth):
        for i in range(n - 2 * width + 1):
            a = table[k - 1, i]
            b = table[k - 1, i + width]
            table[k, i] = a if a <= b else b
        width *= 2
    return table


@njit
def _query(table, lo, hi):  # pragma: no cover - compiled
    """Minimum of ``values[lo:hi + 1]`` (``lo <= hi``)."""
    k = 0
    while (2 << k) <= hi - lo + 1:
        k += 1
    a = table[k, lo]
    b = table[k, hi - (1 << k) + 1]
    return a if a <= b else b


@njit
def _within(s, i, radius):  # pragma: no cover - compiled
    """First and last interval within ``radius`` of interval ``i`` (arc lengths ``s``)."""
    lo = np.searchsorted(s[1:], s[i] - radius, side='right')
    hi = np.searchsorted(s[:-1], s[i + 1] + radius, side='left') - 1
    return min(lo, i), max(hi, i)


@njit
def _self_reach_kernel(s, caps, tau, bisections, out):  # pragma: no cover - compiled
    table = _table(caps)
    for i in range(caps.shape[0]):
        low = 0.0
        high = caps[i]
        for _ in range(bisections):
            trial = 0.5 * (low + high)
            lo, hi = _within(s, i, tau * trial)
            if trial <= _query(table, lo, hi):
                low = trial
            else:
                high = trial
        lo, hi = _within(s, i, tau * low)
        least = _query(table, lo, hi)
        out[i] = low if low <= least else least


@njit
def _reach_kernel(s, values, level, ladder, out):  # pragma: no cover - compiled
    n = values.shape[0]
    present = np.zeros(ladder.shape[0], dtype=np.bool_)
    for i in range(n):
        present[level[i]] = True
    masked = np.empty(n)
    for k in range(ladder.shape[0]):
        if not present[k]:
            continue
        for i in range(n):
            masked[i] = values[i] if level[i] == k else np.inf
        table = _table(masked)
        for i in range(n):
            lo, hi = _within(s, i, ladder[k])
            least = _query(table, lo, hi)
            if least < out[i]:
                out[i] = least


def self_reach_min(s: np.ndarray, caps: np.ndarray, tau: float) -> np.ndarray:
    """Largest ``c`` per interval with ``c <= min(caps)`` over the intervals within ``tau c``.

    With every speed of ``s0`` at arc length ``y`` at most this ``c(y)``, the window of the
    moving average at ``x`` spans at most ``tau`` times its largest ``c``, and that largest
    ``c`` is then within reach of ``x``, so at most ``caps(x)`` (step 3 of
    :mod:`uav_global_planner.core.path.timing`). Found by bisection on ``c``: the minimum over
    the reach only falls as ``c`` grows.

    Parameters
    ----------
    s : numpy.ndarray, shape (n,)
        Arc lengths of the stations [m], increasing.
    caps : numpy.ndarray, shape (n - 1,)
        Speed cap of each interval [m/s].
    tau : float
        Averaging window [s].
    """
    out = np.empty(len(s) - 1)
    _self_reach_kernel(np.ascontiguousarray(s, dtype=np.float64),
                       np.ascontiguousarray(caps, dtype=np.float64), float(tau),
                       REACH_BISECTIONS, out)
    return out


def reach_min(s: np.ndarray, values: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """For each interval, the smallest value of the intervals that reach it.

    Interval ``i`` reaches every interval within ``radius[i]`` [m] of it. The radii are rounded
    up to :data:`REACH_LEVELS` geometric levels (reaching further is only more cautious).

    Parameters
    ----------
    s : numpy.ndarray, shape (n,)
        Arc lengths of the stations [m], increasing.
    values, radius : numpy.ndarray, shape (n - 1,)
        A value per interval, and its reach [m].
    """
    values = np.ascontiguousarray(values, dtype=np.float64)
    out = values.copy()
    top = float(np.max(radius)) if len(radius) else 0.0
    if not top > 0.0:
        return out
    ladder = top * REACH_RATIO ** np.arange(REACH_LEVELS)[::-1]
    level = np.minimum(np.searchsorted(ladder, radius, side='left'), REACH_LEVELS - 1)
    _reach_kernel(np.ascontiguousarray(s, dtype=np.float64), values,
                  level.astype(np.int64), np.ascontiguousarray(ladder), out)
    return out


class MinTable:
    """Range minima of a fixed array in O(1) per query (a sparse table).

    Parameters
    ----------
    values : numpy.ndarray, shape (n,)
    """

    def __init__(self, values: np.ndarray) -> None:
        self.values = np.ascontiguousarray(values, dtype=np.float64)
        self._table = _table(self.values)

    def query(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Minimum over ``values[lo[k]:hi[k] + 1]`` for each k (``lo <= hi``)."""
        out = np.empty(len(lo))
        _queries(self._table, np.asarray(lo, dtype=np.int64), np.asarray(hi, dtype=np.int64),
                 out)
        return out


@njit
def _queries(table, lo, hi, out):  # pragma: no cover - compiled
    for k in range(lo.shape[0]):
        out[k] = _query(table, lo[k], hi[k])
