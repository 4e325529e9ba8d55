"""Starts and goals on the ground: lifted straight up by at most start_tolerance, or refused
with the distance and the fix (core/search/start_admission.py), in the core and through
``uav-plan``."""

import json
from pathlib import Path
import shutil
import subprocess

import numpy as np
import pytest
import yaml

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.io.scene import parse_scene
from uav_global_planner.core.map.obstacles import Box, ObstacleSet
from uav_global_planner.core.map.terrain import flat_ground
from uav_global_planner.core.path.clearance import certify_segments
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.search.start_admission import (admit, explain, FREE_ROOM_CELLS, GOAL,
                                                            is_free, START)
from uav_global_planner.core.settings import SETTINGS_BY_NAME
from uav_global_planner.core.status import PlanStatus

DELTA, GAMMA = 0.5, 0.2
CONFIG = PlannerConfig(bounds_min=(0.0, 0.0, 0.0), bounds_max=(10.0, 10.0, 6.0),
                       resolution=DELTA, safety_margin=GAMMA)
GROUND = flat_ground(0.0, [0.0, 0.0], [10.0, 10.0])
# A box whose margin reaches x = 3.8 .. 6.2 at heights 0.5 .. 3.2.
BOX = Box(np.array([4.0, 4.0, 0.7]), np.array([6.0, 6.0, 3.0]))
FLOOR_REFUSAL = ('start 0.80 m below the floor; start_tolerance is 0.50 m: raise it with '
                 '--start-tolerance or move the start')


def _planner(*obstacles, **changes) -> Planner:
    return Planner(CONFIG.with_changes(**changes), ObstacleSet(list(obstacles)))


def _free(planner: Planner, point) -> bool:
    return is_free(planner.grid, planner.blocked, planner.obstacles,
                   planner.config.planning_margin, np.asarray(point, dtype=float))


# ------------------------------------------------------------------------------ the floor

def test_a_start_0_3_m_below_the_floor_is_lifted_onto_it():
    planner = _planner(BOX)
    admitted = admit(planner, [1.0, 2.0, -0.3], START)
    assert np.allclose(admitted.point, [1.0, 2.0, 0.0])
    assert admitted.adjusted and admitted.refusal == ''
    assert admitted.moved_m == pytest.approx(0.3)
    assert admitted.note.startswith('start [1.0, 2.0, -0.3] is 0.300 m below the floor (outside '
                                    'the bounds); lifted 0.300 m straight up to [1.0, 2.0, 0.0]')
    assert 'take-off leg' in admitted.note and 'start_tolerance 0.5 m' in admitted.note
    assert np.allclose(admitted.leg, [[1.0, 2.0, -0.3], [1.0, 2.0, 0.0]])
    assert admitted.values() == {'start_adjusted': True, 'requested_start': admitted.requested,
                                 'start_note': admitted.note}
    result = planner.plan(admitted.point, [8.0, 8.0, 4.0])
    assert result.ok, result.message
    assert np.allclose(result.smoothed_path[0], [1.0, 2.0, 0.0])


def test_a_start_0_8_m_below_the_floor_is_refused_with_the_distance_and_the_fix():
    planner = _planner(BOX)
    admitted = admit(planner, [1.0, 2.0, -0.8], START)
    assert not admitted.adjusted
    assert np.array_equal(admitted.point, [1.0, 2.0, -0.8])
    assert admitted.refusal == FLOOR_REFUSAL
    result = explain(planner.plan(admitted.point, [8.0, 8.0, 4.0]), [admitted])
    assert result.status is PlanStatus.START_OUTSIDE_MAP
    assert result.message.startswith('start [1.0, 2.0, -0.8] is outside the bounds')
    assert result.message.endswith('; ' + FLOOR_REFUSAL)
    # A larger tolerance lifts it.
    assert np.allclose(admit(planner, [1.0, 2.0, -0.8], START, 1.0).point, [1.0, 2.0, 0.0])
    # The node names its parameter instead of the flag.
    node = admit(planner, [1.0, 2.0, -0.8], START, flag='the start_tolerance parameter')
    assert node.refusal.endswith('raise it with the start_tolerance parameter or move the start')


