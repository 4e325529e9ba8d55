"""Prints the cost of airspace zones in planning time, and flight time and energy by climb weight.

Run inside the project's environment::

    source scripts/venv.sh && python benchmarks/bench_airspace.py [--zones 0,10,100] [--json]

Two tables:

* ``town400`` (13 M voxels, 400 buildings, a corner-to-corner crossing) with 0, 10 and 100
  exclusion zones (prisms and cylinders, half of them full height, drawn with a fixed seed away
  from the start and goal) inside a concave inclusion fence (none for 0 zones): grid build with
  inflation, search, smoothing with its certified clearance check, and the whole plan, for the
  ``adaptive`` and ``weighted`` searches (``octile`` on town400 takes over a second without
  zones, see the README). The grid build is timed on a fresh planner, the rest as the median of
  later plans on the built grid.
* The paper scenes (``paper_medium``, ``paper_high``) planned with ``octile``, and town400 with
  ``weighted``, at climb weight 1 and 3: path length, search cost, climb, flight time and the
  energy of the point-mass model (:mod:`uav_global_planner.core.path.energy`, the default vehicle:
  1.5 kg, 180 W).

Figures only: nothing here asserts a speed.
"""

import argparse
from dataclasses import replace
import json
import statistics
import time
from typing import Any, Dict, List

import numpy as np

from uav_global_planner.core.io.scene import find_scene, load_scene, Scene
from uav_global_planner.core.map.airspace import Airspace
from uav_global_planner.core.map.zones import Cylinder, InclusionFence, Prism
from uav_global_planner.core.path.energy import estimate_energy
from uav_global_planner.core.planner import Planner

# Later plans on a built grid are repeated until this much time was spent [s] (3 to 20 runs).
REPEAT_BUDGET_S = 3.0
ALGORITHMS = ('adaptive', 'weighted')


def town_airspace(scene: Scene, count: int, seed: int = 13) -> Airspace:
    """``count`` zones over the town and a concave fence, keeping the endpoints clear."""
    if count == 0:
        return Airspace()
    rng = np.random.default_rng(seed)
    lo = np.asarray(scene.config.bounds_min)
    hi = np.asarray(scene.config.bounds_max)
    # A fence a little inside the bounds with a notch cut into its east side.
    fence = InclusionFence([[lo[0] + 1, lo[1] + 1], [hi[0] - 1, lo[1] + 1],
                            [hi[0] - 1, -20.0], [20.0, 0.0], [hi[0] - 1, 20.0],
                            [hi[0] - 1, hi[1] - 1], [lo[0] + 1, hi[1] - 1]], 0.0, hi[2] - 2.0)
    zones: List[Any] = []
    ends = np.stack([scene.start[:2], scene.goal[:2]])
    while len(zones) < count:
        center = rng.uniform(lo[:2] + 10.0, hi[:2] - 10.0)
        size = float(rng.uniform(2.0, 8.0))
        if np.min(np.linalg.norm(ends - center, axis=1)) < size + 6.0:
            continue
        ceiling = float(hi[2] + 10.0) if len(zones) % 2 else float(rng.uniform(10.0, 30.0))
        if len(zones) % 3:
            zones.append(Cylinder(center, size, -1.0, ceiling))
        else:
            angles = (np.arange(6) + rng.uniform(0.0, 0.4, 6)) * (np.pi / 3.0)
            radii = size * rng.uniform(0.5, 1.0, 6)
            polygon = center + np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])
            zones.append(Prism(polygon, -1.0, ceiling))
    return Airspace((fence,), tuple(zones))


def measure_town(counts: List[int]) -> List[Dict[str, Any]]:
    scene = load_scene(find_scene('town400'))
    rows = []
    for count in counts:
        airspace = town_airspace(scene, count)
        obstacles = airspace.with_obstacles(scene.obstacles)
        for algorithm in ALGORITHMS:
            config = replace(scene.config, algorithm=algorithm, max_planning_time=0.0)
            planner = Planner(config, obstacles)
            began = time.perf_counter()
            first = planner.plan(scene.start, scene.goal)
            first_s = time.perf_counter() - began
            if not first.ok:
                rows.append({'zones': count, 'algorithm': algorithm, 'status': first.status.value,
                             'message': first.message})
                continue
            totals, searches, smoothings = [], [], []
            spent = 0.0
            while (spent < REPEAT_BUDGET_S and len(totals) < 20) or len(totals) < 3:
                began = time.perf_counter()
                result = planner.plan(scene.start, scene.goal)
                totals.append(time.perf_counter() - began)
                searches.append(result.planning_time_s)
                smoothings.append(result.smoothing_time_s)
                spent += totals[-1]
            rows.append({
                'zones': count, 'algorithm': algorithm, 'status': 'ok',
                'grid_build_s': first.grid_build_time_s, 'first_plan_s': first_s,
                'search_s': statistics.median(searches),
                'smoothing_s': statistics.median(smoothings),
                'plan_s': statistics.median(totals), 'runs': len(totals),
                'expanded': first.expanded_nodes, 'length_m': first.path_length_m,
                'smoothed_m': first.smoothed_length_m, 'min_clearance_m': first.min_clearance_m,
            })
    return rows


