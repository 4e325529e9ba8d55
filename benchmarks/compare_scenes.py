"""Prints the paper's comparison (median search time, length, expansions) on every shipped scene.

Run inside the project's environment::

    source scripts/venv.sh && python benchmarks/compare_scenes.py [--repeats N]

Figures only: no assertion on speed (speed targets live here, not in the tests).
"""

import argparse
import time

from uav_global_planner.cli.compare import compare_algorithms
from uav_global_planner.cli.report import format_table
from uav_global_planner.core.io.scene import load_scene, shipped_scenes


def main() -> None:
    """Compare every algorithm on every shipped scene and print one table per scene."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeats', type=int, default=5)
    args = parser.parse_args()
    for path in shipped_scenes():
        scene = load_scene(path)
        started = time.perf_counter()
        rows = compare_algorithms(scene, repeats=args.repeats)
        elapsed = time.perf_counter() - started
        shape = rows[0].result
        print(f'\n{scene.name}: {len(scene.obstacles)} obstacles, delta {shape.resolution} m '
              f'({elapsed:.1f} s for the whole comparison)')
        print(format_table(
            ['algorithm', 'median search [ms]', 'length [m]', 'vs optimum', 'expanded',
             'expansions/s', 'smoothed [m]', 'clearance [m]'],
            [[row.algorithm, f'{row.median_time_s * 1e3:.3f}',
              f'{row.result.path_length_m:.3f}', f'{(row.relative_cost - 1) * 100:+.2f} %',
              str(row.result.expanded_nodes),
              f'{row.result.expanded_nodes / max(row.median_time_s, 1e-9):.3g}',
              f'{row.result.smoothed_length_m:.3f}', f'{row.result.min_clearance_m:.3f}']
             for row in rows]))


if __name__ == '__main__':
    main()
