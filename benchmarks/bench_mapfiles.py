"""Prints how long loading map files takes: 1 M points from PCD, PLY, LAS, LAZ, .npy and OctoMap.

Run inside the project's environment::

    source scripts/venv.sh && python benchmarks/bench_mapfiles.py [--points N] [--repeats R]

Each file is written by its format's own library into a temporary folder (binary encodings, as
surveys and SLAM tools write them), then read with
:func:`uav_global_planner.core.io.mapfiles.load_map_points`; the figure is the median of the
repeats, the first read (imports, page cache) is shown apart. The target is 1 s for 1 M points of
PCD, PLY, LAS and .npy. Voxel downsampling and the OctoMap file (whose library reads and walks
its tree leaf by leaf) are reported as well.
"""

import argparse
from pathlib import Path
import statistics
import tempfile
import time
from typing import Callable, Dict

import laspy
import numpy as np
import octomap
from plyfile import PlyData, PlyElement
from pypcd4 import PointCloud

from uav_global_planner.core.io.mapfiles import load_map_points, voxel_downsample

TARGET_S = 1.0


def write_pcd(points: np.ndarray, file: Path) -> None:
    """Binary PCD of float32 x, y, z (as PCL writes point clouds)."""
    PointCloud.from_xyz_points(points.astype(np.float32)).save(file)


def write_ply(points: np.ndarray, file: Path) -> None:
    """Binary little-endian PLY of float32 vertices."""
    vertex = np.empty(len(points), dtype=[('x', 'f4'), ('y', 'f4'), ('z', 'f4')])
    vertex['x'], vertex['y'], vertex['z'] = points.T
    PlyData([PlyElement.describe(vertex, 'vertex')]).write(str(file))


def write_las(points: np.ndarray, file: Path) -> None:
    """LAS 1.4 point format 6 with millimetre scales (LAZ when the suffix says so)."""
    header = laspy.LasHeader(point_format=6, version='1.4')
    header.offsets = points.min(axis=0)
    header.scales = np.array([0.001, 0.001, 0.001])
    data = laspy.LasData(header)
    data.x, data.y, data.z = points.T
    data.write(str(file))


def write_npy(points: np.ndarray, file: Path) -> None:
    """An (N, 3) float64 array."""
    np.save(file, points)


def write_bt(points: np.ndarray, file: Path) -> None:
    """An OctoMap of 0.1 m cells with every point's cell occupied."""
    tree = octomap.OcTree(0.1)
    tree.updateNodes(points, True)
    tree.writeBinary(str(file).encode())


WRITERS: Dict[str, Callable[[np.ndarray, Path], None]] = {
    'pcd': write_pcd, 'ply': write_ply, 'las': write_las, 'laz': write_las, 'npy': write_npy,
    'bt': write_bt}


def main() -> None:
    """Write, read and print."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--points', type=int, default=1_000_000)
    parser.add_argument('--repeats', type=int, default=5)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    # A 1 km x 1 km survey, 100 m high.
    points = rng.uniform((0.0, 0.0, 0.0), (1000.0, 1000.0, 100.0), size=(args.points, 3))
    print(f'{args.points} points; median of {args.repeats} reads (first read apart); '
          f'target {TARGET_S:.1f} s for pcd, ply, las and npy')
    print(f'{"format":>6}  {"file [MB]":>9}  {"write [s]":>9}  {"first [s]":>9}  '
          f'{"median [s]":>10}  {"points":>9}  verdict')
    with tempfile.TemporaryDirectory() as folder:
        for suffix, writer in WRITERS.items():
            file = Path(folder) / f'map.{suffix}'
            started = time.perf_counter()
            writer(points, file)
            written = time.perf_counter() - started
            times = []
            for _ in range(args.repeats + 1):
                started = time.perf_counter()
                loaded = load_map_points(file)
                times.append(time.perf_counter() - started)
            median = statistics.median(times[1:])
            verdict = ('' if suffix in ('bt', 'laz') else
                       'ok' if median <= TARGET_S else 'SLOWER THAN TARGET')
            print(f'{suffix:>6}  {file.stat().st_size / 1e6:9.1f}  {written:9.2f}  '
                  f'{times[0]:9.3f}  {median:10.3f}  {len(loaded.points):9d}  {verdict}')
    for cell in (0.5, 2.0, 10.0):
        started = time.perf_counter()
        kept = voxel_downsample(points, cell)
        print(f'voxel downsampling at {cell} m: {len(kept)} points kept in '
              f'{time.perf_counter() - started:.3f} s (margin {cell * np.sqrt(3) / 2:.3f} m)')


if __name__ == '__main__':
    main()
