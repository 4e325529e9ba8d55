"""The vehicle's motion limits, and the acceleration box that keeps its tilt and thrust.

A multirotor makes its acceleration ``a`` (ENU, z up) by tilting its collective thrust
``f = m (a + g e_z)``. Its tilt from the vertical is ``atan(|a_h| / (g + a_z))`` and its
thrust-to-weight ratio is ``|a + g e_z| / g``. :func:`acceleration_box` chooses horizontal and
vertical limits ``A_h``, ``A_z`` such that every acceleration with ``|a_h| <= A_h`` and
``|a_z| <= A_z`` keeps both: the worst corner of the box is ``(A_h, -A_z)`` for the tilt and
``(A_h, +A_z)`` for the thrust, so the two conditions

    A_h <= (g - A_z) tan(max_tilt)          and          A_h^2 + (g + A_z)^2 <= (r g)^2

prove the limits for the whole box. The time parameterisation then keeps the reference's
acceleration inside the box, which makes tilt and thrust limits as exact as the acceleration
limits themselves.
"""

from dataclasses import dataclass
import math
from typing import Tuple

import numpy as np

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.settings import check_setting

#: Standard gravity [m/s^2].
GRAVITY = 9.80665

#: Largest share of the thrust above the weight that vertical acceleration may take, so a
#: vertical limit close to the thrust limit still leaves thrust to accelerate sideways [-].
_VERTICAL_SHARE = 0.5


#: The setting that checks each limit (its range and the words of its refusal).
_SETTING_OF = {'speed_horizontal': 'max_speed_horizontal', 'speed_vertical': 'max_speed_vertical',
               'accel_horizontal': 'max_accel_horizontal', 'accel_vertical': 'max_accel_vertical',
               'jerk': 'max_jerk', 'tilt_deg': 'max_tilt',
               'thrust_to_weight': 'max_thrust_to_weight', 'yaw_rate': 'max_yaw_rate'}


@dataclass(frozen=True)
class MotionLimits:
    """Limits of the timed reference (ENU: horizontal is x, y; vertical is z).

    Attributes
    ----------
    speed_horizontal, speed_vertical : float
        Norm of (vx, vy) and ``|vz|`` [m/s].
    accel_horizontal, accel_vertical : float
        Norm of (ax, ay) and ``|az|`` [m/s^2], as configured (before tilt and thrust).
    jerk : float
        Norm of the jerk vector [m/s^3].
    tilt_deg : float
        Tilt of the collective thrust from the vertical [deg], in (0, 90).
    thrust_to_weight : float
        Collective thrust over weight [-], > 1.
    yaw_rate : float
        ``|d yaw / dt|`` [rad/s].

    Raises
    ------
    InvalidInputError
        Naming the setting (``max_jerk`` ...) of a limit out of its range.
    """

    speed_horizontal: float = 2.0
    speed_vertical: float = 1.0
    accel_horizontal: float = 1.0
    accel_vertical: float = 0.5
    jerk: float = 10.0
    tilt_deg: float = 35.0
    thrust_to_weight: float = 2.0
    yaw_rate: float = 0.785

    def __post_init__(self) -> None:
        for attribute, name in _SETTING_OF.items():
            check_setting(name, getattr(self, attribute))

    @classmethod
    def from_config(cls, config: PlannerConfig) -> 'MotionLimits':
        """The limits of a validated :class:`PlannerConfig`."""
        return cls(speed_horizontal=float(config.max_speed_horizontal),
                   speed_vertical=float(config.max_speed_vertical),
                   accel_horizontal=float(config.max_accel_horizontal),
                   accel_vertical=float(config.max_accel_vertical),
                   jerk=float(config.max_jerk), tilt_deg=float(config.max_tilt),
                   thrust_to_weight=float(config.max_thrust_to_weight),
                   yaw_rate=float(config.max_yaw_rate))

    def acceleration_box(self) -> 'AccelerationBox':
        """The horizontal and vertical acceleration limits that also keep tilt and thrust."""
        return acceleration_box(self)


@dataclass(frozen=True)
class AccelerationBox:
    """Acceleration limits in force [m/s^2] and which limit made each.

    Attributes
    ----------
    horizontal, vertical : float
        Limits on the norm of (ax, ay) and on ``|az|`` [m/s^2].
    horizontal_by, vertical_by : str
        ``'acceleration'``, ``'tilt'`` or ``'thrust'``.
    """

    horizontal: float
    vertical: float
    horizontal_by: str
    vertical_by: str


def acceleration_box(limits: MotionLimits) -> AccelerationBox:
    """Largest acceleration box within the acceleration, tilt and thrust limits.

    The vertical limit is the configured one, lowered where the thrust above the weight is
    short (at most half of ``(r - 1) g`` goes to vertical acceleration, and at most ``g / 2``,
    so the tilt bound ``(g - A_z) tan(theta)`` stays positive); the horizontal limit is the
    configured one lowered by the tilt and the thrust conditions of the module docstring.
    """
    g = GRAVITY
    spare = (limits.thrust_to_weight - 1.0) * g
    vertical, vertical_by = limits.accel_vertical, 'acceleration'
    if _VERTICAL_SHARE * spare < vertical:
        vertical, vertical_by = _VERTICAL_SHARE * spare, 'thrust'
    if 0.5 * g < vertical:
        vertical, vertical_by = 0.5 * g, 'tilt'
    by_tilt = (g - vertical) * math.tan(math.radians(limits.tilt_deg))
    by_thrust = math.sqrt(max((limits.thrust_to_weight * g) ** 2 - (g + vertical) ** 2, 0.0))
    horizontal, horizontal_by = limits.accel_horizontal, 'acceleration'
    if by_tilt < horizontal:
        horizontal, horizontal_by = by_tilt, 'tilt'
    if by_thrust < horizontal:
        horizontal, horizontal_by = by_thrust, 'thrust'
    return AccelerationBox(horizontal, vertical, horizontal_by, vertical_by)


def tilt_and_thrust(accelerations: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Tilt [deg] and thrust-to-weight ratio [-] of the thrust that makes each acceleration.

    Parameters
    ----------
    accelerations : numpy.ndarray, shape (N, 3)
        ENU accelerations [m/s^2].
    """
    a = np.asarray(accelerations, dtype=np.float64).reshape(-1, 3)
    horizontal = np.hypot(a[:, 0], a[:, 1])
    up = GRAVITY + a[:, 2]
    return np.degrees(np.arctan2(horizontal, up)), np.hypot(horizontal, up) / GRAVITY
