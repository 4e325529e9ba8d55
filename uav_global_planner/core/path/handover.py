"""Planning from a moving state: the start conditions of the curve and of its timing.

A replan in flight starts where the plan in force will be when the new one takes over, with
that plan's velocity ``v`` and acceleration ``a`` there (ENU). The new reference continues
them without a jump when

- its curve leaves the start along ``T = v / |v|`` with the curvature vector
  ``K = (a - (a . T) T) / |v|^2`` (the normal part of the acceleration is ``|v|^2 K``), and
- its timing starts with speed ``|v|`` and tangential acceleration ``a . T``

(:mod:`uav_global_planner.core.path.smoothing` and :mod:`uav_global_planner.core.path.timing` keep
one each). :class:`Handover` turns the state into both and measures what the plan kept.
"""

from dataclasses import dataclass
from typing import Any, Optional, Tuple

import numpy as np

from uav_global_planner.core.checks import check_number, check_path, check_point
from uav_global_planner.core.path.motion_limits import MotionLimits
from uav_global_planner.core.path.smoothing import SmoothedPath
from uav_global_planner.core.path.timing import MIN_ALPHA_SHARE, StartMotion
from uav_global_planner.core.result import Trajectory

#: Below this speed a start counts as at rest [m/s].
HANDOVER_MIN_SPEED = 0.05

#: Largest start curvature asked of the curve [1/m]: at the slow speeds where the
#: acceleration's normal part would ask for more, the difference is small.
MAX_START_CURVATURE = 2.0


def _vector(value: Any, name: str) -> np.ndarray:
    return np.zeros(3) if value is None else check_point(name, value)


@dataclass(frozen=True, eq=False)
class Handover:
    """The moving state a plan starts from.

    Attributes
    ----------
    velocity : numpy.ndarray, shape (3,)
        [m/s] (ENU).
    acceleration : numpy.ndarray, shape (3,)
        [m/s^2] (ENU).
    yaw : float or None
        Heading [rad] (ENU).
    path : numpy.ndarray or None, shape (N, 3)
        Where the plan in force goes on from the start [m]: the new curve follows it for its
        lead-in, so the speed the vehicle has fits the curve it flies next.
    """

    velocity: np.ndarray
    acceleration: np.ndarray
    yaw: Optional[float] = None
    path: Optional[np.ndarray] = None

    @classmethod
    def of(cls, velocity: Any = None, acceleration: Any = None,
           yaw: Optional[float] = None, path: Any = None) -> 'Handover':
        """Checked state; ``None`` parts are zero.

        Raises
        ------
        InvalidInputError
            Naming ``start_velocity``, ``start_acceleration``, ``start_yaw`` or ``start_path``
            when it is not finite or not three numbers (a row of three for the path).
        """
        if yaw is not None:
            yaw = check_number('start_yaw', yaw)
        points = None if path is None else check_path('start_path', path, allow_empty=True)
        return cls(_vector(velocity, 'start_velocity'),
                   _vector(acceleration, 'start_acceleration'), yaw, points)

    @property
    def speed(self) -> float:
        """[m/s]."""
        return float(np.linalg.norm(self.velocity))

    @property
    def moving(self) -> bool:
        """True at or above :data:`HANDOVER_MIN_SPEED`."""
        return self.speed >= HANDOVER_MIN_SPEED

    def tangent_and_curvature(self) -> Tuple[np.ndarray, np.ndarray]:
        """Unit tangent [-] and curvature vector [1/m] the curve starts with."""
        speed = self.speed
        tangent = self.velocity / speed
        normal = self.acceleration - float(self.acceleration @ tangent) * tangent
        curvature = normal / speed ** 2
        size = float(np.linalg.norm(curvature))
        if size > MAX_START_CURVATURE:
            curvature *= MAX_START_CURVATURE / size
        return tangent, curvature

    def curve_start(self, limits: MotionLimits) -> Tuple[Optional[np.ndarray],
                                                         Optional[np.ndarray], Optional[float],
                                                         Optional[np.ndarray]]:
        """``start_tangent``, ``start_curvature``, ``start_lead_in`` [m] and
        ``start_lead_in_path`` of :func:`~uav_global_planner.core.path.smoothing.smooth_path`; all
        None from rest.

        The lead-in (the curve follows the start's osculating circle that far) is about the
        distance to brake from the vehicle's speed with the tangential acceleration a bend
        leaves, plus two averaging windows of travel (:mod:`uav_global_planner.core.path.timing`),
        so the new curve's first turn does not force the reference to start slower.
        """
        if not self.moving:
            return None, None, None, None
        tangent, curvature = self.tangent_and_curvature()
        box = limits.acceleration_box()
        braking = MIN_ALPHA_SHARE * min(box.horizontal, box.vertical) \
            if abs(float(tangent[2])) > 0.5 else MIN_ALPHA_SHARE * box.horizontal
        window = 2.0 * max(box.horizontal, box.vertical) / limits.jerk
        speed = self.speed
        lead_in = speed ** 2 / (2.0 * braking * MIN_ALPHA_SHARE) + 4.0 * speed * window
        return tangent, curvature, lead_in, self.path

    def motion_on(self, smoothed: SmoothedPath) -> StartMotion:
        """Speed and tangential acceleration the timing of ``smoothed`` starts with; from rest
        when the curve could not keep the start conditions."""
        if not self.moving or len(smoothed.tangents) < 2 or not smoothed.start_kept:
            return StartMotion()
        tangent = smoothed.tangents[0]
        return StartMotion(speed=float(self.velocity @ tangent),
                           accel=float(self.acceleration @ tangent))

    def error(self, trajectory: Trajectory) -> Tuple[float, float]:
        """How far the reference at time 0 is from this state: ``|dv|`` [m/s], ``|da|`` [m/s^2]."""
        if not len(trajectory.times):
            return 0.0, 0.0
        state = trajectory.state_at(0.0)
        return (float(np.linalg.norm(state.velocity[0] - self.velocity)),
                float(np.linalg.norm(state.acceleration[0] - self.acceleration)))
