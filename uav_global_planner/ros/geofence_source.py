"""The node's geofence: the ``geofence_file`` parameter read into fences and no-fly zones.

The file is a YAML geofence (the scene format's ``geofence`` mapping, or a document with a
``geofence`` key) or a QGroundControl ``.plan`` whose ``geoFence`` polygons and circles are
placed with the ``geodetic_origin`` parameter of the map frame. ``.plan`` fences are 2D:
``geofence_floor`` and ``geofence_ceiling`` give the height band of its inclusion fences in the
map frame; its exclusion zones reach every altitude (as an autopilot treats them).

The zones join the map as shapes of their own (next to the marker obstacles), so the planner,
the certified check of the plan in force and the endpoint checks see them exactly as
obstacles, with the safety margin gamma applied to every wall, floor and ceiling.
"""

from pathlib import Path
from typing import Any, Dict, Mapping, Tuple

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.geofence import load_geofence
from uav_global_planner.core.map.airspace import Airspace
from uav_global_planner.core.map.spatial_index import TableShape
from uav_global_planner.ros.mission_service import origin_from_value, ORIGIN_PARAMETER

#: The parameters the geofence is read from: a change to any of them reads it again.
GEOFENCE_PARAMETERS = ('geofence_file', 'geofence_floor', 'geofence_ceiling', ORIGIN_PARAMETER)

#: Namespace of the geofence's shapes among the map's shapes. Marker keys are (ns, id) with a
#: ROS string ns, which cannot hold a NUL character, so the two never collide.
_SHAPE_NS = '\x00geofence'

ShapeKey = Tuple[str, int]


def airspace_from_values(values: Mapping[str, Any]) -> Airspace:
    """Read the geofence that parameter values name (none when ``geofence_file`` is empty).

    Parameters
    ----------
    values : mapping
        Parameter values by name: ``geofence_file`` (str), ``geofence_floor`` and
        ``geofence_ceiling`` [m], and ``geodetic_origin`` ([lat deg, lon deg, alt m AMSL] or
        None when not set).

    Returns
    -------
    Airspace

    Raises
    ------
    InvalidInputError
        When the file cannot be read or holds an invalid fence (naming ``geofence_file``, the
        file and the key path), or a ``.plan`` file is given without ``geodetic_origin``.
    """
    file = values['geofence_file']
    if not isinstance(file, str):
        raise InvalidInputError(f'geofence_file must be a path (a string), got {file!r}')
    if not file.strip():
        return Airspace()
    floor, ceiling = float(values['geofence_floor']), float(values['geofence_ceiling'])
    path = Path(file.strip()).expanduser()
    origin = origin_from_value(values.get(ORIGIN_PARAMETER))
    if path.suffix.lower() == '.plan' and origin is None:
        raise InvalidInputError(
            f'geofence_file {str(path)!r} is a QGroundControl plan, whose fences are in '
            'latitude and longitude: set geodetic_origin "[LAT, LON, ALT_AMSL]" of the map '
            'frame first')
    try:
        return load_geofence(path, origin, floor, ceiling)
    except InvalidInputError as error:
        raise InvalidInputError(f'geofence_file: {error}') from None


def geofence_key(values: Mapping[str, Any]) -> Tuple[Any, ...]:
    """The values of :data:`GEOFENCE_PARAMETERS` as a comparable tuple (arrays as tuples)."""
    def plain(value: Any) -> Any:
        if value is None or isinstance(value, (str, bool, int, float)):
            return value
        return tuple(float(v) for v in value)
    return tuple(plain(values.get(name)) for name in GEOFENCE_PARAMETERS)


def geofence_shapes(airspace: Airspace) -> Dict[ShapeKey, TableShape]:
    """The fences and zones of ``airspace`` keyed as map shapes, fences first."""
    return {(_SHAPE_NS, number): shape for number, shape in enumerate(airspace.shapes())}


def describe(airspace: Airspace, file: str) -> str:
    """One line for the log and ``/diagnostics``: the file and what it holds."""
    if not len(airspace):
        return 'no geofence'
    return (f'geofence {file}: {len(airspace.inclusions)} inclusion fence(s), '
            f'{len(airspace.exclusions)} exclusion zone(s)')
