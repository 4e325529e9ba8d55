"""How a mission is built: :class:`MissionSettings`, its end actions and firmwares.

The settings are checked when they are made (:func:`check_number` for every number), so a
:class:`MissionSettings` always holds values :func:`~uav_global_planner.core.mission.build_mission`
can fly.
"""

from dataclasses import dataclass
import math
from typing import Any, Optional

import numpy as np

from uav_global_planner.core.errors import InvalidInputError

#: What the vehicle does after the goal (:attr:`MissionSettings.end`).
END_ACTIONS = ('loiter', 'land', 'rtl')
#: Autopilots a mission is written for (:attr:`MissionSettings.firmware`).
FIRMWARES = ('px4', 'ardupilot')


@dataclass(frozen=True)
class MissionSettings:
    """How the mission is built.

    Attributes
    ----------
    acceptance_radius : float
        R [m]: the autopilot's waypoint acceptance radius (PX4 ``NAV_ACC_RAD``, ArduPilot
        ``WPNAV_RADIUS``; also written as each waypoint's param 2). > 0.
    tracking_allowance : float
        a [m]: extra clearance for the autopilot's tracking error, >= 0. Legs and turn regions
        keep gamma + a.
    takeoff_height : float
        Height of the take-off climb above the start [m], >= R (PX4 raises takeoffs below
        ``MIS_TAKEOFF_ALT``, 2.5 m by default, to it: keep this at least as high).
    end : str
        ``loiter`` (hold at the goal), ``land`` (descend at the goal) or ``rtl`` (return home).
    rtl_altitude : float
        Return altitude above home [m] for ``rtl`` (must equal the autopilot's).
    firmware : str
        ``px4`` or ``ardupilot``: the ``.plan`` firmwareType, the yaw convention (PX4: NaN keeps
        the heading mode; ArduPilot: 0) and the speed items (ArduPilot also takes climb and
        descent speeds).
    ground_tolerance : float or None
        The start is on the ground when it is at most this far above the bounds' floor [m];
        None: the grid resolution delta.
    min_height : float or None
        Lowest height of waypoints above the bounds' floor (the ground) [m]; None: the required
        clearance gamma + tracking allowance. The goal and via-points stay where they are.
    """

    acceptance_radius: float = 1.0
    tracking_allowance: float = 0.1
    takeoff_height: float = 2.5
    end: str = 'loiter'
    rtl_altitude: float = 15.0
    firmware: str = 'px4'
    ground_tolerance: Optional[float] = None
    min_height: Optional[float] = None

    def __post_init__(self) -> None:
        check_number('acceptance_radius', self.acceptance_radius, 0.0, 1000.0, low_open=True)
        check_number('tracking_allowance', self.tracking_allowance, 0.0, 100.0)
        check_number('takeoff_height', self.takeoff_height, 0.0, 10000.0, low_open=True)
        check_number('rtl_altitude', self.rtl_altitude, 0.0, 10000.0, low_open=True)
        if self.takeoff_height < self.acceptance_radius:
            raise InvalidInputError(
                f'takeoff_height must be >= acceptance_radius ({self.acceptance_radius} m), got '
                f'{self.takeoff_height} m: the take-off point is a turn')
        if self.end not in END_ACTIONS:
            raise InvalidInputError(
                f'end must be one of {", ".join(END_ACTIONS)}, got {self.end!r}')
        if self.firmware not in FIRMWARES:
            raise InvalidInputError(
                f'firmware must be one of {", ".join(FIRMWARES)}, got {self.firmware!r}')
        if self.ground_tolerance is not None:
            check_number('ground_tolerance', self.ground_tolerance, 0.0, 1000.0)
        if self.min_height is not None:
            check_number('min_height', self.min_height, 0.0, 10000.0)


def check_number(name: str, value: Any, low: float, high: float,
                 low_open: bool = False) -> float:
    """``value`` as a float, checked to be a finite number in ``[low, high]``.

    Parameters
    ----------
    name : str
        The setting's name, for the error message.
    value : object
        The value given (bools are refused).
    low, high : float
        The range, in the setting's unit.
    low_open : bool
        True: ``low`` itself is refused, the range is ``(low, high]``.

    Raises
    ------
    InvalidInputError
        When it is not a number, not finite or out of range.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise InvalidInputError(f'{name} must be a number, got {value!r}')
    number = float(value)
    if not math.isfinite(number):
        raise InvalidInputError(f'{name} must be finite, got {number}')
    if (number <= low if low_open else number < low) or number > high:
        raise InvalidInputError(
            f'{name} must be in {"(" if low_open else "["}{low}, {high}], got {number}')
    return number
