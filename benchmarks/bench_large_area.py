"""Prints the figures of mission-sized grids: build time, a long crossing, memory, first queries.

Run inside the project's environment::

    source scripts/venv.sh && python benchmarks/bench_large_area.py [--only NAME] [--json]

Cases, each in a fresh process (its peak resident memory is its own, VmHWM of /proc):

=============  ==================================================================================
city           1 km x 1 km x 120 m at delta 0.5 m (2001 x 2001 x 241 = 965 M nodes), the 300
               buildings of ``city1km`` (tools: outdoor_scenes), gamma 1 m: grid ready
               (mask build and kernel warm-up), a 1.30 km crossing end to end with the default
               algorithm (first and second plan), peak RSS, bytes a node
voxel_map      a dense-occupancy voxel map of 406^3 = 66.9 M nodes at 1 m, generated here
               (blocks of occupied voxels strewn through the whole volume, one point per
               occupied voxel centre, gamma 1 m so that the face neighbours tie at exactly
               gamma), written as a .npy map file and read with ``load_map_points``: grid
               build and peak RSS; 5.8 % of the voxels occupied (3.9 M points)
voxel_map_18   the same with 18.2 % occupied (12.2 M points): the points, not the grid, then
               dominate the memory
first_query    the 99 M-node sphere-and-box grid (``spheres_boxes_100m``): the first search on
               a fresh grid against the same search repeated
layouts        town400 (13 M nodes) with either layout forced: mask build and search, which
               justifies the layout rule (dense below 16 M nodes)
=============  ==================================================================================

The targets printed beside the figures are the project's goals for mission-sized areas; figures
only, nothing here asserts a speed.
"""

import argparse
import json
import math
import os
from pathlib import Path
import resource
import subprocess
import sys
import tempfile
import time
from typing import Callable, Dict, List

import numpy as np

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.io.mapfiles import load_map_points
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.inflation import blocked_mask
from uav_global_planner.core.map.obstacles import Box, ObstacleSet, PointSet
from uav_global_planner.core.map.sparse_grid import SparseMask
from uav_global_planner.core.map.sparse_inflation import reinflate_sparse
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.search.grid_search import SearchWorkspace
from uav_global_planner_tools.outdoor_scenes import city1km_boxes, spheres_boxes_100m, town400


MB = 1e6


def peak_rss_mb() -> float:
    """Peak resident memory of this process [MB].

    From VmHWM of /proc (the peak of this program's own memory): ``getrusage`` keeps across
    ``exec`` the peak of the parent process this one was forked from.
    """
    try:
        with open('/proc/self/status') as handle:
            for line in handle:
                if line.startswith('VmHWM:'):
                    return int(line.split()[1]) * 1024 / MB
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / MB


def current_rss_mb() -> float:
    """Resident memory now [MB] (from /proc)."""
    with open('/proc/self/statm') as handle:
        return int(handle.read().split()[1]) * os.sysconf('SC_PAGE_SIZE') / MB


def _warm_kernels() -> None:
    """Load the compiled kernels on a tiny grid of each layout (numba's disk cache)."""
    grid = VoxelGrid.from_bounds([0, 0, 0], [4, 4, 4], 0.25)
    obstacles = ObstacleSet([Box(np.ones(3), np.full(3, 2.0)), PointSet(np.full((1, 3), 3.0))])
    for layout in ('dense', 'sparse'):
        mask = blocked_mask(grid, obstacles, 0.3, layout=layout)
        SearchWorkspace(mask).search((0, 0, 0), (16, 16, 16), 'adaptive', 0.25, 1.5)


