"""Reading geofences: the ``geofence`` mapping of a scene or YAML file, and QGroundControl plans.

* The scene file's ``geofence`` key (:func:`parse_geofence`)::

      geofence:
        inclusion: {polygon: [[x, y], ...], floor: 0.0, ceiling: 120.0}   # optional
        exclusion:
          - {type: prism, polygon: [[x, y], ...], floor: 0.0, ceiling: 60.0}
          - {type: cylinder, center: [x, y], radius: 30.0, floor: 0.0, ceiling: 200.0}
          - {type: box, min: [x, y, z], max: [x, y, z]}

  An inclusion may also be a circle, ``{center: [x, y], radius: r, floor, ceiling}``.
* A QGroundControl ``.plan`` file (:func:`load_qgc_plan`): its ``geoFence`` polygons and circles
  (each with its ``inclusion`` flag) in WGS84, placed in the map frame from its geodetic origin
  (:mod:`uav_global_planner.core.io.geodesy`, pymap3d). ``.plan`` fences are 2D: the floor and
  ceiling of the inclusion fences are given separately, exclusion zones reach every altitude
  unless limits are given.
* :func:`load_geofence` reads either, by the file's suffix.

Both build the shapes of :mod:`uav_global_planner.core.map.zones` into an
:class:`~uav_global_planner.core.map.airspace.Airspace`, with the shapes' own checks; errors
name the key path, as for obstacles: ``geofence.exclusion[2].radius: must be > 0 m, got -1.0``.
"""

import dataclasses
import json
from pathlib import Path
from typing import Any, Iterable, List, Optional, Sequence, Tuple, Type, Union

import numpy as np

from uav_global_planner.core.checks import check_number
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.geodesy import geodetic_to_enu, GeodeticOrigin
from uav_global_planner.core.io.text_files import parse_text_file
from uav_global_planner.core.map.airspace import Airspace
from uav_global_planner.core.map.zones import (BoxZone, check_band, CircleBand, Cylinder,
                                               Exclusion, HIGHEST, Inclusion, InclusionCircle,
                                               InclusionFence, LOWEST, PolygonBand, Prism)


def _prefixed(path: str, build, *args, sep: str = '.', **kwargs):
    """``build(*args, **kwargs)``, with the key path put before any validation message."""
    try:
        return build(*args, **kwargs)
    except InvalidInputError as error:
        raise InvalidInputError(f'{path}{sep}{error}') from None


def _mapping(value: Any, path: str, allowed: Iterable[str]) -> dict:
    allowed = set(allowed)
    if not isinstance(value, dict):
        raise InvalidInputError(f'{path}: must be a mapping, got {type(value).__name__}')
    unknown = sorted(str(key) for key in value if key not in allowed)
    if unknown:
        raise InvalidInputError(f'{path}: unknown key(s) {", ".join(unknown)}; allowed: '
                                f'{", ".join(sorted(allowed))}')
    return value


def _require(mapping: dict, key: str, path: str) -> Any:
    if key not in mapping:
        raise InvalidInputError(f'{path}.{key}: missing required key')
    return mapping[key]


def _yaml_band(entry: dict, path: str) -> dict:
    band = {}
    for key in ('floor', 'ceiling'):
        if entry.get(key) is not None:
            band[key] = check_number(f'{path}.{key}:', entry[key])
    return band


def _vector3(value: Any, path: str) -> np.ndarray:
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise InvalidInputError(f'{path}: must be a list of three numbers [x, y, z], got '
                                f'{value!r}')
    return np.array([check_number(f'{path}[{axis}]:', item) for axis, item in enumerate(value)])


def _yaml_polygon(value: Any, path: str) -> list:
    if not isinstance(value, list):
        raise InvalidInputError(f'{path}: must be a list of [x, y] pairs')
    for number, vertex in enumerate(value):
        if not isinstance(vertex, (list, tuple)) or len(vertex) != 2:
            raise InvalidInputError(f'{path}[{number}]: must be two numbers [x, y], got '
                                    f'{vertex!r}')
        for axis, item in enumerate(vertex):
            check_number(f'{path}[{number}][{axis}]:', item)
    return value


_ZONE_KEYS = {'prism': ('polygon',), 'cylinder': ('center', 'radius'), 'box': ('min', 'max')}
_ZONE_OPTIONAL = {'prism': ('floor', 'ceiling'), 'cylinder': ('floor', 'ceiling'), 'box': ()}


def _inclusion(entry: Any, path: str) -> Inclusion:
    if isinstance(entry, dict) and 'polygon' in entry:
        _mapping(entry, path, {'polygon', 'floor', 'ceiling'})
        polygon = _yaml_polygon(entry['polygon'], f'{path}.polygon')
        return _prefixed(path, InclusionFence, polygon, **_yaml_band(entry, path))
    if isinstance(entry, dict) and 'center' in entry:
        _mapping(entry, path, {'center', 'radius', 'floor', 'ceiling'})
        return _prefixed(path, InclusionCircle, entry['center'],
                         _require(entry, 'radius', path), **_yaml_band(entry, path))
    raise InvalidInputError(f'{path}: must be a mapping with a polygon (and floor, ceiling), or '
                            'with a center and a radius')


