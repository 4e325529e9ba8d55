"""Prints the median grid-search time per algorithm on the shipped scenes, and the peak memory.

Run inside the project's environment::

    source scripts/venv.sh && python benchmarks/bench_search.py [--repeats N] [scene.yaml ...]

Only the search is timed (not inflation or smoothing). The first search of the process loads or
compiles the numba kernel; that warm-up is reported separately.
"""

import argparse
from pathlib import Path
import resource
import time

import numpy as np
import yaml

from uav_global_planner.core.jit import JIT_ENABLED
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, PointSet, Sphere
from uav_global_planner.core.map.sparse_grid import SparseMask
from uav_global_planner.core.search.grid_search import ALGORITHM_CODES, search, SearchWorkspace

SCENES = Path(__file__).resolve().parents[1] / 'config' / 'scenes'
# Stop repeating one algorithm once this much search time [s] was spent on it.
TIME_PER_ALGORITHM = 3.0


def load(path: Path):
    """Grid, inflated occupancy, start and goal nodes, delta and eta of a scene file."""
    data = yaml.safe_load(path.read_text(encoding='utf-8'))
    grid = VoxelGrid.from_bounds(data['bounds']['min'], data['bounds']['max'],
                                 data['resolution'])
    shapes = []
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


def main() -> None:
    """Time every algorithm on every scene given (default: all shipped scenes)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeats', type=int, default=20, help='most runs per algorithm')
    parser.add_argument('scenes', nargs='*', type=Path, help='scene files')
    args = parser.parse_args()

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
            times = []
            while len(times) < args.repeats and sum(times) < TIME_PER_ALGORITHM:
                result = workspace.search(start, goal, algorithm, delta, eta)
                times.append(result.search_time_s)
            print(f'  {algorithm:<9} {result.cost_m:>9.3f} {result.expanded_nodes:>10,} '
                  f'{np.median(times) * 1e3:>12.3f} {min(times) * 1e3:>10.3f} {len(times):>5}')
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(f'\npeak RSS of the process: {peak_mb:.0f} MB')


if __name__ == '__main__':
    main()
