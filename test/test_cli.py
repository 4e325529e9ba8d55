"""The ``uav-plan`` console script, run as a real process."""

import json
from pathlib import Path
import shutil
import subprocess

import numpy as np
import pytest

from uav_global_planner.core.map.obstacles import ObstacleSet, Sphere

REPO = Path(__file__).resolve().parents[1]
PLAN_KEYS = {'status', 'message', 'algorithm', 'start', 'goal', 'path', 'path_length_m',
             'expanded_nodes', 'planning_time_s', 'smoothed_path', 'smoothed_length_m',
             'min_clearance_m', 'duration_s'}


def uav_plan(*args, cwd=None):
    executable = shutil.which('uav-plan')
    assert executable, 'uav-plan is not on PATH: run the tests through scripts/test.sh'
    return subprocess.run([executable, *args], capture_output=True, text=True, cwd=cwd,
                          timeout=600)


@pytest.mark.parametrize('algorithm', ['dijkstra', 'astar', 'octile'])
def test_plan_json_on_paper_medium_is_optimal(algorithm):
    run = uav_plan('plan', 'paper_medium', '--algorithm', algorithm, '--json')
    assert run.returncode == 0, run.stderr
    result = json.loads(run.stdout)
    assert PLAN_KEYS <= set(result)
    assert result['status'] == 'ok'
    assert result['algorithm'] == algorithm
    assert result['path_length_m'] == pytest.approx(19.367, abs=5e-4)
    assert result['path'][0] == [0.0, -5.0, 0.0]
    assert result['path'][-1] == [10.0, 5.0, 10.0]
    assert result['min_clearance_m'] >= 0.2


def test_plan_json_reports_a_failure_with_nonzero_exit(tmp_path, scenes_dir):
    text = (scenes_dir / 'paper_medium.yaml').read_text()
    scene = tmp_path / 'goal_inside.yaml'
    scene.write_text(text.replace('goal: [10.0, 5.0, 10.0]', 'goal: [7.4943, 2.3108, 7.2916]'))
    run = uav_plan('plan', str(scene), '--json')
    assert run.returncode == 1
    result = json.loads(run.stdout)
    assert result['status'] == 'goal_occupied'
    assert 'within the safety margin' in result['message']
    assert result['path'] == []


def test_plan_on_a_malformed_scene_names_the_key(tmp_path):
    scene = tmp_path / 'bad.yaml'
    scene.write_text('bounds: {min: [0, 0, 0], max: [1, 1, 1]}\nresolution: 0.1\n'
                     'safety_margin: 0.1\nadaptive_threshold: 1\nstart: [0, 0, 0]\n'
                     'goal: [1, 1, 1]\nobstacles:\n  - {type: cone, center: [0, 0, 0]}\n')
    run = uav_plan('plan', str(scene), '--json')
    assert run.returncode == 2
    result = json.loads(run.stdout)
    assert result['status'] == 'invalid_input'
    assert "obstacles[0].type: unknown obstacle type 'cone'" in result['message']
    human = uav_plan('plan', str(scene))
    assert human.returncode == 2
    assert 'obstacles[0].type' in human.stderr


def test_compare_json_has_one_row_per_algorithm():
    run = uav_plan('compare', 'paper_high', '--json', '--repeats', '2')
    assert run.returncode == 0, run.stderr
    table = json.loads(run.stdout)
    rows = {row['algorithm']: row for row in table['rows']}
    assert set(rows) == {'dijkstra', 'astar', 'adaptive', 'octile', 'weighted', 'bounded'}
    optimum = rows['dijkstra']['path_length_m']
    # Weighted A* keeps its bound (default w = 1.05) on the grid path's cost.
    assert optimum <= rows['weighted']['path_length_m'] <= 1.05 * optimum + 1e-9
    for name in ('astar', 'octile'):
        assert rows[name]['path_length_m'] == pytest.approx(optimum, abs=1e-9)
        assert rows[name]['relative_cost'] == pytest.approx(1.0)
    assert rows['adaptive']['relative_cost'] >= 1.0
    assert rows['adaptive']['expanded_nodes'] < rows['astar']['expanded_nodes']
    assert rows['dijkstra']['expanded_nodes'] > rows['astar']['expanded_nodes']


