"""Time parameterisation of a smoothed path under separate horizontal and vertical limits.

The speed profile is found on the samples of
:class:`~uav_global_planner.core.smoothing.SmoothedPath` in the phase plane ``u = (ds/dt)^2``,
with constant tangential acceleration ``a_j = (u[j+1] - u[j]) / (2 ds_j)`` on the interval between
samples ``j`` and ``j + 1``; ``u`` is then linear in arc length and the speed exact for uniformly
accelerated motion along the arc. At a point with unit tangent ``T`` and curvature vector
``K = d2c/ds2`` the acceleration is ``a T + u K``. Writing ``_h`` for the norm of the (x, y) part
and ``_z`` for the absolute z part, and ``T_h``, ``T_z``, ``K_h``, ``K_z`` for their largest values
over the interval (``SmoothedPath.interval_tangent_max`` and ``interval_curvature_max``: the ends
plus every verification sample inside, <= delta / 20 apart), the limits are enforced through the
sufficient conditions, at both ends of every interval::

    sqrt(u) T_h <= v_h,        sqrt(u) T_z <= v_z                       (speed)
    |a| T_h + u K_h <= a_h,    |a| T_z + u K_z <= a_z                   (acceleration)

They bound the true components by the triangle inequality, and since they are linear in ``u``,
which is linear along the interval, they then hold at every point inside it as well (up to the
delta / 20 sampling of the maxima). The second line reads ``|a| <= g(u)``, ``g`` a minimum of
linear functions decreasing in ``u``; ``u K <= a_lim`` is the curvature (centripetal) limit. A
backward pass from the goal (largest ``u`` from which the vehicle can still brake) and a forward
pass from the start (largest ``u`` it can reach) give the time-optimal profile for these
conditions, and the monotonicity of ``g`` makes every interval satisfy them at both ends. The
speed is 0 at the start, the goal and every stop point (polyline corners, where the curve is not
C1).

The reported acceleration at a sample is the mean of the accelerations of the two intervals
meeting there (each with the tangent of its own side); both are within the limits, and so is
their mean, the limit set being convex. Velocities are ``sqrt(u) T``.
"""

import math
from typing import List

import numpy as np

from uav_global_planner.core.result import Trajectory
from uav_global_planner.core.settings import check_setting
from uav_global_planner.core.smoothing import SmoothedPath


def _split(vectors: np.ndarray):
    """Horizontal norm and vertical magnitude of each row."""
    return np.hypot(vectors[:, 0], vectors[:, 1]), np.abs(vectors[:, 2])


def _ratio(limit: float, component: np.ndarray) -> np.ndarray:
    """``limit / component`` with +inf where the component vanishes."""
    with np.errstate(divide='ignore'):
        return np.where(component > 0.0, limit / np.where(component > 0.0, component, 1.0),
                        np.inf)


def _inverse(component: np.ndarray) -> np.ndarray:
    """``1 / component``, 0 where the component vanishes (its term is dropped anyway)."""
    return np.where(component > 0.0, 1.0 / np.where(component > 0.0, component, 1.0), 0.0)


def time_parameterize(smoothed: SmoothedPath, max_speed_horizontal: float,
                      max_speed_vertical: float, max_accel_horizontal: float,
                      max_accel_vertical: float) -> Trajectory:
    """Fastest rest-to-rest timing of the samples within speed and acceleration limits.

    Parameters
    ----------
    smoothed : SmoothedPath
    max_speed_horizontal, max_speed_vertical : float
        Limits on the norm of (vx, vy) and on |vz| [m/s], > 0.
    max_accel_horizontal, max_accel_vertical : float
        Limits on the norm of (ax, ay) and on |az| [m/s^2], > 0.

    Returns
    -------
    Trajectory
        ``times`` strictly increasing from 0 [s]; ``positions`` the samples [m]; ``velocities``
        [m/s] zero at the start, the goal and every stop point; ``accelerations`` [m/s^2].
    """
    # The limits are checked by their table entries (core/settings.py).
    vh = check_setting('max_speed_horizontal', max_speed_horizontal)
    vz = check_setting('max_speed_vertical', max_speed_vertical)
    ah = check_setting('max_accel_horizontal', max_accel_horizontal)
    az = check_setting('max_accel_vertical', max_accel_vertical)
    positions = smoothed.positions
    count = len(positions)
    if count < 2:
        zeros = np.zeros((count, 3))
        return Trajectory(times=np.zeros(count), positions=positions.copy(), velocities=zeros,
                          accelerations=zeros.copy())

    tangent = smoothed.interval_tangent_max
    curvature = smoothed.interval_curvature_max
    # Per interval: g(u) = min_c (A_c - B_c u) with A = a_lim / T_max, B = K_max / T_max. Where a
    # tangent component vanishes, A = +inf drops the term (the cap below covers u K <= a_lim).
    limits = np.array([ah, az])
    coef_a = _ratio(1.0, tangent) * limits
    coef_b = curvature * _inverse(tangent)
    # Speed caps per interval (speed limits on T_max, curvature limit on K_max); a sample takes
    # the smaller of its two intervals'.
    interval_cap = np.minimum.reduce([_ratio(vh * vh, tangent[:, 0] ** 2),
                                      _ratio(vz * vz, tangent[:, 1] ** 2),
                                      _ratio(ah, curvature[:, 0]), _ratio(az, curvature[:, 1])])
    cap = np.minimum(np.r_[interval_cap, np.inf], np.r_[np.inf, interval_cap])
    cap[smoothed.stop_points] = 0.0
    ds = np.diff(smoothed.arc_length)
    u = _speed_profile(ds.tolist(), cap.tolist(), coef_a.tolist(), coef_b.tolist())

    speed = np.sqrt(u)
    tangential = (u[1:] - u[:-1]) / (2.0 * ds)
    dt = 2.0 * ds / (speed[1:] + speed[:-1])
    times = np.r_[0.0, np.cumsum(dt)]
    velocities = speed[:, None] * smoothed.tangents
    velocities[smoothed.stop_points] = 0.0
    centripetal = u[:, None] * smoothed.curvature_vectors
    leaving = tangential[:, None] * smoothed.tangents[:-1] + centripetal[:-1]
    arriving = tangential[:, None] * smoothed.incoming_tangents[1:] + centripetal[1:]
    accelerations = np.zeros((count, 3))
    accelerations[:-1] += leaving
    accelerations[1:] += arriving
    accelerations[1:-1] *= 0.5
    return Trajectory(times=times, positions=positions.copy(), velocities=velocities,
                      accelerations=accelerations)


