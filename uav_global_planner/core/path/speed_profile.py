"""The profile ``s0`` of the time parameterisation, its moving average, and the sample times.

Steps 2 and 3 of :mod:`uav_global_planner.core.path.timing`: :func:`build_profile` finds the
time-optimal ``s0`` with piecewise constant acceleration for the caps and acceleration bounds
of the stations (backward and forward passes over ``u = v^2``, plateaus of ``tau`` at its
direct turns, waits of ``tau`` at the stops, a history over ``[-tau, 0]`` for a moving start)
and returns its moving average as an :class:`~uav_global_planner.core.path.reference.
ArcProfile`; :func:`jerk_fits` holds that average's jerk exactly against the allowances, and
:func:`times_of` finds when it passes the curve's samples.

The passes and the search for the sample times are compiled loops
(:mod:`uav_global_planner.core.jit`); the same source is the pure-Python fallback.
"""

import math
from typing import List, Optional, Tuple

import numpy as np

from uav_global_planner.core.jit import njit
from uav_global_planner.core.path.piecewise import PiecewisePolynomial
from uav_global_planner.core.path.reach import MinTable
from uav_global_planner.core.path.reference import ArcProfile, profile_from_pieces

#: Rounds of plateaus at the turns of the profile (each may leave new, smaller turns).
PLATEAU_ROUNDS = 3
_PLATEAU_MIN_U = 1e-4     # [m^2/s^2]

#: Rounds that lower a start speed too fast to brake for the curve.
LAUNCH_ROUNDS = 6

#: Bisection steps when finding the time of each sample (the bracket is tau / 4 wide).
BISECTIONS = 44

#: One piece of ``s0``: start time [s], ``s0`` [m], speed [m/s], acceleration [m/s^2].
Piece = Tuple[float, float, float, float]


def build_profile(s_stations: np.ndarray, stop_stations: np.ndarray, cap: np.ndarray,
                  alpha: np.ndarray, tau: float,
                  start: Optional[Tuple[float, float]]) -> Tuple[ArcProfile, float, float]:
    """The averaged profile (steps 2 and 3 of :mod:`~uav_global_planner.core.path.timing`)
    and the start it kept.

    Parameters
    ----------
    s_stations : numpy.ndarray, shape (n,)
        Arc lengths of the stations [m], increasing.
    stop_stations : numpy.ndarray of bool, shape (n,)
        Stations where the speed is zero.
    cap, alpha : numpy.ndarray, shape (n - 1,)
        Speed cap [m/s] and tangential acceleration bound [m/s^2] of each interval, already
        taken over the reach of the window.
    tau : float
        Averaging window [s].
    start : tuple of float, optional
        Speed [m/s] and tangential acceleration [m/s^2] of a moving start; None from rest.

    Returns
    -------
    tuple
        The profile, and the start speed [m/s] and acceleration [m/s^2] it kept.
    """
    length = float(s_stations[-1])
    start_speed, start_accel = 0.0, 0.0
    history: List[Piece] = [(-tau, 0.0, 0.0, 0.0)]
    first, u0 = 0, 0.0
    s, stop, ds, reach2, back = _passes(s_stations, stop_stations, cap, alpha, None)
    if start is not None:
        a = min(max(float(start[1]), -float(alpha[0])), float(alpha[0]))
        v = float(start[0])
        # s0's history over [-tau, 0] (_history) makes the mean over the window start with
        # the vehicle's speed and acceleration; s0 is then at `launch` with speed `ahead`. Too
        # fast to brake for the curve: the largest speed that can (`launch` moves with it, so
        # a few rounds).
        brisk = float(alpha[0])
        for _ in range(LAUNCH_ROUNDS):
            ahead, launch, pieces, fastest = _history(v, a, tau, brisk)
            if not (0.0 < launch < length and ahead > 0.0):
                break
            trial = _passes(s_stations, stop_stations, cap, alpha, launch)
            j = int(np.searchsorted(trial[0], launch))
            if np.any(trial[1][1:j]):
                break   # a corner before the launch point: start from rest
            # The history's speeds enter the mean while the window covers them: they keep the
            # caps of the curve up to the launch point too.
            top = float(np.min(cap[:j]))
            if fastest > top * (1.0 + 1e-12):
                v = max(v - (fastest - top), 0.0) * (1.0 - 1e-9)
                continue
            if ahead ** 2 <= trial[4][j] * (1.0 + 1e-12):
                s, stop, ds, reach2, back = trial
                first, u0 = j, ahead ** 2
                start_speed, start_accel = v, a
                history = pieces
                stop[:first] = False
                break
            v = max(math.sqrt(trial[4][j]) - (ahead - v), 0.0) * (1.0 - 1e-9)
    u = _forward(back, reach2, first, u0)
    # Where s0 turns from accelerating to braking (or back) at once, its acceleration jumps by
    # twice alpha, which only the longest window proves; a plateau of tau seconds at the turn
    # halves the jump, so shorter windows (a smaller lag behind s0) prove the jerk too.
    for _ in range(PLATEAU_ROUNDS):
        level = _plateaus(s, u, first, tau)
        if not np.any(np.isfinite(level)):
            break
        lowered = _backward(np.minimum(back, level), reach2)
        if u0 > lowered[first] * (1.0 + 1e-12):
            break   # the moving start could not brake for them: keep the profile as it is
        back = lowered
        u = _forward(back, reach2, first, u0)
    v = np.sqrt(np.maximum(u, 0.0))
    seg_ds = ds[first:]
    v0, v1 = v[first:-1], v[first + 1:]
    dt = 2.0 * seg_ds / (v0 + v1)
    acc = (u[first + 1:] - u[first:-1]) / (2.0 * seg_ds)
    pos = s[first:-1]
    # Waits of tau at the stops inside the curve.
    waits = np.flatnonzero(stop[first + 1:-1])
    starts_s = np.insert(pos, waits + 1, s[first + 1:-1][waits])
    speeds = np.insert(v0, waits + 1, 0.0)
    accels = np.insert(acc, waits + 1, 0.0)
    durations = np.insert(dt, waits + 1, tau)
    piece_start = np.r_[0.0, np.cumsum(durations)[:-1]]
    end_time = float(np.sum(durations))
    past = np.asarray(history, dtype=np.float64).reshape(-1, 4)
    profile = profile_from_pieces(np.r_[past[:, 0], piece_start], np.r_[past[:, 1], starts_s],
                                  np.r_[past[:, 2], speeds], np.r_[past[:, 3], accels],
                                  end_time, tau, length)
    return profile, start_speed, start_accel