def test_a_free_point_and_an_ok_result_are_left_alone():
    planner = _planner(BOX)
    admitted = admit(planner, [1.0, 2.0, 1.0], START)
    assert not admitted.adjusted and admitted.refusal == '' and admitted.note == ''
    result = planner.plan(admitted.point, [8.0, 8.0, 4.0])
    assert explain(result, [admitted]) is result


def test_a_tolerance_of_0_moves_nothing_and_says_so():
    planner = _planner(BOX, start_tolerance=0.0)
    admitted = admit(planner, [1.0, 2.0, -0.3], START)
    assert not admitted.adjusted
    assert admitted.refusal == ('start 0.30 m below the floor; start_tolerance is 0.00 m: raise '
                                'it with --start-tolerance or move the start')


# ------------------------------------------------------------------------------ other obstacles

def test_a_start_within_the_margin_of_a_box_moves_to_the_nearest_free_node():
    planner = _planner(BOX)
    start = np.array([3.9, 5.1, 1.6])
    admitted = admit(planner, start, START)
    assert admitted.adjusted and admitted.leg is None
    assert 'is within the safety margin; moved' in admitted.note
    moved = admitted.point
    assert _free(planner, moved)
    assert np.allclose(planner.grid.index_to_world(planner.grid.world_to_index(moved)), moved)
    # The nearest of every free node within the tolerance (brute force over the grid).
    nodes = planner.grid.index_to_world(np.argwhere(np.ones(planner.grid.shape, dtype=bool)))
    near = nodes[np.linalg.norm(nodes - start, axis=1) <= 0.5]
    free = near[[_free(planner, node) for node in near]]
    best = np.min(np.linalg.norm(free - start, axis=1))
    assert np.linalg.norm(moved - start) == pytest.approx(best)
    assert planner.plan(moved, [8.0, 8.0, 4.0]).ok


def test_a_start_beside_the_bounds_is_projected_into_them():
    admitted = admit(_planner(BOX), [10.3, 2.0, 1.0], START)
    assert np.allclose(admitted.point, [10.0, 2.0, 1.0])
    assert 'is outside the bounds; moved 0.300 m' in admitted.note


def test_a_goal_within_the_margin_of_a_box_is_left_to_the_planner():
    planner = _planner(BOX)
    admitted = admit(planner, [3.9, 5.1, 1.6], GOAL)
    assert not admitted.adjusted and admitted.refusal == ''
    assert planner.plan([1.0, 1.0, 1.0], admitted.point).status is PlanStatus.GOAL_OCCUPIED


# ------------------------------------------------------------------------------ the ground

def test_a_goal_on_the_ground_is_lifted_to_the_lowest_free_height():
    planner = _planner(GROUND, BOX)
    goal = np.array([8.0, 7.0, 0.0])
    admitted = admit(planner, goal, GOAL)
    assert admitted.adjusted and admitted.refusal == ''
    lifted = admitted.point
    assert np.allclose(lifted[:2], goal[:2]) and lifted[2] > GAMMA
    assert _free(planner, lifted)
    # The lowest free height: within the scan's step of the last height that is not free.
    assert not _free(planner, lifted - [0.0, 0.0, 2e-3 * DELTA])
    assert admitted.note.startswith('goal [8.0, 7.0, 0.0] is within the safety margin (0.2 m) '
                                    'of the ground; the plan ends')
    assert 'landing leg' in admitted.note
    assert np.allclose(admitted.leg, [goal, lifted])
    result = explain(planner.plan([1.0, 1.0, 1.0], lifted), [admitted])
    assert result.ok, result.message
    assert np.allclose(result.smoothed_path[-1], lifted)


