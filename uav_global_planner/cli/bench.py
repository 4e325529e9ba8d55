"""``uav-plan bench``: the performance figures of every shipped scene and algorithm.

Each scene runs in a fresh process, so the peak resident memory reported is that scene's own
(grid, inflation, search workspace, smoothing), as it would be in the planner node. With
``--ros``, the ROS-side figures follow: goal-to-plan latency over DDS, node start-up and the
node's peak memory, from the function registered as ``ros`` in the entry-point group
:data:`BENCH_ENTRY_POINTS` (the ROS latency benchmark of ``uav_global_planner_tools`` registers
itself there; this module imports neither it nor rclpy, so the tool works without ROS). With
``--outdoor``, the per-stage figures of the outdoor scenes (town400, city1km, wall_gap, the town
as a point cloud, a 99 M-node search grid) come instead from the function registered as
``outdoor`` in the same group (the outdoor benchmark of ``uav_global_planner_tools``); scene
names given then select its cases. Figures only: nothing here asserts a speed.
"""

import argparse
from importlib import metadata
import json
import resource
import statistics
import subprocess
import sys
import time
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

from uav_global_planner.cli.options import HelpFormatter
from uav_global_planner.cli.report import finite_or_none, format_table
from uav_global_planner.core.config import ALGORITHMS
from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.core.io.scene import find_scene, load_scene, shipped_scenes
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask
from uav_global_planner.core.planner import Planner

_EXIT_CODES = ('exit codes:\n'
               '  0  the figures were printed\n'
               '  1  a benchmark failed, or the one asked for is not installed\n'
               '  2  invalid options or unknown outdoor case')

# Repeat each measurement until this much time was spent on it [s] (at least 3, at most 50 runs).
_TIME_PER_FIGURE_S = 2.0

# Shipped scenes measured by --outdoor (per stage, one algorithm or two), not by the table of
# every algorithm: Dijkstra alone would take minutes on them.
_OUTDOOR_SCENES = ('town400', 'city1km', 'wall_gap')


def _median_runs(run: Callable[[], Any], budget_s: float = _TIME_PER_FIGURE_S,
                 most: int = 50) -> List[Any]:
    results: List[Any] = []
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


def print_report(scenes: List[Dict[str, Any]], out=None) -> None:
    """Human-readable tables, one per scene, on ``out`` (default: the current sys.stdout)."""
    out = sys.stdout if out is None else out
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


#: Entry-point group of the figures other packages add to ``uav-plan bench``: ``ros`` is a
#: callable taking the ROS benchmark's arguments and returning (JSON document, text report).
BENCH_ENTRY_POINTS = 'uav_global_planner.bench'


def _registered(name: str) -> Any:
    """The function registered as ``name`` in :data:`BENCH_ENTRY_POINTS`.

    Raises
    ------
    RuntimeError
        When no installed package registers it.
    """
    found = [entry for entry in metadata.entry_points(group=BENCH_ENTRY_POINTS)
             if entry.name == name]
    if not found:
        raise RuntimeError(f'no {name} benchmark installed (entry point "{name}" in '
                           f'{BENCH_ENTRY_POINTS}; pip install the package with its tools)')
    return found[0].load()


def measure_ros(options: Sequence[str] = ()) -> Tuple[Dict[str, Any], str]:
    """The ROS-side figures and their tables, from the registered ``ros`` benchmark.

    Parameters
    ----------
    options : sequence of str
        Arguments of the benchmark, for example ``['--goals', '20']``.

    Raises
    ------
    RuntimeError
        When no ROS benchmark is installed, or it fails (ROS missing, the node not answering).
    """
    return _registered('ros')(list(options))


def run_outdoor(cases: Sequence[str], as_json: bool) -> int:
    """Run the registered outdoor benchmark (its output printed as it comes); its exit code.

    Parameters
    ----------
    cases : sequence of str
        Case names or prefixes (``--only``); all cases when empty.
    as_json : bool
        Ask for one JSON document.
    """
    try:
        outdoor = _registered('outdoor')
    except RuntimeError as error:
        print(f'uav-plan bench: {error}', file=sys.stderr)
        return 1
    try:
        return int(outdoor([f'--only={name}' for name in cases]
                           + (['--json'] if as_json else [])))
    except SystemExit as stop:  # its argparse refusing a case: exit code 2, reason printed
        return stop.code if isinstance(stop.code, int) else 2


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of ``uav-plan bench`` (and of the per-scene worker processes)."""
    parser = argparse.ArgumentParser(prog='uav-plan bench', description=__doc__.splitlines()[0],
                                     formatter_class=HelpFormatter, epilog=_EXIT_CODES)
    parser.add_argument('scenes', nargs='*', help='scene names or files (default: all shipped)')
    parser.add_argument('--json', action='store_true', help='print one JSON document')
    parser.add_argument('--ros', action='store_true',
                        help='also measure planner_node over ROS 2: goal-to-plan latency on '
                             'the paper scenes, start-up time, peak memory on dense60_fine')
    parser.add_argument('--ros-goals', type=int, default=50, metavar='N',
                        help='goals per scene of the ROS latency figures (default 50)')
    parser.add_argument('--outdoor', action='store_true',
                        help='per-stage figures of the outdoor scenes instead (town400, '
                             'city1km, wall_gap, the town as a point cloud, a 99 M-node search '
                             'grid; scenes given select its cases)')
    parser.add_argument('--one-scene', help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.one_scene:
        print(json.dumps(measure_scene(args.one_scene)))
        return 0
    if args.outdoor:
        return run_outdoor(args.scenes, args.json)
    if args.ros_goals < 1:
        parser.error(f'argument --ros-goals: must be >= 1, got {args.ros_goals}')
    names = args.scenes or [path.stem for path in shipped_scenes()
                            if path.stem not in _OUTDOOR_SCENES]
    for name in names:
        try:
            find_scene(name)
        except InvalidInputError as error:
            parser.error(str(error))
    figures = [_measure_in_subprocess(name) for name in names]
    if not args.json:
        print_report(figures)
    ros = None
    if args.ros:
        try:
            ros, ros_report = measure_ros(['--goals', str(args.ros_goals)])
        except RuntimeError as error:
            print(f'uav-plan bench: {error}', file=sys.stderr)
            return 1
        if not args.json:
            print()
            print(ros_report)
    if args.json:
        document: Dict[str, Any] = {'scenes': figures}
        if ros is not None:
            document['ros'] = ros
        print(json.dumps(document))
    return 0


if __name__ == '__main__':
    sys.exit(main())
