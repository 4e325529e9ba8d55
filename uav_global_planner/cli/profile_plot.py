"""Speed, acceleration, jerk and tilt of a timed reference against time (matplotlib)."""

from pathlib import Path
from typing import Optional, Union

import matplotlib
matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402 - the backend must be first
import numpy as np  # noqa: E402

from uav_global_planner.core.path.motion_limits import MotionLimits, tilt_and_thrust  # noqa: E402
from uav_global_planner.core.result import Trajectory  # noqa: E402

#: Time step of the drawn curves [s].
_STEP = 0.01


def plot_profile(trajectory: Trajectory, limits: MotionLimits, output: Union[str, Path],
                 title: Optional[str] = None) -> None:
    """Four panels against time: speed, acceleration, jerk and tilt, each with its limits.

    Parameters
    ----------
    trajectory : Trajectory
        A planned trajectory (its continuous reference is evaluated every 10 ms).
    limits : MotionLimits
        Drawn as dashed lines; the acceleration panel shows the box that also keeps tilt and
        thrust.
    output : str or Path
        PNG file.
    title : str, optional
    """
    duration = trajectory.duration_s
    times = np.linspace(0.0, duration, max(2, int(np.ceil(duration / _STEP)) + 1))
    state = trajectory.state_at(times)
    tilt, _ = tilt_and_thrust(state.acceleration)
    box = limits.acceleration_box()
    figure, axes = plt.subplots(4, 1, figsize=(10, 10), sharex=True)
    panels = (
        ('speed [m/s]', state.velocity, limits.speed_horizontal, limits.speed_vertical),
        ('acceleration [m/s²]', state.acceleration, box.horizontal, box.vertical),
    )
    for ax, (label, vectors, horizontal, vertical) in zip(axes[:2], panels):
        ax.plot(times, np.hypot(vectors[:, 0], vectors[:, 1]), label='horizontal',
                color='tab:blue')
        ax.plot(times, np.abs(vectors[:, 2]), label='vertical', color='tab:red')
        ax.axhline(horizontal, color='tab:blue', linestyle='--', linewidth=0.8)
        ax.axhline(vertical, color='tab:red', linestyle='--', linewidth=0.8)
        ax.set_ylabel(label)
        ax.legend(loc='upper right')
    axes[2].plot(times, np.linalg.norm(state.jerk, axis=1), color='tab:green')
    axes[2].axhline(limits.jerk, color='tab:green', linestyle='--', linewidth=0.8)
    axes[2].set_ylabel('jerk [m/s³]')
    axes[3].plot(times, tilt, color='tab:purple')
    axes[3].axhline(limits.tilt_deg, color='tab:purple', linestyle='--', linewidth=0.8)
    axes[3].set_ylabel('tilt [deg]')
    axes[3].set_xlabel('time [s]')
    for ax in axes:
        ax.grid(True, alpha=0.3)
    figure.suptitle(title or 'timed reference')
    figure.tight_layout()
    figure.savefig(str(output), dpi=110)
    plt.close(figure)
