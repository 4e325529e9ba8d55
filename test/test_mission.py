"""Mission export core: geodesy, the certified waypoint choice, the .plan and WPL writers.

The clearance of an exported mission is checked independently of the certificate that chose it:
the written file is read back, converted to the map frame with pymap3d directly, and the obstacle
distance is evaluated at 10^4 samples along the legs and at random points of every turn region.
"""

import json
import math
import sys

import numpy as np
import pymap3d
import pytest

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.geodesy import (enu_to_geodetic, geodetic_to_enu, GeodeticOrigin,
                                                MissingDependencyError, parse_origin)
from uav_global_planner.core.io.scene import find_scene, load_scene, parse_scene
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, PointSet, Sphere
from uav_global_planner.core.mission import (build_mission, certify_triangle, FenceCircle,
                                             FencePolygon, format_from_path,
                                             MAV_CMD_DO_CHANGE_SPEED, MAV_CMD_NAV_LAND,
                                             MAV_CMD_NAV_LOITER_UNLIM,
                                             MAV_CMD_NAV_RETURN_TO_LAUNCH, MAV_CMD_NAV_TAKEOFF,
                                             MAV_CMD_NAV_WAYPOINT, MissionSettings, plan_document,
                                             UncertifiableMissionError, wpl_text)
from uav_global_planner.core.planner import Planner

ORIGIN = GeodeticOrigin(47.397742, 8.545594, 488.0)
POSITION_COMMANDS = {MAV_CMD_NAV_TAKEOFF, MAV_CMD_NAV_WAYPOINT, MAV_CMD_NAV_LOITER_UNLIM,
                     MAV_CMD_NAV_LAND}
DENSE_SAMPLES = 10_000


# --------------------------------------------------------------------------------------------
# An independent reading of the written file
# --------------------------------------------------------------------------------------------

def to_map(lat, lon, alt_amsl):
    """pymap3d directly (heights taken as AMSL, as the module documents)."""
    e, n, u = pymap3d.geodetic2enu(np.asarray(lat, float), np.asarray(lon, float),
                                   np.asarray(alt_amsl, float), ORIGIN.lat, ORIGIN.lon,
                                   ORIGIN.alt_amsl)
    return np.stack([np.atleast_1d(e), np.atleast_1d(n), np.atleast_1d(u)], axis=1)


def flight_of_plan(document, settings, floor):
    """The nominal path an autopilot flies for a .plan document, in the map frame [m]."""
    lat0, lon0, alt0 = document['mission']['plannedHomePosition']
    home = to_map(lat0, lon0, alt0)[0]
    points = []
    items = document['mission']['items']
    if items[0]['command'] != MAV_CMD_NAV_TAKEOFF:
        home = None                      # airborne start: the mission begins at the first item
    else:
        points.append(home)
    for item in items:
        command, params = item['command'], item['params']
        if command in (MAV_CMD_NAV_TAKEOFF, MAV_CMD_NAV_WAYPOINT, MAV_CMD_NAV_LOITER_UNLIM):
            points.append(to_map(params[4], params[5], alt0 + params[6])[0])
        elif command == MAV_CMD_NAV_LAND:
            here = to_map(params[4], params[5], alt0)[0]
            points.append(np.array([here[0], here[1], floor]))
        elif command == MAV_CMD_NAV_RETURN_TO_LAUNCH:
            goal = points[-1]
            base = to_map(lat0, lon0, alt0)[0]
            top = max(goal[2], base[2] + settings.rtl_altitude)
            if top > goal[2]:
                points.append(np.array([goal[0], goal[1], top]))
            points += [np.array([base[0], base[1], top]), base]
    path = np.array(points)
    keep = np.r_[True, np.linalg.norm(np.diff(path, axis=0), axis=1) > 1e-9]
    return path[keep]


def dense_samples(path, count=DENSE_SAMPLES):
    lengths = np.linalg.norm(np.diff(path, axis=0), axis=1)
    per_leg = np.maximum(2, np.ceil(count * lengths / lengths.sum()).astype(int))
    return np.concatenate([a + np.linspace(0.0, 1.0, k)[:, None] * (b - a)
                           for a, b, k in zip(path[:-1], path[1:], per_leg)])