def case_city() -> Dict[str, object]:
    started = time.perf_counter()
    _warm_kernels()
    kernels = time.perf_counter() - started
    base_rss = current_rss_mb()
    boxes = city1km_boxes()
    obstacles = ObstacleSet([Box(b[0], b[1]) for b in boxes])
    config = PlannerConfig(bounds_min=(-500.0, -500.0, 0.0), bounds_max=(500.0, 500.0, 120.0),
                           resolution=0.5, safety_margin=1.0, adaptive_threshold=1.5,
                           max_planning_time=0.0)
    planner = Planner(config, obstacles)
    started = time.perf_counter()
    planner.warm_up()
    ready = time.perf_counter() - started
    mask = planner.blocked
    nodes = planner.grid.size
    ready_rss = current_rss_mb()
    plans = []
    for _ in range(2):
        began = time.perf_counter()
        result = planner.plan((-460.0, -460.0, 2.0), (460.0, 460.0, 2.0))
        plans.append(dict(status=str(result.status.value), wall_s=time.perf_counter() - began,
                          search_s=result.planning_time_s, smoothing_s=result.smoothing_time_s,
                          expanded=result.expanded_nodes, length_m=result.smoothed_length_m,
                          algorithm=result.algorithm))
    records = planner._workspace.record_bytes if planner._workspace is not None else 0
    # A live-map change: a 6 m box appears at a crossroads; the 32-node tiles within reach are
    # re-inflated into a new mask (as the live map does), against a full rebuild.
    reinflate = math.nan
    if isinstance(mask, SparseMask):
        grid = planner.grid
        added = Box(np.zeros(3), np.full(3, 6.0))
        changed = ObstacleSet([Box(b[0], b[1]) for b in boxes] + [added])
        lo = grid.world_to_index(np.array([-2.0, -2.0, 0.0])) // 32
        hi = grid.world_to_index(np.array([8.0, 8.0, 8.0])) // 32
        axes = [np.arange(a, b + 1) for a, b in zip(lo, hi)]
        tiles = np.stack(np.meshgrid(*axes, indexing='ij'), axis=-1).reshape(-1, 3)
        runs = []
        for _ in range(3):  # the first one also loads its kernels
            began = time.perf_counter()
            reinflate_sparse(grid, changed, config.safety_margin, mask, tiles, 32)
            runs.append(time.perf_counter() - began)
        reinflate = float(np.median(runs))
    free, full, mixed = mask.brick_counts() if isinstance(mask, SparseMask) else (0, 0, 0)
    return dict(nodes=nodes, shape=list(planner.grid.shape), kernels_s=kernels, ready_s=ready,
                reinflate_s=reinflate,
                plans=plans, mask_bytes=int(mask.nbytes), record_bytes=int(records),
                bricks=dict(free=free, full=full, mixed=mixed), base_rss_mb=base_rss,
                ready_rss_mb=ready_rss, peak_rss_mb=peak_rss_mb(),
                layout='sparse' if isinstance(mask, SparseMask) else 'dense')


def voxel_map_points(side: int = 406, seed: int = 406, blocks: int = 12000) -> np.ndarray:
    """Centres of the occupied voxels of a generated dense-occupancy map [m], shape (M, 3).

    Blocks of 2 to 12 voxels a side are strewn uniformly through the ``side``^3 volume (voxel
    edge 1 m, voxel (i, j, k) centred at (i, j, k)), so every part of the map holds obstacles.
    """
    rng = np.random.default_rng(seed)
    occupied = np.zeros((side, side, side), dtype=np.bool_)
    for _ in range(blocks):
        low = rng.integers(0, side, 3)
        high = np.minimum(low + rng.integers(2, 13, 3), side)
        occupied[low[0]:high[0], low[1]:high[1], low[2]:high[2]] = True
    points = np.argwhere(occupied).astype(np.float64)
    del occupied
    return points


def case_voxel_map() -> Dict[str, object]:
    _warm_kernels()
    base_rss = current_rss_mb()
    side = 406
    # Read as a user's map file would be (the parent wrote it).
    obstacles = ObstacleSet([load_map_points(os.environ['VOXEL_MAP_FILE']).obstacle()])
    points = obstacles.points
    loaded_rss = current_rss_mb()
    grid = VoxelGrid.from_bounds([0, 0, 0], [side - 1.0] * 3, 1.0)
    started = time.perf_counter()
    mask = blocked_mask(grid, obstacles, 1.0)
    build = time.perf_counter() - started
    free, full, mixed = mask.brick_counts() if isinstance(mask, SparseMask) else (0, 0, 0)
    return dict(nodes=grid.size, points=len(points), occupancy=len(points) / grid.size,
                build_s=build, mask_bytes=int(mask.nbytes), base_rss_mb=base_rss,
                loaded_rss_mb=loaded_rss, peak_rss_mb=peak_rss_mb(),
                bricks=dict(free=free, full=full, mixed=mixed),
                layout='sparse' if isinstance(mask, SparseMask) else 'dense')


