"""Prints the grid build of a dense room scan, old pass against new, and the budget outcome.

Run inside the project's environment::

    source scripts/venv.sh && python benchmarks/bench_dense_map.py [--resolution 0.05]
        [--map room.bt] [--keep room.bt]

The map is an OctoMap of a 7 x 7.6 x 4.4 m room at 2 cm written here with the OctoMap bindings
(octomap-python): the floor, the ceiling and the four walls, a dozen pieces of furniture (a
sofa, tables, shelves, a pillar, a duct) and, as a scanner leaves them, a second layer of cells
on parts of every surface: about a million occupied cells (``--map`` reads another ``.bt``
instead). Figures, at gamma 0.3 m plus the map's margin (the cells' half diagonal):

- the map read (``load_map_points``);
- the blocked mask at each grid resolution, by the pass of the previous release (every point
  stamps its ball, or, as here, a KD-tree query of every node once the balls overlap hundreds
  of times) and by :func:`~uav_global_planner.core.map.inflation.blocked_mask`, with a check that
  both masks are equal;
- ``uav-plan plan ... --max-planning-time 1`` on that room (a process of its own): status,
  message, the plan's own time and the command's wall time, with the default unknown-space
  policy and with ``--unknown-space free``; and the latter without a limit (``0``), with its
  progress lines.

The target is 1 s for the grid build and a TIMEOUT naming the stage within 1.5 s of plan time.
"""

import argparse
import json
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
import time
from typing import List, Tuple

import numpy as np
import octomap

from uav_global_planner.core.io.mapfiles import load_map_points
from uav_global_planner.core.map import inflation, point_inflation, stamping
from uav_global_planner.core.map.grid import VoxelGrid
from uav_global_planner.core.map.obstacles import ObstacleSet, PointSet

ROOM = np.array([7.0, 7.6, 4.4])
CELL = 0.02
GAMMA = 0.3
TARGET_S = 1.0
# Furniture: (min corner, max corner) [m].
FURNITURE: List[Tuple[Tuple[float, float, float], Tuple[float, float, float]]] = [
    ((0.3, 0.3, 0.0), (2.5, 1.2, 0.85)),   # sofa
    ((3.0, 2.5, 0.72), (4.6, 3.4, 0.76)),  # table top
    ((6.5, 0.5, 0.0), (6.9, 3.0, 2.1)),    # shelf
    ((0.2, 5.5, 0.0), (1.4, 7.4, 1.0)),    # cabinet
    ((4.0, 6.6, 0.0), (6.8, 7.4, 0.75)),   # desk
    ((4.5, 6.9, 0.75), (5.1, 7.0, 1.2)),   # monitor
    ((5.5, 6.9, 0.75), (6.1, 7.0, 1.2)),   # monitor
    ((3.2, 0.2, 0.0), (4.4, 0.8, 1.9)),    # wardrobe
    ((2.0, 4.0, 0.0), (2.5, 4.5, 0.45)),   # stool
    ((5.0, 4.5, 0.0), (5.3, 4.8, 4.4)),    # pillar
    ((0.0, 3.0, 2.5), (0.3, 5.0, 2.8)),    # wall shelf
    ((3.0, 3.0, 4.0), (4.0, 4.5, 4.4)),    # duct
] + [((x - 0.03, y - 0.03, 0.0), (x + 0.03, y + 0.03, 0.72))  # table legs
     for x, y in [(3.05, 2.55), (4.55, 2.55), (3.05, 3.35), (4.55, 3.35)]]


def _box_faces(lo, hi, cell: float, bottom: bool) -> np.ndarray:
    """Cell indices on the faces of a box (without the bottom face unless asked)."""
    first = np.floor(np.asarray(lo) / cell).astype(np.int64)
    last = np.ceil(np.asarray(hi) / cell).astype(np.int64) - 1
    faces = []
    for axis in range(3):
        others = [a for a in range(3) if a != axis]
        u, v = np.meshgrid(np.arange(first[others[0]], last[others[0]] + 1),
                           np.arange(first[others[1]], last[others[1]] + 1), indexing='ij')
        for level in (first[axis], last[axis]):
            if axis == 2 and level == first[axis] and not bottom:
                continue
            face = np.empty((u.size, 3), dtype=np.int64)
            face[:, axis] = level
            face[:, others[0]] = u.ravel()
            face[:, others[1]] = v.ravel()
            faces.append(face)
    return np.concatenate(faces)


def _unique(cells: np.ndarray) -> np.ndarray:
    low = cells.min(axis=0)
    span = cells.max(axis=0) - low + 1
    keys = np.unique(((cells[:, 0] - low[0]) * span[1] + cells[:, 1] - low[1]) * span[2]
                     + cells[:, 2] - low[2])
    return np.stack(np.unravel_index(keys, tuple(int(s) for s in span)), axis=-1) + low


def room_cells(cell: float = CELL, layer: float = 0.55, rounds: int = 2,
               seed: int = 0) -> np.ndarray:
    """Centres of the occupied cells of the room [m]: its shell, the furniture's surfaces and,
    ``rounds`` times, a neighbour (along a random axis) of ``layer`` of the cells: the
    thickness a scan gives its surfaces."""
    rng = np.random.default_rng(seed)
    parts = [_box_faces((0.0, 0.0, 0.0), ROOM, cell, bottom=True)]
    parts += [_box_faces(lo, hi, cell, bottom=False) for lo, hi in FURNITURE]
    cells = _unique(np.concatenate(parts))
    for _ in range(rounds):
        chosen = cells[rng.random(len(cells)) < layer]
        step = np.zeros_like(chosen)
        step[np.arange(len(chosen)), rng.integers(0, 3, len(chosen))] = rng.choice(
            [-1, 1], len(chosen))
        cells = _unique(np.concatenate([cells, chosen + step]))
    return (cells + 0.5) * cell


