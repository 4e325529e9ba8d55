"""The core and CLI side of the bad-input catalogue: every refused or awkward input.

:data:`CATALOGUE` is the table, one :class:`Case` per input, and doubles as documentation (the
ROS side is ``test_refused_inputs_ros.py``). Rows with ``covered_by`` are run by the named test
elsewhere and kept here so the table is complete (:func:`test_catalogue_references_exist` keeps
those references honest); the others run here, by surface:

* ``plan``: ``Planner.plan(start, goal, algorithm)`` returns a :class:`PlanResult` whose
  ``status`` is ``expected`` and whose ``message`` contains ``reason``; it never raises.
* ``config``: ``Planner.set_config(...)`` raises ``InvalidInputError`` naming the field.
* ``obstacles``: building an obstacle, or handing the planner something that is not an
  ``ObstacleSet``, raises ``InvalidInputError``.
* ``scene``: ``parse_scene`` of a scene document (as YAML loads it) raises ``InvalidInputError``
  whose message starts with the key path; ``file``: ``load_scene`` of a file.
* ``map``: ``load_map_points`` of a map file written by its format's own library, with the
  bounds, gamma and delta of :data:`SMALL`, raises ``InvalidInputError`` whose message starts
  with the file name; accepted files report what was read, dropped and kept.
* ``cli``: ``uav-plan plan FILE --json [options]`` exits with ``expected``
  (``2 invalid_input`` for invalid input, ``1 <status>`` for planning failures, ``0 ok``) and
  prints one JSON object whose ``message`` contains ``reason``. Every case runs through the
  console script's ``main()`` in this process; :data:`PROCESS_CASES` also as real processes.
  Map files in the options, or beside the scene file, are written first (:class:`MapFile`).
* ``expected`` ``ok``: accepted, not an error; ``reason`` says what happens.

After every case nothing has changed: the planner keeps its settings and obstacles and answers
the next valid request exactly as before; a scene document handed to ``parse_scene`` is not
modified, and the valid scene still loads.

One file, though long: the catalogue is one table that the docs build renders on
``docs/refused_inputs.md`` (``docs/gen_tables.py``); a split would scatter the rows a reader
looks up by surface.
"""

import copy
from dataclasses import dataclass, replace
import json
import math
from pathlib import Path
import shutil
import subprocess
from typing import Any, Callable, Dict, Tuple

from helpers.documents import changed
from helpers.map_files import BLOCK, bt, EMPTY, las, MapFile, NON_FINITE, npy, pcd, ply, UTM
import numpy as np
import pytest
import test_scene
import yaml

from uav_global_planner.cli.main import main as uav_plan_main
from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.mapfiles import load_map_points
from uav_global_planner.core.io.scene import load_scene, parse_scene
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, PointSet, Sphere
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.result import PlanResult
from uav_global_planner.core.status import PlanStatus

HERE = Path(__file__).resolve().parent

PLAN, CONFIG, OBSTACLES, SCENE, FILE, CLI = 'plan', 'config', 'obstacles', 'scene', 'file', 'cli'
MAP = 'map'
ERROR = 'InvalidInputError'
_NAN, _INF = math.nan, math.inf

# The planner every plan, config and obstacles case starts from: a sphere, a box and a point set.
SMALL = PlannerConfig(bounds_min=(0.0, 0.0, 0.0), bounds_max=(6.0, 6.0, 4.0), resolution=0.25,
                      safety_margin=0.2)
SPHERE = Sphere([3.0, 3.0, 2.0], 1.0)
BOX = Box([4.5, 0.5, 0.0], [5.5, 1.5, 1.5])
POINTS = PointSet([[1.0, 5.0, 1.0], [1.2, 5.0, 1.0]])
VALID_START, VALID_GOAL = [0.5, 0.5, 0.5], [5.5, 5.5, 3.5]

# A small valid scene document, as yaml.safe_load returns it (the one test_scene uses).
VALID_SCENE = test_scene.VALID


@dataclass(frozen=True)
class Case:
    """One row of the catalogue.

    Attributes
    ----------
    case_id : str
    surface : str
        :data:`PLAN`, :data:`CONFIG`, :data:`OBSTACLES`, :data:`SCENE`, :data:`FILE`,
        :data:`MAP` or :data:`CLI`.
    given : str
        The input, in words.
    expected : str
        Plan status value (``plan``), ``InvalidInputError`` (``config``, ``obstacles``,
        ``scene``, ``file``), ``<exit code> <status>`` (``cli``); ``ok`` when accepted.
    reason : str
        Substring of the message the user sees. For accepted inputs, what happens; for plan and
        cli rows followed by the substring of the success message in parentheses.
    value : Any
        The input: ``plan``: (start, goal, algorithm); ``config``: a PlannerConfig factory;
        ``obstacles``: a callable taking the planner; ``scene``: (key path, value) to set in
        the valid document (``KeyError`` deletes the key, an empty path replaces the whole
        document); ``file``: the file's bytes (None: no file); ``map``: (:class:`MapFile`,
        options of ``load_map_points``); ``cli``: (scene document, raw bytes or None, extra
        arguments, optionally map files to write beside the scene).
    covered_by : str
        ``file::test`` that runs this case when it is not run here.
    """

    case_id: str
    surface: str
    given: str
    expected: str
    reason: str
    value: Any = None
    covered_by: str = ''


def _config(**changes: Any) -> Callable[[], Any]:
    return lambda: replace(SMALL, **changes)


def _with(path: Tuple, value: Any) -> Dict[str, Any]:
    """A deep copy of the valid scene with one key set (``KeyError``: deleted); an empty path
    gives ``value`` itself as the whole document."""
    return changed(VALID_SCENE, path, value) if path else value


def _shell(center, half: float, wall: float = 0.1) -> list:
    """Six box documents forming a closed hollow cube around ``center``."""
    c = np.asarray(center, dtype=float)
    boxes = []
    for axis in range(3):
        for side in (-1, 1):
            lo, hi = c - half - wall, c + half + wall
            lo[axis] = c[axis] + side * half - wall
            hi[axis] = c[axis] + side * half + wall
            boxes.append({'type': 'box', 'min': lo.tolist(), 'max': hi.tolist()})
    return boxes


# A start 0.29 m from the sphere (so clear of gamma = 0.2 m) whose nearest node is 0.17 m from it.
_START_NODE_BLOCKED = [2.4488, 2.1732, 1.1732]

TEST_PLANNER = 'test_planner.py::test_each_failure_kind_has_its_status_and_message'
TEST_CONFIG = 'test_config.py::test_invalid_settings_name_the_field'
TEST_OBSTACLES = 'test_inflation.py::test_malformed_obstacles_are_refused'
TEST_SCENE = 'test_scene.py::test_malformed_scene_names_the_key_path'
TEST_FILES = 'test_scene.py::test_empty_file_and_non_yaml_file'
TEST_DEM_SETTINGS = 'test_dem.py::test_ground_and_band_refusals'
TEST_DEM_HOLES = 'test_dem.py::test_map_frame_grid_refusals'
TEST_DEM_HEADERS = 'test_dem.py::test_asc_header_refusals'
TEST_DEM_GEOTIFF = 'test_dem.py::test_geotiff_refusals_name_the_file'
THIS = 'test_fuzz_core.py::'
TEST_COMMAND_LINE = 'test_cli_command_line.py::'