def case_first_query() -> Dict[str, object]:
    _warm_kernels()
    scene = spheres_boxes_100m()
    planner = Planner(scene.config(max_planning_time=0.0), scene.obstacle_set())
    started = time.perf_counter()
    planner.warm_up()
    ready = time.perf_counter() - started
    grid = planner.grid
    start = grid.world_to_index(scene.start)
    goal = grid.world_to_index(scene.goal)
    # The first search of each of five fresh workspaces (fresh search memory on the grid),
    # against the same search repeated on the last one.
    firsts, warm = [], []
    expanded = 0
    for _ in range(5):
        workspace = SearchWorkspace(planner.blocked)
        found = workspace.search(start, goal, 'adaptive', grid.resolution,
                                 scene.adaptive_threshold)
        firsts.append(found.search_time_s)
        expanded = found.expanded_nodes
    for _ in range(5):
        warm.append(workspace.search(start, goal, 'adaptive', grid.resolution,
                                     scene.adaptive_threshold).search_time_s)
    octile = []
    for _ in range(2):
        found = workspace.search(start, goal, 'octile', grid.resolution,
                                 scene.adaptive_threshold)
        octile.append((found.search_time_s, found.expanded_nodes))
    fresh = SearchWorkspace(planner.blocked)
    found = fresh.search(start, goal, 'octile', grid.resolution, scene.adaptive_threshold)
    octile.insert(0, (found.search_time_s, found.expanded_nodes))
    return dict(nodes=grid.size, ready_s=ready, first_s=firsts, warm_s=warm,
                adaptive_expanded=expanded, octile=octile, record_bytes=fresh.record_bytes,
                peak_rss_mb=peak_rss_mb())


def case_layouts() -> Dict[str, object]:
    _warm_kernels()
    scene = town400()
    grid = VoxelGrid.from_bounds(scene.bounds_min, scene.bounds_max, scene.resolution)
    obstacles = scene.obstacle_set()
    start = grid.world_to_index(scene.start)
    goal = grid.world_to_index(scene.goal)
    out: Dict[str, object] = dict(nodes=grid.size)
    for layout in ('dense', 'sparse'):
        started = time.perf_counter()
        mask = blocked_mask(grid, obstacles, scene.safety_margin, layout=layout)
        build = time.perf_counter() - started
        workspace = SearchWorkspace(mask)
        figures = {}
        for algorithm in ('adaptive', 'octile'):
            runs = [workspace.search(start, goal, algorithm, grid.resolution,
                                     scene.adaptive_threshold) for _ in range(3)]
            figures[algorithm] = dict(first_s=runs[0].search_time_s,
                                      warm_s=float(np.median([r.search_time_s
                                                              for r in runs[1:]])),
                                      expanded=runs[0].expanded_nodes, cost=runs[0].cost_m)
        out[layout] = dict(build_s=build, mask_bytes=int(mask.nbytes), search=figures)
    return out


CASES: Dict[str, Callable[[], Dict[str, object]]] = {
    'city': case_city, 'voxel_map': case_voxel_map, 'voxel_map_18': case_voxel_map,
    'first_query': case_first_query, 'layouts': case_layouts}

# Blocks strewn into each voxel map: 5.8 % and 18.2 % of the voxels occupied.
VOXEL_BLOCKS = {'voxel_map': 12000, 'voxel_map_18': 40000}


def run_child(name: str) -> Dict[str, object]:
    """One case in a fresh interpreter; its JSON figures."""
    with tempfile.TemporaryDirectory() as folder:
        environment = dict(os.environ)
        if name in VOXEL_BLOCKS:
            environment['VOXEL_MAP_FILE'] = str(Path(folder) / 'voxel_map.npy')
            points = voxel_map_points(blocks=VOXEL_BLOCKS[name])
            np.save(environment['VOXEL_MAP_FILE'], points.astype(np.float32))
            del points
        done = subprocess.run([sys.executable, __file__, '--child', name], capture_output=True,
                              text=True, check=False, env=environment)
    if done.returncode != 0:
        return dict(error=done.stderr.strip().splitlines()[-1:] or ['failed'])
    return json.loads(done.stdout.strip().splitlines()[-1])