def jerk_fits(profile: ArcProfile, s: np.ndarray, allowance: MinTable) -> bool:
    """True when ``|s_ttt| = |s0_tt(t) - s0_tt(t - tau)| / tau`` keeps the allowance of every
    interval the reference passes while it holds.

    Both terms are piecewise constant, so ``s_ttt`` is constant between the merged
    breakpoints of ``s0`` and of ``s0`` shifted by tau: one evaluation in each of those, held
    against the smallest allowance of the arc-length range that piece covers. Exact.
    """
    tau = profile.window_s
    breaks = profile.base.x
    merged = np.unique(np.r_[0.0, breaks, breaks + tau, profile.duration_s])
    merged = merged[(merged >= 0.0) & (merged <= profile.duration_s)]
    if len(merged) < 2:
        return True
    middle = 0.5 * (merged[:-1] + merged[1:])
    jerk = np.abs(profile.base(middle, 2) - profile.base(middle - tau, 2)) / tau
    arc = arc_at(profile, merged)
    last = len(s) - 2
    lo = np.clip(np.searchsorted(s, arc[:-1], side='right') - 1, 0, last)
    hi = np.clip(np.searchsorted(s, arc[1:], side='left') - 1, 0, last)
    hi = np.maximum(hi, lo)
    return bool(np.all(jerk <= allowance.query(lo, hi) * (1.0 + 1e-9)))


