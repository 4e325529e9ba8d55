"""Prints the median grid-search time per algorithm on the shipped scenes, and the peak memory.

Run inside the project's environment::

    source scripts/venv.sh && python benchmarks/bench_search.py [--repeats N] [scene.yaml ...]

Only the search is timed (not inflation or smoothing). The first search of the process loads or
compiles the numba kernel; that warm-up is reported separately.

Scaling mode: ``--sizes 6M 20M 100M 1G`` times the search on the scene family of
``uav_global_planner_tools.search_scenes`` (the same cluttered workspace at each size; the
planner's own mask, dense below 16 M nodes, block-sparse above), for the algorithms of
``--algorithms`` (default dijkstra and octile). ``--against FILE`` also times another copy of
the search module (for instance grid_search.py of an earlier commit, saved outside the package,
with its own kernels), the two interleaved run by run, and prints the speed-up of the medians
and the load average::

    python benchmarks/bench_search.py --sizes 6M 20M --repeats 5 --against /tmp/old_search.py
"""

import argparse
import importlib.util
import os
from pathlib import Path
import resource
import sys
import time
from types import ModuleType
from typing import Dict, List, Optional, Union

import numpy as np
import yaml

from uav_global_planner.core.jit import JIT_ENABLED
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, PointSet, Sphere
from uav_global_planner.core.map.sparse_grid import SparseMask
from uav_global_planner.core.search import grid_search
from uav_global_planner.core.search.grid_search import ALGORITHM_CODES, search, SearchWorkspace
from uav_global_planner_tools.search_scenes import search_scene

SCENES = Path(__file__).resolve().parents[1] / 'config' / 'scenes'
# Stop repeating one algorithm once this much search time [s] was spent on it.
TIME_PER_ALGORITHM = 3.0


def load(path: Path):
    """Grid, inflated occupancy, start and goal nodes, delta and eta of a scene file."""
    data = yaml.safe_load(path.read_text(encoding='utf-8'))
    grid = VoxelGrid.from_bounds(data['bounds']['min'], data['bounds']['max'],
                                 data['resolution'])
    shapes: List[Union[Sphere, Box, PointSet]] = []
    for entry in data.get('obstacles') or []:
        if entry['type'] == 'sphere':
            shapes.append(Sphere(entry['center'], entry['radius']))
        elif entry['type'] == 'box':
            shapes.append(Box(entry['min'], entry['max']))
        else:
            shapes.append(PointSet(entry['points']))
    started = time.perf_counter()
    blocked = blocked_mask(grid, ObstacleSet(shapes), data['safety_margin'])
    inflation_s = time.perf_counter() - started
    return (grid, blocked, inflation_s, grid.world_to_index(data['start']),
            grid.world_to_index(data['goal']), data['resolution'], data['adaptive_threshold'])


