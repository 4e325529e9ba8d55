"""Prints per-stage times and peak memory of the planner on the outdoor scenes, beside targets.

Run wherever the package is installed::

    uav-plan bench --outdoor [CASE ...] [--json]
    python -m uav_global_planner_tools.outdoor_bench [--only NAME] [--json] [--search-only]

``uav-plan bench --outdoor`` finds :func:`main` through the entry point ``outdoor`` of the group
``uav_global_planner.bench``; ``benchmarks/bench_outdoor.py`` of a source checkout runs it too.

Cases (``--only`` takes a case name or the start of one, for example ``town400``; repeat it or
separate names by commas):

==================  ==================================================================
town400_adaptive    town400 (13 M voxels), 277 m corner-to-corner crossing, adaptive
town400_octile      the same with the optimal octile search
city1km             city1km (101 M voxels), 1.30 km crossing, the configured algorithm
wall_gap_0.2        wall_gap (0.40 M voxels, two staggered walls) at gamma 0.2 m
wall_gap_3.0        wall_gap at gamma 3.0 m (the memory delta is against wall_gap_0.2)
cloud_town_grid     grid build from the town's surfaces as a 0.82 M-point cloud, 13 M voxels
paper_medium        smoothing time on the paper's Table 1 scene (median of many plans)
paper_high          the same on the Table 2 scene
search100m          99 M-node sphere-and-box grid, 26.9 m diagonal: octile, and weighted
                    (w = 1.05) where the search offers it, with its cost against the optimum
==================  ==================================================================

Every case runs in a fresh process, so the peak resident memory it reports is its own. The
compiled kernels are loaded first on a tiny scene (reported apart), then each plan is timed
with the whole-plan budget lifted (``max_planning_time`` 0), so slow stages show their true
time instead of a timeout. A planner case reports the first plan (grid build included) and the
median of later plans on the built grid. ``--search-only`` replaces the planner cases by grid
build and search alone (core.inflation and core.search, what the planner runs before
smoothing). ``--quick`` runs shortened versions for smoke tests: wall_gap, the cloud grid on
the town's first 40 buildings, the search grid at 0.1 m (3.1 M nodes). Figures only: nothing
here asserts a speed.
"""

import argparse
from dataclasses import replace
import json
import os
from pathlib import Path
import resource
import statistics
import subprocess
import sys
import time
from typing import Any, Callable, Dict, List, Optional, Union

import numpy as np

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.io.scene import find_scene, load_scene, Scene
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, PointSet, Sphere
from uav_global_planner.core.map.sparse_grid import SparseMask
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.search.grid_search import ALGORITHM_CODES, SearchWorkspace
from uav_global_planner_tools import outdoor_scenes

# Node cap the benchmark allows (city1km has 101 M nodes, the search grid 99 M).
MAX_VOXELS = 110_000_000
# Bounded-suboptimal search: its name, and the bound w measured.
WEIGHTED = 'weighted'
WEIGHT = 1.05
# Later plans on a built grid are repeated until this much time was spent [s] (3 to 20 runs).
REPEAT_BUDGET_S = 3.0

# The figures each case is judged by, with the values measured before the outdoor work and the
# targets set for it.
TARGETS = {
    'town400_adaptive': 'end to end <= 0.5 s, smoothing <= 100 ms (was ~20 s, 19.6-21.1 s)',
    'town400_octile': 'end to end <= 0.5 s, smoothing <= 100 ms (was ~20 s, 19.6-21.1 s)',
    'city1km': 'end to end <= 3 s (was 365 s, 362 s of it smoothing)',
    'wall_gap_0.2': 'reference for wall_gap_3.0',
    'wall_gap_3.0': 'end to end <= 0.2 s, peak RSS <= +50 MB over gamma 0.2 (was 20 s, 4 GB)',
    'cloud_town_grid': 'grid build <= 1 s (was 8.3 s)',
    'paper_medium': 'smoothing no slower than 3-5 ms (goal -> plan over ROS 10-17 ms)',
    'paper_high': 'smoothing no slower than 3-5 ms (goal -> plan over ROS 10-17 ms)',
    'search100m': 'octile search <= 0.4 s (was 1.27 s); weighted w = 1.05 <= 25 ms, cost '
                  '<= 1.05 x optimum',
}


def _rss_mb() -> float:
    """Resident memory of this process now [MiB] (VmRSS of /proc; 0 where it is missing)."""
    try:
        status = Path('/proc/self/status').read_text()
    except OSError:
        return 0.0
    for line in status.splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024.0
    return 0.0


