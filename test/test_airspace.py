"""Airspace: exact distances to zones and fences, validation, the file formats, endpoints, and
planned curves that keep gamma from every fence wall and zone.

Distances are checked against formulas written here independently of the compiled kernels
(numpy segment distances, matplotlib's point-in-polygon test, closest points of the solids)
and, for prisms, against dense samples of the solid's surface.

One file, though long: the independent reference formulas and the random-airspace generator at
the top serve the distance, inflation and planned-curve tests alike.
"""

import copy
from dataclasses import replace
import json
import math
import os
from pathlib import Path
import re
import subprocess
import sys

from helpers.documents import changed
from matplotlib.path import Path as PlanePath
import numpy as np
import pymap3d
import pytest
from scipy import ndimage

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import (GoalOccupiedError, GoalOutsideMapError,
                                            InvalidInputError, StartOccupiedError)
from uav_global_planner.core.io.geodesy import GeodeticOrigin
from uav_global_planner.core.io.geofence import load_geofence, load_qgc_plan, parse_geofence
from uav_global_planner.core.io.scene import find_scene, load_scene, parse_scene
from uav_global_planner.core.map.airspace import Airspace
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, Sphere
from uav_global_planner.core.map.polygons import checked_polygon
from uav_global_planner.core.map.spatial_index import ShapeIndex
from uav_global_planner.core.map.zone_checks import check_endpoint, zone_containing
from uav_global_planner.core.map.zones import (BoxZone, Cylinder, InclusionCircle, InclusionFence,
                                               Prism)
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.status import PlanStatus

REPO = Path(__file__).resolve().parents[1]
ATOL = 1e-9
DENSE_SAMPLES = 10_000


# --- independent reference formulas ---------------------------------------------------------