def test_compare_prints_the_papers_table():
    run = uav_plan('compare', 'paper_medium', '--repeats', '1')
    assert run.returncode == 0, run.stderr
    for word in ('algorithm', 'time [ms]', 'length [m]', 'expanded', 'dijkstra', 'adaptive'):
        assert word in run.stdout


def _is_png(path: Path) -> bool:
    return path.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_plot_and_compare_plot_write_pngs(tmp_path):
    single = tmp_path / 'single.png'
    run = uav_plan('plot', 'paper_medium', '-o', str(single), '--algorithm', 'octile')
    assert run.returncode == 0, run.stderr
    assert _is_png(single) and single.stat().st_size > 20_000
    every = tmp_path / 'every.png'
    run = uav_plan('compare', 'paper_medium', '--repeats', '1', '--plot', str(every))
    assert run.returncode == 0, run.stderr
    assert _is_png(every) and every.stat().st_size > 20_000


def test_overrides_change_the_plan():
    base = json.loads(uav_plan('plan', 'paper_medium', '--json').stdout)
    wider = json.loads(uav_plan('plan', 'paper_medium', '--json', '--safety-margin', '0.6')
                       .stdout)
    assert wider['status'] == 'ok'
    assert wider['safety_margin'] == 0.6
    assert wider['min_clearance_m'] >= 0.6 > base['safety_margin']
    obstacles = ObstacleSet([Sphere(np.array([2.3079, -2.8651, 2.1007]), 2.3517)])
    smoothed = np.array(wider['smoothed_path'])
    assert np.min(obstacles.distance(smoothed)) >= 0.6


def test_plan_through_via_points_from_the_command_line_and_the_scene(tmp_path):
    via = [[0.0, 0.0, 10.0], [5.0, -5.0, 4.0]]
    run = uav_plan('plan', 'paper_medium', '--json', *[f'--via={x},{y},{z}' for x, y, z in via])
    assert run.returncode == 0, run.stderr
    result = json.loads(run.stdout)
    samples = np.asarray(result['smoothed_path'])
    for point in via:
        assert np.min(np.linalg.norm(samples - point, axis=1)) <= 1e-6
    assert [leg['leg'] for leg in result['legs']] == [0, 1, 2]
    assert sum(leg['duration_s'] for leg in result['legs']) == pytest.approx(result['duration_s'])
    # The same via-points from the scene file.
    text = (REPO / 'config' / 'scenes' / 'paper_medium.yaml').read_text()
    scene = tmp_path / 'via.yaml'
    scene.write_text(text + '\nvia: [[0.0, 0.0, 10.0], [5.0, -5.0, 4.0]]\n')
    again = json.loads(uav_plan('plan', str(scene), '--json').stdout)
    assert np.allclose(again['smoothed_path'], result['smoothed_path'])
    # A via-point inside an obstacle names its leg; a malformed one is a usage error.
    inside = uav_plan('plan', 'paper_medium', '--json', '--via=2.3,-2.9,2.1')
    assert inside.returncode == 1
    assert 'via-point 1 (end of leg 0)' in json.loads(inside.stdout)['message']
    bad = uav_plan('plan', 'paper_medium', '--via', '0,0')
    assert bad.returncode == 2 and '--via' in bad.stderr