def _peak_rss_mb() -> float:
    # ru_maxrss is the high-water mark of the resident set, in KiB on Linux.
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _ms(seconds: Optional[float]) -> Optional[float]:
    return None if seconds is None else seconds * 1e3


def _finite(value) -> Optional[float]:
    number = float(value)
    return number if np.isfinite(number) else None


def _blocked_fraction(blocked: Union[np.ndarray, SparseMask]) -> float:
    """Share of the grid's nodes that are blocked, in either mask layout [-]."""
    if isinstance(blocked, SparseMask):
        return blocked.count_blocked() / blocked.size
    return float(blocked.mean())


def warm_up() -> float:
    """Load (or compile) every kernel on a tiny scene with all three obstacle kinds [s]."""
    started = time.perf_counter()
    obstacles = ObstacleSet([Sphere(np.array([1.0, 1.0, 1.0]), 0.3),
                             Box(np.array([2.0, 0.0, 0.0]), np.array([2.5, 3.0, 1.5])),
                             PointSet(np.array([[1.0, 2.5, 1.0], [1.2, 2.5, 1.0]]))])
    config = PlannerConfig(bounds_min=(0.0, 0.0, 0.0), bounds_max=(4.0, 3.0, 2.0),
                           resolution=0.25, safety_margin=0.2, max_planning_time=0.0)
    planner = Planner(config, obstacles)
    for algorithm in ('adaptive', 'octile', WEIGHTED):
        if algorithm in ALGORITHM_CODES:
            planner.plan([0.25, 0.25, 0.5], [3.75, 2.75, 1.5], algorithm)
    return time.perf_counter() - started


def _load(name: str, **changes) -> Scene:
    """A shipped scene, allowed up to MAX_VOXELS nodes, with settings changed."""
    scene = load_scene(find_scene(name), base=PlannerConfig(max_voxels=MAX_VOXELS))
    config = scene.config.with_changes(max_voxels=max(scene.config.max_voxels, MAX_VOXELS),
                                       max_planning_time=0.0, **changes)
    return replace(scene, config=config)


def _plan_figures(result) -> Dict[str, Any]:
    total = getattr(result, 'total_time_s', None)
    return {
        'status': result.status.value,
        'grid_build_s': _finite(result.grid_build_time_s),
        'search_s': _finite(result.planning_time_s),
        'smoothing_s': _finite(result.smoothing_time_s),
        'total_s': _finite(total) if total is not None else None,
        'expanded_nodes': int(result.expanded_nodes),
        'path_length_m': _finite(result.path_length_m),
        'smoothed_length_m': _finite(result.smoothed_length_m),
        'min_clearance_m': _finite(result.min_clearance_m),
        'message': result.message if not result.ok else '',
    }


def plan_case(scene: Scene, algorithm: str) -> Dict[str, Any]:
    """One scene planned end to end: first plan (grid build included), then repeated plans."""
    planner = Planner(scene.config, scene.obstacles)
    rss_before = _rss_mb()
    started = time.perf_counter()
    first = planner.plan(scene.start, scene.goal, algorithm)
    first_s = time.perf_counter() - started
    figures: Dict[str, Any] = {'first': dict(_plan_figures(first), end_to_end_s=first_s)}
    runs: List[Dict[str, Any]] = []
    spent = time.perf_counter()
    while first.ok and (len(runs) < 3 or (
            len(runs) < 20 and time.perf_counter() - spent < REPEAT_BUDGET_S)):
        started = time.perf_counter()
        result = planner.plan(scene.start, scene.goal, algorithm)
        runs.append(dict(_plan_figures(result), end_to_end_s=time.perf_counter() - started))
    if runs:
        figures['repeated'] = {
            'runs': len(runs),
            **{key: statistics.median(r[key] for r in runs)
               for key in ('end_to_end_s', 'search_s', 'smoothing_s')}}
    figures['rss_before_mb'] = rss_before
    figures['algorithm'] = algorithm
    figures['voxels'] = planner.grid.size
    return figures


