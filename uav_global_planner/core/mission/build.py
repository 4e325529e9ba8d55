"""Building a mission from a plan: waypoints, take-off, end action, stored and certified items.

:func:`build_mission` checks the input, chooses the waypoints
(:mod:`~uav_global_planner.core.mission.waypoints`) between the take-off and the end action
(:mod:`~uav_global_planner.core.mission.ends`), rounds them to the stored values
(:mod:`~uav_global_planner.core.mission.stored`), certifies what is stored and makes the
MAVLink items and the geofence (:mod:`~uav_global_planner.core.mission.fences`).
"""

import math
from typing import Any, List, Optional, Sequence, Tuple

import numpy as np

from uav_global_planner.core.checks import check_path
from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.geodesy import GeodeticOrigin
from uav_global_planner.core.map.airspace import Airspace
from uav_global_planner.core.map.ground import ground_height, without_ground
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.mission.certify import (certify_triangle, TURN_CELL_INRADIUS,
                                                     turn_triangle)
from uav_global_planner.core.mission.ends import (check_end_action, end_action_points,
                                                  takeoff_heights)
from uav_global_planner.core.mission.fences import fences_of_airspace, wgs84_geofence
from uav_global_planner.core.mission.model import (FenceCircle, FencePolygon,
                                                   MAV_CMD_DO_CHANGE_SPEED, MAV_CMD_NAV_LAND,
                                                   MAV_CMD_NAV_LOITER_UNLIM,
                                                   MAV_CMD_NAV_RETURN_TO_LAUNCH,
                                                   MAV_CMD_NAV_TAKEOFF, MAV_CMD_NAV_WAYPOINT,
                                                   MAV_FRAME_GLOBAL_RELATIVE_ALT,
                                                   MAV_FRAME_MISSION, Mission, MissionItem,
                                                   SPEED_TYPE_CLIMB, SPEED_TYPE_DESCENT,
                                                   SPEED_TYPE_GROUND, UncertifiableMissionError)
from uav_global_planner.core.mission.settings import MissionSettings
from uav_global_planner.core.mission.stored import ROUNDING_SLACK, stored_item, StoredGeo
from uav_global_planner.core.mission.waypoints import (candidate_points, offset_layers,
                                                       SearchExhausted, WaypointNode,
                                                       WaypointSearch)
from uav_global_planner.core.path.clearance import certify_segments


def _yaw(settings: MissionSettings) -> float:
    # PX4 turns to the given yaw (0 = north) unless it is NaN; ArduCopter ignores the field.
    return math.nan if settings.firmware == 'px4' else 0.0


