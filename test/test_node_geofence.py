"""Geofences and the energy-aware cost in the node, through real processes.

A geofence set at run time (``geofence_file``: YAML or a QGroundControl ``.plan`` placed with
``geodetic_origin``) replans the active goal around its zones; a goal inside a zone is refused
with the zone named; a bad file is refused and the geofence in force stays; ``climb_weight``
changes the cost of plans and is validated like every parameter.
"""

import json
from pathlib import Path
from typing import Iterator

import numpy as np
import pymap3d
import pytest
import yaml

from ros_harness import planner_session, PlannerClient, RUN_NAMESPACE
from uav_global_planner.core.io.geodesy import GeodeticOrigin
from uav_global_planner.core.io.geofence import load_geofence
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.map.zones import Cylinder, InclusionFence
from uav_global_planner.ros import conversions as conv

pytestmark = pytest.mark.ros

GAMMA = 0.2
START = np.array([0.0, -5.0, 0.0])  # the start parameter of config/planner.yaml
GOAL = np.array([0.0, 8.0, 4.0])
# A no-fly cylinder across the straight line from START to GOAL, over every flown height.
ZONE = {'type': 'cylinder', 'center': [0.0, 1.5], 'radius': 2.0, 'floor': -1.0,
        'ceiling': 40.0}
ORIGIN = (47.397742, 8.545594, 488.0)  # lat [deg], lon [deg], alt [m AMSL] of the map frame
NS = f'{RUN_NAMESPACE}/fenced'
# Certified curves keep gamma; the plan message rounds positions to float64 of the message.
TOL = 1e-6
DENSE_SAMPLES = 10_000


@pytest.fixture(scope='module')
def planner() -> Iterator[PlannerClient]:
    """One planner in open air (the paper's box), so only the geofence shapes the paths."""
    with planner_session(NS, {'plan_without_map': True}) as planner:
        yield planner


def write_yaml_fence(path: Path, exclusion: list, inclusion: dict = None) -> Path:
    fence = {'exclusion': exclusion}
    if inclusion is not None:
        fence['inclusion'] = inclusion
    path.write_text(yaml.safe_dump({'geofence': fence}), encoding='utf-8')
    return path


def dense_points(path_msg) -> np.ndarray:
    """The published curve, linearly resampled at :data:`DENSE_SAMPLES` points (the plan's
    samples are 0.1 m apart, so this is finer than the plan itself)."""
    points = conv.path_to_points(path_msg)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    s = np.linspace(0.0, arc[-1], DENSE_SAMPLES)
    return np.stack([np.interp(s, arc, points[:, a]) for a in range(3)], axis=1)


def min_gap(path_msg, fence_file: Path, origin=None) -> float:
    """Smallest distance of the published curve to the fences and zones of the file [m],
    by the core's exact distances at dense samples."""
    airspace = load_geofence(fence_file, origin, 0.0, 120.0)
    return float(np.min(ObstacleSet(list(airspace.shapes())).distance(dense_points(path_msg))))


def set_ok(planner: PlannerClient, values: dict) -> None:
    result = planner.params.set_atomically(values)
    assert result.successful, result.reason


def wait_plan(planner: PlannerClient, mark: int, reason: str, timeout_s: float = 30.0):
    values = planner.wait_diag(mark, 'plan', timeout_s, check=lambda v: reason in v['reason'],
                               what=f'a plan with reason {reason!r}')
    return values, planner.plan_for(values)


