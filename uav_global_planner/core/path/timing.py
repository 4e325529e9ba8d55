"""Jerk-limited time parameterisation of a certified curve, from rest or from a moving state.

The reference flies the certified curve itself (path-velocity decomposition), so its clearance
is the curve's certificate. Only the arc length in time, ``s(t)``, is chosen here, in three
steps; the reference and its derivatives are those of
:mod:`uav_global_planner.core.path.reference`.

1. **Bounds per interval.** Between two samples of the curve (interval ``i``), with ``T_c``,
   ``K_c`` the largest horizontal (``c = h``) and vertical (``c = z``) components of the unit
   tangent and of the curvature vector, ``|K|`` and ``|K'|`` the largest norms of the curvature
   vector and of its arc-length derivative, and ``A_c`` the acceleration box that also keeps
   tilt and thrust (:mod:`uav_global_planner.core.path.motion_limits`), the interval gets a speed
   cap ``w_i``, a tangential acceleration bound ``alpha_i`` and a tangential jerk allowance
   ``zeta_i`` such that, for every speed ``v <= w_i``, ``|s_tt| <= alpha_i`` and
   ``|s_ttt| <= zeta_i``::

       v T_c <= V_c                                            (speed)
       alpha_i T_c + w_i^2 K_c <= A_c                          (acceleration, by components)
       zeta_i + 3 w_i alpha_i |K| + w_i^3 |K'| <= J            (jerk norm)

   Both sides of each line bound the true components by the triangle inequality, since
   ``a = s_tt T + s_t^2 K`` and ``j = s_ttt T + 3 s_t s_tt K + s_t^3 K'``. The centripetal
   term leaves ``TANGENTIAL_RESERVE`` of ``A_c``; in a bend the jerk terms first lower
   ``alpha_i`` (down to ``MIN_ALPHA_SHARE`` of itself), then ``w_i``, and always leave
   ``zeta_i >= alpha_i J / max(alpha)``. A user's speed cap (the vehicle's tracking room near
   obstacles, :mod:`uav_global_planner.core.path.tracking`) lowers ``w_i`` first. The bounds
   are :mod:`uav_global_planner.core.path.interval_bounds`'s; an interval whose speed the curve
   holds down is cut into quarters, bounded each on its own, while that shortens its crossing,
   so that a near-cusp of the curve is slow only over micrometres.

2. **A profile with piecewise constant acceleration** ``s0(t)``. For a window ``tau``, every
   interval takes the smallest ``alpha`` of the intervals that reach it within ``tau w`` and
   the largest ``c <= min(w)`` over its own ``tau c`` (:func:`_reach_min`,
   :func:`_self_reach_min`). The time-optimal ``s0`` for those bounds comes from the backward
   and forward passes over ``u = v^2`` (``u`` is linear in arc length under a constant
   acceleration); where it turns straight from accelerating to braking, or back, it is held
   flat for ``tau`` (:func:`_plateaus`); it stops at each point where the curve is not C1
   (polyline corners) and waits there ``tau`` seconds.

3. **A moving average.** ``s(t)`` is the mean of ``s0`` over ``[t - tau, t]``. Over such a
   window ``s0`` moves at most ``tau`` times its largest speed there, so every speed and
   acceleration of ``s0`` in the window keeps the bounds of the interval where ``s(t)`` is;
   their means do too, which proves speed, acceleration, tilt and thrust at every time.
   ``s_tt`` is continuous (``s0``'s speed is) and ``s_ttt = (s0_tt(t) - s0_tt(t - tau)) /
   tau`` is piecewise constant: :func:`_jerk_fits` holds each of its pieces exactly against
   the allowance ``zeta`` of the arc it covers. ``tau = max(alpha) / J`` is tried first, longer
   windows after; ``2 max(alpha) / J`` proves the jerk for any profile. At a corner ``s0``
   waits ``tau``, so the mean reaches it with zero speed and acceleration, and leaves it as
   smoothly.

From a moving state (speed ``v`` along the start tangent and tangential acceleration ``a``)
``s0`` gets a history over ``[-tau, 0]`` (acceleration ``alpha`` long enough to rise by
``a tau``, then a constant speed) whose mean speed is ``v``: then ``s_t(0) = v`` and
``s_tt(0) = a`` exactly; the start tangent and curvature of the curve
(:func:`uav_global_planner.core.path.smoothing.smooth_path`) carry the rest of the velocity and
acceleration. When the vehicle cannot brake for the new curve from that state, or is faster
than its caps, the speed is lowered to the largest that fits, and
:attr:`TimingResult.start_speed` says so.

The tangent, curvature and curvature-rate maxima of an interval are taken at its ends and at
the curve's verification samples inside it (spacing <= delta / 20), widened by the bound of
their derivative times half the interval; the limits are otherwise proved, not sampled.
"""