def build_mission(smoothed_path: Any, obstacles: ObstacleSet, config: PlannerConfig,
                  origin: GeodeticOrigin, settings: MissionSettings = MissionSettings(), *,
                  raw_path: Any = (), via: Any = (),
                  fence_polygons: Sequence[FencePolygon] = (),
                  fence_circles: Sequence[FenceCircle] = (),
                  airspace: Optional[Airspace] = None) -> Mission:
    """Choose certified waypoints along a plan and make the mission items.

    Parameters
    ----------
    smoothed_path : array_like, shape (M, 3)
        Samples of the plan's smoothed curve, start first and goal last [m] (map frame).
    obstacles : ObstacleSet
        The obstacles the mission must keep clear of (map frame).
    config : PlannerConfig
        Bounds (the floor is the ground, unless ``obstacles`` hold a ground or terrain height
        field: then the ground under the start and the goal is that surface), gamma, delta,
        and the speed limits of the plan.
    origin : GeodeticOrigin
        WGS84 position of the map frame's origin.
    settings : MissionSettings
    raw_path : array_like, shape (N, 3), optional
        The plan's raw grid path: more candidate waypoints.
    via : array_like, shape (V, 3), optional
        Via-points the mission must fly through (never skipped).
    fence_polygons, fence_circles : sequences
        Geofences to write with the mission (not part of the certificate; see
        :mod:`~uav_global_planner.core.mission.fences`).
    airspace : Airspace, optional
        The fences and zones of the map (:mod:`uav_global_planner.core.map.airspace`), written as
        the mission's 2D geofence (:func:`fences_of_airspace`). For the certificate they must be
        in ``obstacles`` as well, as a scene file's ``geofence`` puts them.

    Returns
    -------
    Mission

    Raises
    ------
    InvalidInputError
        For malformed input (shapes, NaN, a path outside the bounds).
    UncertifiableMissionError
        When no mission keeps gamma + allowance: names the place and the reason.
    MissingDependencyError
        When pymap3d is not installed.
    """
    if not isinstance(obstacles, ObstacleSet):
        raise InvalidInputError('obstacles must be an ObstacleSet')
    if not isinstance(settings, MissionSettings):
        raise InvalidInputError('settings must be a MissionSettings')
    smoothed = check_path('smoothed_path', smoothed_path)
    raw = check_path('raw_path', raw_path, allow_empty=True)
    via_points = check_path('via', via, allow_empty=True)
    lo = np.asarray(config.bounds_min, dtype=np.float64)
    hi = np.asarray(config.bounds_max, dtype=np.float64)
    slack_bounds = 1e-6 * max(1.0, float(np.max(hi - lo)))
    if np.any(smoothed < lo - slack_bounds) or np.any(smoothed > hi + slack_bounds):
        raise InvalidInputError('smoothed_path leaves the bounds of the config: not a plan of '
                                'this map')
    # The body keeps gamma: the vehicle radius is added, as the planner does.
    gamma = float(config.safety_margin) + float(config.vehicle_radius)
    delta = float(config.resolution)
    radius = float(settings.acceptance_radius)
    # Rounded to a nanometre so that 0.2 + 0.1 reads 0.3 in every report.
    required = round(gamma + float(settings.tracking_allowance), 9)
    search_margin = required + ROUNDING_SLACK
    # Legs (and so every waypoint) keep a turn cell's inradius more: see
    # WaypointSearch._legs_clear.
    leg_margin = search_margin + TURN_CELL_INRADIUS
    start, goal = smoothed[0], smoothed[-1]
    if np.linalg.norm(goal - start) < radius:
        raise InvalidInputError(
            f'start and goal are {np.linalg.norm(goal - start):.3f} m apart, less than the '
            f'acceptance radius {radius} m: nothing to fly')
    # The ground under the start and the goal: a terrain or ground height field of the
    # obstacles where there is one, else the bounds' floor.
    floor = ground_height(obstacles, start[:2], float(lo[2]))
    goal_floor = ground_height(obstacles, goal[:2], float(lo[2]))
    # The take-off climb and the landing descent go straight up and down through the ground's
    # margin (and an AGL floor): they are kept from every other obstacle.
    vertical_obstacles = without_ground(obstacles)
    tolerance = delta if settings.ground_tolerance is None else float(settings.ground_tolerance)
    min_height = required if settings.min_height is None else float(settings.min_height)
    on_ground = float(start[2]) - floor <= tolerance
    home = start.copy() if on_ground else np.array([start[0], start[1], floor])

    goal_clearance = float(obstacles.distance(goal))
    if goal_clearance < leg_margin:
        raise UncertifiableMissionError(
            f'the goal {np.round(goal, 3).tolist()} is {goal_clearance:.3f} m from an obstacle; '
            f'the mission needs gamma + tracking allowance = {required:.3f} m (plus '
            f'{ROUNDING_SLACK} m for rounding): lower tracking_allowance or move the goal')
    for n, point in enumerate(via_points):
        clearance = float(obstacles.distance(point))
        if clearance < leg_margin:
            raise UncertifiableMissionError(
                f'via-point {n} {np.round(point, 3).tolist()} is {clearance:.3f} m from an '
                f'obstacle; the mission needs {required:.3f} m')

    # The first node: the take-off point (a turn whose incoming leg is the climb), or the start.
    if on_ground:
        heights = takeoff_heights(vertical_obstacles, start, hi, settings, leg_margin, required,
                                  delta,
                                  max(radius, floor + min_height - float(start[2])))
        firsts = [WaypointNode(start + np.array([0.0, 0.0, h]), start, -1, -1.0)
                  for h in heights]
    else:
        firsts = [WaypointNode(start, None, -1, -1.0)]

    spacing = max(delta / 2.0, 1e-3)
    points, progress, fixed = candidate_points(smoothed, raw, via_points, spacing)
    # The ground is kept at the clearance too: waypoints (not the goal or via-points) are
    # lifted to ``min_height`` above the floor; straight legs and turn triangles between points
    # above it stay above it.
    raised = lo.copy()
    raised[2] = min(float(lo[2]) + min_height, float(hi[2]))
    points[~fixed, 2] = np.maximum(points[~fixed, 2], raised[2])
    points, progress, fixed = offset_layers(points, progress, fixed, obstacles, leg_margin,
                                            radius, settings.tracking_allowance + delta, raised,
                                            hi)
    mandatory = np.flatnonzero(fixed)[1:]       # the vias and the goal; not the start
    if progress[0] < 0.0:                       # the start is where the first node is
        points, progress, fixed = points[1:], progress[1:], fixed[1:]
        mandatory = mandatory - 1
    progress = np.maximum(progress, 0.0)

    end_points = end_action_points(goal, home, goal_floor, hi, settings)
    check_end_action(obstacles, goal, end_points, search_margin, required, delta, radius,
                     vertical_obstacles)
    search = WaypointSearch(obstacles, points, progress, mandatory, search_margin, delta,
                            radius, end_points[0] if len(end_points) else None)
    chain = None
    # The highest clear take-off first; a lower one where the turn under an overhang fails.
    for first in firsts:
        try:
            chain = search.run(first)
            break
        except SearchExhausted:
            continue
    if chain is None:
        where = smoothed[min(int(max(search.farthest, 0.0)), len(smoothed) - 1)]
        raise UncertifiableMissionError(
            f'no certified waypoints past {np.round(where, 3).tolist()} (the plan there is '
            f'{float(obstacles.distance(where)):.3f} m from an obstacle): straight legs, turns '
            f'within acceptance radius {radius} m and legs >= that radius cannot keep gamma + '
            f'tracking allowance = {required:.3f} m; lower tracking_allowance or '
            'acceptance_radius, or plan with a larger safety_margin')

    nominal = np.array(([home] if on_ground else []) + [node.position for node in chain])
    geo = StoredGeo(origin, home)
    return _assemble(nominal, end_points, on_ground, geo, (obstacles, vertical_obstacles),
                     config, settings, required, (fence_polygons, fence_circles, airspace),
                     goal_floor)