def _history(v: float, a: float, tau: float,
             brisk: float) -> Tuple[float, float, List[Piece], float]:
    """A history of ``s0`` over ``[-tau, 0]`` whose mean starts with speed ``v`` and
    acceleration ``a``: ``s0`` changes its speed by ``a tau`` over the window, at the rate
    ``brisk`` (or less) for the time ``d`` that takes and at constant speed otherwise, with the
    change first when speeding up and last when slowing down (either keeps ``s0``'s speed at
    ``0``, ``ahead``, as low as the mean allows).

    Returns
    -------
    tuple
        ``ahead`` (s0's speed at 0) [m/s], ``launch`` (s0 at 0, where the mean is 0) [m], the
        pieces ``(start time, s0, speed, acceleration)`` and the fastest speed in them [m/s].
    """
    d = min(tau, abs(a) * tau / brisk) if brisk > 0.0 else tau
    rise = a * tau / d if d > 0.0 else 0.0
    steady = v - 0.5 * a * d
    late = 0.5 * steady * tau + a * (d * d / 3.0 + 0.5 * (tau - d) * d)
    if a >= 0.0 or not (late > 0.0 and steady + a * tau > 0.0):
        # (Slowing down to almost nothing, the change comes first too: s0 must neither start
        # behind the mean nor stand still.)
        ahead = v + 0.5 * a * d
        launch = 0.5 * ahead * tau - a * d * d / 6.0
        early = launch - v * tau
        pieces = [(-tau, early, ahead - a * tau, rise)]
        if 0.0 < d < tau:
            pieces.append((-tau + d, early + (ahead - a * tau) * d + 0.5 * rise * d * d,
                           ahead, 0.0))
        return ahead, launch, pieces, max(ahead, ahead - a * tau)
    ahead = steady + a * tau
    launch = late
    early = launch - v * tau
    if d < tau:
        pieces = [(-tau, early, steady, 0.0), (-d, early + steady * (tau - d), steady, rise)]
    else:
        pieces = [(-tau, early, steady, rise)]
    return ahead, launch, pieces, steady


def _plateaus(s: np.ndarray, u: np.ndarray, first: int, tau: float) -> np.ndarray:
    """Caps on ``u`` per station that flatten each direct turn of the profile for ``tau``.

    A peak (accelerating, then braking) is cut at the highest level whose stretch above it
    takes ``tau`` at that speed; a valley (braking, then accelerating) is held at its level
    for ``tau``. Stretches that reach back to the start (``first``) are left alone.
    """
    level = np.full(len(u), np.inf)
    ds = np.diff(s)
    acc = np.diff(u) / (2.0 * ds)
    sign = np.where(np.abs(acc) > 1e-9, np.sign(acc), 0.0)
    turns = np.flatnonzero(sign[:-1] * sign[1:] < 0.0) + 1
    last = len(u) - 1
    for k in turns.tolist():
        if k <= first + 1:
            continue
        if sign[k - 1] < 0.0:
            height = float(u[k])
            half = 0.5 * math.sqrt(max(height, 0.0)) * tau
            lo = int(np.searchsorted(s, s[k] - half, side='left'))
            hi = int(np.searchsorted(s, s[k] + half, side='right')) - 1
        else:
            lo = hi = k
            height = float(u[k])
            while s[hi] - s[lo] < math.sqrt(max(height, 0.0)) * tau:
                left = float(u[lo - 1]) if lo - 1 > first else -math.inf
                right = float(u[hi + 1]) if hi + 1 <= last else -math.inf
                if left == right == -math.inf:
                    break
                if left >= right:
                    lo -= 1
                    height = min(height, left)
                else:
                    hi += 1
                    height = min(height, right)
        # At (nearly) zero speed there is nothing to flatten: a stop waits tau anyway.
        if lo <= first or not height > _PLATEAU_MIN_U:
            continue
        level[lo:hi + 1] = np.minimum(level[lo:hi + 1], height)
    return level


def _passes(s: np.ndarray, stop: np.ndarray, cap: np.ndarray, alpha: np.ndarray,
            launch: Optional[float]) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                              np.ndarray]:
    """Stations (with one inserted at ``launch``), stops, steps, ``2 alpha ds`` and the
    backward limits of ``u``."""
    if launch is not None:
        j = int(np.searchsorted(s, launch, side='right')) - 1
        s = np.insert(s, j + 1, launch)
        stop = np.insert(stop, j + 1, False)
        cap = np.insert(cap, j, cap[j])
        alpha = np.insert(alpha, j, alpha[j])
    else:
        stop = stop.copy()
    ucap = np.minimum(np.r_[cap, np.inf], np.r_[np.inf, cap]) ** 2
    ucap[stop] = 0.0
    ucap[-1] = 0.0
    ds = np.diff(s)
    reach2 = 2.0 * alpha * ds
    return s, stop, ds, reach2, _backward(ucap, reach2)


def _backward(ucap: np.ndarray, reach2: np.ndarray) -> np.ndarray:
    """Largest ``u`` at each station from which every later cap can still be kept."""
    back = np.array(ucap, dtype=np.float64)
    _backward_kernel(back, np.ascontiguousarray(reach2, dtype=np.float64))
    return back


