"""Prints how much of a path each ``unknown_space`` policy flies through space the map never saw.

Run inside the project's environment (octomap-python, the ``maps`` extra, is needed)::

    source scripts/venv.sh && python benchmarks/bench_unknown_space.py [--map FILE.bt] [--json]

For each policy, ``occupied`` (the default), ``cost`` at three rates of ``unknown_cost`` and
``free``, one plan (octile search) between the same two observed points, and its figures:
whether a path was found, the searched grid path's length, the smoothed curve's length, its
length in unknown space (``PlanResult.unknown_length_m``) and that length's share of the
curve, and the plan time (grid build included). Figures only: nothing here asserts a speed.

Scans
-----
synthetic
    Always run. An outdoor scan built here with the OctoMap bindings (0.2 m cells): a street
    block of 80 x 60 m with nine buildings 6-16 m high on a flat ground, scanned by a
    car-mounted 32-beam LiDAR (1.8 m above the ground, elevations -25 to +15 degrees, 40 m
    range) from stops along an L-shaped street, each stop a ray cast against the ground and the
    buildings inserted with ``insertPointCloud``. Behind the facades, above the roofs and beyond
    the range nothing was observed (nor the cone right above each stop). The plan runs from
    one end of the street to the other, 2.5 m above the ground, across the corner block.
``--map FILE.bt``
    A real OctoMap scan as well. For example ``f.bt`` of the vox_nav project, an outdoor map
    built from an RGB-D SLAM map of its field robot (50 x 56 x 9.5 m at 0.1 m, 25 697
    occupied and 345 955 free leaves, 264 kB; not part of this repository)::

        commit=https://github.com/NMBURobotics/vox_nav/raw/deff3d927054fb88390ad8b72b56aa0bb1eaf315
        curl -LO $commit/botanbot_bringup/maps/f.bt
        python benchmarks/bench_unknown_space.py --map f.bt

    The bounds are the scan's extent; the map is loaded as the command line loads ``--map``
    (the occupied leaf centres, gamma grown by the file's margin, and the unknown space of
    :mod:`uav_global_planner.core.map.unknown_space`). Unless ``--start`` and ``--goal`` are given,
    the ends are two observed free points far apart, gamma (plus the half diagonal of a grid
    cell) from the occupied cells, and as much from anything not observed free where the scan
    has such room (:func:`observed_ends`); the room they have is printed. A scan whose
    observed free space is thinner than gamma (a ground robot's RGB-D scan sees a thin shell
    of free space) leaves the occupied policy no admissible start: it refuses, and the figures
    of the other policies show what flying through unknown space would take.
"""

import argparse
from dataclasses import dataclass
import json
import math
from pathlib import Path
import sys
import tempfile
import time
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from uav_global_planner.core.config import PlannerConfig, validate_config
from uav_global_planner.core.io.mapfiles import load_map_points
from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.map.unknown_space import read_octree, unknown_from_map_files
from uav_global_planner.core.planner import Planner

ALGORITHM = 'octile'
#: The policies compared: (unknown_space, unknown_cost [per metre]).
POLICIES = (('occupied', 0.0), ('cost', 0.1), ('cost', 1.0), ('cost', 10.0),
            ('free', 0.0))

# The synthetic street block (map frame, ENU) [m].
BLOCK = ((0.0, 0.0, 0.0), (80.0, 60.0, 20.0))
SCAN_RESOLUTION = 0.2
SENSOR_HEIGHT = 1.8
LIDAR_RANGE = 40.0
#: Buildings: (x0, y0, x1, y1, height) [m].
BUILDINGS = ((5.0, 5.0, 20.0, 18.0, 12.0), (25.0, 4.0, 38.0, 18.0, 8.0),
             (43.0, 6.0, 55.0, 18.0, 16.0), (5.0, 32.0, 18.0, 45.0, 10.0),
             (22.0, 30.0, 36.0, 44.0, 14.0), (40.0, 31.0, 55.0, 45.0, 6.0),
             (5.0, 49.0, 20.0, 58.0, 9.0), (24.0, 50.0, 40.0, 58.0, 12.0),
             (68.0, 5.0, 78.0, 20.0, 11.0))
#: LiDAR stops: along the street y = 25 and up the side street x = 62.
STOPS = tuple([(x, 25.0) for x in np.arange(2.0, 63.0, 6.0)]
              + [(62.0, y) for y in np.arange(31.0, 59.0, 6.0)])
SYNTHETIC_START = (5.0, 25.0, 2.5)
SYNTHETIC_GOAL = (62.0, 52.0, 2.5)
#: Choosing the ends on a real scan: the most raster cells, and the shortest span of the
#: observed free region they come from [m].
MAX_CELLS = 50_000_000
MIN_SPAN = 10.0