def search_case(grid: VoxelGrid, obstacles: ObstacleSet, gamma: float, start, goal,
                algorithms, eta: float, repeats: int = 3) -> Dict[str, Any]:
    """Grid build and searches on it, timed apart (the planner's stages before smoothing)."""
    rss_before = _rss_mb()
    started = time.perf_counter()
    blocked = blocked_mask(grid, obstacles, gamma)
    build_s = time.perf_counter() - started
    workspace = SearchWorkspace(blocked)
    start_node, goal_node = grid.world_to_index(start), grid.world_to_index(goal)
    rows: Dict[str, Dict[str, Any]] = {}
    for algorithm in algorithms:
        if algorithm not in ALGORITHM_CODES:
            continue
        options: Dict[str, Any] = {'weight': WEIGHT} if algorithm == WEIGHTED else {}
        times = []
        for _ in range(repeats):
            found = workspace.search(start_node, goal_node, algorithm, grid.resolution, eta,
                                     **options)
            times.append(found.search_time_s)
        rows[algorithm] = {'search_s': statistics.median(times), 'min_search_s': min(times),
                           'expanded_nodes': int(found.expanded_nodes),
                           'cost_m': float(found.cost_m)}
    optimum = rows.get('octile', {}).get('cost_m')
    for row in rows.values():
        row['cost_ratio'] = row['cost_m'] / optimum if optimum else None
    return {'voxels': grid.size, 'grid_build_s': build_s, 'blocked_fraction':
            _blocked_fraction(blocked), 'searches': rows, 'rss_before_mb': rss_before}


def _town_search(algorithm: str) -> Dict[str, Any]:
    scene = _load('town400')
    grid = VoxelGrid.from_bounds(scene.config.bounds_min, scene.config.bounds_max,
                                 scene.config.resolution, MAX_VOXELS)
    return search_case(grid, scene.obstacles, scene.config.safety_margin, scene.start,
                       scene.goal, (algorithm,), scene.config.adaptive_threshold)


def case_town(algorithm: str, search_only: bool) -> Callable[[], Dict[str, Any]]:
    def run() -> Dict[str, Any]:
        if search_only:
            return _town_search(algorithm)
        return plan_case(_load('town400'), algorithm)
    return run


def case_city(search_only: bool) -> Dict[str, Any]:
    scene = _load('city1km')
    if search_only:
        config = scene.config
        grid = VoxelGrid.from_bounds(config.bounds_min, config.bounds_max, config.resolution,
                                     MAX_VOXELS)
        return search_case(grid, scene.obstacles, config.safety_margin, scene.start,
                           scene.goal, (config.algorithm,), config.adaptive_threshold,
                           repeats=1)
    return plan_case(scene, scene.config.algorithm)


def case_wall_gap(gamma: float) -> Callable[[], Dict[str, Any]]:
    def run() -> Dict[str, Any]:
        scene = _load('wall_gap', safety_margin=gamma)
        return plan_case(scene, scene.config.algorithm)
    return run


def case_cloud_grid(quick: bool) -> Dict[str, Any]:
    """The town's box surfaces as points, inflated on the town grid (median of 3 builds)."""
    town = _load('town400')
    boxes = np.stack([town.obstacles.box_mins, town.obstacles.box_maxs], axis=1)
    if quick:
        boxes = boxes[:40]
    started = time.perf_counter()
    cloud = outdoor_scenes.surface_cloud(boxes, outdoor_scenes.CLOUD_SPACING)
    sample_s = time.perf_counter() - started
    started = time.perf_counter()
    obstacles = ObstacleSet([PointSet(cloud)])
    index_s = time.perf_counter() - started
    config = town.config
    grid = VoxelGrid.from_bounds(config.bounds_min, config.bounds_max, config.resolution,
                                 MAX_VOXELS)
    rss_before = _rss_mb()
    builds = []
    for _ in range(3):
        started = time.perf_counter()
        blocked = blocked_mask(grid, obstacles, config.safety_margin)
        builds.append(time.perf_counter() - started)
    return {'points': len(cloud), 'spacing_m': outdoor_scenes.CLOUD_SPACING, 'voxels': grid.size,
            'gamma_m': config.safety_margin, 'grid_build_s': statistics.median(builds),
            'grid_build_min_s': min(builds), 'cloud_sampling_s': sample_s,
            'obstacle_set_s': index_s, 'blocked_fraction': _blocked_fraction(blocked),
            'rss_before_mb': rss_before}


def case_paper(name: str) -> Callable[[], Dict[str, Any]]:
    def run() -> Dict[str, Any]:
        scene = _load(name)
        figures: Dict[str, Any] = {'algorithms': {}}
        planner = Planner(scene.config, scene.obstacles)
        planner.plan(scene.start, scene.goal, 'adaptive')
        figures['rss_before_mb'] = _rss_mb()
        for algorithm in ('adaptive', 'octile'):
            runs = [planner.plan(scene.start, scene.goal, algorithm) for _ in range(30)]
            figures['algorithms'][algorithm] = {
                'status': runs[-1].status.value,
                'smoothing_s': statistics.median(r.smoothing_time_s for r in runs),
                'search_s': statistics.median(r.planning_time_s for r in runs),
                'end_to_end_s': statistics.median(
                    getattr(r, 'total_time_s', 0.0) or (r.planning_time_s + r.smoothing_time_s)
                    for r in runs)}
        figures['voxels'] = planner.grid.size
        return figures
    return run