def turn_samples(path, radius, per_turn=2000, seed=7):
    """Random points of every turn triangle (A, P, B) of the path."""
    rng = np.random.default_rng(seed)
    out = []
    for before, corner, after in zip(path[:-2], path[1:-1], path[2:]):
        r = min(radius, np.linalg.norm(before - corner), np.linalg.norm(after - corner))
        a = corner + r * (before - corner) / np.linalg.norm(before - corner)
        b = corner + r * (after - corner) / np.linalg.norm(after - corner)
        u = rng.random((per_turn, 2))
        flip = u.sum(axis=1) > 1.0
        u[flip] = 1.0 - u[flip]
        out.append(a + u[:, :1] * (corner - a) + u[:, 1:] * (b - a))
    return np.concatenate(out) if out else np.empty((0, 3))


# --------------------------------------------------------------------------------------------
# Geodesy
# --------------------------------------------------------------------------------------------

def test_enu_round_trip_is_exact_to_a_micrometre_over_kilometres():
    rng = np.random.default_rng(3)
    points = rng.uniform([-3000, -3000, -50], [3000, 3000, 500], size=(200, 3))
    lat, lon, alt = enu_to_geodetic(points, ORIGIN)
    assert np.max(np.abs(geodetic_to_enu(lat, lon, alt, ORIGIN) - points)) < 1e-6


def test_geodetic_heights_follow_the_ellipsoid_not_a_flat_earth():
    # 1 km east along the tangent plane is ~7.8 cm above the ellipsoid: r^2 / (2 R).
    lat, lon, alt = enu_to_geodetic([[0.0, 0.0, 0.0], [1000.0, 0.0, 0.0], [0.0, 0.0, 12.5]],
                                    ORIGIN)
    assert (lat[0], lon[0], alt[0]) == pytest.approx((ORIGIN.lat, ORIGIN.lon, ORIGIN.alt_amsl))
    assert alt[1] - ORIGIN.alt_amsl == pytest.approx(1000.0 ** 2 / (2 * 6.378e6), rel=0.01)
    assert alt[2] == pytest.approx(ORIGIN.alt_amsl + 12.5, abs=1e-9)
    # Latitude and longitude of 1 km east: the geodesic distance is 1 km (to the curvature).
    _, _, distance = pymap3d.geodetic2aer(lat[1], lon[1], alt[1], ORIGIN.lat, ORIGIN.lon,
                                          ORIGIN.alt_amsl)
    assert distance == pytest.approx(1000.0, abs=1e-6)


def test_missing_pymap3d_names_the_pip_package(monkeypatch):
    monkeypatch.setitem(sys.modules, 'pymap3d', None)   # what an absent package looks like
    with pytest.raises(MissingDependencyError, match='pip install pymap3d') as caught:
        enu_to_geodetic([[0.0, 0.0, 0.0]], ORIGIN)
    assert caught.value.package == 'pymap3d'


@pytest.mark.parametrize('text, problem', [
    ('47.4,8.5', 'LAT,LON,ALT_AMSL'), ('a,b,c', 'three numbers'), ('91,8.5,400', 'lat'),
    ('47,181,400', 'lon'), ('47,8,20000', 'alt_amsl'), ('47,nan,4', 'finite')])
def test_origin_option_refuses_bad_values(text, problem):
    with pytest.raises(InvalidInputError, match=problem):
        parse_origin(text)


def test_scene_key_geodetic_origin(scenes_dir):
    import yaml
    data = yaml.safe_load((scenes_dir / 'paper_medium.yaml').read_text())
    assert parse_scene(data).geodetic_origin is None
    data['geodetic_origin'] = {'lat': 47.1, 'lon': 8.5, 'alt_amsl': 400.0}
    assert parse_scene(data).geodetic_origin == GeodeticOrigin(47.1, 8.5, 400.0)
    data['geodetic_origin'] = {'lat': 47.1, 'lon': 8.5}
    with pytest.raises(InvalidInputError, match='geodetic_origin.alt_amsl: missing'):
        parse_scene(data)
    data['geodetic_origin'] = {'lat': 47.1, 'lon': 8.5, 'alt_amsl': 400.0, 'h': 1}
    with pytest.raises(InvalidInputError, match='geodetic_origin: unknown key'):
        parse_scene(data)


# --------------------------------------------------------------------------------------------
# Certified turn regions
# --------------------------------------------------------------------------------------------

