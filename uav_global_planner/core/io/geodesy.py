"""The geodetic origin of the map frame, and conversions between the map frame and WGS84.

The map frame is a local East-North-Up (ENU) frame, as ROS's REP 103 has it: x east, y north,
z up, in metres, tangent to the WGS84 ellipsoid at its origin. A :class:`GeodeticOrigin` names
that origin: latitude and longitude [deg] and the altitude above mean sea level (AMSL) [m] of
z = 0 at x = y = 0.

The conversions use pymap3d (``pip install pymap3d``, or this package's ``geodesy`` extra), the
field's library for them; it is imported only when a conversion runs, so the rest of the package
works without it.

Heights: ellipsoidal versus AMSL
--------------------------------
pymap3d's heights are ellipsoidal (above the WGS84 ellipsoid). AMSL heights differ from them by
the geoid undulation N (h = H_amsl + N; N is between about -106 m and +85 m on Earth). This module
hands pymap3d the origin's AMSL altitude as its height and reads the heights it returns as AMSL,
which is the same as assuming N constant over the map: the constant cancels from every height
difference, so the conversion is exact up to the change of N across the map. That change is
below a few centimetres over a few kilometres almost everywhere (geoid slopes are of the order
of 1e-5 and reach 1e-4 only in high mountains), far below the altitude accuracy of a
barometer or GPS. Mission items are written with altitudes relative to home
(``MAV_FRAME_GLOBAL_RELATIVE_ALT``), which depend on height differences only; the only absolute
AMSL numbers written are the planned home position, taken from the origin's AMSL altitude.

Horizontal positions are exact geodetic conversions (no flat-earth approximation): a point at
z = 0 far from the origin is above the ellipsoid's surface by about r**2 / (2 R_earth) (8 cm at
1 km), and the converted altitudes say so.
"""

from dataclasses import dataclass
from types import ModuleType
from typing import Any, Sequence, Tuple, Union

import numpy as np

from uav_global_planner.core.checks import check_number
from uav_global_planner.core.errors import InvalidInputError

#: The pip package that provides the conversions.
PYMAP3D_PACKAGE = 'pymap3d'

#: Accepted altitudes of the origin [m AMSL]: the Dead Sea shore to well above Everest.
ALTITUDE_RANGE_M = (-500.0, 10000.0)

_Column = Union[Sequence[float], np.ndarray]


class MissingDependencyError(ImportError):
    """An optional dependency needed for the requested feature is not installed.

    Parameters
    ----------
    package : str
        The pip package to install.
    feature : str
        What needs it.
    """

    def __init__(self, package: str, feature: str) -> None:
        super().__init__(f'{feature} needs the Python package {package!r}, which is not '
                         f'installed: pip install {package} (or pip install '
                         f"'uav_global_planner[geodesy]')", name=package)
        self.package = package


@dataclass(frozen=True)
class GeodeticOrigin:
    """WGS84 position of the map frame's origin.

    Attributes
    ----------
    lat : float
        Latitude [deg], in [-90, 90] (the poles themselves are refused: east and north are not
        defined there).
    lon : float
        Longitude [deg], in [-180, 180].
    alt_amsl : float
        Altitude above mean sea level of z = 0 [m] (see the module notes on AMSL).
    """

    lat: float
    lon: float
    alt_amsl: float

    def __post_init__(self) -> None:
        lat = _finite('geodetic_origin.lat', self.lat)
        lon = _finite('geodetic_origin.lon', self.lon)
        alt = _finite('geodetic_origin.alt_amsl', self.alt_amsl)
        if not -90.0 < lat < 90.0:
            raise InvalidInputError(
                f'geodetic_origin.lat: must be in (-90, 90) deg, got {lat}')
        if not -180.0 <= lon <= 180.0:
            raise InvalidInputError(
                f'geodetic_origin.lon: must be in [-180, 180] deg, got {lon}')
        low, high = ALTITUDE_RANGE_M
        if not low <= alt <= high:
            raise InvalidInputError(
                f'geodetic_origin.alt_amsl: must be in [{low}, {high}] m, got {alt}')
        object.__setattr__(self, 'lat', lat)
        object.__setattr__(self, 'lon', lon)
        object.__setattr__(self, 'alt_amsl', alt)

    def as_list(self) -> list:
        """``[lat, lon, alt_amsl]``, the form of the scene key and of the node parameter."""
        return [self.lat, self.lon, self.alt_amsl]


def _finite(name: str, value: Any) -> float:
    return check_number(f'{name}:', value)