def report(name: str, figures: Dict) -> List[str]:
    """Printed lines of one case, with the targets."""
    if 'error' in figures:
        return [f'{name}: FAILED {figures["error"]}']
    lines = []
    if name == 'city':
        nodes = figures['nodes']
        first, second = figures['plans']
        lines += [
            f'city 1 km x 1 km x 120 m @ 0.5 m: {nodes / 1e6:.0f} M nodes {figures["shape"]}, '
            f'layout {figures["layout"]}',
            f'  grid ready (mask + warm-up): {figures["ready_s"]:.2f} s (target <= 5 s; kernels '
            f'loaded before: {figures["kernels_s"]:.2f} s)',
            f'  1.30 km crossing end to end ({first["algorithm"]}): first '
            f'{first["wall_s"]:.2f} s (search {first["search_s"]:.3f} s, smoothing '
            f'{first["smoothing_s"]:.2f} s), second {second["wall_s"]:.2f} s (target <= 2 s); '
            f'{first["status"]}, {first["expanded"]} expanded, {first["length_m"]:.0f} m',
            f'  peak RSS {figures["peak_rss_mb"]:.0f} MB (target <= 2000 MB; interpreter and '
            f'libraries {figures["base_rss_mb"]:.0f} MB, after grid ready '
            f'{figures["ready_rss_mb"]:.0f} MB)',
            f'  mask {figures["mask_bytes"] / MB:.1f} MB = '
            f'{figures["mask_bytes"] / nodes:.4f} B/node (bricks {figures["bricks"]}); search '
            f'records {figures["record_bytes"] / MB:.1f} MB = '
            f'{figures["record_bytes"] / nodes:.4f} B/node; total '
            f'{(figures["mask_bytes"] + figures["record_bytes"]) / nodes:.4f} B/node '
            f'(dense layout: 18 B/node + 20 B per open entry)',
            f'  a 6 m box added, its tiles re-inflated into a new mask: '
            f'{figures["reinflate_s"] * 1e3:.0f} ms, median of 3 (a full build: see grid ready)']
    elif name in VOXEL_BLOCKS:
        lines += [
            f'voxel map 406^3 (generated, {figures["nodes"] / 1e6:.1f} M nodes, '
            f'{figures["points"] / 1e6:.2f} M occupied voxels = '
            f'{100 * figures["occupancy"]:.1f} %), layout {figures["layout"]}',
            f'  grid build {figures["build_s"]:.2f} s (target <= 1.5 s)',
            f'  peak RSS {figures["peak_rss_mb"]:.0f} MB (target <= 500 MB; interpreter '
            f'{figures["base_rss_mb"]:.0f} MB, with the map read into an ObstacleSet '
            f'{figures["loaded_rss_mb"]:.0f} MB); mask {figures["mask_bytes"] / MB:.1f} MB '
            f'(bricks {figures["bricks"]})']
    elif name == 'first_query':
        first = float(np.median(figures['first_s']))
        warm = float(np.median(figures['warm_s']))
        lines += [
            f'first query, {figures["nodes"] / 1e6:.0f} M-node grid (ready in '
            f'{figures["ready_s"]:.2f} s): adaptive, median of 5 fresh workspaces '
            f'{first * 1e3:.2f} ms, warm (median of 5) {warm * 1e3:.2f} ms, ratio '
            f'{first / max(warm, 1e-9):.2f} (target <= 2); {figures["adaptive_expanded"]} '
            'expanded',
            '  octile, fresh workspace then warm twice: ' + ', '.join(
                f'{t * 1e3:.0f} ms' for t, _ in figures['octile'])
            + f' ({figures["octile"][0][1]} expanded); records of the fresh one '
            f'{figures["record_bytes"] / MB:.1f} MB, peak RSS {figures["peak_rss_mb"]:.0f} MB']
    elif name == 'layouts':
        lines.append(f'layouts on town400 ({figures["nodes"] / 1e6:.1f} M nodes):')
        for layout in ('dense', 'sparse'):
            part = figures[layout]
            search = part['search']
            lines.append(
                f'  {layout:6s} build {part["build_s"]:.3f} s, mask '
                f'{part["mask_bytes"] / MB:.1f} MB; ' + ', '.join(
                    f'{a} {s["warm_s"] * 1e3:.1f} ms warm / {s["first_s"] * 1e3:.1f} ms first '
                    f'({s["expanded"]} exp, cost {s["cost"]:.4f})' for a, s in search.items()))
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--only', action='append', default=[], help='case name(s)')
    parser.add_argument('--json', action='store_true', help='print the figures as JSON')
    parser.add_argument('--child', help=argparse.SUPPRESS)
    options = parser.parse_args()
    if options.child:
        print(json.dumps(CASES[options.child]()))
        return
    names = [n for part in options.only for n in part.split(',')] or list(CASES)
    results = {}
    for name in names:
        results[name] = run_child(name)
        if not options.json:
            print('\n'.join(report(name, results[name])), flush=True)
    if options.json:
        print(json.dumps(results, indent=2))


if __name__ == '__main__':
    main()