def test_turn_region_certificate_sees_an_obstacle_inside_the_triangle():
    a, b, c = np.array([0.0, 0.0, 1.0]), np.array([4.0, 0.0, 1.0]), np.array([0.0, 4.0, 1.0])
    inside = ObstacleSet([PointSet([[1.2, 1.2, 1.0]])])
    margin = 0.5
    # Every side keeps the margin...
    from uav_global_planner.core.path.clearance import certify_segments
    sides = certify_segments(inside, np.stack([a, b, c]), np.stack([b, c, a]), margin, 0.1)
    assert sides.clear.all()
    # ...but the filled triangle does not.
    assert certify_triangle(inside, a, b, c, margin, 0.1) == (False, -math.inf)
    outside = ObstacleSet([Sphere([3.0, 3.0, 1.0], 0.5)])
    clear, bound = certify_triangle(outside, a, b, c, margin, 0.1)
    assert clear and bound >= margin
    u = np.random.default_rng(0).random((5000, 2))
    u[u.sum(1) > 1] = 1 - u[u.sum(1) > 1]
    samples = a + u[:, :1] * (b - a) + u[:, 1:] * (c - a)
    assert outside.distance(samples).min() >= bound


# --------------------------------------------------------------------------------------------
# Missions on the shipped scenes
# --------------------------------------------------------------------------------------------

SCENES = ['paper_medium', 'paper_high', 'town400']


@pytest.fixture(scope='module')
def planned():
    cache = {}

    def plan(name):
        if name not in cache:
            try:
                path = find_scene(name)
            except InvalidInputError:
                pytest.skip(f'scene {name} is not in config/scenes (not generated yet)')
            scene = load_scene(path)
            # No time budget: a loaded machine must not turn a slow plan into a failure.
            planner = Planner(scene.config.with_changes(max_planning_time=0.0), scene.obstacles)
            result = planner.plan(scene.start, scene.goal)
            assert result.ok, result.message
            cache[name] = (scene, result)
        return cache[name]
    return plan


@pytest.mark.parametrize('name', SCENES)
def test_exported_legs_and_turns_keep_the_stated_clearance(name, planned):
    scene, result = planned(name)
    settings = MissionSettings()
    mission = build_mission(result.smoothed_path, scene.obstacles, scene.config, ORIGIN,
                            settings, raw_path=result.path)
    required = scene.config.safety_margin + settings.tracking_allowance
    assert mission.required_clearance_m == pytest.approx(required)
    assert mission.certified_clearance_m >= required
    document = json.loads(json.dumps(plan_document(mission)))
    path = flight_of_plan(document, settings, scene.config.bounds_min[2])
    assert np.allclose(path, mission.flight_path, atol=1e-6)
    samples = dense_samples(path)
    assert len(samples) >= DENSE_SAMPLES
    assert scene.obstacles.distance(samples).min() >= required
    turns = turn_samples(path, settings.acceptance_radius)
    assert scene.obstacles.distance(turns).min() >= required
    # Fewer waypoints than the route has corners, and no leg shorter than R (2 R between turns).
    legs = np.linalg.norm(np.diff(path, axis=0), axis=1)
    radius = settings.acceptance_radius
    assert len(path) < len(result.shortcut_path) + 3
    assert legs.min() >= radius - 0.02
    assert np.all(legs[1:-1] >= 2 * radius - 0.02)
    # It ends at the goal, within the stored resolution (1e-7 deg is about 1 cm).
    assert np.linalg.norm(path[-1] - scene.goal) < 0.01
    assert document['mission']['items'][-1]['command'] == MAV_CMD_NAV_LOITER_UNLIM


def test_takeoff_climbs_vertically_from_the_start_on_the_ground(planned):
    scene, result = planned('paper_medium')
    settings = MissionSettings(takeoff_height=2.5)
    mission = build_mission(result.smoothed_path, scene.obstacles, scene.config, ORIGIN,
                            settings)
    first = mission.items[0]
    assert first.command == MAV_CMD_NAV_TAKEOFF and first.frame == 3
    home, takeoff = mission.flight_path[0], mission.flight_path[1]
    assert np.allclose(home, scene.start, atol=0.01)
    assert np.allclose(takeoff[:2], home[:2], atol=1e-6)
    assert first.params[6] == pytest.approx(takeoff[2] - home[2], abs=1e-3)
    assert 1.0 <= first.params[6] <= 2.5
    assert math.isnan(first.params[3])          # PX4: keep the yaw mode