CATALOGUE = (
    # ---------------------------------------------------------------- Planner.plan
    Case('plan_start_nan', PLAN, 'start z = NaN', 'invalid_input', 'start must be finite',
         covered_by=TEST_PLANNER),
    Case('plan_start_inf', PLAN, 'start y = -inf', 'invalid_input', 'start must be finite',
         ([0.5, -_INF, 0.5], VALID_GOAL, None)),
    Case('plan_goal_nan', PLAN, 'goal x = NaN', 'invalid_input', 'goal must be finite',
         (VALID_START, [_NAN, 5.5, 3.5], None)),
    Case('plan_goal_inf', PLAN, 'goal y = +inf', 'invalid_input', 'goal must be finite',
         covered_by=TEST_PLANNER),
    Case('plan_start_two_numbers', PLAN, 'start [x, y]', 'invalid_input',
         'start must be three numbers', covered_by=TEST_PLANNER),
    Case('plan_start_none', PLAN, 'start None', 'invalid_input',
         'start must be three numbers [x, y, z], got None', (None, VALID_GOAL, None)),
    Case('plan_goal_text', PLAN, "goal 'abc'", 'invalid_input',
         "goal must be three numbers [x, y, z], got 'abc'", (VALID_START, 'abc', None)),
    Case('plan_goal_nested', PLAN, 'goal [[x, y, z]] (shape 1 x 3)', 'invalid_input',
         'goal must be three numbers', (VALID_START, [[5.5, 5.5, 3.5]], None)),
    Case('plan_start_complex', PLAN, 'start with a complex number', 'invalid_input',
         'start must be three numbers', ([0.5 + 1j, 0.5, 0.5], VALID_GOAL, None)),
    Case('plan_start_outside', PLAN, 'start z = -1 m, below the bounds', 'start_outside_map',
         'is outside the bounds', covered_by=TEST_PLANNER),
    Case('plan_start_just_outside', PLAN, 'start 1 um below the floor of the bounds',
         'start_outside_map', 'start [0.5, 0.5, -1e-06] is outside the bounds [0.0, 0.0, 0.0]',
         ([0.5, 0.5, -1e-6], VALID_GOAL, None)),
    Case('plan_goal_outside', PLAN, 'goal y = 7 m, bounds end at 6 m', 'goal_outside_map',
         'is outside the bounds', covered_by=TEST_PLANNER),
    Case('plan_goal_far_outside', PLAN, 'goal x = 1e308 m', 'goal_outside_map',
         'goal [1e+308, 5.5, 3.5] is outside the bounds', (VALID_START, [1e308, 5.5, 3.5], None)),
    Case('plan_start_in_sphere', PLAN, 'start at the centre of a sphere', 'start_occupied',
         'is within the safety margin', covered_by=TEST_PLANNER),
    Case('plan_goal_in_sphere', PLAN, 'goal inside a sphere', 'goal_occupied',
         'its clearance is 0.000 m', covered_by=TEST_PLANNER),
    Case('plan_goal_in_margin', PLAN, 'goal 0.15 m from a sphere, gamma 0.2 m',
         'goal_occupied', 'gamma is 0.2 m', covered_by=TEST_PLANNER),
    Case('plan_goal_in_box', PLAN, 'goal inside a box', 'goal_occupied',
         'goal [5.0, 1.0, 0.75] is within the safety margin: its clearance is 0.000 m',
         (VALID_START, [5.0, 1.0, 0.75], None)),
    Case('plan_start_near_points', PLAN, 'start 0.1 m from an occupied point', 'start_occupied',
         'is within the safety margin: its clearance is', ([1.1, 5.1, 1.0], VALID_GOAL, None)),
    Case('plan_start_node_in_margin', PLAN,
         'start 0.29 m from a sphere, its nearest node 0.17 m (gamma 0.2 m)', 'start_occupied',
         'its clearance is 0.173 m, gamma is 0.2 m', (_START_NODE_BLOCKED, VALID_GOAL, None)),
    Case('plan_no_path', PLAN, 'goal sealed in a hollow box', 'no_valid_path', 'expanded',
         covered_by=TEST_PLANNER),
    Case('plan_timeout', PLAN, 'max_expansions = 5', 'timeout', 'max_expansions',
         covered_by=TEST_PLANNER),
    Case('plan_unknown_algorithm', PLAN, "algorithm 'bfs'", 'invalid_input', "got 'bfs'",
         covered_by='test_planner.py::test_unknown_algorithm_is_invalid_input'),
    Case('plan_algorithm_wrong_case', PLAN, "algorithm 'ADAPTIVE'", 'invalid_input',
         'algorithm must be one of dijkstra, astar, adaptive, octile, weighted, bounded, '
         "got 'ADAPTIVE'",
         (VALID_START, VALID_GOAL, 'ADAPTIVE')),
    Case('plan_algorithm_number', PLAN, 'algorithm 42', 'invalid_input', 'got 42',
         (VALID_START, VALID_GOAL, 42)),
    Case('plan_algorithm_empty', PLAN, "algorithm ''", 'invalid_input', "got ''",
         (VALID_START, VALID_GOAL, '')),
    Case('plan_start_equals_goal', PLAN, 'goal equal to the start, on a node', 'ok',
         'accepted: a single-point plan (path of 0.000 m over 1 nodes)',
         covered_by='test_planner.py::test_start_equal_to_goal_gives_a_single_point_plan'),
    Case('plan_start_equals_goal_off_node', PLAN, 'goal equal to the start, off the nodes',
         'ok', 'accepted: a single-point plan at the start (path of 0.000 m over 1 nodes)',
         ([0.43, 0.61, 0.37], [0.43, 0.61, 0.37], None)),
    Case('plan_start_on_corner', PLAN, 'start on a corner of the bounds', 'ok',
         'accepted: the bounds include their faces (path of',
         ([0.0, 0.0, 0.0], VALID_GOAL, None)),
    Case('plan_failures_in_a_row', PLAN, 'NaN start, occupied start, far goal, then valid',
         'ok', 'each refused, then the valid request plans (ok)',
         covered_by='test_planner.py::test_failures_keep_the_planner_usable'),
    # ---------------------------------------------------------------- Planner.set_config
    Case('config_resolution_zero', CONFIG, 'resolution 0', ERROR,
         'resolution must be in (0.0, 100.0]', covered_by=TEST_CONFIG),
    Case('config_resolution_negative', CONFIG, 'resolution -1 m', ERROR, 'resolution',
         covered_by='test_planner.py::test_invalid_config_keeps_the_previous_one'),
    Case('config_resolution_nan', CONFIG, 'resolution NaN', ERROR, 'resolution must be finite',
         covered_by=TEST_CONFIG),
    Case('config_resolution_text', CONFIG, "resolution '0.5' (a string)", ERROR,
         "resolution must be a number, got '0.5'", _config(resolution='0.5')),
    Case('config_resolution_bool', CONFIG, 'resolution True', ERROR,
         'resolution must be a number, got True', _config(resolution=True)),
    Case('config_resolution_too_large', CONFIG, 'resolution 1000 m', ERROR,
         'resolution must be in (0.0, 100.0], got 1000.0', _config(resolution=1000.0)),
    Case('config_safety_margin_negative', CONFIG, 'safety_margin -0.1 m', ERROR,
         'safety_margin must be in [0.0', covered_by=TEST_CONFIG),
    Case('config_safety_margin_inf', CONFIG, 'safety_margin +inf', ERROR,
         'safety_margin must be finite, got inf', _config(safety_margin=_INF)),
    Case('config_safety_margin_too_large', CONFIG, 'safety_margin 101 m', ERROR,
         'safety_margin must be in [0.0, 100.0], got 101.0', _config(safety_margin=101.0)),
    Case('config_adaptive_threshold_text', CONFIG, "adaptive_threshold 'far'", ERROR,
         'adaptive_threshold must be a number', covered_by=TEST_CONFIG),
    Case('config_adaptive_threshold_negative', CONFIG, 'adaptive_threshold -1 m', ERROR,
         'adaptive_threshold must be in [0.0, 1000000.0], got -1.0',
         _config(adaptive_threshold=-1.0)),
    Case('config_algorithm_unknown', CONFIG, "algorithm 'bfs'", ERROR,
         'algorithm must be one of dijkstra, astar, adaptive, octile, weighted, bounded, got',
         covered_by=TEST_CONFIG),
    Case('config_algorithm_none', CONFIG, 'algorithm None', ERROR,
         'algorithm must be one of dijkstra, astar, adaptive, octile, weighted, bounded, '
         'got None',
         _config(algorithm=None)),
    Case('config_smoothing_unknown', CONFIG, "smoothing 'bezier'", ERROR,
         'smoothing must be one of chord, index, none', covered_by=TEST_CONFIG),
    Case('config_smoothing_wrong_case', CONFIG, "smoothing 'CHORD'", ERROR,
         "smoothing must be one of chord, index, none, got 'CHORD'", _config(smoothing='CHORD')),
    Case('config_shortcut_text', CONFIG, "shortcut 'yes'", ERROR,
         'shortcut must be true or false', covered_by=TEST_CONFIG),
    Case('config_shortcut_int', CONFIG, 'shortcut 1', ERROR,
         'shortcut must be true or false, got 1', _config(shortcut=1)),
    Case('config_max_expansions_negative', CONFIG, 'max_expansions -1', ERROR,
         'max_expansions must be >= 0', covered_by=TEST_CONFIG),
    Case('config_max_expansions_fraction', CONFIG, 'max_expansions 2.5', ERROR,
         'max_expansions must be an integer', covered_by=TEST_CONFIG),
    Case('config_max_expansions_bool', CONFIG, 'max_expansions True', ERROR,
         'max_expansions must be an integer, got True', _config(max_expansions=True)),
    Case('config_max_planning_time_negative', CONFIG, 'max_planning_time -1 s', ERROR,
         'max_planning_time must be in', covered_by=TEST_CONFIG),
    Case('config_max_planning_time_nan', CONFIG, 'max_planning_time NaN', ERROR,
         'max_planning_time must be finite, got nan', _config(max_planning_time=_NAN)),
    Case('config_sample_spacing_zero', CONFIG, 'sample_spacing 0 m', ERROR,
         'sample_spacing must be in (0.0, 10.0], got 0.0', _config(sample_spacing=0.0)),
    Case('config_index_step_above_one', CONFIG, 'index_step 2', ERROR,
         'index_step must be in (0.0, 1.0], got 2.0', _config(index_step=2.0)),
    Case('config_max_speed_vertical_zero', CONFIG, 'max_speed_vertical 0 m/s', ERROR,
         'max_speed_vertical must be in', covered_by=TEST_CONFIG),
    Case('config_max_speed_horizontal_inf', CONFIG, 'max_speed_horizontal +inf', ERROR,
         'max_speed_horizontal must be finite, got inf', _config(max_speed_horizontal=_INF)),
    Case('config_max_accel_vertical_negative', CONFIG, 'max_accel_vertical -0.5 m/s^2', ERROR,
         'max_accel_vertical must be in (0.0, 1000.0], got -0.5',
         _config(max_accel_vertical=-0.5)),
    Case('config_bounds_inverted', CONFIG, 'bounds.min z above bounds.max z', ERROR,
         'bounds.min must be below bounds.max', covered_by=TEST_CONFIG),
    Case('config_bounds_flat', CONFIG, 'bounds.min z = bounds.max z', ERROR,
         'bounds.min must be below bounds.max on every axis',
         _config(bounds_min=(0.0, 0.0, 4.0))),
    Case('config_bounds_two_numbers', CONFIG, 'bounds.max [x, y]', ERROR,
         'bounds.max must be three numbers', covered_by=TEST_CONFIG),
    Case('config_bounds_nan', CONFIG, 'bounds.min x = NaN', ERROR,
         'bounds.min[0] must be finite, got nan', _config(bounds_min=(_NAN, 0.0, 0.0))),
    Case('config_bounds_text', CONFIG, "bounds.max 'big'", ERROR,
         "bounds.max must be three numbers [x, y, z], got 'big'", _config(bounds_max='big')),
    Case('config_voxel_cap_fine', CONFIG, 'resolution 0.01 m on 20 x 20 x 15 m', ERROR,
         'exceeds max_voxels', covered_by=TEST_CONFIG),
    Case('config_voxel_cap_wide', CONFIG, 'bounds of +-1e6 m at 0.25 m', ERROR,
         'nodes exceeds max_voxels = 1200000000; raise the resolution or shrink the bounds',
         _config(bounds_min=(-1e6, -1e6, 0.0), bounds_max=(1e6, 1e6, 4.0))),
    Case('config_max_voxels_low', CONFIG, 'max_voxels 1000', ERROR,
         'exceeds max_voxels = 1000', covered_by=TEST_CONFIG),
    Case('config_max_voxels_zero', CONFIG, 'max_voxels 0', ERROR,
         'max_voxels must be >= 1, got 0', _config(max_voxels=0)),
    Case('config_max_voxels_float', CONFIG, 'max_voxels 1e6 (a float)', ERROR,
         'max_voxels must be an integer, got 1000000.0', _config(max_voxels=1e6)),
    Case('config_not_a_config', CONFIG, "a dict {'resolution': 0.5} instead of a PlannerConfig",
         ERROR, 'config must be a PlannerConfig, got dict', lambda: {'resolution': 0.5}),
    Case('config_unknown_key', CONFIG, "setting 'speed' (config_from_mapping)", ERROR,
         'unknown setting(s): speed',
         covered_by='test_config.py::test_unknown_keys_are_refused'),
    # ---------------------------------------------------------------- obstacles
    Case('obstacle_radius_zero', OBSTACLES, 'sphere radius 0', ERROR,
         'sphere radius must be > 0', covered_by=TEST_OBSTACLES),
    Case('obstacle_radius_negative', OBSTACLES, 'sphere radius -1 m', ERROR,
         'sphere radius must be > 0', covered_by=TEST_OBSTACLES),
    Case('obstacle_radius_inf', OBSTACLES, 'sphere radius +inf', ERROR,
         'sphere radius must be finite', covered_by=TEST_OBSTACLES),
    Case('obstacle_radius_nan', OBSTACLES, 'sphere radius NaN', ERROR,
         'sphere radius must be finite, got nan', lambda planner: Sphere([0, 0, 0], _NAN)),
    Case('obstacle_radius_text', OBSTACLES, "sphere radius 'big'", ERROR,
         "sphere radius must be a number, got 'big'", lambda planner: Sphere([0, 0, 0], 'big')),
    Case('obstacle_center_nan', OBSTACLES, 'sphere centre y = NaN', ERROR,
         'sphere center must be finite', covered_by=TEST_OBSTACLES),
    Case('obstacle_center_two_numbers', OBSTACLES, 'sphere centre [x, y]', ERROR,
         'sphere center must be three numbers', lambda planner: Sphere([0, 0], 1.0)),
    Case('obstacle_box_flat', OBSTACLES, 'box with min y = max y', ERROR,
         'box min must be below box max', covered_by=TEST_OBSTACLES),
    Case('obstacle_box_inverted', OBSTACLES, 'box with min above max on every axis', ERROR,
         'box min must be below box max on every axis, got [1.0, 1.0, 1.0] and [0.0, 0.0, 0.0]',
         lambda planner: Box([1, 1, 1], [0, 0, 0])),
    Case('obstacle_box_inf', OBSTACLES, 'box max z = +inf', ERROR, 'box max must be finite',
         lambda planner: Box([0, 0, 0], [1, 1, _INF])),
    Case('obstacle_box_two_numbers', OBSTACLES, 'box min [x, y]', ERROR,
         'box min must be three numbers', covered_by=TEST_OBSTACLES),
    Case('obstacle_points_nan', OBSTACLES, 'point set with a NaN', ERROR,
         'points must be finite', covered_by=TEST_OBSTACLES),
    Case('obstacle_points_inf', OBSTACLES, 'point set with -inf', ERROR,
         'points must be finite; found NaN or inf',
         lambda planner: PointSet([[0, 0, 0], [0, -_INF, 0]])),
    Case('obstacle_points_pairs', OBSTACLES, 'point set of [x, y] pairs', ERROR,
         r'points must have shape (M, 3)', covered_by=TEST_OBSTACLES),
    Case('obstacle_points_flat', OBSTACLES, 'point set [x, y, z] (one flat triple)', ERROR,
         'points must have shape (M, 3), got shape (3,)', lambda planner: PointSet([0, 0, 0])),
    Case('obstacle_points_ragged', OBSTACLES, 'point set [[x, y, z], [x, y]]', ERROR,
         'points must be a list of [x, y, z] triples',
         lambda planner: PointSet([[0, 0, 0], [1, 1]])),
    Case('obstacle_points_text', OBSTACLES, "point set [['a', 'b', 'c']]", ERROR,
         'points must be a list of [x, y, z] triples',
         lambda planner: PointSet([['a', 'b', 'c']])),
    Case('obstacle_points_empty', OBSTACLES, 'point set []', 'ok',
         'accepted: an empty point set blocks nothing', lambda planner: PointSet([])),
    Case('obstacle_set_of_text', OBSTACLES, "ObstacleSet(['sphere'])", ERROR,
         'unsupported type str', covered_by=TEST_OBSTACLES),
    Case('obstacle_set_of_none', OBSTACLES, 'ObstacleSet([None])', ERROR,
         'obstacle 0 has unsupported type NoneType', lambda planner: ObstacleSet([None])),
    Case('planner_obstacles_list', OBSTACLES, 'Planner(config, [Sphere(...)]): a list', ERROR,
         'obstacles must be an ObstacleSet', lambda planner: Planner(SMALL, [SPHERE])),
    Case('set_obstacles_list', OBSTACLES, 'set_obstacles([Sphere(...)]): a list', ERROR,
         'obstacles must be an ObstacleSet', lambda planner: planner.set_obstacles([SPHERE])),
    Case('set_obstacles_none', OBSTACLES, 'set_obstacles(None)', ERROR,
         'obstacles must be an ObstacleSet', lambda planner: planner.set_obstacles(None)),
    # ---------------------------------------------------------------- scene documents
    Case('scene_missing_resolution', SCENE, 'no resolution', ERROR,
         'resolution: missing required key', covered_by=TEST_SCENE),
    Case('scene_missing_goal', SCENE, 'no goal', ERROR, 'goal: missing required key',
         covered_by=TEST_SCENE),
    Case('scene_missing_bounds_max', SCENE, 'bounds without max', ERROR,
         'bounds.max: missing required key', covered_by=TEST_SCENE),
    Case('scene_missing_bounds', SCENE, 'no bounds', ERROR, 'bounds: missing required key',
         (('bounds',), KeyError)),
    Case('scene_missing_start', SCENE, 'no start', ERROR, 'start: missing required key',
         (('start',), KeyError)),
    Case('scene_missing_safety_margin', SCENE, 'no safety_margin', ERROR,
         'safety_margin: missing required key', (('safety_margin',), KeyError)),
    Case('scene_resolution_text', SCENE, "resolution 'fine'", ERROR,
         "resolution: must be a number, got 'fine'", covered_by=TEST_SCENE),
    Case('scene_resolution_negative', SCENE, 'resolution -0.5', ERROR,
         'resolution: must be in', covered_by=TEST_SCENE),
    Case('scene_resolution_inf', SCENE, 'resolution .inf', ERROR,
         'resolution: must be finite, got inf', (('resolution',), _INF)),
    Case('scene_resolution_too_fine', SCENE, 'resolution 0.0001 m (8e11 nodes)', ERROR,
         'exceeds max_voxels = 1200000000', (('resolution',), 0.0001)),
    Case('scene_safety_margin_bool', SCENE, 'safety_margin true', ERROR,
         'safety_margin: must be a number', covered_by=TEST_SCENE),
    Case('scene_safety_margin_negative', SCENE, 'safety_margin -1', ERROR,
         'safety_margin: must be in [0.0, 100.0], got -1.0', (('safety_margin',), -1.0)),
    Case('scene_adaptive_threshold_yes', SCENE, 'adaptive_threshold yes (YAML true)', ERROR,
         'adaptive_threshold: must be a number, got True', (('adaptive_threshold',), True)),
    Case('scene_start_two_numbers', SCENE, 'start [x, y]', ERROR,
         'start: must be a list of three numbers', covered_by=TEST_SCENE),
    Case('scene_start_text', SCENE, "start 'origin'", ERROR,
         "start: must be a list of three numbers [x, y, z], got 'origin'",
         (('start',), 'origin')),
    Case('scene_goal_nan', SCENE, 'goal z = .nan', ERROR, 'goal[2]: must be finite',
         covered_by=TEST_SCENE),
    Case('scene_bounds_inverted', SCENE, 'bounds.min x above bounds.max x', ERROR,
         'bounds.min must be below bounds.max', covered_by=TEST_SCENE),
    Case('scene_bounds_list', SCENE, 'bounds [[...], [...]] (a list)', ERROR,
         'bounds: must be a mapping, got list',
         (('bounds',), [[-2.0, -2.0, 0.0], [2.0, 2.0, 3.0]])),
    Case('scene_bounds_unknown_key', SCENE, 'bounds.centre', ERROR,
         'bounds: unknown key(s) centre', covered_by=TEST_SCENE),
    Case('scene_unknown_key', SCENE, 'top-level key speed', ERROR, 'scene: unknown key(s) speed',
         covered_by=TEST_SCENE),
    Case('scene_unknown_key_typo', SCENE, "top-level key 'obstacle' (typo of obstacles)", ERROR,
         'scene: unknown key(s) obstacle; allowed: adaptive_threshold, bounds',
         (('obstacle',), [])),
    Case('scene_frame_id_empty', SCENE, "frame_id ''", ERROR,
         'frame_id: must be a non-empty string', covered_by=TEST_SCENE),
    Case('scene_frame_id_null', SCENE, 'frame_id null', ERROR,
         'frame_id: must be a non-empty string, got None', (('frame_id',), None)),
    Case('scene_description_number', SCENE, 'description 42', ERROR,
         'description: must be a string', (('description',), 42)),
    Case('scene_obstacles_mapping', SCENE, 'obstacles {type: sphere} (a mapping)', ERROR,
         'obstacles: must be a list', covered_by=TEST_SCENE),
    Case('scene_obstacles_false', SCENE, 'obstacles false', ERROR,
         'obstacles: must be a list, got bool', (('obstacles',), False)),
    Case('scene_obstacles_empty_mapping', SCENE, 'obstacles {}', ERROR,
         'obstacles: must be a list, got dict', (('obstacles',), {})),
    Case('scene_obstacles_null', SCENE, 'obstacles null (key left empty)', 'ok',
         'accepted: no obstacles', (('obstacles',), None)),
    Case('scene_obstacle_not_mapping', SCENE, "obstacles[1] 'box'", ERROR,
         'obstacles[1]: must be a mapping', covered_by=TEST_SCENE),
    Case('scene_obstacle_type_unknown', SCENE, 'obstacles[0].type cone', ERROR,
         "obstacles[0].type: unknown obstacle type 'cone'", covered_by=TEST_SCENE),
    Case('scene_obstacle_type_missing', SCENE, 'obstacles[0] without type', ERROR,
         'obstacles[0].type: missing required key', (('obstacles', 0, 'type'), KeyError)),
    Case('scene_obstacle_type_number', SCENE, 'obstacles[0].type 3', ERROR,
         'obstacles[0].type: unknown obstacle type 3; allowed: sphere, box, points',
         (('obstacles', 0, 'type'), 3)),
    Case('scene_obstacle_unknown_key', SCENE, 'obstacles[0].colour', ERROR,
         'obstacles[0]: unknown key(s) colour', covered_by=TEST_SCENE),
    Case('scene_radius_missing', SCENE, 'sphere without radius', ERROR,
         'obstacles[0].radius: missing required key', covered_by=TEST_SCENE),
    Case('scene_radius_zero', SCENE, 'radius 0', ERROR, 'obstacles[0].radius: must be > 0 m',
         covered_by=TEST_SCENE),
    Case('scene_radius_negative', SCENE, 'radius -1', ERROR,
         'obstacles[0].radius: must be > 0 m, got -1.0', (('obstacles', 0, 'radius'), -1.0)),
    Case('scene_radius_text', SCENE, "radius '1'", ERROR,
         'obstacles[0].radius: must be a number', covered_by=TEST_SCENE),
    Case('scene_radius_null', SCENE, 'radius null', ERROR,
         'obstacles[0].radius: must be a number, got None', (('obstacles', 0, 'radius'), None)),
    Case('scene_radius_nan', SCENE, 'radius .nan', ERROR,
         'obstacles[0].radius: must be finite', (('obstacles', 0, 'radius'), _NAN)),
    Case('scene_center_text', SCENE, "sphere center [0, 'a', 1]", ERROR,
         "obstacles[0].center[1]: must be a number, got 'a'",
         (('obstacles', 0, 'center'), [0.0, 'a', 1.0])),
    Case('scene_box_flat', SCENE, 'box with min z = max z', ERROR,
         'obstacles[1]: min must be below max', covered_by=TEST_SCENE),
    Case('scene_box_inverted', SCENE, 'box with max below min', ERROR,
         'obstacles[1]: min must be below max on every axis',
         (('obstacles', 1, 'max'), [0.0, -2.0, -1.0])),
    Case('scene_box_max_text', SCENE, "box max 'top'", ERROR,
         'obstacles[1].max: must be a list of three numbers', (('obstacles', 1, 'max'), 'top')),
    Case('scene_points_pair', SCENE, 'points [[0, 0, 0], [1, 1]]', ERROR,
         'obstacles[2].points[1]: must be a list of three numbers', covered_by=TEST_SCENE),
    Case('scene_points_number', SCENE, 'points 7', ERROR, 'obstacles[2].points: must be a list',
         covered_by=TEST_SCENE),
    Case('scene_points_nan', SCENE, 'points [[0, 0, .nan]]', ERROR,
         'obstacles[2].points[0][2]: must be finite',
         (('obstacles', 2, 'points'), [[0.0, 0.0, _NAN]])),
    Case('scene_points_empty', SCENE, 'points []', 'ok',
         'accepted: an empty point set blocks nothing', (('obstacles', 2, 'points'), [])),
    Case('scene_top_level_number', SCENE, 'the document is 42', ERROR,
         'scene: must be a mapping, got int', ((), 42)),
    Case('scene_top_level_text', SCENE, "the document is 'hello'", ERROR,
         'scene: must be a mapping, got str', ((), 'hello')),
    # ---------------------------------------------------------------- ground and terrain
    Case('scene_ground_word', SCENE, "ground 'grass'", ERROR,
         "ground: must be none, floor or a number in [-100000.0, 100000.0], got 'grass'",
         (('ground',), 'grass')),
    Case('scene_ground_above', SCENE, 'ground 100 m, above the bounds', ERROR,
         'ground must be below bounds.max z', (('ground',), 100.0)),
    Case('scene_min_agl_no_ground', SCENE, 'min_agl 2 m without a ground or terrain', ERROR,
         'min_agl and max_agl are heights above the ground, and there is none',
         (('min_agl',), 2.0)),
    Case('scene_agl_band_inverted', CONFIG, 'max_agl 5 m not above min_agl 5 m', ERROR,
         'max_agl must be above min_agl', covered_by=TEST_DEM_SETTINGS),
    Case('scene_terrain_missing', SCENE, 'terrain {file: missing.tif}', ERROR,
         'terrain.file: missing.tif: no such terrain file',
         (('terrain',), {'file': 'missing.tif'})),
    Case('scene_terrain_npy_bare', SCENE, 'terrain {file: heights.npy} without origin', ERROR,
         'terrain: an .npy terrain needs origin: [x, y] and spacing: [dx, dy]',
         (('terrain',), {'file': 'heights.npy'})),
    Case('scene_terrain_spacing', SCENE, 'terrain .npy spacing [0, 1]', ERROR,
         'terrain.spacing: must be > 0 m on both axes',
         (('terrain',), {'file': 'h.npy', 'origin': [0, 0], 'spacing': [0, 1]})),
    Case('scene_terrain_format', SCENE, 'terrain {file: dem.xyz}', ERROR,
         'not a terrain file', (('terrain',), {'file': 'dem.xyz'})),
    Case('dem_nodata_hole', FILE, 'a DEM (GeoTIFF, .asc, .npy) with nodata inside the bounds',
         ERROR, 'hole', covered_by=TEST_DEM_HOLES),
    Case('dem_not_covering', FILE, 'a DEM that does not cover the bounds', ERROR,
         'the terrain does not cover the bounds', covered_by=TEST_DEM_HOLES),
    Case('dem_header_non_finite', FILE, '.asc header cellsize nan, xllcorner inf', ERROR,
         'must be finite', covered_by=TEST_DEM_HEADERS),
    Case('dem_header_cellsize', FILE, '.asc header cellsize 0 or -1', ERROR,
         'cellsize must be > 0', covered_by=TEST_DEM_HEADERS),
    Case('dem_geotiff_no_crs', FILE, 'a GeoTIFF without a CRS', ERROR, 'no CRS',
         covered_by=TEST_DEM_GEOTIFF),
    Case('dem_geographic_no_origin', FILE, 'an EPSG:4326 GeoTIFF, the scene without '
         'geodetic_origin', ERROR, 'give the scene a geodetic_origin',
         covered_by=TEST_DEM_GEOTIFF),
    # ---------------------------------------------------------------- scene files
    Case('file_empty', FILE, 'an empty file', ERROR, 'the scene file is empty',
         covered_by=TEST_FILES),
    Case('file_not_yaml', FILE, 'text that is not YAML', ERROR, 'not valid YAML',
         covered_by=TEST_FILES),
    Case('file_yaml_list', FILE, 'a YAML list, not a mapping', ERROR, 'must be a mapping',
         covered_by=TEST_FILES),
    Case('file_missing', FILE, 'a path that does not exist', ERROR, 'cannot read scene file',
         covered_by=TEST_FILES),
    Case('file_no_such_scene', FILE, 'a name that is no shipped scene', ERROR,
         'no such scene file or shipped scene', covered_by=TEST_FILES),
    Case('file_only_comments', FILE, 'a file of comments only', ERROR,
         'bad: the scene file is empty', b'# a scene, one day\n'),
    Case('file_binary', FILE, 'a binary file (a PNG passed by mistake)', ERROR,
         'not a text file, so not a scene file', b'\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\xff'),
    Case('file_python_tag', FILE, 'YAML with a !!python/object tag', ERROR, 'not valid YAML',
         b'bounds: !!python/object/apply:os.system ["true"]\n'),
    Case('file_directory', FILE, 'a directory', ERROR, 'cannot read scene file (Is a directory)',
         'directory'),
    # ---------------------------------------------------------------- map files
    Case('map_ply_no_points', MAP, 'a PLY file with 0 vertices (plyfile)', ERROR,
         'empty.ply: no points: the PLY file holds 0 points',
         (MapFile('empty.ply', ply(EMPTY)), {})),
    Case('map_pcd_no_points', MAP, 'a PCD file with 0 points (pypcd4)', ERROR,
         'empty.pcd: no points: the PCD file holds 0 points',
         (MapFile('empty.pcd', pcd(EMPTY)), {})),
    Case('map_las_no_points', MAP, 'a LAS file with 0 points (laspy)', ERROR,
         'empty.las: no points: the LAS file holds 0 points',
         (MapFile('empty.las', las(EMPTY)), {})),
    Case('map_bt_no_occupied_cells', MAP, 'an OctoMap .bt with no occupied cell', ERROR,
         'empty.bt: no points: the OctoMap binary file holds 0 occupied cells',
         (MapFile('empty.bt', bt(EMPTY)), {})),
    Case('map_npy_no_points', MAP, 'a .npy array of shape (0, 3)', ERROR,
         'empty.npy: no points: the NumPy .npy file holds 0 points, and an empty map would be '
         'planned as open air', (MapFile('empty.npy', npy(EMPTY)), {})),
    Case('map_ply_all_non_finite', MAP, 'a PLY file whose 50 vertices are NaN or inf', ERROR,
         'nan.ply: no usable points: all 50 points of the PLY file have NaN or infinite '
         'coordinates', (MapFile('nan.ply', ply(NON_FINITE)), {})),
    Case('map_pcd_all_non_finite', MAP, 'a PCD file whose 50 points are NaN or inf', ERROR,
         'nan.pcd: no usable points: all 50 points', (MapFile('nan.pcd', pcd(NON_FINITE)), {})),
    Case('map_npy_all_non_finite', MAP, 'a .npy array of NaN and inf only', ERROR,
         'nan.npy: no usable points: all 50 points', (MapFile('nan.npy', npy(NON_FINITE)), {})),
    Case('map_las_all_outside', MAP, 'a LAS survey in UTM coordinates, bounds of a local frame',
         ERROR, 'utm.las: all 50 usable points lie outside the planning bounds [0.0, 0.0, 0.0] '
         '.. [6.0, 6.0, 4.0] (by more than 0.2 m): the points span x [465000, 465001]',
         (MapFile('utm.las', las(UTM)), {})),
    Case('map_npy_all_outside_millimetres', MAP, 'a .npy map written in millimetres', ERROR,
         'Is the map in another frame or unit', (MapFile('mm.npy', npy(BLOCK * 1000.0)), {})),
    Case('map_bt_resolution_too_fine', MAP, 'an OctoMap of 1 mm cells, delta 0.25 m', ERROR,
         'fine.bt: the OctoMap resolution 0.001 m is finer than delta / 100 = 0.0025 m',
         (MapFile('fine.bt', bt(BLOCK, 0.001)), {})),
    Case('map_downsample_too_fine', MAP, 'downsampling cell 1 mm, delta 0.25 m', ERROR,
         'block.npy: the downsampling cell 0.001 m is finer than delta / 100 = 0.0025 m',
         (MapFile('block.npy', npy(BLOCK)), {'downsample': 0.001})),
    Case('map_pcd_non_finite_viewpoint', MAP, 'a PCD header with VIEWPOINT nan 0 0 1 0 0 0',
         ERROR, 'viewpoint.pcd: the PCD header holds a non-finite VIEWPOINT',
         (MapFile('viewpoint.pcd', pcd(BLOCK, (math.nan, 0, 0, 1, 0, 0, 0))), {})),
    Case('map_las_non_finite_scale', MAP, 'a LAS header with an x scale of NaN', ERROR,
         'scale.las: the LAS header holds a non-finite scale (nan, 0.001, 0.001)',
         (MapFile('scale.las', las(BLOCK, (math.nan, 0.001, 0.001))), {})),
    Case('map_npy_some_non_finite', MAP, 'a .npy map with 2 NaN rows among 52', 'ok',
         'accepted: the NaN rows are dropped and counted (52 points read, dropped 2 '
         'non-finite, 50 kept)',
         (MapFile('some.npy', npy(np.vstack([BLOCK, NON_FINITE[:2]]))), {})),
    Case('map_npy_some_outside', MAP, 'a .npy map reaching 100 m beyond the bounds', 'ok',
         'accepted: the far points are dropped and counted (51 points read, dropped 1 outside '
         'the bounds, 50 kept)',
         (MapFile('wide.npy', npy(np.vstack([BLOCK, [[100.0, 0.0, 0.0]]]))), {})),
    # ---------------------------------------------------------------- uav-plan plan FILE --json
    Case('cli_missing_file', CLI, 'a file that does not exist', '2 invalid_input',
         'scene.yaml: no such scene file', (None, None, [])),
    Case('cli_empty_file', CLI, 'an empty file', '2 invalid_input', 'the scene file is empty',
         (None, b'', [])),
    Case('cli_not_yaml', CLI, 'text that is not YAML', '2 invalid_input', 'not valid YAML',
         (None, b'bounds: {min: [0, 0, 0]\nresolution: [', [])),
    Case('cli_binary_file', CLI, 'a binary file', '2 invalid_input', 'not a text file',
         (None, b'\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\xff', [])),
    Case('cli_yaml_list', CLI, 'a YAML list', '2 invalid_input',
         'scene: must be a mapping, got list', ([1, 2, 3], None, [])),
    Case('cli_missing_key', CLI, 'no start', '2 invalid_input', 'start: missing required key',
         (_with(('start',), KeyError), None, [])),
    Case('cli_wrong_type', CLI, "resolution 'fine'", '2 invalid_input',
         "resolution: must be a number, got 'fine'", (_with(('resolution',), 'fine'), None, [])),
    Case('cli_unknown_key', CLI, 'top-level key speed', '2 invalid_input',
         'scene: unknown key(s) speed', (_with(('speed',), 3), None, [])),
    Case('cli_unknown_obstacle_type', CLI, 'obstacle type cone', '2 invalid_input',
         "obstacles[0].type: unknown obstacle type 'cone'",
         covered_by='test_cli.py::test_plan_on_a_malformed_scene_names_the_key'),
    Case('cli_goal_nan', CLI, 'goal x = .nan', '2 invalid_input', 'goal[0]: must be finite',
         (_with(('goal', 0), _NAN), None, [])),
    Case('cli_radius_negative', CLI, 'radius -1', '2 invalid_input',
         'obstacles[0].radius: must be > 0 m, got -1.0',
         (_with(('obstacles', 0, 'radius'), -1.0), None, [])),
    Case('cli_obstacles_false', CLI, 'obstacles false', '2 invalid_input',
         'obstacles: must be a list, got bool', (_with(('obstacles',), False), None, [])),
    Case('cli_voxel_cap', CLI, 'resolution 0.0001 m', '2 invalid_input', 'exceeds max_voxels',
         (_with(('resolution',), 0.0001), None, [])),
    Case('cli_option_not_a_number', CLI, '--resolution abc', '2 invalid_input',
         "argument --resolution: invalid float value: 'abc'",
         (VALID_SCENE, None, ['--resolution', 'abc'])),
    Case('cli_option_unknown_algorithm', CLI, '--algorithm bfs', '2 invalid_input',
         "argument --algorithm: invalid choice: 'bfs'",
         (VALID_SCENE, None, ['--algorithm', 'bfs'])),
    Case('cli_option_unknown', CLI, '--speed 3 (no such option)', '2 invalid_input',
         'unrecognized arguments: --speed 3', (VALID_SCENE, None, ['--speed', '3'])),
    Case('cli_option_out_of_range', CLI, '--safety-margin -1', '2 invalid_input',
         'safety_margin must be in [0.0, 100.0], got -1.0',
         (VALID_SCENE, None, ['--safety-margin', '-1'])),
    Case('cli_option_nan', CLI, '--resolution nan', '2 invalid_input',
         'resolution must be finite', (VALID_SCENE, None, ['--resolution', 'nan'])),
    Case('cli_start_outside', CLI, 'start z = -1 m, below the bounds', '1 start_outside_map',
         'start [-1.5, -1.5, -1.0] is outside the bounds',
         (_with(('start', 2), -1.0), None, [])),
    Case('cli_goal_outside', CLI, 'goal x = 5 m, bounds end at 2 m', '1 goal_outside_map',
         'is outside the bounds', (_with(('goal', 0), 5.0), None, [])),
    Case('cli_start_occupied', CLI, 'start at the sphere centre', '1 start_occupied',
         'is within the safety margin', (_with(('start',), [0.0, 0.0, 1.5]), None, [])),
    Case('cli_goal_occupied', CLI, 'goal inside an obstacle', '1 goal_occupied',
         'within the safety margin',
         covered_by='test_cli.py::test_plan_json_reports_a_failure_with_nonzero_exit'),
    Case('cli_no_path', CLI, 'goal sealed in a hollow box', '1 no_valid_path',
         'no path from start to goal: all',
         (_with(('obstacles',), _shell([1.0, 1.0, 1.5], 0.75)) | {'goal': [1.0, 1.0, 1.5]},
          None, [])),
    Case('cli_start_equals_goal', CLI, 'goal equal to the start', '0 ok',
         'accepted: a single-point plan (path of 0.000 m over 1 nodes)',
         (_with(('goal',), [-1.5, -1.5, 0.5]), None, [])),
    Case('cli_map_ply_no_points', CLI, '--map of a PLY file with 0 vertices', '2 invalid_input',
         'empty.ply: no points: the PLY file holds 0 points',
         (VALID_SCENE, None, ['--map', MapFile('empty.ply', ply(EMPTY))])),
    Case('cli_map_npy_all_non_finite', CLI, '--map of a .npy array of NaN and inf only',
         '2 invalid_input', 'nan.npy: no usable points: all 50 points',
         (VALID_SCENE, None, ['--map', MapFile('nan.npy', npy(NON_FINITE))])),
    Case('cli_map_las_all_outside', CLI, '--map of a LAS survey in UTM coordinates',
         '2 invalid_input', 'utm.las: all 50 usable points lie outside the planning bounds '
         '[-2.0, -2.0, 0.0] .. [2.0, 2.0, 3.0]',
         (VALID_SCENE, None, ['--map', MapFile('utm.las', las(UTM))])),
    Case('cli_map_bt_resolution_too_fine', CLI, '--map of an OctoMap of 1 mm cells',
         '2 invalid_input', 'fine.bt: the OctoMap resolution 0.001 m is finer than delta / 100',
         (VALID_SCENE, None, ['--map', MapFile('fine.bt', bt(BLOCK, 0.001))])),
    Case('cli_map_downsample_too_fine', CLI, '--map-downsample 0.001 (delta 0.25 m)',
         '2 invalid_input', 'the downsampling cell 0.001 m is finer than delta / 100',
         (VALID_SCENE, None, ['--map', MapFile('block.npy', npy(BLOCK)),
                              '--map-downsample', '0.001'])),
    Case('cli_map_pcd_non_finite_viewpoint', CLI, '--map of a PCD file with a NaN VIEWPOINT',
         '2 invalid_input', 'the PCD header holds a non-finite VIEWPOINT',
         (VALID_SCENE, None,
          ['--map', MapFile('viewpoint.pcd', pcd(BLOCK, (math.nan, 0, 0, 1, 0, 0, 0)))])),
    Case('cli_points_file_no_points', CLI, 'a points_file obstacle of an empty .bt',
         '2 invalid_input', 'empty.bt: no points: the OctoMap binary file holds 0 occupied cells',
         (_with(('obstacles',), VALID_SCENE['obstacles'] + [{'type': 'points_file',
                                                             'path': 'empty.bt'}]),
          None, [], [MapFile('empty.bt', bt(EMPTY))])),
    # ------------------------------------------------- uav-plan: scene names, values, memory
    Case('cli_scene_path_named_like_a_shipped_scene', CLI,
         'a path that does not exist, named like a shipped scene (.../paper_medium.yaml)',
         '2 invalid_input', 'no such scene file; the shipped scene of that name is given by its '
         'name alone: paper_medium', covered_by=f'{TEST_COMMAND_LINE}'
         'test_a_missing_scene_path_is_refused_not_replaced_by_a_shipped_scene'),
    Case('cli_scene_file_name_not_here', CLI,
         'paper_medium.yaml with no such file in the current folder', '2 invalid_input',
         'paper_medium.yaml: no such scene file',
         covered_by=f'{TEST_COMMAND_LINE}test_text_that_names_a_path_must_be_a_file'),
    Case('cli_scene_unknown_name', CLI, 'the name paper_mediun', '2 invalid_input',
         'no such scene file or shipped scene (shipped scenes: airspace_demo, city1km',
         covered_by=f'{TEST_COMMAND_LINE}test_an_unknown_name_lists_every_shipped_scene'),
    Case('cli_scene_folder', CLI, 'a folder as the scene', '2 invalid_input',
         'is a folder, not a scene file',
         covered_by=f'{TEST_COMMAND_LINE}test_a_folder_is_not_a_scene_file'),
    Case('cli_via_negative', CLI, '--via -1.5,1.5,1 (a value starting with a minus sign)',
         '0 ok', 'accepted: read as the via-point, not as an option (path of',
         (VALID_SCENE, None, ['--via', '-1.5,1.5,1'])),
    Case('cli_via_negative_outside', CLI, '--via -50,100,40, outside the bounds',
         '1 goal_outside_map', 'via-point 1 (end of leg 0) [-50.0, 100.0, 40.0] is outside '
         'the bounds', (VALID_SCENE, None, ['--via', '-50,100,40'])),
    Case('cli_option_negative_exponent', CLI, '--max-jerk -1e3', '2 invalid_input',
         'max_jerk must be in (0.0, 10000.0], got -1000.0',
         (VALID_SCENE, None, ['--max-jerk', '-1e3'])),
    Case('cli_every_option_negative', CLI,
         'every option of plan, compare, plot and export given -1.5e0', '2 invalid_input',
         "the option's own refusal, never 'expected one argument'",
         covered_by=f'{TEST_COMMAND_LINE}'
         'test_every_option_reads_a_value_that_starts_with_a_minus_sign'),
    Case('cli_origin_negative', CLI, 'export --origin -33.86,151.2,10 (south of the equator)',
         '0 ok', 'accepted: the mission is placed at latitude -33.86 (home position)',
         covered_by=f'{TEST_COMMAND_LINE}test_origin_with_a_negative_latitude_exports'),
    Case('cli_image_without_format', CLI, 'plot -o out (no image extension)',
         '2 invalid_input', '-o: out: the extension names no image format; use one of',
         covered_by=f'{TEST_COMMAND_LINE}test_an_image_file_without_a_format_is_refused'),
    Case('cli_bench_unknown_scene', CLI, 'bench paper_mediun; bench --ros-goals -5',
         '2 invalid_input', 'paper_mediun: no such scene file or shipped scene',
         covered_by=f'{TEST_COMMAND_LINE}test_bench_refuses_an_unknown_scene_and_a_goal_count_'
         'below_one_before_measuring'),
    Case('cli_grid_beyond_search', CLI, '--resolution 0.001 --max-voxels 100000000000',
         '2 invalid_input', 'nodes: the search supports at most 2147483647',
         (VALID_SCENE, None, ['--resolution', '0.001', '--max-voxels', '100000000000'])),
    Case('cli_grid_beyond_memory', CLI, 'a grid whose mask and search records exceed the '
         'memory available', '2 invalid_input', 'before the search, up to',
         covered_by=f'{TEST_COMMAND_LINE}'
         'test_a_grid_larger_than_the_memory_available_is_refused_before_it_is_built'),
    Case('cli_search_out_of_memory', CLI, 'dijkstra on 223 M nodes under a 350 MB data limit',
         '2 invalid_input', 'out of memory: grid of 222.9 M nodes (block-sparse)',
         covered_by=f'{TEST_COMMAND_LINE}'
         'test_a_search_that_runs_out_of_memory_is_an_error_not_a_killed_process'),
)

