"""What a mission is: MAVLink numbers, mission items, geofences and the certified :class:`Mission`.
"""

from dataclasses import dataclass, field
from typing import Tuple

import numpy as np

from uav_global_planner.core.checks import check_number, check_point
from uav_global_planner.core.errors import InvalidInputError, PlanningError
from uav_global_planner.core.io.geodesy import GeodeticOrigin
from uav_global_planner.core.mission.settings import MissionSettings
from uav_global_planner.core.status import PlanStatus

# MAVLink numbers (common.xml).
MAV_CMD_NAV_WAYPOINT = 16
MAV_CMD_NAV_LOITER_UNLIM = 17
MAV_CMD_NAV_RETURN_TO_LAUNCH = 20
MAV_CMD_NAV_LAND = 21
MAV_CMD_NAV_TAKEOFF = 22
MAV_CMD_DO_CHANGE_SPEED = 178
MAV_FRAME_GLOBAL = 0
MAV_FRAME_MISSION = 2
MAV_FRAME_GLOBAL_RELATIVE_ALT = 3
MAV_TYPE_QUADROTOR = 2
#: ``firmwareType`` of the ``.plan`` file: MAV_AUTOPILOT values.
MAV_AUTOPILOT = {'px4': 12, 'ardupilot': 3}
#: DO_CHANGE_SPEED speed types.
SPEED_TYPE_GROUND = 1
SPEED_TYPE_CLIMB = 2
SPEED_TYPE_DESCENT = 3
#: Commands with a position (the mission's "waypoints" in the answer of the export service).
POSITION_COMMANDS = (MAV_CMD_NAV_WAYPOINT, MAV_CMD_NAV_LOITER_UNLIM, MAV_CMD_NAV_LAND,
                     MAV_CMD_NAV_TAKEOFF)


class UncertifiableMissionError(PlanningError):
    """No mission keeps the required clearance along the plan (says where and why)."""

    status = PlanStatus.NO_VALID_PATH


@dataclass(frozen=True, eq=False)
class FencePolygon:
    """A polygonal geofence in the map frame.

    Attributes
    ----------
    vertices : numpy.ndarray, shape (K, 2)
        x, y of the corners [m], K >= 3.
    inclusion : bool
        True: stay inside; False: stay outside.
    """

    vertices: np.ndarray
    inclusion: bool = True

    def __post_init__(self) -> None:
        vertices = np.asarray(self.vertices, dtype=np.float64)
        if vertices.ndim != 2 or vertices.shape[1] != 2 or len(vertices) < 3:
            raise InvalidInputError(f'fence polygon needs (K >= 3, 2) vertices [m], got shape '
                                    f'{vertices.shape}')
        if not np.all(np.isfinite(vertices)):
            raise InvalidInputError('fence polygon vertices must be finite')
        object.__setattr__(self, 'vertices', vertices)


@dataclass(frozen=True, eq=False)
class FenceCircle:
    """A circular geofence in the map frame.

    Attributes
    ----------
    center : numpy.ndarray, shape (2,)
        x, y [m].
    radius : float
        [m], > 0.
    inclusion : bool
        True: stay inside; False: stay outside.
    """

    center: np.ndarray
    radius: float
    inclusion: bool = True

    def __post_init__(self) -> None:
        center = check_point('fence circle center', self.center, 'xy')
        check_number('fence circle radius', self.radius, 0.0, 1.0e7, low_open=True)
        object.__setattr__(self, 'center', center)
        object.__setattr__(self, 'radius', float(self.radius))


@dataclass(frozen=True)
class MissionItem:
    """One MAVLink mission item, as both file formats store it.

    Attributes
    ----------
    command : int
        MAV_CMD.
    frame : int
        MAV_FRAME (3 = global, altitude relative to home; 2 = mission, no position).
    params : tuple of float
        param1..4, latitude [deg], longitude [deg], altitude [m above home]; NaN where a param is
        left to the autopilot (written as ``null`` in ``.plan`` files). Rounded to the stored
        decimals, so every writer stores exactly these numbers.
    auto_continue : bool
    """

    command: int
    frame: int
    params: Tuple[float, ...]
    auto_continue: bool = True

    @property
    def has_position(self) -> bool:
        """True for items that fly to a position (take-off, waypoint, loiter, land)."""
        return self.command in POSITION_COMMANDS


@dataclass(frozen=True, eq=False)
class GeoFence:
    """Geofences in WGS84, as written to the ``.plan`` file.

    Attributes
    ----------
    polygons : tuple of (tuple of (lat, lon), bool)
        Vertices [deg] in clockwise order, and the inclusion flag.
    circles : tuple of ((lat, lon), radius, bool)
        Centre [deg], radius [m], inclusion flag.
    skipped : tuple of str
        Exclusion zones of the airspace not written, with the reason: the mission flies over or
        under them inside their footprint, which a 2D autopilot fence would call a breach.
    """

    polygons: Tuple[Tuple[Tuple[Tuple[float, float], ...], bool], ...] = ()
    circles: Tuple[Tuple[Tuple[float, float], float, bool], ...] = ()
    skipped: Tuple[str, ...] = ()


@dataclass(frozen=True, eq=False)
class Mission:
    """A certified mission in the map frame and in WGS84.

    Attributes
    ----------
    items : tuple of MissionItem
        The mission, first item first (no home item: writers add it where the format has one).
    home : tuple of float
        Planned home position (lat [deg], lon [deg], alt [m AMSL]): the take-off point, to
        which every item altitude is relative.
    home_enu : numpy.ndarray, shape (3,)
        Home in the map frame [m], as stored (after rounding).
    origin : GeodeticOrigin
    settings : MissionSettings
    flight_path : numpy.ndarray, shape (P, 3)
        The nominal path the autopilot flies, in the map frame [m], from the stored (rounded)
        positions: home or the start, the take-off point, the waypoints, and the end (descent,
        or the return legs of ``rtl``). Its segments are the certified legs.
    turn_regions : numpy.ndarray, shape (T, 3, 3)
        The certified turn triangles ``(A, P, B)`` [m].
    safety_margin_m : float
        gamma [m].
    required_clearance_m : float
        gamma + tracking allowance [m]: what every leg and turn region keeps.
    certified_clearance_m : float
        Smallest certified lower bound over the legs and turn regions [m], >= the required
        clearance (capped a little above it by the engine).
    speed_horizontal, speed_vertical : float
        Speeds written to the speed items [m/s] (the plan's timing limits).
    fence : GeoFence
    """

    items: Tuple[MissionItem, ...]
    home: Tuple[float, float, float]
    home_enu: np.ndarray
    origin: GeodeticOrigin
    settings: MissionSettings
    flight_path: np.ndarray
    turn_regions: np.ndarray
    safety_margin_m: float
    required_clearance_m: float
    certified_clearance_m: float
    speed_horizontal: float
    speed_vertical: float
    fence: GeoFence = field(default_factory=GeoFence)

    @property
    def waypoint_count(self) -> int:
        """Items that fly to a position (take-off, waypoints, loiter, land)."""
        return sum(item.has_position for item in self.items)

    @property
    def legs(self) -> np.ndarray:
        """The certified straight legs, shape (L, 2, 3) [m]."""
        path = self.flight_path
        return np.stack([path[:-1], path[1:]], axis=1)
