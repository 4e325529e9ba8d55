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
   the largest ``c <= min(w)`` over its own ``tau c``
   (:mod:`uav_global_planner.core.path.reach`). The time-optimal ``s0`` for those bounds comes
   from the backward and forward passes over ``u = v^2`` (``u`` is linear in arc length under a
   constant acceleration); where it turns straight from accelerating to braking, or back, it is
   held flat for ``tau``; it stops at each point where the curve is not C1 (polyline corners)
   and waits there ``tau`` seconds (:mod:`uav_global_planner.core.path.speed_profile`).

3. **A moving average.** ``s(t)`` is the mean of ``s0`` over ``[t - tau, t]``. Over such a
   window ``s0`` moves at most ``tau`` times its largest speed there, so every speed and
   acceleration of ``s0`` in the window keeps the bounds of the interval where ``s(t)`` is;
   their means do too, which proves speed, acceleration, tilt and thrust at every time.
   ``s_tt`` is continuous (``s0``'s speed is) and ``s_ttt = (s0_tt(t) - s0_tt(t - tau)) /
   tau`` is piecewise constant: :func:`~uav_global_planner.core.path.speed_profile.jerk_fits`
   holds each of its pieces exactly against
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
:mod:`uav_global_planner.core.path.limit_checks` samples a timed reference densely to check it.
"""

from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from uav_global_planner.core.path.interval_bounds import MIN_ALPHA_SHARE, Stations as _Stations
from uav_global_planner.core.path.limit_checks import check_limits, longest_crawl
from uav_global_planner.core.path.motion_limits import MotionLimits
from uav_global_planner.core.path.reach import MinTable, reach_min, self_reach_min
from uav_global_planner.core.path.reference import ArcProfile, TimedReference
from uav_global_planner.core.path.smoothing import SmoothedPath
from uav_global_planner.core.path.speed_profile import (build_profile, jerk_fits, speed_at,
                                                        times_of)
from uav_global_planner.core.path.yaw import yaw_profile, YawProfile
from uav_global_planner.core.result import Trajectory

#: Windows tried, in units of max(alpha) / J: the last one proves the jerk for any profile.
_WINDOW_FACTORS = (1.0, 2.0)
_MOVING_WINDOW_FACTORS = (1.0, 1.25, 1.5, 2.0)


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
    allowance = MinTable(zeta)
    # A moving start also wants the window that keeps its speed: a longer window makes s0
    # lead the mean by more, which a vehicle accelerating near its speed cap cannot.
    best: Optional[Tuple[ArcProfile, float, float]] = None
    for factor in _MOVING_WINDOW_FACTORS if moving else _WINDOW_FACTORS:
        tau = factor * shortest
        near_cap = self_reach_min(stations.s, cap, tau)
        near_alpha = reach_min(stations.s, alpha, tau * cap)
        found = build_profile(stations.s, stations.stop, near_cap, near_alpha, tau,
                              (start.speed, start.accel) if moving else None)
        if factor < 2.0 and not jerk_fits(found[0], stations.s, allowance):
            continue
        if best is None or found[1] > best[1]:
            best = found
        if not moving or found[1] >= start.speed:
            break
    assert best is not None  # the last window always proves the jerk
    profile, start_speed, start_accel = best
    times = times_of(profile, arc)
    yaw = yaw_profile(yaw_mode, profile.duration_s, limits.yaw_rate,
                      _SampledMotion(times, positions, speed_at(profile, times)[:, None]
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
    return TimingResult(trajectory=trajectory, window_s=profile.window_s, start_speed=start_speed,
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


__all__ = ['MIN_ALPHA_SHARE', 'StartMotion', 'TimingResult',
           'time_parameterize', 'check_limits', 'longest_crawl', 'YawProfile']
