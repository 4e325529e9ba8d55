"""Checks of a timed reference against the motion limits, at a dense grid of times.

:func:`check_limits` lists every limit the continuous reference breaks, :func:`longest_crawl`
finds where it creeps along. Both sample the reference (tests and benchmarks measure with them);
the limits themselves are proved by construction in :mod:`uav_global_planner.core.path.timing`.
"""

from typing import List

import numpy as np

from uav_global_planner.core.path.motion_limits import MotionLimits
from uav_global_planner.core.result import Trajectory


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