RUN_HERE = [case for case in CATALOGUE if not case.covered_by]


def _ids(cases) -> list:
    return [case.case_id for case in cases]


def _by_surface(surface: str) -> list:
    return [case for case in RUN_HERE if case.surface == surface]


def _accepted_reason(case: Case) -> str:
    """The part of an accepted case's reason that the success message contains."""
    return case.reason.split('(', 1)[1].rstrip(')')


# ----------------------------------------------------------------------------------------------
# The table itself
# ----------------------------------------------------------------------------------------------

def test_catalogue_is_well_formed():
    ids = _ids(CATALOGUE)
    assert len(ids) == len(set(ids))
    assert len(CATALOGUE) >= 40
    for case in CATALOGUE:
        assert case.surface in (PLAN, CONFIG, OBSTACLES, SCENE, FILE, MAP, CLI), case.case_id
        assert case.reason and case.given, case.case_id
        assert (case.value is None) == bool(case.covered_by) or case.surface == FILE, case.case_id
        if case.expected in ('ok', '0 ok') and case.surface in (PLAN, CLI, MAP):
            assert '(' in case.reason, case.case_id
        if case.surface == PLAN:
            assert case.expected in {status.value for status in PlanStatus}, case.case_id
        elif case.surface == CLI:
            code, status = case.expected.split()
            assert code in ('0', '1', '2') and (code == '2') == (status == 'invalid_input')
            assert (code == '0') == (status == 'ok')
        else:
            assert case.expected in (ERROR, 'ok'), case.case_id