def load_module(path: Path) -> ModuleType:
    """Import another copy of the search module from a file."""
    spec = importlib.util.spec_from_file_location(f'search_copy_{path.stem}', path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    # Registered first: numba's disk cache finds the module of a compiled function by name.
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def sized_scene(size: str):
    """Grid, mask, start, goal, delta and eta of the search scene of one size."""
    scene = search_scene(size)
    planner = scene.planner()
    grid = planner.grid
    return (grid, planner.blocked, grid.world_to_index(scene.start),
            grid.world_to_index(scene.goal), grid.resolution, scene.config.adaptive_threshold)


def scaling(sizes: List[str], algorithms: List[str], repeats: int,
            against: Optional[ModuleType]) -> None:
    """Median search times on the scaled scene, this module against ``against`` if given."""
    modules = [('this', grid_search)] + ([('other', against)] if against is not None else [])
    for module in (m for _, m in modules):
        module.search(np.zeros((2, 2, 2), dtype=bool), (0, 0, 0), (1, 1, 1), 'octile', 1.0, 1.0)
    for size in sizes:
        grid, blocked, start, goal, delta, eta = sized_scene(size)
        kind = 'block-sparse' if isinstance(blocked, SparseMask) else 'dense'
        print(f'\n{size}: {" x ".join(map(str, grid.shape))} = {grid.size / 1e6:.1f} M nodes '
              f'({kind} mask), load average {os.getloadavg()[0]:.2f}', flush=True)
        for algorithm in algorithms:
            times: Dict[str, List[float]] = {name: [] for name, _ in modules}
            outcome = {}
            for name, module in modules:
                # Warm the records of this workspace first (a first query commits its pages).
                workspace = module.SearchWorkspace(blocked)
                workspace.search(start, goal, algorithm, delta, eta)
                outcome[name] = workspace
            for _ in range(repeats):
                for name, module in modules:
                    result = outcome[name].search(start, goal, algorithm, delta, eta)
                    times[name].append(result.search_time_s)
                    print(f'  {algorithm:<9} {name:<6} cost {result.cost_m:.9f} m, '
                          f'{result.expanded_nodes:,} expanded, '
                          f'{result.search_time_s * 1e3:.0f} ms', flush=True)
            medians = {name: float(np.median(t)) for name, t in times.items()}
            line = ', '.join(f'{n} median {m * 1e3:.0f} ms' for n, m in medians.items())
            if against is not None:
                line += f'; speed-up {medians["other"] / medians["this"]:.2f}x'
            print(f'  {algorithm}: {line} (load average {os.getloadavg()[0]:.2f})')
            del outcome


def main() -> None:
    """Time every algorithm on every scene given (default: all shipped scenes)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeats', type=int, default=20, help='most runs per algorithm')
    parser.add_argument('--sizes', nargs='+', help='scaling mode: scene sizes (6M, 20M, ...)')
    parser.add_argument('--algorithms', nargs='+', default=['dijkstra', 'octile'],
                        choices=sorted(ALGORITHM_CODES), help='scaling mode: algorithms')
    parser.add_argument('--against', type=Path,
                        help='scaling mode: another copy of grid_search.py to time as well')
    parser.add_argument('scenes', nargs='*', type=Path, help='scene files')
    args = parser.parse_args()
    if args.sizes:
        against = load_module(args.against) if args.against else None
        scaling(args.sizes, args.algorithms, args.repeats, against)
        return

    started = time.perf_counter()
    search(np.zeros((2, 2, 2), dtype=bool), (0, 0, 0), (1, 1, 1), 'astar', 1.0, 1.0)
    print(f'JIT enabled: {JIT_ENABLED}; kernel load/compile '
          f'{time.perf_counter() - started:.2f} s')
    for path in args.scenes or sorted(SCENES.glob('*.yaml')):
        grid, blocked, inflation_s, start, goal, delta, eta = load(path)
        # A block-sparse mask (16 M nodes or more) counts its blocked nodes itself.
        count = (blocked.count_blocked() if isinstance(blocked, SparseMask)
                 else int(np.count_nonzero(blocked)))
        print(f'\n{path.stem}: {" x ".join(map(str, grid.shape))} = {grid.size:,} nodes, '
              f'{count / grid.size:.1%} blocked, inflation {inflation_s * 1e3:.0f} ms')
        print(f'  {"algorithm":<9} {"cost [m]":>9} {"expanded":>10} {"median [ms]":>12} '
              f'{"min [ms]":>10} {"runs":>5}')
        workspace = SearchWorkspace(blocked)
        for algorithm in ALGORITHM_CODES:
            times: List[float] = []
            while len(times) < args.repeats and sum(times) < TIME_PER_ALGORITHM:
                result = workspace.search(start, goal, algorithm, delta, eta)
                times.append(result.search_time_s)
            print(f'  {algorithm:<9} {result.cost_m:>9.3f} {result.expanded_nodes:>10,} '
                  f'{np.median(times) * 1e3:>12.3f} {min(times) * 1e3:>10.3f} {len(times):>5}')
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(f'\npeak RSS of the process: {peak_mb:.0f} MB')


if __name__ == '__main__':
    main()