def _exclusion(entry: Any, path: str, label: str) -> Exclusion:
    if not isinstance(entry, dict):
        raise InvalidInputError(f'{path}: must be a mapping with a type, got '
                                f'{type(entry).__name__}')
    kind = _require(entry, 'type', path)
    if kind not in _ZONE_KEYS:
        raise InvalidInputError(f'{path}.type: unknown zone type {kind!r}; allowed: '
                                f'{", ".join(_ZONE_KEYS)}')
    _mapping(entry, path, {'type', *_ZONE_KEYS[kind], *_ZONE_OPTIONAL[kind]})
    values = {key: _require(entry, key, path) for key in _ZONE_KEYS[kind]}
    name = f'{label} ({kind})'
    if kind == 'prism':
        polygon = _yaml_polygon(values['polygon'], f'{path}.polygon')
        return _prefixed(path, Prism, polygon, label=name, **_yaml_band(entry, path))
    if kind == 'cylinder':
        return _prefixed(path, Cylinder, values['center'], values['radius'], label=name,
                         **_yaml_band(entry, path))
    lo = _vector3(values['min'], f'{path}.min')
    hi = _vector3(values['max'], f'{path}.max')
    return _prefixed(path, BoxZone, lo, hi, label=name)


def parse_geofence(data: Any, path: str = 'geofence') -> Airspace:
    """The airspace of a ``geofence`` mapping (see the module notes).

    Parameters
    ----------
    data : Any
        The mapping, as loaded from YAML; None gives an empty airspace.
    path : str
        Key path of ``data`` in messages.

    Raises
    ------
    InvalidInputError
        Naming the key path of the first problem, for example
        ``geofence.exclusion[1].floor: must be below the ceiling ...``.
    """
    if data is None:
        return Airspace()
    top = _mapping(data, path, {'inclusion', 'exclusion'})
    inclusions: List[Inclusion] = []
    if top.get('inclusion') is not None:
        inclusions.append(_inclusion(top['inclusion'], f'{path}.inclusion'))
    entries = top.get('exclusion')
    if entries is None:
        entries = []
    if not isinstance(entries, list):
        raise InvalidInputError(f'{path}.exclusion: must be a list, got '
                                f'{type(entries).__name__}')
    exclusions = [_exclusion(entry, f'{path}.exclusion[{number}]', f'exclusion zone {number}')
                  for number, entry in enumerate(entries)]
    return Airspace(tuple(inclusions), tuple(exclusions))


# --- QGroundControl plan files ---------------------------------------------------------------

def _plan_point(value: Any, path: str) -> Tuple[float, float]:
    # QGC writes [lat, lon] and, with altitude, [lat, lon, alt]; fences are 2D.
    if not isinstance(value, list) or len(value) not in (2, 3):
        raise InvalidInputError(f'{path}: must be [latitude, longitude] in degrees, got '
                                f'{value!r}')
    lat = check_number(f'{path}[0]:', value[0])
    lon = check_number(f'{path}[1]:', value[1])
    if not -90.0 <= lat <= 90.0 or not -180.0 <= lon <= 180.0:
        raise InvalidInputError(f'{path}: latitude must be in [-90, 90] and longitude in '
                                f'[-180, 180] degrees, got {[lat, lon]}')
    return lat, lon


def _to_plane(points: Sequence[Tuple[float, float]], origin: GeodeticOrigin) -> np.ndarray:
    """WGS84 (lat, lon) pairs at the origin's altitude to map-frame (x, y) [m]."""
    lat, lon = np.asarray(points, dtype=np.float64).reshape(-1, 2).T
    enu = geodetic_to_enu(lat, lon, np.full(len(lat), origin.alt_amsl), origin)
    return enu[:, :2]