def test_a_blocked_climb_is_lowered_or_refused():
    config = PlannerConfig(bounds_min=(-10, -10, 0), bounds_max=(10, 10, 15), resolution=0.5,
                           safety_margin=0.2)
    start, goal = np.array([0.0, 0.0, 0.0]), np.array([8.0, 0.0, 3.0])
    path = np.linspace(start, goal, 50)
    roof = ObstacleSet([Box([-1.0, -1.0, 1.9], [1.0, 1.0, 2.5])])
    mission = build_mission(path, roof, config, ORIGIN, MissionSettings())
    assert mission.flight_path[1][2] <= 1.9 - 0.3
    low_roof = ObstacleSet([Box([-1.0, -1.0, 0.9], [1.0, 1.0, 2.5])])
    with pytest.raises(UncertifiableMissionError, match='take-off climb'):
        build_mission(path, low_roof, config, ORIGIN, MissionSettings())


def test_speed_items_follow_the_timing_limits(planned):
    scene, result = planned('paper_medium')
    config = scene.config.with_changes(max_speed_horizontal=3.5, max_speed_vertical=0.75)
    px4 = build_mission(result.smoothed_path, scene.obstacles, config, ORIGIN, MissionSettings())
    speeds = [i.params[:3] for i in px4.items if i.command == MAV_CMD_DO_CHANGE_SPEED]
    assert speeds == [(1.0, 3.5, -1.0)]
    ardupilot = build_mission(result.smoothed_path, scene.obstacles, config, ORIGIN,
                              MissionSettings(firmware='ardupilot'))
    speeds = [i.params[:3] for i in ardupilot.items if i.command == MAV_CMD_DO_CHANGE_SPEED]
    assert speeds == [(1.0, 3.5, -1.0), (2.0, 0.75, -1.0), (3.0, 0.75, -1.0)]
    assert all(i.params[3] == 0.0 for i in ardupilot.items if i.command == MAV_CMD_NAV_WAYPOINT)
    document = plan_document(ardupilot)
    assert document['mission']['hoverSpeed'] == 3.5
    assert document['mission']['firmwareType'] == 3


def open_field():
    """A 40 m field with one tower between start and goal: every end action is flyable."""
    config = PlannerConfig(bounds_min=(-20, -20, 0), bounds_max=(20, 20, 30), resolution=0.5,
                           safety_margin=0.5, max_planning_time=0.0)
    obstacles = ObstacleSet([Box([-2.0, -2.0, 0.0], [2.0, 2.0, 12.0])])
    result = Planner(config, obstacles).plan([-10.0, -10.0, 0.0], [12.0, 10.0, 6.0])
    assert result.ok, result.message
    return config, obstacles, result


@pytest.mark.parametrize('end, last_commands', [
    ('loiter', [MAV_CMD_NAV_LOITER_UNLIM]), ('land', [MAV_CMD_NAV_WAYPOINT, MAV_CMD_NAV_LAND]),
    ('rtl', [MAV_CMD_NAV_WAYPOINT, MAV_CMD_NAV_RETURN_TO_LAUNCH])])
def test_end_actions_are_flown_and_certified(end, last_commands):
    config, obstacles, result = open_field()
    settings = MissionSettings(end=end, rtl_altitude=20.0, acceptance_radius=2.0)
    mission = build_mission(result.smoothed_path, obstacles, config, ORIGIN, settings,
                            raw_path=result.path)
    assert [i.command for i in mission.items[-len(last_commands):]] == last_commands
    path = flight_of_plan(plan_document(mission), settings, 0.0)
    assert np.allclose(path, mission.flight_path, atol=1e-6)
    required = config.safety_margin + settings.tracking_allowance
    assert obstacles.distance(dense_samples(path)).min() >= required
    assert obstacles.distance(turn_samples(path, 2.0)).min() >= required
    if end == 'land':
        assert np.allclose(path[-1], [12.0, 10.0, 0.0], atol=0.01)
    if end == 'rtl':
        assert np.allclose(path[-1], path[0], atol=1e-9)
        assert path[-2][2] == pytest.approx(20.0, abs=1e-3)


def test_an_end_action_through_an_obstacle_is_refused():
    config, _, result = open_field()
    shed = ObstacleSet([Box([-2.0, -2.0, 0.0], [2.0, 2.0, 12.0]),
                        Box([11.0, 9.0, 0.0], [13.0, 11.0, 3.0])])   # under the goal
    with pytest.raises(UncertifiableMissionError, match='end of the mission'):
        build_mission(result.smoothed_path, shed, config, ORIGIN, MissionSettings(end='land'))
    mission = build_mission(result.smoothed_path, shed, config, ORIGIN,
                            MissionSettings(end='loiter'))
    assert mission.items[-1].command == MAV_CMD_NAV_LOITER_UNLIM