def test_a_fence_set_at_run_time_replans_the_active_goal_around_it(planner, tmp_path) -> None:
    values, path = planner.plan_to(GOAL)
    assert values['status'] == 'ok', values
    fence = write_yaml_fence(tmp_path / 'zone.yaml', [ZONE])
    assert min_gap(path, fence) < GAMMA, 'the straight plan should cross the zone'
    mark = planner.diagnostics.mark()
    set_ok(planner, {'geofence_file': str(fence)})
    # The plan in force crosses the new zone: withdrawn, and the goal planned again.
    withdrawn = planner.wait_diag(mark, 'plan_withdrawn')
    assert 'the new map makes it collide' in withdrawn['message'], withdrawn
    values, path = wait_plan(planner, mark, '')
    assert values['status'] == 'ok', values
    assert 'exclusion zone(s)' in values['geofence'] and '1 exclusion' in values['geofence']
    assert np.allclose(conv.path_to_points(path)[-1], GOAL, atol=1e-6)
    assert min_gap(path, fence) >= GAMMA - TOL
    # Removing the fence replans the goal again, and it is straight through once more.
    mark = planner.diagnostics.mark()
    set_ok(planner, {'geofence_file': ''})
    values, path = wait_plan(planner, mark, 'the geofence changed')
    assert values['status'] == 'ok' and values['geofence'] == 'no geofence', values
    assert min_gap(path, fence) < GAMMA


def test_a_goal_inside_a_zone_is_refused_with_the_zone_named(planner, tmp_path) -> None:
    fence = write_yaml_fence(tmp_path / 'zones.yaml', [
        {'type': 'box', 'min': [5.0, 5.0, 0.0], 'max': [8.0, 8.0, 10.0]}, ZONE])
    set_ok(planner, {'geofence_file': str(fence)})
    try:
        plans = planner.plans.mark()
        values, path = planner.plan_to([0.0, 1.5, 5.0])
        assert values['status'] == 'goal_occupied', values
        assert 'is inside exclusion zone 1 (cylinder)' in values['message'], values
        assert path is None
        for msg in planner.plans.messages[plans:]:
            points = conv.path_to_points(msg)
            assert not len(points) or np.linalg.norm(points[-1] - [0.0, 1.5, 5.0]) > 1.0
        # Within gamma of a wall: refused, naming the zone and the clearance.
        values, _ = planner.plan_to([0.0, 1.5 + 2.0 + 0.1, 5.0])
        assert values['status'] == 'goal_occupied', values
        assert 'within the safety margin of exclusion zone 1 (cylinder)' in values['message']
        # Outside an inclusion fence: outside the map, as beyond the bounds.
        fenced = write_yaml_fence(tmp_path / 'inclusion.yaml', [], {
            'polygon': [[-8.0, -8.0], [8.0, -8.0], [8.0, 8.0], [-8.0, 8.0]],
            'floor': -1.0, 'ceiling': 12.0})
        set_ok(planner, {'geofence_file': str(fenced)})
        values, _ = planner.plan_to([9.0, 0.0, 5.0])
        assert values['status'] == 'goal_outside_map', values
        assert 'is outside the inclusion fence' in values['message'], values
    finally:
        set_ok(planner, {'geofence_file': ''})


def test_bad_geofences_are_refused_and_the_fence_in_force_stays(planner, tmp_path) -> None:
    fence = write_yaml_fence(tmp_path / 'zone.yaml', [ZONE])
    set_ok(planner, {'geofence_file': str(fence)})
    try:
        bowtie = write_yaml_fence(tmp_path / 'bowtie.yaml', [
            {'type': 'prism', 'polygon': [[0, 0], [4, 4], [4, 0], [0, 4]], 'floor': 0.0,
             'ceiling': 5.0}])
        cases = {
            str(bowtie): 'geofence.exclusion[0].polygon',
            str(tmp_path / 'missing.yaml'): 'cannot read geofence file',
            str(write_yaml_fence(tmp_path / 'radius.yaml', [{**ZONE, 'radius': -1.0}])):
                'radius',
        }
        for file, words in cases.items():
            (result,) = planner.params.set({'geofence_file': file})
            assert not result.successful, file
            assert result.reason.startswith('geofence_file: ') and words in result.reason, \
                result.reason
        result = planner.params.set_atomically({'geofence_floor': 10.0,
                                                'geofence_ceiling': 5.0})
        assert not result.successful and 'geofence_floor must be below' in result.reason
        assert planner.params.get(['geofence_file'])['geofence_file'] == str(fence)
        # The zone in force still shapes new plans.
        values, path = planner.plan_to(GOAL)
        assert values['status'] == 'ok', values
        assert min_gap(path, fence) >= GAMMA - TOL
    finally:
        set_ok(planner, {'geofence_file': ''})


