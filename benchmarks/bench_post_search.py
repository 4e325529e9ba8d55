"""Prints the time of each stage of a plan after the search, on maps of 6 M to 1 G nodes.

Run inside the project's environment::

    source scripts/venv.sh && python benchmarks/bench_post_search.py [--nodes 6e6 20e6 100e6]
        [--repeats 5]

The scene: the 60 spheres of the shipped scene ``dense60_fine`` and 20 boxes (drawn with
``default_rng(7)``, kept clear of the endpoints) in its 20 x 20 x 15 m workspace, gamma 0.2 m,
a 30 m diagonal from (-9.5, -9.5, 0.5) to (9.5, 9.5, 14.5); delta is chosen for the number of
nodes asked for (about 46 % of them blocked). Each plan uses the ``adaptive`` search. The stages
of :meth:`Planner.plan` are timed by wrapping the functions it calls:

* ``search``: the grid search (``PlanResult.planning_time_s``);
* ``shortcut``: certified line-of-sight shortcutting of the node path;
* ``fit+certify``: the spline, its clearance certificate and its repairs;
* ``assemble``: output samples, arc lengths, the curve evaluator;
* ``timing``: the time parameterisation;
* ``post``: everything after the search (``smoothing_time_s``), and ``total``.

Repetitions of the node counts are interleaved (a plan per map per round) and medians are
printed, with the load average before and after: other processes on the machine change the
figures. A 1 G-node map takes about 1 GB for its mask and more for the search; ask for it only
with several GB free.
"""

import argparse
import functools
import os
import resource
import time
from typing import Callable, Dict, List

import numpy as np
import yaml

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, Sphere
import uav_global_planner.core.path.smoothing as smoothing
import uav_global_planner.core.planner as planner_module
from uav_global_planner.core.planner import Planner

SCENE = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'config', 'scenes',
                     'dense60_fine.yaml')
START = np.array([-9.5, -9.5, 0.5])
GOAL = np.array([9.5, 9.5, 14.5])
STAGES = ('search', 'shortcut', 'fit+certify', 'assemble', 'timing', 'post', 'total')


def build(nodes: float, seed: int = 7):
    """Settings and obstacles of the benchmark scene with about ``nodes`` grid nodes."""
    with open(SCENE, encoding='utf-8') as stream:
        data = yaml.safe_load(stream)
    lo = np.array(data['bounds']['min'], dtype=float)
    hi = np.array(data['bounds']['max'], dtype=float)
    shapes: list = [Sphere(o['center'], o['radius']) for o in data['obstacles']]
    rng = np.random.default_rng(seed)
    boxes: list = []
    while len(boxes) < 20:
        centre = lo + rng.random(3) * (hi - lo)
        size = rng.uniform(1.5, 4.5, 3)
        if any(np.all(np.abs(p - centre) < size / 2 + 1.0) for p in (START, GOAL)):
            continue
        boxes.append(Box(centre - size / 2, centre + size / 2))
    delta = float((np.prod(hi - lo) / nodes) ** (1.0 / 3.0))
    config = PlannerConfig(bounds_min=tuple(lo), bounds_max=tuple(hi), resolution=delta,
                           safety_margin=float(data['safety_margin']),
                           adaptive_threshold=float(data['adaptive_threshold']),
                           algorithm='adaptive', max_voxels=int(2e9), max_planning_time=0.0)
    return config, ObstacleSet(shapes + boxes)


class StageClock:
    """Wall time spent in wrapped functions, per stage, for the current plan [s]."""

    def __init__(self) -> None:
        self.spent: Dict[str, float] = {}

    def wrap(self, module, name: str, stage: str) -> None:
        original: Callable = getattr(module, name)

        @functools.wraps(original)
        def timed(*args, **kwargs):
            started = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                self.spent[stage] = self.spent.get(stage, 0.0) + time.perf_counter() - started

        setattr(module, name, timed)


def load_average() -> str:
    return ' '.join(f'{x:.2f}' for x in os.getloadavg())


def main() -> None:
    """Plan on each map size, interleaved, and print the median time of every stage."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--nodes', type=float, nargs='+', default=[6e6, 20e6, 100e6],
                        help='grid sizes [nodes]')
    parser.add_argument('--repeats', type=int, default=5, help='timed plans per map')
    args = parser.parse_args()

    clock = StageClock()
    clock.wrap(smoothing, 'shortcut_legs', 'shortcut')
    clock.wrap(smoothing, 'repair_curve', 'fit+certify')
    clock.wrap(smoothing, '_assemble', 'assemble')
    clock.wrap(planner_module, 'time_parameterize', 'timing')

    print(f'load average before: {load_average()}')
    planners = []
    for nodes in args.nodes:
        config, obstacles = build(nodes)
        planner = Planner(config, obstacles)
        started = time.perf_counter()
        result = planner.plan(START, GOAL)    # builds the grid, compiles, loads caches
        if not result.ok:
            raise SystemExit(f'{nodes:.0e} nodes: {result.message}')
        print(f'{nodes:.0e} nodes: delta {config.resolution * 1e3:.1f} mm, grid '
              f'{" x ".join(map(str, planner.grid.shape))}, first plan '
              f'{time.perf_counter() - started:.1f} s; {len(result.path)} path nodes, '
              f'{len(result.shortcut_path)} shortcut vertices, {len(result.repaired_stretches)}'
              f' repaired, min clearance {result.min_clearance_m:.4f} m')
        planners.append(planner)
    times: List[Dict[str, List[float]]] = [{stage: [] for stage in STAGES} for _ in planners]
    for _ in range(args.repeats):
        for planner, record in zip(planners, times):
            clock.spent = {}
            result = planner.plan(START, GOAL)
            assert result.ok and result.min_clearance_m >= planner.config.safety_margin
            for stage in STAGES[1:5]:
                record[stage].append(clock.spent.get(stage, 0.0))
            record['search'].append(result.planning_time_s)
            record['post'].append(result.smoothing_time_s)
            record['total'].append(result.total_time_s)
    print(f'load average after: {load_average()}')
    print(f'\nmedian of {args.repeats} plans [ms]')
    print(f'{"nodes":>7} ' + ' '.join(f'{stage:>11}' for stage in STAGES))
    for nodes, record in zip(args.nodes, times):
        print(f'{nodes:>7.0e} ' + ' '.join(f'{np.median(record[stage]) * 1e3:>11.1f}'
                                           for stage in STAGES))
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(f'\npeak RSS of the process: {peak_mb:.0f} MB')


if __name__ == '__main__':
    main()
