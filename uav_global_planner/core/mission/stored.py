"""The values as the mission files store them: rounding, items, and positions read back.

Files store latitude and longitude to 1e-7 deg (the MAVLink integer resolution, about 1 cm)
and altitudes to 1 mm; every writer stores exactly the rounded numbers of the items made here,
and the final certificate is computed on the map-frame positions read back from them.
"""

import math
from typing import Tuple

import numpy as np

from uav_global_planner.core.io.geodesy import enu_to_geodetic, geodetic_to_enu, GeodeticOrigin
from uav_global_planner.core.mission.model import MissionItem

#: Decimal places stored: latitude/longitude (MAVLink's 1e-7 deg integers), altitudes, params.
LATLON_DECIMALS = 7
ALTITUDE_DECIMALS = 3
PARAM_DECIMALS = 6
#: Slack kept above the required clearance while choosing, so that rounding to the stored
#: decimals (at most 8 mm at a point, 16 mm at a turn triangle's corner) cannot take a leg or a
#: turn below it [m].
ROUNDING_SLACK = 0.02


def round_stored(value: float, decimals: int) -> float:
    """``value`` rounded to ``decimals`` places (NaN stays NaN, -0.0 becomes 0.0)."""
    return value if math.isnan(value) else round(float(value), decimals) + 0.0


def stored_item(command: int, frame: int, p1: float = 0.0, p2: float = 0.0, p3: float = 0.0,
                p4: float = 0.0, lat: float = 0.0, lon: float = 0.0,
                alt: float = 0.0) -> MissionItem:
    """A :class:`MissionItem` with its params rounded to the stored decimals.

    ``p1``..``p4`` are the command's params, ``lat``, ``lon`` [deg] and ``alt`` [m above home]
    its position.
    """
    params = tuple(round_stored(p, PARAM_DECIMALS) for p in (p1, p2, p3, p4)) + (
        round_stored(lat, LATLON_DECIMALS), round_stored(lon, LATLON_DECIMALS),
        round_stored(alt, ALTITUDE_DECIMALS))
    return MissionItem(int(command), int(frame), params, True)


class StoredGeo:
    """Rounded WGS84 values of map-frame points, and the map-frame points they stand for."""

    def __init__(self, origin: GeodeticOrigin, home: np.ndarray) -> None:
        self.origin = origin
        lat, lon, alt = enu_to_geodetic(home[None], origin)
        self.home = (round_stored(lat[0], LATLON_DECIMALS), round_stored(lon[0], LATLON_DECIMALS),
                     round_stored(alt[0], ALTITUDE_DECIMALS))

    def stored(self, points: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Latitude, longitude [deg] and altitude above home [m], rounded as stored."""
        lat, lon, alt = enu_to_geodetic(points, self.origin)
        return (np.round(lat, LATLON_DECIMALS), np.round(lon, LATLON_DECIMALS),
                np.round(alt - self.home[2], ALTITUDE_DECIMALS))

    def back(self, lat: np.ndarray, lon: np.ndarray, rel: np.ndarray) -> np.ndarray:
        """Map-frame positions of stored values [m]."""
        return geodetic_to_enu(lat, lon, np.asarray(rel) + self.home[2], self.origin)