def qgc_plan(path: Path, circle_enu, radius: float, polygon_enu) -> Path:
    """A QGroundControl plan file (its published JSON layout) with one exclusion circle and
    one inclusion polygon, from map-frame coordinates turned into WGS84 by pymap3d."""
    def geodetic(east: float, north: float):
        lat, lon, _ = pymap3d.enu2geodetic(east, north, 0.0, *ORIGIN)
        return [float(lat), float(lon)]
    plan = {
        'fileType': 'Plan', 'version': 1, 'groundStation': 'QGroundControl',
        'mission': {'version': 2, 'firmwareType': 12, 'vehicleType': 2, 'cruiseSpeed': 15,
                    'hoverSpeed': 5, 'plannedHomePosition': [ORIGIN[0], ORIGIN[1], ORIGIN[2]],
                    'items': []},
        'geoFence': {'version': 2, 'circles': [
            {'circle': {'center': geodetic(*circle_enu), 'radius': radius},
             'inclusion': False, 'version': 1}],
            'polygons': [{'polygon': [geodetic(*p) for p in polygon_enu], 'inclusion': True,
                          'version': 1}]},
        'rallyPoints': {'version': 2, 'points': []},
    }
    path.write_text(json.dumps(plan, indent=4), encoding='utf-8')
    return path


def test_a_qgc_plan_geofence_needs_the_origin_and_is_flown_around(planner, tmp_path) -> None:
    file = qgc_plan(tmp_path / 'fence.plan', (0.0, 1.5), 2.0,
                    [(-9.0, -9.0), (9.0, -9.0), (9.0, 9.5), (-9.0, 9.5)])
    (result,) = planner.params.set({'geofence_file': str(file)})
    assert not result.successful and 'set geodetic_origin' in result.reason, result.reason
    set_ok(planner, {'geodetic_origin': list(ORIGIN), 'geofence_file': str(file),
                     'geofence_floor': -1.0, 'geofence_ceiling': 12.0})
    try:
        values, path = planner.plan_to(GOAL)
        assert values['status'] == 'ok', values
        assert '1 inclusion fence(s), 1 exclusion zone(s)' in values['geofence'], values
        airspace = load_geofence(file, GeodeticOrigin(*ORIGIN), -1.0, 12.0)
        assert isinstance(airspace.exclusions[0], Cylinder)
        assert isinstance(airspace.inclusions[0], InclusionFence)
        gaps = ObstacleSet(list(airspace.shapes())).distance(dense_points(path))
        assert float(np.min(gaps)) >= GAMMA - TOL
        # The ceiling parameter is the fence's: a goal above it is outside the fence.
        values, _ = planner.plan_to([0.0, 8.0, 12.5])
        assert values['status'] == 'goal_outside_map', values
    finally:
        set_ok(planner, {'geofence_file': ''})


def test_climb_weight_changes_the_cost_and_is_validated(planner) -> None:
    goal = [6.0, 6.0, 12.0]
    set_ok(planner, {'climb_weight': 1.0, 'descent_weight': 1.0})
    values, path = planner.plan_to(goal)
    assert values['status'] == 'ok', values
    level_cost = float(values['path_cost'])
    # With weight 1 the cost is the geometric length of the grid path (paper eq. 15).
    assert level_cost == pytest.approx(float(values['path_length_m']), abs=2e-4)
    mark = planner.diagnostics.mark()
    set_ok(planner, {'climb_weight': 3.0})
    try:
        values, _ = wait_plan(planner, mark, 'parameters changed')
        assert values['status'] == 'ok' and float(values['climb_weight']) == 3.0, values
        # The climb of 12 m costs 2 x 12 m more; the length may not grow beyond the cost.
        cost = float(values['path_cost'])
        assert cost >= float(values['path_length_m']) + 2.0 * 12.0 - 1e-3, values
        for bad in (-0.5, 1000.0):
            (result,) = planner.params.set({'climb_weight': bad})
            assert not result.successful, bad
        assert planner.params.get(['climb_weight'])['climb_weight'] == 3.0
    finally:
        set_ok(planner, {'climb_weight': 1.0})