def segment_distances(xy: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Distance from each point (M, 2) to the polygon's boundary, by closest points on edges."""
    a = polygon
    b = np.roll(polygon, -1, axis=0)
    edge = b - a
    rel = xy[:, None, :] - a[None, :, :]
    t = np.clip(np.sum(rel * edge, axis=2) / np.sum(edge * edge, axis=1), 0.0, 1.0)
    closest = a[None, :, :] + t[:, :, None] * edge[None, :, :]
    return np.min(np.linalg.norm(xy[:, None, :] - closest, axis=2), axis=1)


def inside_polygon(xy: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    return PlanePath(polygon).contains_points(xy)


def interval_gap(z: np.ndarray, low: float, high: float) -> np.ndarray:
    return np.maximum(np.maximum(low - z, z - high), 0.0)


def prism_reference(points: np.ndarray, polygon, floor, ceiling) -> np.ndarray:
    """Distance to a solid prism as the nearest of its faces: the walls (each a vertical
    rectangle) and the two caps (each the polygon at one height); 0 inside."""
    xy, z = points[:, :2], points[:, 2]
    inside_xy = inside_polygon(xy, polygon)
    edge = segment_distances(xy, polygon)
    walls = np.sqrt(edge ** 2 + interval_gap(z, floor, ceiling) ** 2)
    plane = np.where(inside_xy, 0.0, edge)
    caps = np.full(len(points), np.inf)
    for height in (floor, ceiling):
        if np.isfinite(height):
            caps = np.minimum(caps, np.sqrt(plane ** 2 + (z - height) ** 2))
    solid = inside_xy & (z >= floor) & (z <= ceiling)
    return np.where(solid, 0.0, np.minimum(walls, caps))


def cylinder_reference(points: np.ndarray, center, radius, floor, ceiling) -> np.ndarray:
    """Distance to a solid cylinder from its closest point."""
    rel = points[:, :2] - center
    across = np.linalg.norm(rel, axis=1)
    with np.errstate(invalid='ignore', divide='ignore'):
        scale = np.where(across > radius, radius / across, 1.0)
    closest = np.column_stack([center + rel * scale[:, None],
                               np.clip(points[:, 2], floor, ceiling)])
    return np.linalg.norm(points - closest, axis=1)


def fence_reference(points: np.ndarray, polygon, floor, ceiling) -> np.ndarray:
    """Distance to the outside of an inclusion fence: 0 outside, else the nearest of the
    walls, the floor and the ceiling."""
    xy, z = points[:, :2], points[:, 2]
    inside = inside_polygon(xy, polygon) & (z >= floor) & (z <= ceiling)
    nearest = np.minimum(segment_distances(xy, polygon), np.minimum(z - floor, ceiling - z))
    return np.where(inside, nearest, 0.0)


def circle_fence_reference(points, center, radius, floor, ceiling) -> np.ndarray:
    across = np.linalg.norm(points[:, :2] - center, axis=1)
    inside = (across <= radius) & (points[:, 2] >= floor) & (points[:, 2] <= ceiling)
    nearest = np.minimum(radius - across, np.minimum(points[:, 2] - floor,
                                                     ceiling - points[:, 2]))
    return np.where(inside, nearest, 0.0)


def reference(zone, points: np.ndarray) -> np.ndarray:
    """Exact distance from ``points`` to any zone, fence or obstacle used in these tests."""
    if isinstance(zone, Prism):
        return prism_reference(points, zone.polygon, zone.floor, zone.ceiling)
    if isinstance(zone, Cylinder):
        return cylinder_reference(points, zone.center, zone.radius, zone.floor, zone.ceiling)
    if isinstance(zone, InclusionFence):
        return fence_reference(points, zone.polygon, zone.floor, zone.ceiling)
    if isinstance(zone, InclusionCircle):
        return circle_fence_reference(points, zone.center, zone.radius, zone.floor,
                                      zone.ceiling)
    if isinstance(zone, (BoxZone, Box)):
        excess = np.maximum(np.maximum(zone.min - points, points - zone.max), 0.0)
        return np.linalg.norm(excess, axis=1)
    assert isinstance(zone, Sphere)
    return np.maximum(np.linalg.norm(points - zone.center, axis=1) - zone.radius, 0.0)


def nearest_reference(items, points: np.ndarray) -> np.ndarray:
    return np.min([reference(item, points) for item in items], axis=0)


# --- random airspace ------------------------------------------------------------------------

def star_polygon(rng, center, radius, count) -> np.ndarray:
    """A simple polygon, often concave: vertices at sorted angles and random radii."""
    # Angular gaps below pi keep the polygon star-shaped around the centre, so simple.
    angles = (np.arange(count) + rng.uniform(0.0, 0.4, count)) * (2.0 * np.pi / count)
    radii = radius * rng.uniform(0.3, 1.0, count)
    return np.column_stack([center[0] + radii * np.cos(angles),
                            center[1] + radii * np.sin(angles)])


def random_zones(rng, count: int, extent: float = 40.0):
    zones = []
    for number in range(count):
        center = rng.uniform(-extent, extent, 2)
        floor = float(rng.uniform(-5.0, 10.0))
        ceiling = floor + float(rng.uniform(0.5, 20.0))
        if number % 4 == 3:
            floor, ceiling = -math.inf, (math.inf if rng.random() < 0.5 else ceiling)
        size = float(10.0 ** rng.uniform(-1.0, 1.0))
        if number % 3 == 0:
            zones.append(Prism(star_polygon(rng, center, size, int(rng.integers(3, 12))),
                               floor, ceiling))
        elif number % 3 == 1:
            zones.append(Cylinder(center, size, floor, ceiling))
        else:
            lo = np.r_[center - size, max(floor, -50.0)]
            zones.append(BoxZone(lo, np.r_[center + size, min(ceiling, 50.0)]))
    return zones


def random_fence(rng) -> InclusionFence:
    return InclusionFence(star_polygon(rng, np.zeros(2), 45.0, 14), -8.0, 30.0)


def queries(rng, zones, count: int = 4000) -> np.ndarray:
    """Points everywhere, near every vertex and wall, and on the surfaces."""
    parts = [rng.uniform(-55.0, 55.0, (count, 3)) * [1.0, 1.0, 0.5]]
    for zone in zones:
        if hasattr(zone, 'polygon'):
            floor = zone.floor if np.isfinite(zone.floor) else -3.0
            vertex = zone.polygon[rng.integers(len(zone.polygon), size=20)]
            parts.append(np.column_stack([vertex + rng.normal(0.0, 0.05, (20, 2)),
                                          np.full(20, floor)]))
    return np.vstack(parts)


# --- distances ------------------------------------------------------------------------------

@pytest.mark.parametrize('seed', range(6))
def test_zone_and_fence_distances_equal_independent_formulas(seed):
    rng = np.random.default_rng(seed)
    zones = random_zones(rng, 12) + [random_fence(rng)]
    points = queries(rng, zones)
    for zone in zones:
        alone = ObstacleSet([zone])
        assert np.allclose(alone.distance(points), reference(zone, points), rtol=0.0,
                           atol=ATOL), zone.label
    obstacles = ObstacleSet(zones + [Sphere([1.0, 2.0, 3.0], 2.0)])
    expected = nearest_reference(obstacles.items, points)
    assert np.allclose(obstacles.distance(points), expected, rtol=0.0, atol=ATOL)


def test_prism_distance_equals_dense_samples_of_its_surface():
    """An L-shaped (concave) prism: the distance to its surface from outside, against the
    nearest of 400 000 surface samples (which can only be farther, by half their spacing)."""
    polygon = np.array([[0.0, 0.0], [6.0, 0.0], [6.0, 2.0], [2.0, 2.0], [2.0, 5.0], [0.0, 5.0]])
    prism = ObstacleSet([Prism(polygon, 1.0, 4.0)])
    spacing = 0.02
    walls = []
    for a, b in zip(polygon, np.roll(polygon, -1, axis=0)):
        t = np.arange(0.0, 1.0, spacing / np.linalg.norm(b - a))
        z = np.arange(1.0, 4.0 + 1e-9, spacing)
        tt, zz = np.meshgrid(t, z)
        walls.append(np.column_stack([(a + tt.reshape(-1, 1) * (b - a)), zz.reshape(-1)]))
    gx, gy = np.meshgrid(np.arange(0.0, 6.0, spacing), np.arange(0.0, 5.0, spacing))
    plane = np.column_stack([gx.ravel(), gy.ravel()])
    plane = plane[inside_polygon(plane, polygon) | (segment_distances(plane, polygon) < 1e-12)]
    caps = [np.column_stack([plane, np.full(len(plane), h)]) for h in (1.0, 4.0)]
    surface = np.vstack(walls + caps)
    rng = np.random.default_rng(4)
    points = rng.uniform([-3.0, -3.0, -2.0], [9.0, 8.0, 7.0], (300, 3))
    exact = prism.distance(points)
    outside = exact > 0.0
    sampled = np.array([np.min(np.linalg.norm(surface - p, axis=1)) for p in points[outside]])
    assert np.all(sampled >= exact[outside] - 1e-12)
    assert np.all(sampled <= exact[outside] + spacing)
    assert np.allclose(exact, prism_reference(points, polygon, 1.0, 4.0), atol=ATOL)


@pytest.mark.parametrize('seed', range(4))
def test_capped_lattice_queries_with_many_zones_and_a_fence(seed):
    """Over 16 shapes the lattice answers; the fence is on its always-checked list."""
    rng = np.random.default_rng(50 + seed)
    zones = random_zones(rng, 60) + [random_fence(rng)]
    obstacles = ObstacleSet(zones + [Box([-1e30, -1e30, -30.0], [1e30, 1e30, -20.0])])
    points = queries(rng, zones, 6000)
    expected = nearest_reference(obstacles.items, points)
    for cap in (1e-3, 0.4, 2.5, 9.0):
        capped = obstacles.distance(points, cap)
        assert np.allclose(capped, np.minimum(expected, cap), rtol=0.0, atol=ATOL), cap
    index = ShapeIndex(obstacles.shape_kind, obstacles.shape_params, 4.0,
                       obstacles.shape_vertices, obstacles.shape_vstart)
    assert len(index.always) == 1
    assert np.allclose(index.query(points, 4.0), np.minimum(expected, 4.0), atol=ATOL)


def test_a_circular_inclusion_fence():
    fence = InclusionCircle([3.0, -2.0], 10.0, 0.0, 12.0)
    points = np.random.default_rng(1).uniform([-10, -15, -2], [16, 11, 14], (5000, 3))
    assert np.allclose(ObstacleSet([fence]).distance(points), reference(fence, points),
                       atol=ATOL)


@pytest.mark.parametrize('gamma', [0.0, 0.35, 1.2])
def test_inflation_blocks_exactly_the_nodes_within_gamma_of_a_zone(gamma):
    rng = np.random.default_rng(7)
    zones = random_zones(rng, 9, extent=8.0) + [
        InclusionFence(star_polygon(rng, np.zeros(2), 10.0, 9), 0.3, 7.7)]
    obstacles = ObstacleSet(zones)
    grid = VoxelGrid.from_bounds([-11.0, -11.0, -1.0], [11.0, 11.0, 9.0], 0.25)
    nodes = grid.index_to_world(np.argwhere(np.ones(grid.shape, dtype=bool)))
    distance = obstacles.distance(nodes).reshape(grid.shape)
    blocked = blocked_mask(grid, obstacles, gamma)
    assert np.array_equal(blocked, distance <= gamma)
    assert 0 < blocked.sum() < blocked.size


_FALLBACK_SCRIPT = """
import json, numpy as np
from uav_global_planner.core.map.zones import Cylinder, InclusionFence, Prism
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask
from uav_global_planner.core.jit import JIT_ENABLED
from uav_global_planner.core.map.obstacles import ObstacleSet
zones = [Prism([[0, 0], [3, 0], [1, 1], [0, 3]], 0.5, 2.0), Cylinder([-2, 1], 0.7, 1.0, 3.0),
         InclusionFence([[-4, -4], [4, -4], [4, 4], [0, 1], [-4, 4]], 0.25, 3.5)]
grid = VoxelGrid.from_bounds([-5, -5, 0], [5, 5, 4], 0.5)
mask = blocked_mask(grid, ObstacleSet(zones), 0.3)
print(json.dumps({'jit': JIT_ENABLED, 'mask': np.flatnonzero(mask).tolist()}))
"""


def test_the_uncompiled_inflation_of_zones_is_the_same():
    runs = {}
    for disabled in ('1', '0'):
        env = dict(os.environ, UAV_PLANNER_DISABLE_JIT=disabled)
        env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(REPO), env.get('PYTHONPATH')]))
        done = subprocess.run([sys.executable, '-c', _FALLBACK_SCRIPT], env=env, check=True,
                              capture_output=True, text=True, timeout=300)
        runs[disabled] = json.loads(done.stdout)
    assert runs['1']['jit'] is False
    assert runs['1']['mask'] == runs['0']['mask'] and runs['1']['mask']