def test_no_mission_when_the_passage_is_too_narrow_for_the_allowance():
    # Two walls 1.4 m apart: the plan keeps gamma = 0.5, the mission would need 0.8 m a side.
    config = PlannerConfig(bounds_min=(-10, -10, 0), bounds_max=(10, 10, 6), resolution=0.25,
                           safety_margin=0.5, max_planning_time=0.0)
    walls = ObstacleSet([Box([-10.0, -0.2, 0.0], [-0.7, 0.2, 6.0]),
                         Box([0.7, -0.2, 0.0], [10.0, 0.2, 6.0])])
    result = Planner(config, walls).plan([0.0, -6.0, 0.0], [0.0, 6.0, 3.0])
    assert result.ok, result.message
    mission = build_mission(result.smoothed_path, walls, config, ORIGIN,
                            MissionSettings(tracking_allowance=0.1))
    assert mission.certified_clearance_m >= 0.6
    with pytest.raises(UncertifiableMissionError, match='no certified waypoints past'):
        build_mission(result.smoothed_path, walls, config, ORIGIN,
                      MissionSettings(tracking_allowance=0.3))


def test_a_goal_inside_the_allowance_is_refused_by_name(planned):
    scene, result = planned('paper_medium')
    with pytest.raises(UncertifiableMissionError, match='the goal .* from an obstacle'):
        build_mission(result.smoothed_path, scene.obstacles, scene.config, ORIGIN,
                      MissionSettings(tracking_allowance=3.5, takeoff_height=3.0))


@pytest.mark.parametrize('changes, problem', [
    ({'end': 'fly'}, 'end must be one of'), ({'firmware': 'inav'}, 'firmware must be one of'),
    ({'acceptance_radius': 0.0}, 'acceptance_radius must be in'),
    ({'tracking_allowance': -0.1}, 'tracking_allowance must be in'),
    ({'takeoff_height': 0.5}, 'takeoff_height must be >= acceptance_radius'),
    ({'rtl_altitude': float('nan')}, 'rtl_altitude must be finite')])
def test_settings_refuse_bad_values(changes, problem):
    with pytest.raises(InvalidInputError, match=problem):
        MissionSettings(**changes)


def test_malformed_paths_are_refused():
    config = PlannerConfig()
    with pytest.raises(InvalidInputError, match='smoothed_path must be finite'):
        build_mission([[0, 0, 0], [np.nan, 1, 1]], ObstacleSet(), config, ORIGIN)
    with pytest.raises(InvalidInputError, match='leaves the bounds'):
        build_mission([[0, 0, 0], [0, 0, 50]], ObstacleSet(), config, ORIGIN)
    with pytest.raises(InvalidInputError, match='nothing to fly'):
        build_mission([[0, 0, 0], [0.1, 0, 0]], ObstacleSet(), config, ORIGIN)


# --------------------------------------------------------------------------------------------
# Writers
# --------------------------------------------------------------------------------------------

def test_plan_document_layout(planned):
    scene, result = planned('paper_medium')
    mission = build_mission(result.smoothed_path, scene.obstacles, scene.config, ORIGIN)
    document = json.loads(json.dumps(plan_document(mission), allow_nan=False))
    assert (document['fileType'], document['version']) == ('Plan', 1)
    assert document['groundStation']
    body = document['mission']
    assert (body['version'], body['firmwareType'], body['vehicleType']) == (2, 12, 2)
    assert body['plannedHomePosition'] == list(mission.home)
    assert [item['doJumpId'] for item in body['items']] == list(range(1, len(mission.items) + 1))
    for item in body['items']:
        assert item['type'] == 'SimpleItem' and item['autoContinue'] is True
        assert len(item['params']) == 7
        if item['command'] == MAV_CMD_NAV_WAYPOINT:
            assert item['frame'] == 3 and item['params'][1] == 1.0     # acceptance radius
            assert item['params'][3] is None                            # NaN yaw
    assert document['geoFence'] == {'version': 2, 'polygons': [], 'circles': []}
    assert document['rallyPoints'] == {'version': 2, 'points': []}