def test_catalogue_references_exist():
    for case in CATALOGUE:
        if not case.covered_by:
            continue
        file, name = case.covered_by.split('::')
        source = (HERE / file).read_text()
        assert f'def {name}(' in source, case.covered_by


# ----------------------------------------------------------------------------------------------
# Planner.plan, set_config and obstacles: refused, and nothing changed
# ----------------------------------------------------------------------------------------------

def _planner() -> Planner:
    return Planner(SMALL, ObstacleSet([SPHERE, BOX, POINTS]))


def _answer(result: PlanResult) -> tuple:
    return (result.status, result.path.tobytes(), result.smoothed_path.tobytes(),
            result.expanded_nodes)


@pytest.fixture(scope='module')
def reference_answer() -> tuple:
    """A fresh planner's answer to the valid request."""
    return _answer(_planner().plan(VALID_START, VALID_GOAL))


def _nothing_changed(planner: Planner, config: PlannerConfig, obstacles: ObstacleSet,
                     reference: tuple) -> None:
    assert planner.config is config
    assert planner.obstacles is obstacles
    result = planner.plan(VALID_START, VALID_GOAL)
    assert result.ok, result.message
    assert _answer(result) == reference


@pytest.mark.parametrize('case', _by_surface(PLAN), ids=_ids(_by_surface(PLAN)))
def test_plan_refuses_with_a_typed_status(case, reference_answer):
    planner = _planner()
    config, obstacles = planner.config, planner.obstacles
    assert _answer(planner.plan(VALID_START, VALID_GOAL)) == reference_answer
    start, goal, algorithm = case.value
    result = planner.plan(start, goal, algorithm)
    assert result.status.value == case.expected, result.message
    if case.expected == 'ok':
        assert _accepted_reason(case) in result.message, result.message
        assert np.allclose(result.smoothed_path[0], start, rtol=0.0, atol=1e-9)
        assert np.allclose(result.smoothed_path[-1], goal, rtol=0.0, atol=1e-9)
    else:
        assert case.reason in result.message, result.message
        assert len(result.path) == 0 and result.trajectory is None
    _nothing_changed(planner, config, obstacles, reference_answer)