# --- validation -----------------------------------------------------------------------------

@pytest.mark.parametrize('polygon, message', [
    ([[0, 0], [4, 4], [4, 0], [0, 4]], r'polygon: is self-intersecting: edges 0 and 2'),
    ([[0, 0], [1, 1], [2, 2]], r'polygon: is degenerate'),
    ([[0, 0], [1, 0]], r'at least 3 distinct vertices, got 2'),
    ([[0, 0], [2, 0], [2, 0], [0, 2]], r'vertices 1 and 2 coincide'),
    ([[0, 0], [4, 0], [2, 0], [2, 3]], r'fold back'),
    ([[0, 0], [4, 0], [4, 4], [2, 0], [0, 4]], r'self-intersecting'),   # touches an edge
    ([[0, 0], [1, float('nan')], [0, 1]], r'finite'),
    ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], r'\[x, y\] pairs'),
])
def test_bad_polygons_are_refused(polygon, message):
    with pytest.raises(InvalidInputError, match=message):
        checked_polygon(polygon)


def test_a_closed_polygon_and_either_orientation_are_accepted():
    square = [[0, 0], [1, 0], [1, 1], [0, 1]]
    assert checked_polygon(square + [[0, 0]]).shape == (4, 2)
    assert checked_polygon(square[::-1]).shape == (4, 2)