def case_search100m(quick: bool) -> Dict[str, Any]:
    scene = outdoor_scenes.spheres_boxes_100m()
    # --quick: the same obstacles at 0.1 m (3.1 M nodes), for smoke tests.
    delta = 0.1 if quick else scene.resolution
    grid = VoxelGrid.from_bounds(scene.bounds_min, scene.bounds_max, delta, MAX_VOXELS)
    figures = search_case(grid, scene.obstacle_set(), scene.safety_margin, scene.start,
                          scene.goal, ('octile', WEIGHTED), scene.adaptive_threshold)
    figures['weighted_available'] = WEIGHTED in ALGORITHM_CODES
    figures['weight'] = WEIGHT
    figures['diagonal_m'] = float(np.linalg.norm(np.subtract(scene.goal, scene.start)))
    return figures


def cases(search_only: bool, quick: bool) -> Dict[str, Callable[[], Dict[str, Any]]]:
    """Every case by name, in the order they are reported."""
    table: Dict[str, Callable[[], Dict[str, Any]]] = {
        'town400_adaptive': case_town('adaptive', search_only),
        'town400_octile': case_town('octile', search_only),
        'city1km': lambda: case_city(search_only),
        'wall_gap_0.2': case_wall_gap(0.2),
        'wall_gap_3.0': case_wall_gap(3.0),
        'cloud_town_grid': lambda: case_cloud_grid(quick),
        'paper_medium': case_paper('paper_medium'),
        'paper_high': case_paper('paper_high'),
        'search100m': lambda: case_search100m(quick),
    }
    return table


# This module's name, for the worker processes it starts.
_MODULE = 'uav_global_planner_tools.outdoor_bench'

QUICK_CASES = ('wall_gap_0.2', 'wall_gap_3.0', 'cloud_town_grid', 'search100m')


def run_case(name: str, search_only: bool, quick: bool) -> Dict[str, Any]:
    """Measure one case in this process."""
    warm_s = warm_up()
    figures = cases(search_only, quick)[name]()
    figures.update(case=name, kernel_load_s=warm_s, peak_rss_mb=_peak_rss_mb(),
                   target=TARGETS[name], search_only=search_only, quick=quick)
    return figures


def _run_in_subprocess(name: str, search_only: bool, quick: bool) -> Dict[str, Any]:
    command = [sys.executable, '-m', _MODULE, '--case', name]
    command += ['--search-only'] if search_only else []
    command += ['--quick'] if quick else []
    run = subprocess.run(command, capture_output=True, text=True, check=False)
    if run.returncode != 0:
        return {'case': name, 'error': run.stderr.strip().splitlines()[-1:] or ['failed'],
                'target': TARGETS[name]}
    return json.loads(run.stdout)


def _s(value: Optional[float], digits: int = 3) -> str:
    if value is None:
        return '-'
    if value < 1.0:
        return f'{value * 1e3:.{max(digits - 2, 1)}f} ms'
    return f'{value:.{digits - 1}f} s'