@pytest.mark.parametrize('case', _by_surface(CONFIG), ids=_ids(_by_surface(CONFIG)))
def test_set_config_refuses_and_keeps_the_previous_settings(case, reference_answer):
    planner = _planner()
    config, obstacles = planner.config, planner.obstacles
    planner.plan(VALID_START, VALID_GOAL)  # the grid is built: a refusal must not drop it
    with pytest.raises(InvalidInputError) as refused:
        planner.set_config(case.value())
    assert case.reason in str(refused.value)
    _nothing_changed(planner, config, obstacles, reference_answer)


@pytest.mark.parametrize('case', _by_surface(OBSTACLES), ids=_ids(_by_surface(OBSTACLES)))
def test_malformed_obstacles_are_refused_and_change_nothing(case, reference_answer):
    planner = _planner()
    config, obstacles = planner.config, planner.obstacles
    if case.expected == 'ok':
        item = case.value(planner)
        assert planner.plan(VALID_START, VALID_GOAL, 'octile').ok
        empty = ObstacleSet([item])
        assert empty.is_empty() and np.isinf(empty.distance([0.0, 0.0, 0.0]))
    else:
        with pytest.raises(InvalidInputError) as refused:
            case.value(planner)
        assert case.reason in str(refused.value)
    _nothing_changed(planner, config, obstacles, reference_answer)


