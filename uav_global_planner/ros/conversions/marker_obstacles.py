"""Obstacles from ``visualization_msgs/MarkerArray`` messages, keyed by (namespace, id).

Markers are applied all or nothing: a refused message leaves the obstacles in force unchanged.
Each accepted marker becomes an obstacle *enclosing* what RViz draws, so the safety guarantee
holds for every marker the planner accepts.
"""

from typing import Dict, Mapping, Optional, Tuple

import numpy as np
from visualization_msgs.msg import Marker, MarkerArray

from uav_global_planner.core.map.obstacles import Box, Obstacle, ObstacleSet, PointSet, Sphere
from uav_global_planner.ros.conversions.errors import InputRejected
from uav_global_planner.ros.conversions.poses import (check_frame, point_to_array,
                                                      quaternion_to_array, rotation_matrix)

#: Marker identity: (namespace, id), as RViz keys markers.
MarkerKey = Tuple[str, int]


def marker_to_obstacle(marker: Marker, max_size: float) -> Obstacle:
    """Obstacle enclosing one ``SPHERE`` or ``CUBE`` marker (action ADD).

    A ``SPHERE`` becomes the sphere of radius ``max(scale) / 2``, which encloses the ellipsoid
    RViz draws; a ``CUBE`` becomes its axis-aligned bounding box, exact when unrotated.
    Enclosing shapes keep the safety guarantee for every marker the planner accepts.

    Parameters
    ----------
    marker : visualization_msgs.msg.Marker
    max_size : float
        Largest accepted scale component [m]; bigger markers are refused as implausible.

    Raises
    ------
    InputRejected
        For an unsupported type, non-finite pose, or a scale component that is not in
        (0, max_size].
    """
    what = f'marker (ns {marker.ns!r}, id {marker.id})'
    if marker.type not in (Marker.SPHERE, Marker.CUBE):
        raise InputRejected(
            f'{what} has unsupported type {marker.type}; only SPHERE ({Marker.SPHERE}) and '
            f'CUBE ({Marker.CUBE}) describe obstacles')
    center = point_to_array(marker.pose.position, f'{what} position')
    rotation = quaternion_to_array(marker.pose.orientation, what)
    scale = np.array([marker.scale.x, marker.scale.y, marker.scale.z], dtype=np.float64)
    if not np.all(np.isfinite(scale)) or np.any(scale <= 0.0):
        raise InputRejected(f'{what} scale must be finite and > 0 m, got {scale.tolist()}')
    if np.any(scale > max_size):
        raise InputRejected(
            f'{what} scale {scale.tolist()} exceeds max_obstacle_size = {max_size} m')
    if marker.type == Marker.SPHERE:
        return Sphere(center, 0.5 * float(np.max(scale)))
    half = np.abs(rotation_matrix(rotation)) @ (0.5 * scale)
    return Box(center - half, center + half)


def apply_marker_array(current: Mapping[MarkerKey, Obstacle], msg: MarkerArray,
                       expected_frame: str, max_size: float) -> Dict[MarkerKey, Obstacle]:
    """Apply a ``MarkerArray`` to the obstacles keyed by (ns, id), all or nothing.

    Markers are applied in order: ADD/MODIFY insert or replace, DELETE removes (a missing key is
    not an error), DELETEALL removes every marker, or only those of its namespace when ``ns`` is
    set. Frames are checked for ADD only, because deletions carry no geometry. ``lifetime`` and
    ``frame_locked`` are ignored: an obstacle stays until it is deleted.

    Returns
    -------
    dict
        A new mapping; ``current`` is never modified, so a refused message leaves the previous
        obstacles in force.

    Raises
    ------
    InputRejected
        At the first bad marker, naming it; nothing is applied then.
    """
    updated = dict(current)
    for marker in msg.markers:
        key = (str(marker.ns), int(marker.id))
        if marker.action == Marker.ADD:
            check_frame(marker.header.frame_id, expected_frame,
                        f'marker (ns {marker.ns!r}, id {marker.id})')
            updated[key] = marker_to_obstacle(marker, max_size)
        elif marker.action == Marker.DELETE:
            updated.pop(key, None)
        elif marker.action == Marker.DELETEALL:
            if marker.ns:
                updated = {k: v for k, v in updated.items() if k[0] != marker.ns}
            else:
                updated = {}
        else:
            raise InputRejected(
                f'marker (ns {marker.ns!r}, id {marker.id}) has unknown action {marker.action}')
    return updated


def same_obstacle(first: Obstacle, second: Obstacle) -> bool:
    """True when two obstacles have the same shape and the same numbers."""
    if first is second:
        return True
    if type(first) is not type(second):
        return False
    if isinstance(first, Sphere) and isinstance(second, Sphere):
        return (first.radius == second.radius
                and bool(np.array_equal(first.center, second.center)))
    if isinstance(first, Box) and isinstance(second, Box):
        return (bool(np.array_equal(first.min, second.min))
                and bool(np.array_equal(first.max, second.max)))
    if isinstance(first, PointSet) and isinstance(second, PointSet):
        return bool(np.array_equal(first.points, second.points))
    return False  # shapes no marker makes (geofence, terrain): equal only when the same object


def same_marker_obstacles(first: Mapping[MarkerKey, Obstacle],
                          second: Mapping[MarkerKey, Obstacle]) -> bool:
    """True when two (ns, id)-keyed obstacle maps hold the same keys and the same shapes.

    An empty ``MarkerArray``, a DELETE of an unknown marker or a republished map change nothing.
    """
    return (first.keys() == second.keys()
            and all(same_obstacle(first[key], second[key]) for key in first))


def combine_obstacles(markers: Mapping[MarkerKey, Obstacle],
                      cloud: Optional[np.ndarray]) -> ObstacleSet:
    """One :class:`ObstacleSet` of the marker obstacles (in key order) and the cloud points."""
    items = [markers[key] for key in sorted(markers)]
    if cloud is not None and len(cloud):
        items.append(PointSet(cloud))
    return ObstacleSet(items)