@dataclass(frozen=True)
class Case:
    """One scan and the plans' settings."""

    name: str
    map_file: Path
    bounds: Tuple[np.ndarray, np.ndarray]
    resolution: float
    gamma: float
    start: Optional[np.ndarray] = None
    goal: Optional[np.ndarray] = None


# --------------------------------------------------------------------------------------------
# The synthetic scan
# --------------------------------------------------------------------------------------------

def _lidar_directions(azimuths: int = 720, beams: int = 32) -> np.ndarray:
    """Unit ray directions of one LiDAR sweep: ``beams`` elevations from -25 to +15 degrees."""
    azimuth = np.linspace(0.0, 2.0 * np.pi, azimuths, endpoint=False)
    elevation = np.radians(np.linspace(-25.0, 15.0, beams))
    a, e = np.meshgrid(azimuth, elevation, indexing='ij')
    return np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)],
                    axis=-1).reshape(-1, 3)


def _ray_hits(origin: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Distance along each ray to the ground (z = 0) or the nearest building [m]; inf when
    nothing is hit."""
    hit = np.full(len(directions), np.inf)
    down = directions[:, 2] < 0.0
    hit[down] = -origin[2] / directions[down, 2]
    with np.errstate(divide='ignore', invalid='ignore'):
        inverse = 1.0 / directions
    for x0, y0, x1, y1, height in BUILDINGS:
        lo = np.array([x0, y0, 0.0])
        hi = np.array([x1, y1, height])
        with np.errstate(invalid='ignore'):
            t_a = (lo - origin) * inverse
            t_b = (hi - origin) * inverse
        near = np.nanmax(np.minimum(t_a, t_b), axis=1)
        far = np.nanmin(np.maximum(t_a, t_b), axis=1)
        enters = (far >= near) & (far > 0.0)
        hit = np.where(enters, np.minimum(hit, np.maximum(near, 0.0)), hit)
    return hit


def write_synthetic_scan(file: Path) -> Dict[str, Any]:
    """Write the synthetic street scan (see the module notes) as an OctoMap ``.bt`` file."""
    import octomap
    tree = octomap.OcTree(SCAN_RESOLUTION)
    directions = _lidar_directions()
    rays = 0
    for x, y in STOPS:
        origin = np.array([x, y, SENSOR_HEIGHT])
        hit = _ray_hits(origin, directions)
        # Rays that hit nothing within the range end beyond it: the beam is free up to the
        # range and marks no obstacle.
        length = np.where(hit <= LIDAR_RANGE, hit, LIDAR_RANGE + 1.0)
        endpoints = origin + directions * length[:, None]
        tree.insertPointCloud(endpoints, origin, maxrange=LIDAR_RANGE)
        rays += len(endpoints)
    tree.updateInnerOccupancy()
    if not tree.writeBinary(str(file).encode()):
        raise RuntimeError(f'{file}: could not write the scan')
    return {'stops': len(STOPS), 'rays': rays, 'leaves': int(tree.getNumLeafNodes())}


# --------------------------------------------------------------------------------------------
# Ends of the plans on a real scan: observed free points far apart
# --------------------------------------------------------------------------------------------

def observed_ends(map_file: Path, bounds: Tuple[np.ndarray, np.ndarray],
                  clearance: float) -> Tuple[np.ndarray, np.ndarray, float]:
    """Two observed free points far apart, ``clearance`` [m] from the scan's occupied cells
    and the bounds, and as far from unobserved space as the scan allows, up to ``clearance``.

    The scan's leaves are rasterised on cells of the tree's resolution (coarser when the
    bounds would need more than :data:`MAX_CELLS`; a cell is free or occupied when its centre
    lies in such a leaf). Exact Euclidean distance transforms give each free cell its distance
    to the nearest occupied cell and its room, the distance to the nearest cell not observed
    free, each less one cell. Among the free cells clear of the occupied ones and the bounds,
    those with room >= ``clearance`` are split into 26-connected regions, and the ends are a
    far-apart pair of the largest (two farthest-point sweeps). A scan that has no such region
    at least :data:`MIN_SPAN` long (a thin shell of observed free space, as a ground robot's
    RGB-D scan has) gets the pair at the largest room that has one.

    Returns
    -------
    start, goal : numpy.ndarray, shape (3,)
        Cell centres [m].
    room : float
        The room both ends have [m].
    """
    from scipy import ndimage
    tree = read_octree(map_file)
    lo, hi = bounds
    cell = max(float(tree.getResolution()), (float(np.prod(hi - lo)) / MAX_CELLS) ** (1 / 3))
    shape = tuple(int(n) for n in np.ceil((hi - lo) / cell))
    free = np.zeros(shape, dtype=bool)
    occupied = np.zeros(shape, dtype=bool)
    for leaf in tree.begin_leafs():
        centre = np.array([leaf.getX(), leaf.getY(), leaf.getZ()])
        half = leaf.getSize() / 2.0
        first = np.maximum(np.ceil((centre - half - lo) / cell - 0.5), 0).astype(int)
        last = np.minimum(np.ceil((centre + half - lo) / cell - 0.5), shape).astype(int)
        if np.all(last > first):
            target = occupied if tree.isNodeOccupied(leaf) else free
            target[first[0]:last[0], first[1]:last[1], first[2]:last[2]] = True
    room = ndimage.distance_transform_edt(free) * cell - cell
    clear = ndimage.distance_transform_edt(~occupied) * cell - cell >= clearance
    centres = [lo[a] + (np.arange(shape[a]) + 0.5) * cell for a in range(3)]
    for axis, values in enumerate(centres):
        inside = (values - lo[axis] >= clearance) & (hi[axis] - values >= clearance)
        clear &= inside.reshape([-1 if a == axis else 1 for a in range(3)])
    free &= clear
    best = float(room[free].max()) if free.any() else 0.0
    for threshold in [clearance, *np.arange(np.floor(best / cell) * cell, -cell / 2, -cell)]:
        if threshold > clearance:
            continue
        labels, count = ndimage.label(free & (room >= threshold - 1e-9),
                                      structure=np.ones((3, 3, 3), dtype=bool))
        if count == 0:
            continue
        sizes = np.bincount(labels.ravel())[1:]
        points = lo + (np.argwhere(labels == 1 + int(np.argmax(sizes))) + 0.5) * cell
        first = points[np.argmax(np.linalg.norm(points - points.mean(axis=0), axis=1))]
        second = points[np.argmax(np.linalg.norm(points - first, axis=1))]
        first = points[np.argmax(np.linalg.norm(points - second, axis=1))]
        if np.linalg.norm(second - first) >= MIN_SPAN:
            return first, second, max(float(threshold), 0.0)
    raise SystemExit(f'{map_file}: no observed free region {MIN_SPAN:g} m long: give --start '
                     'and --goal')


# --------------------------------------------------------------------------------------------
# The plans
# --------------------------------------------------------------------------------------------

def run_case(case: Case) -> List[Dict[str, Any]]:
    """Load the scan as the command line loads ``--map`` and plan once per policy."""
    lo, hi = case.bounds
    began = time.perf_counter()
    config = PlannerConfig(bounds_min=tuple(lo), bounds_max=tuple(hi),
                           resolution=case.resolution, safety_margin=case.gamma,
                           adaptive_threshold=3.0 * case.resolution, algorithm=ALGORITHM,
                           max_planning_time=0.0)
    maps = load_map_points(case.map_file, bounds=(lo, hi), reach=case.gamma,
                           resolution=case.resolution)
    unknown = unknown_from_map_files([case.map_file], lo, hi)
    load_s = time.perf_counter() - began
    obstacles = ObstacleSet([maps.obstacle()])
    # gamma as asked plus the map's margin (the half diagonal of its cells), as --map does.
    gamma = case.gamma + maps.margin_m
    if case.start is None or case.goal is None:
        # The ends snap to grid nodes up to a half diagonal of delta away, which must be
        # clear as well.
        start, goal, room = observed_ends(case.map_file, case.bounds,
                                          gamma + case.resolution * math.sqrt(3.0) / 2.0)
    else:
        start, goal = case.start, case.goal
        room = float(np.min(unknown.distance(np.stack([start, goal])))) \
            if unknown is not None else float('inf')
    base = {'case': case.name, 'map': str(case.map_file), 'occupied_points': len(maps.points),
            'unknown_boxes': len(unknown) if unknown is not None else 0,
            'unknown_volume_share': (unknown.volume_m3 / float(np.prod(hi - lo))
                                     if unknown is not None else 0.0),
            'load_s': load_s, 'gamma_m': gamma, 'delta_m': case.resolution,
            'start': np.round(start, 3).tolist(), 'goal': np.round(goal, 3).tolist(),
            'ends_room_m': room,
            'straight_line_m': float(np.linalg.norm(goal - start))}
    rows = []
    for policy, cost in POLICIES:
        changes: Dict[str, Any] = {'safety_margin': gamma, 'unknown_space': policy}
        if policy == 'cost':
            changes['unknown_cost'] = cost
        planner = Planner(validate_config(config.with_changes(**changes)), obstacles,
                          unknown=unknown)
        began = time.perf_counter()
        result = planner.plan(start, goal, ALGORITHM)
        plan_s = time.perf_counter() - began
        length = result.smoothed_length_m
        inside = result.unknown_length_m
        rows.append({**base, 'policy': policy if policy != 'cost' else f'cost {cost:g}/m',
                     'status': result.status.value, 'found': result.ok,
                     'searched_length_m': result.path_length_m,
                     'smoothed_length_m': length, 'unknown_length_m': inside,
                     'unknown_share': inside / length if result.ok and length > 0 else None,
                     'plan_s': plan_s, 'message': '' if result.ok else result.message})
    return rows


def synthetic_case(folder: Path) -> Tuple[Case, Dict[str, Any]]:
    file = folder / 'street_scan.bt'
    scan = write_synthetic_scan(file)
    case = Case('synthetic street', file, (np.array(BLOCK[0]), np.array(BLOCK[1])),
                resolution=0.5, gamma=1.0, start=np.array(SYNTHETIC_START),
                goal=np.array(SYNTHETIC_GOAL))
    return case, scan


def map_case(file: Path, delta: float, gamma: float, start: Optional[Sequence[float]],
             goal: Optional[Sequence[float]]) -> Case:
    """A real scan: bounds from its extent, whole cells of delta."""
    tree = read_octree(file)
    lo = np.floor(np.array(tree.getMetricMin()) / delta) * delta
    hi = np.ceil(np.array(tree.getMetricMax()) / delta) * delta
    return Case(file.name, file, (lo, hi), resolution=delta, gamma=gamma,
                start=None if start is None else np.asarray(start, dtype=np.float64),
                goal=None if goal is None else np.asarray(goal, dtype=np.float64))


def _print(rows: List[Dict[str, Any]]) -> None:
    first = rows[0]
    print(f"\n{first['case']}: {first['map']}")
    print(f"  {first['occupied_points']} occupied cells, {first['unknown_boxes']} unknown boxes "
          f"({100.0 * first['unknown_volume_share']:.1f} % of the bounds), loaded in "
          f"{first['load_s']:.2f} s; delta {first['delta_m']:g} m, gamma {first['gamma_m']:.3f} "
          f"m (with the map's margin)")
    print(f"  start {first['start']}, goal {first['goal']}, straight line "
          f"{first['straight_line_m']:.1f} m, ends {first['ends_room_m']:.2f} m from unobserved "
          'space')
    print(f"  {'policy':<14}{'found':<7}{'status':<17}{'searched m':>11}{'length m':>10}"
          f"{'unknown m':>11}{'unknown %':>11}{'plan s':>9}")
    for row in rows:
        share = ('-' if row['unknown_share'] is None
                 else f"{100.0 * row['unknown_share']:.1f}")
        searched = '-' if not row['found'] else f"{row['searched_length_m']:.1f}"
        length = '-' if not row['found'] else f"{row['smoothed_length_m']:.1f}"
        unknown = '-' if not row['found'] else f"{row['unknown_length_m']:.1f}"
        print(f"  {row['policy']:<14}{'yes' if row['found'] else 'no':<7}{row['status']:<17}"
              f"{searched:>11}{length:>10}{unknown:>11}{share:>11}{row['plan_s']:>9.2f}")
        if row['message']:
            print(f"      {row['message'][:300]}")


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--map', type=Path, help='a real OctoMap .bt scan, planned as well')
    parser.add_argument('--resolution', type=float, default=0.25,
                        help='delta for the --map scan [m] (default 0.25)')
    parser.add_argument('--safety-margin', type=float, default=0.3,
                        help="gamma for the --map scan, before the map's margin [m] "
                             '(default 0.3)')
    parser.add_argument('--start', type=float, nargs=3, metavar=('X', 'Y', 'Z'),
                        help='start on the --map scan [m] (default: chosen, see the notes)')
    parser.add_argument('--goal', type=float, nargs=3, metavar=('X', 'Y', 'Z'),
                        help='goal on the --map scan [m]')
    parser.add_argument('--json', action='store_true', help='print the figures as JSON')
    args = parser.parse_args(argv)
    if (args.start is None) != (args.goal is None):
        parser.error('--start and --goal go together')
    if args.map is not None and args.map.suffix.lower() != '.bt':
        parser.error('--map: an OctoMap .bt file')
    rows: List[Dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as folder:
        case, scan = synthetic_case(Path(folder))
        synthetic = run_case(case)
        for row in synthetic:
            row.update(scan)
        rows += synthetic
        if not args.json:
            print(f"synthetic scan: {scan['stops']} LiDAR stops, {scan['rays']} rays, "
                  f"{scan['leaves']} leaves")
            _print(synthetic)
        if args.map is not None:
            real = run_case(map_case(args.map, args.resolution, args.safety_margin,
                                     args.start, args.goal))
            rows += real
            if not args.json:
                _print(real)
    if args.json:
        print(json.dumps(rows, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