from dataclasses import dataclass
import math
from typing import List, Optional, Tuple

import numpy as np

from uav_global_planner.core.path.interval_bounds import MIN_ALPHA_SHARE, Stations as _Stations
from uav_global_planner.core.path.motion_limits import MotionLimits
from uav_global_planner.core.path.reference import ArcProfile, profile_from_pieces, TimedReference
from uav_global_planner.core.path.smoothing import SmoothedPath
from uav_global_planner.core.path.yaw import yaw_profile, YawProfile
from uav_global_planner.core.result import Trajectory

#: Windows tried, in units of max(alpha) / J: the last one proves the jerk for any profile.
_WINDOW_FACTORS = (1.0, 2.0)
_MOVING_WINDOW_FACTORS = (1.0, 1.25, 1.5, 2.0)

#: Geometric levels of reach radii in :func:`_reach_min`, each this ratio of the next.
_REACH_LEVELS = 24
_REACH_RATIO = 0.8

#: Bisection steps of :func:`_self_reach_min`: the cap it finds is within 2^-24 of the
#: largest that fits, and always one that fits.
_REACH_BISECTIONS = 24

#: Rounds of plateaus at the turns of the profile (each may leave new, smaller turns).
_PLATEAU_ROUNDS = 3
_PLATEAU_MIN_U = 1e-4     # [m^2/s^2]

#: Rounds that lower a start speed too fast to brake for the curve.
_LAUNCH_ROUNDS = 6

#: Bisection steps when finding the time of each sample (the bracket is tau / 4 wide).
_BISECTIONS = 44


@dataclass(frozen=True)
class StartMotion:
    """The state the reference starts from, along the start tangent of the curve.

    Attributes
    ----------
    speed : float
        [m/s], >= 0.
    accel : float
        Tangential acceleration [m/s^2].
    """

    speed: float = 0.0
    accel: float = 0.0


@dataclass(frozen=True, eq=False)
class TimingResult:
    """A timed trajectory and how its start and limits came out.

    Attributes
    ----------
    trajectory : Trajectory
        Samples at the curve's samples, and the continuous reference.
    window_s : float
        The averaging window tau [s].
    start_speed, start_accel : float
        Speed [m/s] and tangential acceleration [m/s^2] the reference starts with; below the
        requested ones only when the vehicle could not brake for the curve otherwise.
    """

    trajectory: Trajectory
    window_s: float
    start_speed: float
    start_accel: float


