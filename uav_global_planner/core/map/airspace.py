"""Airspace: an inclusion fence and exclusion zones (no-fly volumes) in the planning model.

The vehicle must stay inside the *inclusion fence* (a polygon in x-y with a floor and a
ceiling, or a circle) and outside every *exclusion zone*: vertical prisms (polygon, floor,
ceiling), vertical cylinders (centre, radius, floor, ceiling) and axis-aligned boxes. Without an
inclusion fence the planning bounds are the fence. Every zone and fence is a row of the shape
table of :mod:`uav_global_planner.core.map.spatial_index`, with an exact distance (to a zone's
solid, 0 inside it; to the *outside* of a fence, 0 outside it): put them into the
:class:`~uav_global_planner.core.map.obstacles.ObstacleSet` (:meth:`Airspace.with_obstacles`) and
the grid inflation and every clearance certificate keep gamma from fence walls as from
obstacles. Several inclusion fences are all enforced (the vehicle stays inside each of them),
which is the reading that satisfies both PX4 (inside at least one) and ArduPilot (inside all).

Coordinates are in the planning frame [m], z up. Floors and ceilings may be left out: a zone
without a floor reaches down without end, one without a ceiling up without end.

Where fences come from
----------------------
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

Errors name the key path, as for obstacles: ``geofence.exclusion[2].radius: must be > 0 m,
got -1.0``; polygons must be simple (no two edges cross or touch), with at least three
distinct vertices and a non-zero area.

One module, though long (about 750 lines): the zone and fence shapes, their validation and the
two file formats (YAML, QGroundControl ``.plan``) build the same objects with the same checks
and key-path messages.
"""

import dataclasses
from dataclasses import dataclass
import json
import math
from pathlib import Path
from typing import Any, Iterable, List, Optional, Sequence, Tuple, Type, Union

import numpy as np

from uav_global_planner.core.errors import (GoalOccupiedError, GoalOutsideMapError,
                                            InvalidInputError, StartOccupiedError,
                                            StartOutsideMapError)
from uav_global_planner.core.io.geodesy import geodetic_to_enu, GeodeticOrigin
from uav_global_planner.core.io.text_files import parse_text_file
from uav_global_planner.core.map.grid import finite_point
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.map.spatial_index import (BOX, CIRCLE_FENCE, CYLINDER, FENCE, PRISM,
                                                       row_gaps, TableShape, UNBOUNDED_KINDS)

#: Most vertices of one polygon: validation compares every pair of edges.
MAX_POLYGON_VERTICES = 4096

_LOWEST = -math.inf
_HIGHEST = math.inf


