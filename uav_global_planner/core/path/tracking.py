"""The vehicle's tracking error in the margin: slow down where the curve leaves little room.

The body keeps gamma when the vehicle's centre stays within ``room = d - gamma - r`` of the
reference, where ``d`` is the reference's distance to the nearest obstacle and ``r`` the
vehicle radius. The curve is certified at ``gamma + r + tracking_margin``, so the room is
never below the allowance; where the curve passes with just that, the reference slows so that
the predicted error fits.

The error model is linear in the reference speed ``v``::

    e(v) = TRACKING_ERROR_AT_REST + TRACKING_ERROR_PER_SPEED * v

the upper envelope, over every 1 s window flown, of the distance of the vehicle from the
reference's path (what the clearance depends on; the lag along the path does not bring the
body closer to an obstacle) in the still-air closed-loop flights of
``benchmarks/bench_flight.py``: RotorPy's multirotor with its ``SE3Control`` geometric
controller, with the Hummingbird (fit 0.031 m + 0.004 s * v) and the PX4 SIH (0.081 m +
0.009 s * v) parameter sets. Turbulence is not in the model: Dryden turbulence of 4 m/s RMS
moved the Hummingbird 0.58 m off the path (docs/flight.md), which a ``tracking_margin`` must
cover on its own. A vehicle whose controller tracks worse needs the benchmark's fit of its own.
"""

import numpy as np

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.map.obstacles import ObstacleSet

#: Tracking error of the model at hover [m].
TRACKING_ERROR_AT_REST = 0.08

#: Growth of the tracking error with the reference speed [m per m/s].
TRACKING_ERROR_PER_SPEED = 0.01

#: The slowest the reference is asked to fly for its tracking error [m/s]: where even that
#: does not fit, the allowance is too small for the model and the room is all there is.
MIN_TRACKING_SPEED = 0.3


def tracking_error(speed: np.ndarray) -> np.ndarray:
    """Predicted tracking error at ``speed`` [m/s] of the reference [m]."""
    return TRACKING_ERROR_AT_REST + TRACKING_ERROR_PER_SPEED * np.asarray(speed)


def tracking_speed_cap(positions: np.ndarray, obstacles: ObstacleSet,
                       config: PlannerConfig) -> np.ndarray:
    """Largest speed at each point [m/s] whose predicted tracking error fits the room left.

    Parameters
    ----------
    positions : numpy.ndarray, shape (M, 3)
        Samples of the curve [m].
    obstacles : ObstacleSet
    config : PlannerConfig
        gamma, vehicle radius and the speed limits.
    """
    top = max(float(config.max_speed_horizontal), float(config.max_speed_vertical))
    reserve = float(config.safety_margin) + float(config.vehicle_radius)
    # Beyond this distance even the top speed fits: the capped distance is enough.
    horizon = reserve + float(tracking_error(np.asarray(top))) + 1e-6
    distance = np.asarray(obstacles.distance(positions, cap=horizon), dtype=np.float64)
    room = distance - reserve
    cap = (room - TRACKING_ERROR_AT_REST) / TRACKING_ERROR_PER_SPEED
    return np.maximum(cap, MIN_TRACKING_SPEED)