def time_parameterize(smoothed: SmoothedPath, limits: MotionLimits = MotionLimits(), *,
                      start: StartMotion = StartMotion(),
                      speed_cap: Optional[np.ndarray] = None, yaw_mode: str = 'velocity',
                      initial_yaw: Optional[float] = None) -> TimingResult:
    """Fastest jerk-limited timing of the certified curve that this construction proves.

    Parameters
    ----------
    smoothed : SmoothedPath
        The certified curve and its samples.
    limits : MotionLimits
        Speed, acceleration, jerk, tilt, thrust and yaw-rate limits.
    start : StartMotion
        Speed and tangential acceleration at the start; from rest by default.
    speed_cap : numpy.ndarray, shape (M,), optional
        Largest speed at each sample of ``smoothed`` [m/s], > 0 (an interval takes the
        smaller of its ends').
    yaw_mode : str
        ``'velocity'``, ``'fixed'`` or ``'goal'`` (:mod:`uav_global_planner.core.path.yaw`).
    initial_yaw : float, optional
        Heading at the start [rad] (ENU).

    Returns
    -------
    TimingResult
    """
    positions = smoothed.positions
    arc = np.asarray(smoothed.arc_length, dtype=np.float64)
    count = len(positions)
    goal = positions[-1] if count else np.zeros(3)
    if count < 2 or not arc[-1] > 0.0:
        return _at_rest(smoothed, limits, yaw_mode, initial_yaw)
    box = limits.acceleration_box()
    stations = _Stations.of(smoothed, speed_cap).refined(smoothed.curve, limits,
                                                         box.horizontal, box.vertical)
    cap, alpha, zeta, shortest = stations.bounds(limits, box.horizontal, box.vertical)
    moving = start.speed > 0.0
    # With tau = max(alpha) / J a jump of alpha in the tangential acceleration over the
    # window fits the allowance zeta; a jump from +alpha to -alpha needs twice the window,
    # which proves the jerk whatever the profile. Shorter windows are tried first and kept
    # where the exact check of the profile built with them passes.
    table = _MinTable(cap)
    allowance = _MinTable(zeta)
    # A moving start also wants the window that keeps its speed: a longer window makes s0
    # lead the mean by more, which a vehicle accelerating near its speed cap cannot.
    best: Optional[Tuple[ArcProfile, float, float]] = None
    for factor in _MOVING_WINDOW_FACTORS if moving else _WINDOW_FACTORS:
        tau = factor * shortest
        near_cap = _self_reach_min(stations.s, table, tau)
        near_alpha = _reach_min(stations.s, alpha, tau * cap)
        found = _profile(stations, near_cap, near_alpha, tau, start if moving else None)
        if factor < 2.0 and not _jerk_fits(found[0], stations.s, allowance):
            continue
        if best is None or found[1] > best[1]:
            best = found
        if not moving or found[1] >= start.speed:
            break
    assert best is not None  # the last window always proves the jerk
    profile, start_speed, start_accel = best
    times = _times_of(profile, arc)
    yaw = yaw_profile(yaw_mode, profile.duration_s, limits.yaw_rate,
                      _SampledMotion(times, positions, profile.evaluate(times)[1][:, None]
                                     * smoothed.tangents), goal, initial_yaw)
    reference = TimedReference(curve=smoothed.curve, arc=profile, yaw=yaw)
    state = reference.evaluate(times)
    velocities, accelerations, jerks = state.velocity, state.acceleration, state.jerk
    stops = np.asarray(smoothed.stop_points, dtype=np.int64)
    if moving:
        stops = stops[stops != 0]
    velocities[stops] = 0.0
    accelerations[stops] = 0.0
    trajectory = Trajectory(times=times, positions=positions.copy(), velocities=velocities,
                            accelerations=accelerations, jerks=jerks, yaws=state.yaw,
                            yaw_rates=state.yaw_rate, reference=reference)
    return TimingResult(trajectory=trajectory, window_s=tau, start_speed=start_speed,
                        start_accel=start_accel)