def test_fences_are_written_clockwise_in_wgs84(planned):
    scene, result = planned('paper_medium')
    counter_clockwise = [[-9.0, -9.0], [9.0, -9.0], [9.0, 9.0], [-9.0, 9.0]]
    mission = build_mission(result.smoothed_path, scene.obstacles, scene.config, ORIGIN,
                            fence_polygons=[FencePolygon(counter_clockwise)],
                            fence_circles=[FenceCircle([3.0, 4.0], 2.5, inclusion=False)])
    fence = plan_document(mission)['geoFence']
    polygon = fence['polygons'][0]
    assert polygon['version'] == 1 and polygon['inclusion'] is True
    xy = to_map(*np.array(polygon['polygon']).T, np.full(4, ORIGIN.alt_amsl))[:, :2]
    signed = 0.5 * np.sum(xy[:, 0] * np.roll(xy[:, 1], -1) - np.roll(xy[:, 0], -1) * xy[:, 1])
    assert signed < 0.0                                            # clockwise from above
    gaps = np.linalg.norm(xy[:, None, :] - np.array(counter_clockwise)[None], axis=2)
    assert np.all(gaps.min(axis=0) < 0.01)                         # every corner, within 1 cm
    circle = fence['circles'][0]
    assert circle['version'] == 1 and circle['inclusion'] is False
    assert circle['circle']['radius'] == 2.5
    center = to_map(*circle['circle']['center'], ORIGIN.alt_amsl)[0]
    assert np.allclose(center[:2], [3.0, 4.0], atol=0.01)


def test_wpl_text_has_twelve_tab_separated_fields_and_home_first(planned):
    scene, result = planned('paper_medium')
    mission = build_mission(result.smoothed_path, scene.obstacles, scene.config, ORIGIN,
                            MissionSettings(firmware='ardupilot'))
    lines = wpl_text(mission).splitlines()
    assert lines[0] == 'QGC WPL 110'
    rows = [line.split('\t') for line in lines[1:]]
    assert all(len(row) == 12 for row in rows)
    assert rows[0][:4] == ['0', '1', '0', '16']
    assert [float(v) for v in rows[0][8:11]] == list(mission.home)
    assert [int(row[0]) for row in rows] == list(range(len(mission.items) + 1))


@pytest.mark.parametrize('name, expected', [('a.plan', 'qgc'), ('b.waypoints', 'wpl'),
                                            ('c.TXT', 'wpl')])
def test_format_from_extension(name, expected):
    assert format_from_path(name) == expected


def test_unknown_extension_is_refused():
    with pytest.raises(InvalidInputError, match='.kml'):
        format_from_path('mission.kml')


def test_scene_airspace_becomes_the_2d_geofence():
    from uav_global_planner.core.map.airspace import Airspace
    from uav_global_planner.core.map.zones import BoxZone, Cylinder, InclusionFence
    fence = InclusionFence([[-19.0, -19.0], [19.0, -19.0], [19.0, 19.0], [-19.0, 19.0]])
    tower = Cylinder([10.0, -10.0], 2.0)                        # every altitude, off the route
    shed = BoxZone([-1.0, -1.0, 0.0], [1.0, 1.0, 3.0])          # low: the route flies over it
    airspace = Airspace((fence,), (tower, shed))
    config = PlannerConfig(bounds_min=(-20, -20, 0), bounds_max=(20, 20, 20), resolution=0.5,
                           safety_margin=0.5, max_planning_time=0.0)
    obstacles = airspace.with_obstacles(ObstacleSet())
    result = Planner(config, obstacles).plan([-10.0, -10.0, 0.0], [10.0, 10.0, 6.0])
    assert result.ok, result.message
    mission = build_mission(result.smoothed_path, obstacles, config, ORIGIN, airspace=airspace)
    document = plan_document(mission)['geoFence']
    assert [p['inclusion'] for p in document['polygons']] == [True]
    assert [(c['inclusion'], c['circle']['radius']) for c in document['circles']] == [
        (False, 2.0)]
    # The straight route climbs over the shed: a 2D fence of it would be a breach.
    assert mission.fence.skipped == ('box: the mission flies over or under it',)
    over = mission.flight_path[(np.abs(mission.flight_path[:, 0]) < 3.0)
                               & (np.abs(mission.flight_path[:, 1]) < 3.0)]
    assert len(over) == 0 or over[:, 2].min() > 3.0
    required = config.safety_margin + MissionSettings().tracking_allowance
    assert obstacles.distance(dense_samples(mission.flight_path)).min() >= required
