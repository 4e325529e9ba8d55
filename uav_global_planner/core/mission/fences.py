"""The mission's 2D geofence: autopilot fences of the airspace, in WGS84.

Fences
------
The map's airspace (:mod:`uav_global_planner.core.map.airspace`: inclusion fences, exclusion zones)
keeps the clearance like any obstacle when it is in the obstacle set, as a scene file's
``geofence`` puts it. It is also written as the ``.plan`` ``geoFence`` (WGS84, polygons
clockwise), with :class:`FencePolygon` and :class:`FenceCircle` given directly: autopilot fences
are 2D, so an exclusion zone whose footprint the mission flies over or under is left out (and
named in :attr:`GeoFence.skipped`) instead of being written as a fence the mission breaches.
Without fences the ``geoFence`` is empty (version 2, no polygons, no circles).
"""

import math
from typing import assert_never, List, Sequence, Tuple

import numpy as np

from uav_global_planner.core.io.geodesy import enu_to_geodetic, GeodeticOrigin
from uav_global_planner.core.map.airspace import Airspace
from uav_global_planner.core.map.zones import (BoxZone, Cylinder, InclusionCircle, InclusionFence,
                                               Prism)
from uav_global_planner.core.mission.model import FenceCircle, FencePolygon, GeoFence
from uav_global_planner.core.mission.stored import ALTITUDE_DECIMALS, LATLON_DECIMALS, round_stored


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (a[..., 0] - o[..., 0]) * (b[..., 1] - o[..., 1]) - (
        a[..., 1] - o[..., 1]) * (b[..., 0] - o[..., 0])


def _segments_meet(p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> bool:
    """True when any 2D segment ``p0[i] p1[i]`` meets any ``q0[j] q1[j]`` (touching counts)."""
    a, b = p0[:, None], p1[:, None]
    c, d = q0[None], q1[None]
    d1, d2 = _cross(c, d, a), _cross(c, d, b)
    d3, d4 = _cross(a, b, c), _cross(a, b, d)
    proper = (d1 * d2 < 0.0) & (d3 * d4 < 0.0)
    if np.any(proper):
        return True

    def on(o, e, x, side):
        lo, hi = np.minimum(o, e), np.maximum(o, e)
        return (side == 0.0) & np.all((x >= lo - 1e-12) & (x <= hi + 1e-12), axis=-1)
    return bool(np.any(on(c, d, a, d1) | on(c, d, b, d2) | on(a, b, c, d3) | on(a, b, d, d4)))


def _inside_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd test of 2D points against a simple polygon."""
    x, y = points[:, 0:1], points[:, 1:2]
    x0, y0 = polygon[:, 0], polygon[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    straddle = (y0 > y) != (y1 > y)
    with np.errstate(divide='ignore', invalid='ignore'):
        at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    return np.sum(straddle & (x < at), axis=1) % 2 == 1


def _footprint_crossed(polygon: np.ndarray, legs: np.ndarray, turns: np.ndarray) -> bool:
    """True when the 2D footprint of the flight (legs and turn triangles) meets the polygon."""
    edges0, edges1 = polygon, np.roll(polygon, -1, axis=0)
    starts, ends = legs[:, 0, :2], legs[:, 1, :2]
    if len(turns):
        # A turn triangle's sides on the legs are legs already; its cut A -> B is not.
        starts = np.vstack([starts, turns[:, 0, :2]])
        ends = np.vstack([ends, turns[:, 2, :2]])
    if _segments_meet(starts, ends, edges0, edges1):
        return True
    if np.any(_inside_polygon(legs[:, 0, :2], polygon)):
        return True
    return any(np.any(_inside_polygon(polygon[:1], tri[:, :2])) for tri in turns)


def _circle_polygon(center: np.ndarray, radius: float, count: int = 64) -> np.ndarray:
    """A polygon around a circle (circumscribed), for the footprint test."""
    angles = np.linspace(0.0, 2.0 * math.pi, count, endpoint=False)
    scale = radius / math.cos(math.pi / count)
    return center + scale * np.c_[np.cos(angles), np.sin(angles)]


def fences_of_airspace(airspace: Airspace, legs: np.ndarray = np.empty((0, 2, 3)),
                       turns: np.ndarray = np.empty((0, 3, 3))
                       ) -> Tuple[List[FencePolygon], List[FenceCircle], List[str]]:
    """The 2D autopilot fences of an airspace, for a mission flying ``legs`` and ``turns``.

    Inclusion fences become inclusion polygons and circles; prisms, boxes and cylinders become
    exclusion polygons and circles (their footprints). Autopilot fences are 2D (PX4 and
    ArduPilot take the height limit from parameters), so an exclusion zone whose footprint the
    mission flies over or under is skipped (named in the third list) rather than written as a
    fence the mission would breach; the mission keeps its clearance from it all the same.
    """
    polygons: List[FencePolygon] = []
    circles: List[FenceCircle] = []
    skipped: List[str] = []
    for fence in airspace.inclusions:
        if isinstance(fence, InclusionFence):
            polygons.append(FencePolygon(fence.polygon, inclusion=True))
        elif isinstance(fence, InclusionCircle):
            circles.append(FenceCircle(fence.center, fence.radius, inclusion=True))
    for zone in airspace.exclusions:
        if isinstance(zone, Cylinder):
            footprint = _circle_polygon(zone.center, zone.radius)
        elif isinstance(zone, Prism):
            footprint = zone.polygon
        elif isinstance(zone, BoxZone):
            (x0, y0), (x1, y1) = zone.min[:2], zone.max[:2]
            footprint = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
        else:
            assert_never(zone)  # Airspace holds only these three kinds
        if len(legs) and _footprint_crossed(footprint, legs, turns):
            skipped.append(f'{zone.label}: the mission flies over or under it')
            continue
        if isinstance(zone, Cylinder):
            circles.append(FenceCircle(zone.center, zone.radius, inclusion=False))
        else:
            polygons.append(FencePolygon(footprint, inclusion=False))
    return polygons, circles, skipped


def wgs84_geofence(polygons: Sequence[FencePolygon], circles: Sequence[FenceCircle],
                   origin: GeodeticOrigin, skipped: Sequence[str] = ()) -> GeoFence:
    """The fences in WGS84 as stored (polygons clockwise seen from above), and the skipped."""
    out_polygons = []
    for polygon in polygons:
        xy = polygon.vertices
        signed = 0.5 * float(np.sum(xy[:, 0] * np.roll(xy[:, 1], -1)
                                    - np.roll(xy[:, 0], -1) * xy[:, 1]))
        if signed > 0.0:   # counter-clockwise seen from above (x east, y north): reverse
            xy = xy[::-1]
        lat, lon, _ = enu_to_geodetic(np.c_[xy, np.zeros(len(xy))], origin)
        out_polygons.append((tuple((round_stored(a, LATLON_DECIMALS),
                                    round_stored(b, LATLON_DECIMALS))
                                   for a, b in zip(lat, lon)), bool(polygon.inclusion)))
    out_circles = []
    for circle in circles:
        lat, lon, _ = enu_to_geodetic(np.r_[circle.center, 0.0][None], origin)
        out_circles.append(((round_stored(lat[0], LATLON_DECIMALS),
                             round_stored(lon[0], LATLON_DECIMALS)),
                            round_stored(circle.radius, ALTITUDE_DECIMALS),
                            bool(circle.inclusion)))
    return GeoFence(tuple(out_polygons), tuple(out_circles), tuple(skipped))