class _SampledMotion:
    """Positions and velocities of the reference between its samples (the heading's input),
    linear in time: the heading follows them at most at the yaw-rate limit anyway."""

    def __init__(self, times: np.ndarray, positions: np.ndarray,
                 velocities: np.ndarray) -> None:
        self._times = times
        self._positions = positions
        self._velocities = velocities

    def __call__(self, times: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        def column(values: np.ndarray) -> np.ndarray:
            return np.stack([np.interp(times, self._times, values[:, k]) for k in range(3)],
                            axis=1)
        return column(self._positions), column(self._velocities)


class _MinTable:
    """Range minima of a fixed array in O(1) per query (a sparse table)."""

    def __init__(self, values: np.ndarray) -> None:
        self.levels: List[np.ndarray] = [np.asarray(values, dtype=np.float64)]
        width = 1
        while 2 * width <= len(values):
            last = self.levels[-1]
            self.levels.append(np.minimum(last[:-width], last[width:]))
            width *= 2

    def query(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Minimum over ``values[lo[k]:hi[k] + 1]`` for each k (``lo <= hi``)."""
        level = np.floor(np.log2(hi - lo + 1)).astype(np.int64)
        out = np.empty(len(lo))
        for k in np.unique(level):
            rows = np.flatnonzero(level == k)
            table = self.levels[k]
            out[rows] = np.minimum(table[lo[rows]], table[hi[rows] - (1 << int(k)) + 1])
        return out


def _within(s: np.ndarray, radius: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """First and last interval within ``radius`` of each interval (arc lengths ``s``)."""
    own = np.arange(len(s) - 1)
    lo = np.minimum(np.searchsorted(s[1:], s[:-1] - radius, side='right'), own)
    hi = np.maximum(np.searchsorted(s[:-1], s[1:] + radius, side='left') - 1, own)
    return lo, hi


def _self_reach_min(s: np.ndarray, caps: '_MinTable', tau: float) -> np.ndarray:
    """Largest ``c`` per interval with ``c <= min(cap)`` over the intervals within ``tau c``.

    With every speed of ``s0`` at arc length ``y`` at most this ``c(y)``, the window of the
    moving average at ``x`` spans at most ``tau`` times its largest ``c``, and that largest
    ``c`` is then within reach of ``x``, so at most ``cap(x)`` (module docstring, step 3).
    Found by bisection on ``c``: the minimum over the reach only falls as ``c`` grows.
    """
    low = np.zeros(len(s) - 1)
    high = caps.levels[0].copy()
    for _ in range(_REACH_BISECTIONS):
        trial = 0.5 * (low + high)
        lo, hi = _within(s, tau * trial)
        fits = trial <= caps.query(lo, hi)
        low = np.where(fits, trial, low)
        high = np.where(fits, high, trial)
    lo, hi = _within(s, tau * low)
    return np.minimum(low, caps.query(lo, hi))


def _reach_min(s: np.ndarray, values: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """For each interval, the smallest value of the intervals that reach it.

    Interval ``i`` reaches every interval within ``radius[i]`` of it. The radii are rounded up
    to :data:`_REACH_LEVELS` geometric levels (reaching further is only more cautious), and
    each level is one sliding minimum.
    """
    out = np.asarray(values, dtype=np.float64).copy()
    top = float(np.max(radius)) if len(radius) else 0.0
    if not top > 0.0:
        return out
    ladder = top * _REACH_RATIO ** np.arange(_REACH_LEVELS)[::-1]
    level = np.minimum(np.searchsorted(ladder, radius, side='left'), _REACH_LEVELS - 1)
    for k in np.unique(level):
        masked = np.where(level == k, values, np.inf)
        lo, hi = _within(s, np.full(len(values), ladder[k]))
        out = np.minimum(out, _MinTable(masked).query(lo, hi))
    return out


def _profile(stations: _Stations, cap: np.ndarray, alpha: np.ndarray, tau: float,
             start: Optional[StartMotion]) -> Tuple[ArcProfile, float, float]:
    """The averaged profile (module docstring, steps 2 and 3) and the start it kept."""
    length = float(stations.s[-1])
    start_speed, start_accel = 0.0, 0.0
    history: List[Tuple[float, float, float, float]] = [(-tau, 0.0, 0.0, 0.0)]
    first, u0 = 0, 0.0
    s, stop, ds, reach2, back = _passes(stations.s, stations.stop, cap, alpha, None)
    if start is not None:
        a = min(max(float(start.accel), -float(alpha[0])), float(alpha[0]))
        v = float(start.speed)
        # s0 starts at `launch` with speed `ahead`, so that the mean over the window is at the
        # start with the vehicle's speed and acceleration. Too fast to brake for the curve: the
        # largest speed that can (`launch` moves with it, so a few rounds).
        # s0's history over [-tau, 0] (_history) makes the mean over the window start with
        # the vehicle's speed and acceleration.
        brisk = float(alpha[0])
        for _ in range(_LAUNCH_ROUNDS):
            ahead, launch, pieces, fastest = _history(v, a, tau, brisk)
            if not (0.0 < launch < length and ahead > 0.0):
                break
            trial = _passes(stations.s, stations.stop, cap, alpha, launch)
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
    u = np.asarray(_forward(back, reach2.tolist(), first, u0))
    # Where s0 turns from accelerating to braking (or back) at once, its acceleration jumps by
    # twice alpha, which only the longest window proves; a plateau of tau seconds at the turn
    # halves the jump, so shorter windows (a smaller lag behind s0) prove the jerk too.
    for _ in range(_PLATEAU_ROUNDS):
        level = _plateaus(s, u, first, tau)
        if not np.any(np.isfinite(level)):
            break
        lowered = _backward(np.minimum(back, level).tolist(), reach2.tolist())
        if u0 > lowered[first] * (1.0 + 1e-12):
            break   # the moving start could not brake for them: keep the profile as it is
        back = lowered
        u = np.asarray(_forward(back, reach2.tolist(), first, u0))
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


def _jerk_fits(profile: ArcProfile, s: np.ndarray, allowance: '_MinTable') -> bool:
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
    arc = _arc_at(profile, merged)
    last = len(s) - 2
    lo = np.clip(np.searchsorted(s, arc[:-1], side='right') - 1, 0, last)
    hi = np.clip(np.searchsorted(s, arc[1:], side='left') - 1, 0, last)
    hi = np.maximum(hi, lo)
    return bool(np.all(jerk <= allowance.query(lo, hi) * (1.0 + 1e-9)))


def _history(v: float, a: float, tau: float,
             brisk: float) -> Tuple[float, float, List[Tuple[float, float, float, float]], float]:
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
                                              List[float]]:
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
    return s, stop, ds, reach2, _backward(ucap.tolist(), reach2.tolist())


def _backward(ucap: List[float], reach2: List[float]) -> List[float]:
    """Largest ``u`` at each station from which every later cap can still be kept."""
    back = list(ucap)
    for j in range(len(back) - 2, -1, -1):
        back[j] = min(back[j], back[j + 1] + reach2[j])
    return back


def _forward(back: List[float], reach2: List[float], first: int, u0: float) -> List[float]:
    """Fastest ``u`` from station ``first`` (at ``u0``) within the backward limits."""
    u = list(back)
    u[first] = u0
    for j in range(first, len(u) - 1):
        u[j + 1] = min(back[j + 1], u[j] + reach2[j])
    for j in range(first):
        u[j] = 0.0
    return u


def _times_of(profile: ArcProfile, arc: np.ndarray) -> np.ndarray:
    """The times at which the averaged profile passes the arc lengths ``arc`` [s]."""
    duration = profile.duration_s
    step = profile.window_s / 4.0
    grid = np.linspace(0.0, duration, max(2, int(math.ceil(duration / step)) + 1))
    grid_s = _arc_at(profile, grid)
    grid_s = np.maximum.accumulate(grid_s)
    right = np.clip(np.searchsorted(grid_s, arc, side='left'), 1, len(grid) - 1)
    lo, hi = grid[right - 1], grid[right]
    for _ in range(_BISECTIONS):
        mid = 0.5 * (lo + hi)
        below = _arc_at(profile, mid) < arc
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    times = hi
    times[0] = 0.0
    times[-1] = duration
    return times


def _arc_at(profile: ArcProfile, t: np.ndarray) -> np.ndarray:
    tau = profile.window_s
    return (profile.integral(t) - profile.integral(t - tau)) / tau


def _at_rest(smoothed: SmoothedPath, limits: MotionLimits, yaw_mode: str,
             initial_yaw: Optional[float]) -> TimingResult:
    """A trajectory of one point (start and goal together)."""
    count = len(smoothed.positions)
    zeros = np.zeros((count, 3))
    yaw = 0.0 if initial_yaw is None else float(initial_yaw)
    trajectory = Trajectory(times=np.zeros(count), positions=smoothed.positions.copy(),
                            velocities=zeros, accelerations=zeros.copy(), jerks=zeros.copy(),
                            yaws=np.full(count, yaw), yaw_rates=np.zeros(count),
                            reference=None)
    del limits, yaw_mode
    return TimingResult(trajectory=trajectory, window_s=0.0, start_speed=0.0,
                        start_accel=0.0)


def check_limits(trajectory: Trajectory, limits: MotionLimits, step_s: float = 0.005,
                 rtol: float = 1e-6) -> List[str]:
    """Describe every limit the continuous reference breaks at a ``step_s`` grid of times.

    An empty list means none. The acceleration box of the limits (tilt and thrust included),
    the jerk norm, the speeds and the yaw rate are checked, each with relative tolerance
    ``rtol``, and the times of the samples must increase strictly.
    """
    box = limits.acceleration_box()
    peaks = trajectory.peaks(step_s)
    problems = []
    checks = (('horizontal speed', peaks.speed_horizontal, limits.speed_horizontal, 'm/s'),
              ('vertical speed', peaks.speed_vertical, limits.speed_vertical, 'm/s'),
              ('horizontal acceleration', peaks.accel_horizontal, box.horizontal, 'm/s^2'),
              ('vertical acceleration', peaks.accel_vertical, box.vertical, 'm/s^2'),
              ('jerk', peaks.jerk, limits.jerk, 'm/s^3'),
              ('tilt', peaks.tilt_deg, limits.tilt_deg, 'deg'),
              ('thrust-to-weight ratio', peaks.thrust_to_weight, limits.thrust_to_weight, ''),
              ('yaw rate', peaks.yaw_rate, limits.yaw_rate, 'rad/s'))
    for name, value, limit, unit in checks:
        if value > limit * (1.0 + rtol):
            problems.append(f'{name} {value:.6g} {unit} exceeds {limit:g} {unit}'.rstrip())
    times = trajectory.times
    if len(times) > 1 and not np.all(np.diff(times) > 0.0):
        problems.append('times are not strictly increasing')
    return problems


def longest_crawl(trajectory: Trajectory, below: float = 0.01, step_s: float = 0.01) -> float:
    """Longest time [s] the reference moves slower than ``below`` [m/s] before its end.

    A crawl: the speed is sampled every ``step_s`` [s] from the start; the last sample (the
    stop at the end) is left out. A stop at a corner takes a fraction of a second.
    """
    times = np.arange(0.0, trajectory.duration_s, step_s)
    slow = np.linalg.norm(trajectory.state_at(times).velocity, axis=1) < below
    longest = run = 0
    for flag in slow[:-1]:
        run = run + 1 if flag else 0
        longest = max(longest, run)
    return longest * step_s


__all__ = ['MIN_ALPHA_SHARE', 'StartMotion', 'TimingResult',
           'time_parameterize', 'check_limits', 'longest_crawl', 'YawProfile']