def test_a_start_under_the_ground_is_lifted_through_it():
    planner = _planner(GROUND)
    admitted = admit(planner, [2.0, 2.0, -0.3], START)
    assert admitted.note.startswith('start [2.0, 2.0, -0.3] is 0.300 m below the ground '
                                    '(outside the bounds); lifted ')
    assert _free(planner, admitted.point)
    assert admitted.point[2] == pytest.approx(0.25, abs=1e-3 * DELTA)  # the node above gamma
    assert admit(planner, [2.0, 2.0, -0.8], START).refusal == FLOOR_REFUSAL.replace(
        'floor', 'ground')


def test_the_take_off_leg_blocked_by_a_box_overhead_is_refused():
    overhead = Box(np.array([1.5, 1.5, 0.3]), np.array([2.5, 2.5, 1.0]))
    planner = _planner(GROUND, overhead)
    admitted = admit(planner, [2.0, 2.0, -0.1], START)
    assert not admitted.adjusted
    assert admitted.refusal.startswith('start [2.0, 2.0, -0.1] is 0.100 m below the ground '
                                       '(outside the bounds); the take-off leg straight up ')
    assert admitted.refusal.endswith('passes within the safety margin (0.2 m) of an obstacle: '
                                     'move the start')
    result = explain(planner.plan(admitted.point, [8.0, 8.0, 4.0]), [admitted])
    assert result.status is PlanStatus.START_OUTSIDE_MAP
    assert result.message.endswith(admitted.refusal)
    # The same landing is refused for a goal.
    landing = admit(planner, [2.0, 2.0, 0.0], GOAL)
    assert 'the landing leg straight up' in landing.refusal and not landing.adjusted


def test_the_take_off_leg_is_certified_clear_of_everything_but_the_ground():
    beside = Box(np.array([2.5, 1.0, 0.0]), np.array([3.5, 3.0, 2.0]))
    planner = _planner(GROUND, beside)
    admitted = admit(planner, [2.0, 2.0, 0.05], START)
    assert admitted.adjusted, admitted.refusal
    assert certify_segments(ObstacleSet([beside]), admitted.leg[:1], admitted.leg[1:], GAMMA,
                            DELTA).clear[0]


def test_a_start_on_the_ground_climbs_to_the_agl_floor():
    # The AGL floor of min_agl 2 m (a solid up to h + min_agl - margin): the take-off leg
    # climbs to the band, farther than the tolerance, which bounds only the depth.
    agl_floor = flat_ground(2.0 - GAMMA, [0.0, 0.0], [10.0, 10.0], label='min_agl')
    planner = _planner(GROUND, agl_floor)
    admitted = admit(planner, [2.0, 2.0, 0.0], START)
    assert admitted.adjusted, admitted.refusal
    assert 2.0 < admitted.point[2] <= 2.0 + DELTA
    assert 'of the ground' in admitted.note


def test_the_room_is_the_one_the_planner_needs():
    planner = _planner(GROUND)
    admitted = admit(planner, [2.0, 2.0, 0.0], GOAL)
    clearance = float(planner.obstacles.distance(admitted.point))
    assert clearance > GAMMA + FREE_ROOM_CELLS * DELTA
    assert planner.plan([5.0, 5.0, 3.0], admitted.point).ok


# ------------------------------------------------------------------------------ the setting

def test_start_tolerance_is_one_setting_of_the_core_table():
    entry = SETTINGS_BY_NAME['start_tolerance']
    assert (entry.default, entry.unit, entry.low, entry.high) == (0.5, 'm', 0.0, 100.0)
    assert (entry.field, entry.scene_key, entry.flag, entry.node) == (
        'start_tolerance', 'planner.start_tolerance', '--start-tolerance', True)
    assert PlannerConfig().start_tolerance == 0.5
    document = {'bounds': {'min': [0, 0, 0], 'max': [10, 10, 6]}, 'resolution': 0.5,
                'safety_margin': 0.2, 'adaptive_threshold': 1.5, 'start': [1, 2, -0.8],
                'goal': [8, 8, 4], 'planner': {'start_tolerance': 1.0}}
    assert parse_scene(document).config.start_tolerance == 1.0


# ------------------------------------------------------------------------------ uav-plan