GEOFENCE = {
    'inclusion': {'polygon': [[0, 0], [20, 0], [20, 20], [10, 8], [0, 20]], 'floor': 0.0,
                  'ceiling': 15.0},
    'exclusion': [
        {'type': 'prism', 'polygon': [[2, 2], [5, 2], [3, 5]], 'floor': 0.0, 'ceiling': 6.0},
        {'type': 'cylinder', 'center': [15, 4], 'radius': 2.0, 'floor': 0.0, 'ceiling': 30.0},
        {'type': 'box', 'min': [8, 1, 0], 'max': [11, 3, 4]},
        {'type': 'cylinder', 'center': [18, 15], 'radius': 1.0},
    ],
}


@pytest.mark.parametrize('path, value, message', [
    (('exclusion', 1, 'radius'), -1.0,
     r'^geofence\.exclusion\[1\]\.radius: must be > 0 m, got -1\.0$'),
    (('exclusion', 0, 'floor'), 6.0,
     r'^geofence\.exclusion\[0\]\.floor: must be below the ceiling, got floor 6\.0 m'),
    (('exclusion', 0, 'polygon'), [[0, 0], [4, 4], [4, 0], [0, 4]],
     r'^geofence\.exclusion\[0\]\.polygon: is self-intersecting'),
    (('inclusion', 'polygon'), [[0, 0], [1, 1], [2, 2]],
     r'^geofence\.inclusion\.polygon: is degenerate'),
    (('inclusion', 'ceiling'), -1.0, r'^geofence\.inclusion\.floor: must be below'),
    (('exclusion', 2, 'type'), 'dome', r'^geofence\.exclusion\[2\]\.type: unknown zone type'),
    (('exclusion', 2, 'height'), 3.0, r'^geofence\.exclusion\[2\]: unknown key\(s\) height'),
    (('exclusion', 1, 'center'), KeyError, r'^geofence\.exclusion\[1\]\.center: missing'),
    (('exclusion', 2, 'min'), [8, 1], r'^geofence\.exclusion\[2\]\.min: must be a list of three'),
    (('exclusion', 2, 'max'), [11, 3, 0], r'^geofence\.exclusion\[2\]\.min: must be below max'),
    (('exclusion', 0, 'polygon', 1), [2, 'x'],
     r'^geofence\.exclusion\[0\]\.polygon\[1\]\[1\]: must be a number'),
    (('exclusion', 1, 'radius'), float('inf'), r'^geofence\.exclusion\[1\]\.radius: must be fi'),
    (('exclusion',), {'type': 'box'}, r'^geofence\.exclusion: must be a list'),
])
def test_geofence_errors_name_the_key_path(path, value, message):
    with pytest.raises(InvalidInputError, match=message):
        parse_geofence(changed(GEOFENCE, path, value))


