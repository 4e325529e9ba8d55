"""How a mission is built: :class:`MissionSettings`, its end actions and firmwares.

:data:`MISSION_SETTINGS` is the one table of the mission's settings (the same
:class:`~uav_global_planner.core.settings.Setting` type as the planner's): the checks of
:class:`MissionSettings`, the flags of ``uav-plan export`` and the ``mission_*`` parameters of the
planner node (with their ranges) are made from it, so they accept the same values and refuse
them in the same words. A :class:`MissionSettings` always holds values
:func:`~uav_global_planner.core.mission.build_mission` can fly.
"""

from dataclasses import dataclass
from typing import Dict, Optional, Tuple

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.settings import by_name, Kind, Setting

#: What the vehicle does after the goal (:attr:`MissionSettings.end`).
END_ACTIONS = ('loiter', 'land', 'rtl')
#: Autopilots a mission is written for (:attr:`MissionSettings.firmware`).
FIRMWARES = ('px4', 'ardupilot')

#: Every mission setting. ``node``: the planner node declares it as ``mission_<name>``;
#: ``flag``: the ``uav-plan export`` option. The optional ones (default None) are checked
#: only when given.
MISSION_SETTINGS: Tuple[Setting, ...] = (
    Setting('acceptance_radius', Kind.FLOAT, 1.0, 'waypoint acceptance radius R',
            "The autopilot's waypoint acceptance radius (PX4 NAV_ACC_RAD, ArduPilot "
            "WPNAV_RADIUS), written as each waypoint's param 2; turns within R are certified.",
            unit='m', low=0.0, high=1000.0, low_open=True, flag='--acceptance-radius'),
    Setting('tracking_allowance', Kind.FLOAT, 0.1, 'tracking allowance a',
            "Clearance added to gamma for the autopilot's tracking error; legs and turns keep "
            'gamma + a.', unit='m', low=0.0, high=100.0, flag='--tracking-allowance'),
    Setting('takeoff_height', Kind.FLOAT, 2.5, 'take-off height',
            'Take-off climb above the start; lowered to the highest climb that keeps the '
            'clearance (PX4 raises take-offs below MIS_TAKEOFF_ALT to it: keep this as high).',
            unit='m', low=0.0, high=10000.0, low_open=True, rule='>= acceptance_radius',
            flag='--takeoff-height'),
    Setting('end', Kind.CHOICE, 'loiter', 'end action',
            'After the goal: loiter (hold), land (descend at the goal), or rtl (return to '
            'launch at the rtl altitude).', choices=END_ACTIONS, flag='--end'),
    Setting('rtl_altitude', Kind.FLOAT, 15.0, 'return altitude',
            "Return altitude above home for the end action rtl; must equal the autopilot's "
            'RTL_RETURN_ALT / RTL_ALT.', unit='m', low=0.0, high=10000.0, low_open=True,
            flag='--rtl-altitude'),
    Setting('firmware', Kind.CHOICE, 'px4', 'autopilot firmware',
            'Autopilot of the mission: the .plan firmwareType, the yaw convention (PX4: NaN '
            'keeps the heading mode; ArduPilot: 0) and the speed items.', choices=FIRMWARES,
            flag='--firmware'),
    Setting('ground_tolerance', Kind.FLOAT, None, 'ground tolerance',
            "The start is on the ground when it is at most this far above the bounds' floor; "
            'unset: the grid spacing delta.', unit='m', low=0.0, high=1000.0, node=False),
    Setting('min_height', Kind.FLOAT, None, 'lowest waypoint height',
            "Lowest height of waypoints above the bounds' floor (the ground); unset: the "
            'required clearance gamma + tracking allowance. The goal and via-points stay where '
            'they are.', unit='m', low=0.0, high=10000.0, node=False, flag='--min-height'),
)

#: :data:`MISSION_SETTINGS` by name.
MISSION_SETTING: Dict[str, Setting] = by_name(MISSION_SETTINGS)


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

    acceptance_radius: float = MISSION_SETTING['acceptance_radius'].default
    tracking_allowance: float = MISSION_SETTING['tracking_allowance'].default
    takeoff_height: float = MISSION_SETTING['takeoff_height'].default
    end: str = MISSION_SETTING['end'].default
    rtl_altitude: float = MISSION_SETTING['rtl_altitude'].default
    firmware: str = MISSION_SETTING['firmware'].default
    ground_tolerance: Optional[float] = MISSION_SETTING['ground_tolerance'].default
    min_height: Optional[float] = MISSION_SETTING['min_height'].default

    def __post_init__(self) -> None:
        for setting in MISSION_SETTINGS:
            value = getattr(self, setting.name)
            if value is not None or setting.default is not None:
                object.__setattr__(self, setting.name, setting.check(value))
        if self.takeoff_height < self.acceptance_radius:
            raise InvalidInputError(
                f'takeoff_height must be >= acceptance_radius ({self.acceptance_radius} m), got '
                f'{self.takeoff_height} m: the take-off point is a turn')