# ----------------------------------------------------------------------------------------------
# Scene documents and files
# ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize('case', _by_surface(SCENE), ids=_ids(_by_surface(SCENE)))
def test_malformed_scene_is_refused_with_its_key_path(case):
    path, value = case.value
    data = _with(path, value)
    pristine = copy.deepcopy(data)
    if case.expected == 'ok':
        scene = parse_scene(data)
        assert len(scene.obstacles) < len(VALID_SCENE['obstacles']) or (
            scene.obstacles.points.shape == (0, 3))
    else:
        with pytest.raises(InvalidInputError) as refused:
            parse_scene(data)
        assert case.reason in str(refused.value)
    # The document handed in is not modified, and the valid scene still parses.
    assert repr(data) == repr(pristine)
    assert len(parse_scene(copy.deepcopy(VALID_SCENE)).obstacles) == 3


@pytest.mark.parametrize('case', _by_surface(FILE), ids=_ids(_by_surface(FILE)))
def test_unreadable_scene_file_is_refused(case, tmp_path):
    if case.value == 'directory':
        target = tmp_path / 'bad.yaml'
        target.mkdir()
    else:
        target = tmp_path / 'bad.yaml'
        target.write_bytes(case.value)
    with pytest.raises(InvalidInputError) as refused:
        load_scene(target)
    assert case.reason in str(refused.value)
    valid = tmp_path / 'valid.yaml'
    valid.write_text(yaml.safe_dump(VALID_SCENE))
    assert load_scene(valid).name == 'valid'


