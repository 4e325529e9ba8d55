"""The ROS benchmark runs end to end and reports sane figures (structure only, no timing).

``latency_bench`` starts planner_node, sends it goals over DDS and reads the node's memory; here
on paper_medium with a handful of goals, and paper_medium also as the memory scene so that the
algorithm switching over the parameter services is covered without the 6-million-voxel grid.
"""

import json
import math
import subprocess
import sys

import pytest

from ros_harness import ros_environment, STARTUP_TIMEOUT_S, unique_domain_id
from uav_global_planner.cli.bench import format_ros_report, main as bench_main
from uav_global_planner.core.config import ALGORITHMS

GOALS = 4


def _positive(value) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value) and value > 0


@pytest.fixture(scope='module')
def figures():
    domain_id = unique_domain_id()
    run = subprocess.run(
        [sys.executable, '-m', 'uav_global_planner.ros.latency_bench', 'paper_medium',
         '--goals', str(GOALS), '--memory-scene', 'paper_medium', '--domain-id',
         str(domain_id), '--timeout', str(STARTUP_TIMEOUT_S), '--json'],
        env=ros_environment(domain_id), capture_output=True, text=True,
        timeout=2 * STARTUP_TIMEOUT_S + 60)
    assert run.returncode == 0, run.stdout + run.stderr
    assert 'Traceback' not in run.stderr, run.stderr
    return json.loads(run.stdout)


@pytest.mark.ros
@pytest.mark.slow
def test_every_goal_gets_a_plan_with_finite_positive_latency(figures):
    assert figures['goals'] == GOALS
    [scene] = figures['scenes']
    assert scene['scene'] == 'paper_medium'
    assert scene['plans_received'] == GOALS
    assert scene['failures'] == []
    latency = scene['latency']
    for key in ('min_ms', 'median_ms', 'p90_ms', 'max_ms'):
        assert _positive(latency[key]), latency
    assert latency['min_ms'] <= latency['median_ms'] <= latency['p90_ms'] <= latency['max_ms']
    # The bytes of each plan arrive before they are deserialised.
    received = scene['bytes_latency']
    for key in ('min_ms', 'median_ms', 'p90_ms', 'max_ms'):
        assert _positive(received[key]) and received[key] <= latency[key], (received, latency)
    assert _positive(scene['startup_s'])
    # Goals alternate between the scene's goal and a second free point.
    assert [g['goals'] for g in scene['by_goal']] == [GOALS // 2, GOALS - GOALS // 2]
    assert scene['by_goal'][0]['goal'] == [10.0, 5.0, 10.0]
    assert scene['by_goal'][1]['goal'] != scene['by_goal'][0]['goal']
    for goal in scene['by_goal']:
        assert _positive(goal['latency']['median_ms']) and _positive(goal['node_plan_ms'])
    assert _positive(scene['node_smoothing_ms'])
    assert scene['poses'] > 2
    assert _positive(scene['peak_rss_mb'])
    assert scene['exit_code'] == 0


@pytest.mark.ros
@pytest.mark.slow
def test_memory_figure_covers_every_algorithm(figures):
    memory = figures['memory']
    assert memory['scene'] == 'paper_medium'
    assert [row['algorithm'] for row in memory['algorithms']] == list(ALGORITHMS)
    for row in memory['algorithms']:
        assert row['status'] == 'ok', row
        assert _positive(row['latency_ms']), row
        assert _positive(row['peak_rss_mb']), row
    assert _positive(memory['peak_rss_mb']) and _positive(memory['rss_mb'])
    assert memory['peak_rss_mb'] >= max(row['peak_rss_mb'] for row in memory['algorithms'])
    assert memory['exit_code'] == 0


@pytest.mark.ros
@pytest.mark.slow
def test_report_table_shows_the_figures(figures):
    report = format_ros_report(figures)
    assert 'paper_medium' in report and f'{GOALS}/{GOALS}' in report
    assert 'VmHWM' in report
    for algorithm in ALGORITHMS:
        assert algorithm in report


def test_cli_bench_prints_ros_figures_after_the_core_tables(monkeypatch, capsys):
    """``uav-plan bench --ros``: the ROS figures come from the child process, after the core
    tables (both measurements replaced by canned figures here)."""
    from uav_global_planner.cli import bench
    core = {'scene': 'paper_medium', 'voxels': 52111, 'shape': [41, 41, 31],
            'grid_build_s': 0.001, 'peak_rss_mb': 100.0, 'rows': []}
    ros = {'domain_id': 7, 'goals': 3, 'cpus': 2, 'load_average': 0.5,
           'load_average_after': 0.6, 'memory': None,
           'scenes': [{'scene': 'paper_medium', 'startup_s': 1.0, 'goals': 3,
                       'plans_received': 3, 'failures': [],
                       'latency': {'median_ms': 12.5, 'p90_ms': 14.0, 'max_ms': 15.0,
                                   'min_ms': 10.0},
                       'bytes_latency': {'median_ms': 9.5, 'p90_ms': 11.0, 'max_ms': 12.0,
                                         'min_ms': 7.0},
                       'node_search_ms': 0.1, 'node_smoothing_ms': 5.0, 'poses': 170,
                       'peak_rss_mb': 220.0, 'exit_code': 0}]}
    calls = []
    monkeypatch.setattr(bench, '_measure_in_subprocess', lambda name: core)
    monkeypatch.setattr(bench, 'measure_ros', lambda options: calls.append(options) or ros)
    assert bench_main(['paper_medium', '--ros', '--ros-goals', '3']) == 0
    text = capsys.readouterr().out
    assert calls == [['--goals', '3']]
    assert text.index('paper_medium: 41 x 41 x 31') < text.index('ROS: goal published')
    assert '12.5' in text
    assert bench_main(['paper_medium', '--ros', '--json']) == 0
    assert json.loads(capsys.readouterr().out) == {'scenes': [core], 'ros': ros}
    assert bench_main(['paper_medium', '--json']) == 0
    assert json.loads(capsys.readouterr().out) == {'scenes': [core]}
