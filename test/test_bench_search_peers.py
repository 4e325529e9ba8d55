"""The search scene family has the sizes it names, and the peer benchmark prints its table.

Structure only: no speed is asserted (figures belong in benchmarks/, not in timed tests).
"""

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from ros_harness import unique_domain_id
from uav_global_planner.core import Planner
from uav_global_planner.core.config import ALGORITHMS
from uav_global_planner_tools.processes import ros_environment
from uav_global_planner_tools.search_scenes import (blocked_fraction, GOAL, parse_sizes,
                                                    scene_obstacles, search_scene, START)


def test_scene_family_names_its_node_counts_without_building_them():
    counts = {size: search_scene(size).nodes for size in ('6M', '20M', '100M', '1G')}
    assert counts['6M'] == 201 * 201 * 151
    assert counts['20M'] == 301 * 301 * 226
    assert counts['100M'] == 511 * 511 * 383
    assert counts['1G'] == 1101 * 1101 * 826
    for size, count in counts.items():
        target = {'6M': 6e6, '20M': 20e6, '100M': 100e6, '1G': 1e9}[size]
        assert abs(count / target - 1.0) < 0.03, (size, count)
    # A grid the planner accepts at every size (the node cap follows the size).
    assert search_scene('1G').config.max_voxels >= counts['1G']
    with pytest.raises(ValueError, match='size'):
        search_scene('7M')
    with pytest.raises(ValueError, match='size'):
        parse_sizes('6M,abc')
    assert parse_sizes('6M, 0.5') == ['6M', 0.5]


def test_scene_at_a_small_size_blocks_48_percent_with_free_ends_27_m_apart():
    scene = search_scene(0.2)
    assert scene.shape == (101, 101, 76) and scene.nodes == 101 * 101 * 76
    planner = scene.planner()
    assert isinstance(planner, Planner)
    blocked = planner.blocked
    assert blocked.shape == scene.shape
    assert 0.46 <= blocked_fraction(blocked) <= 0.50
    grid = planner.grid
    for end in (START, GOAL):
        assert not blocked[tuple(grid.world_to_index(end))], end
    assert math.dist(START, GOAL) == pytest.approx(27.1, abs=0.05)
    # 60 spheres of dense60_fine and 20 boxes, the same on every build (fixed seed).
    first, second = scene_obstacles(), scene_obstacles()
    assert len(first.sphere_radii) == 60 and len(first.box_mins) == 20
    np.testing.assert_array_equal(first.box_mins, second.box_mins)
    np.testing.assert_array_equal(first.box_maxs, second.box_maxs)
    # A path exists: the plan succeeds end to end.
    result = planner.plan(scene.start, scene.goal, 'adaptive')
    assert result.status.name.lower() == 'ok', result.message


def _benchmark(repo_root, tmp_path, *options, pythonpath=None):
    out = tmp_path / 'figures.json'
    env = ros_environment(unique_domain_id(), tmp_path / 'ros_log')
    if pythonpath is not None:
        env['PYTHONPATH'] = os.pathsep.join(
            [str(pythonpath)] + ([env['PYTHONPATH']] if env.get('PYTHONPATH') else []))
    run = subprocess.run([sys.executable, str(repo_root / 'benchmarks' / 'bench_search_peers.py'),
                          '--sizes', '0.5', '--repeats', '1', '--json', str(out), *options],
                         cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stdout + run.stderr
    return run.stdout, json.loads(out.read_text(encoding='utf-8'))


def test_benchmark_prints_the_table_at_a_tiny_size(repo_root, tmp_path):
    stdout, figures = _benchmark(repo_root, tmp_path)
    assert '| method | delta=0.5 |' in stdout and 'load average' in stdout
    [size] = figures['sizes'].values()
    assert size['nodes'] == 41 * 41 * 31
    methods = size['methods']
    optimum = size['optimum_m']
    assert optimum >= math.dist(START, GOAL)
    # Every algorithm the core lists is measured or says why not, without a code change.
    for name in ALGORITHMS:
        assert f'| {name} |' in stdout
        assert name in methods
    assert methods['octile']['cost_ratio_min'] == pytest.approx(1.0)
    for name, figure in methods.items():
        if 'bound' in figure and 'cost_ratio_max' in figure:
            assert figure['cost_ratio_max'] <= figure['bound'] + 1e-9, name
    plan = methods['whole plan, adaptive']
    assert plan['solved'] == plan['runs'] and 0.0 < plan['search_s'] < plan['median_s']
    for peer, rows in (('ompl', ['BIT* (OMPL)']),
                       ('dijkstra3d', ['dijkstra3d A*', 'dijkstra3d Dijkstra'])):
        for row in rows:
            if figures['peers'][peer] == 'ok':
                assert methods[row]['runs'] >= 1, row
            else:
                assert methods[row] == {'skipped': 'absent'}
                assert f'{peer} is absent' in stdout
    if figures['peers']['dijkstra3d'] == 'ok':
        # Edge costs of step lengths: dijkstra3d finds our optimum, not a cheaper path.
        for row in ('dijkstra3d A*', 'dijkstra3d Dijkstra'):
            assert methods[row]['cost_ratio_min'] == pytest.approx(1.0, abs=1e-9)
    if figures['peers']['ompl'] == 'ok':
        assert methods['BIT* (OMPL)']['solved'] >= 1
        assert methods['BIT* (OMPL)']['cost_ratio_max'] <= 1.05 + 1e-9


def test_benchmark_says_when_the_peers_are_absent(repo_root, tmp_path):
    # Packages that fail to import stand for peers that are not installed.
    hidden = tmp_path / 'hidden'
    for name in ('ompl', 'dijkstra3d'):
        (hidden / name).mkdir(parents=True)
        (hidden / name / '__init__.py').write_text(f"raise ImportError('no {name} here')\n")
    stdout, figures = _benchmark(repo_root, tmp_path, pythonpath=hidden)
    assert figures['peers'] == {'ompl': 'absent', 'dijkstra3d': 'absent'}
    assert 'ompl is absent' in stdout and 'dijkstra3d is absent' in stdout
    assert '| BIT* (OMPL) | absent |' in stdout
    [size] = figures['sizes'].values()
    assert size['methods']['octile']['runs'] >= 1