# ----------------------------------------------------------------------------------------------
# Map files
# ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize('case', _by_surface(MAP), ids=_ids(_by_surface(MAP)))
def test_map_file_that_cannot_be_right_is_refused(case, tmp_path):
    map_file, options = case.value
    path = map_file.at(tmp_path)
    checks = {'bounds': (SMALL.bounds_min, SMALL.bounds_max),
              'reach': SMALL.safety_margin, 'resolution': SMALL.resolution, **options}
    if case.expected == 'ok':
        loaded = load_map_points(path, **checks)
        (report,) = loaded.reports
        assert _accepted_reason(case) in report.summary(), report.summary()
        assert report.points_kept == len(loaded.points) > 0
        assert report.points_read == (report.dropped_non_finite + report.dropped_outside_bounds
                                      + report.dropped_downsampled + report.points_kept)
    else:
        with pytest.raises(InvalidInputError) as refused:
            load_map_points(path, **checks)
        message = str(refused.value)
        assert message.startswith(str(tmp_path)), message
        assert case.reason in message, message


# ----------------------------------------------------------------------------------------------
# uav-plan plan FILE --json: every case through the console script's main() in this process,
# and a few as real processes (about a second of start-up each) to show they agree
# ----------------------------------------------------------------------------------------------

def _cli_arguments(case: Case, folder: Path) -> list:
    """Write the case's scene file (always named scene.yaml) and its map files, and return
    the arguments (a :class:`MapFile` among them becomes the path it was written to)."""
    document, raw, options, *beside = case.value
    scene = folder / case.case_id / 'scene.yaml'
    scene.parent.mkdir(parents=True)
    if raw is not None:
        scene.write_bytes(raw)
    elif document is not None:
        scene.write_text(yaml.safe_dump(document))
    for map_file in (beside[0] if beside else []):
        map_file.at(scene.parent)
    options = [str(option.at(scene.parent)) if isinstance(option, MapFile) else option
               for option in options]
    return ['plan', str(scene), '--json', *options]