def _assemble(nominal: np.ndarray, end_points: np.ndarray, on_ground: bool, geo: StoredGeo,
              both: Tuple[ObstacleSet, ObstacleSet], config: PlannerConfig,
              settings: MissionSettings, required: float,
              fences: Tuple[Sequence[FencePolygon], Sequence[FenceCircle], Optional[Airspace]],
              goal_floor: float) -> Mission:
    """Round to the stored values, certify what is stored and make the items.

    ``both`` holds the obstacles and those a take-off climb or landing descent is kept from
    (without the ground, :func:`~uav_global_planner.core.map.ground.without_ground`).
    """
    obstacles, vertical_obstacles = both
    radius = settings.acceptance_radius
    yaw = _yaw(settings)
    lat, lon, rel = geo.stored(nominal)
    count = len(nominal)
    if on_ground:
        # Home and the take-off point share the start's horizontal position, as flown.
        lat[1], lon[1] = lat[0], lon[0]
    stored = geo.back(lat, lon, rel)
    home_enu = geo.back(np.array([geo.home[0]]), np.array([geo.home[1]]), np.zeros(1))[0]
    if on_ground:
        stored[0] = home_enu
    # The end action flies from the stored goal and returns to the stored home; the files hold
    # no positions of their own for it (LAND takes the goal's, RTL none).
    if len(end_points):
        end_points = end_action_points(stored[-1], home_enu, goal_floor,
                                       np.asarray(config.bounds_max, dtype=np.float64),
                                       settings)
    path = np.vstack([stored, end_points])
    # Drop repeated points (an end descent of length 0, a return already at altitude).
    keep = np.r_[True, np.linalg.norm(np.diff(path, axis=0), axis=1) > 1e-9]
    flight = path[keep]

    # Turns: every interior point of the flight path, except the loiter goal at the end.
    turn_list = []
    for n in range(1, len(flight) - 1):
        before, corner, after = flight[n - 1], flight[n], flight[n + 1]
        r = min(radius, float(np.linalg.norm(before - corner)),
                float(np.linalg.norm(after - corner)))
        turn_list.append(turn_triangle(before, corner, after, r))
    turns = np.array(turn_list).reshape(-1, 3, 3)

    delta = config.resolution
    legs = certify_segments(obstacles, flight[:-1], flight[1:], required, delta)
    clear, leg_bounds = np.array(legs.clear, dtype=bool), np.array(legs.bound, dtype=float)
    # The take-off climb from home and a final descent to the ground, straight up and down.
    ground_legs = {0} if on_ground else set()
    if settings.end in ('land', 'rtl') and len(end_points) and len(flight) > 1 \
            and np.allclose(flight[-2, :2], flight[-1, :2]):
        ground_legs.add(len(flight) - 2)
    if vertical_obstacles is not obstacles and ground_legs:
        rows = np.array(sorted(ground_legs))
        again = certify_segments(vertical_obstacles, flight[rows], flight[rows + 1], required,
                                 delta)
        clear[rows], leg_bounds[rows] = again.clear, again.bound
    bounds = [np.min(leg_bounds)] if len(leg_bounds) else []
    if not np.all(clear):
        bad = int(np.flatnonzero(~clear)[0])
        raise UncertifiableMissionError(
            f'the stored leg {np.round(flight[bad], 3).tolist()} -> '
            f'{np.round(flight[bad + 1], 3).tolist()} does not keep {required:.3f} m')
    for tri in turns:
        ok, bound = certify_triangle(obstacles, tri[0], tri[1], tri[2], required, delta)
        if not ok:
            raise UncertifiableMissionError(
                f'the turn at {np.round(tri[1], 3).tolist()} does not keep {required:.3f} m '
                'from the obstacles')
        bounds.append(bound)
    certified = float(min(bounds)) if bounds else math.inf
    polygons, circles, airspace = fences
    skipped: List[str] = []
    if airspace is not None:
        extra_polygons, extra_circles, skipped = fences_of_airspace(
            airspace, np.stack([flight[:-1], flight[1:]], axis=1), turns)
        polygons, circles = list(polygons) + extra_polygons, list(circles) + extra_circles
    fence = wgs84_geofence(polygons, circles, geo.origin, skipped)

    items: List[MissionItem] = []
    first_wp = 1 if on_ground else 0
    if on_ground:
        items.append(stored_item(MAV_CMD_NAV_TAKEOFF, MAV_FRAME_GLOBAL_RELATIVE_ALT, 0.0, 0.0,
                                 0.0, yaw, lat[1], lon[1], rel[1]))
        first_wp = 2
    vh, vz = float(config.max_speed_horizontal), float(config.max_speed_vertical)
    items.append(stored_item(MAV_CMD_DO_CHANGE_SPEED, MAV_FRAME_MISSION, SPEED_TYPE_GROUND, vh,
                             -1.0))
    if settings.firmware == 'ardupilot':
        items.append(stored_item(MAV_CMD_DO_CHANGE_SPEED, MAV_FRAME_MISSION, SPEED_TYPE_CLIMB,
                                 vz, -1.0))
        items.append(stored_item(MAV_CMD_DO_CHANGE_SPEED, MAV_FRAME_MISSION, SPEED_TYPE_DESCENT,
                                 vz, -1.0))
    last = count - 1
    for n in range(first_wp, count):
        if n == last and settings.end == 'loiter':
            items.append(stored_item(MAV_CMD_NAV_LOITER_UNLIM, MAV_FRAME_GLOBAL_RELATIVE_ALT,
                                     0.0, 0.0, 0.0, yaw, lat[n], lon[n], rel[n]))
        else:
            items.append(stored_item(MAV_CMD_NAV_WAYPOINT, MAV_FRAME_GLOBAL_RELATIVE_ALT, 0.0,
                                     radius, 0.0, yaw, lat[n], lon[n], rel[n]))
    if settings.end == 'land':
        items.append(stored_item(MAV_CMD_NAV_LAND, MAV_FRAME_GLOBAL_RELATIVE_ALT, 0.0, 0.0, 0.0,
                                 yaw, lat[last], lon[last], 0.0))
    elif settings.end == 'rtl':
        items.append(stored_item(MAV_CMD_NAV_RETURN_TO_LAUNCH, MAV_FRAME_MISSION))
    return Mission(items=tuple(items), home=geo.home, home_enu=home_enu, origin=geo.origin,
                   settings=settings, flight_path=flight, turn_regions=turns,
                   safety_margin_m=float(config.safety_margin), required_clearance_m=required,
                   certified_clearance_m=certified, speed_horizontal=vh, speed_vertical=vz,
                   fence=fence)


def mission_from_plan(result: Any, obstacles: ObstacleSet, config: PlannerConfig,
                      origin: GeodeticOrigin, settings: MissionSettings = MissionSettings(),
                      **fences: Any) -> Mission:
    """:func:`build_mission` for a :class:`~uav_global_planner.core.result.PlanResult`.

    Raises
    ------
    InvalidInputError
        When the plan did not succeed.
    """
    if not getattr(result, 'ok', False):
        raise InvalidInputError(f'no plan to export: the plan failed '
                                f'({getattr(result, "status", "?")})')
    return build_mission(result.smoothed_path, obstacles, config, origin, settings,
                         raw_path=result.path, via=getattr(result, 'via', ()), **fences)
