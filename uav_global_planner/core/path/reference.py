"""The continuous timed reference: arc length as a function of time, on the certified curve.

The reference flies the certified curve ``c(s)`` (path-velocity decomposition: the certificate
of the curve is the certificate of the reference) with the arc length ``s(t)`` of
:class:`ArcProfile`. With the unit tangent ``T = c'``, the curvature vector ``K = c''`` and
its derivative ``K' = c'''`` (derivatives by arc length)::

    velocity      = s_t T
    acceleration  = s_tt T + s_t^2 K
    jerk          = s_ttt T + 3 s_t s_tt K + s_t^3 K'

:class:`ArcProfile` is a moving average, over a window of ``tau`` seconds, of a profile
``s0(t)`` with piecewise constant acceleration (the construction is in
:mod:`uav_global_planner.core.path.timing`)::

    s(t) = (1 / tau) * integral of s0 over [t - tau, t]

so ``s_t = (s0(t) - s0(t - tau)) / tau``, ``s_tt = (s0_t(t) - s0_t(t - tau)) / tau`` and
``s_ttt = (s0_tt(t) - s0_tt(t - tau)) / tau``: the acceleration is continuous (``s0_t`` is)
and the jerk piecewise constant. Every value here is exact (piecewise polynomials), not
sampled.
"""

from dataclasses import dataclass
from typing import Tuple

import numpy as np

from uav_global_planner.core.path.curve import PathCurve
from uav_global_planner.core.path.piecewise import PiecewisePolynomial
from uav_global_planner.core.path.yaw import YawProfile
from uav_global_planner.core.result import ReferenceState


@dataclass(frozen=True, eq=False)
class ArcProfile:
    """Arc length along the curve as a function of time: the moving average of ``s0``.

    Attributes
    ----------
    base : PiecewisePolynomial
        ``s0(t)`` [m], quadratic pieces from ``t = -window_s`` on, constant after its end.
    integral : PiecewisePolynomial
        Its antiderivative [m s].
    window_s : float
        The averaging window tau [s], > 0.
    duration_s : float
        Time at which ``s(t)`` reaches the end of the curve and stays [s].
    length_m : float
        Arc length of the curve [m].
    """

    base: PiecewisePolynomial
    integral: PiecewisePolynomial
    window_s: float
    duration_s: float
    length_m: float

    def evaluate(self, times: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray,
                                                   np.ndarray]:
        """``s``, ``s_t``, ``s_tt`` and ``s_ttt`` at ``times`` [s] (clamped to the profile).

        Returns
        -------
        tuple of numpy.ndarray
            Arc length [m], speed [m/s], tangential acceleration [m/s^2] and its rate [m/s^3].
        """
        tau = self.window_s
        t = np.clip(np.asarray(times, dtype=np.float64), 0.0, self.duration_s)
        earlier = t - tau
        s = (self.integral(t) - self.integral(earlier)) / tau
        speed = (self.base(t) - self.base(earlier)) / tau
        accel = (self.base(t, 1) - self.base(earlier, 1)) / tau
        jerk = (self.base(t, 2) - self.base(earlier, 2)) / tau
        return np.clip(s, 0.0, self.length_m), np.maximum(speed, 0.0), accel, jerk


@dataclass(frozen=True, eq=False)
class TimedReference:
    """The exact reference: the curve flown with an :class:`ArcProfile`, and a heading.

    Attributes
    ----------
    curve : PathCurve
        The certified curve.
    arc : ArcProfile
        Arc length in time.
    yaw : YawProfile
        Heading in time.
    """

    curve: PathCurve
    arc: ArcProfile
    yaw: YawProfile

    @property
    def duration_s(self) -> float:
        """Flight time [s]."""
        return self.arc.duration_s

    def evaluate(self, times: np.ndarray) -> ReferenceState:
        """Position, velocity, acceleration, jerk, yaw and yaw rate at ``times`` [s]."""
        t = np.clip(np.asarray(times, dtype=np.float64).reshape(-1), 0.0, self.duration_s)
        s, speed, accel, jerk_s = self.arc.evaluate(t)
        position, tangent, curvature, curvature_rate = self.curve.derivatives3(s)
        # At a stop the speed is zero and the curve has no tangent of its own: keep the
        # state finite whatever side the evaluator took.
        tangent = np.nan_to_num(tangent)
        curvature = np.nan_to_num(curvature)
        curvature_rate = np.nan_to_num(curvature_rate)
        v = speed[:, None]
        a = accel[:, None]
        velocity = v * tangent
        acceleration = a * tangent + v ** 2 * curvature
        jerk = jerk_s[:, None] * tangent + 3.0 * v * a * curvature + v ** 3 * curvature_rate
        yaw, yaw_rate = self.yaw.evaluate(t)
        return ReferenceState(time=t, position=position, velocity=velocity,
                              acceleration=acceleration, jerk=jerk, yaw=yaw, yaw_rate=yaw_rate)


def profile_from_pieces(start_times: np.ndarray, positions: np.ndarray, speeds: np.ndarray,
                        accels: np.ndarray, end_time: float, window_s: float,
                        length_m: float) -> ArcProfile:
    """The :class:`ArcProfile` of a piecewise uniformly accelerated ``s0``.

    Parameters
    ----------
    start_times : numpy.ndarray, shape (n,)
        Start of each piece [s], increasing; the first is ``-window_s``.
    positions, speeds, accels : numpy.ndarray, shape (n,)
        ``s0``, ``s0_t`` and ``s0_tt`` at the start of each piece [m], [m/s], [m/s^2].
    end_time : float
        When ``s0`` reaches ``length_m`` and stops [s]; the profile ends ``window_s`` later.
    window_s : float
        The averaging window [s].
    length_m : float
        Arc length of the curve [m].
    """
    breaks = np.r_[start_times, end_time, end_time + 2.0 * window_s + 1.0]
    coef = np.zeros((3, len(start_times) + 1))
    coef[0, :-1] = 0.5 * accels
    coef[1, :-1] = speeds
    coef[2, :-1] = positions
    coef[2, -1] = length_m
    base = PiecewisePolynomial(coef, breaks)
    return ArcProfile(base=base, integral=base.antiderivative(), window_s=float(window_s),
                      duration_s=float(end_time + window_s), length_m=float(length_m))