def measure_energy() -> List[Dict[str, Any]]:
    rows = []
    for name, algorithm in (('paper_medium', 'octile'), ('paper_high', 'octile'),
                            ('town400', 'weighted')):
        scene = load_scene(find_scene(name))
        for climb in (1.0, 3.0):
            config = replace(scene.config, algorithm=algorithm, climb_weight=climb,
                             max_planning_time=0.0)
            result = Planner(config, scene.obstacles).plan(scene.start, scene.goal)
            energy = estimate_energy(result.trajectory, scene.vehicle)
            path = result.path
            rows.append({
                'scene': name, 'algorithm': algorithm, 'climb_weight': climb,
                'length_m': result.path_length_m,
                'cost_m': result.cost,
                'path_climb_m': float(np.sum(np.maximum(np.diff(path[:, 2]), 0.0))),
                'smoothed_m': result.smoothed_length_m, 'climb_m': energy.climb_m,
                'flight_time_s': energy.flight_time_s, 'energy_j': energy.energy_j,
                'energy_wh': energy.energy_wh, 'climb_energy_j': energy.climb_energy_j,
            })
    return rows


def main() -> None:
    """Run both measurements and print them."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--zones', default='0,10,100',
                        help='zone counts on town400, comma-separated (default 0,10,100)')
    parser.add_argument('--json', action='store_true', help='one JSON object instead of tables')
    args = parser.parse_args()
    counts = [int(part) for part in args.zones.split(',') if part.strip()]
    # Compile the kernels first, so that no figure includes it.
    warm = load_scene(find_scene('paper_medium'))
    Planner(warm.config, Airspace((), (Cylinder([5.0, 0.0], 1.0),)).with_obstacles(
        warm.obstacles)).plan(warm.start, warm.goal)
    town = measure_town(counts)
    energy = measure_energy()
    if args.json:
        print(json.dumps({'town400': town, 'energy': energy}, indent=2))
        return
    print('town400 with exclusion zones (medians; grid build on a fresh planner)')
    print(f'{"zones":>5}  {"algorithm":9}  {"grid [s]":>8}  {"search [ms]":>11}  '
          f'{"smoothing [ms]":>14}  {"plan [ms]":>9}  {"expanded":>8}  {"length [m]":>10}  '
          f'{"clearance [m]":>13}')
    for row in town:
        if row['status'] != 'ok':
            print(f'{row["zones"]:5d}  {row["algorithm"]:9}  {row["status"]}: {row["message"]}')
            continue
        print(f'{row["zones"]:5d}  {row["algorithm"]:9}  {row["grid_build_s"]:8.2f}  '
              f'{row["search_s"] * 1e3:11.1f}  {row["smoothing_s"] * 1e3:14.1f}  '
              f'{row["plan_s"] * 1e3:9.1f}  {row["expanded"]:8d}  {row["length_m"]:10.2f}  '
              f'{row["min_clearance_m"]:13.3f}')
    print()
    print('flight time and energy by climb weight (1.5 kg, 180 W)')
    print(f'{"scene":12}  {"algorithm":9}  {"w_climb":>7}  {"length [m]":>10}  {"cost [m]":>8}  '
          f'{"grid climb [m]":>14}  {"flown climb [m]":>15}  {"time [s]":>8}  '
          f'{"energy [kJ]":>11}  {"of it climb [J]":>15}')
    for row in energy:
        print(f'{row["scene"]:12}  {row["algorithm"]:9}  {row["climb_weight"]:7.1f}  '
              f'{row["length_m"]:10.3f}  {row["cost_m"]:8.3f}  {row["path_climb_m"]:14.2f}  '
              f'{row["climb_m"]:15.2f}  {row["flight_time_s"]:8.2f}  '
              f'{row["energy_j"] / 1e3:11.3f}  {row["climb_energy_j"]:15.1f}')


if __name__ == '__main__':
    main()