def uav_plan(*args):
    executable = shutil.which('uav-plan')
    assert executable, 'uav-plan is not on PATH: run the tests through scripts/test.sh'
    return subprocess.run([executable, *args], capture_output=True, text=True, timeout=600)


def plan_json(scene: str, code: int) -> dict:
    """``uav-plan plan SCENE --json``, which must exit with ``code``: its printed result."""
    run = uav_plan('plan', scene, '--json')
    assert run.returncode == code, run.stdout + run.stderr
    return json.loads(run.stdout)


def _scene(tmp_path: Path, start, goal, **extra) -> str:
    document = {'bounds': {'min': [0.0, 0.0, 0.0], 'max': [10.0, 10.0, 6.0]},
                'resolution': DELTA, 'safety_margin': GAMMA, 'adaptive_threshold': 1.5,
                'start': list(start), 'goal': list(goal),
                'obstacles': [{'type': 'box', 'min': [4.0, 4.0, 0.7], 'max': [6.0, 6.0, 3.0]}],
                **extra}
    path = tmp_path / 'ground.yaml'
    path.write_text(yaml.safe_dump(document))
    return str(path)


def test_cli_lifts_a_start_below_the_floor_and_reports_it(tmp_path):
    scene = _scene(tmp_path, [1.0, 2.0, -0.3], [8.0, 8.0, 4.0])
    result = plan_json(scene, 0)
    assert result['status'] == 'ok'
    assert result['start_adjusted'] is True and result['goal_adjusted'] is False
    assert result['requested_start'] == [1.0, 2.0, -0.3]
    assert result['start'] == [1.0, 2.0, 0.0] and result['path'][0] == [1.0, 2.0, 0.0]
    assert result['start_note'].startswith('start [1.0, 2.0, -0.3] is 0.300 m below the floor')
    assert result['goal_note'] == '' and result['requested_goal'] == [8.0, 8.0, 4.0]
    text = uav_plan('plan', scene)
    assert text.returncode == 0, text.stderr
    assert 'start adjusted: start [1.0, 2.0, -0.3] is 0.300 m below the floor' in text.stdout


def test_cli_refuses_a_start_far_below_the_floor_with_the_fix(tmp_path):
    scene = _scene(tmp_path, [1.0, 2.0, -0.8], [8.0, 8.0, 4.0])
    result = plan_json(scene, 1)
    assert result['status'] == 'start_outside_map'
    assert result['message'].endswith(FLOOR_REFUSAL)
    assert result['start_adjusted'] is False and result['requested_start'] == [1.0, 2.0, -0.8]
    text = uav_plan('plan', scene)
    assert text.returncode == 1
    assert FLOOR_REFUSAL in text.stdout
    # The flag and the scene key raise the tolerance.
    raised = json.loads(uav_plan('plan', scene, '--json', '--start-tolerance', '1').stdout)
    assert raised['status'] == 'ok' and raised['start'] == [1.0, 2.0, 0.0]
    keyed = _scene(tmp_path, [1.0, 2.0, -0.8], [8.0, 8.0, 4.0],
                   planner={'start_tolerance': 1.0})
    assert json.loads(uav_plan('plan', keyed, '--json').stdout)['status'] == 'ok'


def test_cli_refuses_a_negative_start_tolerance():
    run = uav_plan('plan', 'paper_medium', '--start-tolerance=-1')
    assert run.returncode == 2
    assert 'start_tolerance must be in [0.0, 100.0], got -1.0' in run.stderr


def test_cli_lifts_a_goal_on_the_ground(tmp_path):
    scene = _scene(tmp_path, [1.0, 2.0, 1.0], [8.0, 8.0, 0.0], ground='floor')
    result = plan_json(scene, 0)
    assert result['goal_adjusted'] is True and result['start_adjusted'] is False
    assert result['requested_goal'] == [8.0, 8.0, 0.0]
    assert result['goal'][:2] == [8.0, 8.0] and result['goal'][2] > GAMMA
    assert 'landing leg' in result['goal_note']
    assert np.allclose(result['smoothed_path'][-1], result['goal'], atol=1e-6)
