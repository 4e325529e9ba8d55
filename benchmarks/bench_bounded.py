"""Prints the certified bounded search (``bounded``) against octile, weighted and adaptive A* on
the search scene family (uav_global_planner_tools.search_scenes: 60 spheres + 20 boxes, 48 %
of the nodes blocked, start and goal 27.1 m apart).

Run inside the project's environment::

    source scripts/venv.sh && python benchmarks/bench_bounded.py [--sizes 6M,20M,100M]
        [--repeats 3] [--bound 1.05]

Only the search is timed (the mask is the planner's own, built first). Repetitions of the
algorithms are interleaved; each row gives the median time, the expansions, the cost, its
measured ratio to the octile optimum and, for ``bounded``, the proven ratio (cost / lower
bound, <= w) and what certified it. The load average is printed with every size.
"""

import argparse
import os
import time
from typing import Dict, List

import numpy as np

from uav_global_planner.core.search.bounded import bounded_search
from uav_global_planner.core.search.grid_search import SearchWorkspace
from uav_global_planner_tools.search_scenes import parse_sizes, search_scene


def main() -> None:
    """Time the algorithms at every size given."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--sizes', default='6M,20M,100M', help='sizes (6M, 20M, 100M, 1G)')
    parser.add_argument('--repeats', type=int, default=3, help='runs per algorithm')
    parser.add_argument('--bound', type=float, default=1.05, help='w of bounded and weighted')
    parser.add_argument('--algorithms', default='octile,weighted,adaptive,bounded')
    parser.add_argument('--no-warm', action='store_true',
                        help='skip the untimed first run of each algorithm (1G)')
    args = parser.parse_args()
    algorithms = args.algorithms.split(',')
    for size in parse_sizes(args.sizes):
        scene = search_scene(size)
        planner = scene.planner()
        started = time.perf_counter()
        blocked, grid = planner.blocked, planner.grid
        build_s = time.perf_counter() - started
        start, goal = grid.world_to_index(scene.start), grid.world_to_index(scene.goal)
        delta, eta = scene.config.resolution, scene.config.adaptive_threshold
        workspace = SearchWorkspace(blocked)

        def run(algorithm: str):
            if algorithm == 'bounded':
                return bounded_search(workspace, start, goal, delta, eta, args.bound)
            return workspace.search(start, goal, algorithm, delta, eta, weight=args.bound)

        for algorithm in ([] if args.no_warm else algorithms):  # kernels loaded, pages committed
            run(algorithm)
        run('adaptive')  # the kernel loaded
        times: Dict[str, List[float]] = {a: [] for a in algorithms}
        results = {}
        for _ in range(args.repeats):
            for algorithm in algorithms:
                began = time.perf_counter()
                results[algorithm] = run(algorithm)
                times[algorithm].append(time.perf_counter() - began)
        print(f'\n{scene.size}: {" x ".join(map(str, grid.shape))} = {grid.size / 1e6:.1f} M '
              f'nodes, mask {build_s:.1f} s, load average {os.getloadavg()[0]:.2f}')
        optimum = results['octile'].cost_m if 'octile' in results else float('nan')
        for algorithm in algorithms:
            found = results[algorithm]
            line = (f'  {algorithm:<9} {np.median(times[algorithm]) * 1e3:10.1f} ms '
                    f'{found.expanded_nodes:>11,} expanded  cost {found.cost_m:.4f} m  '
                    f'ratio {found.cost_m / optimum:.4f}')
            if algorithm == 'bounded':
                line += (f'  proven <= {found.certified_ratio:.4f} (w {found.bound}) by '
                         f'{found.phase}')
            elif algorithm == 'weighted':
                line += f'  proven <= {args.bound}'
            print(line, flush=True)


if __name__ == '__main__':
    main()
