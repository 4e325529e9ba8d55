"""The heading of the timed reference: continuous, within the yaw-rate limit.

Three modes (the setting ``yaw_mode``), all in the ENU planning frame (yaw 0 along +x,
counter-clockwise positive):

- ``velocity``: along the horizontal direction of travel; while the horizontal speed is below
  :data:`HEADING_SPEED` (take-off, landing, hover, vertical climbs) the last heading is kept;
- ``fixed``: the heading at the start throughout;
- ``goal``: towards the goal's horizontal position, kept within :data:`GOAL_HOLD` of it.

The wanted heading is followed on a grid of :data:`YAW_STEP` seconds by a turn whose rate
never exceeds ``max_yaw_rate`` and whose rate changes at most at :data:`YAW_ACCELERATION`
(it starts braking its turn in time, the shorter way round). Between grid times the yaw
acceleration is constant, so the heading and its rate are continuous at every time and both
limits hold between grid times too.
"""

from dataclasses import dataclass
import math
from typing import Callable, Optional, Tuple

import numpy as np

#: Grid step of the heading profile [s].
YAW_STEP = 0.05

#: Largest yaw acceleration of the heading profile [rad/s^2]: a jump in the yaw rate asks
#: the rotors for a torque step; a few rad/s^2 is what small multirotors turn with smoothly.
YAW_ACCELERATION = 2.0

#: Horizontal speed below which the ``velocity`` mode keeps its heading [m/s].
HEADING_SPEED = 0.2

#: Horizontal distance to the goal within which the ``goal`` mode keeps its heading [m].
GOAL_HOLD = 0.5


@dataclass(frozen=True, eq=False)
class YawProfile:
    """Heading at grid times with its rate, and a constant yaw acceleration in between.

    Attributes
    ----------
    times : numpy.ndarray, shape (n,)
        Grid times [s], from 0 to the end of the trajectory.
    yaws : numpy.ndarray, shape (n,)
        Heading [rad], unwrapped (continuous, may leave [-pi, pi]).
    rates : numpy.ndarray, shape (n,)
        Yaw rate [rad/s].
    accelerations : numpy.ndarray, shape (n,)
        Yaw acceleration from each grid time to the next [rad/s^2].
    """

    times: np.ndarray
    yaws: np.ndarray
    rates: np.ndarray
    accelerations: np.ndarray

    def evaluate(self, times: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """Heading wrapped to (-pi, pi] [rad] and yaw rate [rad/s] at ``times`` [s]."""
        t = np.asarray(times, dtype=np.float64)
        k = np.clip(np.searchsorted(self.times, t, side='right') - 1, 0, len(self.times) - 1)
        dt = np.clip(t - self.times[k], 0.0, None)
        dt = np.where(k == len(self.times) - 1, 0.0, dt)
        accel = self.accelerations[k]
        rate = self.rates[k] + accel * dt
        yaw = self.yaws[k] + self.rates[k] * dt + 0.5 * accel * dt * dt
        return _wrap(yaw), rate


def _wrap(angle: np.ndarray) -> np.ndarray:
    return np.pi - np.mod(np.pi - angle, 2.0 * np.pi)


def yaw_profile(mode: str, duration_s: float, max_yaw_rate: float,
                state: Callable[[np.ndarray], Tuple[np.ndarray, np.ndarray]],
                goal: np.ndarray, initial_yaw: Optional[float] = None) -> YawProfile:
    """The heading profile of a trajectory.

    Parameters
    ----------
    mode : str
        ``'velocity'``, ``'fixed'`` or ``'goal'``.
    duration_s : float
        Flight time [s].
    max_yaw_rate : float
        [rad/s], > 0.
    state : callable
        ``state(times) -> (positions, velocities)`` of the reference, shapes (n, 3) [m], [m/s].
    goal : numpy.ndarray, shape (3,)
        [m].
    initial_yaw : float, optional
        Heading at the start [rad]; when None the first wanted heading (no turn at the start).
    """
    count = max(2, int(np.ceil(duration_s / YAW_STEP)) + 1)
    times = np.linspace(0.0, max(duration_s, 0.0), count)
    positions, velocities = state(times)
    if mode == 'velocity':
        wanted = np.arctan2(velocities[:, 1], velocities[:, 0])
        valid = np.hypot(velocities[:, 0], velocities[:, 1]) >= HEADING_SPEED
    elif mode == 'goal':
        offset = goal[None, :2] - positions[:, :2]
        wanted = np.arctan2(offset[:, 1], offset[:, 0])
        valid = np.hypot(offset[:, 0], offset[:, 1]) >= GOAL_HOLD
    elif mode == 'fixed':
        wanted = np.zeros(count)
        valid = np.zeros(count, dtype=bool)
    else:
        raise ValueError(f'yaw_mode must be one of velocity, fixed, goal, got {mode!r}')
    first = np.flatnonzero(valid)
    if initial_yaw is not None and np.isfinite(initial_yaw):
        current = float(initial_yaw)
    elif len(first):
        current = float(wanted[first[0]])
    else:
        current = 0.0
    step = float(times[1] - times[0])
    yaws = np.empty(count)
    rates = np.zeros(count)
    accels = np.zeros(count)
    yaws[0] = current
    rate = 0.0
    limit = YAW_ACCELERATION
    wanted_list, valid_list = wanted.tolist(), valid.tolist()
    # The follower is sequential by nature (each step depends on the last); the grid has
    # 20 points per second of flight.
    for k in range(count - 1):
        target = 0.0
        if valid_list[k + 1]:
            error = math.pi - (math.pi - (wanted_list[k + 1] - current)) % (2.0 * math.pi)
            # The fastest rate from which the turn still stops at the heading wanted.
            reach = min(max_yaw_rate, math.sqrt(2.0 * limit * abs(error)), abs(error) / step)
            target = math.copysign(reach, error)
        accel = min(max((target - rate) / step, -limit), limit)
        current += rate * step + 0.5 * accel * step * step
        # The target is within the rate limit and the step does not pass it: no clamp needed.
        rate += accel * step
        accels[k] = accel
        yaws[k + 1] = current
        rates[k + 1] = rate
    return YawProfile(times=times, yaws=yaws, rates=rates, accelerations=accels)
