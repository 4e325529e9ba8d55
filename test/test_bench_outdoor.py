"""The outdoor benchmark runs end to end and reports sane figures (structure only, no timing)."""

import json
import subprocess
import sys

import pytest

from uav_global_planner.core.search.grid_search import ALGORITHM_CODES


def _positive(value) -> bool:
    return isinstance(value, (int, float)) and value > 0


def _run(command, repo_root, timeout=600) -> subprocess.CompletedProcess:
    return subprocess.run(command, cwd=repo_root, capture_output=True, text=True,
                          timeout=timeout)


def test_uav_plan_bench_outdoor_runs_the_smallest_case(tmp_path):
    # Outside the source tree: the benchmark is installed with the tools, not read from it.
    run = _run([sys.executable, '-m', 'uav_global_planner.cli.main', 'bench', '--outdoor',
                'wall_gap_0.2', '--json'], tmp_path)
    assert run.returncode == 0, run.stdout + run.stderr
    document = json.loads(run.stdout)
    assert document['machine']['cpus'] >= 1
    [case] = document['cases']
    assert case['case'] == 'wall_gap_0.2'
    first = case['first']
    assert first['status'] == 'ok', first['message']
    for key in ('end_to_end_s', 'grid_build_s', 'search_s', 'smoothing_s', 'expanded_nodes',
                'path_length_m', 'smoothed_length_m'):
        assert _positive(first[key]), (key, first[key])
    # The figures belong to a plan that keeps the margin it was asked for.
    assert first['min_clearance_m'] >= 0.2
    assert case['repeated']['runs'] >= 3 and _positive(case['repeated']['end_to_end_s'])
    assert _positive(case['peak_rss_mb']) and _positive(case['rss_before_mb'])
    assert case['voxels'] == 81 * 81 * 61
    assert 'target' in case


@pytest.mark.slow
def test_quick_cloud_grid_and_search_cases_report_their_figures(repo_root):
    run = _run([sys.executable, 'benchmarks/bench_outdoor.py', '--quick', '--only',
                'cloud_town_grid,search100m', '--json'], repo_root)
    assert run.returncode == 0, run.stdout + run.stderr
    cases = {case['case']: case for case in json.loads(run.stdout)['cases']}
    cloud = cases['cloud_town_grid']
    assert cloud['quick'] and _positive(cloud['points']) and _positive(cloud['grid_build_s'])
    assert cloud['voxels'] == 401 * 401 * 81 and 0.0 < cloud['blocked_fraction'] < 1.0
    search = cases['search100m']
    octile = search['searches']['octile']
    assert _positive(octile['cost_m']) and _positive(octile['expanded_nodes'])
    assert octile['cost_ratio'] == 1.0
    assert octile['cost_m'] >= search['diagonal_m']
    if 'weighted' in ALGORITHM_CODES:
        weighted = search['searches']['weighted']
        # The bound the weighted search promises, on the figures the benchmark prints.
        assert 1.0 - 1e-12 <= weighted['cost_ratio'] <= search['weight'] + 1e-12
    assert _positive(search['peak_rss_mb'])


def test_unknown_case_is_refused_with_the_list_of_cases(repo_root):
    run = _run([sys.executable, 'benchmarks/bench_outdoor.py', '--only', 'no_such_case'],
               repo_root, timeout=120)
    assert run.returncode == 2
    assert 'unknown case(s) no_such_case' in run.stderr and 'town400_adaptive' in run.stderr


def test_uav_plan_bench_outdoor_refuses_an_unknown_case(tmp_path):
    run = _run(['uav-plan', 'bench', '--outdoor', 'no_such_case'], tmp_path, timeout=120)
    assert run.returncode == 2
    assert 'unknown case(s) no_such_case' in run.stderr and 'Traceback' not in run.stderr