def origin_from_sequence(values: Sequence[Any], name: str = 'geodetic_origin') -> GeodeticOrigin:
    """A :class:`GeodeticOrigin` from ``[lat, lon, alt_amsl]``.

    Raises
    ------
    InvalidInputError
        Naming ``name`` when it is not three valid numbers.
    """
    if isinstance(values, (str, bytes)) or not hasattr(values, '__len__') or len(values) != 3:
        raise InvalidInputError(f'{name}: must be [lat, lon, alt_amsl] (deg, deg, m), got '
                                f'{values!r}')
    return GeodeticOrigin(*(_finite(f'{name}[{n}]', v) for n, v in enumerate(values)))


def parse_origin(text: str) -> GeodeticOrigin:
    """Parse ``'LAT,LON,ALT'`` (deg, deg, m AMSL), the form of the ``--origin`` option.

    Raises
    ------
    InvalidInputError
        When the text is not three comma-separated numbers in range.
    """
    parts = [part.strip() for part in str(text).split(',')]
    if len(parts) != 3:
        raise InvalidInputError(f'--origin: must be LAT,LON,ALT_AMSL (deg, deg, m), got {text!r}')
    try:
        values = [float(part) for part in parts]
    except ValueError:
        raise InvalidInputError(
            f'--origin: must be LAT,LON,ALT_AMSL (three numbers), got {text!r}') from None
    return origin_from_sequence(values, '--origin')


def pymap3d_module() -> ModuleType:
    """The pymap3d module.

    Raises
    ------
    MissingDependencyError
        When pymap3d is not installed, naming the pip package.
    """
    try:
        import pymap3d
    except ImportError:
        raise MissingDependencyError(PYMAP3D_PACKAGE,
                                     'converting between the map frame and WGS84') from None
    return pymap3d


def _as_points(points: Any) -> np.ndarray:
    try:
        array = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError('points must be an (N, 3) array of numbers [m]') from None
    array = array.reshape(-1, 3) if array.size else array.reshape(0, 3)
    if not np.all(np.isfinite(array)):
        raise InvalidInputError('points must be finite; found NaN or inf')
    return array


def enu_to_geodetic(points: Any, origin: GeodeticOrigin
                    ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Map-frame (ENU) positions to WGS84.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        x east, y north, z up [m] in the map frame.
    origin : GeodeticOrigin

    Returns
    -------
    lat, lon : numpy.ndarray, shape (N,)
        [deg]
    alt_amsl : numpy.ndarray, shape (N,)
        Altitude above mean sea level [m] (see the module notes).

    Raises
    ------
    MissingDependencyError
        When pymap3d is not installed.
    """
    pm = pymap3d_module()
    enu = _as_points(points)
    lat, lon, alt = pm.enu2geodetic(enu[:, 0], enu[:, 1], enu[:, 2], origin.lat, origin.lon,
                                    origin.alt_amsl)
    return (np.asarray(lat, dtype=np.float64).reshape(-1),
            np.asarray(lon, dtype=np.float64).reshape(-1),
            np.asarray(alt, dtype=np.float64).reshape(-1))


def geodetic_to_enu(lat: _Column, lon: _Column, alt_amsl: _Column,
                    origin: GeodeticOrigin) -> np.ndarray:
    """WGS84 positions to the map frame (ENU).

    Parameters
    ----------
    lat, lon : array_like, shape (N,)
        [deg]
    alt_amsl : array_like, shape (N,)
        Altitude above mean sea level [m].
    origin : GeodeticOrigin

    Returns
    -------
    numpy.ndarray, shape (N, 3)
        x east, y north, z up [m].

    Raises
    ------
    MissingDependencyError
        When pymap3d is not installed.
    """
    pm = pymap3d_module()
    columns = [np.asarray(v, dtype=np.float64).reshape(-1) for v in (lat, lon, alt_amsl)]
    if len({len(c) for c in columns}) != 1:
        raise InvalidInputError('lat, lon and alt_amsl must have the same length')
    if not all(np.all(np.isfinite(c)) for c in columns):
        raise InvalidInputError('lat, lon and alt_amsl must be finite; found NaN or inf')
    east, north, up = pm.geodetic2enu(columns[0], columns[1], columns[2], origin.lat,
                                      origin.lon, origin.alt_amsl)
    return np.stack([np.asarray(east, dtype=np.float64).reshape(-1),
                     np.asarray(north, dtype=np.float64).reshape(-1),
                     np.asarray(up, dtype=np.float64).reshape(-1)], axis=1)