def test_compare_shows_the_fenced_plans_beside_the_unconstrained_optimum():
    run = uav_plan('compare', 'airspace_demo', '--json', '--repeats', '1')
    assert run.returncode == 0, run.stderr
    rows = {row['algorithm']: row for row in json.loads(run.stdout)['rows']}
    fenced, free = rows['octile'], rows['octile, no geofence']
    # The geofence makes the optimum go around: longer, and its relative cost says by how much.
    assert free['path_length_m'] < fenced['path_length_m']
    assert free['relative_cost'] == pytest.approx(free['path_length_m'] / fenced['path_length_m'])
    for row in rows.values():
        assert row['flight_time_s'] > 0.0 and row['energy_wh'] > 0.0
    assert free['energy_wh'] < fenced['energy_wh']


def test_geofence_file_replaces_the_scene_fence_and_plans_report_energy(tmp_path):
    fence = tmp_path / 'fence.yaml'
    # A no-fly cylinder across paper_medium's straight line from start to goal.
    fence.write_text('exclusion:\n'
                     '  - {type: cylinder, center: [6.0, 0.5], radius: 2.0, floor: 0.0, '
                     'ceiling: 15.0}\n')
    plain = json.loads(uav_plan('plan', 'paper_medium', '--json').stdout)
    fenced_run = uav_plan('plan', 'paper_medium', '--json', '--geofence', str(fence))
    assert fenced_run.returncode == 0, fenced_run.stderr
    fenced = json.loads(fenced_run.stdout)
    samples = np.asarray(fenced['smoothed_path'])
    horizontal = np.hypot(samples[:, 0] - 6.0, samples[:, 1] - 0.5)
    assert np.all(horizontal >= 2.0 + 0.2 - 1e-9), 'the flown curve enters the zone'
    assert np.min(np.hypot(np.asarray(plain['smoothed_path'])[:, 0] - 6.0,
                           np.asarray(plain['smoothed_path'])[:, 1] - 0.5)) < 2.2, (
        'the zone does not cross the unconstrained path: the test proves nothing')
    assert fenced['flight_time_s'] == pytest.approx(fenced['duration_s'])
    assert fenced['energy_wh'] > 0.0 and fenced['cost'] >= fenced['path_length_m'] - 1e-9
    missing = uav_plan('plan', 'paper_medium', '--geofence', str(tmp_path / 'none.yaml'))
    assert missing.returncode == 2 and 'none.yaml' in missing.stderr


def test_a_long_plan_reports_its_stage_on_stderr_and_json_stays_one_object():
    # paper_medium with Dijkstra on ever finer grids (6 M, 17.6 M, 48 M nodes) until the search
    # takes two seconds or more, whatever this machine's speed.
    for resolution in ('0.1', '0.07', '0.05'):
        run = uav_plan('plan', 'paper_medium', '--resolution', resolution, '--algorithm',
                       'dijkstra', '--max-planning-time', '0', '--json')
        assert run.returncode == 0, run.stderr
        result = json.loads(run.stdout)
        if result['total_time_s'] >= 1.5:
            assert 'planning: search after' in run.stderr, run.stderr
        elif result['total_time_s'] < 1.0:
            # Progress is reported once a plan has run 1 s (core.budget.REPORT_AFTER_S).
            assert 'planning:' not in run.stderr
        if result['planning_time_s'] >= 2.0:
            break
    # The budget covers the grid build too: room for the build and 0.3 of the search (at least
    # 0.6 s), so the second run times out in its search unless its build takes 0.6 s longer or
    # its search is 3 times shorter (the machine's load may change between the runs, not that
    # much).
    search_s = result['planning_time_s']
    assert search_s >= 2.0, f'the search ({search_s:.2f} s) is too quick to run out'
    limit = result['grid_build_time_s'] + 0.3 * search_s
    budget = uav_plan('plan', 'paper_medium', '--resolution', resolution, '--algorithm',
                      'dijkstra', '--max-planning-time', f'{limit:.3f}', '--json')
    assert budget.returncode == 1
    timed_out = json.loads(budget.stdout)
    assert timed_out['status'] == 'timeout'
    assert timed_out['message'].startswith('search ran out of the planning time budget')
