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
from uav_global_planner.core.config import ALGORITHMS
from uav_global_planner_tools.latency_bench.report import format_ros_report

GOALS = 4


def _positive(value) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value) and value > 0


def check_latency_against_node_times(scene) -> None:
    """The measured latencies cover the work the node itself reports for the same goals.

    A plan is published after its search and smoothing, so for every goal the time until its
    bytes arrive, and until it is deserialised, is at least the node's search plus smoothing
    time; medians keep that order. A clock started late, a plan matched to the wrong goal or
    a unit mix-up (seconds against milliseconds) breaks it.
    """
    latency, received = scene['latency'], scene['bytes_latency']
    for key in ('min_ms', 'median_ms', 'p90_ms', 'max_ms'):
        assert _positive(latency[key]) and _positive(received[key]), (latency, received)
    node_ms = {key: scene[key] for key in ('node_search_ms', 'node_smoothing_ms')}
    assert all(_positive(value) for value in node_ms.values()), node_ms
    assert received['median_ms'] >= max(node_ms.values()), (received, node_ms)
    assert latency['median_ms'] >= max(node_ms.values()), (latency, node_ms)
    for goal in scene['by_goal']:
        assert goal['latency']['median_ms'] >= goal['node_plan_ms'], goal


@pytest.fixture(scope='module')
def figures():
    domain_id = unique_domain_id()
    run = subprocess.run(
        [sys.executable, '-m', 'uav_global_planner_tools.latency_bench', 'paper_medium',
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
    check_latency_against_node_times(scene)
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


@pytest.mark.ros
@pytest.mark.slow
def test_cli_bench_prints_ros_figures_after_the_core_tables():
    """``uav-plan bench --ros`` for real: core tables first, then the ROS figures measured by a
    child benchmark process talking to a real planner_node."""
    domain_id = unique_domain_id()
    command = [sys.executable, '-m', 'uav_global_planner.cli.main', 'bench', 'paper_medium',
               '--ros', '--ros-goals', '2']
    text_run = subprocess.run(command, env=ros_environment(domain_id), capture_output=True,
                              text=True, timeout=900)
    assert text_run.returncode == 0, text_run.stdout + text_run.stderr
    text = text_run.stdout
    assert text.index('paper_medium: 41 x 41 x 31') < text.index('ROS: goal published')
    assert 'VmHWM' in text and '2/2' in text
    json_run = subprocess.run(command + ['--json'], env=ros_environment(domain_id),
                              capture_output=True, text=True, timeout=900)
    assert json_run.returncode == 0, json_run.stdout + json_run.stderr
    figures = json.loads(json_run.stdout)
    assert [scene['scene'] for scene in figures['scenes']] == ['paper_medium']
    assert {row['algorithm'] for row in figures['scenes'][0]['rows']} == set(ALGORITHMS)
    measured = {scene['scene']: scene for scene in figures['ros']['scenes']}
    assert measured, figures['ros']
    for scene in measured.values():
        assert scene['plans_received'] == scene['goals'] == 2
        assert _positive(scene['latency']['median_ms'])
    assert _positive(figures['ros']['memory']['peak_rss_mb'])
