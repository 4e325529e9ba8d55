"""``visualization_msgs/MarkerArray`` drawings of obstacle sets, for RViz and as map input."""

import math
from typing import Sequence

from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.ros.conversions.poses import vector3
from uav_global_planner.ros.conversions.stamps import time_from_ns

_OBSTACLE_COLOR = ColorRGBA(r=0.8, g=0.2, b=0.2, a=0.9)
_INFLATED_COLOR = ColorRGBA(r=1.0, g=0.6, b=0.1, a=0.25)


def _marker(frame_id: str, stamp_ns: int, ns: str, marker_id: int, marker_type: int,
            color: ColorRGBA) -> Marker:
    marker = Marker()
    marker.header = Header(frame_id=frame_id, stamp=time_from_ns(stamp_ns))
    marker.ns, marker.id, marker.type, marker.action = ns, marker_id, marker_type, Marker.ADD
    marker.pose.orientation.w = 1.0
    marker.color = color
    return marker


def _set_scale(marker: Marker, size: Sequence[float]) -> None:
    marker.scale = vector3(size)


def obstacle_markers(obstacles: ObstacleSet, frame_id: str, stamp_ns: int,
                     safety_margin: float, max_points: int = 20_000) -> MarkerArray:
    """Obstacles as used by the planner, for RViz, after a DELETEALL that clears stale ones.

    Namespace ``obstacles`` draws the obstacles themselves, ``inflated`` each grown by the
    safety margin gamma (boxes as their grown bounding box; the true inflated box has rounded
    edges, so the drawing is slightly conservative), and point sets as sphere lists (at most
    ``max_points`` points, evenly subsampled, so a large cloud cannot flood RViz).
    """
    gamma = float(safety_margin)
    clear = Marker(action=Marker.DELETEALL)
    clear.header = Header(frame_id=frame_id, stamp=time_from_ns(stamp_ns))
    markers = [clear]
    next_id = {'obstacles': 0, 'inflated': 0}

    def add(ns: str, marker_type: int, color: ColorRGBA, center, size) -> Marker:
        marker = _marker(frame_id, stamp_ns, ns, next_id[ns], marker_type, color)
        next_id[ns] += 1
        marker.pose.position = Point(x=float(center[0]), y=float(center[1]),
                                     z=float(center[2]))
        _set_scale(marker, size)
        markers.append(marker)
        return marker

    for center, radius in zip(obstacles.sphere_centers, obstacles.sphere_radii):
        add('obstacles', Marker.SPHERE, _OBSTACLE_COLOR, center, [2 * radius] * 3)
        add('inflated', Marker.SPHERE, _INFLATED_COLOR, center, [2 * (radius + gamma)] * 3)
    for lo, hi in zip(obstacles.box_mins, obstacles.box_maxs):
        center = 0.5 * (lo + hi)
        add('obstacles', Marker.CUBE, _OBSTACLE_COLOR, center, hi - lo)
        add('inflated', Marker.CUBE, _INFLATED_COLOR, center, hi - lo + 2 * gamma)
    points = obstacles.points
    if len(points):
        stride = max(1, int(math.ceil(len(points) / max_points)))
        shown = [Point(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in points[::stride]]
        raw = add('obstacles', Marker.CUBE_LIST, _OBSTACLE_COLOR, (0.0, 0.0, 0.0),
                  [0.05] * 3)
        raw.points = shown
        if gamma > 0.0:
            grown = add('inflated', Marker.SPHERE_LIST, _INFLATED_COLOR, (0.0, 0.0, 0.0),
                        [2 * gamma] * 3)
            grown.points = shown
    msg = MarkerArray()
    msg.markers = markers
    return msg


def obstacle_input_markers(obstacles: ObstacleSet, frame_id: str, stamp_ns: int,
                           ns: str = 'scene') -> MarkerArray:
    """Spheres and boxes of an obstacle set as the planner's ``obstacles`` input.

    Starts with a DELETEALL of ``ns``, so republishing replaces the previous scene. Point sets
    are not included; send them as a cloud (:func:`points_to_cloud`).
    """
    clear = Marker(ns=ns, action=Marker.DELETEALL)
    clear.header = Header(frame_id=frame_id, stamp=time_from_ns(stamp_ns))
    markers = [clear]
    for center, radius in zip(obstacles.sphere_centers, obstacles.sphere_radii):
        marker = _marker(frame_id, stamp_ns, ns, len(markers) - 1, Marker.SPHERE,
                         _OBSTACLE_COLOR)
        marker.pose.position = Point(x=float(center[0]), y=float(center[1]),
                                     z=float(center[2]))
        _set_scale(marker, [2.0 * float(radius)] * 3)
        markers.append(marker)
    for lo, hi in zip(obstacles.box_mins, obstacles.box_maxs):
        marker = _marker(frame_id, stamp_ns, ns, len(markers) - 1, Marker.CUBE,
                         _OBSTACLE_COLOR)
        center = 0.5 * (lo + hi)
        marker.pose.position = Point(x=float(center[0]), y=float(center[1]),
                                     z=float(center[2]))
        _set_scale(marker, hi - lo)
        markers.append(marker)
    msg = MarkerArray()
    msg.markers = markers
    return msg