def _check_cli(case: Case, code: int, stdout: str, stderr: str) -> dict:
    expected_code, expected_status = case.expected.split()
    assert code == int(expected_code), (stdout, stderr)
    lines = stdout.strip().splitlines()
    assert len(lines) == 1, stdout       # one JSON object, nothing else on stdout
    result = json.loads(lines[0])
    assert result['status'] == expected_status
    reason = _accepted_reason(case) if expected_status == 'ok' else case.reason
    assert reason in result['message'], result['message']
    if expected_status != 'ok':
        assert result['path'] == []
    assert 'Traceback' not in stderr
    return result


@pytest.mark.parametrize('case', _by_surface(CLI), ids=_ids(_by_surface(CLI)))
def test_cli_plan_json_exit_code_status_and_reason(case, tmp_path, capsys):
    code = uav_plan_main(_cli_arguments(case, tmp_path))
    stdout, stderr = capsys.readouterr()
    _check_cli(case, code, stdout, stderr)


PROCESS_CASES = ('cli_binary_file', 'cli_option_unknown_algorithm', 'cli_no_path',
                 'cli_map_ply_no_points')


def test_cli_cases_in_real_processes(tmp_path):
    executable = shutil.which('uav-plan')
    assert executable, 'uav-plan is not on PATH: run the tests through scripts/test.sh'
    cases = [case for case in _by_surface(CLI) if case.case_id in PROCESS_CASES]
    assert len(cases) == len(PROCESS_CASES)
    running = [(case, subprocess.Popen([executable, *_cli_arguments(case, tmp_path)],
                                       stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                       text=True)) for case in cases]
    for case, process in running:
        stdout, stderr = process.communicate(timeout=300)
        _check_cli(case, process.returncode, stdout, stderr)