def describe(figures: Dict[str, Any]) -> List[List[str]]:
    """Rows (figure, measured) of one case for the text report."""
    if 'error' in figures:
        return [['error', ' '.join(figures['error'])]]
    rows: List[List[str]] = []
    if 'first' in figures:
        first = figures['first']
        rows.append([f"first plan ({figures['algorithm']}, {first['status']})",
                     f"end to end {_s(first['end_to_end_s'])}: grid build "
                     f"{_s(first['grid_build_s'])}, search {_s(first['search_s'])} "
                     f"({first['expanded_nodes']} expanded), smoothing + timing "
                     f"{_s(first['smoothing_s'])}"])
        if first['path_length_m'] is not None:
            rows.append(['path', f"grid {first['path_length_m']:.1f} m, smoothed "
                         f"{first['smoothed_length_m'] or float('nan'):.1f} m, min clearance "
                         f"{first['min_clearance_m'] or float('nan'):.3f} m"])
        if first['message']:
            rows.append(['message', first['message'][:160]])
        repeated = figures.get('repeated')
        if repeated:
            rows.append([f"later plans (median of {repeated['runs']})",
                         f"end to end {_s(repeated['end_to_end_s'])}: search "
                         f"{_s(repeated['search_s'])}, smoothing + timing "
                         f"{_s(repeated['smoothing_s'])}"])
    if 'searches' in figures:
        rows.append(['grid build', f"{_s(figures['grid_build_s'])} ({figures['voxels'] / 1e6:.1f}"
                     f" M voxels, {figures['blocked_fraction']:.1%} blocked)"])
        for algorithm, row in figures['searches'].items():
            ratio = row['cost_ratio']
            rows.append([f'search {algorithm}',
                         f"{_s(row['search_s'])} (min {_s(row['min_search_s'])}), "
                         f"{row['expanded_nodes']} expanded, cost {row['cost_m']:.3f} m"
                         + (f', {ratio:.4f} x optimum' if ratio else '')])
        if figures.get('weighted_available') is False:
            rows.append([f'search {WEIGHTED}', 'not offered by core.search'])
    if 'points' in figures:
        rows.append(['grid build from the cloud',
                     f"{_s(figures['grid_build_s'])} (min {_s(figures['grid_build_min_s'])}): "
                     f"{figures['points']} points at {figures['spacing_m']} m, "
                     f"{figures['voxels'] / 1e6:.1f} M voxels, gamma {figures['gamma_m']} m"])
        rows.append(['before it', f"sampling {_s(figures['cloud_sampling_s'])}, obstacle set "
                     f"(KD-tree) {_s(figures['obstacle_set_s'])}"])
    if 'algorithms' in figures:
        for algorithm, row in figures['algorithms'].items():
            rows.append([f'{algorithm} ({row["status"]})',
                         f"smoothing + timing {_s(row['smoothing_s'])}, search "
                         f"{_s(row['search_s'])}, end to end {_s(row['end_to_end_s'])}"])
    rows.append(['peak RSS', f"{figures['peak_rss_mb']:.0f} MB (before the timed work "
                 f"{figures['rss_before_mb']:.0f} MB); kernel load "
                 f"{_s(figures['kernel_load_s'])}"])
    return rows


def print_report(results: List[Dict[str, Any]]) -> None:
    """One block per case: its figures, then the target."""
    by_name = {r['case']: r for r in results}
    for figures in results:
        print(f"\n{figures['case']}" + (' (quick)' if figures.get('quick') else ''))
        for label, value in describe(figures):
            print(f'  {label:<34} {value}')
        if figures['case'] == 'wall_gap_3.0' and 'wall_gap_0.2' in by_name:
            low = by_name['wall_gap_0.2']
            if 'error' not in low and 'error' not in figures:
                print(f"  {'peak RSS over gamma 0.2':<34} "
                      f"{figures['peak_rss_mb'] - low['peak_rss_mb']:+.0f} MB")
        print(f"  {'target':<34} {figures['target']}")


def main(argv: Optional[List[str]] = None) -> int:
    """Run the selected cases, each in its own process, and print the figures; the exit code
    (0 every case measured, 1 a case failed, 2 unknown case or option).

    This is the ``outdoor`` entry point of ``uav-plan bench``
    (:data:`uav_global_planner.cli.bench.BENCH_ENTRY_POINTS`).
    """
    parser = argparse.ArgumentParser(prog='uav-plan bench --outdoor',
                                     description=__doc__.splitlines()[0])
    parser.add_argument('--only', action='append', default=[], metavar='NAME',
                        help='case name or prefix (repeatable, or comma-separated)')
    parser.add_argument('--json', action='store_true', help='print one JSON document')
    parser.add_argument('--search-only', action='store_true',
                        help='grid build and search only for the planner cases')
    parser.add_argument('--quick', action='store_true',
                        help='shortened cases for smoke tests (see the module docstring)')
    parser.add_argument('--case', help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.case:
        print(json.dumps(run_case(args.case, args.search_only, args.quick)))
        return 0
    names = list(cases(args.search_only, args.quick))
    if args.quick:
        names = [n for n in names if n in QUICK_CASES]
    wanted = [w for item in args.only for w in item.split(',') if w]
    if wanted:
        unknown = [w for w in wanted if not any(n.startswith(w) for n in names)]
        if unknown:
            parser.error(f'unknown case(s) {", ".join(unknown)}; cases: {", ".join(names)}')
        names = [n for n in names if any(n.startswith(w) for w in wanted)]
    results = [_run_in_subprocess(name, args.search_only, args.quick) for name in names]
    machine = {'cpus': os.cpu_count(), 'load_average': os.getloadavg()[0]}
    if args.json:
        print(json.dumps({'machine': machine, 'cases': results}))
    else:
        print(f"{machine['cpus']} CPUs, load average {machine['load_average']:.2f}")
        print_report(results)
    return 1 if any('error' in r for r in results) else 0


if __name__ == '__main__':
    sys.exit(main())
