"""The ``uav-plan`` console script, run as a real process."""

import json
from pathlib import Path
import shutil
import subprocess

import numpy as np
import pytest

from uav_global_planner.core.obstacles import ObstacleSet, Sphere

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
    assert set(rows) == {'dijkstra', 'astar', 'adaptive', 'octile'}
    optimum = rows['dijkstra']['path_length_m']
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