def test_the_geofence_parses_with_labels():
    airspace = parse_geofence(copy.deepcopy(GEOFENCE))
    assert [type(z) for z in airspace.exclusions] == [Prism, Cylinder, BoxZone, Cylinder]
    assert [z.label for z in airspace.exclusions] == [
        'exclusion zone 0 (prism)', 'exclusion zone 1 (cylinder)', 'exclusion zone 2 (box)',
        'exclusion zone 3 (cylinder)']
    assert airspace.exclusions[3].floor == -math.inf and airspace.exclusions[3].ceiling == math.inf
    assert airspace.inclusions[0].label == 'the inclusion fence'
    assert len(parse_geofence(None)) == 0


SCENE = {
    'bounds': {'min': [-1.0, -1.0, 0.0], 'max': [21.0, 21.0, 16.0]},
    'resolution': 0.5, 'safety_margin': 0.4, 'adaptive_threshold': 1.5,
    'start': [3.0, 14.0, 3.0], 'goal': [17.0, 12.0, 5.0],
    'obstacles': [{'type': 'sphere', 'center': [6.0, 10.0, 4.0], 'radius': 1.0}],
    'geofence': GEOFENCE,
    'cost': {'climb_weight': 2.0, 'descent_weight': 0.5},
    'vehicle': {'mass': 2.5, 'hover_power': 300.0},
}


def test_scene_keys_geofence_cost_and_vehicle():
    scene = parse_scene(copy.deepcopy(SCENE))
    assert len(scene.airspace) == 5 and len(scene.obstacles) == 6
    assert scene.obstacles.zones == scene.airspace.shapes()
    assert (scene.config.climb_weight, scene.config.descent_weight) == (2.0, 0.5)
    assert (scene.vehicle.mass, scene.vehicle.hover_power) == (2.5, 300.0)
    plain = parse_scene({k: v for k, v in SCENE.items()
                         if k not in ('geofence', 'cost', 'vehicle')})
    assert len(plain.airspace) == 0
    assert (plain.config.climb_weight, plain.config.descent_weight) == (1.0, 1.0)


@pytest.mark.parametrize('key, value, message', [
    ('cost', {'climb_weight': -1.0},
     r'^cost\.climb_weight: must be in \[0\.0, 100\.0\], got -1\.0'),
    ('cost', {'climb': 2.0}, r'^cost: unknown key\(s\) climb'),
    ('cost', {'descent_weight': 'low'}, r'^cost\.descent_weight: must be a number'),
    ('vehicle', {'mass': 0.0}, r'^vehicle\.mass: must be in \(0\.0, 1000\.0\]'),
    ('vehicle', {'hover_power': -5}, r'^vehicle\.hover_power: must be in'),
    ('vehicle', {'battery': 5}, r'^vehicle: unknown key\(s\) battery'),
    ('geofence', {'exclusion': [{'type': 'cylinder', 'center': [1, 1], 'radius': -2.0}]},
     r'^geofence\.exclusion\[0\]\.radius: must be > 0 m'),
])
def test_scene_errors_name_the_key_path(key, value, message):
    data = copy.deepcopy(SCENE)
    data[key] = value
    with pytest.raises(InvalidInputError, match=message):
        parse_scene(data)