def _number(value: Any, name: str, allow_infinite: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InvalidInputError(f'{name}: must be a number, got {value!r}')
    number = float(value)
    if math.isnan(number) or (not allow_infinite and not math.isfinite(number)):
        raise InvalidInputError(f'{name}: must be finite, got {number}')
    return number


def _band(floor: Any, ceiling: Any) -> Tuple[float, float]:
    """Validated (floor, ceiling) [m]; either may be infinite (no limit)."""
    low = _number(floor, 'floor', allow_infinite=True)
    high = _number(ceiling, 'ceiling', allow_infinite=True)
    if low == _HIGHEST:
        raise InvalidInputError('floor: must be below +inf')
    if high == _LOWEST:
        raise InvalidInputError('ceiling: must be above -inf')
    if not low < high:
        raise InvalidInputError(f'floor: must be below the ceiling, got floor {low} m and '
                                f'ceiling {high} m')
    return low, high


def _plane_point(value: Any, name: str) -> np.ndarray:
    return finite_point(value, f'{name}:', 'xy')


def _radius(value: Any) -> float:
    radius = _number(value, 'radius')
    if radius <= 0.0:
        raise InvalidInputError(f'radius: must be > 0 m, got {radius}')
    return radius


def _orientation(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Twice the signed area of triangles (a, b, c), broadcast [m^2]."""
    return ((b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1])
            - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0]))


def _on_segment(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> np.ndarray:
    """For collinear a, b, p: whether p lies on the closed segment ab."""
    return ((np.minimum(a[..., 0], b[..., 0]) <= p[..., 0])
            & (p[..., 0] <= np.maximum(a[..., 0], b[..., 0]))
            & (np.minimum(a[..., 1], b[..., 1]) <= p[..., 1])
            & (p[..., 1] <= np.maximum(a[..., 1], b[..., 1])))


def checked_polygon(value: Any, name: str = 'polygon') -> np.ndarray:
    """A simple polygon as an (V, 2) float array [m], or a message naming the problem.

    A closing vertex equal to the first is dropped. Refused: fewer than three distinct
    vertices, consecutive vertices that coincide, a zero area, an edge folding back onto the
    previous one, and any two edges that cross or touch (a self-intersecting polygon).

    Raises
    ------
    InvalidInputError
        Starting with ``name``.
    """
    try:
        points = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f'{name}: must be a list of [x, y] pairs') from None
    if points.ndim != 2 or points.shape[1] != 2:
        raise InvalidInputError(f'{name}: must be a list of [x, y] pairs, got shape '
                                f'{tuple(points.shape)}')
    if not np.all(np.isfinite(points)):
        raise InvalidInputError(f'{name}: vertices must be finite; found NaN or inf')
    if len(points) > 1 and np.array_equal(points[0], points[-1]):
        points = points[:-1]
    count = len(points)
    if count < 3:
        raise InvalidInputError(f'{name}: needs at least 3 distinct vertices, got {count}')
    if count > MAX_POLYGON_VERTICES:
        raise InvalidInputError(f'{name}: has {count} vertices; at most '
                                f'{MAX_POLYGON_VERTICES} are supported')
    nxt = np.roll(points, -1, axis=0)
    same = np.flatnonzero(np.all(points == nxt, axis=1))
    if len(same):
        k = int(same[0])
        raise InvalidInputError(f'{name}: vertices {k} and {(k + 1) % count} coincide '
                                f'({points[k].tolist()})')
    # All vertices on one line (to rounding): no area whatever the order.
    extent = float(np.max(np.ptp(points, axis=0)))
    far = int(np.argmax(np.linalg.norm(points - points[0], axis=1)))
    spread = float(np.max(np.abs(_orientation(points[0], points[far], points))))
    if spread <= 1e-12 * extent * extent:
        raise InvalidInputError(f'{name}: is degenerate: its vertices lie on one line')
    # An edge folding back onto the previous one: the turn at the shared vertex is a reversal.
    prev = np.roll(points, 1, axis=0)
    turn = _orientation(prev, points, nxt)
    back = np.einsum('ij,ij->i', prev - points, nxt - points)
    folded = np.flatnonzero((turn == 0.0) & (back > 0.0))
    if len(folded):
        k = int(folded[0])
        raise InvalidInputError(f'{name}: is self-intersecting: edges {(k - 1) % count} and {k} '
                                f'fold back onto each other at vertex {k} '
                                f'{points[k].tolist()}')
    # Every pair of edges that share no vertex must not meet at all.
    first, second = np.triu_indices(count, 2)
    keep = ~((first == 0) & (second == count - 1))
    first, second = first[keep], second[keep]
    a, b, c, d = points[first], nxt[first], points[second], nxt[second]
    o1, o2 = _orientation(a, b, c), _orientation(a, b, d)
    o3, o4 = _orientation(c, d, a), _orientation(c, d, b)
    meet = ((np.sign(o1) * np.sign(o2) < 0) & (np.sign(o3) * np.sign(o4) < 0))
    meet |= (o1 == 0) & _on_segment(a, b, c)
    meet |= (o2 == 0) & _on_segment(a, b, d)
    meet |= (o3 == 0) & _on_segment(c, d, a)
    meet |= (o4 == 0) & _on_segment(c, d, b)
    crossing = np.flatnonzero(meet)
    if len(crossing):
        k = int(crossing[0])
        raise InvalidInputError(f'{name}: is self-intersecting: edges {int(first[k])} and '
                                f'{int(second[k])} cross or touch')
    area = 0.5 * float(np.sum(points[:, 0] * nxt[:, 1] - nxt[:, 0] * points[:, 1]))
    if abs(area) <= 1e-12 * extent * extent:
        raise InvalidInputError(f'{name}: is degenerate: its area is {abs(area):.3g} m^2')
    points = np.ascontiguousarray(points)
    points.setflags(write=False)
    return points


def _polygon_row(polygon: np.ndarray, floor: float, ceiling: float) -> np.ndarray:
    lo = polygon.min(axis=0)
    hi = polygon.max(axis=0)
    return np.array([lo[0], lo[1], floor, hi[0], hi[1], ceiling])


@dataclass(frozen=True, eq=False)
class _PolygonBand(TableShape):
    """A polygon in x-y between a floor and a ceiling, validated on construction.

    Attributes
    ----------
    polygon : numpy.ndarray, shape (V, 2)
        Simple polygon [m], either orientation, convex or not.
    floor, ceiling : float
        Height interval [m], floor < ceiling; -inf / +inf for no limit.
    label : str
        What messages call it.
    """

    polygon: np.ndarray
    floor: float = _LOWEST
    ceiling: float = _HIGHEST
    label: str = ''

    def __post_init__(self) -> None:
        object.__setattr__(self, 'polygon', checked_polygon(self.polygon))
        floor, ceiling = _band(self.floor, self.ceiling)
        object.__setattr__(self, 'floor', floor)
        object.__setattr__(self, 'ceiling', ceiling)


@dataclass(frozen=True, eq=False)
class _CircleBand(TableShape):
    """A circle in x-y between a floor and a ceiling, validated on construction.

    Attributes
    ----------
    center : numpy.ndarray, shape (2,)
        Axis position (x, y) [m].
    radius : float
        [m], > 0.
    floor, ceiling : float
        Height interval [m], floor < ceiling; -inf / +inf for no limit.
    label : str
        What messages call it.
    """

    center: np.ndarray
    radius: float
    floor: float = _LOWEST
    ceiling: float = _HIGHEST
    label: str = ''

    def __post_init__(self) -> None:
        object.__setattr__(self, 'center', _plane_point(self.center, 'center'))
        object.__setattr__(self, 'radius', _radius(self.radius))
        floor, ceiling = _band(self.floor, self.ceiling)
        object.__setattr__(self, 'floor', floor)
        object.__setattr__(self, 'ceiling', ceiling)

    def _row(self) -> np.ndarray:
        return np.array([self.center[0], self.center[1], self.radius, self.floor, self.ceiling,
                         0.0])


@dataclass(frozen=True, eq=False)
class Prism(_PolygonBand):
    """Solid vertical prism: a polygon in x-y between a floor and a ceiling (a no-fly volume).

    Built from ``polygon`` [m] (V, 2), ``floor`` and ``ceiling`` [m] and ``label`` (default
    ``'prism'``), checked as :class:`_PolygonBand` says.
    """

    label: str = 'prism'

    def table_row(self) -> Tuple[int, np.ndarray, np.ndarray]:
        return PRISM, _polygon_row(self.polygon, self.floor, self.ceiling), self.polygon


@dataclass(frozen=True, eq=False)
class Cylinder(_CircleBand):
    """Solid vertical cylinder (a no-fly volume).

    Built from ``center`` (x, y) [m], ``radius`` [m], ``floor`` and ``ceiling`` [m] and
    ``label`` (default ``'cylinder'``), checked as :class:`_CircleBand` says.
    """

    label: str = 'cylinder'

    def table_row(self) -> Tuple[int, np.ndarray, np.ndarray]:
        return CYLINDER, self._row(), np.empty((0, 2))


@dataclass(frozen=True, eq=False)
class BoxZone(TableShape):
    """Axis-aligned box no-fly volume.

    Attributes
    ----------
    min, max : numpy.ndarray, shape (3,)
        Opposite corners [m], min < max on every axis.
    label : str
    """

    min: np.ndarray
    max: np.ndarray
    label: str = 'box'

    def __post_init__(self) -> None:
        lo = np.asarray(self.min, dtype=np.float64)
        hi = np.asarray(self.max, dtype=np.float64)
        for name, corner in (('min', lo), ('max', hi)):
            if corner.shape != (3,) or not np.all(np.isfinite(corner)):
                raise InvalidInputError(f'{name}: must be three finite numbers [x, y, z]')
        if np.any(lo >= hi):
            raise InvalidInputError(f'min: must be below max on every axis, got min '
                                    f'{lo.tolist()} and max {hi.tolist()}')
        object.__setattr__(self, 'min', lo)
        object.__setattr__(self, 'max', hi)

    def table_row(self) -> Tuple[int, np.ndarray, np.ndarray]:
        return BOX, np.r_[self.min, self.max], np.empty((0, 2))


@dataclass(frozen=True, eq=False)
class InclusionFence(_PolygonBand):
    """Operating area: a polygon in x-y between a floor and a ceiling; the vehicle stays inside.

    As a shape it is the *outside* of that prism: its distance is the distance to the nearest
    wall, floor or ceiling from inside, 0 outside. Built like :class:`Prism` (fields of
    :class:`_PolygonBand`); without floor or ceiling the planning bounds still apply.
    """

    label: str = 'the inclusion fence'

    def table_row(self) -> Tuple[int, np.ndarray, np.ndarray]:
        return FENCE, _polygon_row(self.polygon, self.floor, self.ceiling), self.polygon


@dataclass(frozen=True, eq=False)
class InclusionCircle(_CircleBand):
    """Circular operating area (a QGroundControl inclusion circle): stay inside the cylinder.

    Built like :class:`Cylinder` (fields of :class:`_CircleBand`).
    """

    label: str = 'the inclusion fence'

    def table_row(self) -> Tuple[int, np.ndarray, np.ndarray]:
        return CIRCLE_FENCE, self._row(), np.empty((0, 2))


Inclusion = Union[InclusionFence, InclusionCircle]
Exclusion = Union[Prism, Cylinder, BoxZone]


@dataclass(frozen=True, eq=False)
class Airspace:
    """Inclusion fences and exclusion zones of one planning frame.

    Attributes
    ----------
    inclusions : tuple of InclusionFence or InclusionCircle
        Every one is enforced; none: the planning bounds are the fence.
    exclusions : tuple of Prism, Cylinder or BoxZone
    """

    inclusions: Tuple[Inclusion, ...] = ()
    exclusions: Tuple[Exclusion, ...] = ()

    def __post_init__(self) -> None:
        inclusions = tuple(self.inclusions)
        exclusions = tuple(self.exclusions)
        for item in inclusions:
            if not isinstance(item, (InclusionFence, InclusionCircle)):
                raise InvalidInputError(f'inclusions: {type(item).__name__} is not an '
                                        'inclusion fence')
        for zone in exclusions:
            if not isinstance(zone, (Prism, Cylinder, BoxZone)):
                raise InvalidInputError(f'exclusions: {type(zone).__name__} is not an '
                                        'exclusion zone')
        object.__setattr__(self, 'inclusions', inclusions)
        object.__setattr__(self, 'exclusions', exclusions)

    def __len__(self) -> int:
        return len(self.inclusions) + len(self.exclusions)

    def shapes(self) -> Tuple[TableShape, ...]:
        """Every fence and zone, fences first."""
        return self.inclusions + self.exclusions

    def with_obstacles(self, obstacles: Optional[ObstacleSet] = None) -> ObstacleSet:
        """An obstacle set holding ``obstacles`` and every fence and zone of this airspace."""
        items = list(obstacles.items) if obstacles is not None else []
        return ObstacleSet(items + list(self.shapes()))

    def merged(self, other: 'Airspace') -> 'Airspace':
        """Both airspaces' fences and zones together."""
        return Airspace(self.inclusions + other.inclusions, self.exclusions + other.exclusions)


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
            band[key] = _number(entry[key], f'{path}.{key}')
    return band


def _vector3(value: Any, path: str) -> np.ndarray:
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise InvalidInputError(f'{path}: must be a list of three numbers [x, y, z], got '
                                f'{value!r}')
    return np.array([_number(item, f'{path}[{axis}]') for axis, item in enumerate(value)])


def _yaml_polygon(value: Any, path: str) -> list:
    if not isinstance(value, list):
        raise InvalidInputError(f'{path}: must be a list of [x, y] pairs')
    for number, vertex in enumerate(value):
        if not isinstance(vertex, (list, tuple)) or len(vertex) != 2:
            raise InvalidInputError(f'{path}[{number}]: must be two numbers [x, y], got '
                                    f'{vertex!r}')
        for axis, item in enumerate(vertex):
            _number(item, f'{path}[{number}][{axis}]')
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
    lat = _number(value[0], f'{path}[0]')
    lon = _number(value[1], f'{path}[1]')
    if not -90.0 <= lat <= 90.0 or not -180.0 <= lon <= 180.0:
        raise InvalidInputError(f'{path}: latitude must be in [-90, 90] and longitude in '
                                f'[-180, 180] degrees, got {[lat, lon]}')
    return lat, lon


def _to_plane(points: Sequence[Tuple[float, float]], origin: GeodeticOrigin) -> np.ndarray:
    """WGS84 (lat, lon) pairs at the origin's altitude to map-frame (x, y) [m]."""
    lat, lon = np.asarray(points, dtype=np.float64).reshape(-1, 2).T
    enu = geodetic_to_enu(lat, lon, np.full(len(lat), origin.alt_amsl), origin)
    return enu[:, :2]


def parse_qgc_geofence(plan: Any, origin: Optional[GeodeticOrigin], floor: float = _LOWEST,
                       ceiling: float = _HIGHEST, zone_floor: float = _LOWEST,
                       zone_ceiling: float = _HIGHEST, name: str = 'plan') -> Airspace:
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
    band = _band(floor, ceiling)
    zone_band = _band(zone_floor, zone_ceiling)
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
                polygon_kind: Type[_PolygonBand] = InclusionFence if inclusion else Prism
                low, high = band if inclusion else zone_band
                shape_object = _prefixed(path, polygon_kind, plane, low, high, label=label)
            else:
                circle = _require(entry, 'circle', path)
                if not isinstance(circle, dict):
                    raise InvalidInputError(f'{path}.circle: must be an object')
                center = _to_plane([_plan_point(_require(circle, 'center', f'{path}.circle'),
                                                f'{path}.circle.center')], origin)[0]
                radius = _require(circle, 'radius', f'{path}.circle')
                circle_kind: Type[_CircleBand] = InclusionCircle if inclusion else Cylinder
                low, high = band if inclusion else zone_band
                shape_object = _prefixed(f'{path}.circle', circle_kind, center, radius, low,
                                         high, label=label)
            (inclusions if inclusion else exclusions).append(shape_object)
    if len(inclusions) == 1:
        only = inclusions[0]
        inclusions[0] = dataclasses.replace(only, label='the inclusion fence')
    return Airspace(tuple(inclusions), tuple(exclusions))


def load_qgc_plan(path: Union[str, Path], origin: Optional[GeodeticOrigin], floor: float = _LOWEST,
                  ceiling: float = _HIGHEST, zone_floor: float = _LOWEST,
                  zone_ceiling: float = _HIGHEST) -> Airspace:
    """Read the ``geoFence`` of a QGroundControl ``.plan`` file (see
    :func:`parse_qgc_geofence` for the arguments)."""
    file = Path(path)
    plan = parse_text_file(file, 'plan file', json.loads, json.JSONDecodeError, 'not valid JSON',
                           not_text='not a text file, so not a plan file')
    return parse_qgc_geofence(plan, origin, floor, ceiling, zone_floor, zone_ceiling,
                              name=file.name)


def load_geofence(path: Union[str, Path], origin: Optional[GeodeticOrigin] = None,
                  floor: float = _LOWEST, ceiling: float = _HIGHEST) -> Airspace:
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


# --- endpoints ------------------------------------------------------------------------------

def zone_gaps(obstacles: ObstacleSet, point) -> np.ndarray:
    """Exact distance from ``point`` to each zone and fence of ``obstacles.zones`` [m].

    For a fence it is the distance to its outside (0 outside the fence).
    """
    return row_gaps(np.asarray(point, dtype=np.float64), obstacles.zone_rows,
                    obstacles.shape_kind, obstacles.shape_params, obstacles.shape_vertices,
                    obstacles.shape_vstart)


def zone_containing(obstacles: ObstacleSet, point) -> Optional[TableShape]:
    """The first zone of ``obstacles`` that ``point`` [m] is inside, or whose fence it is
    outside of (on the boundary counts); None when the point is in free airspace."""
    gaps = zone_gaps(obstacles, point)
    inside = np.flatnonzero(gaps <= 0.0)
    return obstacles.zones[int(inside[0])] if len(inside) else None


def check_endpoint(obstacles: ObstacleSet, point, which: str, gamma: float,
                   slack: float = 0.0) -> None:
    """Refuse an endpoint that is outside a fence, inside a zone or within gamma of one.

    Parameters
    ----------
    obstacles : ObstacleSet
        Its :attr:`~ObstacleSet.zones` are checked (obstacles are not).
    point : array_like, shape (3,)
        [m]
    which : str
        ``'start'`` or ``'goal'``: the error class and the message's first word.
    gamma : float
        Safety margin [m].
    slack : float
        Extra room [m]: a clearance <= gamma + slack is refused (the planner keeps a little
        room for rounding), while the message states gamma.

    Raises
    ------
    StartOutsideMapError, GoalOutsideMapError
        Outside an inclusion fence: ``goal [..] is outside the inclusion fence``.
    StartOccupiedError, GoalOccupiedError
        Inside an exclusion zone (``goal [..] is inside exclusion zone 2 (cylinder)``) or
        within gamma of a zone or of a fence wall, floor or ceiling.
    """
    if which not in ('start', 'goal'):
        raise ValueError(f"which must be 'start' or 'goal', got {which!r}")
    if not len(obstacles.zones):
        return
    p = np.asarray(point, dtype=np.float64)
    gaps = zone_gaps(obstacles, p)
    near = np.flatnonzero(gaps <= gamma + slack)
    if not len(near):
        return
    # A point inside something is named by that; otherwise by the nearest zone.
    number = int(near[np.argmin(gaps[near])])
    zone = obstacles.zones[number]
    gap = float(gaps[number])
    fence = int(obstacles.shape_kind[obstacles.zone_rows[number]]) in UNBOUNDED_KINDS
    where = [round(float(v), 6) for v in p]
    if gap <= 0.0 and fence:
        outside = StartOutsideMapError if which == 'start' else GoalOutsideMapError
        raise outside(f'{which} {where} is outside {zone.label}')
    error = StartOccupiedError if which == 'start' else GoalOccupiedError
    if gap <= 0.0:
        raise error(f'{which} {where} is inside {zone.label}')
    boundary = f'the walls, floor or ceiling of {zone.label}' if fence else zone.label
    raise error(f'{which} {where} is within the safety margin of {boundary}: its clearance is '
                f'{gap:.3f} m, gamma is {gamma} m')