def _speed_profile(ds: List[float], cap: List[float], coef_a: List[list],
                   coef_b: List[list]) -> np.ndarray:
    """Backward then forward pass over ``u = speed^2``; plain floats, one sample at a time."""
    count = len(cap)
    inf = math.inf

    def explicit(u: float, a: list, b: list) -> float:
        # g(u): the tangential acceleration left by the curvature terms.
        return min(a[0] - b[0] * u if a[0] != inf else inf,
                   a[1] - b[1] * u if a[1] != inf else inf)

    def implicit(base: float, step: float, a: list, b: list) -> float:
        # Largest u with u - base <= step * (A - B u) for both terms.
        out = inf
        for c in (0, 1):
            if a[c] != inf:
                out = min(out, (base + step * a[c]) / (1.0 + step * b[c]))
        return out

    back = [0.0] * count
    for j in range(count - 2, -1, -1):
        step = 2.0 * ds[j]
        nxt = back[j + 1]
        reach = min(nxt + step * explicit(nxt, coef_a[j], coef_b[j]),
                    implicit(nxt, step, coef_a[j], coef_b[j]))
        back[j] = min(cap[j], max(nxt, reach))
    u = [0.0] * count
    for j in range(count - 1):
        step = 2.0 * ds[j]
        cur = u[j]
        reach = min(cur + step * explicit(cur, coef_a[j], coef_b[j]),
                    implicit(cur, step, coef_a[j], coef_b[j]))
        u[j + 1] = min(back[j + 1], max(cur, reach))
    return np.maximum(np.asarray(u), 0.0)


def check_limits(trajectory: Trajectory, max_speed_horizontal: float, max_speed_vertical: float,
                 max_accel_horizontal: float, max_accel_vertical: float,
                 rtol: float = 1e-6) -> List[str]:
    """Describe every limit the trajectory's samples break; an empty list means none.

    Parameters
    ----------
    trajectory : Trajectory
    max_speed_horizontal, max_speed_vertical : float
        [m/s]
    max_accel_horizontal, max_accel_vertical : float
        [m/s^2]
    rtol : float
        Relative tolerance on each limit [-].
    """
    problems = []
    checks = (('horizontal speed', trajectory.velocities, 'h', max_speed_horizontal, 'm/s'),
              ('vertical speed', trajectory.velocities, 'z', max_speed_vertical, 'm/s'),
              ('horizontal acceleration', trajectory.accelerations, 'h', max_accel_horizontal,
               'm/s^2'),
              ('vertical acceleration', trajectory.accelerations, 'z', max_accel_vertical,
               'm/s^2'))
    for name, vectors, axis, limit, unit in checks:
        if not len(vectors):
            continue
        horizontal, vertical = _split(vectors)
        values = horizontal if axis == 'h' else vertical
        worst = int(np.argmax(values))
        if values[worst] > limit * (1.0 + rtol):
            problems.append(f'{name} {values[worst]:.6g} {unit} exceeds {limit:g} {unit} at '
                            f'sample {worst} (t = {trajectory.times[worst]:.3f} s)')
    times = trajectory.times
    if len(times) > 1 and not np.all(np.diff(times) > 0.0):
        problems.append('times are not strictly increasing')
    return problems