# --- QGroundControl plan files --------------------------------------------------------------

ORIGIN = GeodeticOrigin(47.3977, 8.5456, 488.0)


def _geodetic(points_xy):
    """Map-frame (x, y) at z = 0 to [lat, lon], by pymap3d directly."""
    out = []
    for x, y in points_xy:
        lat, lon, _ = pymap3d.enu2geodetic(x, y, 0.0, ORIGIN.lat, ORIGIN.lon, ORIGIN.alt_amsl)
        out.append([float(lat), float(lon)])
    return out


def _plan(polygons=(), circles=(), version=2):
    return {
        'fileType': 'Plan', 'groundStation': 'QGroundControl', 'version': 1,
        'mission': {'items': [], 'plannedHomePosition': [ORIGIN.lat, ORIGIN.lon, 488.0],
                    'version': 2, 'firmwareType': 12, 'vehicleType': 2},
        'rallyPoints': {'points': [], 'version': 2},
        'geoFence': {'version': version,
                     'polygons': [{'inclusion': inc, 'polygon': _geodetic(poly), 'version': 1}
                                  for inc, poly in polygons],
                     'circles': [{'inclusion': inc, 'version': 1,
                                  'circle': {'center': _geodetic([c])[0], 'radius': r}}
                                 for inc, c, r in circles]},
    }


FENCE_XY = [[-50.0, -50.0], [60.0, -40.0], [55.0, 70.0], [0.0, 10.0], [-45.0, 65.0]]
NO_FLY_XY = [[10.0, -20.0], [25.0, -20.0], [20.0, -5.0]]


def test_a_qgc_plan_geofence_is_placed_in_the_map_frame(tmp_path):
    file = tmp_path / 'site.plan'
    file.write_text(json.dumps(_plan(polygons=[(True, FENCE_XY), (False, NO_FLY_XY)],
                                     circles=[(False, [-20.0, 0.0], 12.5)])))
    airspace = load_qgc_plan(file, ORIGIN, floor=0.0, ceiling=120.0)
    fence, = airspace.inclusions
    prism, cylinder = airspace.exclusions
    assert np.allclose(fence.polygon, FENCE_XY, atol=1e-6)
    assert (fence.floor, fence.ceiling) == (0.0, 120.0)
    assert np.allclose(prism.polygon, NO_FLY_XY, atol=1e-6)
    assert (prism.floor, prism.ceiling) == (-math.inf, math.inf)
    assert np.allclose(cylinder.center, [-20.0, 0.0], atol=1e-6) and cylinder.radius == 12.5
    assert fence.label == 'the inclusion fence'
    assert prism.label == 'exclusion zone 0 (polygon 1 of site.plan)'
    assert cylinder.label == 'exclusion zone 1 (circle 0 of site.plan)'
    # The same file through the dispatcher, and a YAML file beside it.
    assert len(load_geofence(file, ORIGIN, 0.0, 120.0)) == 3
    yaml_file = tmp_path / 'fence.yaml'
    yaml_file.write_text(json.dumps({'geofence': GEOFENCE}))
    assert len(load_geofence(yaml_file)) == 5


@pytest.mark.parametrize('change, message', [
    (lambda p: p.update(fileType='Mission'), r'not a QGroundControl plan'),
    (lambda p: p.pop('geoFence'), r'geoFence: missing'),
    (lambda p: p['geoFence'].update(version=1), r'geoFence\.version: only version 2'),
    (lambda p: p['geoFence']['polygons'][0].pop('inclusion'),
     r'site\.plan: geoFence\.polygons\[0\]\.inclusion: must be true or false'),
    (lambda p: p['geoFence']['polygons'][0]['polygon'].__setitem__(1, [91.0, 8.0]),
     r'geoFence\.polygons\[0\]\.polygon\[1\]: latitude must be in'),
    (lambda p: p['geoFence']['polygons'][0].__setitem__('polygon', _geodetic(
        [[0, 0], [10, 10], [10, 0], [0, 10]])),
     r'site\.plan: geoFence\.polygons\[0\]\.polygon: is self-intersecting'),
    (lambda p: p['geoFence']['circles'][0]['circle'].__setitem__('radius', -3),
     r'geoFence\.circles\[0\]\.circle\.radius: must be > 0 m'),
])
def test_bad_qgc_plans_are_refused_with_the_key_path(tmp_path, change, message):
    plan = _plan(polygons=[(True, FENCE_XY)], circles=[(False, [0.0, -30.0], 5.0)])
    change(plan)
    file = tmp_path / 'site.plan'
    file.write_text(json.dumps(plan))
    with pytest.raises(InvalidInputError, match=message):
        load_qgc_plan(file, ORIGIN, 0.0, 100.0)