def write_room(file: Path) -> int:
    """Write the room as an OctoMap binary; the number of occupied cells."""
    centres = room_cells()
    tree = octomap.OcTree(CELL)
    tree.updateNodes(centres, True)
    tree.writeBinary(str(file).encode())
    return len(centres)


def old_pass(grid: VoxelGrid, points: np.ndarray, gamma: float) -> np.ndarray:
    """The point pass of the previous release: stamping, or a KD-tree query of every node
    once the balls visit more than 300 nodes per grid node."""
    blocked = np.zeros(grid.shape, dtype=bool)
    relevant = point_inflation.relevant_points(grid, points, gamma)
    if point_inflation.ball_visits(grid, len(relevant), gamma) > 300.0 * grid.size:
        point_inflation.mark_by_nearest_point_in(grid, relevant, gamma, blocked,
                                                 np.zeros(3, np.int64))
    else:
        stamping.stamp_points(blocked, np.asarray(grid.bounds_min), grid.resolution,
                              point_inflation.in_memory_order(grid, relevant), gamma)
    return blocked


def _timed(function, *args):
    started = time.perf_counter()
    value = function(*args)
    return value, time.perf_counter() - started


def _cli(scene: Path, map_file: Path, budget: str, extra: List[str]) -> None:
    executable = shutil.which('uav-plan')
    if executable is None:
        print('uav-plan not on PATH: skipped the command line')
        return
    command = [executable, 'plan', str(scene), '--map', str(map_file), '--json',
               '--max-planning-time', budget, *extra]
    started = time.perf_counter()
    run = subprocess.run(command, capture_output=True, text=True, timeout=900)
    wall = time.perf_counter() - started
    result = json.loads(run.stdout)
    progress = [line for line in run.stderr.splitlines() if line.startswith('planning:')]
    options = ' '.join(['--max-planning-time', budget, *extra])
    print(f'  uav-plan plan {options}: exit {run.returncode}, '
          f'{result["status"]}, plan time {result.get("total_time_s") or 0.0:.2f} s '
          f'(grid build {result.get("grid_build_time_s") or 0.0:.2f} s), command wall '
          f'{wall:.1f} s')
    print(f'    message: {result["message"]}')
    for line in progress:
        print(f'    stderr: {line}')


def main() -> None:
    """Write (or read) the room, time the builds, run the command line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--resolution', type=float, action='append',
                        help='grid resolution delta [m]; repeatable (default 0.1 and 0.05)')
    parser.add_argument('--map', type=Path, help='an OctoMap .bt to read instead of the room')
    parser.add_argument('--keep', type=Path, help='also save the generated room here')
    parser.add_argument('--no-cli', action='store_true', help='skip the command line runs')
    args = parser.parse_args()
    deltas = args.resolution or [0.1, 0.05]
    with tempfile.TemporaryDirectory() as folder:
        map_file = args.map
        if map_file is None:
            map_file = Path(folder) / 'room.bt'
            cells, seconds = _timed(write_room, map_file)
            print(f'room {ROOM.tolist()} m at {CELL} m: {cells} occupied cells written in '
                  f'{seconds:.1f} s ({map_file.stat().st_size / 1e6:.1f} MB)')
            if args.keep:
                shutil.copy(map_file, args.keep)
        loaded, seconds = _timed(load_map_points, map_file)
        points = loaded.points
        gamma = GAMMA + loaded.margin_m
        # The room's own box (7 x 7.6 x 4.4 m): the cells on its faces stick out by half a cell.
        low = np.round(points.min(axis=0), 1)
        high = np.round(points.max(axis=0), 1)
        print(f'map read in {seconds:.2f} s: {len(points)} points, margin '
              f'{loaded.margin_m:.4f} m, so gamma {gamma:.4f} m')
        obstacles = ObstacleSet([PointSet(points)])
        print(f'{"delta [m]":>9}  {"nodes":>10}  {"old [s]":>8}  {"new [s]":>8}  '
              f'{"new again [s]":>13}  {"equal":>5}  verdict')
        scenes = []
        for delta in deltas:
            grid = VoxelGrid.from_bounds(low, high, delta)
            new, first = _timed(inflation.blocked_mask, grid, obstacles, gamma)
            _, again = _timed(inflation.blocked_mask, grid, obstacles, gamma)
            old, old_s = _timed(old_pass, grid, points, gamma)
            dense = new if isinstance(new, np.ndarray) else new.to_dense()
            verdict = 'ok' if again <= TARGET_S else 'SLOWER THAN TARGET'
            print(f'{delta:9.3f}  {grid.size:10d}  {old_s:8.2f}  {first:8.2f}  {again:13.2f}  '
                  f'{str(np.array_equal(old, dense)):>5}  {verdict}')
            scene = Path(folder) / f'room_{delta}.yaml'
            free = low + 0.35 * (high - low)
            goal = low + np.array([0.8, 0.75, 0.55]) * (high - low)
            scene.write_text(
                f'bounds: {{min: {low.tolist()}, max: {high.tolist()}}}\n'
                f'resolution: {delta}\nsafety_margin: {GAMMA}\nadaptive_threshold: 1.0\n'
                f'start: {free.round(2).tolist()}\ngoal: {goal.round(2).tolist()}\n'
                'obstacles: []\n')
            scenes.append((delta, scene))
        if args.no_cli:
            return
        for delta, scene in scenes:
            print(f'command line at delta {delta} m:')
            for budget, extra in (('1', []), ('1', ['--unknown-space', 'free']),
                                  ('0', ['--unknown-space', 'free'])):
                _cli(scene, map_file, budget, extra)
    sys.stdout.flush()


if __name__ == '__main__':
    main()
