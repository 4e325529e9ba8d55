"""The fixed parts at both ends of a mission: the take-off climb and the end action.

From a start on the ground the mission begins with a vertical climb (``NAV_TAKEOFF``), certified
like a leg; after the goal the end action flies ``land`` (a vertical descent) or ``rtl`` (climb,
return above home, descend), certified with its turns. ``loiter`` flies nothing after the goal.
"""

import math
from typing import List, Optional

import numpy as np

from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.mission.certify import (certify_triangle, TURN_CELL_INRADIUS,
                                                     turn_triangle)
from uav_global_planner.core.mission.model import UncertifiableMissionError
from uav_global_planner.core.mission.settings import MissionSettings
from uav_global_planner.core.path.clearance import certify_segments

#: Take-off heights tried, the highest clear one first.
_TAKEOFF_ALTERNATIVES = 4


def takeoff_heights(obstacles: ObstacleSet, start: np.ndarray, hi: np.ndarray,
                    settings: MissionSettings, margin: float, required: float,
                    delta: float, lowest: float) -> List[float]:
    """Clear take-off climb heights between ``lowest`` and ``takeoff_height``, highest first.

    ``lowest`` is the acceptance radius (the take-off point is a turn) or the minimum height,
    whichever is higher. A climb clear to some height is clear to every lower one; the highest
    clear height of a ladder ``delta / 4`` apart comes first, then up to
    :data:`_TAKEOFF_ALTERNATIVES` lower ones spread down to ``lowest``.
    """
    top = min(max(settings.takeoff_height, lowest), float(hi[2] - start[2]))
    if top < lowest:
        raise UncertifiableMissionError(
            f'the take-off climb needs {lowest:.3f} m of height above the start (the acceptance '
            f'radius, or the minimum height), but the map ends {hi[2] - start[2]:.3f} m above it')
    steps = max(int(math.ceil((top - lowest) / (delta / 4.0))), 0)
    heights = np.linspace(top, lowest, steps + 1) if steps else np.array([top])
    ends = start + np.c_[np.zeros((len(heights), 2)), heights]
    clear = certify_segments(obstacles, np.broadcast_to(start, ends.shape), ends, margin,
                             delta).clear
    if not np.any(clear):
        raise UncertifiableMissionError(
            f'the take-off climb from {np.round(start, 3).tolist()} does not keep '
            f'{required:.3f} m from the obstacles even to {lowest:.3f} m above it (the start '
            f'itself is {float(obstacles.distance(start)):.3f} m from one)')
    usable = heights[int(np.argmax(clear)):]
    picks = np.unique(np.round(np.linspace(0, len(usable) - 1,
                                           min(len(usable), _TAKEOFF_ALTERNATIVES))))
    return [float(usable[int(i)]) for i in picks]


def check_end_action(obstacles: ObstacleSet, goal: np.ndarray, end_points: np.ndarray,
                     margin: float, required: float, delta: float, radius: float,
                     descent_obstacles: Optional[ObstacleSet] = None) -> None:
    """Certify the legs and the fixed turns flown after the goal (land, rtl).

    A final descent straight down (to the ground) is certified against
    ``descent_obstacles`` when given: the obstacles without the ground it lands on.
    """
    if not len(end_points):
        return
    path = np.vstack([goal[None], end_points])
    legs = certify_segments(obstacles, path[:-1], path[1:], margin + TURN_CELL_INRADIUS, delta)
    clear = np.array(legs.clear, dtype=bool)
    if descent_obstacles is not None and np.allclose(path[-2, :2], path[-1, :2]):
        clear[-1] = certify_segments(descent_obstacles, path[-2:-1], path[-1:],
                                     margin + TURN_CELL_INRADIUS, delta).clear[0]
    if not np.all(clear):
        bad = int(np.flatnonzero(~clear)[0])
        raise UncertifiableMissionError(
            f'the end of the mission flies {np.round(path[bad], 3).tolist()} -> '
            f'{np.round(path[bad + 1], 3).tolist()}, which does not keep {required:.3f} m from '
            'the obstacles; choose another end action (loiter holds at the goal)')
    for n in range(1, len(path) - 1):
        r = min(radius, float(np.linalg.norm(path[n] - path[n - 1])),
                float(np.linalg.norm(path[n + 1] - path[n])))
        a, p, b = turn_triangle(path[n - 1], path[n], path[n + 1], r)
        if not certify_triangle(obstacles, a, p, b, margin, delta,
                                known_sides=margin + TURN_CELL_INRADIUS)[0]:
            raise UncertifiableMissionError(
                f'the turn of the end action at {np.round(path[n], 3).tolist()} does not keep '
                f'{required:.3f} m from the obstacles; choose another end action')


def end_action_points(goal: np.ndarray, home: np.ndarray, floor: float, hi: np.ndarray,
                      settings: MissionSettings) -> np.ndarray:
    """Map-frame points flown after the goal by the end action."""
    if settings.end == 'land':
        return np.array([[goal[0], goal[1], floor]]) if goal[2] > floor else np.empty((0, 3))
    if settings.end == 'rtl':
        top = max(float(goal[2]), float(home[2]) + settings.rtl_altitude)
        if top > hi[2] + 1e-9:
            raise UncertifiableMissionError(
                f'the return altitude {top - home[2]:.3f} m above home reaches z = {top:.3f} m, '
                f'above the map (bounds max z {hi[2]} m), where no obstacles are known')
        points = []
        if top > goal[2]:
            points.append([goal[0], goal[1], top])
        points += [[home[0], home[1], top], home.tolist()]
        return np.array(points)
    return np.empty((0, 3))