def test_a_qgc_plan_needs_an_origin_and_a_valid_band(tmp_path):
    file = tmp_path / 'site.plan'
    file.write_text(json.dumps(_plan(polygons=[(True, FENCE_XY)])))
    with pytest.raises(InvalidInputError, match='geodetic origin'):
        load_geofence(file)
    with pytest.raises(InvalidInputError, match='floor: must be below the ceiling'):
        load_qgc_plan(file, ORIGIN, 50.0, 20.0)
    (tmp_path / 'broken.plan').write_text('{"fileType": ')
    with pytest.raises(InvalidInputError, match='not valid JSON'):
        load_qgc_plan(tmp_path / 'broken.plan', ORIGIN)


# --- endpoints ------------------------------------------------------------------------------

def _scene_planner(**changes):
    scene = parse_scene(copy.deepcopy(SCENE))
    return scene, Planner(replace(scene.config, algorithm='octile', **changes), scene.obstacles)


@pytest.mark.parametrize('start, goal, status, message', [
    ([3, 14, 3], [15, 4, 5], PlanStatus.GOAL_OCCUPIED,
     r'^goal \[15\.0, 4\.0, 5\.0\] is inside exclusion zone 1 \(cylinder\)$'),
    ([3.5, 2.8, 2], [17, 12, 5], PlanStatus.START_OCCUPIED,
     r'^start \[3\.5, 2\.8, 2\.0\] is inside exclusion zone 0 \(prism\)$'),
    ([3, 14, 3], [10, 12, 5], PlanStatus.GOAL_OUTSIDE_MAP,
     r'^goal \[10\.0, 12\.0, 5\.0\] is outside the inclusion fence$'),
    ([3, 14, 3], [17, 12, 15.5], PlanStatus.GOAL_OUTSIDE_MAP, r'outside the inclusion fence'),
    ([0.2, 14, 3], [17, 12, 5], PlanStatus.START_OCCUPIED,
     r'^start \[0\.2, 14\.0, 3\.0\] is within the safety margin of the walls, floor or ceiling '
     r'of the inclusion fence: its clearance is 0\.200 m, gamma is 0\.4 m$'),
    ([3, 14, 3], [11.3, 2, 2], PlanStatus.GOAL_OCCUPIED,
     r'within the safety margin of exclusion zone 2 \(box\): its clearance is 0\.300 m'),
])
def test_endpoints_in_a_zone_or_outside_the_fence_are_refused_naming_it(start, goal, status,
                                                                        message):
    _, planner = _scene_planner()
    result = planner.plan(start, goal)
    assert result.status is status
    assert result.path.size == 0
    assert re.search(message, result.message), result.message


def test_check_endpoint_and_zone_containing():
    scene = parse_scene(copy.deepcopy(SCENE))
    obstacles = scene.obstacles
    assert zone_containing(obstacles, [15.0, 4.0, 1.0]).label == 'exclusion zone 1 (cylinder)'
    assert zone_containing(obstacles, [10.0, 15.0, 1.0]).label == 'the inclusion fence'
    assert zone_containing(obstacles, [3.0, 14.0, 3.0]) is None
    check_endpoint(obstacles, [3.0, 14.0, 3.0], 'start', 0.4)
    with pytest.raises(GoalOutsideMapError):
        check_endpoint(obstacles, [10.0, 15.0, 1.0], 'goal', 0.4)
    with pytest.raises(GoalOccupiedError):
        check_endpoint(obstacles, [15.0, 6.3, 3.0], 'goal', 0.4)
    with pytest.raises(StartOccupiedError):
        check_endpoint(obstacles, [15.0, 6.3, 3.0], 'start', 0.2, slack=0.2)
    # A via-point in a zone is named as such.
    _, planner = _scene_planner()
    result = planner.plan([3, 14, 3], [17, 12, 5], via=[[18.0, 15.0, 4.0]])
    assert result.status is PlanStatus.GOAL_OCCUPIED
    assert result.message.startswith('via-point 1 (end of leg 0) [18.0, 15.0, 4.0] is inside '
                                     'exclusion zone 3 (cylinder)'), result.message