def parse_qgc_geofence(plan: Any, origin: Optional[GeodeticOrigin], floor: float = LOWEST,
                       ceiling: float = HIGHEST, zone_floor: float = LOWEST,
                       zone_ceiling: float = HIGHEST, name: str = 'plan') -> Airspace:
    """The airspace of a QGroundControl plan (the JSON document, already loaded).

    Parameters
    ----------
    plan : Any
        The plan document: ``{"fileType": "Plan", "geoFence": {"polygons": [...],
        "circles": [...], "version": 2}, ...}``.
    origin : GeodeticOrigin
        WGS84 position of the map frame's origin.
    floor, ceiling : float
        Height interval of the inclusion fences in the map frame [m] (``.plan`` fences are 2D).
    zone_floor, zone_ceiling : float
        Height interval of the exclusion zones [m]; by default every altitude.
    name : str
        The file's name, for messages and zone labels.

    Raises
    ------
    InvalidInputError
        Naming the file and the key path, e.g. ``mission.plan: geoFence.polygons[0].polygon:
        is self-intersecting: ...``.
    MissingDependencyError
        When pymap3d is not installed.
    """
    if not isinstance(origin, GeodeticOrigin):
        raise InvalidInputError(f'{name}: a QGroundControl plan needs the geodetic origin of the '
                                'map frame')
    band = check_band(floor, ceiling)
    zone_band = check_band(zone_floor, zone_ceiling)
    if not isinstance(plan, dict) or plan.get('fileType') != 'Plan':
        raise InvalidInputError(f'{name}: not a QGroundControl plan (fileType must be "Plan")')
    fence = plan.get('geoFence')
    if not isinstance(fence, dict):
        raise InvalidInputError(f'{name}: geoFence: missing, or not an object')
    if fence.get('version') != 2:
        raise InvalidInputError(f'{name}: geoFence.version: only version 2 (polygons and '
                                f'circles) is supported, got {fence.get("version")!r}')
    inclusions: List[Inclusion] = []
    exclusions: List[Exclusion] = []
    for key in ('polygons', 'circles'):
        entries = fence.get(key, [])
        if not isinstance(entries, list):
            raise InvalidInputError(f'{name}: geoFence.{key}: must be a list')
        for number, entry in enumerate(entries):
            path = f'{name}: geoFence.{key}[{number}]'
            if not isinstance(entry, dict):
                raise InvalidInputError(f'{path}: must be an object')
            inclusion = entry.get('inclusion')
            if not isinstance(inclusion, bool):
                raise InvalidInputError(f'{path}.inclusion: must be true or false, got '
                                        f'{inclusion!r}')
            shape = 'polygon' if key == 'polygons' else 'circle'
            label = (f'inclusion fence {len(inclusions)} ({shape} {number} of {name})'
                     if inclusion else
                     f'exclusion zone {len(exclusions)} ({shape} {number} of {name})')
            if key == 'polygons':
                vertices = _require(entry, 'polygon', path)
                if not isinstance(vertices, list):
                    raise InvalidInputError(f'{path}.polygon: must be a list of [lat, lon]')
                plane: Union[np.ndarray, List[Any]] = _to_plane(
                    [_plan_point(v, f'{path}.polygon[{n}]') for n, v in enumerate(vertices)],
                    origin) if vertices else []
                polygon_kind: Type[PolygonBand] = InclusionFence if inclusion else Prism
                low, high = band if inclusion else zone_band
                shape_object = _prefixed(path, polygon_kind, plane, low, high, label=label)
            else:
                circle = _require(entry, 'circle', path)
                if not isinstance(circle, dict):
                    raise InvalidInputError(f'{path}.circle: must be an object')
                center = _to_plane([_plan_point(_require(circle, 'center', f'{path}.circle'),
                                                f'{path}.circle.center')], origin)[0]
                radius = _require(circle, 'radius', f'{path}.circle')
                circle_kind: Type[CircleBand] = InclusionCircle if inclusion else Cylinder
                low, high = band if inclusion else zone_band
                shape_object = _prefixed(f'{path}.circle', circle_kind, center, radius, low,
                                         high, label=label)
            (inclusions if inclusion else exclusions).append(shape_object)
    if len(inclusions) == 1:
        only = inclusions[0]
        inclusions[0] = dataclasses.replace(only, label='the inclusion fence')
    return Airspace(tuple(inclusions), tuple(exclusions))


def load_qgc_plan(path: Union[str, Path], origin: Optional[GeodeticOrigin], floor: float = LOWEST,
                  ceiling: float = HIGHEST, zone_floor: float = LOWEST,
                  zone_ceiling: float = HIGHEST) -> Airspace:
    """Read the ``geoFence`` of a QGroundControl ``.plan`` file (see
    :func:`parse_qgc_geofence` for the arguments)."""
    file = Path(path)
    plan = parse_text_file(file, 'plan file', json.loads, json.JSONDecodeError, 'not valid JSON',
                           not_text='not a text file, so not a plan file')
    return parse_qgc_geofence(plan, origin, floor, ceiling, zone_floor, zone_ceiling,
                              name=file.name)


def load_geofence(path: Union[str, Path], origin: Optional[GeodeticOrigin] = None,
                  floor: float = LOWEST, ceiling: float = HIGHEST) -> Airspace:
    """Read a geofence file: a QGroundControl ``.plan`` or a YAML file.

    A YAML file holds the ``geofence`` mapping itself (``inclusion``, ``exclusion``) or a
    document with a ``geofence`` key (a scene file, for example).

    Parameters
    ----------
    path : str or Path
    origin : GeodeticOrigin, optional
        Needed for ``.plan`` files.
    floor, ceiling : float
        Height interval of ``.plan`` inclusion fences [m].

    Raises
    ------
    InvalidInputError
        For unreadable files and invalid content, naming the file and the key path.
    """
    file = Path(path)
    if file.suffix.lower() == '.plan':
        return load_qgc_plan(file, origin, floor, ceiling)
    import yaml  # the scene module's parser; imported here, where YAML is read
    data = parse_text_file(file, 'geofence file', yaml.safe_load, yaml.YAMLError,
                           'not a YAML geofence file')
    if isinstance(data, dict) and 'geofence' in data:
        return _prefixed(file.name, parse_geofence, data['geofence'], sep=': ')
    return _prefixed(file.name, parse_geofence, data, sep=': ')
