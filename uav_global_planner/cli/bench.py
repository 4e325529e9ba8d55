"""``uav-plan bench``: the performance figures of every shipped scene and algorithm.

Each scene runs in a fresh process, so the peak resident memory reported is that scene's own
(grid, inflation, search workspace, smoothing), as it would be in the planner node. Figures only:
nothing here asserts a speed.
"""

import argparse
import json
import resource
import statistics
import subprocess
import sys
import time
from typing import Any, Dict, List, Optional

from uav_global_planner.cli.report import finite_or_none, format_table
from uav_global_planner.core.config import ALGORITHMS
from uav_global_planner.core.grid import VoxelGrid
from uav_global_planner.core.inflation import blocked_mask
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.scene import find_scene, load_scene, shipped_scenes

# Repeat each measurement until this much time was spent on it [s] (at least 3, at most 50 runs).
_TIME_PER_FIGURE_S = 2.0


def _median_runs(run, budget_s: float = _TIME_PER_FIGURE_S, most: int = 50) -> List[Any]:
    results = []
    started = time.perf_counter()
    while len(results) < 3 or (
            len(results) < most and time.perf_counter() - started < budget_s):
        results.append(run())
    return results


def measure_scene(name: str) -> Dict[str, Any]:
    """Every figure of one scene, measured in this process.

    Returns
    -------
    dict
        ``scene``, ``voxels``, ``grid_build_s`` (median of grid + inflation builds),
        ``peak_rss_mb`` and ``rows`` (one dict per algorithm).
    """
    scene = load_scene(find_scene(name))
    config = scene.config
    grid = VoxelGrid.from_bounds(config.bounds_min, config.bounds_max, config.resolution,
                                 config.max_voxels)
    builds = [time.perf_counter()]
    for _ in range(3):
        blocked_mask(grid, scene.obstacles, config.safety_margin)
        builds.append(time.perf_counter())
    build_s = statistics.median(b - a for a, b in zip(builds, builds[1:]))

    planner = Planner(config, scene.obstacles)
    planner.warm_up()
    rows = []
    for algorithm in ALGORITHMS:
        runs = _median_runs(lambda: planner.plan(scene.start, scene.goal, algorithm))
        last = runs[-1]
        search_s = statistics.median(r.planning_time_s for r in runs)
        rows.append({
            'algorithm': algorithm, 'status': last.status.value, 'runs': len(runs),
            'median_search_s': search_s, 'expanded_nodes': last.expanded_nodes,
            'expansions_per_s': last.expanded_nodes / search_s if search_s > 0 else None,
            'path_length_m': finite_or_none(last.path_length_m),
            'median_smoothing_s': statistics.median(r.smoothing_time_s for r in runs),
            'smoothed_length_m': finite_or_none(last.smoothed_length_m),
            'min_clearance_m': finite_or_none(last.min_clearance_m),
        })
    optimum = min((r['path_length_m'] for r in rows
                   if r['algorithm'] != 'adaptive' and r['path_length_m'] is not None),
                  default=None)
    for row in rows:
        length = row['path_length_m']
        row['relative_to_optimum'] = (length / optimum if optimum and length is not None
                                      else None)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return {'scene': scene.name, 'voxels': grid.size, 'shape': list(grid.shape),
            'grid_build_s': build_s, 'peak_rss_mb': peak_mb, 'rows': rows}


def _measure_in_subprocess(name: str) -> Dict[str, Any]:
    run = subprocess.run([sys.executable, '-m', 'uav_global_planner.cli.bench', '--one-scene',
                          name], capture_output=True, text=True, check=False)
    if run.returncode != 0:
        raise RuntimeError(f'benchmark of {name} failed:\n{run.stderr}')
    return json.loads(run.stdout)


def print_report(scenes: List[Dict[str, Any]], out=sys.stdout) -> None:
    """Human-readable tables, one per scene."""
    for figures in scenes:
        shape = ' x '.join(str(n) for n in figures['shape'])
        print(f"\n{figures['scene']}: {shape} = {figures['voxels'] / 1e6:.2f} M voxels, grid "
              f"build with inflation {figures['grid_build_s'] * 1e3:.1f} ms, peak RSS "
              f"{figures['peak_rss_mb']:.0f} MB", file=out)
        print(format_table(
            ['algorithm', 'search [ms]', 'expanded', 'expansions/s', 'length [m]',
             'vs optimum', 'smoothing [ms]', 'runs'],
            [[r['algorithm'], f"{r['median_search_s'] * 1e3:.3f}", str(r['expanded_nodes']),
              f"{r['expansions_per_s']:.3g}" if r['expansions_per_s'] else '-',
              f"{r['path_length_m']:.3f}" if r['path_length_m'] is not None else '-',
              f"{(r['relative_to_optimum'] - 1) * 100:+.2f} %"
              if r['relative_to_optimum'] else '-',
              f"{r['median_smoothing_s'] * 1e3:.2f}", str(r['runs'])]
             for r in figures['rows']]), file=out)


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of ``uav-plan bench`` (and of the per-scene worker processes)."""
    parser = argparse.ArgumentParser(prog='uav-plan bench', description=__doc__.splitlines()[0])
    parser.add_argument('scenes', nargs='*', help='scene names or files (default: all shipped)')
    parser.add_argument('--json', action='store_true', help='print one JSON document')
    parser.add_argument('--one-scene', help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.one_scene:
        print(json.dumps(measure_scene(args.one_scene)))
        return 0
    names = args.scenes or [path.stem for path in shipped_scenes()]
    figures = [_measure_in_subprocess(name) for name in names]
    if args.json:
        print(json.dumps({'scenes': figures}))
    else:
        print_report(figures)
    return 0


if __name__ == '__main__':
    sys.exit(main())
