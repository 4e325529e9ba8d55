"""The planner's timed trajectory as the flat outputs of a geometric controller.

:func:`reference_at` evaluates the continuous reference
(:meth:`uav_global_planner.core.result.Trajectory.state_at`) at the controller's times, all at
once; :func:`flat_output` hands one of them to RotorPy's ``SE3Control``. Times past the end
give the goal at rest, as ``state_at`` clamps them.
"""

from typing import Any, Dict

import numpy as np

from uav_global_planner.core.result import ReferenceState, Trajectory


def trajectory_of(trajectory_like: Any) -> Trajectory:
    """The trajectory itself, given one or anything with a ``trajectory`` (a PlanResult).

    Raises
    ------
    ValueError
        When there is no trajectory (a failed plan) or it has fewer than two samples.
    """
    trajectory = getattr(trajectory_like, 'trajectory', trajectory_like)
    if trajectory is None:
        raise ValueError('no trajectory to fly (the plan failed)')
    if len(np.asarray(trajectory.times)) < 2:
        raise ValueError('a trajectory needs at least two samples to be flown')
    return trajectory


def reference_at(trajectory_like: Any, times: np.ndarray) -> ReferenceState:
    """The reference of a trajectory (or a PlanResult) at ``times`` [s]."""
    return trajectory_of(trajectory_like).state_at(np.asarray(times, dtype=np.float64))


def flat_output(reference: ReferenceState, k: int) -> Dict[str, Any]:
    """State ``k`` as the flat outputs RotorPy's ``SE3Control.update`` reads (ENU)."""
    return {'x': reference.position[k], 'x_dot': reference.velocity[k],
            'x_ddot': reference.acceleration[k], 'x_dddot': reference.jerk[k],
            'x_ddddot': np.zeros(3), 'yaw': float(reference.yaw[k]),
            'yaw_dot': float(reference.yaw_rate[k]), 'yaw_ddot': 0.0}