# --- planned curves -------------------------------------------------------------------------

def dense_clearance(result, items) -> float:
    """Smallest exact distance from the flown curve to any of ``items``, at 10^4 samples."""
    s = np.linspace(0.0, result.curve.length_m, DENSE_SAMPLES)
    return float(nearest_reference(items, result.curve.evaluate(s)).min())


def random_airspace_scene(seed: int):
    """A 24 m site with a random concave fence, random zones and a few spheres."""
    rng = np.random.default_rng(seed)
    fence = InclusionFence(star_polygon(rng, np.zeros(2), 12.0, 10), 0.5, 9.0)
    zones = [fence] + random_zones(rng, 8, extent=9.0)
    items = zones + [Sphere(rng.uniform([-8, -8, 1], [8, 8, 8]), rng.uniform(0.3, 1.5))
                     for _ in range(4)]
    obstacles = ObstacleSet(items)
    gamma = float(rng.uniform(0.1, 0.6))
    config = PlannerConfig(bounds_min=(-12.0, -12.0, 0.0), bounds_max=(12.0, 12.0, 10.0),
                           resolution=0.4, safety_margin=gamma, max_planning_time=0.0)
    grid = VoxelGrid.from_bounds(config.bounds_min, config.bounds_max, config.resolution)
    # Start and goal in the largest 26-connected free region, so that a path exists.
    labels, _ = ndimage.label(~blocked_mask(grid, obstacles, gamma + 0.05),
                              structure=np.ones((3, 3, 3)))
    largest = np.argmax(np.bincount(labels.ravel())[1:]) + 1
    free = np.flatnonzero(labels.ravel() == largest)
    start, goal = grid.index_to_world(grid.unravel(rng.choice(free, 2, replace=False)))
    return config, obstacles, items, start, goal


@pytest.mark.parametrize('seed', range(10))
def test_every_planned_curve_keeps_gamma_from_every_fence_wall_and_zone(seed):
    config, obstacles, items, start, goal = random_airspace_scene(seed)
    for algorithm in ('octile', 'adaptive', 'weighted'):
        planner = Planner(replace(config, algorithm=algorithm), obstacles)
        result = planner.plan(start, goal)
        assert result.ok, result.message
        assert dense_clearance(result, items) >= config.safety_margin - 1e-9


def test_the_shipped_airspace_demo_goes_around_the_zones():
    scene = load_scene(find_scene('airspace_demo'))
    assert len(scene.airspace.exclusions) == 3
    fence = scene.airspace.inclusions[0]
    assert not PlanePath(fence.polygon).contains_point((50.0, 85.0)), 'fence not concave there'
    zones = scene.airspace.shapes()
    config = replace(scene.config, algorithm='octile')
    others = ObstacleSet([item for item in scene.obstacles.items if item not in zones])
    free = Planner(config, others).plan(scene.start, scene.goal)
    assert free.ok, free.message
    s = np.linspace(0.0, free.curve.length_m, DENSE_SAMPLES)
    crossed = [zone.label for zone in zones
               if reference(zone, free.curve.evaluate(s)).min() == 0.0]
    assert 'exclusion zone 0 (cylinder)' in crossed and 'the inclusion fence' in crossed
    fenced = Planner(config, scene.obstacles).plan(scene.start, scene.goal)
    assert fenced.ok, fenced.message
    assert dense_clearance(fenced, zones) >= config.safety_margin - 1e-9
    assert dense_clearance(fenced, scene.obstacles.items) >= config.safety_margin - 1e-9
    assert fenced.path_length_m > free.path_length_m + 10.0


def test_an_airspace_is_combined_with_obstacles():
    airspace = Airspace((InclusionFence([[0, 0], [9, 0], [9, 9], [0, 9]], 0.0, 5.0),),
                        (Cylinder([4.0, 4.0], 1.0),))
    combined = airspace.with_obstacles(ObstacleSet([Sphere([2.0, 2.0, 2.0], 0.5)]))
    assert len(combined) == 3 and combined.zones == airspace.shapes()
    assert float(combined.distance([4.0, 6.0, 2.5])) == pytest.approx(1.0)
    assert float(combined.distance([4.0, 8.5, 2.5])) == pytest.approx(0.5)
    with pytest.raises(InvalidInputError, match='not an exclusion zone'):
        Airspace((), (Sphere([0.0, 0.0, 0.0], 1.0),))