def _forward(back: np.ndarray, reach2: np.ndarray, first: int, u0: float) -> np.ndarray:
    """Fastest ``u`` from station ``first`` (at ``u0``) within the backward limits."""
    u = np.array(back, dtype=np.float64)
    _forward_kernel(u, np.ascontiguousarray(reach2, dtype=np.float64), first, u0)
    return u


@njit
def _backward_kernel(back, reach2):  # pragma: no cover - compiled
    for j in range(back.shape[0] - 2, -1, -1):
        back[j] = min(back[j], back[j + 1] + reach2[j])


@njit
def _forward_kernel(u, reach2, first, u0):  # pragma: no cover - compiled
    u[first] = u0
    for j in range(first, u.shape[0] - 1):
        u[j + 1] = min(u[j + 1], u[j] + reach2[j])
    for j in range(first):
        u[j] = 0.0


def times_of(profile: ArcProfile, arc: np.ndarray) -> np.ndarray:
    """The times at which the averaged profile passes the arc lengths ``arc`` [s].

    A bracket from a grid of times ``tau / 4`` apart, then :data:`BISECTIONS` halvings.
    """
    duration = profile.duration_s
    step = profile.window_s / 4.0
    grid = np.linspace(0.0, duration, max(2, int(math.ceil(duration / step)) + 1))
    grid_s = arc_at(profile, grid)
    grid_s = np.maximum.accumulate(grid_s)
    right = np.clip(np.searchsorted(grid_s, arc, side='left'), 1, len(grid) - 1)
    times = grid[right].copy()
    _bisect_kernel(*_coefficients(profile.integral), profile.window_s,
                   np.ascontiguousarray(arc, dtype=np.float64), grid[right - 1], times,
                   BISECTIONS)
    times[0] = 0.0
    times[-1] = duration
    return times


def arc_at(profile: ArcProfile, t: np.ndarray) -> np.ndarray:
    """Arc length ``s(t)`` of the averaged profile at times ``t`` [s], unclamped [m]."""
    t = np.ascontiguousarray(t, dtype=np.float64)
    out = np.empty(t.shape)
    _arc_kernel(*_coefficients(profile.integral), profile.window_s, t.reshape(-1),
                out.reshape(-1))
    return out


def _coefficients(poly: PiecewisePolynomial) -> Tuple[np.ndarray, np.ndarray]:
    """Coefficients (order, pieces) and breaks of a 1-D piecewise polynomial, contiguous."""
    return (np.ascontiguousarray(poly.c, dtype=np.float64),
            np.ascontiguousarray(poly.x, dtype=np.float64))


def speed_at(profile: ArcProfile, t: np.ndarray) -> np.ndarray:
    """Speed ``s_t`` of the averaged profile at times ``t`` [s], clamped to the profile, as
    :meth:`~uav_global_planner.core.path.reference.ArcProfile.evaluate` gives it [m/s]."""
    t = np.clip(np.asarray(t, dtype=np.float64).reshape(-1), 0.0, profile.duration_s)
    out = np.empty(t.shape)
    _arc_kernel(*_coefficients(profile.base), profile.window_s, t, out)
    return np.maximum(out, 0.0)


@njit
def _ppoly_at(c, x, t):  # pragma: no cover - compiled
    """A 1-D :class:`~uav_global_planner.core.path.piecewise.PiecewisePolynomial`
    (coefficients ``c``, breaks ``x``, extrapolating) at ``t``, term by term as it sums."""
    last = x.shape[0] - 2
    i = np.searchsorted(x, t, side='right') - 1
    i = min(max(i, 0), last)
    d = t - x[i]
    total = 0.0
    z = 1.0
    order = c.shape[0]
    for k in range(order):
        total = total + c[order - k - 1, i] * z
        if k < order - 1:
            z *= d
    return total


@njit
def _arc_kernel(c, x, tau, t, out):  # pragma: no cover - compiled
    for k in range(t.shape[0]):
        out[k] = (_ppoly_at(c, x, t[k]) - _ppoly_at(c, x, t[k] - tau)) / tau


@njit
def _bisect_kernel(c, x, tau, arc, lo, hi, steps):  # pragma: no cover - compiled
    for k in range(arc.shape[0]):
        a, b = lo[k], hi[k]
        for _ in range(steps):
            mid = 0.5 * (a + b)
            if (_ppoly_at(c, x, mid) - _ppoly_at(c, x, mid - tau)) / tau < arc[k]:
                a = mid
            else:
                b = mid
        hi[k] = b
